//! The [`Emulator`] trait every device emulator implements, and the loops that serve one over TCP or a pty.
//!
//! An emulator is sans-IO: it is handed bytes with the time they arrived and answers with bytes; it never
//! reads a clock or sleeps. The same emulator runs in-process behind an
//! [`EmulatorLink`](crate::pipe::EmulatorLink), or behind a socket or pseudo-terminal served here.

use std::any::Any;
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread;
use std::time::Duration;

use crate::clock::{SharedClock, Timestamp};

/// A device emulator as a state machine: bytes in, time passing, bytes out.
pub trait Emulator: Send {
    /// Bytes arrived at `now` (never earlier than a previous call's time). Append the device's answer to
    /// `out`.
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>);

    /// Time has reached `now` with nothing received: run timers and the physical model. Append anything the
    /// device says by itself to `out`.
    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>);

    /// The next time at which [`Emulator::advance`] would do something observable (a timer, a message the
    /// device sends unasked, the end of a motion), or `None`.
    fn next_wakeup(&self) -> Option<Timestamp>;

    /// The host's connection ended at `now` (a TCP client closed its socket): a telegram received in part is
    /// discarded, so that it cannot be completed by the bytes of the next connection. Everything else the
    /// device holds (its state, its motion, its watchdog) goes on as on a real device whose cable was
    /// pulled.
    fn connection_closed(&mut self, now: Timestamp);

    /// What the device did since the last call that a test or an operator watching `motionlink sim
    /// --events` wants to see (a motion started, an axis came to rest, a watchdog halted the drives), one
    /// line of text each, oldest first. A device without such changes returns nothing.
    fn take_events(&mut self) -> Vec<String> {
        Vec::new()
    }

    /// The host held the line at "space" (a break) from `now` for `duration`
    /// ([`Link::send_break`](crate::link::Link::send_break)). A device that gives a break no meaning ignores
    /// it (the default).
    fn line_break(&mut self, now: Timestamp, duration: std::time::Duration) {
        let _ = (now, duration);
    }
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
    fn connection_closed(&mut self, now: Timestamp) {
        (**self).connection_closed(now)
    }
    fn take_events(&mut self) -> Vec<String> {
        (**self).take_events()
    }
    fn line_break(&mut self, now: Timestamp, duration: std::time::Duration) {
        (**self).line_break(now, duration)
    }
}

/// The device's events with the time each happened, as a host that runs the device lazily (an
/// [`EmulatorHost`](crate::pipe::EmulatorHost), a [`CanBus`](crate::can::CanBus)) keeps them once asked
/// to: after each step of the device (a byte or frame received, a timer fired) its events are taken, at
/// that step's time. At most [`TimedEvents::MOST`] are kept (the oldest go first).
#[derive(Debug, Default)]
pub(crate) struct TimedEvents {
    keep: bool,
    list: std::collections::VecDeque<(Timestamp, String)>,
}

impl TimedEvents {
    /// How many events are kept for a caller that does not take them.
    pub(crate) const MOST: usize = 1000;

    /// From now on the events are taken after each step.
    pub(crate) fn keep(&mut self) {
        self.keep = true;
    }

    /// Where events are kept, those the device produced at `t` (`take`: its `take_events`).
    pub(crate) fn collect(&mut self, t: Timestamp, take: impl FnOnce() -> Vec<String>) {
        if !self.keep {
            return;
        }
        for e in take() {
            if self.list.len() == Self::MOST {
                self.list.pop_front();
            }
            self.list.push_back((t, e));
        }
    }

    /// The events kept, oldest first.
    pub(crate) fn take(&mut self) -> Vec<(Timestamp, String)> {
        self.list.drain(..).collect()
    }
}

/// Where a server reports the device's events ([`Emulator::take_events`]); called on the serving thread
/// right after the device produced them.
pub type EventSink = Arc<dyn Fn(&str) + Send + Sync>;

/// Options of [`serve_tcp_with`] and [`serve_pty_with`].
#[derive(Clone, Default)]
pub struct ServeOptions {
    /// Receives each of the device's events as it happens; `None` drops them.
    pub on_event: Option<EventSink>,
}

