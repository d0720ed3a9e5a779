//! The state a session shares with its operations, and the exchange engine: requests out, acknowledges
//! matched in, answer timeouts, stale answers dropped, the watchdog refresh on its deadlines. Sans-IO: it
//! is handed bytes or frames and the time, and hands out what to send.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::Duration;

use motionlink_link::can::CanFrame;
use motionlink_link::exec::{Jobs, Ticket};
use motionlink_link::session::{Action as LinkAction, OpId};
use motionlink_link::{LinkError, Timestamp};

use super::Config;
use crate::error::Error;
use crate::model::{Broadcast, BroadcastForm, ConfigWord, ModuleKind, Param};
use crate::wire::can::{self as can_wire, Role};
use crate::wire::rs232::{self, Rs232Decoder, TelKind};
use crate::wire::Payload;
use crate::wire::{AckPosition, Action, Reply, Request};

/// What a finished job gives its operation.
#[derive(Debug)]
pub(crate) enum JobResult {
    /// One result per request of an exchange, in the order of the batch.
    Exchange(Vec<Result<Reply, Error>>),
    /// A broadcast went out, or the line refused it.
    Broadcast(Result<(), Error>),
}

enum Job {
    Exchange { ticket: Ticket, op: OpId, batch: Vec<(u8, Request)>, timeout: Duration },
    Broadcast { ticket: Ticket, op: OpId, broadcast: Broadcast },
}

impl Job {
    fn op(&self) -> OpId {
        match self {
            Job::Exchange { op, .. } | Job::Broadcast { op, .. } => *op,
        }
    }
}

/// The exchange under way: every request is out (or going out), acknowledges are matched as they come.
struct InFlight {
    ticket: Ticket,
    batch: Vec<(u8, Request)>,
    start: Timestamp,
    deadline: Timestamp,
    results: Vec<Option<Reply>>,
    corrupt: Vec<Option<String>>,
    open: usize,
}

/// What the last action handed to the driver was, so that a link error it reports is laid at the right
/// door.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sent {
    Nothing,
    Refresh,
    Exchange,
    Broadcast(Ticket),
}

/// What came in: an acknowledge from a module, or something broken.
enum Incoming {
    Frame { address: u8, payload: Payload },
    Corrupt(String),
}

/// The watchdog duty of a session (chapter 13): which modules it switched on, and the refresh schedule.
#[derive(Debug, Default)]
pub(crate) struct WatchdogDuty {
    /// The refresh is broadcast every period while this is true.
    pub serving: bool,
    /// When the next refresh is due (absolute: one period after the last one was due).
    pub next_due: Timestamp,
    /// Modules whose watchdog this session switched on.
    pub online: BTreeSet<u8>,
    /// Modules to which an operation is sending a life sign now (switching the watchdog on or off): it
    /// claimed the toggle (taken out of `online` to switch it off), so that no other operation sends a second
    /// one, which would toggle it back. Their watchdog may be online.
    pub toggling: BTreeSet<u8>,
    /// Modules armed by [`Op::EnableWatchdog`](crate::session::Op): switched off only by
    /// [`Op::DisableWatchdog`](crate::session::Op) or the close, never at the end of a guarded motion.
    pub by_user: BTreeSet<u8>,
    /// Modules whose watchdog a guarded motion under way arms (or found armed) for its motion: its end
    /// switches it off (unless in `by_user`); [`Op::DisableWatchdog`](crate::session::Op) leaves it to it.
    pub held: BTreeSet<u8>,
    /// Counts the spells of the refresh (each [`WatchdogDuty::start_serving`]): an observation of a
    /// watchdog with the refresh stopped holds only if no new spell began meanwhile.
    pub spell: u64,
    /// Modules in which this session set CONFIGID_MOD_WATCHDOG_ENABLE, with their Config word before.
    pub config_before: BTreeMap<u8, ConfigWord>,
    /// Modules that got a life sign this session could not confirm: their watchdog may be online or not.
    pub uncertain: BTreeSet<u8>,
    /// The state word of each module as the last arming read it, before its Config word or life sign:
    /// whether a Reset after a failed arming would clear a latch set before it (see
    /// `Ctx::release_failed_arming`).
    pub state_before: BTreeMap<u8, crate::model::CubeState>,
    /// The last failure of a refresh.
    pub last_error: Option<String>,
    /// When the last refresh was handed to the driver, on the session's time (none yet since the refresh
    /// started being served).
    pub last_refresh: Option<Timestamp>,
    /// The longest time between two consecutive refreshes since the refresh started being served.
    pub longest_gap: Duration,
}

