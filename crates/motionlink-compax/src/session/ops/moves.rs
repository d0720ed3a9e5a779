//! Moves: one drive (POSA, POSR, POSA HOME), the synchronous start of several, a command to every drive,
//! and a raw command whose motion is handed over or waited for.

use super::super::core::{bit, drives_in, Effect, Retry};
use super::super::ctx::Ctx;
use super::super::types::{AfterRaw, MoveOptions, RawOutcome};
use super::S2_RESOLUTION;
use crate::error::{Error, Result};
use crate::model::{Command, ModelError, Position, S17Flag};
use crate::wire::{Address, Body, Flags, Request, WireError};

impl Ctx {
    fn move_request<'a>(address: Address, cmd: &Command, text: &'a [u8], opts: MoveOptions) -> Result<Request<'a>> {
        if opts.binary {
            if opts.message {
                return Err(WireError::Flags("the binary form takes no '$'").into());
            }
            return Ok(Request { address, body: Body::Binary(cmd.to_binary()?), flags: Flags::NONE });
        }
        Ok(Request {
            address,
            body: Body::Command(text),
            flags: Flags { position_message: opts.message, ..Flags::NONE },
        })
    }

    /// Sends move `cmd` to one drive; for a POSR, `target_before` is the drive's S2 if the caller has just
    /// read it. If the reply is lost, the drive's target S2 tells whether it took the move: unchanged, it
    /// did not and the move is sent again; moved as the move says, it did; anything else is
    /// [`Error::MoveUncertain`], as is a POSR whose distance S2 cannot show (below its resolution) and a
    /// move sent again that the drive then refuses (the first may have been taken). Never sent again blind.
    pub(crate) async fn start_move(
        &self,
        address: Address,
        cmd: Command,
        opts: MoveOptions,
        target_before: Option<f64>,
    ) -> Result<()> {
        if address.is_broadcast() {
            return Err(Error::Broadcast(
                "a move needs one drive's answer (broadcast() moves every drive, sync_start() several at once)",
            ));
        }
        if !cmd.is_move() {
            return Err(ModelError::Syntax { what: "a move", text: cmd.to_string() }.into());
        }
        self.check_cancel()?;
        let (style, retries) = {
            let core = self.core();
            (core.cfg.style, core.cfg.retries)
        };
        let text = cmd.to_ascii(style)?;
        let req = Self::move_request(address, &cmd, text.as_bytes(), opts)?;
        let before = match (cmd, target_before) {
            (Command::PosR(_), Some(b)) => Some(b),
            (Command::PosR(_), None) => Some(self.read_target(address).await?.units()),
            _ => None,
        };
        let expected = match cmd {
            Command::PosA(p) => p.units(),
            Command::PosR(d) => before.unwrap_or(0.0) + d.units(),
            _ => 0.0,
        };
        // The read above may have taken a while: a cancel that came meanwhile still keeps the move unsent.
        self.check_cancel()?;
        // Counted as started before it is sent: if the session fails now, the stop still reaches it.
        let (saved, saved_awaiting) = {
            let mut core = self.core();
            let saved = core.before_send(address, Effect::Starts);
            let saved_awaiting = core.awaiting_message;
            if opts.message {
                core.awaiting_message |= bit(address);
                core.message_seen &= !bit(address);
            }
            (saved, saved_awaiting)
        };
        let restore = || {
            let mut core = self.core();
            core.unmark(saved);
            // Only this drive's: another operation may be awaiting its own drive's message meanwhile.
            core.awaiting_message = (core.awaiting_message & !bit(address)) | (saved_awaiting & bit(address));
        };
        // The drive's target S2 as read after a lost reply, and the error that says it does not tell.
        let mut s2_read = None;
        let uncertain = |target: f64| Error::MoveUncertain {
            address,
            command: cmd.to_string(),
            target: Position::from_units_unchecked(target),
        };
        let mut attempts = 0;
        loop {
            attempts += 1;
            match self.exchange(&req, Retry::DiscardedOnly).await {
                Ok(_) => return Ok(()),
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::UnexpectedReply { .. })) => {
                    // The reply is lost (or only a reply that cannot be the acknowledgement came): did the
                    // drive take the move? Its target position tells.
                    let target = self.read_target(address).await?.units();
                    s2_read = Some(target);
                    let close = |a: f64, b: f64| (a - b).abs() < S2_RESOLUTION;
                    // A relative distance within S2's resolution leaves S2 alike whether it was taken or not:
                    // it cannot tell, and the move is never sent again on it.
                    let s2_tells = before.is_none_or(|b| !close(expected, b));
                    if close(target, expected) && s2_tells {
                        tracing::info!("drive {address}: reply lost, but the drive took the move (S2 = {target})");
                        return Ok(());
                    }
                    if !s2_tells {
                        return Err(uncertain(target));
                    }
                    let not_taken = match before {
                        Some(b) => close(target, b),
                        None => !self.read_s17(address).await?.contains(S17Flag::CommandActive),
                    };
                    if not_taken && attempts <= retries {
                        tracing::info!("drive {address}: reply lost and the move was not taken: sending it again");
                        continue;
                    }
                    if not_taken {
                        restore();
                        return Err(e);
                    }
                    return Err(uncertain(target));
                }
                Err(e @ Error::CancelledBeforeMotion) => {
                    // Cancelled before it went out: never sent.
                    restore();
                    return Err(e);
                }
                Err(e) => {
                    if let (Error::Refused { .. }, Some(target)) = (&e, s2_read) {
                        // Sent again after a reply was lost and the drive's state showed the move not taken,
                        // and now refused (E92 while it moves, for one): the first may have been taken after
                        // all. The drive stays the session's to stop.
                        return Err(uncertain(target));
                    }
                    if matches!(e, Error::Refused { .. }) {
                        // Refused (E92 while it still moves, for one): it started nothing new, and an axis
                        // this session set moving before is still its to stop.
                        restore();
                        return Err(self.explain_refused_move(address, e).await);
                    }
                    return Err(e);
                }
            }
        }
    }

    /// Stores each move in its drive's buffer (`,`), then sends one `32!` that executes them all. If
    /// storing fails for one drive, no `!` is sent and the error names the drives that still hold a
    /// buffered move ([`Error::SyncIncomplete`]). A drive outside `moves` that may still hold a move of this
    /// session in its buffer would run it at the `32!`: refused before anything is sent ([`Error::BufferHeld`]).
    pub(crate) async fn sync_start(&self, moves: &[(Address, Command)], message: bool) -> Result<()> {
        for (a, c) in moves {
            if !c.is_move() || a.is_broadcast() {
                return Err(ModelError::Syntax { what: "a move to one drive", text: format!("{a}: {c}") }.into());
            }
        }
        let listed = moves.iter().fold(0u32, |m, (a, _)| m | bit(*a));
        let held = self.core().buffered & !listed;
        if held != 0 {
            return Err(Error::BufferHeld { held: drives_in(held).iter().map(|d| d.get()).collect() });
        }
        self.check_cancel()?;
        let mut stored = 0u32;
        for (a, c) in moves {
            let flags = Flags { buffer: true, position_message: message, ..Flags::NONE };
            match self.send_command(*a, c, flags).await {
                Ok(_) => {
                    stored |= bit(*a);
                    self.core().buffered |= bit(*a);
                }
                Err(e) => {
                    if e.is_transport() {
                        // The reply was lost: the drive may have stored the move.
                        self.core().buffered |= bit(*a);
                        stored |= bit(*a);
                    }
                    tracing::error!("drive {a}: storing the synchronous move failed ({e}); buffered moves remain");
                    return Err(Error::SyncIncomplete {
                        failed: a.get(),
                        source: Box::new(e),
                        buffered: drives_in(stored).iter().map(|d| d.get()).collect(),
                    });
                }
            }
        }
        self.check_cancel()?;
        let executed = {
            let mut core = self.core();
            for (a, _) in moves {
                if message {
                    core.awaiting_message |= bit(*a);
                    core.message_seen &= !bit(*a);
                }
            }
            core.execute_buffers(Address::BROADCAST)
        };
        let req = Request { address: Address::BROADCAST, body: Body::Execute, flags: Flags::NONE };
        match self.exchange(&req, Retry::DiscardedOnly).await {
            Ok(_) => Ok(()),
            Err(Error::CancelledBeforeMotion) => {
                // The `!` never went out: the moves stay in the buffers.
                self.core().unexecute(executed);
                Err(Error::CancelledBeforeMotion)
            }
            Err(e) => Err(e),
        }
    }

    /// Sends `cmd` to every drive at once (no reply). A move counts as started for every drive that has
    /// answered this session; `OUTPUT O0=0` ends every record of a started axis.
    pub(crate) async fn broadcast(&self, cmd: &Command) -> Result<()> {
        let effect = Effect::of_command(cmd);
        if effect == Effect::Starts {
            self.check_cancel()?;
        }
        let style = self.core().cfg.style;
        let text = cmd.to_ascii(style)?;
        let saved = self.core().before_send(Address::BROADCAST, effect);
        let req = Request { address: Address::BROADCAST, body: Body::Command(text.as_bytes()), flags: Flags::NONE };
        match self.exchange(&req, Retry::DiscardedOnly).await {
            Ok(_) => {}
            Err(e @ Error::CancelledBeforeMotion) => {
                self.core().unmark(saved);
                return Err(e);
            }
            Err(e) => return Err(e),
        }
        self.core().after_send(Address::BROADCAST, effect);
        Ok(())
    }

    /// A raw command, then what it set in motion handed over or waited for. Cancelled while it was sent,
    /// what it started is stopped instead (never handed over).
    pub(crate) async fn raw_motion(&self, address: Address, text: &str, after: AfterRaw) -> Result<RawOutcome> {
        let before = self.core().started;
        let reply = self.raw(address, text).await?;
        let started = drives_in(self.core().started & !before);
        if self.is_cancelled() && !started.is_empty() {
            return Err(self.abort(Error::CancelledBeforeMotion, &started).await);
        }
        let waited = match (after, started.is_empty()) {
            (AfterRaw::Wait(timeout), false) => {
                self.wait_reached(&started, Some(timeout)).await?;
                true
            }
            _ => {
                // A move sent raw runs on after the caller is done with it: handed over.
                self.core().release(&started);
                false
            }
        };
        Ok(RawOutcome { reply, started, waited })
    }
}
