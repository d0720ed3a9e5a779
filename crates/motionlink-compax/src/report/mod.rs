//! What the operations report, as data: every report serialises (serde) with the names the command line's
//! `--json` prints, and the command line, the console and Python show these, never a copy built by hand.
//! Positions are in the drive's unit (`_units` in the names).
//!
//! - [`DrivePosition`]: `{"drive", "position_units"}` (a drive found by a scan, where a drive stands).
//! - [`StatusReport`] of [`StatusReading`]s: `{"status": [{"status": "S1", "name", "unit", "value"}]}`;
//!   a [`StatusValue`] serialises as a number (positions, numbers), a flag word with its `pattern` (S16,
//!   S17: [`WithPattern`]) or text (S18, identification).
//! - [`ParamReading`]: `{"name": "P194", "id", "value", "unit", "access"}`; [`ParamWritten`] adds
//!   `read_back`, `verified` and `not_verifiable`.
//! - [`MoveReport`]: `{"drive", "target_units", "reached_units",
//!   "difference_units", "tolerance_units", "waited": true, "verified", "not_verifiable"}`;
//!   [`StartedMove`]: `{"drive", "target_units", "waited": false, "verified", "not_verifiable"}`.
//! - [`RawOutcome`]: `{"reply", "waited"}`; [`OutputSwitched`]: `{"output", "state", "read_back", "verified",
//!   "not_verifiable"}`.
//! - [`WatchSample`]: `{"drive", "position_units", "s17", "moving"}`, and [`Timed`] puts `t_s` before it.
//! - [`ErrorHistory`]: S18 decoded, `{"errors": [{"code", "text", "meaning"}]}`.
//! - [`StopReport`](crate::error::StopReport): `{"drives": [{"drive", "outcome", "reason"?}], "confirmed"}`;
//!   [`DriveStop`] adds `position_units`, `o0` (and why either could not be read), [`StopResult`] `action`
//!   and `holder`.

use serde::ser::{Serialize, SerializeMap, Serializer};

mod history;
mod stopped;
pub use history::ErrorHistory;
pub use stopped::{DriveStop, StopResult};

use crate::model::{OutputState, ParamId, Position, S16Bits, S17Bits, StatusId, StatusValue, ValidFrom};
use crate::session::{MoveReport, RawOutcome, StartedMove, WatchSample};
use crate::wire::Address;

/// S16 or S17 as a result shows it: the flag word (`word`, `flags`, `unknown_bits` when nonzero, as every
/// flag word) and `pattern`, the word as the drive sends it ("1101 1010").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WithPattern<W>(pub W);

macro_rules! with_pattern {
    ($bits:ty) => {
        impl Serialize for WithPattern<$bits> {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                use motionlink_link::flags::FlagWord;
                let w = self.0;
                let mut map = s.serialize_map(None)?;
                map.serialize_entry("word", &w.raw())?;
                map.serialize_entry("flags", &w.names())?;
                if w.unknown() != 0 {
                    map.serialize_entry("unknown_bits", &w.unknown())?;
                }
                map.serialize_entry("pattern", &w.pattern().to_string())?;
                map.end()
            }
        }
    };
}
with_pattern!(S16Bits);
with_pattern!(S17Bits);

/// A number for positions and numbers, S16 / S17 with their pattern ([`WithPattern`]), text otherwise (the
/// history S18 as the drive writes it, identification).
impl Serialize for StatusValue {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            StatusValue::Position(p) => p.serialize(s),
            StatusValue::Number(n) => n.serialize(s),
            StatusValue::S16(b) => WithPattern(*b).serialize(s),
            StatusValue::S17(b) => WithPattern(*b).serialize(s),
            other => s.collect_str(other),
        }
    }
}

/// Where a drive stands: S1 (a drive found by a scan; the result of a wait or a homing).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DrivePosition {
    /// The drive.
    pub drive: Address,
    /// Its actual position S1.
    #[serde(rename = "position_units")]
    pub position: Position,
}

impl From<(Address, Position)> for DrivePosition {
    fn from((drive, position): (Address, Position)) -> Self {
        DrivePosition { drive, position }
    }
}

/// One status value as read: `{"status": "S1", "name", "unit", "value"}` (name and unit from the table;
/// "(meaning not documented)" and "" for a value it does not describe).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatusReading {
    /// Which value.
    pub id: StatusId,
    /// What the drive gave.
    pub value: StatusValue,
}

impl StatusReading {
    /// What the value is (the table's title), or "(meaning not documented)".
    pub fn name(&self) -> &'static str {
        self.id.info().map_or("(meaning not documented)", |i| i.title)
    }

    /// Its unit ("" when none or unknown).
    pub fn unit(&self) -> &'static str {
        self.id.info().map_or("", |i| i.unit)
    }
}

