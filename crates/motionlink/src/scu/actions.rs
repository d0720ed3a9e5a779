//! The actions of `motionlink scu`: each calls the library and prints what it returns.

use std::io::Write;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_scu::model::{
    Actuator, ActuatorStatus1, DataEntry, DataEntryExt, DataIndex, ErrorCode, Flags, Function, Item, Kind,
    MotionFunction, PositionCounts, Speed, SpeedMode,
};
use motionlink_scu::session::{MoveProgress, MoveReport, RunAction, RunProgress, Snapshot};
use motionlink_scu::value::Value;
use motionlink_scu::{Client, MoveOptions};
use serde_json::json;

use super::Report;
use crate::common::{self, CliError, Row};

/// How `watch` prints its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Format {
    /// One line of text per sample.
    Text,
    /// One JSON object per sample.
    Json,
    /// A CSV header, then one line per actuator and sample.
    Csv,
}

impl Format {
    /// JSON when `json`, else text.
    pub fn from_json(json: bool) -> Self {
        if json {
            Format::Json
        } else {
            Format::Text
        }
    }
}

/// A flag word as JSON (naming.md): `word`, `flags` (the manual's names), `unknown_bits` only when nonzero.
fn flag_word_json(f: &Flags) -> serde_json::Value {
    let known = f.set.bits().into_iter().fold(0u32, |m, b| m | (1 << b.bit));
    let mut v = json!({"word": f.bits, "flags": f.set_names().collect::<Vec<_>>()});
    if f.bits & !known != 0 {
        v["unknown_bits"] = json!(f.bits & !known);
    }
    v
}

/// A value as the JSON of every command prints it: the library's typed value (deci-amps as amperes,
/// centi- and deci-volts as volts), a flag word as [`flag_word_json`], an error code as `{code, bits}`.
pub(super) fn value_json(v: &Value) -> serde_json::Value {
    match v {
        Value::CurrentDeciAmps(_) | Value::BatteryDeciVolts(_) | Value::AnalogueCentiVolts(_) => {
            json!(v.as_f64())
        }
        Value::Flags(f) => flag_word_json(f),
        _ => v.to_json(),
    }
}

/// The unit of `e`'s value as [`value_json`] gives it: amperes and volts for the converted ones, and for a
/// remote speed the one in force (`--speed-mode`).
pub(super) fn unit_json(e: &DataEntry, speed_mode: SpeedMode) -> &'static str {
    match e.kind {
        Kind::CurrentDeciAmps => "A",
        Kind::BatteryDeciVolts | Kind::AnalogueCentiVolts => "V",
        Kind::RemoteSpeed => speed_mode.unit(),
        _ => e.unit,
    }
}

/// An actuator's status 1 as the fields of its JSON object: `word`, `flags`, `unknown_bits` (when
/// nonzero) and `moving`.
fn status_fields(s: ActuatorStatus1) -> serde_json::Value {
    let mut v = flag_word_json(&Flags::from(s));
    v["moving"] = json!(s.moving());
    v
}

/// A current in amperes: the library's value (deci-amps converted once, there); NaN for no current.
fn current_amps(current: &Value) -> f64 {
    match current {
        Value::CurrentDeciAmps(_) => current.as_f64().unwrap_or(f64::NAN),
        _ => f64::NAN,
    }
}

/// `fields` with `extra`'s fields added.
fn with(mut fields: serde_json::Value, extra: serde_json::Value) -> serde_json::Value {
    if let (Some(map), serde_json::Value::Object(e)) = (fields.as_object_mut(), extra) {
        map.extend(e);
    }
    fields
}

/// A library error as the command line reports it.
fn cl(e: motionlink_scu::Error) -> CliError {
    common::classified(&e)
}

