//! The actions of `motionlink scu`: each calls the library and prints the report it returns (`--json`: as
//! the report serialises; else a table made from the same report).

use std::io::Write;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_scu::model::{Actuator, DataEntryExt, ErrorCode, Item, MotionFunction, PositionCounts, Speed};
use motionlink_scu::results::{ActuatorState, ErrorHistory, GetReport, RunOutcome, Running, SampleReport};
use motionlink_scu::session::{MoveProgress, MoveReport, RunAction, RunProgress, Snapshot};
use motionlink_scu::{Client, MoveOptions};

use crate::common::Out;
use crate::common::{self, CliError, Row, WatchFormat as Format};

/// A library error as the command line reports it.
fn cl(e: motionlink_scu::Error) -> CliError {
    common::classified(&e)
}

/// `get`: entries or groups, one after the other (one JSON object each).
pub(super) fn get(client: &Client, items: &[Item], report: &Out<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    for it in items {
        report.show(out, &client.read(*it).map_err(cl)?, |out, r: &GetReport| {
            let rows: Vec<Row> =
                r.values.iter().map(|(e, v)| (format!("{} ({})", e.name, e.index()), v.show(r.speed_mode))).collect();
            common::print_table(out, &rows)
        })?;
    }
    Ok(())
}

/// `set`: written, read back and compared by the library; what the unit holds then.
pub(super) fn set(
    client: &Client,
    it: Item,
    value: &str,
    report: &Out<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let (entry, value) = motionlink_scu::args::parse_write(it, value).map_err(CliError::usage)?;
    report.show(out, &client.write(entry, value).map_err(cl)?, |out, w| {
        let how = match w.set.verified {
            true => "written, read back".to_string(),
            false => format!("written; not verified: {}", w.set.not_verifiable.join("; ")),
        };
        let row =
            (format!("{} ({})", w.entry.name, w.entry.index()), format!("{} ({how})", w.value.show(w.speed_mode)));
        common::print_table(out, &[row])
    })
}

/// `move`: the library's verified move, with a progress bar on a terminal.
#[allow(clippy::too_many_arguments)]
pub(super) fn move_to(
    client: &Client,
    a: Actuator,
    position: PositionCounts,
    speed: Speed,
    function: MotionFunction,
    report: &Out<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let start = client.position(a).map_err(cl)?;
    let bar = common::progress_bar(start.counts_from(position).unsigned_abs(), format!("{a} -> {}", position.get()));
    let progress = |p: &MoveProgress| bar.set_position(p.position_counts.counts_from(p.start_counts).unsigned_abs());
    let options = MoveOptions { progress: Some(&progress), function: Some(function) };
    let result = client.move_to(a, position, speed, &options);
    bar.finish_and_clear();
    report.show(out, &result.map_err(cl)?, print_move_text)
}

/// An actuator's position and status 1, in words.
fn state_text(s: &ActuatorState) -> String {
    format!("{}, {}", s.position_counts, motionlink_scu::model::Flags::from(s.status))
}

pub(super) fn info(client: &Client, report: &Out<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    report.show(out, &client.info().map_err(cl)?, |out, info| {
        let mut rows: Vec<Row> = vec![
            ("port".into(), client.port().to_string()),
            ("firmware".into(), format!("{:?}", info.firmware)),
            ("configuration".into(), format!("{:?}", info.configuration)),
            ("battery/mains".into(), info.battery_mains.to_string()),
            ("last error".into(), info.last_error.to_string()),
        ];
        rows.extend(info.actuators.iter().map(|s| (format!("actuator {}", s.actuator.number()), state_text(s))));
        common::print_table(out, &rows)
    })
}

/// `errors`: Error_Code 1..5 (JSON: `{"errors": [...]}`).
pub(super) fn errors(client: &Client, report: &Out<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    report.show(out, &ErrorHistory { errors: client.error_history().map_err(cl)? }, |out, h| {
        let mut rows = Vec::new();
        for (i, code) in h.errors.iter().enumerate() {
            let label = match i {
                0 => "error code 1 (last recent)".to_string(),
                _ => format!("error code {} (history {i})", i + 1),
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
    })
}

/// `watch`: the library samples (through the keepalive RC where the unit takes the session's cyclic object);
/// this prints each sample, one row per connected actuator.
pub(super) fn watch(
    client: &Client,
    report: &Out<'_>,
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
            if let Err(e) = print_sample(out, report, format, &SampleReport::new(s, t)) {
                failed = Some(e);
                // Nothing more can be printed: the watch ends.
                interrupt.cancel();
            }
        }
    };
    let watched = client.watch(Duration::from_millis(interval_ms), count, &mut print);
    match (failed, watched) {
        (Some(e), _) => Err(e),
        (None, Ok(_)) => Ok(()),
        // A link too slow for the object's definition, where the user did not allow the lapse: say how.
        (None, Err(e @ motionlink_scu::Error::NoRoom { .. })) if !client.config().watch_may_lapse => {
            Err(CliError::transport(format!(
                "{e}; on a link this slow, `watch --allow-watchdog-lapse` defines the session's cyclic object \
                 across one lapse of the unit's watchdog, which stops every motion under way on the unit"
            )))
        }
        (None, Err(e)) => Err(cl(e)),
    }
}

