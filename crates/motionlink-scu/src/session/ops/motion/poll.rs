//! A move's looks at its actuators while the motion runs, their judgement, and its report.

use super::{idx, Ended, Move};
use crate::error::Error;
use crate::model::{ActuatorStatus1, DataIndex, ErrorCode, PositionCounts, StopMode};
use crate::session::ctx::Ctx;
use crate::session::ops::{error_code, positions, read_item, statuses, ItemRead, Progress};
use crate::session::report::{ActuatorOutcome, MoveProgress, MoveReport};
use crate::session::request::{PreparedRequest, Req, Schedule};
use crate::wire::Command;

/// Error_Code 1, read for the report of a move that ended away from its target.
pub(crate) const LAST_ERROR: DataIndex = DataIndex(0x00D1);

/// A look at the actuators: status 1 and position of A1..A6.
type Look = ([ActuatorStatus1; 6], [PositionCounts; 6]);

impl Move {
    fn primary_target(&self) -> PositionCounts {
        self.targets.iter().find(|(a, _)| *a == self.spec.primary).map_or(PositionCounts(0), |(_, t)| *t)
    }

    /// Waits for the next look and takes it: the next keepalive RC that carries the session's cyclic object,
    /// or, at the time of the next reads, RG of the status and the positions. `Err`: the cause to stop with
    /// (a cancel meanwhile, with the last position seen; a failed read).
    pub(super) async fn look(&mut self, ctx: &Ctx) -> Result<Look, Error> {
        let primary = self.spec.primary;
        let cancelled =
            |last: &[PositionCounts; 6]| Error::Cancelled { actuator: primary, position_counts: last[idx(primary)] };
        if self.by_snapshot {
            return match ctx.snapshot().await {
                Some(Ok(s)) => Ok((s.statuses, s.positions)),
                Some(Err(_)) | None if ctx.cancelled() => Err(cancelled(&self.last_position)),
                Some(Err(e)) => Err(e),
                None => Err(cancelled(&self.last_position)),
            };
        }
        let now = ctx.now();
        // The next poll is due one interval after this one was due (no drift), and never in the past.
        let interval = ctx.core().config.poll_interval;
        while self.next_poll <= now {
            self.next_poll += interval;
        }
        ctx.pause_until(self.next_poll).await;
        if ctx.cancelled() {
            return Err(cancelled(&self.last_position));
        }
        // While polling, a cancel stops the function at once (where it came to rest is read after the stop).
        let reads = ctx.ending_on_cancel(cancelled(&self.last_position));
        let status = statuses(&read_item(&reads, ItemRead::actuators(DataIndex(0x0170), self.actuators())).await?)?;
        let positions = positions(&read_item(&reads, ItemRead::actuators(DataIndex(0x0010), self.actuators())).await?)?;
        Ok((status, positions))
    }

