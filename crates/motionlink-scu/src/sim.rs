//! An emulator of the SCU control unit as its manual describes it: a sans-IO state machine (bytes in at a time,
//! bytes out) with a simple physical model of up to six actuators.
//!
//! ```
//! use motionlink_scu::sim::{ScuEmulator, SimConfig};
//! use motionlink_scu::wire::{request_to_vec, Request};
//! use motionlink_link::emulator::Emulator;
//! use motionlink_link::Timestamp;
//!
//! let mut unit = ScuEmulator::new(SimConfig::default()).unwrap();
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
//!   the Safety_ID, all motions (0, 1) or the remote motions (2) are fast-stopped. With Safety_ID 0 only RC,
//!   RA and RO are accepted afterwards, until a new RO. With 1 and 2 the next RC re-arms the watchdog.
//! - Error replies: a CRC mismatch gets CSE, an unknown command ICE, bad parameter values PDE, a wrong data
//!   length PCE, a command the present state forbids PE. A telegram left incomplete for 1000 ms is dropped.
//! - RT writes only remote data (0x3xxx; entries or whole 0x3xxx groups): any other index is PDE, a value out
//!   of range (speed above 100 % or 1000 counts/s) PDE, a wrong length PCE.
//! - RC with a cyclic object (index 0..4 = CyclicObj 1..5) writes its write data and answers with its read
//!   data; RC with index 0xFF answers with the status alone.
//! - RE on F1..F10 moves the actuators the parameterisation assigns to the function, to the position the
//!   motion_direction names (9: the remote position of each actuator), at the function's remote speed, with a
//!   soft start ramp. RS stops it (0 fast, 1 along the ramp). F11 buzzer, F17/F18 binary outputs, F21/F22 the
//!   operating unit's LEDs are switched on by RE and off by RS. F20 emergency stop fast-stops everything; while
//!   it is on, motion functions are refused (PE), every function shows as locked in Lock Status and the release
//!   flags of actuator status 2 are cleared.
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
//!   stops its drive, bits 1..5 reset the unit, which ends remote mode, the other bits stop every motion).
//!   When the next motion starts (an RE of a motion function with a direction other than 0, or the hand
//!   switch), bits 14..21 ("bit reset on next motion") leave Error_Code 1; the other bits stay, and the
//!   history keeps what happened.
//! - Events ([`Emulator::take_events`], printed by `motionlink sim scu --events`): remote mode opened, closed
//!   or ended by the watchdog, a function started or stopped, an actuator at rest with its position, an error
//!   bit set or reset, a switching function on or off.

use std::time::Duration;

use motionlink_link::emulator::Emulator;
use motionlink_link::Timestamp;

use crate::model::{
    error_bits, item, status1, status2, Actuator, CyclicObject, DataEntry, DataEntryExt, DataIndex, ErrorCode,
    Function, Item, MotionDirection, SafetyId, StopMode, UserPositionData, UserPositions, UNUSED,
};
use crate::value::{SpeedMode, Value};
use crate::wire::{encode_reply, Command, Incoming, Reply, Request, RequestDecoder, Status, MAX_REPLY_LEN};

pub use crate::model::timing::{INTER_BYTE_LIMIT, WATCHDOG};
/// Step of the physical model.
const STEP: Duration = Duration::from_millis(5);

/// One actuator's parameterisation.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ActuatorConfig {
    /// The In end of the stroke, in counts.
    pub stroke_min_counts: i32,
    /// The Out end of the stroke, in counts.
    pub stroke_max_counts: i32,
    /// Position at power-on, in counts.
    pub start_position_counts: i32,
    /// Speed at 100 %, in counts per second.
    pub counts_per_second_at_full_speed: f64,
    /// Soft start and soft stop ramp: time from standstill to 100 %, in ms.
    pub ramp_ms: u64,
    /// Current while moving at 100 %, in 0.1 A (scaled with speed, plus a third at standstill of the motor).
    pub current_at_full_speed_deci_amps: u16,
    /// Below this speed (percent) the actuator stalls: it does not move though the motion bit is set, as TLT
    /// columns do below about 30 %. 0: never stalls.
    pub stall_below_percent: u16,
    /// On reaching the In end, the position reads this many counts below it (as real units do after homing).
    pub in_end_undershoot_counts: i32,
    /// A drive that stays stalled (below [`ActuatorConfig::stall_below_percent`], or pushing against
    /// [`ActuatorConfig::obstacle_counts`]) this long while its motion is on is stopped with its drive error
    /// bit (15 for drive 1 .. 20 for drive 6) set, as the unit's drive time-out does. 0: never.
    pub stall_error_after_ms: u64,
    /// An obstacle at this position: the drive cannot pass it and stalls there, pushing (twice its full-speed
    /// current), until its stall error stops it. None: no obstacle.
    pub obstacle_counts: Option<i32>,
    /// Stored positions (UserPositionData). Its virtual limits bound every motion of the drive.
    pub user_positions: UserPositionData,
}

impl Default for ActuatorConfig {
    fn default() -> Self {
        let mut user_positions = UserPositionData::default();
        for (u, up) in user_positions.users.iter_mut().enumerate() {
            *up = UserPositions {
                memory_counts: [100 + 10 * u as i32, 300, 500, 700],
                intermediate_in_counts: 200,
                intermediate_out_counts: 600,
            };
        }
        user_positions.virtual_limit_in_counts = 0;
        user_positions.virtual_limit_out_counts = 865;
        ActuatorConfig {
            stroke_min_counts: 0,
            stroke_max_counts: 865,
            start_position_counts: 0,
            counts_per_second_at_full_speed: 110.0,
            ramp_ms: 300,
            current_at_full_speed_deci_amps: 30,
            stall_below_percent: 0,
            in_end_undershoot_counts: 0,
            stall_error_after_ms: 5000,
            obstacle_counts: None,
            user_positions,
        }
    }
}

/// An error the emulated unit raises by itself at a chosen time, for tests of how a host reacts
/// (`[[error]]` in the TOML configuration).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScheduledError {
    /// The manual's bit number, 1..32 ("Bit 15" is drive 1).
    pub bit: u8,
    /// When, in ms after the emulator started (power-on).
    pub at_ms: u64,
}

