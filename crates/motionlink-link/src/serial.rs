//! Serial ports through the `serialport` crate (built without system libraries), and pseudo-terminal pairs
//! for tests.

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use crate::link::{Link, LinkError, Parity, SerialSettings};

/// A serial port: a USB adapter, an on-board UART, or one side of a pseudo-terminal.
///
/// A request is handed to the kernel and not waited for: no drain (`tcdrain`) after it, which would hold the
/// session until the bytes have left the wire (a session's reply deadline already counts from before the
/// write, and COMPAX adds the time on the wire itself), and on unix one `write` with no poll before it. The
/// kernel sends what it was given, also when the port is closed right after (a last stop command).
pub struct SerialLink {
    port: Box<dyn serialport::SerialPort>,
    /// The port's file descriptor (unix, where the port was opened here): requests are written to it directly.
    #[cfg(unix)]
    fd: Option<std::os::fd::RawFd>,
    name: String,
}

impl std::fmt::Debug for SerialLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialLink").field("name", &self.name).finish()
    }
}

impl SerialLink {
    /// Opens `path` (`/dev/ttyUSB0`, `COM3`) with `settings`: 8 data bits, 1 stop bit, no flow control, and
    /// DTR and RTS switched on if asked for (they stay on while the port is open).
    ///
    /// A pseudo-terminal cannot drive modem lines; failing to set them is a warning on a real port and a debug
    /// message on a pty, never an error (a unit that needs them will not answer, which says more).
    pub fn open(path: &str, settings: SerialSettings) -> Result<Self, LinkError> {
        let parity = match settings.parity {
            Parity::None => serialport::Parity::None,
            Parity::Even => serialport::Parity::Even,
            Parity::Odd => serialport::Parity::Odd,
        };
        let port = serialport::new(path, settings.baud_rate)
            .data_bits(serialport::DataBits::Eight)
            .stop_bits(serialport::StopBits::One)
            .parity(parity)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100));
        let open_err = |e: serialport::Error| LinkError::Open { port: path.to_string(), reason: e.to_string() };
        #[cfg(unix)]
        let (mut port, fd) = {
            use std::os::fd::AsRawFd;
            let native = port.open_native().map_err(open_err)?;
            let fd = native.as_raw_fd();
            (Box::new(native) as Box<dyn serialport::SerialPort>, Some(fd))
        };
        #[cfg(not(unix))]
        let mut port = port.open().map_err(open_err)?;
        if settings.dtr_rts_on {
            let dtr = port.write_data_terminal_ready(true);
            let rts = port.write_request_to_send(true);
            if let Err(e) = dtr.and(rts) {
                if path.starts_with("/dev/pts/") {
                    tracing::debug!("{path}: a pseudo-terminal has no DTR and RTS ({e})");
                } else {
                    tracing::warn!(
                        "{path}: could not switch DTR and RTS on ({e}); a device powered by them will not answer"
                    );
                }
            }
        }
        let _ = port.clear(serialport::ClearBuffer::All);
        Ok(SerialLink {
            port,
            #[cfg(unix)]
            fd,
            name: path.to_string(),
        })
    }

    /// Wraps an already open port.
    pub fn from_port(port: Box<dyn serialport::SerialPort>, name: impl Into<String>) -> Self {
        SerialLink {
            port,
            #[cfg(unix)]
            fd: None,
            name: name.into(),
        }
    }

    /// Wraps an open terminal (unix): requests are written to its file descriptor directly.
    #[cfg(unix)]
    pub fn from_tty(port: serialport::TTYPort, name: impl Into<String>) -> Self {
        use std::os::fd::AsRawFd;
        let fd = Some(port.as_raw_fd());
        SerialLink { port: Box::new(port), fd, name: name.into() }
    }
}

/// Writes `bytes` with `write(2)` on `fd`, a terminal the caller owns and keeps open during the call; what is
/// left when the descriptor would block (the caller then writes it through the port, which waits until it can).
#[cfg(unix)]
pub(crate) fn write_fd(fd: std::os::fd::RawFd, mut bytes: &[u8]) -> std::io::Result<&[u8]> {
    while !bytes.is_empty() {
        // SAFETY: `fd` is open for the whole call (the caller's promise), and the pointer and length are those
        // of a live slice.
        let n = unsafe { libc::write(fd, bytes.as_ptr().cast(), bytes.len()) };
        if n < 0 {
            let e = std::io::Error::last_os_error();
            match e.kind() {
                ErrorKind::Interrupted => continue,
                ErrorKind::WouldBlock => return Ok(bytes),
                _ => return Err(e),
            }
        }
        bytes = &bytes[n.unsigned_abs()..];
    }
    Ok(bytes)
}

impl Link for SerialLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        #[cfg(unix)]
        let bytes = match self.fd {
            Some(fd) => write_fd(fd, bytes).map_err(|e| LinkError::from_io(&self.name, e))?,
            None => bytes,
        };
        self.port.write_all(bytes).map_err(|e| LinkError::from_io(&self.name, e))
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        self.port.set_timeout(timeout).map_err(|e| LinkError::from_io(&self.name, e.into()))?;
        match self.port.read(buf) {
            Ok(0) => Err(LinkError::Disconnected { port: self.name.clone(), reason: "end of stream".into() }),
            Ok(n) => Ok(n),
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) => Ok(0),
            Err(e) => Err(LinkError::from_io(&self.name, e)),
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.port.clear(serialport::ClearBuffer::Input).map_err(|e| LinkError::from_io(&self.name, e.into()))
    }

    fn send_break(&mut self, duration: Duration) -> Result<(), LinkError> {
        self.port.set_break().map_err(|e| LinkError::from_io(&self.name, e.into()))?;
        std::thread::sleep(duration);
        self.port.clear_break().map_err(|e| LinkError::from_io(&self.name, e.into()))
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// A connected pseudo-terminal pair for tests: the `master` end as a link, and the path of the other end,
/// which a client opens like a serial port.
#[cfg(unix)]
pub fn pty_pair() -> Result<(SerialLink, String), LinkError> {
    let open_err = |e: serialport::Error| LinkError::Open { port: "pty".into(), reason: e.to_string() };
    let (master, slave) = serialport::TTYPort::pair().map_err(open_err)?;
    let path = serialport::SerialPort::name(&slave)
        .ok_or_else(|| LinkError::Open { port: "pty".into(), reason: "no device path".into() })?;
    // The slave handle is closed here; the master stays usable once a client opens the path.
    drop(slave);
    Ok((SerialLink::from_port(Box::new(master), format!("pty master of {path}")), path))
}
