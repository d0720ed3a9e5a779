//! A sans-IO session wired straight to a sans-IO emulator: no link, no thread, no clock but the time this
//! harness moves. What the session sends reaches the emulator after its time on the wire and the line's
//! latency; the emulator's answers come back the same way; the time jumps from one thing that happens to
//! the next (a telegram arriving, the session's or the emulator's next deadline), so minutes of device
//! time run in milliseconds, deterministically. Faults are arranged per test: telegrams lost either way, a
//! byte flipped, a reply held back. Every family's session tests run on it: any
//! [`Session`], any emulator ([`Serial`] around an
//! [`Emulator`](motionlink_link::emulator::Emulator) for a serial line, [`Can`] around a
//! [`CanEmulator`](motionlink_link::can::CanEmulator) for a CAN bus):
//! `Wired::new(session, Serial(emulator), Line::baud(38_400, 10))`, then [`Wired::start`] and
//! [`Wired::wait_done`], [`Wired::run_for`], the records in [`Wired::sent`] and [`Wired::device_events`].

use std::collections::VecDeque;
use std::time::Duration;

mod device;

pub use device::{Can, Device, Serial, SerialOrCan, Telegram};

use motionlink_link::session::{Action, Event, Input, OpId, Session};
use motionlink_link::Timestamp;

/// What an operation of session `S` ends with.
pub type Outcome<S> = Result<<S as Session>::Output, <S as Session>::Error>;

/// The line between the session and the device: its timing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Line {
    /// Wire time of one byte, each way (a frame takes [`Line::frame_time`]).
    pub byte_time: Duration,
    /// Wire time of one CAN frame, each way.
    pub frame_time: Duration,
    /// Latency each way on top of the wire time (a gateway, a slow converter).
    pub one_way: Duration,
    /// The device's answers reach the session byte by byte, each at its own time; otherwise each answer
    /// arrives whole once its last byte is through.
    pub bytewise: bool,
}

impl Line {
    /// No wire time, no latency: what is sent arrives at once.
    pub fn instant() -> Line {
        Line::default()
    }

    /// A serial line at `baud` with `bits` per character (10 for 8N1, 11 with parity).
    pub fn baud(baud: u32, bits: u32) -> Line {
        Line { byte_time: Duration::from_nanos(1_000_000_000 * u64::from(bits) / u64::from(baud)), ..Line::default() }
    }

    /// The same line, its answers delivered byte by byte.
    pub fn bytewise(self) -> Line {
        Line { bytewise: true, ..self }
    }
}

/// Which telegrams to the device are lost (see [`Wired::lose`]).
pub type Loss = Box<dyn FnMut(&Telegram) -> bool>;

/// A session wired to a device; see the [module documentation](self). Fields are the test's to read and
/// to set (the faults, the line's timing) between steps.
pub struct Wired<S: Session, D> {
    /// The session under test.
    pub session: S,
    /// The device at the other end.
    pub device: D,
    /// The time of the harness (the session's and the device's).
    pub now: Timestamp,
    /// The line's timing.
    pub line: Line,
    /// Everything sent to the device is lost while set.
    pub cut: bool,
    /// Everything the device answers is lost while set.
    pub deaf: bool,
    /// Telegrams to the device for which this is true are lost (it may count what it has seen).
    pub lose: Option<Loss>,
    /// The byte with this number (counted from the first sent, see [`Wired::to_device_count`]) is XORed with
    /// the mask on its way to the device.
    pub corrupt_to_device: Option<(u64, u8)>,
    /// Bytes from the device with these numbers (see [`Wired::to_host_count`]) are lost.
    pub drop_to_host: Vec<u64>,
    /// The device's next answer leaves this much later.
    pub hold_next_reply: Option<Duration>,
    /// Bytes sent to the device so far.
    pub to_device_count: u64,
    /// Bytes the device answered so far (lost ones included).
    pub to_host_count: u64,
    /// Everything the session sent, with its time.
    pub sent: Vec<(Timestamp, Telegram)>,
    /// Operations that ended, in order (a test takes them out).
    pub done: Vec<(OpId, Outcome<S>)>,
    /// Progress reports, in order.
    pub progress: Vec<(OpId, S::Progress)>,
    /// The outcome of the close sequence, once it ended.
    pub closed: Option<Result<(), S::Error>>,
    /// What the device did, with its time.
    pub device_events: Vec<(Timestamp, String)>,
    /// How often the session had the port reopened.
    pub reopens: u32,
    /// On their way to the device: when each arrives.
    pub to_device: VecDeque<(Timestamp, Telegram)>,
    /// On their way to the session: when each arrives.
    pub to_host: VecDeque<(Timestamp, Telegram)>,
    /// When each direction's wire has sent everything queued so far.
    device_wire: Timestamp,
    host_wire: Timestamp,
}

