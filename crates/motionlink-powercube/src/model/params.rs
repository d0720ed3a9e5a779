//! The parameter table (chapter 4.6): one row per parameter (identifier, name, data type, unit, access and
//! class), made into the shared [`Table`] of [`Entry`] rows ([`PARAMS`]) that every family uses, and the
//! [`Param`] enum that names them.
//!
//! ```
//! use motionlink_powercube::model::{Access, DataType, Param, ParamClass, Unit, PARAMS};
//! let p: Param = "ActPos".parse().unwrap();
//! assert_eq!((p.id(), p.data_type(), p.unit()), (0x3c, DataType::F32, Unit::Position));
//! assert_eq!((p.access(), p.class()), (Access::Read, ParamClass::Actual));
//! assert_eq!("0x4f".parse::<Param>().unwrap(), Param::TargetVel);
//! assert!(!Param::TargetVel.access().readable());
//! assert_eq!(PARAMS.lookup("actpos").map(|e| e.kind.param), Some(Param::ActPos));
//! assert_eq!(PARAMS.by_id(0x3c).map(|e| e.unit), Some("rad|m"));
//! ```

use std::fmt;
use std::str::FromStr;

pub use motionlink_link::table::Access;
use motionlink_link::table::{Entry, Table};

use super::units::ModuleKind;

/// The data type of a parameter on the wire (little-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DataType {
    /// 32-bit float.
    F32,
    /// Unsigned 32-bit integer.
    U32,
    /// Signed 32-bit integer.
    I32,
    /// Unsigned 16-bit integer.
    U16,
    /// Signed 16-bit integer.
    I16,
    /// Unsigned 8-bit integer.
    U8,
    /// Float position, short state byte, DIO byte (6 bytes; ActFPosStateDio).
    PosStateDio,
    /// Float position and a UInt16 millisecond time stamp (6 bytes; ActFPosTime).
    PosTime,
}

impl DataType {
    /// Bytes on the wire.
    pub fn size(self) -> usize {
        match self {
            DataType::F32 | DataType::U32 | DataType::I32 => 4,
            DataType::U16 | DataType::I16 => 2,
            DataType::U8 => 1,
            DataType::PosStateDio | DataType::PosTime => 6,
        }
    }

    /// The manual's name.
    pub fn name(self) -> &'static str {
        match self {
            DataType::F32 => "float",
            DataType::U32 => "UInt32",
            DataType::I32 => "Int32",
            DataType::U16 => "UInt16",
            DataType::I16 => "Int16",
            DataType::U8 => "UInt8",
            DataType::PosStateDio => "float/UInt8/UInt8",
            DataType::PosTime => "float/UInt16",
        }
    }
}

/// The unit class of a parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Unit {
    /// rad (rotary) or m (linear).
    Position,
    /// rad/s or m/s.
    Velocity,
    /// rad/s² or m/s².
    Acceleration,
    /// Encoder ticks.
    Ticks,
    /// Encoder ticks per second.
    TicksPerSec,
    /// Encoder ticks per second squared.
    TicksPerSec2,
    /// Encoder ticks per rad or m.
    TicksPerUnit,
    /// Amperes.
    Amperes,
    /// Volts.
    Volts,
    /// Degrees Celsius.
    Celsius,
    /// Milliseconds.
    Millis,
    /// Raw converter digits.
    Digits,
    /// A dimensionless ratio or gain.
    Ratio,
    /// A word of flags.
    Flags,
    /// A count, an address, a code or a version.
    Plain,
}

