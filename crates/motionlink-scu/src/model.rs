//! The SCU's vocabulary as types: the data list, functions, Safety_ID, bit sets and the error code.
//!
//! The data list is one table, [`DATA_LIST`]; the client, the emulator, the command line and the decoder all
//! read it. Each entry has its index, a name for the command line, the manual's name, a [`Kind`] that fixes
//! its size, type, unit and meaning, and its access.
//!
//! ```
//! use motionlink_scu::model::{entry, DataIndex, Kind, lookup};
//! assert_eq!(lookup("actual_position_a1").unwrap().index(), DataIndex(0x0011));
//! let entry = entry(DataIndex(0x0011)).unwrap();
//! assert_eq!(entry.kind, Kind::PositionCounts);
//! assert_eq!(entry.size(), 4);
//! ```

use std::fmt;

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

/// Who may write an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Read with RG only.
    ReadOnly,
    /// Read with RG, written with RT (remote data, 0x3xxx).
    ReadWrite,
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

/// One entry of the data list.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DataEntry {
    /// The data index.
    pub index: DataIndex,
    /// The name used on the command line and in JSON.
    pub name: &'static str,
    /// The manual's name.
    pub title: &'static str,
    /// Size, type, unit and meaning.
    pub kind: Kind,
    /// Read-only or writable with RT.
    pub access: Access,
}

impl DataEntry {
    /// Size in bytes on the wire.
    pub const fn size(&self) -> usize {
        self.kind.size()
    }
}

/// One row of the table macro: index, command-line name, manual name, kind, access.
macro_rules! data_list {
    ($( $index:literal $name:literal $title:literal $kind:ident $(($arg:expr))?, $access:ident; )*) => {
        /// Every entry of the data list, in index order (both manuals' table 4, "Data list").
        pub const DATA_LIST: &[DataEntry] = &[
            $( DataEntry {
                index: DataIndex($index),
                name: $name,
                title: $title,
                kind: Kind::$kind $(($arg))?,
                access: Access::$access,
            }, )*
        ];
    };
}

