//! Results as data: every report and record an operation returns serialises (`serde::Serialize`) with the
//! names `motionlink powercube --json` prints, so that the command line, the web console and Python give the
//! same fields. A position's name carries its unit, which depends on the module's kind (`reached_rad` on a
//! rotary module, `reached_m` on a linear one): each report that holds a position holds the kind too.
//!
//! The state word shows as every flag word does (`word`, `flags`, `unknown_bits` when nonzero), with its
//! `faults` (the flags that are no information): [`StateReport`].

use motionlink_link::flags::FlagWord;
use motionlink_link::table::Entry;
use serde::ser::{Serialize, SerializeMap, Serializer};

mod acted;
pub use acted::{Acted, Released, Timed};

use crate::model::{CubeState, ModuleKind, Param, ParamKind, Position, StateFlag, Value};
use crate::session::{
    HaltReport, HomeReport, ModuleInfo, MotionReport, MoveReport, Readback, ScanEntry, SetpointReport,
};
use crate::wire::{AckPosition, ExtAck};

/// The name of a quantity `stem` of a module of `kind`: `position_rad`, `max_velocity_m_per_s` (`tail` after
/// the unit: "", "_per_s", "_per_s2").
fn key(stem: &str, kind: ModuleKind, tail: &str) -> String {
    format!("{stem}_{}{tail}", kind.unit())
}

/// A flag of the state word as an error history shows it (as the SCU's error bits): `bit` (its bit number,
/// 0..31), `name` and `cause` (the manual's meaning).
impl Serialize for StateFlag {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("bit", &self.mask().trailing_zeros())?;
        map.serialize_entry("name", self.name())?;
        map.serialize_entry("cause", self.meaning())?;
        map.end()
    }
}

/// The state word as results show it: `word`, `flags` (the manual's names), `unknown_bits` (only when
/// nonzero) and `faults` (the flags set that are not information: why a module stopped).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateReport(pub CubeState);

impl Serialize for StateReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let w = self.0;
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("word", &w.0)?;
        map.serialize_entry("flags", &w.names())?;
        if w.unknown() != 0 {
            map.serialize_entry("unknown_bits", &w.unknown())?;
        }
        map.serialize_entry("faults", &w.faults().map(|f| f.name()).collect::<Vec<_>>())?;
        map.end()
    }
}

/// A value as results show it: a number, or for ActFPosStateDio `{position, short_state, dio}` (both flag
/// words) and for ActFPosTime `{position, time_ms}`.
impl Serialize for Value {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match *self {
            Value::F32(x) => s.serialize_f32(x),
            Value::U32(x) => s.serialize_u32(x),
            Value::I32(x) => s.serialize_i32(x),
            Value::U16(x) => s.serialize_u16(x),
            Value::I16(x) => s.serialize_i16(x),
            Value::U8(x) => s.serialize_u8(x),
            Value::PosStateDio { pos, state, dio } => {
                let mut map = s.serialize_map(Some(3))?;
                map.serialize_entry("position", &pos)?;
                map.serialize_entry("short_state", &state)?;
                map.serialize_entry("dio", &dio)?;
                map.end()
            }
            Value::PosTime { pos, time_ms } => {
                let mut map = s.serialize_map(Some(2))?;
                map.serialize_entry("position", &pos)?;
                map.serialize_entry("time_ms", &time_ms)?;
                map.end()
            }
        }
    }
}

/// A module's identity into `map`: `module`, `kind`, `version`, `serial`, `state`.
fn identity<M: SerializeMap>(map: &mut M, i: &ModuleInfo) -> Result<(), M::Error> {
    map.serialize_entry("module", &i.address.get())?;
    map.serialize_entry("kind", &i.kind)?;
    map.serialize_entry("version", &i.version.to_string())?;
    map.serialize_entry("serial", &i.serial)?;
    map.serialize_entry("state", &StateReport(i.state))
}

