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
use crate::error::{Error, Result};
use crate::model::{Command, Position, S17Flag};
use crate::wire::{Address, Body, Flags, Reply, Request, BROADCAST};

/// What an error of the store or of `!` leaves behind.
struct Failure {
    why: &'static str,
    source: Error,
    holders: u32,
}

impl Ctx {
    /// Stores move `cmd` in `address`'s buffer with its echo, compares the echo with the telegram sent, and
    /// executes it with `!` only when they are the same. `before` is the drive's target S2 read before (a
    /// POSR adds its distance to it). Errors: [`Error::NotExecuted`] when the echo differs, is corrupt or
    /// never comes, or when `!` is refused or did not start the move (each naming the drives that may hold
    /// the command in their buffer); [`Error::MoveUncertain`] when the reply to `!` was lost and S2 / S17
    /// do not tell whether it started.
    pub(crate) async fn start_echoed_move(&self, address: Address, cmd: Command, before: Option<f64>) -> Result<()> {
        let (style, retries, mode) = {
            let core = self.core();
            (core.cfg.style, core.cfg.retries, core.cfg.mode)
        };
        let text = cmd.to_ascii(style)?;
        let flags = Flags { buffer: true, echo: true, ..Flags::NONE };
        let req = Request { address, body: Body::Command(text.as_bytes()), flags };
        let frame = req.encode(&mode)?;
        // The echo is the telegram as received: everything before its CR.
        let sent = frame.as_bytes().split(|&b| b == b'\r').next().unwrap_or_default().to_vec();
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
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::Unexpected { .. })) => {
                    let why = if matches!(e, Error::Timeout { .. }) {
                        "no echo came back, so no '!' was sent"
                    } else {
                        "its echo came back corrupt, so no '!' was sent"
                    };
                    return Err(fail(Failure { why, source: e, holders: 0 }));
                }
                Err(e) => return Err(e),
            }
        };
        if let Some(holders) = Self::echo_differs(address, &echo, &sent, mode.reply_address) {
            tracing::info!("drive {address}: the echo {:?} is not the telegram sent {:?}", echo.text_str(), sent);
            let shown = match echo.address() {
                Some(a) => format!("{a}:{}", echo.text_str()),
                None => echo.text_str().to_string(),
            };
            let source = Error::Unexpected { address, command: format!("{text}{flags}"), reply: shown };
            return Err(fail(Failure {
                why: "its echo was not the telegram sent, so no '!' was sent",
                source,
                holders,
            }));
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
                Ok(r) => Error::Unexpected {
                    address,
                    command: "!".into(),
                    reply: r.map(|r| r.text_str().to_string()).unwrap_or_default(),
                },
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::Unexpected { .. })) => e,
                Err(e @ Error::Device { .. }) => {
                    return Err(fail(Failure { why: "the drive refused '!'", source: e, holders: 0 }));
                }
                Err(e) => return Err(e),
            };
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
                    why: "'!' got no reply, and S2 and S17 show the move did not start",
                    source: lost,
                    holders: 0,
                }));
            }
            tracing::info!("drive {address}: reply to '!' lost and the move did not start (S2, S17): '!' again");
            self.core().execute_buffers(address);
        }
    }

    /// `None` when `echo` is the telegram `sent` (as a drive answers with P196's address prefix when
    /// `prefixed`); otherwise the drives that may hold the command: one whose address the echo shows.
    fn echo_differs(address: Address, echo: &Reply, sent: &[u8], prefixed: bool) -> Option<u32> {
        let from = echo.address();
        let from_ok = if prefixed { from == Some(address.get()) } else { from.is_none() };
        if from_ok && echo.text() == sent {
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
