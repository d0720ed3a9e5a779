//! Results as data: every report an operation returns serialises (`serde::Serialize`) with the names the
//! command line's `--json` shows, units in the names (`position_counts`, `reached_counts`, `current_amps`,
//! `time_s`). The command line prints these, the web console and Python send and convert them: nobody
//! builds a copy of a result by hand.
//!
//! The session's own reports ([`MoveReport`], [`StopReport`](crate::session::StopReport), [`SetReport`]) serialise here too; this module
//! adds the reports that several reads make up ([`InfoReport`], [`GetReport`], [`WriteReport`],
//! [`SampleReport`]) and how a run or a stream of targets ended ([`RunOutcome`], [`FollowReport`]).
//!
//! ```
//! use motionlink_scu::model::{Actuator, ActuatorStatus1, PositionCounts};
//! use motionlink_scu::results::ActuatorState;
//! let a1 = ActuatorState::new(Actuator::new(1).unwrap(), PositionCounts(400), ActuatorStatus1(0x01), None);
//! let json = serde_json::to_value(&a1).unwrap();
//! assert_eq!(json, serde_json::json!({"actuator": 1, "position_counts": 400, "word": 1, "flags": ["available"], "moving": false}));
//! ```

use serde::ser::{Serialize, SerializeMap, SerializeSeq, Serializer};

mod actions;
pub use actions::{ErrorHistory, FunctionStop, Running, StopResult, StopScope, Stopped, SwitchedOff};

use crate::client::FollowReport;
use crate::error::Error;
use crate::model::{
    Actuator, ActuatorStatus1, DataEntry, DataEntryExt, ErrorCode, Flags, Function, Item, MotionFunction,
    PositionCounts, SpeedMode, DATA_LIST, GROUPS,
};
use crate::session::{ActuatorOutcome, MoveReport, RunReport, SetReport, Snapshot};
use crate::value::{shown_unit, Value};

/// Serialises `pairs` as `[{"actuator": n, KEY: counts}, ...]`.
struct PerActuator<'a> {
    pairs: &'a [(Actuator, PositionCounts)],
    key: &'static str,
}

impl Serialize for PerActuator<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut seq = s.serialize_seq(Some(self.pairs.len()))?;
        for (a, p) in self.pairs {
            let mut one = std::collections::BTreeMap::new();
            one.insert("actuator", i64::from(a.number()));
            one.insert(self.key, i64::from(p.get()));
            seq.serialize_element(&one)?;
        }
        seq.end()
    }
}

/// An actuator's state at one look: its position, status 1 and, in a sample, its motor current.
/// Serialises as `{actuator, position_counts, current_amps (in a sample), word, flags, unknown_bits (when
/// nonzero), moving}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorState {
    /// The actuator.
    pub actuator: Actuator,
    /// Its position.
    pub position_counts: PositionCounts,
    /// Its status 1.
    pub status: ActuatorStatus1,
    /// Its motor current in A, where it was read.
    pub current_amps: Option<f64>,
}

impl ActuatorState {
    /// The state of `actuator`.
    pub fn new(
        actuator: Actuator,
        position_counts: PositionCounts,
        status: ActuatorStatus1,
        current_amps: Option<f64>,
    ) -> Self {
        ActuatorState { actuator, position_counts, status, current_amps }
    }
}

impl Serialize for ActuatorState {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        #[derive(serde::Serialize)]
        struct View {
            actuator: Actuator,
            position_counts: PositionCounts,
            #[serde(skip_serializing_if = "Option::is_none")]
            current_amps: Option<f64>,
            #[serde(flatten)]
            status: ActuatorStatus1,
            moving: bool,
        }
        View {
            actuator: self.actuator,
            position_counts: self.position_counts,
            current_amps: self.current_amps,
            status: self.status,
            moving: self.status.moving(),
        }
        .serialize(s)
    }
}