impl<S: Session, D: Device> Wired<S, D> {
    /// `session` wired to `device` over `line`, at time zero.
    pub fn new(session: S, device: D, line: Line) -> Self {
        Wired {
            session,
            device,
            now: Timestamp::ZERO,
            line,
            cut: false,
            deaf: false,
            lose: None,
            corrupt_to_device: None,
            drop_to_host: Vec::new(),
            hold_next_reply: None,
            to_device_count: 0,
            to_host_count: 0,
            sent: Vec::new(),
            done: Vec::new(),
            progress: Vec::new(),
            closed: None,
            device_events: Vec::new(),
            reopens: 0,
            to_device: VecDeque::new(),
            to_host: VecDeque::new(),
            device_wire: Timestamp::ZERO,
            host_wire: Timestamp::ZERO,
        }
    }

    /// Starts `op` now.
    pub fn start(&mut self, op: S::Op) -> OpId {
        self.session.start(op, self.now)
    }

    /// Hands over everything the session has to send now.
    pub fn transmit(&mut self) {
        while let Some(action) = self.session.poll_transmit(self.now) {
            match action {
                Action::Send(bytes) => self.send(Telegram::Bytes(bytes)),
                Action::SendFrame(frame) => self.send(Telegram::Frame(frame)),
                Action::DiscardInput => {}
                Action::Reopen => {
                    self.reopens += 1;
                    self.to_host.clear();
                    self.session.handle_reopened(Ok(()), self.now);
                }
            }
        }
    }

    fn send(&mut self, telegram: Telegram) {
        self.sent.push((self.now, telegram.clone()));
        let mut telegram = telegram;
        let on_wire = match &mut telegram {
            Telegram::Bytes(bytes) => {
                for b in bytes.iter_mut() {
                    if let Some((_, mask)) = self.corrupt_to_device.filter(|(at, _)| *at == self.to_device_count) {
                        *b ^= mask;
                    }
                    self.to_device_count += 1;
                }
                self.line.byte_time * bytes.len() as u32
            }
            Telegram::Frame(_) => self.line.frame_time,
        };
        self.device_wire = self.device_wire.max(self.now) + on_wire;
        if self.cut || self.lose.as_mut().is_some_and(|lose| lose(&telegram)) {
            return;
        }
        self.to_device.push_back((self.device_wire + self.line.one_way, telegram));
    }

    /// The device's answers at `now` start on their way back.
    fn answer(&mut self, now: Timestamp, out: Vec<Telegram>) {
        for telegram in out {
            let start = self.host_wire.max(now) + self.hold_next_reply.take().unwrap_or_default();
            match telegram {
                Telegram::Bytes(bytes) if self.line.bytewise => {
                    for (i, b) in bytes.into_iter().enumerate() {
                        let n = self.to_host_count;
                        self.to_host_count += 1;
                        let at = start + self.line.byte_time * (i as u32 + 1);
                        self.host_wire = at;
                        if !self.deaf && !self.drop_to_host.contains(&n) {
                            self.to_host.push_back((at + self.line.one_way, Telegram::Bytes(vec![b])));
                        }
                    }
                }
                Telegram::Bytes(bytes) => {
                    let first = self.to_host_count;
                    self.to_host_count += bytes.len() as u64;
                    self.host_wire = start + self.line.byte_time * bytes.len() as u32;
                    let kept: Vec<u8> = bytes
                        .into_iter()
                        .enumerate()
                        .filter(|(i, _)| !self.drop_to_host.contains(&(first + *i as u64)))
                        .map(|(_, b)| b)
                        .collect();
                    if !self.deaf && !kept.is_empty() {
                        self.to_host.push_back((self.host_wire + self.line.one_way, Telegram::Bytes(kept)));
                    }
                }
                frame @ Telegram::Frame(_) => {
                    self.host_wire = start + self.line.frame_time;
                    if !self.deaf {
                        self.to_host.push_back((self.host_wire + self.line.one_way, frame));
                    }
                }
            }
        }
    }

    /// Takes the session's events into [`Wired::done`], [`Wired::progress`] and [`Wired::closed`]; true if
    /// there were any.
    pub fn collect(&mut self) -> bool {
        let mut any = false;
        while let Some(event) = self.session.poll_event() {
            any = true;
            match event {
                Event::Progress(id, p) => self.progress.push((id, p)),
                Event::Done(id, r) => self.done.push((id, r)),
                Event::Closed(r) => self.closed = Some(r),
            }
        }
        any
    }

    /// Does what the session asks now, takes its events; then moves the time to the next thing that
    /// happens (no later than `horizon`), delivers it and takes the events that followed. False if nothing
    /// happened and nothing ever will.
    pub fn step(&mut self, horizon: Option<Timestamp>) -> bool {
        self.transmit();
        let happened = self.collect();
        let next = [self.next_event(), horizon].into_iter().flatten().min();
        let Some(next) = next else { return happened };
        self.now = self.now.max(next);
        self.deliver();
        self.collect();
        true
    }

