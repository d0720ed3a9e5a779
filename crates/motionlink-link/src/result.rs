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
