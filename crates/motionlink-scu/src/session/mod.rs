//! The SCU protocol as a sans-IO [`Session`](motionlink_link::session::Session): bytes in with the time,
//! bytes out, the next deadline, and events; no thread, no clock of its own, no I/O. A
//! [`Driver`](motionlink_link::driver::Driver) runs it over a link ([`crate::Client`], `AsyncClient`);
//! tests wire it directly to the emulator.
//!
//! ```
//! use motionlink_link::emulator::Emulator as _;
//! use motionlink_link::session::{Action, Event, Input, Session as _};
//! use motionlink_link::Timestamp;
//! use motionlink_scu::{Config, Emulator, Op, Session, SimConfig};
//!
//! let mut unit = Emulator::new(SimConfig::default())?;
//! let mut session = Session::new(Config::default(), Timestamp::ZERO)?;
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
//! - **The keepalive**: an RC on a grid of deadlines one [`crate::Config::keepalive_period`] apart
//!   (it cannot drift), or one [`crate::Config::poll_interval`] apart while a motion is polled through
//!   it: then each RC carries the session's poll object and reads the status and position of every actuator,
//!   so every exchange of a move feeds the unit's watchdog.
//! - **Room on the line**: a request other than RC goes out only if its reply is expected back (by the round
//!   trip measured so far) before the latest time the next RC must be sent, [`crate::config::RC_DEADLINE`]
//!   after the last one; so a link with round trips of 300 ms still keeps the unit alive during a move, which
//!   it then watches through the RC alone. A request that finds no room within
//!   [`crate::config::MAX_ROOM_WAIT`] fails ([`crate::Error::NoRoom`]); stops are never held back.
//! - **Operations** ([`Op`]) are `async fn`s that read like the manual's routines, run by the one executor of
//!   `motionlink-link` ([`motionlink_link::exec`]), and end with one [`Event::Done`](motionlink_link::session::Event);
//!   a cancelled one stops what it started (RS for every RE); [`Session::close`](motionlink_link::session::Session::close)
//!   cancels them all, sends RS for every function still started, then RA, and reports [`Event::Closed`](motionlink_link::session::Event).

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::Duration;

use motionlink_link::exec::{CoreGuard, Executor, Jobs, Report, Ticket};
use motionlink_link::session::{Action, Event, Input, OpId, Session as SessionTrait};
use motionlink_link::{LinkError, Timestamp};

use crate::config::Config;
use crate::error::Error;
use crate::model::{CyclicObject, DataIndex};

mod caps;
mod core;
mod ctx;
mod dispatch;
mod line;
pub(crate) mod ops;
mod pe_guard;
pub(crate) mod report;
mod request;

pub use caps::Capabilities;
use ctx::Ctx;
use line::{Exchange, Line, LineCounts};
pub use ops::WatchSpec;
pub use ops::{MoveSpec, MoveTargets, Op, Output, Progress, RunAction, RunSpec};
pub use report::{
    ActuatorOutcome, ActuatorRest, ClientStats, MoveProgress, MoveReport, RefusedStop, RunProgress, RunReport,
    SetReport, Snapshot, StopReport, SwitchReport,
};
pub(crate) use request::{OwnedReply, Req};

use pe_guard::PeGuarded;
pub use request::PreparedRequest;

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
    /// An operation, for the reply under `ticket`; `cancellable`: sent by the operation's own part (not by
    /// the part that stops what it started), so a cancel may cut its repetitions short.
    Op {
        id: OpId,
        ticket: Ticket,
        cancellable: bool,
    },
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
    pe_guard: Option<PeGuarded>,
    exchange: Exchange,
}

