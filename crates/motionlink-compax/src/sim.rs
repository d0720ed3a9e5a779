//! An emulator of a COMPAX RS485 bus: up to 31 drives on one byte stream, as one sans-IO
//! [`motionlink_link::emulator::Emulator`].
//!
//! Every drive hears every byte and frames it with its own P196 mode; the addressed one answers, a broadcast
//! (32) is executed by all and answered by none. Each drive has P194 / P195 / P196 (valid from power-on, as
//! the manual's table says: see [`CompaxBus::power_cycle`]), the 40-character input buffer (E71), the BCC
//! check (E72), timeout supervision (E73 after five character times of silence at its baud rate), parity
//! errors on demand (E70, [`CompaxBus::inject_parity_error`]), echo, no-reply, buffer and execute, the `$`
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
//! - Events ([`Emulator::take_events`], shown by `motionlink sim compax --events`): a positioning started
//!   or ended (`drive 1 at rest 12.500`), the drive switched off or on, an error recorded in S18.
//! - Status values the emulator does not model (S4, S5, S11, S13..S15, S19..S30, S33..S40) are refused with
//!   E90 rather than answered with 0.
//! - S18 (the last eight errors, newest first) records every error a drive meets (E70..E73, E90, E92, ...),
//!   also those of telegrams it does not answer; E70..E73 are followed by 99 (acknowledged) at the next
//!   error-free transmission, as the manual's chapter 6 says they need no acknowledgement.
//! - A drive with a baud rate (P195) other than the line's hears only noise: it never answers.
//! - A drive with address 0 (the factory setting) answers nothing, but executes broadcasts.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::time::Duration;

use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::Emulator;
use motionlink_link::link::char_time;
use serde::Deserialize;

use crate::model::{
    write_param_reply, Command, ErrorCode, HistoryEntry, ParamId, Position, S16Bits, S17Bits, StatusId, StatusValue,
    BAUD_RATES,
};
use crate::wire::reply::encode_reply;
use crate::wire::request::{Body, ParsedRequest, RequestDecoder, RequestError, RequestEvent, RequestFrame};
use crate::wire::{Mode, TextBuf, BROADCAST};

/// The error the emulator answers to a command it refuses for a reason the manuals give no code for (syntax,
/// range, empty buffer, drive switched off). Not a documented COMPAX code.
pub const REFUSED: ErrorCode = ErrorCode(90);

/// P003, the parameter of the user guide's example of a write (`P003=-1055.88`): every emulated drive
/// models it (0 at power-on), so the example in the README works against the emulator. Its meaning is not
/// in our sources; the emulator stores it as a plain number.
const USER_GUIDE_EXAMPLE_PARAM: u16 = 3;

/// The motion model's step.
const TICK: Duration = Duration::from_millis(1);

/// A configuration error of the emulator.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("emulator configuration: {0}")]
pub struct SimConfigError(pub String);

/// One emulated drive's settings at power-on.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveConfig {
    /// P194, 1..=31 (0: answers nothing).
    pub address: u8,
    /// P195, bit/s (default: the line's baud rate).
    #[serde(default)]
    pub baud_rate: Option<u32>,
    /// P196 (default: the bus's mode).
    #[serde(default)]
    pub p196: Option<u32>,
    /// The position at power-on, in the drive's unit.
    #[serde(default)]
    pub position: f64,
}

/// The emulated bus.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// The line's baud rate (the rate the host sends at).
    #[serde(default = "default_baud")]
    pub baud_rate: u32,
    /// P196 of every drive that does not set its own.
    #[serde(default)]
    pub p196: u32,
    /// The speed of SPEED 100, in position units per second.
    #[serde(default = "default_max_speed")]
    pub max_speed_units_per_s: f64,
    /// The drives.
    #[serde(default = "default_drives", rename = "drive")]
    pub drives: Vec<DriveConfig>,
    /// Parameters besides P194..P196 that every drive models, with their values at power-on (`P12 = 0.0`).
    /// The manual defines only P194..P196: a drive answers a read or write of any other parameter with
    /// [`REFUSED`] (E90) unless it is listed here.
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
}

fn default_baud() -> u32 {
    9600
}
fn default_max_speed() -> f64 {
    100.0
}
fn default_drives() -> Vec<DriveConfig> {
    vec![DriveConfig { address: 1, baud_rate: None, p196: None, position: 0.0 }]
}

impl Default for SimConfig {
    /// One drive at address 1, 9600 baud, P196 = 0, 100 units/s.
    fn default() -> Self {
        SimConfig {
            baud_rate: 9600,
            p196: 0,
            max_speed_units_per_s: 100.0,
            drives: default_drives(),
            params: BTreeMap::new(),
        }
    }
}

impl SimConfig {
    /// Drives at `addresses`, every one with `p196` at `baud_rate`.
    pub fn bus(addresses: &[u8], p196: u32, baud_rate: u32) -> Self {
        SimConfig {
            baud_rate,
            p196,
            max_speed_units_per_s: 100.0,
            drives: addresses
                .iter()
                .map(|&address| DriveConfig { address, baud_rate: None, p196: None, position: 0.0 })
                .collect(),
            params: BTreeMap::new(),
        }
    }

    /// Lets every drive model parameter `id` (besides P194..P196), starting at `value`.
    pub fn with_param(mut self, id: ParamId, value: f64) -> Self {
        self.params.insert(id.to_string(), value);
        self
    }

    /// The extra parameters as numbers (see [`SimConfig::params`]).
    fn param_ids(&self) -> Result<Vec<(ParamId, f64)>, SimConfigError> {
        self.params
            .iter()
            .map(|(name, &v)| {
                let id = ParamId::parse(name).map_err(|e| SimConfigError(format!("params: {e}")))?;
                if id.info().is_some() {
                    return Err(SimConfigError(format!("params: {id} is set by the drive's own settings")));
                }
                id.check(v).map_err(|e| SimConfigError(format!("params: {e}")))?;
                Ok((id, v))
            })
            .collect()
    }

