//! Stopping a function and confirming that its actuators came to rest.

use std::time::Duration;

use motionlink_link::error::{Classify, ErrorClass};
use motionlink_link::Timestamp;

use super::{positions, statuses, Cx, ItemRead, Next, Operation, Output, Resume, Step};
use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataIndex, Function, MotionFunction, PositionCounts, StopMode};
use crate::session::report::{ActuatorRest, RefusedStop, StopReport};
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

/// RS of a function (or of several, one after the other), then its actuators' status until none moves (at
/// most 500 ms after a fast stop, 3 s after a soft one, which follows the unit's stop ramp), then where they
/// came to rest. The RS goes out before anything else; the status is read through the keepalive RC when the
/// session polls motions that way. Of several functions, one whose RS the unit refuses is noted and the next
/// one is stopped all the same: the status read afterwards is what confirms the stop.
pub(crate) struct StopMachine {
    functions: Vec<Function>,
    /// How many RS have been answered.
    answered: usize,
    /// The RS the unit refused (only when stopping several functions), with the unit's answer.
    refused: Vec<(Function, String)>,
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
        Self::several(vec![function], mode, watch)
    }

    /// RS of each of `functions` in turn (none: only the status is read), then the status of `watch`.
    pub fn several(functions: Vec<Function>, mode: StopMode, watch: Vec<Actuator>) -> Self {
        StopMachine {
            functions,
            answered: 0,
            refused: Vec::new(),
            mode,
            watch,
            phase: Phase::Rs,
            give_up: Timestamp::ZERO,
            by_snapshot: false,
            poll_interval: Duration::from_millis(50),
            last_status: [ActuatorStatus1::EMPTY; 6],
        }
    }

    /// "fast RS of F1", "soft RS of F1, F2".
    pub fn describe(&self) -> String {
        let names: Vec<String> = self
            .functions
            .iter()
            .map(|f| match f {
                Function::Motion(m) => m.to_string(),
                other => other.to_string(),
            })
            .collect();
        let motion = self.functions.iter().all(|f| matches!(f, Function::Motion(_)));
        match (motion, self.mode) {
            (true, StopMode::Fast) => format!("fast RS of {}", names.join(", ")),
            (true, StopMode::Soft) if self.functions.len() > 1 => format!("soft RS of {}", names.join(", ")),
            _ => format!("RS of {}", names.join(", ")),
        }
    }

    /// The RS the unit refused, with its answer (only when stopping several functions; one function's
    /// refused RS ends the stop as not confirmed).
    pub fn refused(&self) -> &[(Function, String)] {
        &self.refused
    }

    /// The RS of the next function not yet stopped.
    fn next_rs(&self) -> Next {
        let f = self.functions[self.answered];
        Next::Send(Req::op(PreparedRequest::stop(f.id(), self.mode)).when(Schedule::Now))
    }

    /// The status, once every RS was answered (or the next RS).
    fn after_rs(&mut self, cx: &mut Cx<'_>, now: Timestamp) -> Step<Result<Rest, Unconfirmed>> {
        if self.answered < self.functions.len() {
            self.phase = Phase::Rs;
            return Step::Wait(self.next_rs());
        }
        self.give_up = now + self.patience();
        self.poll_interval = cx.config().poll_interval;
        self.by_snapshot = cx.core.poll_slot().is_some() && cx.core.poll.configured;
        self.look(cx)
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
            (_, Resume::Start) => self.after_rs(cx, now),
            (Phase::Rs, Resume::Reply(result)) => {
                let function = self.functions[self.answered];
                self.answered += 1;
                if let Err(e) = result.and_then(|r| r.ack(Command::Stop)) {
                    let refused = matches!(e.class(), ErrorClass::Refused | ErrorClass::Device);
                    if !(refused && self.functions.len() > 1) {
                        tracing::info!("could not stop {function}: {e}");
                        return Step::Done(Err((e.to_string(), e)));
                    }
                    // The unit answered: the line works; the other functions are stopped all the same.
                    tracing::warn!("the unit refused the RS of {function}: {e}");
                    self.refused.push((function, e.to_string()));
                }
                self.after_rs(cx, now)
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

/// A stop of several motion functions, confirmed by the status of every actuator ([`super::Op::StopMotions`]).
pub(crate) struct StopMotionsOp {
    machine: StopMachine,
    functions: Vec<MotionFunction>,
    mode: StopMode,
}

impl StopMotionsOp {
    pub fn new(functions: Vec<MotionFunction>, mode: StopMode) -> Self {
        let machine = StopMachine::several(
            functions.iter().map(|f| Function::Motion(*f)).collect(),
            mode,
            Actuator::all().collect(),
        );
        StopMotionsOp { machine, functions, mode }
    }
}

impl Operation for StopMotionsOp {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        let stopped = match self.machine.step(cx, resume) {
            Step::Wait(next) => return next,
            Step::Done(r) => r,
        };
        Next::Done(match stopped {
            Ok((status, positions)) => {
                let refused = self
                    .machine
                    .refused()
                    .iter()
                    .filter_map(|(f, reason)| match f {
                        Function::Motion(m) => Some(RefusedStop { function: *m, reason: reason.clone() }),
                        _ => None,
                    })
                    .collect();
                let at_rest = Actuator::all()
                    .filter(|a| status[usize::from(a.number() - 1)].available())
                    .map(|a| ActuatorRest { actuator: a, position_counts: positions[usize::from(a.number() - 1)] })
                    .collect();
                Ok(Output::Stopped(StopReport { functions: self.functions.clone(), mode: self.mode, refused, at_rest }))
            }
            Err((detail, e)) => {
                Err(Error::StopUnconfirmed { cause: Box::new(e), stop: self.machine.describe(), detail })
            }
        })
    }

    fn interruptible(&self) -> bool {
        false
    }
}
