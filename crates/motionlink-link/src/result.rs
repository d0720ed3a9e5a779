//! A family command's result as one JSON object, the same from every front end (the command line's
//! `--json`, the gateway's replies): what it is about first (`family`, `port`, then the keys the front end
//! adds: the command line's `profile`, the unit the command names: `module`, `drive`), then the report's own
//! fields as it serialises (a report that is no object goes under `result`).
//!
//! ```
//! use motionlink_link::result::identified;
//! #[derive(serde::Serialize)]
//! struct Read { position_rad: f64 }
//! let v = identified("powercube", "/dev/ttyS0", &[("module", 1.into())], &Read { position_rad: 0.5 }).unwrap();
//! assert_eq!(v, serde_json::json!({"family": "powercube", "port": "/dev/ttyS0", "module": 1, "position_rad": 0.5}));
//! ```

use serde_json::{Map, Value};

/// `report` with what it is about: `family`, `port`, each `(key, value)` of `identity` in its order, then the
/// report's fields. An error only if the report cannot be serialised.
pub fn identified<T: serde::Serialize + ?Sized>(
    family: &str,
    port: &str,
    identity: &[(&str, Value)],
    report: &T,
) -> Result<Value, serde_json::Error> {
    let mut map = Map::new();
    map.insert("family".into(), family.into());
    map.insert("port".into(), port.into());
    for (k, v) in identity {
        map.insert((*k).into(), v.clone());
    }
    match serde_json::to_value(report)? {
        Value::Object(fields) => map.extend(fields),
        other => {
            map.insert("result".into(), other);
        }
    }
    Ok(Value::Object(map))
}

/// A value under a name known only at run time (`"position_rad": 0.5`, `{"log": "..."}`): one entry, of the
/// object it is flattened into or of an object of its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Named<T>(pub &'static str, pub T);

impl<T: serde::Serialize> serde::Serialize for Named<T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(1))?;
        map.serialize_entry(self.0, &self.1)?;
        map.end()
    }
}

/// One look at an axis as a live view shows it (the web console's rows, many times a second): its position
/// and speed under their names with units, its motor current where the device reports it, the names of the
/// flags set, the faults among them (by the family's rule), set bits without a name, and whether it moves.
/// Each family makes it from its own readings (`axis_look` in its results).
///
/// ```
/// use motionlink_link::result::{AxisLook, Named};
/// let look = AxisLook { speed: Some(Named("velocity_rad_per_s", 0.1)), ..AxisLook::at(Named("position_rad", 0.5)) };
/// assert_eq!(
///     serde_json::to_value(&look).unwrap(),
///     serde_json::json!({"position_rad": 0.5, "velocity_rad_per_s": 0.1, "flags": [], "faults": [], "moving": false})
/// );
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AxisLook {
    /// The position, under its name with its unit (`position_counts`, `position_rad`, ...).
    #[serde(flatten)]
    pub position: Named<f64>,
    /// The speed, under its name with its unit, where known.
    #[serde(flatten)]
    pub speed: Option<Named<f64>>,
    /// The motor current in A, where the device reports it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub current_amps: Option<f64>,
    /// The names of the flags set, as the family names them.
    pub flags: Vec<&'static str>,
    /// The flags among them (or the clear bits) that report a fault.
    pub faults: Vec<&'static str>,
    /// Set bits that have no name (left out when none).
    #[serde(skip_serializing_if = "is_zero")]
    pub unknown_bits: u64,
    /// True while it moves.
    pub moving: bool,
}

impl AxisLook {
    /// An axis at `position`, with nothing else known yet.
    pub fn at(position: Named<f64>) -> AxisLook {
        AxisLook {
            position,
            speed: None,
            current_amps: None,
            flags: Vec::new(),
            faults: Vec::new(),
            unknown_bits: 0,
            moving: false,
        }
    }
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Fails at the first key an object of the JSON text `json` gives twice, with its path from the top
/// (`key "args.position" given twice`), where reading the text into a map (`serde_json::Value`) would keep
/// the last value silently. A request of a page or of the gateway is refused so, never half-read.
///
/// ```
/// use motionlink_link::result::each_key_once;
/// assert!(each_key_once(br#"{"op": "move", "args": {"position": 1, "speed": [1, 2]}}"#).is_ok());
/// let e = each_key_once(br#"{"args": {"position": 1, "position": 2}}"#).unwrap_err();
/// assert_eq!(e.to_string(), r#"key "args.position" given twice at line 1 column 35"#);
/// ```
pub fn each_key_once(json: &[u8]) -> Result<(), serde_json::Error> {
    serde::de::DeserializeSeed::deserialize(OnceEach(String::new()), &mut serde_json::Deserializer::from_slice(json))
}

/// The walk of [`each_key_once`] below the path it carries.
struct OnceEach(String);

impl<'de> serde::de::DeserializeSeed<'de> for OnceEach {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> serde::de::Visitor<'de> for OnceEach {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("JSON")
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = std::collections::HashSet::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = if self.0.is_empty() { key.clone() } else { format!("{}.{key}", self.0) };
            if !seen.insert(key) {
                return Err(serde::de::Error::custom(format!("key {path:?} given twice")));
            }
            map.next_value_seed(OnceEach(path))?;
        }
        Ok(())
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0;
        while seq.next_element_seed(OnceEach(format!("{}[{i}]", self.0)))?.is_some() {
            i += 1;
        }
        Ok(())
    }
    fn visit_str<E>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_bool<E>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E>(self) -> Result<(), E> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_that_is_no_object_goes_under_result_after_the_identity() {
        let v = identified("scu", "sim", &[("profile", "profiles.toml#x".into())], &[1, 2]).unwrap();
        assert_eq!(
            v,
            serde_json::json!({"family": "scu", "port": "sim", "profile": "profiles.toml#x", "result": [1, 2]})
        );
    }
}
