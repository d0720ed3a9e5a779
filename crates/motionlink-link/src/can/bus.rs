//! An in-memory CAN bus for tests, benchmarks and in-process emulators.
//!
//! Any number of nodes ([`CanBusLink`]) and at most one emulated device ([`CanEmulator`]) share one medium.
//! A frame occupies the bus for its real length with stuff bits ([`CanFrame::bit_length_stuffed`]) at the
//! configured bit rate, after every frame
//! queued before it (first come, first served: identifier arbitration between frames queued at the same
//! instant is not modelled), and then arrives at every other node and at the device. The device runs
//! lazily, like [`EmulatorHost`](crate::pipe::EmulatorHost): whenever a node sends or reads, it is brought up
//! to the clock's time, each frame delivered at the instant it arrived.
//!
//! ```
//! use motionlink_link::can::{CanBus, CanBusConfig, CanFrame, CanLink};
//! use motionlink_link::clock::{Clock, ManualClock, Timestamp};
//! use std::time::Duration;
//!
//! let clock = ManualClock::new();
//! let bus = CanBus::new(clock.shared(), CanBusConfig::paced(1_000_000));
//! let (mut a, mut b) = (bus.connect(), bus.connect());
//! a.send(&CanFrame::new(0x0D1, &[0x0a, 0x3c]).unwrap()).unwrap();
//! // still on the wire: 63 bits and 2 stuff bits = 65 µs
//! assert_eq!(b.recv(Duration::ZERO).unwrap(), None);
//! clock.advance(Duration::from_micros(65));
//! assert_eq!(b.recv(Duration::ZERO).unwrap().unwrap().id(), 0x0D1);
//! ```

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::{CanEmulator, CanFrame, CanLink};
use crate::clock::{lock, SharedClock, Signal, Timestamp};
use crate::link::LinkError;

/// Which stuff bits a paced bus counts in a frame's time on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StuffBits {
    /// The stuff bits each frame's own bits call for ([`CanFrame::bit_length_stuffed`]): what a real bus
    /// carries. The default.
    #[default]
    Actual,
    /// The most any frame of that length can have ([`CanFrame::bit_length_worst_case`]).
    WorstCase,
    /// None ([`CanFrame::bit_length`]): shorter than any real bus.
    Ignored,
}

/// How the bus is paced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CanBusConfig {
    /// Bits per second; `None`: frames arrive at the instant they are sent.
    pub bitrate: Option<u32>,
    /// Which stuff bits count in a frame's time on the wire.
    pub stuffing: StuffBits,
    /// A node waiting for a frame spins until it is there instead of sleeping: no wake-up latency of the
    /// operating system in what a benchmark measures (the host's own time per exchange), at the cost of a
    /// core while it waits. For the real clock only (an auto-advancing manual clock moves only while its
    /// participants sleep). Default false.
    pub reader_spins: bool,
}

impl CanBusConfig {
    /// Frames arrive at the instant they are sent.
    pub fn instant() -> Self {
        CanBusConfig { bitrate: None, stuffing: StuffBits::Actual, reader_spins: false }
    }

    /// Frames take their real length in bits, stuff bits included, at `bitrate` bits per second.
    pub fn paced(bitrate: u32) -> Self {
        CanBusConfig { bitrate: Some(bitrate), stuffing: StuffBits::Actual, reader_spins: false }
    }

    /// The length in bits that times `frame` on this bus.
    pub fn frame_bits(&self, frame: &CanFrame) -> u32 {
        match self.stuffing {
            StuffBits::Actual => frame.bit_length_stuffed(),
            StuffBits::WorstCase => frame.bit_length_worst_case(),
            StuffBits::Ignored => frame.bit_length(),
        }
    }

    /// How long `frame` occupies the bus.
    pub fn frame_time(&self, frame: &CanFrame) -> Duration {
        match self.bitrate {
            None => Duration::ZERO,
            Some(rate) => {
                Duration::from_nanos(u64::from(self.frame_bits(frame)) * 1_000_000_000 / u64::from(rate.max(1)))
            }
        }
    }
}

