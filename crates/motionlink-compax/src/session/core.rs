//! The engine of a session: the one line (a queue of telegrams, one in flight at a time, its reply matched,
//! timed out, sent again when that is safe) and the session's record of the drives (which it set in
//! motion, which answered it, which owe a `$` message, which have comparators armed). Operations reach it
//! through their [`Ctx`](super::ctx::Ctx); nothing here does I/O or reads a clock.

use std::collections::{HashMap, HashSet, VecDeque};
use std::task::Waker;
use std::time::Duration;

use motionlink_link::exec::{Jobs, Ticket};
use motionlink_link::session::OpId;
use motionlink_link::{LinkError, Timestamp};

use super::types::Config;
use crate::error::Error;
use crate::model::{parse_param_reply, Command, ErrorCode, OutputState, ParamId, StatusId, StatusValue};
use crate::wire::reply::ReplyError;
use crate::wire::{Address, Body, EscapedBytes, Flags, Reply, ReplyDecoder, ReplyEvent, ReplyKind, Request, BROADCAST};

/// Bits 1..=31: every drive address.
pub(crate) const ALL_DRIVES: u32 = !1;

/// The drives a command marked started before it was sent ([`Core::before_send`]), and which of them were
/// started already: what a refusal gives back.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Marked {
    drives: u32,
    before: u32,
}

/// The bit of drive `a` in the session's sets of drives; for the broadcast address 32, every drive's.
pub(crate) fn bit(a: Address) -> u32 {
    if a.is_broadcast() {
        ALL_DRIVES
    } else {
        1 << a.get()
    }
}

/// The drives in a set, ascending.
pub(crate) fn drives_in(set: u32) -> Vec<Address> {
    (1..BROADCAST).filter(|a| set & (1 << a) != 0).filter_map(|a| Address::drive(a).ok()).collect()
}

/// When a telegram may be sent again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Retry {
    /// After E70 / E72 / E73, a timeout or a corrupt reply.
    Idempotent,
    /// After E70 / E72 / E73 only; a lost reply is returned to the caller (who checks the drive's state).
    DiscardedOnly,
}

/// What the reply to a request can be, as far as a bare number (`35`, which is also what a comparator sends)
/// is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ReplyShape {
    /// The value of a status read: a bare number is its reply if it reads as that status value.
    Status(StatusId),
    /// The value of a parameter read: a bare number is its reply if it reads as a value.
    Param(ParamId),
    /// An acknowledgement or `Exx` only (moves, settings, outputs, binary telegrams): never a bare number.
    AckOnly,
    /// Anything (an echo, `!`, text the model cannot read): a bare number may be its reply.
    Any,
}

impl ReplyShape {
    pub(crate) fn of(req: &Request<'_>) -> ReplyShape {
        if req.flags.echo {
            return ReplyShape::Any;
        }
        match req.body {
            Body::Execute => ReplyShape::Any,
            Body::Binary(_) => ReplyShape::AckOnly,
            Body::Command(t) => match Command::parse(t) {
                Ok(Command::ReadStatus(id)) => ReplyShape::Status(id),
                Ok(Command::ReadParam(id)) => ReplyShape::Param(id),
                Ok(_) => ReplyShape::AckOnly,
                Err(_) => ReplyShape::Any,
            },
        }
    }

    /// True if `text` (not an error message) can answer the request at all: an acknowledgement is empty,
    /// a read's reply reads as its value.
    fn accepts(self, text: &[u8]) -> bool {
        match self {
            ReplyShape::AckOnly => text.is_empty(),
            other => other.fits(text),
        }
    }

    /// True if a bare number `text` can be the reply.
    fn fits(self, text: &[u8]) -> bool {
        match self {
            ReplyShape::Status(id) => StatusValue::parse(id, text).is_ok(),
            ReplyShape::Param(id) => parse_param_reply(id, text).is_ok(),
            ReplyShape::AckOnly => false,
            ReplyShape::Any => true,
        }
    }
}

