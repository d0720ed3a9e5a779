//! A family's client wired to its emulator in-process: the emulator behind an in-memory link (paced at a baud
//! rate, or instant) or on an in-memory CAN bus, on a manual clock that jumps ahead whenever every
//! participant waits (minutes of device time run in milliseconds, deterministically). A test arranges
//! faults for each request as it goes out, unplugs the adapter, reads what went over the line. Every
//! family's client tests run on it.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::can::{CanBus, CanBusConfig, CanBusLink, CanEmulator};
use motionlink_link::chunk;
use motionlink_link::clock::{lock, Clock, ManualClock, ParticipantGuard, SharedClock};
use motionlink_link::emulator::Emulator;
use motionlink_link::link::{Connector, Link, LinkError};
use motionlink_link::pipe::{EmulatorHost, FaultControl, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript};

/// Called with every telegram a client sends (its bytes) and the connection's fault control, just before it
/// is sent: a test arranges faults for that telegram's reply (its first byte is the next one the device
/// sends).
pub type Hook = Arc<dyn Fn(&[u8], &FaultControl) + Send + Sync>;

/// A link that runs the rig's hook on each telegram it sends.
struct Hooked {
    inner: Box<dyn Link>,
    faults: FaultControl,
    hook: Arc<Mutex<Option<Hook>>>,
}

impl Link for Hooked {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let hook = lock(&self.hook).clone();
        if let Some(h) = hook {
            h(bytes, &self.faults);
        }
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        self.inner.recv(buf, timeout)
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
    fn send_break(&mut self, duration: std::time::Duration) -> Result<(), LinkError> {
        self.inner.send_break(duration)
    }
}

/// An emulator behind in-memory links on a manual clock; see the [module documentation](self).
pub struct Rig<E> {
    /// The clock of the device, the links and the client.
    pub clock: ManualClock,
    /// The emulator's end: a new connection each [`Rig::link`].
    pub host: EmulatorHost<E>,
    /// Everything that went over the rig's links, both ways, with its time.
    pub transcript: Transcript,
    /// The fault control of the latest connection (shared: a test's callback may reach it).
    pub faults: Arc<Mutex<Option<FaultControl>>>,
    hook: Arc<Mutex<Option<Hook>>>,
    /// How many connections were opened.
    pub connects: Arc<Mutex<u32>>,
    /// While true, opening the port fails (the adapter is unplugged).
    pub unplugged: Arc<Mutex<bool>>,
    _participant: Option<ParticipantGuard>,
}

impl<E: Emulator + 'static> Rig<E> {
    /// `emulator` behind links configured by `pipe` (paced at a baud rate, or instant), on an
    /// auto-advancing manual clock.
    pub fn new(emulator: E, pipe: PipeConfig) -> Self {
        let clock = ManualClock::new_auto();
        let host = EmulatorHost::new(emulator, clock.shared(), pipe);
        Rig {
            clock,
            host,
            transcript: Transcript::new(),
            faults: Arc::default(),
            hook: Arc::default(),
            connects: Arc::default(),
            unplugged: Arc::default(),
            _participant: None,
        }
    }

    /// The same rig, the test's own thread counted among the clock's participants: the clock moves on only
    /// while the test waits on it too (a test that looks at the device between calls sees it where the
    /// client left it).
    pub fn with_test_thread(mut self) -> Self {
        self._participant = Some(self.clock.reserve_participant().enter());
        self
    }

    /// A new connection to the emulator: recorded in [`Rig::transcript`], run through the hook of
    /// [`Rig::on_request`]; its fault control becomes [`Rig::faults`]. Fails while the adapter is unplugged.
    pub fn link(&self) -> Result<Box<dyn Link>, LinkError> {
        connect(&self.host, &self.transcript, &self.faults, &self.hook, &self.connects, &self.unplugged)
    }

    /// What opens the port, each time [`Rig::link`] (for clients that reopen it).
    pub fn connector(&self) -> Connector {
        let (host, transcript) = (self.host.clone(), self.transcript.clone());
        let (faults, hook) = (Arc::clone(&self.faults), Arc::clone(&self.hook));
        let (connects, unplugged) = (Arc::clone(&self.connects), Arc::clone(&self.unplugged));
        Box::new(move || connect(&host, &transcript, &faults, &hook, &connects, &unplugged))
    }

    /// From now on, `hook` sees every telegram before it is sent.
    pub fn on_request(&self, hook: impl Fn(&[u8], &FaultControl) + Send + Sync + 'static) {
        *lock(&self.hook) = Some(Arc::new(hook));
    }

    /// The fault control of the latest connection.
    pub fn faults(&self) -> FaultControl {
        lock(&self.faults).clone().expect("a link was opened")
    }

    /// Runs `f` on the emulator.
    pub fn device<R>(&self, f: impl FnOnce(&mut E) -> R) -> R {
        self.host.with_device(f)
    }

    /// Lets `ms` milliseconds of clock time pass.
    pub fn sleep(&self, ms: u64) {
        self.clock.sleep(Duration::from_millis(ms));
    }

    /// Every write to the device so far, one entry per write.
    pub fn sent(&self) -> Vec<Vec<u8>> {
        self.transcript
            .records()
            .into_iter()
            .filter(|r| r.direction == chunk::Direction::ToDevice)
            .map(|r| r.bytes)
            .collect()
    }

    /// The shared clock, for the client.
    pub fn shared_clock(&self) -> SharedClock {
        self.clock.shared()
    }
}

fn connect<E: Emulator + 'static>(
    host: &EmulatorHost<E>,
    transcript: &Transcript,
    faults: &Arc<Mutex<Option<FaultControl>>>,
    hook: &Arc<Mutex<Option<Hook>>>,
    connects: &Arc<Mutex<u32>>,
    unplugged: &Arc<Mutex<bool>>,
) -> Result<Box<dyn Link>, LinkError> {
    if *lock(unplugged) {
        return Err(LinkError::Disconnected { port: "sim".into(), reason: "unplugged".into() });
    }
    let (link, f) = host.connect();
    *lock(faults) = Some(f.clone());
    *lock(connects) += 1;
    let tapped = TapLink::new(link, host.clock().clone(), transcript.clone());
    Ok(Box::new(Hooked { inner: Box::new(tapped), faults: f, hook: Arc::clone(hook) }))
}

/// An emulator on an in-memory CAN bus on a manual clock: [`Rig`] for CAN.
pub struct CanRig<E: CanEmulator> {
    /// The clock of the bus, the device and the client.
    pub clock: ManualClock,
    /// The bus, with the emulator on it.
    pub bus: CanBus<E>,
}

impl<E: CanEmulator + 'static> CanRig<E> {
    /// `emulator` on a bus configured by `config`, on an auto-advancing manual clock.
    pub fn new(emulator: E, config: CanBusConfig) -> Self {
        let clock = ManualClock::new_auto();
        let bus = CanBus::with_emulator(emulator, clock.shared(), config);
        CanRig { clock, bus }
    }

    /// A new node on the bus.
    pub fn link(&self) -> CanBusLink<E> {
        self.bus.connect()
    }

    /// The shared clock, for the client.
    pub fn shared_clock(&self) -> SharedClock {
        self.clock.shared()
    }
}