data_list! {
    0x0001 "firmware_info" "Firmware info Name Version CS" Text(31), ReadOnly;
    0x0002 "configuration_info" "Configuration info Name Version CS" Text(36), ReadOnly;
    0x0011 "actual_position_a1" "Actual_Position Actuator 1" PositionCounts, ReadOnly;
    0x0012 "actual_position_a2" "Actual_Position Actuator 2" PositionCounts, ReadOnly;
    0x0013 "actual_position_a3" "Actual_Position Actuator 3" PositionCounts, ReadOnly;
    0x0014 "actual_position_a4" "Actual_Position Actuator 4" PositionCounts, ReadOnly;
    0x0015 "actual_position_a5" "Actual_Position Actuator 5" PositionCounts, ReadOnly;
    0x0016 "actual_position_a6" "Actual_Position Actuator 6" PositionCounts, ReadOnly;
    0x0020 "binary_inputs" "Actual_State_Binary Inputs 1..4" Flags(FlagSet::BinaryInputs), ReadOnly;
    0x0031 "analogue_input_1" "Actual_State_Analogue_Input_1" AnalogueCentiVolts, ReadOnly;
    0x0032 "analogue_input_2" "Actual_State_Analogue_Input_2" AnalogueCentiVolts, ReadOnly;
    0x0033 "analogue_input_3" "Actual_State_Analogue_Input_3" AnalogueCentiVolts, ReadOnly;
    0x0034 "analogue_input_4" "Actual_State_Analogue_Input_4" AnalogueCentiVolts, ReadOnly;
    0x0040 "keys" "Actual_State_Keys" Flags(FlagSet::Keys), ReadOnly;
    0x0061 "relay_in_cycles_a1" "Number_cycle_off_on_off_Relay_in A1" Counter, ReadOnly;
    0x0062 "relay_in_cycles_a2" "Number_cycle_off_on_off_Relay_in A2" Counter, ReadOnly;
    0x0063 "relay_in_cycles_a3" "Number_cycle_off_on_off_Relay_in A3" Counter, ReadOnly;
    0x0064 "relay_in_cycles_a4" "Number_cycle_off_on_off_Relay_in A4" Counter, ReadOnly;
    0x0065 "relay_in_cycles_a5" "Number_cycle_off_on_off_Relay_in A5" Counter, ReadOnly;
    0x0066 "relay_in_cycles_a6" "Number_cycle_off_on_off_Relay_in A6" Counter, ReadOnly;
    0x0071 "relay_out_cycles_a1" "Number_cycle_off_on_off_Relay_out A1" Counter, ReadOnly;
    0x0072 "relay_out_cycles_a2" "Number_cycle_off_on_off_Relay_out A2" Counter, ReadOnly;
    0x0073 "relay_out_cycles_a3" "Number_cycle_off_on_off_Relay_out A3" Counter, ReadOnly;
    0x0074 "relay_out_cycles_a4" "Number_cycle_off_on_off_Relay_out A4" Counter, ReadOnly;
    0x0075 "relay_out_cycles_a5" "Number_cycle_off_on_off_Relay_out A5" Counter, ReadOnly;
    0x0076 "relay_out_cycles_a6" "Number_cycle_off_on_off_Relay_out A6" Counter, ReadOnly;
    0x0081 "actuator_errors_a1" "Number_Actuator error A1" ActuatorErrorCounter, ReadOnly;
    0x0082 "actuator_errors_a2" "Number_Actuator error A2" ActuatorErrorCounter, ReadOnly;
    0x0083 "actuator_errors_a3" "Number_Actuator error A3" ActuatorErrorCounter, ReadOnly;
    0x0084 "actuator_errors_a4" "Number_Actuator error A4" ActuatorErrorCounter, ReadOnly;
    0x0085 "actuator_errors_a5" "Number_Actuator error A5" ActuatorErrorCounter, ReadOnly;
    0x0086 "actuator_errors_a6" "Number_Actuator error A6" ActuatorErrorCounter, ReadOnly;
    0x008F "total_over_current_count" "Number_Total_Over_Current" Counter, ReadOnly;
    0x0091 "cumulated_stroke_a1" "Cumulated_Stroke A1" StrokeCounts, ReadOnly;
    0x0092 "cumulated_stroke_a2" "Cumulated_Stroke A2" StrokeCounts, ReadOnly;
    0x0093 "cumulated_stroke_a3" "Cumulated_Stroke A3" StrokeCounts, ReadOnly;
    0x0094 "cumulated_stroke_a4" "Cumulated_Stroke A4" StrokeCounts, ReadOnly;
    0x0095 "cumulated_stroke_a5" "Cumulated_Stroke A5" StrokeCounts, ReadOnly;
    0x0096 "cumulated_stroke_a6" "Cumulated_Stroke A6" StrokeCounts, ReadOnly;
    0x00A1 "current_a1" "Current A1" CurrentDeciAmps, ReadOnly;
    0x00A2 "current_a2" "Current A2" CurrentDeciAmps, ReadOnly;
    0x00A3 "current_a3" "Current A3" CurrentDeciAmps, ReadOnly;
    0x00A4 "current_a4" "Current A4" CurrentDeciAmps, ReadOnly;
    0x00A5 "current_a5" "Current A5" CurrentDeciAmps, ReadOnly;
    0x00A6 "current_a6" "Current A6" CurrentDeciAmps, ReadOnly;
    0x00B1 "max_current_a1" "Max_Current A1" CurrentDeciAmps, ReadOnly;
    0x00B2 "max_current_a2" "Max_Current A2" CurrentDeciAmps, ReadOnly;
    0x00B3 "max_current_a3" "Max_Current A3" CurrentDeciAmps, ReadOnly;
    0x00B4 "max_current_a4" "Max_Current A4" CurrentDeciAmps, ReadOnly;
    0x00B5 "max_current_a5" "Max_Current A5" CurrentDeciAmps, ReadOnly;
    0x00B6 "max_current_a6" "Max_Current A6" CurrentDeciAmps, ReadOnly;
    0x00BF "max_total_current" "Max_Total_Current" CurrentDeciAmps, ReadOnly;
    0x00C0 "max_temp_rectifier_fet" "Max_Temp_Rectifier_FET" TemperatureAdc, ReadOnly;
    0x00C1 "over_temp_count_rectifier_fet" "Number_Over_Temp_Rectifier_FET" Counter, ReadOnly;
    0x00D1 "error_code_1" "Error_Code 1 (last recent)" ErrorCode, ReadOnly;
    0x00D2 "error_code_2" "Error_Code 2 (History 1)" ErrorCode, ReadOnly;
    0x00D3 "error_code_3" "Error_Code 3 (History 2)" ErrorCode, ReadOnly;
    0x00D4 "error_code_4" "Error_Code 4 (History 3)" ErrorCode, ReadOnly;
    0x00D5 "error_code_5" "Error_Code 5 (History 4)" ErrorCode, ReadOnly;
    0x00E1 "actuator_status2_a1" "Actuator status 2 A1" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E2 "actuator_status2_a2" "Actuator status 2 A2" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E3 "actuator_status2_a3" "Actuator status 2 A3" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E4 "actuator_status2_a4" "Actuator status 2 A4" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E5 "actuator_status2_a5" "Actuator status 2 A5" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00E6 "actuator_status2_a6" "Actuator status 2 A6" Flags(FlagSet::ActuatorStatus2), ReadOnly;
    0x00F1 "speed_a1" "Speed A1" SpeedPercent, ReadOnly;
    0x00F2 "speed_a2" "Speed A2" SpeedPercent, ReadOnly;
    0x00F3 "speed_a3" "Speed A3" SpeedPercent, ReadOnly;
    0x00F4 "speed_a4" "Speed A4" SpeedPercent, ReadOnly;
    0x00F5 "speed_a5" "Speed A5" SpeedPercent, ReadOnly;
    0x00F6 "speed_a6" "Speed A6" SpeedPercent, ReadOnly;
    0x0100 "battery_mains" "Battery Mains" Flags(FlagSet::BatteryMains), ReadOnly;
    0x0110 "binary_outputs" "Binary Output Status" Flags(FlagSet::BinaryOutputs), ReadOnly;
    0x0120 "led_hand_switch" "LED HS" Flags(FlagSet::LedHandSwitch), ReadOnly;
    0x0130 "led_locking_box" "LED LB" Flags(FlagSet::LedLockingBox), ReadOnly;
    0x0140 "buzzer" "Buzzer" Flags(FlagSet::Buzzer), ReadOnly;
    0x0150 "sensor_supply" "Sensor Supply" Flags(FlagSet::SensorSupply), ReadOnly;
    0x0162 "lock_status" "Lock Status" Flags(FlagSet::LockStatus), ReadOnly;
    0x0164 "battery_voltage" "Battery voltage" BatteryDeciVolts, ReadOnly;
    0x0165 "locking_box_detected" "Locking Box detected" Number, ReadOnly;
    0x0166 "user" "User" Number, ReadOnly;
    0x0171 "actuator_status1_a1" "Actuator Status 1 A1" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0172 "actuator_status1_a2" "Actuator Status 1 A2" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0173 "actuator_status1_a3" "Actuator Status 1 A3" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0174 "actuator_status1_a4" "Actuator Status 1 A4" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0175 "actuator_status1_a5" "Actuator Status 1 A5" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x0176 "actuator_status1_a6" "Actuator Status 1 A6" Flags(FlagSet::ActuatorStatus1), ReadOnly;
    0x1011 "conversion_factor_a1" "Conversion factor A1" ConversionFactor, ReadOnly;
    0x1012 "conversion_factor_a2" "Conversion factor A2" ConversionFactor, ReadOnly;
    0x1013 "conversion_factor_a3" "Conversion factor A3" ConversionFactor, ReadOnly;
    0x1014 "conversion_factor_a4" "Conversion factor A4" ConversionFactor, ReadOnly;
    0x1015 "conversion_factor_a5" "Conversion factor A5" ConversionFactor, ReadOnly;
    0x1016 "conversion_factor_a6" "Conversion factor A6" ConversionFactor, ReadOnly;
    0x2001 "user_positions_a1" "UserPositionData A1" UserPositions, ReadOnly;
    0x2002 "user_positions_a2" "UserPositionData A2" UserPositions, ReadOnly;
    0x2003 "user_positions_a3" "UserPositionData A3" UserPositions, ReadOnly;
    0x2004 "user_positions_a4" "UserPositionData A4" UserPositions, ReadOnly;
    0x2005 "user_positions_a5" "UserPositionData A5" UserPositions, ReadOnly;
    0x2006 "user_positions_a6" "UserPositionData A6" UserPositions, ReadOnly;
    0x3001 "cyclic_obj_1" "CyclicObj 1" CyclicObject, ReadWrite;
    0x3002 "cyclic_obj_2" "CyclicObj 2" CyclicObject, ReadWrite;
    0x3003 "cyclic_obj_3" "CyclicObj 3" CyclicObject, ReadWrite;
    0x3004 "cyclic_obj_4" "CyclicObj 4" CyclicObject, ReadWrite;
    0x3005 "cyclic_obj_5" "CyclicObj 5" CyclicObject, ReadWrite;
    0x3011 "remote_speed_f1" "Remote Speed F1" RemoteSpeed, ReadWrite;
    0x3012 "remote_speed_f2" "Remote Speed F2" RemoteSpeed, ReadWrite;
    0x3013 "remote_speed_f3" "Remote Speed F3" RemoteSpeed, ReadWrite;
    0x3014 "remote_speed_f4" "Remote Speed F4" RemoteSpeed, ReadWrite;
    0x3015 "remote_speed_f5" "Remote Speed F5" RemoteSpeed, ReadWrite;
    0x3016 "remote_speed_f6" "Remote Speed F6" RemoteSpeed, ReadWrite;
    0x3017 "remote_speed_f7" "Remote Speed F7" RemoteSpeed, ReadWrite;
    0x3018 "remote_speed_f8" "Remote Speed F8" RemoteSpeed, ReadWrite;
    0x3019 "remote_speed_f9" "Remote Speed F9" RemoteSpeed, ReadWrite;
    0x301A "remote_speed_f10" "Remote Speed F10" RemoteSpeed, ReadWrite;
    0x3021 "remote_position_a1" "Remote Position A1" RemotePosition, ReadWrite;
    0x3022 "remote_position_a2" "Remote Position A2" RemotePosition, ReadWrite;
    0x3023 "remote_position_a3" "Remote Position A3" RemotePosition, ReadWrite;
    0x3024 "remote_position_a4" "Remote Position A4" RemotePosition, ReadWrite;
    0x3025 "remote_position_a5" "Remote Position A5" RemotePosition, ReadWrite;
    0x3026 "remote_position_a6" "Remote Position A6" RemotePosition, ReadWrite;
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
        DATA_LIST.iter().filter(move |e| (self.first..=self.last).contains(&e.index.0))
    }

    /// Size in bytes of the group's data.
    pub fn size(&self) -> usize {
        self.members().map(DataEntry::size).sum()
    }

    /// True if RT may write the whole group at once (remote data).
    pub fn is_remote(&self) -> bool {
        self.index.is_remote()
    }
}

