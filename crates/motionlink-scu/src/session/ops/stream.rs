//! Streamed setpoints: checks and the speed before the first target, then each update's remote positions and
//! RE.

use super::basic::{check_against_map, Stroke, StrokeFound, StrokeRead, Write};
use super::stop::StopMachine;
use super::{statuses, Cx, ItemRead, Next, Operation, Output, Resume, Step};
use crate::error::Error;
use crate::model::{
    Actuator, DataIndex, Function, MotionDirection, MotionFunction, PositionCounts, Speed, StopMode, UNUSED,
};
use crate::session::request::{PreparedRequest, Req};
use crate::value::Value;
use crate::wire::{Command, Request};

enum OpenPhase {
    Status(ItemRead),
    Stroke(usize, StrokeRead),
    Speed(Write),
}

/// The checks of a stream ([`super::Op::StreamOpen`]): the actuators (connected; exactly the ones the
/// function map says the function drives, if it knows it), their strokes, and the speed (read back).
pub(crate) struct StreamOpen {
    function: MotionFunction,
    actuators: Vec<Actuator>,
    speed: Speed,
    phase: OpenPhase,
    strokes: Vec<Stroke>,
}

impl StreamOpen {
    pub fn new(function: MotionFunction, actuators: Vec<Actuator>, speed: Speed) -> Self {
        let phase = OpenPhase::Status(ItemRead::all(DataIndex(0x0170)));
        StreamOpen { function, actuators, speed, phase, strokes: Vec::new() }
    }

    /// The status of the stream's actuators: each must be connected.
    fn status(&mut self, cx: &mut Cx<'_>, mut read: ItemRead, resume: Resume) -> Next {
        let data = match read.step(cx, resume) {
            Step::Wait(next) => {
                self.phase = OpenPhase::Status(read);
                return next;
            }
            Step::Done(r) => r,
        };
        let status = match data.and_then(|d| statuses(&d)) {
            Ok(s) => s,
            Err(e) => return Next::Done(Err(e)),
        };
        if let Some(a) = self.actuators.iter().find(|a| !status[usize::from(a.number() - 1)].available()) {
            return Next::Done(Err(Error::NotConnected(*a)));
        }
        self.next_stroke(cx)
    }

    fn next_stroke(&mut self, cx: &mut Cx<'_>) -> Next {
        let i = self.strokes.len();
        if i == self.actuators.len() {
            let raw = match self.speed.for_motion(cx.config().speed_mode) {
                Ok(r) => r,
                Err(e) => return Next::Done(Err(Error::InvalidArgument(e))),
            };
            let mut write = Write::new(self.function.remote_speed_index(), raw.to_le_bytes().to_vec(), true);
            let step = write.step(cx, Resume::Start);
            self.phase = OpenPhase::Speed(write);
            return match step {
                Step::Wait(next) => next,
                Step::Done(r) => Next::Done(r.map(|_| Output::Strokes(self.strokes.clone()))),
            };
        }
        let mut read = StrokeRead(self.actuators[i]);
        match read.step(cx, Resume::Start) {
            Step::Wait(next) => {
                self.phase = OpenPhase::Stroke(i, read);
                next
            }
            Step::Done(found) => self.stroke_found(cx, found),
        }
    }

    /// A stroke was read: a stream checks each target against it, so a stroke that cannot be known ends it.
    fn stroke_found(&mut self, cx: &mut Cx<'_>, found: Result<StrokeFound, Error>) -> Next {
        match found {
            Ok(Ok(s)) => {
                self.strokes.push(s);
                self.next_stroke(cx)
            }
            Ok(Err(why)) => Next::Done(Err(Error::NotSupported(format!(
                "a stream checks every target against its actuator's stroke, which is not known: {why}"
            )))),
            Err(e) => Next::Done(Err(e)),
        }
    }
}

