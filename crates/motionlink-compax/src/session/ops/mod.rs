//! The operations of a session, each a state machine written as an `async fn` over a [`Ctx`]: the compiler
//! turns each into an enum of its steps, which the session resumes whenever what a step waits for (a
//! reply, a time, a cancellation) is there: the one executor of `motionlink-link` ([`motionlink_link::exec`])
//! runs them. No thread, no I/O.
//!
//! This file: reads, writes, settings, raw commands, the scan and the watch. [`moves`]: moves, the
//! synchronous start, broadcasts. [`echoed`]: a move stored with its echo, compared, then executed.
//! [`wait`]: waits, checked moves, stops.

mod echoed;
mod moves;
mod wait;

use std::ops::RangeInclusive;
use std::time::Duration;

use super::core::{bit, Effect, Retry};
use super::ctx::Ctx;
use super::types::{s16_of, s17_of, Progress, WatchSample};
use crate::error::{Error, Result};
use crate::model::{
    param_reply_decimals, parse_param_reply, Command, ErrorCode, ModelError, ParamId, Position, S16Bits, S17Bits,
    S17Flag, StatusId, StatusValue,
};
use crate::wire::number::{same_decimal, MAX_DECIMALS};
use crate::wire::{Address, Body, Flags, Mode, Reply, Request};

/// How far apart two readings of S2 (printed with three decimals) must be to count as different, in units.
pub(super) const S2_RESOLUTION: f64 = 0.0015;

/// `v` rounded to `decimals` decimals, to the nearest (as decimal text shows it).
fn rounded(v: f64, decimals: usize) -> f64 {
    format!("{v:.decimals$}").parse().unwrap_or(v)
}

/// `v` cut to `decimals` decimals (the digits after them dropped).
fn truncated(v: f64, decimals: usize) -> f64 {
    let text = format!("{v:.prec$}", prec = MAX_DECIMALS + 3);
    let cut = text.find('.').map_or(text.len(), |i| if decimals == 0 { i } else { (i + 1 + decimals).min(text.len()) });
    text[..cut].parse().unwrap_or(v)
}

/// What a scan says of address `a` when an error answered its S1: the error, which names the drive once.
pub(crate) fn scan_warning(a: Address, e: &Error) -> String {
    match e {
        Error::Refused { .. } | Error::UnexpectedReply { .. } => e.to_string(),
        _ => format!("drive {a}: {e}"),
    }
}

/// What a scan says once of the addresses whose S1 was answered with a BCC error (E72) although the session
/// sends no BCC: a drive on the bus checks one, so the drives' P196 is not the session's. Such a drive waits
/// after the CR for a BCC that never comes, takes the next telegram's first byte for it and answers then:
/// the answer comes while another address is asked, and without the reply address (valence 64) nothing tells
/// whose it is.
pub(crate) fn bcc_mismatch_warning(mode: &Mode, addresses: &[Address]) -> String {
    let list: Vec<String> = addresses.iter().map(|a| a.to_string()).collect();
    let s = if list.len() == 1 { "" } else { "es" };
    format!(
        "E72 (BCC error) answered S1 at address{s} {}, although this client sends no BCC (P196 {} has no valence \
         8): a drive on the bus checks a BCC, so the drives' P196 is another (with valence 8); a drive that waits \
         for a BCC answers when the next telegram begins, so these answers may all come from another drive, late",
        list.join(", "),
        mode.to_p196()
    )
}

impl Ctx {
    /// Sends `cmd` to `address` with `flags`. A command that is not idempotent (a POSR, a comparator) is
    /// sent again only after E70 / E72 / E73 (the drive did not take it), also when it is stored (`,`): the
    /// manual does not say that a store replaces the command held, and a buffer that kept both would run a
    /// relative move twice.
    pub(crate) async fn send_command(&self, address: Address, cmd: &Command, flags: Flags) -> Result<Option<Reply>> {
        let style = self.core().cfg.style;
        let text = cmd.to_ascii(style)?;
        let retry = if cmd.is_idempotent() { Retry::Idempotent } else { Retry::DiscardedOnly };
        self.exchange(&Request { address, body: Body::Command(text.as_bytes()), flags }, retry).await
    }