    /// When the next thing happens: a telegram arrives, the session's or the device's deadline.
    fn next_event(&self) -> Option<Timestamp> {
        [
            self.session.poll_timeout(),
            self.to_device.front().map(|(t, _)| *t),
            self.to_host.front().map(|(t, _)| *t),
            self.device.next_wakeup(),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Delivers everything due at the present time: to the device (and its answers on their way), to the
    /// session; the session's deadline if it is due.
    fn deliver(&mut self) {
        let now = self.now;
        let mut out = Vec::new();
        while self.to_device.front().is_some_and(|(t, _)| *t <= now) {
            let (_, telegram) = self.to_device.pop_front().expect("checked");
            self.device.receive(now, &telegram, &mut out);
        }
        self.device.advance(now, &mut out);
        for e in self.device.take_events() {
            self.device_events.push((now, e));
        }
        self.answer(now, out);
        let mut bytes = Vec::new();
        while self.to_host.front().is_some_and(|(t, _)| *t <= now) {
            match self.to_host.pop_front().expect("checked").1 {
                Telegram::Bytes(b) => bytes.extend(b),
                Telegram::Frame(f) => {
                    if !bytes.is_empty() {
                        self.session.handle_input(Input::Bytes(&std::mem::take(&mut bytes)), now);
                    }
                    self.session.handle_input(Input::Frame(&f), now);
                }
            }
        }
        if !bytes.is_empty() {
            self.session.handle_input(Input::Bytes(&bytes), now);
        }
        if self.session.poll_timeout().is_some_and(|t| t <= now) {
            self.session.handle_timeout(now);
        }
    }

    /// Everything that happens at the present time without the time moving: what the session sends, the
    /// device's answers on an instant line, the session's reaction to them, until nothing more does; then
    /// the session's events.
    pub fn settle(&mut self) {
        loop {
            self.transmit();
            let due = |q: &VecDeque<(Timestamp, Telegram)>| q.front().is_some_and(|(t, _)| *t <= self.now);
            if !due(&self.to_device) && !due(&self.to_host) {
                break;
            }
            self.deliver();
        }
        self.collect();
    }

    /// Settles, then goes on to the next thing that happens if it happens no later than `limit`; false (and
    /// the time unchanged) if nothing does.
    pub fn step_before(&mut self, limit: Timestamp) -> bool {
        self.settle();
        match self.next_event() {
            Some(t) if t <= limit => {
                self.now = self.now.max(t);
                self.deliver();
                self.settle();
                true
            }
            _ => false,
        }
    }

    /// Steps until `until` holds, for at most `limit` of harness time. The time must move on: a session that
    /// asks to be woken at the same time again and again is a busy loop, and fails the test.
    pub fn run_until(&mut self, limit: Duration, until: impl FnMut(&Self) -> bool) {
        self.advance_until(limit, None, until);
    }

    fn advance_until(&mut self, limit: Duration, horizon: Option<Timestamp>, mut until: impl FnMut(&Self) -> bool) {
        let give_up = self.now + limit;
        let mut still = 0;
        while !until(self) {
            assert!(self.now < give_up, "not reached within {limit:?}; at {}", self.now);
            let before = self.now;
            assert!(self.step(horizon), "nothing more happens at {}", self.now);
            still = if self.now == before { still + 1 } else { 0 };
            assert!(still < 1000, "the session spins at {}", self.now);
        }
    }

    /// Lets `d` of harness time pass, everything that happens meanwhile done; ends at exactly `now + d`, with
    /// what the session sends at that time handed over.
    pub fn run_for(&mut self, d: Duration) {
        let end = self.now + d;
        self.advance_until(d + Duration::from_secs(1), Some(end), |b| b.now >= end);
        self.transmit();
        self.collect();
    }

    /// Starts `op` and runs it to its end (at most an hour of harness time).
    pub fn run_op(&mut self, op: S::Op) -> Result<S::Output, S::Error> {
        let id = self.start(op);
        self.wait_done(id)
    }

    /// Runs until operation `id` ends (at most an hour of harness time), and takes its result.
    pub fn wait_done(&mut self, id: OpId) -> Result<S::Output, S::Error> {
        self.wait_done_within(id, Duration::from_secs(3600))
    }

    /// Runs until operation `id` ends (at most `limit`), and takes its result.
    pub fn wait_done_within(&mut self, id: OpId, limit: Duration) -> Result<S::Output, S::Error> {
        self.run_until(limit, |b| b.done.iter().any(|(d, _)| *d == id));
        self.take_done(id).expect("it ended")
    }

    /// The result of operation `id`, if it has ended (taken out of [`Wired::done`]).
    pub fn take_done(&mut self, id: OpId) -> Option<Result<S::Output, S::Error>> {
        self.collect();
        let i = self.done.iter().position(|(d, _)| *d == id)?;
        Some(self.done.remove(i).1)
    }

    /// Closes the session and runs until its close sequence ended (at most `limit`); its outcome.
    pub fn close_session(&mut self, limit: Duration) -> Result<(), S::Error> {
        self.session.close(self.now);
        self.run_until(limit, |b| b.closed.is_some());
        self.closed.take().expect("it closed")
    }

    /// When the device first did something whose description starts with `prefix`.
    pub fn device_saw(&self, prefix: &str) -> Option<Timestamp> {
        self.device_events.iter().find(|(_, e)| e.starts_with(prefix)).map(|(t, _)| *t)
    }
}
