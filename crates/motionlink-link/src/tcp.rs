//! TCP links: a serial-over-TCP gateway (ser2net and the like) or motionlink's own emulator server.

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use crate::emulator::BUSY_PREFIX;
use crate::link::{Link, LinkError};

/// How long [`TcpLink::connect`] waits for a connection.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// How long a send may wait for room in the connection (a peer that stopped reading): then it fails with a
/// timeout instead of blocking its caller, and the session's close, for ever.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// A TCP connection carrying a device's byte stream.
///
/// A connection that a busy `motionlink sim` server refuses starts with [`BUSY_PREFIX`]: the link reports
/// [`LinkError::Busy`] instead of handing those bytes on as the device's. To know them, it holds back the
/// first bytes of a connection as long as they are a beginning of that prefix (a device's first byte is
/// never `m`, so in practice nothing is held).
#[derive(Debug)]
pub struct TcpLink {
    stream: TcpStream,
    name: String,
    /// The first bytes of the connection while they may still be the busy server's refusal; `None` once
    /// they cannot be.
    greeting: Option<Vec<u8>>,
    /// Bytes that were held back by that check and are still to be handed out.
    held: Vec<u8>,
}

/// What the first bytes of a connection are, so far.
enum Greeting {
    /// The busy server's refusal.
    Refusal,
    /// Perhaps the refusal: more bytes decide.
    Undecided,
    /// The device's bytes.
    Device,
}

fn greeting(seen: &[u8]) -> Greeting {
    let prefix = BUSY_PREFIX.as_bytes();
    let n = seen.len().min(prefix.len());
    if seen[..n] != prefix[..n] {
        Greeting::Device
    } else if n == prefix.len() {
        Greeting::Refusal
    } else {
        Greeting::Undecided
    }
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
                    return Ok(TcpLink { stream, name, greeting: Some(Vec::new()), held: Vec::new() });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(open_err(last.map_or_else(|| "host has no address".to_string(), |e| e.to_string())))
    }
}

impl TcpLink {
    /// Passes `fresh` (bytes just read) through the check of the connection's first bytes: how many bytes
    /// are now in `buf` for the caller (`fresh` is `buf[..n]`), or the busy server's refusal.
    fn check_greeting(&mut self, buf: &mut [u8], n: usize) -> Result<usize, LinkError> {
        let Some(seen) = self.greeting.as_mut() else { return Ok(n) };
        seen.extend_from_slice(&buf[..n]);
        match greeting(seen) {
            Greeting::Refusal => {
                self.greeting = None;
                Err(LinkError::Busy { port: self.name.clone() })
            }
            Greeting::Undecided => Ok(0),
            Greeting::Device => {
                self.held = self.greeting.take().unwrap_or_default();
                Ok(self.take_held(buf))
            }
        }
    }

    /// Moves held-back bytes into `buf`: how many.
    fn take_held(&mut self, buf: &mut [u8]) -> usize {
        let n = self.held.len().min(buf.len());
        buf[..n].copy_from_slice(&self.held[..n]);
        self.held.drain(..n);
        n
    }

    /// One read of the socket, as [`Link::recv`] (without the check of the first bytes).
    fn read_socket(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
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
}

impl Link for TcpLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.stream.write_all(bytes).map_err(|e| LinkError::from_io(&self.name, e))
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        if !self.held.is_empty() {
            return Ok(self.take_held(buf));
        }
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let n = self.read_socket(buf, left)?;
            if n == 0 {
                return Ok(0);
            }
            match self.check_greeting(buf, n)? {
                // The first bytes may still be the refusal: wait for more, within the time given.
                0 if !left.is_zero() => continue,
                given => return Ok(given),
            }
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.held.clear();
        self.stream.set_nonblocking(true).map_err(|e| LinkError::from_io(&self.name, e))?;
        let mut buf = [0u8; 512];
        let result = loop {
            match self.stream.read(&mut buf) {
                Ok(0) => {
                    break Err(LinkError::Disconnected { port: self.name.clone(), reason: "closed by peer".into() })
                }
                // Dropped, but a connection's first bytes are still looked at: a refusal is no device's.
                Ok(n) => match self.check_greeting(&mut buf, n) {
                    Err(e) => break Err(e),
                    Ok(_) => self.held.clear(),
                },
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    const BUSY_BYTES: &[u8] = crate::emulator::BUSY_MESSAGE.as_bytes();

    /// A peer that sends `chunks` (one write each, a pause between them) and then closes; the link to it.
    fn peer_sending(chunks: &'static [&'static [u8]]) -> (TcpLink, std::thread::JoinHandle<()>) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let peer = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            s.set_nodelay(true).unwrap();
            for c in chunks {
                s.write_all(c).unwrap();
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        (TcpLink::connect("127.0.0.1", port).unwrap(), peer)
    }

    /// Everything the link hands out until the peer closes.
    fn all(link: &mut TcpLink) -> (Vec<u8>, LinkError) {
        let mut got = Vec::new();
        let mut buf = [0u8; 4];
        loop {
            match link.recv(&mut buf, Duration::from_secs(2)) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) => return (got, e),
            }
        }
    }

    #[test]
    fn bytes_that_only_begin_like_the_refusal_are_the_devices_in_full() {
        let (mut link, peer) = peer_sending(&[b"motionlink s", b"imulated\n", b"next"]);
        let (got, end) = all(&mut link);
        assert_eq!(got, b"motionlink simulated\nnext");
        assert!(matches!(end, LinkError::Disconnected { .. }), "{end}");
        peer.join().unwrap();
        let (mut link, peer) = peer_sending(&[b"\x52\x4f\x06\x9a\x4d"]);
        assert_eq!(all(&mut link).0, b"\x52\x4f\x06\x9a\x4d");
        peer.join().unwrap();
    }

    #[test]
    fn the_refusal_is_known_in_pieces_and_in_what_is_discarded() {
        let (mut link, peer) = peer_sending(&[b"motionlink sim", b": busy: another client is connected\n"]);
        let (got, end) = all(&mut link);
        assert!(got.is_empty() && matches!(end, LinkError::Busy { .. }), "{got:?} {end}");
        peer.join().unwrap();
        let (mut link, peer) = peer_sending(&[BUSY_BYTES]);
        std::thread::sleep(Duration::from_millis(100));
        assert!(matches!(link.discard_input(), Err(LinkError::Busy { .. })));
        peer.join().unwrap();
    }
}
