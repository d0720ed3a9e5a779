//! The toy device and its session, shared by the driver tests: a protocol with every duty a device session
//! has (see tests/driver.rs).

#![allow(dead_code)]

use std::collections::{HashMap, VecDeque};
use std::time::Duration;

use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::Emulator;
use motionlink_link::error::{Classify, ErrorClass, TransportKind};
use motionlink_link::session::{Action, Event, Input, OpId, OpIds, Session, SessionError};
use motionlink_link::LinkError;

// ----------------------------------------------------------------------------------------------------------
// The toy device

#[derive(Default)]
pub struct Toy {
    pub line: Vec<u8>,
    pub position: i64,
    pub target: i64,
    pub moving_since: Option<Timestamp>,
    pub last_ping: Timestamp,
    pub watchdog_stops: u32,
    pub pings: Vec<Timestamp>,
    pub commands: Vec<String>,
}

impl Toy {
    fn run_until(&mut self, now: Timestamp) {
        while let Some(since) = self.moving_since {
            let step = since + Duration::from_millis(10);
            if step > now {
                break;
            }
            if step > self.last_ping + Duration::from_millis(100) {
                self.moving_since = None;
                self.watchdog_stops += 1;
                break;
            }
            self.position += (self.target - self.position).signum();
            self.moving_since = (self.position != self.target).then_some(step);
        }
    }
}

impl Emulator for Toy {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        self.run_until(now);
        for &b in bytes {
            if b != b'\n' {
                self.line.push(b);
                continue;
            }
            let line = String::from_utf8_lossy(&std::mem::take(&mut self.line)).to_string();
            self.commands.push(line.clone());
            let reply = match line.split_once(' ').unwrap_or((&line, "")) {
                ("GET", _) => format!("VAL {}", self.position),
                ("MOVE", t) => {
                    self.target = t.parse().unwrap_or(self.position);
                    if self.target != self.position {
                        self.moving_since = Some(now);
                    }
                    "OK".into()
                }
                ("STOP", _) => {
                    self.moving_since = None;
                    "OK".into()
                }
                ("PING", _) => {
                    self.last_ping = now;
                    self.pings.push(now);
                    "PONG".into()
                }
                _ => "ERR".into(),
            };
            out.extend_from_slice(reply.as_bytes());
            out.push(b'\n');
        }
    }
    fn advance(&mut self, now: Timestamp, _out: &mut Vec<u8>) {
        self.run_until(now);
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        self.moving_since.map(|t| t + Duration::from_millis(10))
    }
    fn connection_closed(&mut self, _now: Timestamp) {
        self.line.clear();
    }
}

// ----------------------------------------------------------------------------------------------------------
// The toy session