    /// Reads a TOML configuration:
    ///
    /// ```toml
    /// baud_rate = 9600
    /// p196 = 8
    /// max_speed_units_per_s = 100.0
    /// params = { P12 = 0.0 }
    /// [[drive]]
    /// address = 1
    /// [[drive]]
    /// address = 5
    /// position = 12.5
    /// ```
    pub fn from_toml(text: &str) -> Result<Self, SimConfigError> {
        let c: SimConfig = toml::from_str(text).map_err(|e| SimConfigError(e.to_string()))?;
        c.validate()?;
        Ok(c)
    }

    /// Checks addresses (unique, 0..=31), baud rates and modes.
    pub fn validate(&self) -> Result<(), SimConfigError> {
        let err = |m: String| Err(SimConfigError(m));
        if self.drives.is_empty() || self.drives.len() > 31 {
            return err(format!("{} drives: a bus has 1 to 31", self.drives.len()));
        }
        if !(self.max_speed_units_per_s.is_finite() && self.max_speed_units_per_s > 0.0) {
            return err(format!("max_speed_units_per_s = {} must be positive", self.max_speed_units_per_s));
        }
        let mut seen = [false; 32];
        for d in &self.drives {
            if d.address > 31 {
                return err(format!("address {} is not 0..=31 (P194)", d.address));
            }
            if d.address != 0 && std::mem::replace(&mut seen[usize::from(d.address)], true) {
                return err(format!("two drives have address {}", d.address));
            }
            let baud = d.baud_rate.unwrap_or(self.baud_rate);
            if !BAUD_RATES.contains(&baud) {
                return err(format!("baud rate {baud} is not one P195 accepts ({BAUD_RATES:?})"));
            }
            Mode::from_p196(d.p196.unwrap_or(self.p196)).map_err(|e| SimConfigError(e.to_string()))?;
            Position::new(d.position).map_err(|e| SimConfigError(e.to_string()))?;
        }
        if !BAUD_RATES.contains(&self.baud_rate) {
            return err(format!("line baud rate {} is not one P195 accepts", self.baud_rate));
        }
        self.param_ids()?;
        Ok(())
    }
}

/// A command waiting in a drive's buffer (`,`) for `!`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stored {
    Text(TextBuf<48>, bool),
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Comparator {
    distance: f64,
    output: u16,
    state: u8,
    number: u8,
}

/// The settings of the next positioning.
#[derive(Debug, Clone, PartialEq)]
struct MoveSettings {
    speed_percent: f64,
    accel_ms: u16,
    brake_ms: u16,
    comparators: Vec<Comparator>,
    speed_step: Option<(f64, f64)>,
}

/// A positioning in progress.
#[derive(Debug, Clone, PartialEq)]
struct Motion {
    target: f64,
    start: f64,
    /// Speed (units/s, >= 0, towards the target).
    speed: f64,
    last_tick: Timestamp,
    settings: MoveSettings,
    position_message: bool,
    homing: bool,
}

/// One emulated drive.
#[derive(Debug, Clone)]
pub struct Drive {
    params: BTreeMap<u16, f64>,
    address: u8,
    mode: Mode,
    baud_rate: u32,
    rx: RequestDecoder,
    rx_last: Timestamp,
    rx_parity_error: bool,
    buffer: Option<Stored>,
    next: MoveSettings,
    motion: Option<Motion>,
    position: f64,
    target: f64,
    o0: u8,
    outputs: [u8; 17],
    homed: bool,
    reached: bool,
    idle_after_stop: bool,
    motion_cycles: u64,
    history: [u8; 8],
    /// The newest S18 entry is an RS485 error that the next error-free transmission acknowledges.
    auto_ack: bool,
    powered_at: Timestamp,
    /// Unsolicited messages waiting for the line to be free: texts such as `$` or a comparator number.
    pending: Vec<TextBuf<4>>,
    xoff: bool,
    held: Vec<u8>,
    max_speed: f64,
    telegrams: u64,
    /// What happened since the last [`CompaxBus::take_events`](Emulator::take_events), one line each.
    events: Vec<String>,
}

impl Drive {
    fn new(cfg: &DriveConfig, bus: &SimConfig) -> Self {
        let baud = cfg.baud_rate.unwrap_or(bus.baud_rate);
        let p196 = cfg.p196.unwrap_or(bus.p196);
        let mode = Mode::from_p196(p196).unwrap_or_default();
        let mut params = BTreeMap::new();
        params.insert(ParamId::DEVICE_ADDRESS.get(), f64::from(cfg.address));
        params.insert(ParamId::BAUD_RATE.get(), f64::from(baud));
        params.insert(ParamId::OPERATING_MODE.get(), f64::from(p196));
        // The user guide's example of a parameter write (`P003=-1055.88`): every drive models it.
        params.insert(USER_GUIDE_EXAMPLE_PARAM, 0.0);
        // Validated with the configuration.
        for (id, v) in bus.param_ids().unwrap_or_default() {
            params.insert(id.get(), v);
        }
        Drive {
            params,
            address: cfg.address,
            mode,
            baud_rate: baud,
            rx: RequestDecoder::new(&mode),
            rx_last: Timestamp::ZERO,
            rx_parity_error: false,
            buffer: None,
            next: MoveSettings {
                speed_percent: 100.0,
                accel_ms: 0,
                brake_ms: 0,
                comparators: Vec::new(),
                speed_step: None,
            },
            motion: None,
            position: cfg.position,
            target: cfg.position,
            o0: 1,
            outputs: [0; 17],
            homed: false,
            reached: true,
            idle_after_stop: false,
            motion_cycles: 0,
            history: [99; 8],
            auto_ack: false,
            powered_at: Timestamp::ZERO,
            pending: Vec::new(),
            xoff: false,
            held: Vec::new(),
            max_speed: bus.max_speed_units_per_s,
            telegrams: 0,
            events: Vec::new(),
        }
    }