/// What a data index refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
            Item::Entry(e) => e.index,
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
            Item::Entry(e) => e.access == Access::ReadWrite,
            Item::Group(g) => g.is_remote(),
        }
    }
}

/// The entry at `index`, if the data list has one.
pub fn entry(index: DataIndex) -> Option<&'static DataEntry> {
    DATA_LIST.binary_search_by_key(&index, |e| e.index).ok().map(|i| &DATA_LIST[i])
}

/// The entry or group at `index`.
pub fn item(index: DataIndex) -> Option<Item> {
    entry(index).map(Item::Entry).or_else(|| GROUPS.iter().find(|g| g.index == index).map(Item::Group))
}

/// Finds an entry or group by command-line name (case-insensitive) or by index written as `0x0011` or `0011`.
pub fn lookup(text: &str) -> Option<Item> {
    let t = text.trim();
    if let Some(e) = DATA_LIST.iter().find(|e| e.name.eq_ignore_ascii_case(t)) {
        return Some(Item::Entry(e));
    }
    if let Some(g) = GROUPS.iter().find(|g| g.name.eq_ignore_ascii_case(t)) {
        return Some(Item::Group(g));
    }
    parse_index(t).and_then(item)
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

// ---------------------------------------------------------------------------------------------------------
// Actuators and functions

/// One of the up to six actuators (drives) of a control unit, numbered 1..6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Actuator(u8);

impl Actuator {
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

/// One of the motion functions F1..F10, whose drives the unit's parameterisation decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
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

impl fmt::Display for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "F{} ({})", self.number(), self.description())
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

/// How RS stops a motion function (table 6, para_ID motion_stop).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
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

// ---------------------------------------------------------------------------------------------------------
// Bit sets

/// A named bit of a [`FlagSet`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FlagBit {
    /// Bit number, 0 = least significant.
    pub bit: u8,
    /// Name for JSON and tables.
    pub name: &'static str,
    /// Meaning when set.
    pub set: &'static str,
    /// Meaning when clear.
    pub clear: &'static str,
}

