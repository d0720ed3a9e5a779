//! Actuators, motion functions, the function list, directions, stop modes and Safety_ID.

use std::fmt;

use super::{per_actuator, DataIndex};

/// One of the up to six actuators (drives) of a control unit, numbered 1..6 (in JSON: its number).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(transparent)]
pub struct Actuator(u8);

impl Actuator {
    /// "A1, A2" (or "no actuator"), as messages name a set of actuators.
    pub(crate) fn list(actuators: &[Actuator]) -> String {
        if actuators.is_empty() {
            return "no actuator".into();
        }
        actuators.iter().map(Actuator::to_string).collect::<Vec<_>>().join(", ")
    }

    /// Actuator `number` (1..6), or `None`.
    pub const fn new(number: u8) -> Option<Actuator> {
        if number >= 1 && number <= 6 {
            Some(Actuator(number))
        } else {
            None
        }
    }

    /// Its number, 1..6.
    pub const fn number(self) -> u8 {
        self.0
    }

    /// All six.
    pub fn all() -> impl Iterator<Item = Actuator> {
        (1..=6).map(Actuator)
    }

    /// Data index of its actual position (0x0011..0x0016).
    pub const fn position_index(self) -> DataIndex {
        per_actuator(0x0010, self)
    }

    /// Data index of its status 1 (0x0171..0x0176).
    pub const fn status1_index(self) -> DataIndex {
        per_actuator(0x0170, self)
    }

    /// Data index of its status 2 (0x00E1..0x00E6).
    pub const fn status2_index(self) -> DataIndex {
        per_actuator(0x00E0, self)
    }

    /// Data index of its remote target position (0x3021..0x3026).
    pub const fn remote_position_index(self) -> DataIndex {
        per_actuator(0x3020, self)
    }

    /// Data index of its current (0x00A1..0x00A6).
    pub const fn current_index(self) -> DataIndex {
        per_actuator(0x00A0, self)
    }
}

impl fmt::Display for Actuator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "A{}", self.0)
    }
}

/// One of the motion functions F1..F10, whose drives the unit's parameterisation decides (in JSON: its
/// number, 1..10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(transparent)]
pub struct MotionFunction(u8);

impl MotionFunction {
    /// Function F`number` (1..10), or `None`.
    pub const fn new(number: u8) -> Option<MotionFunction> {
        if number >= 1 && number <= 10 {
            Some(MotionFunction(number))
        } else {
            None
        }
    }

    /// Its number, 1..10.
    pub const fn number(self) -> u8 {
        self.0
    }

    /// All ten, F1..F10.
    pub fn all() -> impl Iterator<Item = MotionFunction> {
        (1..=10).map(MotionFunction)
    }

    /// Its fnc_ID on the wire (F1 is 0).
    pub const fn id(self) -> u8 {
        self.0 - 1
    }

    /// Data index of its remote speed (0x3011..0x301A).
    pub const fn remote_speed_index(self) -> DataIndex {
        DataIndex(0x3010 + self.0 as u16)
    }
}

impl fmt::Display for MotionFunction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "F{}", self.0)
    }
}

/// An entry of the function list (table 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Function {
    /// F1..F10: motion, depending on the parameterisation.
    Motion(MotionFunction),
    /// F11: buzzer (from FW V2B1).
    Buzzer,
    /// F17: binary output 1 (from FW V2B1).
    BinaryOutput1,
    /// F18: binary output 2 (from FW V2B1).
    BinaryOutput2,
    /// F20: emergency stop (from FW V2B1).
    EmergencyStop,
    /// F21: operating unit LED 1 (from FW V2B1).
    Led1,
    /// F22: operating unit LED 2 (from FW V2B1).
    Led2,
}

impl Function {
    /// The function with this fnc_ID (0..9 motion, 10, 16, 17, 19, 20, 21).
    pub const fn from_id(id: u8) -> Option<Function> {
        match id {
            0..=9 => Some(Function::Motion(MotionFunction(id + 1))),
            10 => Some(Function::Buzzer),
            16 => Some(Function::BinaryOutput1),
            17 => Some(Function::BinaryOutput2),
            19 => Some(Function::EmergencyStop),
            20 => Some(Function::Led1),
            21 => Some(Function::Led2),
            _ => None,
        }
    }

