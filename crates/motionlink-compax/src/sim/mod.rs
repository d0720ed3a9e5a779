//! An emulator of a COMPAX RS485 bus: up to 31 drives on one byte stream, as one sans-IO
//! [`motionlink_link::emulator::Emulator`].
//!
//! Every drive hears every byte and frames it with its own P196 mode; the addressed one answers, a broadcast
//! (32) is executed by all and answered by none. Each drive has P194 / P195 / P196 (valid from power-on, as
//! the manual's table says: see [`Emulator::power_cycle`]), the 40-character input buffer (E71), the BCC
//! check (E72), timeout supervision (E73 after five character times of silence at its baud rate), parity
//! errors on demand (E70, [`Emulator::inject_parity_error`]), echo, no-reply, buffer and execute, the `$`
//! message when a position is reached, E92 for a move while moving, the binary commands, XON/XOFF, and a
//! motion model that the status values follow.
//!
//! The motion model: a trapezoidal profile computed in 1 ms steps from the timestamps the emulator is given
//! (it never reads a clock). The speed is `SPEED` percent of a maximum speed (100 units/s by default); `ACCEL`
//! is the time to ramp from standstill to the maximum speed (so the ramp rate does not change with SPEED),
//! `ACCEL-` the braking time alone; 0 ms is an instant ramp. SPEED / ACCEL / comparators / speed steps sent
//! during a positioning apply to the next one, as the user guide says of "preparatory" commands.
//!
//! Choices where the manuals are silent (see also the crate's decisions):
//! - A drive answers a command it cannot parse, a value out of range, `!` with an empty buffer, or a move
//!   while switched off with [`REFUSED`] (E90): the code a real drive uses for these is not in our sources.
//!   The RS485 manual lists only E70..E74, and no code for an invalid parameter or status number.
//! - Parameters: the manual defines P194..P196 only. A read or write of any other parameter is refused with
//!   E90, unless the configuration lists it ([`SimConfig::params`]); nothing reads as a made-up 0. P003 is
//!   the exception: the user guide writes it in its example (`P003=-1055.88`), so every drive models it (0
//!   at power-on; its meaning is not in our sources).
//! - Switched off (`OUTPUT O0=0`, or 2): S16 shows it (bits 7 / 8), S17 "RUN" is clear, a running
//!   positioning ends where the axis is, and every move is refused with E90 until `OUTPUT O0=1`.
//! - Events ([`take_events`](motionlink_link::emulator::Emulator::take_events), shown by `motionlink sim compax --events`): a positioning started
//!   or ended (`drive 1 at rest 12.500`), the drive switched off or on, an error recorded in S18.
//! - Status values the emulator does not model (S4, S5, S11, S13..S15, S19..S30, S33..S40) are refused with
//!   E90 rather than answered with 0.
//! - S18 (the last eight errors, newest first) records every error a drive meets (E70..E73, E90, E92, ...),
//!   also those of telegrams it does not answer; E70..E73 are followed by 99 (acknowledged) at the next
//!   error-free transmission, as the manual's chapter 6 says they need no acknowledgement.
//! - A drive with a baud rate (P195) other than the line's hears only noise: it never answers.
//! - A drive with address 0 (the factory setting) answers nothing, but executes broadcasts.

mod config;
mod drive;
mod telegram;
#[cfg(test)]
mod tests;
mod variant;

pub use config::{DriveConfig, SimConfig, SimConfigError};
pub use drive::Drive;
pub use motionlink_link::emulator::FirmwareVariant;
pub use variant::{UnknownVariant, Variant, QUEUE_DEPTH, SLOW_REPLY_DELAY};

use std::collections::VecDeque;
use std::time::Duration;

use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::Emulator as EmulatorTrait;

use crate::model::ErrorCode;

/// The error the emulator answers to a command it refuses for a reason the manuals give no code for (syntax,
/// range, empty buffer, drive switched off). Not a documented COMPAX code.
pub const REFUSED: ErrorCode = ErrorCode(90);

/// P003, the parameter of the user guide's example of a write (`P003=-1055.88`): every emulated drive
/// models it (0 at power-on), so the example in docs/compax.md works against the emulator. Its meaning is not
/// in our sources; the emulator stores it as a plain number.
pub(crate) const USER_GUIDE_EXAMPLE_PARAM: u16 = 3;

/// The motion model's step.
pub(crate) const TICK: Duration = Duration::from_millis(1);

/// The emulated bus of COMPAX drives: one [`Emulator`](motionlink_link::emulator::Emulator) on the byte
/// stream.
///
/// ```
/// use motionlink_compax::sim::{Emulator, SimConfig};
/// use motionlink_link::{clock::Timestamp, emulator::Emulator as _};
/// let mut bus = Emulator::new(SimConfig::bus(&[1, 5], 0, 9600)).unwrap();
/// let mut out = Vec::new();
/// bus.receive(Timestamp::ZERO, b"5S1\r", &mut out);
/// assert_eq!(out, b"S001: 0.000\r\n>");
/// ```
#[derive(Debug, Clone)]
pub struct Emulator {
    drives: Vec<Drive>,
    line_baud: u32,
    parity_error_next: bool,
    /// What the drives said, held back until it is due ([`Variant::SlowReplies`]), oldest first.
    delayed: VecDeque<(Timestamp, Vec<u8>)>,
}