impl WatchdogDuty {
    /// Starts serving the refresh at `now` (the timing of an earlier spell forgotten).
    pub fn start_serving(&mut self, now: Timestamp) {
        self.serving = true;
        self.spell += 1;
        self.next_due = now;
        self.last_refresh = None;
        self.longest_gap = Duration::ZERO;
    }

    /// True if the watchdog of `address` is (or may be) online by this session's doing: switched on, a life
    /// sign not confirmed, or one under way.
    pub fn may_be_online(&self, address: u8) -> bool {
        self.online.contains(&address) || self.uncertain.contains(&address) || self.toggling.contains(&address)
    }

    /// Every module whose watchdog is (or may be) online by this session's doing, in address order.
    pub fn left_online(&self) -> Vec<u8> {
        let all: BTreeSet<u8> = self.online.iter().chain(&self.uncertain).chain(&self.toggling).copied().collect();
        all.into_iter().collect()
    }

    /// The refresh goes out at `now`.
    fn refreshed(&mut self, now: Timestamp) {
        if let Some(last) = self.last_refresh {
            self.longest_gap = self.longest_gap.max(now.saturating_since(last));
        }
        self.last_refresh = Some(now);
    }

    /// How the refresh went out up to `now`, if it has gone out at all: the longest gap between two
    /// refreshes, the time since the last one counted as a gap while the refresh is served.
    pub fn timing(
        &self,
        now: Timestamp,
        round_trips: Option<crate::error::RoundTripRange>,
    ) -> Option<crate::error::RefreshTiming> {
        let last = self.last_refresh?;
        let open = if self.serving { now.saturating_since(last) } else { Duration::ZERO };
        Some(crate::error::RefreshTiming {
            longest_gap: self.longest_gap.max(open),
            allowed: crate::model::WATCHDOG_TIMEOUT,
            round_trips,
        })
    }
}

/// What the streamed setpoints of one module ([`Op::Setpoint`](crate::session::Op::Setpoint)) keep between
/// calls, so that a later call is one exchange: dropped ([`Core::drop_setpoints`]) whenever what it holds
/// may no longer be true.
#[derive(Debug, Default)]
pub(crate) struct SetpointCache {
    /// Which cache this is: a value read for a cache dropped meanwhile is not kept in its successor.
    pub generation: u64,
    /// The first setpoint's checks are done: the module was found ready (no error, not halted, its Config
    /// word lets it move), its watchdog armed where the guard asked for it, and a command acknowledged.
    pub ready: bool,
    /// The limits read for the checks, by parameter.
    pub limits: BTreeMap<Param, f64>,
    /// Where the last extended acknowledge put the module (the start of a step's speed rule).
    pub last_position: Option<AckPosition>,
    /// When the full state word last showed the module not homed, and nothing worse: until
    /// `FULL_STATE_EVERY` later, its SHORT_NOT_OK is taken to say no more than that.
    pub not_homed_at: Option<Timestamp>,
}