/// `module`, `kind` (rotary, linear), `version` ("3.5.1D"), `serial`, `state`.
impl Serialize for ModuleInfo {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        identity(&mut map, self)?;
        map.end()
    }
}

/// A module that was read as [`ModuleInfo`]; one that answered and then could not be read as
/// `{module, error}` (the error's message).
impl Serialize for ScanEntry {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match &self.info {
            Ok(info) => info.serialize(s),
            Err(e) => {
                let mut map = s.serialize_map(Some(2))?;
                map.serialize_entry("module", &self.address.get())?;
                map.serialize_entry("error", &e.to_string())?;
                map.end()
            }
        }
    }
}

/// `target_rad`, `reached_rad`, `difference_rad` (reached − target; `_m` on a linear module), `state`,
/// `homed` (STATE_HOME_OK at the end, [`MoveReport::homed`]), `verified`, `not_verifiable`.
impl Serialize for MoveReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (target, reached) = (self.target.value(), self.reached.value());
        let mut map = s.serialize_map(None)?;
        map.serialize_entry(&key("target", self.kind, ""), &target)?;
        map.serialize_entry(&key("reached", self.kind, ""), &reached)?;
        map.serialize_entry(&key("difference", self.kind, ""), &(reached - target))?;
        map.serialize_entry("state", &StateReport(self.state))?;
        map.serialize_entry("homed", &self.homed())?;
        map.serialize_entry("verified", &self.verified)?;
        map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        map.end()
    }
}

/// The extended acknowledge of a motion command: `position` (as the module sent it: rad or m for the float
/// modes, encoder ticks for the I modes), `position_unit` ("rad", "m", "rad|m" where the kind was not known,
/// or "ticks"), `short_state` and `dio` (flag words).
struct ExtAckReport<'a>(&'a ExtAck);

impl Serialize for ExtAckReport<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(4))?;
        match self.0.position {
            AckPosition::Unit(p) => {
                map.serialize_entry("position", &p.value())?;
                map.serialize_entry("position_unit", p.unit().symbol())?;
            }
            AckPosition::Ticks(t) => {
                map.serialize_entry("position", &t.0)?;
                map.serialize_entry("position_unit", "ticks")?;
            }
        }
        map.serialize_entry("short_state", &self.0.state)?;
        map.serialize_entry("dio", &self.0.dio)?;
        map.end()
    }
}

/// `mode` (the manual's name: "FVEL_MODE"), `start_rad`, `target_rad` (position modes), `reached_rad`,
/// `difference_rad` (position modes: reached − target; `_m` on a linear module), `held_s` (continuous
/// modes), `ended` ("reached", "velocity_zero", "halted"), `ext_ack` (when one came: `{position,
/// position_unit, short_state, dio}`), `state`, `homed` ([`MotionReport::homed`]), `verified`,
/// `not_verifiable`.
impl Serialize for MotionReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let reached = self.reached.value();
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("mode", self.mode.name())?;
        map.serialize_entry(&key("start", self.kind, ""), &self.start.value())?;
        if let Some(target) = self.target {
            map.serialize_entry(&key("target", self.kind, ""), &target.value())?;
        }
        map.serialize_entry(&key("reached", self.kind, ""), &reached)?;
        if let Some(target) = self.target {
            map.serialize_entry(&key("difference", self.kind, ""), &(reached - target.value()))?;
        }
        if let Some(held) = self.held {
            map.serialize_entry("held_s", &held.as_secs_f64())?;
        }
        map.serialize_entry("ended", &self.ending)?;
        if let Some(ext) = &self.ext_ack {
            map.serialize_entry("ext_ack", &ExtAckReport(ext))?;
        }
        map.serialize_entry("state", &StateReport(self.state))?;
        map.serialize_entry("homed", &self.homed())?;
        map.serialize_entry("verified", &self.verified)?;
        map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        map.end()
    }
}