impl Emulator {
    /// A bus as `config` describes.
    pub fn new(config: SimConfig) -> Result<Self, SimConfigError> {
        config.validate()?;
        let drives = config.drives.iter().map(|d| Drive::new(d, &config)).collect();
        Ok(Emulator { drives, line_baud: config.baud_rate, parity_error_next: false, delayed: VecDeque::new() })
    }

    /// The drive whose address in force is `address`.
    pub fn drive(&self, address: u8) -> Option<&Drive> {
        self.drives.iter().find(|d| d.address == address)
    }

    /// Every drive.
    pub fn drives(&self) -> &[Drive] {
        &self.drives
    }

    /// Switches every drive off and on at `now`: written P194 / P195 / P196 take effect, motions end.
    pub fn power_cycle(&mut self, now: Timestamp) {
        for d in &mut self.drives {
            d.update(now);
            d.power_cycle(now);
        }
    }

    /// The next byte received has a parity error (for drives whose P196 has parity on): the addressed drive
    /// answers E70.
    pub fn inject_parity_error(&mut self) {
        self.parity_error_next = true;
    }

    /// The line's baud rate.
    pub fn line_baud(&self) -> u32 {
        self.line_baud
    }

    /// The firmware variants the drives run (those of the first drive: every drive runs the same).
    pub fn variants(&self) -> &[Variant] {
        self.drives.first().map_or(&[], |d| d.variants.as_slice())
    }

    /// Runs every drive as the firmware `variants` say from now on (what they hold stays as it is).
    pub fn set_variants(&mut self, variants: &[Variant]) {
        for d in &mut self.drives {
            d.variants = variants.to_vec();
        }
    }

    /// Hands what the drives said at `now` (`said`, drained) to the line: at once, or, for drives of the
    /// `slow-replies` variant, [`SLOW_REPLY_DELAY`] later (in order); then whatever held back is due by
    /// `now`.
    fn send(&mut self, now: Timestamp, said: &mut Vec<u8>, out: &mut Vec<u8>) {
        if !said.is_empty() {
            if self.variants().contains(&Variant::SlowReplies) {
                self.delayed.push_back((now + SLOW_REPLY_DELAY, std::mem::take(said)));
            } else {
                out.append(said);
            }
        }
        while self.delayed.front().is_some_and(|(due, _)| *due <= now) {
            if let Some((_, bytes)) = self.delayed.pop_front() {
                out.extend_from_slice(&bytes);
            }
        }
    }
}

impl EmulatorTrait for Emulator {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        let mut said = Vec::new();
        for d in &mut self.drives {
            d.update(now);
        }
        for &b in bytes {
            let parity_error = std::mem::take(&mut self.parity_error_next);
            for d in &mut self.drives {
                d.on_byte(now, b, parity_error, self.line_baud, &mut said);
            }
        }
        for d in &mut self.drives {
            d.flush_pending(&mut said);
        }
        self.send(now, &mut said, out);
    }

    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        let mut said = Vec::new();
        for d in &mut self.drives {
            d.update(now);
            d.check_timeout(now, &mut said);
            if d.baud_rate == self.line_baud {
                d.flush_pending(&mut said);
            } else {
                d.pending.clear();
            }
        }
        self.send(now, &mut said, out);
    }

    fn next_wakeup(&self) -> Option<Timestamp> {
        let due = self.delayed.front().map(|(due, _)| *due);
        self.drives.iter().filter_map(Drive::next_wakeup).chain(due).min()
    }

    /// Each drive's events since the last call, drive by drive (oldest first within a drive): `drive 1
    /// motion started to 100.000 from 0.000`, `drive 1 at rest 100.000` (a positioning ended: reached, or
    /// ended by switching the drive off), `drive 1 switched off (O0=0)`, `drive 1 switched on (O0=1)`,
    /// `drive 1 homing started from 0.000`, `drive 1 error E92 (...)` (every error recorded in S18),
    /// `drive 1 powered on (switched on, O0=1)`.
    fn take_events(&mut self) -> Vec<String> {
        self.drives.iter_mut().flat_map(|d| std::mem::take(&mut d.events)).collect()
    }

    /// A telegram the host left half-sent is dropped by every drive, and what slow drives had yet to send
    /// is lost with the connection; motion, XON/XOFF and buffers stay.
    fn connection_closed(&mut self, _now: Timestamp) {
        self.parity_error_next = false;
        self.delayed.clear();
        for d in &mut self.drives {
            d.rx.reset();
            d.rx_parity_error = false;
        }
    }
}
