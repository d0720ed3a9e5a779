//! TCP links: a serial-over-TCP gateway (ser2net and the like) or motionlink's own emulator server.

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use crate::link::{Link, LinkError};

/// How long [`TcpLink::connect`] waits for a connection.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// How long a send may wait for room in the connection (a peer that stopped reading): then it fails with a
/// timeout instead of blocking its caller, and the session's close, for ever.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// A TCP connection carrying a device's byte stream.
#[derive(Debug)]
pub struct TcpLink {
    stream: TcpStream,
    name: String,
}

impl TcpLink {
    /// Connects to `host:port`.
    pub fn connect(host: &str, port: u16) -> Result<Self, LinkError> {
        let name = format!("tcp://{host}:{port}");
        let open_err = |reason: String| LinkError::Open { port: name.clone(), reason };
        let addrs = (host, port).to_socket_addrs().map_err(|e| open_err(e.to_string()))?;
        let mut last = None;
        for addr in addrs {
            match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
                Ok(stream) => {
                    stream.set_nodelay(true).map_err(|e| open_err(e.to_string()))?;
                    stream.set_write_timeout(Some(WRITE_TIMEOUT)).map_err(|e| open_err(e.to_string()))?;
                    return Ok(TcpLink { stream, name });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(open_err(last.map_or_else(|| "host has no address".to_string(), |e| e.to_string())))
    }
}

impl Link for TcpLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.stream.write_all(bytes).map_err(|e| LinkError::from_io(&self.name, e))
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        if timeout.is_zero() {
            // Only what has arrived: a non-blocking read. (The shortest socket timeout is a whole kernel
            // tick, 4 to 10 ms, which a client that looks for late bytes before every request would pay on
            // every exchange.)
            self.stream.set_nonblocking(true).map_err(|e| LinkError::from_io(&self.name, e))?;
            let r = self.stream.read(buf);
            self.stream.set_nonblocking(false).map_err(|e| LinkError::from_io(&self.name, e))?;
            return match r {
                Ok(0) => Err(LinkError::Disconnected { port: self.name.clone(), reason: "closed by peer".into() }),
                Ok(n) => Ok(n),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::Interrupted) => Ok(0),
                Err(e) => Err(LinkError::from_io(&self.name, e)),
            };
        }
        // A zero read timeout means "block forever" to the OS; the shortest real wait stands in for it.
        self.stream
            .set_read_timeout(Some(timeout.max(Duration::from_micros(1))))
            .map_err(|e| LinkError::from_io(&self.name, e))?;
        match self.stream.read(buf) {
            Ok(0) => Err(LinkError::Disconnected { port: self.name.clone(), reason: "closed by peer".into() }),
            Ok(n) => Ok(n),
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) => Ok(0),
            Err(e) => Err(LinkError::from_io(&self.name, e)),
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.stream.set_nonblocking(true).map_err(|e| LinkError::from_io(&self.name, e))?;
        let mut buf = [0u8; 512];
        let result = loop {
            match self.stream.read(&mut buf) {
                Ok(0) => {
                    break Err(LinkError::Disconnected { port: self.name.clone(), reason: "closed by peer".into() })
                }
                Ok(_) => continue,
                Err(e) if e.kind() == ErrorKind::WouldBlock => break Ok(()),
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => break Err(LinkError::from_io(&self.name, e)),
            }
        };
        self.stream.set_nonblocking(false).map_err(|e| LinkError::from_io(&self.name, e))?;
        result
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}
