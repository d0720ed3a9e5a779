//! What the client tests share: the unit on the workspace's one rig (`motionlink_testkit::rig`: the emulator
//! behind an in-memory link on a manual clock that jumps ahead whenever every participant waits, a link that
//! lets a test arrange faults for each request), a slow gateway, and the watchdog scenario.

#![allow(dead_code, unused_imports)]

pub use std::sync::{Arc, Mutex};
pub use std::time::{Duration, Instant};

pub use motionlink_link::cancel::CancelToken;
pub use motionlink_link::clock::{Clock, ManualClock};
pub use motionlink_link::error::{Classify, ErrorClass, TransportKind};
pub use motionlink_link::link::{Connector, Link, LinkError};
pub use motionlink_link::pipe::{Direction, EmulatorHost, Fault, FaultControl, PipeConfig};
pub use motionlink_scu::model::Speed;
pub use motionlink_scu::model::{
    Actuator, ActuatorStatus1, CyclicObject, DataIndex, ErrorCode, Function, MotionDirection, MotionFunction,
    PositionCounts, SafetyId, Status1Flag, StopMode,
};
pub use motionlink_scu::sim::{RemoteMode, SimConfig};
pub use motionlink_scu::value::Value;
pub use motionlink_scu::wire::{Command, Status};
pub use motionlink_scu::Emulator;
pub use motionlink_scu::{Client, Config, Error, FunctionMap, MoveOptions, MovePolling, StrokeLimits};

/// The unit behind an in-memory link at 38400 baud on the manual clock (the shared rig), the test's thread
/// among the clock's participants.
pub struct Rig(motionlink_testkit::rig::Rig<Emulator>);

impl std::ops::Deref for Rig {
    type Target = motionlink_testkit::rig::Rig<Emulator>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl Rig {
    pub fn new(config: SimConfig) -> Rig {
        let unit = Emulator::new(config).unwrap();
        Rig(motionlink_testkit::rig::Rig::new(unit, PipeConfig::paced(38_400)).with_test_thread())
    }

    pub fn client(&self, config: Config) -> Client {
        Client::with_connector(self.connector(), self.clock.shared(), config).unwrap()
    }

    pub fn unit<R>(&self, f: impl FnOnce(&mut Emulator) -> R) -> R {
        self.device(f)
    }

    /// The answers to the RGs of data index `index` numbered `reads` (0: the next one) come with their fourth
    /// byte corrupted (the CRC fails: the session sends the RG again, three sendings at most).
    pub fn corrupt_reads(&self, index: u16, reads: std::ops::Range<u32>) {
        let count = std::sync::atomic::AtomicU32::new(0);
        let [lo, hi] = index.to_le_bytes();
        self.on_request(move |bytes, faults| {
            if bytes.starts_with(&[b'R', b'G', lo, hi])
                && reads.contains(&count.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
            {
                let at = faults.bytes_sent(Direction::DeviceToHost) + 3;
                faults.inject(Direction::DeviceToHost, at, Fault::Corrupt { xor: 1 });
            }
        });
    }
}

pub fn a(n: u8) -> Actuator {
    Actuator::new(n).unwrap()
}

pub fn f(n: u8) -> MotionFunction {
    MotionFunction::new(n).unwrap()
}

pub fn pct(n: u16) -> Speed {
    Speed::percent(n).unwrap()
}

/// Starts a long move, then the host falls silent (every byte to the unit lost, as when the program is killed):
/// the unit's own watchdog must stop the drive 500 ms after the last RC it received.
pub fn watchdog_expires_after_500_ms(safety: SafetyId) -> (Rig, Client) {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { safety_id: safety, ..Default::default() });
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    rig.sleep(1000);
    assert!(rig.unit(|u| u.is_moving(a(1))));
    let cyclic_before = rig.unit(|u| u.stats().cyclic);
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    // Find when the unit last saw an RC: the keepalive is at most 200 ms old.
    let cut = rig.clock.now();
    rig.sleep(250);
    assert_eq!(rig.unit(|u| u.stats().cyclic), cyclic_before, "nothing reaches the unit any more");
    // The unit stops at last RC + 500 ms, which lies in (cut - 200 ms, cut] + 500 ms.
    let mut t = cut + Duration::from_millis(250);
    while rig.unit(|u| u.is_moving(a(1))) {
        rig.clock.sleep_until(t + Duration::from_millis(1));
        t = rig.clock.now();
        assert!(t < cut + Duration::from_millis(501), "still moving {:?} after the cut", t - cut);
    }
    assert!(t > cut + Duration::from_millis(300), "stopped too early: {:?} after the cut", t - cut);
    assert_eq!(rig.unit(|u| u.last_error()), ErrorCode::from_bit(22));
    // What the emulator reports (`motionlink sim scu --events` prints the same lines).
    let events = rig.unit(motionlink_link::emulator::Emulator::take_events);
    let expiry = format!("remote mode ended by watchdog (Safety_ID {})", safety.code());
    let at = events.iter().position(|e| e.starts_with(&expiry)).unwrap_or_else(|| panic!("{events:?}"));
    assert!(events[at + 1].starts_with("A1 at rest"), "{events:?}");
    (rig, client)
}

// ---------------------------------------------------------------------------------------------------------
// Keepalive timing, corrupted lengths, bit flips, dead links

/// Records the clock time of every keepalive RC (`52 43 01 00 FF ..`) the client sends.
pub fn record_keepalives(rig: &Rig) -> Arc<Mutex<Vec<Duration>>> {
    let times = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&times);
    let clock = rig.clock.shared();
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x43, 0x01, 0x00, 0xFF]) {
            sink.lock().unwrap().push(clock.now().since_origin());
        }
    });
    times
}

