//! The actions of `motionlink scu`: each calls the library and prints what it returns.

use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_scu::model::{
    status1, Actuator, DataEntry, DataEntryExt, DataIndex, ErrorCode, FlagSet, Flags, Function, Item, MotionFunction,
    Speed,
};
use motionlink_scu::session::{MoveProgress, MoveReport, RunAction, RunProgress};
use motionlink_scu::value::Value;
use motionlink_scu::{Client, MoveOptions};
use serde_json::json;

use crate::common::{self, CliError, Row};

/// A library error as the command line reports it.
fn cl(e: motionlink_scu::Error) -> CliError {
    common::classified(&e)
}

fn value_rows(values: &[(&'static DataEntry, Value)]) -> Vec<Row> {
    values.iter().map(|(e, v)| (format!("{} ({})", e.name, e.index()), v.to_string())).collect()
}

fn values_json(values: &[(&'static DataEntry, Value)]) -> serde_json::Value {
    let mut map = serde_json::Map::new();
    for (e, v) in values {
        map.insert(e.name.to_string(), v.to_json());
    }
    serde_json::Value::Object(map)
}

/// `get`: an entry or a group.
pub(super) fn get(client: &Client, it: Item, json: bool, out: &mut dyn Write) -> Result<(), CliError> {
    let values = client.get(it.index()).map_err(cl)?;
    if json {
        let (value, unit) = match it {
            Item::Entry(e) => (values[0].1.to_json(), e.kind.unit()),
            Item::Group(_) => (values_json(&values), ""),
        };
        common::print_json(
            out,
            &json!({"index": it.index().to_string(), "name": it.name(), "value": value, "unit": unit}),
        )
    } else {
        common::print_table(out, &value_rows(&values))
    }
}

/// `set`: written and read back by the library.
pub(super) fn set(client: &Client, it: Item, value: &str, json: bool, out: &mut dyn Write) -> Result<(), CliError> {
    let Item::Entry(e) = it else {
        return Err(CliError::usage(format!("{} is a group; set its entries one by one", it.name())));
    };
    let v = Value::parse(e.kind, value).map_err(|err| CliError::usage(format!("{}: {err}", e.name)))?;
    client.set(e.index(), &v).map_err(cl)?;
    if json {
        common::print_json(
            out,
            &json!({"index": e.index().to_string(), "name": e.name, "value": v.to_json(), "read_back": true}),
        )
    } else {
        common::print_table(out, &[(format!("{} ({})", e.name, e.index()), format!("{v} (written, read back)"))])
    }
}

/// `move`: the library's verified move, with a progress bar on a terminal.
#[allow(clippy::too_many_arguments)]
pub(super) fn move_to(
    client: &Client,
    a: Actuator,
    position: i32,
    speed: Speed,
    function: MotionFunction,
    json: bool,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let start = client.position(a).map_err(cl)?;
    let bar = common::progress_bar(u64::from(start.abs_diff(position)), format!("{a} -> {position}"));
    let progress = |p: &MoveProgress| bar.set_position(u64::from(p.position_counts.abs_diff(p.start_counts)));
    let options = MoveOptions { cancel: Some(interrupt), progress: Some(&progress), function: Some(function) };
    let result = client.move_to(a, position, speed, &options);
    bar.finish_and_clear();
    print_move_report(out, &result.map_err(cl)?, json)
}

pub(super) fn connected_actuators(client: &Client) -> Result<Vec<(Actuator, u8)>, CliError> {
    let raw = client.get_raw(DataIndex(0x0170)).map_err(cl)?;
    Ok(Actuator::all().zip(raw).filter(|(_, s)| s & status1::AVAILABLE != 0).collect())
}

fn status_text(s: u8) -> String {
    Value::Flags(Flags { set: FlagSet::ActuatorStatus1, bits: u32::from(s) }).to_string()
}

pub(super) fn info(client: &Client, json: bool, out: &mut dyn Write) -> Result<(), CliError> {
    let get = |i: u16| client.get_value(DataIndex(i)).map_err(cl);
    let firmware = get(0x0001)?;
    let configuration = get(0x0002)?;
    let mains = get(0x0100)?;
    let last_error = get(0x00D1)?;
    let actuators = connected_actuators(client)?;
    let positions = client.get(DataIndex(0x0010)).map_err(cl)?;
    let position = |a: Actuator| positions[usize::from(a.number() - 1)].1.clone();
    if json {
        let acts: Vec<_> = actuators
            .iter()
            .map(|(a, s)| {
                json!({"actuator": a.number(), "position": position(*a).to_json(), "status": s,
                       "moving": s & status1::MOTION != 0})
            })
            .collect();
        common::print_json(
            out,
            &json!({"port": client.port(), "firmware": firmware.to_json(), "configuration": configuration.to_json(),
                    "battery_mains": mains.to_json(), "last_error": last_error.to_json(), "actuators": acts}),
        )
    } else {
        let mut rows: Vec<Row> = vec![
            ("port".into(), client.port().to_string()),
            ("firmware".into(), firmware.to_string()),
            ("configuration".into(), configuration.to_string()),
            ("battery/mains".into(), mains.to_string()),
            ("last error".into(), last_error.to_string()),
        ];
        for (a, s) in &actuators {
            rows.push((format!("actuator {}", a.number()), format!("{}, {}", position(*a), status_text(*s))));
        }
        common::print_table(out, &rows)
    }
}

pub(super) fn errors(client: &Client, json: bool, out: &mut dyn Write) -> Result<(), CliError> {
    let history = client.error_history().map_err(cl)?;
    if json {
        let list: Vec<_> = history.iter().map(|c| Value::ErrorCode(*c).to_json()).collect();
        return common::print_json(out, &json!({"errors": list}));
    }
    let mut rows = Vec::new();
    for (i, code) in history.iter().enumerate() {
        let label = if i == 0 {
            "error code 1 (last recent)".to_string()
        } else {
            format!("error code {} (history {i})", i + 1)
        };
        rows.push((label, format!("0x{:08X}", code.0)));
        for b in code.bits() {
            rows.push((format!("  bit {}", b.number()), format!("{}; reaction: {}", b.cause(), b.reaction())));
        }
        if code.unknown_bits() != 0 {
            rows.push(("  undefined bits".into(), format!("0x{:08X}", code.unknown_bits())));
        }
    }
    common::print_table(out, &rows)
}

/// Waits `duration` on the client's clock, returning early on Ctrl-C.
fn pause(client: &Client, duration: Duration, interrupt: &CancelToken) {
    let clock = client.clock();
    let signal = clock.signal();
    let until = clock.now() + duration;
    while clock.now() < until && !interrupt.is_cancelled() {
        signal.wait_until(Some(until.min(clock.now() + Duration::from_millis(10))));
    }
}

pub(super) fn watch(
    client: &Client,
    json: bool,
    interval_ms: u64,
    count: Option<u64>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let clock = Arc::clone(client.clock());
    let actuators = connected_actuators(client)?;
    let mut n = 0u64;
    let started = clock.now();
    while !interrupt.is_cancelled() && count.is_none_or(|c| n < c) {
        let positions = client.get(DataIndex(0x0010)).map_err(cl)?;
        let status = client.get_raw(DataIndex(0x0170)).map_err(cl)?;
        let currents = client.get(DataIndex(0x00A0)).map_err(cl)?;
        let last_error = client.get_value(DataIndex(0x00D1)).map_err(cl)?;
        let t = (clock.now() - started).as_secs_f64();
        // One row per connected actuator, from the three group reads (a short reply is an error, not a panic).
        let mut rows = Vec::with_capacity(actuators.len());
        for (a, _) in &actuators {
            let i = usize::from(a.number() - 1);
            let short = |what: &str| CliError::transport(format!("the unit's {what} reply has no entry for {a}"));
            let position = &positions.get(i).ok_or_else(|| short("position (0x0010)"))?.1;
            let status = *status.get(i).ok_or_else(|| short("status (0x0170)"))?;
            let current = &currents.get(i).ok_or_else(|| short("current (0x00A0)"))?.1;
            rows.push((a, position, status, current));
        }
        if json {
            let acts: Vec<_> = rows
                .iter()
                .map(|(a, position, status, current)| {
                    json!({"actuator": a.number(), "position": position.to_json(), "status": status,
                           "moving": status & status1::MOTION != 0, "current_deci_amps": current.to_json()})
                })
                .collect();
            common::print_json(out, &json!({"t": t, "actuators": acts, "last_error": last_error.to_json()}))?;
        } else {
            let mut line = format!("{t:7.2} s");
            for (a, position, status, current) in &rows {
                let moving = if status & status1::MOTION != 0 { "moving" } else { "stopped" };
                line.push_str(&format!("  {a}: {position} {moving} {current}"));
            }
            if let Value::ErrorCode(c) = last_error {
                if c != ErrorCode::NONE {
                    line.push_str(&format!("  last error 0x{:08X}", c.0));
                }
            }
            writeln!(out, "{line}")?;
        }
        out.flush()?;
        n += 1;
        if count.is_none_or(|c| n < c) {
            pause(client, Duration::from_millis(interval_ms), interrupt);
        }
    }
    Ok(())
}

/// `run`: the library runs the function, watches it, stops it and confirms the stop; this prints.
pub(super) fn run(
    client: &Client,
    action: RunAction,
    limit: Option<Duration>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let function = match action {
        RunAction::Motion(m, _) => Function::Motion(m),
        RunAction::Switch(f) => f,
    };
    // The first progress comes right after the unit acknowledged the RE.
    let said = std::cell::Cell::new(false);
    let progress = |_: &RunProgress| {
        if !said.replace(true) {
            let _ = writeln!(std::io::stdout(), "{function} running; Ctrl-C stops it");
            let _ = std::io::stdout().flush();
        }
    };
    let (rest, interrupted) = match client.run(action, limit, &progress, Some(interrupt)) {
        Ok(report) => (report.rest, false),
        Err(motionlink_scu::Error::RunCancelled { rest, .. }) => (rest, true),
        Err(e) => return Err(cl(e)),
    };
    writeln!(out, "{function} stopped")?;
    let rows: Vec<Row> = rest.iter().map(|(a, p)| (a.to_string(), format!("{p} counts"))).collect();
    common::print_table(out, &rows)?;
    if interrupted {
        return Err(CliError::Interrupted(format!("interrupted; {function} stopped (the unit confirmed it)")));
    }
    Ok(())
}

/// Prints how a move ended: each actuator whose remote position it wrote, with its target and difference.
pub(super) fn print_move_report(out: &mut dyn Write, report: &MoveReport, json: bool) -> Result<(), CliError> {
    if json {
        let actuators: Vec<_> = report
            .actuators
            .iter()
            .map(|o| {
                json!({"actuator": o.actuator.number(), "target": o.target_counts, "position": o.position_counts,
                       "difference": o.difference_counts(), "moved": o.moved})
            })
            .collect();
        let target = report.actuators.iter().find(|o| o.actuator == report.actuator).map(|o| o.target_counts);
        return common::print_json(
            out,
            &json!({"actuator": report.actuator.number(), "function": report.function.number(),
                    "position": report.position_counts, "target": target,
                    "seconds": report.duration.as_secs_f64(), "actuators": actuators}),
        );
    }
    let mut rows: Vec<Row> = vec![("function".into(), report.function.to_string())];
    for o in &report.actuators {
        let text = if o.moved || o.actuator == report.actuator {
            format!("{} counts (target {}, difference {})", o.position_counts, o.target_counts, o.difference_counts())
        } else {
            format!("{} counts (did not move: not driven by {})", o.position_counts, report.function)
        };
        rows.push((o.actuator.to_string(), text));
    }
    rows.push(("time".into(), format!("{:.1} s", report.duration.as_secs_f64())));
    common::print_table(out, &rows)
}
