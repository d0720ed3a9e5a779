//! A function's run: RE, then watching until the motion ends, a time limit, or a cancel; then the stop,
//! confirmed by the status.

use std::time::Duration;

use motionlink_link::Timestamp;

use super::object::DefineObject;
use super::stop::StopMachine;
use super::{statuses, Cx, ItemRead, Next, Operation, Output, Progress, Resume, RunAction, RunSpec, Step};
use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataIndex, Function, PositionCounts, StopMode, UNUSED};
use crate::session::report::{RunProgress, RunReport};
use crate::session::request::{PreparedRequest, Req};
use crate::wire::{Command, Request};

enum Phase {
    /// The session's cyclic object is defined and probed (a motion function is watched through the
    /// keepalive).
    Define(DefineObject),
    Execute,
    /// Waiting for the next look (a poll through the keepalive RC, or a pause before a read).
    Watch,
    Status(ItemRead),
    Stopping(StopMachine),
}

/// A run; see [`super::Op::Run`] and [`crate::Client::run`].
pub(crate) struct Run {
    spec: RunSpec,
    phase: Phase,
    started_at: Timestamp,
    seen_motion: bool,
    by_snapshot: bool,
}

/// A pause without end: a switching function without a time limit runs until it is cancelled.
const FOREVER: Duration = Duration::from_secs(100 * 365 * 86_400);

impl Run {
    pub fn new(spec: RunSpec, now: Timestamp) -> Self {
        Run { spec, phase: Phase::Execute, started_at: now, seen_motion: false, by_snapshot: false }
    }

    fn function(&self) -> Function {
        match self.spec.action {
            RunAction::Motion(m, _) => Function::Motion(m),
            RunAction::Switch(f) => f,
        }
    }

    fn is_motion(&self) -> bool {
        matches!(self.spec.action, RunAction::Motion(..))
    }

    fn watch(&mut self, cx: &mut Cx<'_>) -> Next {
        self.phase = Phase::Watch;
        let now = cx.now();
        let limit_at = self.spec.limit.map(|l| self.started_at + l);
        if !self.is_motion() {
            return Next::Sleep(limit_at.unwrap_or(now + FOREVER));
        }
        if self.by_snapshot {
            return Next::Snapshot;
        }
        let next = now + cx.config().poll_interval;
        Next::Sleep(limit_at.map_or(next, |l| l.min(next)))
    }

    /// One look at the actuators: progress, and whether the run is over.
    fn look(&mut self, cx: &mut Cx<'_>, status: [ActuatorStatus1; 6], positions: [PositionCounts; 6]) -> Next {
        let now = cx.now();
        let elapsed = now - self.started_at;
        let function = self.function();
        cx.progress(Progress::Run(RunProgress { function, elapsed, statuses: status, positions }));
        if cx.cancelled || self.spec.limit.is_some_and(|l| elapsed >= l) {
            return self.stop(cx);
        }
        if self.spec.limit.is_none() {
            // A motion function ends when none of the actuators moves any more.
            let moving = status.iter().any(|s| s.moving());
            self.seen_motion |= moving;
            if !moving && (self.seen_motion || elapsed >= cx.config().start_grace) {
                return self.stop(cx);
            }
        }
        self.watch(cx)
    }

    fn execute(&mut self, function: Function) -> Next {
        self.phase = Phase::Execute;
        let params = match self.spec.action {
            RunAction::Motion(_, direction) => [direction.code(), UNUSED],
            RunAction::Switch(_) => [UNUSED, UNUSED],
        };
        match PreparedRequest::new(&Request::Execute { function: function.id(), params }) {
            Ok(r) => Next::Send(Req::op(r)),
            Err(e) => Next::Done(Err(e)),
        }
    }

    /// The status read of a look went on: more to read, or the look.
    fn status_read(&mut self, cx: &mut Cx<'_>, read: ItemRead, step: Step<Result<Vec<u8>, Error>>) -> Next {
        match step {
            Step::Wait(next) => {
                self.phase = Phase::Status(read);
                next
            }
            Step::Done(r) => match r.and_then(|d| statuses(&d)) {
                Ok(s) => self.look(cx, s, [PositionCounts(0); 6]),
                Err(e) => {
                    tracing::warn!("{}: the status could not be read ({e}); stopping it", self.function());
                    self.stop(cx)
                }
            },
        }
    }