/// A bus without an emulated device: only the nodes talk.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoDevice;

impl CanEmulator for NoDevice {
    fn receive(&mut self, _now: Timestamp, _frame: &CanFrame, _out: &mut Vec<CanFrame>) {}
    fn advance(&mut self, _now: Timestamp, _out: &mut Vec<CanFrame>) {}
    fn next_wakeup(&self) -> Option<Timestamp> {
        None
    }
}

/// Who put a frame on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sender {
    Node(usize),
    Device,
}

struct Node {
    queue: VecDeque<(Timestamp, CanFrame)>,
    wake: Signal,
}

struct BusState<E> {
    config: CanBusConfig,
    busy_until: Timestamp,
    nodes: Vec<Option<Node>>,
    device: Option<E>,
    to_device: VecDeque<(Timestamp, CanFrame)>,
    device_last: Timestamp,
    scratch: Vec<CanFrame>,
    drop_to_device: u64,
    drop_from_device: u64,
    broken: bool,
    frames_carried: u64,
    /// The device's events with their times, once [`CanBus::keep_event_times`] asked for them.
    events: crate::emulator::TimedEvents,
}

impl<E: CanEmulator> BusState<E> {
    fn transmit(&mut self, from: Sender, at: Timestamp, frame: CanFrame) {
        match from {
            Sender::Device if self.drop_from_device > 0 => {
                self.drop_from_device -= 1;
                return;
            }
            Sender::Node(_) if self.drop_to_device > 0 && self.device.is_some() => {
                self.drop_to_device -= 1;
                return;
            }
            _ => {}
        }
        let start = self.busy_until.max(at);
        let end = start + self.config.frame_time(&frame);
        self.busy_until = end;
        self.frames_carried += 1;
        for (i, node) in self.nodes.iter_mut().enumerate() {
            if let Some(node) = node {
                if from != Sender::Node(i) {
                    node.queue.push_back((end, frame));
                    node.wake.raise();
                }
            }
        }
        if from != Sender::Device && self.device.is_some() {
            self.to_device.push_back((end, frame));
        }
    }

    /// Runs the device up to `now`: delivers frames at their arrival times, fires its timers in order.
    fn pump(&mut self, now: Timestamp) {
        let Some(mut device) = self.device.take() else { return };
        loop {
            let frame_at = self.to_device.front().map(|(t, _)| *t).filter(|t| *t <= now);
            let timer_at = device.next_wakeup().filter(|t| *t <= now && *t >= self.device_last);
            let (t, is_frame) = match (frame_at, timer_at) {
                (Some(f), Some(w)) if w < f => (w, false),
                (Some(f), _) => (f, true),
                (None, Some(w)) => (w, false),
                (None, None) => break,
            };
            let mut out = std::mem::take(&mut self.scratch);
            out.clear();
            if is_frame {
                if let Some((_, frame)) = self.to_device.pop_front() {
                    device.receive(t, &frame, &mut out);
                }
            } else {
                let before = device.next_wakeup();
                device.advance(t, &mut out);
                if device.next_wakeup() == before && out.is_empty() {
                    self.device_last = t;
                    self.scratch = out;
                    self.events.collect(t, || device.take_events());
                    break;
                }
            }
            self.device_last = self.device_last.max(t);
            self.events.collect(t, || device.take_events());
            for f in out.drain(..) {
                self.transmit(Sender::Device, t, f);
            }
            self.scratch = out;
        }
        let mut out = std::mem::take(&mut self.scratch);
        out.clear();
        // The device may be ahead of `now` (see `pump_ahead`): it is never run backwards.
        if now >= self.device_last {
            device.advance(now, &mut out);
            self.device_last = now;
            self.events.collect(now, || device.take_events());
        }
        for f in out.drain(..) {
            self.transmit(Sender::Device, now, f);
        }
        self.scratch = out;
        self.device = Some(device);
    }
}