    /// The address in force (P194 at the last power-on).
    pub fn address(&self) -> u8 {
        self.address
    }

    /// The mode in force (P196 at the last power-on).
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The baud rate in force (P195 at the last power-on).
    pub fn baud_rate(&self) -> u32 {
        self.baud_rate
    }

    /// The actual position (S1).
    pub fn position(&self) -> f64 {
        self.position
    }

    /// The target position (S2).
    pub fn target(&self) -> f64 {
        self.target
    }

    /// The current speed in units/s (0 when idle).
    pub fn speed(&self) -> f64 {
        self.motion.as_ref().map_or(0.0, |m| m.speed)
    }

    /// True while a positioning runs (S17 "command active").
    pub fn is_moving(&self) -> bool {
        self.motion.is_some()
    }

    /// The O0 state: 1 switched on (the power-on state), 0 switched off.
    pub fn o0(&self) -> u8 {
        self.o0
    }

    /// The state of output `n` (1..=16).
    pub fn output(&self, n: u16) -> Option<u8> {
        self.outputs.get(usize::from(n)).copied()
    }

    /// A parameter as stored (written values of P194..P196 take effect at power-on); `None` for one the drive
    /// does not model (see [`SimConfig::params`]).
    pub fn param(&self, id: ParamId) -> Option<f64> {
        self.params.get(&id.get()).copied()
    }

    /// The error history S18, newest first (99: acknowledged).
    pub fn history(&self) -> [u8; 8] {
        self.history
    }

    /// Records error `code` in S18. The RS485 errors E70..E73 need no acknowledgement (manual chapter 6):
    /// the next error-free transmission acknowledges them, which S18 shows as 99.
    fn record(&mut self, code: ErrorCode) {
        self.event(format!("error {code}"));
        self.history.rotate_right(1);
        self.history[0] = code.0;
        self.auto_ack = (70..=73).contains(&code.0);
    }

    /// Notes an event of this drive (`drive N ...`) for [`Emulator::take_events`].
    fn event(&mut self, what: String) {
        self.events.push(format!("drive {} {what}", self.address));
    }

    /// Number of telegrams addressed to this drive (or broadcast) that it executed or answered.
    pub fn telegrams(&self) -> u64 {
        self.telegrams
    }

    /// The speed and ramp settings for the next positioning: (percent, accel ms, brake ms).
    pub fn move_settings(&self) -> (f64, u16, u16) {
        (self.next.speed_percent, self.next.accel_ms, self.next.brake_ms)
    }

    fn s16(&self) -> S16Bits {
        let mut b = S16Bits(0);
        b.set(S16Bits::NO_FAULT, true);
        b.set(S16Bits::NO_WARNING, true);
        b.set(S16Bits::MACHINE_ZERO, self.homed);
        b.set(S16Bits::READY_FOR_START, self.o0 == 1 && self.motion.is_none());
        b.set(S16Bits::POSITION_REACHED, self.reached && self.motion.is_none());
        b.set(S16Bits::IDLE_AFTER_STOP, self.idle_after_stop);
        b.set(S16Bits::O0_BIT7, self.o0 == 1);
        b.set(S16Bits::O0_BIT8, self.o0 == 2);
        b
    }

    fn s17(&self) -> S17Bits {
        let mut b = S17Bits(0);
        b.set(S17Bits::COMMAND_ACTIVE, self.motion.is_some());
        b.set(S17Bits::RUN, self.o0 == 1);
        b
    }

    /// Status value `id`, or [`REFUSED`] for one the emulator does not model.
    fn status(&self, id: StatusId, now: Timestamp) -> Result<StatusValue, ErrorCode> {
        let pos = |v: f64| StatusValue::Position(Position::new(v).unwrap_or_default());
        let text = |s: &str| {
            let mut t = TextBuf::new();
            let _ = t.write_str(s);
            StatusValue::Text(t)
        };
        Ok(match id {
            StatusId::ACTUAL_POSITION | StatusId::ABSOLUTE_SENSOR => pos(self.position),
            StatusId::TARGET_POSITION => pos(self.target),
            StatusId::CONTOUR_ERROR => pos(0.0),
            StatusId::TEMPERATURE => StatusValue::Number(35.0),
            StatusId::CONTROL_VOLTAGE => StatusValue::Number(24.0),
            StatusId::DC_LINK_VOLTAGE => StatusValue::Number(560.0),
            StatusId::MOTION_CYCLES => StatusValue::Number(self.motion_cycles as f64),
            StatusId::OPERATING_HOURS => {
                StatusValue::Number(now.saturating_since(self.powered_at).as_secs_f64() / 3600.0)
            }
            StatusId::STATUS_BITS_1 => StatusValue::S16(self.s16()),
            StatusId::STATUS_BITS_2 => StatusValue::S17(self.s17()),
            StatusId::ERROR_HISTORY => StatusValue::History(self.history.map(HistoryEntry::from_number)),
            StatusId::DEVICE_ID_1 => text("COMPAX EMULATOR"),
            StatusId::DEVICE_ID_2 => text("MOTIONLINK"),
            // Not modelled (S4, S5, S11 without programs, S13..S15, S19..S30, S33..S40): refused, not 0.
            _ => return Err(REFUSED),
        })
    }

