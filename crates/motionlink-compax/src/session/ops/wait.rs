//! Waiting for positionings, checked moves (limits, switched on, target read back, position at rest), and
//! stopping what the session set in motion (`OUTPUT O0=0`, confirmed by S17).

use std::time::Duration;

use super::super::core::{bit, drives_in};
use super::super::ctx::Ctx;
use super::super::types::{EchoForm, MoveOptions, MoveReport, MoveRequest, MoveTarget, Progress, StartedMove};
use crate::error::{Error, Result, StopOutcome, StopReport};
use crate::model::{Command, Position, S16Flag, S17Flag, StatusId};
use crate::wire::Address;

/// The longest time between the two S1 reads that tell whether a drive rests where S17 cannot be relied on
/// ([`Ctx::at_rest_by_s1`]): the poll interval, but no more than this.
pub(crate) const REST_CHECK_MAX: Duration = Duration::from_millis(200);

impl Ctx {
    /// POSA HOME to drive `a`, the wait until its positioning ended, then S16 (machine zero approached) and
    /// where it rests: see [`Op::Home`](crate::session::Op::Home).
    pub(crate) async fn home(&self, a: Address, timeout: Option<Duration>) -> Result<Position> {
        self.start_move(a, Command::PosAHome, MoveOptions::default(), None).await?;
        self.wait_reached(&[a], timeout).await?;
        let s16 = self.read_s16(a).await?;
        let position = self.read_position(a).await?;
        let (switched_off, machine_zero) = (s16.o0_state() == 0, s16.contains(S16Flag::MachineZero));
        if switched_off || !machine_zero {
            return Err(Error::NotHomed { address: a, position, switched_off, machine_zero });
        }
        Ok(position)
    }

    /// Waits until every drive in `drives` has ended its positioning: by its `$` message when the move
    /// asked for one, otherwise by polling S17 every poll interval, reporting each polled position. While it
    /// listens for `$` messages it still reads each drive's S17 every message check interval. On timeout,
    /// cancellation or a line failure, the drives it waits for that this session started are stopped and
    /// the error is [`Error::FailedDuringMotion`] (a cancel: [`Error::Cancelled`]).
    pub(crate) async fn wait_reached(&self, drives: &[Address], timeout: Option<Duration>) -> Result<()> {
        if drives.iter().any(|a| a.is_broadcast()) {
            return Err(Error::Broadcast("a wait reads each drive's state: name the drives"));
        }
        let mut pending: Vec<Address> = drives.to_vec();
        pending.sort();
        pending.dedup();
        let scope = pending.clone();
        match self.wait_inner(pending, timeout).await {
            Ok(()) => Ok(()),
            Err(e) => Err(self.abort(e, &scope).await),
        }
    }

    async fn wait_inner(&self, mut pending: Vec<Address>, timeout: Option<Duration>) -> Result<()> {
        let (timeout, check_every, poll_every, reply_address) = {
            let core = self.core();
            let c = &core.cfg;
            (timeout.unwrap_or(c.wait_timeout), c.message_check_interval, c.poll_interval, c.mode.reply_address)
        };
        let started_at = self.now();
        let give_up_at = started_at + timeout;
        let mut next_check = started_at + check_every;
        let mut poll_at = started_at;
        loop {
            self.check_cancel()?;
            let check_due = self.now() >= next_check;
            let mut still = Vec::new();
            for &a in &pending {
                let (by_message, seen, attributable, unattributed) = {
                    let core = self.core();
                    (
                        core.awaiting_message & bit(a) != 0,
                        core.message_seen & bit(a) != 0,
                        reply_address || core.awaiting_message.count_ones() == 1,
                        core.unattributed_messages,
                    )
                };
                if by_message && seen {
                    self.core().finish(a);
                    continue;
                }
                if by_message && unattributed == 0 && attributable && !check_due {
                    still.push(a);
                    continue;
                }
                let s17 = self.read_s17(a).await;
                // Cancelled meanwhile: the stop goes out before anything more is read. A poll that failed
                // after the cancel (which cuts its retries short) is that cancel.
                self.check_cancel()?;
                let s17 = s17?;
                if let Ok(p) = self.read_position(a).await {
                    self.progress(Progress::Position { drive: a, position: p });
                }
                let rests = !s17.contains(S17Flag::CommandActive) && self.at_rest_by_s1(a, None).await?;
                self.check_cancel()?;
                if !rests {
                    still.push(a);
                } else {
                    if by_message && self.core().message_seen & bit(a) == 0 {
                        tracing::info!("drive {a}: positioning ended without its '$' message (lost, or stopped)");
                    }
                    self.core().finish(a);
                }
            }
            if check_due {
                next_check = self.now() + check_every;
            }
            pending = still;
            if pending.is_empty() {
                return Ok(());
            }
            let now = self.now();
            if now >= give_up_at {
                return Err(Error::MoveTimeout { address: pending[0], after: now - started_at });
            }
            // The next poll is due one interval after the start of this one (at once if this one took
            // longer), never later than the end of the wait.
            poll_at = (poll_at + poll_every).max(now).min(give_up_at);
            self.listen_until(poll_at).await?;
        }
    }

