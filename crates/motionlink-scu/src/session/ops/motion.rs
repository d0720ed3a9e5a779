//! A verified move of the actuators of one function: checks, writes read back, one RE, polling until the
//! unit reports the end of the motion, the in-position check, and RS; any failure or a cancel stops the
//! function at once and confirms the stop.

use motionlink_link::Timestamp;

use super::basic::{check_against_map, check_stroke, StrokeRead, Write};
use super::stop::{after_stop, StopMachine};
use super::{get, positions, statuses, Cx, MoveSpec, MoveTargets, Next, Operation, Output, Progress, Resume, Step};
use crate::error::Error;
use crate::model::ActuatorStatus1;
use crate::model::{
    Actuator, CyclicObject, DataIndex, ErrorCode, Function, MotionDirection, PositionCounts, StopMode, UNUSED,
};
use crate::session::report::{ActuatorOutcome, MoveProgress, MoveReport, Snapshot};
use crate::session::request::{PreparedRequest, Req, Schedule};
use crate::session::POLL_READ;
use crate::value::Value;
use crate::wire::{Command, Request};

enum Phase {
    /// The status of every actuator: which are connected.
    Status,
    /// The stroke of `order[i]`.
    Stroke(usize, StrokeRead),
    /// Where every actuator starts.
    Start,
    /// The session's poll object is defined.
    DefinePoll(Write),
    /// The remote position of `targets[i]`.
    Target(usize, Write),
    Speed(Write),
    Execute,
    /// Waiting for the next look at the actuators.
    Poll,
    /// Reading the status (reads polling); then the positions.
    PollStatus,
    PollPositions([ActuatorStatus1; 6]),
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
}

fn idx(a: Actuator) -> usize {
    usize::from(a.number() - 1)
}

impl Move {
    pub fn new(spec: MoveSpec, now: Timestamp) -> Self {
        Move {
            spec,
            phase: Phase::Status,
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
        }
    }

