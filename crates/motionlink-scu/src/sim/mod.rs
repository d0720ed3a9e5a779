//! An emulator of the SCU control unit as its manual describes it: a sans-IO state machine (bytes in at a time,
//! bytes out) with a simple physical model of up to six actuators.
//!
//! ```
//! use motionlink_scu::sim::{Emulator, SimConfig};
//! use motionlink_scu::wire::{request_to_vec, Request};
//! use motionlink_link::emulator::Emulator as _;
//! use motionlink_link::Timestamp;
//!
//! let mut unit = Emulator::new(SimConfig::default()).unwrap();
//! let mut out = Vec::new();
//! unit.receive(Timestamp::ZERO, &request_to_vec(&Request::Open { safety_id: 0 }).unwrap(), &mut out);
//! assert_eq!(&out[..3], b"RO\x06"); // ACK
//! ```
//!
//! # Behaviour
//!
//! - Remote mode: RO opens it with a Safety_ID; an RC must come before any other command (PE until then);
//!   RG, RT, RC, RE and RS outside remote mode are refused with PE. RA leaves remote mode (ACK also outside it)
//!   and fast-stops remote motions still running (the manual is silent; a motion nobody can stop is worse).
//! - The RC watchdog: if no RC comes for 500 ms in remote mode, error bit 22 is recorded and, depending on
//!   the Safety_ID, all motions (0, 1) or the remote motions (2) are fast-stopped (the RO row of E 4.1 / S
//!   4.1). With Safety_ID 0 only RC, RA and RO are accepted afterwards, until a new RO (the RO row). With 1
//!   and 2 the unit deactivates remote mode, as chapter 5 says ("the SCU will stop all drives in motion and
//!   deactivate the remote mode", E 5.1, S 5): RG, RT, RC, RE and RS are refused with PE until a new RO
//!   ([`Variant::RcRearmsWatchdog`]: refused until the next RC, which re-arms the watchdog).
//! - Error replies: a CRC mismatch gets CSE, an unknown command ICE, bad parameter values PDE, a wrong data
//!   length PCE, a command the present state forbids PE. A telegram left incomplete for 1000 ms is dropped.
//! - RT writes only remote data (0x3xxx; entries or whole 0x3xxx groups): any other index is PDE, a value out
//!   of range (speed above 100 % or 1000 counts/s) PDE, a wrong length PCE.
//! - RC with a cyclic object (index 0..4 = CyclicObj 1..5) writes its write data and answers with its read
//!   data; RC with index 0xFF answers with the status alone.
//! - RE on F1..F10 moves the actuators the parameterisation assigns to the function, to the position the
//!   motion_direction names (9: the remote position of each actuator), at the function's remote speed, with a
//!   soft start ramp. RS stops it (0 fast, 1 along the ramp). F11 buzzer, F17/F18 binary outputs, F21/F22 the
//!   operating unit's LEDs are switched on by RE and off by RS: the buzzer shows in 0x0140, the outputs in
//!   0x0110 (bits 0 and 1), the LEDs in the hand switch's 0x0120 (bits 0 and 1). F20 emergency stop fast-stops
//!   everything; while it is on, motion functions are refused (PE), every function shows as locked in Lock
//!   Status and the release flags of actuator status 2 are cleared. [`SimConfig::failed_switches`] (and
//!   [`Emulator::fail_switch`]) make a switching function's output fail: RE and RS acknowledged, nothing
//!   switched.
//! - Every data-list index answers: positions, status bits (motion, in/out position reached, limit signals),
//!   currents and their maxima, speeds, cumulated stroke, relay cycle counters, error codes with a history of
//!   five, and fixed plausible values for the rest.
//! - A motion never passes the stroke ends, nor the virtual limits of UserPositionData (0x2001..0x2006; both 0
//!   means none): a target beyond them is clamped, as a unit stops at its limits. A new remote speed (RT of
//!   0x3011..0x301A) changes the running remote motions of that function along the ramp ("the speed can be
//!   changed during motion"); a new remote position takes effect with the next RE.
//! - Errors (Error_Code 1 is the newest of a history of five): a drive that stays stalled (below
//!   `stall_below_percent`, or pushing against a configured `obstacle_counts`) for `stall_error_after_ms`
//!   (5 s by default) stops with its drive error bit (15 + n - 1); a total current above
//!   `total_current_limit_deci_amps` sets bit 14 and fast-stops every drive; `[[error]]` entries of the
//!   configuration raise a chosen bit at a chosen time. Reactions follow the manual's table (a drive error
//!   stops its drive; bits 1..5 reset the unit, which ends remote mode and initialises the remote data with
//!   their presets: remote speeds the configured function speed, remote positions memory 1 of user 1,
//!   cyclic objects -1; the other bits stop every motion). After the bits whose reaction is that motions are
//!   not performed (8, 13, 24..32: [`MOTIONS_NOT_PERFORMED`]) no motion starts as long as the emulator runs
//!   (the manual names nothing that clears them; a reset does not): an RE of a motion function is refused
//!   with PE, "command not possible with SCU mode/state" ([`Variant::AckWithoutMotion`]: acknowledged,
//!   nothing moves), and the hand switch moves nothing. Bit 13 ("control unit switches itself off") is
//!   emulated as such an error: the unit goes on answering, so that its error code can be read.
//!   When the next motion starts (an RE of a motion function with a direction other than 0, or the hand
//!   switch), bits 14..21 ("bit reset on next motion") leave Error_Code 1; the other bits stay, and the
//!   history keeps what happened.
//! - Variants ([`SimConfig::variants`], [`Variant`]): a unit whose firmware does what the manual leaves open
//!   the other plausible way (refuses grouping indices, UserPositionData or cyclic objects, ...).
//! - Events ([`Emulator::take_events`], printed by `motionlink sim scu --events`): remote mode opened, closed
//!   or ended by the watchdog, a function started or stopped, an actuator at rest with its position, an error
//!   bit set or reset, a switching function on or off.

