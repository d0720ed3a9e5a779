//! A move checked before it starts: stored in the drive's buffer with its echo (`,?`), the echo compared
//! byte for byte with the telegram sent, and only then executed (`!`).
//!
//! The RS485 manual (4.1, 4.2): `,` stores a command in "the COMPAX buffer" instead of executing it, `?`
//! makes the drive "send the received data back in full", `!` executes "a command previously stored in
//! the buffer". So the host sees what the drive received (address, command, value) before anything moves.
//!
//! Sent again: the manual speaks of "the COMPAX buffer" and of `!` executing "a command previously
//! stored", without saying how many it holds or whether a store replaces one; the crate reads it as one
//! command that the next `,` replaces (the emulator does so), but does not rely on that where a second
//! copy would run a move twice. A store whose echo is lost is sent again for an absolute move (POSA): were
//! the buffer a queue (the emulator's `buffer-queues`), the copy left in it would go to the same target.
//! A relative move (POSR) is not stored again: the move ends in [`Error::NotExecuted`], naming the drive
//! that may hold it. An echo that comes back otherwise than sent, or corrupt, is not repaired by a resend:
//! the move is refused, no `!` goes out. The `!` itself is not repeated blind: after a lost reply to it,
//! S2 and S17 tell whether the move started.

use super::super::core::{bit, Retry};
use super::super::ctx::Ctx;
use super::super::types::{EchoForm, MoveOptions};
use crate::error::{Error, Result};
use crate::model::{Command, Position, S17Flag, StatusId, StatusValue};
use crate::wire::{Address, Body, Flags, Reply, Request, BROADCAST};

/// A move sent as a command of its own: ASCII, no `$`.
const PLAIN: MoveOptions = MoveOptions { binary: false, message: false };

/// What a move sent as a command of its own to a drive that echoes a command sent with `,?` without
/// storing it could not check.
fn no_store(address: Address) -> String {
    format!(
        "drive {address} refused the '!' after echoing a move sent with ',?', and is taken not to store a command \
         sent so (the manual does not say that it does): the move was sent as a command of its own, without being \
         checked before it started (its target was read back after, from S2)"
    )
}

/// What an error of the store or of `!` leaves behind.
struct Failure {
    why: String,
    source: Error,
    holders: u32,
}

/// The address digits, the command and the flag characters of telegram `sent` (everything before its CR)
/// to `address` whose command text is `text`.
fn parts<'a>(sent: &'a [u8], address: Address, text: &[u8]) -> (&'a [u8], &'a [u8]) {
    let n = address.digits().1.min(sent.len());
    let flags = sent.get(n + text.len()..).unwrap_or_default();
    (&sent[..n], flags)
}