/// The emulated unit's parameterisation: actuators, function mapping, speeds, limits and errors. Loaded from
/// TOML by `motionlink sim scu --config FILE`.
///
/// ```toml
/// preset = "tlt"            # or "scp11" (the default) or "liftkit": starting point, the keys below override it
/// actuators = 2             # how many actuators are connected (1..6)
/// speed_mode = "percent"    # or "counts_per_second"
/// total_current_limit_deci_amps = 50   # above this total current (0.1 A) error bit 14 stops everything; 0: none
/// [functions]               # which actuators each function F1..F10 drives
/// F1 = [1, 2]
/// [[actuator]]              # per actuator, in order (missing ones take the defaults)
/// stroke_max_counts = 865
/// counts_per_second_at_full_speed = 110.0
/// obstacle_counts = 500     # the drive stalls here and stops with its drive error bit set
/// [[error]]                 # raise error bit 12 five seconds after power-on
/// bit = 12
/// at_ms = 5000
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// The connected actuators, 1..6 of them.
    pub actuators: Vec<ActuatorConfig>,
    /// For F1..F10 (index 0..9), the actuators it drives.
    pub functions: [Vec<Actuator>; 10],
    /// Whether remote speeds are percent or counts per second.
    pub speed_mode: SpeedMode,
    /// Default remote speed of every function ("function speed from configuration").
    pub default_speed: u16,
    /// Firmware info (0x0001).
    pub firmware_info: String,
    /// Configuration info (0x0002).
    pub configuration_info: String,
    /// Above this total current of all drives, in 0.1 A, error bit 14 is set and every motion fast-stops.
    /// 0: no limit.
    pub total_current_limit_deci_amps: u16,
    /// Errors the unit raises by itself at chosen times.
    pub scheduled_errors: Vec<ScheduledError>,
}

impl SimConfig {
    /// SCP11 with `n` actuators: actuator k on function Fk.
    pub fn scp11(n: usize) -> Self {
        let n = n.clamp(1, 6);
        let mut functions: [Vec<Actuator>; 10] = Default::default();
        for (k, f) in functions.iter_mut().enumerate().take(n) {
            f.push(Actuator::new(k as u8 + 1).unwrap_or(Actuator::new(1).expect("1 is an actuator")));
        }
        SimConfig {
            actuators: vec![ActuatorConfig::default(); n],
            functions,
            speed_mode: SpeedMode::Percent,
            default_speed: 100,
            firmware_info: "SCU V2B3 motionlink-sim".into(),
            configuration_info: "SCP11 motionlink emulator".into(),
            total_current_limit_deci_amps: 0,
            scheduled_errors: Vec::new(),
        }
    }

    /// A TLT-like column pair: F1 drives actuators 1 and 2 together, F2 and F3 each one alone; the columns stall
    /// below 30 % and read a few counts below zero after reaching the In end.
    pub fn tlt() -> Self {
        let mut c = SimConfig::scp11(2);
        let a1 = Actuator::new(1).expect("1 is an actuator");
        let a2 = Actuator::new(2).expect("2 is an actuator");
        c.functions = Default::default();
        c.functions[0] = vec![a1, a2];
        c.functions[1] = vec![a1];
        c.functions[2] = vec![a2];
        for a in &mut c.actuators {
            a.stall_below_percent = 30;
            a.in_end_undershoot_counts = 3;
        }
        c.configuration_info = "TLT motionlink emulator".into();
        c
    }

    /// The mapping the public LIFTKIT and TLT drivers assume: F1 (function index 0) drives actuator 1, F2
    /// (index 1) actuator 2, F8 (index 7) both together; the columns behave like the TLT preset's.
    pub fn liftkit() -> Self {
        let mut c = SimConfig::tlt();
        let a1 = Actuator::new(1).expect("1 is an actuator");
        let a2 = Actuator::new(2).expect("2 is an actuator");
        c.functions = Default::default();
        c.functions[0] = vec![a1];
        c.functions[1] = vec![a2];
        c.functions[7] = vec![a1, a2];
        c.configuration_info = "LIFTKIT motionlink emulator".into();
        c
    }

