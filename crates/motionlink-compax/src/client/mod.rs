//! Drivers of a COMPAX [`Session`](crate::Session) over a byte link (an RS485 adapter, RS232, a TCP serial
//! gateway, a pseudo-terminal, an in-process emulator): [`Client`] for blocking callers (shareable between
//! threads: its methods take `&self`) and, with the `tokio` feature, `AsyncClient` for async ones. Both
//! are thin typed calls over [`motionlink_link::driver`]; the protocol, its retries and its safety are the
//! session's, the same for both.
//!
//! Safety: a drive the session set in motion is remembered until the session has seen it stop. A failed
//! or cancelled wait or checked move (a cancel token of the blocking client, a dropped future of the async
//! one) stops the drives it concerns that still move with `OUTPUT O0=0` ("switch off drive", the one
//! documented command that ends a running positioning), reading S17 first and again to confirm. The error
//! says per drive whether the drive confirmed the stop ([`Error::Cancelled`], [`Error::FailedDuringMotion`],
//! [`StopReport`]); if not, that the axis may still be moving.
//!
//! Closing ([`Client::close`], or dropping the client) stops every axis the session set in motion that
//! still moves and returns the report; it waits for that at most
//! [`Config::close_bound`](crate::session::Config::close_bound) (5 s by default), never longer: past
//! that, the error says the axes may still be moving. [`Client::release`] hands a running move over: the
//! session forgets it and does not stop it.
//!
//! What the drives do not do: COMPAX has no host watchdog. A host that dies (killed, crashed, unplugged)
//! leaves a running positioning running to its target; nothing on the link stops it.

#[cfg(feature = "tokio")]
mod asynch;
mod blocking;
mod drive;

#[cfg(feature = "tokio")]
pub use asynch::{AsyncClient, AsyncDrive, AsyncWatch};
pub use blocking::{raw_may_start_motion, Client};
pub use drive::Drive;

pub use crate::error::{Error, Result, RoundTripRange, StopOutcome, StopReport};
pub use crate::session::{
    AfterRaw, Config, EchoForm, MoveOptions, MoveReport, MoveRequest, MoveTarget, Progress, RawOutcome, StartedMove,
    TravelLimits, WatchSample, DEFAULT_IN_POSITION_TOLERANCE,
};

use motionlink_link::driver::DriverConfig;
use motionlink_link::link::{Link, SerialSettings};
use motionlink_link::url::PortUrl;
use motionlink_link::LinkError;

use crate::session::Output;

/// The line [`Client::open`] opens: the serial device or TCP port `url` names, at the configuration's baud
/// rate with the parity of its mode. `sim` and CAN ports are refused, naming what to do instead.
pub fn open_line(url: &PortUrl, cfg: &Config) -> Result<Box<dyn Link>> {
    let refuse = |reason: &str| Error::Link(LinkError::InvalidPort { port: url.to_string(), reason: reason.into() });
    match url {
        PortUrl::Sim => {
            Err(refuse("an emulator in this process: make one (`Emulator`) and give its link to `with_link`"))
        }
        u if u.is_can() => Err(refuse("COMPAX drives speak RS485 / RS232, not CAN")),
        u => {
            let mut settings = SerialSettings::new(cfg.baud_rate);
            settings.parity = cfg.mode.parity;
            Ok(u.open_byte_link(settings)?)
        }
    }
}

/// The driver settings of a session configured by `cfg`.
fn driver_config(cfg: &Config) -> DriverConfig {
    DriverConfig { close_bound: cfg.close_bound, read_slice: cfg.read_slice }
}

/// An output of the kind the operation ends with, or an error naming the mismatch (which the session's
/// operations never produce).
fn output<T>(out: Output, what: &str, take: impl FnOnce(Output) -> std::result::Result<T, Output>) -> Result<T> {
    take(out).map_err(|other| Error::WrongOutput { what: what.to_string(), got: other.name() })
}
