//! Streamed setpoints ([`Op::Setpoint`](crate::session::Op::Setpoint)): a motion command sent once per
//! cycle of a control loop, checked as a motion run to its end is checked, with what the checks read
//! cached per module (`SetpointCache`), so that after the first call
//! each call is the command and its acknowledge.

use crate::error::{Error, StopOutcome};
use crate::model::{AckKind, Address, Motion, ShortFlag, StateFlag};
use crate::session::ctx::Ctx;
use crate::session::ops::modes::Limits;
use crate::session::ops::motion::{motion_units, FULL_STATE_EVERY};
use crate::session::{Guard, MotionSpec, SetpointReport};
use crate::wire::{ModelError, Request};

impl Ctx {
    /// One setpoint of module `a` (see [`Op::Setpoint`](crate::session::Op::Setpoint)). Whatever error
    /// ends it drops the module's setpoint cache: the next call checks everything again.
    pub(crate) async fn setpoint(
        &self,
        a: u8,
        motion: Motion,
        ack: AckKind,
        guard: Guard,
    ) -> Result<SetpointReport, Error> {
        let result = self.setpoint_cached(a, motion, ack, guard).await;
        if let Err(e) = &result {
            tracing::debug!("module {a}: setpoint failed: {e}");
            self.core().drop_setpoints(a);
        }
        result
    }

    /// [`Ctx::setpoint`], before its error drops the cache.
    async fn setpoint_cached(
        &self,
        a: u8,
        motion: Motion,
        ack: AckKind,
        guard: Guard,
    ) -> Result<SetpointReport, Error> {
        let address = Address::checked(a);
        // The spec's own rules (finite numbers, ICUR's digits, a time above 0, no `_ACK` loop), not copied.
        MotionSpec { ack, ..MotionSpec::new(motion) }.validate()?;
        let request = Request::motion(motion, ack)?;
        let mode = motion.id(ack).ok_or(ModelError::NoExtendedAck(motion.mode().name()))?;
        self.check_units(a, &motion_units(motion)).await?;
        let kind = self.kind(a).await?;
        let (generation, ready) = {
            let mut core = self.core();
            let cache = core.setpoint_cache(a);
            (cache.generation, cache.ready)
        };
        // Before anything changes the module, as a motion run to its end: the limits (read the first time).
        self.check_limits(a, motion, Limits::Cached(generation)).await?;
        if !ready {
            let state = self.ready_for_motion(a).await?;
            self.config_allows_motion(a, state).await?;
            let now = self.now();
            if let Some(cache) = self.core().setpoints_of(a, generation) {
                cache.not_homed_at = (!state.contains(StateFlag::HomeOk)).then_some(now);
            }
            if guard == Guard::Watchdog {
                self.arm_for_setpoints(a).await?;
            }
        }
        if self.cancelled() {
            // Nothing sent by this call; a module an earlier command of this session set moving is stopped,
            // as the cancel of a motion is.
            let started = self.core().started.contains(&a);
            let stop = if started { self.stop_motion(a).await } else { StopOutcome::NotStarted };
            return Err(Error::Cancelled { address, stop });
        }
        let reply = self.request(a, request).await;
        self.halt_if_cancelled(a, &request).await?;
        let reply = match reply {
            Ok(reply) => reply,
            // It may have arrived and set the module in motion.
            Err(e) => return Err(self.lost(a, e).await),
        };
        let ext_ack = match self.ext_ack_of(a, ack, &request, reply) {
            Ok(ext) => ext,
            Err(e) => return Err(self.lost(a, e).await),
        };
        if let Some(ext) = ext_ack {
            if let Some(cache) = self.core().setpoints_of(a, generation) {
                cache.last_position = Some(ext.position);
            }
            if ext.state.contains(ShortFlag::NotOk) {
                self.not_ok(a, generation).await?;
            }
        }
        if let Some(cache) = self.core().setpoints_of(a, generation) {
            cache.ready = true;
        }
        Ok(SetpointReport { kind, mode, ext_ack, watchdog: self.watchdog_armed(a) })
    }

    /// After an extended acknowledge of module `a` with SHORT_NOT_OK, "(STATE_ERROR) OR (NOT STATE_HOME_OK)
    /// OR (STATE_HALTED)" (manual 4.5.1): the state word read, unless it showed the module merely not homed
    /// less than `FULL_STATE_EVERY` ago. An error flag is [`Error::Device`], STATE_HALTED [`Error::Halted`]
    /// (a module that still shows STATE_MOTION then is halted: [`Error::FailedDuringMotion`]); not homed is
    /// remembered, and the stream goes on. A read that fails while the module may move halts it.
    async fn not_ok(&self, a: u8, generation: u64) -> Result<(), Error> {
        let now = self.now();
        let not_homed_lately = self
            .core()
            .setpoints_of(a, generation)
            .and_then(|c| c.not_homed_at)
            .is_some_and(|at| now.saturating_since(at) < FULL_STATE_EVERY);
        if not_homed_lately {
            return Ok(());
        }
        let state = match self.state(a).await {
            Ok(state) => state,
            Err(e) => return Err(self.lost(a, e).await),
        };
        let address = Address::checked(a);
        let e = if state.has_fault() {
            Error::Device { address, state }
        } else if state.contains(StateFlag::Halted) {
            Error::Halted { address, state }
        } else {
            if let Some(cache) = self.core().setpoints_of(a, generation) {
                cache.not_homed_at = (!state.contains(StateFlag::HomeOk)).then_some(now);
            }
            return Ok(());
        };
        if state.contains(StateFlag::Motion) {
            let stop = self.stop_motion(a).await;
            return Err(Error::FailedDuringMotion { address, cause: Box::new(e), stop });
        }
        // At rest by its own doing: nothing left for the close to stop.
        self.core().started.remove(&a);
        Err(e)
    }

    /// The first setpoint of module `a` under [`Guard::Watchdog`]: its watchdog switched on where the link
    /// allows it (as a guarded motion decides), held as [`Op::EnableWatchdog`](crate::session::Op) holds it
    /// (refreshed after the call, until `disable_watchdog` or the close). A link that cannot serve it is
    /// not an error: the report says `watchdog: false`.
    async fn arm_for_setpoints(&self, a: u8) -> Result<(), Error> {
        let reliable = self.watchdog_reliable();
        if !reliable || self.ignores_rs232_broadcast(a) {
            let why = if reliable {
                "it ignores the watchdog refresh broadcast on RS232"
            } else {
                "this session's settings refuse the watchdog on RS232 (Config::watchdog_on_rs232)"
            };
            self.core().warn_once(a, "setpoint_watchdog", || {
                format!("module {a}: its setpoints run without a watchdog: {why}")
            });
            return Ok(());
        }
        let cannot_arm = |e: Error| Error::Context {
            context: format!("cannot arm the watchdog of module {a} for its setpoints"),
            source: Box::new(e),
            hint: "",
        };
        self.enable_watchdog_held(&[a]).await.map_err(cannot_arm)?;
        match self.probe_broadcast_refresh(a).await {
            Ok(None) => {
                tracing::info!("watchdog armed in module {a} for its setpoints");
                Ok(())
            }
            Ok(Some(note)) => {
                // Switched off again (and the module reset): not the caller's to keep.
                self.core().duty.by_user.remove(&a);
                tracing::info!("module {a}: {note}");
                Ok(())
            }
            Err(e) => Err(cannot_arm(e)),
        }
    }
}
