//! Motions and what makes them trustworthy: writes that are read back, targets checked against the
//! module's limits, the target of the motion command read back, waits that poll at a set rate, the final
//! position checked, and a stop that says whether it was confirmed whenever a motion cannot go on.

use std::time::Duration;

use crate::error::{unexpected, Error, StopOutcome};
use crate::model::{
    AckKind, Broadcast, ConfigFlag, CubeState, DataType, ModuleKind, Motion, Param, Position, Quantity, ShortState,
    StateFlag, Value,
};
use crate::session::ctx::Ctx;
use crate::session::ops::checked;
use crate::session::ops::modes::Limits;
use crate::session::ops::twins::{self, TwinCheck};
use crate::session::{Begun, HomeReport, MoveReport, MoveSpec, Progress, Readback, Until};
use crate::wire::{ExtAck, Reply, Request};

impl Ctx {
    /// Stops module `a` after an action that may have set it in motion cannot go on, and says whether the
    /// module confirmed it: up to three Halts by address (a Halt may be repeated safely; not after the line
    /// itself failed), then, once one is acknowledged, the state until STATE_MOTION clears (at most
    /// [`HALT_SETTLE`](crate::session::HALT_SETTLE), as `stop` reads it). Confirmed only when the module
    /// showed itself at rest; otherwise (no Halt acknowledged, still in motion, its state unreadable) a Halt
    /// broadcast to every module and the watchdog refresh stopped, so that an armed module halts itself
    /// within 50 ms.
    pub async fn stop_motion(&self, a: u8) -> StopOutcome {
        let reason = match self.halt_repeated(a).await {
            Ok(()) => match self.at_rest_after_halt(a).await {
                Ok(_) => return StopOutcome::Confirmed,
                Err(Error::StillMoving { state, waited, .. }) => format!(
                    "module {a} acknowledged the Halt, but still reported STATE_MOTION {} ms later (state: {state})",
                    waited.as_millis()
                ),
                Err(e) => {
                    format!("module {a} acknowledged the Halt, but its state could not be read to see it at rest: {e}")
                }
            },
            Err((e, _)) => e.to_string(),
        };
        tracing::warn!(
            "module {a}: halt not confirmed ({reason}); broadcasting a halt and stopping the watchdog refresh"
        );
        let watchdog_armed = self.watchdog_armed(a);
        if let Err(e) = self.broadcast(Broadcast::Halt).await {
            tracing::warn!("the halt broadcast could not be sent either: {e}");
        }
        // Nothing confirmed it: the module stays among those the session started (the broadcast on CAN
        // takes it off), so that `started()` names it and the close tries again.
        self.core().mark_started(a);
        self.abandon_watchdog();
        StopOutcome::Unconfirmed { reason, watchdog_armed }
    }

    /// An error of a request sent while module `a` may be moving: the motion is stopped, and the error says
    /// whether that was confirmed. Once the operation is cancelled, a request that failed (not retried then)
    /// ends it as the cancel: [`Error::Cancelled`], with the stop's outcome.
    pub async fn lost(&self, a: u8, cause: Error) -> Error {
        let stop = self.stop_motion(a).await;
        let address = crate::model::Address::checked(a);
        if self.cancelled() {
            tracing::debug!("module {a}: after the cancel: {cause}");
            return Error::Cancelled { address, stop };
        }
        Error::FailedDuringMotion { address, cause: Box::new(cause), stop }
    }

    /// Refuses a module that would ignore a motion command: one with an error flag ([`Error::Device`]) or
    /// halted ([`Error::Halted`]; a reset clears it).
    pub(crate) async fn ready_for_motion(&self, a: u8) -> Result<CubeState, Error> {
        let state = self.state(a).await?;
        if state.has_fault() {
            return Err(Error::Device { address: crate::model::Address::checked(a), state });
        }
        if state.contains(StateFlag::Halted) {
            return Err(Error::Halted { address: crate::model::Address::checked(a), state });
        }
        // Before anything moves: how this module can be polled while it does.
        self.probe_pos_state_dio(a).await?;
        Ok(state)
    }

    /// Refuses a motion command that module `a` (in `state`) would not carry out as sent, or not acknowledge,
    /// by its Config word (read with its kind): CONFIGID_MOD_DISABLE_ACK on CAN (no acknowledge comes: the
    /// motion could not be confirmed nor a Halt), CONFIGID_MOD_SYNC_MOTION on CAN (the module waits for the broadcast
    /// startMotionAll after a motion command, manual 7.4), or CONFIGID_MOD_M3_COMPATIBLE while it is not
    /// homed (it "does not accept motion commands unless successfully homed"). A module that gives no Config
    /// word is not checked.
    pub(crate) async fn config_allows_motion(&self, a: u8, state: CubeState) -> Result<(), Error> {
        self.kind(a).await?;
        let (word, can) = {
            let core = self.core();
            (core.configs.get(&a).copied().flatten(), core.can)
        };
        let Some(word) = word else { return Ok(()) };
        let why = if can && word.contains(ConfigFlag::DisableAck) {
            "its Config word has CONFIGID_MOD_DISABLE_ACK: on CAN it acknowledges no command, and this client \
             needs the acknowledges (of the motion command, of a Halt) to know what the module took (clear the \
             flag with the tool that set it)"
        } else if can && word.contains(ConfigFlag::SyncMotion) {
            "its Config word has CONFIGID_MOD_SYNC_MOTION: after a motion command it waits for the broadcast \
             startMotionAll, which a move of one module does not send (clear the flag with `set Config` to \
             move it alone)"
        } else if word.contains(ConfigFlag::M3Compatible) && !state.contains(StateFlag::HomeOk) {
            "it is not homed (STATE_HOME_OK clear) and its Config word has CONFIGID_MOD_M3_COMPATIBLE: it \
             accepts no motion command until homed (home it first: `powercube home`)"
        } else {
            return Ok(());
        };
        Err(Error::NotReady { address: crate::model::Address::checked(a), why })
    }

