//! The operations of a session, each a state machine written as an `async fn` over a [`Ctx`]: the
//! compiler turns each into an enum of its steps, which the session resumes whenever what a step waits for
//! (an exchange's answers, a broadcast sent, a time) is there: the one executor of `motionlink-link`
//! ([`motionlink_link::exec`]) runs them. No thread, no I/O.

mod basic;
mod modes;
mod motion;
mod probes;
mod run;
mod setpoint;
mod twins;
mod watchdog;

pub(crate) use run::run;

use std::collections::{BTreeMap, BTreeSet};

use crate::error::{Error, StopOutcome};
use crate::model::Param;
use crate::session::core::Core;
use crate::session::ctx::Ctx;
use crate::session::{Guard, ScanEntry};
use crate::wire::Request;
use crate::wire::MAX_ADDRESS;

/// Stops refreshing the watchdog and marks the session failed: every module whose watchdog the session
/// switched on halts itself within 50 ms of the last refresh that reached it. True if any watchdog was (or
/// may have been) online.
pub(crate) fn abandon_watchdog(core: &mut Core) -> bool {
    core.failed = true;
    let was_serving = core.duty.serving;
    core.duty.serving = false;
    if was_serving {
        tracing::warn!("watchdog refresh stopped: the modules it protects halt within 50 ms");
    }
    was_serving && !core.duty.left_online().is_empty()
}

impl Ctx {
    /// Asks addresses 1..31 for their version (see [`Op::Scan`](crate::session::Op)).
    pub async fn scan(&self) -> Result<Vec<ScanEntry>, Error> {
        let probe = Request::Get(Param::DefCubeVersion);
        let (timeout, retries, can) = {
            let core = self.core();
            (core.config.scan_timeout, core.config.read_retries, core.can)
        };
        let mut todo: Vec<u8> = (1..=MAX_ADDRESS).collect();
        let mut answered = BTreeSet::new();
        let mut broken: BTreeMap<u8, Error> = BTreeMap::new();
        for _ in 0..=retries {
            if todo.is_empty() {
                break;
            }
            let batch: Vec<(u8, Request)> = todo.iter().map(|a| (*a, probe)).collect();
            let answers = if can {
                self.exchange(batch.clone(), timeout).await
            } else {
                let mut answers = Vec::with_capacity(batch.len());
                for r in &batch {
                    answers.extend(self.exchange(vec![*r], timeout).await);
                }
                answers
            };
            todo.clear();
            for ((a, _), r) in batch.iter().zip(answers) {
                match r {
                    Ok(_) => {
                        broken.remove(a);
                        answered.insert(*a);
                    }
                    Err(e @ Error::Corrupt { .. }) => {
                        tracing::debug!("scan: {e}; asking again");
                        todo.push(*a);
                        broken.insert(*a, e);
                    }
                    // Nobody there. After a corrupt answer, silence means the garbage was not this module's
                    // (on RS232 a frame with a wrong BCC names no trustworthy address): absent, with a warning.
                    Err(Error::Timeout { .. }) => {
                        if let Some(e) = broken.remove(a) {
                            tracing::warn!("scan: address {a}: {e}, then silence when asked again: taken as absent");
                        }
                    }
                    Err(e) => return Err(e),
                }
            }
        }
        let mut entries = Vec::with_capacity(answered.len() + broken.len());
        for a in answered {
            let info = self.info(a).await;
            entries.push(ScanEntry { address: crate::model::Address::new(a)?, info });
        }
        for (a, e) in broken {
            entries.push(ScanEntry { address: crate::model::Address::new(a)?, info: Err(e) });
        }
        entries.sort_by_key(|e| e.address);
        Ok(entries)
    }

