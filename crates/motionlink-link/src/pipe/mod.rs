//! In-memory byte links for tests, benchmarks and in-process emulators.
//!
//! A [`pipe`] is a pair of connected [`Link`] ends. An [`EmulatorLink`] is a host end whose far side is an
//! [`Emulator`] run in-process, lazily, at the exact clock time each byte arrives. Both can pace bytes at a
//! baud rate (10 bit times per byte, as 8N1 on a wire) and inject faults through a [`FaultControl`]: drop,
//! corrupt or delay bytes, and disconnect.
//!
//! ```
//! use motionlink_link::clock::{ManualClock, Clock};
//! use motionlink_link::link::Link;
//! use motionlink_link::pipe::{pipe, PipeConfig, Direction};
//! use std::time::Duration;
//!
//! let clock = ManualClock::new();
//! let (mut host, mut device, faults) = pipe(clock.shared(), PipeConfig::paced(38_400));
//! faults.corrupt_next(Direction::HostToDevice, 0x01);
//! host.send(b"RO").unwrap();
//! clock.advance(Duration::from_millis(1)); // two bytes take 0.52 ms at 38400 baud
//! let mut buf = [0u8; 8];
//! assert_eq!(device.recv(&mut buf, Duration::ZERO).unwrap(), 2);
//! assert_eq!(&buf[..2], b"SO"); // 'R' ^ 0x01 == 'S'
//! ```

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::clock::{lock, SharedClock, Signal, Timestamp};
use crate::emulator::Emulator;
use crate::link::{char_time, Link, LinkError, Parity};

/// Which way bytes travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// From the host (the client) to the device.
    HostToDevice,
    /// From the device to the host.
    DeviceToHost,
}

impl Direction {
    fn index(self) -> usize {
        match self {
            Direction::HostToDevice => 0,
            Direction::DeviceToHost => 1,
        }
    }
}

/// A fault applied to one byte on its way through the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// The byte arrives with these bits flipped.
    Corrupt {
        /// Bits to flip.
        xor: u8,
    },
    /// The byte is lost.
    Drop,
    /// The byte (and so every byte after it) arrives this much later.
    Delay(Duration),
    /// The link breaks when this byte is sent; both ends see [`LinkError::Disconnected`].
    Disconnect,
}

/// Settings of an in-memory link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PipeConfig {
    /// Pace bytes at this rate (10 bit times per byte); `None`: bytes arrive at the instant they are sent.
    pub baud_rate: Option<u32>,
}

impl PipeConfig {
    /// Bytes arrive at the instant they are sent.
    pub fn instant() -> Self {
        PipeConfig { baud_rate: None }
    }

    /// Bytes are paced at `baud_rate`, 8N1.
    pub fn paced(baud_rate: u32) -> Self {
        PipeConfig { baud_rate: Some(baud_rate) }
    }

    fn byte_time(&self) -> Duration {
        self.baud_rate.map_or(Duration::ZERO, |b| char_time(b, Parity::None))
    }
}

/// One direction of a wire: bytes in flight with their arrival times.
#[derive(Debug, Default)]
struct Wire {
    byte_time: Duration,
    /// When the wire has finished sending everything queued so far.
    busy_until: Timestamp,
    in_flight: VecDeque<(Timestamp, u8)>,
    /// Bytes offered to this wire so far: the offset of the next byte.
    offered: u64,
    /// Faults by byte offset, kept sorted.
    faults: Vec<(u64, Fault)>,
    /// Ranges of byte offsets that are lost.
    dropped: Vec<std::ops::Range<u64>>,
}

impl Wire {
    fn new(byte_time: Duration) -> Self {
        Wire { byte_time, ..Wire::default() }
    }

    /// Puts `bytes` on the wire at `now`. Returns false if a fault breaks the link.
    fn offer(&mut self, now: Timestamp, bytes: &[u8]) -> bool {
        for &b in bytes {
            let offset = self.offered;
            self.offered += 1;
            let mut byte = Some(b);
            self.dropped.retain(|r| r.end > offset);
            if self.dropped.iter().any(|r| r.contains(&offset)) {
                byte = None;
            }
            while let Some(i) = self.faults.iter().position(|(o, _)| *o == offset) {
                let (_, fault) = self.faults.remove(i);
                match fault {
                    Fault::Corrupt { xor } => byte = byte.map(|b| b ^ xor),
                    Fault::Drop => byte = None,
                    Fault::Delay(d) => self.busy_until = self.busy_until.max(now) + d,
                    Fault::Disconnect => return false,
                }
            }
            let start = self.busy_until.max(now);
            self.busy_until = start + self.byte_time;
            if let Some(b) = byte {
                self.in_flight.push_back((self.busy_until, b));
            }
        }
        true
    }