const fn fb(bit: u8, name: &'static str, clear: &'static str, set: &'static str) -> FlagBit {
    FlagBit { bit, name, set, clear }
}

/// The named bit sets of the data list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FlagSet {
    /// 0x0020: logic and input level of binary inputs 1..4.
    BinaryInputs,
    /// 0x0040: keys K1..K20 closed.
    Keys,
    /// 0x0100: mains, battery, charging.
    BatteryMains,
    /// 0x0110: binary outputs.
    BinaryOutputs,
    /// 0x0120: LEDs of the hand switch.
    LedHandSwitch,
    /// 0x0130: LEDs of the locking box.
    LedLockingBox,
    /// 0x0140: buzzer.
    Buzzer,
    /// 0x0150: sensor supply.
    SensorSupply,
    /// 0x0162: functions locked.
    LockStatus,
    /// 0x0171..0x0176: actuator status 1.
    ActuatorStatus1,
    /// 0x00E1..0x00E6: actuator status 2.
    ActuatorStatus2,
}

const BINARY_INPUTS: &[FlagBit] = &[
    fb(0, "input1_logic", "not active", "active"),
    fb(1, "input2_logic", "not active", "active"),
    fb(2, "input3_logic", "not active", "active"),
    fb(3, "input4_logic", "not active", "active"),
    fb(4, "input1_level", "not active", "active"),
    fb(5, "input2_level", "not active", "active"),
    fb(6, "input3_level", "not active", "active"),
    fb(7, "input4_level", "not active", "active"),
];
const KEYS: &[FlagBit] = &[
    fb(0, "k1", "open", "closed"),
    fb(1, "k2", "open", "closed"),
    fb(2, "k3", "open", "closed"),
    fb(3, "k4", "open", "closed"),
    fb(4, "k5", "open", "closed"),
    fb(5, "k6", "open", "closed"),
    fb(6, "k7", "open", "closed"),
    fb(7, "k8", "open", "closed"),
    fb(8, "k9", "open", "closed"),
    fb(9, "k10", "open", "closed"),
    fb(10, "k11", "open", "closed"),
    fb(11, "k12", "open", "closed"),
    fb(12, "k13", "open", "closed"),
    fb(13, "k14", "open", "closed"),
    fb(14, "k15", "open", "closed"),
    fb(15, "k16", "open", "closed"),
    fb(16, "k17", "open", "closed"),
    fb(17, "k18", "open", "closed"),
    fb(18, "k19", "open", "closed"),
    fb(19, "k20", "open", "closed"),
];
const BATTERY_MAINS: &[FlagBit] = &[
    fb(0, "mains_connected", "mains not connected", "mains connected"),
    fb(1, "battery_connected", "battery disconnected", "battery connected"),
    fb(2, "charge_controller", "charge controller off", "charge controller on"),
    fb(3, "charging", "charging inactive", "charging active"),
];
const BINARY_OUTPUTS: &[FlagBit] = &[fb(0, "output1", "off", "on"), fb(1, "output2", "off", "on")];
const LED_HAND_SWITCH: &[FlagBit] = &[fb(0, "led1", "off", "on"), fb(1, "led2", "off", "on")];
const LED_LOCKING_BOX: &[FlagBit] = &[
    fb(0, "led1", "off", "on"),
    fb(1, "led2", "off", "on"),
    fb(2, "led3", "off", "on"),
    fb(3, "led4", "off", "on"),
    fb(4, "led5", "off", "on"),
    fb(5, "led6", "off", "on"),
    fb(6, "led7", "off", "on"),
    fb(7, "led8", "off", "on"),
];
const BUZZER: &[FlagBit] = &[fb(0, "buzzer", "off", "on")];
const SENSOR_SUPPLY: &[FlagBit] = &[fb(0, "sensor_supply", "off", "on")];
const LOCK_STATUS: &[FlagBit] = &[
    fb(0, "f1_locked", "unlocked", "locked"),
    fb(1, "f2_locked", "unlocked", "locked"),
    fb(2, "f3_locked", "unlocked", "locked"),
    fb(3, "f4_locked", "unlocked", "locked"),
    fb(4, "f5_locked", "unlocked", "locked"),
    fb(5, "f6_locked", "unlocked", "locked"),
    fb(6, "f7_locked", "unlocked", "locked"),
    fb(7, "f8_locked", "unlocked", "locked"),
    fb(8, "f9_locked", "unlocked", "locked"),
    fb(9, "f10_locked", "unlocked", "locked"),
];
const ACTUATOR_STATUS1: &[FlagBit] = &[
    fb(0, "available", "drive unavailable", "drive available"),
    fb(1, "limit_in_out", "signal limit_in_out inactive", "signal limit_in_out active"),
    fb(2, "switch1", "signal switch 1 inactive", "signal switch 1 active"),
    fb(3, "switch2", "signal switch 2 inactive", "signal switch 2 active"),
    fb(4, "motion", "motion inactive", "motion active"),
    fb(5, "in_position", "in position not reached", "in position reached"),
    fb(6, "out_position", "out position not reached", "out position reached"),
    fb(7, "stroke_done", "stroke not done", "stroke done"),
];
const ACTUATOR_STATUS2: &[FlagBit] = &[
    fb(0, "initialized", "not initialized", "initialized"),
    fb(1, "release_retraction", "no release for retraction", "released for retraction"),
    fb(2, "release_extension", "no release for extension", "released for extension"),
];

