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
//! assert_eq!(TABLE.suggest("actual_positon_a1"), vec!["actual_position_a1"]);
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

impl<K: 'static> Table<K> {
    /// The names of the entries nearest to `text` (a misspelt name): the best one or two within
    /// [`nearest`]'s threshold, for a "did you mean" hint. Empty when none is near.
    pub fn suggest(&self, text: &str) -> Vec<&'static str> {
        nearest(text, self.entries.iter().map(|e| e.name))
    }
}

/// The edit distance between `a` and `b`, ignoring ASCII case: the fewest single-character insertions,
/// deletions, substitutions and transpositions of two adjacent characters that turn one into the other
/// (optimal string alignment, a restricted Damerau-Levenshtein distance): `stpo` is 1 from `stop`,
/// `remote_sped_f1` 1 from `remote_speed_f1`.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().map(|c| c.to_ascii_lowercase()).collect();
    let b: Vec<char> = b.chars().map(|c| c.to_ascii_lowercase()).collect();
    // Three rows of the distance matrix: two back (for transpositions), one back, and the current one.
    let mut before: Vec<usize> = vec![0; b.len() + 1];
    let mut previous: Vec<usize> = (0..=b.len()).collect();
    let mut current: Vec<usize> = vec![0; b.len() + 1];
    for i in 1..=a.len() {
        current[0] = i;
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut d = (previous[j] + 1).min(current[j - 1] + 1).min(previous[j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                d = d.min(before[j - 2] + 1);
            }
            current[j] = d;
        }
        std::mem::swap(&mut before, &mut previous);
        std::mem::swap(&mut previous, &mut current);
    }
    previous[b.len()]
}

/// The largest [`edit_distance`] at which a name still counts as meant by `text`: a third of its length,
/// at least 1 (so `gte` finds `get`, `stpo` finds `stop`, but `xyz` finds nothing among short names).
pub fn suggestion_threshold(text: &str) -> usize {
    (text.chars().count() / 3).max(1)
}

/// The Jaro similarity of `a` and `b`, ignoring ASCII case: 1 for the same text, 0 for nothing in common;
/// [`nearest`] uses it to choose between names at the same [`edit_distance`] (`ActPoss` is nearer to
/// `ActPos` than to `ActPos_`).
pub fn jaro_similarity(a: &str, b: &str) -> f64 {
    let a: Vec<char> = a.chars().map(|c| c.to_ascii_lowercase()).collect();
    let b: Vec<char> = b.chars().map(|c| c.to_ascii_lowercase()).collect();
    if a.is_empty() && b.is_empty() {
        return 1.0;
    }
    if a.is_empty() || b.is_empty() {
        return 0.0;
    }
    let window = (a.len().max(b.len()) / 2).saturating_sub(1);
    let mut b_used = vec![false; b.len()];
    let mut a_matched = Vec::new();
    for (i, ca) in a.iter().enumerate() {
        let from = i.saturating_sub(window);
        let to = (i + window + 1).min(b.len());
        if let Some(j) = (from..to).find(|&j| !b_used[j] && b[j] == *ca) {
            b_used[j] = true;
            a_matched.push(*ca);
        }
    }
    let m = a_matched.len();
    if m == 0 {
        return 0.0;
    }
    let b_matched = b.iter().zip(&b_used).filter(|(_, used)| **used).map(|(c, _)| *c);
    let transpositions = a_matched.iter().zip(b_matched).filter(|(x, y)| **x != *y).count() / 2;
    let m = m as f64;
    (m / a.len() as f64 + m / b.len() as f64 + (m - transpositions as f64) / m) / 3.0
}

/// The one or two `candidates` nearest to `text` within [`suggestion_threshold`]: the smallest
/// [`edit_distance`] (ignoring case), and among those the highest [`jaro_similarity`]; two only when two
/// are equally near (duplicates once, in the order given). Empty when none is that near, or when `text` is
/// empty.
///
/// ```
/// use motionlink_link::table::nearest;
/// assert_eq!(nearest("stpo", ["set", "stop", "state"]), vec!["stop"]);
/// assert_eq!(nearest("ActPoss", ["ActPos", "ActPos_", "ActVel"]), vec!["ActPos"]);
/// assert!(nearest("banana", ["set", "stop"]).is_empty());
/// ```
pub fn nearest<'a>(text: &str, candidates: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let text = text.trim();
    if text.is_empty() {
        return Vec::new();
    }
    let limit = suggestion_threshold(text);
    let mut best: Vec<&'a str> = Vec::new();
    let mut best_score = (usize::MAX, 0.0);
    for candidate in candidates {
        let d = edit_distance(text, candidate);
        if d > limit {
            continue;
        }
        let score = (d, jaro_similarity(text, candidate));
        let better = score.0 < best_score.0 || (score.0 == best_score.0 && score.1 > best_score.1 + 1e-9);
        let tied = score.0 == best_score.0 && (score.1 - best_score.1).abs() <= 1e-9;
        if better {
            best.clear();
            best_score = score;
        }
        if (better || tied) && best.len() < 2 && !best.iter().any(|b| b.eq_ignore_ascii_case(candidate)) {
            best.push(candidate);
        }
    }
    best
}