impl Unit {
    /// The unit's symbol for a module of `kind` ("" for dimensionless).
    pub fn symbol(self, kind: ModuleKind) -> &'static str {
        match (self, kind) {
            (Unit::Position, ModuleKind::Rotary) => "rad",
            (Unit::Position, ModuleKind::Linear) => "m",
            (Unit::Velocity, ModuleKind::Rotary) => "rad/s",
            (Unit::Velocity, ModuleKind::Linear) => "m/s",
            (Unit::Acceleration, ModuleKind::Rotary) => "rad/s²",
            (Unit::Acceleration, ModuleKind::Linear) => "m/s²",
            (Unit::Ticks, _) => "ticks",
            (Unit::TicksPerSec, _) => "ticks/s",
            (Unit::TicksPerSec2, _) => "ticks/s²",
            (Unit::TicksPerUnit, ModuleKind::Rotary) => "ticks/rad",
            (Unit::TicksPerUnit, ModuleKind::Linear) => "ticks/m",
            (Unit::Amperes, _) => "A",
            (Unit::Volts, _) => "V",
            (Unit::Celsius, _) => "°C",
            (Unit::Millis, _) => "ms",
            (Unit::Digits, _) => "digits",
            (Unit::Ratio, _) | (Unit::Flags, _) | (Unit::Plain, _) => "",
        }
    }

    /// The unit's symbol whatever the module's kind ("rad|m" where it depends on it), as the table shows it.
    pub const fn generic_symbol(self) -> &'static str {
        match self {
            Unit::Position => "rad|m",
            Unit::Velocity => "rad|m/s",
            Unit::Acceleration => "rad|m/s²",
            Unit::Ticks => "ticks",
            Unit::TicksPerSec => "ticks/s",
            Unit::TicksPerSec2 => "ticks/s²",
            Unit::TicksPerUnit => "ticks/(rad|m)",
            Unit::Amperes => "A",
            Unit::Volts => "V",
            Unit::Celsius => "°C",
            Unit::Millis => "ms",
            Unit::Digits => "digits",
            Unit::Ratio | Unit::Flags | Unit::Plain => "",
        }
    }
}

/// The manual's classes of parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParamClass {
    /// Stored in the module's ROM; initialises the variables.
    Default,
    /// Settable limits and settings, lost at power off.
    Limit,
    /// Targets of motion commands.
    Target,
    /// Actual values.
    Actual,
    /// "Vorgabe": a setting the host gives (only Config): written after power on, lost at power off like a
    /// limit, though it limits nothing; its ROM default is DefConfig.
    Setting,
}

impl ParamClass {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            ParamClass::Default => "default",
            ParamClass::Limit => "limit",
            ParamClass::Target => "target",
            ParamClass::Actual => "actual",
            ParamClass::Setting => "setting",
        }
    }
}

/// What the shared table's rows carry besides id, name, title, unit and access: the PowerCube's own
/// details of a parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamKind {
    /// The parameter.
    pub param: Param,
    /// Its data type on the wire.
    pub data_type: DataType,
    /// Its unit class (the table row's `unit` is its [`Unit::generic_symbol`]).
    pub unit: Unit,
    /// The manual's class.
    pub class: ParamClass,
}

/// Makes the [`Param`] enum and the [`Entry`] rows of the shared table from one list of rows.
macro_rules! param_table {
    ( $( $var:ident = ($id:literal, $name:literal, $ty:ident, $unit:ident, $access:ident, $class:ident, $doc:literal) ),* $(,)? ) => {
        /// A module parameter: every entry of the manual's parameter table.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Param {
            $( #[doc = $doc] $var ),*
        }

        /// The rows of the parameter table, in the order of [`Param`].
        pub static PARAM_ENTRIES: &[Entry<ParamKind>] = &[
            $( Entry {
                id: $id,
                name: $name,
                title: $doc,
                unit: Unit::$unit.generic_symbol(),
                access: Access::$access,
                kind: ParamKind {
                    param: Param::$var,
                    data_type: DataType::$ty,
                    unit: Unit::$unit,
                    class: ParamClass::$class,
                },
            } ),*
        ];

        impl Param {
            /// Every parameter, by identifier.
            pub const ALL: &'static [Param] = &[$(Param::$var),*];

            /// The parameter with this ParameterID (the same rows, as a `match` for the decoder).
            pub fn from_id(id: u8) -> Option<Param> {
                match id { $($id => Some(Param::$var),)* _ => None }
            }
        }
    };
}

