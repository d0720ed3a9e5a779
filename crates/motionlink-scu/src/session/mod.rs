//! The SCU protocol as a sans-IO [`Session`](motionlink_link::session::Session): bytes in with the time,
//! bytes out, the next deadline, and events; no thread, no clock of its own, no I/O. A
//! [`Driver`](motionlink_link::driver::Driver) runs it over a link ([`crate::Client`], [`crate::AsyncClient`]);
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
//!   and expected length, and repeated as the crate documentation ("Replies, retries and a dead link") says.
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

use crate::config::{ClientConfig, MovePolling, MAX_ROOM_WAIT, RC_DEADLINE};
use crate::error::Error;
use crate::model::{CyclicObject, DataIndex, SafetyId};
use crate::wire::{Command, Request, Status};

mod line;
pub(crate) mod ops;
pub(crate) mod report;
mod request;
mod txn;

use line::{Exchange, Line, LineCounts};
use ops::{Cx, Next, Operation, Resume};
pub use ops::{MoveSpec, MoveTargets, Op, Output, Progress, RunAction, RunSpec};
pub use report::{ActuatorOutcome, ClientStats, MoveProgress, MoveReport, RunProgress, RunReport, Snapshot};
pub(crate) use request::{OwnedReply, Req, Schedule};

pub use request::PreparedRequest;
use txn::{Txn, TxnStep};

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

/// The session's own cyclic object, which polls motions.
#[derive(Debug, Default)]
pub(crate) struct PollObject {
    /// Its definition was written and read back.
    pub configured: bool,
    /// The unit refused it: motions are polled with reads.
    pub refused: bool,
}