/// "did you mean X?" or "did you mean X or Y?" for the names [`nearest`] found; `None` for none.
pub fn did_you_mean(names: &[&str]) -> Option<String> {
    match names {
        [] => None,
        [one] => Some(format!("did you mean {one}?")),
        [first, rest @ ..] => Some(format!("did you mean {first} or {}?", rest.join(" or "))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_distance_counts_insertions_deletions_substitutions_and_swaps_ignoring_case() {
        assert_eq!(edit_distance("", ""), 0);
        assert_eq!(edit_distance("abc", ""), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("stop", "STOP"), 0);
        assert_eq!(edit_distance("stpo", "stop"), 1, "a swap of two neighbours is one edit");
        assert_eq!(edit_distance("remote_sped_f1", "remote_speed_f1"), 1);
        assert_eq!(edit_distance("ActPoss", "ActPos"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(
            edit_distance("remote_sped_f1", "actual_position_a1"),
            edit_distance("actual_position_a1", "remote_sped_f1")
        );
        assert!(edit_distance("remote_sped_f1", "actual_position_a1") > 10);
        assert_eq!(edit_distance("ca", "abc"), 3, "optimal string alignment: no edit of a swapped pair");
    }

    #[test]
    fn the_jaro_similarity_is_one_for_the_same_text_and_breaks_ties_of_the_distance() {
        assert_eq!(jaro_similarity("ActPos", "actpos"), 1.0);
        assert_eq!(jaro_similarity("abc", "xyz"), 0.0);
        assert_eq!(jaro_similarity("", ""), 1.0);
        assert!((jaro_similarity("martha", "marhta") - 0.944).abs() < 0.001, "the textbook example");
        assert!(jaro_similarity("ActPoss", "ActPos") > jaro_similarity("ActPoss", "ActPos_"));
    }

    #[test]
    fn the_nearest_names_are_the_best_one_or_two_within_a_third_of_the_length() {
        let names = ["remote_speed_f1", "remote_speed_f2", "remote_speed_f10", "actual_position_a1"];
        assert_eq!(nearest("remote_sped_f1", names), vec!["remote_speed_f1"]);
        assert_eq!(nearest("REMOTE_SPEED_F1", names), vec!["remote_speed_f1"]);
        assert_eq!(nearest("remote_speed_f", names), vec!["remote_speed_f1", "remote_speed_f2"], "a tie: two");
        assert!(nearest("position", names).is_empty(), "too far from every name");
        assert!(nearest("", names).is_empty());
        assert_eq!(nearest("stpo", ["set", "stop"]), vec!["stop"], "set is three edits away");
        assert_eq!(nearest("gte", ["get", "set"]), vec!["get"]);
        assert_eq!(nearest("ActPoss", ["ActPos_", "ActPos"]), vec!["ActPos"], "the same distance, nearer by Jaro");
        assert!(nearest("xyz", ["get", "set"]).is_empty());
        assert_eq!(suggestion_threshold("ab"), 1);
        assert_eq!(suggestion_threshold("remote_sped_f1"), 4);
    }

    #[test]
    fn a_table_suggests_its_own_names_and_the_hint_reads_as_a_question() {
        static ENTRIES: &[Entry<()>] = &[
            Entry { id: 1, name: "ActPos", title: "", unit: "rad", access: Access::Read, kind: () },
            Entry { id: 2, name: "ActVel", title: "", unit: "rad/s", access: Access::Read, kind: () },
            Entry { id: 3, name: "MaxPos", title: "", unit: "rad", access: Access::ReadWrite, kind: () },
        ];
        let table = Table::new("parameter", ENTRIES);
        assert_eq!(table.suggest("ActPoss"), vec!["ActPos"]);
        assert_eq!(table.suggest("actvle"), vec!["ActVel"]);
        assert!(table.suggest("Temperature").is_empty());
        assert_eq!(did_you_mean(&["ActPos"]).as_deref(), Some("did you mean ActPos?"));
        assert_eq!(did_you_mean(&["a", "b"]).as_deref(), Some("did you mean a or b?"));
        assert_eq!(did_you_mean(&[]), None);
    }
}