/// The parameter table, searchable by name or number as every family's table is.
pub static PARAMS: Table<ParamKind> = Table::new("parameter", PARAM_ENTRIES);

impl Param {
    /// The parameter's row of [`PARAMS`].
    pub fn entry(self) -> &'static Entry<ParamKind> {
        &PARAM_ENTRIES[self as usize]
    }

    /// The ParameterID.
    pub fn id(self) -> u8 {
        // Every id in the table is a byte (the rows are written as byte literals).
        self.entry().id as u8
    }

    /// The manual's name.
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// The data type on the wire.
    pub fn data_type(self) -> DataType {
        self.entry().kind.data_type
    }

    /// The unit class.
    pub fn unit(self) -> Unit {
        self.entry().kind.unit
    }

    /// Read and write access.
    pub fn access(self) -> Access {
        self.entry().access
    }

    /// The manual's class.
    pub fn class(self) -> ParamClass {
        self.entry().kind.class
    }

    /// The manual's explanation.
    pub fn description(self) -> &'static str {
        self.entry().title
    }

    /// The parameter a write of this one is read back from when that is another one: the write-only
    /// TargetPos, TargetVel and TargetAcc are kept by the module in encoder ticks, in TargetPosInc,
    /// TargetVelInc and TargetAccInc. `None`: the parameter is read back as itself (where it can be read).
    /// What [`Op::SetChecked`](crate::session::Op::SetChecked) reads, and what front ends name.
    pub fn read_back_as(self) -> Option<Param> {
        match self {
            Param::TargetPos => Some(Param::TargetPosInc),
            Param::TargetVel => Some(Param::TargetVelInc),
            Param::TargetAcc => Some(Param::TargetAccInc),
            _ => None,
        }
    }

    /// A value read back from this parameter's tick twin ([`Param::read_back_as`]) in this parameter's
    /// own unit (rad, rad/s, rad/s² or m, m/s, m/s² by the module's kind), given the module's IncRatio
    /// (encoder ticks per unit, above 0). `None` for a parameter that has no tick twin, a value that is no
    /// number, or a ratio that is not a number above 0.
    pub fn from_read_back_ticks(self, ticks: &super::Value, inc_ratio: f64) -> Option<f64> {
        self.read_back_as()?;
        if !(inc_ratio.is_finite() && inc_ratio > 0.0) {
            return None;
        }
        ticks.as_f64().map(|t| t / inc_ratio)
    }
}