#[derive(Debug, thiserror::Error)]
pub enum ToyError {
    #[error("no answer")]
    Timeout,
    #[error("cancelled")]
    Cancelled,
    #[error("closed")]
    Closed,
    #[error("close unconfirmed")]
    Unconfirmed,
    #[error("{0}")]
    Link(#[from] LinkError),
}

impl Classify for ToyError {
    fn class(&self) -> ErrorClass {
        match self {
            ToyError::Timeout | ToyError::Unconfirmed => ErrorClass::Transport(TransportKind::Timeout),
            ToyError::Cancelled => ErrorClass::Cancelled,
            ToyError::Closed => ErrorClass::Usage,
            ToyError::Link(e) => e.class(),
        }
    }
}

impl SessionError for ToyError {
    fn close_timed_out(_bound: Duration) -> Self {
        ToyError::Unconfirmed
    }
    fn session_closed() -> Self {
        ToyError::Closed
    }
}

pub enum Op {
    Get,
    Move(i64),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Who {
    Op(OpId),
    Keepalive,
    Close,
}

pub enum Phase {
    Get,
    Moving { next_poll: Option<Timestamp> },
    Stopping,
}

pub struct ToySession {
    pub ids: OpIds,
    pub ops: HashMap<OpId, (Phase, i64)>,
    pub queue: VecDeque<(Who, String)>,
    pub in_flight: Option<(Who, String, Timestamp, u32)>,
    pub rx: Vec<u8>,
    pub events: VecDeque<Event<ToySession>>,
    pub next_ping: Timestamp,
    pub moving: bool,
    pub closing: bool,
    /// Whether the session keeps the device alive with PING (on by default).
    pub pings: bool,
    pub sent: Vec<String>,
    /// The name of the thread that asked for each telegram to be sent.
    pub sent_by: Vec<Option<String>>,
    /// How often the driver's background thread looked at the session.
    pub background_looks: std::sync::atomic::AtomicU32,
    pub retries: HashMap<String, u32>,
    /// Report each look twice, the second as its negative (two reports in one go, before a caller reads).
    pub double_progress: bool,
}

const ANSWER: Duration = Duration::from_millis(20);
const PING: Duration = Duration::from_millis(30);
const POLL: Duration = Duration::from_millis(10);

impl ToySession {
    pub fn new(now: Timestamp) -> Self {
        ToySession {
            ids: OpIds::default(),
            ops: HashMap::new(),
            queue: VecDeque::new(),
            in_flight: None,
            rx: Vec::new(),
            events: VecDeque::new(),
            next_ping: now,
            moving: false,
            closing: false,
            pings: true,
            double_progress: false,
            sent: Vec::new(),
            sent_by: Vec::new(),
            background_looks: std::sync::atomic::AtomicU32::new(0),
            retries: HashMap::new(),
        }
    }

    fn finish(&mut self, id: OpId, r: Result<i64, ToyError>) {
        if self.ops.remove(&id).is_some() {
            self.events.push_back(Event::Done(id, r));
        }
    }

    fn stop(&mut self, who: Who) {
        self.queue.push_front((who, "STOP".into()));
    }

    fn answer(&mut self, who: Who, request: &str, reply: &str, now: Timestamp) {
        match who {
            Who::Keepalive => {}
            Who::Close => {
                self.moving = false;
                self.events.push_back(Event::Closed(Ok(())));
            }
            Who::Op(id) => {
                let value: i64 = reply.strip_prefix("VAL ").and_then(|v| v.parse().ok()).unwrap_or(0);
                let Some((phase, target)) = self.ops.get_mut(&id) else { return };
                let target = *target;
                match phase {
                    Phase::Get => self.finish(id, Ok(value)),
                    Phase::Stopping => {
                        self.moving = false;
                        self.finish(id, Err(ToyError::Cancelled));
                    }
                    Phase::Moving { next_poll } => {
                        if request.starts_with("MOVE") {
                            self.moving = true;
                            *next_poll = Some(now + POLL);
                        } else if value == target {
                            self.moving = false;
                            // The last look comes with the end (as a watch's last sample does).
                            self.events.push_back(Event::Progress(id, value));
                            self.finish(id, Ok(value));
                        } else {
                            *next_poll = Some(now + POLL);
                            self.events.push_back(Event::Progress(id, value));
                            if self.double_progress {
                                self.events.push_back(Event::Progress(id, -value));
                            }
                        }
                    }
                }
            }
        }
    }
}

impl Session for ToySession {
    type Op = Op;
    type Output = i64;
    type Progress = i64;
    type Error = ToyError;

    fn start(&mut self, op: Op, _now: Timestamp) -> OpId {
        let id = self.ids.next_id();
        match op {
            Op::Get => {
                self.ops.insert(id, (Phase::Get, 0));
                self.queue.push_back((Who::Op(id), "GET".into()));
            }
            Op::Move(t) => {
                self.ops.insert(id, (Phase::Moving { next_poll: None }, t));
                self.queue.push_back((Who::Op(id), format!("MOVE {t}")));
            }
        }
        id
    }

