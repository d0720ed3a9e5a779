//! The SCU protocol as a sans-IO [`Session`](motionlink_link::session::Session): bytes in with the time,
//! bytes out, the next deadline, and events; no thread, no clock of its own, no I/O. A
//! [`Driver`](motionlink_link::driver::Driver) runs it over a link ([`crate::Client`], `AsyncClient`);
//! tests wire it directly to the emulator.
//!
//! ```
//! use motionlink_link::emulator::Emulator as _;
//! use motionlink_link::session::{Action, Event, Input, Session as _};
//! use motionlink_link::Timestamp;
//! use motionlink_scu::{ClientConfig, Emulator, Op, Session, SimConfig};
//!
//! let mut unit = Emulator::new(SimConfig::default())?;
//! let mut session = Session::new(ClientConfig::default(), Timestamp::ZERO)?;
//! let open = session.start(Op::Open, Timestamp::ZERO);
//! let mut now = Timestamp::ZERO;
//! loop {
//!     while let Some(action) = session.poll_transmit(now) {
//!         if let Action::Send(bytes) = action {
//!             let mut reply = Vec::new();
//!             unit.receive(now, &bytes, &mut reply);
//!             session.handle_input(Input::Bytes(&reply), now);
//!         }
//!     }
//!     if let Some(Event::Done(id, result)) = session.poll_event() {
//!         assert_eq!(id, open);
//!         result?;
//!         break;
//!     }
//!     now = session.poll_timeout().unwrap_or(now);
//!     session.handle_timeout(now);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Duties
//!
//! - **Requests** go out one at a time (the line is half-duplex); each is matched with its reply by command
//!   and expected length, and repeated as the crate documentation says ("Decisions": "Reply timeout and
//!   retries" and "RE is repeated").
//! - **The keepalive**: an RC on a grid of deadlines one [`crate::ClientConfig::keepalive_period`] apart
//!   (it cannot drift), or one [`crate::ClientConfig::poll_interval`] apart while a motion is polled through
//!   it: then each RC carries the session's poll object and reads the status and position of every actuator,
//!   so every exchange of a move feeds the unit's watchdog.
//! - **Room on the line**: a request other than RC goes out only if its reply is expected back (by the round
//!   trip measured so far) before the latest time the next RC must be sent, [`crate::config::RC_DEADLINE`]
//!   after the last one; so a link with round trips of 300 ms still keeps the unit alive during a move, which
//!   it then watches through the RC alone. A request that finds no room within
//!   [`crate::config::MAX_ROOM_WAIT`] fails ([`crate::Error::NoRoom`]); stops are never held back.
//! - **Operations** ([`Op`]) are state machines that end with one [`Event::Done`](motionlink_link::session::Event);
//!   a cancelled one stops what it started (RS for every RE); [`Session::close`](motionlink_link::session::Session::close)
//!   cancels them all, sends RS for every function still started, then RA, and reports [`Event::Closed`](motionlink_link::session::Event).

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::Duration;

use motionlink_link::session::{Action, Event, Input, OpId, OpIds, Session as SessionTrait};
use motionlink_link::{LinkError, Timestamp};

use crate::config::{ClientConfig, MAX_ROOM_WAIT};
use crate::error::Error;
use crate::model::{CyclicObject, DataIndex};
use crate::wire::Command;

mod caps;
mod core;
mod engine;
mod line;
pub(crate) mod ops;
pub(crate) mod report;
mod request;
mod txn;

pub use caps::Capabilities;
use line::{Exchange, Line, LineCounts};
pub use ops::WatchSpec;
use ops::{Cx, Operation, Resume};
pub use ops::{MoveSpec, MoveTargets, Op, Output, Progress, RunAction, RunSpec};
pub use report::{
    ActuatorOutcome, ActuatorRest, ClientStats, MoveProgress, MoveReport, RefusedStop, RunProgress, RunReport,
    SetReport, Snapshot, StopReport,
};
pub(crate) use request::{OwnedReply, Req, Schedule};

pub use request::PreparedRequest;
use txn::Txn;

/// Where the session stands with the unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum State {
    /// Not yet opened (RO and RC not yet acknowledged).
    Opening,
    /// Remote mode, keepalive running.
    Open,
    /// The unit ended remote mode; every request fails with this message until reopened.
    Ended(String),
    /// The port is lost.
    Lost(String),
    /// The session has ended.
    Closed,
}

/// The cyclic object the keepalive RC carries for the caller.
#[derive(Debug, Clone)]
pub(crate) struct CyclicUse {
    pub slot: u8,
    pub object: CyclicObject,
    pub write: Vec<u8>,
}