impl std::fmt::Debug for ServeOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServeOptions").field("on_event", &self.on_event.is_some()).finish()
    }
}

/// The line a TCP server writes to a second client before it closes that connection. It starts with
/// [`BUSY_PREFIX`], by which a client ([`crate::tcp::TcpLink`]) knows the refusal.
pub const BUSY_MESSAGE: &str = "motionlink sim: busy: another client is connected; this connection is closed\n";

/// The first bytes of [`BUSY_MESSAGE`]: a connection whose first bytes are these was refused by a busy
/// server ([`crate::LinkError::Busy`]). No device of the families sends them.
pub const BUSY_PREFIX: &str = "motionlink sim: busy:";

const _: () = assert!(BUSY_MESSAGE.len() > BUSY_PREFIX.len());

/// How long a refused connection is read (and what it sent dropped) after the refusal, waiting for the
/// client to close it: a socket closed with unread input is reset, and a reset may reach the client before
/// it has read the refusal.
const REFUSAL_DRAIN: Duration = Duration::from_secs(2);

/// Refuses `stream`: [`BUSY_MESSAGE`], the end of the server's side, then what the client sends is read and
/// dropped (on a thread of its own, for at most [`REFUSAL_DRAIN`]) until it closes its side.
fn refuse(mut stream: TcpStream) {
    let _ = stream.write_all(BUSY_MESSAGE.as_bytes());
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let drained = thread::Builder::new().name("emulator-refuse".into()).spawn(move || {
        let deadline = std::time::Instant::now() + REFUSAL_DRAIN;
        let mut buf = [0u8; 256];
        while let Some(left) = deadline.checked_duration_since(std::time::Instant::now()) {
            if stream.set_read_timeout(Some(left.max(Duration::from_millis(1)))).is_err() {
                return;
            }
            match stream.read(&mut buf) {
                Ok(0) | Err(_) => return,
                Ok(_) => {}
            }
        }
    });
    if let Err(e) = drained {
        tracing::warn!("cannot start the thread that ends a refused connection: {e}");
    }
}

/// How often a serve loop looks at the device when nothing arrives and the device has no timer due: it
/// bounds how late a motion model's end is seen, and how long a stopping server takes to notice.
const IDLE_POLL: Duration = Duration::from_millis(10);

/// How long the TCP server waits for a client while the device has no timer due.
const IDLE_WAIT: Duration = Duration::from_millis(50);

/// A byte stream a serve loop can use.
trait Stream: Read + Write {
    fn set_wait(&mut self, wait: Duration) -> std::io::Result<()>;
}

impl Stream for TcpStream {
    fn set_wait(&mut self, wait: Duration) -> std::io::Result<()> {
        self.set_read_timeout(Some(wait.max(Duration::from_micros(100))))
    }
}

#[cfg(unix)]
struct SerialStream(serialport::TTYPort);

#[cfg(unix)]
impl Read for SerialStream {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

#[cfg(unix)]
impl Write for SerialStream {
    /// One `write(2)` on the pty's descriptor, no poll before it (see [`SerialLink`](crate::serial::SerialLink)).
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        use std::os::fd::AsRawFd;
        let left = crate::serial::write_fd(self.0.as_raw_fd(), buf)?;
        match left.len() {
            n if n == buf.len() => self.0.write(buf),
            n => Ok(buf.len() - n),
        }
    }
    /// Nothing to wait for: the emulator's answer is in the pty once written (a drain, `tcdrain`, would
    /// cost the round trip a system call for nothing).
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[cfg(unix)]
impl Stream for SerialStream {
    fn set_wait(&mut self, wait: Duration) -> std::io::Result<()> {
        serialport::SerialPort::set_timeout(&mut self.0, wait).map_err(std::io::Error::from)
    }
}

/// Hands the device's events to the sink, if there is one.
fn report_events<E: Emulator + ?Sized>(device: &mut E, options: &ServeOptions) {
    let events = device.take_events();
    if let Some(sink) = &options.on_event {
        for e in &events {
            sink(e);
        }
    }
}

/// The served device, locked. A lock poisoned by a panic (of the device, or of another thread that held it)
/// guards a device its panic may have left half-changed: serving it on would answer clients with what a
/// broken emulator makes of that, so the panic is passed on, and the server ends ([`crashed`]).
fn lock_device<E: ?Sized>(device: &Mutex<E>) -> MutexGuard<'_, E> {
    match device.lock() {
        Ok(guard) => guard,
        Err(_) => panic!("the emulated device's lock is poisoned: a thread panicked while it held the device"),
    }
}