/// A link whose received bytes reach the client `latency` after they arrived: a slow gateway.
pub struct Latency {
    pub inner: Box<dyn Link>,
    pub clock: motionlink_link::SharedClock,
    pub latency: Arc<Mutex<Duration>>,
    pub queue: std::collections::VecDeque<(motionlink_link::Timestamp, u8)>,
}

impl Latency {
    fn pull(&mut self, timeout: Duration) -> Result<(), LinkError> {
        let mut tmp = [0u8; 256];
        let n = self.inner.recv(&mut tmp, timeout)?;
        let now = self.clock.now();
        self.queue.extend(tmp[..n].iter().map(|b| (now, *b)));
        Ok(())
    }
}

impl Link for Latency {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let deadline = self.clock.now() + timeout;
        loop {
            let now = self.clock.now();
            let mut n = 0;
            let latency = *self.latency.lock().unwrap();
            while n < buf.len() && self.queue.front().is_some_and(|(t, _)| *t + latency <= now) {
                buf[n] = self.queue.pop_front().unwrap().1;
                n += 1;
            }
            if n > 0 || now >= deadline {
                return Ok(n);
            }
            let until = self.queue.front().map_or(deadline, |(t, _)| (*t + latency).min(deadline));
            self.pull(until.saturating_since(now))?;
        }
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.queue.clear();
        self.inner.discard_input()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

impl Rig {
    /// A unit with `config` whose firmware has `variants`.
    pub fn with_variants(mut config: SimConfig, variants: &[motionlink_scu::Variant]) -> Rig {
        config.add_variants(variants.iter().copied());
        Rig::new(config)
    }

    /// A client whose replies reach it `latency` (which the test may change) after the unit sent them.
    pub fn client_behind(&self, latency: &Arc<Mutex<Duration>>, config: Config) -> Result<Client, Error> {
        let host = self.host.clone();
        let clock = self.clock.shared();
        let latency = Arc::clone(latency);
        let connector: Connector = Box::new(move || {
            let (link, _) = host.connect();
            Ok(Box::new(Latency {
                inner: Box::new(link),
                clock: Arc::clone(&clock),
                latency: Arc::clone(&latency),
                queue: Default::default(),
            }) as Box<dyn Link>)
        });
        Client::with_connector(connector, self.clock.shared(), config)
    }
}