/// What `info` reads from a unit ([`crate::Client::info`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct InfoReport {
    /// The firmware info text (0x0001).
    pub firmware: String,
    /// The configuration info text (0x0002).
    pub configuration: String,
    /// Battery / mains (0x0100), a flag word.
    pub battery_mains: Flags,
    /// Error_Code 1, the most recent (0x00D1).
    pub last_error: ErrorCode,
    /// Every connected actuator ("drive available"), with its position and status 1.
    pub actuators: Vec<ActuatorState>,
}

/// A read of a data-list entry or group ([`crate::Client::read`]): `{name, id, value, unit, access}`; a
/// group's value is an object of its entries' values by name.
#[derive(Debug, Clone, PartialEq)]
pub struct GetReport {
    /// The entry or group.
    pub item: Item,
    /// Each entry read and its value (one for an entry).
    pub values: Vec<(&'static DataEntry, Value)>,
    /// The unit's speed mode, which gives a remote speed its unit.
    pub speed_mode: SpeedMode,
}

impl Serialize for GetReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(5))?;
        map.serialize_entry("name", self.item.name())?;
        map.serialize_entry("id", &self.item.index().0)?;
        match (self.item, self.values.as_slice()) {
            (Item::Entry(e), [(_, v)]) => {
                map.serialize_entry("value", v)?;
                map.serialize_entry("unit", shown_unit(e, self.speed_mode))?;
                map.serialize_entry("access", e.access.short())?;
            }
            (_, values) => {
                let by_name: std::collections::BTreeMap<&str, &Value> =
                    values.iter().map(|(e, v)| (e.name, v)).collect();
                map.serialize_entry("value", &by_name)?;
                map.serialize_entry("unit", "")?;
                map.serialize_entry("access", "r")?;
            }
        }
        map.end()
    }
}

/// A write of a remote data entry, checked as the library checks it ([`crate::Client::write`]): `{name,
/// id, value, unit, access, read_back, verified, not_verifiable}`.
#[derive(Debug, Clone, PartialEq)]
pub struct WriteReport {
    /// The entry written.
    pub entry: &'static DataEntry,
    /// The value written.
    pub value: Value,
    /// What the unit holds now, read after the write was checked (None where the unit does not read remote
    /// data back: `set` says why).
    pub read_back: Option<Value>,
    /// Whether the write was read back and compared.
    pub set: SetReport,
    /// The unit's speed mode, which gives a remote speed its unit.
    pub speed_mode: SpeedMode,
}

impl Serialize for WriteReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(8))?;
        map.serialize_entry("name", self.entry.name)?;
        map.serialize_entry("id", &self.entry.id)?;
        map.serialize_entry("value", &self.value)?;
        map.serialize_entry("unit", shown_unit(self.entry, self.speed_mode))?;
        map.serialize_entry("access", self.entry.access.short())?;
        map.serialize_entry("read_back", &self.read_back)?;
        map.serialize_entry("verified", &self.set.verified)?;
        map.serialize_entry("not_verifiable", &self.set.not_verifiable)?;
        map.end()
    }
}

/// One sample of a watch: `{t_s, actuators, last_error}`, the connected actuators with their current.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SampleReport {
    /// Seconds since the watch's first sample.
    pub t_s: f64,
    /// Every connected actuator.
    pub actuators: Vec<ActuatorState>,
    /// Error_Code 1.
    pub last_error: ErrorCode,
}

impl SampleReport {
    /// The sample `snapshot` shows, `t_s` seconds into the watch.
    pub fn new(snapshot: &Snapshot, t_s: f64) -> Self {
        let actuators = Actuator::all()
            .filter(|a| snapshot.status(*a).available())
            .map(|a| {
                let deci_amps = snapshot.currents_deci_amps[usize::from(a.number() - 1)];
                // The data list's deci-amps, converted once, by the value.
                let amps = Value::CurrentDeciAmps(deci_amps).as_f64();
                ActuatorState::new(a, snapshot.position(a), snapshot.status(a), amps)
            })
            .collect();
        SampleReport { t_s, actuators, last_error: snapshot.last_error }
    }
}