/// What a command does to the session's record of the axes it moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Effect {
    /// Nothing the session tracks.
    None,
    /// It may start a positioning (a move, or `!`, which runs whatever the buffer holds).
    Starts,
    /// `OUTPUT O0=0` / `=2`: the drive is switched off, its positioning ends.
    SwitchesOff,
    /// `POSR x OUTPUT Oy=z`: a comparator, whose number the drive will send unasked.
    Comparator,
}

impl Effect {
    pub(crate) fn of_command(c: &Command) -> Effect {
        match c {
            c if c.is_move() => Effect::Starts,
            Command::Output { output: 0, state } if *state != OutputState::ON => Effect::SwitchesOff,
            Command::PosROutput { .. } => Effect::Comparator,
            _ => Effect::None,
        }
    }

    /// Of a telegram as a raw command sends it. A stored (`,`) command is not executed; `!` may start
    /// anything. An echoed (`?`) one may start what it names: the manual says only that the drive sends it
    /// back, not that it does not also carry it out (the emulator's `echo-executes` does), so it counts as
    /// started, while its other effects (a switch-off, a comparator) are not taken for done. Text the model
    /// cannot read is not tracked.
    pub(crate) fn of_request(body: &Body<'_>, flags: Flags) -> Effect {
        if flags.buffer {
            return Effect::None;
        }
        let effect = match body {
            Body::Execute => Effect::Starts,
            Body::Command(t) => Command::parse(t).map_or(Effect::None, |c| Effect::of_command(&c)),
            Body::Binary(b) => Command::from_binary(b).map_or(Effect::None, |c| Effect::of_command(&c)),
        };
        match effect {
            Effect::Starts => Effect::Starts,
            _ if flags.echo => Effect::None,
            other => other,
        }
    }
}

/// A telegram to send, and how its reply is matched and retried.
#[derive(Debug)]
pub(crate) struct Job {
    /// Its ticket, once queued.
    pub id: Option<Ticket>,
    pub op: OpId,
    pub frame: Vec<u8>,
    pub address: Address,
    /// The command as messages name it.
    pub command: String,
    pub expects_reply: bool,
    /// What can answer it (any other reply is late or garbled).
    pub accept: ReplyShape,
    pub retry: Retry,
    /// How often it may be sent again.
    pub retries: u32,
    /// Sent before the other operations' telegrams (the stop sequence).
    pub urgent: bool,
    /// A reply from another drive is this telegram's reply too (the echo of a buffered move `,?`: another
    /// drive answering means a flipped address digit reached it, which the caller must learn of).
    pub take_foreign: bool,
    attempts: u32,
    last_corrupt: Option<ReplyError>,
    unfit: Option<String>,
    /// Its operation was cancelled ([`Core::cut_short`]): unanswered, it fails at once, without a late window.
    cut: bool,
    /// A late window of it passed without any reply: the line lost that reply rather than that the drive
    /// is slow, and its further sendings get no window.
    window_silent: bool,
}

impl Job {
    /// A job for `req`, owned by `op`.
    pub(crate) fn new(op: OpId, req: &Request<'_>, cfg: &Config, retry: Retry) -> Result<Job, Error> {
        let frame = req.encode(&cfg.mode)?;
        Ok(Job {
            id: None,
            op,
            frame: frame.as_bytes().to_vec(),
            address: req.address,
            command: command_text(&req.body, req.flags),
            expects_reply: req.expects_reply(),
            accept: ReplyShape::of(req),
            retry,
            retries: cfg.retries,
            urgent: false,
            take_foreign: req.flags.echo && req.flags.buffer,
            attempts: 0,
            last_corrupt: None,
            unfit: None,
            cut: false,
            window_silent: false,
        })
    }
}

