//! The one parameter-table mechanism of every family: each family's table of readable and writable values
//! (the SCU data list, the PowerCube parameters, the COMPAX parameters and status values) is a static slice
//! of [`Entry`], found by name or number the same way everywhere ([`Table`]), with family-specific details
//! (wire type, range) in the entry's `kind`.
//!
//! ```
//! use motionlink_link::table::{Access, Entry, Table};
//! static ENTRIES: &[Entry<&str>] = &[
//!     Entry { id: 0x11, name: "actual_position_a1", title: "Actual_Position Actuator 1", unit: "counts",
//!             access: Access::Read, kind: "i32" },
//! ];
//! static TABLE: Table<&str> = Table::new("data list", ENTRIES);
//! assert_eq!(TABLE.by_name("Actual_Position_A1").map(|e| e.id), Some(0x11));
//! assert_eq!(TABLE.by_id(0x11).map(|e| e.unit), Some("counts"));
//! assert!(TABLE.lookup("0x0011").is_some());
//! ```

use std::fmt;

/// Who may read and write an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only.
    Read,
    /// Write only (a command value that cannot be read back).
    Write,
    /// Read and write.
    ReadWrite,
}

impl Access {
    /// True if the entry can be read (and so a write can be read back).
    pub fn readable(self) -> bool {
        matches!(self, Access::Read | Access::ReadWrite)
    }

    /// True if the entry can be written.
    pub fn writable(self) -> bool {
        matches!(self, Access::Write | Access::ReadWrite)
    }

    /// `r`, `w` or `rw`.
    pub fn short(self) -> &'static str {
        match self {
            Access::Read => "r",
            Access::Write => "w",
            Access::ReadWrite => "rw",
        }
    }
}

impl fmt::Display for Access {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.short())
    }
}

/// One entry of a family's table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry<K: 'static> {
    /// The number on the wire: a data index, a ParameterID, a parameter number.
    pub id: u32,
    /// The name on the command line, in JSON and in Python (the manual's name where it is one word).
    pub name: &'static str,
    /// The manual's name or description.
    pub title: &'static str,
    /// The unit of the value as shown ("" when none).
    pub unit: &'static str,
    /// Who may read and write it.
    pub access: Access,
    /// What the family needs besides: the wire type, the range, the class.
    pub kind: K,
}

/// A family's table, searchable by name and number.
#[derive(Debug)]
pub struct Table<K: 'static> {
    /// What the table is called in messages ("data list", "parameter").
    pub what: &'static str,
    /// Every entry.
    pub entries: &'static [Entry<K>],
}

impl<K: 'static> Table<K> {
    /// A table of `entries`, called `what` in messages.
    pub const fn new(what: &'static str, entries: &'static [Entry<K>]) -> Self {
        Table { what, entries }
    }

    /// The entry with this name, ignoring case.
    pub fn by_name(&self, name: &str) -> Option<&'static Entry<K>> {
        self.entries.iter().find(|e| e.name.eq_ignore_ascii_case(name))
    }

    /// The entry with this number.
    pub fn by_id(&self, id: u32) -> Option<&'static Entry<K>> {
        self.entries.iter().find(|e| e.id == id)
    }

    /// The entry named `text`, or numbered by it (decimal, or hex with `0x`).
    pub fn lookup(&self, text: &str) -> Option<&'static Entry<K>> {
        let t = text.trim();
        self.by_name(t).or_else(|| parse_number(t).and_then(|id| self.by_id(id)))
    }

    /// Every entry.
    pub fn iter(&self) -> impl Iterator<Item = &'static Entry<K>> {
        self.entries.iter()
    }
}

/// Parses `17`, `0x11`, `0X11`.
pub fn parse_number(text: &str) -> Option<u32> {
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}