    /// Runs the motion model up to `now`.
    fn update(&mut self, now: Timestamp) {
        while let Some(m) = self.motion.as_mut() {
            let tick_at = m.last_tick + TICK;
            if tick_at > now {
                break;
            }
            m.last_tick = tick_at;
            let dt = TICK.as_secs_f64();
            let remaining = (m.target - self.position).abs();
            let dir = if m.target >= self.position { 1.0 } else { -1.0 };
            let travelled = (self.position - m.start).abs();
            let mut percent = m.settings.speed_percent;
            if let Some((at, step)) = m.settings.speed_step {
                if travelled >= at {
                    percent = step;
                }
            }
            let cruise = self.max_speed * percent / 100.0;
            let rate = |ms: u16| if ms == 0 { f64::INFINITY } else { self.max_speed / (f64::from(ms) / 1000.0) };
            let accel = rate(m.settings.accel_ms);
            let brake = rate(m.settings.brake_ms);
            let stoppable = (2.0 * brake * remaining).sqrt();
            let want = cruise.min(stoppable);
            m.speed = if m.speed < want { (m.speed + accel * dt).min(want) } else { (m.speed - brake * dt).max(want) };
            let step = m.speed * dt;
            let finished = step >= remaining || remaining < 1e-9;
            let new_pos = if finished { m.target } else { self.position + dir * step };
            let new_travelled = (new_pos - m.start).abs();
            for c in m.settings.comparators.iter().filter(|c| travelled < c.distance && new_travelled >= c.distance) {
                if let Some(o) = self.outputs.get_mut(usize::from(c.output)) {
                    *o = c.state;
                }
                let mut t = TextBuf::new();
                let _ = write!(t, "{}", c.number);
                self.pending.push(t);
            }
            self.position = new_pos;
            if finished {
                let m = self.motion.take().expect("checked above");
                self.reached = true;
                self.motion_cycles += 1;
                self.event(format!("at rest {:.3}", self.position));
                if m.homing {
                    self.homed = true;
                }
                if m.position_message {
                    let mut t = TextBuf::new();
                    let _ = t.write_str("$");
                    self.pending.push(t);
                }
            }
        }
    }

    fn next_wakeup(&self) -> Option<Timestamp> {
        let tick = self.motion.as_ref().map(|m| m.last_tick + TICK);
        let timeout = self.rx_deadline();
        [tick, timeout].into_iter().flatten().min()
    }

    fn rx_deadline(&self) -> Option<Timestamp> {
        (self.mode.timeout_supervision && !self.rx.is_idle() && self.could_be_mine())
            .then(|| self.rx_last + char_time(self.baud_rate, self.mode.parity) * 5)
    }

    /// True while the telegram being received may be addressed to this drive (its address digits so far).
    fn could_be_mine(&self) -> bool {
        let a = self.rx.partial_address();
        self.address != 0 && (a == self.address || (!self.rx.past_address() && a != 0 && self.address / 10 == a))
    }

    fn reply(&mut self, out: &mut Vec<u8>, text: &[u8]) {
        let mut buf = Vec::with_capacity(text.len() + 8);
        encode_reply(&mut buf, &self.mode, self.address, text);
        self.send(out, &buf);
    }

    fn send(&mut self, out: &mut Vec<u8>, bytes: &[u8]) {
        if self.xoff {
            self.held.extend_from_slice(bytes);
        } else {
            out.extend_from_slice(bytes);
        }
    }

    fn flush_pending(&mut self, out: &mut Vec<u8>) {
        if !self.rx.is_idle() || self.pending.is_empty() {
            return;
        }
        for t in std::mem::take(&mut self.pending) {
            self.reply(out, t.as_bytes());
        }
    }

    fn error(&mut self, out: &mut Vec<u8>, code: ErrorCode) {
        self.record(code);
        let mut t = TextBuf::<4>::new();
        let _ = write!(t, "E{:02}", code.0);
        self.reply(out, t.as_bytes());
    }

    /// Checks the telegram timeout at `now`; answers E73 if it expired.
    fn check_timeout(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        if let Some(deadline) = self.rx_deadline() {
            if now >= deadline {
                let mine = self.rx.partial_address() == self.address;
                self.rx.reset();
                self.rx_parity_error = false;
                if mine {
                    self.error(out, ErrorCode::TIMEOUT);
                }
                self.flush_pending(out);
            }
        }
    }

    fn on_byte(&mut self, now: Timestamp, b: u8, parity_error: bool, line_baud: u32, out: &mut Vec<u8>) {
        if self.baud_rate != line_baud {
            return;
        }
        self.check_timeout(now, out);
        self.rx_last = now;
        if parity_error && self.mode.parity != motionlink_link::link::Parity::None {
            self.rx_parity_error = true;
        }
        match self.rx.push(b) {
            None | Some(RequestEvent::Garbage(_)) => {}
            Some(RequestEvent::Flow(xoff)) => {
                self.xoff = xoff;
                if !xoff {
                    let held = std::mem::take(&mut self.held);
                    out.extend_from_slice(&held);
                    self.flush_pending(out);
                }
            }
            Some(RequestEvent::Frame(f)) => {
                let parity = std::mem::take(&mut self.rx_parity_error);
                self.on_frame(now, &f, parity, out);
                self.flush_pending(out);
            }
        }
        if self.rx.is_idle() {
            self.rx_parity_error = false;
        }
    }

