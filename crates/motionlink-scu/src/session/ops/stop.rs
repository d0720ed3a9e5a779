//! Stopping a function and confirming that its actuators came to rest.

use std::time::Duration;

use motionlink_link::Timestamp;

use super::{positions, statuses, Cx, ItemRead, Next, Operation, Output, Resume, Step};
use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataIndex, Function, MotionFunction, PositionCounts, StopMode};
use crate::session::request::{PreparedRequest, Req, Schedule};
use crate::wire::Command;

enum Phase {
    Rs,
    /// Waiting for the next poll through the keepalive RC.
    Snapshot,
    /// Reading the status.
    Status(ItemRead),
    Positions(ItemRead),
    Pause,
}

/// RS of a function, then its actuators' status until none moves (at most 500 ms after a fast stop, 3 s after
/// a soft one, which follows the unit's stop ramp), then where they came to rest. The RS goes out before
/// anything else; the status is read through the keepalive RC when the session polls motions that way.
pub(crate) struct StopMachine {
    function: Function,
    mode: StopMode,
    watch: Vec<Actuator>,
    phase: Phase,
    give_up: Timestamp,
    by_snapshot: bool,
    poll_interval: Duration,
    last_status: [ActuatorStatus1; 6],
}

/// Where a stop left the actuators: status 1 and position of A1..A6.
pub(crate) type Rest = ([ActuatorStatus1; 6], [PositionCounts; 6]);

/// Why a stop is not confirmed: words for the message, and the error underneath.
pub(crate) type Unconfirmed = (String, Error);

impl StopMachine {
    pub fn new(function: Function, mode: StopMode, watch: Vec<Actuator>) -> Self {
        StopMachine {
            function,
            mode,
            watch,
            phase: Phase::Rs,
            give_up: Timestamp::ZERO,
            by_snapshot: false,
            poll_interval: Duration::from_millis(50),
            last_status: [ActuatorStatus1::EMPTY; 6],
        }
    }

    /// "fast RS of F1".
    pub fn describe(&self) -> String {
        let f = match self.function {
            Function::Motion(m) => m.to_string(),
            other => other.to_string(),
        };
        match (self.function, self.mode) {
            (Function::Motion(_), StopMode::Fast) => format!("fast RS of {f}"),
            _ => format!("RS of {f}"),
        }
    }

    fn patience(&self) -> Duration {
        match self.mode {
            StopMode::Fast => Duration::from_millis(500),
            StopMode::Soft => Duration::from_secs(3),
        }
    }

    fn look(&mut self, cx: &mut Cx<'_>) -> Step<Result<Rest, Unconfirmed>> {
        if self.by_snapshot {
            self.phase = Phase::Snapshot;
            return Step::Wait(Next::Snapshot);
        }
        let read = ItemRead::actuators(DataIndex(0x0170), self.watch.clone());
        self.read(cx, Phase::Status(read), Resume::Start)
    }

    /// A read of the status or the positions goes on with `resume`.
    fn read(&mut self, cx: &mut Cx<'_>, phase: Phase, resume: Resume) -> Step<Result<Rest, Unconfirmed>> {
        let now = cx.now();
        let (mut read, positions_read) = match phase {
            Phase::Status(r) => (r, false),
            Phase::Positions(r) => (r, true),
            _ => unreachable!("only reads are read"),
        };
        let data = match read.step(cx, resume) {
            Step::Wait(next) => {
                self.phase = if positions_read { Phase::Positions(read) } else { Phase::Status(read) };
                return Step::Wait(next);
            }
            Step::Done(r) => r,
        };
        if positions_read {
            return match data.and_then(|d| positions(&d)) {
                Ok(p) => Step::Done(Ok((self.last_status, p))),
                Err(e) => Step::Done(Err((format!("the positions could not be read: {e}"), e))),
            };
        }
        match data.and_then(|d| statuses(&d)) {
            Ok(s) => self.judge(cx, &s, None, now),
            Err(e) => Step::Done(Err((format!("the status could not be read: {e}"), e))),
        }
    }