    fn primary_target(&self) -> PositionCounts {
        self.targets.iter().find(|(a, _)| *a == self.spec.primary).map_or(PositionCounts(0), |(_, t)| *t)
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

    fn next_stroke(&mut self, cx: &mut Cx<'_>, i: usize) -> Next {
        if i >= self.order.len() {
            self.phase = Phase::Start;
            return get(DataIndex(0x0010));
        }
        let mut read = StrokeRead(self.order[i].0);
        let step = read.step(cx, Resume::Start);
        self.phase = Phase::Stroke(i, read);
        match step {
            Step::Wait(next) => next,
            Step::Done(stroke) => self.stroke_read(cx, i, stroke),
        }
    }

    fn stroke_read(&mut self, cx: &mut Cx<'_>, i: usize, stroke: Result<super::basic::Stroke, Error>) -> Next {
        let (a, target) = self.order[i];
        let checked = stroke.and_then(|s| check_stroke(a, target, &s));
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

    /// The poll object is defined once per session (again after remote mode was opened again).
    fn define_poll(&mut self, cx: &mut Cx<'_>) -> Next {
        if let (Some(slot), false) = (cx.core.poll_slot(), cx.core.poll.configured) {
            let object = CyclicObject::new(&[], &POLL_READ).expect("two read indices fit");
            let mut write = Write::new(DataIndex(0x3000 + u16::from(slot)), object.to_bytes().to_vec(), true);
            let step = write.step(Resume::Start);
            self.phase = Phase::DefinePoll(write);
            if let Step::Wait(next) = step {
                return next;
            }
        }
        self.next_target(0)
    }

    fn next_target(&mut self, i: usize) -> Next {
        let write = if i < self.targets.len() {
            let (a, t) = self.targets[i];
            Write::new(a.remote_position_index(), Value::RemotePosition(t.get()).to_bytes(), true)
        } else {
            Write::new(self.spec.function.remote_speed_index(), self.speed.to_le_bytes().to_vec(), true)
        };
        let mut write = write;
        let step = write.step(Resume::Start);
        self.phase = if i < self.targets.len() { Phase::Target(i, write) } else { Phase::Speed(write) };
        match step {
            Step::Wait(next) => next,
            Step::Done(Err(e)) => Next::Done(Err(e)),
            Step::Done(Ok(())) => unreachable!("a write waits for its reply"),
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
        let watch = self.targets.iter().map(|(a, _)| *a).collect();
        let mut machine = StopMachine::new(Function::Motion(self.spec.function), StopMode::Fast, watch);
        let step = machine.step(cx, Resume::Start);
        self.phase = Phase::Stopping(machine, Some(cause));
        match step {
            Step::Wait(next) => next,
            Step::Done(_) => unreachable!("a stop sends RS first"),
        }
    }

    fn poll(&mut self, cx: &mut Cx<'_>) -> Next {
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

    fn read_status(&mut self) -> Next {
        self.phase = Phase::PollStatus;
        match self.single() {
            Some(a) => get(a.status1_index()),
            None => get(DataIndex(0x0170)),
        }
    }

    fn single(&self) -> Option<Actuator> {
        match self.targets[..] {
            [(a, _)] => Some(a),
            _ => None,
        }
    }

    /// One look at the actuators: progress, the end of the motion and its judgement, a stall, the time limit.
    fn judge(&mut self, cx: &mut Cx<'_>, status: [ActuatorStatus1; 6], positions: [PositionCounts; 6]) -> Next {
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
                    return get(DataIndex(0x00D0));
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

    fn report(&self, cx: &Cx<'_>) -> MoveReport {
        let primary = self.spec.primary;
        let position_counts = self
            .outcomes
            .iter()
            .find(|o| o.actuator == primary)
            .map_or(self.start[idx(primary)], |o| o.position_counts);
        MoveReport {
            actuator: primary,
            function: self.spec.function,
            position_counts,
            duration: cx.now() - self.started_at,
            actuators: self.outcomes.clone(),
        }
    }
}

impl Operation for Move {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        // Before RE nothing moves: a cancel ends the move where it is.
        let before_re = matches!(
            self.phase,
            Phase::Status
                | Phase::Stroke(..)
                | Phase::Start
                | Phase::DefinePoll(_)
                | Phase::Target(..)
                | Phase::Speed(_)
        );
        if cx.cancelled && before_re && !matches!(resume, Resume::Start) {
            return Next::Done(Err(Error::CancelledBeforeSending(Command::Execute)));
        }
        // While polling, a cancel stops the function at once (where it came to rest is read after the stop).
        let polling = matches!(self.phase, Phase::Poll | Phase::PollStatus | Phase::PollPositions(_));
        if cx.cancelled && polling && !matches!(resume, Resume::Snapshot(Ok(_))) {
            let p = self.last_position[idx(self.spec.primary)];
            return self.stop(cx, Error::Cancelled { actuator: self.spec.primary, position_counts: p });
        }
        match (std::mem::replace(&mut self.phase, Phase::Poll), resume) {
            (_, Resume::Start) => {
                self.phase = Phase::Status;
                if let Err(e) = self.check(cx) {
                    return Next::Done(Err(e));
                }
                get(DataIndex(0x0170))
            }
            (Phase::Status, Resume::Reply(r)) => {
                if let Err(e) = r.and_then(|r| r.data(Command::Get)).and_then(|d| self.checked_status(d)) {
                    return Next::Done(Err(e));
                }
                self.next_stroke(cx, 0)
            }
            (Phase::Stroke(i, mut read), resume) => match read.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Stroke(i, read);
                    next
                }
                Step::Done(stroke) => self.stroke_read(cx, i, stroke),
            },
            (Phase::Start, Resume::Reply(r)) => {
                match r.and_then(|r| r.data(Command::Get)).and_then(|d| positions(&d)) {
                    Ok(p) => {
                        self.start = p;
                        self.last_position = p;
                        self.define_poll(cx)
                    }
                    Err(e) => Next::Done(Err(e)),
                }
            }
            (Phase::DefinePoll(mut write), resume) => match write.step(resume) {
                Step::Wait(next) => {
                    self.phase = Phase::DefinePoll(write);
                    next
                }
                Step::Done(Ok(())) => {
                    cx.core.poll.configured = true;
                    self.next_target(0)
                }
                Step::Done(Err(Error::Refused { status, .. })) => {
                    tracing::warn!("the unit refused the poll object ({status}); moves are polled with reads");
                    cx.core.poll.refused = true;
                    self.next_target(0)
                }
                Step::Done(Err(e)) => Next::Done(Err(e)),
            },
            (Phase::Target(i, mut write), resume) => match write.step(resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Target(i, write);
                    next
                }
                Step::Done(Ok(())) => self.next_target(i + 1),
                Step::Done(Err(e)) => Next::Done(Err(e)),
            },
            (Phase::Speed(mut write), resume) => match write.step(resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Speed(write);
                    next
                }
                Step::Done(Ok(())) => self.execute(),
                Step::Done(Err(e)) => Next::Done(Err(e)),
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
            (Phase::Poll, Resume::Wake) => self.read_status(),
            (Phase::Poll, Resume::Snapshot(Ok(Snapshot { statuses, positions, .. }))) => {
                self.judge(cx, statuses, positions)
            }
            (Phase::Poll, Resume::Snapshot(Err(e))) => self.stop(cx, e),
            (Phase::PollStatus, Resume::Reply(r)) => {
                let status = r.and_then(|r| r.data(Command::Get)).and_then(|d| match self.single() {
                    Some(a) => match d[..] {
                        [bits] => {
                            let mut s = [ActuatorStatus1::EMPTY; 6];
                            s[idx(a)] = ActuatorStatus1(bits);
                            Ok(s)
                        }
                        _ => Err(Error::UnexpectedReply { command: Command::Get, detail: "status is one byte".into() }),
                    },
                    None => statuses(&d),
                });
                match status {
                    Ok(s) => {
                        self.phase = Phase::PollPositions(s);
                        match self.single() {
                            Some(a) => get(a.position_index()),
                            None => get(DataIndex(0x0010)),
                        }
                    }
                    Err(e) => self.stop(cx, e),
                }
            }
            (Phase::PollPositions(status), Resume::Reply(r)) => {
                let read = r.and_then(|r| r.data(Command::Get)).and_then(|d| match self.single() {
                    Some(a) => match d[..] {
                        [b0, b1, b2, b3] => {
                            let mut p = self.start;
                            p[idx(a)] = PositionCounts(i32::from_le_bytes([b0, b1, b2, b3]));
                            Ok(p)
                        }
                        _ => Err(Error::UnexpectedReply {
                            command: Command::Get,
                            detail: "a position is 4 bytes".into(),
                        }),
                    },
                    None => positions(&d),
                });
                match read {
                    Ok(p) => self.judge(cx, status, p),
                    Err(e) => self.stop(cx, e),
                }
            }
            (Phase::ErrorCode(mut e), Resume::Reply(r)) => {
                let code = r.and_then(|r| r.data(Command::Get)).ok().and_then(|d| d.get(..4).map(<[u8]>::to_vec));
                if let (Error::MotionEnded { error_code, .. }, Some(b)) = (&mut e, code) {
                    *error_code = ErrorCode(u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
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
        Phase::Status => "reading the status",
        Phase::Stroke(..) => "reading a stroke",
        Phase::Start => "reading the positions",
        Phase::DefinePoll(_) => "defining the poll object",
        Phase::Target(..) => "writing a target",
        Phase::Speed(_) => "writing the speed",
        Phase::Execute => "starting the function",
        Phase::Poll | Phase::PollStatus | Phase::PollPositions(_) => "polling",
        Phase::ErrorCode(_) => "reading the error code",
        Phase::FinalStop => "ending the function",
        Phase::Stopping(..) => "stopping",
    }
}
