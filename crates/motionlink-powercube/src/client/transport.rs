//! The carrier under a session: RS232 frames on a byte link, or PowerCube frames on a CAN link.

use std::collections::VecDeque;
use std::time::Duration;

use motionlink_link::can::CanLink;
use motionlink_link::{Link, LinkError};

use crate::model::{Broadcast, BroadcastForm};
use crate::wire::can::{self as can_wire, Role};
use crate::wire::rs232::{self, Rs232Decoder, TelKind};
use crate::wire::Payload;

/// What came in: an acknowledge from a module, or something broken.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Incoming {
    /// A frame from the module at `address`.
    Frame { address: u8, payload: Payload },
    /// A frame or bytes that could not be used (bad BCC, broken frame).
    Corrupt(String),
}

enum Carrier {
    Rs232 { link: Box<dyn Link>, decoder: Rs232Decoder, pending: VecDeque<Incoming> },
    Can { link: Box<dyn CanLink> },
}

/// One end of the session's line.
pub(crate) struct Transport {
    carrier: Carrier,
    /// A timeout left replies possibly on their way: drop what is pending before the next request.
    pub stale: bool,
}

impl Transport {
    pub fn rs232(link: Box<dyn Link>) -> Self {
        Transport {
            carrier: Carrier::Rs232 { link, decoder: Rs232Decoder::new(), pending: VecDeque::new() },
            stale: false,
        }
    }

    pub fn can(link: Box<dyn CanLink>) -> Self {
        Transport { carrier: Carrier::Can { link }, stale: false }
    }

    pub fn is_can(&self) -> bool {
        matches!(self.carrier, Carrier::Can { .. })
    }

    pub fn describe(&self) -> String {
        match &self.carrier {
            Carrier::Rs232 { link, .. } => link.describe(),
            Carrier::Can { link } => link.describe(),
        }
    }

    /// Drops replies that came too late for an earlier request.
    pub fn discard_stale(&mut self) -> Result<(), LinkError> {
        if !self.stale {
            return Ok(());
        }
        self.stale = false;
        match &mut self.carrier {
            Carrier::Rs232 { link, decoder, pending } => {
                pending.clear();
                decoder.reset();
                link.discard_input()
            }
            Carrier::Can { link } => link.discard_input(),
        }
    }

    /// Sends a command to the module at `address` (0: every module, on RS232).
    pub fn send(&mut self, address: u8, payload: &Payload) -> Result<(), LinkError> {
        match &mut self.carrier {
            Carrier::Rs232 { link, .. } => {
                let mut buf = [0u8; rs232::MAX_FRAME];
                let n = rs232::encode(TelKind::Send, address, payload, &mut buf).map_err(|e| LinkError::Io {
                    port: link.describe(),
                    source: std::io::Error::new(std::io::ErrorKind::InvalidInput, e.to_string()),
                })?;
                link.send(&buf[..n])
            }
            Carrier::Can { link } => link.send(&can_wire::to_frame(Role::for_command(address, payload), payload)),
        }
    }

    /// Sends a broadcast: on CAN the broadcast identifier with the manual's payload; on RS232 module address
    /// 0 with the command followed by 0x00, as Schunk's libm5api sends it ([`BroadcastForm::Padded`]).
    pub fn broadcast(&mut self, broadcast: &Broadcast) -> Result<(), LinkError> {
        match &mut self.carrier {
            Carrier::Rs232 { .. } => self.send(0, &broadcast.encode_as(BroadcastForm::Padded)),
            Carrier::Can { link } => link.send(&can_wire::to_frame(Role::Broadcast, &broadcast.encode())),
        }
    }

    /// Waits up to `timeout` for something from a module.
    pub fn recv(&mut self, timeout: Duration) -> Result<Option<Incoming>, LinkError> {
        match &mut self.carrier {
            Carrier::Rs232 { link, decoder, pending } => {
                if let Some(i) = pending.pop_front() {
                    return Ok(Some(i));
                }
                let mut buf = [0u8; 64];
                let n = link.recv(&mut buf, timeout)?;
                for result in decoder.feed(&buf[..n]) {
                    match result {
                        Ok(f) if f.kind == TelKind::Send => {} // our own frame echoed by a converter
                        Ok(f) if !f.bcc_ok() => pending.push_back(Incoming::Corrupt(format!(
                            "frame from module {} with a wrong BCC (0x{:02X}, expected 0x{:02X})",
                            f.address, f.bcc_received, f.bcc_computed
                        ))),
                        // The manual's own acknowledge examples carry TELID length 6 for 3 data bytes: that
                        // one slip is accepted; any other length that differs from the data is corruption
                        // the BCC let through.
                        Ok(f) if !(f.length_ok() || (f.declared_len == 6 && f.payload.len() == 3)) => pending
                            .push_back(Incoming::Corrupt(format!(
                                "frame from module {} with TELID length {} for {} data bytes",
                                f.address,
                                f.declared_len,
                                f.payload.len()
                            ))),
                        Ok(f) => pending.push_back(Incoming::Frame { address: f.address, payload: f.payload }),
                        Err(e) => pending.push_back(Incoming::Corrupt(e.to_string())),
                    }
                }
                Ok(pending.pop_front())
            }
            Carrier::Can { link } => {
                let Some(frame) = link.recv(timeout)? else { return Ok(None) };
                Ok(match can_wire::from_frame(&frame) {
                    Ok((Role::Ack(address), payload)) => Some(Incoming::Frame { address, payload }),
                    Ok(_) => None, // commands from another master, broadcasts
                    Err(e) => {
                        tracing::debug!("{}: {e}", link.describe());
                        None
                    }
                })
            }
        }
    }
}
