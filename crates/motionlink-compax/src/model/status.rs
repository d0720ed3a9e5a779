//! Status values S1..S40: their numbers, and the table of those whose meaning is known, as rows of the
//! shared [`Table`] ([`STATUS`]).
//!
//! ```
//! use motionlink_compax::model::{StatusId, StatusKind, STATUS};
//! assert_eq!(STATUS.lookup("actual_position").map(|e| e.id), Some(1));
//! assert_eq!(STATUS.by_id(17).map(|e| e.kind.kind), Some(StatusKind::BitsS17));
//! assert_eq!(StatusId::parse("S016").unwrap(), StatusId::STATUS_BITS_1);
//! assert_eq!(StatusId::parse("target_position").unwrap(), StatusId::TARGET_POSITION);
//! ```

use std::fmt;

use motionlink_link::table::{Access, Entry, Table};

use super::{unknown_name, ModelError};

/// How a status value is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StatusKind {
    /// A position in the drive's unit.
    Position,
    /// Another number.
    Number,
    /// The 8 status bits of S16.
    BitsS16,
    /// The 8 status bits of S17.
    BitsS17,
    /// The 8-entry error history of S18.
    History,
    /// Text.
    Text,
}

/// What the COMPAX table says of a status value besides the shared columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StatusDetail {
    /// How to read it.
    pub kind: StatusKind,
    /// What it is.
    pub description: &'static str,
}

/// A status value number, 1..=40.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StatusId(pub(crate) u8);

/// Writes the constants of [`StatusId`] and the rows of [`STATUS`] from one list.
macro_rules! status_table {
    ($( $num:literal => $konst:ident, $name:literal, $title:literal, $desc:literal, $kind:ident, $unit:literal; )*) => {
        impl StatusId {
            $(
                #[doc = concat!("S", stringify!($num), ": ", $desc, ".")]
                pub const $konst: StatusId = StatusId($num);
            )*
        }

        /// The rows of [`STATUS`].
        const STATUS_ENTRIES: &[Entry<StatusDetail>] = &[
            $( Entry { id: $num, name: $name, title: $title, unit: $unit, access: Access::Read,
                       kind: StatusDetail { kind: StatusKind::$kind, description: $desc } }, )*
        ];
    };
}

status_table! {
    1 => ACTUAL_POSITION, "actual_position", "actual position", "actual position, relative to the real zero", Position, "unit";
    2 => TARGET_POSITION, "target_position", "target position", "target position of the current or last positioning", Position, "unit";
    3 => CONTOUR_ERROR, "contour_error", "contour error", "contour (following) error: set minus actual position", Position, "unit";
    6 => TEMPERATURE, "temperature", "temperature", "temperature of the power output stage", Number, "°C";
    7 => CONTROL_VOLTAGE, "control_voltage", "control voltage", "control voltage", Number, "V";
    8 => DC_LINK_VOLTAGE, "dc_link_voltage", "DC link voltage", "intermediate circuit voltage", Number, "V";
    9 => MOTION_CYCLES, "motion_cycles", "motion cycles", "number of axis motion cycles", Number, "";
    10 => OPERATING_HOURS, "operating_hours", "operating hours", "COMPAX operating hours", Number, "h";
    11 => LOOP_COUNTER, "loop_counter", "loop counter", "loop counter of a running REPEAT loop", Number, "";
    12 => ABSOLUTE_SENSOR, "absolute_sensor", "absolute sensor", "position of the absolute value sensor", Position, "unit";
    16 => STATUS_BITS_1, "status_bits_1", "status bits S16", "status bits: fault, warning, machine zero, ready, reached, idle", BitsS16, "";
    17 => STATUS_BITS_2, "status_bits_2", "status bits S17", "status bits: passwords, command active, program, stop, RUN", BitsS17, "";
    18 => ERROR_HISTORY, "error_history", "error history", "the last eight errors, newest first (99 acknowledged, 98 power on)", History, "";
    30 => ERROR_MESSAGE, "error_message", "error message", "the pending error message", Text, "";
    31 => DEVICE_ID_1, "device_id_1", "device identification 1", "device identification", Text, "";
    32 => DEVICE_ID_2, "device_id_2", "device identification 2", "device identification", Text, "";
    33 => DEVICE_ID_3, "device_id_3", "device identification 3", "device identification", Text, "";
    34 => DEVICE_ID_4, "device_id_4", "device identification 4", "device identification", Text, "";
    35 => DEVICE_ID_5, "device_id_5", "device identification 5", "device identification", Text, "";
    36 => DEVICE_ID_6, "device_id_6", "device identification 6", "device identification", Text, "";
    37 => DEVICE_ID_7, "device_id_7", "device identification 7", "device identification", Text, "";
    38 => DEVICE_ID_8, "device_id_8", "device identification 8", "device identification", Text, "";
    39 => DEVICE_ID_9, "device_id_9", "device identification 9", "device identification", Text, "";
}