/// The rows of `get`: each entry's name and index, and its value with its unit (a remote speed in the unit
/// of `mode`).
fn value_rows(values: &[(&'static DataEntry, Value)], mode: SpeedMode) -> Vec<Row> {
    values.iter().map(|(e, v)| (format!("{} ({})", e.name, e.index()), v.show(mode))).collect()
}

fn values_json(values: &[(&'static DataEntry, Value)]) -> serde_json::Value {
    let mut map = serde_json::Map::new();
    for (e, v) in values {
        map.insert(e.name.to_string(), value_json(v));
    }
    serde_json::Value::Object(map)
}

/// `get`: entries or groups, one after the other (one JSON object each).
pub(super) fn get(client: &Client, items: &[Item], report: &Report<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    for it in items {
        let values = client.get(it.index()).map_err(cl)?;
        if report.json {
            let (value, unit, access) = match it {
                Item::Entry(e) => {
                    (value_json(&values[0].1), unit_json(e, client.config().speed_mode), e.access.short())
                }
                Item::Group(_) => (values_json(&values), "", "r"),
            };
            report.print(
                out,
                json!({"name": it.name(), "id": it.index().0, "value": value, "unit": unit, "access": access}),
            )?;
        } else {
            common::print_table(out, &value_rows(&values, client.config().speed_mode))?;
        }
    }
    Ok(())
}

/// `set`: written and read back by the library.
pub(super) fn set(
    client: &Client,
    it: Item,
    value: &str,
    report: &Report<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let Item::Entry(e) = it else {
        return Err(CliError::usage(format!("{} is a group; set its entries one by one", it.name())));
    };
    let v = Value::parse(e.kind, value).map_err(|err| CliError::usage(format!("{}: {err}", e.name)))?;
    let written = client.set(e.index(), &v).map_err(cl)?;
    if report.json {
        // The library compared what it read back with what it wrote; the value the device gives now is
        // `read_back` (null where the unit does not read remote data back).
        let read_back = match written.verified {
            true => value_json(&client.get_value(e.index()).map_err(cl)?),
            false => serde_json::Value::Null,
        };
        report.print(
            out,
            json!({"name": e.name, "id": e.id, "value": value_json(&v), "unit": unit_json(e, client.config().speed_mode),
                   "access": e.access.short(), "read_back": read_back, "verified": written.verified,
                   "not_verifiable": written.not_verifiable}),
        )
    } else {
        let shown = v.show(client.config().speed_mode);
        let how = match written.verified {
            true => "written, read back".to_string(),
            false => format!("written; not verified: {}", written.not_verifiable.join("; ")),
        };
        common::print_table(out, &[(format!("{} ({})", e.name, e.index()), format!("{shown} ({how})"))])
    }
}

/// `move`: the library's verified move, with a progress bar on a terminal.
#[allow(clippy::too_many_arguments)]
pub(super) fn move_to(
    client: &Client,
    a: Actuator,
    position: PositionCounts,
    speed: Speed,
    function: MotionFunction,
    report: &Report<'_>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let start = client.position(a).map_err(cl)?;
    let bar = common::progress_bar(start.counts_from(position).unsigned_abs(), format!("{a} -> {}", position.get()));
    let progress = |p: &MoveProgress| bar.set_position(p.position_counts.counts_from(p.start_counts).unsigned_abs());
    let options = MoveOptions { cancel: Some(interrupt), progress: Some(&progress), function: Some(function) };
    let result = client.move_to(a, position, speed, &options);
    bar.finish_and_clear();
    print_move_report(out, &result.map_err(cl)?, report)
}

pub(super) fn connected_actuators(client: &Client) -> Result<Vec<(Actuator, ActuatorStatus1)>, CliError> {
    let statuses = client.statuses().map_err(cl)?;
    Ok(Actuator::all().zip(statuses).filter(|(_, s)| s.available()).collect())
}

fn status_text(s: ActuatorStatus1) -> String {
    Value::Flags(Flags::from(s)).to_string()
}

pub(super) fn info(client: &Client, report: &Report<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    let get = |i: u16| client.get_value(DataIndex(i)).map_err(cl);
    let firmware = get(0x0001)?;
    let configuration = get(0x0002)?;
    let mains = get(0x0100)?;
    let last_error = get(0x00D1)?;
    let actuators = connected_actuators(client)?;
    let positions = client.get(DataIndex(0x0010)).map_err(cl)?;
    let position = |a: Actuator| positions[usize::from(a.number() - 1)].1.clone();
    if report.json {
        let acts: Vec<_> = actuators
            .iter()
            .map(|(a, s)| {
                with(json!({"actuator": a.number(), "position_counts": position(*a).to_json()}), status_fields(*s))
            })
            .collect();
        report.print(
            out,
            json!({"firmware": firmware.to_json(), "configuration": configuration.to_json(),
                   "battery_mains": value_json(&mains), "last_error": last_error.to_json(), "actuators": acts}),
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

pub(super) fn errors(client: &Client, report: &Report<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    let history = client.error_history().map_err(cl)?;
    if report.json {
        let list: Vec<_> = history.iter().map(|c| Value::ErrorCode(*c).to_json()).collect();
        return report.print(out, json!({"errors": list}));
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

/// `watch`: the library samples (through the keepalive RC where the unit takes the session's cyclic object);
/// this prints each sample, one row per connected actuator.
pub(super) fn watch(
    client: &Client,
    report: &Report<'_>,
    format: Format,
    interval_ms: u64,
    count: Option<u64>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    if format == Format::Csv {
        writeln!(out, "t_s,actuator,position_counts,moving,current_amps,last_error_code")?;
    }
    let mut started = None;
    let mut failed: Option<CliError> = None;
    let mut print = |s: &Snapshot| {
        if failed.is_none() {
            let t = (s.at - *started.get_or_insert(s.at)).as_secs_f64();
            if let Err(e) = print_sample(out, report, format, t, s) {
                failed = Some(e);
                // Nothing more can be printed: the watch ends.
                interrupt.cancel();
            }
        }
    };
    let watched = client.watch(Duration::from_millis(interval_ms), count, &mut print, Some(interrupt));
    match failed {
        Some(e) => Err(e),
        None => watched.map(|_| ()).map_err(cl),
    }
}

/// One sample: a JSON object, CSV lines, or a line of text.
fn print_sample(
    out: &mut dyn Write,
    report: &Report<'_>,
    format: Format,
    t: f64,
    s: &Snapshot,
) -> Result<(), CliError> {
    let rows: Vec<(Actuator, PositionCounts, ActuatorStatus1, Value)> = Actuator::all()
        .filter(|a| s.status(*a).available())
        .map(|a| {
            (a, s.position(a), s.status(a), Value::CurrentDeciAmps(s.currents_deci_amps[usize::from(a.number() - 1)]))
        })
        .collect();
    let last_error = Value::ErrorCode(s.last_error);
    let code = s.last_error.0;
    match format {
        Format::Json => {
            let acts: Vec<_> = rows
                .iter()
                .map(|(a, position, status, current)| {
                    with(
                        json!({"actuator": a.number(), "position_counts": position.get(),
                               "current_amps": current_amps(current)}),
                        status_fields(*status),
                    )
                })
                .collect();
            report.print(out, json!({"t_s": t, "actuators": acts, "last_error": last_error.to_json()}))?;
        }
        Format::Csv => {
            for (a, position, status, current) in &rows {
                let fields = [
                    format!("{t:.3}"),
                    a.number().to_string(),
                    position.get().to_string(),
                    status.moving().to_string(),
                    format!("{:.1}", current_amps(current)),
                    code.to_string(),
                ];
                writeln!(out, "{}", common::csv_line(&fields))?;
            }
        }
        Format::Text => {
            let mut line = format!("{t:7.2} s");
            for (a, position, status, current) in &rows {
                let moving = if status.moving() { "moving" } else { "stopped" };
                line.push_str(&format!("  {a}: {} {moving} {current}", Value::PositionCounts(position.get())));
            }
            if code != ErrorCode::NONE.0 {
                line.push_str(&format!("  last error 0x{code:08X}"));
            }
            writeln!(out, "{line}")?;
        }
    }
    out.flush()?;
    Ok(())
}

/// `run`: the library runs the function, watches it, stops it and confirms the stop; this prints.
pub(super) fn run(
    client: &Client,
    action: RunAction,
    limit: Option<Duration>,
    report: &Report<'_>,
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
            let line = if report.json {
                common::identified("scu", report.port, json!({"function": function.number(), "running": true}))
                    .to_string()
            } else {
                format!("{function} running; Ctrl-C stops it")
            };
            let _ = writeln!(std::io::stdout(), "{line}");
            let _ = std::io::stdout().flush();
        }
    };
    let (rest, interrupted) = match client.run(action, limit, &progress, Some(interrupt)) {
        Ok(report) => (report.rest, false),
        Err(motionlink_scu::Error::RunCancelled { rest, .. }) => (rest, true),
        Err(e) => return Err(cl(e)),
    };
    if report.json {
        let acts: Vec<_> = rest.iter().map(|(a, p)| json!({"actuator": a.number(), "reached_counts": p})).collect();
        report.print(
            out,
            json!({"function": function.number(), "stopped": true, "interrupted": interrupted, "actuators": acts}),
        )?;
    } else {
        writeln!(out, "{function} stopped")?;
        let rows: Vec<Row> = rest.iter().map(|(a, p)| (a.to_string(), p.to_string())).collect();
        common::print_table(out, &rows)?;
    }
    if interrupted {
        return Err(CliError::Interrupted(format!("interrupted; {function} stopped (the unit confirmed it)")));
    }
    Ok(())
}

/// Prints how a move ended: each actuator whose remote position it wrote, with its target and difference.
pub(super) fn print_move_report(out: &mut dyn Write, report: &MoveReport, how: &Report<'_>) -> Result<(), CliError> {
    if how.json {
        let actuators: Vec<_> = report
            .actuators
            .iter()
            .map(|o| {
                json!({"actuator": o.actuator.number(), "target_counts": o.target_counts,
                       "reached_counts": o.position_counts, "difference_counts": o.difference_counts(),
                       "moved": o.moved})
            })
            .collect();
        let target = report.actuators.iter().find(|o| o.actuator == report.actuator).map(|o| o.target_counts);
        return how.print(
            out,
            json!({"actuator": report.actuator.number(), "function": report.function.number(),
                   "reached_counts": report.position_counts, "target_counts": target,
                   "difference_counts": target.map(|t| report.position_counts.counts_from(t)),
                   "time_s": report.duration.as_secs_f64(), "actuators": actuators,
                   "verified": report.verified, "not_verifiable": report.not_verifiable}),
        );
    }
    let mut rows: Vec<Row> = vec![("function".into(), report.function.to_string())];
    for o in &report.actuators {
        let text = if o.moved || o.actuator == report.actuator {
            format!(
                "{} (target {} counts, difference {} counts)",
                o.position_counts,
                o.target_counts.get(),
                o.difference_counts()
            )
        } else {
            format!("{} (did not move: not driven by {})", o.position_counts, report.function)
        };
        rows.push((o.actuator.to_string(), text));
    }
    rows.push(("time".into(), format!("{:.1} s", report.duration.as_secs_f64())));
    rows.push(("verified".into(), verified_text(report.verified, &report.not_verifiable)));
    common::print_table(out, &rows)
}

/// "yes", or "no: " and what could not be verified.
fn verified_text(verified: bool, not_verifiable: &[String]) -> String {
    match verified {
        true => "yes".into(),
        false => format!("no: {}", not_verifiable.join("; ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motionlink_scu::model::FlagSet;

    #[test]
    fn currents_are_amperes_converted_once_and_flag_words_have_word_and_flags() {
        // 30 deci-amps on the wire are 3 A (the library converts); not 0.3 A.
        assert_eq!(current_amps(&Value::CurrentDeciAmps(30)), 3.0);
        assert_eq!(value_json(&Value::CurrentDeciAmps(30)), json!(3.0));
        let f = Flags { set: FlagSet::ActuatorStatus1, bits: 0x01 };
        let v = value_json(&Value::Flags(f));
        assert_eq!(v["word"], 1);
        assert!(v["flags"].is_array() && v.get("set").is_none() && v.get("unknown_bits").is_none(), "{v}");
    }
}
