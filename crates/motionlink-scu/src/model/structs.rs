//! The structures of the data list: stored positions, cyclic object definitions, error counters.

use super::{item, DataIndex};

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