    fn next_arrival(&self) -> Option<Timestamp> {
        self.in_flight.front().map(|(t, _)| *t)
    }

    /// When the last byte in flight arrives. A reader waits for that rather than for each byte, as a UART
    /// driver hands a burst over at once: one exact wake-up per telegram instead of one per byte time
    /// (87 µs at 115200 baud, each spun through on a real clock).
    fn last_arrival(&self) -> Option<Timestamp> {
        self.in_flight.back().map(|(t, _)| *t)
    }

    /// Moves bytes that have arrived by `now` into `buf`.
    fn take_arrived(&mut self, now: Timestamp, buf: &mut [u8]) -> usize {
        let mut n = 0;
        while n < buf.len() {
            match self.in_flight.front() {
                Some(&(t, b)) if t <= now => {
                    buf[n] = b;
                    n += 1;
                    self.in_flight.pop_front();
                }
                _ => break,
            }
        }
        n
    }
}

#[derive(Debug)]
struct Faults {
    /// Wires, by [`Direction::index`].
    wires: [Wire; 2],
    broken: bool,
}

impl Faults {
    fn schedule(&mut self, dir: Direction, offset: u64, fault: Fault) {
        let faults = &mut self.wires[dir.index()].faults;
        let at = faults.partition_point(|(o, _)| *o <= offset);
        faults.insert(at, (offset, fault));
    }
}

/// Injects faults into an in-memory link; cheap to clone and usable from any thread.
#[derive(Clone)]
pub struct FaultControl {
    shared: Arc<Mutex<Shared>>,
    /// Raised to wake both ends after a change (a disconnect must interrupt a blocked read).
    wake: [Signal; 2],
}

impl std::fmt::Debug for FaultControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("FaultControl")
    }
}

impl FaultControl {
    fn with<R>(&self, f: impl FnOnce(&mut Faults) -> R) -> R {
        let r = f(&mut lock(&self.shared).faults);
        self.wake.iter().for_each(Signal::raise);
        r
    }

    /// Schedules `fault` for the byte at `offset` (counted from the first byte ever sent that way).
    pub fn inject(&self, dir: Direction, offset: u64, fault: Fault) {
        self.with(|f| f.schedule(dir, offset, fault));
    }

    /// Bytes sent in direction `dir` so far.
    pub fn bytes_sent(&self, dir: Direction) -> u64 {
        lock(&self.shared).faults.wires[dir.index()].offered
    }

    /// Flips bits `xor` in the next byte sent in direction `dir`.
    pub fn corrupt_next(&self, dir: Direction, xor: u8) {
        self.with(|f| {
            let at = f.wires[dir.index()].offered;
            f.schedule(dir, at, Fault::Corrupt { xor });
        });
    }

    /// Loses the next `count` bytes sent in direction `dir` (`u64::MAX`: everything from now on).
    pub fn drop_next(&self, dir: Direction, count: u64) {
        self.with(|f| {
            let wire = &mut f.wires[dir.index()];
            let at = wire.offered;
            wire.dropped.push(at..at.saturating_add(count));
        });
    }

    /// Cancels every fault not yet applied (the line is healthy again).
    pub fn heal(&self) {
        self.with(|f| {
            for w in &mut f.wires {
                w.faults.clear();
                w.dropped.clear();
            }
        });
    }

    /// Holds the next byte sent in direction `dir` (and what follows it) back by `by`.
    pub fn delay_next(&self, dir: Direction, by: Duration) {
        self.with(|f| {
            let at = f.wires[dir.index()].offered;
            f.schedule(dir, at, Fault::Delay(by));
        });
    }

    /// Breaks the link now: both ends report [`LinkError::Disconnected`] from their next call.
    pub fn disconnect(&self) {
        self.with(|f| f.broken = true);
    }

    /// True once the link is broken.
    pub fn is_disconnected(&self) -> bool {
        lock(&self.shared).faults.broken
    }
}

struct Shared {
    faults: Faults,
    /// Ends dropped, by [`Direction::index`] of the direction they send in.
    closed: [bool; 2],
}