    /// Sends a command whose answer is wanted, sent again at most `retries` times; refuses the broadcast
    /// address (nobody answers it).
    async fn ask(&self, address: Address, cmd: &Command, what: &'static str, retries: u32) -> Result<Reply> {
        if address.is_broadcast() {
            return Err(Error::Broadcast(what));
        }
        let style = self.core().cfg.style;
        let text = cmd.to_ascii(style)?;
        let req = Request { address, body: Body::Command(text.as_bytes()), flags: Flags::NONE };
        self.exchange_retries(&req, Retry::Idempotent, retries).await?.ok_or(Error::Broadcast(what))
    }

    fn unexpected(address: Address, command: &Command, r: &[u8]) -> Error {
        Error::UnexpectedReply { address, command: command.to_string(), reply: String::from_utf8_lossy(r).into_owned() }
    }

    /// Reads status value `id`, asking again when the reply does not read as that value (without a BCC a
    /// flipped bit can garble a reply beyond recognition), up to the session's retries: a read changes
    /// nothing.
    pub(crate) async fn read_status(&self, address: Address, id: StatusId) -> Result<StatusValue> {
        let retries = self.core().cfg.retries;
        self.read_status_retries(address, id, retries).await
    }

    /// [`Ctx::read_status`] with `retries` instead of the session's.
    pub(crate) async fn read_status_retries(
        &self,
        address: Address,
        id: StatusId,
        retries: u32,
    ) -> Result<StatusValue> {
        let cmd = Command::ReadStatus(id);
        let mut attempts = 0;
        loop {
            attempts += 1;
            let r = self.ask(address, &cmd, "a status value cannot be read from it", retries).await?;
            match StatusValue::parse(id, r.text()) {
                Ok(v) => return Ok(v),
                Err(_) if attempts <= retries => {
                    tracing::info!("drive {address}: {id} answered {:?}, not a value: reading again", r.text_str());
                }
                Err(_) => return Err(Self::unexpected(address, &cmd, r.text())),
            }
        }
    }

    /// Several status values, a cancel ending it between two.
    pub(crate) async fn read_statuses(
        &self,
        address: Address,
        ids: &[StatusId],
    ) -> Result<Vec<(StatusId, StatusValue)>> {
        let mut values = Vec::with_capacity(ids.len());
        for &id in ids {
            self.check_cancel()?;
            values.push((id, self.read_status(address, id).await?));
        }
        Ok(values)
    }

    async fn read_position_value(&self, address: Address, id: StatusId, retries: u32) -> Result<Position> {
        match self.read_status_retries(address, id, retries).await? {
            StatusValue::Position(p) => Ok(p),
            other => Err(Error::UnexpectedReply { address, command: id.to_string(), reply: other.to_string() }),
        }
    }

    /// S1.
    pub(crate) async fn read_position(&self, address: Address) -> Result<Position> {
        let retries = self.core().cfg.retries;
        self.read_position_value(address, StatusId::ACTUAL_POSITION, retries).await
    }

    /// S2.
    pub(crate) async fn read_target(&self, address: Address) -> Result<Position> {
        let retries = self.core().cfg.retries;
        self.read_position_value(address, StatusId::TARGET_POSITION, retries).await
    }

    /// S16.
    pub(crate) async fn read_s16(&self, address: Address) -> Result<S16Bits> {
        let v = self.read_status(address, StatusId::STATUS_BITS_1).await?;
        s16_of(&v).ok_or_else(|| Error::UnexpectedReply { address, command: "S16".into(), reply: v.to_string() })
    }