    fn cancel(&mut self, id: OpId, _now: Timestamp) {
        match self.ops.get_mut(&id) {
            Some((phase @ Phase::Moving { .. }, _)) => {
                *phase = Phase::Stopping;
                self.queue.retain(|(w, _)| *w != Who::Op(id));
                self.stop(Who::Op(id));
            }
            Some(_) => self.finish(id, Err(ToyError::Cancelled)),
            None => {}
        }
    }

    fn close(&mut self, now: Timestamp) {
        self.closing = true;
        let ids: Vec<OpId> = self.ops.keys().copied().collect();
        for id in ids {
            self.cancel(id, now);
        }
        self.stop(Who::Close);
    }

    fn handle_input(&mut self, input: Input<'_>, now: Timestamp) {
        let Input::Bytes(bytes) = input else { return };
        for &b in bytes {
            if b != b'\n' {
                self.rx.push(b);
                continue;
            }
            let reply = String::from_utf8_lossy(&std::mem::take(&mut self.rx)).to_string();
            if let Some((who, request, _, _)) = self.in_flight.take() {
                self.answer(who, &request, &reply, now);
            }
        }
    }

    fn handle_link_error(&mut self, error: LinkError, _now: Timestamp) {
        let ids: Vec<OpId> = self.ops.keys().copied().collect();
        let text = error.to_string();
        for id in ids {
            self.finish(id, Err(ToyError::Link(LinkError::Disconnected { port: "toy".into(), reason: text.clone() })));
        }
    }

    fn handle_reopened(&mut self, _result: Result<(), LinkError>, _now: Timestamp) {}

    fn poll_transmit(&mut self, now: Timestamp) -> Option<Action> {
        if self.in_flight.is_some() {
            return None;
        }
        let (who, text) = self.queue.pop_front()?;
        self.sent.push(text.clone());
        self.sent_by.push(std::thread::current().name().map(str::to_string));
        let bytes = format!("{text}\n").into_bytes();
        let tries = self.retries.remove(&text).unwrap_or(0);
        self.in_flight = Some((who, text, now, tries));
        Some(Action::Send(bytes))
    }

    fn poll_timeout(&self) -> Option<Timestamp> {
        if std::thread::current().name() == Some("motionlink-driver") {
            self.background_looks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        let polls = self.ops.values().filter_map(|(p, _)| match p {
            Phase::Moving { next_poll } => *next_poll,
            _ => None,
        });
        let answer = self.in_flight.as_ref().map(|(_, _, at, _)| *at + ANSWER);
        let ping = (!self.closing && self.pings).then_some(self.next_ping);
        polls.chain(answer).chain(ping).min()
    }

    fn handle_timeout(&mut self, now: Timestamp) {
        if let Some((who, text, at, tries)) = &mut self.in_flight {
            if now >= *at + ANSWER {
                if *tries < 2 {
                    self.retries.insert(text.clone(), *tries + 1);
                    let (who, text) = (*who, text.clone());
                    self.in_flight = None;
                    self.queue.push_front((who, text));
                } else if let Who::Op(id) = *who {
                    self.in_flight = None;
                    self.finish(id, Err(ToyError::Timeout));
                } else {
                    self.in_flight = None;
                }
            }
        }
        if !self.closing && self.pings && now >= self.next_ping {
            // Deadline-based: the next ping is due one period after the last due time, not after sending.
            while self.next_ping <= now {
                self.next_ping += PING;
            }
            self.queue.push_front((Who::Keepalive, "PING".into()));
        }
        for (id, (phase, _)) in self.ops.iter_mut() {
            if let Phase::Moving { next_poll: Some(t) } = phase {
                if now >= *t {
                    *phase = Phase::Moving { next_poll: None };
                    self.queue.push_back((Who::Op(*id), "GET".into()));
                }
            }
        }
    }

    fn poll_event(&mut self) -> Option<Event<Self>> {
        self.events.pop_front()
    }

    fn wants_input(&self) -> bool {
        self.in_flight.is_some()
    }

    fn is_idle(&self) -> bool {
        self.ops.is_empty() && self.queue.is_empty() && self.in_flight.is_none()
    }
}
