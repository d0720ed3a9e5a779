//! Opening the link a port URL names, as every front end does (the command line, the web console, Python):
//! RS232 bytes over a serial device or TCP, CAN frames over an SLCAN adapter or SocketCAN.

use motionlink_link::can::CanLink;
use motionlink_link::url::PortUrl;
use motionlink_link::{Link, LinkError, SerialSettings, SharedClock};

use crate::args::{Baud, CanBitRate};
use crate::error::Error;
use crate::session::Config;

/// An opened port, for [`Client::with_link`](super::Client::with_link): the byte link of an RS232 line or the
/// frame link of a CAN bus (`Box<dyn Link>` and `Box<dyn CanLink>` convert into it).
pub enum PortLink {
    /// A serial device or a TCP port (ser2net, a served emulator), RS232 framing.
    Rs232(Box<dyn Link>),
    /// An SLCAN adapter or a SocketCAN interface.
    Can(Box<dyn CanLink>),
}

impl From<Box<dyn Link>> for PortLink {
    fn from(link: Box<dyn Link>) -> Self {
        PortLink::Rs232(link)
    }
}

impl From<Box<dyn CanLink>> for PortLink {
    fn from(link: Box<dyn CanLink>) -> Self {
        PortLink::Can(link)
    }
}

impl PortLink {
    /// Opens what `url` names as [`PortLink::open`] does, at the rates of `config`; `sim` is refused, naming
    /// what to do instead.
    pub fn open_configured(url: &PortUrl, config: &Config, clock: &SharedClock) -> Result<PortLink, Error> {
        PortLink::open(url, config.baud, config.can_bitrate, clock)?.ok_or_else(|| {
            Error::Link(LinkError::InvalidPort {
                port: url.to_string(),
                reason: "an emulator in this process: make one (`Emulator`) and give its link to `with_link`".into(),
            })
        })
    }

    /// True for a CAN bus.
    pub fn is_can(&self) -> bool {
        matches!(self, PortLink::Can(_))
    }

    /// Opens what `url` names: a serial device at `baud` (DTR and RTS left off: the modules need neither), a
    /// TCP port, an SLCAN adapter at `bitrate`, a SocketCAN interface (Linux). `None` for `sim`: the
    /// emulator is the caller's to start.
    pub fn open(
        url: &PortUrl,
        baud: Baud,
        bitrate: CanBitRate,
        clock: &SharedClock,
    ) -> Result<Option<PortLink>, Error> {
        Ok(Some(match url {
            PortUrl::Sim => return Ok(None),
            PortUrl::Serial(_) | PortUrl::Tcp { .. } => PortLink::Rs232(
                url.open_byte_link(SerialSettings { dtr_rts_on: false, ..SerialSettings::new(baud.get()) })?,
            ),
            PortUrl::Slcan(path) => {
                PortLink::Can(Box::new(motionlink_link::url::open_slcan(path, clock.clone(), bitrate.slcan())?))
            }
            PortUrl::SocketCan(ifname) => PortLink::Can(socketcan(ifname)?),
        }))
    }
}

#[cfg(target_os = "linux")]
fn socketcan(ifname: &str) -> Result<Box<dyn CanLink>, Error> {
    Ok(Box::new(motionlink_link::can::socketcan::SocketCanLink::open(ifname)?))
}

#[cfg(not(target_os = "linux"))]
fn socketcan(_ifname: &str) -> Result<Box<dyn CanLink>, Error> {
    Err(Error::NotSupported("socketcan:// ports need Linux".into()))
}
