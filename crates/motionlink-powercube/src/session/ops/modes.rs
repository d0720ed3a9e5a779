//! Every motion mode of the manual run to its end with the checks of a ramp move
//! ([`Op::RunMotion`](crate::session::Op::RunMotion)): the limits refused before anything moves, the
//! target read back where the module shows it, the end waited for and checked, and, for the modes that
//! run until something ends them (velocity, current, the loops), a hold watched as a wait watches a
//! motion and an end that is confirmed.

use std::time::Duration;

use crate::error::{Error, StopOutcome};
use crate::model::{
    Address, CubeState, ModuleKind, Motion, Param, Position, Quantity, StateFlag, TicksPerSec, Value, Velocity,
};
use crate::session::ctx::Ctx;
use crate::session::ops::motion::{motion_units, next_slot};
use crate::session::{Begun, MotionEnding, MotionReport, MotionSpec, Until};
use crate::wire::{AckPosition, Request};

/// Where the limits a motion is checked against come from ([`Ctx::check_limits`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Limits {
    /// Read from the module now (a motion run to its end, a checked move or write).
    Read,
    /// The module's setpoint cache of this generation ([`Op::Setpoint`](crate::session::Op::Setpoint)):
    /// each limit read the first time it is needed and kept until the cache is dropped.
    Cached(u64),
}

/// What the checks before a motion found ([`Ctx::check_motion`]): the module's kind, and for a position
/// mode its target.
pub(crate) struct Fit {
    kind: ModuleKind,
    target: Option<Target>,
}

/// The target of a position mode.
#[derive(Debug, Clone, Copy)]
struct Target {
    /// In the module's unit (an IRAMP / ISTEP target converted from ticks with IncRatio).
    unit: f32,
    /// In encoder ticks (a float target converted with IncRatio): what TargetPosInc and StepInc show.
    ticks: i32,
    /// The module's IncRatio.
    ratio: f64,
}

/// How the target of a position mode is read back.
enum TargetCheck {
    /// Not a position mode.
    None,
    /// A ramp (FRAMP, IRAMP): TargetPosInc, with what the session knows of it (see
    /// [`Ctx::prepare_target_read_back`]).
    PosInc(Option<bool>),
    /// A step (FSTEP, ISTEP): StepInc, "step mode target position in encoder ticks" (manual 4.6), as it
    /// read before the command.
    StepInc(i32),
}

/// True when `ticks` is the target `sent` (one tick allowed for the rounding of a float target).
fn same_ticks(ticks: i32, sent: i32) -> bool {
    (i64::from(ticks) - i64::from(sent)).abs() <= 1
}