impl<E: CanEmulator> BusState<E> {
    /// Where the one node on the bus waits and the next event is a frame of its reaching the device at `at`:
    /// runs the device up to `at` now, so that the node sleeps once, until the answer is there (as a reader of
    /// a kernel socket does), rather than also at the moment the device takes the frame. Exact with one node:
    /// nothing else can reach the device before `at`, and the node sends again only after the answer, which
    /// comes after `at`. With more nodes the device runs in step with the clock.
    fn pump_ahead(&mut self, at: Timestamp) -> bool {
        if self.nodes.iter().flatten().count() != 1 || self.to_device.front().is_none_or(|(t, _)| *t != at) {
            return false;
        }
        self.pump(at);
        true
    }
}

thread_local! {
    /// Whether this thread's timers were made precise for its waits on a bus.
    static PRECISE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// An in-memory CAN bus, optionally with an emulated device `E` on it; cheap to clone (clones share the bus).
pub struct CanBus<E = NoDevice> {
    state: Arc<Mutex<BusState<E>>>,
    clock: SharedClock,
}

impl<E> Clone for CanBus<E> {
    fn clone(&self) -> Self {
        CanBus { state: Arc::clone(&self.state), clock: Arc::clone(&self.clock) }
    }
}

impl CanBus<NoDevice> {
    /// A bus with nodes only.
    pub fn new(clock: SharedClock, config: CanBusConfig) -> Self {
        Self::build(None, clock, config)
    }
}

impl<E: CanEmulator> CanBus<E> {
    /// A bus with `device` on it.
    pub fn with_emulator(device: E, clock: SharedClock, config: CanBusConfig) -> Self {
        Self::build(Some(device), clock, config)
    }

    fn build(device: Option<E>, clock: SharedClock, config: CanBusConfig) -> Self {
        CanBus {
            state: Arc::new(Mutex::new(BusState {
                config,
                busy_until: Timestamp::ZERO,
                nodes: Vec::new(),
                device,
                to_device: VecDeque::new(),
                device_last: Timestamp::ZERO,
                scratch: Vec::new(),
                drop_to_device: 0,
                drop_from_device: 0,
                broken: false,
                frames_carried: 0,
                events: Default::default(),
            })),
            clock,
        }
    }

    /// A new node on the bus. It receives every frame put on the bus after this call by anyone else.
    pub fn connect(&self) -> CanBusLink<E> {
        let wake = self.clock.signal();
        let mut st = lock(&self.state);
        let now = self.clock.now();
        st.pump(now);
        let node = Node { queue: VecDeque::new(), wake: wake.clone() };
        let index = match st.nodes.iter().position(Option::is_none) {
            Some(i) => {
                st.nodes[i] = Some(node);
                i
            }
            None => {
                st.nodes.push(Some(node));
                st.nodes.len() - 1
            }
        };
        CanBusLink { bus: self.clone(), index, wake, name: format!("in-memory CAN bus (node {index})") }
    }

    /// Runs `f` on the device, brought up to the clock's current time first. `None` on a bus without one.
    pub fn with_device<R>(&self, f: impl FnOnce(&mut E) -> R) -> Option<R> {
        let mut st = lock(&self.state);
        st.pump(self.clock.now());
        st.device.as_mut().map(f)
    }

    /// From now on the device's events are kept with the time each happened, for
    /// [`CanBus::take_timed_events`] (as [`EmulatorHost::keep_event_times`](crate::pipe::EmulatorHost::keep_event_times)).
    pub fn keep_event_times(&self) {
        lock(&self.state).events.keep();
    }

    /// The events kept since the last call, oldest first, each with the clock's time at which the device
    /// produced it; the device is brought up to date first.
    pub fn take_timed_events(&self) -> Vec<(Timestamp, String)> {
        let mut st = lock(&self.state);
        st.pump(self.clock.now());
        st.events.take()
    }

    /// Loses the next `count` frames the nodes send to the device (a device that misses them).
    pub fn drop_next_to_device(&self, count: u64) {
        lock(&self.state).drop_to_device += count;
    }

    /// Loses the next `count` frames the device sends.
    pub fn drop_next_from_device(&self, count: u64) {
        lock(&self.state).drop_from_device += count;
    }

    /// Breaks the bus (a cable pulled, a controller gone bus-off): every node's next call fails with
    /// [`LinkError::Disconnected`].
    pub fn disconnect(&self) {
        let mut st = lock(&self.state);
        st.broken = true;
        for node in st.nodes.iter().flatten() {
            node.wake.raise();
        }
    }

    /// Frames carried so far (every frame counts once, however many nodes receive it).
    pub fn frames_carried(&self) -> u64 {
        lock(&self.state).frames_carried
    }

    /// The clock that times the bus.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }
}

/// One node of a [`CanBus`]; a [`CanLink`].
pub struct CanBusLink<E = NoDevice> {
    bus: CanBus<E>,
    index: usize,
    wake: Signal,
    name: String,
}

impl<E> CanBusLink<E> {
    fn gone(&self) -> LinkError {
        LinkError::Disconnected { port: self.name.clone(), reason: "CAN bus broken".into() }
    }
}

impl<E: CanEmulator> CanLink for CanBusLink<E> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let now = self.bus.clock.now();
        let mut st = lock(&self.bus.state);
        if st.broken {
            return Err(self.gone());
        }
        st.pump(now);
        st.transmit(Sender::Node(self.index), now, *frame);
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let deadline = self.bus.clock.now() + timeout;
        loop {
            let now = self.bus.clock.now();
            let (next, spins) = {
                let mut st = lock(&self.bus.state);
                if st.broken {
                    return Err(self.gone());
                }
                st.pump(now);
                let Some(Some(node)) = st.nodes.get_mut(self.index) else { return Err(self.gone()) };
                match node.queue.front() {
                    Some(&(t, frame)) if t <= now => {
                        node.queue.pop_front();
                        return Ok(Some(frame));
                    }
                    _ => {}
                }
                let own = node.queue.front().map(|(t, _)| *t);
                let dev = st.to_device.front().map(|(t, _)| *t);
                let timer = st.device.as_ref().and_then(|d| d.next_wakeup()).filter(|t| *t > now);
                let next = [own, dev, timer].into_iter().flatten().min();
                if next.is_some_and(|t| Some(t) == dev && t <= deadline && own.is_none_or(|o| o > t))
                    && st.pump_ahead(next.unwrap_or(now))
                {
                    continue;
                }
                (next, st.config.reader_spins)
            };
            if now >= deadline {
                return Ok(None);
            }
            let until = next.map_or(deadline, |t| t.min(deadline));
            // As a reader of a kernel socket does: asleep until the frame is there, leaving the CPU to others
            // (a frame read a little late is still read; spinning would make this thread compete for the
            // CPU it waits on). A socket's reader is woken by the frame itself; here the frame arrives on a
            // timer, so the waiting thread's timers are made precise (Linux delays a timed wake-up by up to
            // 50 µs by default, which would count as the host's time).
            if spins {
                // A raise (another frame on the bus) ends the spin as it would end a sleep.
                while self.bus.clock.now() < until
                    && self.wake.wait_until(Some(Timestamp::ZERO)) != crate::clock::Wake::Raised
                {
                    std::hint::spin_loop();
                }
                continue;
            }
            PRECISE.with(|p| {
                if !p.get() {
                    p.set(true);
                    crate::clock::precise_timers();
                }
            });
            self.wake.wait_until_sleeping(Some(until));
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        let now = self.bus.clock.now();
        let mut st = lock(&self.bus.state);
        st.pump(now);
        if let Some(Some(node)) = st.nodes.get_mut(self.index) {
            node.queue.retain(|(t, _)| *t > now);
        }
        Ok(())
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

impl<E> Drop for CanBusLink<E> {
    fn drop(&mut self) {
        let mut st = lock(&self.bus.state);
        if let Some(slot) = st.nodes.get_mut(self.index) {
            *slot = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::{Clock, ManualClock};

    /// Answers a frame with id X by id X + 1 and the same data; says 0x7FF by itself at 10 ms.
    #[derive(Default)]
    struct Plus1 {
        seen: Vec<Timestamp>,
        told: bool,
        said: bool,
    }

    impl CanEmulator for Plus1 {
        fn receive(&mut self, now: Timestamp, frame: &CanFrame, out: &mut Vec<CanFrame>) {
            self.seen.push(now);
            out.push(CanFrame::new(frame.id() + 1, frame.data()).unwrap());
        }
        fn advance(&mut self, now: Timestamp, out: &mut Vec<CanFrame>) {
            if !self.told && now >= Timestamp::from_millis(10) {
                self.told = true;
                out.push(CanFrame::new(0x7FF, &[]).unwrap());
            }
        }
        fn next_wakeup(&self) -> Option<Timestamp> {
            (!self.told).then_some(Timestamp::from_millis(10))
        }
        fn take_events(&mut self) -> Vec<String> {
            let told = self.told && !self.said;
            self.said |= told;
            told.then(|| "told".to_string()).into_iter().collect()
        }
    }

    #[test]
    fn kept_events_carry_the_time_the_device_produced_them() {
        let clock = ManualClock::new();
        let bus = CanBus::with_emulator(Plus1::default(), clock.shared(), CanBusConfig::paced(500_000));
        bus.keep_event_times();
        clock.advance(Duration::from_millis(40));
        assert_eq!(bus.take_timed_events(), [(Timestamp::from_millis(10), "told".to_string())]);
        assert!(bus.take_timed_events().is_empty());
    }

    #[test]
    fn frames_queue_back_to_back_at_the_bit_rate() {
        let clock = ManualClock::new();
        let bus = CanBus::with_emulator(Plus1::default(), clock.shared(), CanBusConfig::paced(500_000));
        let mut host = bus.connect();
        // 63 bits and 4 stuff bits = 134 µs at 500 kbit/s.
        let f = CanFrame::new(0x100, &[1, 2]).unwrap();
        assert_eq!(f.bit_length_stuffed(), 67);
        host.send(&f).unwrap();
        host.send(&f).unwrap();
        clock.advance(Duration::from_millis(1));
        // Device saw them at 134 and 268 µs; its answers follow at 402 and 536 µs.
        assert_eq!(
            bus.with_device(|d| d.seen.clone()).unwrap(),
            vec![Timestamp::from_micros(134), Timestamp::from_micros(268)]
        );
        assert_eq!(host.recv(Duration::ZERO).unwrap().unwrap().id(), 0x101);
        assert_eq!(host.recv(Duration::ZERO).unwrap().unwrap().id(), 0x101);
        assert_eq!(host.recv(Duration::ZERO).unwrap(), None);
        assert_eq!(bus.frames_carried(), 4);
    }

    #[test]
    fn the_stuffing_model_times_the_frames() {
        let f = CanFrame::new(0x0D1, &[0x0a, 0x3c]).unwrap();
        let at = |stuffing| CanBusConfig { stuffing, ..CanBusConfig::paced(1_000_000) }.frame_time(&f);
        assert_eq!(at(StuffBits::Actual), Duration::from_micros(65));
        assert_eq!(at(StuffBits::WorstCase), Duration::from_micros(75));
        assert_eq!(at(StuffBits::Ignored), Duration::from_micros(63));
        assert_eq!(CanBusConfig::paced(1_000_000).stuffing, StuffBits::Actual);
        assert_eq!(CanBusConfig::instant().frame_time(&f), Duration::ZERO);
    }

    #[test]
    fn a_waiting_node_is_woken_by_the_device_timer() {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let bus = CanBus::with_emulator(Plus1::default(), clock.shared(), CanBusConfig::paced(1_000_000));
        let mut host = bus.connect();
        let got = host.recv(Duration::from_secs(1)).unwrap().unwrap();
        assert_eq!(got.id(), 0x7FF);
        // 0x7FF without data: 47 bits and 3 stuff bits.
        assert_eq!(clock.now(), Timestamp::from_millis(10) + Duration::from_micros(50));
    }

    #[test]
    fn nodes_hear_each_other_not_themselves_and_faults_apply() {
        let clock = ManualClock::new();
        let bus = CanBus::with_emulator(Plus1::default(), clock.shared(), CanBusConfig::instant());
        let mut a = bus.connect();
        let mut b = bus.connect();
        bus.drop_next_from_device(1);
        a.send(&CanFrame::new(0x10, &[]).unwrap()).unwrap();
        assert_eq!(b.recv(Duration::ZERO).unwrap().unwrap().id(), 0x10);
        assert_eq!(b.recv(Duration::ZERO).unwrap(), None, "the device's answer was dropped");
        assert_eq!(a.recv(Duration::ZERO).unwrap(), None, "a node does not hear itself");
        bus.drop_next_to_device(1);
        a.send(&CanFrame::new(0x20, &[]).unwrap()).unwrap();
        assert_eq!(bus.with_device(|d| d.seen.len()).unwrap(), 1);
        bus.disconnect();
        assert!(a.recv(Duration::ZERO).unwrap_err().is_disconnect());
        assert!(b.send(&CanFrame::new(1, &[]).unwrap()).unwrap_err().is_disconnect());
    }

    #[test]
    fn a_lone_waiting_node_gets_its_answer_at_the_wire_time_with_the_device_run_ahead_never_backwards() {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let bus = CanBus::with_emulator(Plus1::default(), clock.shared(), CanBusConfig::paced(500_000));
        let mut host = bus.connect();
        let f = CanFrame::new(0x100, &[1, 2]).unwrap();
        host.send(&f).unwrap();
        let got = host.recv(Duration::from_secs(1)).unwrap().unwrap();
        assert_eq!(got.id(), 0x101);
        // The request reaches the device at 134 µs, the answer the node at 268 µs: as when the device runs in
        // step with the clock.
        assert_eq!(bus.with_device(|d| d.seen.clone()).unwrap(), vec![Timestamp::from_micros(134)]);
        assert_eq!(clock.now(), Timestamp::from_micros(268));
        // The device's own timer still fires at its time, and the node hears it then.
        let told = host.recv(Duration::from_secs(1)).unwrap().unwrap();
        assert_eq!(told.id(), 0x7FF);
        assert_eq!(clock.now(), Timestamp::from_millis(10) + Duration::from_micros(100));
    }

    #[test]
    fn a_spinning_reader_gets_its_answer_no_sooner_than_the_wire_allows() {
        let clock = crate::clock::RealClock::shared();
        let config = CanBusConfig { reader_spins: true, ..CanBusConfig::paced(500_000) };
        let bus = CanBus::with_emulator(Plus1::default(), Arc::clone(&clock), config);
        let mut host = bus.connect();
        let sent = clock.now();
        host.send(&CanFrame::new(0x100, &[1, 2]).unwrap()).unwrap();
        // Request and answer: 134 µs each on the wire at 500 kbit/s.
        let got = host.recv(Duration::from_secs(1)).unwrap().expect("the answer");
        assert_eq!(got.id(), 0x101);
        assert!(clock.now() - sent >= Duration::from_micros(268), "{:?}", clock.now() - sent);
        assert_eq!(host.recv(Duration::ZERO).unwrap(), None);
    }
}