/// The command of a telegram as messages name it.
pub(crate) fn command_text(body: &Body<'_>, flags: Flags) -> String {
    match body {
        Body::Command(t) => format!("{}{flags}", EscapedBytes(t)),
        Body::Execute => format!("!{flags}"),
        Body::Binary(b) => format!("{b} (binary)"),
    }
}

/// The outcome of a job: the reply (`None` when none is due), or why there is none.
pub(crate) type JobResult = Result<Option<Reply>, Error>;

/// A telegram whose reply did not come in time, while the line stays quiet for its late reply.
#[derive(Debug)]
struct LateWindow {
    job: Job,
    /// When it was sent.
    sent_at: Timestamp,
    /// How long it waited (the wire time of request and reply, and the reply timeout).
    waited: Duration,
    /// The end of the window: one more reply timeout after the telegram's deadline.
    until: Timestamp,
}

/// The telegram on the line.
#[derive(Debug)]
struct InFlight {
    job: Job,
    /// When its reply is late (or, for a telegram without reply, when it has left).
    deadline: Timestamp,
    /// When it was handed to the line.
    sent_at: Timestamp,
}

/// The session's state, shared by its operations.
#[derive(Debug)]
pub(crate) struct Core {
    pub cfg: Config,
    /// The time of the latest call into the session.
    pub now: Timestamp,
    /// Drives this session set in motion and has not yet seen stop (bit n: address n).
    pub started: u32,
    /// Drives that have answered this session (a broadcast move counts as started for each of them).
    pub known: u32,
    /// Drives whose move asked for `$` and whose message has not come.
    pub awaiting_message: u32,
    /// Drives whose `$` has come.
    pub message_seen: u32,
    /// `$` messages without address that could not be attributed.
    pub unattributed_messages: u32,
    /// Drives with comparators armed (their bare-number messages are expected).
    pub comparators: u32,
    /// Drives that may hold a move in their buffer, stored by this session and not yet executed.
    pub buffered: u32,
    /// How each drive echoes, once found out (index: address).
    pub echo_forms: [Option<super::types::EchoForm>; 32],
    /// The device profile (its reference) each drive's echo form was taken from, while no exchange of this
    /// session has shown the drive to echo so: a drive that then behaves otherwise has the form found again.
    pub echo_profiles: HashMap<u8, String>,
    /// Drives that echoed a move sent with `,?` and then refused the `!` (they do not store such a command):
    /// their moves go out as commands of their own.
    pub echo_without_store: u32,
    /// Drives whose S17 has shown "command active" in this session: their S17 is taken to show a positioning.
    pub command_bit_seen: u32,
    /// Drives found moving (S1 changing) while their S17 showed no command active: whether they rest is
    /// judged by S1 from then on.
    pub command_bit_missing: u32,
    /// What was already warned about (drive, which): each finding is said once per session.
    pub warned: HashSet<(u8, &'static str)>,
    /// The round trips measured on the line: each reply since its telegram went out.
    pub round_trips: Option<crate::error::RoundTripRange>,
    /// Replies that came after their telegram's time (in its late window, and dropped): how long after
    /// the telegram went out.
    pub late_replies: Option<crate::error::RoundTripRange>,
    /// How long after its telegram the latest late reply came (a scan takes it to name the address).
    pub last_late: Option<Duration>,
    decoder: ReplyDecoder,
    queue: VecDeque<Job>,
    in_flight: Option<InFlight>,
    /// A job whose reply came corrupt: the rest of the broken reply passes before it is decided on.
    settling: Option<InFlight>,
    /// A job whose reply did not come in time: nothing is sent until its late reply came (dropped) or as
    /// long again has passed, so that a late reply is never taken for the next telegram's.
    late: Option<LateWindow>,
    /// The outcomes of telegrams, for the operations that await them.
    pub jobs: Jobs<JobResult>,
    /// XOFF received (since when).
    paused: Option<Timestamp>,
    /// Earliest time of the next send (after a telegram without reply, after a broadcast).
    quiet_until: Timestamp,
    /// Operations that listen while they wait: a line failure ends their wait (and wakes them).
    pub listeners: HashMap<OpId, Waker>,
    /// A line failure for each listening operation.
    pub line_failures: HashMap<OpId, LinkError>,
}

impl Core {
    pub(crate) fn new(cfg: Config, now: Timestamp) -> Self {
        Core {
            decoder: ReplyDecoder::new(&cfg.mode),
            cfg,
            now,
            started: 0,
            known: 0,
            awaiting_message: 0,
            message_seen: 0,
            unattributed_messages: 0,
            comparators: 0,
            buffered: 0,
            echo_forms: [None; 32],
            echo_profiles: HashMap::new(),
            echo_without_store: 0,
            command_bit_seen: 0,
            command_bit_missing: 0,
            warned: HashSet::new(),
            round_trips: None,
            late_replies: None,
            last_late: None,
            queue: VecDeque::new(),
            in_flight: None,
            settling: None,
            late: None,
            jobs: Jobs::default(),
            paused: None,
            quiet_until: Timestamp::ZERO,
            listeners: HashMap::new(),
            line_failures: HashMap::new(),
        }
    }

