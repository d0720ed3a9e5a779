//! The actions of `motionlink powercube` on one module: one function per action (`scan`, `info` and `watch`
//! are in `show`, `send` in `send`). With `--json` each prints the library's report as it serialises.

use super::*;
use motionlink_powercube::report::{Acted, ParamReading, Released, SetReport, StateReport};

/// `state`: reads and prints the module's CubeState, flag by flag.
pub(super) fn state(args: &Args, m: &Module<'_>, port: &str, out: &mut dyn Write) -> Result<(), CliError> {
    let s = m.state().map_err(failed)?;
    if args.json {
        return print(out, port, args.module, &StateReport(s));
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
pub(super) fn get(
    args: &Args,
    m: &Module<'_>,
    port: &str,
    params: &[String],
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let params = params.iter().map(|p| parse_param(p)).collect::<Result<Vec<_>, _>>()?;
    let mut rows = Vec::new();
    for param in params {
        let value = m.get(param).map_err(failed)?;
        // The unit depends on the module type (rad or m): no guessing when it cannot be read.
        let kind = m.kind().map_err(|e| {
            context(e, format!("{} read, but the module type (and so its unit) cannot be read", param.name()))
        })?;
        if args.json {
            print(out, port, args.module, &ParamReading { param, kind, value })?;
        } else {
            rows.push((param.name().to_string(), value.show(param, kind)));
        }
    }
    if !args.json {
        common::print_table(out, &rows)?;
    }
    Ok(())
}

/// `set`: writes `value` to the parameter `param` (targets beyond their limits refused) and reads it back.
pub(super) fn set(
    args: &Args,
    m: &Module<'_>,
    port: &str,
    param: &str,
    value: &str,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let param = parse_param(param)?;
    let value = Value::parse(param, value).map_err(CliError::usage)?;
    // Targets beyond their limits are refused; what was written is read back where the module allows it.
    let readback = m.set_checked(param, value).map_err(failed)?;
    if args.json {
        return print(out, port, args.module, &SetReport { param, value, readback });
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
    args: &Args,
    m: &Module<'_>,
    guard: Guard,
    port: &str,
    timeout: std::time::Duration,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let bar = common::progress_bar(0, format!("homing module {}", args.module));
    let r = m.home_guarded(timeout, guard, &mut |p: &Progress| bar.set_message(progress_text(p)));
    bar.finish_and_clear();
    let report = r.map_err(failed)?;
    if args.json {
        return print(out, port, args.module, &Acted::homed(report));
    }
    report_done(out, "homed", report.reached, report.kind, report.state)?;
    not_verified(out, &report.not_verifiable)
}

/// What a motion could not verify, one line (nothing when it verified everything).
fn not_verified(out: &mut dyn Write, why: &[String]) -> Result<(), CliError> {
    if !why.is_empty() {
        writeln!(out, "not verified: {}", why.join("; "))?;
    }
    Ok(())
}

/// `reset`: resets the module, switching off a watchdog that expired with no host serving it.
pub(super) fn reset(args: &Args, m: &Module<'_>, port: &str, out: &mut dyn Write) -> Result<(), CliError> {
    // After a host died with the watchdog online, a plain Reset would be undone 50 ms later.
    let released = m.reset_and_release_watchdog().map_err(failed)?;
    if args.json {
        print(out, port, args.module, &Acted::reset(Released { watchdog_released: released }))?;
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
    args: &Args,
    m: &Module<'_>,
    port: &str,
    stopped: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    if let (Some(h), false) = (stopped, args.json) {
        writeln!(out, "{}", h.describe())?;
    }
    let halted = m.halt_confirmed().map_err(failed)?;
    if args.json {
        return print(out, port, args.module, &Acted::halted(halted, stopped));
    }
    writeln!(
        out,
        "module {} halted: at rest (state read back) at {}; it takes no motion until reset",
        args.module,
        halted.position.show(halted.kind)
    )?;
    Ok(())
}

/// `move`: moves the module as `spec` says with a progress bar and prints where it came to rest.
pub(super) fn move_to(
    args: &Args,
    m: &Module<'_>,
    guard: Guard,
    port: &str,
    spec: &MoveSpec,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let position = spec.target.value();
    let bar = common::progress_bar(0, format!("module {}", args.module));
    let mut start = None;
    let r = m.move_to_guarded(spec, guard, &mut |p: &Progress| {
        let from = *start.get_or_insert(p.position.value());
        bar.set_length(((position - from).abs() * 1000.0).round() as u64);
        bar.set_position(((p.position.value() - from).abs() * 1000.0).round() as u64);
        bar.set_message(progress_text(p));
    });
    bar.finish_and_clear();
    let report = r.map_err(failed)?;
    if args.json {
        return print(out, port, args.module, &Acted::reached(report));
    }
    report_done(out, "reached", report.reached, report.kind, report.state)?;
    not_verified(out, &report.not_verifiable)
}