    /// S17.
    pub(crate) async fn read_s17(&self, address: Address) -> Result<S17Bits> {
        let retries = self.core().cfg.retries;
        self.read_s17_retries(address, retries).await
    }

    /// S17 with `retries` retries.
    pub(crate) async fn read_s17_retries(&self, address: Address, retries: u32) -> Result<S17Bits> {
        let v = self.read_status_retries(address, StatusId::STATUS_BITS_2, retries).await?;
        let s17 = s17_of(&v).ok_or_else(|| Error::UnexpectedReply {
            address,
            command: "S17".into(),
            reply: v.to_string(),
        })?;
        if s17.contains(S17Flag::CommandActive) {
            self.core().command_bit_seen |= bit(address);
        }
        Ok(s17)
    }

    /// Reads parameter `id`, asking again when the reply does not read as a value.
    pub(crate) async fn read_param(&self, address: Address, id: ParamId) -> Result<f64> {
        self.read_param_shown(address, id).await.map(|(v, _)| v)
    }

    /// [`Ctx::read_param`], and how many decimals the drive's reply shows.
    async fn read_param_shown(&self, address: Address, id: ParamId) -> Result<(f64, usize)> {
        let retries = self.core().cfg.retries;
        let cmd = Command::ReadParam(id);
        let mut attempts = 0;
        loop {
            attempts += 1;
            let r = self.ask(address, &cmd, "a parameter cannot be read from it", retries).await?;
            match parse_param_reply(id, r.text()) {
                Ok(v) => return Ok((v, param_reply_decimals(id, r.text()))),
                Err(_) if attempts <= retries => {
                    tracing::info!("drive {address}: {id} answered {:?}, not a value: reading again", r.text_str());
                }
                Err(_) => return Err(Self::unexpected(address, &cmd, r.text())),
            }
        }
    }

    /// Writes parameter `id` (checked against its known range, and that the command carries it, first) and
    /// reads it back. To address 32 the value is written and cannot be read back. A value that reads back
    /// as itself rounded to the decimals the drive shows it with is [`Error::Rounded`] (the drive keeps the
    /// parameter at that step); any other value read back is [`Error::ReadBack`].
    pub(crate) async fn write_param(&self, address: Address, id: ParamId, value: f64) -> Result<()> {
        id.check(value)?;
        self.expect_ack(address, &Command::WriteParam(id, value)).await?;
        if address.is_broadcast() {
            return Ok(());
        }
        let (read, decimals) = self.read_param_shown(address, id).await?;
        // The reply is decimal text: what was written reads back as the same number, at any magnitude.
        if same_decimal(value, read) {
            return Ok(());
        }
        if decimals < MAX_DECIMALS
            && [rounded(value, decimals), truncated(value, decimals)].iter().any(|&r| same_decimal(r, read))
        {
            return Err(Error::Rounded { address, param: id, wrote: value, read, decimals });
        }
        Err(Error::ReadBack { address, param: id, wrote: value, read })
    }

    pub(crate) async fn expect_ack(&self, address: Address, cmd: &Command) -> Result<()> {
        match self.send_command(address, cmd, Flags::NONE).await? {
            Some(r) if !r.text().is_empty() => Err(Self::unexpected(address, cmd, r.text())),
            _ => Ok(()),
        }
    }

    /// A command other than a move; the reply text.
    pub(crate) async fn command(&self, address: Address, cmd: &Command) -> Result<String> {
        if cmd.is_move() {
            return Err(ModelError::Syntax {
                what: "a command (use the move methods for moves)",
                text: cmd.to_string(),
            }
            .into());
        }
        if address.is_broadcast() && matches!(cmd, Command::ReadStatus(_) | Command::ReadParam(_)) {
            return Err(Error::Broadcast("nothing can be read from it"));
        }
        let effect = Effect::of_command(cmd);
        let r = self.send_command(address, cmd, Flags::NONE).await?;
        self.core().after_send(address, effect);
        Ok(r.map(|r| r.text_str().to_string()).unwrap_or_default())
    }

