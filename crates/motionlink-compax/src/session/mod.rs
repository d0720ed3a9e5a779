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
//! read back; the watch) is a state machine inside the session (the private module `ops`). Safety lives here too:
//!
//! - [`Session::cancel`](motionlink_link::session::Session::cancel): the operation's telegrams not yet sent
//!   are dropped (a move not yet sent is never sent); a wait or checked move that had set an axis in
//!   motion stops it (`OUTPUT O0=0` to that drive if S17 says it still moves, confirmed by S17) and ends
//!   with [`Error::Aborted`] saying whether each drive confirmed its stop.
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
    AfterRaw, BusConfig, EchoForm, MoveOptions, MoveReport, MoveRequest, MoveTarget, Op, Output, Progress, RawOutcome,
    StartedMove, TravelLimits, WatchSample, DEFAULT_IN_POSITION_TOLERANCE,
};

use std::collections::VecDeque;
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll, Waker};

use motionlink_link::clock::lock;
use motionlink_link::session::{self as contract, Action, Event, Input, OpId, OpIds};
use motionlink_link::{LinkError, Timestamp};

use self::core::{drives_in, Core};
use self::ctx::Ctx;
use crate::error::{Error, Result, StopReport};
use crate::wire::Address;

type OpFuture = Pin<Box<dyn Future<Output = Result<Output>> + Send>>;

/// One operation under way.
struct Running {
    id: OpId,
    future: OpFuture,
}

/// The COMPAX protocol as a sans-IO state machine; see the [module documentation](self).
pub struct Session {
    core: Arc<Mutex<Core>>,
    ids: OpIds,
    ops: Vec<Running>,
    /// The close sequence, once it runs.
    closer: Option<OpFuture>,
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
        f.debug_struct("Session").field("ops", &self.ops.len()).field("closing", &self.closing).finish()
    }
}

impl Session {
    /// A session for drives as `cfg` says, starting at `now`.
    pub fn new(cfg: BusConfig, now: Timestamp) -> Self {
        Session {
            core: Arc::new(Mutex::new(Core::new(cfg, now))),
            ids: OpIds::default(),
            ops: Vec::new(),
            closer: None,
            closing: false,
            closed: false,
            stopped_by_ops: StopReport::default(),
            events: VecDeque::new(),
            close_report: Arc::new(Mutex::new(None)),
        }
    }

    fn core(&self) -> MutexGuard<'_, Core> {
        lock(&self.core)
    }

    /// The configuration.
    pub fn config(&self) -> BusConfig {
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

    /// Takes how drive `address` echoes from `form` (a device profile's finding) where this session has not
    /// found out yet: the probe is skipped, and no warning is given for it.
    pub fn seed_echo_form(&mut self, address: Address, form: EchoForm) {
        if let Some(slot) = self.core().echo_forms.get_mut(usize::from(address.get())) {
            slot.get_or_insert(form);
        }
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

    fn future_of(ctx: Ctx, op: Op) -> OpFuture {
        Box::pin(async move {
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
        })
    }

    /// Resumes every operation (and the close sequence) until none can go further now.
    fn run(&mut self) {
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            let mut ended = false;
            let mut i = 0;
            while i < self.ops.len() {
                if let Poll::Ready(result) = self.ops[i].future.as_mut().poll(&mut cx) {
                    let op = self.ops.swap_remove(i);
                    self.forget(op.id);
                    if let (true, Err(e)) = (self.closing, &result) {
                        if let Some(stop) = e.stop_report() {
                            self.stopped_by_ops.drives.extend(stop.drives.iter().cloned());
                        }
                    }
                    self.events.push_back(Event::Done(op.id, result));
                    ended = true;
                } else {
                    i += 1;
                }
            }
            if self.closing && self.ops.is_empty() && self.closer.is_none() && !self.closed {
                let ctx = Ctx::new(Arc::clone(&self.core), OpId(0));
                self.closer = Some(Box::pin(async move {
                    let report = ctx.stop_started().await;
                    Ok(Output::Stopped(report))
                }));
            }
            if let Some(closer) = self.closer.as_mut() {
                if let Poll::Ready(result) = closer.as_mut().poll(&mut cx) {
                    let mut report = std::mem::take(&mut self.stopped_by_ops);
                    if let Ok(Output::Stopped(r)) = result {
                        report.drives.extend(r.drives);
                    }
                    let outcome = if report.all_confirmed() {
                        Ok(())
                    } else {
                        Err(Error::CloseUnconfirmed { stop: report.clone() })
                    };
                    *lock(&self.close_report) = Some(report);
                    self.events.push_back(Event::Closed(outcome));
                    self.closer = None;
                    self.closed = true;
                }
            }
            let progress: Vec<_> = self.core().progress.drain(..).collect();
            self.events.extend(progress.into_iter().map(|(id, p)| Event::Progress(id, p)));
            if !ended {
                break;
            }
        }
    }

    /// Drops what the session kept for operation `id`.
    fn forget(&mut self, id: OpId) {
        let mut core = self.core();
        core.cancelled.remove(&id);
        core.sleepers.remove(&id);
        core.listeners.remove(&id);
        core.line_failures.remove(&id);
    }
}

impl contract::Session for Session {
    type Op = Op;
    type Output = Output;
    type Progress = Progress;
    type Error = Error;

    fn start(&mut self, op: Op, now: Timestamp) -> OpId {
        let id = self.ids.next_id();
        self.core().now = now;
        if self.closing {
            self.events.push_back(Event::Done(id, Err(Error::Closed)));
            return id;
        }
        let ctx = Ctx::new(Arc::clone(&self.core), id);
        self.ops.push(Running { id, future: Self::future_of(ctx, op) });
        self.run();
        id
    }

    fn cancel(&mut self, id: OpId, now: Timestamp) {
        if !self.ops.iter().any(|o| o.id == id) {
            return;
        }
        {
            let mut core = self.core();
            core.now = now;
            core.cancelled.insert(id);
            core.drop_queued(id);
        }
        self.run();
    }

    fn close(&mut self, now: Timestamp) {
        if self.closing {
            return;
        }
        self.closing = true;
        let ids: Vec<OpId> = self.ops.iter().map(|o| o.id).collect();
        {
            let mut core = self.core();
            core.now = now;
            for id in ids {
                core.cancelled.insert(id);
                core.drop_queued(id);
            }
        }
        self.run();
    }

    fn handle_input(&mut self, input: Input<'_>, now: Timestamp) {
        match input {
            Input::Bytes(bytes) => self.core().receive(bytes, now),
            Input::Frame(_) => tracing::warn!("a CAN frame on a COMPAX session: ignored"),
        }
        self.run();
    }

    fn handle_link_error(&mut self, error: LinkError, now: Timestamp) {
        tracing::info!("line failure: {error}");
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
        let frame = {
            let mut core = self.core();
            core.tick(now);
            core.transmit(now)
        };
        self.run();
        frame.map(Action::Send)
    }

    fn poll_timeout(&self) -> Option<Timestamp> {
        let core = self.core();
        let sleepers = core.sleepers.values().copied().min();
        match (core.line_timeout(), sleepers) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn handle_timeout(&mut self, now: Timestamp) {
        self.core().tick(now);
        self.run();
    }

    fn poll_event(&mut self) -> Option<Event<Self>> {
        self.events.pop_front()
    }

    fn wants_input(&self) -> bool {
        self.core().wants_input()
    }

    fn is_idle(&self) -> bool {
        self.ops.is_empty() && (!self.closing || self.closed) && self.core().line_idle()
    }
}