    fn stop(&mut self, cx: &mut Cx<'_>) -> Next {
        let watch = if self.is_motion() { Actuator::all().collect() } else { Vec::new() };
        let mut machine = StopMachine::new(self.function(), StopMode::Fast, watch);
        let step = machine.step(cx, Resume::Start);
        self.phase = Phase::Stopping(machine);
        match step {
            Step::Wait(next) => next,
            Step::Done(_) => unreachable!("a stop sends RS first"),
        }
    }
}

impl Operation for Run {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        let function = self.function();
        match (std::mem::replace(&mut self.phase, Phase::Watch), resume) {
            (_, Resume::Start) => {
                if let RunAction::Switch(Function::Motion(m)) = self.spec.action {
                    return Next::Done(Err(Error::invalid(format!(
                        "{m} is a motion function: run it with a direction"
                    ))));
                }
                if self.is_motion() {
                    if let Some((define, next)) = DefineObject::start(cx) {
                        self.phase = Phase::Define(define);
                        return next;
                    }
                }
                self.execute(function)
            }
            (Phase::Define(mut define), resume) => {
                if cx.cancelled {
                    return Next::Done(Err(Error::CancelledBeforeSending(Command::Execute)));
                }
                match define.step(cx, resume) {
                    Step::Wait(next) => {
                        self.phase = Phase::Define(define);
                        next
                    }
                    Step::Done(Ok(())) => self.execute(function),
                    Step::Done(Err(e)) => Next::Done(Err(e)),
                }
            }
            (Phase::Execute, Resume::Reply(Err(e @ Error::CancelledBeforeSending(_)))) => Next::Done(Err(e)),
            (Phase::Execute, Resume::Reply(r)) => match r.and_then(|r| r.ack(Command::Execute)) {
                // The unit refused: nothing started.
                Err(e @ Error::Refused { .. }) => Next::Done(Err(e)),
                // Without a clean answer the RE may have started the function: it is stopped.
                Err(e) => {
                    tracing::warn!("{function}: {e}; stopping it");
                    self.stop(cx)
                }
                Ok(_) => {
                    self.by_snapshot = cx.core.poll_slot().is_some() && cx.core.poll.configured;
                    let now = cx.now();
                    cx.progress(Progress::Run(RunProgress {
                        function,
                        elapsed: now - self.started_at,
                        statuses: [ActuatorStatus1::EMPTY; 6],
                        positions: [PositionCounts(0); 6],
                    }));
                    if cx.cancelled {
                        return self.stop(cx);
                    }
                    self.watch(cx)
                }
            },
            (Phase::Watch, Resume::Wake) => {
                if cx.cancelled || !self.is_motion() {
                    return self.stop(cx);
                }
                if self.spec.limit.is_some_and(|l| cx.now() - self.started_at >= l) {
                    return self.stop(cx);
                }
                let mut read = ItemRead::all(DataIndex(0x0170));
                let step = read.step(cx, Resume::Start);
                self.status_read(cx, read, step)
            }
            (Phase::Watch, Resume::Snapshot(Ok(s))) => self.look(cx, s.statuses, s.positions),
            (Phase::Status(mut read), resume) => {
                if cx.cancelled {
                    return self.stop(cx);
                }
                let step = read.step(cx, resume);
                self.status_read(cx, read, step)
            }
            (Phase::Watch, Resume::Snapshot(Err(e))) => {
                tracing::warn!("{function}: {e}; stopping it");
                self.stop(cx)
            }
            (Phase::Stopping(mut machine), resume) => match machine.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Stopping(machine);
                    next
                }
                Step::Done(stopped) => {
                    let stop = machine.describe();
                    Next::Done(match stopped {
                        Ok((status, positions)) => {
                            let rest: Vec<(Actuator, PositionCounts)> = Actuator::all()
                                .filter(|a| status[usize::from(a.number() - 1)].available())
                                .map(|a| (a, positions[usize::from(a.number() - 1)]))
                                .collect();
                            if cx.cancelled {
                                Err(Error::RunCancelled { function, rest })
                            } else {
                                let duration = cx.now() - self.started_at;
                                Ok(Output::Run(RunReport { function, duration, rest }))
                            }
                        }
                        Err((detail, _)) if cx.cancelled => Err(Error::StopUnconfirmed {
                            cause: Box::new(Error::Interrupted(format!("cancelled while {function} ran"))),
                            stop,
                            detail,
                        }),
                        Err((_, e)) => Err(e),
                    })
                }
            },
            (phase, other) => {
                self.phase = phase;
                tracing::warn!("{function}: {other:?} unexpected; stopping it");
                self.stop(cx)
            }
        }
    }

    fn interruptible(&self) -> bool {
        !matches!(self.phase, Phase::Stopping(_))
    }
}