/// The session's own cyclic object, which watches motions and samples the state.
#[derive(Debug, Default)]
pub(crate) struct PollObject {
    /// Its definition was written and read back, and an RC carrying it was answered.
    pub configured: bool,
    /// The unit did not take it: motions are watched with reads.
    pub refused: bool,
}

impl PollObject {
    /// The unit does not take the object (`why`): motions and samples are read with RG from now on; said
    /// once per session.
    pub fn refuse(&mut self, why: &str) {
        if !self.refused {
            tracing::warn!("{why}: this session watches motions and samples with reads (RG) instead");
        }
        self.refused = true;
        self.configured = false;
    }
}

/// The indices the session's cyclic object reads: status 1 of every actuator, every position, every
/// current, and Error_Code 1 (46 bytes).
pub(crate) const POLL_READ: [DataIndex; 4] =
    [DataIndex(0x0170), DataIndex(0x0010), DataIndex(0x00A0), DataIndex(0x00D1)];

/// The number of bytes the session's cyclic object reads.
pub(crate) const POLL_READ_LEN: usize = 6 + 24 + 12 + 4;

/// Who is waiting for the exchange under way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Owner {
    Op(OpId),
    Keepalive(Carries),
}

/// What a keepalive RC carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Carries {
    Nothing,
    CallersObject,
    PollObject,
}

struct InFlight {
    owner: Owner,
    txn: Option<Txn>,
    exchange: Exchange,
}

struct Queued {
    owner: OpId,
    req: Req,
    at: Timestamp,
}

/// What an operation waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Waiting {
    Nothing,
    Queued,
    InFlight,
    Until(Timestamp),
    Snapshot,
    Reopen,
}

/// How an operation's end is reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// [`Event::Done`].
    Public,
    /// The end of the session: [`Event::Closed`].
    Close,
    /// The session's own (an automatic reconnection): logged.
    Internal,
}

struct Slot {
    op: Box<dyn Operation>,
    waiting: Waiting,
    kind: Kind,
    cancelled: bool,
}

/// Everything but the operations.
pub(crate) struct Core {
    pub config: ClientConfig,
    pub now: Timestamp,
    ids: OpIds,
    pub line: Line,
    counts: LineCounts,
    in_flight: Option<InFlight>,
    outbox: VecDeque<Action>,
    queue: VecDeque<Queued>,
    pub state: State,
    /// The port is there (not lost, not being reopened).
    pub link_up: bool,
    /// Functions started with RE and not yet stopped with an acknowledged RS (wire ids).
    pub started: BTreeSet<u8>,
    pub stats: ClientStats,
    /// When the next RC is due: a grid of deadlines.
    keepalive_due: Timestamp,
    /// When the last RC went out.
    last_rc_sent: Option<Timestamp>,
    last_was_rc: bool,
    next_reconnect: Timestamp,
    reopen_waiter: Option<OpId>,
    pub cyclic: Option<CyclicUse>,
    pub last_cyclic_read: Option<(Timestamp, Vec<u8>)>,
    pub poll: PollObject,
    /// What the unit was found to do beyond the manual's words.
    pub(crate) probed: caps::Probed,
    /// Operations waiting for the next poll of a motion.
    subscribers: BTreeSet<OpId>,
    events: VecDeque<Event<Session>>,
    closing: bool,
}

/// The SCU protocol as a sans-IO session. See the [module documentation](self).
pub struct Session {
    core: Core,
    ops: BTreeMap<OpId, Slot>,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("state", &self.core.state)
            .field("started", &self.core.started)
            .field("operations", &self.ops.len())
            .finish()
    }
}

impl Session {
    /// A session with `config` (checked) at `now`. Nothing is sent until [`Op::Open`] is started.
    pub fn new(config: ClientConfig, now: Timestamp) -> Result<Session, Error> {
        config.validate()?;
        Ok(Session {
            core: Core {
                config,
                now,
                ids: OpIds::default(),
                line: Line::default(),
                counts: LineCounts::default(),
                in_flight: None,
                outbox: VecDeque::new(),
                queue: VecDeque::new(),
                state: State::Opening,
                link_up: true,
                started: BTreeSet::new(),
                stats: ClientStats::default(),
                keepalive_due: now,
                last_rc_sent: None,
                last_was_rc: false,
                next_reconnect: now,
                reopen_waiter: None,
                cyclic: None,
                last_cyclic_read: None,
                poll: PollObject::default(),
                probed: caps::Probed::default(),
                subscribers: BTreeSet::new(),
                events: VecDeque::new(),
                closing: false,
            },
            ops: BTreeMap::new(),
        })
    }

