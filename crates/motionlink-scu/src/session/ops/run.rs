//! A function's run: RE, then watching until the motion ends, a time limit, or a cancel; then the stop,
//! confirmed by the status.

use std::time::Duration;

use motionlink_link::Timestamp;

use super::object::define_object;
use super::stop::{after_stop, Stop};
use super::switch::{self, Before, Checked};
use super::{read_item, statuses, ItemRead, Output, Progress, RunAction, RunSpec};
use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataIndex, Function, PositionCounts, StopMode, UNUSED};
use crate::session::ctx::Ctx;
use crate::session::report::{RunProgress, RunReport};
use crate::session::request::{PreparedRequest, Req};
use crate::wire::{Command, Request};

/// A pause without end: a switching function without a time limit runs until it is cancelled.
const FOREVER: Duration = Duration::from_secs(100 * 365 * 86_400);

/// A run; see [`super::Op::Run`] and [`crate::Client::run`].
struct Run {
    spec: RunSpec,
    started_at: Timestamp,
    seen_motion: bool,
    /// Why the watch could not go on (a look at the actuators failed): the run is stopped and fails with it.
    failed: Option<Error>,
    /// A switching function: what its status showed after the RE.
    switched_on: Option<Checked>,
}

/// Runs a function ([`super::Op::Run`]): RE, the watch until it is over, the stop.
pub(crate) async fn run(ctx: &Ctx, spec: RunSpec) -> Result<Output, Error> {
    let mut run = Run { spec, started_at: ctx.now(), seen_motion: false, failed: None, switched_on: None };
    let function = run.function();
    if let RunAction::Switch(Function::Motion(m)) = spec.action {
        return Err(Error::invalid(format!("{m} is a motion function: run it with a direction")));
    }
    if run.is_motion() {
        // A motion function is watched through the keepalive where the unit takes the session's object.
        define_object(&ctx.ending_on_cancel(Error::CancelledBeforeMotion(Command::Execute))).await?;
    }
    let params = match spec.action {
        RunAction::Motion(_, direction) => [direction.code(), UNUSED],
        RunAction::Switch(_) => [UNUSED, UNUSED],
    };
    // A switching function's status entry, read before the RE where the session has yet to see it follow.
    let before = match run.is_motion() {
        true => Before::NotRead,
        false => switch::before(ctx, function, true).await?,
    };
    let re = PreparedRequest::new(&Request::Execute { function: function.id(), params })?;
    match ctx.send(Req::op(re)).await {
        Err(e @ Error::CancelledBeforeMotion(_)) => return Err(e),
        reply => match reply.and_then(|r| r.ack(Command::Execute)) {
            // The unit refused. A switching function is left as it is (an RS would switch off what another
            // host may have switched on: an emergency stop). A motion function gets its RS: a refusal can
            // answer a repeat of an RE the unit took after a lost answer (see `PeGuarded::next`), the motion
            // then running.
            Err(e @ Error::Refused { .. }) if !run.is_motion() => {
                super::say_last_error_of_pe(ctx, &e).await;
                return Err(e);
            }
            Err(e @ Error::Refused { .. }) => {
                tracing::warn!("{function}: {e}; stopping it (an earlier sending may have started it)");
                let refused = e.clone();
                let stopped = run.stop_after(ctx, e).await;
                super::say_last_error_of_pe(ctx, &refused).await;
                return Err(stopped);
            }
            // Without a clean answer the RE may have started the function: it is stopped. A cancel that cut
            // the RE's repeats short is that cancel; otherwise the run failed (it was never seen to start).
            Err(e) if ctx.cancelled() => {
                tracing::warn!("{function}: {e}; stopping it");
                return run.stop(ctx).await;
            }
            Err(e) => {
                tracing::warn!("{function}: {e}; stopping it");
                return Err(run.stop_after(ctx, e).await);
            }
            Ok(_) => {}
        },
    }
    if !run.is_motion() {
        // What the status shows after the RE; one that shows it off is an error, after the RS that follows.
        match switch::check(ctx, function, true, &before).await {
            Ok(checked) => run.switched_on = Some(checked),
            Err(e) => {
                tracing::info!("{function}: {e}; switching it off");
                return Err(match run.stop_after(ctx, e).await {
                    Error::SwitchNotShown { function, command, word, after, .. } => {
                        Error::SwitchNotShown { function, command, word, after, switched_off: true }
                    }
                    other => other,
                });
            }
        }
    }
    let by_snapshot = {
        let core = ctx.core();
        core.poll_slot().is_some() && core.poll.configured
    };
    ctx.progress(Progress::Run(RunProgress {
        function,
        elapsed: ctx.now() - run.started_at,
        statuses: [ActuatorStatus1::EMPTY; 6],
        positions: [PositionCounts(0); 6],
        switched_on_shown: run.switched_on.as_ref().map(|c| c.why.is_none()),
    }));
    if ctx.cancelled() {
        return run.stop(ctx).await;
    }
    loop {
        let over = if by_snapshot && run.is_motion() {
            match ctx.snapshot().await {
                Some(Ok(s)) => run.look(ctx, s.statuses, s.positions),
                None => true,
                Some(Err(_)) if ctx.cancelled() => true,
                Some(Err(e)) => {
                    tracing::warn!("{function}: {e}; stopping it");
                    run.failed = Some(e);
                    true
                }
            }
        } else {
            run.watch(ctx).await
        };
        if over {
            // A run whose watch failed did not end: it is stopped, and fails with what failed.
            return match run.failed.take() {
                Some(e) => Err(run.stop_after(ctx, e).await),
                None => run.stop(ctx).await,
            };
        }
    }
}