struct Queued {
    owner: OpId,
    /// Where its reply goes.
    ticket: Ticket,
    req: Req,
    at: Timestamp,
    /// A cancel of its operation takes it out of the queue.
    cancellable: bool,
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

/// Everything the operations share with the session.
pub(crate) struct Core {
    pub config: Config,
    pub now: Timestamp,
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
    /// Functions whose stop (RS acknowledged or not) was not confirmed by the status: the end of the session
    /// does not leave remote mode until their actuators are found at rest.
    pub unconfirmed_stops: Vec<crate::model::Function>,
    /// The unit refused an RE of a running function (PE): a stream sends RS before each new RE.
    pub re_needs_rs: bool,
    pub stats: ClientStats,
    /// When the next RC is due: a grid of deadlines.
    keepalive_due: Timestamp,
    /// When the last RC went out.
    last_rc_sent: Option<Timestamp>,
    last_was_rc: bool,
    next_reconnect: Timestamp,
    /// The operation waiting for the port to be reopened, and where the outcome goes.
    reopen_waiter: Option<(OpId, Ticket)>,
    pub cyclic: Option<CyclicUse>,
    pub last_cyclic_read: Option<(Timestamp, Vec<u8>)>,
    pub poll: PollObject,
    /// What the unit was found to do beyond the manual's words.
    pub(crate) probed: caps::Probed,
    /// What each switching function's status entry was found to do.
    pub(crate) switches: ops::SwitchFindings,
    /// Operations waiting for the next poll of a motion, and where it goes.
    subscribers: BTreeMap<OpId, Ticket>,
    /// Replies to the operations' requests.
    pub replies: Jobs<Result<OwnedReply, Error>>,
    /// The next poll of a motion, for the operations subscribed to it.
    pub snapshots: Jobs<Result<Snapshot, Error>>,
    /// The outcome of reopening the port.
    pub reopens: Jobs<Result<(), Error>>,
    closing: bool,
}

/// The SCU protocol as a sans-IO session. See the [module documentation](self).
pub struct Session {
    /// The settings (the core has them too; this copy can be lent out).
    config: Config,
    /// The operations, run by the one executor of `motionlink-link`, around the core.
    exec: Executor<Core, Progress, Result<Output, Error>>,
    /// How each operation's end is reported.
    kinds: BTreeMap<OpId, Kind>,
    events: VecDeque<Event<Session>>,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let core = self.core();
        f.debug_struct("Session")
            .field("state", &core.state)
            .field("started", &core.started)
            .field("operations", &self.exec.len())
            .finish()
    }
}

impl Session {
    /// A session with `config` (checked) at `now`. Nothing is sent until [`Op::Open`] is started.
    pub fn new(config: Config, now: Timestamp) -> Result<Session, Error> {
        config.validate()?;
        let core = Core {
            config: config.clone(),
            now,
            line: Line::default(),
            counts: LineCounts::default(),
            in_flight: None,
            outbox: VecDeque::new(),
            queue: VecDeque::new(),
            state: State::Opening,
            link_up: true,
            started: BTreeSet::new(),
            unconfirmed_stops: Vec::new(),
            re_needs_rs: false,
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
            switches: ops::SwitchFindings::default(),
            subscribers: BTreeMap::new(),
            replies: Jobs::default(),
            snapshots: Jobs::default(),
            reopens: Jobs::default(),
            closing: false,
        };
        Ok(Session { config, exec: Executor::new(core, now), kinds: BTreeMap::new(), events: VecDeque::new() })
    }