    /// The preset called `name` (scp11 with two actuators, tlt, liftkit).
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "scp11" => Some(SimConfig::scp11(2)),
            "tlt" => Some(SimConfig::tlt()),
            "liftkit" => Some(SimConfig::liftkit()),
            _ => None,
        }
    }

    /// The names of the presets.
    pub const PRESETS: [&'static str; 3] = ["scp11", "tlt", "liftkit"];

    /// Reads a configuration from TOML text (see the type's documentation).
    pub fn from_toml(text: &str) -> Result<Self, SimConfigError> {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            preset: Option<String>,
            actuators: Option<usize>,
            speed_mode: Option<SpeedMode>,
            default_speed: Option<u16>,
            firmware_info: Option<String>,
            configuration_info: Option<String>,
            functions: Option<std::collections::BTreeMap<String, Vec<u8>>>,
            actuator: Option<Vec<toml::Table>>,
            total_current_limit_deci_amps: Option<u16>,
            error: Option<Vec<ScheduledError>>,
        }
        let f: File = toml::from_str(text).map_err(|e| SimConfigError(e.to_string()))?;
        let mut c = match f.preset.as_deref() {
            None | Some("scp11") => SimConfig::scp11(f.actuators.unwrap_or(2)),
            Some(name) => SimConfig::preset(name).ok_or_else(|| {
                SimConfigError(format!("unknown preset {name:?} (known: {})", SimConfig::PRESETS.join(", ")))
            })?,
        };
        if let Some(limit) = f.total_current_limit_deci_amps {
            c.total_current_limit_deci_amps = limit;
        }
        if let Some(errors) = f.error {
            c.scheduled_errors = errors;
        }
        if let Some(n) = f.actuators {
            if !(1..=6).contains(&n) {
                return Err(SimConfigError(format!("actuators = {n}: a unit has 1 to 6 actuators")));
            }
            c.actuators.resize(n, ActuatorConfig::default());
        }
        if let Some(list) = f.actuator {
            if list.len() > 6 {
                return Err(SimConfigError("at most 6 [[actuator]] tables".into()));
            }
            if list.len() > c.actuators.len() {
                c.actuators.resize(list.len(), ActuatorConfig::default());
            }
            for (i, (slot, given)) in c.actuators.iter_mut().zip(list).enumerate() {
                // The keys given override the preset's actuator; a stroke given without stored positions
                // moves the virtual limits with it.
                let mut merged = toml::Table::try_from(&*slot).map_err(|e| SimConfigError(e.to_string()))?;
                let new_stroke = given.contains_key("stroke_min_counts") || given.contains_key("stroke_max_counts");
                let positions_given = given.contains_key("user_positions");
                merged.extend(given);
                let mut a: ActuatorConfig =
                    merged.try_into().map_err(|e| SimConfigError(format!("[[actuator]] {}: {e}", i + 1)))?;
                if new_stroke && !positions_given {
                    a.user_positions.virtual_limit_in_counts = a.stroke_min_counts;
                    a.user_positions.virtual_limit_out_counts = a.stroke_max_counts;
                }
                *slot = a;
            }
        }
        if let Some(m) = f.speed_mode {
            c.speed_mode = m;
        }
        if let Some(s) = f.default_speed {
            c.default_speed = s;
        }
        if let Some(s) = f.firmware_info {
            c.firmware_info = s;
        }
        if let Some(s) = f.configuration_info {
            c.configuration_info = s;
        }
        if let Some(map) = f.functions {
            for (name, list) in map {
                let n: usize = name
                    .trim_start_matches(['F', 'f'])
                    .parse()
                    .ok()
                    .filter(|n| (1..=10).contains(n))
                    .ok_or_else(|| SimConfigError(format!("[functions] {name}: expected F1..F10")))?;
                c.functions[n - 1] = list
                    .iter()
                    .map(|&a| {
                        Actuator::new(a)
                            .ok_or_else(|| SimConfigError(format!("[functions] {name}: actuator {a} is not 1..6")))
                    })
                    .collect::<Result<_, _>>()?;
            }
        }
        c.validate()?;
        Ok(c)
    }

    /// Checks the configuration is consistent.
    pub fn validate(&self) -> Result<(), SimConfigError> {
        if self.actuators.is_empty() || self.actuators.len() > 6 {
            return Err(SimConfigError(format!("{} actuators: a unit has 1 to 6", self.actuators.len())));
        }
        for (i, f) in self.functions.iter().enumerate() {
            if let Some(a) = f.iter().find(|a| usize::from(a.number()) > self.actuators.len()) {
                return Err(SimConfigError(format!(
                    "F{} drives {a}, but only {} actuators are connected",
                    i + 1,
                    self.actuators.len()
                )));
            }
        }
        for (i, a) in self.actuators.iter().enumerate() {
            if a.stroke_min_counts >= a.stroke_max_counts {
                return Err(SimConfigError(format!(
                    "actuator {}: stroke_min_counts must be below stroke_max_counts",
                    i + 1
                )));
            }
            if !(a.stroke_min_counts..=a.stroke_max_counts).contains(&a.start_position_counts) {
                return Err(SimConfigError(format!("actuator {}: start_position_counts is outside the stroke", i + 1)));
            }
            if !(a.counts_per_second_at_full_speed > 0.0 && a.counts_per_second_at_full_speed.is_finite()) {
                return Err(SimConfigError(format!("actuator {}: counts_per_second_at_full_speed must be > 0", i + 1)));
            }
        }
        for e in &self.scheduled_errors {
            if !(1..=32).contains(&e.bit) {
                return Err(SimConfigError(format!("[[error]] bit = {}: the error bits are 1..32", e.bit)));
            }
        }
        for (i, a) in self.actuators.iter().enumerate() {
            let v = &a.user_positions;
            if v.virtual_limit_in_counts > v.virtual_limit_out_counts {
                return Err(SimConfigError(format!(
                    "actuator {}: the virtual limit In ({}) is above the virtual limit Out ({})",
                    i + 1,
                    v.virtual_limit_in_counts,
                    v.virtual_limit_out_counts
                )));
            }
        }
        if self.default_speed > self.speed_mode.max() {
            return Err(SimConfigError(format!(
                "default_speed {} is above {}",
                self.default_speed,
                self.speed_mode.max()
            )));
        }
        Ok(())
    }
}

impl Default for SimConfig {
    /// Two actuators, SCP11, stroke 0..865 counts, start at 0, 110 counts/s at 100 %.
    fn default() -> Self {
        SimConfig::scp11(2)
    }
}

/// A configuration that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid SCU emulator configuration: {0}")]
pub struct SimConfigError(pub String);

/// Who started an actuator's motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Origin {
    /// RE over the serial line.
    Remote,
    /// The hand switch.
    Local,
}

#[derive(Debug, Clone)]
struct ActuatorState {
    cfg: ActuatorConfig,
    /// Position, counts.
    position: f64,
    /// Signed velocity, counts/s.
    velocity: f64,
    /// Where it is going, counts (None: standing).
    target: Option<f64>,
    /// Commanded speed, counts/s.
    commanded_speed: f64,
    /// Commanded speed in percent (for the speed entry and stalling).
    commanded_percent: u16,
    /// Decelerating to a stop along the ramp.
    soft_stopping: bool,
    origin: Origin,
    /// The motion function (wire id 0..9) whose RE started the motion, if a remote one did.
    function: Option<u8>,
    /// Too slow to move (below the stall speed).
    stalled: bool,
    /// Pushing against the configured obstacle.
    blocked: bool,
    /// How long it has been stalled or blocked with its motion on, s.
    stalled_for: f64,
    cumulated_stroke: f64,
    relay_in_cycles: u32,
    relay_out_cycles: u32,
    max_current: u16,
    error_count: u32,
}

impl ActuatorState {
    fn new(cfg: ActuatorConfig) -> Self {
        ActuatorState {
            position: f64::from(cfg.start_position_counts),
            cfg,
            velocity: 0.0,
            target: None,
            commanded_speed: 0.0,
            commanded_percent: 0,
            soft_stopping: false,
            origin: Origin::Remote,
            function: None,
            stalled: false,
            blocked: false,
            stalled_for: 0.0,
            cumulated_stroke: 0.0,
            relay_in_cycles: 0,
            relay_out_cycles: 0,
            max_current: 0,
            error_count: 0,
        }
    }

    fn moving(&self) -> bool {
        self.target.is_some() || self.velocity != 0.0
    }

    /// Acceleration along the ramp, counts/s².
    fn acceleration(&self) -> f64 {
        let ramp = (self.cfg.ramp_ms.max(1) as f64) / 1000.0;
        self.cfg.counts_per_second_at_full_speed / ramp
    }

    /// The range a motion may reach: the stroke, narrowed by the virtual limits of UserPositionData (both 0:
    /// none set).
    fn travel_range(&self) -> (i32, i32) {
        let v = &self.cfg.user_positions;
        let (mut lo, mut hi) = (self.cfg.stroke_min_counts, self.cfg.stroke_max_counts);
        if (v.virtual_limit_in_counts, v.virtual_limit_out_counts) != (0, 0) {
            lo = lo.max(v.virtual_limit_in_counts);
            hi = hi.min(v.virtual_limit_out_counts).max(lo);
        }
        (lo, hi)
    }