use std::time::Duration;

use motionlink_link::emulator::Emulator as EmulatorTrait;
use motionlink_link::Timestamp;

use crate::model::{error_bits, item, Actuator, CyclicObject, DataIndex, ErrorCode, SafetyId, Status1Flag, UNUSED};
use crate::value::SpeedMode;
use crate::wire::{Command, Incoming, Request, RequestDecoder, Status, MAX_REPLY_LEN};

mod actuator;
mod commands;
mod config;
mod data;
#[cfg(test)]
mod tests;
mod variants;

pub use crate::model::timing::{INTER_BYTE_LIMIT, WATCHDOG};
use actuator::{ActuatorState, Origin};
pub use config::{ActuatorConfig, ScheduledError, SimConfig, SimConfigError};
pub use motionlink_link::emulator::FirmwareVariant;
pub use variants::{UnknownVariant, Variant, SLEEP_AFTER};

/// Step of the physical model.
const STEP: Duration = Duration::from_millis(5);

/// Remote mode of the unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RemoteMode {
    /// Normal mode: only RO and RA are accepted (also after a watchdog expiry with Safety_ID 1 or 2, which
    /// deactivates remote mode).
    Off,
    /// Opened by RO; waiting for the first RC.
    AwaitingRc(SafetyId),
    /// Remote mode with a running watchdog.
    Active(SafetyId),
    /// The watchdog expired with Safety_ID 0: only RC, RA and RO are accepted until RO.
    Locked,
    /// The watchdog expired with Safety_ID 1 or 2 on a unit of [`Variant::RcRearmsWatchdog`]: the next RC
    /// re-arms it (by default the unit deactivates remote mode then: [`RemoteMode::Off`]).
    TimedOut(SafetyId),
}

/// Counters of what the emulator saw, for tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SimStats {
    /// Telegrams answered (with any status).
    pub telegrams: u64,
    /// RC telegrams accepted.
    pub cyclic: u64,
    /// Watchdog expiries.
    pub watchdog_expiries: u64,
    /// Telegrams with a wrong CRC.
    pub crc_errors: u64,
    /// Garbage bytes skipped.
    pub garbage_bytes: u64,
    /// Partial telegrams dropped after the inter-byte limit.
    pub dropped_partial: u64,
}