    /// The session's settings.
    pub fn config(&self) -> &ClientConfig {
        &self.core.config
    }

    /// Counters of the session.
    pub fn stats(&self) -> ClientStats {
        let mut s = self.core.stats;
        s.retries = self.core.counts.retries;
        s.flushes = self.core.counts.flushes;
        s
    }

    /// Functions started with RE and not yet stopped (wire ids).
    pub fn started_functions(&self) -> Vec<u8> {
        self.core.started.iter().copied().collect()
    }

    /// True while the session is open (not lost, not ended by the unit, not closed).
    pub fn is_open(&self) -> bool {
        self.core.state == State::Open
    }

    /// Why the session is not open, if it is not: lost, ended by the unit, or closed.
    pub fn not_open_reason(&self) -> Option<String> {
        match &self.core.state {
            State::Open => None,
            State::Opening => Some("the session is not open yet".into()),
            State::Ended(why) => Some(why.clone()),
            State::Lost(why) => Some(format!("session lost: {why}")),
            State::Closed => Some("the session is closed".into()),
        }
    }

    /// The read data of the latest keepalive RC that carried the caller's cyclic object, with its time and
    /// the object.
    pub fn last_cyclic_read(&self) -> Option<(Timestamp, CyclicObject, Vec<u8>)> {
        let (t, data) = self.core.last_cyclic_read.clone()?;
        Some((t, self.core.cyclic.as_ref()?.object, data))
    }

    /// Keepalive RCs carry no cyclic object of the caller's again.
    pub fn stop_cyclic(&mut self) {
        self.core.cyclic = None;
        self.core.last_cyclic_read = None;
    }

    /// The caller wrote the definition of CyclicObj `slot`: if the session polls motions through it, it
    /// defines it again before the next move.
    pub fn cyclic_slot_written(&mut self, slot: u8) {
        if self.core.poll_slot() == Some(slot) {
            self.core.poll.configured = false;
        }
    }

    /// The round trip the session measured lately (the longest, decaying).
    pub fn round_trip(&self) -> Duration {
        self.core.line.round_trip
    }

    /// What the session found the unit to do where the manual leaves it open (probed as checks needed it).
    pub fn capabilities(&self) -> Capabilities {
        self.core.probed.caps
    }

    /// Takes what `known` says of the unit (from a device profile, or a probe) where this session has not
    /// found out yet: those behaviours are not probed again, and no warning is given for them. A finding of
    /// the session stays.
    pub fn seed_capabilities(&mut self, known: Capabilities) {
        self.core.probed.caps = self.core.probed.caps.or(known);
    }
}

impl SessionTrait for Session {
    type Op = Op;
    type Output = Output;
    type Progress = Progress;
    type Error = Error;

    fn start(&mut self, op: Op, now: Timestamp) -> OpId {
        self.core.now = now;
        if self.core.closing || self.core.state == State::Closed {
            let id = self.core.ids.next_id();
            self.core.events.push_back(Event::Done(id, Err(Error::Closed)));
            return id;
        }
        let op = ops::operation(op, &self.core);
        self.add_op(op, Kind::Public)
    }

    fn cancel(&mut self, id: OpId, now: Timestamp) {
        self.core.now = now;
        let Some(slot) = self.ops.get_mut(&id) else { return };
        if slot.cancelled || slot.kind != Kind::Public {
            return;
        }
        slot.cancelled = true;
        if !slot.op.interruptible() {
            return;
        }
        match slot.waiting {
            Waiting::Queued => {
                let Some(i) = self.core.queue.iter().position(|q| q.owner == id) else { return };
                let q = self.core.queue.remove(i).expect("found in the queue");
                slot.waiting = Waiting::Nothing;
                self.advance(id, Resume::Reply(Err(Error::CancelledBeforeSending(q.req.request.command))));
            }
            Waiting::Until(_) | Waiting::Snapshot | Waiting::Nothing => {
                slot.waiting = Waiting::Nothing;
                self.core.subscribers.remove(&id);
                self.advance(id, Resume::Wake);
            }
            Waiting::InFlight | Waiting::Reopen => {}
        }
    }

    fn close(&mut self, now: Timestamp) {
        self.core.now = now;
        if self.core.closing {
            return;
        }
        self.core.closing = true;
        let public: Vec<OpId> = self.ops.iter().filter(|(_, s)| s.kind == Kind::Public).map(|(id, _)| *id).collect();
        for id in public {
            self.cancel(id, now);
        }
        self.maybe_start_close();
    }

