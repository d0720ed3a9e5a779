//! The module watchdog (chapter 13): switching it on with a life sign in the modules a session moves,
//! serving it (the refresh is the engine's: see [`Core::poll_transmit`](crate::session)), switching it off
//! again and restoring the Config word, finding out the state of a watchdog whose toggle was not
//! confirmed, and releasing one a dead host left expired.

use crate::error::Error;
use crate::model::{ConfigFlag, ConfigWord, CubeState, Param, StateFlag, Value, WATCHDOG_TIMEOUT};
use crate::session::ctx::Ctx;
use crate::wire::{Action, Request};

/// How long after a Reset its module may still show STATE_ERROR before the Reset counts as not having cleared
/// it (the state is read again in the meantime).
pub(crate) const RESET_SETTLE: std::time::Duration = std::time::Duration::from_millis(100);

impl Ctx {
    /// True when this session can arm the watchdog: on CAN, and on RS232 unless
    /// [`Config::watchdog_on_rs232`](crate::session::Config::watchdog_on_rs232) is false.
    pub fn watchdog_reliable(&self) -> bool {
        let core = self.core();
        core.can || core.config.watchdog_on_rs232
    }

    /// True if this session switched the watchdog of `address` on (or may have) and still refreshes it.
    pub fn watchdog_armed(&self, address: u8) -> bool {
        let core = self.core();
        let duty = &core.duty;
        duty.serving && (duty.online.contains(&address) || duty.uncertain.contains(&address))
    }

    /// Stops refreshing and marks the session failed; true if any watchdog was (or may have been) online.
    pub fn abandon_watchdog(&self) -> bool {
        super::abandon_watchdog(&mut self.core())
    }

