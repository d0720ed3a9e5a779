//! A move checked before it starts: stored in the drive's buffer with its echo (`,?`), the echo compared
//! byte for byte with the telegram sent, and only then executed (`!`).
//!
//! The RS485 manual (4.1, 4.2): `,` stores a command in "the COMPAX buffer" instead of executing it, `?`
//! makes the drive "send the received data back in full", `!` executes "a command previously stored in
//! the buffer". So the host sees what the drive received (address, command, value) before anything moves.
//!
//! Sent again: the manual speaks of "the COMPAX buffer" and of `!` executing "a command previously
//! stored", without saying how many it holds or whether a store replaces one; the crate reads it as one
//! command that the next `,` replaces (the emulator does so). Storing the same command again therefore
//! leaves one copy in the buffer (were it a queue, a second copy would wait there), and one `!` runs one. That is why a store whose echo is lost is sent again even
//! for a relative move (POSR): what is repeated is the store, never the execution. An echo that comes back
//! otherwise than sent, or corrupt, is not repaired by a resend: the move is refused, no `!` goes out. The
//! `!` itself is not repeated blind: after a lost reply to it, S2 and S17 tell whether the move started.

use super::super::core::{bit, Retry};
use super::super::ctx::Ctx;
use super::super::types::EchoForm;
use crate::error::{Error, Result};
use crate::model::{Command, Position, S17Flag, StatusId, StatusValue};
use crate::wire::{Address, Body, Flags, Reply, Request, BROADCAST};

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
                Err(e @ Error::Refused { code, .. }) if (70..=74).contains(&code.0) => Some(e),
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

    /// Stores move `cmd` in `address`'s buffer with its echo, compares the echo with the telegram sent, and
    /// executes it with `!` only when they are the same. `before` is the drive's target S2 read before (a
    /// POSR adds its distance to it). Errors: [`Error::NotExecuted`] when the echo differs, is corrupt or
    /// never comes, or when `!` is refused or did not start the move (each naming the drives that may hold
    /// the command in their buffer); [`Error::MoveUncertain`] when the reply to `!` was lost and S2 / S17
    /// do not tell whether it started.
    pub(crate) async fn start_echoed_move(
        &self,
        address: Address,
        cmd: Command,
        before: Option<f64>,
        form: EchoForm,
    ) -> Result<()> {
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
        let Some(expected_echo) = form.render(digits, text.as_bytes(), flag_chars) else {
            return Err(Error::Broadcast("a drive that does not echo takes no stored move with its echo"));
        };
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
                Err(Error::Timeout { .. }) if attempts <= retries => {
                    tracing::info!(
                        "drive {address}: no echo of the stored move: storing it again (it replaces itself)"
                    );
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::UnexpectedReply { .. })) => {
                    let why = if matches!(e, Error::Timeout { .. }) {
                        "no echo came back, so no '!' was sent"
                    } else {
                        "its echo came back corrupt, so no '!' was sent"
                    };
                    return Err(fail(Failure { why: why.into(), source: e, holders: 0 }));
                }
                Err(e) => return Err(e),
            }
        };
        if let Some(holders) = Self::echo_differs(address, &echo, &expected_echo, mode.reply_address) {
            tracing::info!("drive {address}: the echo {:?} is not the telegram sent {:?}", echo.text_str(), sent);
            let shown = match echo.address() {
                Some(a) => format!("{a}:{}", echo.text_str()),
                None => echo.text_str().to_string(),
            };
            let source = Error::UnexpectedReply { address, command: format!("{text}{flags}"), reply: shown.clone() };
            let why = format!(
                "its echo was not the telegram sent (expected {:?} from drive {address}, the form it echoes in), \
                 so no '!' was sent; the echo {shown:?} is what the drive that answered received, and what its \
                 buffer holds if the ',' arrived",
                String::from_utf8_lossy(&expected_echo)
            );
            return Err(fail(Failure { why, source, holders }));
        }

        // 2. The execution: counted as started before it is sent.
        self.check_cancel()?;
        self.core().execute_buffers(address);
        let exec = Request { address, body: Body::Execute, flags: Flags::NONE };
        let close = |a: f64, b: f64| (a - b).abs() < 0.0015;
        let mut attempts = 0;
        loop {
            attempts += 1;
            let lost = match self.exchange(&exec, Retry::DiscardedOnly).await {
                Ok(Some(r)) if r.text().is_empty() => return Ok(()),
                Ok(r) => Error::UnexpectedReply {
                    address,
                    command: "!".into(),
                    reply: r.map(|r| r.text_str().to_string()).unwrap_or_default(),
                },
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::UnexpectedReply { .. })) => e,
                Err(e @ Error::Refused { .. }) => {
                    let why = "the drive refused '!' right after echoing the stored move: it may not store a \
                               command sent with ',?' (the manual does not say that it does), so nothing ran";
                    return Err(fail(Failure { why: why.into(), source: e, holders: 0 }));
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
                return Ok(());
            }
            let moving = self.read_s17(address).await?.contains(S17Flag::CommandActive);
            let unchanged = before.is_none_or(|b| close(target, b));
            if moving || !unchanged {
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
