//! devices.toml gives a named device every option of its family's commands (issue 20): the file's options
//! apply, the command line wins, an unknown key or a bad value is named with the file and the device.

use std::process::Output;

use crate::common;

const DEVICES: &str = r#"
[device.lift]
family = "scu"
port = "sim"
functions = "tlt"
tolerance = 3
timeout-ms = 1500          # spelled as the option is, too

[device.arm]
family = "powercube"
port = "sim"
module = 3
timeout_ms = 300
modules = [1, 2, 3]        # the console's option; `motionlink powercube` has none and leaves it

[device.axis]
family = "compax"
port = "sim"
drive = 4
short = true
max_pos = 500              # `move --max-pos` and the console's
timeout_s = 30             # `move --timeout-s`, which `--no-wait` excludes

[device.typo]
family = "scu"
port = "sim"
functoins = "tlt"

[device.listen]
family = "scu"
port = "sim"
listen = "0.0.0.0:0"

[device.target]
family = "compax"
port = "sim"
abs = 100

[device.steep]
family = "scu"
port = "sim"
tolerance = 500

[device.list]
family = "compax"
port = "sim"
drive = [1, 2]
"#;

/// Runs `motionlink <args>` with DEVICES as the configuration file.
fn with_devices(args: &[&str]) -> Output {
    let path = common::temp_path(&format!("devices-{}.toml", args.join("-").replace(['/', ' '], "_")));
    std::fs::write(&path, DEVICES).unwrap();
    let out = common::run_with(args, &[("MOTIONLINK_CONFIG", path.to_str().unwrap())], "");
    let _ = std::fs::remove_file(&path);
    out
}

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{o:?}");
    let text = String::from_utf8_lossy(&o.stdout);
    serde_json::from_str(text.lines().last().expect("a line")).expect("one JSON object")
}

fn usage_error(o: &Output) -> String {
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_devices_options_apply_and_the_command_line_wins() {
    // functions = "tlt": F1 drives both columns of the (in-process) TLT unit.
    let v = json(&with_devices(&["--json", "scu", "--device", "lift", "move", "1", "60"]));
    let moved: Vec<i64> = v["actuators"].as_array().unwrap().iter().map(|a| a["actuator"].as_i64().unwrap()).collect();
    assert_eq!(moved, vec![1, 2], "{v}");
    // --functions on the command line (after the action too) wins over the file's.
    let v = json(&with_devices(&["--json", "scu", "--device", "lift", "move", "1", "50", "--functions", "scp11"]));
    let moved: Vec<i64> = v["actuators"].as_array().unwrap().iter().map(|a| a["actuator"].as_i64().unwrap()).collect();
    assert_eq!(moved, vec![1], "{v}");
    // module = 3 (and the emulated bus has it); --module 1 wins.
    let v = json(&with_devices(&["--json", "powercube", "--device", "arm", "info"]));
    assert_eq!(v["module"].as_i64(), Some(3), "{v}");
    let v = json(&with_devices(&["--json", "powercube", "info", "--device", "arm", "--module", "1"]));
    assert_eq!(v["module"].as_i64(), Some(1), "{v}");
    // drive = 4, and the switch short = true: the short command names go on the line.
    let o = with_devices(&["compax", "--device", "axis", "move", "--abs", "5", "-v"]);
    assert!(o.status.success(), "{o:?}");
    let trace = String::from_utf8_lossy(&o.stderr);
    assert!(trace.contains("\"4PA 5"), "the short POSA to drive 4: {trace}");
    // An action's option: max_pos refuses a move beyond it before anything moves (and --max-pos wins).
    let o = with_devices(&["compax", "--device", "axis", "move", "--abs", "600"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("500"), "{o:?}");
    let o = with_devices(&["compax", "--device", "axis", "move", "--abs", "600", "--max-pos", "700"]);
    assert!(o.status.success(), "{o:?}");
    // timeout_s is left out where --no-wait excludes it.
    let o = with_devices(&["compax", "--device", "axis", "move", "--abs", "5", "--no-wait"]);
    assert!(o.status.success(), "{o:?}");
    // --port wins over the device's port.
    let o = with_devices(&["scu", "--device", "lift", "--port", "tcp://127.0.0.1:1", "info"]);
    assert_eq!(o.status.code(), Some(3), "{o:?}");
}

#[test]
fn a_wrong_key_or_value_is_named_with_the_file_and_the_device() {
    let e = usage_error(&with_devices(&["scu", "--device", "typo", "info"]));
    assert!(e.contains("[device.typo]: unknown key `functoins` (did you mean functions?)"), "{e}");
    assert!(e.contains("the scu options are: ") && e.contains("speed_mode") && e.contains("tolerance"), "{e}");
    assert!(e.contains(" speed,") && e.contains("sim_preset"), "actions' and the console's options: {e}");
    assert!(e.contains("devices-"), "the file is named: {e}");
    // The console's serving address is not a device's, nor a move's target.
    let e = usage_error(&with_devices(&["scu", "--device", "listen", "info"]));
    assert!(e.contains("unknown key `listen` (give it on the command line)"), "{e}");
    let e = usage_error(&with_devices(&["compax", "--device", "target", "status"]));
    assert!(e.contains("unknown key `abs` (give it on the command line)"), "{e}");
    // A value the option refuses: refused as the file's, with clap's reason.
    let e = usage_error(&with_devices(&["scu", "--device", "steep", "info"]));
    assert!(e.contains("[device.steep]:") && e.contains("--tolerance") && e.contains("from 0 to 100 counts"), "{e}");
    let e = usage_error(&with_devices(&["compax", "--device", "list", "status"]));
    assert!(e.contains("[device.list]: `drive` takes one value, not a list"), "{e}");
    // The family check, as before.
    let e = usage_error(&with_devices(&["compax", "--device", "lift", "status"]));
    assert!(e.contains("is a scu device"), "{e}");
    // --json: the same error as one JSON object.
    let o = with_devices(&["--json", "scu", "--device", "typo", "info"]);
    let e = common::json_error(&o);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("usage"), Some(2)), "{e}");
}
