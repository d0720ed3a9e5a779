//! `motionlink probe powercube`.

use super::*;
use crate::common::Sim;

/// Requests of ActFPosStateDio (GetExtended 0x0A, parameter 0x62) in a capture.
fn pos_state_dio_reads(capture: &str) -> usize {
    capture.lines().filter(|l| l.contains(" -> ") && l.contains(" 0A 62 ")).count()
}

/// The last JSON object a command printed (a move prints its progress first).
fn last_json(o: &Output) -> serde_json::Value {
    let text = stdout(o);
    let last = text.lines().last().unwrap_or_else(|| panic!("no output: {o:?}"));
    serde_json::from_str(last).unwrap_or_else(|e| panic!("not JSON ({e}): {o:?}"))
}

#[test]
fn probe_powercube_finds_each_module_and_save_makes_its_probe_disappear() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--modules", "1,3", "--variant", "no-pos-state-dio"]);
    let p = sim.address.as_str();
    let dir = config_dir("probe-powercube");

    let out = run_in(&dir, &["probe", "powercube", "--port", p], &[]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.contains("module 1: rotary version") && text.contains("module 3: "), "{text}");
    assert!(text.contains("unsupported  pos_state_dio @3"), "{text}");

    let capture = dir.join("move.capture");
    let cap = capture.to_str().unwrap();
    let moved = |to: &str| {
        let args = ["powercube", "--port", p, "--module", "3", "--no-watchdog", "--json", "--capture", cap, "move", to];
        run_in(&dir, &args, &[])
    };
    let out = moved("0.1");
    assert!(out.status.success(), "{out:?}");
    assert_eq!(last_json(&out)["profile"], serde_json::Value::Null);
    assert!(
        pos_state_dio_reads(&std::fs::read_to_string(&capture).unwrap()) >= 1,
        "probed (a read retried after silence)"
    );

    let out = run_in(&dir, &["probe", "powercube", "--port", p, "--json", "--save"], &[]);
    let v = one_json(&out);
    super::assert_report_shape(&v, "powercube", p);
    assert_eq!(v["devices"].as_array().unwrap().len(), 2);
    assert_eq!(result_of(&v, "pos_state_dio", Some(1)), "unsupported");
    assert_eq!(result_of(&v, "baud", None), "skipped");
    assert_eq!(v["saved"].as_array().unwrap().len(), 2);
    let saved3 = v["saved"][1].as_str().unwrap();
    assert!(saved3.contains(&format!("#powercube:{p}:3:")), "{saved3}");

    let out = moved("0.2");
    assert!(out.status.success(), "{out:?}");
    assert_eq!(last_json(&out)["profile"].as_str(), Some(saved3));
    assert_eq!(pos_state_dio_reads(&std::fs::read_to_string(&capture).unwrap()), 0, "known from the profile");
    let _ = std::fs::remove_dir_all(&dir);
}