/// How a function's run ended: `{function, stopped: true, interrupted, actuators: [{actuator,
/// reached_counts}]}`, and for a switching function (F11..F22) `verified` and `not_verifiable`: whether the
/// status entry that shows it showed it on after the RE and off after the RS. The stop was confirmed by the
/// unit in either case (a motion function's by the status of every actuator, a switching function's by the
/// acknowledge of its RS).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunOutcome {
    /// The function.
    pub function: Function,
    /// True when a cancel (Ctrl-C) ended it.
    pub interrupted: bool,
    /// Where each connected actuator came to rest.
    pub rest: Vec<(Actuator, PositionCounts)>,
    /// As [`RunReport::verified`].
    pub verified: bool,
    /// As [`RunReport::not_verifiable`].
    pub not_verifiable: Vec<String>,
}

impl RunOutcome {
    /// A run's result as an outcome: a run that ended ([`RunReport`]), or one a cancel ended after the unit
    /// confirmed the stop ([`Error::RunCancelled`]); other errors stay errors.
    pub fn of(result: Result<RunReport, Error>) -> Result<RunOutcome, Error> {
        match result {
            Ok(r) => Ok(RunOutcome::from(&r)),
            Err(Error::RunCancelled { function, rest, verified, not_verifiable }) => {
                Ok(RunOutcome { function, interrupted: true, rest, verified, not_verifiable })
            }
            Err(e) => Err(e),
        }
    }
}

impl From<&RunReport> for RunOutcome {
    fn from(r: &RunReport) -> Self {
        RunOutcome {
            function: r.function,
            interrupted: false,
            rest: r.rest.clone(),
            verified: r.verified,
            not_verifiable: r.not_verifiable.clone(),
        }
    }
}

impl Serialize for RunOutcome {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("function", &self.function)?;
        map.serialize_entry("stopped", &true)?;
        map.serialize_entry("interrupted", &self.interrupted)?;
        map.serialize_entry("actuators", &PerActuator { pairs: &self.rest, key: "reached_counts" })?;
        // A switching function's state is read back; a motion function's report says so only where something
        // was not verified (the console's jog with a speed the unit does not read back).
        if !matches!(self.function, Function::Motion(_)) || !self.not_verifiable.is_empty() {
            map.serialize_entry("verified", &self.verified)?;
            map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        }
        map.end()
    }
}

/// A stream of targets ended: `{stopped: true, actuators: [{actuator, reached_counts}], updates}`.
impl Serialize for FollowReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("stopped", &true)?;
        map.serialize_entry("actuators", &PerActuator { pairs: &self.rest, key: "reached_counts" })?;
        map.serialize_entry("updates", &self.updates)?;
        map.end()
    }
}

/// A stream of targets began: `{function, following: true, actuators: [n, ...]}`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FollowStart {
    /// The function that moves.
    pub function: MotionFunction,
    /// The actuators that follow the targets, in the stream's order.
    pub actuators: Vec<Actuator>,
}

impl Serialize for FollowStart {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("function", &self.function)?;
        map.serialize_entry("following", &true)?;
        map.serialize_entry("actuators", &self.actuators)?;
        map.end()
    }
}

/// Targets applied to a stream: `{targets: [{actuator, target_counts}]}`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TargetsApplied(pub Vec<(Actuator, PositionCounts)>);

impl Serialize for TargetsApplied {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(1))?;
        map.serialize_entry("targets", &PerActuator { pairs: &self.0, key: "target_counts" })?;
        map.end()
    }
}