    /// Runs a motion of module `a` under `guard` (see [`Guard`]): the watchdog of `a` armed before it where
    /// the guard asks for it and the link allows it, `a` halted after it if it still moves, and its watchdog
    /// switched off again (with the Config word as it was) whether the motion succeeded, failed or was
    /// cancelled. Only module `a`: what other operations of the session move, and the watchdogs they (or the
    /// caller of [`Op::EnableWatchdog`](crate::session::Op)) armed, are theirs. A second guarded motion of `a`
    /// while one is under way is refused before any command goes to the module: the two would share its watchdog and fight
    /// over the module. With the result, what the guard could not do (a module that ignores the RS232
    /// broadcast refresh runs without a watchdog: see `probes`).
    pub async fn guarded<T>(
        &self,
        a: u8,
        guard: Guard,
        motion: impl std::future::Future<Output = Result<T, Error>>,
    ) -> Result<(T, Vec<String>), Error> {
        if !self.core().guarded.insert(a) {
            return Err(Error::NotSupported(format!(
                "a guarded motion of module {a} is under way in this session: a second one is refused (the two \
                 would share the module's watchdog and fight over the module); wait for the first to end"
            )));
        }
        let result = self.guarded_alone(a, guard, motion).await;
        let mut core = self.core();
        core.guarded.remove(&a);
        core.duty.held.remove(&a);
        result
    }

    /// [`Ctx::guarded`], once this operation is the only guarded motion of module `a`.
    async fn guarded_alone<T>(
        &self,
        a: u8,
        guard: Guard,
        motion: impl std::future::Future<Output = Result<T, Error>>,
    ) -> Result<(T, Vec<String>), Error> {
        let ignores_broadcast = self.ignores_rs232_broadcast(a);
        let arm = guard == Guard::Watchdog && self.watchdog_reliable() && !ignores_broadcast;
        if guard == Guard::Watchdog && !self.watchdog_reliable() {
            tracing::warn!("module {a}: the watchdog is not armed: this session's settings refuse it on RS232");
        }
        let mut notes = Vec::new();
        if guard == Guard::Watchdog && ignores_broadcast {
            notes.push(probes::no_rs232_watchdog(a));
        }
        if !arm {
            let result = motion.await;
            let stopped = self.halt_own(a).await;
            return both(result, stopped).map(|v| (v, notes));
        }
        // A module halted or in error is refused before its watchdog is armed: the motion would refuse it
        // anyway, and the arming would leave it more to clear (the probe of the RS232 broadcast refresh may end
        // with a Reset, which must never clear a latch someone else set, a `stop`'s Halt or an error, and move
        // it; a life sign it does not acknowledge leaves an expired watchdog).
        let cannot_arm = |e: Error| {
            let hint = match &e {
                Error::Device { state, .. } if state.contains(crate::model::StateFlag::CommError) => {
                    " (its watchdog expired: a host stopped refreshing it; `reset` clears it)"
                }
                // The arming reads CubeState first: silence to the Config word alone is a module that does
                // not know it.
                Error::Timeout { request: Request::Get(Param::Config), .. } => {
                    " (a module before version 3.5.00 has no Config word, manual 7.2, and so no way to enable its \
                     watchdog; without the watchdog, `--no-watchdog`, it moves)"
                }
                _ => "",
            };
            Error::Context { context: format!("cannot arm the watchdog of module {a}"), source: Box::new(e), hint }
        };
        // From here on, the watchdog of `a` is this motion's: `disable_watchdog` leaves it to its end.
        self.core().duty.held.insert(a);
        self.ready_for_motion(a).await.map_err(|e| match e {
            Error::Device { .. } => cannot_arm(e),
            e => e,
        })?;
        if let Err(e) = self.enable_watchdog(&[a]).await {
            if self.core().duty.by_user.contains(&a) {
                // Armed (or being armed) by the caller of EnableWatchdog, whose to undo.
                return Err(cannot_arm(e));
            }
            // Undo what was done before the failure (a Config word changed, a life sign sent), and say what
            // the module is left in: a life sign not acknowledged may have switched the watchdog online, which
            // expires once the refresh stops (see `release_failed_arming`).
            if let Err(undo) = self.disarm(&[a]).await {
                tracing::info!("switching the watchdog off again: {undo}");
            }
            let e = match (e, self.release_failed_arming(a).await) {
                (Error::WatchdogUnconfirmed { address, on, detail }, Some(left)) => {
                    Error::WatchdogUnconfirmed { address, on, detail: format!("{detail}; {left}") }
                }
                (e, Some(left)) => {
                    tracing::warn!("module {a}: {left}");
                    e
                }
                (e, None) => e,
            };
            return Err(cannot_arm(e));
        }
        tracing::info!("watchdog armed in module {a}");
        let result = match self.probe_broadcast_refresh(a).await {
            Ok(None) => motion.await.map_err(|e| self.explain_expiry(e)),
            Ok(Some(note)) => {
                // The watchdog is off again and the module reset: the motion runs without it.
                notes.push(note);
                let result = motion.await;
                let stopped = self.halt_own(a).await;
                return both(result, stopped).map(|v| (v, notes));
            }
            Err(e) => Err(e),
        };
        // The module is stopped (if it still moves) before its watchdog goes offline.
        let stopped = self.halt_own(a).await;
        let result = both(result, stopped);
        match (result, self.disarm_own(a).await) {
            (result, Ok(())) => result.map(|v| (v, notes)),
            (Ok(_), Err(e)) => Err(Error::Context {
                context: format!("cannot switch the watchdog of module {a} off again"),
                source: Box::new(e),
                hint: "",
            }),
            // A motion whose halt was not confirmed says already that its watchdog was left online.
            (Err(e), Err(Error::WatchdogLeftOnline { .. }))
                if matches!(e.stop(), Some(StopOutcome::Unconfirmed { watchdog_armed: true, .. })) =>
            {
                Err(e)
            }
            (Err(e), Err(undo)) => Err(Error::Also { error: Box::new(e), also: Box::new(undo) }),
        }
    }

