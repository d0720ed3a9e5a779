//! A [`CanLink`] on a Linux SocketCAN interface (`can0`, `vcan0`, `slcan0`), through the `socketcan` crate.

use std::time::Duration;

use socketcan::{EmbeddedFrame, ExtendedId, Frame as _, Id, Socket, StandardId};

use super::{CanFrame, CanLink};
use crate::link::LinkError;

/// A raw CAN socket bound to one interface.
pub struct SocketCanLink {
    socket: socketcan::CanSocket,
    name: String,
}

impl std::fmt::Debug for SocketCanLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SocketCanLink").field("name", &self.name).finish()
    }
}

impl SocketCanLink {
    /// Opens the interface `ifname` (it must exist and be up: `ip link set can0 up type can bitrate 1000000`).
    pub fn open(ifname: &str) -> Result<Self, LinkError> {
        let name = format!("socketcan://{ifname}");
        let socket = socketcan::CanSocket::open(ifname).map_err(|e| LinkError::Open {
            port: name.clone(),
            reason: format!("{e} (does the interface exist and is it up?)"),
        })?;
        Ok(SocketCanLink { socket, name })
    }
}

fn to_socketcan(frame: &CanFrame) -> Option<socketcan::CanFrame> {
    let id: Id = if frame.is_extended() {
        Id::Extended(ExtendedId::new(frame.id())?)
    } else {
        Id::Standard(StandardId::new(u16::try_from(frame.id()).ok()?)?)
    };
    if frame.is_remote() {
        socketcan::CanFrame::new_remote(id, usize::from(frame.dlc()))
    } else {
        socketcan::CanFrame::new(id, frame.data())
    }
}

fn from_socketcan(frame: &socketcan::CanFrame) -> Option<CanFrame> {
    if frame.is_error_frame() {
        return None;
    }
    let (id, extended) = match frame.id() {
        Id::Standard(id) => (u32::from(id.as_raw()), false),
        Id::Extended(id) => (id.as_raw(), true),
    };
    if frame.is_remote_frame() {
        CanFrame::new_remote(id, extended, frame.dlc() as u8).ok()
    } else if extended {
        CanFrame::new_extended(id, frame.data()).ok()
    } else {
        CanFrame::new(id, frame.data()).ok()
    }
}

impl CanLink for SocketCanLink {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let raw = to_socketcan(frame).ok_or_else(|| LinkError::Io {
            port: self.name.clone(),
            source: std::sync::Arc::new(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("cannot send {frame}"),
            )),
        })?;
        self.socket.write_frame_insist(&raw).map_err(|e| LinkError::from_io(&self.name, e))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.socket.read_frame_timeout(left.max(Duration::from_micros(1))) {
                Ok(frame) => match from_socketcan(&frame) {
                    Some(f) => return Ok(Some(f)),
                    None => {
                        tracing::debug!("{}: error frame {:?}", self.name, frame);
                        if left.is_zero() {
                            return Ok(None);
                        }
                    }
                },
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted
                    ) =>
                {
                    return Ok(None)
                }
                Err(e) => return Err(LinkError::from_io(&self.name, e)),
            }
        }
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_convert_both_ways() {
        for f in [
            CanFrame::new(0x0F1, &[1, 2, 3]).unwrap(),
            CanFrame::new_extended(0x1234_5678, &[9]).unwrap(),
            CanFrame::new_remote(0x0D1, false, 2).unwrap(),
        ] {
            let raw = to_socketcan(&f).unwrap();
            assert_eq!(from_socketcan(&raw), Some(f));
        }
    }

    #[test]
    fn a_missing_interface_is_an_open_error() {
        let err = SocketCanLink::open("motionlink-no-such-if0").unwrap_err();
        assert!(matches!(err, LinkError::Open { .. }), "{err}");
    }
}
