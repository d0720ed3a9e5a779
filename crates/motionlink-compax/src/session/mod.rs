//! The COMPAX protocol as a sans-IO [`Session`]: it is told what arrived on the line and what time it is,
//! and says what to send, when to wake it, and what happened. No thread, no clock, no I/O.
//!
//! One telegram is on the line at a time (RS485 is half duplex, and a drive answers only when asked). The
//! session matches each reply to its request, ignoring replies that cannot answer it (text to a move, an
//! acknowledgement or another value to a read: late or garbled); takes the `$` position-reached message
//! and comparator numbers for what they are; sends a telegram again after E70, E72 and E73 (the drive
//! discarded it), and after a timeout or a corrupt reply only when that is safe (reads, settings, POSA,
//! buffered commands; never a POSR, whose arrival the drive's target S2 tells instead).
//!
//! Every multi-step operation ([`Op`]: a checked move with its limits, S16 / S17 checks, S2 read back, the
//! wait at its poll rate and the in-position check; the scan; the synchronous start; a parameter write
//! read back; the watch) is an `async fn` of the session (the private module `ops`), run by the one executor of
//! `motionlink-link`. Safety lives here too:
//!
//! - [`Session::cancel`](motionlink_link::session::Session::cancel): the operation's telegrams not yet sent
//!   are dropped (a move not yet sent is never sent); a wait or checked move that had set an axis in
//!   motion stops it (`OUTPUT O0=0` to that drive if S17 says it still moves, confirmed by S17) and ends
//!   with [`Error::Cancelled`] saying whether each drive confirmed its stop.
//! - [`Session::close`](motionlink_link::session::Session::close): every operation is cancelled, then every
//!   drive the session set in motion and has not seen stop is stopped the same way; [`Event::Closed`] is
//!   `Ok` once every drive confirmed, [`Error::CloseUnconfirmed`] otherwise.
//!
//! The stop is addressed to each drive the session started, never broadcast: other drives on the bus may be
//! someone else's. COMPAX has no host watchdog: nothing stops an axis if the host dies.

pub(crate) mod core;
pub(crate) mod ctx;
mod ops;
#[cfg(test)]
mod tests;
mod types;

pub use types::{
    AfterRaw, Config, EchoForm, MoveOptions, MoveReport, MoveRequest, MoveTarget, Op, Output, Progress, RawOutcome,
    StartedMove, TravelLimits, WatchSample, DEFAULT_IN_POSITION_TOLERANCE,
};

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use motionlink_link::clock::lock;
use motionlink_link::exec::{CoreGuard, Executor, Report};
use motionlink_link::session::{self as contract, Action, Event, Input, OpId};
use motionlink_link::{LinkError, Timestamp};

use self::core::{drives_in, Core};
use self::ctx::Ctx;
use crate::error::{Error, Result, StopReport};
use crate::wire::Address;

/// The id of the close sequence (operations get ids from 1).
const CLOSER: OpId = OpId(0);

/// The COMPAX protocol as a sans-IO state machine; see the [module documentation](self).
pub struct Session {
    /// The operations (and the close sequence, once it runs), run by the one executor of `motionlink-link`.
    exec: Executor<Core, Progress, Result<Output>>,
    /// The close sequence has started.
    closer: bool,
    closing: bool,
    /// The close sequence has ended.
    closed: bool,
    /// What the operations the close cancelled stopped themselves (part of the close's report).
    stopped_by_ops: StopReport,
    events: VecDeque<Event<Session>>,
    /// What the close sequence found, for the caller who closed.
    close_report: Arc<Mutex<Option<StopReport>>>,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session").field("ops", &self.exec.len()).field("closing", &self.closing).finish()
    }
}

impl Session {
    /// A session for drives as `cfg` says, starting at `now`.
    pub fn new(cfg: Config, now: Timestamp) -> Self {
        Session {
            exec: Executor::new(Core::new(cfg, now), now),
            closer: false,
            closing: false,
            closed: false,
            stopped_by_ops: StopReport::default(),
            events: VecDeque::new(),
            close_report: Arc::new(Mutex::new(None)),
        }
    }

