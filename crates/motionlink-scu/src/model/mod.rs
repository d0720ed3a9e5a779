//! The SCU's vocabulary as types: the data list, functions, Safety_ID, bit sets and the error code.
//!
//! The data list is one table, [`DATA_LIST`] (the shared parameter [`Table`] [`TABLE`]); the session, the
//! emulator, the command line and the decoder all read it. Each entry has its index, a name for the command
//! line, the manual's name, its unit, its access, and a [`Kind`] that fixes its size, type and meaning. The
//! named bit sets and the error code are words of the shared flag-set mechanism; speeds and positions carry
//! their unit in their type ([`Speed`], [`PositionCounts`]).
//!
//! ```
//! use motionlink_scu::model::{entry, lookup, DataEntryExt, DataIndex, Kind, TABLE};
//! assert_eq!(lookup("actual_position_a1").unwrap().index(), DataIndex(0x0011));
//! let entry = entry(DataIndex(0x0011)).unwrap();
//! assert_eq!(entry.kind, Kind::PositionCounts);
//! assert_eq!(entry.size(), 4);
//! assert_eq!(TABLE.lookup("0x0011").map(|e| e.unit), Some("counts"));
//! ```

use std::fmt;

pub use motionlink_link::table::{Access, Entry, Table};

mod data_list;
mod errors;
mod flags;
mod functions;
mod structs;
mod switching;
mod units;

pub use data_list::{DATA_LIST, TABLE};
pub use errors::*;
pub use flags::*;
pub use functions::*;
pub use structs::*;
pub use switching::*;
pub use units::*;

/// An index of the data list (`data_ID`), such as 0x0011 (position of actuator 1) or a group such as 0x0010.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct DataIndex(pub u16);

impl fmt::Display for DataIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:04X}", self.0)
    }
}

impl DataIndex {
    /// "Not used" in a cyclic object definition (-1).
    pub const NONE: DataIndex = DataIndex(0xFFFF);

    /// True for the remote data entries (0x3xxx), the only ones RT may write.
    pub const fn is_remote(self) -> bool {
        self.0 & 0xF000 == 0x3000
    }
}

/// What an entry holds: its size, wire type, unit and meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A zero-padded text of this many bytes.
    Text(usize),
    /// INT32 position in encoder counts.
    PositionCounts,
    /// UINT32 event counter.
    Counter,
    /// UINT32 stroke in encoder counts.
    StrokeCounts,
    /// UINT32 actuator error counter: 2 bytes errors, 1 byte peak-current events, 1 byte short circuits.
    ActuatorErrorCounter,
    /// UINT16 current in 0.1 A.
    CurrentDeciAmps,
    /// UINT16 analogue input in 0.01 V (0..600).
    AnalogueCentiVolts,
    /// UINT16 battery voltage in 0.1 V (0..400).
    BatteryDeciVolts,
    /// UINT16 speed of an actuator in percent.
    SpeedPercent,
    /// UINT8 temperature as a raw ADC value (0..255).
    TemperatureAdc,
    /// UINT8 small number (locking box type 0..2, user 1..4).
    Number,
    /// A named bit set of this many bytes.
    Flags(FlagSet),
    /// UINT32 SCU error code (named bits, chapter 4.6).
    ErrorCode,
    /// FLOAT conversion factor.
    ConversionFactor,
    /// STRUCT ACTUATOR_POSITIONS: 26 INT32.
    UserPositions,
    /// `UINT16[12]` cyclic object definition: 6 write indices, 6 read indices.
    CyclicObject,
    /// UINT16 remote speed of a function: percent (0..100) or counts per second (0..1000).
    RemoteSpeed,
    /// INT32 remote target position of an actuator in encoder counts.
    RemotePosition,
}