impl FlagSet {
    /// Size in bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            FlagSet::Keys => 4,
            FlagSet::LockStatus => 2,
            _ => 1,
        }
    }

    /// The named bits.
    pub const fn bits(self) -> &'static [FlagBit] {
        match self {
            FlagSet::BinaryInputs => BINARY_INPUTS,
            FlagSet::Keys => KEYS,
            FlagSet::BatteryMains => BATTERY_MAINS,
            FlagSet::BinaryOutputs => BINARY_OUTPUTS,
            FlagSet::LedHandSwitch => LED_HAND_SWITCH,
            FlagSet::LedLockingBox => LED_LOCKING_BOX,
            FlagSet::Buzzer => BUZZER,
            FlagSet::SensorSupply => SENSOR_SUPPLY,
            FlagSet::LockStatus => LOCK_STATUS,
            FlagSet::ActuatorStatus1 => ACTUATOR_STATUS1,
            FlagSet::ActuatorStatus2 => ACTUATOR_STATUS2,
        }
    }

    /// The bit named `name`.
    pub fn bit(self, name: &str) -> Option<&'static FlagBit> {
        self.bits().iter().find(|b| b.name == name)
    }
}

/// A value of a named bit set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Flags {
    /// Which set.
    pub set: FlagSet,
    /// The raw bits.
    pub bits: u32,
}

impl Flags {
    /// True if the bit named `name` is set.
    pub fn is_set(&self, name: &str) -> bool {
        self.set.bit(name).is_some_and(|b| self.bits & (1 << b.bit) != 0)
    }

    /// Names of the set bits.
    pub fn set_names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.set.bits().iter().filter(|b| self.bits & (1 << b.bit) != 0).map(|b| b.name)
    }
}

impl fmt::Display for Flags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let width = self.set.size() * 2;
        write!(f, "0x{:0width$X}", self.bits)?;
        let names: Vec<_> = self.set_names().collect();
        if !names.is_empty() {
            write!(f, " [{}]", names.join(", "))?;
        }
        Ok(())
    }
}

/// Bits of actuator status 1 used by the client and the emulator.
pub mod status1 {
    /// Bit 0: drive available.
    pub const AVAILABLE: u8 = 1 << 0;
    /// Bit 1: signal limit_in_out active.
    pub const LIMIT_IN_OUT: u8 = 1 << 1;
    /// Bit 2: signal switch 1 active.
    pub const SWITCH1: u8 = 1 << 2;
    /// Bit 3: signal switch 2 active.
    pub const SWITCH2: u8 = 1 << 3;
    /// Bit 4: motion active.
    pub const MOTION: u8 = 1 << 4;
    /// Bit 5: in position reached.
    pub const IN_POSITION: u8 = 1 << 5;
    /// Bit 6: out position reached.
    pub const OUT_POSITION: u8 = 1 << 6;
    /// Bit 7: stroke done.
    pub const STROKE_DONE: u8 = 1 << 7;
}

/// Bits of actuator status 2.
pub mod status2 {
    /// Bit 0: initialised.
    pub const INITIALIZED: u8 = 1 << 0;
    /// Bit 1: released for retraction.
    pub const RELEASE_RETRACTION: u8 = 1 << 1;
    /// Bit 2: released for extension.
    pub const RELEASE_EXTENSION: u8 = 1 << 2;
}

// ---------------------------------------------------------------------------------------------------------
// Error code

/// One bit of the SCU error code, as the manual numbers it (1..32): bit n is mask `1 << (n - 1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorBit {
    /// The manual's bit number, 1..32.
    pub number: u8,
    /// Name for JSON.
    pub name: &'static str,
    /// Cause.
    pub cause: &'static str,
    /// When it can appear.
    pub condition: &'static str,
    /// What the unit does.
    pub reaction: &'static str,
}

impl ErrorBit {
    /// The bit's mask in the 32-bit error code.
    pub const fn mask(&self) -> u32 {
        1 << (self.number - 1)
    }
}

const fn eb(
    number: u8,
    name: &'static str,
    cause: &'static str,
    condition: &'static str,
    reaction: &'static str,
) -> ErrorBit {
    ErrorBit { number, name, cause, condition, reaction }
}

const STOP_RESET: &str = "motions are stopped and the control unit carries out a reset";
const FAST_STOP_RESET: &str = "motions are stopped (fast stop) and the control unit carries out a reset";
const FAST_STOP: &str = "motions are stopped (fast stop)";
const NOT_PERFORMED: &str = "motions are not performed or stopped";
const DRIVE_FAULT_CONDITION: &str =
    "peak current, short circuit current, sensor monitor, over current or time out (if not limit position)";
const DRIVE_FAULT_REACTION: &str = "drive stopped (fast stop); bit reset on next motion";