impl Serialize for StatusReading {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(4))?;
        map.serialize_entry("status", &self.id.to_string())?;
        map.serialize_entry("name", self.name())?;
        map.serialize_entry("unit", self.unit())?;
        map.serialize_entry("value", &self.value)?;
        map.end()
    }
}

/// Several status values of one drive, in the order asked: `{"status": [...]}`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StatusReport {
    /// The values.
    pub status: Vec<StatusReading>,
}

impl From<Vec<(StatusId, StatusValue)>> for StatusReport {
    fn from(values: Vec<(StatusId, StatusValue)>) -> Self {
        StatusReport { status: values.into_iter().map(|(id, value)| StatusReading { id, value }).collect() }
    }
}

/// A parameter as read: `{"name": "P194", "id": 194, "value", "unit", "access"}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamReading {
    /// Which parameter.
    pub id: ParamId,
    /// Its value.
    pub value: f64,
}

impl ParamReading {
    /// Its unit in the table ("" when none or unknown).
    pub fn unit(&self) -> &'static str {
        self.id.info().map_or("", |i| i.unit)
    }

    fn entries<M: SerializeMap>(&self, map: &mut M) -> Result<(), M::Error> {
        map.serialize_entry("name", &self.id.to_string())?;
        map.serialize_entry("id", &self.id.get())?;
        map.serialize_entry("value", &self.value)?;
        map.serialize_entry("unit", self.unit())?;
        map.serialize_entry("access", self.id.info().map_or("rw", |i| i.access.short()))
    }
}

impl Serialize for ParamReading {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        self.entries(&mut map)?;
        map.end()
    }
}

/// A parameter written and read back: the reading of the value written, `read_back` (what the drive gives
/// now), `verified` (always true: a value that reads back otherwise is [`Error::ReadBack`](crate::Error),
/// never a report) and `not_verifiable` (nothing, as every family's results say it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamWritten {
    /// The parameter and the value written.
    pub written: ParamReading,
    /// The value read back after the write.
    pub read_back: f64,
}

impl ParamWritten {
    /// True when the value takes effect only at the drive's next power-on (P194..P196).
    pub fn at_power_on(&self) -> bool {
        self.written.id.info().is_some_and(|i| i.kind.valid_from == ValidFrom::PowerOn)
    }

    /// What the value written does at the next power-on that a user must know before it: P196 = 164 / 165
    /// (the drive speaks the COMTAC fieldbus protocol from then on, and answers no ASCII telegram), or a
    /// fieldbus baud rate in P195 (for the fieldbus protocol only).
    ///
    /// ```
    /// use motionlink_compax::model::ParamId;
    /// use motionlink_compax::report::{ParamReading, ParamWritten};
    /// let written = ParamReading { id: ParamId::OPERATING_MODE, value: 164.0 };
    /// let w = ParamWritten { written, read_back: 164.0 };
    /// assert!(w.power_on_note().unwrap().contains("fieldbus"));
    /// ```
    pub fn power_on_note(&self) -> Option<&'static str> {
        let value = self.written.value;
        let is = |list: &[u32]| list.iter().any(|&v| f64::from(v) == value);
        match self.written.id {
            ParamId::OPERATING_MODE if is(crate::model::FIELDBUS_MODES) => Some(
                "from the next power-on the drive speaks the COMTAC fieldbus protocol (P196 = 164/165), which \
                 motionlink does not: it will answer no ASCII telegram on this line",
            ),
            ParamId::BAUD_RATE if !is(crate::model::BAUD_RATES) => Some(
                "a baud rate of the fieldbus protocol: with an ASCII mode in P196 the drive's rate is one of \
                 150..115200 bit/s",
            ),
            _ => None,
        }
    }
}

impl Serialize for ParamWritten {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        self.written.entries(&mut map)?;
        map.serialize_entry("read_back", &self.read_back)?;
        map.serialize_entry("verified", &true)?;
        map.serialize_entry("not_verifiable", &[] as &[String])?;
        map.end()
    }
}

/// A move waited for and checked at rest (`start` is left out: S1 before the move is no key of the results).
impl Serialize for MoveReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("drive", &self.address)?;
        map.serialize_entry("target_units", &self.target)?;
        map.serialize_entry("reached_units", &self.reached)?;
        map.serialize_entry("difference_units", &self.difference())?;
        map.serialize_entry("tolerance_units", &self.tolerance)?;
        map.serialize_entry("waited", &true)?;
        map.serialize_entry("verified", &self.verified)?;
        map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        map.end()
    }
}

/// A move the drive took and that was handed over, not waited for.
impl Serialize for StartedMove {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("drive", &self.address)?;
        map.serialize_entry("target_units", &self.target)?;
        map.serialize_entry("waited", &false)?;
        map.serialize_entry("verified", &self.not_verifiable.is_empty())?;
        map.serialize_entry("not_verifiable", &self.not_verifiable)?;
        map.end()
    }
}