/// Everything a session and its operations share.
pub(crate) struct Core {
    pub now: Timestamp,
    pub config: Config,
    pub can: bool,
    pub port: String,
    rs232: Rs232Decoder,
    queue: VecDeque<Job>,
    sending: VecDeque<LinkAction>,
    in_flight: Option<InFlight>,
    /// A timeout left answers possibly on their way: drop what is pending before the next exchange.
    stale: bool,
    /// The results of exchanges and broadcasts, for the operations that await them.
    pub jobs: Jobs<JobResult>,
    sent: Sent,
    /// A broadcast handed out and not yet known to have failed: it succeeded unless the driver reports a
    /// link error at once.
    broadcast_out: Option<Ticket>,
    pub duty: WatchdogDuty,
    /// Modules this session may have set in motion and has not seen stop. Changed one module at a time
    /// ([`Core::mark_started`], [`Core::seen_stopped`]), never replaced by a copy taken before an await: a
    /// module another operation set in motion meanwhile would be forgotten.
    pub started: BTreeSet<u8>,
    /// How often each module was counted as set in motion ([`Core::mark_started`]): an operation that saw a
    /// module at rest takes it off `started` only if nothing set it in motion again since it looked.
    pub start_count: BTreeMap<u8, u64>,
    /// Modules a guarded motion of this session is under way on (`Ctx::guarded`): a second one is refused.
    pub guarded: BTreeSet<u8>,
    /// When this session last sent each module a motion command.
    pub motion_sent: BTreeMap<u8, Timestamp>,
    /// Modules known to exist: every address that has answered this session.
    pub known: BTreeSet<u8>,
    /// Module kinds read from their Config words.
    pub kinds: BTreeMap<u8, ModuleKind>,
    /// The Config word read with each kind (`None`: the kind came from DefConfig, the module gives no
    /// Config word). Forgotten with the kind when the session writes Config (kept, with the new word, when
    /// the write changes only CONFIGID_MOD_WATCHDOG_ENABLE: arming and disarming a watchdog).
    pub configs: BTreeMap<u8, Option<crate::model::ConfigWord>>,
    /// What the session established about each module where the manual is silent.
    pub findings: BTreeMap<u8, super::ModuleFindings>,
    /// The findings already warned about (module, which), so that each is said once per session.
    pub warned: BTreeSet<(u8, &'static str)>,
    /// What the streamed setpoints of each module keep between calls.
    pub setpoints: BTreeMap<u8, SetpointCache>,
    /// How many setpoint caches were made: the generation of the next.
    pub setpoint_generations: u64,
    /// The session lost its line or could not stop what it started.
    pub failed: bool,
    /// The round trips measured on the line: each acknowledge since its request went out.
    pub round_trips: Option<crate::error::RoundTripRange>,
}

impl Core {
    pub fn new(config: Config, can: bool, port: String, now: Timestamp) -> Core {
        Core {
            now,
            config,
            can,
            port,
            rs232: Rs232Decoder::new(),
            queue: VecDeque::new(),
            sending: VecDeque::new(),
            in_flight: None,
            stale: false,
            jobs: Jobs::default(),
            sent: Sent::Nothing,
            broadcast_out: None,
            duty: WatchdogDuty::default(),
            started: BTreeSet::new(),
            start_count: BTreeMap::new(),
            guarded: BTreeSet::new(),
            motion_sent: BTreeMap::new(),
            known: BTreeSet::new(),
            kinds: BTreeMap::new(),
            configs: BTreeMap::new(),
            findings: BTreeMap::new(),
            warned: BTreeSet::new(),
            setpoints: BTreeMap::new(),
            setpoint_generations: 0,
            failed: false,
            round_trips: None,
        }
    }

    /// Counts module `address` as set in motion (again): a motion command, a Home, a broadcast that reaches
    /// it, an acknowledge of one it was not sent, or a stop not confirmed.
    pub fn mark_started(&mut self, address: u8) {
        self.started.insert(address);
        *self.start_count.entry(address).or_default() += 1;
    }

    /// How often module `address` has been counted as set in motion, for [`Core::seen_stopped`].
    pub fn start_mark(&self, address: u8) -> u64 {
        self.start_count.get(&address).copied().unwrap_or(0)
    }

    /// Module `address` was seen at rest (or halted) by an operation that looked when its count was `mark`
    /// ([`Core::start_mark`]): it is taken off `started` unless something set it in motion again since.
    pub fn seen_stopped(&mut self, address: u8, mark: u64) {
        if self.start_mark(address) == mark {
            self.started.remove(&address);
        }
    }

    /// The setpoint cache of module `address`, made (empty, a new generation) where there is none.
    pub fn setpoint_cache(&mut self, address: u8) -> &mut SetpointCache {
        let generations = &mut self.setpoint_generations;
        self.setpoints.entry(address).or_insert_with(|| {
            *generations += 1;
            SetpointCache { generation: *generations, ..SetpointCache::default() }
        })
    }

    /// The setpoint cache of module `address` if it is still generation `generation` (not dropped since).
    pub fn setpoints_of(&mut self, address: u8, generation: u64) -> Option<&mut SetpointCache> {
        self.setpoints.get_mut(&address).filter(|c| c.generation == generation)
    }

