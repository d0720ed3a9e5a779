//! The [`Emulator`] trait every device emulator implements, and the loops that serve one over TCP or a pty.
//!
//! An emulator is sans-IO: it is handed bytes with the time they arrived and answers with bytes; it never
//! reads a clock or sleeps. The same emulator runs in-process behind an
//! [`EmulatorLink`](crate::pipe::EmulatorLink), or behind a socket or pseudo-terminal served here.

use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use crate::clock::{lock, SharedClock, Timestamp};

/// A device emulator as a state machine: bytes in, time passing, bytes out.
pub trait Emulator: Send {
    /// Bytes arrived at `now` (never earlier than a previous call's time). Append the device's answer to
    /// `out`.
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>);

    /// Time has reached `now` with nothing received: run timers and the physical model. Append anything the
    /// device says by itself to `out`.
    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>);

    /// The next time at which [`Emulator::advance`] would do something observable (a timer, a message the
    /// device sends unasked), or `None`.
    fn next_wakeup(&self) -> Option<Timestamp>;
}

impl<E: Emulator + ?Sized> Emulator for Box<E> {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        (**self).receive(now, bytes, out)
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        (**self).advance(now, out)
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        (**self).next_wakeup()
    }
}

/// How often a serve loop looks at the device when nothing arrives.
const IDLE_POLL: Duration = Duration::from_millis(10);

/// A byte stream a serve loop can use.
trait Stream: Read + Write {
    fn set_wait(&mut self, wait: Duration) -> std::io::Result<()>;
}

impl Stream for TcpStream {
    fn set_wait(&mut self, wait: Duration) -> std::io::Result<()> {
        self.set_read_timeout(Some(wait.max(Duration::from_micros(100))))
    }
}

struct SerialStream(Box<dyn serialport::SerialPort>);

impl Read for SerialStream {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for SerialStream {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

impl Stream for SerialStream {
    fn set_wait(&mut self, wait: Duration) -> std::io::Result<()> {
        self.0.set_timeout(wait).map_err(std::io::Error::from)
    }
}

/// Serves `device` on one connected stream until the peer closes it or `stop` is set.
fn serve_stream<E: Emulator>(
    stream: &mut dyn Stream,
    device: &Mutex<E>,
    clock: &SharedClock,
    stop: &AtomicBool,
    end_of_stream_is_close: bool,
) -> std::io::Result<()> {
    let mut buf = [0u8; 4096];
    let mut out = Vec::with_capacity(4096);
    while !stop.load(Ordering::Relaxed) {
        let wait = {
            let dev = lock(device);
            let now = clock.now();
            dev.next_wakeup().map_or(IDLE_POLL, |t| t.saturating_since(now).min(IDLE_POLL))
        };
        stream.set_wait(wait)?;
        let n = match stream.read(&mut buf) {
            Ok(0) if end_of_stream_is_close => return Ok(()),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) => 0,
            Err(e) if e.raw_os_error() == Some(5) && !end_of_stream_is_close => {
                // EIO on a pty master: no client has the other side open. Wait for one.
                thread::sleep(IDLE_POLL);
                0
            }
            Err(e) if matches!(e.kind(), ErrorKind::ConnectionReset | ErrorKind::BrokenPipe) => return Ok(()),
            Err(e) => return Err(e),
        };
        out.clear();
        {
            let mut dev = lock(device);
            let now = clock.now();
            if n > 0 {
                dev.receive(now, &buf[..n], &mut out);
            }
            dev.advance(now, &mut out);
        }
        if !out.is_empty() {
            match stream.write_all(&out).and_then(|_| stream.flush()) {
                Ok(()) => {}
                Err(e) if end_of_stream_is_close => {
                    tracing::debug!("client went away while writing: {e}");
                    return Ok(());
                }
                Err(e) => tracing::debug!("write to pty failed (no client?): {e}"),
            }
        }
    }
    Ok(())
}

/// A running emulator server; stops (and joins its thread) when dropped.
pub struct Server {
    address: String,
    stop: Arc<AtomicBool>,
    thread: Option<thread::JoinHandle<()>>,
}

impl std::fmt::Debug for Server {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Server").field("address", &self.address).finish()
    }
}

impl Server {
    /// Where clients connect: `tcp://127.0.0.1:PORT` or the pty's device path.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// Blocks until the server stops (it does not by itself; for `motionlink sim`, which runs until killed).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Serves `device` over TCP at `bind` (such as `127.0.0.1:0`), one client at a time, accepting a new client
/// after the previous one closed. The device keeps its state across connections, as a real one would.
pub fn serve_tcp<E: Emulator + 'static>(
    bind: &str,
    device: Arc<Mutex<E>>,
    clock: SharedClock,
) -> std::io::Result<Server> {
    let listener = TcpListener::bind(bind)?;
    let address = format!("tcp://{}", listener.local_addr()?);
    listener.set_nonblocking(true)?;
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let thread = thread::Builder::new().name("emulator-tcp".into()).spawn(move || {
        let mut out = Vec::new();
        while !stop2.load(Ordering::Relaxed) {
            match listener.accept() {
                Ok((mut stream, peer)) => {
                    tracing::info!("client connected from {peer}");
                    let _ = stream.set_nonblocking(false);
                    let _ = stream.set_nodelay(true);
                    if let Err(e) = serve_stream(&mut stream, &device, &clock, &stop2, true) {
                        tracing::warn!("connection from {peer} ended: {e}");
                    } else {
                        tracing::info!("client {peer} disconnected");
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    // Keep the device's time moving while nobody is connected (its watchdog, its motion).
                    out.clear();
                    lock(&device).advance(clock.now(), &mut out);
                    thread::sleep(IDLE_POLL);
                }
                Err(e) => {
                    tracing::warn!("accept failed: {e}");
                    thread::sleep(IDLE_POLL);
                }
            }
        }
    })?;
    Ok(Server { address, stop, thread: Some(thread) })
}

/// Serves `device` on a new pseudo-terminal. [`Server::address`] is the device path (`/dev/pts/N`) that a
/// client opens as if it were a serial port. Clients may close and reopen it.
#[cfg(unix)]
pub fn serve_pty<E: Emulator + 'static>(device: Arc<Mutex<E>>, clock: SharedClock) -> std::io::Result<Server> {
    let (master, slave) = serialport::TTYPort::pair().map_err(std::io::Error::from)?;
    let address = serialport::SerialPort::name(&slave)
        .ok_or_else(|| std::io::Error::other("the pseudo-terminal has no device path"))?;
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let thread = thread::Builder::new().name("emulator-pty".into()).spawn(move || {
        // Holding the slave side open keeps the master readable between clients.
        let _keep_open = slave;
        let mut stream = SerialStream(Box::new(master));
        if let Err(e) = serve_stream(&mut stream, &device, &clock, &stop2, false) {
            tracing::error!("pty server stopped: {e}");
        }
    })?;
    Ok(Server { address, stop, thread: Some(thread) })
}