/// The indices the poll object reads: status 1 of every actuator, then every position.
pub(crate) const POLL_READ: [DataIndex; 2] = [DataIndex(0x0170), DataIndex(0x0010)];

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

    fn add_op(&mut self, op: Box<dyn Operation>, kind: Kind) -> OpId {
        let id = self.core.ids.next_id();
        self.ops.insert(id, Slot { op, waiting: Waiting::Nothing, kind, cancelled: false });
        self.advance(id, Resume::Start);
        id
    }

    /// Resumes operation `id` with `resume` and does what it wants next, until it waits for something.
    fn advance(&mut self, id: OpId, mut resume: Resume) {
        loop {
            let Some(slot) = self.ops.get_mut(&id) else { return };
            let mut cx = Cx { core: &mut self.core, id, cancelled: slot.cancelled };
            let next = slot.op.step(&mut cx, resume);
            self.core.subscribers.remove(&id);
            match next {
                Next::Send(req) => {
                    if let Err(e) = self.core.admit(&req) {
                        resume = Resume::Reply(Err(e));
                        continue;
                    }
                    self.core.queue.push_back(Queued { owner: id, req, at: self.core.now });
                    slot_mut(&mut self.ops, id).waiting = Waiting::Queued;
                }
                Next::Sleep(t) => {
                    if t <= self.core.now {
                        resume = Resume::Wake;
                        continue;
                    }
                    slot_mut(&mut self.ops, id).waiting = Waiting::Until(t);
                }
                Next::Snapshot => {
                    if !self.core.link_up {
                        resume = Resume::Snapshot(Err(self.core.lost_error()));
                        continue;
                    }
                    if self.core.subscribers.is_empty() {
                        // Polling starts: the next RC is due one poll interval from now at the latest.
                        let first = self.core.now + self.core.config.poll_interval;
                        self.core.keepalive_due = self.core.keepalive_due.min(first);
                    }
                    self.core.subscribers.insert(id);
                    slot_mut(&mut self.ops, id).waiting = Waiting::Snapshot;
                }
                Next::Reopen => {
                    self.core.link_up = false;
                    self.core.reopen_waiter = Some(id);
                    self.core.outbox.push_back(Action::Reopen);
                    slot_mut(&mut self.ops, id).waiting = Waiting::Reopen;
                }
                Next::Done(result) => {
                    let slot = self.ops.remove(&id).expect("the slot was just used");
                    match slot.kind {
                        Kind::Public => self.core.events.push_back(Event::Done(id, result)),
                        Kind::Close => {
                            self.core.state = State::Closed;
                            self.core.line.remote = false;
                            self.core.events.push_back(Event::Closed(result.map(|_| ())));
                        }
                        Kind::Internal => {
                            if let Err(e) = result {
                                tracing::info!("{e}");
                            }
                        }
                    }
                    self.maybe_start_close();
                }
            }
            return;
        }
    }

    /// Once every caller's operation has ended, the end of the session begins.
    fn maybe_start_close(&mut self) {
        if !self.core.closing || self.core.state == State::Closed {
            return;
        }
        if self.ops.values().any(|s| s.kind == Kind::Public || s.kind == Kind::Close) {
            return;
        }
        // An automatic reconnection under way is given up (once its exchange, if any, has ended).
        if self
            .ops
            .values()
            .any(|s| s.kind == Kind::Internal && matches!(s.waiting, Waiting::InFlight | Waiting::Reopen))
        {
            return;
        }
        let internal: Vec<OpId> =
            self.ops.iter().filter(|(_, s)| s.kind == Kind::Internal).map(|(id, _)| *id).collect();
        for id in internal {
            self.ops.remove(&id);
            self.core.queue.retain(|q| q.owner != id);
        }
        self.add_op(Box::new(ops::Close::new()), Kind::Close);
    }

    /// The exchange under way ended with `result`.
    fn exchange_done(&mut self, owner: Owner, txn: Option<Txn>, result: Result<OwnedReply, Error>) {
        match owner {
            Owner::Keepalive(carries) => self.keepalive_done(carries, result),
            Owner::Op(id) => {
                let Some(mut txn) = txn else { return };
                match txn.next(&mut self.core, result) {
                    TxnStep::Again(request) => {
                        self.core.start_exchange(Owner::Op(id), Some(txn), request);
                    }
                    TxnStep::Finished(result) => {
                        if let Some(slot) = self.ops.get_mut(&id) {
                            slot.waiting = Waiting::Nothing;
                        }
                        self.advance(id, Resume::Reply(result));
                    }
                }
            }
        }
    }

    fn keepalive_done(&mut self, carries: Carries, result: Result<OwnedReply, Error>) {
        let now = self.core.now;
        let snapshot = match result {
            Ok(reply) if reply.status == Status::Ack => {
                self.core.stats.keepalives += 1;
                match carries {
                    Carries::CallersObject => {
                        if let Some(data) = reply.data {
                            self.core.last_cyclic_read = Some((now, data));
                        }
                        None
                    }
                    Carries::PollObject => {
                        self.core.stats.motion_polls += 1;
                        Some(snapshot_of(reply.data.as_deref().unwrap_or_default(), now))
                    }
                    Carries::Nothing => None,
                }
            }
            Ok(reply) => {
                tracing::warn!("keepalive RC refused: {}", reply.status);
                let e = if reply.status == Status::PermissionError {
                    let why = "the unit has left remote mode: it refused even RC with PE (it was reset, or another \
                               host sent RA); the session does not open remote mode again by itself"
                        .to_string();
                    self.core.state = State::Ended(why.clone());
                    self.core.line.remote = false;
                    Error::RemoteEnded(why)
                } else {
                    Error::Refused { command: Command::Cyclic, status: reply.status }
                };
                (carries == Carries::PollObject).then_some(Err(e))
            }
            // A unit that did not answer (or answered garbage) is not a lost port: a caller learns of it from
            // its own request; the end of the session still sends RS and RA.
            Err(e) => {
                tracing::warn!("keepalive failed: {e}");
                (carries == Carries::PollObject).then_some(Err(e))
            }
        };
        if let Some(snapshot) = snapshot {
            let waiting: Vec<OpId> = std::mem::take(&mut self.core.subscribers).into_iter().collect();
            for id in waiting {
                if let Some(slot) = self.ops.get_mut(&id) {
                    slot.waiting = Waiting::Nothing;
                }
                self.advance(id, Resume::Snapshot(snapshot.clone()));
            }
        }
    }

    /// The port failed: every exchange and request fails, the unit's watchdog stops the drives.
    fn lost(&mut self, why: String) {
        tracing::warn!("SCU session lost: {why}");
        let core = &mut self.core;
        core.link_up = false;
        core.line.remote = false;
        core.line.late = None;
        core.outbox.clear();
        if core.state != State::Closed {
            core.state = State::Lost(why.clone());
        }
        core.next_reconnect = core.now + core.config.reconnect_interval;
        let e = Error::SessionLost(why);
        if let Some(f) = core.in_flight.take() {
            self.exchange_done(f.owner, f.txn.map(Txn::abandon), Err(e.clone()));
        }
        let queued: Vec<Queued> = self.core.queue.drain(..).collect();
        for q in queued {
            if let Some(slot) = self.ops.get_mut(&q.owner) {
                slot.waiting = Waiting::Nothing;
            }
            self.advance(q.owner, Resume::Reply(Err(e.clone())));
        }
        let waiting: Vec<OpId> = std::mem::take(&mut self.core.subscribers).into_iter().collect();
        for id in waiting {
            self.advance(id, Resume::Snapshot(Err(e.clone())));
        }
    }

    /// Starts what can go out now: a stop, the keepalive when due, or a request that has room.
    fn schedule(&mut self) {
        let now = self.core.now;
        self.fail_roomless(now);
        let core = &mut self.core;
        if core.in_flight.is_some() || core.reopen_waiter.is_some() || !core.link_up {
            return;
        }
        let running = core.keepalive_running();
        let mut rc_due = running && now >= core.keepalive_due;
        if rc_due && core.line.silent {
            // The unit has not been heard for a whole request: its watchdog is left to expire (it stops the
            // drives); the next request tries the line.
            core.advance_keepalive(now);
            rc_due = false;
        }
        let room = core.has_room(now);
        let urgent = core.queue.iter().position(|q| {
            !core.line.held_by_late(q.req.request.command, now)
                && (q.req.schedule == Schedule::Now
                    || (q.req.schedule == Schedule::RoomOrLate && now >= q.at + MAX_ROOM_WAIT))
        });
        let polite = if room {
            core.queue.iter().position(|q| !core.line.held_by_late(q.req.request.command, now))
        } else {
            None
        };
        let rc_free = !core.line.held_by_late(Command::Cyclic, now);
        let pick = if let Some(i) = urgent {
            Some(i)
        } else if rc_due && rc_free && (!core.last_was_rc || polite.is_none()) {
            core.send_keepalive(now);
            return;
        } else {
            polite
        };
        let Some(i) = pick else { return };
        let q = core.queue.remove(i).expect("picked from the queue");
        if let Some(slot) = self.ops.get_mut(&q.owner) {
            slot.waiting = Waiting::InFlight;
        }
        let txn = Txn::new(q.req.clone());
        if let Some(f) = q.req.request.starts {
            // Counted as started before it is sent: a lost reply may hide a started motion.
            self.core.started.insert(f);
        }
        self.core.start_exchange(Owner::Op(q.owner), Some(txn), q.req.request);
    }

    /// Requests that waited too long for room: fail, or go anyway.
    fn fail_roomless(&mut self, now: Timestamp) {
        let expired: Vec<usize> = self
            .core
            .queue
            .iter()
            .enumerate()
            .filter(|(_, q)| q.req.schedule == Schedule::Room && now >= q.at + MAX_ROOM_WAIT)
            .map(|(i, _)| i)
            .collect();
        for i in expired.into_iter().rev() {
            let q = self.core.queue.remove(i).expect("index from the queue");
            let e = Error::NoRoom {
                command: q.req.request.command,
                round_trip: self.core.line.round_trip,
                waited: now - q.at,
            };
            if let Some(slot) = self.ops.get_mut(&q.owner) {
                slot.waiting = Waiting::Nothing;
            }
            self.advance(q.owner, Resume::Reply(Err(e)));
        }
    }
}