    /// Drops the setpoint cache of module `address`: its next setpoint reads again what it checks.
    pub fn drop_setpoints(&mut self, address: u8) {
        if self.setpoints.remove(&address).is_some() {
            tracing::debug!("module {address}: the cache of its setpoints is dropped");
        }
    }

    /// Before `request` goes to module `address`: a write of a limit its setpoints are checked against (or
    /// of the Config word), a Reset, a Home or a Halt drops its setpoint cache.
    pub fn note_request(&mut self, address: u8, request: &Request) {
        let drops = match request {
            // The session's own arming and disarming of a watchdog changes that flag alone: kept.
            Request::Set(Param::Config, value) => {
                let known = self.configs.get(&address).copied().flatten();
                !value.as_u32().is_some_and(|word| known.is_some_and(|k| only_watchdog_flag(k, ConfigWord(word))))
            }
            Request::Set(param, _) => setpoint_limit(*param),
            Request::Action(action) => matches!(action, Action::Reset | Action::Home | Action::Halt),
            _ => false,
        };
        if drops {
            self.drop_setpoints(address);
        }
    }

    /// Warns `message` about module `address` once per session (`which` names the finding).
    pub fn warn_once(&mut self, address: u8, which: &'static str, message: impl FnOnce() -> String) {
        if self.warned.insert((address, which)) {
            tracing::warn!("{}", message());
        }
    }

    /// Queues an exchange for `op`: every request sent (on CAN at once), the acknowledges collected in any
    /// order until all came or `timeout` passed since the first went out.
    pub fn enqueue_exchange(&mut self, op: OpId, batch: Vec<(u8, Request)>, timeout: Duration) -> Ticket {
        let ticket = self.jobs.open(op);
        self.queue.push_back(Job::Exchange { ticket, op, batch, timeout });
        ticket
    }

    /// Queues a broadcast for `op` (never acknowledged).
    pub fn enqueue_broadcast(&mut self, op: OpId, broadcast: Broadcast) -> Ticket {
        let ticket = self.jobs.open(op);
        self.queue.push_back(Job::Broadcast { ticket, op, broadcast });
        ticket
    }

    /// Hands the result of a job to the operation that awaits it (dropped if it has ended).
    fn finish(&mut self, ticket: Ticket, result: JobResult) {
        self.jobs.finish(ticket, result);
    }

    /// Forgets what operation `op` was waiting for: its queued jobs are not sent, the result of one on the
    /// line is dropped when it comes.
    pub fn forget(&mut self, op: OpId) {
        self.jobs.forget(op);
        self.queue.retain(|j| j.op() != op);
    }

    /// A broadcast handed out earlier did not fail: its operation learns so.
    fn settle_broadcast(&mut self) {
        if let Some(ticket) = self.broadcast_out.take() {
            self.finish(ticket, JobResult::Broadcast(Ok(())));
        }
    }

    /// The frame of `payload` to `address` (0: every module, on RS232) on this session's carrier.
    fn frame(&self, address: u8, payload: &Payload) -> Result<LinkAction, Error> {
        if self.can {
            Ok(LinkAction::SendFrame(can_wire::to_frame(Role::for_command(address, payload), payload)))
        } else {
            let mut buf = [0u8; rs232::MAX_FRAME];
            let n = rs232::encode(TelKind::Send, address, payload, &mut buf)?;
            Ok(LinkAction::Send(buf[..n].to_vec()))
        }
    }

    /// A broadcast on this carrier: on CAN the broadcast identifier with the manual's payload; on RS232
    /// module address 0 with the command followed by 0x00, as Schunk's libm5api sends it.
    fn broadcast_action(&self, broadcast: &Broadcast) -> Result<LinkAction, Error> {
        if self.can {
            Ok(LinkAction::SendFrame(can_wire::to_frame(Role::Broadcast, &broadcast.encode())))
        } else {
            self.frame(0, &broadcast.encode_as(BroadcastForm::Padded))
        }
    }

