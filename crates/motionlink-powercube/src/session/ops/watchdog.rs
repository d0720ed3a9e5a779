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
        core.duty.serving && core.duty.may_be_online(address)
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
        let mut first_error = None;
        for &a in addresses {
            if !self.claim_toggle_on(a, &mut first_error).await? {
                continue;
            }
            // The acknowledge of the life sign is the only confirmation the manual offers that the toggle
            // arrived (no state flag shows an online watchdog). Silence leaves the watchdog in an unknown
            // state: it is served (refreshed) as if online, reported, and never toggled again blindly.
            let sent = self.request(a, Request::Action(Action::LifeSign)).await;
            let mut core = self.core();
            core.duty.toggling.remove(&a);
            match sent {
                Ok(_) => {
                    tracing::debug!("module {a}: watchdog online");
                    core.duty.online.insert(a);
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. })) => {
                    tracing::info!("module {a}: life sign not acknowledged ({e}); its watchdog state is unknown");
                    core.duty.uncertain.insert(a);
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

    /// Before the life sign that switches the watchdog of `a` on: claims the toggle (no other operation sends
    /// one meanwhile; one under way is waited for) and makes sure the refresh is served. False when no life
    /// sign is due: the watchdog is online already, or its state is unknown (said in `first_error`: never
    /// toggled again blindly).
    async fn claim_toggle_on(&self, a: u8, first_error: &mut Option<Error>) -> Result<bool, Error> {
        loop {
            let period = {
                let mut core = self.core();
                if core.failed {
                    return Err(Error::NotSupported(
                        "this session has failed (its line broke or a stop was not confirmed): it cannot serve a \
                         watchdog"
                            .into(),
                    ));
                }
                let now = core.now;
                let duty = &mut core.duty;
                if !duty.toggling.contains(&a) {
                    if duty.online.contains(&a) {
                        return Ok(false);
                    }
                    if duty.uncertain.contains(&a) {
                        first_error.get_or_insert(Error::WatchdogUnconfirmed {
                            address: crate::model::Address::checked(a),
                            on: true,
                            detail: "an earlier life sign was not acknowledged; not toggled again (disable_watchdog \
                                     finds out its state)"
                                .into(),
                        });
                        return Ok(false);
                    }
                    // Served from before the life sign on: an online watchdog never waits for its refresh.
                    if !duty.serving {
                        duty.start_serving(now);
                    }
                    duty.toggling.insert(a);
                    return Ok(true);
                }
                core.config.poll_interval.max(std::time::Duration::from_millis(1))
            };
            // Another operation of this session is toggling it: its outcome decides.
            let next = self.now() + period;
            self.sleep_until(next).await;
        }
    }

    /// Switches the watchdog on in `addresses` for the caller of [`Op::EnableWatchdog`](crate::session::Op):
    /// they stay armed until [`Ctx::disable_watchdog`] or the close, whatever guarded motion of theirs ends.
    pub async fn enable_watchdog_held(&self, addresses: &[u8]) -> Result<(), Error> {
        // Marked before the first await: a guarded motion of one of them that ends meanwhile leaves it on.
        self.core().duty.by_user.extend(addresses.iter().copied().filter(|a| crate::wire::is_module_address(*a)));
        let result = self.enable_watchdog(addresses).await;
        // Those it did not arm (refused, failed before their life sign) are not the caller's to keep.
        let mut core = self.core();
        let d = &mut core.duty;
        for a in addresses {
            if !d.may_be_online(*a) && !d.config_before.contains_key(a) {
                d.by_user.remove(a);
            }
        }
        result
    }

    /// Undoes [`Ctx::enable_watchdog`] (see [`Op::DisableWatchdog`](crate::session::Op)): every watchdog this
    /// session switched on, except those a guarded motion under way holds (its end switches them off).
    pub async fn disable_watchdog(&self) -> Result<(), Error> {
        if self.core().failed {
            // A failed session may have left something moving that it could not stop: the watchdog is what
            // stops it now. It is not switched off.
            let left: Vec<u8> = {
                let mut core = self.core();
                let left = core.duty.left_online();
                super::abandon_watchdog(&mut core);
                left
            };
            return left_online(left);
        }
        let addresses: Vec<u8> = {
            let mut core = self.core();
            let d = &mut core.duty;
            let all: std::collections::BTreeSet<u8> =
                d.online.iter().chain(&d.uncertain).chain(&d.toggling).chain(d.config_before.keys()).copied().collect();
            // A watchdog a guarded motion armed is switched off at its end; one the caller armed is theirs.
            let mine: Vec<u8> = all.into_iter().filter(|a| !d.held.contains(a) || d.by_user.contains(a)).collect();
            for a in &mine {
                d.by_user.remove(a);
            }
            mine
        };
        self.disarm(&addresses).await
    }

    /// What the end of a guarded motion of module `a` switches off: its watchdog, unless the caller of
    /// [`Op::EnableWatchdog`](crate::session::Op) armed it (it stays armed for them).
    pub(crate) async fn disarm_own(&self, a: u8) -> Result<(), Error> {
        if self.core().duty.by_user.contains(&a) {
            return Ok(());
        }
        self.disarm(&[a]).await
    }

    /// Switches the watchdog of each of `addresses` off and restores its Config word, touching no other
    /// module's: a second life sign to each that this session switched on, sent by this operation alone
    /// (claimed first: taken out of `online`, so that no other operation sends one too, which would switch
    /// it on again). The refresh stops once no module of this session needs it any more; a watchdog whose
    /// life sign was not confirmed is then observed (never toggled blindly).
    pub(crate) async fn disarm(&self, addresses: &[u8]) -> Result<(), Error> {
        if self.core().failed {
            let left: Vec<u8> = {
                let mut core = self.core();
                super::abandon_watchdog(&mut core);
                addresses.iter().copied().filter(|a| core.duty.may_be_online(*a)).collect()
            };
            return left_online(left);
        }
        let mut first_error = None;
        for &a in addresses {
            if !self.claim_toggle_off(a).await {
                continue;
            }
            let sent = self.request(a, Request::Action(Action::LifeSign)).await;
            let mut core = self.core();
            core.duty.toggling.remove(&a);
            match sent {
                Ok(_) => tracing::debug!("module {a}: watchdog offline"),
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. })) => {
                    // It may or may not have arrived: a second life sign could switch the watchdog on again.
                    tracing::warn!("module {a}: life sign not acknowledged ({e}); its watchdog state is unknown");
                    core.duty.uncertain.insert(a);
                }
                Err(e) => {
                    tracing::info!("module {a}: cannot switch the watchdog off: {e}");
                    core.duty.online.insert(a);
                    first_error.get_or_insert(e);
                }
            }
        }
        if let Err(e) = self.stop_refresh_if_unneeded(addresses).await {
            first_error.get_or_insert(e);
        }
        let restore: Vec<(u8, ConfigWord)> = {
            let core = self.core();
            let duty = &core.duty;
            addresses
                .iter()
                .filter(|a| !duty.may_be_online(**a))
                .filter_map(|a| duty.config_before.get(a).map(|w| (*a, *w)))
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

    /// Before the life sign that switches the watchdog of `a` off: claims it (out of `online`, into
    /// `toggling`), after waiting for a toggle another operation has under way. False when this session has
    /// no online watchdog of `a` to switch off (off already, switched off by another operation, or in an
    /// unknown state: never toggled blindly).
    async fn claim_toggle_off(&self, a: u8) -> bool {
        loop {
            let period = {
                let mut core = self.core();
                let duty = &mut core.duty;
                if !duty.toggling.contains(&a) {
                    if !duty.online.remove(&a) {
                        return false;
                    }
                    duty.toggling.insert(a);
                    return true;
                }
                core.config.poll_interval.max(std::time::Duration::from_millis(1))
            };
            let next = self.now() + period;
            self.sleep_until(next).await;
        }
    }

    /// After the watchdogs of `addresses` were switched off: stops the refresh if nothing else of this session
    /// needs it (no other watchdog online, being toggled, or unknown and still held by a guarded motion or the
    /// caller of [`Op::EnableWatchdog`](crate::session::Op)), then observes the unknown ones. Those of
    /// `addresses` whose state stays unknown because the refresh must go on are an error.
    async fn stop_refresh_if_unneeded(&self, addresses: &[u8]) -> Result<(), Error> {
        let (stopped, unknown) = {
            let mut core = self.core();
            let d = &mut core.duty;
            let held =
                d.uncertain.iter().any(|a| !addresses.contains(a) && (d.held.contains(a) || d.by_user.contains(a)));
            let needed = !d.online.is_empty() || !d.toggling.is_empty() || held;
            let unknown: Vec<u8> = d.uncertain.iter().copied().filter(|a| addresses.contains(a)).collect();
            if needed {
                (false, unknown)
            } else {
                d.serving = false;
                (true, d.uncertain.iter().copied().collect::<Vec<u8>>())
            }
        };
        if !stopped {
            return match unknown.first() {
                None => Ok(()),
                Some(&a) => Err(Error::WatchdogUnconfirmed {
                    address: crate::model::Address::checked(a),
                    on: false,
                    detail: "the life sign that switches it off was not acknowledged; not sent again: it is still \
                             refreshed, as other watchdogs of this session are, and its state is found out once the \
                             refresh stops (disable_watchdog, the close)"
                        .into(),
                }),
            };
        }
        // Every unknown watchdog is observed (one whose guarded motion ended while others were served too); only
        // those of `addresses` are this operation's to report, the others stay unknown for the close to say.
        let mut first_error = None;
        for (a, e) in self.observe_uncertain_watchdogs(&unknown).await {
            if addresses.contains(&a) {
                first_error.get_or_insert(e);
            } else {
                tracing::warn!("{e}");
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// With the refresh stopped, finds out whether the modules `uncertain`, whose life sign was not
    /// confirmed, have their watchdog online, the only way the manual offers to observe it: an online
    /// watchdog that is not refreshed expires (STATE_COMM_ERROR, STATE_HALTED) within [`WATCHDOG_TIMEOUT`].
    /// Waits twice that on the session's time, then reads each one's state. The modules that could not be
    /// seen offline, each with its error.
    async fn observe_uncertain_watchdogs(&self, uncertain: &[u8]) -> Vec<(u8, Error)> {
        if uncertain.is_empty() {
            return Vec::new();
        }
        let spell = self.core().duty.spell;
        let until = self.now() + WATCHDOG_TIMEOUT * 2;
        self.sleep_until(until).await;
        let restarted = {
            let core = self.core();
            core.duty.serving || core.duty.spell != spell
        };
        let mut errors = Vec::new();
        for &a in uncertain {
            let address = crate::model::Address::checked(a);
            if restarted {
                // Another operation armed a watchdog meanwhile: the refresh may have kept this one alive.
                errors.push((
                    a,
                    Error::WatchdogUnconfirmed {
                        address,
                        on: false,
                        detail: "its state could not be observed: the refresh was started again meanwhile (another \
                                 watchdog armed); it is found out once the refresh stops (disable_watchdog, the close)"
                            .into(),
                    },
                ));
                continue;
            }
            match self.state(a).await {
                Ok(state) if !state.contains(StateFlag::CommError) => {
                    tracing::debug!("module {a}: watchdog seen offline");
                    self.core().duty.uncertain.remove(&a);
                }
                Ok(state) => errors.push((
                    a,
                    Error::WatchdogUnconfirmed {
                        address,
                        on: false,
                        detail: format!(
                            "its watchdog was still online and has expired ({state}); the module is halted, `reset` \
                             clears it"
                        ),
                    },
                )),
                Err(e) => errors.push((
                    a,
                    Error::WatchdogUnconfirmed {
                        address,
                        on: false,
                        detail: format!("its state cannot be read to check: {e}"),
                    },
                )),
            }
        }
        errors
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
        if uncertain && self.core().duty.serving {
            // Other watchdogs of this session are served: the refresh keeps this one alive if it is online, so
            // its state shows nothing yet. It stays unknown (and refreshed) until the refresh stops.
            return Some(format!(
                "its watchdog may have gone online: it is refreshed while this session serves other watchdogs, and \
                 found out once the refresh stops (disable_watchdog, the close); if online then, module {a} halts \
                 with STATE_COMM_ERROR (`reset` clears it)"
            ));
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

/// What switching off leaves online in a session that failed: nothing (`Ok`), or these modules, whose
/// watchdog now halts them within 50 ms.
fn left_online(left: Vec<u8>) -> Result<(), Error> {
    if left.is_empty() {
        return Ok(());
    }
    Err(Error::WatchdogLeftOnline {
        addresses: crate::session::ops::checked(left),
        detail: "the session failed (its line broke, or a stop it sent was not confirmed)".into(),
    })
}