    fn reported_position(&self) -> i32 {
        let p = self.position.round() as i32;
        if !self.moving() && p <= self.cfg.stroke_min_counts {
            p - self.cfg.in_end_undershoot_counts
        } else {
            p
        }
    }

    /// Starts a motion to `target` (clamped to the travel range, as a unit stops at its limits). Returns false
    /// if the actuator is already there and nothing moves.
    fn start(
        &mut self,
        target: i32,
        speed_counts_per_s: f64,
        percent: u16,
        origin: Origin,
        function: Option<u8>,
    ) -> bool {
        let (lo, hi) = self.travel_range();
        let target = target.clamp(lo, hi);
        let t = f64::from(target);
        if (t - self.position).abs() < 0.5 {
            // Already there: nothing moves.
            return false;
        }
        if t < self.position {
            self.relay_in_cycles += 1;
        } else {
            self.relay_out_cycles += 1;
        }
        self.target = Some(t);
        self.soft_stopping = false;
        self.origin = origin;
        self.function = function;
        self.blocked = false;
        self.stalled_for = 0.0;
        self.set_speed(speed_counts_per_s, percent);
        true
    }

    /// A new commanded speed; the motion follows it along the ramp.
    fn set_speed(&mut self, speed_counts_per_s: f64, percent: u16) {
        self.commanded_speed = speed_counts_per_s;
        self.commanded_percent = percent;
        let stalls = self.cfg.stall_below_percent > 0 && percent < self.cfg.stall_below_percent;
        if !stalls {
            self.stalled_for = if self.blocked { self.stalled_for } else { 0.0 };
        }
        self.stalled = stalls;
    }

    fn fast_stop(&mut self) {
        self.target = None;
        self.velocity = 0.0;
        self.soft_stopping = false;
        self.stalled = false;
        self.blocked = false;
        self.stalled_for = 0.0;
    }

    fn soft_stop(&mut self) {
        if self.moving() {
            self.soft_stopping = true;
            self.target = None;
        }
        self.stalled = false;
        self.blocked = false;
        self.stalled_for = 0.0;
        if self.velocity == 0.0 {
            self.soft_stopping = false;
        }
    }

    fn current(&self) -> u16 {
        if (self.stalled || self.blocked) && self.target.is_some() {
            return self.cfg.current_at_full_speed_deci_amps.saturating_mul(2);
        }
        if !self.moving() {
            return 0;
        }
        let frac = (self.velocity.abs() / self.cfg.counts_per_second_at_full_speed).min(1.5);
        let base = f64::from(self.cfg.current_at_full_speed_deci_amps);
        (base / 3.0 + base * 2.0 / 3.0 * frac).round() as u16
    }

    fn speed_percent(&self) -> u16 {
        ((self.velocity.abs() / self.cfg.counts_per_second_at_full_speed) * 100.0).round() as u16
    }

    /// Runs the model for `dt`. Returns true when the drive's stall time-out expired: the caller raises its
    /// drive error.
    fn step(&mut self, dt: f64) -> bool {
        let accel = self.acceleration();
        if self.soft_stopping {
            let dv = accel * dt;
            let new_v = if self.velocity > 0.0 { (self.velocity - dv).max(0.0) } else { (self.velocity + dv).min(0.0) };
            self.integrate((self.velocity + new_v) / 2.0 * dt);
            self.velocity = new_v;
            if self.velocity == 0.0 {
                self.soft_stopping = false;
            }
        } else if let Some(target) = self.target {
            if self.stalled || self.blocked {
                self.velocity = 0.0;
            } else {
                let remaining = target - self.position;
                let dir = remaining.signum();
                // Slow down in time to stop at the target along the ramp; follow a lower commanded speed
                // along the ramp too.
                let brake_limit = (2.0 * accel * remaining.abs()).sqrt();
                let speed = self.velocity.abs();
                let wanted = self.commanded_speed.min(brake_limit);
                let new_speed = if wanted > speed {
                    (speed + accel * dt).min(wanted)
                } else if wanted < brake_limit {
                    (speed - accel * dt).max(wanted)
                } else {
                    wanted
                };
                let travel = ((speed + new_speed) / 2.0 * dt).max(new_speed * dt * 0.5);
                if travel >= remaining.abs() || remaining.abs() < 0.5 {
                    self.integrate(remaining);
                    self.position = target;
                    self.velocity = 0.0;
                    self.target = None;
                } else {
                    self.integrate(dir * travel);
                    self.velocity = dir * new_speed;
                }
                // An obstacle in the way stops the drive there, still pushing.
                if let Some(o) = self.cfg.obstacle_counts.map(f64::from) {
                    let before = self.position - dir * travel;
                    let crossed = (before < o && self.position >= o && dir > 0.0)
                        || (before > o && self.position <= o && dir < 0.0);
                    if crossed && (target - o).abs() >= 0.5 {
                        self.position = o;
                        self.velocity = 0.0;
                        self.blocked = true;
                        self.target = Some(target);
                    }
                }
            }
        }
        // The ends of the stroke stop everything.
        let (lo, hi) = (f64::from(self.cfg.stroke_min_counts), f64::from(self.cfg.stroke_max_counts));
        if self.position <= lo && self.velocity < 0.0 || self.position >= hi && self.velocity > 0.0 {
            self.position = self.position.clamp(lo, hi);
            self.velocity = 0.0;
            self.target = None;
            self.soft_stopping = false;
        }
        self.max_current = self.max_current.max(self.current());
        if (self.stalled || self.blocked) && self.target.is_some() {
            self.stalled_for += dt;
            let limit = self.cfg.stall_error_after_ms as f64 / 1000.0;
            return self.cfg.stall_error_after_ms > 0 && self.stalled_for >= limit - 1e-9;
        }
        false
    }

    fn integrate(&mut self, delta: f64) {
        self.position += delta;
        self.cumulated_stroke += delta.abs();
    }

    fn status1(&self) -> u8 {
        let p = self.position.round() as i32;
        let at_in = p <= self.cfg.stroke_min_counts;
        let at_out = p >= self.cfg.stroke_max_counts;
        let mut s = status1::AVAILABLE | status1::STROKE_DONE;
        if at_in || at_out {
            s |= status1::LIMIT_IN_OUT;
        }
        if at_in {
            s |= status1::SWITCH1 | status1::IN_POSITION;
        }
        if at_out {
            s |= status1::SWITCH2 | status1::OUT_POSITION;
        }
        if self.moving() {
            s |= status1::MOTION;
        }
        s
    }
}

