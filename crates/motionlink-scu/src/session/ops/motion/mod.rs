//! A verified move of the actuators of one function: checks, writes read back, one RE, polling until the
//! unit reports the end of the motion, the in-position check, and RS; any failure or a cancel stops the
//! function at once and confirms the stop. Where the unit in use does not do what a check needs beyond the
//! manual's words (UserPositionData, reading remote data back), the move runs in the manual's plain form and
//! its report says what could not be verified.

use motionlink_link::Timestamp;

use super::basic::{check_against_map, check_stroke, stroke, stroke_not_set, write, StrokeFound};
use super::object::define_object;
use super::stop::{after_stop, Stop};
use super::{positions, read_item, statuses, ItemRead, MoveSpec, MoveTargets, Output};
use crate::config::Config;
use crate::error::Error;
use crate::model::ActuatorStatus1;
use crate::model::{Actuator, DataIndex, Function, MotionDirection, PositionCounts, StopMode, UNUSED};
use crate::session::ctx::Ctx;
use crate::session::report::ActuatorOutcome;
use crate::session::request::{PreparedRequest, Req};
use crate::value::Value;
use crate::wire::{Command, Request};

pub(crate) mod poll;

/// A move under way; see [`super::Op::Move`] and [`crate::Client::move_function`].
struct Move {
    spec: MoveSpec,
    started_at: Timestamp,
    speed: u16,
    drives_unknown: bool,
    /// Given targets of a function the map does not know: the connected actuators they do not name are held.
    hold_unnamed: bool,
    /// Connected actuators the caller named no target for, of a function the function map does not know
    /// (it may drive them): each gets its remote position written with where it stands, so that the
    /// function, should it drive it, keeps it there; from then on they are targets like the others (watched,
    /// judged, reported).
    held: Vec<Actuator>,
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

/// A verified move ([`super::Op::Move`]). Before RE nothing moves: a cancel ends the move where it is
/// ([`Error::CancelledBeforeMotion`]); from RE on, a cancel or any failure stops the function at once and
/// the stop is confirmed.
pub(crate) async fn move_function(ctx: &Ctx, spec: MoveSpec) -> Result<Output, Error> {
    let mut m = Move::new(spec, ctx.now());
    let config = ctx.core().config.clone();
    m.check(&config)?;
    let before_re = ctx.ending_on_cancel(Error::CancelledBeforeMotion(Command::Execute));
    m.prepare(&before_re).await?;
    m.execute(ctx).await
}

impl Move {
    fn new(spec: MoveSpec, now: Timestamp) -> Self {
        Move {
            spec,
            started_at: now,
            speed: 0,
            drives_unknown: false,
            hold_unnamed: false,
            held: Vec::new(),
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

    fn actuators(&self) -> Vec<Actuator> {
        self.targets.iter().map(|(a, _)| *a).collect()
    }

    /// Checks what can be checked before anything is sent.
    fn check(&mut self, config: &Config) -> Result<(), Error> {
        self.speed = self.spec.speed.for_motion(config.speed_mode).map_err(Error::InvalidArgument)?;
        match &self.spec.targets {
            MoveTargets::Given(targets) => {
                if targets.is_empty() {
                    return Err(Error::invalid("a move needs at least one actuator and its target"));
                }
                let actuators: Vec<Actuator> = targets.iter().map(|(a, _)| *a).collect();
                check_against_map(config, self.spec.function, &actuators)?;
                self.hold_unnamed = config.function_map.drives(self.spec.function).is_none();
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
    /// connected, and each target lies within its stroke. Then where they start, the session's cyclic object
    /// (defined and probed once per session, again after remote mode was opened again), the targets and the
    /// speed, each read back.
    async fn prepare(&mut self, ctx: &Ctx) -> Result<(), Error> {
        let data = read_item(ctx, ItemRead::all(DataIndex(0x0170))).await?;
        self.checked_status(data)?;
        for i in 0..self.order.len() {
            let found = stroke(ctx, self.order[i].0).await;
            self.stroke_read(i, found)?;
        }
        let mut read = self.actuators();
        read.extend(&self.held);
        let data = read_item(ctx, ItemRead::actuators(DataIndex(0x0010), read)).await?;
        let p = positions(&data)?;
        self.start = p;
        self.last_position = p;
        for &a in &self.held {
            self.targets.push((a, p[idx(a)]));
            self.order.push((a, p[idx(a)]));
        }
        define_object(ctx).await?;
        for (a, t) in self.targets.clone() {
            let index = a.remote_position_index();
            if write(ctx, index, &Value::RemotePosition(t.get()).to_bytes(), true).await?.is_some() {
                self.not_read_back.push(index);
            }
        }
        let index = self.spec.function.remote_speed_index();
        if write(ctx, index, &self.speed.to_le_bytes(), true).await?.is_some() {
            self.not_read_back.push(index);
        }
        Ok(())
    }

    /// The status of every actuator: which are connected, and which the move drives.
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
        if self.hold_unnamed {
            let named = self.actuators();
            self.held = Actuator::all().filter(|a| available(*a) && !named.contains(a)).collect();
        }
        Ok(())
    }

    /// The stroke of `order[i]` was read: its target is checked against it.
    fn stroke_read(&mut self, i: usize, stroke: Result<StrokeFound, Error>) -> Result<(), Error> {
        let (a, target) = self.order[i];
        let checked = match stroke {
            Ok(Ok(None)) => {
                self.not_verifiable.push(stroke_not_set(a));
                Ok(())
            }
            Ok(Ok(s)) => check_stroke(a, target, &s),
            Ok(Err(why)) => {
                self.not_verifiable.push(why);
                Ok(())
            }
            Err(e) => Err(e),
        };
        match checked {
            Err(e @ Error::OutsideLimits { .. }) if self.drives_unknown && a != self.spec.primary => {
                Err(Error::InvalidArgument(format!(
                    "{e}. The function map does not say which actuators {} drives, so every connected actuator \
                     gets the target; say which ones it drives (Config::function_map, --functions)",
                    self.spec.function
                )))
            }
            other => other,
        }
    }

    /// RE, then the looks at the actuators until the motion ends (see `poll`).
    async fn execute(&mut self, ctx: &Ctx) -> Result<Output, Error> {
        let re = Request::Execute {
            function: self.spec.function.id(),
            params: [MotionDirection::RemotePosition.code(), UNUSED],
        };
        let reply = ctx.send(Req::op(PreparedRequest::new(&re)?)).await;
        if let Err(e @ Error::CancelledBeforeMotion(_)) = reply {
            return Err(e);
        }
        // An RE that failed (refused, a lost or corrupt reply) may still have started the motion: it gets its
        // RS like any other failure. One whose reply was lost after a cancel (it is not sent again then) is
        // that cancel.
        let primary = self.spec.primary;
        if let Err(e) = reply.and_then(|r| r.ack(Command::Execute)) {
            let refused = e.clone();
            let cause = match e {
                Error::Timeout { .. } if ctx.cancelled() => {
                    Error::Cancelled { actuator: primary, position_counts: self.start[idx(primary)] }
                }
                e => e,
            };
            // The stop first; then, for a PE, what the unit's last error says.
            let stopped = self.stop(ctx, cause).await;
            super::say_last_error_of_pe(ctx, &refused).await;
            return Err(stopped);
        }
        if ctx.cancelled() {
            let e = Error::Cancelled { actuator: primary, position_counts: self.start[idx(primary)] };
            return Err(self.stop(ctx, e).await);
        }
        self.by_snapshot = {
            let core = ctx.core();
            core.poll_slot().is_some() && core.poll.configured
        };
        self.next_poll = self.started_at;
        loop {
            let ended = match self.look(ctx).await {
                Ok((status, positions)) => self.judge(ctx, status, positions).await,
                Err(cause) => Some(Err(Ended::Stop(cause))),
            };
            match ended {
                None => continue,
                Some(Ok(report)) => return Ok(Output::Move(report)),
                Some(Err(Ended::Stop(cause))) => return Err(self.stop(ctx, cause).await),
                Some(Err(Ended::Failed(e))) => return Err(e),
            }
        }
    }

    /// Stops the function at once after `cause`; the error to report.
    async fn stop(&self, ctx: &Ctx, cause: Error) -> Error {
        let stop = Stop::new(Function::Motion(self.spec.function), StopMode::Fast, self.actuators());
        let stopped = stop.run(ctx).await.rest;
        after_stop(cause, stopped.map(|(_, p)| p), &stop)
    }
}

/// How a move that did not reach its target ends.
enum Ended {
    /// The function is stopped, then this is reported.
    Stop(Error),
    /// This is reported as it is (the RS that ends a move that arrived failed).
    Failed(Error),
}