    /// The next thing to hand to the driver at `now`.
    pub fn poll_transmit(&mut self, now: Timestamp) -> Option<LinkAction> {
        self.now = now;
        self.settle_broadcast();
        // The watchdog refresh first: it is the one thing with a hard deadline (the modules wait 50 ms).
        if self.duty.serving && now >= self.duty.next_due {
            // Absolute deadlines: the next refresh is due one period after this one was due, so late sends
            // do not make the schedule drift; one more than a period late is followed by the next a period
            // after it went out.
            let period = self.config.watchdog_period;
            let next = self.duty.next_due + period;
            self.duty.next_due = if next > now { next } else { now + period };
            match self.broadcast_action(&Broadcast::WatchdogRefresh) {
                Ok(a) => {
                    self.duty.refreshed(now);
                    self.sent = Sent::Refresh;
                    return Some(a);
                }
                Err(e) => tracing::error!("cannot frame the watchdog refresh: {e}"),
            }
        }
        if let Some(a) = self.sending.pop_front() {
            self.sent = Sent::Exchange;
            return Some(a);
        }
        if self.in_flight.is_some() {
            return None;
        }
        let job = self.queue.pop_front()?;
        match job {
            Job::Broadcast { ticket, broadcast, .. } => match self.broadcast_action(&broadcast) {
                Ok(a) => {
                    self.sent = Sent::Broadcast(ticket);
                    self.broadcast_out = Some(ticket);
                    Some(a)
                }
                Err(e) => {
                    self.finish(ticket, JobResult::Broadcast(Err(e)));
                    self.poll_transmit(now)
                }
            },
            Job::Exchange { ticket, batch, timeout, .. } => {
                let frames: Result<Vec<LinkAction>, Error> =
                    batch.iter().map(|(a, r)| self.frame(*a, &r.encode())).collect();
                let frames = match frames {
                    Ok(f) => f,
                    Err(e) => {
                        let results = batch.iter().map(|_| Err(clone_encode(&e))).collect();
                        self.finish(ticket, JobResult::Exchange(results));
                        return self.poll_transmit(now);
                    }
                };
                if self.stale {
                    self.stale = false;
                    self.rs232.reset();
                    self.sending.push_back(LinkAction::DiscardInput);
                }
                self.sending.extend(frames);
                let n = batch.len();
                self.in_flight = Some(InFlight {
                    ticket,
                    batch,
                    start: now,
                    deadline: now + timeout,
                    results: vec![None; n],
                    corrupt: vec![None; n],
                    open: n,
                });
                self.sent = Sent::Exchange;
                self.sending.pop_front()
            }
        }
    }

    /// When the engine next needs the time: an answer's deadline, the next refresh.
    pub fn poll_timeout(&self) -> Option<Timestamp> {
        let answer = self.in_flight.as_ref().map(|f| f.deadline);
        let refresh = self.duty.serving.then_some(self.duty.next_due);
        [answer, refresh].into_iter().flatten().min()
    }

    /// Time has reached `now`: an exchange whose answers are late ends.
    pub fn handle_timeout(&mut self, now: Timestamp) {
        self.now = now;
        self.settle_broadcast();
        if self.in_flight.as_ref().is_some_and(|f| now >= f.deadline) {
            self.complete();
        }
    }

    /// True while an answer is due.
    pub fn wants_input(&self) -> bool {
        self.in_flight.is_some()
    }

    /// True when nothing is queued, going out or awaited.
    pub fn is_quiet(&self) -> bool {
        self.queue.is_empty() && self.sending.is_empty() && self.in_flight.is_none() && self.broadcast_out.is_none()
    }

    /// Bytes of the serial line arrived at `now`.
    pub fn handle_bytes(&mut self, bytes: &[u8], now: Timestamp) {
        self.now = now;
        self.settle_broadcast();
        let mut incoming = Vec::new();
        for result in self.rs232.feed(bytes) {
            match result {
                Ok(f) if f.kind == TelKind::Send => {} // our own frame echoed by a converter
                Ok(f) if !f.bcc_ok() => incoming.push(Incoming::Corrupt(format!(
                    "frame from module {} with a wrong BCC (0x{:02X}, expected 0x{:02X})",
                    f.address, f.bcc_received, f.bcc_computed
                ))),
                // The manual's own acknowledge examples carry TELID length 6 for 3 data bytes: that one slip
                // is accepted; any other length that differs from the data is corruption the BCC let through.
                Ok(f) if !(f.length_ok() || f.manual_length_slip()) => incoming.push(Incoming::Corrupt(format!(
                    "frame from module {} with TELID length {} for {} data bytes",
                    f.address,
                    f.declared_len,
                    f.payload.len()
                ))),
                Ok(f) => incoming.push(Incoming::Frame { address: f.address, payload: f.payload }),
                Err(e) => incoming.push(Incoming::Corrupt(e.to_string())),
            }
        }
        for i in incoming {
            self.incoming(i);
        }
    }

