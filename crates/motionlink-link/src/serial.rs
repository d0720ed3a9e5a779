//! Serial ports through the `serialport` crate (built without system libraries), and pseudo-terminal pairs
//! for tests.

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use crate::link::{Link, LinkError, Parity, SerialSettings};

/// A serial port: a USB adapter, an on-board UART, or one side of a pseudo-terminal.
pub struct SerialLink {
    port: Box<dyn serialport::SerialPort>,
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
        let mut port = serialport::new(path, settings.baud_rate)
            .data_bits(serialport::DataBits::Eight)
            .stop_bits(serialport::StopBits::One)
            .parity(parity)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| LinkError::Open { port: path.to_string(), reason: e.to_string() })?;
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
        Ok(SerialLink { port, name: path.to_string() })
    }

    /// Wraps an already open port.
    pub fn from_port(port: Box<dyn serialport::SerialPort>, name: impl Into<String>) -> Self {
        SerialLink { port, name: name.into() }
    }
}

impl Link for SerialLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.port.write_all(bytes).and_then(|_| self.port.flush()).map_err(|e| LinkError::from_io(&self.name, e))
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
