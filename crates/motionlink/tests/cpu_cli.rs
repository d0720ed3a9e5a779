//! What a long move costs the host: the command waits for the motion at a set poll rate, not as fast as the
//! line answers, so its CPU stays small (the goal is under 2 % of a core; the bound here leaves room for a
//! loaded test machine).

use std::process::{Command, Stdio};
use std::time::Instant;

use crate::common::{cpu_seconds_of, Sim, BIN};

fn cpu_share_of_a_move(family: &str, port: &str, args: &[&str], at_least_s: f64) -> f64 {
    let _light = crate::light();
    let t0 = Instant::now();
    let child = Command::new(BIN)
        .args([family, "--port", port])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let (code, cpu) = cpu_seconds_of(child);
    let wall = t0.elapsed().as_secs_f64();
    assert_eq!(code, 0, "{family} {args:?}");
    assert!(wall >= at_least_s, "the move took {wall} s");
    let share = cpu / wall;
    eprintln!("CPU of `{family} {}` over {wall:.2} s: {cpu:.3} s = {:.2} %", args.join(" "), share * 100.0);
    share
}

#[cfg(target_os = "linux")]
#[test]
fn a_long_scu_move_costs_the_command_little_cpu() {
    let sim = Sim::tcp("scu");
    // 200 counts at full speed: about 2 s, watched through the keepalive RC every 50 ms.
    let share = cpu_share_of_a_move("scu", &sim.address, &["move", "1", "200", "--speed", "100"], 1.8);
    assert!(share < 0.05, "{:.2} % of a core", share * 100.0);
}

#[cfg(target_os = "linux")]
#[test]
fn a_long_powercube_move_costs_the_command_little_cpu() {
    let sim = Sim::tcp("powercube");
    // 1.0 rad along the emulated module's ramp: about 2.4 s, polled at --poll-ms, the watchdog refreshed every
    // 20 ms.
    let share = cpu_share_of_a_move("powercube", &sim.address, &["move", "1.0"], 1.8);
    assert!(share < 0.05, "{:.2} % of a core", share * 100.0);
}

#[cfg(target_os = "linux")]
#[test]
fn a_long_compax_move_costs_the_command_little_cpu() {
    let sim = Sim::tcp("compax");
    // 200 units at 100 units/s: 2 s of waiting, polled every 50 ms.
    let share = cpu_share_of_a_move("compax", &sim.address, &["move", "--abs", "200"], 1.8);
    assert!(share < 0.05, "{:.2} % of a core", share * 100.0);
}