impl Kind {
    /// Size in bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            Kind::Text(n) => n,
            Kind::PositionCounts
            | Kind::Counter
            | Kind::StrokeCounts
            | Kind::ActuatorErrorCounter
            | Kind::ErrorCode
            | Kind::ConversionFactor
            | Kind::RemotePosition => 4,
            Kind::CurrentDeciAmps
            | Kind::AnalogueCentiVolts
            | Kind::BatteryDeciVolts
            | Kind::SpeedPercent
            | Kind::RemoteSpeed => 2,
            Kind::TemperatureAdc | Kind::Number => 1,
            Kind::Flags(set) => set.size(),
            Kind::UserPositions => UserPositionData::SIZE,
            Kind::CyclicObject => CyclicObject::SIZE,
        }
    }

    /// The manual's data type.
    pub const fn data_type(self) -> &'static str {
        match self {
            Kind::Text(_) => "STRING",
            Kind::PositionCounts | Kind::RemotePosition => "INT32",
            Kind::Counter | Kind::StrokeCounts | Kind::ActuatorErrorCounter | Kind::ErrorCode => "UINT32",
            Kind::CurrentDeciAmps
            | Kind::AnalogueCentiVolts
            | Kind::BatteryDeciVolts
            | Kind::SpeedPercent
            | Kind::RemoteSpeed => "UINT16",
            Kind::TemperatureAdc | Kind::Number => "UINT8",
            Kind::Flags(set) => match set.size() {
                1 => "UINT8",
                2 => "UINT16",
                _ => "UINT32",
            },
            Kind::ConversionFactor => "FLOAT",
            Kind::UserPositions => "STRUCT",
            Kind::CyclicObject => "UINT16[12]",
        }
    }

    /// The unit, as text.
    pub const fn unit(self) -> &'static str {
        match self {
            Kind::PositionCounts | Kind::StrokeCounts | Kind::RemotePosition | Kind::UserPositions => "counts",
            Kind::CurrentDeciAmps => "0.1 A",
            Kind::AnalogueCentiVolts => "0.01 V",
            Kind::BatteryDeciVolts => "0.1 V",
            Kind::SpeedPercent => "%",
            Kind::RemoteSpeed => "% (or counts/s)",
            Kind::TemperatureAdc => "ADC",
            _ => "",
        }
    }
}

/// One entry of the data list: its index (`id`), command-line name, the manual's name, unit, access, and the
/// [`Kind`] that fixes its size, wire type and meaning. The data list is a [`Table`] of them ([`TABLE`]).
pub type DataEntry = Entry<Kind>;

/// What an SCU data-list entry knows besides the shared [`Entry`] fields.
pub trait DataEntryExt {
    /// The data index.
    fn index(&self) -> DataIndex;
    /// Size in bytes on the wire.
    fn size(&self) -> usize;
}

impl DataEntryExt for Entry<Kind> {
    fn index(&self) -> DataIndex {
        DataIndex(self.id as u16)
    }

    fn size(&self) -> usize {
        self.kind.size()
    }
}

/// A group index and its name: RG on it returns its members' values one after the other, in index order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Group {
    /// The group's index.
    pub index: DataIndex,
    /// The name used on the command line.
    pub name: &'static str,
    /// The lowest member index.
    pub first: u16,
    /// The highest member index.
    pub last: u16,
}

/// The group indices of the data list. Members are the entries from `first` to `last`.
pub const GROUPS: &[Group] = &[
    Group { index: DataIndex(0x0000), name: "info", first: 0x0001, last: 0x0002 },
    Group { index: DataIndex(0x0010), name: "actual_positions", first: 0x0011, last: 0x0016 },
    Group { index: DataIndex(0x0030), name: "analogue_inputs", first: 0x0031, last: 0x0034 },
    Group { index: DataIndex(0x0060), name: "relay_in_cycles", first: 0x0061, last: 0x0066 },
    Group { index: DataIndex(0x0070), name: "relay_out_cycles", first: 0x0071, last: 0x0076 },
    Group { index: DataIndex(0x0080), name: "actuator_errors", first: 0x0081, last: 0x008F },
    Group { index: DataIndex(0x0090), name: "cumulated_strokes", first: 0x0091, last: 0x0096 },
    Group { index: DataIndex(0x00A0), name: "currents", first: 0x00A1, last: 0x00A6 },
    Group { index: DataIndex(0x00B0), name: "max_currents", first: 0x00B1, last: 0x00BF },
    Group { index: DataIndex(0x00D0), name: "error_codes", first: 0x00D1, last: 0x00D5 },
    Group { index: DataIndex(0x00E0), name: "actuator_status2", first: 0x00E1, last: 0x00E6 },
    Group { index: DataIndex(0x00F0), name: "speeds", first: 0x00F1, last: 0x00F6 },
    Group { index: DataIndex(0x0170), name: "actuator_status1", first: 0x0171, last: 0x0176 },
    Group { index: DataIndex(0x1000), name: "collection_1000", first: 0x1001, last: 0x1FFF },
    Group { index: DataIndex(0x1010), name: "conversion_factors", first: 0x1011, last: 0x1016 },
    Group { index: DataIndex(0x2000), name: "user_positions", first: 0x2001, last: 0x2006 },
    Group { index: DataIndex(0x3000), name: "remote_data", first: 0x3001, last: 0x3FFF },
    Group { index: DataIndex(0x3010), name: "remote_speeds", first: 0x3011, last: 0x301A },
    Group { index: DataIndex(0x3020), name: "remote_positions", first: 0x3021, last: 0x3026 },
];

impl Group {
    /// The entries of the group, in index order.
    pub fn members(&self) -> impl Iterator<Item = &'static DataEntry> + '_ {
        DATA_LIST.iter().filter(move |e| (u32::from(self.first)..=u32::from(self.last)).contains(&e.id))
    }