/// `mode` (the manual's name: "FVEL_ACK"), `ext_ack` (when one came: `{position, position_unit,
/// short_state, dio}`, as in [`MotionReport`]), `watchdog` (armed and refreshed by the session).
impl Serialize for SetpointReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("mode", self.mode.name())?;
        if let Some(ext) = &self.ext_ack {
            map.serialize_entry("ext_ack", &ExtAckReport(ext))?;
        }
        map.serialize_entry("watchdog", &self.watchdog)?;
        map.end()
    }
}

/// `reached_rad` (`reached_m`), `state`, `verified`, `not_verifiable`.
impl Serialize for HomeReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry(&key("reached", self.kind, ""), &self.reached.value())?;
        map.serialize_entry("state", &StateReport(self.state))?;
        map.serialize_entry("verified", &self.verified)?;
        map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        map.end()
    }
}

/// `position_rad` (`position_m`) and `state`.
impl Serialize for HaltReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry(&key("position", self.kind, ""), &self.position.value())?;
        map.serialize_entry("state", &StateReport(self.state))?;
        map.end()
    }
}

/// A parameter read from a module of `kind`: `name`, `id`, `value`, `unit` (of the kind: "rad/s", "m/s")
/// and `access` ("r", "w", "rw").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamReading {
    /// The parameter.
    pub param: Param,
    /// The module's kind (the parameter's unit).
    pub kind: ModuleKind,
    /// The value read.
    pub value: Value,
}

impl Serialize for ParamReading {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(5))?;
        map.serialize_entry("name", self.param.name())?;
        map.serialize_entry("id", &self.param.id())?;
        map.serialize_entry("value", &self.value)?;
        map.serialize_entry("unit", self.param.unit().symbol(self.kind))?;
        map.serialize_entry("access", self.param.access().short())?;
        map.end()
    }
}

/// A parameter written and checked ([`Readback`]): `name`, `id`, `value` (as written), `ok`, `read_back`
/// (in the parameter's unit, also for TargetPos / TargetVel / TargetAcc read through their tick twins;
/// null when nothing could be read back), `verified`, `not_verifiable`.
#[derive(Debug, Clone, PartialEq)]
pub struct SetReport {
    /// The parameter.
    pub param: Param,
    /// The value written.
    pub value: Value,
    /// How it was checked.
    pub readback: Readback,
}

impl Serialize for SetReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("name", self.param.name())?;
        map.serialize_entry("id", &self.param.id())?;
        map.serialize_entry("value", &self.value)?;
        map.serialize_entry("ok", &true)?;
        match (self.readback.read_in_unit, &self.readback.read) {
            (Some(in_unit), _) => map.serialize_entry("read_back", &in_unit)?,
            (None, read) => map.serialize_entry("read_back", read)?,
        }
        map.serialize_entry("verified", &self.readback.verified)?;
        map.serialize_entry("not_verifiable", &self.readback.not_verifiable)?;
        map.end()
    }
}

/// A module's identity, state, limits and position (`motionlink powercube info`): the fields of
/// [`ModuleInfo`], then `min_position_rad`, `max_position_rad`, `max_velocity_rad_per_s`,
/// `max_acceleration_rad_per_s2` and `position_rad` (`_m` ... on a linear module).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModuleDetails {
    /// Type, version, serial number, state.
    pub info: ModuleInfo,
    /// MinPos.
    pub min_position: Value,
    /// MaxPos.
    pub max_position: Value,
    /// MaxVel.
    pub max_velocity: Value,
    /// MaxAcc.
    pub max_acceleration: Value,
    /// ActPos.
    pub position: Value,
}

impl ModuleDetails {
    /// The parameters read besides [`ModuleInfo`], in the order [`ModuleDetails::new`] takes their values.
    pub const PARAMS: [Param; 5] = [Param::MinPos, Param::MaxPos, Param::MaxVel, Param::MaxAcc, Param::ActPos];

    /// The details of `info` with the values of [`ModuleDetails::PARAMS`], in that order.
    pub fn new(
        info: ModuleInfo,
        [min_position, max_position, max_velocity, max_acceleration, position]: [Value; 5],
    ) -> Self {
        ModuleDetails { info, min_position, max_position, max_velocity, max_acceleration, position }
    }