    /// Reads a float parameter that must be a finite number.
    async fn get_finite(&self, a: u8, param: Param) -> Result<f32, Error> {
        let v = self.get_f32(a, param).await?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(unexpected(a, &Request::Get(param), format!("{v} (not a finite number)")))
        }
    }

    /// The encoder ticks per unit (IncRatio), which must be a number above 0.
    pub(super) async fn inc_ratio(&self, a: u8) -> Result<f64, Error> {
        let r = self.get_finite(a, Param::IncRatio).await?;
        if r > 0.0 {
            Ok(f64::from(r))
        } else {
            Err(unexpected(a, &Request::Get(Param::IncRatio), format!("{r} (not above 0)")))
        }
    }

    /// A limit parameter of module `a` as a number, read as the type the manual gives it: a float (MinPos,
    /// MaxVel ...) that must be finite, or an Int32 in ticks (ActIMinPos, ActIMaxVel ...).
    async fn limit_value(&self, a: u8, param: Param) -> Result<f64, Error> {
        match param.data_type() {
            DataType::I32 => self.get_as(a, param, Value::as_i32).await.map(f64::from),
            _ => self.get_finite(a, param).await.map(f64::from),
        }
    }

    /// The limit `param` of module `a` as `limits` gives it: read now, or taken from the module's setpoint
    /// cache of that generation, where it is read (and kept) the first time.
    async fn limit_from(&self, a: u8, param: Param, limits: Limits) -> Result<f64, Error> {
        let Limits::Cached(generation) = limits else { return self.limit_value(a, param).await };
        let cached = self.core().setpoints_of(a, generation).and_then(|c| c.limits.get(&param).copied());
        if let Some(value) = cached {
            return Ok(value);
        }
        let value = self.limit_value(a, param).await?;
        // Kept only if the cache was not dropped meanwhile (a write of the limit under way).
        if let Some(c) = self.core().setpoints_of(a, generation) {
            c.limits.insert(param, value);
        }
        Ok(value)
    }

    /// Refuses `value` (named `what`) if it lies beyond the limit `param` of the module (`upper`: a maximum),
    /// as `limits` gives it.
    pub(super) async fn within_limit(
        &self,
        a: u8,
        what: &str,
        value: f64,
        param: Param,
        upper: bool,
        limits: Limits,
    ) -> Result<(), Error> {
        let limit = self.limit_from(a, param, limits).await?;
        let beyond = if upper { value > limit } else { value < limit };
        if beyond {
            return Err(self.outside_limit(a, what, value, (param, limit), limits).await);
        }
        Ok(())
    }

    /// Refuses `value` (named `what`, either sign) if its size lies beyond the limit `param` of the module
    /// (a maximum of a speed or a current, which holds both ways), as `limits` gives it.
    pub(super) async fn within_size(
        &self,
        a: u8,
        what: &str,
        value: f64,
        param: Param,
        limits: Limits,
    ) -> Result<(), Error> {
        let limit = self.limit_from(a, param, limits).await?;
        // A NaN is beyond every limit.
        if value.is_nan() || value.abs() > limit {
            return Err(self.outside_limit(a, what, value, (param, limit), limits).await);
        }
        Ok(())
    }

    /// The refusal of `value` (named `what`) beyond the limit `param` of the module, which is `limit`: with
    /// the unit and, for a position, the whole range (its other end as `limits` gives it).
    async fn outside_limit(
        &self,
        a: u8,
        what: &str,
        value: f64,
        (param, limit): (Param, f64),
        limits: Limits,
    ) -> Error {
        let unit = self.kind(a).await.map_or("", |k| param.unit().symbol(k));
        let other = match param {
            Param::MinPos => Some(Param::MaxPos),
            Param::MaxPos => Some(Param::MinPos),
            Param::ActIMinPos => Some(Param::ActIMaxPos),
            Param::ActIMaxPos => Some(Param::ActIMinPos),
            _ => None,
        };
        let other_limit = match other {
            Some(p) => self.limit_from(a, p, limits).await.ok().map(|v| (p, v)),
            None => None,
        };
        Error::OutsideLimits {
            address: crate::model::Address::checked(a),
            what: what.into(),
            value,
            limit: param,
            limit_value: limit,
            unit,
            other_limit,
        }
    }

    /// Writes `param` and checks that the module took it (see [`Op::SetChecked`](crate::session::Op)).
    pub async fn set_checked(&self, a: u8, param: Param, value: Value) -> Result<Readback, Error> {
        Request::set(param, value)?;
        let number = value.as_f64();
        let name = param.name();
        // A ramp's velocity and acceleration are sizes (the target gives the direction; the Inc twins are
        // UInt32 in the manual's table): a negative one is refused, named as given.
        if let (Param::TargetVel | Param::TargetAcc | Param::TargetVelInc | Param::TargetAccInc, Some(v)) =
            (param, number)
        {
            if v < 0.0 {
                return Err(Error::InvalidArgument {
                    what: name,
                    must: "at least 0 (a ramp's size: the target position gives the direction)",
                    value: v.to_string(),
                });
            }
        }
        match (param, number) {
            (Param::TargetPos, Some(v)) => {
                self.within_limit(a, name, v, Param::MinPos, false, Limits::Read).await?;
                self.within_limit(a, name, v, Param::MaxPos, true, Limits::Read).await?;
            }
            (Param::TargetPosInc, Some(v)) => {
                self.within_limit(a, name, v, Param::ActIMinPos, false, Limits::Read).await?;
                self.within_limit(a, name, v, Param::ActIMaxPos, true, Limits::Read).await?;
            }
            (Param::TargetVel, Some(v)) => self.within_limit(a, name, v, Param::MaxVel, true, Limits::Read).await?,
            (Param::TargetVelInc, Some(v)) => {
                self.within_limit(a, name, v, Param::ActIMaxVel, true, Limits::Read).await?
            }
            (Param::TargetAcc, Some(v)) => self.within_limit(a, name, v, Param::MaxAcc, true, Limits::Read).await?,
            (Param::TargetAccInc, Some(v)) => {
                self.within_limit(a, name, v, Param::ActIMaxAcc, true, Limits::Read).await?
            }
            (Param::Cur, Some(v)) => self.within_limit(a, name, v.abs(), Param::MaxCur, true, Limits::Read).await?,
            _ => {}
        }
        if param.read_back_as().is_some() && number.is_some() {
            let ratio = self.inc_ratio(a).await?;
            return Ok(match self.write_twinned(a, param, value, ratio).await? {
                TwinCheck::Verified(read) => {
                    Readback { read_in_unit: param.from_read_back_ticks(&read, ratio), ..Readback::same(read) }
                }
                TwinCheck::Unverified(why) => Readback::unverified(why),
            });
        }
        self.set(a, param, value).await?;
        if param == Param::Cur {
            return Ok(Readback::unverified("reading Cur gives the measured current, not the value written"));
        }
        if !param.access().readable() {
            return Ok(Readback::unverified("the manual has no way to read it"));
        }
        let read = self.get(a, param).await?;
        let same = match (param, value.as_u32(), read.as_u32()) {
            // Only the outputs of the DIO word are written; the inputs and switches are the outside world's.
            (Param::DioSetup, Some(w), Some(r)) => w & 0xF0 == r & 0xF0,
            _ => read == value,
        };
        if same {
            Ok(Readback::same(read))
        } else {
            Err(Error::ReadBack { address: crate::model::Address::checked(a), param, wrote: value, read, twin: None })
        }
    }

    /// A motion command in any mode, its units checked against the module's kind; the extended
    /// acknowledge if `ack` asks for one and the module gives it (a firmware before PowerCube-OS 2.5.16 /
    /// 3.5.13 answers with the simple one: `None`, the motion taken, one warning). Cancelled while its
    /// acknowledge is awaited, the module is halted.
    pub async fn motion(&self, a: u8, motion: Motion, ack: AckKind) -> Result<Option<ExtAck>, Error> {
        let request = Request::motion(motion, ack)?;
        self.check_units(a, &motion_units(motion)).await?;
        let reply = self.request(a, request).await;
        self.halt_if_cancelled(a, &request).await?;
        self.ext_ack_of(a, ack, &request, reply?)
    }

    /// The extended acknowledge in `reply` to the motion command `request` (with acknowledge `ack`), in the
    /// unit of the module's kind where known. The simple acknowledge to an extended-acknowledge MotionID
    /// (a firmware before PowerCube-OS 2.5.16 / 3.5.13) is `None`, the motion taken, said once per module.
    pub(super) fn ext_ack_of(
        &self,
        a: u8,
        ack: AckKind,
        request: &Request,
        reply: Reply,
    ) -> Result<Option<ExtAck>, Error> {
        match reply {
            Reply::Motion { ext, .. } => {
                if ext.is_none() && ack == AckKind::Extended {
                    self.core().warn_once(a, "extended_ack", || {
                        format!(
                            "module {a} answers a motion command with an extended-acknowledge MotionID with the \
                             simple acknowledge (PowerCube-OS before 2.5.16 / 3.5.13): the motion was taken, \
                             without position, state and DIO"
                        )
                    });
                }
                Ok(ext.map(|e| e.resolved(self.known_kind(a))))
            }
            other => Err(unexpected(a, request, other)),
        }
    }

    /// A raw request to `a`; a motion command whose operation was cancelled while its acknowledge was
    /// awaited is halted.
    pub async fn raw_request(&self, a: u8, request: Request) -> Result<Reply, Error> {
        let reply = self.request(a, request).await;
        self.halt_if_cancelled(a, &request).await?;
        reply
    }

    /// If the operation was cancelled and `request` may have set `a` in motion: the module is halted and
    /// that is the operation's end.
    pub(super) async fn halt_if_cancelled(&self, a: u8, request: &Request) -> Result<(), Error> {
        if request.starts_motion() && self.cancelled() {
            return Err(Error::Cancelled {
                address: crate::model::Address::checked(a),
                stop: self.stop_motion(a).await,
            });
        }
        Ok(())
    }

    /// Waits for `until` (polled every [`Config::poll_interval`](crate::session::Config) on a fixed
    /// schedule), halting on a timeout, a cancellation or a failing line.
    pub async fn wait(&self, a: u8, until: Until, timeout: Duration) -> Result<CubeState, Error> {
        self.wait_begun(a, until, timeout, None).await.map(|(state, _)| state)
    }

    /// [`Ctx::wait`] for the end of a motion this operation started with a command sent at `begun.at`: a
    /// state that shows the end counts only once the module has shown STATE_MOTION during the wait, or stands
    /// within the tolerance of `begun.target`, or [`Config::start_grace`](crate::session::Config) has passed
    /// since the command (an end flag of an earlier motion may still be set while a module has not started
    /// this one). Also returns whether STATE_MOTION was seen.
    pub async fn wait_begun(
        &self,
        a: u8,
        until: Until,
        timeout: Duration,
        begun: Option<Begun>,
    ) -> Result<(CubeState, bool), Error> {
        let grace = self.core().config.start_grace;
        let mut motion_seen = false;
        let start = self.now();
        let deadline = start + timeout;
        let period = self.poll_period();
        let mut due = start;
        let mut poll = self.start_polls(a).await?;
        loop {
            let (state, position) = self.watch(a, &mut poll, start).await?;
            let now = self.now();
            motion_seen |= state.contains(StateFlag::Motion);
            let begun_ok = begun.is_none_or(|b| {
                motion_seen
                    || now.saturating_since(b.at) >= grace
                    || b.target.is_some_and(|(target, tolerance)| (position.value() - target).abs() <= tolerance)
            });
            if until.reached(state) && begun_ok {
                self.core().started.remove(&a);
                return Ok((state, motion_seen));
            }
            if self.cancelled() {
                return Err(Error::Cancelled {
                    address: crate::model::Address::checked(a),
                    stop: self.stop_motion(a).await,
                });
            }
            if now >= deadline {
                let stop = self.stop_motion(a).await;
                return Err(Error::MoveTimeout {
                    address: crate::model::Address::checked(a),
                    what: until.what(),
                    waited: timeout,
                    state,
                    stop,
                });
            }
            next_slot(&mut due, now, period);
            self.sleep_until_cancelled(due.min(deadline)).await;
            if self.cancelled() {
                return Err(Error::Cancelled {
                    address: crate::model::Address::checked(a),
                    stop: self.stop_motion(a).await,
                });
            }
        }
    }

    /// How often a wait polls: [`Config::poll_interval`](crate::session::Config), at least every 100 µs.
    pub(super) fn poll_period(&self) -> Duration {
        self.core().config.poll_interval.max(Duration::from_micros(100))
    }

    /// What the polls of a wait of module `a` start from: how the module can be polled (probed once; a
    /// failing probe while a motion may run is lost, see [`Ctx::lost`]).
    pub(super) async fn start_polls(&self, a: u8) -> Result<Poll, Error> {
        if let Err(e) = self.probe_pos_state_dio(a).await {
            return Err(self.lost(a, e).await);
        }
        Ok(Poll { separate: self.lacks_pos_state_dio(a), ..Poll::default() })
    }

    /// One poll of module `a` while a motion is watched ([`Ctx::poll_state`]), reported as [`Progress`]
    /// (the time since `start`): its state and position. A module that shows an error flag
    /// ([`Error::Device`]) or STATE_HALTED ([`Error::Halted`]) has stopped on its own and ends the watch;
    /// a poll that fails while the motion may run halts it ([`Ctx::lost`]).
    pub(super) async fn watch(
        &self,
        a: u8,
        poll: &mut Poll,
        start: motionlink_link::Timestamp,
    ) -> Result<(CubeState, Position), Error> {
        let (state, position) = match self.poll_state(a, poll).await {
            Ok(x) => x,
            // The line is failing, or the module stopped answering, while a motion may be running (or
            // the poll was not asked again after a cancel: the cancel, see `lost`).
            Err(e) => return Err(self.lost(a, e).await),
        };
        let now = self.now();
        let address = crate::model::Address::new(a)?;
        let position = Position::native(position).resolved(self.known_kind(a));
        self.progress(Progress { address, position, state, elapsed: now.saturating_since(start) });
        if state.has_fault() {
            self.core().started.remove(&a);
            return Err(Error::Device { address: crate::model::Address::checked(a), state });
        }
        if state.contains(StateFlag::Halted) {
            self.core().started.remove(&a);
            return Err(Error::Halted { address: crate::model::Address::checked(a), state });
        }
        Ok((state, position))
    }

    /// One poll of a wait: the state word and the position of module `a`. One exchange where it can be:
    /// ActFPosStateDio gives the position and the short state in one answer, and the full CubeState is
    /// read only when the short state may say more than the last full read did. It is skipped only in the
    /// middle of a motion: the last full read showed the module moving (STATE_MOTION, no STATE_RAMP_END,
    /// no error flag, not halted), the short state is the same as then (still SHORT_MOTION, no
    /// SHORT_RAMP_END; an error or a halt stops the module, which clears SHORT_MOTION, and on a homed
    /// module raises SHORT_NOT_OK), and that full read is less than [`FULL_STATE_EVERY`] old, so that even
    /// a flag the short state does not carry is seen within that time. Wherever a wait may end (the motion
    /// over, the ramp ended) the state is read in full. A module that refuses ActFPosStateDio is polled
    /// with CubeState and ActPos from then on.
    pub(super) async fn poll_state(&self, a: u8, poll: &mut Poll) -> Result<(CubeState, f32), Error> {
        if !poll.separate {
            let read = self
                .get_as(a, Param::ActFPosStateDio, |v| match *v {
                    Value::PosStateDio { pos, state, .. } => Some((pos, state)),
                    _ => None,
                })
                .await;
            match read {
                Ok((position, short)) => {
                    let now = self.now();
                    if let Some((at, last_short, full)) = poll.last {
                        let moving = full.contains(StateFlag::Motion)
                            && !full.contains(StateFlag::RampEnd)
                            && !full.contains(StateFlag::Halted)
                            && !full.has_fault();
                        if moving && last_short == short && now.saturating_since(at) < FULL_STATE_EVERY {
                            return Ok((full, position));
                        }
                    }
                    let full = self.state(a).await?;
                    poll.last = Some((now, short, full));
                    return Ok((full, position));
                }
                Err(Error::Refused { .. }) => {
                    tracing::debug!("module {a} refuses ActFPosStateDio: polling CubeState and ActPos");
                    poll.separate = true;
                }
                Err(e) => return Err(e),
            }
        }
        let state = self.state(a).await?;
        Ok((state, self.get_f32(a, Param::ActPos).await?))
    }

    /// Homes the module and waits for the end of homing (see [`Op::HomeAndWait`](crate::session::Op)).
    pub async fn home_and_wait(&self, a: u8, timeout: Duration) -> Result<HomeReport, Error> {
        if timeout.is_zero() {
            return Err(Error::InvalidArgument { what: "the timeout", must: "above 0", value: "0".into() });
        }
        // The unit of the position the report gives, known before anything moves.
        let kind = self.kind(a).await?;
        self.ready_for_motion(a).await?;
        if self.cancelled() {
            return Err(Error::Cancelled { address: crate::model::Address::checked(a), stop: StopOutcome::NotStarted });
        }
        let at = self.now();
        if let Err(e) = self.action(a, crate::wire::Action::Home).await {
            return Err(self.lost(a, e).await);
        }
        tracing::info!("module {a}: homing");
        let (state, _) = self.wait_begun(a, Until::Home, timeout, Some(Begun { at, target: None })).await?;
        let reached = self.position(a).await?.in_unit_of(kind);
        Ok(HomeReport { kind, reached, state, verified: true, not_verifiable: Vec::new() })
    }

    /// A ramp move with every check this protocol allows (see [`Op::MoveTo`](crate::session::Op)).
    pub async fn move_to(&self, a: u8, spec: &MoveSpec) -> Result<MoveReport, Error> {
        let kind = self.check_move(a, spec).await?;
        self.move_checked(a, spec, kind).await
    }

    /// What can be checked of a move before anything is sent that changes the module: its numbers, their
    /// units against the module's kind, the target against MinPos/MaxPos and the velocity and acceleration
    /// against MaxVel/MaxAcc (refused, never clamped). Reads only; the module's kind.
    pub async fn check_move(&self, a: u8, spec: &MoveSpec) -> Result<ModuleKind, Error> {
        spec.validate()?;
        let tolerance = spec.tolerance();
        let mut units = vec![
            ("the target position", Quantity::Position(spec.target)),
            ("the tolerance", Quantity::Position(tolerance)),
        ];
        units.extend(spec.vel.map(|v| ("the velocity", Quantity::Velocity(v))));
        units.extend(spec.acc.map(|acc| ("the acceleration", Quantity::Acceleration(acc))));
        self.check_units(a, &units).await?;
        let kind = self.kind(a).await?;
        let target = f64::from(spec.target.value());
        self.within_limit(a, "the target position", target, Param::MinPos, false, Limits::Read).await?;
        self.within_limit(a, "the target position", target, Param::MaxPos, true, Limits::Read).await?;
        if let Some(v) = spec.vel {
            self.within_limit(a, "the velocity", f64::from(v.value()), Param::MaxVel, true, Limits::Read).await?;
        }
        if let Some(acc) = spec.acc {
            self.within_limit(a, "the acceleration", f64::from(acc.value()), Param::MaxAcc, true, Limits::Read).await?;
        }
        Ok(kind)
    }

    /// [`Ctx::move_to`] after [`Ctx::check_move`] found `spec` fit for module `a` of `kind`.
    pub async fn move_checked(&self, a: u8, spec: &MoveSpec, kind: ModuleKind) -> Result<MoveReport, Error> {
        let state = self.ready_for_motion(a).await?;
        self.config_allows_motion(a, state).await?;
        let tolerance = spec.tolerance();
        let target = f64::from(spec.target.value());
        let ratio = self.inc_ratio(a).await?;
        let start = self.position(a).await?;
        let motion = Request::motion(Motion::FRamp { pos: spec.target }, AckKind::Simple)?;
        let mut not_verifiable = Vec::new();
        for (param, given) in
            [(Param::TargetVel, spec.vel.map(|v| v.value())), (Param::TargetAcc, spec.acc.map(|acc| acc.value()))]
        {
            match given {
                Some(v) => {
                    if let TwinCheck::Unverified(why) = self.write_twinned(a, param, Value::F32(v), ratio).await? {
                        not_verifiable.push(why);
                    }
                }
                None => self.own_ramp_value_usable(a, param).await?,
            }
        }
        let pos_known = self.prepare_target_read_back(a, spec.target.value(), ratio).await?;
        if self.cancelled() {
            return Err(Error::Cancelled { address: crate::model::Address::checked(a), stop: StopOutcome::NotStarted });
        }
        let at = self.now();
        if let Err(e) = self.request(a, motion).await {
            // It may have arrived and started the ramp.
            return Err(self.lost(a, e).await);
        }
        tracing::info!("module {a}: moving from {:.4} to {}", start.value(), spec.target.value());
        let sent = (target * ratio).round() as i32;
        if let Some(why) = self.check_target_taken(a, sent, pos_known).await? {
            not_verifiable.push(why);
        }
        let begun = Begun { at, target: Some((spec.target.value(), tolerance.value())) };
        let (state, motion_seen) = self.wait_begun(a, Until::Ramp, spec.timeout, Some(begun)).await?;
        let reached = self.check_reached(a, spec.target.value(), tolerance.value(), state, motion_seen).await?;
        let (start, reached) = (start.in_unit_of(kind), reached.in_unit_of(kind));
        let target = spec.target.in_unit_of(kind);
        Ok(MoveReport { kind, target, start, reached, state, verified: not_verifiable.is_empty(), not_verifiable })
    }

    /// Before a ramp that runs with module `a`'s own TargetVel or TargetAcc (`param`, not written): refused
    /// when its Inc twin, found to mirror it on this module, reads 0 (a ramp with it would not move). The
    /// float cannot be read (it is write-only): only a twin found to mirror it shows it, and a module known to
    /// keep them apart shows nothing (no check); a twin not found out yet that reads 0 is a warning.
    pub(super) async fn own_ramp_value_usable(&self, a: u8, param: Param) -> Result<(), Error> {
        let known = self.twin_known(a, param);
        if known == Some(false) {
            return Ok(());
        }
        let twin = param.read_back_as().unwrap_or(param);
        if self.get(a, twin).await?.as_f64() != Some(0.0) {
            return Ok(());
        }
        if known == Some(true) {
            return Err(Error::InvalidArgument {
                what: if param == Param::TargetVel { "the velocity" } else { "the acceleration" },
                must: "given: the module's own value (its Inc twin, found to mirror it) is 0, and a ramp with it \
                       would not move",
                value: "none".into(),
            });
        }
        // Not found out on this module (no write has shown it yet): a 0 here may be a twin kept apart. The ramp
        // runs with the module's own value; a 0 there ends it unmoved (or at the timeout, halted), which the
        // final position check reports.
        tracing::warn!(
            "module {a}: {twin} reads 0, but whether it shows the module's own {param} is not known on this \
             module: the ramp runs with the module's own {param} unchecked (give a value to set it)"
        );
        Ok(())
    }

    /// Before a ramp command to `target` (in the module's unit, `ratio` its IncRatio) whose target is to be
    /// read back through TargetPosInc: whether TargetPosInc follows the target on module `a`, found out the
    /// first time by writing TargetPos as the target, which the motion command sets anyway (see `twins`).
    /// `None`: not established (TargetPosInc held the target already).
    pub(super) async fn prepare_target_read_back(&self, a: u8, target: f32, ratio: f64) -> Result<Option<bool>, Error> {
        if self.twin_known(a, Param::TargetPos).is_none() {
            self.write_twinned(a, Param::TargetPos, Value::F32(target), ratio).await?;
        }
        Ok(self.twin_known(a, Param::TargetPos))
    }

    /// Right after a ramp command whose target was `sent` ticks: the module's target read back from
    /// TargetPosInc (what `known` says of it, see [`Ctx::prepare_target_read_back`]). A difference of more
    /// than one tick is a corrupted command: the module is halted ([`Error::TargetMismatch`]). What could
    /// not be checked (a module that keeps TargetPosInc apart; a TargetPosInc that held the target before)
    /// is returned, in plain words. A failing read halts the motion ([`Ctx::lost`]).
    pub(super) async fn check_target_taken(
        &self,
        a: u8,
        sent: i32,
        known: Option<bool>,
    ) -> Result<Option<String>, Error> {
        if known == Some(false) {
            return Ok(Some(twins::kept_apart(Param::TargetPos)));
        }
        let taken = match self.get_as(a, Param::TargetPosInc, Value::as_i32).await {
            Ok(taken) => taken,
            Err(e) => return Err(self.lost(a, e).await),
        };
        // Not known (TargetPosInc held the target already): a TargetPosInc that changed to another target
        // mirrors all the same, and that is a discrepancy too.
        if (i64::from(taken) - i64::from(sent)).abs() <= 1 {
            return Ok(known.is_none().then(|| twins::undecided(Param::TargetPos)));
        }
        if known.is_none() {
            self.remember_twin(a, Param::TargetPos, true);
        }
        let stop = self.stop_motion(a).await;
        Err(Error::TargetMismatch { address: crate::model::Address::checked(a), sent, taken, stop })
    }

    /// After the end of a motion to `target` (the module's unit) was seen (`state`, and whether STATE_MOTION
    /// was seen during the wait): the position of module `a`, read twice, both within `tolerance` of the
    /// target. A module that does not stand there is [`Error::NotReached`]; one never seen moving may start
    /// yet, so it is halted ([`Error::FailedDuringMotion`]).
    pub(super) async fn check_reached(
        &self,
        a: u8,
        target: f32,
        tolerance: f32,
        state: CubeState,
        motion_seen: bool,
    ) -> Result<Position, Error> {
        let mut reached = Position::native(target);
        for _ in 0..2 {
            reached = self.position(a).await?;
            let difference = reached.value() - target;
            // A NaN reading is not within any tolerance.
            let within = difference.abs() <= tolerance;
            if !within {
                let unit = reached.unit();
                let missed = Error::NotReached {
                    address: crate::model::Address::checked(a),
                    target: Position::new(target, unit),
                    reached,
                    difference: Position::new(difference, unit),
                    tolerance: Position::new(tolerance, unit),
                    state,
                };
                if motion_seen {
                    return Err(missed);
                }
                // Never seen moving, away from its target after the start grace: it may start yet (the
                // manual does not say how soon it shows a motion), so it is halted.
                let stop = self.stop_motion(a).await;
                return Err(Error::FailedDuringMotion {
                    address: crate::model::Address::checked(a),
                    cause: Box::new(missed),
                    stop,
                });
            }
        }
        Ok(reached)
    }

    /// Whether module `a`, which does not show STATE_MOTION now, shows it (or cannot be read) before
    /// [`Config::start_grace`](crate::session::Config) has passed since this session's last motion command
    /// to it: its state is read again every poll interval until then. A module may take that long to show a
    /// motion it was sent; one whose command is older than that is at rest.
    async fn starts_within_grace(&self, a: u8, read_at: motionlink_link::Timestamp) -> bool {
        let (grace, period, sent) = {
            let core = self.core();
            (
                core.config.start_grace,
                core.config.poll_interval.max(Duration::from_millis(1)),
                core.motion_sent.get(&a).copied(),
            )
        };
        let Some(sent) = sent else { return false };
        // `read_at`: when the state without STATE_MOTION was read. Read again until a read made once the
        // grace had passed (the close may have waited for another module meanwhile) shows none either.
        let mut read_at = read_at;
        loop {
            if read_at.saturating_since(sent) >= grace {
                return false;
            }
            let now = self.now();
            if now.saturating_since(sent) < grace {
                self.sleep_until((now + period).min(sent + grace)).await;
            }
            read_at = self.now();
            match self.request(a, Request::Get(Param::CubeState)).await {
                Ok(Reply::Get(_, Value::U32(s))) if !CubeState(s).contains(StateFlag::Motion) => {}
                _ => return true,
            }
        }
    }

    /// Halts every module this session set in motion that is still moving or cannot be asked (see
    /// [`Op::HaltStarted`](crate::session::Op)), each Halt confirmed as a stop is (the state read until
    /// STATE_MOTION clears). An error if a Halt had to be broadcast (the session failed);
    /// the modules whose halt was not confirmed stay among those the session started, so that `started()`
    /// names them and the close tries again (and says so if it cannot confirm it either).
    pub async fn halt_started(&self) -> Result<(), Error> {
        let started: Vec<u8> = self.core().started.iter().copied().collect();
        self.halt_modules(started).await
    }

    /// [`Ctx::halt_started`] for module `a` alone, if the session counts it as set in motion: the end of an
    /// operation that moved `a` stops what it started, and nothing another operation moves.
    pub async fn halt_own(&self, a: u8) -> Result<(), Error> {
        if !self.core().started.contains(&a) {
            return Ok(());
        }
        self.halt_modules(vec![a]).await
    }

    /// Halts those of `modules` that still move or cannot be asked. Each module is taken off `started` on
    /// its own once seen at rest, absent or halted (and only if nothing set it in motion again while it was
    /// being looked at); the others stay.
    async fn halt_modules(&self, modules: Vec<u8>) -> Result<(), Error> {
        if modules.is_empty() {
            return Ok(());
        }
        let (known, marks): (_, Vec<u64>) = {
            let core = self.core();
            (core.known.clone(), modules.iter().map(|a| core.start_mark(*a)).collect())
        };
        // (The reads go out after this: a module's state is at least as recent.)
        let read_at = self.now();
        let states =
            self.request_many(&modules.iter().map(|a| (*a, Request::Get(Param::CubeState))).collect::<Vec<_>>()).await;
        let mut unconfirmed = Vec::new();
        let mut detail = String::new();
        for ((a, mark), s) in modules.iter().zip(marks).zip(states) {
            let moving = match s {
                Ok(Reply::Get(_, Value::U32(s))) => {
                    CubeState(s).contains(StateFlag::Motion) || self.starts_within_grace(*a, read_at).await
                }
                Ok(_) => true,
                // Never answered this session and silent now: nobody is there.
                Err(Error::Timeout { .. }) if !known.contains(a) => {
                    tracing::debug!("module {a} never answered this session: taken as absent");
                    false
                }
                // A module that answered before and not now cannot be halted by address: broadcast below.
                Err(e @ Error::Timeout { .. }) => {
                    unconfirmed.push(*a);
                    detail = e.to_string();
                    continue;
                }
                Err(_) => true,
            };
            if !moving {
                self.core().seen_stopped(*a, mark);
                continue;
            }
            // Confirmed as every stop is: the Halt acknowledged, then the state until STATE_MOTION clears.
            tracing::warn!("halting module {a}, set in motion by this session");
            match self.stop_motion(*a).await {
                StopOutcome::Unconfirmed { reason, .. } => {
                    unconfirmed.push(*a);
                    detail = reason;
                }
                _ => {
                    // Halted: a motion command sent to it since is ignored until a reset.
                    self.core().started.remove(a);
                }
            }
        }
        if unconfirmed.is_empty() {
            return Ok(());
        }
        let port = self.core().port.clone();
        tracing::warn!("{port}: a module this session started cannot be asked; halting every module");
        let watchdog_armed = unconfirmed.iter().any(|a| self.watchdog_armed(*a));
        self.core().failed = true;
        if let Err(e) = self.broadcast(Broadcast::Halt).await {
            tracing::warn!("the halt broadcast could not be sent either: {e}");
        }
        // The modules whose halt was not confirmed stay (the broadcast on CAN took every module off).
        self.core().started.extend(unconfirmed.iter().copied());
        Err(Error::StopUnconfirmed { addresses: checked(unconfirmed), detail, watchdog_armed })
    }
}

