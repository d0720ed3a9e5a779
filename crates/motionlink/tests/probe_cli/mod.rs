//! `motionlink probe <family>` end to end: the built binary against `motionlink sim <family> [--variant X]`
//! over TCP (and a pty for the latency timer): the text and `--json` shapes, `--save` and the profile that a
//! later command names and that makes the probe exchanges disappear, a profile of another device ignored with
//! a notice, and the latency timer read from a fake sysfs.

mod compax;
mod powercube;
mod scu;

use std::process::Output;

use crate::common;

/// `motionlink <args>` with the configuration directory at `dir` (profiles.toml lies there).
fn run_in(dir: &std::path::Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let config = dir.join("devices.toml");
    let mut all = vec![("MOTIONLINK_CONFIG", config.to_str().unwrap())];
    all.extend_from_slice(env);
    common::run_with(args, &all, "")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The one JSON object of a command's stdout.
fn one_json(o: &Output) -> serde_json::Value {
    let text = stdout(o);
    assert_eq!(text.lines().count(), 1, "one line: {o:?}");
    serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {o:?}"))
}

/// A fresh configuration directory for one test.
fn config_dir(name: &str) -> std::path::PathBuf {
    let dir = common::temp_path(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The report's shape, the same for every family: `family`, `port`, `devices`, `link`, `checks` whose
/// results are one of the four words.
fn assert_report_shape(v: &serde_json::Value, family: &str, port: &str) {
    assert_eq!((v["family"].as_str(), v["port"].as_str()), (Some(family), Some(port)), "{v}");
    assert!(v["devices"].is_array() && v["link"].is_object(), "{v}");
    for key in ["kind", "baud", "exchanges", "errors", "round_trip_ms", "latency_timer"] {
        assert!(v["link"].get(key).is_some(), "link.{key}: {v}");
    }
    let checks = v["checks"].as_array().unwrap();
    assert!(!checks.is_empty());
    for c in checks {
        assert!(c["name"].is_string() && c["detail"].is_string(), "{c}");
        let r = c["result"].as_str().unwrap();
        assert!(["ok", "unsupported", "failed", "skipped"].contains(&r), "{c}");
    }
}

/// The result of check `name` (of the device at `address`).
fn result_of<'a>(v: &'a serde_json::Value, name: &str, address: Option<u64>) -> &'a str {
    v["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name && c["address"].as_u64() == address)
        .unwrap_or_else(|| panic!("no check {name}: {v}"))["result"]
        .as_str()
        .unwrap()
}