fn slot_mut(ops: &mut BTreeMap<OpId, Slot>, id: OpId) -> &mut Slot {
    ops.get_mut(&id).expect("the operation's slot")
}

/// The state in the read data of the poll object.
fn snapshot_of(data: &[u8], at: Timestamp) -> Result<Snapshot, Error> {
    if data.len() != 30 {
        return Err(Error::UnexpectedReply {
            command: Command::Cyclic,
            detail: format!("{} bytes of read data; the poll object reads 30", data.len()),
        });
    }
    Ok(Snapshot { at, statuses: ops::statuses(&data[..6])?, positions: ops::positions(&data[6..])? })
}

impl Core {
    /// The error every request gets while the port is gone.
    pub fn lost_error(&self) -> Error {
        match &self.state {
            State::Lost(why) => Error::SessionLost(why.clone()),
            _ => Error::SessionLost("port not connected".into()),
        }
    }

    /// Checks whether `req` may be queued in the present state.
    fn admit(&self, req: &Req) -> Result<(), Error> {
        if !self.link_up {
            return Err(self.lost_error());
        }
        if !req.needs_open {
            return Ok(());
        }
        match &self.state {
            State::Open | State::Opening => Ok(()),
            State::Ended(why) => Err(Error::RemoteEnded(why.clone())),
            State::Lost(why) => Err(Error::SessionLost(why.clone())),
            State::Closed => Err(Error::Closed),
        }
    }