    /// A CAN frame arrived at `now`.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Timestamp) {
        self.now = now;
        self.settle_broadcast();
        match can_wire::from_frame(frame) {
            Ok((Role::Ack(address), payload)) => self.incoming(Incoming::Frame { address, payload }),
            // The manual's last CAN table shows the extended acknowledge of a motion command on the command
            // identifier (0x0E0 + address): taken there too, from the module asked for one, when it is 8
            // bytes (a command of the same mode is at most 8 too, so one identical to a request is not).
            Ok((Role::Put(address), payload)) if self.awaits_extended_ack(address, &payload) => {
                self.incoming(Incoming::Frame { address, payload })
            }
            Ok(_) => {} // commands from another master, broadcasts
            Err(e) => tracing::debug!("{}: {e}", self.port),
        }
    }

    /// True when `payload` on the command identifier of `address` is the 8-byte extended acknowledge of a
    /// motion command in flight to that module (and not that command itself).
    fn awaits_extended_ack(&self, address: u8, payload: &Payload) -> bool {
        let Some(f) = self.in_flight.as_ref() else { return false };
        payload.len() == 8
            && f.batch.iter().enumerate().any(|(i, (a, req))| {
                *a == address
                    && f.results[i].is_none()
                    && matches!(req, Request::Motion(_, crate::model::AckKind::Extended))
                    && req.encode() != *payload
            })
    }

    fn incoming(&mut self, incoming: Incoming) {
        let Some(f) = self.in_flight.as_mut() else {
            // Nothing is awaited (the driver reads only while an answer is due, so this is rare): a motion
            // acknowledge still counts as a module set in motion.
            if let Incoming::Frame { address, payload } = incoming {
                if let Ok(r) = Reply::decode(&payload) {
                    if moves(&r) {
                        tracing::warn!("module {address} acknowledged {r}, which it was not sent: it may be moving");
                        self.mark_started(address);
                    }
                }
            }
            return;
        };
        match incoming {
            Incoming::Frame { address, payload } => {
                let reply = Reply::decode(&payload);
                let slot = f.batch.iter().enumerate().position(|(i, (a, req))| {
                    *a == address && f.results[i].is_none() && reply.as_ref().is_ok_and(|r| r.answers(req))
                });
                match (slot, reply) {
                    (Some(i), Ok(r)) => {
                        f.results[i] = Some(r);
                        f.open -= 1;
                        self.known.insert(address);
                        let took = self.now.saturating_since(f.start);
                        self.round_trips = Some(crate::error::RoundTripRange::with(self.round_trips, took));
                    }
                    (_, Err(e)) => {
                        tracing::debug!("module {address}: undecodable answer {payload:?}: {e}");
                        for (i, (a, _)) in f.batch.iter().enumerate() {
                            if *a == address && f.results[i].is_none() {
                                f.corrupt[i] = Some(format!("{e} in {payload:?}"));
                            }
                        }
                    }
                    (None, Ok(r)) => {
                        // A module acknowledged a motion command it was not sent in this exchange: a command
                        // whose address or content was corrupted on the way (the modules ignore the BCC). It
                        // may be moving: the session halts it when it stops what it started.
                        let expected_motion = f.batch.iter().any(|(a, req)| *a == address && r.answers(req));
                        if moves(&r) && !expected_motion {
                            tracing::warn!(
                                "module {address} acknowledged {r}, which it was not sent: it may be moving"
                            );
                            // `mark_started`, with the exchange in flight still borrowed.
                            self.started.insert(address);
                            *self.start_count.entry(address).or_default() += 1;
                        }
                        // On a line that carries one request at a time, a frame from the module asked that
                        // answers something else is a corrupted answer (its echoed command or parameter is
                        // wrong), not silence.
                        if let [(a, req)] = f.batch.as_slice() {
                            if *a == address && f.results[0].is_none() {
                                f.corrupt[0] = Some(format!("answer {r} does not echo {req}"));
                            }
                        }
                        tracing::debug!("module {address}: unexpected answer {r} (ignored)");
                    }
                }
            }
            Incoming::Corrupt(detail) => {
                tracing::debug!("{}: {detail}", self.port);
                for (i, c) in f.corrupt.iter_mut().enumerate() {
                    if f.results[i].is_none() {
                        *c = Some(detail.clone());
                    }
                }
            }
        }
        if self.in_flight.as_ref().is_some_and(|f| f.open == 0) {
            self.complete();
        }
    }