/// Every status value whose meaning is known (COMPAX-M / -S user guide and its fieldbus interface
/// description); the others of S1..S40 can be read as text. Found by name or number like every family's
/// table.
pub static STATUS: Table<StatusDetail> = Table::new("status value", STATUS_ENTRIES);

/// Marks a status value without a row in [`STATUS`].
const NO_INFO: u8 = u8::MAX;

/// For each number 0..=40, the index of its row in [`STATUS`] (or [`NO_INFO`]): reading a reply needs the
/// row's kind on the hot path, where a search through the table would cost more than the parse.
const STATUS_INDEX: [u8; StatusId::MAX as usize + 1] = {
    let mut index = [NO_INFO; StatusId::MAX as usize + 1];
    let mut i = 0;
    while i < STATUS_ENTRIES.len() {
        index[STATUS_ENTRIES[i].id as usize] = i as u8;
        i += 1;
    }
    index
};

impl StatusId {
    /// The highest status value number.
    pub const MAX: u8 = 40;

    /// A drive's main status values, what `status` reads when it is given none: S1 position, S2 target,
    /// S3 contour error, the status bits S16 and S17, the error history S18.
    pub const OVERVIEW: [StatusId; 6] = [
        StatusId::ACTUAL_POSITION,
        StatusId::TARGET_POSITION,
        StatusId::CONTOUR_ERROR,
        StatusId::STATUS_BITS_1,
        StatusId::STATUS_BITS_2,
        StatusId::ERROR_HISTORY,
    ];

    /// S1..=S40.
    pub fn new(n: u8) -> Result<Self, ModelError> {
        if (1..=Self::MAX).contains(&n) {
            Ok(StatusId(n))
        } else {
            Err(ModelError::Range { what: "status value", value: format!("S{n}"), range: "S1..=S40" })
        }
    }

    /// The number.
    pub fn get(self) -> u8 {
        self.0
    }

    /// Its row of [`STATUS`], if its meaning is known.
    #[inline]
    pub fn info(self) -> Option<&'static Entry<StatusDetail>> {
        match STATUS_INDEX.get(usize::from(self.0)) {
            Some(&i) if i != NO_INFO => STATUS_ENTRIES.get(usize::from(i)),
            _ => None,
        }
    }

    /// How to read it (text when unknown).
    #[inline]
    pub fn kind(self) -> StatusKind {
        self.info().map_or(StatusKind::Text, |i| i.kind.kind)
    }

    /// What it is, if known.
    pub fn description(self) -> Option<&'static str> {
        self.info().map(|i| i.kind.description)
    }

    /// Parses `S1`, `s16`, `S016`, or a name of [`STATUS`] (`actual_position`).
    pub fn parse(text: &str) -> Result<Self, ModelError> {
        let t = text.trim();
        if let Some(e) = STATUS.by_name(t) {
            return StatusId::new(e.id as u8);
        }
        let digits = t.strip_prefix('S').or_else(|| t.strip_prefix('s')).unwrap_or(t);
        digits
            .parse::<u8>()
            .map_err(|_| unknown_name("a status value", t, &STATUS, "give S1..S40 or a name such as actual_position"))
            .and_then(StatusId::new)
    }
}

impl fmt::Display for StatusId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "S{}", self.0)
    }
}