/// Makes a connected pair of in-memory links: `(host end, device end, fault control)`.
pub fn pipe(clock: SharedClock, config: PipeConfig) -> (PipeEnd, PipeEnd, FaultControl) {
    let shared = Arc::new(Mutex::new(Shared {
        faults: Faults { wires: [Wire::new(config.byte_time()), Wire::new(config.byte_time())], broken: false },
        closed: [false; 2],
    }));
    let wake = [clock.signal(), clock.signal()];
    let host = PipeEnd {
        shared: Arc::clone(&shared),
        clock: Arc::clone(&clock),
        tx: Direction::HostToDevice,
        my_wake: wake[1].clone(),
        peer_wake: wake[0].clone(),
        name: "pipe (host end)".into(),
    };
    let device = PipeEnd {
        shared: Arc::clone(&shared),
        clock,
        tx: Direction::DeviceToHost,
        my_wake: wake[0].clone(),
        peer_wake: wake[1].clone(),
        name: "pipe (device end)".into(),
    };
    (host, device, FaultControl { shared, wake: [wake[0].clone(), wake[1].clone()] })
}

/// One end of an in-memory [`pipe`].
pub struct PipeEnd {
    shared: Arc<Mutex<Shared>>,
    clock: SharedClock,
    /// The direction this end sends in.
    tx: Direction,
    /// Raised when bytes are sent towards this end.
    my_wake: Signal,
    peer_wake: Signal,
    name: String,
}

impl PipeEnd {
    fn rx(&self) -> Direction {
        match self.tx {
            Direction::HostToDevice => Direction::DeviceToHost,
            Direction::DeviceToHost => Direction::HostToDevice,
        }
    }

    fn gone(&self, why: &str) -> LinkError {
        LinkError::Disconnected { port: self.name.clone(), reason: why.into() }
    }
}

impl Drop for PipeEnd {
    fn drop(&mut self) {
        lock(&self.shared).closed[self.tx.index()] = true;
        self.peer_wake.raise();
    }
}

