//! A verified move of the actuators of one function: checks, writes read back, one RE, polling until the
//! unit reports the end of the motion, the in-position check, and RS; any failure or a cancel stops the
//! function at once and confirms the stop. Where the unit in use does not do what a check needs beyond the
//! manual's words (UserPositionData, reading remote data back), the move runs in the manual's plain form and
//! its report says what could not be verified.

use motionlink_link::Timestamp;

use super::basic::{check_against_map, check_stroke, StrokeFound, StrokeRead, Write};
use super::object::DefineObject;
use super::stop::{after_stop, StopMachine};
use super::{positions, statuses, Cx, ItemRead, MoveSpec, MoveTargets, Next, Operation, Output, Resume, Step};
use crate::error::Error;
use crate::model::ActuatorStatus1;
use crate::model::{Actuator, DataIndex, Function, MotionDirection, PositionCounts, StopMode, UNUSED};
use crate::session::report::{ActuatorOutcome, Snapshot};
use crate::session::request::{PreparedRequest, Req};
use crate::value::Value;
use crate::wire::{Command, Request};

mod poll;

enum Phase {
    /// The status of every actuator: which are connected.
    Status(ItemRead),
    /// The stroke of `order[i]`.
    Stroke(usize, StrokeRead),
    /// Where the actuators start.
    Start(ItemRead),
    /// The session's cyclic object is defined and probed.
    Define(DefineObject),
    /// The remote position of `targets[i]`.
    Target(usize, Write),
    Speed(Write),
    Execute,
    /// Waiting for the next look at the actuators.
    Poll,
    /// Reading the status (reads polling); then the positions.
    PollStatus(ItemRead),
    PollPositions([ActuatorStatus1; 6], ItemRead),
    /// Reading Error_Code 1 for the report of a move that ended away from its target.
    ErrorCode(Error),
    /// The RS that ends a move that reached its target.
    FinalStop,
    /// Stopping after `cause`.
    Stopping(StopMachine, Option<Error>),
}

/// A move; see [`super::Op::Move`] and [`crate::Client::move_function`].
pub(crate) struct Move {
    spec: MoveSpec,
    phase: Phase,
    started_at: Timestamp,
    speed: u16,
    drives_unknown: bool,
    targets: Vec<(Actuator, PositionCounts)>,
    /// The targets, the primary actuator first (its problem is the one reported).
    order: Vec<(Actuator, PositionCounts)>,
    status: [ActuatorStatus1; 6],
    start: [PositionCounts; 6],
    seen_motion: [bool; 6],
    last_position: [PositionCounts; 6],
    last_progress_at: [Timestamp; 6],
    next_poll: Timestamp,
    by_snapshot: bool,
    outcomes: Vec<ActuatorOutcome>,
    /// What the move could not verify on this unit.
    not_verifiable: Vec<String>,
    /// Written values the unit did not read back.
    not_read_back: Vec<DataIndex>,
}

fn idx(a: Actuator) -> usize {
    usize::from(a.number() - 1)
}

impl Move {
    pub fn new(spec: MoveSpec, now: Timestamp) -> Self {
        Move {
            spec,
            phase: Phase::Poll,
            started_at: now,
            speed: 0,
            drives_unknown: false,
            targets: Vec::new(),
            order: Vec::new(),
            status: [ActuatorStatus1::EMPTY; 6],
            start: [PositionCounts(0); 6],
            seen_motion: [false; 6],
            last_position: [PositionCounts(0); 6],
            last_progress_at: [now; 6],
            next_poll: now,
            by_snapshot: false,
            outcomes: Vec::new(),
            not_verifiable: Vec::new(),
            not_read_back: Vec::new(),
        }
    }