    fn on_frame(&mut self, now: Timestamp, f: &RequestFrame, parity_error: bool, out: &mut Vec<u8>) {
        let addr = f.address();
        let broadcast = addr == BROADCAST && f.bytes().len() >= 2 && f.bytes()[..2] == *b"32";
        let mine = self.address != 0 && addr == self.address;
        if !mine && !broadcast {
            return;
        }
        self.telegrams += 1;
        let answer = mine;
        if parity_error {
            if answer {
                self.error(out, ErrorCode::PARITY);
            }
            return;
        }
        let p = match f.parse() {
            Ok(p) => p,
            Err(e) => {
                if answer {
                    let code = match e {
                        RequestError::Bcc { .. } => ErrorCode::BCC,
                        RequestError::Overflow(_) => ErrorCode::BUFFER_OVERFLOW,
                        RequestError::Address(_) | RequestError::AddressTooLong(_) => return,
                        RequestError::Empty | RequestError::Binary(_) => REFUSED,
                    };
                    self.error(out, code);
                }
                return;
            }
        };
        if std::mem::take(&mut self.auto_ack) {
            // An error-free transmission acknowledges the RS485 error (E70..E73) before it.
            self.history.rotate_right(1);
            self.history[0] = 99;
        }
        let answer = answer && !p.flags.no_reply;
        if p.flags.echo {
            if answer {
                let echo = f.bytes().to_vec();
                self.reply(out, &echo);
            }
            return;
        }
        let result = self.execute(now, &p);
        match result {
            Ok(text) if answer => self.reply(out, text.as_bytes()),
            Ok(_) => {}
            Err(code) if answer => self.error(out, code),
            // Unanswered (a broadcast, `/`): the error still happened.
            Err(code) => self.record(code),
        }
    }

    fn execute(&mut self, now: Timestamp, p: &ParsedRequest<'_>) -> Result<TextBuf<48>, ErrorCode> {
        self.update(now);
        match p.body {
            Body::Execute => match self.buffer.take() {
                None => Err(REFUSED),
                Some(Stored::Text(t, dollar)) => {
                    let c = Command::parse(t.as_bytes()).map_err(|_| REFUSED)?;
                    self.run(now, c, dollar)
                }
            },
            Body::Command(text) => {
                let c = Command::parse(text).map_err(|_| REFUSED)?;
                if p.flags.position_message && !c.is_move() {
                    return Err(REFUSED);
                }
                if p.flags.buffer {
                    let mut t = TextBuf::new();
                    let _ = t.write_str(std::str::from_utf8(text).unwrap_or(""));
                    self.buffer = Some(Stored::Text(t, p.flags.position_message));
                    return Ok(TextBuf::new());
                }
                self.run(now, c, p.flags.position_message)
            }
            Body::Binary(b) => {
                let c = Command::from_binary(&b).map_err(|_| REFUSED)?;
                self.run(now, c, false)
            }
        }
    }

    fn run(&mut self, now: Timestamp, c: Command, position_message: bool) -> Result<TextBuf<48>, ErrorCode> {
        let ack = TextBuf::new();
        match c {
            Command::PosA(_) | Command::PosR(_) | Command::PosAHome => {
                if self.motion.is_some() {
                    return Err(ErrorCode::COMMAND_ACTIVE);
                }
                if self.o0 != 1 {
                    return Err(REFUSED);
                }
                let target = match c {
                    Command::PosA(p) => p.units(),
                    Command::PosR(d) => self.target + d.units(),
                    _ => 0.0,
                };
                Position::new(target).map_err(|_| REFUSED)?;
                self.target = target;
                self.reached = false;
                self.idle_after_stop = false;
                let mut settings = self.next.clone();
                // Comparators and speed steps belong to this positioning only.
                self.next.comparators.clear();
                self.next.speed_step = None;
                settings.comparators.sort_by(|a, b| a.distance.total_cmp(&b.distance));
                if c == Command::PosAHome {
                    self.event(format!("homing started from {:.3}", self.position));
                } else {
                    self.event(format!("motion started to {target:.3} from {:.3}", self.position));
                }
                self.motion = Some(Motion {
                    target,
                    start: self.position,
                    speed: 0.0,
                    last_tick: now,
                    settings,
                    position_message,
                    homing: c == Command::PosAHome,
                });
                Ok(ack)
            }
            Command::Speed(s) => {
                self.next.speed_percent = s.percent();
                Ok(ack)
            }
            Command::Accel(ms) => {
                self.next.accel_ms = ms.ms();
                self.next.brake_ms = ms.ms();
                Ok(ack)
            }
            Command::AccelBrake(ms) => {
                self.next.brake_ms = ms.ms();
                Ok(ack)
            }
            Command::Output { output: 0, state } => {
                let was = std::mem::replace(&mut self.o0, state.get());
                if self.o0 != was {
                    self.event(if self.o0 == 1 {
                        "switched on (O0=1)".to_string()
                    } else {
                        format!("switched off (O0={})", self.o0)
                    });
                }
                if self.o0 != 1 && self.motion.take().is_some() {
                    // Switched off: the positioning ends where the axis is.
                    self.target = self.position;
                    self.idle_after_stop = true;
                    self.event(format!("at rest {:.3}", self.position));
                }
                Ok(ack)
            }
            Command::Output { output, state } => {
                *self.outputs.get_mut(usize::from(output)).ok_or(REFUSED)? = state.get();
                Ok(ack)
            }
            Command::PosROutput { distance, output, state } => {
                if usize::from(output) >= self.outputs.len() || output == 0 || self.next.comparators.len() >= 16 {
                    return Err(REFUSED);
                }
                let number = self.next.comparators.len() as u8 + 1;
                self.next.comparators.push(Comparator {
                    distance: distance.units().abs(),
                    output,
                    state: state.get(),
                    number,
                });
                Ok(ack)
            }
            Command::PosRSpeed { distance, speed } => {
                self.next.speed_step = Some((distance.units().abs(), speed.percent()));
                Ok(ack)
            }
            Command::ReadStatus(id) => {
                let mut t = TextBuf::new();
                let _ = self.status(id, now)?.write_reply(id, &mut t);
                Ok(t)
            }
            Command::ReadParam(id) => {
                let mut t = TextBuf::new();
                let _ = write_param_reply(id, self.param(id).ok_or(REFUSED)?, &mut t);
                Ok(t)
            }
            Command::WriteParam(id, v) => {
                id.check(v).map_err(|_| REFUSED)?;
                *self.params.get_mut(&id.get()).ok_or(REFUSED)? = v;
                Ok(ack)
            }
        }
    }