    fn keepalive_running(&self) -> bool {
        self.line.remote && self.state == State::Open && self.link_up
    }

    /// The RC rhythm: the keepalive period, or the poll interval while a motion is polled through the RC.
    fn rc_period(&self) -> Duration {
        if self.subscribers.is_empty() {
            self.config.keepalive_period
        } else {
            self.config.poll_interval.min(self.config.keepalive_period)
        }
    }

    /// True if a request sent now is expected back before the next RC must go out.
    fn has_room(&self, now: Timestamp) -> bool {
        if !self.keepalive_running() || self.line.silent {
            return true;
        }
        self.last_rc_sent.is_none_or(|t| now + self.line.round_trip <= t + RC_DEADLINE)
    }

    fn advance_keepalive(&mut self, now: Timestamp) {
        let period = self.rc_period();
        while self.keepalive_due <= now {
            self.keepalive_due += period;
        }
    }

    /// Whether the session polls motions through its cyclic object (else with reads), and which slot.
    pub fn poll_slot(&self) -> Option<u8> {
        match self.config.move_polling {
            MovePolling::Cyclic { slot } if !self.poll.refused && self.cyclic.is_none() => Some(slot),
            _ => None,
        }
    }

    fn send_keepalive(&mut self, now: Timestamp) {
        self.advance_keepalive(now);
        let poll = (!self.subscribers.is_empty() && self.poll.configured).then(|| self.poll_slot()).flatten();
        let (carries, request) = match (poll, &self.cyclic) {
            (Some(slot), _) => (
                Carries::PollObject,
                PreparedRequest::with_reply_len(&Request::Cyclic { object: slot - 1, write: &[] }, Some(30)),
            ),
            (None, Some(c)) => {
                let read_len = c.object.read_size().and_then(|n| u16::try_from(n).ok());
                (
                    Carries::CallersObject,
                    PreparedRequest::with_reply_len(&Request::Cyclic { object: c.slot - 1, write: &c.write }, read_len),
                )
            }
            (None, None) => (Carries::Nothing, Ok(PreparedRequest::keepalive())),
        };
        match request {
            Ok(r) => self.start_exchange(Owner::Keepalive(carries), None, r),
            Err(e) => tracing::warn!("keepalive not sent: {e}"),
        }
    }

    fn start_exchange(&mut self, owner: Owner, txn: Option<Txn>, request: PreparedRequest) {
        let now = self.now;
        let is_rc = request.command == Command::Cyclic;
        if is_rc {
            self.last_rc_sent = Some(now);
        }
        self.last_was_rc = is_rc;
        let exchange = Exchange::start(request, &mut self.line, &self.config, now, &mut self.outbox);
        self.in_flight = Some(InFlight { owner, txn, exchange });
    }

    pub fn push_progress(&mut self, id: OpId, p: Progress) {
        self.events.push_back(Event::Progress(id, p));
    }

    /// Counts a reopened remote mode.
    pub fn opened(&mut self, rc_sent: Timestamp) {
        self.state = State::Open;
        self.keepalive_due = rc_sent + self.config.keepalive_period;
        self.last_rc_sent = Some(rc_sent);
        self.poll.configured = false;
    }

    /// The unit ended remote mode.
    pub fn ended(&mut self, why: String) -> Error {
        tracing::warn!("{why}");
        self.line.remote = false;
        self.state = State::Ended(why.clone());
        Error::RemoteEnded(why)
    }

    /// What the unit stops when its watchdog expires.
    pub fn lapse_stops(&self) -> &'static str {
        match self.config.safety_id {
            SafetyId::StopRemoteOnly => "the remote motions",
            _ => "every motion",
        }
    }

    /// The port was opened again: a fresh line.
    pub fn reset_line(&mut self) {
        self.line = Line { round_trip: self.line.round_trip, ..Line::default() };
        self.link_up = true;
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
            slot_mut(&mut self.ops, id).waiting = Waiting::Nothing;
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