    /// The stop's progress; its end: the status and the position of A1..A6 at rest, or why the stop is not
    /// confirmed.
    pub fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Step<Result<Rest, Unconfirmed>> {
        let now = cx.now();
        match (std::mem::replace(&mut self.phase, Phase::Pause), resume) {
            (_, Resume::Start) => {
                self.phase = Phase::Rs;
                Step::Wait(Next::Send(
                    Req::op(PreparedRequest::stop(self.function.id(), self.mode)).when(Schedule::Now),
                ))
            }
            (Phase::Rs, Resume::Reply(result)) => {
                if let Err(e) = result.and_then(|r| r.ack(Command::Stop)) {
                    tracing::error!("could not stop {}: {e}", self.function);
                    return Step::Done(Err((e.to_string(), e)));
                }
                self.give_up = now + self.patience();
                self.poll_interval = cx.config().poll_interval;
                self.by_snapshot = cx.core.poll_slot().is_some() && cx.core.poll.configured;
                self.look(cx)
            }
            (phase @ (Phase::Status(_) | Phase::Positions(_)), resume) => self.read(cx, phase, resume),
            (Phase::Snapshot, Resume::Snapshot(result)) => match result {
                Ok(s) => self.judge(cx, &s.statuses, Some(s.positions), now),
                Err(e) => Step::Done(Err((format!("the status could not be read: {e}"), e))),
            },
            (Phase::Pause, Resume::Wake) => self.look(cx),
            // A stop is not interruptible: nothing else comes while it waits.
            (_, other) => {
                let e = Error::UnexpectedReply { command: Command::Stop, detail: format!("{other:?} while stopping") };
                Step::Done(Err((e.to_string(), e)))
            }
        }
    }

    fn judge(
        &mut self,
        cx: &mut Cx<'_>,
        status: &[ActuatorStatus1; 6],
        positions: Option<[PositionCounts; 6]>,
        now: Timestamp,
    ) -> Step<Result<Rest, Unconfirmed>> {
        self.last_status = *status;
        let moving: Vec<Actuator> =
            self.watch.iter().copied().filter(|a| status[usize::from(a.number() - 1)].moving()).collect();
        if moving.is_empty() {
            return match positions {
                Some(p) => Step::Done(Ok((*status, p))),
                None => {
                    let read = ItemRead::actuators(DataIndex(0x0010), self.watch.clone());
                    self.read(cx, Phase::Positions(read), Resume::Start)
                }
            };
        }
        if now >= self.give_up {
            let e = Error::StillMoving(moving);
            return Step::Done(Err((e.to_string(), e)));
        }
        if self.by_snapshot {
            return self.look(cx);
        }
        self.phase = Phase::Pause;
        Step::Wait(Next::Sleep(self.give_up.min(now + self.poll_interval)))
    }
}

/// The error to report after `cause` ended an action and the stop that followed ended with `stopped`:
/// `cause` (a cancel with the position where its actuator came to rest) when the stop was confirmed,
/// [`Error::StopUnconfirmed`] otherwise.
pub(crate) fn after_stop(cause: Error, stopped: Result<[PositionCounts; 6], Unconfirmed>, stop: String) -> Error {
    match stopped {
        Ok(p) => match cause {
            Error::Cancelled { actuator, .. } => {
                Error::Cancelled { actuator, position_counts: p[usize::from(actuator.number() - 1)] }
            }
            other => other,
        },
        Err((detail, _)) => Error::StopUnconfirmed { cause: Box::new(cause), stop, detail },
    }
}

/// A stop of the caller's ([`super::Op::Stop`]).
pub(crate) struct StopOp {
    machine: StopMachine,
    after: Option<Box<Error>>,
}

impl StopOp {
    pub fn new(function: MotionFunction, mode: StopMode, watch: Vec<Actuator>, after: Option<Box<Error>>) -> Self {
        StopOp { machine: StopMachine::new(Function::Motion(function), mode, watch), after }
    }
}

impl Operation for StopOp {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        let stopped = match self.machine.step(cx, resume) {
            Step::Wait(next) => return next,
            Step::Done(r) => r,
        };
        let stop = self.machine.describe();
        Next::Done(match self.after.take() {
            Some(cause) => Err(after_stop(*cause, stopped.map(|(_, p)| p), stop)),
            None => match stopped {
                Ok((_, p)) => {
                    Ok(Output::Rest(self.machine.watch.iter().map(|a| (*a, p[usize::from(a.number() - 1)])).collect()))
                }
                Err((detail, e)) => Err(Error::StopUnconfirmed { cause: Box::new(e), stop, detail }),
            },
        })
    }

    fn interruptible(&self) -> bool {
        false
    }
}