/// Remote mode of the unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RemoteMode {
    /// Normal mode: only RO and RA are accepted.
    Off,
    /// Opened by RO; waiting for the first RC.
    AwaitingRc(SafetyId),
    /// Remote mode with a running watchdog.
    Active(SafetyId),
    /// The watchdog expired with Safety_ID 0: only RC, RA and RO are accepted until RO.
    Locked,
    /// The watchdog expired with Safety_ID 1 or 2: the next RC re-arms it.
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
pub struct ScuEmulator {
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
}

/// The most events an emulator keeps for [`Emulator::take_events`] (a host that never takes them loses the
/// oldest).
pub const MAX_EVENTS: usize = 1024;

/// Error bits the manual resets on the next motion: 14 (total current), 15..20 (drives 1..6), 21 (position
/// difference of synchronised drives).
pub const RESET_ON_NEXT_MOTION: u32 = ((1u32 << 21) - 1) & !((1u32 << 13) - 1);

impl ScuEmulator {
    /// A unit with `config`, powered on at time zero.
    pub fn new(config: SimConfig) -> Result<Self, SimConfigError> {
        config.validate()?;
        let actuators = config.actuators.iter().cloned().map(ActuatorState::new).collect::<Vec<_>>();
        let mut remote_position = [0i32; 6];
        for (slot, a) in remote_position.iter_mut().zip(&config.actuators) {
            // "Default value: memory 1 / user 1 position of UserPositionData".
            *slot = a.user_positions.users[0].memory_counts[0];
        }
        let mut scheduled_errors = config.scheduled_errors.clone();
        scheduled_errors.sort_by_key(|e| e.at_ms);
        Ok(ScuEmulator {
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

    /// Raises an error now: enters it in the history (Error_Code 1 is the newest) and applies the manual's
    /// reaction: a drive error (bits 15..20) fast-stops that drive; bit 22 (remote time-out) only records;
    /// bits 1..5 stop everything and reset the unit, which leaves remote mode; every other defined bit
    /// fast-stops every motion. For tests that need a unit in trouble.
    pub fn inject_error(&mut self, code: ErrorCode) {
        self.record_error(code);
        let mut stop_all = false;
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
                    if self.mode != RemoteMode::Off {
                        self.push_event("remote mode ended by a reset of the unit".into());
                    }
                    self.mode = RemoteMode::Off;
                }
                _ => stop_all = true,
            }
        }
        if stop_all {
            self.actuators.iter_mut().for_each(ActuatorState::fast_stop);
        }
        self.note_rest();
    }