    fn power_cycle(&mut self, now: Timestamp) {
        let p = |id: ParamId| self.params.get(&id.get()).copied().unwrap_or(0.0);
        self.address = p(ParamId::DEVICE_ADDRESS) as u8;
        self.baud_rate = p(ParamId::BAUD_RATE) as u32;
        self.mode = Mode::from_p196(p(ParamId::OPERATING_MODE) as u32).unwrap_or_default();
        self.rx = RequestDecoder::new(&self.mode);
        self.rx_parity_error = false;
        self.buffer = None;
        if self.motion.take().is_some() {
            self.event(format!("at rest {:.3}", self.position));
        }
        self.target = self.position;
        self.o0 = 1;
        self.event("powered on (switched on, O0=1)".to_string());
        self.pending.clear();
        self.xoff = false;
        self.held.clear();
        self.powered_at = now;
    }
}

/// The emulated bus of COMPAX drives: one [`Emulator`] on the byte stream.
///
/// ```
/// use motionlink_compax::sim::{CompaxBus, SimConfig};
/// use motionlink_link::{clock::Timestamp, emulator::Emulator};
/// let mut bus = CompaxBus::new(SimConfig::bus(&[1, 5], 0, 9600)).unwrap();
/// let mut out = Vec::new();
/// bus.receive(Timestamp::ZERO, b"5S1\r", &mut out);
/// assert_eq!(out, b"S001: 0.000\r\n>");
/// ```
#[derive(Debug, Clone)]
pub struct CompaxBus {
    drives: Vec<Drive>,
    line_baud: u32,
    parity_error_next: bool,
}