impl Operation for StreamOpen {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        if cx.cancelled && !matches!(resume, Resume::Start) {
            return Next::Done(Err(Error::CancelledBeforeSending(Command::Execute)));
        }
        let placeholder = OpenPhase::Status(ItemRead::all(DataIndex(0x0170)));
        match (std::mem::replace(&mut self.phase, placeholder), resume) {
            (_, Resume::Start) => {
                if let Err(e) = self.speed.for_motion(cx.config().speed_mode) {
                    return Next::Done(Err(Error::InvalidArgument(e)));
                }
                if self.actuators.is_empty() {
                    return Next::Done(Err(Error::invalid("a stream needs at least one actuator")));
                }
                if let Err(e) = check_against_map(cx, self.function, &self.actuators) {
                    return Next::Done(Err(e));
                }
                self.status(cx, ItemRead::actuators(DataIndex(0x0170), self.actuators.clone()), Resume::Start)
            }
            (OpenPhase::Status(read), resume) => self.status(cx, read, resume),
            (OpenPhase::Stroke(i, mut read), resume) => match read.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = OpenPhase::Stroke(i, read);
                    next
                }
                Step::Done(found) => self.stroke_found(cx, found),
            },
            (OpenPhase::Speed(mut write), resume) => match write.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = OpenPhase::Speed(write);
                    next
                }
                Step::Done(r) => Next::Done(r.map(|_| Output::Strokes(self.strokes.clone()))),
            },
        }
    }
}

/// One update of a stream ([`super::Op::StreamTargets`]): the remote positions (not read back: that would
/// halve the rate; the CRC of every telegram and the unit's ACK are the check), then RE with direction 9.
pub(crate) struct StreamTargets {
    function: MotionFunction,
    targets: Vec<(Actuator, PositionCounts)>,
    next: usize,
    executing: bool,
    stopping: Option<StopMachine>,
}

impl StreamTargets {
    pub fn new(function: MotionFunction, targets: Vec<(Actuator, PositionCounts)>) -> Self {
        StreamTargets { function, targets, next: 0, executing: false, stopping: None }
    }

    fn send_next(&mut self) -> Next {
        let request = if self.next < self.targets.len() {
            let (a, t) = self.targets[self.next];
            let data = Value::RemotePosition(t.get()).to_bytes();
            PreparedRequest::new(&Request::Transfer { index: a.remote_position_index().0, data: &data })
        } else {
            self.executing = true;
            PreparedRequest::new(&Request::Execute {
                function: self.function.id(),
                params: [MotionDirection::RemotePosition.code(), UNUSED],
            })
        };
        match request {
            Ok(r) => Next::Send(Req::op(r)),
            Err(e) => Next::Done(Err(e)),
        }
    }
}

impl Operation for StreamTargets {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        if let Some(machine) = self.stopping.as_mut() {
            return match machine.step(cx, resume) {
                Step::Wait(next) => next,
                Step::Done(Ok(_)) => Next::Done(Err(Error::Interrupted(format!(
                    "cancelled; {} stopped (the unit confirmed it)",
                    self.function
                )))),
                Step::Done(Err((detail, _))) => Next::Done(Err(Error::StopUnconfirmed {
                    cause: Box::new(Error::Interrupted(format!("cancelled while {} was started", self.function))),
                    stop: machine.describe(),
                    detail,
                })),
            };
        }
        match resume {
            Resume::Start => self.send_next(),
            Resume::Reply(Err(e @ Error::CancelledBeforeSending(_))) => Next::Done(Err(e)),
            Resume::Reply(r) if self.executing => {
                let result = r.and_then(|r| r.ack(Command::Execute));
                if cx.cancelled {
                    let watch = self.targets.iter().map(|(a, _)| *a).collect();
                    let mut machine = StopMachine::new(Function::Motion(self.function), StopMode::Fast, watch);
                    let step = machine.step(cx, Resume::Start);
                    self.stopping = Some(machine);
                    if let Step::Wait(next) = step {
                        return next;
                    }
                }
                Next::Done(result.map(|_| Output::Done))
            }
            Resume::Reply(r) => match r.and_then(|r| r.ack(Command::Transfer)) {
                Ok(_) if cx.cancelled => Next::Done(Err(Error::CancelledBeforeSending(Command::Execute))),
                Ok(_) => {
                    self.next += 1;
                    self.send_next()
                }
                Err(e) => Next::Done(Err(e)),
            },
            Resume::Wake | Resume::Snapshot(_) | Resume::Reopened(_) => {
                Next::Done(Err(Error::CancelledBeforeSending(Command::Execute)))
            }
        }
    }

    fn interruptible(&self) -> bool {
        self.stopping.is_none()
    }
}