impl Ctx {
    /// How drive `address` echoes (see [`EchoForm`]): found out the first time with S1 sent with `?` (a
    /// drive does not execute what it echoes, and S1 is only a read), then remembered. No echo (a refusal,
    /// the value of S1, silence) counts only when it comes twice: one flipped bit of the probe can make a
    /// drive refuse it or read S1, and a drive that echoes must never be taken for one that does not. An echo
    /// of another command text is sent once more; twice, it is a discrepancy no form explains: refused
    /// ([`Error::UnexpectedReply`]).
    pub(crate) async fn echo_form(&self, address: Address) -> Result<EchoForm> {
        if let Some(form) = self.core().echo_forms[usize::from(address.get())] {
            return Ok(form);
        }
        let (style, mode) = {
            let core = self.core();
            (core.cfg.style, core.cfg.mode)
        };
        let cmd = Command::ReadStatus(StatusId::ACTUAL_POSITION);
        let text = cmd.to_ascii(style)?;
        let req = Request { address, body: Body::Command(text.as_bytes()), flags: Flags { echo: true, ..Flags::NONE } };
        let frame = req.encode(&mode)?;
        let sent = frame.as_bytes().split(|&b| b == b'\r').next().unwrap_or_default().to_vec();
        let (digits, flags) = parts(&sent, address, text.as_bytes());
        // A "no echo" (a refusal of '?', silence) counts only when it comes twice, the drive having answered
        // a plain read of S1 in between: one flipped bit can make a drive deaf for a while (a binary length
        // byte swallows what follows) and then answer errors and late replies, while a drive that does not
        // echo answers S1 and then refuses '?' again. Anything else that is not an echo (a read answered,
        // other text, an RS485 line error E70..E74) is asked once more; twice, it is the error.
        let (mut none, mut garbled) = (0, 0);
        let form = loop {
            let garble = match self.exchange(&req, Retry::Idempotent).await {
                Ok(Some(r)) => {
                    let from_ok = !mode.reply_address || r.address() == Some(address.get());
                    if let Some(form) = EchoForm::of(r.text(), digits, text.as_bytes(), flags).filter(|_| from_ok) {
                        break form;
                    }
                    // Not an echo: a read answered (a drive that ignores '?', or a late reply to a read), or
                    // other text. Neither is taken for "no echo": such a drive would store a move sent
                    // with ',?' without a word, or run it.
                    let read = StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()).is_ok();
                    tracing::info!("drive {address}: {:?} in answer to {:?}", r.text_str(), sent);
                    Some(Error::UnexpectedReply {
                        address,
                        command: format!("{text}?"),
                        reply: format!(
                            "{} ({}, twice: not an echo in any form)",
                            r.text_str(),
                            if read { "the value of S1" } else { "other text than sent" }
                        ),
                    })
                }
                Ok(None) => return Err(Error::Broadcast("an echo needs one drive's answer")),
                Err(e @ Error::Refused { code, .. }) if code.is_line_error() => Some(e),
                Err(Error::Refused { .. } | Error::Timeout { .. }) => None,
                Err(e) => return Err(e),
            };
            match garble {
                Some(e) => {
                    garbled += 1;
                    if garbled == 2 {
                        return Err(e);
                    }
                }
                None => {
                    none += 1;
                    if none == 2 {
                        break EchoForm::None;
                    }
                    self.read_position(address).await?;
                }
            }
        };
        let mut core = self.core();
        core.echo_forms[usize::from(address.get())] = Some(form);
        // Found by this session: no longer a profile's finding.
        core.echo_profiles.remove(&address.get());
        let why = form.unchecked(address, mode.reply_address);
        if !why.is_empty() {
            core.warn_once(address, "echo", || {
                format!(
                    "drive {address} echoes a telegram sent with '?' {} (the manual says only \"in full\"): {}; moves \
                     say so in their results",
                    form.described(),
                    why.join("; ")
                )
            });
        }
        Ok(form)
    }

    /// The echo form of `address` where it was taken from a device profile and no echo of this session has
    /// shown it yet: forgotten (the next [`Ctx::echo_form`] finds it out on the drive), with the profile's
    /// reference and the form it gave.
    fn forget_profile_form(&self, address: Address) -> Option<(String, EchoForm)> {
        let mut core = self.core();
        let profile = core.echo_profiles.remove(&address.get())?;
        let form = core.echo_forms[usize::from(address.get())].take()?;
        Some((profile, form))
    }

    /// Stores move `cmd` in `address`'s buffer with its echo, compares the echo with the telegram sent, and
    /// executes it with `!` only when they are the same. `before` is the drive's target S2 read before (a
    /// POSR adds its distance to it). Returns what could not be checked (see [`EchoForm::unchecked`]).
    ///
    /// Where the form came from a device profile and the drive contradicts it (it refuses the store, or
    /// echoes the command in another form), the profile's finding is forgotten and the form found on the
    /// drive as without a profile (S1 sent with `?`): a drive that does not echo gets the move as a command
    /// of its own; one whose echo of S1 is in the form its echo of the move showed gets the `!`. A drive
    /// that echoes the move and then refuses the `!` does not store a command sent with `,?`: remembered,
    /// and the move sent as a command of its own once S17 (and for a POSR S2) show that nothing ran.
    ///
    /// Errors: [`Error::NotExecuted`] when the echo differs, is corrupt or never comes, or when `!` did not
    /// start the move (each naming the drives that may hold the command in their buffer);
    /// [`Error::MoveUncertain`] when the reply to `!` was lost and S2 / S17 do not tell whether it started.
    pub(crate) async fn start_echoed_move(
        &self,
        address: Address,
        cmd: Command,
        before: Option<f64>,
        form: EchoForm,
    ) -> Result<Vec<String>> {
        if self.core().echo_without_store & bit(address) != 0 {
            self.start_move(address, cmd, PLAIN, before).await?;
            return Ok(vec![no_store(address)]);
        }
        let (style, retries, mode) = {
            let core = self.core();
            (core.cfg.style, core.cfg.retries, core.cfg.mode)
        };
        let text = cmd.to_ascii(style)?;
        let flags = Flags { buffer: true, echo: true, ..Flags::NONE };
        let req = Request { address, body: Body::Command(text.as_bytes()), flags };
        let frame = req.encode(&mode)?;
        // The telegram as received: everything before its CR; the echo is that in the drive's form.
        let sent = frame.as_bytes().split(|&b| b == b'\r').next().unwrap_or_default().to_vec();
        let (digits, flag_chars) = parts(&sent, address, text.as_bytes());
        let Some(mut expected_echo) = form.render(digits, text.as_bytes(), flag_chars) else {
            return Err(Error::Broadcast("a drive that does not echo takes no stored move with its echo"));
        };
        let mut form = form;
        let expected = match cmd {
            Command::PosR(d) => before.unwrap_or(0.0) + d.units(),
            Command::PosA(p) => p.units(),
            _ => 0.0,
        };
        let fail = |f: Failure| {
            let holders = f.holders | bit(address);
            self.core().buffered |= holders;
            Error::NotExecuted {
                address,
                command: text.to_string(),
                why: f.why,
                source: Box::new(f.source),
                buffered: (1..BROADCAST).filter(|a| holders & (1 << a) != 0).collect(),
            }
        };

        // 1. The store, with its echo.
        let mut attempts = 0;
        let echo = loop {
            attempts += 1;
            self.check_cancel()?;
            // From now on the drive may hold it: a later '!' of this session counts it as started.
            self.core().buffered |= bit(address);
            match self.exchange(&req, Retry::DiscardedOnly).await {
                Ok(Some(r)) => break r,
                Ok(None) => {
                    return Err(Error::Broadcast("a buffered move with its echo needs one drive's answer"));
                }
                // An absolute move is stored again: should the buffer queue commands, the copy left in it
                // goes to the same target.
                Err(Error::Timeout { .. }) if attempts <= retries && cmd.is_idempotent() => {
                    tracing::info!(
                        "drive {address}: no echo of the stored move: storing it again (it replaces itself)"
                    );
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::UnexpectedReply { .. })) => {
                    let why = match e {
                        // A relative move is not: a buffer that queued two copies would run it twice.
                        Error::Timeout { .. } if !cmd.is_idempotent() => {
                            "no echo came back, so no '!' was sent; a relative move is not stored again (the manual \
                             does not say that a store replaces the command held: a buffer that kept both would \
                             run it twice)"
                        }
                        Error::Timeout { .. } => "no echo came back, so no '!' was sent",
                        _ => "its echo came back corrupt, so no '!' was sent",
                    };
                    return Err(fail(Failure { why: why.into(), source: e, holders: 0 }));
                }
                // Refused (not an RS485 line error) where the form is only a profile's finding: perhaps a
                // drive that does not know '?'. Found out on this drive before anything else is sent.
                Err(e @ Error::Refused { code, .. }) if !code.is_line_error() => {
                    let Some((profile, said)) = self.forget_profile_form(address) else { return Err(e) };
                    return self.after_refused_store(address, cmd, before, e, &profile, said).await;
                }
                Err(e) => return Err(e),
            }
        };
        let from_ok = |r: &Reply| {
            let from = r.address();
            if mode.reply_address {
                from == Some(address.get())
            } else {
                from.is_none()
            }
        };
        // The form the echo is in, where it is the telegram sent (the command text byte for byte).
        let shown_form = EchoForm::of(echo.text(), digits, text.as_bytes(), flag_chars).filter(|_| from_ok(&echo));
        if let Some(holders) = Self::echo_differs(address, &echo, &expected_echo, mode.reply_address) {
            tracing::info!("drive {address}: the echo {:?} is not the telegram sent {:?}", echo.text_str(), sent);
            let shown = match echo.address() {
                Some(a) => format!("{a}:{}", echo.text_str()),
                None => echo.text_str().to_string(),
            };
            let source = Error::UnexpectedReply { address, command: format!("{text}{flags}"), reply: shown.clone() };
            let expected_text = String::from_utf8_lossy(&expected_echo).into_owned();
            let profile = shown_form.and_then(|_| self.forget_profile_form(address));
            match (shown_form, profile) {
                // The command as sent, in another form than a device profile says: the form is found out on
                // this drive (S1 sent with '?', which stores nothing and runs nothing); the echo is taken when
                // that shows the same form.
                (Some(shown_in), Some((profile, said))) => {
                    let found = match self.echo_form(address).await {
                        Ok(found) => found,
                        Err(e) => {
                            let why = format!(
                                "its echo {shown:?} is the telegram sent, but {} (not {} as the device profile \
                                 {profile} says), and finding the form again with S1 sent with '?' failed, so no \
                                 '!' was sent",
                                shown_in.described(),
                                said.described()
                            );
                            return Err(fail(Failure { why, source: e, holders }));
                        }
                    };
                    if found != shown_in {
                        let why = format!(
                            "its echo {shown:?} is the telegram sent, but {}, while its echo of S1 sent with '?' \
                             came {} (and the device profile {profile} says {}): no form explains both, so no '!' \
                             was sent",
                            shown_in.described(),
                            found.described(),
                            said.described()
                        );
                        return Err(fail(Failure { why, source, holders }));
                    }
                    self.core().warn_once(address, "profile", || {
                        format!(
                            "drive {address}: the device profile {profile} says it echoes {}, but it echoed \
                             {shown:?} for {:?}, {}, and so does its echo of S1 sent with '?': the profile's \
                             finding is not used this session; moves are checked in the form found",
                            said.described(),
                            String::from_utf8_lossy(&sent),
                            shown_in.described()
                        )
                    });
                    form = shown_in;
                    expected_echo = form.render(digits, text.as_bytes(), flag_chars).unwrap_or_default();
                    debug_assert!(Self::echo_differs(address, &echo, &expected_echo, mode.reply_address).is_none());
                }
                (Some(shown_in), None) => {
                    let why = format!(
                        "its echo {shown:?} is the telegram sent, but {}, not {} as drive {address} was found to \
                         echo (expected {expected_text:?}): an echo in another form than found is not taken, so no \
                         '!' was sent",
                        shown_in.described(),
                        form.described()
                    );
                    return Err(fail(Failure { why, source, holders }));
                }
                (None, _) => {
                    let why = format!(
                        "its echo was not the telegram sent (expected {expected_text:?} from drive {address}, the \
                         form it echoes in), so no '!' was sent; the echo {shown:?} shows what the drive that \
                         answered received (in the form it echoes in) unless the echo was changed on its way \
                         back, and what its buffer holds if the ',' arrived"
                    );
                    return Err(fail(Failure { why, source, holders }));
                }
            }
        } else {
            // The drive echoed in the form taken: a profile's finding is now this session's.
            self.core().echo_profiles.remove(&address.get());
        }
        let prefixed = mode.reply_address;

        // 2. The execution: counted as started before it is sent.
        self.check_cancel()?;
        self.core().execute_buffers(address);
        let exec = Request { address, body: Body::Execute, flags: Flags::NONE };
        let close = |a: f64, b: f64| (a - b).abs() < super::S2_RESOLUTION;
        let mut attempts = 0;
        loop {
            attempts += 1;
            let lost = match self.exchange(&exec, Retry::DiscardedOnly).await {
                Ok(Some(r)) if r.text().is_empty() => return Ok(form.unchecked(address, prefixed)),
                Ok(r) => Error::UnexpectedReply {
                    address,
                    command: "!".into(),
                    reply: r.map(|r| r.text_str().to_string()).unwrap_or_default(),
                },
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::UnexpectedReply { .. })) => e,
                Err(e @ Error::Refused { code, .. }) if code.is_line_error() => {
                    let why = format!("the drive refused '!' with {code}, an RS485 line error");
                    return Err(fail(Failure { why, source: e, holders: 0 }));
                }
                // '!' refused after the echo of a relative move: it is not sent again as a command of its own.
                // Whether the drive holds it after all is not known (the refusal may have another reason), and a
                // later '!' (a `32!` of a synchronous start) would run it a second time after the plain one.
                Err(e @ Error::Refused { .. }) if matches!(cmd, Command::PosR(_)) => {
                    let why = "the drive refused '!' right after echoing the stored move (it may not store a \
                               command sent with ',?'; the manual does not say that it does): a relative move is not \
                               sent again as a command of its own, so it did not run";
                    return Err(fail(Failure { why: why.into(), source: e, holders: 0 }));
                }
                Err(e @ Error::Refused { .. }) => {
                    // '!' refused right after the echo of the move: the drive did not store it (the manual lists
                    // ',' and '?' as optional characters of one telegram, and says neither that a drive
                    // stores nor that it does not store what it echoes). Remembered for the session. (An
                    // absolute move sent again goes to the same target, should the drive hold it after all.)
                    {
                        let mut core = self.core();
                        core.echo_without_store |= bit(address);
                        // It may hold the command after all (the manual has no command that empties a buffer).
                        core.buffered |= bit(address);
                    }
                    let what = format!(
                        "the drive refused '!' right after echoing the move sent with ',?' ({e}): it is taken not to \
                         store a command sent with ',?'"
                    );
                    self.send_plain_after_refusal(address, cmd, before, e, &what).await?;
                    self.core().warn_once(address, "store", || {
                        format!(
                            "drive {address} echoed a move sent with ',?' and then refused the '!' after it, and \
                             S17{} showed that nothing ran: it is taken not to store a command sent with ',?' (the \
                             manual does not say that it does); moves are sent as commands of their own, not \
                             checked before they start, and say so in their results",
                            if before.is_some() { " and S2" } else { "" }
                        )
                    });
                    return Ok(vec![no_store(address)]);
                }
                Err(e) => return Err(e),
            };
            // Cancelled meanwhile: the move counts as started, and the stop tells (no S2 read first).
            if self.is_cancelled() {
                return Err(lost);
            }
            // The reply to '!' is lost: did the move start? The target S2 and "command active" tell.
            let target = self.read_target(address).await?.units();
            if close(target, expected) {
                tracing::info!("drive {address}: reply to '!' lost, but the move started (S2 = {target})");
                return Ok(form.unchecked(address, prefixed));
            }
            let moving = self.read_s17(address).await?.contains(S17Flag::CommandActive);
            let unchanged = before.is_none_or(|b| close(target, b));
            // A relative distance within S2's resolution leaves S2 alike whether it started or not.
            let s2_tells = before.is_none_or(|b| !close(expected, b));
            if moving || !unchanged || !s2_tells {
                return Err(Error::MoveUncertain {
                    address,
                    command: format!("! ({text})"),
                    // Read as a Position (S2): in range.
                    target: Position::from_units_unchecked(target),
                });
            }
            if attempts > retries {
                return Err(fail(Failure {
                    why: "'!' got no reply, and S2 and S17 show the move did not start".into(),
                    source: lost,
                    holders: 0,
                }));
            }
            tracing::info!("drive {address}: reply to '!' lost and the move did not start (S2, S17): '!' again");
            self.core().execute_buffers(address);
        }
    }

    /// The store of move `cmd` with `,?` was refused (`refused`) while the echo form was only the finding of
    /// device profile `profile` (`said`), now forgotten: the form is found out on the drive. One that does
    /// not echo explains the refusal, and gets the move as a command of its own (once nothing of the
    /// refused telegram is seen to have run); for one that echoes, the refusal stands.
    async fn after_refused_store(
        &self,
        address: Address,
        cmd: Command,
        before: Option<f64>,
        refused: Error,
        profile: &str,
        said: EchoForm,
    ) -> Result<Vec<String>> {
        let found = self.echo_form(address).await?;
        let (command, code) = match &refused {
            Error::Refused { command, code, .. } => (command.clone(), *code),
            _ => return Err(refused),
        };
        if found != EchoForm::None {
            self.core().warn_once(address, "profile", || {
                format!(
                    "drive {address}: the device profile {profile} says it echoes {}; it echoes S1 sent with '?' {}: \
                     the profile's finding is not used this session",
                    said.described(),
                    found.described()
                )
            });
            // The drive echoes: what it refused is the move itself.
            return Err(refused);
        }
        let what = format!(
            "drive {address} refused {command:?} with {code} and refuses S1 sent with '?' too: it does not echo"
        );
        self.send_plain_after_refusal(address, cmd, before, refused, &what).await?;
        self.core().warn_once(address, "profile", || {
            format!(
                "drive {address}: the device profile {profile} says it echoes {}, but it refused {command:?} with \
                 {code}, and S1 sent with '?' too: it does not echo, so the profile's finding is not used this \
                 session; the move was sent as a command of its own, not checked before it started",
                said.described()
            )
        });
        let prefixed = self.core().cfg.mode.reply_address;
        Ok(EchoForm::None.unchecked(address, prefixed))
    }

    /// Sends move `cmd` as a command of its own (the manual's plain form) after the drive refused a telegram
    /// of it (`refused`; `what` says which and what that shows). Not a repeat of an executed command: the
    /// drive answered that telegram with an error in place of its acknowledgement (manual 4.3), and a
    /// stored command runs only by a '!' the drive takes (4.2). The manual does not say in so many words that
    /// a refused telegram ran nothing, so S17 must show no command active and, for a POSR, S2 still the
    /// target read before it (a POSR that ran would have moved it by its distance) before the move goes out;
    /// otherwise nothing more is sent and the error says what was seen. (A POSA sent again would be
    /// harmless: the same absolute target.)
    async fn send_plain_after_refusal(
        &self,
        address: Address,
        cmd: Command,
        before: Option<f64>,
        refused: Error,
        what: &str,
    ) -> Result<()> {
        let active = self.read_s17(address).await?.contains(S17Flag::CommandActive);
        let target = match before {
            Some(_) => Some(self.read_target(address).await?.units()),
            None => None,
        };
        let moved = match (before, target) {
            (Some(b), Some(t)) if (t - b).abs() >= super::S2_RESOLUTION => Some((b, t)),
            _ => None,
        };
        if active || moved.is_some() {
            let seen = match moved {
                Some((b, t)) => format!("S2 reads {t}, not {b} as before"),
                None => "S17 shows a command active".into(),
            };
            let text = cmd.to_ascii(self.core().cfg.style)?;
            return Err(Error::NotExecuted {
                address,
                command: text.to_string(),
                why: format!(
                    "{what}; but then {seen}: something may have run, so the move was not sent again as a command \
                     of its own"
                ),
                source: Box::new(refused),
                buffered: vec![address.get()],
            });
        }
        tracing::info!("drive {address}: {what}; nothing ran (S17, S2): sending the move as a command of its own");
        self.start_move(address, cmd, PLAIN, before).await
    }

    /// `None` when `echo` is `expected`, the telegram sent in the form the drive echoes in (as a drive
    /// answers with P196's address prefix when `prefixed`); otherwise the drives that may hold the command:
    /// one whose address the echo shows.
    fn echo_differs(address: Address, echo: &Reply, expected: &[u8], prefixed: bool) -> Option<u32> {
        let from = echo.address();
        let from_ok = if prefixed { from == Some(address.get()) } else { from.is_none() };
        if from_ok && echo.text() == expected {
            return None;
        }
        let digits: Vec<u8> = echo.text().iter().take_while(|c| c.is_ascii_digit()).map(|c| c - b'0').collect();
        let shown = match digits.as_slice() {
            [a] => Some(*a),
            [a, b] => Some(a * 10 + b),
            _ => None,
        };
        let holders = [from, shown]
            .into_iter()
            .flatten()
            .filter(|a| (1..BROADCAST).contains(a))
            .fold(0u32, |acc, a| acc | (1 << a));
        Some(holders)
    }
}