    fn core(&self) -> CoreGuard<'_, Core, Progress> {
        self.exec.core()
    }

    /// Every call into the session tells it the time: the engine's and the operations' clock.
    fn now_is(&mut self, now: Timestamp) {
        self.exec.core_at(now).now = now;
    }

    /// The session's settings.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Counters of the session.
    pub fn stats(&self) -> ClientStats {
        let core = self.core();
        let mut s = core.stats;
        s.retries = core.counts.retries;
        s.flushes = core.counts.flushes;
        s
    }

    /// The functions this session started with RE and has not stopped yet.
    pub fn started(&self) -> Vec<crate::model::Function> {
        self.core().started.iter().filter_map(|&id| crate::model::Function::from_id(id)).collect()
    }

    /// True while the session is open (not lost, not ended by the unit, not closed).
    pub fn is_open(&self) -> bool {
        self.core().state == State::Open
    }

    /// Why the session is not open, if it is not: lost, ended by the unit, or closed.
    pub fn not_open_reason(&self) -> Option<String> {
        let state = self.core().state.clone();
        match &state {
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
        let core = self.core();
        let (t, data) = core.last_cyclic_read.clone()?;
        Some((t, core.cyclic.as_ref()?.object, data))
    }

    /// Keepalive RCs carry no cyclic object of the caller's again.
    pub fn stop_cyclic(&mut self) {
        let mut core = self.core();
        core.cyclic = None;
        core.last_cyclic_read = None;
    }

    /// The caller wrote the definition of CyclicObj `slot`: if the session polls motions through it, it
    /// defines it again before the next move.
    pub fn cyclic_slot_written(&mut self, slot: u8) {
        let mut core = self.core();
        if core.poll_slot() == Some(slot) {
            core.poll.configured = false;
        }
    }

    /// The round trip the session measured lately (the longest, decaying).
    pub fn round_trip(&self) -> Duration {
        self.core().line.round_trip
    }

    /// What the session found the unit to do where the manual leaves it open (probed as checks needed it).
    pub fn capabilities(&self) -> Capabilities {
        self.core().probed.known()
    }
}

impl Session {
    /// Starts an operation of `kind`, the future `op` makes of its handle, and runs it until it waits.
    fn add_op<F>(&mut self, kind: Kind, op: impl FnOnce(Ctx) -> F) -> OpId
    where
        F: std::future::Future<Output = Result<Output, Error>> + Send + 'static,
    {
        let id = self.exec.next_id();
        self.kinds.insert(id, kind);
        self.exec.spawn(id, |ctx| op(Ctx::new(ctx)));
        self.run();
        id
    }

    /// Runs every operation whose awaited result is there, until none is; reports their ends; starts the
    /// end of the session once the callers' operations have ended.
    fn run(&mut self) {
        loop {
            let mut ended = Vec::new();
            let mut closed = false;
            let (events, kinds) = (&mut self.events, &mut self.kinds);
            self.exec.run(|report| match report {
                Report::Progress(id, p) => events.push_back(Event::Progress(id, p)),
                Report::Done(id, result) => {
                    ended.push(id);
                    match kinds.remove(&id) {
                        Some(Kind::Public) => events.push_back(Event::Done(id, result)),
                        Some(Kind::Close) => {
                            closed = true;
                            events.push_back(Event::Closed(result.map(|_| ())));
                        }
                        Some(Kind::Internal) | None => {
                            if let Err(e) = result {
                                tracing::info!("{e}");
                            }
                        }
                    }
                }
            });
            if ended.is_empty() {
                return;
            }
            {
                let mut core = self.core();
                for id in ended {
                    core.forget(id);
                }
                if closed {
                    core.state = State::Closed;
                    core.line.remote = false;
                }
            }
            self.maybe_start_close();
        }
    }

    /// Once every caller's operation has ended, the end of the session begins.
    fn maybe_start_close(&mut self) {
        let internal: Vec<OpId> = {
            let core = self.core();
            if !core.closing || core.state == State::Closed {
                return;
            }
            if self.kinds.values().any(|k| *k == Kind::Public || *k == Kind::Close) {
                return;
            }
            let internal: Vec<OpId> =
                self.kinds.iter().filter(|(_, k)| **k == Kind::Internal).map(|(id, _)| *id).collect();
            // An automatic reconnection under way is given up (once its exchange, if any, has ended).
            if internal.iter().any(|id| core.busy_for(*id)) {
                return;
            }
            internal
        };
        for id in internal {
            self.kinds.remove(&id);
            self.exec.abort(id);
            self.core().forget(id);
        }
        self.add_op(Kind::Close, |ctx| async move { ops::close(&ctx).await });
    }

    /// Takes what `known` says of the unit (from a device profile, or a probe) where this session has not
    /// found out yet. What the unit lacks is not asked for again (the plain form is used, without a
    /// warning); what it has is still found out by the first check that depends on it, where that costs no
    /// more than the check (a unit that refuses it then runs in the plain form, with a warning that names
    /// the profile). A finding of the session stays.
    pub fn seed_capabilities(&mut self, known: Capabilities) {
        let mut core = self.core();
        core.probed.seeded = core.probed.seeded.or(known);
    }
}