impl Link for PipeEnd {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let now = self.clock.now();
        {
            let mut sh = lock(&self.shared);
            if sh.faults.broken {
                return Err(self.gone("link broken"));
            }
            if sh.closed[self.rx().index()] {
                return Err(self.gone("the other end was closed"));
            }
            if !sh.faults.wires[self.tx.index()].offer(now, bytes) {
                sh.faults.broken = true;
            }
        }
        self.peer_wake.raise();
        self.my_wake.raise();
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let deadline = self.clock.now() + timeout;
        loop {
            let now = self.clock.now();
            let next = {
                let mut sh = lock(&self.shared);
                if sh.faults.broken {
                    return Err(self.gone("link broken"));
                }
                let wire = &mut sh.faults.wires[self.rx().index()];
                let n = wire.take_arrived(now, buf);
                if n > 0 {
                    return Ok(n);
                }
                let next = wire.last_arrival();
                if next.is_none() && sh.closed[self.rx().index()] {
                    return Err(self.gone("the other end was closed"));
                }
                next
            };
            if now >= deadline {
                return Ok(0);
            }
            let until = next.map_or(deadline, |t| t.min(deadline));
            self.my_wake.wait_until(Some(until));
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        let now = self.clock.now();
        let mut sh = lock(&self.shared);
        let wire = &mut sh.faults.wires[self.rx().index()];
        wire.in_flight.retain(|(t, _)| *t > now);
        Ok(())
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

// ---------------------------------------------------------------------------------------------------------
// In-process emulator link

struct EmulatorSide<E> {
    device: E,
    scratch: Vec<u8>,
    /// The last time the device was brought up to date.
    last: Timestamp,
    /// The device's events with their times, once [`EmulatorHost::keep_event_times`] asked for them.
    events: crate::emulator::TimedEvents,
}

impl<E: Emulator> EmulatorSide<E> {
    /// The device's events of the step at `t`, where they are kept.
    fn events_at(&mut self, t: Timestamp) {
        let device = &mut self.device;
        self.events.collect(t, || device.take_events());
    }

    /// Runs the device up to `now`: delivers arrived bytes at their own arrival times, fires its timers in
    /// time order, and puts what it says on the wire to the host.
    fn pump(&mut self, faults: &mut Faults, now: Timestamp) -> bool {
        let mut ok = true;
        loop {
            let byte_at = faults.wires[0].next_arrival().filter(|t| *t <= now);
            let timer_at = self.device.next_wakeup().filter(|t| *t <= now && *t >= self.last);
            let (t, byte) = match (byte_at, timer_at) {
                (Some(b), Some(w)) if w < b => (w, false),
                (Some(b), _) => (b, true),
                (None, Some(w)) => (w, false),
                (None, None) => break,
            };
            self.scratch.clear();
            if byte {
                let mut one = [0u8; 1];
                faults.wires[0].take_arrived(t, &mut one);
                self.device.receive(t, &one, &mut self.scratch);
            } else {
                let before = self.device.next_wakeup();
                self.device.advance(t, &mut self.scratch);
                if self.device.next_wakeup() == before && self.scratch.is_empty() {
                    // A timer that does not move on would spin: let the final advance handle it.
                    self.last = t;
                    self.events_at(t);
                    break;
                }
            }
            self.last = self.last.max(t);
            self.events_at(t);
            if !self.scratch.is_empty() {
                ok &= faults.wires[1].offer(t, &self.scratch);
            }
        }
        self.scratch.clear();
        self.device.advance(now, &mut self.scratch);
        self.last = self.last.max(now);
        self.events_at(now);
        if !self.scratch.is_empty() {
            ok &= faults.wires[1].offer(now, &self.scratch);
        }
        ok
    }
}

/// A shared, in-process emulator that host links connect to; see [`EmulatorLink`].
///
/// The device runs lazily: whenever a link reads, or [`EmulatorHost::with_device`] looks at it, it is
/// brought up to the clock's current time, every byte delivered at the instant it arrived.
pub struct EmulatorHost<E> {
    side: Arc<Mutex<EmulatorSide<E>>>,
    clock: SharedClock,
    config: PipeConfig,
    /// The wires of the connection in use, if any (the device runs against them).
    current: Arc<Mutex<Option<Arc<Mutex<Shared>>>>>,
}

impl<E> Clone for EmulatorHost<E> {
    fn clone(&self) -> Self {
        EmulatorHost {
            side: Arc::clone(&self.side),
            clock: Arc::clone(&self.clock),
            config: self.config,
            current: Arc::clone(&self.current),
        }
    }
}

impl<E: Emulator> EmulatorHost<E> {
    /// Puts `device` behind links timed by `clock` and shaped by `config`.
    pub fn new(device: E, clock: SharedClock, config: PipeConfig) -> Self {
        EmulatorHost {
            side: Arc::new(Mutex::new(EmulatorSide {
                device,
                scratch: Vec::new(),
                last: Timestamp::ZERO,
                events: Default::default(),
            })),
            clock,
            config,
            current: Arc::new(Mutex::new(None)),
        }
    }

    /// A [`Connector`](crate::link::Connector) that plugs a new connection in at each call ([`EmulatorHost::connect`]):
    /// a client that reconnects finds the same device again.
    pub fn connector(&self) -> crate::link::Connector
    where
        E: 'static,
    {
        let host = self.clone();
        Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>))
    }

    /// A new connection to the device (as if a cable were plugged in), with its own fault control. Bytes
    /// still in flight on an earlier connection are lost, as on a real line.
    pub fn connect(&self) -> (EmulatorLink<E>, FaultControl) {
        self.bring_up_to_date();
        if lock(&self.current).is_some() {
            // The earlier connection is unplugged: a telegram it left half-sent is not completed by this one.
            lock(&self.side).device.connection_closed(self.clock.now());
        }
        let wires = Arc::new(Mutex::new(Shared {
            faults: Faults {
                wires: [Wire::new(self.config.byte_time()), Wire::new(self.config.byte_time())],
                broken: false,
            },
            closed: [false; 2],
        }));
        *lock(&self.current) = Some(Arc::clone(&wires));
        let wake = self.clock.signal();
        let control = FaultControl { shared: Arc::clone(&wires), wake: [wake.clone(), wake.clone()] };
        let link = EmulatorLink { host: self.clone(), wires, wake, name: "sim (in-process emulator)".into() };
        (link, control)
    }

    fn bring_up_to_date(&self) {
        let now = self.clock.now();
        let mut side = lock(&self.side);
        let current = lock(&self.current).clone();
        match current {
            Some(wires) => {
                let mut sh = lock(&wires);
                if !side.pump(&mut sh.faults, now) {
                    sh.faults.broken = true;
                }
            }
            None => {
                let side = &mut *side;
                side.scratch.clear();
                side.device.advance(now, &mut side.scratch);
                side.last = side.last.max(now);
                side.events_at(now);
            }
        }
    }

