//! What `motionlink powercube` prints: `scan`, `info`, `watch` and the end of a motion.

use std::time::Duration;

use super::*;
use motionlink_powercube::model::AxisUnit;
use motionlink_powercube::report::{Sample, Timed};

pub(super) fn scan(client: &Client, o: &Out<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    let found = client.scan().map_err(failed)?;
    if o.json {
        // A listing: one object per module (JSON Lines).
        for e in &found {
            Out { unit: None, ..*o }.print(out, e)?;
        }
    } else if found.is_empty() {
        writeln!(out, "no module answered on {}", client.port())?;
    } else {
        writeln!(out, "{:<7}  {:<6}  {:<7}  {:<8}  state", "address", "type", "version", "serial")?;
        for e in &found {
            match &e.info {
                Ok(i) => writeln!(
                    out,
                    "{:<7}  {:<6}  {:<7}  {:<8}  {}",
                    i.address.get(),
                    i.kind.name(),
                    i.version.to_string(),
                    i.serial,
                    i.state
                )?,
                Err(err) => writeln!(out, "{:<7}  answered the scan, then: {err}", e.address.get())?,
            }
        }
    }
    if found.is_empty() {
        return Err(CliError::transport(format!("no module answered on {}", client.port())));
    }
    // Every module is listed; the exit code still says that one could not be read.
    match found.into_iter().find_map(|e| e.info.err()) {
        Some(e) => Err(failed(e)),
        None => Ok(()),
    }
}

pub(super) fn info(o: &Out<'_>, m: &Module<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    let details = m.details().map_err(failed)?;
    if o.json {
        return o.print(out, details);
    }
    let info = details.info;
    let mut rows = vec![
        ("address".to_string(), info.address.to_string()),
        ("type".to_string(), info.kind.name().to_string()),
        ("version".to_string(), info.version.to_string()),
        ("serial".to_string(), info.serial.to_string()),
        ("state".to_string(), info.state.to_string()),
    ];
    rows.extend(details.limits().iter().map(|(p, v)| (p.name().to_string(), v.show(*p, info.kind))));
    common::print_table(out, &rows)
}

pub(super) fn watch(
    client: &Client,
    o: &Out<'_>,
    m: &Module<'_>,
    out: &mut dyn Write,
    format: WatchFormat,
    interval_ms: u64,
    count: Option<u64>,
) -> Result<(), CliError> {
    let token = common::interrupt_token();
    let kind = m.kind().map_err(failed)?;
    let clock = Arc::clone(client.clock());
    let interval = Duration::from_millis(interval_ms);
    let mut due = clock.now();
    let started = due;
    let mut n = 0u64;
    if format == WatchFormat::Csv {
        writeln!(out, "t_s,module,position_{},flags", kind.unit())?;
    }
    while !token.is_cancelled() && count.is_none_or(|c| n < c) {
        let s = m.state().map_err(failed)?;
        let p = m.position().map_err(failed)?;
        let t = clock.now();
        let t_s = (t - started).as_secs_f64();
        match format {
            WatchFormat::Json => o.print(out, Timed { t_s, sample: Sample { kind, position: p, state: s } })?,
            WatchFormat::Csv => {
                let flags: Vec<String> = s.iter().map(|f| f.label()).collect();
                let fields = [format!("{t_s:.3}"), m.address().to_string(), p.value().to_string(), flags.join(" ")];
                writeln!(out, "{}", common::csv_line(&fields))?;
            }
            WatchFormat::Text => writeln!(out, "{:>9.3} s  {}  {}", t_s, p.show(kind), s)?,
        }
        out.flush()?;
        n += 1;
        if count.is_some_and(|c| n >= c) {
            break;
        }
        // The next sample on a fixed schedule; a signal ends the wait within 20 ms.
        due += interval;
        while !token.is_cancelled() && clock.now() < due {
            clock.sleep_until(due.min(clock.now() + Duration::from_millis(20)));
        }
    }
    Ok(())
}

pub(super) fn progress_text(p: &Progress) -> String {
    // The unit once the session knows the module's kind (a bare number until then).
    let unit = match p.position.unit() {
        AxisUnit::ModuleUnit => String::new(),
        u => format!(" {u}"),
    };
    format!("module {}: {:.4}{unit}  {}", p.address, p.position.value(), p.state)
}

/// The end of a motion: `reached: position 1.2000 rad, state ...` (in the unit of a module of `kind`), then
/// the report's note on a module not homed and what it could not verify.
pub(super) fn report_done(
    out: &mut dyn Write,
    what: &str,
    (pos, kind, s): (Position, ModuleKind, CubeState),
    note: Option<&str>,
    not_verifiable: &[String],
) -> Result<(), CliError> {
    writeln!(out, "{what}: position {}, state {s}", pos.show(kind))?;
    if let Some(note) = note {
        writeln!(out, "note: {note}")?;
    }
    common::not_verified(out, not_verifiable)
}