param_table! {
    DefHomeOffset = (0x00, "DefHomeOffset", F32, Position, Read, Default, "Offset of the home position (default)."),
    DefGearRatio = (0x01, "DefGearRatio", F32, Ratio, Read, Default, "Gear ratio (default)."),
    DefLinRatio = (0x02, "DefLinRatio", F32, Ratio, Read, Default, "Rotary to linear transmission factor (default)."),
    DefMinPos = (0x03, "DefMinPos", F32, Position, Read, Default, "Minimum position (default)."),
    DefMaxPos = (0x04, "DefMaxPos", F32, Position, Read, Default, "Maximum position (default)."),
    DefMaxDeltaPos = (0x05, "DefMaxDeltaPos", F32, Position, Read, Default, "Maximum following error (default)."),
    DefMaxDeltaVel = (0x06, "DefMaxDeltaVel", F32, Velocity, Read, Default,
        "Maximum following error of velocity control (default)."),
    DefTorqueRatio = (0x07, "DefTorqueRatio", F32, Ratio, Read, Default, "Current to torque factor (default)."),
    DefCurRatio = (0x08, "DefCurRatio", F32, Ratio, Read, Default, "Current measurement factor (default)."),
    DefMinVel = (0x09, "DefMinVel", F32, Velocity, Read, Default, "Minimum velocity (default)."),
    DefMaxVel = (0x0a, "DefMaxVel", F32, Velocity, Read, Default, "Maximum velocity (default)."),
    DefMinAcc = (0x0b, "DefMinAcc", F32, Acceleration, Read, Default, "Minimum acceleration (default)."),
    DefMaxAcc = (0x0c, "DefMaxAcc", F32, Acceleration, Read, Default, "Maximum acceleration (default)."),
    DefMinCur = (0x0d, "DefMinCur", F32, Amperes, Read, Default, "Minimum current (default)."),
    DefMaxCur = (0x0e, "DefMaxCur", F32, Amperes, Read, Default, "Maximum current (default)."),
    DefHomeVel = (0x0f, "DefHomeVel", F32, Velocity, Read, Default,
        "Homing velocity; its sign is the homing direction (default)."),
    DefHomeAcc = (0x10, "DefHomeAcc", F32, Acceleration, Read, Default, "Homing acceleration (default)."),
    DefCubeSerial = (0x1a, "DefCubeSerial", U32, Plain, Read, Default, "Serial number."),
    DefConfig = (0x1b, "DefConfig", U32, Flags, Read, Default, "Config word (default)."),
    DefPulsesPerTurn = (0x1c, "DefPulsesPerTurn", U32, Ticks, Read, Default, "Encoder ticks per revolution."),
    DefCubeVersion = (0x1d, "DefCubeVersion", U16, Plain, Read, Default, "Firmware version."),
    DefServiceInterval = (0x1e, "DefServiceInterval", U16, Plain, Read, Default, "Service interval."),
    DefBrakeTimeOut = (0x1f, "DefBrakeTimeOut", U16, Millis, Read, Default, "Delay for releasing the brake."),
    DefAddress = (0x20, "DefAddress", U8, Plain, Read, Default, "Bus address 1..31."),
    DefPrimBaud = (0x22, "DefPrimBaud", U8, Plain, Read, Default, "Primary baud rate setting."),
    DefScndBaud = (0x23, "DefScndBaud", U8, Plain, Read, Default, "Secondary baud rate setting."),
    PosCount = (0x24, "PosCount", I32, Ticks, Read, Actual, "Absolute counter value."),
    RefPosCount = (0x25, "RefPosCount", I32, Ticks, Read, Actual, "Absolute counter value at the home position."),
    DioSetup = (0x26, "DioSetup", U32, Flags, ReadWrite, Actual, "Digital I/O word."),
    CubeState = (0x27, "CubeState", U32, Flags, Read, Actual, "Module state word."),
    TargetPosInc = (0x28, "TargetPosInc", I32, Ticks, ReadWrite, Target,
        "Target position in encoder ticks (signed; the manual prints UInt32)."),
    TargetVelInc = (0x29, "TargetVelInc", U32, TicksPerSec, ReadWrite, Target, "Target velocity in ticks/s."),
    TargetAccInc = (0x2a, "TargetAccInc", U32, TicksPerSec2, ReadWrite, Target, "Target acceleration in ticks/s²."),
    StepInc = (0x2b, "StepInc", I32, Ticks, Read, Actual,
        "Step mode target position in ticks (signed; the manual prints UInt32)."),
    HomeOffsetInc = (0x2c, "HomeOffsetInc", I32, Ticks, Read, Actual, "Home offset in encoder ticks."),
    RawCur = (0x35, "RawCur", I16, Digits, ReadWrite, Actual, "Commanded current in digits -500..500."),
    HomeToZeroInc = (0x36, "HomeToZeroInc", I32, Ticks, Read, Actual,
        "Encoder ticks between the home switch and the encoder index."),
    Config = (0x39, "Config", U32, Flags, ReadWrite, Setting,
        "Config word (the manual's class \"Vorgabe\": a setting, lost at power off; DefConfig is its default)."),
    MoveMode = (0x3a, "MoveMode", U8, Plain, Read, Actual, "Motion mode (the MotionID last commanded)."),
    IncRatio = (0x3b, "IncRatio", F32, TicksPerUnit, Read, Actual, "Encoder ticks per rad or m."),
    ActPos = (0x3c, "ActPos", F32, Position, Read, Actual, "Actual position."),
    PrevActPos = (0x3d, "ActPos_", F32, Position, Read, Actual, "Previous position."),
    IPolPos = (0x3e, "IPolPos", F32, Position, Read, Actual, "Actual interpolated position."),
    DeltaPos = (0x3f, "DeltaPos", F32, Position, Read, Actual, "Actual following error."),
    MaxDeltaPos = (0x40, "MaxDeltaPos", F32, Position, ReadWrite, Limit, "Maximum following error."),
    ActVel = (0x41, "ActVel", F32, Velocity, Read, Actual, "Actual velocity."),
    IPolVel = (0x42, "IPolVel", F32, Velocity, Read, Actual, "Actual interpolated velocity."),
    MinPos = (0x45, "MinPos", F32, Position, ReadWrite, Limit, "Minimum position (soft limit)."),
    MaxPos = (0x46, "MaxPos", F32, Position, ReadWrite, Limit, "Maximum position (soft limit)."),
    MaxVel = (0x48, "MaxVel", F32, Velocity, ReadWrite, Limit, "Maximum velocity."),
    MaxAcc = (0x4a, "MaxAcc", F32, Acceleration, ReadWrite, Limit, "Maximum acceleration."),
    MaxCur = (0x4c, "MaxCur", F32, Amperes, ReadWrite, Limit, "Maximum current."),
    Cur = (0x4d, "Cur", F32, Amperes, ReadWrite, Actual, "Actual current."),
    TargetPos = (0x4e, "TargetPos", F32, Position, Write, Target, "Target position."),
    TargetVel = (0x4f, "TargetVel", F32, Velocity, Write, Target, "Target velocity of ramp motions."),
    TargetAcc = (0x50, "TargetAcc", F32, Acceleration, Write, Target, "Target acceleration of ramp motions."),
    DefC0 = (0x51, "DefC0", I16, Ratio, Read, Default, "Servo loop gain C0 (default)."),
    DefDamp = (0x52, "DefDamp", I16, Ratio, Read, Default, "Servo loop damping (default)."),
    DefA0 = (0x53, "DefA0", I16, Ratio, Read, Default,
        "Servo loop parameter A0 (default; the manual marks no access, read like the other defaults)."),
    ActC0 = (0x54, "ActC0", I16, Ratio, ReadWrite, Actual, "Servo loop gain C0."),
    ActDamp = (0x55, "ActDamp", I16, Ratio, ReadWrite, Actual, "Servo loop damping."),
    ActA0 = (0x56, "ActA0", I16, Ratio, ReadWrite, Actual, "Servo loop parameter A0."),
    DefBurnCount = (0x57, "DefBurnCount", U8, Plain, Read, Default, "Number of flash downloads."),
    Setup = (0x58, "Setup", U32, Flags, Read, Default, "Setup word."),
    HomeOffset = (0x59, "HomeOffset", F32, Position, ReadWrite, Actual, "Home offset."),
    ActIPos = (0x5a, "ActIPos", I32, Ticks, Read, Actual, "Actual position in encoder ticks."),
    ActIMaxDeltaPos = (0x5b, "ActIMaxDeltaPos", I32, Ticks, ReadWrite, Limit, "Maximum following error in ticks."),
    ActIMinPos = (0x5c, "ActIMinPos", I32, Ticks, ReadWrite, Limit, "Minimum position in ticks."),
    ActIMaxPos = (0x5d, "ActIMaxPos", I32, Ticks, ReadWrite, Limit, "Maximum position in ticks."),
    ActIMaxVel = (0x5e, "ActIMaxVel", I32, TicksPerSec, ReadWrite, Limit, "Maximum velocity in ticks/s."),
    ActIMaxAcc = (0x5f, "ActIMaxAcc", I32, TicksPerSec2, ReadWrite, Limit, "Maximum acceleration in ticks/s²."),
    ActIVel = (0x60, "ActIVel", I32, TicksPerSec, Read, Actual, "Actual velocity in ticks/s."),
    ActIDeltaPos = (0x61, "ActIDeltaPos", I32, Ticks, Read, Actual, "Actual following error in ticks."),
    ActFPosStateDio = (0x62, "ActFPosStateDio", PosStateDio, Position, Read, Actual,
        "Actual position, short state and DIO in one read."),
    ActFSavedPos = (0x63, "ActFSavedPos", F32, Position, Read, Actual, "Position saved by the last broadcast."),
    ActFHomeVel = (0x64, "ActFHomeVel", F32, Velocity, Read, Actual, "Actual homing velocity."),
    ActIHomeVel = (0x65, "ActIHomeVel", I32, TicksPerSec, Read, Actual, "Actual homing velocity in ticks/s."),
    ActSyncTime = (0x66, "ActSyncTime", U16, Millis, ReadWrite, Actual, "Actual SYNC time."),
    ActIIPolVel = (0x6a, "ActIIPolVel", I32, TicksPerSec, Read, Actual, "Actual calculated velocity in ticks/s."),
    ActRawMotorCurrent = (0x6c, "ActRawMotorCurrent", U16, Digits, Read, Actual, "DC bus current."),
    ActRawMotorSupply = (0x6d, "ActRawMotorSupply", U16, Digits, Read, Actual, "DC bus voltage."),
    ActRawTemp = (0x6e, "ActRawTemp", I16, Digits, Read, Actual, "Temperature inside the housing."),
    ActRawLogicSupply = (0x6f, "ActRawLogicSupply", U16, Digits, Read, Actual, "Logic voltage."),
    ActFMotorCurrent = (0x70, "ActFMotorCurrent", F32, Amperes, Read, Actual, "DC bus current."),
    ActFMotorSupply = (0x71, "ActFMotorSupply", F32, Volts, Read, Actual, "DC bus voltage."),
    ActFTemp = (0x72, "ActFTemp", F32, Celsius, Read, Actual, "Temperature inside the housing."),
    ActFLogicSupply = (0x73, "ActFLogicSupply", F32, Volts, Read, Actual, "Logic supply voltage."),
    ActMinLogicSupply = (0x74, "ActMinLogicSupply", F32, Volts, ReadWrite, Limit, "Minimum logic voltage."),
    ActMaxLogicSupply = (0x75, "ActMaxLogicSupply", F32, Volts, ReadWrite, Limit, "Maximum logic voltage."),
    ActMinMotorSupply = (0x76, "ActMinMotorSupply", F32, Volts, ReadWrite, Limit, "Minimum motor voltage."),
    ActMaxMotorSupply = (0x77, "ActMaxMotorSupply", F32, Volts, ReadWrite, Limit, "Maximum motor voltage."),
    ActLogicUndershootTime = (0x7a, "ActLogicUndershootTime", U32, Millis, ReadWrite, Limit,
        "Longest allowed logic undervoltage."),
    ActLogicOvershootTime = (0x7b, "ActLogicOvershootTime", U32, Millis, ReadWrite, Limit,
        "Longest allowed logic overvoltage."),
    ActMotorUndershootTime = (0x7c, "ActMotorUndershootTime", U32, Millis, ReadWrite, Limit,
        "Longest allowed motor undervoltage."),
    ActMotorOvershootTime = (0x7d, "ActMotorOvershootTime", U32, Millis, ReadWrite, Limit,
        "Longest allowed motor overvoltage."),
    ActMaxTemp = (0x84, "ActMaxTemp", F32, Celsius, ReadWrite, Limit, "Maximum housing temperature."),
    ActMinTemp = (0x85, "ActMinTemp", F32, Celsius, ReadWrite, Limit, "Minimum housing temperature."),
    ActFPosTime = (0xa1, "ActFPosTime", PosTime, Position, Read, Actual, "Actual position and time stamp."),
    ActFScanPosFallEdge = (0xa2, "ActFScanPosFallEdge", F32, Position, Read, Actual,
        "Position saved at an edge of input SW3."),
    ActFScanPosRisgEdge = (0xa3, "ActFScanPosRisgEdge", F32, Position, Read, Actual,
        "Position saved at the other edge of input SW3."),
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A parameter name or number that is not in the table; its message names the nearest parameter when the
/// name looks misspelt (`ActPoss`: did you mean ActPos?).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown parameter {0:?}: {hint}", hint = unknown_param_hint(.0))]
pub struct UnknownParam(pub String);

/// What to give instead of `text`: the nearest names of [`PARAMS`], or the forms a parameter takes.
fn unknown_param_hint(text: &str) -> String {
    motionlink_link::table::did_you_mean(&PARAMS.suggest(text))
        .unwrap_or_else(|| "give a name such as ActPos or an id such as 60 or 0x3c".to_string())
}

impl FromStr for Param {
    type Err = UnknownParam;

    /// A name (case-insensitive) or an identifier in decimal or `0x` hex, looked up in [`PARAMS`].
    fn from_str(s: &str) -> Result<Self, UnknownParam> {
        PARAMS.lookup(s).map(|e| e.kind.param).ok_or_else(|| UnknownParam(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_unique_and_names_parse() {
        for (i, p) in Param::ALL.iter().enumerate() {
            assert_eq!(Param::from_id(p.id()), Some(*p));
            assert_eq!(p.name().parse::<Param>().unwrap(), *p);
            assert_eq!(p.id().to_string().parse::<Param>().unwrap(), *p);
            assert!(Param::ALL[i + 1..].iter().all(|q| q.id() != p.id()));
            // Every GetExtended acknowledge fits 8 bytes, every SetExtended 3..6.
            assert!(2 + p.data_type().size() <= 8);
            if p.access().writable() {
                assert!((3..=6).contains(&(2 + p.data_type().size())), "{p}");
            }
        }
        assert_eq!(Param::ALL.len(), 100, "the manual lists 100 parameters");
        assert!("nosuch".parse::<Param>().is_err());
        assert!("0x11".parse::<Param>().is_err(), "0x11 is not in the table");
    }

    #[test]
    fn a_misspelt_name_is_answered_with_the_nearest_one() {
        let e = "ActPoss".parse::<Param>().unwrap_err().to_string();
        assert_eq!(e, "unknown parameter \"ActPoss\": did you mean ActPos?");
        let e = "targetvle".parse::<Param>().unwrap_err().to_string();
        assert!(e.ends_with("did you mean TargetVel?"), "{e}");
        let e = "Banana".parse::<Param>().unwrap_err().to_string();
        assert!(e.contains("give a name such as ActPos"), "nothing near: the forms a parameter takes: {e}");
    }

    #[test]
    fn the_manuals_access_rules() {
        assert_eq!(Param::TargetAcc.access(), Access::Write);
        assert_eq!(Param::Config.access(), Access::ReadWrite);
        assert_eq!(Param::Setup.access(), Access::Read);
        assert_eq!(Param::DefCubeSerial.class(), ParamClass::Default);
        assert_eq!(Param::MaxVel.class(), ParamClass::Limit);
        assert_eq!(Param::TargetVel.class(), ParamClass::Target);
        assert_eq!(Param::ActPos.class(), ParamClass::Actual);
        assert_eq!(Param::PrevActPos.name(), "ActPos_");
        // "Config word (Vorgabe)": the only parameter of its class; not a ROM default (that is DefConfig),
        // not a limit.
        assert_eq!(Param::Config.class(), ParamClass::Setting);
        assert_eq!(Param::DefConfig.class(), ParamClass::Default);
        assert_eq!(Param::ALL.iter().filter(|p| p.class() == ParamClass::Setting).count(), 1);
    }

    #[test]
    fn the_table_rows_follow_the_enum() {
        for (i, p) in Param::ALL.iter().enumerate() {
            assert_eq!(PARAM_ENTRIES[i].kind.param, *p);
            assert_eq!(PARAMS.by_name(p.name()).map(|e| e.kind.param), Some(*p));
        }
        assert_eq!(PARAMS.what, "parameter");
        assert_eq!(Param::TargetVel.access().short(), "w");
    }
}
