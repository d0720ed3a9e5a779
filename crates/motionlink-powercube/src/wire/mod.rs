//! The sans-IO codec: the command layout shared by every bus, and its three carriers.
//!
//! A PowerCube command, on every bus, is `[CommandID][ParamID or MotionID][data 0..]`, at most 8 bytes,
//! little-endian data: a [`Payload`]. The carriers differ only in how they address it:
//!
//! - [`rs232`]: `STX TELID TELID data BCC ETX` with DLE escaping, decoded incrementally.
//! - [`can`]: the identifier says the role (ack 0x0A0, get 0x0C0, put 0x0E0 + module, broadcast 0x100), the
//!   DLC the length.
//! - [`profibus`]: an 8-byte output image (byte 7 a rolling counter) and a 16-byte input image.
//!
//! Nothing here does I/O, reads a clock or allocates; the meaning of the bytes is in
//! [`model`](crate::model).

pub mod can;
pub mod profibus;
mod reply;
mod request;
pub mod rs232;

pub use reply::{AckPosition, ExtAck, Reply};
pub(crate) use request::payload;
pub use request::{Action, ModelError, Request, RAW_CUR_MAX};

use std::fmt;

/// The status byte of an acknowledge that says "done" (`0x64`).
pub const ACK_OK: u8 = 0x64;

/// The most bytes a command or acknowledge carries.
pub const MAX_PAYLOAD: usize = 8;

/// Command identifiers (the first byte of every command and acknowledge).
pub mod cmd {
    /// Reset: clear the error state.
    pub const RESET: u8 = 0x00;
    /// Home: start the homing procedure.
    pub const HOME: u8 = 0x01;
    /// Halt: stop immediately.
    pub const HALT: u8 = 0x02;
    /// Watchdog: the life sign to one module (switches its watchdog on or off), or the refresh broadcast.
    pub const WATCHDOG: u8 = 0x07;
    /// SetExtended: write a parameter.
    pub const SET_EXTENDED: u8 = 0x08;
    /// RecalcPIDParam to one module; "change baud rate" as a broadcast.
    pub const RECALC_PID: u8 = 0x09;
    /// Change baud rate (broadcast only; the same code as [`RECALC_PID`]).
    pub const CHANGE_BAUD: u8 = 0x09;
    /// GetExtended: read a parameter.
    pub const GET_EXTENDED: u8 = 0x0a;
    /// SetMotion: a motion command.
    pub const SET_MOTION: u8 = 0x0b;
    /// SetIStep: a motion command in step mode, encoder ticks.
    pub const SET_ISTEP: u8 = 0x0d;
    /// Save position (broadcast only).
    pub const SAVE_POSITION: u8 = 0x0e;
    /// Start synchronised motion (broadcast only).
    pub const START_MOTION: u8 = 0x0f;
    /// SaveParameters (vendor library; not in the data exchange manual).
    pub const SAVE_PARAMETERS: u8 = 0x10;
    /// ResetTime: reset the module's millisecond clock.
    pub const RESET_TIME: u8 = 0x12;
}

/// An error building a payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("a PowerCube command carries at most {MAX_PAYLOAD} bytes, not {0}")]
pub struct PayloadTooLong(pub usize);

/// The bytes of one command or acknowledge, without carrier framing: at most 8, `Copy`, no allocation.
///
/// ```
/// use motionlink_powercube::wire::Payload;
/// let p = Payload::new(&[0x0a, 0x3c]).unwrap();
/// assert_eq!(p.command(), Some(0x0a));
/// assert_eq!(p.as_bytes(), &[0x0a, 0x3c]);
/// assert!(Payload::new(&[0; 9]).is_err());
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Payload {
    len: u8,
    bytes: [u8; MAX_PAYLOAD],
}

impl Payload {
    /// The empty payload.
    pub const EMPTY: Payload = Payload { len: 0, bytes: [0; MAX_PAYLOAD] };

    /// A payload of `bytes` (at most 8).
    #[inline]
    pub fn new(bytes: &[u8]) -> Result<Self, PayloadTooLong> {
        if bytes.len() > MAX_PAYLOAD {
            return Err(PayloadTooLong(bytes.len()));
        }
        let mut p = Payload::EMPTY;
        p.bytes[..bytes.len()].copy_from_slice(bytes);
        p.len = bytes.len() as u8;
        Ok(p)
    }

    /// Appends bytes; fails if the total would exceed 8.
    pub fn push(&mut self, bytes: &[u8]) -> Result<(), PayloadTooLong> {
        let len = usize::from(self.len);
        let total = len + bytes.len();
        if total > MAX_PAYLOAD {
            return Err(PayloadTooLong(total));
        }
        self.bytes[len..total].copy_from_slice(bytes);
        self.len = total as u8;
        Ok(())
    }

    /// The bytes.
    #[inline]
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }

    /// Number of bytes.
    #[inline]
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// True if there are no bytes.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The command identifier (the first byte), if any.
    pub fn command(&self) -> Option<u8> {
        self.as_bytes().first().copied()
    }
}

impl fmt::Debug for Payload {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Payload[")?;
        for (i, b) in self.as_bytes().iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{b:02X}")?;
        }
        f.write_str("]")
    }
}

/// The highest module address.
pub const MAX_ADDRESS: u8 = 31;

/// True for a module address the manual allows (1..31).
pub fn is_module_address(address: u8) -> bool {
    (1..=MAX_ADDRESS).contains(&address)
}