    /// `e`, or the cancel when it is a telegram that went unanswered after the operation was cancelled (it
    /// is not sent again then: [`Core::cut_short`](super::super::core::Core::cut_short)).
    fn cancel_or(&self, e: Error) -> Error {
        match e {
            Error::Timeout { .. } if self.is_cancelled() => Error::CancelledBeforeMotion,
            e => e,
        }
    }

    /// Whether drive `a`, whose S17 has just shown no command active, is at rest. Once this session has
    /// seen the drive's S17 show a positioning, S17 says so. Until then (bit 3 is the user guide's, not the
    /// RS485 manual's: a drive may not show it), and on a drive found not to, S1 is read twice, one poll
    /// interval apart (at most [`REST_CHECK_MAX`]: a stop does not wait longer): a change beyond the
    /// in-position tolerance means it moves, and the drive is remembered as one whose S17 does not show its
    /// positioning (one warning). `retries` for the S1 reads (`None`: the session's); the wait between them
    /// is not cut short by a cancel (a stop makes it).
    pub(crate) async fn at_rest_by_s1(&self, a: Address, retries: Option<u32>) -> Result<bool> {
        let (seen, poll, tolerance, retries) = {
            let c = self.core();
            let seen = c.command_bit_seen & bit(a) != 0 && c.command_bit_missing & bit(a) == 0;
            let poll = c.cfg.poll_interval.min(REST_CHECK_MAX);
            (seen, poll, c.cfg.in_position_tolerance.units().abs(), retries.unwrap_or(c.cfg.retries))
        };
        if seen {
            return Ok(true);
        }
        let first = self.read_position_value(a, StatusId::ACTUAL_POSITION, retries).await?;
        self.sleep_until(self.now() + poll).await;
        let second = self.read_position_value(a, StatusId::ACTUAL_POSITION, retries).await?;
        if (second.units() - first.units()).abs() <= tolerance {
            return Ok(true);
        }
        let mut core = self.core();
        core.command_bit_missing |= bit(a);
        core.warn_once(a, "command-bit", || {
            format!(
                "drive {a} moves (S1 {first} then {second}, {} ms apart) while its S17 shows no command active: \
                 whether it rests is judged by S1 for the rest of the session",
                poll.as_millis()
            )
        });
        Ok(false)
    }

    /// `cause` ended an action while axes of this session in `scope` may be moving: stops them and says
    /// how that went ([`Error::Cancelled`] for a cancel, else [`Error::FailedDuringMotion`]); with nothing
    /// to stop, `cause` alone.
    pub(crate) async fn abort(&self, cause: Error, scope: &[Address]) -> Error {
        let scope_bits = scope.iter().fold(0u32, |acc, a| acc | bit(*a));
        let to_stop = drives_in(self.core().started & scope_bits);
        if to_stop.is_empty() {
            return cause;
        }
        tracing::info!("{cause}: stopping the axes this session moved");
        let stop = self.stop_drives(&to_stop).await;
        match cause {
            Error::CancelledBeforeMotion => Error::Cancelled { stop },
            cause => Error::FailedDuringMotion { cause: Box::new(cause), stop },
        }
    }