    fn core(&self) -> CoreGuard<'_, Core, Progress> {
        self.exec.core()
    }

    /// Every call into the session tells it the time: the line's and the operations' clock.
    fn now_is(&mut self, now: Timestamp) {
        self.exec.core_at(now).now = now;
    }

    /// The configuration.
    pub fn config(&self) -> Config {
        self.core().cfg.clone()
    }

    /// The drives this session set in motion and has not yet seen stop.
    pub fn started(&self) -> Vec<Address> {
        drives_in(self.core().started)
    }

    /// How drive `address` echoes, if this session has found out (see [`EchoForm`]).
    pub fn echo_form(&self, address: Address) -> Option<EchoForm> {
        self.core().echo_forms.get(usize::from(address.get())).copied().flatten()
    }

    /// Takes how drive `address` echoes from `form`, the finding of the device profile `profile` (its
    /// reference, which messages name), where this session has not found out yet: the probe is skipped, and
    /// no warning is given for it. A drive that then contradicts it (refuses a move sent with `,?`, or
    /// echoes one in another form) has its form found out again, as without a profile, with a warning that
    /// names the profile; once an echo has shown the form, it is checked as one found by this session.
    pub fn seed_echo_form(&mut self, address: Address, form: EchoForm, profile: &str) {
        let mut core = self.core();
        if let Some(slot @ None) = core.echo_forms.get_mut(usize::from(address.get())) {
            *slot = Some(form);
            core.echo_profiles.insert(address.get(), profile.to_string());
        }
    }

    /// True when drive `address` was found this session to echo a move sent with `,?` without storing it
    /// (it refused the `!` after the echo): its moves are sent as commands of their own.
    pub fn echo_without_store(&self, address: Address) -> bool {
        self.core().echo_without_store & self::core::bit(address) != 0
    }

    /// The drives that have answered this session.
    pub fn known(&self) -> Vec<Address> {
        drives_in(self.core().known)
    }

    /// Hands the motion of `drives` over to the caller: the session forgets that it set them in motion, so
    /// neither closing it nor a cancelled wait stops them, and it no longer waits for their `$` messages.
    /// The broadcast address releases every drive.
    pub fn release(&mut self, drives: &[Address]) {
        self.core().release(drives);
    }

    /// Where the report of the close sequence is put when it ends (shared with the client that closes).
    pub fn close_report(&self) -> Arc<Mutex<Option<StopReport>>> {
        Arc::clone(&self.close_report)
    }

    async fn run_op(ctx: Ctx, op: Op) -> Result<Output> {
        {
            Ok(match op {
                Op::ReadStatus(a, id) => Output::Status(ctx.read_status(a, id).await?),
                Op::ReadStatuses(a, ids) => Output::Statuses(ctx.read_statuses(a, &ids).await?),
                Op::ReadParam(a, id) => Output::Number(ctx.read_param(a, id).await?),
                Op::WriteParam(a, id, v) => {
                    ctx.write_param(a, id, v).await?;
                    Output::Done
                }
                Op::Command(a, c) => Output::Text(ctx.command(a, &c).await?),
                Op::Setting(a, c, binary) => {
                    ctx.setting(a, &c, binary).await?;
                    Output::Done
                }
                Op::Raw(a, text) => Output::Reply(ctx.raw(a, &text).await?),
                Op::RawMotion(a, text, after) => Output::Raw(ctx.raw_motion(a, &text, after).await?),
                Op::Echo(a, text) => Output::Text(ctx.echo(a, &text).await?),
                Op::ProbeEcho(a) => {
                    ctx.echo_form(a).await?;
                    Output::Done
                }
                Op::Move(a, c, opts) => {
                    ctx.start_move(a, c, opts, None).await?;
                    Output::Done
                }
                Op::SyncStart(moves, message) => {
                    ctx.sync_start(&moves, message).await?;
                    Output::Done
                }
                Op::Broadcast(c) => {
                    ctx.broadcast(&c).await?;
                    Output::Done
                }
                Op::Home(a, timeout) => Output::Homed(ctx.home(a, timeout).await?),
                Op::Wait(drives, timeout) => {
                    ctx.wait_reached(&drives, timeout).await?;
                    Output::Done
                }
                Op::MoveTo(a, request) => Output::Moved(ctx.move_to(a, &request).await?),
                Op::StartMove(a, request, hand_over) => {
                    let started = ctx.start_checked_move(a, &request).await?;
                    if hand_over {
                        ctx.core().release(&[a]);
                    }
                    Output::Started(started)
                }
                Op::FinishMove(started, timeout) => Output::Moved(ctx.finish_checked_move(&started, timeout).await?),
                Op::Scan(range) => Output::Found(ctx.scan(range).await?),
                Op::Stop(a) => {
                    ctx.stop(a).await?;
                    Output::Done
                }
                Op::StopStarted => Output::Stopped(ctx.stop_started().await),
                Op::StopIfMoving(drives) => {
                    if drives.iter().any(|a| a.is_broadcast()) {
                        return Err(Error::Broadcast("a stop reads each drive's S17"));
                    }
                    Output::Stopped(ctx.stop_if_moving(&drives).await)
                }
                Op::Watch(a, interval) => {
                    ctx.watch(a, interval).await?;
                    Output::Done
                }
                Op::Pause(d) => {
                    ctx.pause(d).await?;
                    Output::Done
                }
            })
        }
    }

    /// Resumes every operation (and the close sequence) until none can go further now.
    fn run(&mut self) {
        loop {
            let mut ended = Vec::new();
            let closing = self.closing;
            let (events, stopped_by_ops, closed) = (&mut self.events, &mut self.stopped_by_ops, &mut self.closed);
            let close_report = &self.close_report;
            self.exec.run(|report| match report {
                Report::Progress(id, p) => events.push_back(Event::Progress(id, p)),
                Report::Done(CLOSER, result) => {
                    ended.push(CLOSER);
                    let mut report = std::mem::take(stopped_by_ops);
                    if let Ok(Output::Stopped(r)) = result {
                        report.drives.extend(r.drives);
                    }
                    let outcome = if report.all_confirmed() {
                        Ok(())
                    } else {
                        Err(Error::CloseUnconfirmed { stop: report.clone() })
                    };
                    *lock(close_report) = Some(report);
                    events.push_back(Event::Closed(outcome));
                    *closed = true;
                }
                Report::Done(id, result) => {
                    ended.push(id);
                    if let (true, Err(e)) = (closing, &result) {
                        if let Some(stop) = e.stop_report() {
                            stopped_by_ops.drives.extend(stop.drives.iter().cloned());
                        }
                    }
                    events.push_back(Event::Done(id, result));
                }
            });
            for id in ended {
                self.core().forget(id);
            }
            if self.closing && self.exec.is_empty() && !self.closer && !self.closed {
                self.closer = true;
                self.exec.spawn(CLOSER, |ctx| async move { Ok(Output::Stopped(Ctx::new(ctx).stop_started().await)) });
                continue;
            }
            return;
        }
    }
}