    /// Warns `message` about drive `address` once per session (`which` names the finding).
    pub(crate) fn warn_once(&mut self, address: Address, which: &'static str, message: impl FnOnce() -> String) {
        if self.warned.insert((address.get(), which)) {
            tracing::warn!("{}", message());
        }
    }

    // --------------------------------------------------------------------------------------------------
    // The record of the drives

    /// Records what sending a command with `effect` to `address` does, before it is sent (a move counts as
    /// started before it is sent: if the session fails then, the stop still reaches it). Returns what to give
    /// [`Core::unmark`] if the drive refuses the command (or it is never sent).
    pub(crate) fn before_send(&mut self, address: Address, effect: Effect) -> Marked {
        let drives = match effect {
            Effect::Starts if address.is_broadcast() => self.known,
            Effect::Starts => bit(address),
            _ => 0,
        };
        if effect == Effect::Starts && address.is_broadcast() && drives == 0 {
            tracing::warn!("a broadcast that may start motion before any drive answered: none can be stopped");
        }
        let marked = Marked { drives, before: self.started & drives };
        self.started |= drives;
        marked
    }

    /// A command [`Core::before_send`] marked was refused or never sent: its drives are as they were before
    /// it. Only its own drives: another operation may have set others moving meanwhile.
    pub(crate) fn unmark(&mut self, marked: Marked) {
        self.started = (self.started & !marked.drives) | marked.before;
    }

    /// Records what a command with `effect` did once the drive took it.
    pub(crate) fn after_send(&mut self, address: Address, effect: Effect) {
        match effect {
            Effect::SwitchesOff => self.finish(address),
            Effect::Comparator => self.comparators |= bit(address),
            Effect::Starts | Effect::None => {}
        }
    }

    /// Before a `!` to `address` (32: every drive) is sent: the buffered moves it executes count as started.
    /// Returns what to give [`Core::unexecute`] if the `!` is refused or never sent.
    pub(crate) fn execute_buffers(&mut self, address: Address) -> Marked {
        let executed = self.buffered & bit(address);
        let marked = Marked { drives: executed, before: self.started & executed };
        self.started |= executed;
        self.buffered &= !executed;
        marked
    }

    /// A `!` [`Core::execute_buffers`] marked was refused or never sent: its moves are still buffered.
    pub(crate) fn unexecute(&mut self, marked: Marked) {
        self.unmark(marked);
        self.buffered |= marked.drives;
    }

    /// Forgets `a` as moving: its positioning ended (or the broadcast address: every drive's). Its
    /// comparators belonged to that positioning, so bare numbers are replies again.
    pub(crate) fn finish(&mut self, a: Address) {
        self.started &= !bit(a);
        self.awaiting_message &= !bit(a);
        self.message_seen &= !bit(a);
        self.comparators &= !bit(a);
        if self.awaiting_message == 0 {
            self.unattributed_messages = 0;
        }
    }

