//! The [`Link`] trait: a byte stream to one device or one bus, with read timeouts.

use std::fmt;
use std::time::Duration;

/// A transport failure: the line itself, not the device's answer. Cloneable (the I/O error is shared), so
/// that every operation waiting on a line that failed gets the same error.
#[derive(Debug, Clone, thiserror::Error)]
pub enum LinkError {
    /// The port could not be opened.
    #[error("cannot open {port}: {reason}")]
    Open {
        /// The port as the user named it.
        port: String,
        /// What the operating system or the peer said.
        reason: String,
    },
    /// The port went away or the peer closed the connection.
    #[error("{port}: connection lost ({reason})")]
    Disconnected {
        /// The port as the user named it.
        port: String,
        /// What happened.
        reason: String,
    },
    /// The port is served to another client: a `motionlink sim` server (or a gateway speaking its refusal,
    /// [`crate::emulator::BUSY_PREFIX`]) refused this connection because another client is connected.
    #[error("{port} is busy: another client is connected")]
    Busy {
        /// The port as the user named it.
        port: String,
    },
    /// Another I/O failure on an open port.
    #[error("{port}: {source}")]
    Io {
        /// The port as the user named it.
        port: String,
        /// The underlying error.
        #[source]
        source: std::sync::Arc<std::io::Error>,
    },
    /// The port name or URL is not understood.
    #[error("invalid port {port:?}: {reason}")]
    InvalidPort {
        /// The text that was given.
        port: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl LinkError {
    /// Classifies an I/O error of an open port: errors that mean the port is gone become
    /// [`LinkError::Disconnected`].
    pub fn from_io(port: &str, e: std::io::Error) -> Self {
        use std::io::ErrorKind::*;
        let gone = matches!(
            e.kind(),
            BrokenPipe | ConnectionReset | ConnectionAborted | NotConnected | UnexpectedEof | NotFound
        ) || e.raw_os_error() == Some(5); // EIO: a pty or USB adapter whose other side went away
        if gone {
            LinkError::Disconnected { port: port.to_string(), reason: e.to_string() }
        } else {
            LinkError::Io { port: port.to_string(), source: std::sync::Arc::new(e) }
        }
    }

    /// True when the link is gone and must be reopened (a busy server closed it too).
    pub fn is_disconnect(&self) -> bool {
        matches!(self, LinkError::Disconnected { .. } | LinkError::Busy { .. })
    }
}

/// A byte stream to a device: a serial port, a TCP connection to a serial gateway, a pty, an in-memory pipe.
///
/// Reads wait at most a given timeout and return `Ok(0)` when nothing arrived: a timeout is not an error at
/// this layer, the protocol decides what it means. An end of stream is [`LinkError::Disconnected`].
pub trait Link: Send {
    /// Writes all of `bytes`.
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError>;

    /// Waits up to `timeout` for at least one byte, then returns how many were put into `buf` (0: timeout).
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError>;

    /// Drops every byte received but not yet read (stale replies after a timeout or a reconnect).
    fn discard_input(&mut self) -> Result<(), LinkError>;

    /// The port as a user would name it, for messages.
    fn describe(&self) -> String;

    /// Holds the line at "space" (a break) for `duration`, then releases it: an SCU in low-power mode wakes
    /// when its RxD is held at space for at least 100 ms. Only a serial line (and an emulator in this
    /// process) has such a state; another link refuses ([`LinkError::InvalidPort`]).
    fn send_break(&mut self, duration: Duration) -> Result<(), LinkError> {
        let _ = duration;
        Err(LinkError::InvalidPort {
            port: self.describe(),
            reason: "a break (the line held at space) can only be sent on a serial device".into(),
        })
    }
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        (**self).send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        (**self).recv(buf, timeout)
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        (**self).discard_input()
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
    fn send_break(&mut self, duration: Duration) -> Result<(), LinkError> {
        (**self).send_break(duration)
    }
}

/// Opens (and re-opens, after a loss) the link of a session.
pub type Connector = Box<dyn FnMut() -> Result<Box<dyn Link>, LinkError> + Send>;

/// Serial line settings: rate and framing. motionlink's devices all use 8 data bits and 1 stop bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialSettings {
    /// Bits per second.
    pub baud_rate: u32,
    /// Parity bit.
    pub parity: Parity,
    /// Hold DTR and RTS on (the SCU powers its RS232 converter from them).
    pub dtr_rts_on: bool,
}

impl SerialSettings {
    /// 8N1 at `baud_rate`, DTR and RTS on.
    pub fn new(baud_rate: u32) -> Self {
        SerialSettings { baud_rate, parity: Parity::None, dtr_rts_on: true }
    }

    /// Time on the wire of one character: start bit, 8 data bits, parity bit if any, stop bit.
    pub fn char_time(&self) -> Duration {
        char_time(self.baud_rate, self.parity)
    }
}

/// Parity bit of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parity {
    /// No parity bit.
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

impl fmt::Display for Parity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Parity::None => "N",
            Parity::Even => "E",
            Parity::Odd => "O",
        })
    }
}

/// Wire time of one character at `baud_rate`: 10 bit times for 8N1, 11 with a parity bit.
///
/// ```
/// use motionlink_link::link::{char_time, Parity};
/// assert_eq!(char_time(38_400, Parity::None).as_nanos(), 260_416);
/// ```
pub fn char_time(baud_rate: u32, parity: Parity) -> Duration {
    let bits: u64 = if parity == Parity::None { 10 } else { 11 };
    Duration::from_nanos(bits * 1_000_000_000 / u64::from(baud_rate.max(1)))
}
