//! Probes of behaviours the manual does not state, each run the first time a check depends on it and
//! remembered for the session ([`ModuleFindings`](crate::session::ModuleFindings)); the Inc twins have their
//! own module (`twins`).
//!
//! - **The RS232 broadcast refresh.** The manual lists broadcasts for CAN only; on RS232 the session sends
//!   the watchdog refresh as libm5api does (module address 0, the command followed by 0x00). Whether a module
//!   takes it shows only one way: its watchdog, once online and refreshed so, stays online past the 50 ms it
//!   waits. So the first time the session arms a module's watchdog on RS232, it waits the watchdog's
//!   timeout and two refresh periods (nothing moves: the motion has not been sent) and reads the state. No
//!   STATE_COMM_ERROR: the refresh arrives. STATE_COMM_ERROR with every refresh sent in time: the module
//!   ignores that form; the session switches its watchdog offline again (a second life sign), restores the
//!   Config word, resets the module (the manual's way to restart after an expiry), and runs the motion
//!   without a watchdog, saying so in its result. STATE_COMM_ERROR after a refresh that went out late: the
//!   host was too slow, which says nothing about the module ([`Error::WatchdogExpired`]).
//! - **ActFPosStateDio (0x62).** Waits read the position and the short state in one exchange with this
//!   parameter, which only later firmware has. Before the first motion the session reads it once; a module
//!   that does not acknowledge it (and answers CubeState) is polled with CubeState and ActPos instead.

use crate::error::Error;
use crate::model::{Param, StateFlag, WATCHDOG_TIMEOUT};
use crate::session::ctx::Ctx;
use crate::wire::Action;

/// What the motion of a guarded operation could not have, in plain words, when a module ignores the RS232
/// broadcast refresh.
pub(crate) fn no_rs232_watchdog(a: u8) -> String {
    format!(
        "module {a}'s watchdog could not be armed: it ignores the watchdog refresh broadcast on RS232 (module \
         address 0, the command followed by 0x00, as libm5api sends it; the manual defines broadcasts for CAN \
         only), so the motion ran without a watchdog"
    )
}

impl Ctx {
    /// Whether module `a` is known to ignore the RS232 broadcast refresh (on CAN: never).
    pub(crate) fn ignores_rs232_broadcast(&self, a: u8) -> bool {
        let core = self.core();
        !core.can && core.findings.get(&a).and_then(|f| f.rs232_broadcast) == Some(false)
    }

    /// True if arming the watchdog of module `a` is followed by the probe of the RS232 broadcast refresh
    /// ([`Ctx::probe_broadcast_refresh`]): on RS232, the first time.
    pub(crate) fn broadcast_probe_due(&self, a: u8) -> bool {
        let core = self.core();
        !core.can && core.findings.get(&a).and_then(|f| f.rs232_broadcast).is_none()
    }

    /// Right after the watchdog of module `a` was armed: on RS232, the first time, finds out whether the
    /// refresh reaches it (see the [module documentation](self)). `Ok(None)`: it does (or CAN, or known);
    /// `Ok(Some(note))`: it does not, and the watchdog has been switched off again and the module reset (of
    /// the STATE_COMM_ERROR the probe's life sign caused: a module halted or in error before is refused
    /// before its watchdog is armed, see `Ctx::guarded`).
    pub(crate) async fn probe_broadcast_refresh(&self, a: u8) -> Result<Option<String>, Error> {
        if !self.broadcast_probe_due(a) {
            return Ok(None);
        }
        let period = self.core().config.watchdog_period;
        let until = self.now() + WATCHDOG_TIMEOUT + period * 2;
        self.sleep_until(until).await;
        let state = self.state(a).await?;
        if !state.contains(StateFlag::CommError) {
            self.core().findings.entry(a).or_default().rs232_broadcast = Some(true);
            return Ok(None);
        }
        let timing = {
            let core = self.core();
            core.duty.timing(core.now, core.round_trips)
        };
        if let Some(timing) = timing.filter(|t| t.was_late()) {
            return Err(Error::WatchdogExpired { address: crate::model::Address::checked(a), state, timing });
        }
        {
            let mut core = self.core();
            core.findings.entry(a).or_default().rs232_broadcast = Some(false);
            core.warn_once(a, "rs232_broadcast", || {
                format!(
                    "module {a} ignores the watchdog refresh broadcast on RS232 (address 0, two data bytes): its \
                     motions run without a watchdog in this session"
                )
            });
        }
        // The manual's way to restart: the watchdog offline, then a Reset (this module's alone: the watchdogs
        // other operations armed are theirs).
        self.disarm(&[a]).await?;
        self.action(a, Action::Reset).await?;
        let after = self.state(a).await?;
        if after.has_fault() {
            return Err(Error::Device { address: crate::model::Address::checked(a), state: after });
        }
        Ok(Some(no_rs232_watchdog(a)))
    }

    /// Before the first motion of module `a`: whether it answers ActFPosStateDio (0x62). A module that gives
    /// no acknowledge for it while it answers CubeState does not know it; a refusal means the same.
    pub(crate) async fn probe_pos_state_dio(&self, a: u8) -> Result<(), Error> {
        if self.core().findings.get(&a).and_then(|f| f.pos_state_dio).is_some() {
            return Ok(());
        }
        let known = match self.get(a, Param::ActFPosStateDio).await {
            Ok(_) => true,
            Err(Error::Timeout { .. } | Error::Refused { .. }) => {
                // Silence from a module that answers otherwise is a parameter it does not know.
                self.state(a).await?;
                false
            }
            Err(e) => return Err(e),
        };
        let mut core = self.core();
        core.findings.entry(a).or_default().pos_state_dio = Some(known);
        if !known {
            core.warn_once(a, "pos_state_dio", || {
                format!(
                    "module {a} does not answer ActFPosStateDio (0x62, a later firmware's parameter): waits read \
                     CubeState and ActPos instead"
                )
            });
        }
        Ok(())
    }

    /// True when module `a` is known not to answer ActFPosStateDio.
    pub(crate) fn lacks_pos_state_dio(&self, a: u8) -> bool {
        self.core().findings.get(&a).and_then(|f| f.pos_state_dio) == Some(false)
    }
}
