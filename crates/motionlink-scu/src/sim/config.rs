//! The emulated unit's parameterisation: actuators, function mapping, presets, the TOML file.

use super::*;
use crate::model::{DataEntryExt, Function, UserPositionData, UserPositions};

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
    /// On reaching the In end, the position reads this many counts below it (as real units do after homing):
    /// 0 up to the stroke (`stroke_max_counts - stroke_min_counts`).
    pub in_end_undershoot_counts: i32,
    /// A drive that stays stalled (below [`ActuatorConfig::stall_below_percent`], or pushing against
    /// [`ActuatorConfig::obstacle_counts`]) this long while its motion is on is stopped with its drive error
    /// bit (15 for drive 1 .. 20 for drive 6) set, as the unit's drive time-out does. 0: never.
    pub stall_error_after_ms: u64,
    /// An obstacle at this position, within the stroke: the drive cannot pass it and stalls there, pushing
    /// (twice its full-speed current), until its stall error stops it. None: no obstacle.
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
/// variants = ["no-groups"] # firmware variants (see [`Variant`]); `--variant` adds more
/// failed_switches = ["F17"] # RE and RS of F17 are acknowledged, binary output 1 stays as it is
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
    /// Firmware info (0x0001): at most 31 bytes of UTF-8, the entry's size.
    pub firmware_info: String,
    /// Configuration info (0x0002): at most 36 bytes of UTF-8, the entry's size.
    pub configuration_info: String,
    /// Above this total current of all drives, in 0.1 A, error bit 14 is set and every motion fast-stops.
    /// 0: no limit.
    pub total_current_limit_deci_amps: u16,
    /// Errors the unit raises by itself at chosen times.
    pub scheduled_errors: Vec<ScheduledError>,
    /// How this unit's firmware differs from the emulator's default reading of the manual (each once, in
    /// the order of [`Variant::ALL`]: [`SimConfig::add_variants`]).
    pub variants: Vec<Variant>,
    /// Switching functions whose output has failed: the unit acknowledges their RE and RS, and what the data
    /// list shows of them stays as it is (for tests of a host that reads it back; `failed_switches = ["F17"]`
    /// in the TOML configuration).
    pub failed_switches: Vec<Function>,
}

impl SimConfig {
    /// Adds the firmware `variants` to the configuration's, each kept once (sorted).
    pub fn add_variants(&mut self, variants: impl IntoIterator<Item = Variant>) {
        Variant::merge(&mut self.variants, variants);
    }

    /// Refuses a unit that no client could wake if it were served on a TCP port or a pty: one of the
    /// `low-power` variant, which only a break wakes, and a break crosses neither.
    pub fn check_servable(&self) -> Result<(), SimConfigError> {
        if self.variants.contains(&Variant::LowPower) {
            return Err(SimConfigError(
                "the variant low-power is woken only by a break (the line held at space), which neither TCP nor a \
                 pty carries: use it in the client's own process (--port sim --sim-variant low-power --wake, or \
                 Python's Emulator without serve=)"
                    .into(),
            ));
        }
        Ok(())
    }

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
            variants: Vec::new(),
            failed_switches: Vec::new(),
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
        Self::from_toml_over(text, None, &[])
    }

    /// A configuration file's `text` as `motionlink sim scu --sim-config` (and a gateway's `sim_config`) reads
    /// it: `preset` is its starting point where the file names no preset of its own (a file that names another
    /// preset is an error naming both; the same one is fine), and the firmware `variants` are added to the
    /// file's.
    ///
    /// ```
    /// use motionlink_scu::SimConfig;
    /// use motionlink_scu::Variant;
    /// let c = SimConfig::from_toml_over("default_speed = 80\n", Some("tlt"), &[Variant::NoGroups]).unwrap();
    /// assert_eq!(c.configuration_info, SimConfig::tlt().configuration_info);
    /// assert_eq!(c.variants, [Variant::NoGroups]);
    /// ```
    pub fn from_toml_over(text: &str, preset: Option<&str>, variants: &[Variant]) -> Result<Self, SimConfigError> {
        let mut c = Self::from_toml_with(text, preset)?;
        c.add_variants(variants.iter().copied());
        Ok(c)
    }

    fn from_toml_with(text: &str, default_preset: Option<&str>) -> Result<Self, SimConfigError> {
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
            variants: Option<Vec<Variant>>,
            failed_switches: Option<Vec<String>>,
        }
        let f: File = toml::from_str(text).map_err(|e| SimConfigError(e.to_string()))?;
        // The preset given beside the text is where a text that names none starts; a text that names another
        // one contradicts it, and which of the two was meant is not known.
        let preset = match (f.preset.as_deref(), default_preset) {
            (Some(named), Some(given)) if named != given => {
                return Err(SimConfigError(format!(
                    "preset = {named:?} in the configuration differs from the preset {given:?} given with it: \
                     name one of them, or the same in both"
                )));
            }
            (named, given) => named.or(given),
        };
        let mut c = match preset {
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
        if let Some(v) = f.variants {
            c.variants.clear();
            c.add_variants(v);
        }
        if let Some(names) = f.failed_switches {
            c.failed_switches = names
                .iter()
                .map(|name| match Function::parse(name) {
                    Some(Function::Motion(_)) | None => Err(SimConfigError(format!(
                        "failed_switches: {name:?} is not a switching function (F11, F17, F18, F20, F21, F22)"
                    ))),
                    Some(f) => Ok(f),
                })
                .collect::<Result<_, _>>()?;
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
            // The stroke in counts, in i64: the span of a stroke across the whole counts range is above i32::MAX.
            let stroke_counts = i64::from(a.stroke_max_counts) - i64::from(a.stroke_min_counts);
            if !(0..=stroke_counts).contains(&i64::from(a.in_end_undershoot_counts)) {
                return Err(SimConfigError(format!(
                    "actuator {}: in_end_undershoot_counts = {}: allowed 0 to {stroke_counts} (the stroke, \
                     stroke_max_counts - stroke_min_counts)",
                    i + 1,
                    a.in_end_undershoot_counts
                )));
            }
            if let Some(o) = a.obstacle_counts {
                if !(a.stroke_min_counts..=a.stroke_max_counts).contains(&o) {
                    return Err(SimConfigError(format!(
                        "actuator {}: obstacle_counts = {o} is outside the stroke: allowed {} to {}",
                        i + 1,
                        a.stroke_min_counts,
                        a.stroke_max_counts
                    )));
                }
            }
            if !(a.counts_per_second_at_full_speed > 0.0 && a.counts_per_second_at_full_speed.is_finite()) {
                return Err(SimConfigError(format!(
                    "actuator {}: counts_per_second_at_full_speed must be a finite number above 0, not {}",
                    i + 1,
                    a.counts_per_second_at_full_speed
                )));
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
        // The info texts are read as their data-list entries, zero-padded to the entry's size: a longer text
        // would be cut, perhaps in the middle of a character.
        for (name, text, index) in [
            ("firmware_info", &self.firmware_info, DataIndex(0x0001)),
            ("configuration_info", &self.configuration_info, DataIndex(0x0002)),
        ] {
            let size_bytes = crate::model::entry(index).map_or(0, DataEntryExt::size);
            if text.len() > size_bytes {
                return Err(SimConfigError(format!(
                    "{name} {text:?} is {} bytes long: its data-list entry ({index}) holds at most {size_bytes} bytes",
                    text.len()
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