    /// From now on the device's events are kept with the time each happened (the step of the device that
    /// produced it, as the link ran it), for [`EmulatorHost::take_timed_events`]; its own
    /// [`Emulator::take_events`] then gives nothing more.
    pub fn keep_event_times(&self) {
        lock(&self.side).events.keep();
    }

    /// The events kept since the last call ([`EmulatorHost::keep_event_times`]), oldest first, each with the
    /// clock's time at which the device produced it; the device is brought up to date first.
    pub fn take_timed_events(&self) -> Vec<(Timestamp, String)> {
        self.bring_up_to_date();
        lock(&self.side).events.take()
    }

    /// Runs `f` on the device, brought up to the clock's current time first.
    pub fn with_device<R>(&self, f: impl FnOnce(&mut E) -> R) -> R {
        self.bring_up_to_date();
        f(&mut lock(&self.side).device)
    }

    /// The clock that times this emulator.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }
}

/// A host link whose other end is an in-process [`Emulator`], made by [`EmulatorHost::connect`].
pub struct EmulatorLink<E> {
    host: EmulatorHost<E>,
    wires: Arc<Mutex<Shared>>,
    wake: Signal,
    name: String,
}

impl<E> EmulatorLink<E> {
    fn gone(&self, why: &str) -> LinkError {
        LinkError::Disconnected { port: self.name.clone(), reason: why.into() }
    }
}

impl<E: Emulator> Link for EmulatorLink<E> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let now = self.host.clock.now();
        let mut sh = lock(&self.wires);
        if sh.faults.broken {
            return Err(self.gone("link broken"));
        }
        if !sh.faults.wires[Direction::HostToDevice.index()].offer(now, bytes) {
            sh.faults.broken = true;
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let deadline = self.host.clock.now() + timeout;
        loop {
            let now = self.host.clock.now();
            let next = {
                let mut side = lock(&self.host.side);
                let mut sh = lock(&self.wires);
                if sh.faults.broken {
                    return Err(self.gone("link broken"));
                }
                if !side.pump(&mut sh.faults, now) {
                    sh.faults.broken = true;
                    return Err(self.gone("link broken"));
                }
                let n = sh.faults.wires[Direction::DeviceToHost.index()].take_arrived(now, buf);
                if n > 0 {
                    return Ok(n);
                }
                // Wake for the next byte to the host, the next byte the device must see, or a device timer
                // (which may make it speak unasked).
                [
                    sh.faults.wires[Direction::DeviceToHost.index()].last_arrival(),
                    sh.faults.wires[Direction::HostToDevice.index()].last_arrival(),
                    side.device.next_wakeup().filter(|t| *t > now),
                ]
                .into_iter()
                .flatten()
                .min()
            };
            if now >= deadline {
                return Ok(0);
            }
            let until = next.map_or(deadline, |t| t.min(deadline));
            self.wake.wait_until(Some(until));
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        let now = self.host.clock.now();
        let mut side = lock(&self.host.side);
        let mut sh = lock(&self.wires);
        if !side.pump(&mut sh.faults, now) {
            sh.faults.broken = true;
        }
        sh.faults.wires[Direction::DeviceToHost.index()].in_flight.retain(|(t, _)| *t > now);
        Ok(())
    }

    fn send_break(&mut self, duration: Duration) -> Result<(), LinkError> {
        let start = self.host.clock.now();
        {
            let mut side = lock(&self.host.side);
            let mut sh = lock(&self.wires);
            if sh.faults.broken {
                return Err(self.gone("link broken"));
            }
            // What was sent before the break reaches the device first.
            if !side.pump(&mut sh.faults, start) {
                sh.faults.broken = true;
                return Err(self.gone("link broken"));
            }
            side.device.line_break(start, duration);
        }
        // The line is held that long: nothing else goes out meanwhile.
        let end = start + duration;
        while self.host.clock.now() < end {
            self.wake.wait_until(Some(end));
        }
        Ok(())
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

impl<E> Drop for EmulatorLink<E> {
    fn drop(&mut self) {
        let mut current = lock(&self.host.current);
        if current.as_ref().is_some_and(|w| Arc::ptr_eq(w, &self.wires)) {
            *current = None;
        }
    }
}

#[cfg(test)]
mod tests;