impl contract::Session for Session {
    type Op = Op;
    type Output = Output;
    type Progress = Progress;
    type Error = Error;

    fn start(&mut self, op: Op, now: Timestamp) -> OpId {
        let id = self.exec.next_id();
        self.now_is(now);
        if self.closing {
            self.events.push_back(Event::Done(id, Err(Error::Closed)));
            return id;
        }
        self.exec.spawn(id, |ctx| Self::run_op(Ctx::new(ctx), op));
        self.run();
        id
    }

    fn cancel(&mut self, id: OpId, now: Timestamp) {
        if id == CLOSER || !self.exec.contains(id) {
            return;
        }
        self.now_is(now);
        self.exec.cancel(id);
        self.core().drop_queued(id);
        self.core().cut_short(id);
        self.run();
    }

    fn close(&mut self, now: Timestamp) {
        if self.closing {
            return;
        }
        self.closing = true;
        self.now_is(now);
        for id in self.exec.ids() {
            self.exec.cancel(id);
            self.core().drop_queued(id);
        }
        self.run();
    }

    fn handle_input(&mut self, input: Input<'_>, now: Timestamp) {
        self.now_is(now);
        match input {
            Input::Bytes(bytes) => self.core().receive(bytes, now),
            Input::Frame(_) => tracing::warn!("a CAN frame on a COMPAX session: ignored"),
        }
        self.run();
    }

    fn handle_link_error(&mut self, error: LinkError, now: Timestamp) {
        tracing::info!("line failure: {error}");
        self.now_is(now);
        self.core().line_failed(error, now);
        self.run();
    }

    fn handle_reopened(&mut self, result: std::result::Result<(), LinkError>, now: Timestamp) {
        // A COMPAX session never asks for a reopen; a failed one is a line failure like any other.
        if let Err(e) = result {
            self.handle_link_error(e, now);
        }
    }

    fn poll_transmit(&mut self, now: Timestamp) -> Option<Action> {
        self.now_is(now);
        let frame = {
            let mut core = self.core();
            core.tick(now);
            core.transmit(now)
        };
        self.run();
        frame.map(Action::Send)
    }

    fn poll_timeout(&self) -> Option<Timestamp> {
        let line = self.core().line_timeout();
        [line, self.exec.poll_timeout()].into_iter().flatten().min()
    }

    fn handle_timeout(&mut self, now: Timestamp) {
        self.now_is(now);
        self.core().tick(now);
        self.exec.handle_timeout(now);
        self.run();
    }

    fn poll_event(&mut self) -> Option<Event<Self>> {
        self.events.pop_front()
    }

    fn wants_input(&self) -> bool {
        self.core().wants_input()
    }

    fn is_idle(&self) -> bool {
        self.exec.is_empty() && (!self.closing || self.closed) && self.core().line_idle()
    }
}
