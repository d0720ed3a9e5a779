//! A move's looks at its actuators while the motion runs, their judgement, and its report.

use super::{idx, Move, Phase};
use crate::error::Error;
use crate::model::{ActuatorStatus1, DataIndex, ErrorCode, PositionCounts, StopMode};
use crate::session::ops::{get, Cx, Next, Progress};
use crate::session::report::{ActuatorOutcome, MoveProgress, MoveReport};
use crate::session::request::{PreparedRequest, Req, Schedule};

/// Error_Code 1, read for the report of a move that ended away from its target.
const LAST_ERROR: DataIndex = DataIndex(0x00D1);

impl Move {
    fn primary_target(&self) -> PositionCounts {
        self.targets.iter().find(|(a, _)| *a == self.spec.primary).map_or(PositionCounts(0), |(_, t)| *t)
    }

    /// Waits for the next look: the next keepalive RC that carries the session's cyclic object, or the time
    /// of the next reads.
    pub(super) fn poll(&mut self, cx: &mut Cx<'_>) -> Next {
        self.phase = Phase::Poll;
        if self.by_snapshot {
            return Next::Snapshot;
        }
        let now = cx.now();
        // The next poll is due one interval after this one was due (no drift), and never in the past.
        let interval = cx.config().poll_interval;
        while self.next_poll <= now {
            self.next_poll += interval;
        }
        Next::Sleep(self.next_poll)
    }

    /// One look at the actuators: progress, the end of the motion and its judgement, a stall, the time limit.
    pub(super) fn judge(
        &mut self,
        cx: &mut Cx<'_>,
        status: [ActuatorStatus1; 6],
        positions: [PositionCounts; 6],
    ) -> Next {
        let (tolerance_counts, start_grace, stall_timeout, move_timeout) = {
            let c = cx.config();
            (c.position_tolerance_counts, c.start_grace, c.stall_timeout, c.move_timeout)
        };
        let now = cx.now();
        let primary = self.spec.primary;
        cx.progress(Progress::Move(MoveProgress {
            actuator: primary,
            position_counts: positions[idx(primary)],
            start_counts: self.start[idx(primary)],
            target_counts: self.primary_target(),
            status: status[idx(primary)],
        }));
        if cx.cancelled {
            return self.stop(cx, Error::Cancelled { actuator: primary, position_counts: positions[idx(primary)] });
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
                    self.phase = Phase::FinalStop;
                    let rs = PreparedRequest::stop(self.spec.function.id(), StopMode::Soft);
                    return Next::Send(Req::op(rs).when(Schedule::RoomOrLate));
                }
                Some(o) if self.seen_motion.iter().any(|s| *s) || now - self.started_at >= start_grace => {
                    self.phase = Phase::ErrorCode(Error::MotionEnded {
                        actuator: o.actuator,
                        position_counts: o.position_counts,
                        target_counts: o.target_counts,
                        tolerance_counts,
                        error_code: ErrorCode::NONE,
                    });
                    return get(LAST_ERROR);
                }
                // The unit has not raised the motion bit yet.
                Some(_) => return self.poll(cx),
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
                return self.stop(cx, Error::Stalled { actuator: a, position_counts: positions[i], after });
            }
        }
        if now - self.started_at >= move_timeout {
            let e =
                Error::MoveTimeout { actuator: primary, position_counts: positions[idx(primary)], after: move_timeout };
            return self.stop(cx, e);
        }
        self.poll(cx)
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

    pub(super) fn report(&self, cx: &Cx<'_>) -> MoveReport {
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
            duration: cx.now() - self.started_at,
            actuators: self.outcomes.clone(),
            verified: not_verifiable.is_empty(),
            not_verifiable,
        }
    }
}