/// How one actuator of a move ended: `{actuator, target_counts, reached_counts, difference_counts, moved}`
/// (where it started is a field, not part of the result).
impl Serialize for ActuatorOutcome {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(5))?;
        map.serialize_entry("actuator", &self.actuator)?;
        map.serialize_entry("target_counts", &self.target_counts)?;
        map.serialize_entry("reached_counts", &self.position_counts)?;
        map.serialize_entry("difference_counts", &self.difference_counts())?;
        map.serialize_entry("moved", &self.moved)?;
        map.end()
    }
}

/// How a move ended: `{actuator, function, reached_counts, target_counts, difference_counts, time_s,
/// actuators, verified, not_verifiable}` (the target and difference of the actuator the move is about).
impl Serialize for MoveReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let target = self.actuators.iter().find(|o| o.actuator == self.actuator).map(|o| o.target_counts);
        let mut map = s.serialize_map(Some(9))?;
        map.serialize_entry("actuator", &self.actuator)?;
        map.serialize_entry("function", &self.function)?;
        map.serialize_entry("reached_counts", &self.position_counts)?;
        map.serialize_entry("target_counts", &target)?;
        map.serialize_entry("difference_counts", &target.map(|t| self.position_counts.counts_from(t)))?;
        map.serialize_entry("time_s", &self.duration.as_secs_f64())?;
        map.serialize_entry("actuators", &self.actuators)?;
        map.serialize_entry("verified", &self.verified)?;
        map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        map.end()
    }
}

/// One entry or group of the data list as `names` lists it: `{name, id, unit, access, title, size}`
/// ([`data_items`]).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct DataItemInfo {
    /// The name the front ends take.
    pub name: &'static str,
    /// The data index.
    pub id: u16,
    /// The unit of its values as results give them ([`shown_unit`]); "" for a group.
    pub unit: &'static str,
    /// "r", "w" or "rw" ("r" for a group).
    pub access: &'static str,
    /// The manual's name; for a group, the range of its members.
    pub title: String,
    /// Its size on the wire, in bytes.
    pub size: usize,
}

/// Every entry of the data list, then every group, as `names` lists them; a remote speed's unit is the one
/// of `speed_mode`.
pub fn data_items(speed_mode: SpeedMode) -> impl Iterator<Item = DataItemInfo> {
    let entries = DATA_LIST.iter().map(move |e| DataItemInfo {
        name: e.name,
        id: e.index().0,
        unit: shown_unit(e, speed_mode),
        access: e.access.short(),
        title: e.title.to_string(),
        size: e.size(),
    });
    let groups = GROUPS.iter().map(|g| DataItemInfo {
        name: g.name,
        id: g.index.0,
        unit: "",
        access: "r",
        title: format!("group 0x{:04X}..0x{:04X}", g.first, g.last),
        size: g.size(),
    });
    entries.chain(groups)
}

/// The names of an actuator's position and speed in its [`axis_look`]: counts, and the remote speed in %.
pub const LOOK_KEYS: (&str, &str) = ("position_counts", "speed_percent");

/// One look at an actuator as a live view shows it: `position` with `status` (its flags; the error-class ones
/// are its faults), the speed it runs at (%) and its motor current (A) where read.
pub fn axis_look(
    position: PositionCounts,
    status: ActuatorStatus1,
    speed_percent: Option<f64>,
    current_amps: Option<f64>,
) -> motionlink_link::result::AxisLook {
    use motionlink_link::flags::{FlagClass, FlagWord};
    use motionlink_link::result::{AxisLook, Named};
    AxisLook {
        speed: speed_percent.map(|s| Named(LOOK_KEYS.1, s)),
        current_amps,
        flags: status.names(),
        faults: status.set_flags().into_iter().filter(|f| f.class() == FlagClass::Error).map(|f| f.name()).collect(),
        unknown_bits: status.unknown(),
        moving: status.moving(),
        ..AxisLook::at(Named(LOOK_KEYS.0, f64::from(position.get())))
    }
}

#[cfg(test)]
mod tests;