    /// Its fnc_ID on the wire.
    pub const fn id(self) -> u8 {
        match self {
            Function::Motion(m) => m.id(),
            Function::Buzzer => 10,
            Function::BinaryOutput1 => 16,
            Function::BinaryOutput2 => 17,
            Function::EmergencyStop => 19,
            Function::Led1 => 20,
            Function::Led2 => 21,
        }
    }

    /// Its name in the manual, F1..F22.
    pub const fn number(self) -> u8 {
        self.id() + 1
    }

    /// What it does.
    pub const fn description(self) -> &'static str {
        match self {
            Function::Motion(_) => "motion function",
            Function::Buzzer => "buzzer",
            Function::BinaryOutput1 => "binary output 1",
            Function::BinaryOutput2 => "binary output 2",
            Function::EmergencyStop => "emergency stop",
            Function::Led1 => "operating unit LED 1",
            Function::Led2 => "operating unit LED 2",
        }
    }

    /// Parses `F1`..`F22` or `1`..`22` (the manual's function numbers, not the wire ids).
    pub fn parse(text: &str) -> Option<Function> {
        let t = text.trim();
        let n: u8 = t.strip_prefix(['F', 'f']).unwrap_or(t).parse().ok()?;
        n.checked_sub(1).and_then(Function::from_id)
    }
}

/// In results, a function is its number in the manual, 1..22.
impl serde::Serialize for Function {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(self.number())
    }
}

impl fmt::Display for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "F{} ({})", self.number(), self.description())
    }
}

/// Functions as messages name them: `F1, F11`.
pub fn function_list(functions: &[Function]) -> String {
    functions.iter().map(|f| format!("F{}", f.number())).collect::<Vec<_>>().join(", ")
}

/// A stop in words: "fast RS of F1", "soft RS of F1, F2", "RS of F11" (a function that is not a motion
/// function, or one soft stop).
pub fn stop_words(functions: &[Function], mode: StopMode) -> String {
    let names: Vec<String> = functions
        .iter()
        .map(|f| match f {
            Function::Motion(m) => m.to_string(),
            other => other.to_string(),
        })
        .collect();
    let motion = functions.iter().all(|f| matches!(f, Function::Motion(_)));
    match (motion, mode) {
        (true, StopMode::Fast) => format!("fast RS of {}", names.join(", ")),
        (true, StopMode::Soft) if functions.len() > 1 => format!("soft RS of {}", names.join(", ")),
        _ => format!("RS of {}", names.join(", ")),
    }
}

/// Where an RE on a motion function moves to (table 6, para_ID motion_direction).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MotionDirection {
    /// 0: undefined direction (no motion).
    Undefined,
    /// 1: move to position In.
    In,
    /// 2: move to position Out.
    Out,
    /// 3: move to position Mem1.
    Memory1,
    /// 4: move to position Mem2.
    Memory2,
    /// 5: move to position Mem3.
    Memory3,
    /// 6: move to position Mem4.
    Memory4,
    /// 7: move to position Intermediate In.
    IntermediateIn,
    /// 8: move to position Intermediate Out.
    IntermediateOut,
    /// 9: move to the remote position (0x3021..0x3026).
    RemotePosition,
}

impl MotionDirection {
    /// Every direction, by code.
    pub const ALL: [MotionDirection; 10] = [
        MotionDirection::Undefined,
        MotionDirection::In,
        MotionDirection::Out,
        MotionDirection::Memory1,
        MotionDirection::Memory2,
        MotionDirection::Memory3,
        MotionDirection::Memory4,
        MotionDirection::IntermediateIn,
        MotionDirection::IntermediateOut,
        MotionDirection::RemotePosition,
    ];

    /// The code on the wire, 0..9.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The direction with this code.
    pub fn from_code(code: u8) -> Option<MotionDirection> {
        Self::ALL.get(usize::from(code)).copied()
    }