    /// Presses the hand switch: moves the actuators of motion function `function` (1..10) In or Out as a
    /// local (non-remote) motion, at 100 %. Keys K(2n-1) and K(2n) show as pressed.
    pub fn press_hand_switch(&mut self, function: u8, out: bool) {
        let Some(f) = (1..=10).contains(&function).then(|| usize::from(function) - 1) else { return };
        if self.emergency_stop {
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
                    let total: u16 = self.actuators.iter().map(ActuatorState::current).sum();
                    self.max_total_current = self.max_total_current.max(total);
                    self.now = next;
                    if drive_errors != 0 {
                        self.inject_error(ErrorCode(drive_errors));
                    }
                    let limit = self.config.total_current_limit_deci_amps;
                    if limit > 0 && total > limit && self.any_moving() {
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
        self.mode = match safety {
            SafetyId::StopAllAndLock => RemoteMode::Locked,
            s => RemoteMode::TimedOut(s),
        };
        let what = match safety {
            SafetyId::StopAllAndLock => "all motions stopped; remote motion locked until RO",
            SafetyId::StopAll => "all motions stopped; the next RC re-arms it",
            SafetyId::StopRemoteOnly => "remote motions stopped; the next RC re-arms it",
        };
        self.push_event(format!("remote mode ended by watchdog (Safety_ID {}): {what}", safety.code()));
        self.note_rest();
    }

    fn reply_status(&mut self, command: Command, status: Status) {
        self.push_reply(&Reply::status_only(command, status));
    }

    fn push_reply(&mut self, reply: &Reply<'_>) {
        let start = self.reply.len();
        self.reply.resize(start + reply.encoded_len(), 0);
        match encode_reply(reply, &mut self.reply[start..]) {
            Ok(n) => self.reply.truncate(start + n),
            Err(e) => {
                // Data that does not fit a reply (every path that reads data is bounded by the value checks,
                // so this is a defect): the unit answers PDE rather than nothing.
                tracing::error!("SCU emulator: {} reply not encodable ({e}); answering PDE", reply.command);
                self.reply.truncate(start);
                let pde = Reply::status_only(reply.command, Status::ParameterDataError);
                self.reply.resize(start + pde.encoded_len(), 0);
                let n = encode_reply(&pde, &mut self.reply[start..]).unwrap_or(0);
                self.reply.truncate(start + n);
            }
        }
        self.stats.telegrams += 1;
    }

    /// The value bytes of data-list entry `e`.
    fn read_entry(&self, e: &DataEntry, out: &mut Vec<u8>) {
        let v = self.entry_value(e).unwrap_or_else(|| {
            tracing::error!("SCU emulator: {} ({}) has no modelled value; answering zeros", e.name, e.index());
            Value::Counter(0)
        });
        // Entries of raw-number kinds are encoded through their own kind's size.
        let start = out.len();
        match (&v, e.kind) {
            (Value::Number(n), _) => out.push(*n),
            (Value::Counter(n), k) => out.extend_from_slice(&n.to_le_bytes()[..k.size()]),
            (v, k) => v.encode(k, out),
        }
        out.resize(start + e.size(), 0);
    }

    /// The emulated unit's value of entry `e`; `None` for an entry the emulator does not model (a test
    /// checks that there is none).
    fn entry_value(&self, e: &DataEntry) -> Option<Value> {
        let i = e.index().0;
        let actuator = |base: u16| self.actuators.get(usize::from(i - base).wrapping_sub(1));
        Some(match i {
            0x0001 => Value::Text(self.config.firmware_info.clone()),
            0x0002 => Value::Text(self.config.configuration_info.clone()),
            0x0011..=0x0016 => Value::PositionCounts(actuator(0x0010).map_or(0, ActuatorState::reported_position)),
            0x0031..=0x0034 => Value::AnalogueCentiVolts(if i == 0x0031 { 250 } else { 0 }),
            0x0061..=0x0066 => Value::Counter(actuator(0x0060).map_or(0, |a| a.relay_in_cycles)),
            0x0071..=0x0076 => Value::Counter(actuator(0x0070).map_or(0, |a| a.relay_out_cycles)),
            0x0081..=0x0086 => Value::Counter(actuator(0x0080).map_or(0, |a| a.error_count)),
            0x0091..=0x0096 => Value::StrokeCounts(actuator(0x0090).map_or(0, |a| a.cumulated_stroke.round() as u32)),
            0x00A1..=0x00A6 => Value::CurrentDeciAmps(actuator(0x00A0).map_or(0, ActuatorState::current)),
            0x00B1..=0x00B6 => Value::CurrentDeciAmps(actuator(0x00B0).map_or(0, |a| a.max_current)),
            0x00BF => Value::CurrentDeciAmps(self.max_total_current),
            0x00C0 => Value::TemperatureAdc(96),
            0x00D1..=0x00D5 => Value::ErrorCode(ErrorCode(self.error_history[usize::from(i - 0x00D1)])),
            0x00E1..=0x00E6 => Value::Number(actuator(0x00E0).map_or(0, |_| {
                if self.emergency_stop {
                    status2::INITIALIZED
                } else {
                    status2::INITIALIZED | status2::RELEASE_RETRACTION | status2::RELEASE_EXTENSION
                }
            })),
            0x00F1..=0x00F6 => Value::SpeedPercent(actuator(0x00F0).map_or(0, ActuatorState::speed_percent)),
            0x0040 => Value::Counter(self.keys),
            0x0100 => Value::Number(0b0001), // mains connected, no battery
            0x0110 => Value::Number(self.binary_outputs),
            0x0120 => Value::Number(self.led_hand_switch),
            0x0140 => Value::Number(u8::from(self.buzzer)),
            0x0150 => Value::Number(1),
            0x0162 => Value::Counter(if self.emergency_stop { 0x03FF } else { 0 }),
            0x0164 => Value::BatteryDeciVolts(0),
            0x0166 => Value::Number(1),
            0x0171..=0x0176 => Value::Number(actuator(0x0170).map_or(0, ActuatorState::status1)),
            0x1011..=0x1016 => Value::ConversionFactor(if actuator(0x1010).is_some() { 0.31 } else { 0.0 }),
            0x2001..=0x2006 => {
                Value::UserPositions(Box::new(actuator(0x2000).map_or_else(Default::default, |a| a.cfg.user_positions)))
            }
            0x3001..=0x3005 => Value::CyclicObject(self.cyclic_objects[usize::from(i - 0x3001)]),
            0x3011..=0x301A => Value::RemoteSpeed(self.remote_speed[usize::from(i - 0x3011)]),
            0x3021..=0x3026 => Value::RemotePosition(self.remote_position[usize::from(i - 0x3021)]),
            // Nothing is wired to the binary inputs, no locking box is connected, and the model has no
            // temperature rise.
            0x0020 => Value::Number(0),
            0x008F => Value::Counter(self.total_over_current_count),
            0x00C1 => Value::Counter(0),
            0x0130 => Value::Number(0),
            0x0165 => Value::Number(0),
            _ => return None,
        })
    }

    fn read_item(&self, it: Item, out: &mut Vec<u8>) {
        match it {
            Item::Entry(e) => self.read_entry(e, out),
            Item::Group(g) => g.members().for_each(|e| self.read_entry(e, out)),
        }
    }

    /// Writes the bytes of remote entry `e` (already checked to be 0x3xxx and of the right size).
    fn write_entry(&mut self, e: &DataEntry, bytes: &[u8]) -> Result<(), Status> {
        let v = Value::decode(e.kind, bytes).map_err(|_| Status::ParameterCountError)?;
        v.check_range(self.config.speed_mode).map_err(|_| Status::ParameterDataError)?;
        let i = e.index().0;
        match (i, v) {
            (0x3001..=0x3005, Value::CyclicObject(o)) => self.cyclic_objects[usize::from(i - 0x3001)] = o,
            (0x3011..=0x301A, Value::RemoteSpeed(s)) => {
                let function = (i - 0x3011) as u8;
                self.remote_speed[usize::from(function)] = s;
                // "The speed can be changed during motion": the function's running remote motions follow
                // it along the ramp.
                for k in 0..self.actuators.len() {
                    let a = &self.actuators[k];
                    if a.function == Some(function) && a.origin == Origin::Remote && a.target.is_some() {
                        let (counts_per_s, percent) = self.speed_of(k, s);
                        self.actuators[k].set_speed(counts_per_s, percent);
                    }
                }
            }
            (0x3021..=0x3026, Value::RemotePosition(p)) => self.remote_position[usize::from(i - 0x3021)] = p,
            _ => return Err(Status::ParameterDataError),
        }
        Ok(())
    }

    fn write_item(&mut self, it: Item, bytes: &[u8]) -> Result<(), Status> {
        if !it.is_writable() {
            return Err(Status::ParameterDataError);
        }
        if bytes.len() != it.size() {
            return Err(Status::ParameterCountError);
        }
        match it {
            Item::Entry(e) => self.write_entry(e, bytes),
            Item::Group(g) => {
                // Check all first, then write all: a group write is all or nothing.
                let mut at = 0;
                for e in g.members() {
                    let v =
                        Value::decode(e.kind, &bytes[at..at + e.size()]).map_err(|_| Status::ParameterCountError)?;
                    v.check_range(self.config.speed_mode).map_err(|_| Status::ParameterDataError)?;
                    at += e.size();
                }
                let mut at = 0;
                for e in g.members() {
                    self.write_entry(e, &bytes[at..at + e.size()])?;
                    at += e.size();
                }
                Ok(())
            }
        }
    }

    fn handle(&mut self, incoming: Incoming<'_>) {
        let request = match incoming {
            Incoming::UnknownCommand { code } => {
                let command_echo = Reply::status_only(Command::Get, Status::InvalidCommand);
                // The reply repeats the unknown letters.
                let start = self.reply.len();
                self.push_reply(&command_echo);
                if self.reply.len() >= start + 5 {
                    self.reply[start..start + 2].copy_from_slice(&code);
                    let crc = crate::wire::crc16(&self.reply[start..start + 3]);
                    self.reply[start + 3..start + 5].copy_from_slice(&crc.to_le_bytes());
                }
                return;
            }
            Incoming::Request(r) => r,
        };
        let command = request.command();
        // Mode rules.
        let allowed = match (self.mode, command) {
            (_, Command::Open | Command::Abort) => true,
            (RemoteMode::Off, _) => false,
            (_, Command::Cyclic) => true,
            (RemoteMode::Active(_), _) => true,
            (RemoteMode::AwaitingRc(_) | RemoteMode::Locked | RemoteMode::TimedOut(_), _) => false,
        };
        if !allowed {
            self.reply_status(command, Status::PermissionError);
            return;
        }
        match request {
            Request::Open { safety_id } => match SafetyId::from_code(safety_id) {
                Some(s) => {
                    self.mode = RemoteMode::AwaitingRc(s);
                    self.last_rc = self.now;
                    self.reply_status(command, Status::Ack);
                    self.push_event(format!("remote mode opened (Safety_ID {safety_id})"));
                }
                None => self.reply_status(command, Status::ParameterDataError),
            },
            Request::Abort => {
                // Leaving remote mode ends remote control: remote motions stop (a decision; the manual is silent).
                if self.mode != RemoteMode::Off {
                    self.actuators.iter_mut().filter(|a| a.origin == Origin::Remote).for_each(ActuatorState::fast_stop);
                    self.push_event("remote mode closed by RA".into());
                }
                self.mode = RemoteMode::Off;
                self.reply_status(command, Status::Ack);
                self.note_rest();
            }
            Request::Cyclic { object, write } => self.handle_cyclic(object, write),
            Request::Get { index } => match item(DataIndex(index)) {
                Some(it) => {
                    let mut data = Vec::with_capacity(it.size());
                    self.read_item(it, &mut data);
                    self.push_reply(&Reply::with_data(command, &data));
                }
                None => self.reply_status(command, Status::ParameterDataError),
            },
            Request::Transfer { index, data } => {
                let status = match item(DataIndex(index)) {
                    Some(it) => self.write_item(it, data).err().unwrap_or(Status::Ack),
                    None => Status::ParameterDataError,
                };
                self.reply_status(command, status);
            }
            Request::Execute { function, params } => {
                let status = self.execute(function, params).err().unwrap_or(Status::Ack);
                self.reply_status(command, status);
            }
            Request::Stop { function, param } => {
                let status = self.stop(function, param).err().unwrap_or(Status::Ack);
                self.reply_status(command, status);
            }
        }
    }

    fn handle_cyclic(&mut self, object: u8, write: &[u8]) {
        let command = Command::Cyclic;
        self.stats.cyclic += 1;
        // Any RC feeds the watchdog and completes the opening of remote mode.
        self.last_rc = self.now;
        self.mode = match self.mode {
            RemoteMode::AwaitingRc(s) | RemoteMode::TimedOut(s) | RemoteMode::Active(s) => RemoteMode::Active(s),
            m => m,
        };
        if object == UNUSED {
            if !write.is_empty() {
                self.reply_status(command, Status::ParameterCountError);
            } else {
                self.reply_status(command, Status::Ack);
            }
            return;
        }
        let Some(obj) = self.cyclic_objects.get(usize::from(object)).copied() else {
            self.reply_status(command, Status::ParameterDataError);
            return;
        };
        if self.mode == RemoteMode::Locked {
            // After a Safety_ID 0 timeout RC is accepted, but no data is exchanged until RO.
            self.reply_status(command, Status::PermissionError);
            return;
        }
        let (Some(write_size), Some(_)) = (obj.write_size(), obj.read_size()) else {
            self.reply_status(command, Status::ParameterDataError);
            return;
        };
        if write.len() != write_size {
            self.reply_status(command, Status::ParameterCountError);
            return;
        }
        let mut at = 0;
        for idx in obj.write_indices() {
            let Some(it) = item(idx) else { break };
            let n = it.size();
            if let Err(status) = self.write_item(it, &write[at..at + n]) {
                self.reply_status(command, status);
                return;
            }
            at += n;
        }
        let mut data = Vec::new();
        for idx in obj.read_indices() {
            if let Some(it) = item(idx) {
                self.read_item(it, &mut data);
            }
        }
        self.push_reply(&Reply::with_data(command, &data));
    }

    fn execute(&mut self, function: u8, params: [u8; 2]) -> Result<(), Status> {
        let f = Function::from_id(function).ok_or(Status::ParameterDataError)?;
        match f {
            Function::Motion(m) => {
                let direction = MotionDirection::from_code(params[0]).ok_or(Status::ParameterDataError)?;
                if params[1] != UNUSED {
                    return Err(Status::ParameterDataError);
                }
                let drives = self.config.functions[usize::from(m.id())].clone();
                if drives.is_empty() || self.emergency_stop {
                    return Err(Status::PermissionError);
                }
                self.executed[usize::from(function)] = true;
                if direction != MotionDirection::Undefined {
                    self.reset_errors_on_motion();
                }
                let speed = self.remote_speed[usize::from(m.id())];
                let mut moves = Vec::new();
                for a in drives {
                    let i = usize::from(a.number()) - 1;
                    let cfg = &self.config.actuators[i];
                    let user = &cfg.user_positions.users[0];
                    let target = match direction {
                        MotionDirection::Undefined => continue,
                        MotionDirection::In => cfg.stroke_min_counts,
                        MotionDirection::Out => cfg.stroke_max_counts,
                        MotionDirection::Memory1 => user.memory_counts[0],
                        MotionDirection::Memory2 => user.memory_counts[1],
                        MotionDirection::Memory3 => user.memory_counts[2],
                        MotionDirection::Memory4 => user.memory_counts[3],
                        MotionDirection::IntermediateIn => user.intermediate_in_counts,
                        MotionDirection::IntermediateOut => user.intermediate_out_counts,
                        MotionDirection::RemotePosition => self.remote_position[i],
                    };
                    let (counts_per_s, percent) = self.speed_of(i, speed);
                    let moves_now =
                        self.actuators[i].start(target, counts_per_s, percent, Origin::Remote, Some(m.id()));
                    let (lo, hi) = self.actuators[i].travel_range();
                    moves.push(format!(
                        "{a} -> {}{}",
                        target.clamp(lo, hi),
                        if moves_now { "" } else { " (already there)" }
                    ));
                }
                self.push_event(format!(
                    "{} started direction {} ({}): {}",
                    m,
                    direction.code(),
                    direction.description(),
                    if moves.is_empty() { "nothing moves".to_string() } else { moves.join(", ") }
                ));
                self.note_rest();
                Ok(())
            }
            other => {
                if params != [UNUSED, UNUSED] {
                    return Err(Status::ParameterDataError);
                }
                self.executed[usize::from(function)] = true;
                self.switch(other, true);
                Ok(())
            }
        }
    }

    /// Counts per second and percent of actuator `i` at remote speed `speed` (in the unit's speed mode).
    fn speed_of(&self, i: usize, speed: u16) -> (f64, u16) {
        let cfg = &self.config.actuators[i];
        match self.config.speed_mode {
            SpeedMode::Percent => (cfg.counts_per_second_at_full_speed * f64::from(speed) / 100.0, speed),
            SpeedMode::CountsPerSecond => {
                (f64::from(speed), (f64::from(speed) / cfg.counts_per_second_at_full_speed * 100.0).round() as u16)
            }
        }
    }

    fn stop(&mut self, function: u8, param: u8) -> Result<(), Status> {
        let f = Function::from_id(function).ok_or(Status::ParameterDataError)?;
        match f {
            Function::Motion(m) => {
                let mode = StopMode::from_code(param).ok_or(Status::ParameterDataError)?;
                self.executed[usize::from(function)] = false;
                for a in self.config.functions[usize::from(m.id())].clone() {
                    let act = &mut self.actuators[usize::from(a.number()) - 1];
                    if act.origin == Origin::Remote {
                        match mode {
                            StopMode::Fast => act.fast_stop(),
                            StopMode::Soft => act.soft_stop(),
                        }
                    }
                }
                let how = match mode {
                    StopMode::Fast => "fast",
                    StopMode::Soft => "soft",
                };
                self.push_event(format!("{m} stopped (RS {how})"));
                self.note_rest();
                Ok(())
            }
            other => {
                if param != UNUSED {
                    return Err(Status::ParameterDataError);
                }
                self.executed[usize::from(function)] = false;
                self.switch(other, false);
                Ok(())
            }
        }
    }

    fn switch(&mut self, f: Function, on: bool) {
        let set = |bits: &mut u8, bit: u8| {
            if on {
                *bits |= 1 << bit;
            } else {
                *bits &= !(1 << bit);
            }
        };
        match f {
            Function::Buzzer => self.buzzer = on,
            Function::BinaryOutput1 => set(&mut self.binary_outputs, 0),
            Function::BinaryOutput2 => set(&mut self.binary_outputs, 1),
            Function::Led1 => set(&mut self.led_hand_switch, 0),
            Function::Led2 => set(&mut self.led_hand_switch, 1),
            Function::EmergencyStop => {
                self.emergency_stop = on;
                if on {
                    self.actuators.iter_mut().for_each(ActuatorState::fast_stop);
                }
            }
            Function::Motion(_) => {}
        }
        self.push_event(format!("F{} {} ({})", f.number(), if on { "on" } else { "off" }, f.description()));
        self.note_rest();
    }
}

impl Emulator for ScuEmulator {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        self.run_until(now);
        if let Some(last) = self.last_byte {
            if self.decoder.is_mid_telegram() && now.saturating_since(last) > INTER_BYTE_LIMIT {
                self.decoder.reset();
                self.stats.dropped_partial += 1;
            }
        }
        if !bytes.is_empty() {
            self.last_byte = Some(now);
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
        [watchdog, motion, self.next_scheduled_error()].into_iter().flatten().min()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::DATA_LIST;

    fn send(unit: &mut ScuEmulator, at_ms: u64, r: Request<'_>) -> Vec<u8> {
        let mut out = Vec::new();
        unit.receive(Timestamp::from_millis(at_ms), &crate::wire::request_to_vec(&r).unwrap(), &mut out);
        out
    }

    #[test]
    fn take_events_reports_switching_and_keeps_only_the_newest_when_nobody_takes_them() {
        let mut unit = ScuEmulator::new(SimConfig::default()).unwrap();
        send(&mut unit, 0, Request::Open { safety_id: 2 });
        send(&mut unit, 0, Request::Cyclic { object: UNUSED, write: &[] });
        send(&mut unit, 1, Request::Execute { function: 10, params: [UNUSED, UNUSED] });
        send(&mut unit, 2, Request::Stop { function: 10, param: UNUSED });
        assert_eq!(unit.take_events(), ["remote mode opened (Safety_ID 2)", "F11 on (buzzer)", "F11 off (buzzer)"]);
        for i in 0..MAX_EVENTS as u64 {
            send(&mut unit, 3 + i / 10, Request::Execute { function: 20, params: [UNUSED, UNUSED] });
            send(&mut unit, 3 + i / 10, Request::Stop { function: 20, param: UNUSED });
            send(&mut unit, 3 + i / 10, Request::Cyclic { object: UNUSED, write: &[] });
        }
        let events = unit.take_events();
        assert_eq!(events.len(), MAX_EVENTS);
        assert_eq!(events.last().map(String::as_str), Some("F21 off (operating unit LED 1)"));
    }

    #[test]
    fn next_wakeup_is_the_watchdog_while_idle_and_every_model_step_while_moving() {
        let mut unit = ScuEmulator::new(SimConfig::default()).unwrap();
        assert_eq!(unit.next_wakeup(), None, "outside remote mode nothing happens by itself");
        send(&mut unit, 100, Request::Open { safety_id: 0 });
        assert_eq!(unit.next_wakeup(), Some(Timestamp::from_millis(600)));
        send(&mut unit, 200, Request::Cyclic { object: UNUSED, write: &[] });
        send(&mut unit, 200, Request::Execute { function: 0, params: [2, UNUSED] });
        assert_eq!(unit.next_wakeup(), Some(Timestamp::from_millis(205)));
        let mut out = Vec::new();
        unit.advance(Timestamp::from_millis(700), &mut out);
        assert!(out.is_empty());
        assert!(!unit.any_moving(), "the watchdog stopped it at 700 ms");
        assert_eq!(unit.next_wakeup(), None, "locked: nothing is due");
        let events = unit.take_events();
        assert!(events.iter().any(|e| e.starts_with("A1 at rest")), "{events:?}");
        assert!(events.iter().any(|e| e.starts_with("remote mode ended by watchdog (Safety_ID 0)")), "{events:?}");
    }

    #[test]
    fn every_entry_of_the_data_list_has_a_modelled_value() {
        let unit = ScuEmulator::new(SimConfig::scp11(6)).unwrap();
        for e in DATA_LIST {
            assert!(unit.entry_value(e).is_some(), "{} ({}) is not modelled", e.name, e.index());
        }
    }
}