/// The emulated SCU control unit. See the [module documentation](self) for its behaviour.
#[derive(Debug)]
pub struct Emulator {
    config: SimConfig,
    decoder: RequestDecoder,
    last_byte: Option<Timestamp>,
    now: Timestamp,
    mode: RemoteMode,
    last_rc: Timestamp,
    actuators: Vec<ActuatorState>,
    /// Functions executed with RE and not yet stopped with RS.
    executed: [bool; 22],
    remote_speed: [u16; 10],
    remote_position: [i32; 6],
    cyclic_objects: [CyclicObject; 5],
    /// Error_Code 1..5: last recent first.
    error_history: [u32; 5],
    /// The bits raised whose reaction is that motions are not performed ([`MOTIONS_NOT_PERFORMED`]): while
    /// any stands, no motion starts.
    standing_errors: u32,
    binary_outputs: u8,
    led_hand_switch: u8,
    buzzer: bool,
    emergency_stop: bool,
    keys: u32,
    /// Total over-current events (0x008F).
    total_over_current_count: u32,
    /// The highest total current of all actuators together, in 0.1 A (0x00BF).
    max_total_current: u16,
    stats: SimStats,
    reply: Vec<u8>,
    /// What happened, for [`Emulator::take_events`]; the oldest are dropped beyond [`MAX_EVENTS`].
    events: std::collections::VecDeque<String>,
    /// Whether each actuator was moving when last looked at (to report when it comes to rest).
    was_moving: [bool; 6],
    /// The scheduled errors, by time, and how many of them were raised.
    scheduled_errors: Vec<ScheduledError>,
    scheduled_raised: usize,
    /// When the last byte came (for [`Variant::Sleepy`]).
    last_rx: Option<Timestamp>,
    /// A [`Variant::Sleepy`] unit dozed off: the next telegram only wakes it.
    dozing: bool,
    /// A [`Variant::LowPower`] unit in low-power mode: it takes no telegram until a break of at least
    /// 100 ms wakes it ([`Emulator::line_break`](motionlink_link::emulator::Emulator::line_break)).
    low_power: bool,
    /// Said once per low-power spell: a telegram came and was not taken.
    low_power_said: bool,
    /// Entries whose RG is refused with PDE ([`Emulator::refuse_reads`]).
    refused_reads: Vec<DataIndex>,
}

/// The most events an emulator keeps for [`Emulator::take_events`] (a host that never takes them loses the
/// oldest).
pub const MAX_EVENTS: usize = 1024;

/// Error bits the manual resets on the next motion: 14 (total current), 15..20 (drives 1..6), 21 (position
/// difference of synchronised drives).
pub const RESET_ON_NEXT_MOTION: u32 = ((1u32 << 21) - 1) & !((1u32 << 13) - 1);

/// Error bits after which the manual's reaction is that motions are not performed: 8 ("Motion not
/// executed"), 13 ("Control unit switches itself off"), 24..30 and 32 ("Motions not performed or stopped"),
/// 31 ("Motions not performed"). While one of them stands (from when it is raised until the emulator is
/// restarted: the manual names nothing that clears them), motions do not start: see
/// [`Emulator::standing_errors`]. Bit 21 ("Motion not started") is not among them: the manual resets it on
/// the next motion ([`RESET_ON_NEXT_MOTION`]).
pub const MOTIONS_NOT_PERFORMED: u32 = (1 << (8 - 1)) | (1 << (13 - 1)) | !((1u32 << 23) - 1);

/// The remote positions a unit starts with: "Default value: memory 1 / user 1 position of UserPositionData".
fn preset_remote_positions(config: &SimConfig) -> [i32; 6] {
    let mut remote_position = [0i32; 6];
    for (slot, a) in remote_position.iter_mut().zip(&config.actuators) {
        *slot = a.user_positions.users[0].memory_counts[0];
    }
    remote_position
}