    /// The names [`MotionDirection::parse`] takes (besides the codes 0..9).
    pub const NAMES: &'static [&'static str] =
        &["in", "out", "mem1", "mem2", "mem3", "mem4", "int-in", "int-out", "remote", "none", "undefined"];

    /// Parses `in`, `out`, `mem1`..`mem4`, `int-in`, `int-out`, `remote`, `none` (or `undefined`), or a
    /// code 0..9.
    pub fn parse(text: &str) -> Option<MotionDirection> {
        Some(match text.trim().to_ascii_lowercase().as_str() {
            "none" | "undefined" => MotionDirection::Undefined,
            "in" => MotionDirection::In,
            "out" => MotionDirection::Out,
            "mem1" => MotionDirection::Memory1,
            "mem2" => MotionDirection::Memory2,
            "mem3" => MotionDirection::Memory3,
            "mem4" => MotionDirection::Memory4,
            "int-in" => MotionDirection::IntermediateIn,
            "int-out" => MotionDirection::IntermediateOut,
            "remote" => MotionDirection::RemotePosition,
            other => return other.parse::<u8>().ok().and_then(MotionDirection::from_code),
        })
    }

    /// What it does.
    pub const fn description(self) -> &'static str {
        match self {
            MotionDirection::Undefined => "undefined direction (no motion)",
            MotionDirection::In => "move to position In",
            MotionDirection::Out => "move to position Out",
            MotionDirection::Memory1 => "move to position Mem1",
            MotionDirection::Memory2 => "move to position Mem2",
            MotionDirection::Memory3 => "move to position Mem3",
            MotionDirection::Memory4 => "move to position Mem4",
            MotionDirection::IntermediateIn => "move to position Intermediate In",
            MotionDirection::IntermediateOut => "move to position Intermediate Out",
            MotionDirection::RemotePosition => "move to remote position",
        }
    }
}

/// How RS stops a motion function (table 6, para_ID motion_stop); in JSON `fast` or `soft`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StopMode {
    /// 0: fast stop, the stop ramp is not used.
    Fast,
    /// 1: soft stop along the stop ramp.
    Soft,
}

impl StopMode {
    /// The code on the wire.
    pub const fn code(self) -> u8 {
        match self {
            StopMode::Fast => 0,
            StopMode::Soft => 1,
        }
    }

    /// The mode with this code.
    pub const fn from_code(code: u8) -> Option<StopMode> {
        match code {
            0 => Some(StopMode::Fast),
            1 => Some(StopMode::Soft),
            _ => None,
        }
    }
}

/// The unused-parameter value of a byte parameter (-1).
pub const UNUSED: u8 = 0xFF;

/// What the unit does when the RC watchdog (500 ms) expires, chosen with RO.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum SafetyId {
    /// 0: all motions stop, and afterwards only RC, RA and RO are accepted (no motion can start until RO).
    #[default]
    StopAllAndLock,
    /// 1: all motions stop.
    StopAll,
    /// 2: only remote motions stop (FW V2B3).
    StopRemoteOnly,
}

impl SafetyId {
    /// The code on the wire.
    pub const fn code(self) -> u8 {
        match self {
            SafetyId::StopAllAndLock => 0,
            SafetyId::StopAll => 1,
            SafetyId::StopRemoteOnly => 2,
        }
    }

    /// The Safety_ID with this code.
    pub const fn from_code(code: u8) -> Option<SafetyId> {
        match code {
            0 => Some(SafetyId::StopAllAndLock),
            1 => Some(SafetyId::StopAll),
            2 => Some(SafetyId::StopRemoteOnly),
            _ => None,
        }
    }

    /// What a communication timeout does.
    pub const fn description(self) -> &'static str {
        match self {
            SafetyId::StopAllAndLock => "on timeout all motions stop and only RC, RA, RO are accepted",
            SafetyId::StopAll => "on timeout all motions stop",
            SafetyId::StopRemoteOnly => "on timeout only remote motions stop",
        }
    }
}