    /// A setting (SPEED, ACCEL, ACCEL-, OUTPUT), ASCII or binary.
    pub(crate) async fn setting(&self, address: Address, cmd: &Command, binary: bool) -> Result<()> {
        if binary {
            let b = cmd.to_binary()?;
            self.exchange(&Request { address, body: Body::Binary(b), flags: Flags::NONE }, Retry::Idempotent).await?;
        } else {
            self.expect_ack(address, cmd).await?;
        }
        self.core().after_send(address, Effect::of_command(cmd));
        Ok(())
    }

    /// Sends `text` as it is; flag characters at its end are sent as flags. Sent again only after E70, E72
    /// or E73. A move or `!` counts as started (for address 32: every drive that has answered); `OUTPUT
    /// O0=0` counts as a stop.
    pub(crate) async fn raw(&self, address: Address, text: &str) -> Result<Option<String>> {
        let Request { body, flags, .. } = Request::raw(address, text);
        let effect = Effect::of_request(&body, flags);
        if effect == Effect::Starts {
            self.check_cancel()?;
        }
        let saved = self.core().before_send(address, effect);
        let executes = matches!(body, Body::Execute) && !flags.echo && !flags.buffer;
        let executed = if executes { Some(self.core().execute_buffers(address)) } else { None };
        let stores_move =
            flags.buffer && matches!(body, Body::Command(t) if Command::parse(t).is_ok_and(|c| c.is_move()));
        match self.exchange(&Request { address, body, flags }, Retry::DiscardedOnly).await {
            Ok(r) => {
                let mut core = self.core();
                if stores_move {
                    // A broadcast store reaches every drive; the session can stop only those it knows.
                    core.buffered |= if address.is_broadcast() { core.known } else { super::core::bit(address) };
                }
                core.after_send(address, effect);
                Ok(r.map(|r| r.text_str().to_string()))
            }
            Err(e @ (Error::Refused { .. } | Error::CancelledBeforeMotion | Error::Encode(_))) => {
                // Refused, or never sent: it started nothing (an axis that was moving before still is), and a
                // `!` executed no buffer.
                {
                    let mut core = self.core();
                    core.unmark(saved);
                    if let Some(executed) = executed {
                        core.unexecute(executed);
                    }
                }
                if effect == Effect::Starts && matches!(e, Error::Refused { .. }) {
                    return Err(self.explain_refused_move(address, e).await);
                }
                Err(e)
            }
            Err(e) => Err(e),
        }
    }

    /// A move `address` refused: if the drive is switched off (S16), that is the reason to give
    /// ([`Error::SwitchedOff`]) rather than the bare code. E92 (the axis still moves) needs no reading.
    pub(crate) async fn explain_refused_move(&self, address: Address, e: Error) -> Error {
        let Error::Refused { code, .. } = e else { return e };
        if code == crate::model::ErrorCode::COMMAND_ACTIVE || address.is_broadcast() {
            return e;
        }
        match self.read_s16(address).await {
            Ok(s16) if s16.o0_state() != 1 => Error::SwitchedOff { address, o0: s16.o0_state(), refused: Some(code) },
            _ => e,
        }
    }