    /// `OUTPUT O0=0` to one drive (32: every drive), acknowledged.
    pub(crate) async fn stop(&self, address: Address) -> Result<()> {
        self.expect_ack(address, &Command::SWITCH_OFF).await?;
        self.core().finish(address);
        Ok(())
    }

    /// Stops `drives` (those still started), each only if it still moves, and reports per drive how that
    /// ended. It reads the drive's S17 first (one attempt, no retries): a drive at rest is forgotten without
    /// being switched off. A drive whose S17 says "command active", or cannot be read (on a failing line a
    /// moving axis must not be left running), is sent `OUTPUT O0=0`; once acknowledged, S17 is read again
    /// to confirm that no command is active. Without a BCC the acknowledgement alone proves little (a
    /// flipped bit can turn `O0=0` into `O0=1`): if S17 still shows the positioning, the stop is sent once
    /// more. A drive that does not confirm stays on the session's list, so closing tries once more.
    pub(crate) async fn stop_drives(&self, drives: &[Address]) -> StopReport {
        let started: Vec<Address> = drives.iter().copied().filter(|a| self.core().started & bit(*a) != 0).collect();
        self.stop_if_moving(&started).await
    }

    /// Stops each of `drives` that still moves, whoever set it in motion, as [`Ctx::stop_drives`] does for
    /// this session's own: S17 first (one attempt); a drive at rest is left switched on; one that moves, or
    /// whose S17 cannot be read, gets `OUTPUT O0=0`, confirmed by S17 afterwards.
    pub(crate) async fn stop_if_moving(&self, drives: &[Address]) -> StopReport {
        let urgent = self.urgent();
        let mut report = StopReport::default();
        for &a in drives {
            match urgent.read_s17_retries(a, 0).await {
                Ok(s) if !s.contains(S17Flag::CommandActive) => match urgent.at_rest_by_s1(a, Some(0)).await {
                    Ok(true) => {
                        tracing::debug!("drive {a}: at rest, not switched off");
                        self.core().finish(a);
                        report.drives.push((a, StopOutcome::AtRest));
                        continue;
                    }
                    Ok(false) => tracing::info!("drive {a} moves although S17 shows no command: stopping it"),
                    Err(e) => tracing::info!("drive {a}: S1 unreadable ({e}): stopping it anyway"),
                },
                Ok(_) => tracing::info!("drive {a} still moves: stopping it"),
                Err(e) => tracing::info!("drive {a}: S17 unreadable ({e}): stopping it anyway"),
            }
            let outcome = urgent.switch_off_confirmed(a).await;
            match &outcome {
                StopOutcome::NotConfirmed { reason } => tracing::info!("drive {a}: stop not confirmed: {reason}"),
                _ => tracing::info!("drive {a}: switched off, at rest"),
            }
            report.drives.push((a, outcome));
        }
        report
    }

    /// Every drive this session set in motion and has not seen stop: [`Ctx::stop_drives`].
    pub(crate) async fn stop_started(&self) -> StopReport {
        let started = drives_in(self.core().started);
        self.stop_drives(&started).await
    }

    /// `OUTPUT O0=0` to `a`, confirmed by S17 ("command active" clear) afterwards.
    async fn switch_off_confirmed(&self, a: Address) -> StopOutcome {
        for _ in 0..2 {
            if let Err(e) = self.expect_ack(a, &Command::SWITCH_OFF).await {
                return StopOutcome::NotConfirmed { reason: format!("OUTPUT O0=0 was not acknowledged: {e}") };
            }
            let rests = match self.read_s17(a).await {
                Ok(s) if !s.contains(S17Flag::CommandActive) => self.at_rest_by_s1(a, None).await,
                other => other.map(|_| false),
            };
            match rests {
                Ok(true) => {
                    self.core().finish(a);
                    return StopOutcome::SwitchedOff;
                }
                Ok(false) => {
                    tracing::info!("drive {a}: still moving after OUTPUT O0=0 (S17 or S1): sending it again")
                }
                Err(e) => {
                    return StopOutcome::NotConfirmed {
                        reason: format!(
                            "OUTPUT O0=0 was acknowledged, but S17 or S1 could not be read afterwards: {e}"
                        ),
                    }
                }
            }
        }
        StopOutcome::NotConfirmed {
            reason: "S17 still shows a command active (or S1 still changes) after OUTPUT O0=0 was acknowledged twice"
                .into(),
        }
    }