    /// Each parameter of [`ModuleDetails::PARAMS`] with its value.
    pub fn limits(&self) -> [(Param, Value); 5] {
        let v = [self.min_position, self.max_position, self.max_velocity, self.max_acceleration, self.position];
        let p = Self::PARAMS;
        [(p[0], v[0]), (p[1], v[1]), (p[2], v[2]), (p[3], v[3]), (p[4], v[4])]
    }
}

impl Serialize for ModuleDetails {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let kind = self.info.kind;
        let mut map = s.serialize_map(None)?;
        identity(&mut map, &self.info)?;
        map.serialize_entry(&key("min_position", kind, ""), &self.min_position)?;
        map.serialize_entry(&key("max_position", kind, ""), &self.max_position)?;
        map.serialize_entry(&key("max_velocity", kind, "_per_s"), &self.max_velocity)?;
        map.serialize_entry(&key("max_acceleration", kind, "_per_s2"), &self.max_acceleration)?;
        map.serialize_entry(&key("position", kind, ""), &self.position)?;
        map.end()
    }
}

/// One look at a module (`watch`): `position_rad` (`position_m`) and `state`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// The module's kind (the unit of `position`).
    pub kind: ModuleKind,
    /// The actual position.
    pub position: Position,
    /// The state word.
    pub state: CubeState,
}

impl Serialize for Sample {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(2))?;
        map.serialize_entry(&key("position", self.kind, ""), &self.position.value())?;
        map.serialize_entry("state", &StateReport(self.state))?;
        map.end()
    }
}

/// One row of the parameter table ([`PARAMS`](crate::model::PARAMS)): `id`, `name`, `type`, `unit` ("rad|m"
/// where it depends on the kind), `access`, `class`, `description`.
#[derive(Debug, Clone, Copy)]
pub struct ParamRow(pub &'static Entry<ParamKind>);

impl Serialize for ParamRow {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let e = self.0;
        let mut map = s.serialize_map(Some(7))?;
        map.serialize_entry("id", &e.id)?;
        map.serialize_entry("name", e.name)?;
        map.serialize_entry("type", e.kind.data_type.name())?;
        map.serialize_entry("unit", e.unit)?;
        map.serialize_entry("access", e.access.short())?;
        map.serialize_entry("class", e.kind.class.name())?;
        map.serialize_entry("description", e.title)?;
        map.end()
    }
}

/// The names of a module's position and velocity in its [`axis_look`], by its kind (plain `position` and
/// `velocity` while the kind is not known).
pub fn look_keys(kind: Option<ModuleKind>) -> (&'static str, &'static str) {
    match kind {
        Some(ModuleKind::Rotary) => ("position_rad", "velocity_rad_per_s"),
        Some(ModuleKind::Linear) => ("position_m", "velocity_m_per_s"),
        None => ("position", "velocity"),
    }
}

/// One look at a module as a live view shows it: `position`, moving as its short state says, the flags of
/// its state word where read (the ones that are not information are its faults), its velocity and motor
/// current where read.
pub fn axis_look(
    kind: Option<ModuleKind>,
    position: Position,
    moving: bool,
    state: Option<CubeState>,
    velocity: Option<f64>,
    current_amps: Option<f64>,
) -> motionlink_link::result::AxisLook {
    use motionlink_link::result::{AxisLook, Named};
    let (position_key, velocity_key) = look_keys(kind);
    let mut look = AxisLook {
        speed: velocity.map(|v| Named(velocity_key, v)),
        current_amps,
        moving,
        ..AxisLook::at(Named(position_key, f64::from(position.value())))
    };
    if let Some(s) = state {
        (look.flags, look.faults, look.unknown_bits) = (s.names(), s.faults().map(|f| f.name()).collect(), s.unknown());
    }
    look
}

#[cfg(test)]
mod tests;