    /// Sends `text` with `?`: the drive sends it back. Whether a drive also carries out what it echoes the
    /// manual does not say: after a lost or corrupt reply, text that is not a command known to be idempotent
    /// (a relative move, a comparator or speed step, or text that is no known command) is not sent again.
    pub(crate) async fn echo(&self, address: Address, text: &str) -> Result<String> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("no echo comes back"));
        }
        let flags = Flags { echo: true, ..Flags::NONE };
        let req = Request { address, body: Body::Command(text.as_bytes()), flags };
        let retry = match Command::parse(text.as_bytes()) {
            Ok(c) if c.is_idempotent() => Retry::Idempotent,
            _ => Retry::DiscardedOnly,
        };
        // A move echoed may have been carried out too (see `Effect::of_request`): it counts as started.
        let effect = Effect::of_request(&req.body, flags);
        if effect == Effect::Starts {
            self.check_cancel()?;
        }
        let saved = self.core().before_send(address, effect);
        match self.exchange(&req, retry).await {
            Ok(r) => Ok(r.map(|r| r.text_str().to_string()).unwrap_or_default()),
            Err(e @ (Error::Refused { .. } | Error::CancelledBeforeMotion | Error::Encode(_))) => {
                self.core().unmark(saved);
                Err(e)
            }
            Err(e) => Err(e),
        }
    }

    /// S1 of every address in `range`, once each (no retries), each announced as [`Progress::Scan`]; a
    /// cancel ends it before the next address.
    pub(crate) async fn scan(&self, range: RangeInclusive<u8>) -> Result<Vec<(Address, Position)>> {
        let mut found = Vec::new();
        let mut result = Ok(());
        let mode = self.core().cfg.mode;
        let mut bcc_errors = Vec::new();
        let addresses: Vec<Address> = range.filter_map(|a| Address::drive(a).ok()).collect();
        for (index, &a) in addresses.iter().enumerate() {
            if let Err(e) = self.check_cancel() {
                result = Err(e);
                break;
            }
            self.progress(Progress::Scan { drive: a, index, of: addresses.len() });
            self.core().last_late = None;
            match self.read_position_value(a, StatusId::ACTUAL_POSITION, 0).await {
                Ok(p) => found.push((a, p)),
                Err(Error::Timeout { waited, .. }) => {
                    // Answered, but too late to be taken (nothing else was sent meanwhile): not counted as
                    // found, and said, so that "no drive answered" is not the whole story.
                    if let Some(took) = self.core().last_late.take() {
                        tracing::warn!(
                            "address {a}: a reply to S1 came {} ms after it was sent, later than the {} ms allowed: \
                             not counted as a drive (a longer reply timeout allows for a drive that slow)",
                            took.as_millis(),
                            waited.as_millis()
                        );
                    }
                }
                Err(Error::Corrupt { .. }) => {}
                Err(e @ (Error::Link(_) | Error::CancelledBeforeMotion)) => {
                    result = Err(e);
                    break;
                }
                Err(Error::Refused { code: ErrorCode::BCC, .. }) if !mode.bcc => bcc_errors.push(a),
                Err(e) => tracing::warn!("{}", scan_warning(a, &e)),
            }
        }
        if !bcc_errors.is_empty() {
            tracing::warn!("{}", bcc_mismatch_warning(&mode, &bcc_errors));
        }
        result.map(|()| found)
    }

    /// S1 and S17 of `drive` every `interval`, reported as progress, until cancelled.
    pub(crate) async fn watch(&self, drive: Address, interval: Duration) -> Result<()> {
        if drive.is_broadcast() {
            return Err(Error::Broadcast("a watch reads one drive's state"));
        }
        let mut next = self.now();
        let tolerance = self.core().cfg.in_position_tolerance;
        let mut previous = None;
        loop {
            if self.is_cancelled() {
                return Ok(());
            }
            let position = self.read_position(drive).await?;
            let s17 = self.read_s17(drive).await?;
            self.progress(Progress::Watch(WatchSample::after(previous, drive, position, s17, tolerance)));
            previous = Some(position);
            next = (next + interval).max(self.now());
            match self.listen_until(next).await {
                Ok(()) => {}
                Err(Error::CancelledBeforeMotion) => return Ok(()),
                Err(e) => return Err(e),
            }
        }
    }

    /// Listens for `d` (a cancel ends it with [`Error::CancelledBeforeMotion`]).
    pub(crate) async fn pause(&self, d: Duration) -> Result<()> {
        let until = self.now() + d;
        self.listen_until(until).await
    }
}