impl Ctx {
    /// The limits of module `a` that `motion` must keep, as `limits` gives them (read now, or cached for
    /// the module's setpoints), each refused ([`Error::OutsideLimits`]), never clamped:
    ///
    /// - a float target (FRAMP, FSTEP) and a loop's far end (FRAMPLOOP, FCOSLOOP) within MinPos..MaxPos;
    /// - a tick target (IRAMP, ISTEP) within ActIMinPos..ActIMaxPos, the module's own limits in ticks (no
    ///   conversion through IncRatio, whose rounding could let a target one tick beyond pass);
    /// - a velocity within ±MaxVel (FVEL) or ±ActIMaxVel (IVEL), a current within ±MaxCur (FCUR); ICUR's
    ///   -500..500 digits are the spec's own check ([`MotionSpec::validate`]);
    /// - a step's speed, its distance from where the module stands over its time, within MaxVel (FSTEP)
    ///   or ActIMaxVel (ISTEP): a step faster than that the module would stretch, which is a limit too.
    ///   Where it stands is read now; with cached limits, it is where the last extended acknowledge of the
    ///   same kind (a float position for FSTEP, ticks for ISTEP) put it, and read only without one.
    pub(crate) async fn check_limits(&self, a: u8, motion: Motion, limits: Limits) -> Result<(), Error> {
        let range = |what: &'static str, value: f64, (min, max): (Param, Param)| async move {
            self.within_limit(a, what, value, min, false, limits).await?;
            self.within_limit(a, what, value, max, true, limits).await
        };
        let float_range = (Param::MinPos, Param::MaxPos);
        let tick_range = (Param::ActIMinPos, Param::ActIMaxPos);
        match motion {
            Motion::FRamp { pos } | Motion::FStep { pos, .. } => {
                range("the target position", f64::from(pos.value()), float_range).await?;
            }
            Motion::FRampLoop { pos } | Motion::FCosLoop { pos, .. } => {
                range("the loop's far end", f64::from(pos.value()), float_range).await?;
            }
            Motion::IRamp { pos } | Motion::IStep { pos, .. } => {
                range("the target position in ticks", f64::from(pos.0), tick_range).await?;
            }
            Motion::FVel { vel } => {
                self.within_size(a, "the velocity", f64::from(vel.value()), Param::MaxVel, limits).await?;
            }
            Motion::IVel { vel } => {
                self.within_size(a, "the velocity in ticks/s", f64::from(vel.0), Param::ActIMaxVel, limits).await?;
            }
            Motion::FCur { cur } => {
                self.within_size(a, "the current", f64::from(cur.0), Param::MaxCur, limits).await?;
            }
            Motion::ICur { .. } => {}
        }
        // The speed a step needs: at least its distance over its time, whatever the profile the module runs.
        const STEP_SPEED: &str = "the speed the step needs (its distance over its time)";
        let (to, time, in_ticks, max) = match motion {
            Motion::FStep { pos, time } => (f64::from(pos.value()), time, false, Param::MaxVel),
            Motion::IStep { pos, time } => (f64::from(pos.0), time, true, Param::ActIMaxVel),
            _ => return Ok(()),
        };
        let from = self.step_start(a, in_ticks, limits).await?;
        let speed = (to - from).abs() / (f64::from(time.0) / 1000.0);
        self.within_size(a, STEP_SPEED, speed, max, limits).await
    }

    /// Where module `a` stands for a step's speed rule, in ticks (ISTEP) or in its unit (FSTEP): read
    /// (ActIPos, ActPos), or, with cached limits, the position of its last extended acknowledge where that
    /// has the same form.
    async fn step_start(&self, a: u8, in_ticks: bool, limits: Limits) -> Result<f64, Error> {
        if let Limits::Cached(generation) = limits {
            let last = self.core().setpoints_of(a, generation).and_then(|c| c.last_position);
            match last {
                Some(AckPosition::Ticks(t)) if in_ticks => return Ok(f64::from(t.0)),
                Some(AckPosition::Unit(p)) if !in_ticks => return Ok(f64::from(p.value())),
                _ => {}
            }
        }
        if in_ticks {
            Ok(f64::from(self.get_as(a, Param::ActIPos, Value::as_i32).await?))
        } else {
            Ok(f64::from(self.position(a).await?.value()))
        }
    }

    /// What can be checked of a motion before anything is sent that changes the module (reads only; see
    /// [`Op::RunMotion`](crate::session::Op::RunMotion)): the spec's numbers, their units against the
    /// module's kind, and the module's limits read now ([`Ctx::check_limits`]).
    pub(crate) async fn check_motion(&self, a: u8, spec: &MotionSpec) -> Result<Fit, Error> {
        spec.validate()?;
        let mut units = motion_units(spec.motion);
        units.extend(spec.tolerance.map(|t| ("the tolerance", Quantity::Position(t))));
        self.check_units(a, &units).await?;
        let kind = self.kind(a).await?;
        self.check_limits(a, spec.motion, Limits::Read).await?;
        let target = match spec.motion {
            Motion::FRamp { pos } | Motion::FStep { pos, .. } => {
                let ratio = self.inc_ratio(a).await?;
                let ticks = (f64::from(pos.value()) * ratio).round() as i32;
                Some(Target { unit: pos.value(), ticks, ratio })
            }
            Motion::IRamp { pos } | Motion::IStep { pos, .. } => {
                let ratio = self.inc_ratio(a).await?;
                Some(Target { unit: (f64::from(pos.0) / ratio) as f32, ticks: pos.0, ratio })
            }
            _ => None,
        };
        Ok(Fit { kind, target })
    }

    /// A motion of any mode with every check (see [`Op::RunMotion`](crate::session::Op::RunMotion)), after
    /// [`Ctx::check_motion`] found `spec` fit for module `a`.
    pub(crate) async fn run_motion_checked(&self, a: u8, spec: &MotionSpec, fit: Fit) -> Result<MotionReport, Error> {
        let address = Address::checked(a);
        let state = self.ready_for_motion(a).await?;
        self.config_allows_motion(a, state).await?;
        let request = Request::motion(spec.motion, spec.ack)?;
        let mode = spec.id().ok_or(crate::wire::ModelError::NoExtendedAck(spec.motion.mode().name()))?;
        // A ramp runs with the module's own TargetVel and TargetAcc: one found to be 0 would not move it.
        if matches!(spec.motion, Motion::FRamp { .. } | Motion::IRamp { .. } | Motion::FRampLoop { .. }) {
            for param in [Param::TargetVel, Param::TargetAcc] {
                self.own_ramp_value_usable(a, param).await?;
            }
        }
        let start = self.position(a).await?;
        let check = match (spec.motion, fit.target) {
            (Motion::FRamp { .. } | Motion::IRamp { .. }, Some(t)) => {
                TargetCheck::PosInc(self.prepare_target_read_back(a, t.unit, t.ratio).await?)
            }
            (Motion::FStep { .. } | Motion::IStep { .. }, Some(_)) => {
                TargetCheck::StepInc(self.get_as(a, Param::StepInc, Value::as_i32).await?)
            }
            _ => TargetCheck::None,
        };
        if self.cancelled() {
            return Err(Error::Cancelled { address, stop: StopOutcome::NotStarted });
        }
        let at = self.now();
        let reply = match self.request(a, request).await {
            Ok(reply) => reply,
            // It may have arrived and set the module in motion.
            Err(e) => return Err(self.lost(a, e).await),
        };
        let ext_ack = match self.ext_ack_of(a, spec.ack, &request, reply) {
            Ok(ext) => ext,
            Err(e) => return Err(self.lost(a, e).await),
        };
        tracing::info!("module {a}: {} ({}) from {:.4}", mode.name(), spec.motion.describe(), start.value());
        let kind = fit.kind;
        let mut report = MotionReport {
            kind,
            mode,
            start: start.in_unit_of(kind),
            target: None,
            reached: start.in_unit_of(kind),
            held: None,
            ending: MotionEnding::Reached,
            ext_ack,
            state,
            verified: false,
            not_verifiable: Vec::new(),
        };
        match fit.target {
            Some(target) => self.to_target(a, spec, target, check, at, &mut report).await?,
            None => self.hold_and_end(a, spec, at, &mut report).await?,
        }
        report.verified = report.not_verifiable.is_empty();
        Ok(report)
    }

    /// A position mode, its command sent at `at`: the target read back (`check`), the end waited for, and
    /// the position read twice within the tolerance; into `report`.
    async fn to_target(
        &self,
        a: u8,
        spec: &MotionSpec,
        target: Target,
        check: TargetCheck,
        at: motionlink_link::Timestamp,
        report: &mut MotionReport,
    ) -> Result<(), Error> {
        let address = Address::checked(a);
        // StepInc as it read before the command, while the step is not seen to take it yet.
        let mut step_pending = None;
        match check {
            TargetCheck::None => {}
            TargetCheck::PosInc(known) => {
                let note = self.check_target_taken(a, target.ticks, known).await?;
                let ticks_apart = known == Some(false) && matches!(spec.motion, Motion::IRamp { .. });
                report.not_verifiable.extend(note.map(|why| {
                    match ticks_apart {
                        // Found with a float target (TargetPos): whether an IRAMP's ticks reach it is not known.
                        true => "the motion's target could not be read back: this module keeps TargetPosInc apart \
                             from the targets it is sent (a TargetPos written left it as it was), and the manual \
                             has no other way to read it"
                            .to_string(),
                        false => why,
                    }
                }));
            }
            TargetCheck::StepInc(before) => {
                let now = match self.get_as(a, Param::StepInc, Value::as_i32).await {
                    Ok(now) => now,
                    Err(e) => return Err(self.lost(a, e).await),
                };
                if same_ticks(now, target.ticks) {
                    if same_ticks(before, target.ticks) {
                        report.not_verifiable.push(
                            "the step's target could not be read back: StepInc already held it before the \
                             command, so it cannot show whether the module took it"
                                .into(),
                        );
                    }
                } else if now == before {
                    // Not taken yet: a step under way (the new one waits in the module's buffer), or a module
                    // that starts later. Read again once the motion is over.
                    step_pending = Some(before);
                } else {
                    // StepInc changed, to another target: the command was corrupted on the way.
                    let stop = self.stop_motion(a).await;
                    return Err(Error::TargetMismatch { address, sent: target.ticks, taken: now, stop });
                }
            }
        }
        // A step sets no STATE_RAMP_END (the manual gives it to ramps; the flags of a step are
        // STATE_INPROGRESS and STATE_FULLBUFFER): its end is the module at rest.
        let until = match spec.motion {
            Motion::FStep { .. } | Motion::IStep { .. } => Until::Motion,
            _ => Until::Ramp,
        };
        let tolerance = spec.tolerance().value();
        let begun = Begun { at, target: Some((target.unit, tolerance)) };
        let (state, motion_seen) = self.wait_begun(a, until, spec.timeout, Some(begun)).await?;
        let reached = self.check_reached(a, target.unit, tolerance, state, motion_seen).await?;
        if let Some(before) = step_pending {
            let after = self.get_as(a, Param::StepInc, Value::as_i32).await?;
            if !same_ticks(after, target.ticks) {
                report.not_verifiable.push(format!(
                    "the step's target could not be read back: StepInc shows {after} ticks after the step (and \
                     {before} before it), not the {} ticks sent; the module stands within the tolerance of the \
                     target all the same",
                    target.ticks
                ));
            }
        }
        report.target = Some(Position::native(target.unit).in_unit_of(report.kind));
        report.reached = reached.in_unit_of(report.kind);
        report.ending = MotionEnding::Reached;
        report.state = state;
        Ok(())
    }

    /// A continuous mode, its command sent at `at`: watched for [`MotionSpec::hold`] (until cancelled
    /// without one), then ended: a velocity mode with velocity 0 and the wait for rest, a current or loop
    /// mode with a Halt confirmed by its state; into `report`.
    async fn hold_and_end(
        &self,
        a: u8,
        spec: &MotionSpec,
        at: motionlink_link::Timestamp,
        report: &mut MotionReport,
    ) -> Result<(), Error> {
        let address = Address::checked(a);
        let motion_seen = self.hold(a, at, spec.hold).await?;
        report.held = Some(self.now().saturating_since(at));
        let zero = match spec.motion {
            Motion::FVel { vel } => Some(Motion::FVel { vel: Velocity::new(0.0, vel.unit()) }),
            Motion::IVel { .. } => Some(Motion::IVel { vel: TicksPerSec(0) }),
            _ => None,
        };
        let what = match spec.motion {
            Motion::FVel { .. } | Motion::IVel { .. } => {
                "the velocity the module took could not be read back: the manual has no parameter that shows a \
                 velocity command's value (ActVel is the velocity measured)"
            }
            Motion::FCur { .. } | Motion::ICur { .. } => {
                "the current the module took could not be read back: the manual has no parameter that shows a \
                 current command's value (Cur is the current measured)"
            }
            _ => {
                "the loop's far end could not be read back: the manual has no parameter that shows the target of \
                 a loop"
            }
        };
        report.not_verifiable.push(what.into());
        if !motion_seen {
            report.not_verifiable.push(
                "the module never showed STATE_MOTION while the motion was held: that it ran as commanded could \
                 not be seen"
                    .into(),
            );
        }
        match zero {
            Some(zero) => {
                let request = Request::motion(zero, spec.ack)?;
                if let Err(e) = self.request(a, request).await {
                    return Err(self.lost(a, e).await);
                }
                tracing::info!("module {a}: {} 0 after {:?}", report.mode.name(), report.held.unwrap_or_default());
                // The module was set in motion by this operation before: at rest now is the end of this stop.
                let (state, _) = self.wait_begun(a, Until::Motion, spec.timeout, None).await?;
                report.state = state;
                report.ending = MotionEnding::VelocityZero;
            }
            None => {
                if let StopOutcome::Unconfirmed { reason, watchdog_armed } = self.stop_motion(a).await {
                    return Err(Error::StopUnconfirmed { addresses: vec![address], detail: reason, watchdog_armed });
                }
                let state = self.state(a).await?;
                if !state.contains(StateFlag::Halted) {
                    report.not_verifiable.push(
                        "the module acknowledged the Halt and came to rest, but its state read after it does not \
                         show STATE_HALTED"
                            .into(),
                    );
                }
                report.state = state;
                report.ending = MotionEnding::Halted;
            }
        }
        // At rest now: where it came to rest.
        report.reached = self.position(a).await?.in_unit_of(report.kind);
        Ok(())
    }

    /// Watches module `a`, set in motion at `at`, until `hold` has passed since (for ever without one),
    /// polled as a wait polls ([`Ctx::watch`]): a module that shows an error flag or halts on its own ends
    /// it as an error (one that still shows STATE_MOTION then is halted, [`Error::FailedDuringMotion`]), as
    /// does a failing line; a cancel halts the module ([`Error::Cancelled`]). Whether STATE_MOTION was seen.
    async fn hold(&self, a: u8, at: motionlink_link::Timestamp, hold: Option<Duration>) -> Result<bool, Error> {
        let address = Address::checked(a);
        let start = self.now();
        let deadline = hold.map(|h| at + h);
        let period = self.poll_period();
        let mut due = start;
        let mut poll = self.start_polls(a).await?;
        let mut motion_seen = false;
        loop {
            let state: CubeState = match self.watch(a, &mut poll, start).await {
                Ok((state, _)) => state,
                Err(e @ (Error::Device { state, .. } | Error::Halted { state, .. }))
                    if state.contains(StateFlag::Motion) =>
                {
                    let stop = self.stop_motion(a).await;
                    return Err(Error::FailedDuringMotion { address, cause: Box::new(e), stop });
                }
                Err(e) => return Err(e),
            };
            motion_seen |= state.contains(StateFlag::Motion);
            let now = self.now();
            if deadline.is_some_and(|d| now >= d) {
                return Ok(motion_seen);
            }
            if self.cancelled() {
                return Err(Error::Cancelled { address, stop: self.stop_motion(a).await });
            }
            next_slot(&mut due, now, period);
            self.sleep_until_cancelled(deadline.map_or(due, |d| due.min(d))).await;
            if self.cancelled() {
                return Err(Error::Cancelled { address, stop: self.stop_motion(a).await });
            }
        }
    }
}
