//! `--port sim` is the unit the command names (issue 20): the SCU's functions (`--functions`,
//! `--sim-preset`), the PowerCube module (`--module`), the COMPAX drive (`--drive`); and a second client of
//! `motionlink sim` gets one plain line and exit code 3 in every family.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Output;
use std::time::Duration;

use crate::common::{self, Sim};

fn run(args: &[&str]) -> Output {
    common::run_with(args, &[], "")
}

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{o:?}");
    let text = String::from_utf8_lossy(&o.stdout);
    serde_json::from_str(text.lines().last().expect("a line")).expect("one JSON object")
}

/// The actuators a move reached, and where: `[(actuator, reached_counts)]`.
fn reached(v: &serde_json::Value) -> Vec<(i64, i64)> {
    let list = v["actuators"].as_array().unwrap_or_else(|| panic!("no actuators in {v}"));
    list.iter().map(|a| (a["actuator"].as_i64().unwrap(), a["reached_counts"].as_i64().unwrap())).collect()
}

#[test]
fn scu_port_sim_takes_the_function_map_of_the_command() {
    // TLT: F1 drives both columns (the in-process unit used to be SCP11: A2 stayed at 0).
    let v = json(&run(&["--json", "scu", "--port", "sim", "--functions", "tlt", "move", "1", "60"]));
    assert_eq!((v["function"].as_i64(), reached(&v)), (Some(1), vec![(1, 60), (2, 60)]), "{v}");
    // One function given as F1=1,2 on the default unit.
    let v = json(&run(&["--json", "scu", "--port", "sim", "--functions", "F1=1,2", "move", "1", "50"]));
    assert_eq!(reached(&v), vec![(1, 50), (2, 50)], "{v}");
    // --sim-preset: the liftkit unit, where F8 drives both and F1 only A1.
    let args = ["--json", "scu", "--port", "sim", "--sim-preset", "liftkit", "--functions", "liftkit"];
    let v = json(&run(&[&args[..], &["move", "1", "40", "--function", "8"]].concat()));
    assert_eq!((v["function"].as_i64(), reached(&v)), (Some(8), vec![(1, 40), (2, 40)]), "{v}");
    let v = json(&run(&[&args[..], &["move", "1", "30"]].concat()));
    assert_eq!(reached(&v), vec![(1, 30)], "F1 of the liftkit drives A1 alone: {v}");
    // A unit with a third actuator, named by a function.
    let v =
        json(&run(&["--json", "scu", "--port", "sim", "--functions", "F7=3", "move", "3", "20", "--function", "7"]));
    assert_eq!(reached(&v), vec![(3, 20)], "{v}");
}

#[test]
fn scu_sim_preset_is_checked_and_only_for_the_emulator() {
    let o = run(&["scu", "--port", "sim", "--sim-preset", "lift", "info"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("liftkit"), "{o:?}");
    let o = run(&["scu", "--port", "tcp://127.0.0.1:1", "--sim-preset", "tlt", "info"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("only for --port sim"), "{o:?}");
}

#[test]
fn powercube_and_compax_port_sim_have_the_unit_the_command_names() {
    let v = json(&run(&["--json", "powercube", "--port", "sim", "--module", "5", "info"]));
    assert_eq!((v["module"].as_i64(), v["kind"].as_str()), (Some(5), Some("rotary")), "{v}");
    let o = run(&["--json", "powercube", "--port", "sim", "--module", "17", "scan"]);
    let found: Vec<i64> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["module"].as_i64().unwrap())
        .collect();
    assert_eq!(found, vec![17], "{o:?}");
    let v = json(&run(&["--json", "powercube", "--port", "sim", "--module", "9", "move", "0.2", "--vel", "1"]));
    assert_eq!(v["module"].as_i64(), Some(9), "{v}");
    let v = json(&run(&["--json", "compax", "--port", "sim", "--drive", "7", "status", "S1"]));
    assert_eq!(v["drive"].as_i64(), Some(7), "{v}");
}

/// A client that holds the emulator's one connection (served: the emulator answered it).
fn first_client(sim: &Sim, hello: &[u8]) -> TcpStream {
    let tcp = sim.address.strip_prefix("slcan://").unwrap_or(&sim.address);
    let mut s = TcpStream::connect(tcp.strip_prefix("tcp://").unwrap()).unwrap();
    s.write_all(hello).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut buf = [0u8; 1];
    s.read_exact(&mut buf).expect("the first client is served");
    s
}

#[test]
fn a_second_client_is_told_the_port_is_busy_in_one_line_with_exit_code_3() {
    // Each family with a request of its own that the emulator answers, and a command that reads.
    let cases: [(&str, &[u8], &[&str]); 3] = [
        ("scu", &[0x52, 0x4F, 0x00, 0x5C, 0x2D], &["info"]),
        // PowerCube GetExtended DefCubeVersion of module 1.
        ("powercube", &[0x02, 0x04, 0x22, 0x0A, 0x1D, 0x4D, 0x03], &["info"]),
        ("compax", b"1S1\r", &["status", "S1"]),
    ];
    for (family, hello, action) in cases {
        let sim = Sim::tcp(family);
        let _first = first_client(&sim, hello);
        let port = sim.address.as_str();
        let o = run(&[&[family, "--port", port][..], action].concat());
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{family}: {o:?}");
        assert_eq!(stderr, format!("motionlink: {port} is busy: another client is connected\n"), "{family}");
        assert!(o.stdout.is_empty(), "{family}: {o:?}");
        let o = run(&[&["--json", family, "--port", port][..], action].concat());
        let e = common::json_error(&o);
        assert_eq!(String::from_utf8_lossy(&o.stderr).lines().count(), 1, "{family}: one line: {o:?}");
        assert_eq!((e["exit_code"].as_i64(), e["kind"].as_str()), (Some(3), Some("io")), "{family}: {e}");
        assert_eq!(e["message"], format!("{port} is busy: another client is connected"), "{family}");
    }
}

#[test]
fn an_slcan_adapter_behind_a_busy_emulator_is_told_busy_too() {
    let sim = Sim::start("powercube", &["--slcan", "--tcp", "127.0.0.1:0"]);
    let _first = first_client(&sim, b"V\r");
    // `motionlink sim` names the port to give: the adapter's URL.
    assert!(sim.address.starts_with("slcan://tcp://"), "{}", sim.address);
    let o = run(&["powercube", "--port", &sim.address, "info"]);
    assert_eq!(o.status.code(), Some(3), "{o:?}");
    // The TCP port behind the adapter is what is busy.
    let said = String::from_utf8_lossy(&o.stderr);
    let tcp = sim.address.strip_prefix("slcan://").unwrap();
    assert_eq!(said, format!("motionlink: {tcp} is busy: another client is connected\n"), "{o:?}");
}