    fn handle_input(&mut self, input: Input<'_>, now: Timestamp) {
        self.core.now = now;
        let Input::Bytes(bytes) = input else { return };
        let core = &mut self.core;
        let Some(f) = core.in_flight.as_mut() else {
            core.line.take_unsolicited(bytes, now);
            return;
        };
        let outcome = f.exchange.on_input(bytes, &mut core.line, &core.config, &mut core.counts, now, &mut core.outbox);
        if let Some(result) = outcome {
            let f = core.in_flight.take().expect("checked above");
            self.exchange_done(f.owner, f.txn, result);
        }
    }

    fn handle_link_error(&mut self, error: LinkError, now: Timestamp) {
        self.core.now = now;
        if self.core.reopen_waiter.is_some() || !self.core.link_up {
            return;
        }
        self.lost(error.to_string());
    }

    fn handle_reopened(&mut self, result: Result<(), LinkError>, now: Timestamp) {
        self.core.now = now;
        let Some(id) = self.core.reopen_waiter.take() else { return };
        let result = match result {
            Ok(()) => {
                self.core.reset_line();
                Ok(())
            }
            Err(e) => Err(Error::from(e)),
        };
        if let Some(slot) = self.ops.get_mut(&id) {
            slot.waiting = Waiting::Nothing;
        }
        self.advance(id, Resume::Reopened(result));
    }

    fn poll_transmit(&mut self, now: Timestamp) -> Option<Action> {
        self.core.now = now;
        if let Some(a) = self.core.outbox.pop_front() {
            return Some(a);
        }
        self.schedule();
        self.core.outbox.pop_front()
    }

    fn poll_timeout(&self) -> Option<Timestamp> {
        let core = &self.core;
        let timers = self.ops.values().filter_map(|s| match s.waiting {
            Waiting::Until(t) => Some(t),
            _ => None,
        });
        let mut next = timers.min();
        let mut consider = |t: Timestamp| next = Some(next.map_or(t, |n: Timestamp| n.min(t)));
        if let Some(f) = &core.in_flight {
            consider(f.exchange.timeout_at());
        } else if core.link_up && core.reopen_waiter.is_none() {
            if core.keepalive_running() {
                // An RC held back by late replies to an earlier RC goes out when they came or their time is up.
                match core.line.late {
                    Some(late) if core.line.held_by_late(Command::Cyclic, core.now) => {
                        consider(core.keepalive_due.max(late.until))
                    }
                    _ => consider(core.keepalive_due),
                }
            }
            if let Some(late) = core.line.late {
                consider(late.until);
            }
            for q in &core.queue {
                if q.req.schedule != Schedule::Now {
                    consider(q.at + MAX_ROOM_WAIT);
                }
            }
        }
        if matches!(core.state, State::Lost(_)) && core.config.auto_reconnect && !core.closing {
            consider(core.next_reconnect);
        }
        next
    }

    fn handle_timeout(&mut self, now: Timestamp) {
        self.core.now = now;
        {
            let core = &mut self.core;
            if let Some(f) = core.in_flight.as_mut() {
                if let Some(result) =
                    f.exchange.on_timeout(&mut core.line, &core.config, &mut core.counts, now, &mut core.outbox)
                {
                    let f = core.in_flight.take().expect("checked above");
                    self.exchange_done(f.owner, f.txn, result);
                }
            }
        }
        self.core.line.expire_late(now);
        let due: Vec<OpId> = self
            .ops
            .iter()
            .filter(|(_, s)| matches!(s.waiting, Waiting::Until(t) if t <= now))
            .map(|(id, _)| *id)
            .collect();
        for id in due {
            engine::slot_mut(&mut self.ops, id).waiting = Waiting::Nothing;
            self.advance(id, Resume::Wake);
        }
        self.fail_roomless(now);
        let core = &self.core;
        let reconnect = matches!(core.state, State::Lost(_))
            && core.config.auto_reconnect
            && !core.closing
            && now >= core.next_reconnect
            && core.reopen_waiter.is_none()
            && !self.ops.values().any(|s| s.kind == Kind::Internal);
        if reconnect {
            self.core.next_reconnect = now + self.core.config.reconnect_interval;
            self.add_op(Box::new(ops::Reopen::new(true)), Kind::Internal);
        }
    }

    fn poll_event(&mut self) -> Option<Event<Self>> {
        self.core.events.pop_front()
    }

    fn wants_input(&self) -> bool {
        self.core.in_flight.is_some() || self.core.line.late.is_some()
    }

    fn is_idle(&self) -> bool {
        self.ops.is_empty()
            && self.core.queue.is_empty()
            && self.core.in_flight.is_none()
            && self.core.outbox.is_empty()
    }
}