    /// Ends the exchange under way: every request answered, or the time is up.
    fn complete(&mut self) {
        let Some(f) = self.in_flight.take() else { return };
        self.sending.clear();
        let waited = self.now.saturating_since(f.start);
        if f.open > 0 {
            self.stale = true;
        }
        let results = f
            .results
            .into_iter()
            .zip(f.corrupt)
            .zip(&f.batch)
            .map(|((r, c), (address, request))| match (r, c) {
                (Some(r), _) => Ok(r),
                (None, Some(detail)) => {
                    Err(Error::Corrupt { address: crate::model::Address::checked(*address), request: *request, detail })
                }
                (None, None) => Err(Error::Timeout {
                    address: crate::model::Address::checked(*address),
                    request: *request,
                    waited,
                    round_trips: self.round_trips,
                }),
            })
            .collect();
        self.finish(f.ticket, JobResult::Exchange(results));
    }

    /// The link failed: the job it was doing fails with it, and the session is failed (it may no longer
    /// be able to stop what it started).
    pub fn handle_link_error(&mut self, error: LinkError, now: Timestamp) {
        self.now = now;
        self.failed = true;
        let sent = std::mem::replace(&mut self.sent, Sent::Nothing);
        match sent {
            Sent::Refresh => {
                tracing::info!("watchdog refresh failed: {error}");
                self.duty.last_error = Some(error.to_string());
                return;
            }
            Sent::Broadcast(ticket) => {
                if let Some(t) = self.broadcast_out.take() {
                    if t == ticket {
                        self.finish(t, JobResult::Broadcast(Err(Error::Link(error))));
                        return;
                    }
                    self.broadcast_out = Some(t);
                }
            }
            Sent::Exchange | Sent::Nothing => {}
        }
        self.settle_broadcast();
        let Some(f) = self.in_flight.take() else {
            tracing::info!("{}: {error}", self.port);
            return;
        };
        self.sending.clear();
        // Every request of the batch failed with the line: each gets the line's error.
        let results = f.batch.iter().map(|_| Err(Error::Link(error.clone()))).collect();
        self.finish(f.ticket, JobResult::Exchange(results));
    }
}

/// True for a limit the checks of a motion read ([`Op::Setpoint`](crate::session::Op::Setpoint) caches
/// them): MinPos, MaxPos, MaxVel, MaxCur and the tick limits ActIMinPos, ActIMaxPos, ActIMaxVel.
pub(crate) fn setpoint_limit(param: Param) -> bool {
    matches!(
        param,
        Param::MinPos
            | Param::MaxPos
            | Param::MaxVel
            | Param::MaxCur
            | Param::ActIMinPos
            | Param::ActIMaxPos
            | Param::ActIMaxVel
    )
}

/// True when Config words `before` and `after` differ at most in CONFIGID_MOD_WATCHDOG_ENABLE (what arming
/// and disarming a watchdog writes): the module's kind and what it lets move are the same.
pub(crate) fn only_watchdog_flag(before: ConfigWord, after: ConfigWord) -> bool {
    let flag = crate::model::ConfigFlag::WatchdogEnable;
    before.with(flag) == after.with(flag)
}

/// True for an acknowledge of something that sets a module in motion.
fn moves(r: &Reply) -> bool {
    matches!(r, Reply::Motion { .. } | Reply::IStep | Reply::Action(Action::Home))
}

fn clone_encode(e: &Error) -> Error {
    match e {
        Error::Encode(x) => Error::Encode(*x),
        other => Error::NotSupported(other.to_string()),
    }
}