    /// A checked move: [`Ctx::start_checked_move`], then [`Ctx::finish_checked_move`].
    pub(crate) async fn move_to(&self, address: Address, request: &MoveRequest) -> Result<MoveReport> {
        let started = self.start_checked_move(address, request).await?;
        self.finish_checked_move(&started, request.timeout).await
    }

    /// Starts a move and confirms the drive took the right target, in this order: an absolute target
    /// outside the limits is refused before anything is sent; S16 (a drive switched off is refused), S17 (a
    /// drive still executing a command is refused, [`Error::StillMoving`]), S1 (the start), for a relative
    /// move S2 (the drive adds the distance to it) and the limits for the target that makes; SPEED and ACCEL if given; the move stored with its
    /// echo, compared with the telegram sent, and executed with `!` only when they match
    /// ([`Ctx::start_echoed_move`]; a binary move, which takes no flags, is sent as it is); S2 read back
    /// (twice if it differs: a mismatch stops the axis, [`Error::TargetMismatch`]). Once the move may have
    /// been sent, any error, and a cancel, stops the axis if it moves ([`Error::FailedDuringMotion`]).
    pub(crate) async fn start_checked_move(&self, address: Address, request: &MoveRequest) -> Result<StartedMove> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("a checked move reads one drive's state"));
        }
        self.check_cancel()?;
        if let MoveTarget::Absolute(p) = request.target {
            request.limits.check(address, p)?;
        }
        let s16 = self.read_s16(address).await?;
        if s16.o0_state() != 1 {
            return Err(Error::SwitchedOff { address, o0: s16.o0_state(), refused: None });
        }
        if self.read_s17(address).await?.contains(S17Flag::CommandActive) {
            // Someone else's positioning (or one this session handed over): not this call's to stop. The
            // drive reported no error: S17 shows it busy, and the move is not sent.
            return Err(Error::StillMoving { address });
        }
        let start = self.read_position(address).await?;
        let (cmd, target, before) = match request.target {
            MoveTarget::Absolute(p) => (Command::PosA(p), p, None),
            MoveTarget::Relative(d) => {
                let s2 = self.read_target(address).await?;
                (Command::PosR(d), Position::new(s2.units() + d.units())?, Some(s2.units()))
            }
        };
        request.limits.check(address, target)?;
        // How this drive echoes, found out the first time with a read sent with '?' (nothing moves yet).
        let form = if request.binary { None } else { Some(self.echo_form(address).await?) };
        self.check_cancel()?;
        // The axis is at rest and switched on. From the first telegram that can change that on, it counts as
        // this session's to stop: without a BCC one flipped bit turns a binary SPEED into a POSR (53 -> 52),
        // and a move the drive then refuses with E92 means exactly that.
        self.core().started |= bit(address);
        let not_verifiable = match self.send_checked_move(address, request, cmd, before, form).await {
            Ok(why) => why,
            Err(e) => {
                self.core().started |= bit(address);
                return Err(self.abort(self.cancel_or(e), &[address]).await);
            }
        };
        // Cancelled while the move was sent: it is stopped, not handed on (nor its target read first).
        if self.is_cancelled() {
            return Err(self.abort(Error::CancelledBeforeMotion, &[address]).await);
        }
        if let Err(e) = self.confirm_target(address, target).await {
            return Err(self.abort(self.cancel_or(e), &[address]).await);
        }
        if self.is_cancelled() {
            return Err(self.abort(Error::CancelledBeforeMotion, &[address]).await);
        }
        Ok(StartedMove { address, start, target, not_verifiable })
    }

    /// Sends the settings and the move of a checked move; returns what could not be checked before it
    /// started (empty for a move stored with its echo in full and executed with `!`).
    async fn send_checked_move(
        &self,
        address: Address,
        request: &MoveRequest,
        cmd: Command,
        before: Option<f64>,
        form: Option<EchoForm>,
    ) -> Result<Vec<String>> {
        if let Some(speed) = request.speed {
            self.setting(address, &Command::Speed(speed), request.binary).await?;
        }
        if let Some(ramp) = request.accel {
            self.setting(address, &Command::Accel(ramp), request.binary).await?;
        }
        match form {
            // A binary telegram takes no flags (manual 4.4): no store, no echo; nor does a drive that does
            // not echo get its move stored. Either is sent as it is, its target read back after.
            None | Some(EchoForm::None) => {
                let opts = MoveOptions { binary: request.binary, message: false };
                self.start_move(address, cmd, opts, before).await?;
                Ok(match form {
                    Some(f) => f.unchecked(address, self.core().cfg.mode.reply_address),
                    None => vec![EchoForm::binary_unchecked(address)],
                })
            }
            Some(form) => self.start_echoed_move(address, cmd, before, form).await,
        }
    }

    /// Reads S2 after a move was sent; [`Error::TargetMismatch`] when it is off the target twice.
    async fn confirm_target(&self, address: Address, target: Position) -> Result<()> {
        let tolerance = self.core().cfg.in_position_tolerance.units().abs();
        let mut taken = target;
        for attempt in 0..2 {
            taken = self.read_target(address).await?;
            if (taken.units() - target.units()).abs() <= tolerance {
                return Ok(());
            }
            tracing::debug!("drive {address}: S2 reads {taken}, not the target {target} (read {})", attempt + 1);
        }
        Err(Error::TargetMismatch { address, requested: target, taken })
    }

    /// Waits for a started move and checks where the axis came to rest: S1 must lie within the in-position
    /// tolerance of the target, or the error is [`Error::NotReached`]. A position off the target is checked
    /// against S17 and read once more before it counts: if S17 still shows the positioning (a garbled status
    /// reply ended the wait early), the wait goes on; a second S1 read decides.
    pub(crate) async fn finish_checked_move(
        &self,
        started: &StartedMove,
        timeout: Option<Duration>,
    ) -> Result<MoveReport> {
        let a = started.address;
        let (tolerance, wait_timeout) = {
            let core = self.core();
            (core.cfg.in_position_tolerance.units().abs(), core.cfg.wait_timeout)
        };
        let target = started.target;
        let give_up_at = self.now() + timeout.unwrap_or(wait_timeout);
        let report = |reached: Position| {
            let mut not_verifiable = started.not_verifiable.clone();
            if self.core().command_bit_missing & bit(a) != 0 {
                not_verifiable.push(format!(
                    "drive {a}'s S17 did not show the positioning (bit 3, command active, clear while S1 moved): \
                     its end was judged by S1 coming to rest"
                ));
            }
            MoveReport {
                address: a,
                start: started.start,
                target,
                reached,
                tolerance: Position::from_units_unchecked(tolerance),
                verified: not_verifiable.is_empty(),
                not_verifiable,
            }
        };
        let close = |p: Position| (p.units() - target.units()).abs() <= tolerance;
        loop {
            let left = give_up_at.saturating_since(self.now()).max(Duration::from_millis(1));
            self.wait_reached(&[a], Some(left)).await?;
            let reached = self.read_position(a).await?;
            if close(reached) {
                return Ok(report(reached));
            }
            if self.read_s17(a).await?.contains(S17Flag::CommandActive) {
                tracing::info!("drive {a}: the positioning still runs (a garbled status reply?): waiting on");
                self.core().started |= bit(a);
                continue;
            }
            let again = self.read_position(a).await?;
            if close(again) {
                return Ok(report(again));
            }
            return Err(Error::NotReached {
                address: a,
                target,
                reached: again,
                // Distances in the drive's unit, from positions in range.
                difference: Position::from_units_unchecked(again.units() - target.units()),
                tolerance: Position::from_units_unchecked(tolerance),
            });
        }
    }
}
