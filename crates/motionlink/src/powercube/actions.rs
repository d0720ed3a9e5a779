//! The actions of `motionlink powercube` on one module: one function per action (`scan`, `info` and `watch`
//! are in `show`, `send` in `send`).

use super::*;

/// `state`: reads and prints the module's CubeState, flag by flag.
pub(super) fn state(args: &Args, m: &Module<'_>, port: &str, out: &mut dyn Write) -> Result<(), CliError> {
    let s = m.state().map_err(failed)?;
    if args.json {
        common::print_json(out, &identified(args, port, state_json(s)))?;
    } else {
        writeln!(out, "CubeState {:#010x}", s.0)?;
        let rows: Vec<_> =
            s.iter().map(|f| (f.label(), format!("{:<11}  {}", f.class().name(), f.meaning()))).collect();
        common::print_table(out, &rows)?;
        if s.is_empty() {
            writeln!(out, "(no flag set)")?;
        }
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
    for p in params {
        let v = m.get(p).map_err(failed)?;
        // The unit depends on the module type (rad or m): no guessing when it cannot be read.
        let kind = m.kind().map_err(|e| {
            context(e, format!("{} read, but the module type (and so its unit) cannot be read", p.name()))
        })?;
        if args.json {
            let access = PARAMS.iter().find(|e| e.id == u32::from(p.id())).map_or("", |e| e.access.short());
            common::print_json(
                out,
                &identified(
                    args,
                    port,
                    json!({"name": p.name(), "id": p.id(), "value": value_json(&v),
                           "unit": p.unit().symbol(kind), "access": access}),
                ),
            )?;
        } else {
            rows.push((p.name().to_string(), v.show(p, kind)));
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
    let p = parse_param(param)?;
    let v = Value::parse(p, value).map_err(CliError::usage)?;
    // Targets beyond their limits are refused; what was written is read back where the module allows it.
    let Readback { read, verified, not_verifiable } = m.set_checked(p, v).map_err(failed)?;
    if args.json {
        let read_back = match read {
            Some(r) => Some(read_back_json(m, p, &r)?),
            None => None,
        };
        let result = json!({"name": p.name(), "id": p.id(), "value": value_json(&v), "ok": true,
                "read_back": read_back, "verified": verified, "not_verifiable": not_verifiable});
        common::print_json(out, &identified(args, port, result))?;
    } else {
        let kind = m.kind().map_err(|e| {
            context(e, format!("{} was set, but the module type (and so its unit) cannot be read", p.name()))
        })?;
        let how =
            if verified { "read back".to_string() } else { format!("not verified: {}", not_verifiable.join("; ")) };
        writeln!(out, "{} set to {} ({how})", p.name(), v.show(p, kind))?;
    }
    Ok(())
}

/// `home`: homes the module with a progress bar, giving up after `timeout_s`.
pub(super) fn home(
    args: &Args,
    m: &Module<'_>,
    guard: Guard,
    port: &str,
    timeout_s: f64,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let timeout = positive_secs("--timeout-s", timeout_s)?;
    let bar = common::progress_bar(0, format!("homing module {}", args.module));
    let r = m.home_guarded(timeout, guard, &mut |p: &Progress| bar.set_message(progress_text(p)));
    bar.finish_and_clear();
    let (position, s) = r.map_err(failed)?;
    let kind = m.kind().map_err(|e| {
        context(e, "homed, but the module type (and so the unit of its position) cannot be read".into())
    })?;
    if args.json {
        let fields = json!({"action": "homed", unit_key("reached", kind): position.value(),
                            "state": state_json(s)});
        common::print_json(out, &identified(args, port, fields))?;
    } else {
        report_done(out, "homed", position, kind, s)?;
    }
    Ok(())
}

/// `reset`: resets the module, switching off a watchdog that expired with no host serving it.
pub(super) fn reset(args: &Args, m: &Module<'_>, port: &str, out: &mut dyn Write) -> Result<(), CliError> {
    // After a host died with the watchdog online, a plain Reset would be undone 50 ms later.
    let released = m.reset_and_release_watchdog().map_err(failed)?;
    if args.json {
        common::print_json(
            out,
            &identified(args, port, json!({"ok": true, "action": "reset", "watchdog_released": released})),
        )?;
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
    stopped: Option<&crate::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    if let (Some(h), false) = (stopped, args.json) {
        writeln!(out, "{}", h.describe())?;
    }
    let halted = m.halt_confirmed().map_err(failed)?;
    let kind = m.kind().map_err(|e| {
        context(e, "halted, but the module type (and so the unit of its position) cannot be read".into())
    })?;
    if args.json {
        let fields = json!({"ok": true, "action": "halted", unit_key("position", kind): halted.position.value(),
                            "state": state_json(halted.state), "holder": stopped});
        common::print_json(out, &identified(args, port, fields))?;
    } else {
        writeln!(
            out,
            "module {} halted: at rest (state read back) at {}; it takes no motion until reset",
            args.module,
            halted.position.show(kind)
        )?;
    }
    Ok(())
}

/// The move `move` asks for, its numbers in the module's own unit (rad or m).
pub(super) fn move_spec(
    position: f32,
    vel: Option<f32>,
    acc: Option<f32>,
    timeout_s: f64,
    tolerance: f32,
) -> Result<MoveSpec, CliError> {
    // Numbers on the command line are in the module's own unit (rad or m).
    Ok(MoveSpec {
        target: Position::native(position),
        // Only what was given is written; TargetVel / TargetAcc otherwise stay as the module has them.
        vel: vel.map(Velocity::native),
        acc: acc.map(Acceleration::native),
        tolerance: Some(Position::native(tolerance)),
        timeout: positive_secs("--timeout-s", timeout_s)?,
    })
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
    let kind = m.kind().map_err(|e| {
        context(e, "the move ended, but the module type (and so the unit of its position) cannot be read".into())
    })?;
    if args.json {
        let reached = report.reached.value();
        let fields = json!({"action": "reached", unit_key("target", kind): position,
                            unit_key("reached", kind): reached,
                            unit_key("difference", kind): reached - position,
                            "state": state_json(report.state),
                            "verified": report.verified, "not_verifiable": report.not_verifiable});
        common::print_json(out, &identified(args, port, fields))?;
    } else {
        report_done(out, "reached", report.reached, kind, report.state)?;
        if !report.verified {
            writeln!(out, "not verified: {}", report.not_verifiable.join("; "))?;
        }
    }
    Ok(())
}