/// The text of a panic's payload.
fn panic_text(payload: &(dyn Any + Send)) -> &str {
    match (payload.downcast_ref::<&str>(), payload.downcast_ref::<String>()) {
        (Some(text), _) => text,
        (None, Some(text)) => text,
        (None, None) => "a panic without a message",
    }
}

/// Reports that the device (or the event sink) panicked and the server ended: an error in the log, and an
/// event (`the emulator crashed (...)`) to the sink, so that an operator watching `motionlink sim --events`
/// and a Python host see it. The thread then passes the panic on, for [`Server::wait`].
fn crashed(payload: &(dyn Any + Send), options: &ServeOptions) {
    let text =
        format!("the emulator crashed ({}); the server has stopped and serves no client any more", panic_text(payload));
    tracing::error!("{text}");
    if let Some(sink) = &options.on_event {
        // The sink may be what panicked: a second panic of it is not passed on, the first one is.
        let _ = std::panic::catch_unwind(AssertUnwindSafe(|| sink(&text)));
    }
}

/// Serves `device` on one connected stream until the peer closes it or `stop` is set.
fn serve_stream<E: Emulator>(
    stream: &mut dyn Stream,
    device: &Mutex<E>,
    clock: &SharedClock,
    stop: &AtomicBool,
    end_of_stream_is_close: bool,
    options: &ServeOptions,
) -> std::io::Result<()> {
    let mut buf = [0u8; 4096];
    let mut out = Vec::with_capacity(4096);
    while !stop.load(Ordering::Relaxed) {
        let wait = {
            let dev = lock_device(device);
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
            let mut dev = lock_device(device);
            let now = clock.now();
            if n > 0 {
                dev.receive(now, &buf[..n], &mut out);
            }
            dev.advance(now, &mut out);
            report_events(&mut *dev, options);
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

/// A running emulator server; stops (and joins its threads) when dropped.
pub struct Server {
    address: String,
    stop: Arc<AtomicBool>,
    /// A TCP server's own address, connected to once on drop to wake its blocking `accept`.
    wake: Option<std::net::SocketAddr>,
    threads: Vec<thread::JoinHandle<()>>,
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

    /// Blocks until the server stops. It does not by itself (for `motionlink sim`, which runs until killed),
    /// unless the device panicked: that ends the server (its clients' connections close, later ones find no
    /// server, and an event says so), and the panic is passed on here, so that a process that serves until
    /// the server ends does not end as if all were well (`motionlink sim` exits with 101 after the panic's
    /// message).
    pub fn wait(mut self) {
        let mut panicked = None;
        for t in self.threads.drain(..) {
            if let Err(payload) = t.join() {
                panicked.get_or_insert(payload);
            }
        }
        if let Some(payload) = panicked {
            std::panic::resume_unwind(payload);
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(addr) = self.wake {
            let _ = TcpStream::connect_timeout(&addr, Duration::from_secs(1));
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// How long a new TCP connection waits, when another client is being served, for that client's closed
/// connection to be noticed before it is refused: a command that runs right after another one (a script,
/// a test) connects a moment after the previous process closed its socket.
const BUSY_GRACE: Duration = Duration::from_millis(100);

/// Waits up to [`BUSY_GRACE`] for the client being served to turn out gone (`busy` cleared by the serving
/// thread), and takes the slot if it does. False if it is still connected.
fn previous_client_gone(busy: &AtomicBool) -> bool {
    let deadline = std::time::Instant::now() + BUSY_GRACE;
    while std::time::Instant::now() < deadline {
        if !busy.swap(true, Ordering::SeqCst) {
            return true;
        }
        thread::sleep(Duration::from_millis(1));
    }
    false
}

/// Serves `device` over TCP at `bind` (such as `127.0.0.1:0`); see [`serve_tcp_with`].
pub fn serve_tcp<E: Emulator + 'static>(
    bind: &str,
    device: Arc<Mutex<E>>,
    clock: SharedClock,
) -> std::io::Result<Server> {
    serve_tcp_with(bind, device, clock, ServeOptions::default())
}

/// Serves `device` over TCP at `bind` (such as `127.0.0.1:0`), one client at a time, as a serial-over-TCP
/// gateway does: a client that connects while another is served gets the one line [`BUSY_MESSAGE`] and is
/// closed (after at most 100 ms in which the other client's closing connection may still be noticed); a new client is accepted as soon as the previous one closed. The device keeps its state
/// across connections, as a real one would, and its time runs on between them (its watchdog, its motion);
/// a telegram left incomplete by a closed connection is discarded ([`Emulator::connection_closed`]).
///
/// A connection is accepted, and a request answered, as soon as it arrives: the accepting thread blocks in
/// `accept`, the serving thread in a read whose timeout is the device's next wake-up.
///
/// A panic of the device (or of the event sink) ends the server: the client's connection closes, the port
/// is closed (a later client's connection is refused, rather than told another client is connected), an
/// event says the emulator crashed, and [`Server::wait`] passes the panic on. A device whose lock is
/// poisoned is not served on.
pub fn serve_tcp_with<E: Emulator + 'static>(
    bind: &str,
    device: Arc<Mutex<E>>,
    clock: SharedClock,
    options: ServeOptions,
) -> std::io::Result<Server> {
    let listener = TcpListener::bind(bind)?;
    let local = listener.local_addr()?;
    let address = format!("tcp://{local}");
    let wake = if local.ip().is_unspecified() {
        std::net::SocketAddr::new(
            if local.is_ipv4() { std::net::Ipv4Addr::LOCALHOST.into() } else { std::net::Ipv6Addr::LOCALHOST.into() },
            local.port(),
        )
    } else {
        local
    };
    let stop = Arc::new(AtomicBool::new(false));
    let busy = Arc::new(AtomicBool::new(false));
    let (tx, rx) = std::sync::mpsc::channel::<(TcpStream, std::net::SocketAddr)>();

    let (accept_stop, accept_busy) = (Arc::clone(&stop), Arc::clone(&busy));
    let acceptor = thread::Builder::new().name("emulator-accept".into()).spawn(move || loop {
        let accepted = listener.accept();
        if accept_stop.load(Ordering::SeqCst) {
            return;
        }
        match accepted {
            Ok((stream, peer)) => {
                if accept_busy.swap(true, Ordering::SeqCst) && !previous_client_gone(&accept_busy) {
                    tracing::info!("refused {peer}: another client is connected");
                    refuse(stream);
                    continue;
                }
                if tx.send((stream, peer)).is_err() {
                    return;
                }
            }
            Err(e) => {
                tracing::warn!("accept failed: {e}");
                thread::sleep(IDLE_POLL);
            }
        }
    })?;

    let serve_stop = Arc::clone(&stop);
    let server = thread::Builder::new().name("emulator-tcp".into()).spawn(move || {
        let served = std::panic::catch_unwind(AssertUnwindSafe(|| {
            serve_clients(&device, &clock, &serve_stop, &busy, &rx, &options)
        }));
        if let Err(payload) = served {
            // The server ends: the acceptor is woken to stop (and close the port), and the slot is freed, so
            // that a client that connects meanwhile is closed rather than told another one is connected.
            serve_stop.store(true, Ordering::SeqCst);
            busy.store(false, Ordering::SeqCst);
            let _ = TcpStream::connect_timeout(&wake, Duration::from_secs(1));
            crashed(&*payload, &options);
            std::panic::resume_unwind(payload);
        }
    })?;
    Ok(Server { address, stop, wake: Some(wake), threads: vec![acceptor, server] })
}

/// The serving thread of [`serve_tcp_with`]: the clients the acceptor hands over (`accepted`), one after
/// the other, and the device's time between them, until `stop` is set.
fn serve_clients<E: Emulator>(
    device: &Mutex<E>,
    clock: &SharedClock,
    stop: &AtomicBool,
    busy: &AtomicBool,
    accepted: &std::sync::mpsc::Receiver<(TcpStream, std::net::SocketAddr)>,
    options: &ServeOptions,
) {
    let mut out = Vec::new();
    while !stop.load(Ordering::SeqCst) {
        // Keep the device's time moving while nobody is connected (its watchdog, its motion).
        let wait = {
            let mut dev = lock_device(device);
            let now = clock.now();
            out.clear();
            dev.advance(now, &mut out);
            report_events(&mut *dev, options);
            dev.next_wakeup()
                .map_or(IDLE_WAIT, |t| t.saturating_since(now).clamp(Duration::from_micros(100), IDLE_WAIT))
        };
        let (mut stream, peer) = match accepted.recv_timeout(wait) {
            Ok(accepted) => accepted,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return,
        };
        tracing::info!("client connected from {peer}");
        let _ = stream.set_nodelay(true);
        match serve_stream(&mut stream, device, clock, stop, true, options) {
            Ok(()) => tracing::info!("client {peer} disconnected"),
            Err(e) => tracing::warn!("connection from {peer} ended: {e}"),
        }
        {
            let mut dev = lock_device(device);
            dev.connection_closed(clock.now());
            report_events(&mut *dev, options);
        }
        busy.store(false, Ordering::SeqCst);
    }
}

/// Serves `device` on a new pseudo-terminal. [`Server::address`] is the device path (`/dev/pts/N`) that a
/// client opens as if it were a serial port. Clients may close and reopen it.
#[cfg(unix)]
pub fn serve_pty<E: Emulator + 'static>(device: Arc<Mutex<E>>, clock: SharedClock) -> std::io::Result<Server> {
    serve_pty_with(device, clock, ServeOptions::default())
}

/// [`serve_pty`] with options. A pseudo-terminal cannot tell when a client closes it, so a telegram left
/// incomplete is discarded only by the device's own inter-byte timeout, as on a serial line. A panic of the
/// device ends the server as [`serve_tcp_with`]'s does (the pseudo-terminal goes away).
#[cfg(unix)]
pub fn serve_pty_with<E: Emulator + 'static>(
    device: Arc<Mutex<E>>,
    clock: SharedClock,
    options: ServeOptions,
) -> std::io::Result<Server> {
    let (master, slave) = serialport::TTYPort::pair().map_err(std::io::Error::from)?;
    let address = serialport::SerialPort::name(&slave)
        .ok_or_else(|| std::io::Error::other("the pseudo-terminal has no device path"))?;
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = Arc::clone(&stop);
    let thread = thread::Builder::new().name("emulator-pty".into()).spawn(move || {
        // Holding the slave side open keeps the master readable between clients.
        let _keep_open = slave;
        let mut stream = SerialStream(master);
        let served = std::panic::catch_unwind(AssertUnwindSafe(|| {
            serve_stream(&mut stream, &device, &clock, &stop2, false, &options)
        }));
        match served {
            Ok(Ok(())) => {}
            Ok(Err(e)) => tracing::error!("pty server stopped: {e}"),
            Err(payload) => {
                stop2.store(true, Ordering::SeqCst);
                crashed(&*payload, &options);
                std::panic::resume_unwind(payload);
            }
        }
    })?;
    Ok(Server { address, stop, wake: None, threads: vec![thread] })
}

/// A firmware variant of a family's emulator: one behaviour the manual leaves open, done the other plausible
/// way (`motionlink sim FAMILY --variant NAME`, `variants = [...]` in the emulator's TOML, Python's
/// `Emulator(variants=...)`). Each family's `sim::Variant` implements it, so that every family names, parses
/// and refuses variants by the same rule and with the same message.
///
/// ```
/// use motionlink_link::emulator::FirmwareVariant;
/// #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
/// enum Echo { Bare, None }
/// impl FirmwareVariant for Echo {
///     const FAMILY: &'static str = "COMPAX";
///     const ALL: &'static [Echo] = &[Echo::Bare, Echo::None];
///     fn name(self) -> &'static str { ["echo-bare", "no-echo"][self as usize] }
///     fn description(self) -> &'static str { "" }
/// }
/// assert_eq!(Echo::named(" NO_ECHO "), Ok(Echo::None));
/// assert_eq!(Echo::list("no-echo, echo-bare,no-echo"), Ok(vec![Echo::Bare, Echo::None]));
/// assert_eq!(
///     Echo::named("echo").unwrap_err().to_string(),
///     "\"echo\" is not a variant of the COMPAX emulator (known: echo-bare, no-echo)"
/// );
/// ```
pub trait FirmwareVariant: Copy + Ord + Sized + 'static {
    /// The family, as messages name it ("SCU", "PowerCube", "COMPAX").
    const FAMILY: &'static str;
    /// Every variant, in the order the family's documentation lists them.
    const ALL: &'static [Self];

    /// The name the command line, the TOML configuration and Python take (`no-echo`).
    fn name(self) -> &'static str;

    /// What the device does differently, in one sentence.
    fn description(self) -> &'static str;

    /// The variant `text` names: in any case, with `_` for `-` (`no-echo`, `NO_ECHO`), blanks around it
    /// ignored.
    fn named(text: &str) -> Result<Self, UnknownVariant> {
        let text = text.trim();
        let found = Self::ALL.iter().copied().find(|&v| {
            let n = v.name();
            n.eq_ignore_ascii_case(text) || n.replace('-', "_").eq_ignore_ascii_case(text)
        });
        found.ok_or_else(|| UnknownVariant { family: Self::FAMILY, name: text.to_string(), known: Self::known() })
    }

    /// Names separated by commas (empty entries ignored), each once in the result, in the order of
    /// [`ALL`](Self::ALL).
    fn list(text: &str) -> Result<Vec<Self>, UnknownVariant> {
        let mut found = Vec::new();
        let named = text.split(',').map(str::trim).filter(|s| !s.is_empty()).map(Self::named);
        Self::merge(&mut found, named.collect::<Result<Vec<_>, _>>()?);
        Ok(found)
    }

    /// Adds `more` to `variants`, each once in the result, in the order of [`ALL`](Self::ALL) (how every
    /// family's emulator configuration keeps them: `SimConfig::add_variants`).
    fn merge(variants: &mut Vec<Self>, more: impl IntoIterator<Item = Self>) {
        variants.extend(more);
        variants.sort();
        variants.dedup();
    }

    /// The names of every variant, comma-separated (for messages and help texts).
    fn known() -> String {
        Self::ALL.iter().map(|v| v.name()).collect::<Vec<_>>().join(", ")
    }
}

/// A name that is none of a family's [`FirmwareVariant`]s.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{name:?} is not a variant of the {family} emulator (known: {known})")]
pub struct UnknownVariant {
    /// The family ("SCU", "PowerCube", "COMPAX").
    pub family: &'static str,
    /// The name given, blanks around it removed.
    pub name: String,
    /// Every name the family knows, comma-separated.
    pub known: String,
}

/// Implements `Display` (the name), `FromStr` and `TryFrom<String>` (serde's `try_from`) for a family's
/// [`FirmwareVariant`] by the trait's rule.
#[macro_export]
macro_rules! firmware_variant_traits {
    ($variant:ty) => {
        impl ::std::fmt::Display for $variant {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str($crate::emulator::FirmwareVariant::name(*self))
            }
        }

        impl ::std::str::FromStr for $variant {
            type Err = $crate::emulator::UnknownVariant;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                <$variant as $crate::emulator::FirmwareVariant>::named(s)
            }
        }

        impl TryFrom<String> for $variant {
            type Error = $crate::emulator::UnknownVariant;
            fn try_from(s: String) -> Result<Self, Self::Error> {
                <$variant as $crate::emulator::FirmwareVariant>::named(&s)
            }
        }
    };
}