    /// The close sequence: what [`Session::close`](motionlink_link::session::Session::close) runs once every
    /// operation has ended. Halts what the session set in motion and still moves; then, unless the session
    /// failed, switches off the watchdogs it switched on and restores their Config words; then stops the
    /// refresh. After a failure the watchdogs stay online and the modules halt within 50 ms.
    pub async fn close_sequence(&self) -> Result<(), Error> {
        let stopped = self.halt_started().await.map_err(|e| match e {
            Error::StopUnconfirmed { addresses, detail, watchdog_armed } => {
                Error::CloseUnconfirmed { addresses, detail, watchdog_armed }
            }
            other => other,
        });
        let (armed, failed) = {
            let core = self.core();
            let d = &core.duty;
            (d.serving || !d.left_online().is_empty() || !d.config_before.is_empty(), core.failed)
        };
        let mut result = stopped;
        if armed {
            if result.is_ok() && !failed {
                if let Err(e) = self.disable_watchdog().await {
                    tracing::info!("switching the watchdog off on close failed (those modules halt within 50 ms): {e}");
                    result = Err(e);
                }
            } else {
                // Said by the close's error (or the error of what failed before it).
                tracing::info!("the session failed: the watchdog stays online and the modules halt within 50 ms");
                let left: Vec<u8> = self.core().duty.left_online();
                if result.is_ok() && !left.is_empty() {
                    result = Err(Error::WatchdogLeftOnline {
                        addresses: checked(left),
                        detail: "the session failed (its line broke, or a stop it sent was not confirmed)".into(),
                    });
                }
            }
        }
        self.core().duty.serving = false;
        result
    }
}

impl Ctx {
    /// A module that reports STATE_COMM_ERROR while this session refreshes its watchdog halted itself:
    /// the error says whether the refresh went out late (this host was not scheduled in time) or in time
    /// (the line or the module lost it), from the session's own record of when it sent each refresh.
    fn explain_expiry(&self, e: Error) -> Error {
        let (address, state) = match &e {
            Error::Device { address, state } | Error::Halted { address, state }
                if state.contains(crate::model::StateFlag::CommError) =>
            {
                (*address, *state)
            }
            _ => return e,
        };
        let timing = {
            let core = self.core();
            core.duty.timing(core.now, core.round_trips)
        };
        match timing {
            Some(timing) => Error::WatchdogExpired { address, state, timing },
            None => e,
        }
    }
}

/// Module numbers the session keeps (each from a checked address or a module's answer) as addresses.
pub(crate) fn checked(numbers: Vec<u8>) -> Vec<crate::model::Address> {
    numbers.into_iter().map(crate::model::Address::checked).collect()
}

/// The first error of a motion and of the stop after it.
fn both<T>(result: Result<T, Error>, stopped: Result<(), Error>) -> Result<T, Error> {
    match (result, stopped) {
        (Ok(v), Ok(())) => Ok(v),
        (Ok(_), Err(e)) => Err(e),
        (Err(e), Ok(())) => Err(e),
        // The motion's error says already that its stop was not confirmed: the same said twice is noise.
        (Err(e), Err(_)) if e.stop().is_some_and(|s| !s.is_confirmed()) => Err(e),
        (Err(e), Err(also)) => Err(Error::Also { error: Box::new(e), also: Box::new(also) }),
    }
}