/// The 32 bits of the SCU error code (table 7). Bits 9 and 23 are unused.
pub const ERROR_BITS: &[ErrorBit] = &[
    eb(1, "rom_test", "CRC error with ROM test, faulty ROM", "", STOP_RESET),
    eb(2, "ram_test", "error with RAM test, faulty RAM", "", STOP_RESET),
    eb(3, "cpu_test", "error with CPU test, faulty CPU", "", STOP_RESET),
    eb(4, "stack_overrun", "stack overrun detected", "", FAST_STOP_RESET),
    eb(5, "program_sequence", "program sequence error, watchdog reset", "", FAST_STOP_RESET),
    eb(
        6,
        "hand_switch_test",
        "error with hand switch test, short in hand switch",
        "only if the hand switch is parameterised as safe",
        FAST_STOP,
    ),
    eb(
        7,
        "binary_inputs_test",
        "error with binary inputs, short between binary inputs",
        "only if binary inputs are parameterised as safe and no analogue input is parameterised",
        FAST_STOP,
    ),
    eb(
        8,
        "relay_fet_test",
        "error with relay and FET tests, faulty relay or FET",
        "test performed at start of motion",
        "motion not executed",
    ),
    eb(10, "move_enable_communication", "no reply from the MoveEnable controller", "", FAST_STOP),
    eb(11, "move_enable_output", "the MoveEnable controller output is incorrect", "", FAST_STOP),
    eb(12, "over_temperature", "overtemperature at rectifier or FET", "", FAST_STOP),
    eb(
        13,
        "battery_discharge",
        "switched off due to excessive discharge of battery",
        "",
        "motions are stopped (fast stop); the control unit switches itself off",
    ),
    eb(
        14,
        "total_current",
        "total current exceeded",
        "if motion in process",
        "motions are stopped (fast stop); bit reset in the next motion",
    ),
    eb(15, "drive1", "error with drive 1", DRIVE_FAULT_CONDITION, DRIVE_FAULT_REACTION),
    eb(16, "drive2", "error with drive 2", DRIVE_FAULT_CONDITION, DRIVE_FAULT_REACTION),
    eb(17, "drive3", "error with drive 3", DRIVE_FAULT_CONDITION, DRIVE_FAULT_REACTION),
    eb(18, "drive4", "error with drive 4", DRIVE_FAULT_CONDITION, DRIVE_FAULT_REACTION),
    eb(19, "drive5", "error with drive 5", DRIVE_FAULT_CONDITION, DRIVE_FAULT_REACTION),
    eb(20, "drive6", "error with drive 6", DRIVE_FAULT_CONDITION, DRIVE_FAULT_REACTION),
    eb(
        21,
        "position_difference",
        "position difference between drives too great (synchronised parallel run)",
        "only if synchronised parallel run is parameterised",
        "motion not started, or stopped (fast stop); bit reset on next motion",
    ),
    eb(22, "remote_timeout", "remote communication time out", "", "depending on the Safety_ID"),
    eb(
        24,
        "locking_box_i2c",
        "locking box I2C communication error",
        "only if the locking box is parameterised as safe",
        NOT_PERFORMED,
    ),
    eb(25, "eeprom_configuration_crc", "RAM copy of EEPROM configuration data has a wrong CRC", "", NOT_PERFORMED),
    eb(26, "eeprom_user_crc", "RAM copy of EEPROM user data has a wrong CRC", "", NOT_PERFORMED),
    eb(27, "eeprom_locking_box_crc", "EEPROM locking box data has a wrong CRC", "", NOT_PERFORMED),
    eb(28, "eeprom_dynamic_crc", "RAM copy of EEPROM dynamic data has a wrong CRC", "", NOT_PERFORMED),
    eb(29, "eeprom_calibration_crc", "RAM copy of EEPROM calibration data has a wrong CRC", "", NOT_PERFORMED),
    eb(30, "eeprom_hw_settings_crc", "RAM copy of EEPROM hardware settings has a wrong CRC", "", NOT_PERFORMED),
    eb(31, "io_test", "IO test failed", "performed if no motion is active", "motions not performed"),
    eb(32, "operating_system", "IDF operating system error", "", NOT_PERFORMED),
];

/// The error bit with the manual's number `number` (1..32).
pub fn error_bit(number: u8) -> Option<&'static ErrorBit> {
    ERROR_BITS.iter().find(|b| b.number == number)
}

/// Named error bits of the emulator and client.
pub mod error_bits {
    /// Bit 14: total current exceeded.
    pub const TOTAL_CURRENT: u8 = 14;
    /// Bit 15: error with drive 1 (drive n is bit 14 + n).
    pub const DRIVE1: u8 = 15;
    /// Bit 22: remote communication time out.
    pub const REMOTE_TIMEOUT: u8 = 22;
}

/// A 32-bit SCU error code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ErrorCode(pub u32);

impl ErrorCode {
    /// No error.
    pub const NONE: ErrorCode = ErrorCode(0);

    /// The code with only the manual's bit `number` set.
    pub const fn from_bit(number: u8) -> ErrorCode {
        ErrorCode(1 << (number - 1))
    }

    /// True if the manual's bit `number` is set.
    pub const fn has(self, number: u8) -> bool {
        number >= 1 && number <= 32 && self.0 & (1 << (number - 1)) != 0
    }

    /// The known bits that are set.
    pub fn bits(self) -> impl Iterator<Item = &'static ErrorBit> {
        ERROR_BITS.iter().filter(move |b| self.0 & b.mask() != 0)
    }

    /// Set bits the manual does not define (9, 23).
    pub fn unknown_bits(self) -> u32 {
        let known: u32 = ERROR_BITS.iter().map(ErrorBit::mask).fold(0, |a, m| a | m);
        self.0 & !known
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:08X}", self.0)?;
        if self.0 == 0 {
            return f.write_str(" (no error)");
        }
        let mut first = true;
        for b in self.bits() {
            f.write_str(if first { " [" } else { "; " })?;
            first = false;
            write!(f, "bit {}: {}", b.number, b.cause)?;
        }
        if self.unknown_bits() != 0 {
            f.write_str(if first { " [" } else { "; " })?;
            first = false;
            write!(f, "undefined bits 0x{:08X}", self.unknown_bits())?;
        }
        if !first {
            f.write_str("]")?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------------------
// Structures

/// The positions one user stores for an actuator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct UserPositions {
    /// Position Memory 1..4, in counts.
    pub memory_counts: [i32; 4],
    /// Position Intermediate In, in counts.
    pub intermediate_in_counts: i32,
    /// Position Intermediate Out, in counts.
    pub intermediate_out_counts: i32,
}

