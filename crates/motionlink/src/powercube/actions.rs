//! The actions of `motionlink powercube` on one module: one function per action (`scan`, `info` and `watch`
//! are in `show`, `send` in `send`). With `--json` each prints the library's report as it serialises.

use super::*;
use motionlink_powercube::report::{Acted, ParamReading, Released, SetReport, StateReport};

/// `state`: reads and prints the module's CubeState, flag by flag.
pub(super) fn state(o: &Out<'_>, m: &Module<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    let s = m.state().map_err(failed)?;
    if o.json {
        return o.print(out, StateReport(s));
    }
    writeln!(out, "CubeState {:#010x}", s.0)?;
    let rows: Vec<_> = s.iter().map(|f| (f.label(), format!("{:<11}  {}", f.class().name(), f.meaning()))).collect();
    common::print_table(out, &rows)?;
    if s.is_empty() {
        writeln!(out, "(no flag set)")?;
    }
    Ok(())
}

/// `get`: reads and prints the parameters `params`, each in the module's unit.
pub(super) fn get(o: &Out<'_>, m: &Module<'_>, params: &[String], out: &mut dyn Write) -> Result<(), CliError> {
    let params = params.iter().map(|p| parse_param(p)).collect::<Result<Vec<_>, _>>()?;
    let mut rows = Vec::new();
    for param in params {
        let value = m.get(param).map_err(failed)?;
        // The unit depends on the module type (rad or m): no guessing when it cannot be read.
        let kind = m.kind().map_err(|e| {
            context(e, format!("{} read, but the module type (and so its unit) cannot be read", param.name()))
        })?;
        if o.json {
            o.print(out, ParamReading { param, kind, value })?;
        } else {
            rows.push((param.name().to_string(), value.show(param, kind)));
        }
    }
    if !o.json {
        common::print_table(out, &rows)?;
    }
    Ok(())
}

/// `set`: writes `value` to the parameter `param` (targets beyond their limits refused) and reads it back.
pub(super) fn set(o: &Out<'_>, m: &Module<'_>, param: &str, value: &str, out: &mut dyn Write) -> Result<(), CliError> {
    let param = parse_param(param)?;
    let value = Value::parse(param, value).map_err(CliError::usage)?;
    // Targets beyond their limits are refused; what was written is read back where the module allows it.
    let readback = m.set_checked(param, value).map_err(failed)?;
    if o.json {
        return o.print(out, SetReport { param, value, readback });
    }
    let kind = m.kind().map_err(|e| {
        context(e, format!("{} was set, but the module type (and so its unit) cannot be read", param.name()))
    })?;
    let how = if readback.verified {
        "read back".to_string()
    } else {
        format!("not verified: {}", readback.not_verifiable.join("; "))
    };
    writeln!(out, "{} set to {} ({how})", param.name(), value.show(param, kind))?;
    Ok(())
}

/// `home`: homes the module with a progress bar, giving up after `timeout`.
pub(super) fn home(
    o: &Out<'_>,
    m: &Module<'_>,
    guard: Guard,
    timeout: std::time::Duration,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let bar = common::progress_bar(0, format!("homing module {}", m.address()));
    let r = m.home_guarded(timeout, guard, &mut |p: &Progress| bar.set_message(progress_text(p)));
    bar.finish_and_clear();
    let report = r.map_err(failed)?;
    if o.json {
        return o.print(out, Acted::homed(report));
    }
    report_done(out, "homed", (report.reached, report.kind, report.state), None, &report.not_verifiable)
}

/// `reset`: resets the module, switching off a watchdog that expired with no host serving it.
pub(super) fn reset(o: &Out<'_>, m: &Module<'_>, out: &mut dyn Write) -> Result<(), CliError> {
    // After a host died with the watchdog online, a plain Reset would be undone 50 ms later.
    let released = m.reset_and_release_watchdog().map_err(failed)?;
    if o.json {
        o.print(out, Acted::reset(Released { watchdog_released: released }))?;
    } else if released {
        writeln!(out, "reset (the watchdog had expired with no host serving it: switched it offline)")?;
    } else {
        writeln!(out, "reset")?;
    }
    Ok(())
}

/// `stop` (alias `halt`): halts the module, confirmed by its state, and prints where it stands; first what
/// the motionlink that held the port said when it was stopped, if one was.
pub(super) fn stop(
    o: &Out<'_>,
    m: &Module<'_>,
    stopped: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    o.holder(out, stopped)?;
    let halted = m.halt_confirmed().map_err(failed)?;
    if o.json {
        return o.print(out, Acted::halted(halted, stopped));
    }
    writeln!(
        out,
        "module {} halted: at rest (state read back) at {}; it takes no motion until reset",
        m.address(),
        halted.position.show(halted.kind)
    )?;
    Ok(())
}

/// `move`: moves the module as `spec` says with a progress bar and prints where it came to rest.
pub(super) fn move_to(
    o: &Out<'_>,
    m: &Module<'_>,
    guard: Guard,
    spec: &MoveSpec,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let position = spec.target.value();
    let bar = common::progress_bar(0, format!("module {}", m.address()));
    let mut start = None;
    let r = m.move_to_guarded(spec, guard, &mut |p: &Progress| {
        let from = *start.get_or_insert(p.position.value());
        bar.set_length(((position - from).abs() * 1000.0).round() as u64);
        bar.set_position(((p.position.value() - from).abs() * 1000.0).round() as u64);
        bar.set_message(progress_text(p));
    });
    bar.finish_and_clear();
    let report = r.map_err(failed)?;
    if o.json {
        return o.print(out, Acted::reached(report));
    }
    let end = (report.reached, report.kind, report.state);
    report_done(out, "reached", end, report.not_homed_note(), &report.not_verifiable)
}

/// `motion`: runs the mode `spec` gives and prints how it ended and where the module came to rest.
pub(super) fn motion(
    o: &Out<'_>,
    m: &Module<'_>,
    guard: Guard,
    spec: &MotionSpec,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let bar = common::progress_bar(0, format!("module {}", m.address()));
    let r = m.run_motion_guarded(spec, guard, &mut |p: &Progress| bar.set_message(progress_text(p)));
    bar.finish_and_clear();
    let report = r.map_err(failed)?;
    if o.json {
        return o.print(out, Acted::ran(report));
    }
    let (what, end) =
        (format!("{} {}", report.mode.name(), report.ending), (report.reached, report.kind, report.state));
    report_done(out, &what, end, report.not_homed_note(), &report.not_verifiable)
}