    /// Hands the motion of `drives` over: the session forgets it set them in motion.
    pub(crate) fn release(&mut self, drives: &[Address]) {
        for &a in drives {
            self.started &= !bit(a);
            self.awaiting_message &= !bit(a);
            self.message_seen &= !bit(a);
        }
        if self.awaiting_message == 0 {
            self.unattributed_messages = 0;
        }
    }

    // --------------------------------------------------------------------------------------------------
    // The line

    /// Queues `job`; returns its ticket.
    pub(crate) fn submit(&mut self, mut job: Job) -> Ticket {
        let id = self.jobs.open(job.op);
        job.id = Some(id);
        if job.urgent {
            let at = self.queue.iter().position(|j| !j.urgent).unwrap_or(self.queue.len());
            self.queue.insert(at, job);
        } else {
            self.queue.push_back(job);
        }
        id
    }

    /// Hands the outcome of a job to the operation that awaits it.
    fn finish_job(&mut self, ticket: Option<Ticket>, result: JobResult) {
        if let Some(t) = ticket {
            self.jobs.finish(t, result);
        }
    }

    /// Forgets what operation `op` waited for (it ended).
    pub(crate) fn forget(&mut self, op: OpId) {
        self.jobs.forget(op);
        self.listeners.remove(&op);
        self.line_failures.remove(&op);
    }

    /// Operation `op` was cancelled: its telegram on the line (or being settled), unless it belongs to a
    /// stop (urgent), is not sent again; when the present sending goes unanswered it fails at once, so the
    /// stop that answers the cancel goes out one reply timeout after the cancel at most, not after the
    /// telegram's retries (a COMPAX drive has no watchdog: the axis moves until the stop arrives).
    pub(crate) fn cut_short(&mut self, op: OpId) {
        let on_line = self.in_flight.as_mut().map(|f| &mut f.job);
        let settling = self.settling.as_mut().map(|f| &mut f.job);
        let late = self.late.as_mut().map(|l| &mut l.job);
        for job in [on_line, settling, late].into_iter().flatten().filter(|j| j.op == op && !j.urgent) {
            job.retries = job.retries.min(job.attempts.saturating_sub(1));
            job.cut = true;
        }
        // Already unanswered: it fails now, not at the end of its late window.
        if self.late.as_ref().is_some_and(|l| l.job.cut) {
            self.end_late_window();
        }
    }

    /// Drops the telegrams of `op` not yet sent: each ends as cancelled.
    pub(crate) fn drop_queued(&mut self, op: OpId) {
        let (dropped, kept): (Vec<Job>, Vec<Job>) = self.queue.drain(..).partition(|j| j.op == op && !j.urgent);
        self.queue = kept.into();
        for j in dropped {
            tracing::debug!("drive {}: {:?} not sent: its operation was cancelled", j.address, j.command);
            self.finish_job(j.id, Err(Error::CancelledBeforeMotion));
        }
    }

    /// True while a telegram is on the line, being settled, or in its late window.
    pub(crate) fn busy(&self) -> bool {
        self.in_flight.is_some() || self.settling.is_some() || self.late.is_some()
    }

    /// True when nothing is queued or on the line.
    pub(crate) fn line_idle(&self) -> bool {
        !self.busy() && self.queue.is_empty()
    }

    /// True while something may arrive that the session must read.
    pub(crate) fn wants_input(&self) -> bool {
        self.in_flight.as_ref().is_some_and(|f| f.job.expects_reply)
            || self.settling.is_some()
            || self.late.is_some()
            || (!self.listeners.is_empty() && (self.awaiting_message | self.comparators) != 0)
    }