impl Run {
    fn function(&self) -> Function {
        match self.spec.action {
            RunAction::Motion(m, _) => Function::Motion(m),
            RunAction::Switch(f) => f,
        }
    }

    fn is_motion(&self) -> bool {
        matches!(self.spec.action, RunAction::Motion(..))
    }

    /// Waits for the next look (a pause, then a read of the status); true when the run is over.
    async fn watch(&mut self, ctx: &Ctx) -> bool {
        let now = ctx.now();
        let limit_at = self.spec.limit.map(|l| self.started_at + l);
        if !self.is_motion() {
            ctx.pause_until(limit_at.unwrap_or(now + FOREVER)).await;
            return true;
        }
        let next = now + ctx.core().config.poll_interval;
        ctx.pause_until(limit_at.map_or(next, |l| l.min(next))).await;
        if ctx.cancelled() || self.spec.limit.is_some_and(|l| ctx.now() - self.started_at >= l) {
            return true;
        }
        let reads = ctx.ending_on_cancel(Error::CancelledBeforeMotion(Command::Get));
        let status = read_item(&reads, ItemRead::all(DataIndex(0x0170))).await;
        if ctx.cancelled() {
            return true;
        }
        match status.and_then(|d| statuses(&d)) {
            Ok(s) => self.look(ctx, s, [PositionCounts(0); 6]),
            Err(e) => {
                tracing::warn!("{}: the status could not be read ({e}); stopping it", self.function());
                self.failed = Some(e);
                true
            }
        }
    }

    /// One look at the actuators: progress, and whether the run is over.
    fn look(&mut self, ctx: &Ctx, status: [ActuatorStatus1; 6], positions: [PositionCounts; 6]) -> bool {
        let elapsed = ctx.now() - self.started_at;
        let function = self.function();
        ctx.progress(Progress::Run(RunProgress {
            function,
            elapsed,
            statuses: status,
            positions,
            switched_on_shown: None,
        }));
        if ctx.cancelled() || self.spec.limit.is_some_and(|l| elapsed >= l) {
            return true;
        }
        if self.spec.limit.is_none() {
            // A motion function ends when none of the actuators moves any more.
            let moving = status.iter().any(|s| s.moving());
            self.seen_motion |= moving;
            let start_grace = ctx.core().config.start_grace;
            if !moving && (self.seen_motion || elapsed >= start_grace) {
                return true;
            }
        }
        false
    }