/// ACTUATOR_POSITIONS (chapter 7): the stored positions of one actuator, 26 INT32.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct UserPositionData {
    /// Users 1..4.
    pub users: [UserPositions; 4],
    /// Position Virtual Limit In, in counts.
    pub virtual_limit_in_counts: i32,
    /// Position Virtual Limit Out, in counts.
    pub virtual_limit_out_counts: i32,
}

impl UserPositionData {
    /// Size on the wire: 26 INT32.
    pub const SIZE: usize = 26 * 4;

    /// Reads the structure from `bytes` (exactly [`Self::SIZE`] long).
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::SIZE {
            return None;
        }
        let mut words = bytes.chunks_exact(4).map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]));
        let mut next = || words.next().unwrap_or(0);
        let mut data = UserPositionData::default();
        for user in &mut data.users {
            for m in &mut user.memory_counts {
                *m = next();
            }
            user.intermediate_in_counts = next();
            user.intermediate_out_counts = next();
        }
        data.virtual_limit_in_counts = next();
        data.virtual_limit_out_counts = next();
        Some(data)
    }

    /// Writes the structure to `out`.
    pub fn write_to(&self, out: &mut Vec<u8>) {
        for user in &self.users {
            for m in user.memory_counts {
                out.extend_from_slice(&m.to_le_bytes());
            }
            out.extend_from_slice(&user.intermediate_in_counts.to_le_bytes());
            out.extend_from_slice(&user.intermediate_out_counts.to_le_bytes());
        }
        out.extend_from_slice(&self.virtual_limit_in_counts.to_le_bytes());
        out.extend_from_slice(&self.virtual_limit_out_counts.to_le_bytes());
    }
}

/// A cyclic object definition (CyclicObj 1..5, 0x3001..0x3005): the data written to the unit with each RC and
/// the data it answers with.
///
/// The manual says "the first 6 bytes (para[0..5])" define the write data and "the last 6 bytes" the read
/// data of a `UINT16[12]`: it means the first and last six *entries*. -1 (0xFFFF) means unused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CyclicObject {
    /// Indices whose values the host sends with each RC (0x3xxx only).
    pub write: [DataIndex; 6],
    /// Indices whose values the unit returns with each RC.
    pub read: [DataIndex; 6],
}

impl Default for CyclicObject {
    fn default() -> Self {
        CyclicObject { write: [DataIndex::NONE; 6], read: [DataIndex::NONE; 6] }
    }
}

impl CyclicObject {
    /// Size on the wire: 12 UINT16.
    pub const SIZE: usize = 24;

    /// A definition from lists of up to six indices each.
    pub fn new(write: &[DataIndex], read: &[DataIndex]) -> Option<CyclicObject> {
        if write.len() > 6 || read.len() > 6 {
            return None;
        }
        let mut obj = CyclicObject::default();
        obj.write[..write.len()].copy_from_slice(write);
        obj.read[..read.len()].copy_from_slice(read);
        Some(obj)
    }

    /// Reads a definition from 24 bytes.
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::SIZE {
            return None;
        }
        let mut obj = CyclicObject::default();
        for (i, c) in bytes.chunks_exact(2).enumerate() {
            let idx = DataIndex(u16::from_le_bytes([c[0], c[1]]));
            if i < 6 {
                obj.write[i] = idx;
            } else {
                obj.read[i - 6] = idx;
            }
        }
        Some(obj)
    }

    /// The 24 bytes of the definition.
    pub fn to_bytes(&self) -> [u8; Self::SIZE] {
        let mut out = [0u8; Self::SIZE];
        for (i, idx) in self.write.iter().chain(self.read.iter()).enumerate() {
            out[2 * i..2 * i + 2].copy_from_slice(&idx.0.to_le_bytes());
        }
        out
    }

    /// The write indices in use.
    pub fn write_indices(&self) -> impl Iterator<Item = DataIndex> + '_ {
        self.write.iter().copied().filter(|i| *i != DataIndex::NONE)
    }

    /// The read indices in use.
    pub fn read_indices(&self) -> impl Iterator<Item = DataIndex> + '_ {
        self.read.iter().copied().filter(|i| *i != DataIndex::NONE)
    }

    /// Bytes of write data each RC carries, or `None` if an index is not a data-list entry.
    pub fn write_size(&self) -> Option<usize> {
        self.write_indices().map(|i| item(i).map(|it| it.size())).sum()
    }

    /// Bytes of read data each RC answer carries, or `None` if an index is not a data-list entry.
    pub fn read_size(&self) -> Option<usize> {
        self.read_indices().map(|i| item(i).map(|it| it.size())).sum()
    }
}

/// The actuator error counter of 0x0081..0x0086.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct ActuatorErrorCount {
    /// Number of actuator errors (low two bytes).
    pub errors: u16,
    /// Number of peak-current occurrences (third byte).
    pub peak_current: u8,
    /// Number of short-circuit occurrences (high byte).
    pub short_circuit: u8,
}

impl ActuatorErrorCount {
    /// Splits the UINT32.
    pub const fn from_u32(v: u32) -> Self {
        ActuatorErrorCount { errors: v as u16, peak_current: (v >> 16) as u8, short_circuit: (v >> 24) as u8 }
    }