    /// When the line next needs the session.
    pub(crate) fn line_timeout(&self) -> Option<Timestamp> {
        if let Some(f) = self.in_flight.as_ref().or(self.settling.as_ref()) {
            return Some(f.deadline);
        }
        if let Some(l) = &self.late {
            return Some(l.until);
        }
        if self.queue.is_empty() {
            return None;
        }
        let mut t = None;
        if self.quiet_until > self.now {
            t = Some(self.quiet_until);
        }
        if let Some(since) = self.paused {
            let give_up = since + self.cfg.reply_timeout;
            if give_up > self.now {
                t = Some(t.map_or(give_up, |q: Timestamp| q.max(give_up)));
            }
        }
        t
    }

    /// The next telegram to send at `now`, if one may go.
    pub(crate) fn transmit(&mut self, now: Timestamp) -> Option<Vec<u8>> {
        self.now = now;
        if self.late.is_some() && self.queue.front().is_some_and(|j| j.urgent) {
            // A stop does not wait for a late reply: the late window ends (its telegram is decided on now).
            self.end_late_window();
        }
        if self.busy() || self.queue.is_empty() || now < self.quiet_until {
            return None;
        }
        if let Some(since) = self.paused {
            if now < since + self.cfg.reply_timeout {
                return None;
            }
            // The drive asked for a pause (XOFF, P196 valence 1) and has not said XON within the reply
            // timeout: the telegram goes out rather than hold the session (and a stop) for ever. Said, since
            // the drive may then lose characters (E71, E73) or the whole telegram.
            tracing::warn!(
                "the drive held XOFF for {} ms without an XON (more than the reply timeout): sending the next \
                 telegram anyway",
                (now - since).as_millis()
            );
        }
        let mut job = self.queue.pop_front()?;
        job.attempts += 1;
        self.decoder.reset();
        self.decoder.expect_from(Some(job.address.get()));
        tracing::trace!("send {:?}", EscapedBytes(&job.frame));
        let frame = job.frame.clone();
        let deadline = if job.expects_reply {
            now + self.cfg.char_time() * (frame.len() as u32 + 48) + self.cfg.reply_timeout
        } else {
            let on_wire = self.cfg.char_time() * frame.len() as u32;
            let gap = if job.address.is_broadcast() { self.cfg.broadcast_gap } else { Duration::ZERO };
            self.quiet_until = now + on_wire + gap;
            now + on_wire
        };
        self.in_flight = Some(InFlight { job, deadline, sent_at: now });
        Some(frame)
    }

    /// Bytes arrived at `now`.
    pub(crate) fn receive(&mut self, mut bytes: &[u8], now: Timestamp) {
        self.now = now;
        while !bytes.is_empty() {
            let (used, event) = self.decoder.decode(bytes);
            let event = event.map(ReplyEvent::from);
            bytes = &bytes[used.max(1).min(bytes.len())..];
            let Some(ev) = event else { continue };
            match ev {
                ReplyEvent::Flow(xoff) => {
                    self.paused = if xoff { Some(self.paused.unwrap_or(now)) } else { None };
                }
                ReplyEvent::Reply(r) if self.handle_unsolicited(&r) => {}
                ReplyEvent::Reply(r) => self.reply(r),
                ReplyEvent::Error(e) => self.corrupt(e, now),
            }
        }
    }