    /// A motion function's run that ended with no actuator seen moving: its start grace passed (no time
    /// limit, no cancel ended it first).
    fn unseen(&self) -> bool {
        self.is_motion() && !self.seen_motion && self.spec.limit.is_none() && self.failed.is_none()
    }

    /// What a run that no actuator was seen to carry out says, with Error_Code 1 (read now; said if it
    /// cannot be read).
    async fn no_motion_seen(&self, ctx: &Ctx) -> String {
        let read = ctx.firm().get(super::motion::poll::LAST_ERROR).await;
        let code = read.and_then(|r| r.data(Command::Get)).and_then(|d| super::error_code(&d));
        let last = match code {
            Ok(code) => format!("the unit's last error: {code}"),
            Err(e) => format!("its last error could not be read: {e}"),
        };
        format!(
            "no actuator was seen moving within the start grace ({} ms): each already stood at the end it was sent \
             to, or the unit did not carry the function out ({last})",
            ctx.core().config.start_grace.as_millis()
        )
    }

    /// Stops the function (fast) and confirms it; the run's end.
    /// `cause` ended the run before it was seen to start: the function is stopped; the error is `cause` once
    /// the stop is confirmed, else [`Error::StopUnconfirmed`].
    async fn stop_after(&self, ctx: &Ctx, cause: Error) -> Error {
        let stop = self.stopping();
        let stopped = stop.run(ctx).await.rest;
        after_stop(cause, stopped.map(|(_, p)| p), &stop)
    }

    /// The stop of the function (fast), confirmed by the status of every actuator for a motion function.
    fn stopping(&self) -> Stop {
        let watch = if self.is_motion() { Actuator::all().collect() } else { Vec::new() };
        Stop::new(self.function(), StopMode::Fast, watch)
    }

    async fn stop(&self, ctx: &Ctx) -> Result<Output, Error> {
        let function = self.function();
        let stop = self.stopping();
        match stop.run(ctx).await.rest {
            Ok((status, positions)) => {
                let rest: Vec<(Actuator, PositionCounts)> = Actuator::all()
                    .filter(|a| status[usize::from(a.number() - 1)].available())
                    .map(|a| (a, positions[usize::from(a.number() - 1)]))
                    .collect();
                // A switching function: what its status shows after the RS (the unit acknowledged it). A motion
                // function that no actuator was seen to carry out (its start grace passed with none moving,
                // nothing ended the run early) is not taken for one that ran: said, with the unit's last error.
                let (verified, not_verifiable) = match (self.is_motion(), &self.switched_on) {
                    (true, _) if self.unseen() && !ctx.cancelled() => (false, vec![self.no_motion_seen(ctx).await]),
                    (true, _) => (true, Vec::new()),
                    (false, on) => {
                        let off = switch::check(ctx, function, false, &Before::NotRead).await?;
                        match on {
                            Some(on) => switch::run_verified(on, &off),
                            // The RE's answer was lost to a cancel: what counts is that it is off.
                            None => (off.why.is_none(), off.why.into_iter().collect()),
                        }
                    }
                };
                if ctx.cancelled() {
                    Err(Error::RunCancelled { function, rest, verified, not_verifiable })
                } else {
                    let duration = ctx.now() - self.started_at;
                    Ok(Output::Run(RunReport { function, duration, rest, verified, not_verifiable }))
                }
            }
            Err((detail, _)) if ctx.cancelled() => {
                Err(stop.unconfirmed(Error::FunctionCancelled { function_id: function.id(), stopped: false }, detail))
            }
            Err((detail, e)) => Err(stop.unconfirmed(e, detail)),
        }
    }
}