/// What a raw command did: `reply` (null when none was due), `started` (the drives it set in motion) and
/// `waited`.
impl Serialize for RawOutcome {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("reply", &self.reply)?;
        map.serialize_entry("started", &self.started)?;
        map.serialize_entry("waited", &self.waited)?;
        map.end()
    }
}

/// One sample of a watch: S1, S17 with its pattern, and whether a command is active.
impl Serialize for WatchSample {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(4))?;
        map.serialize_entry("drive", &self.drive)?;
        map.serialize_entry("position_units", &self.position)?;
        map.serialize_entry("s17", &WithPattern(self.s17))?;
        map.serialize_entry("moving", &self.moving())?;
        map.end()
    }
}

/// A sample with the time it was taken, in seconds since its series began: `t_s`, then the sample's
/// fields.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Timed<T> {
    /// Seconds since the first sample's series began.
    pub t_s: f64,
    /// The sample.
    #[serde(flatten)]
    pub sample: T,
}

/// An output switched (OUTPUT On=s): `{"output", "state", "read_back", "verified", "not_verifiable"}`, as a
/// parameter written names what was read back. O0 (the drive switched on or off) is read back from S16; of
/// the outputs, the status values show O0 only.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct OutputSwitched {
    /// The output's number (0: the drive itself).
    pub output: u16,
    /// What it was switched to.
    pub state: OutputState,
    /// O0 as S16 showed it after the switch (null where nothing was read back).
    pub read_back: Option<u8>,
    /// True when the state was read back and is the one sent.
    pub verified: bool,
    /// Why it was not read back (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

impl OutputSwitched {
    /// True when `OUTPUT O{output}=s` to `address` can be read back: O0 of one drive, in S16 (bits 7 and 8).
    pub fn shown_in_s16(address: Address, output: u16) -> bool {
        output == 0 && !address.is_broadcast()
    }

    /// The outcome of `OUTPUT O{output}={state}` acknowledged by `address`, with O0 as S16 showed it after
    /// (`read`: `None` when it was not read: another output, or every drive at once). O0 read back as
    /// another state is an error ([`Error::OutputNotTaken`](crate::Error::OutputNotTaken)); an S16 that
    /// could not be read makes the switch not verified, saying why.
    pub fn checked(
        address: Address,
        output: u16,
        state: OutputState,
        read: Option<Result<u8, crate::Error>>,
    ) -> Result<Self, crate::Error> {
        let unverified =
            |why: String| OutputSwitched { output, state, read_back: None, verified: false, not_verifiable: vec![why] };
        Ok(match read {
            Some(Ok(o0)) if o0 == state.get() => {
                OutputSwitched { output, state, read_back: Some(o0), verified: true, not_verifiable: Vec::new() }
            }
            Some(Ok(o0)) => return Err(crate::Error::OutputNotTaken { address, wrote: state.get(), read: o0 }),
            Some(Err(e)) => unverified(format!("S16 could not be read after the switch: {e}")),
            None if address.is_broadcast() => {
                unverified("sent to every drive at once (address 32): none answers, nothing was read back".into())
            }
            None => unverified(format!(
                "output O{output} is not read back: of the outputs, the status values show O0 only (S16)"
            )),
        })
    }
}

/// The names of a drive's position and speed in its [`axis_look`]: drive units, and units per second.
pub const LOOK_KEYS: (&str, &str) = ("position_units", "speed_units_per_s");

/// One look at a drive as a live view shows it: `position` (S1), its speed where known, the flags of S16 and
/// S17, moving while a command is active or `s1_moved` (S1 changed beyond the in-position tolerance since the
/// previous look: a drive may move without S17's bit 3). The faults are S16's NO_FAULT clear (its absence is
/// the fault) and the error-class flags of S17; unknown bits are S16's above S17's (shifted by 8).
pub fn axis_look(
    position: Position,
    speed_units_per_s: Option<f64>,
    s16: S16Bits,
    s17: S17Bits,
    s1_moved: bool,
) -> motionlink_link::result::AxisLook {
    use motionlink_link::flags::{FlagClass, FlagWord};
    use motionlink_link::result::{AxisLook, Named};
    let mut flags = s16.names();
    flags.extend(s17.names());
    let mut faults: Vec<&'static str> = Vec::new();
    if !s16.contains(crate::model::S16Flag::NoFault) {
        faults.push("FAULT (S16 NO_FAULT clear)");
    }
    faults.extend(s17.set_flags().into_iter().filter(|f| f.class() == FlagClass::Error).map(|f| f.name()));
    AxisLook {
        speed: speed_units_per_s.map(|v| Named(LOOK_KEYS.1, v)),
        flags,
        faults,
        unknown_bits: (s16.unknown() << 8) | s17.unknown(),
        moving: s17.contains(crate::model::S17Flag::CommandActive) || s1_moved,
        ..AxisLook::at(Named(LOOK_KEYS.0, position.units()))
    }
}

#[cfg(test)]
mod tests;