    /// A reply that is not an unsolicited message.
    fn reply(&mut self, r: Reply) {
        if let Some(l) = &self.late {
            // Nothing was sent since the telegram whose time is up: this is its reply, late. Dropped (the
            // telegram is decided on as unanswered), and measured, so that its timeout names it.
            let took = self.now.saturating_since(l.sent_at);
            tracing::info!(
                "drive {}: {:?} came {} ms after {:?} was sent, later than the {} ms allowed: not taken",
                l.job.address,
                r.text_str(),
                took.as_millis(),
                l.job.command,
                l.waited.as_millis()
            );
            self.late_replies = Some(crate::error::RoundTripRange::with(self.late_replies, took));
            self.last_late = Some(took);
            self.end_late_window();
            return;
        }
        let Some(f) = self.in_flight.as_mut().filter(|f| f.job.expects_reply) else {
            tracing::debug!("unexpected while listening: {r:?}");
            return;
        };
        let want = f.job.address;
        let foreign_taken = f.job.take_foreign && !matches!(r.kind(), ReplyKind::Error(_));
        if r.address().is_some_and(|a| a != want.get()) && !foreign_taken {
            tracing::debug!("ignoring a reply from drive {:?} while waiting for {want}: {r:?}", r.address());
            return;
        }
        // A reply that cannot answer this request (text to a move or setting, an acknowledgement or
        // another value to a read) is a late reply to an earlier one, or garbled: it is not taken.
        if !matches!(r.kind(), ReplyKind::Error(_)) && !f.job.accept.accepts(r.text()) {
            tracing::info!("drive {want}: {:?} cannot answer this request: ignored", r.text_str());
            f.job.unfit = Some(r.text_str().to_string());
            return;
        }
        let Some(InFlight { job, sent_at, .. }) = self.in_flight.take() else { return };
        if !job.address.is_broadcast() {
            self.known |= bit(job.address);
        }
        self.round_trips =
            Some(crate::error::RoundTripRange::with(self.round_trips, self.now.saturating_since(sent_at)));
        let retry_left = job.attempts <= job.retries;
        match r.kind() {
            ReplyKind::Error(code) if ErrorCode(code).is_retransmit() && retry_left => {
                tracing::info!("drive {} answered E{code}: sending again", job.address);
                self.queue.push_front(job);
            }
            ReplyKind::Error(code) => {
                let e = Error::Refused { address: job.address, command: job.command, code: ErrorCode(code) };
                self.finish_job(job.id, Err(e));
            }
            _ => {
                self.finish_job(job.id, Ok(Some(r)));
            }
        }
    }

    /// A corrupt reply: the rest of it passes (four character times) before the telegram is decided on.
    fn corrupt(&mut self, e: ReplyError, now: Timestamp) {
        let Some(InFlight { mut job, .. }) = self.in_flight.take_if(|f| f.job.expects_reply) else {
            tracing::debug!("corrupt bytes while listening: {e}");
            return;
        };
        tracing::info!("drive {}: corrupt reply ({e})", job.address);
        job.last_corrupt = Some(e);
        self.settling = Some(InFlight { job, deadline: now + self.cfg.char_time() * 4, sent_at: now });
    }

    /// Time has reached `now`: a reply is late, a settling ends, a telegram without reply has left.
    pub(crate) fn tick(&mut self, now: Timestamp) {
        self.now = now;
        if let Some(s) = self.settling.take_if(|s| now >= s.deadline) {
            let job = s.job;
            let retry_left = job.attempts <= job.retries;
            match job.last_corrupt {
                Some(detail) if job.retry != Retry::Idempotent || !retry_left => {
                    let e = Error::Corrupt { address: job.address, command: job.command, detail };
                    self.finish_job(job.id, Err(e));
                }
                _ => self.queue.push_front(job),
            }
        }
        if let Some(l) = self.late.as_mut().filter(|l| now >= l.until) {
            l.job.window_silent = true;
            self.end_late_window();
        }
        let Some(f) = self.in_flight.take_if(|f| now >= f.deadline) else { return };
        let waited = f.deadline.saturating_since(f.sent_at);
        let job = f.job;
        if !job.expects_reply {
            self.finish_job(job.id, Ok(None));
            return;
        }
        tracing::info!("drive {}: no reply (attempt {})", job.address, job.attempts);
        // A drive slower than the allowance answers after all: the line stays quiet for as long again, and
        // a reply that comes then is this telegram's, late (never the next telegram's). A stop's telegram
        // (urgent), and one of a cancelled operation (a stop follows), are decided on at once: a stop does
        // not wait; its telegrams (S17, OUTPUT O0=0) are told apart by their replies' forms, and it is
        // confirmed by S17 read after it. So is a telegram whose earlier late window stayed silent.
        let until = now + self.cfg.reply_timeout;
        let at_once = job.cut || job.urgent || job.window_silent;
        self.late = Some(LateWindow { job, sent_at: f.sent_at, waited, until });
        if at_once || now >= until {
            self.end_late_window();
        }
    }