    /// Size in bytes of the group's data.
    pub fn size(&self) -> usize {
        self.members().map(DataEntryExt::size).sum()
    }

    /// True if RT may write the whole group at once (remote data).
    pub fn is_remote(&self) -> bool {
        self.index.is_remote()
    }
}

/// What a data index refers to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Item {
    /// A single entry.
    Entry(&'static DataEntry),
    /// A group of entries.
    Group(&'static Group),
}

impl Item {
    /// The data index.
    pub fn index(&self) -> DataIndex {
        match self {
            Item::Entry(e) => e.index(),
            Item::Group(g) => g.index,
        }
    }

    /// The command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            Item::Entry(e) => e.name,
            Item::Group(g) => g.name,
        }
    }

    /// Size in bytes of its data.
    pub fn size(&self) -> usize {
        match self {
            Item::Entry(e) => e.size(),
            Item::Group(g) => g.size(),
        }
    }

    /// True if RT may write it.
    pub fn is_writable(&self) -> bool {
        match self {
            Item::Entry(e) => e.access.writable(),
            Item::Group(g) => g.is_remote(),
        }
    }
}

/// The entry at `index`, if the data list has one.
pub fn entry(index: DataIndex) -> Option<&'static DataEntry> {
    DATA_LIST.binary_search_by_key(&u32::from(index.0), |e| e.id).ok().map(|i| &DATA_LIST[i])
}

/// The entry or group at `index`.
pub fn item(index: DataIndex) -> Option<Item> {
    entry(index).map(Item::Entry).or_else(|| GROUPS.iter().find(|g| g.index == index).map(Item::Group))
}

/// Finds an entry or group by command-line name (case-insensitive) or by index written as `0x0011` or `0011`.
pub fn lookup(text: &str) -> Option<Item> {
    let t = text.trim();
    if let Some(e) = TABLE.by_name(t) {
        return Some(Item::Entry(e));
    }
    if let Some(g) = GROUPS.iter().find(|g| g.name.eq_ignore_ascii_case(t)) {
        return Some(Item::Group(g));
    }
    parse_index(t).and_then(item)
}

/// A name or index that is neither an entry nor a group of the data list; its message names the nearest
/// names when it looks misspelt (`remote_sped_f1`: did you mean remote_speed_f1?).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0:?} is not in the data list: {hint}", hint = unknown_item_hint(.0))]
pub struct UnknownItem(pub String);

/// What to give instead of `text`: the nearest names, or the forms an item takes.
fn unknown_item_hint(text: &str) -> String {
    motionlink_link::table::did_you_mean(&suggest(text))
        .unwrap_or_else(|| "give a name such as actual_position_a1 or an index such as 0x0011".to_string())
}

/// [`lookup`], or an error whose message names the nearest names (one message for every front end).
pub fn find(text: &str) -> Result<Item, UnknownItem> {
    lookup(text).ok_or_else(|| UnknownItem(text.to_string()))
}

/// The names of the entries and groups nearest to a misspelt `text` (the best one or two, for a "did you
/// mean" hint; empty when none is near): `remote_sped_f1` finds `remote_speed_f1`.
pub fn suggest(text: &str) -> Vec<&'static str> {
    motionlink_link::table::nearest(text, TABLE.iter().map(|e| e.name).chain(GROUPS.iter().map(|g| g.name)))
}

/// Parses a data index written as hex with `0x` (`0x0011`), or as four hex digits (`0011`, `301A`).
pub fn parse_index(text: &str) -> Option<DataIndex> {
    let t = text.trim();
    let hex = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X"));
    match hex {
        Some(h) => u16::from_str_radix(h, 16).ok().map(DataIndex),
        None if t.len() == 4 => u16::from_str_radix(t, 16).ok().map(DataIndex),
        None => None,
    }
}

/// Index of actuator `n`'s entry in a per-actuator block starting at `base` (such as 0x0010 for positions).
pub const fn per_actuator(base: u16, actuator: Actuator) -> DataIndex {
    DataIndex(base + actuator.number() as u16)
}

// ---------------------------------------------------------------------------------------------------------
// Timing rules (chapter 3.4, network layer, and 4.1, command set)

/// The timing rules of the protocol, as the manual states them.
pub mod timing {
    use std::time::Duration;

    /// The RC watchdog of remote mode: with no RC for this long the unit stops the drives (and reacts as the
    /// Safety_ID says).
    pub const WATCHDOG: Duration = Duration::from_millis(500);
    /// The most time between two bytes of one telegram; the unit drops a telegram left incomplete longer.
    pub const INTER_BYTE_LIMIT: Duration = Duration::from_millis(1000);
    /// The most time the unit takes to reply ("maximum request delay").
    pub const MAX_REPLY_DELAY: Duration = Duration::from_millis(2000);
}

#[cfg(test)]
mod tests;