    /// Switches the watchdog on in `addresses` (see [`Op::EnableWatchdog`](crate::session::Op)).
    pub async fn enable_watchdog(&self, addresses: &[u8]) -> Result<(), Error> {
        let (can, on_rs232, failed) = {
            let core = self.core();
            (core.can, core.config.watchdog_on_rs232, core.failed)
        };
        if !can && !on_rs232 {
            return Err(Error::NotSupported(
                "the watchdog on RS232 is switched off in this session's settings (Config::watchdog_on_rs232)".into(),
            ));
        }
        if failed {
            return Err(Error::NotSupported(
                "this session has failed (its line broke or a stop was not confirmed): it cannot serve a watchdog"
                    .into(),
            ));
        }
        let mut words = Vec::with_capacity(addresses.len());
        for &a in addresses {
            if !crate::wire::is_module_address(a) {
                return Err(Error::InvalidAddress(a));
            }
            let state = self.state(a).await?;
            self.core().duty.state_before.insert(a, state);
            if state.contains(StateFlag::CommError) && !self.core().duty.online.contains(&a) {
                return Err(Error::Device { address: crate::model::Address::checked(a), state });
            }
            words.push((a, self.config_word(a).await?));
        }
        for (a, config) in words {
            if !config.contains(ConfigFlag::WatchdogEnable) {
                // Remembered before the write: a write that fails may still have arrived.
                self.core().duty.config_before.entry(a).or_insert(config);
                // Read back: a Config word corrupted on the way (the modules ignore the BCC) is not used.
                self.set_checked(a, Param::Config, Value::U32(config.with(ConfigFlag::WatchdogEnable).0)).await?;
            }
        }
        {
            let mut core = self.core();
            let now = core.now;
            if !core.duty.serving {
                core.duty.start_serving(now);
            }
        }
        let mut first_error = None;
        for &a in addresses {
            {
                let core = self.core();
                if core.duty.online.contains(&a) {
                    continue;
                }
                if core.duty.uncertain.contains(&a) {
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: crate::model::Address::checked(a),
                        on: true,
                        detail: "an earlier life sign was not acknowledged; not toggled again (disable_watchdog \
                                 finds out its state)"
                            .into(),
                    });
                    continue;
                }
            }
            // The acknowledge of the life sign is the only confirmation the manual offers that the toggle
            // arrived (no state flag shows an online watchdog). Silence leaves the watchdog in an unknown
            // state: it is served (refreshed) as if online, reported, and never toggled again blindly.
            match self.request(a, Request::Action(Action::LifeSign)).await {
                Ok(_) => {
                    tracing::debug!("module {a}: watchdog online");
                    self.core().duty.online.insert(a);
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. })) => {
                    tracing::info!("module {a}: life sign not acknowledged ({e}); its watchdog state is unknown");
                    self.core().duty.uncertain.insert(a);
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: crate::model::Address::checked(a),
                        on: true,
                        detail: format!("the life sign was not acknowledged ({e}); not sent again"),
                    });
                }
                Err(e) => return Err(e),
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Undoes [`Ctx::enable_watchdog`] (see [`Op::DisableWatchdog`](crate::session::Op)).
    pub async fn disable_watchdog(&self) -> Result<(), Error> {
        if self.core().failed {
            // A failed session may have left something moving that it could not stop: the watchdog is what
            // stops it now. It is not switched off.
            let left: Vec<u8> = {
                let mut core = self.core();
                let left = core.duty.online.iter().chain(core.duty.uncertain.iter()).copied().collect();
                super::abandon_watchdog(&mut core);
                left
            };
            if left.is_empty() {
                return Ok(());
            }
            return Err(Error::WatchdogLeftOnline {
                addresses: crate::session::ops::checked(left),
                detail: "the session failed (its line broke, or a stop it sent was not confirmed)".into(),
            });
        }
        let mut first_error = None;
        let online: Vec<u8> = self.core().duty.online.iter().copied().collect();
        for a in online {
            match self.request(a, Request::Action(Action::LifeSign)).await {
                Ok(_) => {
                    tracing::debug!("module {a}: watchdog offline");
                    self.core().duty.online.remove(&a);
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. })) => {
                    // It may or may not have arrived: a second life sign could switch the watchdog on again.
                    tracing::warn!("module {a}: life sign not acknowledged ({e}); its watchdog state is unknown");
                    let mut core = self.core();
                    core.duty.online.remove(&a);
                    core.duty.uncertain.insert(a);
                }
                Err(e) => {
                    tracing::info!("module {a}: cannot switch the watchdog off: {e}");
                    first_error.get_or_insert(e);
                }
            }
        }
        self.core().duty.serving = false;
        if let Err(e) = self.observe_uncertain_watchdogs().await {
            first_error.get_or_insert(e);
        }
        let restore: Vec<(u8, ConfigWord)> = {
            let core = self.core();
            let duty = &core.duty;
            duty.config_before
                .iter()
                .filter(|(a, _)| !duty.online.contains(a) && !duty.uncertain.contains(a))
                .map(|(a, w)| (*a, *w))
                .collect()
        };
        for (a, before) in restore {
            match self.restore_watchdog_flag(a, before).await {
                Ok(()) => {
                    self.core().duty.config_before.remove(&a);
                }
                Err(e) => {
                    tracing::info!("module {a}: cannot restore the Config word {:#010x}: {e}", before.0);
                    first_error.get_or_insert(e);
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// With the refresh stopped, finds out whether the modules whose life sign was not confirmed have their
    /// watchdog online, the only way the manual offers to observe it: an online watchdog that is not
    /// refreshed expires (STATE_COMM_ERROR, STATE_HALTED) within [`WATCHDOG_TIMEOUT`]. Waits twice that on
    /// the session's time, then reads each one's state.
    async fn observe_uncertain_watchdogs(&self) -> Result<(), Error> {
        let uncertain: Vec<u8> = self.core().duty.uncertain.iter().copied().collect();
        if uncertain.is_empty() {
            return Ok(());
        }
        let until = self.now() + WATCHDOG_TIMEOUT * 2;
        self.sleep_until(until).await;
        let mut first_error = None;
        for a in uncertain {
            match self.state(a).await {
                Ok(state) if !state.contains(StateFlag::CommError) => {
                    tracing::debug!("module {a}: watchdog seen offline");
                    self.core().duty.uncertain.remove(&a);
                }
                Ok(state) => {
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: crate::model::Address::checked(a),
                        on: false,
                        detail: format!(
                            "its watchdog was still online and has expired ({state}); the module is halted, `reset` \
                             clears it"
                        ),
                    });
                }
                Err(e) => {
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: crate::model::Address::checked(a),
                        on: false,
                        detail: format!("its state cannot be read to check: {e}"),
                    });
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// After an arming of module `a` that failed, with [`Ctx::disable_watchdog`] run: what more can be
    /// undone, and what the module is left in, in words for the refusal (`None`: the arming failed before
    /// anything was left to undo, or it was all undone by `disable_watchdog`, said as such).
    ///
    /// A module whose life sign was not acknowledged stays uncertain when `disable_watchdog`, having
    /// stopped the refresh, saw its watchdog expire (STATE_COMM_ERROR, STATE_HALTED): the life sign had
    /// arrived, so the watchdog is known to be online. Chapter 13's first way to restart then applies: a
    /// life sign (to a watchdog known online, it switches it offline) and a Reset; twice the watchdog's time
    /// later the state shows whether it expired again (the life sign lost: left as it is, said so). Not on a
    /// module that was halted or in error before the arming: the Reset would clear a latch set before (a
    /// `stop`'s Halt), which only a `reset` asked for may clear.
    pub(crate) async fn release_failed_arming(&self, a: u8) -> Option<String> {
        let (uncertain, online, config_changed, before) = {
            let core = self.core();
            let d = &core.duty;
            (
                d.uncertain.contains(&a),
                d.online.contains(&a),
                d.config_before.contains_key(&a),
                d.state_before.get(&a).copied(),
            )
        };
        if online {
            return Some(format!("its watchdog could not be switched off again: module {a} halts itself within 50 ms (STATE_COMM_ERROR; `reset` clears it)"));
        }
        if !uncertain {
            // Not left online (switched off, or never switched on: the arming may have failed before its life
            // sign), Config word restored if it was changed.
            return Some(if config_changed {
                format!(
                    "its Config word could not be restored: CONFIGID_MOD_WATCHDOG_ENABLE may be left set in module {a}"
                )
            } else {
                format!(
                    "its watchdog is not left online and its Config word is as it was: module {a} is left as it was"
                )
            })
            .filter(|_| before.is_some());
        }
        let left = |state: crate::model::CubeState, why: &str| {
            format!(
                "its watchdog had gone online all the same and, no longer refreshed, expired{why}: module {a} is left \
                 halted with STATE_COMM_ERROR (state: {state}; `reset` clears it)"
            )
        };
        let state = match self.state(a).await {
            Ok(state) => state,
            Err(e) => {
                return Some(format!(
                "its watchdog may have gone online and, no longer refreshed, expired, but module {a}'s state cannot \
                     be read to see ({e}); if it did, the module is halted with STATE_COMM_ERROR (`reset` clears it)"
            ))
            }
        };
        if !state.contains(StateFlag::CommError) {
            // Readable now, and not expired: the watchdog is offline.
            self.core().duty.uncertain.remove(&a);
            return self.restore_after_arming(a, format!("its watchdog is offline (state: {state})")).await;
        }
        if before.is_none_or(|b| b.contains(StateFlag::Halted) || b.has_fault()) {
            return Some(left(state, " (the module was halted or in error before, so it was not reset here)"));
        }
        tracing::info!(
            "module {a}: its watchdog expired after an unacknowledged life sign: switching it offline and resetting"
        );
        match self.request(a, Request::Action(Action::LifeSign)).await {
            Ok(_) | Err(Error::Timeout { .. } | Error::Corrupt { .. }) => {}
            Err(e) => return Some(left(state, &format!(" (switching it offline failed: {e})"))),
        }
        if let Err(e) = self.action(a, Action::Reset).await {
            return Some(left(state, &format!(" (switched offline, but the Reset failed: {e})")));
        }
        let until = self.now() + WATCHDOG_TIMEOUT * 2;
        self.sleep_until(until).await;
        match self.state(a).await {
            Ok(after) if !after.contains(StateFlag::CommError) => {
                self.core().duty.uncertain.remove(&a);
                let what = format!(
                    "its watchdog had gone online all the same and, no longer refreshed, expired; it was switched \
                     offline and the module reset (the manual's restart, chapter 13), and {} ms later it showed no \
                     expiry (state: {after})",
                    (WATCHDOG_TIMEOUT * 2).as_millis()
                );
                self.restore_after_arming(a, what).await
            }
            Ok(after) => Some(left(after, ", and it expired again after a life sign and a Reset")),
            Err(e) => {
                Some(left(state, &format!(" (switched offline and reset, but the state cannot be read to see: {e})")))
            }
        }
    }

    /// The Config word of module `a` as it was before an arming that failed, `what` said first.
    async fn restore_after_arming(&self, a: u8, what: String) -> Option<String> {
        let before = self.core().duty.config_before.get(&a).copied();
        let Some(before) = before else {
            return Some(format!("{what}: module {a} is left as it was"));
        };
        match self.restore_watchdog_flag(a, before).await {
            Ok(()) => {
                self.core().duty.config_before.remove(&a);
                Some(format!("{what}, and its Config word was restored: module {a} is left as it was"))
            }
            Err(e) => Some(format!(
                "{what}, but its Config word could not be restored ({e}): CONFIGID_MOD_WATCHDOG_ENABLE may be left set"
            )),
        }
    }

    /// Gives CONFIGID_MOD_WATCHDOG_ENABLE of module `a` back the value it had in `before`, every other bit
    /// as it is now.
    async fn restore_watchdog_flag(&self, a: u8, before: ConfigWord) -> Result<(), Error> {
        let now = self.config_word(a).await?;
        let mut word = now;
        word.set(ConfigFlag::WatchdogEnable, before.contains(ConfigFlag::WatchdogEnable));
        if word != before {
            tracing::debug!(
                "module {a}: Config word {:#010x} was {:#010x} before; only the watchdog flag is restored",
                word.0,
                before.0
            );
        }
        if word != now {
            self.set_checked(a, Param::Config, Value::U32(word.0)).await?;
        }
        Ok(())
    }

    /// A Reset of module `a` (the plain one, or [`Ctx::reset_and_release_watchdog`]'s) is refused while this
    /// session serves its watchdog: the manual does not say what a Reset does to an online watchdog, and on a
    /// module whose Reset switches it offline the motion it guards would run unguarded.
    pub(crate) fn refuse_reset_while_served(&self, a: u8) -> Result<(), Error> {
        if self.core().duty.online.contains(&a) {
            return Err(Error::NotSupported(format!(
                "module {a}'s watchdog is armed by this session (for a guarded motion, or by enable_watchdog): a \
                 Reset may switch it offline on some modules, leaving the motion unguarded; reset the module once \
                 the watchdog is switched off again (the motion ended or stopped)"
            )));
        }
        Ok(())
    }

    /// Reset, and the manual's first way to restart after a watchdog expiry (see
    /// [`Op::ResetAndReleaseWatchdog`](crate::session::Op)). True if it switched the watchdog offline.
    ///
    /// Refused, before anything is sent, for a module whose watchdog this session serves: the manual does
    /// not say what a Reset does to an online watchdog, and a module whose Reset switches it offline would
    /// leave the motion it guards unguarded, and have it switched on again by the session's second life sign.
    ///
    /// A watchdog switched offline is seen so: the state read once more twice [`WATCHDOG_TIMEOUT`] after the
    /// last Reset shows no STATE_COMM_ERROR (one still online, its life sign lost, has expired again by then:
    /// an error saying so).
    ///
    /// The state is read after the Reset: STATE_ERROR still set [`RESET_SETTLE`] after it is an error naming
    /// the flags the Reset left (a servo amplifier fault, STATE_POWERFAULT, needs the module switched off in
    /// most cases: manual 5).
    pub async fn reset_and_release_watchdog(&self, a: u8) -> Result<bool, Error> {
        self.refuse_reset_while_served(a)?;
        let before = self.state(a).await?;
        self.action(a, Action::Reset).await?;
        if !before.contains(StateFlag::CommError) {
            return self.reset_cleared(a, self.state(a).await?).await.map(|()| false);
        }
        let until = self.now() + WATCHDOG_TIMEOUT * 2;
        self.sleep_until(until).await;
        let after = self.state(a).await?;
        if !after.contains(StateFlag::CommError) {
            return self.reset_cleared(a, after).await.map(|()| false);
        }
        tracing::info!("module {a}: its watchdog expires again after a reset; switching it offline");
        let acknowledged = match self.request(a, Request::Action(Action::LifeSign)).await {
            Ok(_) => true,
            Err(Error::Timeout { .. }) => false,
            Err(e) => return Err(e),
        };
        self.core().duty.uncertain.remove(&a);
        self.action(a, Action::Reset).await?;
        self.reset_cleared(a, self.state(a).await?).await?;
        // Offline, the watchdog expires no more: seen only once it would have expired again.
        let until = self.now() + WATCHDOG_TIMEOUT * 2;
        self.sleep_until(until).await;
        let after = self.state(a).await?;
        if after.contains(StateFlag::CommError) {
            let address = crate::model::Address::checked(a);
            let heard = if acknowledged { "acknowledged" } else { "not acknowledged" };
            return Err(Error::Context {
                context: format!(
                    "module {a}'s watchdog expired again after the life sign that switches it offline ({heard}) \
                     and a Reset: it is still online, and the module halted"
                ),
                source: Box::new(Error::Device { address, state: after }),
                hint: "; reset it again (`motionlink powercube --module N reset`), or switch the module off and on",
            });
        }
        Ok(true)
    }

    /// The state `after` a Reset of module `a`, read again until STATE_ERROR is clear for at most
    /// [`RESET_SETTLE`] (the manual does not say how soon a Reset takes effect): an error if it is still set.
    async fn reset_cleared(&self, a: u8, mut after: CubeState) -> Result<(), Error> {
        let until = self.now() + RESET_SETTLE;
        let period = self.core().config.poll_interval.max(std::time::Duration::from_micros(100));
        while after.contains(StateFlag::Error) && self.now() < until {
            let next = self.now() + period;
            self.sleep_until(next).await;
            after = self.state(a).await?;
        }
        if !after.contains(StateFlag::Error) {
            return Ok(());
        }
        let hint = if after.contains(StateFlag::PowerFault) {
            "; a fault of the servo amplifier (STATE_POWERFAULT) is cleared in most cases only by switching the \
             module off (STATE_POW_VOLT_ERR: once the supply voltage is back)"
        } else {
            ""
        };
        let address = crate::model::Address::checked(a);
        let source = Box::new(Error::Device { address, state: after });
        Err(Error::Context { context: format!("the Reset of module {a} left STATE_ERROR set"), source, hint })
    }
}