    /// Joins the UINT32.
    pub const fn to_u32(self) -> u32 {
        self.errors as u32 | (self.peak_current as u32) << 16 | (self.short_circuit as u32) << 24
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_list_is_sorted_unique_and_names_are_unique() {
        for w in DATA_LIST.windows(2) {
            assert!(w[0].index < w[1].index, "{} then {}", w[0].index, w[1].index);
        }
        let mut names: Vec<_> = DATA_LIST.iter().map(|e| e.name).chain(GROUPS.iter().map(|g| g.name)).collect();
        names.sort_unstable();
        let before = names.len();
        names.dedup();
        assert_eq!(before, names.len(), "duplicate names");
    }

    #[test]
    fn where_the_editions_differ_the_decisions_hold() {
        // Battery Mains bit 2 set: the charge controller is on (the Schaeffler edition's reading).
        let b = FlagSet::BatteryMains.bit("charge_controller").unwrap();
        assert_eq!((b.bit, b.set, b.clear), (2, "charge controller on", "charge controller off"));
        // Error bits 29, 30 and 32 have causes of their own (the Ewellix edition's).
        let cause = |n: u8| ERROR_BITS.iter().find(|b| b.number == n).unwrap().cause;
        assert!(cause(29).contains("calibration"));
        assert!(cause(30).contains("hardware settings"));
        assert!(cause(32).contains("operating system"));
        assert_eq!(Function::from_id(21).map(Function::description), Some("operating unit LED 2"));
    }

    #[test]
    fn only_remote_entries_are_writable() {
        for e in DATA_LIST {
            assert_eq!(e.access == Access::ReadWrite, e.index.is_remote(), "{}", e.name);
        }
    }

    #[test]
    fn groups_cover_their_members() {
        let g = |i| item(DataIndex(i)).unwrap();
        assert_eq!(g(0x0010).size(), 24);
        assert_eq!(g(0x0080).size(), 7 * 4, "0x0080 includes Number_Total_Over_Current 0x008F");
        assert_eq!(g(0x00B0).size(), 7 * 2, "0x00B0 includes Max_Total_Current 0x00BF");
        assert_eq!(g(0x2000).size(), 6 * 104);
        assert_eq!(g(0x0000).size(), 31 + 36);
        for group in GROUPS {
            assert!(group.members().count() > 0, "{}", group.name);
            assert!(entry(group.index).is_none(), "a group index is not also an entry");
        }
    }

    #[test]
    fn lookup_by_name_or_index() {
        assert_eq!(lookup("0x0171").unwrap().name(), "actuator_status1_a1");
        assert_eq!(lookup("0171").unwrap().name(), "actuator_status1_a1");
        assert_eq!(lookup("REMOTE_SPEED_F1").unwrap().index(), DataIndex(0x3011));
        assert_eq!(lookup("actual_positions").unwrap().index(), DataIndex(0x0010));
        assert!(lookup("0x0017").is_none());
        assert!(lookup("nonsense").is_none());
    }

    #[test]
    fn error_bits_follow_the_decision_bit_n_is_mask_1_shl_n_minus_1() {
        assert_eq!(error_bit(1).unwrap().mask(), 0x0000_0001);
        assert_eq!(error_bit(22).unwrap().mask(), 0x0020_0000);
        assert_eq!(error_bit(32).unwrap().mask(), 0x8000_0000);
        assert!(error_bit(9).is_none() && error_bit(23).is_none());
        assert_eq!(ERROR_BITS.len(), 30);
        let code = ErrorCode::from_bit(22);
        assert!(code.has(22) && !code.has(21));
        assert_eq!(code.bits().map(|b| b.name).collect::<Vec<_>>(), ["remote_timeout"]);
        assert!(code.to_string().contains("remote communication time out"));
        assert_eq!(ErrorCode(1 << 8).unknown_bits(), 1 << 8, "bit 9 is undefined");
    }

    #[test]
    fn functions_map_to_wire_ids() {
        assert_eq!(Function::parse("F1"), Some(Function::Motion(MotionFunction::new(1).unwrap())));
        assert_eq!(Function::parse("f11"), Some(Function::Buzzer));
        assert_eq!(Function::parse("20").map(Function::id), Some(19));
        assert_eq!(Function::parse("F12"), None, "F12..F16 and F19 are not in the function list");
        assert_eq!(Function::parse("F19"), None);
        for id in 0..=255u8 {
            if let Some(f) = Function::from_id(id) {
                assert_eq!(f.id(), id);
            }
        }
    }

    #[test]
    fn structures_round_trip() {
        let mut data = UserPositionData::default();
        data.users[2].memory_counts[1] = -5;
        data.virtual_limit_out_counts = 865;
        let mut bytes = Vec::new();
        data.write_to(&mut bytes);
        assert_eq!(bytes.len(), UserPositionData::SIZE);
        assert_eq!(UserPositionData::from_bytes(&bytes), Some(data));
        assert_eq!(&bytes[100..104], &865i32.to_le_bytes());

        let obj = CyclicObject::new(&[DataIndex(0x3021)], &[DataIndex(0x0011), DataIndex(0x0171)]).unwrap();
        assert_eq!(CyclicObject::from_bytes(&obj.to_bytes()), Some(obj));
        assert_eq!(obj.write_size(), Some(4));
        assert_eq!(obj.read_size(), Some(5));
        assert_eq!(&obj.to_bytes()[..4], &[0x21, 0x30, 0xFF, 0xFF]);

        let c = ActuatorErrorCount { errors: 0x0102, peak_current: 3, short_circuit: 4 };
        assert_eq!(c.to_u32(), 0x0403_0102);
        assert_eq!(ActuatorErrorCount::from_u32(c.to_u32()), c);
    }
}