impl SessionTrait for Session {
    type Op = Op;
    type Output = Output;
    type Progress = Progress;
    type Error = Error;

    fn start(&mut self, op: Op, now: Timestamp) -> OpId {
        self.now_is(now);
        let refused = {
            let core = self.core();
            core.closing || core.state == State::Closed
        };
        if refused {
            let id = self.exec.next_id();
            self.events.push_back(Event::Done(id, Err(Error::Closed)));
            return id;
        }
        self.add_op(Kind::Public, |ctx| ops::run(ctx, op))
    }

    fn cancel(&mut self, id: OpId, now: Timestamp) {
        self.now_is(now);
        if self.kinds.get(&id) != Some(&Kind::Public) || self.exec.is_cancelled(id) {
            return;
        }
        // The operation is woken: a pause or a wait for the next poll ends (unless it is stopping what it
        // started); a request of its still in the queue is dropped.
        self.exec.cancel(id);
        self.core().cancel_queued(id);
        self.core().cut_short(id);
        self.run();
    }

    fn close(&mut self, now: Timestamp) {
        self.now_is(now);
        {
            let mut core = self.core();
            if core.closing {
                return;
            }
            core.closing = true;
        }
        let public: Vec<OpId> = self.kinds.iter().filter(|(_, k)| **k == Kind::Public).map(|(id, _)| *id).collect();
        for id in public {
            self.cancel(id, now);
        }
        self.maybe_start_close();
        self.run();
    }

    fn handle_input(&mut self, input: Input<'_>, now: Timestamp) {
        self.now_is(now);
        let Input::Bytes(bytes) = input else { return };
        self.core().handle_bytes(bytes, now);
        self.run();
    }

    fn handle_link_error(&mut self, error: LinkError, now: Timestamp) {
        self.now_is(now);
        {
            let mut core = self.core();
            if core.reopen_waiter.is_some() || !core.link_up {
                return;
            }
            core.lost(error.to_string());
        }
        self.run();
    }

    fn handle_reopened(&mut self, result: Result<(), LinkError>, now: Timestamp) {
        self.now_is(now);
        self.core().reopened(result);
        self.run();
    }

    fn poll_transmit(&mut self, now: Timestamp) -> Option<Action> {
        {
            let mut core = self.exec.core_at(now);
            core.now = now;
            if let Some(a) = core.outbox.pop_front() {
                return Some(a);
            }
            // Requests that waited too long for room, and waits for a poll that will not come, end first:
            // their operations may have something else to send.
            core.fail_waiting(now);
        }
        self.run();
        let mut core = self.core();
        core.schedule(now);
        core.outbox.pop_front()
    }

    fn poll_timeout(&self) -> Option<Timestamp> {
        let timers = self.exec.poll_timeout();
        [timers, self.core().poll_timeout()].into_iter().flatten().min()
    }

    fn handle_timeout(&mut self, now: Timestamp) {
        self.now_is(now);
        self.core().handle_timeout(now);
        self.exec.handle_timeout(now);
        let reconnect = {
            let core = self.core();
            matches!(core.state, State::Lost(_))
                && core.config.auto_reconnect
                && !core.closing
                && now >= core.next_reconnect
                && core.reopen_waiter.is_none()
                && !self.kinds.values().any(|k| *k == Kind::Internal)
        };
        if reconnect {
            let mut core = self.core();
            core.next_reconnect = now + core.config.reconnect_interval;
        }
        if reconnect {
            self.add_op(Kind::Internal, ops::reconnect);
        } else {
            self.run();
        }
    }

    fn poll_event(&mut self) -> Option<Event<Self>> {
        self.events.pop_front()
    }

    fn wants_input(&self) -> bool {
        let core = self.core();
        core.in_flight.is_some() || core.line.late.is_some()
    }

    fn is_idle(&self) -> bool {
        let core = self.core();
        self.exec.is_empty() && core.queue.is_empty() && core.in_flight.is_none() && core.outbox.is_empty()
    }
}