    /// The late window ends (its time is up, the late reply came, a stop must go, or its operation was
    /// cancelled): its telegram, unanswered in time, is sent again if it may be, or fails.
    fn end_late_window(&mut self) {
        let Some(LateWindow { job, waited, .. }) = self.late.take() else { return };
        let retry_left = job.attempts <= job.retries;
        if job.retry == Retry::Idempotent && retry_left {
            // Behind a stop that is waiting, ahead of everything else.
            let at = if job.urgent { 0 } else { self.queue.iter().position(|j| !j.urgent).unwrap_or(self.queue.len()) };
            self.queue.insert(at, job);
            return;
        }
        let (address, command) = (job.address, job.command);
        let e = match (job.unfit, job.last_corrupt) {
            (Some(reply), _) => Error::UnexpectedReply { address, command, reply },
            (None, Some(detail)) if job.retry == Retry::Idempotent => Error::Corrupt { address, command, detail },
            _ => Error::Timeout {
                address,
                command,
                attempts: job.attempts,
                waited,
                round_trips: self.round_trips,
                late: self.late_replies,
            },
        };
        self.finish_job(job.id, Err(e));
    }

    /// The line failed: the telegram on it fails with `error`, and every listening operation learns of it.
    pub(crate) fn line_failed(&mut self, error: LinkError, now: Timestamp) {
        self.now = now;
        for (op, waker) in self.listeners.drain() {
            self.line_failures.insert(op, error.clone());
            waker.wake();
        }
        let job = self.in_flight.take().or_else(|| self.settling.take()).map(|f| f.job);
        match job.or_else(|| self.late.take().map(|l| l.job)) {
            Some(job) => {
                self.finish_job(job.id, Err(Error::Link(error)));
            }
            None => tracing::debug!("line failure while nothing was on it: {error}"),
        }
    }

    fn handle_unsolicited(&mut self, r: &Reply) -> bool {
        match r.kind() {
            ReplyKind::PositionReached => {
                match r.address() {
                    Some(a) => self.message_seen |= 1 << a.min(31),
                    None if self.awaiting_message.count_ones() == 1 => self.message_seen |= self.awaiting_message,
                    None => self.unattributed_messages += 1,
                }
                tracing::debug!("position reached message from {:?}", r.address());
                true
            }
            ReplyKind::Comparator(n) if self.expects_comparator(r.address()) && !self.may_be_the_reply(r) => {
                tracing::info!("comparator {n} switched (drive {:?})", r.address());
                true
            }
            _ => false,
        }
    }

    /// True when a bare number from `from` (the reply's address prefix, if any) is a comparator message: a
    /// comparator is armed on that drive (on any, when replies carry no address).
    fn expects_comparator(&self, from: Option<u8>) -> bool {
        match from {
            Some(a) => a < BROADCAST && self.comparators & (1 << a) != 0,
            None => self.comparators != 0,
        }
    }

    /// True when `r` can be the reply to the request awaiting one (from its drive, when replies carry an
    /// address, and of the form that request is answered with). A reply to an outstanding request is that
    /// request's reply first: a bare number is a comparator message only when it cannot be.
    fn may_be_the_reply(&self, r: &Reply) -> bool {
        match self.in_flight.as_ref().filter(|f| f.job.expects_reply) {
            None => false,
            Some(f) => r.address().is_none_or(|from| from == f.job.address.get()) && f.job.accept.fits(r.text()),
        }
    }
}