    fn actuators(&self) -> impl Iterator<Item = Actuator> + '_ {
        self.targets.iter().map(|(a, _)| *a)
    }

    /// Checks what can be checked before anything is sent.
    fn check(&mut self, cx: &Cx<'_>) -> Result<(), Error> {
        let mode = cx.config().speed_mode;
        self.speed = self.spec.speed.for_motion(mode).map_err(Error::InvalidArgument)?;
        match &self.spec.targets {
            MoveTargets::Given(targets) => {
                if targets.is_empty() {
                    return Err(Error::invalid("a move needs at least one actuator and its target"));
                }
                let actuators: Vec<Actuator> = targets.iter().map(|(a, _)| *a).collect();
                check_against_map(cx, self.spec.function, &actuators)?;
                self.targets = targets.clone();
                if !actuators.contains(&self.spec.primary) {
                    self.spec.primary = actuators[0];
                }
            }
            MoveTargets::EveryConnected(_) => self.drives_unknown = true,
        }
        Ok(())
    }

    /// Everything that can refuse the move is checked before the unit is told anything: the actuators are
    /// connected, and each target lies within its stroke.
    fn checked_status(&mut self, data: Vec<u8>) -> Result<(), Error> {
        self.status = statuses(&data)?;
        let available = |a: Actuator| self.status[idx(a)].available();
        if let MoveTargets::EveryConnected(t) = self.spec.targets {
            if !available(self.spec.primary) {
                return Err(Error::NotConnected(self.spec.primary));
            }
            self.targets = Actuator::all().filter(|a| available(*a)).map(|a| (a, t)).collect();
        }
        self.order = self.targets.clone();
        let primary = self.spec.primary;
        self.order.sort_by_key(|(a, _)| *a != primary);
        if let Some((a, _)) = self.order.iter().find(|(a, _)| !available(*a)) {
            return Err(Error::NotConnected(*a));
        }
        Ok(())
    }

    /// Runs `read` (just made) and goes on with what it wants.
    fn read(&mut self, cx: &mut Cx<'_>, mut read: ItemRead, phase: fn(ItemRead) -> Phase) -> Next {
        match read.step(cx, Resume::Start) {
            Step::Wait(next) => {
                self.phase = phase(read);
                next
            }
            Step::Done(r) => Next::Done(r.map(|d| Output::Data(Some(d)))),
        }
    }

    fn next_stroke(&mut self, cx: &mut Cx<'_>, i: usize) -> Next {
        if i >= self.order.len() {
            let read = ItemRead::actuators(DataIndex(0x0010), self.actuators().collect::<Vec<_>>());
            return self.read(cx, read, Phase::Start);
        }
        let mut read = StrokeRead(self.order[i].0);
        let step = read.step(cx, Resume::Start);
        self.phase = Phase::Stroke(i, read);
        match step {
            Step::Wait(next) => next,
            Step::Done(stroke) => self.stroke_read(cx, i, stroke),
        }
    }

    fn stroke_read(&mut self, cx: &mut Cx<'_>, i: usize, stroke: Result<StrokeFound, Error>) -> Next {
        let (a, target) = self.order[i];
        let checked = match stroke {
            Ok(Ok(s)) => check_stroke(a, target, &s),
            Ok(Err(why)) => {
                self.not_verifiable.push(why);
                Ok(())
            }
            Err(e) => Err(e),
        };
        match checked {
            Err(e @ Error::OutsideStroke { .. }) if self.drives_unknown && a != self.spec.primary => {
                Next::Done(Err(Error::InvalidArgument(format!(
                    "{e}. The function map does not say which actuators {} drives, so every connected actuator \
                     gets the target; say which ones it drives (ClientConfig::function_map, --functions)",
                    self.spec.function
                ))))
            }
            Err(e) => Next::Done(Err(e)),
            Ok(()) => self.next_stroke(cx, i + 1),
        }
    }

    /// The session's cyclic object is defined and probed once per session (again after remote mode was
    /// opened again).
    fn define(&mut self, cx: &mut Cx<'_>) -> Next {
        match DefineObject::start(cx) {
            Some((define, next)) => {
                self.phase = Phase::Define(define);
                next
            }
            None => self.next_target(cx, 0),
        }
    }

    fn next_target(&mut self, cx: &mut Cx<'_>, i: usize) -> Next {
        let mut write = if i < self.targets.len() {
            let (a, t) = self.targets[i];
            Write::new(a.remote_position_index(), Value::RemotePosition(t.get()).to_bytes(), true)
        } else {
            Write::new(self.spec.function.remote_speed_index(), self.speed.to_le_bytes().to_vec(), true)
        };
        let step = write.step(cx, Resume::Start);
        self.phase = if i < self.targets.len() { Phase::Target(i, write) } else { Phase::Speed(write) };
        match step {
            Step::Wait(next) => next,
            Step::Done(Err(e)) => Next::Done(Err(e)),
            Step::Done(Ok(_)) => unreachable!("a write waits for its reply"),
        }
    }

    /// A write of the move ended: the next one, or the RE.
    fn written(&mut self, cx: &mut Cx<'_>, i: Option<usize>, done: Result<Option<String>, Error>) -> Next {
        match done {
            Ok(why) => {
                if why.is_some() {
                    self.not_read_back.push(match i {
                        Some(i) => self.targets[i].0.remote_position_index(),
                        None => self.spec.function.remote_speed_index(),
                    });
                }
                match i {
                    Some(i) => self.next_target(cx, i + 1),
                    None => self.execute(),
                }
            }
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn execute(&mut self) -> Next {
        self.phase = Phase::Execute;
        let re = Request::Execute {
            function: self.spec.function.id(),
            params: [MotionDirection::RemotePosition.code(), UNUSED],
        };
        match PreparedRequest::new(&re) {
            Ok(r) => Next::Send(Req::op(r)),
            Err(e) => Next::Done(Err(e)),
        }
    }

    /// Stops the function at once after `cause`.
    fn stop(&mut self, cx: &mut Cx<'_>, cause: Error) -> Next {
        let watch = self.actuators().collect();
        let mut machine = StopMachine::new(Function::Motion(self.spec.function), StopMode::Fast, watch);
        let step = machine.step(cx, Resume::Start);
        self.phase = Phase::Stopping(machine, Some(cause));
        match step {
            Step::Wait(next) => next,
            Step::Done(_) => unreachable!("a stop sends RS first"),
        }
    }

    /// An RG of a poll ended: the positions next, or the judgement.
    fn polled(
        &mut self,
        cx: &mut Cx<'_>,
        status: Option<[ActuatorStatus1; 6]>,
        step: Step<Result<Vec<u8>, Error>>,
    ) -> Next {
        let data = match step {
            Step::Wait(next) => return next,
            Step::Done(Ok(d)) => d,
            Step::Done(Err(e)) => return self.stop(cx, e),
        };
        match status {
            None => match statuses(&data) {
                Ok(s) => {
                    let mut read = ItemRead::actuators(DataIndex(0x0010), self.actuators().collect::<Vec<_>>());
                    let step = read.step(cx, Resume::Start);
                    self.phase = Phase::PollPositions(s, read);
                    self.polled(cx, Some(s), step)
                }
                Err(e) => self.stop(cx, e),
            },
            Some(s) => match positions(&data) {
                Ok(p) => self.judge(cx, s, p),
                Err(e) => self.stop(cx, e),
            },
        }
    }
}

impl Operation for Move {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        // Before RE nothing moves: a cancel ends the move where it is.
        let before_re = matches!(
            self.phase,
            Phase::Status(_)
                | Phase::Stroke(..)
                | Phase::Start(_)
                | Phase::Define(_)
                | Phase::Target(..)
                | Phase::Speed(_)
        );
        if cx.cancelled && before_re && !matches!(resume, Resume::Start) {
            return Next::Done(Err(Error::CancelledBeforeSending(Command::Execute)));
        }
        // While polling, a cancel stops the function at once (where it came to rest is read after the stop).
        let polling = matches!(self.phase, Phase::Poll | Phase::PollStatus(_) | Phase::PollPositions(..));
        if cx.cancelled && polling && !matches!(resume, Resume::Snapshot(Ok(_))) {
            let p = self.last_position[idx(self.spec.primary)];
            return self.stop(cx, Error::Cancelled { actuator: self.spec.primary, position_counts: p });
        }
        match (std::mem::replace(&mut self.phase, Phase::Poll), resume) {
            (_, Resume::Start) => {
                if let Err(e) = self.check(cx) {
                    return Next::Done(Err(e));
                }
                self.read(cx, ItemRead::all(DataIndex(0x0170)), Phase::Status)
            }
            (Phase::Status(mut read), resume) => match read.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Status(read);
                    next
                }
                Step::Done(r) => match r.and_then(|d| self.checked_status(d)) {
                    Ok(()) => self.next_stroke(cx, 0),
                    Err(e) => Next::Done(Err(e)),
                },
            },
            (Phase::Stroke(i, mut read), resume) => match read.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Stroke(i, read);
                    next
                }
                Step::Done(stroke) => self.stroke_read(cx, i, stroke),
            },
            (Phase::Start(mut read), resume) => match read.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Start(read);
                    next
                }
                Step::Done(r) => match r.and_then(|d| positions(&d)) {
                    Ok(p) => {
                        self.start = p;
                        self.last_position = p;
                        self.define(cx)
                    }
                    Err(e) => Next::Done(Err(e)),
                },
            },
            (Phase::Define(mut define), resume) => match define.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Define(define);
                    next
                }
                Step::Done(Ok(())) => self.next_target(cx, 0),
                Step::Done(Err(e)) => Next::Done(Err(e)),
            },
            (Phase::Target(i, mut write), resume) => match write.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Target(i, write);
                    next
                }
                Step::Done(done) => self.written(cx, Some(i), done),
            },
            (Phase::Speed(mut write), resume) => match write.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Speed(write);
                    next
                }
                Step::Done(done) => self.written(cx, None, done),
            },
            (Phase::Execute, Resume::Reply(Err(Error::CancelledBeforeSending(c)))) => {
                Next::Done(Err(Error::CancelledBeforeSending(c)))
            }
            (Phase::Execute, Resume::Reply(r)) => {
                // An RE that failed (refused, a lost or corrupt reply) may still have started the motion: it
                // gets its RS like any other failure.
                if let Err(e) = r.and_then(|r| r.ack(Command::Execute)) {
                    return self.stop(cx, e);
                }
                if cx.cancelled {
                    let p = self.start[idx(self.spec.primary)];
                    return self.stop(cx, Error::Cancelled { actuator: self.spec.primary, position_counts: p });
                }
                self.by_snapshot = cx.core.poll_slot().is_some() && cx.core.poll.configured;
                self.next_poll = self.started_at;
                self.poll(cx)
            }
            (Phase::Poll, Resume::Wake) => {
                let mut read = ItemRead::actuators(DataIndex(0x0170), self.actuators().collect::<Vec<_>>());
                let step = read.step(cx, Resume::Start);
                self.phase = Phase::PollStatus(read);
                self.polled(cx, None, step)
            }
            (Phase::Poll, Resume::Snapshot(Ok(Snapshot { statuses, positions, .. }))) => {
                self.judge(cx, statuses, positions)
            }
            (Phase::Poll, Resume::Snapshot(Err(e))) => self.stop(cx, e),
            (Phase::PollStatus(mut read), resume) => {
                let step = read.step(cx, resume);
                self.phase = Phase::PollStatus(read);
                self.polled(cx, None, step)
            }
            (Phase::PollPositions(s, mut read), resume) => {
                let step = read.step(cx, resume);
                self.phase = Phase::PollPositions(s, read);
                self.polled(cx, Some(s), step)
            }
            (Phase::ErrorCode(mut e), Resume::Reply(r)) => {
                let code = r.and_then(|r| r.data(Command::Get)).ok().and_then(|d| super::error_code(&d).ok());
                if let (Error::MotionEnded { error_code, .. }, Some(c)) = (&mut e, code) {
                    *error_code = c;
                }
                self.stop(cx, e)
            }
            (Phase::FinalStop, Resume::Reply(r)) => match r.and_then(|r| r.ack(Command::Stop)) {
                Ok(_) => Next::Done(Ok(Output::Move(self.report(cx)))),
                Err(e) => Next::Done(Err(e)),
            },
            (Phase::Stopping(mut machine, mut cause), resume) => match machine.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Stopping(machine, cause);
                    next
                }
                Step::Done(stopped) => {
                    let cause = cause.take().expect("a stop has its cause");
                    Next::Done(Err(after_stop(cause, stopped.map(|(_, p)| p), machine.describe())))
                }
            },
            (phase, resume) => {
                let detail = format!("{resume:?} while {}", phase_name(&phase));
                self.phase = phase;
                self.stop(cx, Error::UnexpectedReply { command: Command::Execute, detail })
            }
        }
    }

    fn interruptible(&self) -> bool {
        !matches!(self.phase, Phase::ErrorCode(_) | Phase::FinalStop | Phase::Stopping(..))
    }
}

fn phase_name(p: &Phase) -> &'static str {
    match p {
        Phase::Status(_) => "reading the status",
        Phase::Stroke(..) => "reading a stroke",
        Phase::Start(_) => "reading the positions",
        Phase::Define(_) => "defining the session's cyclic object",
        Phase::Target(..) => "writing a target",
        Phase::Speed(_) => "writing the speed",
        Phase::Execute => "starting the function",
        Phase::Poll | Phase::PollStatus(_) | Phase::PollPositions(..) => "polling",
        Phase::ErrorCode(_) => "reading the error code",
        Phase::FinalStop => "ending the function",
        Phase::Stopping(..) => "stopping",
    }
}