/// One sample: a JSON object, CSV lines, or a line of text.
fn print_sample(out: &mut dyn Write, report: &Out<'_>, format: Format, s: &SampleReport) -> Result<(), CliError> {
    let amps = |a: &ActuatorState| a.current_amps.unwrap_or(f64::NAN);
    match format {
        Format::Json => report.print(out, s)?,
        Format::Csv => {
            for a in &s.actuators {
                let fields = [
                    format!("{:.3}", s.t_s),
                    a.actuator.number().to_string(),
                    a.position_counts.get().to_string(),
                    a.status.moving().to_string(),
                    format!("{:.1}", amps(a)),
                    s.last_error.0.to_string(),
                ];
                writeln!(out, "{}", common::csv_line(&fields))?;
            }
        }
        Format::Text => {
            let mut line = format!("{:7.2} s", s.t_s);
            for a in &s.actuators {
                let moving = if a.status.moving() { "moving" } else { "stopped" };
                line.push_str(&format!("  {}: {} {moving} {:.1} A", a.actuator, a.position_counts, amps(a)));
            }
            if s.last_error != ErrorCode::NONE {
                line.push_str(&format!("  last error 0x{:08X}", s.last_error.0));
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
    report: &Out<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let function = action.function();
    // A switching function (buzzer, outputs, emergency stop, LEDs) is switched off by the RS that ends the
    // run; the library reads the status entry that shows it after the RE and after the RS.
    let status = function.switch_status();
    // The first progress comes right after the unit acknowledged the RE (for a switching function, once its
    // status was read).
    let said = std::cell::Cell::new(false);
    let progress = |p: &RunProgress| {
        if !said.replace(true) {
            let mut stdout = std::io::stdout();
            let verified = p.switched_on_shown;
            let _ = match (report.json, status) {
                (true, _) => report.print(&mut stdout, Running { function, running: true, verified }),
                (false, None) => writeln!(stdout, "{function} running; Ctrl-C stops it").map_err(CliError::from),
                (false, Some(s)) => {
                    let shown = match verified {
                        Some(true) => format!("read back from {}: {}", s.place(), s.state(true)),
                        _ => "not verified by its status".into(),
                    };
                    writeln!(stdout, "{function} switched on (RE acknowledged; {shown}); Ctrl-C switches it off (RS)")
                        .map_err(CliError::from)
                }
            };
            let _ = stdout.flush();
        }
    };
    let outcome = RunOutcome::of(client.run_function(action, limit, &progress)).map_err(cl)?;
    report.show(out, &outcome, |out, o| {
        let mut rows: Vec<Row> = o.rest.iter().map(|(a, p)| (a.to_string(), p.to_string())).collect();
        match status {
            Some(s) => {
                writeln!(out, "{function} switched off (RS acknowledged)")?;
                let verified = match o.verified {
                    true => format!(
                        "yes: read back from {}: {} after the RE, {} after the RS",
                        s.place(),
                        s.state(true),
                        s.state(false)
                    ),
                    false => format!("no: {}", o.not_verifiable.join("; ")),
                };
                rows.push(("verified".into(), verified));
            }
            None => {
                writeln!(out, "{function} stopped")?;
                // A motion function no actuator was seen to carry out.
                if !o.not_verifiable.is_empty() {
                    rows.push(("verified".into(), format!("no: {}", o.not_verifiable.join("; "))));
                }
            }
        }
        common::print_table(out, &rows)
    })?;
    match (outcome.interrupted, status) {
        (true, None) => Err(CliError::Interrupted(format!("interrupted; {function} stopped (the unit confirmed it)"))),
        (true, Some(s)) => {
            let shown = match outcome.verified {
                true => format!("read back from {}: {}", s.place(), s.state(false)),
                false => "not verified by its status".into(),
            };
            Err(CliError::Interrupted(format!("interrupted; {function} switched off (RS acknowledged; {shown})")))
        }
        (false, _) => Ok(()),
    }
}

/// How a move ended, as a table: each actuator whose remote position it wrote, with its target and difference.
fn print_move_text(out: &mut dyn Write, report: &MoveReport) -> Result<(), CliError> {
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
    let verified = match report.verified {
        true => "yes".into(),
        false => format!("no: {}", report.not_verifiable.join("; ")),
    };
    rows.push(("verified".into(), verified));
    common::print_table(out, &rows)
}