    /// One look at the actuators: progress, the end of the motion and its judgement, a stall, the time limit.
    /// `None`: the next look.
    pub(super) async fn judge(
        &mut self,
        ctx: &Ctx,
        status: [ActuatorStatus1; 6],
        positions: [PositionCounts; 6],
    ) -> Option<Result<MoveReport, Ended>> {
        let (tolerance_counts, start_grace, stall_timeout, move_timeout) = {
            let core = ctx.core();
            let c = &core.config;
            (c.position_tolerance_counts, c.start_grace, c.stall_timeout, c.move_timeout)
        };
        let now = ctx.now();
        let primary = self.spec.primary;
        ctx.progress(Progress::Move(MoveProgress {
            actuator: primary,
            position_counts: positions[idx(primary)],
            start_counts: self.start[idx(primary)],
            target_counts: self.primary_target(),
            status: status[idx(primary)],
        }));
        if ctx.cancelled() {
            let e = Error::Cancelled { actuator: primary, position_counts: positions[idx(primary)] };
            return Some(Err(Ended::Stop(e)));
        }
        let tolerance = i64::from(tolerance_counts);
        let mut moving = false;
        for &(a, _) in &self.targets {
            if status[idx(a)].moving() {
                self.seen_motion[idx(a)] = true;
                moving = true;
            }
        }
        if !moving {
            let outcomes: Vec<ActuatorOutcome> = self
                .targets
                .iter()
                .map(|&(a, target)| ActuatorOutcome {
                    actuator: a,
                    target_counts: target,
                    start_counts: self.start[idx(a)],
                    position_counts: positions[idx(a)],
                    moved: self.seen_motion[idx(a)]
                        || positions[idx(a)].counts_from(self.start[idx(a)]).abs() > tolerance,
                })
                .collect();
            // Where the drives are unknown, an actuator that did not move is not driven by the function.
            let must_arrive = |o: &ActuatorOutcome| !self.drives_unknown || o.actuator == primary || o.moved;
            let off = outcomes.iter().find(|o| must_arrive(o) && o.difference_counts().abs() > tolerance).copied();
            match off {
                None => {
                    self.outcomes = outcomes;
                    // Every RE is ended with an RS, even after the drives stopped by themselves.
                    let rs = PreparedRequest::stop(self.spec.function.id(), StopMode::Soft);
                    let ended = ctx.firm().send(Req::op(rs).when(Schedule::RoomOrLate)).await;
                    return Some(match ended.and_then(|r| r.ack(Command::Stop)) {
                        Ok(_) => Ok(self.report(ctx)),
                        Err(e) => Err(Ended::Failed(e)),
                    });
                }
                Some(o) if self.seen_motion.iter().any(|s| *s) || now - self.started_at >= start_grace => {
                    let read = ctx.firm().get(LAST_ERROR).await;
                    let code = read.and_then(|r| r.data(Command::Get)).ok().and_then(|d| error_code(&d).ok());
                    return Some(Err(Ended::Stop(Error::MotionEnded {
                        actuator: o.actuator,
                        position_counts: o.position_counts,
                        target_counts: o.target_counts,
                        tolerance_counts,
                        error_code: code.unwrap_or(ErrorCode::NONE),
                    })));
                }
                // The unit has not raised the motion bit yet.
                Some(_) => return None,
            }
        }
        for &(a, _) in &self.targets {
            let i = idx(a);
            if positions[i] != self.last_position[i] {
                self.last_position[i] = positions[i];
                self.last_progress_at[i] = now;
            } else if status[i].moving() && now - self.last_progress_at[i] >= stall_timeout {
                tracing::debug!("{a} stalled at {}", positions[i]);
                let after = now - self.last_progress_at[i];
                return Some(Err(Ended::Stop(Error::Stalled { actuator: a, position_counts: positions[i], after })));
            }
        }
        if now - self.started_at >= move_timeout {
            let e =
                Error::MoveTimeout { actuator: primary, position_counts: positions[idx(primary)], after: move_timeout };
            return Some(Err(Ended::Stop(e)));
        }
        None
    }

    /// What could not be verified: the strokes that could not be read, and the writes not read back.
    fn not_verifiable(&self) -> Vec<String> {
        let mut why = self.not_verifiable.clone();
        if !self.not_read_back.is_empty() {
            let names: Vec<String> = self
                .not_read_back
                .iter()
                .map(|i| format!("{} ({i})", crate::model::item(*i).map_or("?", |it| it.name())))
                .collect();
            why.push(format!(
                "{} written (the unit acknowledged RT) but not read back: the unit refuses to read remote data \
                 (RG: PDE)",
                names.join(", ")
            ));
        }
        why
    }

    fn report(&self, ctx: &Ctx) -> MoveReport {
        let primary = self.spec.primary;
        let position_counts = self
            .outcomes
            .iter()
            .find(|o| o.actuator == primary)
            .map_or(self.start[idx(primary)], |o| o.position_counts);
        let not_verifiable = self.not_verifiable();
        MoveReport {
            actuator: primary,
            function: self.spec.function,
            position_counts,
            duration: ctx.now() - self.started_at,
            actuators: self.outcomes.clone(),
            verified: not_verifiable.is_empty(),
            not_verifiable,
        }
    }
}
