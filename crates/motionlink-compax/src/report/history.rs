//! The error history S18 decoded: `{"errors": [{"code": 92, "text": "E92", "meaning": "..."}]}`, newest first
//! (the key of the SCU's error history).

use serde::ser::{Serialize, SerializeMap, Serializer};

use crate::model::HistoryEntry;

/// S18 as read, entry by entry, newest first: each with its `code` (the number in S18), `text` (E92 for an
/// error, the number otherwise) and `meaning`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorHistory(pub [HistoryEntry; 8]);

/// One entry of [`ErrorHistory`].
struct Entry(HistoryEntry);

impl Serialize for Entry {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let (text, meaning) = match self.0 {
            HistoryEntry::Error(c) => (
                format!("E{:02}", c.0),
                c.meaning().unwrap_or("an error whose meaning is not documented in our sources"),
            ),
            HistoryEntry::Acknowledged => ("99".to_string(), "the error before was acknowledged"),
            HistoryEntry::PowerOn => ("98".to_string(), "power-on acknowledgement"),
        };
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("code", &self.0.number())?;
        map.serialize_entry("text", &text)?;
        map.serialize_entry("meaning", meaning)?;
        map.end()
    }
}

impl Serialize for ErrorHistory {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(1))?;
        map.serialize_entry("errors", &self.0.map(Entry))?;
        map.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ErrorCode;

    #[test]
    fn each_entry_has_its_code_text_and_meaning() {
        let mut h = [HistoryEntry::Acknowledged; 8];
        h[0] = HistoryEntry::Error(ErrorCode(92));
        h[1] = HistoryEntry::PowerOn;
        let v = serde_json::to_value(ErrorHistory(h)).unwrap();
        let e = v["errors"].as_array().unwrap();
        assert_eq!(e.len(), 8);
        assert_eq!((e[0]["code"].as_u64(), e[0]["text"].as_str()), (Some(92), Some("E92")));
        assert_eq!(e[0]["meaning"], ErrorCode(92).meaning().unwrap());
        assert_eq!(e[1], serde_json::json!({"code": 98, "text": "98", "meaning": "power-on acknowledgement"}));
        assert_eq!(e[2]["meaning"], "the error before was acknowledged");
    }
}