impl CompaxBus {
    /// A bus as `config` describes.
    pub fn new(config: SimConfig) -> Result<Self, SimConfigError> {
        config.validate()?;
        let drives = config.drives.iter().map(|d| Drive::new(d, &config)).collect();
        Ok(CompaxBus { drives, line_baud: config.baud_rate, parity_error_next: false })
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
}

impl Emulator for CompaxBus {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        for d in &mut self.drives {
            d.update(now);
        }
        for &b in bytes {
            let parity_error = std::mem::take(&mut self.parity_error_next);
            for d in &mut self.drives {
                d.on_byte(now, b, parity_error, self.line_baud, out);
            }
        }
        for d in &mut self.drives {
            d.flush_pending(out);
        }
    }

    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        for d in &mut self.drives {
            d.update(now);
            d.check_timeout(now, out);
            if d.baud_rate == self.line_baud {
                d.flush_pending(out);
            } else {
                d.pending.clear();
            }
        }
    }

    fn next_wakeup(&self) -> Option<Timestamp> {
        self.drives.iter().filter_map(Drive::next_wakeup).min()
    }

    /// Each drive's events since the last call, drive by drive (oldest first within a drive): `drive 1
    /// motion started to 100.000 from 0.000`, `drive 1 at rest 100.000` (a positioning ended: reached, or
    /// ended by switching the drive off), `drive 1 switched off (O0=0)`, `drive 1 switched on (O0=1)`,
    /// `drive 1 homing started from 0.000`, `drive 1 error E92 (...)` (every error recorded in S18),
    /// `drive 1 powered on (switched on, O0=1)`.
    fn take_events(&mut self) -> Vec<String> {
        self.drives.iter_mut().flat_map(|d| std::mem::take(&mut d.events)).collect()
    }

    /// A telegram the host left half-sent is dropped by every drive; motion, XON/XOFF and buffers stay.
    fn connection_closed(&mut self, _now: Timestamp) {
        self.parity_error_next = false;
        for d in &mut self.drives {
            d.rx.reset();
            d.rx_parity_error = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bus(addrs: &[u8], p196: u32) -> CompaxBus {
        CompaxBus::new(SimConfig::bus(addrs, p196, 9600)).unwrap()
    }

    fn ask(bus: &mut CompaxBus, now: u64, bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        bus.receive(Timestamp::from_millis(now), bytes, &mut out);
        out
    }

    #[test]
    fn the_manuals_example_with_and_without_bcc() {
        let mut b = bus(&[1, 5], 0);
        assert_eq!(ask(&mut b, 0, b"1S1\r"), b"S001: 0.000\r\n>");
        assert_eq!(ask(&mut b, 0, b"5S1\r"), b"S001: 0.000\r\n>");
        let mut b = bus(&[1, 5], 8);
        let mut want = b"S001: 0.000\r\n>".to_vec();
        want.push(crate::wire::bcc(b"S001: 0.000"));
        assert_eq!(ask(&mut b, 0, b"1S1\rS"), want);
        let mut e72 = b"E72\r\n>".to_vec();
        e72.push(crate::wire::bcc(b"E72"));
        assert_eq!(ask(&mut b, 0, b"1S1\rX"), e72);
    }

    #[test]
    fn broadcast_buffer_execute_and_motion() {
        let mut b = bus(&[1, 5], 0);
        assert_eq!(ask(&mut b, 0, b"1POSA 10,\r"), b"\r\n>");
        assert_eq!(ask(&mut b, 0, b"5POSR -5,\r"), b"\r\n>");
        assert!(!b.drive(1).unwrap().is_moving());
        assert_eq!(ask(&mut b, 1, b"32!\r"), b"");
        assert!(b.drive(1).unwrap().is_moving() && b.drive(5).unwrap().is_moving());
        // 100 units/s, instant ramps: 10 units take 100 ms.
        assert_eq!(ask(&mut b, 50, b"1POSA 20\r"), b"E92\r\n>");
        let mut out = Vec::new();
        b.advance(Timestamp::from_millis(200), &mut out);
        assert_eq!(b.drive(1).unwrap().position(), 10.0);
        assert_eq!(b.drive(5).unwrap().position(), -5.0);
        assert_eq!(ask(&mut b, 201, b"32!\r"), b"", "the buffer is consumed by '!'");
        assert_eq!(ask(&mut b, 202, b"1!\r"), b"E90\r\n>");
    }

    #[test]
    fn a_configuration_file_sets_each_drive() {
        let cfg = SimConfig::from_toml(
            r#"
            baud_rate = 19200
            p196 = 8
            max_speed_units_per_s = 50.0

            [[drive]]
            address = 1

            [[drive]]
            address = 5
            position = -12.5
            p196 = 72

            [[drive]]
            address = 9
            baud_rate = 9600
            "#,
        )
        .unwrap();
        assert_eq!((cfg.baud_rate, cfg.p196, cfg.max_speed_units_per_s), (19_200, 8, 50.0));
        let mut b = CompaxBus::new(cfg).unwrap();
        let one = b.drive(1).unwrap();
        assert_eq!((one.mode().to_p196(), one.baud_rate(), one.position()), (8, 19_200, 0.0));
        let five = b.drive(5).unwrap();
        assert_eq!((five.mode().to_p196(), five.position(), five.target()), (72, -12.5, -12.5));
        assert_eq!(five.param(ParamId::OPERATING_MODE), Some(72.0));
        assert_eq!(b.drive(9).unwrap().baud_rate(), 9600);
        // Each answers in its own mode: drive 5 with its address in front; drive 9 hears only noise.
        let with_bcc = |text: &[u8]| {
            let mut t = text.to_vec();
            t.push(crate::wire::bcc(&text[..text.len() - 1]));
            t
        };
        let mut want = b"5S001: -12.500\r\n>".to_vec();
        want.push(crate::wire::bcc(b"5S001: -12.500"));
        assert_eq!(ask(&mut b, 0, &with_bcc(b"5S1\r")), want);
        assert!(ask(&mut b, 1, &with_bcc(b"9S1\r")).is_empty());
        // SPEED 100 is 50 units/s: 10 units take 200 ms.
        assert_eq!(ask(&mut b, 2, &with_bcc(b"1POSA 10\r"))[..3], *b"\r\n>");
        let mut out = Vec::new();
        b.advance(Timestamp::from_millis(102), &mut out);
        assert!((b.drive(1).unwrap().position() - 5.0).abs() < 0.1, "{}", b.drive(1).unwrap().position());
        b.advance(Timestamp::from_millis(210), &mut out);
        assert_eq!(b.drive(1).unwrap().position(), 10.0);
        // Every key has a default.
        assert_eq!(SimConfig::from_toml("").unwrap(), SimConfig::default());
    }

    #[test]
    fn a_bad_configuration_file_says_what_is_wrong() {
        for (text, says) in [
            ("[[drive]]\naddress = 32\n", "address 32"),
            ("[[drive]]\naddress = 3\n[[drive]]\naddress = 3\n", "two drives have address 3"),
            ("p196 = 164\n", "COMTAC"),
            ("[[drive]]\naddress = 1\np196 = 200\n", "P196 = 200"),
            ("baud_rate = 1234\n", "1234"),
            ("[[drive]]\naddress = 1\nbaud_rate = 777\n", "777"),
            ("[[drive]]\naddress = 1\nposition = 1e9\n", "position"),
            ("max_speed_units_per_s = 0.0\n", "max_speed_units_per_s"),
            ("[[drive]]\naddress = 1\nspeed = 5\n", "unknown field `speed`"),
            ("drive = []\n", "0 drives"),
            ("baud_rate = \"fast\"\n", "baud_rate"),
        ] {
            let e = SimConfig::from_toml(text).unwrap_err();
            assert!(e.to_string().contains(says), "{text:?}: {e}");
        }
    }

    #[test]
    fn unmodelled_parameters_and_status_values_are_refused_not_zero() {
        let mut b = bus(&[1], 0);
        // The manual defines P194..P196 only: others are refused, read or written.
        assert_eq!(ask(&mut b, 0, b"1P12\r"), b"E90\r\n>");
        assert_eq!(ask(&mut b, 1, b"1P12=3\r"), b"E90\r\n>");
        assert_eq!(ask(&mut b, 2, b"1P12\r"), b"E90\r\n>", "the refused write stored nothing");
        assert_eq!(b.drive(1).unwrap().param(ParamId::new(12).unwrap()), None);
        assert_eq!(ask(&mut b, 3, b"1P194\r"), b"P194=1\r\n>");
        // Status values the emulator does not model.
        for s in ["S4", "S11", "S20", "S30", "S40"] {
            assert_eq!(ask(&mut b, 4, format!("1{s}\r").as_bytes()), b"E90\r\n>", "{s}");
        }
        // A parameter the configuration lists is modelled.
        let cfg = SimConfig::bus(&[1], 0, 9600).with_param(ParamId::new(12).unwrap(), 1.5);
        let mut b = CompaxBus::new(cfg).unwrap();
        assert_eq!(ask(&mut b, 0, b"1P12\r"), b"P012=1.5\r\n>");
        assert_eq!(ask(&mut b, 1, b"1P12=-3\r"), b"\r\n>");
        assert_eq!(b.drive(1).unwrap().param(ParamId::new(12).unwrap()), Some(-3.0));
        let bad = SimConfig::bus(&[1], 0, 9600).with_param(ParamId::DEVICE_ADDRESS, 1.0);
        assert!(CompaxBus::new(bad).is_err(), "P194 comes from the drive's address");
        assert!(SimConfig::from_toml("params = { Q1 = 0.0 }").is_err());
    }

    #[test]
    fn the_error_history_s18_records_errors() {
        let mut b = bus(&[1], 8);
        let with_bcc = |text: &[u8]| {
            let mut t = text.to_vec();
            t.push(crate::wire::bcc(&text[..text.len() - 1]));
            t
        };
        let s18 = |b: &mut CompaxBus, now: u64| {
            let r = ask(b, now, &with_bcc(b"1S18\r"));
            String::from_utf8_lossy(&r[..r.len() - 4]).into_owned()
        };
        assert_eq!(s18(&mut b, 0), "S018: 99 99 99 99 99 99 99 99");
        // E72: a wrong BCC; acknowledged (99) by the next error-free transmission, the S18 read itself.
        assert_eq!(&ask(&mut b, 1, b"1S1\rX")[..3], b"E72");
        assert_eq!(s18(&mut b, 2), "S018: 99 72 99 99 99 99 99 99");
        // E92: a move while moving; E90: an empty buffer.
        assert_eq!(&ask(&mut b, 3, &with_bcc(b"1POSA 50\r"))[..3], b"\r\n>");
        assert_eq!(&ask(&mut b, 10, &with_bcc(b"1POSA 20\r"))[..3], b"E92");
        assert_eq!(&ask(&mut b, 11, &with_bcc(b"1!\r"))[..3], b"E90");
        assert_eq!(s18(&mut b, 12), "S018: 90 92 99 72 99 99 99 99");
        assert_eq!(b.drive(1).unwrap().history()[..2], [90, 92]);
    }

    #[test]
    fn events_tell_what_each_drive_did() {
        let mut b = bus(&[1, 5], 0);
        assert!(b.take_events().is_empty(), "nothing happened yet");
        assert_eq!(ask(&mut b, 0, b"1POSA 10\r"), b"\r\n>");
        assert_eq!(b.take_events(), ["drive 1 motion started to 10.000 from 0.000"]);
        assert!(b.take_events().is_empty(), "taken once");
        // 100 units/s: at rest after 100 ms, with its position.
        let mut out = Vec::new();
        b.advance(Timestamp::from_millis(150), &mut out);
        assert_eq!(b.take_events(), ["drive 1 at rest 10.000"]);
        // A move while moving is refused: the error is an event.
        assert_eq!(ask(&mut b, 200, b"5POSA 100\r"), b"\r\n>");
        assert_eq!(ask(&mut b, 210, b"5POSA 50\r"), b"E92\r\n>");
        let ev = b.take_events();
        assert_eq!(ev[0], "drive 5 motion started to 100.000 from 0.000");
        assert!(ev[1].starts_with("drive 5 error E92"), "{ev:?}");
        // Switched off while moving: switched off, then at rest where it was.
        assert_eq!(ask(&mut b, 300, b"5OUTPUT O0=0\r"), b"\r\n>");
        assert_eq!(b.take_events(), ["drive 5 switched off (O0=0)", "drive 5 at rest 10.000"]);
        // Switched off, it refuses moves; switching off again is no event.
        assert_eq!(ask(&mut b, 310, b"5POSA 1\r"), b"E90\r\n>");
        assert_eq!(ask(&mut b, 311, b"5OUTPUT O0=0\r"), b"\r\n>");
        let ev = b.take_events();
        assert_eq!(ev.len(), 1, "{ev:?}");
        assert!(ev[0].starts_with("drive 5 error E90"), "{ev:?}");
        assert_eq!(ask(&mut b, 320, b"5OUTPUT O0=1\r"), b"\r\n>");
        assert_eq!(b.take_events(), ["drive 5 switched on (O0=1)"]);
        // A broadcast move: every drive tells.
        assert_eq!(ask(&mut b, 400, b"32POSR 1\r"), b"");
        assert_eq!(
            b.take_events(),
            ["drive 1 motion started to 11.000 from 10.000", "drive 5 motion started to 11.000 from 10.000"]
        );
        b.power_cycle(Timestamp::from_millis(401));
        let ev = b.take_events();
        assert_eq!(
            ev,
            [
                "drive 1 at rest 10.100",
                "drive 1 powered on (switched on, O0=1)",
                "drive 5 at rest 10.100",
                "drive 5 powered on (switched on, O0=1)"
            ]
        );
        assert_eq!(ask(&mut b, 500, b"1POSA HOME\r"), b"\r\n>");
        assert_eq!(b.take_events(), ["drive 1 homing started from 10.100"]);
    }

    #[test]
    fn the_user_guides_example_parameter_p003_is_modelled() {
        let mut b = bus(&[1], 0);
        assert_eq!(ask(&mut b, 0, b"1P003\r"), b"P003=0\r\n>");
        assert_eq!(ask(&mut b, 1, b"1P003=-1055.88\r"), b"\r\n>");
        assert_eq!(ask(&mut b, 2, b"1P3\r"), b"P003=-1055.88\r\n>");
        assert_eq!(b.drive(1).unwrap().param(ParamId::new(3).unwrap()), Some(-1055.88));
        // Its neighbours are not modelled.
        assert_eq!(ask(&mut b, 3, b"1P2\r"), b"E90\r\n>");
        assert_eq!(ask(&mut b, 4, b"1P4=1\r"), b"E90\r\n>");
    }

    #[test]
    fn position_message_echo_and_no_reply() {
        let mut b = bus(&[3], 64);
        assert_eq!(ask(&mut b, 0, b"3POSA 1$\r"), b"3\r\n>");
        let mut out = Vec::new();
        b.advance(Timestamp::from_millis(100), &mut out);
        assert_eq!(out, b"3$\r\n>");
        assert_eq!(ask(&mut b, 100, b"3S1?\r"), b"33S1?\r\n>");
        assert_eq!(ask(&mut b, 100, b"3SPEED 50/\r"), b"");
        assert_eq!(b.drive(3).unwrap().move_settings().0, 50.0);
    }
}