impl Emulator {
    /// A unit with `config`, powered on at time zero.
    pub fn new(mut config: SimConfig) -> Result<Self, SimConfigError> {
        config.validate()?;
        if config.variants.contains(&Variant::InEndUndershoot) {
            for a in &mut config.actuators {
                a.in_end_undershoot_counts = a.in_end_undershoot_counts.max(3);
            }
        }
        let actuators = config.actuators.iter().cloned().map(ActuatorState::new).collect::<Vec<_>>();
        let remote_position = preset_remote_positions(&config);
        // A battery unit with <Low Power> enabled is in low-power mode from power-on.
        let low_power = config.variants.contains(&Variant::LowPower);
        let mut scheduled_errors = config.scheduled_errors.clone();
        scheduled_errors.sort_by_key(|e| e.at_ms);
        Ok(Emulator {
            remote_speed: [config.default_speed; 10],
            config,
            decoder: RequestDecoder::new(),
            last_byte: None,
            now: Timestamp::ZERO,
            mode: RemoteMode::Off,
            last_rc: Timestamp::ZERO,
            actuators,
            executed: [false; 22],
            remote_position,
            cyclic_objects: [CyclicObject::default(); 5],
            error_history: [0; 5],
            standing_errors: 0,
            binary_outputs: 0,
            led_hand_switch: 0,
            buzzer: false,
            emergency_stop: false,
            total_over_current_count: 0,
            max_total_current: 0,
            keys: 0,
            stats: SimStats::default(),
            reply: Vec::with_capacity(MAX_REPLY_LEN),
            events: std::collections::VecDeque::new(),
            was_moving: [false; 6],
            scheduled_errors,
            scheduled_raised: 0,
            last_rx: None,
            dozing: false,
            low_power,
            low_power_said: false,
            refused_reads: Vec::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The remote mode.
    pub fn mode(&self) -> RemoteMode {
        self.mode
    }

    /// What the emulator saw.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// Actuator `a`'s position in counts as the unit reports it, if connected.
    pub fn position(&self, a: Actuator) -> Option<i32> {
        self.actuators.get(usize::from(a.number()) - 1).map(ActuatorState::reported_position)
    }

    /// True if actuator `a` is moving.
    pub fn is_moving(&self, a: Actuator) -> bool {
        self.actuators.get(usize::from(a.number()) - 1).is_some_and(ActuatorState::moving)
    }

    /// True if any actuator is moving.
    pub fn any_moving(&self) -> bool {
        self.actuators.iter().any(ActuatorState::moving)
    }

    /// Functions started with RE and not yet stopped with RS (manual numbers F1..F22).
    pub fn executed_functions(&self) -> Vec<u8> {
        (0..22u8).filter(|&i| self.executed[usize::from(i)]).map(|i| i + 1).collect()
    }

    /// The most recent error code (Error_Code 1).
    pub fn last_error(&self) -> ErrorCode {
        ErrorCode(self.error_history[0])
    }

    /// When a [`Variant::LowPower`] unit that is awake outside remote mode goes to low-power mode: 2 s
    /// ([`SLEEP_AFTER`]) after the last byte (the manual gives no time; its parameterisation decides).
    fn next_sleep(&self) -> Option<Timestamp> {
        let idle = self.config.variants.contains(&Variant::LowPower) && !self.low_power && self.mode == RemoteMode::Off;
        idle.then(|| self.last_rx.unwrap_or(Timestamp::ZERO) + SLEEP_AFTER)
    }

    /// Goes to low-power mode if [`Emulator::next_sleep`] has come.
    fn fall_asleep(&mut self, now: Timestamp) {
        if self.next_sleep().is_some_and(|t| t <= now) && !self.any_moving() {
            self.low_power = true;
            self.push_event("gone to low-power mode (outside remote mode, 2 s without a byte)".into());
        }
    }

    /// The error bits raised so far whose reaction is that motions are not performed
    /// ([`MOTIONS_NOT_PERFORMED`]): while this is not [`ErrorCode::NONE`], no motion starts (an RE of a motion
    /// function is refused with PE, or acknowledged without motion on a unit of
    /// [`Variant::AckWithoutMotion`]; the hand switch moves nothing). They stand until the emulator is
    /// restarted, whatever Error_Code 1 shows by then.
    pub fn standing_errors(&self) -> ErrorCode {
        ErrorCode(self.standing_errors)
    }

    /// Raises an error now: enters it in the history (Error_Code 1 is the newest) and applies the manual's
    /// reaction: a drive error (bits 15..20) fast-stops that drive; bit 22 (remote time-out) only records;
    /// bits 1..5 stop everything and reset the unit, which leaves remote mode and initialises the remote data
    /// with their preset values; every other defined bit fast-stops every motion, and those whose reaction is
    /// that motions are not performed ([`MOTIONS_NOT_PERFORMED`]) keep any motion from starting from then on
    /// ([`Emulator::standing_errors`]). For tests that need a unit in trouble.
    pub fn inject_error(&mut self, code: ErrorCode) {
        self.record_error(code);
        self.standing_errors |= code.0 & MOTIONS_NOT_PERFORMED;
        let mut stop_all = false;
        let mut reset = false;
        for n in 1..=32u8 {
            if !code.has(n) {
                continue;
            }
            match n {
                15..=20 => {
                    if let Some(a) = self.actuators.get_mut(usize::from(n - error_bits::DRIVE1)) {
                        a.fast_stop();
                        a.error_count += 1;
                    }
                }
                error_bits::TOTAL_CURRENT => {
                    self.total_over_current_count += 1;
                    stop_all = true;
                }
                error_bits::REMOTE_TIMEOUT | 9 | 23 => {}
                1..=5 => {
                    stop_all = true;
                    reset = true;
                }
                _ => stop_all = true,
            }
        }
        if stop_all {
            self.actuators.iter_mut().for_each(ActuatorState::fast_stop);
        }
        if reset {
            self.reset();
        }
        self.note_rest();
    }

    /// The unit carries out a reset (error bits 1..5): it leaves remote mode, and its remote data, "stored in
    /// volatile register. Initialized after reset with preset values" (E 4.4, S 4.3), take their presets:
    /// the remote speeds the function speed from the configuration, the remote positions memory 1 / user 1
    /// of UserPositionData, the cyclic objects -1 (none). What the data list keeps (positions, counters, the
    /// error history) stays, as do the outputs of switching functions (the manual says nothing of them).
    fn reset(&mut self) {
        if self.mode != RemoteMode::Off {
            self.push_event("remote mode ended by a reset of the unit".into());
        }
        self.mode = RemoteMode::Off;
        self.remote_speed = [self.config.default_speed; 10];
        self.remote_position = preset_remote_positions(&self.config);
        self.cyclic_objects = [CyclicObject::default(); 5];
        self.push_event("reset: remote speeds, remote positions and cyclic objects back to their presets".into());
    }

    /// From now on the unit acknowledges the RE and RS of switching function `f` but no longer switches it:
    /// what the data list shows of it stays as it is (a failed output, for tests that need a unit in trouble;
    /// [`SimConfig::failed_switches`] from power-on).
    pub fn fail_switch(&mut self, f: crate::model::Function) {
        if !self.config.failed_switches.contains(&f) {
            self.config.failed_switches.push(f);
        }
    }

    /// From now on RG of `index` is refused with PDE (a unit without that entry, for tests).
    pub fn refuse_reads(&mut self, index: DataIndex) {
        self.refused_reads.push(index);
    }

    /// Presses the hand switch: moves the actuators of motion function `function` (1..10) In or Out as a
    /// local (non-remote) motion, at 100 %. Keys K(2n-1) and K(2n) show as pressed. Nothing happens while the
    /// emergency stop is on or an error stands after which motions are not performed.
    pub fn press_hand_switch(&mut self, function: u8, out: bool) {
        let Some(f) = (1..=10).contains(&function).then(|| usize::from(function) - 1) else { return };
        if self.emergency_stop || self.standing_errors != 0 {
            return;
        }
        self.keys |= 1 << (2 * f + usize::from(out));
        self.reset_errors_on_motion();
        self.push_event(format!("hand switch: F{function} {}", if out { "out" } else { "in" }));
        for a in self.config.functions[f].clone() {
            let i = usize::from(a.number()) - 1;
            let cfg = &self.config.actuators[i];
            let target = if out { cfg.stroke_max_counts } else { cfg.stroke_min_counts };
            let speed = cfg.counts_per_second_at_full_speed;
            self.actuators[i].start(target, speed, 100, Origin::Local, None);
        }
        self.note_rest();
    }

    /// Releases the hand switch: local motions stop along the ramp.
    pub fn release_hand_switch(&mut self) {
        self.keys = 0;
        for a in &mut self.actuators {
            if a.origin == Origin::Local {
                a.soft_stop();
            }
        }
        self.note_rest();
    }

    fn record_error(&mut self, code: ErrorCode) {
        self.error_history.rotate_right(1);
        self.error_history[0] = code.0;
        for b in 1..=32u8 {
            if code.has(b) {
                let cause = crate::model::error_bit(b).map_or("undefined", |e| e.cause());
                self.push_event(format!("error bit {b} set ({cause})"));
            }
        }
    }

    /// A motion starts: the bits the manual resets "on the next motion" (14, 15..20, 21) leave Error_Code 1.
    fn reset_errors_on_motion(&mut self) {
        if self.config.variants.contains(&Variant::StickyErrors) {
            return;
        }
        let cleared = self.error_history[0] & RESET_ON_NEXT_MOTION;
        if cleared == 0 {
            return;
        }
        self.error_history[0] &= !RESET_ON_NEXT_MOTION;
        let bits: Vec<String> = (1..=32u8).filter(|&b| ErrorCode(cleared).has(b)).map(|b| b.to_string()).collect();
        self.push_event(format!("error bit {} reset by the next motion", bits.join(", ")));
    }

    fn push_event(&mut self, text: String) {
        if self.events.len() >= MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back(text);
    }

    /// Reports actuators that came to rest since the last look.
    fn note_rest(&mut self) {
        for i in 0..self.actuators.len() {
            let moving = self.actuators[i].moving();
            if self.was_moving[i] && !moving {
                let p = self.actuators[i].reported_position();
                self.push_event(format!("A{} at rest {p} counts", i + 1));
            }
            self.was_moving[i] = moving;
        }
    }

    /// The next scheduled error's time, if any is left.
    fn next_scheduled_error(&self) -> Option<Timestamp> {
        self.scheduled_errors.get(self.scheduled_raised).map(|e| Timestamp::from_millis(e.at_ms))
    }

    /// Runs the physical model, the watchdog and the scheduled errors up to `to`.
    fn run_until(&mut self, to: Timestamp) {
        while self.now < to {
            let watchdog_at = match self.mode {
                RemoteMode::AwaitingRc(_) | RemoteMode::Active(_) => Some(self.last_rc + WATCHDOG),
                _ => None,
            };
            let timer_at = [watchdog_at, self.next_scheduled_error()].into_iter().flatten().min();
            let mut next = (self.now + STEP).min(to);
            if let Some(w) = timer_at {
                next = next.min(w.max(self.now));
            }
            let dt = (next - self.now).as_secs_f64();
            if dt > 0.0 {
                if self.any_moving() {
                    let mut drive_errors = 0u32;
                    for (i, a) in self.actuators.iter_mut().enumerate() {
                        if a.step(dt) {
                            drive_errors |= 1 << (u32::from(error_bits::DRIVE1) - 1 + i as u32);
                        }
                    }
                    // Summed in u32 (six drives of up to 6553.5 A each); the UINT16 entry 0x00BF reads at
                    // most its maximum, while the limit is compared with the true total.
                    let total_deci_amps: u32 = self.actuators.iter().map(|a| u32::from(a.current())).sum();
                    let total_entry = u16::try_from(total_deci_amps).unwrap_or(u16::MAX);
                    self.max_total_current = self.max_total_current.max(total_entry);
                    self.now = next;
                    if drive_errors != 0 {
                        self.inject_error(ErrorCode(drive_errors));
                    }
                    let limit = self.config.total_current_limit_deci_amps;
                    if limit > 0 && total_deci_amps > u32::from(limit) && self.any_moving() {
                        self.inject_error(ErrorCode::from_bit(error_bits::TOTAL_CURRENT));
                    }
                    self.note_rest();
                } else if to - self.now > STEP {
                    // Nothing moves: jump to the next timer.
                    let jump_to = timer_at.map_or(to, |w| w.min(to)).max(next);
                    self.now = jump_to;
                } else {
                    self.now = next;
                }
            } else {
                self.now = next;
            }
            self.check_watchdog();
            self.raise_scheduled_errors();
        }
    }

    fn raise_scheduled_errors(&mut self) {
        while let Some(e) = self.scheduled_errors.get(self.scheduled_raised).copied() {
            if self.now < Timestamp::from_millis(e.at_ms) {
                break;
            }
            self.scheduled_raised += 1;
            self.inject_error(ErrorCode::from_bit(e.bit));
        }
    }

    fn check_watchdog(&mut self) {
        let safety = match self.mode {
            RemoteMode::AwaitingRc(s) | RemoteMode::Active(s) if self.now >= self.last_rc + WATCHDOG => s,
            _ => return,
        };
        self.stats.watchdog_expiries += 1;
        self.record_error(ErrorCode::from_bit(error_bits::REMOTE_TIMEOUT));
        match safety {
            SafetyId::StopAllAndLock | SafetyId::StopAll => {
                self.actuators.iter_mut().for_each(ActuatorState::fast_stop);
            }
            SafetyId::StopRemoteOnly => {
                self.actuators.iter_mut().filter(|a| a.origin == Origin::Remote).for_each(ActuatorState::fast_stop);
            }
        }
        // Safety_ID 0: "only the RC, RA and RO commands are available" (the RO row). 1 and 2: the row says only
        // which motions stop; chapter 5 says the unit "will stop all drives in motion and deactivate the remote
        // mode" (E 5.1, S 5), and RG, RT, RC, RE and RS are "only available if the remote function is
        // activated", which RO does (E 4.1, S 4.1).
        let rearms = self.config.variants.contains(&Variant::RcRearmsWatchdog);
        self.mode = match safety {
            SafetyId::StopAllAndLock => RemoteMode::Locked,
            s if rearms => RemoteMode::TimedOut(s),
            _ => RemoteMode::Off,
        };
        let what = match (safety, rearms) {
            (SafetyId::StopAllAndLock, _) => "all motions stopped; remote motion locked until RO",
            (SafetyId::StopAll, true) => "all motions stopped; the next RC re-arms it",
            (SafetyId::StopRemoteOnly, true) => "remote motions stopped; the next RC re-arms it",
            (SafetyId::StopAll, false) => "all motions stopped; remote mode deactivated until RO",
            (SafetyId::StopRemoteOnly, false) => "remote motions stopped; remote mode deactivated until RO",
        };
        self.push_event(format!("remote mode ended by watchdog (Safety_ID {}): {what}", safety.code()));
        // "If the communication is interrupted at this status the controller sets to low power mode."
        if self.config.variants.contains(&Variant::LowPower) {
            self.low_power = true;
            self.push_event("gone to low-power mode (the communication was interrupted)".into());
        }
        self.note_rest();
    }
}

impl EmulatorTrait for Emulator {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        self.run_until(now);
        if let Some(last) = self.last_byte {
            if self.decoder.is_mid_telegram() && now.saturating_since(last) > INTER_BYTE_LIMIT {
                self.decoder.reset();
                self.stats.dropped_partial += 1;
            }
        }
        if self.low_power {
            if !bytes.is_empty() && !std::mem::replace(&mut self.low_power_said, true) {
                self.push_event("in low-power mode: telegrams go unanswered until a break of 100 ms wakes it".into());
            }
            return;
        }
        if !bytes.is_empty() {
            self.last_byte = Some(now);
            if self.config.variants.contains(&Variant::Sleepy)
                && self.last_rx.is_none_or(|t| now.saturating_since(t) >= SLEEP_AFTER)
            {
                self.dozing = true;
            }
            self.last_rx = Some(now);
        }
        let mut input = bytes;
        loop {
            // Decode into a local copy of the event so the decoder's borrow ends before handling it.
            let mut frame = [0u8; crate::wire::MAX_REQUEST_LEN];
            let (used, event) = self.decoder.decode(input);
            input = &input[used..];
            let Some(event) = event else {
                if input.is_empty() {
                    break;
                }
                continue;
            };
            match event {
                Ok(_) if self.dozing => {
                    self.dozing = false;
                    self.push_event("woken by a telegram, which it does not answer".into());
                }
                Ok(incoming) => {
                    let owned = own_request(incoming, &mut frame);
                    self.handle(owned.as_incoming(&frame));
                }
                Err(crate::wire::WireError::Garbage { count }) => self.stats.garbage_bytes += count as u64,
                Err(crate::wire::WireError::Checksum { command, .. }) => {
                    self.stats.crc_errors += 1;
                    if let Some(c) = command {
                        self.reply_status(c, Status::ChecksumError);
                    }
                }
                Err(
                    crate::wire::WireError::Oversized { command, .. }
                    | crate::wire::WireError::Undersized { command, .. }
                    | crate::wire::WireError::UnexpectedLength { command, .. },
                ) => self.reply_status(command, Status::ParameterCountError),
            }
        }
        out.append(&mut self.reply);
    }

    fn advance(&mut self, now: Timestamp, _out: &mut Vec<u8>) {
        self.run_until(now);
        self.fall_asleep(now);
        if let Some(last) = self.last_byte {
            if self.decoder.is_mid_telegram() && now.saturating_since(last) > INTER_BYTE_LIMIT {
                self.decoder.reset();
                self.stats.dropped_partial += 1;
            }
        }
    }

    /// The unit never speaks unasked, and its state is computed exactly whenever it is looked at; but a
    /// server that reports events wants to look when something happens: while an actuator moves (every
    /// model step), when the watchdog would expire, when a scheduled error is due.
    fn next_wakeup(&self) -> Option<Timestamp> {
        let watchdog = match self.mode {
            RemoteMode::AwaitingRc(_) | RemoteMode::Active(_) => Some(self.last_rc + WATCHDOG),
            _ => None,
        };
        let motion = self.any_moving().then(|| self.now + STEP);
        [watchdog, motion, self.next_scheduled_error(), self.next_sleep()].into_iter().flatten().min()
    }

    /// One line per notable change since the last call, oldest first: remote mode opened, closed or ended by
    /// the watchdog; a function started ("F1 started direction 9 ...") or stopped; an actuator at rest
    /// ("A1 at rest 400 counts"); an error bit set or reset; a switching function on or off.
    fn take_events(&mut self) -> Vec<String> {
        self.events.drain(..).collect()
    }

    /// A telegram the host left half-sent is dropped; remote mode, its watchdog and any motion go on.
    fn connection_closed(&mut self, _now: Timestamp) {
        self.decoder.reset();
    }

    /// A break (RxD held at space): one of at least 100 ms wakes a [`Variant::LowPower`] unit from low-power
    /// mode (E 3, S 3, from FW V2B1). A telegram in progress is dropped (the break is no byte of it).
    fn line_break(&mut self, now: Timestamp, duration: std::time::Duration) {
        self.run_until(now);
        self.decoder.reset();
        if !self.low_power {
            return;
        }
        if duration >= crate::config::MIN_WAKE_BREAK {
            self.low_power = false;
            self.low_power_said = false;
            // Awake from now: the 2 s without a byte that put it to sleep count from the break.
            self.last_rx = Some(now + duration);
            self.push_event(format!("woken from low-power mode by a break of {} ms", duration.as_millis()));
        } else {
            self.push_event(format!(
                "a break of {} ms is too short to wake it from low-power mode (100 ms)",
                duration.as_millis()
            ));
        }
    }
}

/// A request copied out of the decoder's buffer, so the emulator can borrow itself mutably to handle it.
enum OwnedIncoming {
    Unknown([u8; 2]),
    Open(u8),
    Abort,
    Cyclic { object: u8, len: usize },
    Get(u16),
    Transfer { index: u16, len: usize },
    Execute(u8, [u8; 2]),
    Stop(u8, u8),
}

fn own_request(incoming: Incoming<'_>, frame: &mut [u8]) -> OwnedIncoming {
    match incoming {
        Incoming::UnknownCommand { code } => OwnedIncoming::Unknown(code),
        Incoming::Request(r) => match r {
            Request::Open { safety_id } => OwnedIncoming::Open(safety_id),
            Request::Abort => OwnedIncoming::Abort,
            Request::Cyclic { object, write } => {
                frame[..write.len()].copy_from_slice(write);
                OwnedIncoming::Cyclic { object, len: write.len() }
            }
            Request::Get { index } => OwnedIncoming::Get(index),
            Request::Transfer { index, data } => {
                frame[..data.len()].copy_from_slice(data);
                OwnedIncoming::Transfer { index, len: data.len() }
            }
            Request::Execute { function, params } => OwnedIncoming::Execute(function, params),
            Request::Stop { function, param } => OwnedIncoming::Stop(function, param),
        },
    }
}

impl OwnedIncoming {
    fn as_incoming<'a>(&self, frame: &'a [u8]) -> Incoming<'a> {
        Incoming::Request(match *self {
            OwnedIncoming::Unknown(code) => return Incoming::UnknownCommand { code },
            OwnedIncoming::Open(safety_id) => Request::Open { safety_id },
            OwnedIncoming::Abort => Request::Abort,
            OwnedIncoming::Cyclic { object, len } => Request::Cyclic { object, write: &frame[..len] },
            OwnedIncoming::Get(index) => Request::Get { index },
            OwnedIncoming::Transfer { index, len } => Request::Transfer { index, data: &frame[..len] },
            OwnedIncoming::Execute(function, params) => Request::Execute { function, params },
            OwnedIncoming::Stop(function, param) => Request::Stop { function, param },
        })
    }
}