/// In the middle of a motion, a wait reads the full state word at least this often (see
/// [`Ctx::poll_state`]); the polls between read only ActFPosStateDio.
pub(super) const FULL_STATE_EVERY: Duration = Duration::from_millis(100);

/// What the polls of one wait remember.
#[derive(Default)]
pub(super) struct Poll {
    /// When the last poll that read CubeState was, its short state and the full state word.
    last: Option<(motionlink_link::Timestamp, ShortState, CubeState)>,
    /// The module refused ActFPosStateDio: CubeState and ActPos are read instead.
    separate: bool,
}

impl ExtAck {
    /// The acknowledge with its float position in the unit of `kind`, if known.
    #[must_use]
    pub fn resolved(self, kind: Option<crate::model::ModuleKind>) -> ExtAck {
        let position = match self.position {
            crate::wire::AckPosition::Unit(p) => crate::wire::AckPosition::Unit(p.resolved(kind)),
            other => other,
        };
        ExtAck { position, ..self }
    }
}

/// The next poll of a wait on its fixed schedule from the first one (`due`, moved on from the slot just
/// polled, at `now`): never faster than `period`, whatever the line; a poll that took longer than a period
/// skips the slots it missed.
pub(super) fn next_slot(due: &mut motionlink_link::Timestamp, now: motionlink_link::Timestamp, period: Duration) {
    *due += period;
    if *due <= now {
        let missed = (now - *due).as_nanos() / period.as_nanos().max(1) + 1;
        *due += period * u32::try_from(missed).unwrap_or(u32::MAX);
    }
}

/// The quantities of `motion` whose unit is checked against the module's kind, each named.
pub(super) fn motion_units(motion: Motion) -> Vec<(&'static str, Quantity)> {
    match motion {
        Motion::FRamp { pos } | Motion::FRampLoop { pos } | Motion::FStep { pos, .. } => {
            vec![("the target position", Quantity::Position(pos))]
        }
        Motion::FCosLoop { pos, .. } => vec![("the loop's far end", Quantity::Position(pos))],
        Motion::FVel { vel } => vec![("the velocity", Quantity::Velocity(vel))],
        _ => Vec::new(),
    }
}
