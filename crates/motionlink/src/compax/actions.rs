//! The actions of `motionlink compax`: their arguments checked before the port is opened, then one function
//! per action.

use super::open::MovePlan;
use super::*;

/// What a COMPAX position is in, in text: the drive's own unit (set in the drive; the JSON keys say
/// `_units`).
pub(super) const UNITS: &str = "units";

/// `value` with `unit` after it (nothing when the parameter has no unit).
fn with_unit(value: f64, unit: &str) -> String {
    if unit.is_empty() {
        value.to_string()
    } else {
        format!("{value} {unit}")
    }
}

/// The arguments of an action, checked before the port is opened.
pub(super) struct Checked {
    /// `move`: the move, planned.
    pub(super) move_plan: Option<MovePlan>,
    /// The interval of the status polls (`move`, `raw --wait`).
    pub(super) poll: Option<Duration>,
    /// `raw --wait`: how long to wait for a move the command started.
    pub(super) raw_wait: Option<Duration>,
    /// `watch`: the interval between two lines.
    pub(super) watch_interval: Option<Duration>,
    /// `status`: the values to read.
    pub(super) status_ids: Vec<StatusId>,
}

/// Checks every argument of the action: nothing is sent for an action that cannot be made.
pub(super) fn check(args: &Args) -> Result<Checked, CliError> {
    let move_plan = match &args.action {
        Action::Move {
            target,
            abs,
            rel,
            speed,
            accel,
            binary,
            timeout_s,
            tolerance,
            min_pos,
            max_pos,
            poll_ms,
            ..
        } => {
            // A plain target is an absolute one, as `move 100` is in every family.
            Some(plan_move(
                target.or(*abs),
                *rel,
                *speed,
                *accel,
                *binary,
                *timeout_s,
                *tolerance,
                (*min_pos, *max_pos),
                *poll_ms,
            )?)
        }
        _ => None,
    };
    let mut checked = Checked {
        poll: move_plan.as_ref().map(|p| p.poll),
        move_plan,
        raw_wait: None,
        watch_interval: None,
        status_ids: Vec::new(),
    };
    match &args.action {
        Action::Raw { wait: true, timeout_s, poll_ms, .. } => {
            checked.raw_wait = Some(checked_s("--timeout-s", *timeout_s)?);
            checked.poll = Some(checked_ms("--poll-ms", *poll_ms, 1, 10_000)?);
        }
        Action::Watch { interval_ms, .. } => {
            checked.watch_interval = Some(checked_ms("--interval-ms", *interval_ms, 1, 60_000)?)
        }
        Action::Output { number, state } => {
            OutputState::new(*number, *state).map_err(model_error)?;
        }
        Action::Get { params } => {
            for param in params {
                ParamId::parse(param).map_err(model_error)?;
            }
        }
        Action::Set { param, value } => {
            ParamId::parse(param).and_then(|id| id.check(*value)).map_err(model_error)?;
        }
        Action::Status { values } if values.is_empty() => {
            checked.status_ids = [1, 2, 3, 16, 17, 18].iter().filter_map(|&n| StatusId::new(n).ok()).collect();
        }
        Action::Status { values } => {
            checked.status_ids =
                values.iter().map(|v| StatusId::parse(v)).collect::<Result<_, _>>().map_err(model_error)?;
        }
        _ => {}
    }
    Ok(checked)
}

/// `scan`: lists the drives that answer on the bus; none is an error.
pub(super) fn scan(args: &Args, bus: &Client, out: &mut dyn Write) -> Result<(), CliError> {
    // A signal ends the scan between two addresses.
    let found = bus.scan(1..=31).map_err(|e| error_for(args, e))?;
    if args.json {
        // A listing: one object per drive found (JSON Lines).
        for (a, p) in &found {
            common::print_json(
                out,
                &common::identified(
                    "compax",
                    &args.resolved_port,
                    json!({"drive": a.get(), "position_units": p.units()}),
                ),
            )?;
        }
    } else if found.is_empty() {
        writeln!(out, "no drive answered on {}", args.resolved_port)?;
    } else {
        let rows: Vec<Row> = found.iter().map(|(a, p)| (format!("drive {a}"), format!("S1 = {p} {UNITS}"))).collect();
        common::print_table(out, &rows)?;
    }
    if found.is_empty() {
        return Err(CliError::transport("no drive answered"));
    }
    Ok(())
}

/// `status`: reads and prints the status values `ids`.
pub(super) fn status(
    args: &Args,
    bus: &Client,
    drive: Address,
    ids: &[StatusId],
    out: &mut dyn Write,
) -> Result<(), CliError> {
    // A signal ends the reads between two values.
    let values = bus.read_statuses(drive, ids).map_err(|e| error_for(args, e))?;
    let (rows, js): (Vec<Row>, Vec<serde_json::Value>) = values.iter().map(|(id, v)| status_rows(*id, v)).unzip();
    if args.json {
        common::print_json(out, &identified(args, json!({"status": js})))?;
    } else {
        common::print_table(out, &rows)?;
    }
    Ok(())
}

/// `get`: reads and prints the parameters `params`.
pub(super) fn get(
    args: &Args,
    bus: &Client,
    drive: Address,
    params: &[String],
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let mut rows = Vec::new();
    for param in params {
        let id = ParamId::parse(param).map_err(model_error)?;
        let v = bus.read_param(drive, id).map_err(|e| error_for(args, e))?;
        let desc = id.description().unwrap_or("");
        if args.json {
            common::print_json(out, &identified(args, param_json(id, json!(v))))?;
        } else {
            rows.push((format!("{id} {desc}").trim_end().to_string(), with_unit(v, id.info().map_or("", |i| i.unit))));
        }
    }
    if !args.json {
        common::print_table(out, &rows)?;
    }
    Ok(())
}

/// `set`: writes the parameter `param`, reads it back and prints both.
pub(super) fn set(
    args: &Args,
    bus: &Client,
    drive: Address,
    param: &str,
    value: f64,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let fail = |e: Error| error_for(args, e);
    let id = ParamId::parse(param).map_err(model_error)?;
    // Written and read back: a value that reads back otherwise is an error (exit code 1).
    bus.write_param(drive, id, value).map_err(fail)?;
    // The library compared what it read back; the value the drive gives now is `read_back` (one drive is
    // addressed, 1..=31: it answers).
    let read_back = bus.read_param(drive, id).map_err(fail)?;
    let note = match id.info() {
        Some(i) if i.kind.valid_from == ValidFrom::PowerOn => " (takes effect at the drive's next power-on)",
        _ => "",
    };
    if args.json {
        let mut v = param_json(id, json!(value));
        v["read_back"] = json!(read_back);
        v["verified"] = json!(true);
        // Nothing it could not check (a value that reads back otherwise is an error), as every family says it.
        v["not_verifiable"] = json!([]);
        common::print_json(out, &identified(args, v))?;
    } else {
        writeln!(out, "{id} = {}, read back{note}", with_unit(value, id.info().map_or("", |i| i.unit)))?;
    }
    Ok(())
}

/// `move --no-wait`: starts the move and hands it over once the drive has taken it.
pub(super) fn move_no_wait(
    args: &Args,
    bus: &Client,
    drive: Address,
    plan: Option<&MovePlan>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let fail = |e: Error| error_for(args, e);
    let plan = plan.ok_or_else(|| CliError::usage("move: no plan"))?;
    // Handed over once its target is read back: the move runs on after this command exits (a signal
    // before that stops it instead).
    let started = bus.start_and_release(drive, &plan.request).map_err(fail)?;
    let now = bus.read_position(drive).map_err(fail)?;
    if args.json {
        common::print_json(
            out,
            &identified(
                args,
                json!({"target_units": started.target.units(), "position_units": now.units(),
                       "waited": false, "verified": started.not_verifiable.is_empty(),
                       "not_verifiable": started.not_verifiable}),
            ),
        )?;
    } else {
        writeln!(out, "drive {drive}: target {} {UNITS}, position {now} {UNITS} (moving on)", started.target)?;
        if !started.not_verifiable.is_empty() {
            writeln!(out, "not verified: {}", started.not_verifiable.join("; "))?;
        }
    }
    Ok(())
}

/// `move`: moves the axis with a progress bar, waits until it is at rest and prints where it came to rest.
pub(super) fn move_and_wait(
    args: &Args,
    bus: &Client,
    drive: Address,
    plan: Option<&MovePlan>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let plan = plan.ok_or_else(|| CliError::usage("move: no plan"))?;
    let bar = common::progress_bar(0, format!("drive {drive}"));
    let mut started_at: Option<f64> = None;
    let report = bus.move_to(drive, &plan.request, &mut |p| {
        let s = *started_at.get_or_insert_with(|| {
            let distance = match plan.request.target {
                MoveTarget::Absolute(t) => t.units() - p.units(),
                MoveTarget::Relative(d) => d.units(),
            };
            bar.set_length((distance.abs() * 1000.0).round() as u64);
            p.units()
        });
        bar.set_position(((p.units() - s).abs() * 1000.0).round() as u64);
    });
    bar.finish_and_clear();
    let report = report.map_err(|e| error_for(args, e))?;
    if args.json {
        common::print_json(
            out,
            &identified(
                args,
                json!({"target_units": report.target.units(), "reached_units": report.reached.units(),
                       "difference_units": report.difference(), "tolerance_units": plan.tolerance.units(),
                       "waited": true, "verified": report.verified, "not_verifiable": report.not_verifiable}),
            ),
        )?;
    } else {
        writeln!(out, "drive {drive}: target {} {UNITS}, position {} {UNITS}", report.target, report.reached)?;
        if !report.verified {
            writeln!(out, "not verified: {}", report.not_verifiable.join("; "))?;
        }
    }
    Ok(())
}

/// `output`: switches output `number` to `state`.
pub(super) fn output(
    args: &Args,
    bus: &Client,
    drive: Address,
    number: u16,
    state: u8,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let st = OutputState::new(number, state).map_err(model_error)?;
    bus.set_output(drive, number, st, false).map_err(|e| error_for(args, e))?;
    if args.json {
        common::print_json(out, &identified(args, json!({"output": number, "state": state})))?;
    } else {
        writeln!(out, "drive {drive}: OUTPUT O{number}={state}")?;
    }
    Ok(())
}

/// `stop`: stops the drive if it moves (S17; `OUTPUT O0=0`, the only stop there is, switches it off; S17
/// again), reads where it stands, and prints that; first what the motionlink that held the port said when
/// it was stopped, if one was.
pub(super) fn stop(
    args: &Args,
    bus: &Client,
    drive: Address,
    stopped: Option<&crate::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    if let (Some(h), false) = (stopped, args.json) {
        writeln!(out, "{}", h.describe())?;
    }
    let report = bus.stop_if_moving(&[drive]).map_err(|e| error_for(args, e))?;
    if !report.all_confirmed() {
        let mut message = report.to_string();
        for a in report.switched_off() {
            message.push('\n');
            message.push_str(&switch_on_hint(args, a.get()));
        }
        return Err(CliError::Device(message));
    }
    // The stop is confirmed by S17; then where the axis stands (S1) and whether the drive is switched on
    // (S16: this stop, or an earlier one, may have switched it off). What cannot be read is said.
    let position = bus.read_position(drive);
    let o0 = bus.read_s16(drive).map(|s| s.o0_state());
    if args.json {
        let mut fields = json!({"action": "stop", "holder": stopped,
                                "position_units": position.as_ref().ok().map(|p| p.units()),
                                "o0": o0.as_ref().ok()});
        if let (Some(map), Ok(serde_json::Value::Object(r))) = (fields.as_object_mut(), serde_json::to_value(&report)) {
            map.extend(r);
        }
        for (key, e) in [("position_not_read", position.as_ref().err()), ("o0_not_read", o0.as_ref().err())] {
            if let Some(e) = e {
                fields[key] = json!(e.to_string());
            }
        }
        common::print_json(out, &identified(args, fields))?;
        return Ok(());
    }
    match &position {
        Ok(p) => writeln!(out, "{report}; at rest at {p} {UNITS} (S17 and S1 read back)")?,
        Err(e) => writeln!(out, "{report}; at rest (S17 read back), but the position could not be read: {e}")?,
    }
    match o0 {
        Ok(1) => {}
        Ok(_) => writeln!(out, "{}", switch_on_hint(args, drive.get()))?,
        Err(e) => writeln!(out, "whether drive {drive} is switched on could not be read (S16): {e}")?,
    }
    Ok(())
}

/// `raw`: sends `command` as it is and prints the reply; `wait` is how long to wait for a move it starts.
pub(super) fn raw(
    args: &Args,
    bus: &Client,
    drive: Address,
    command: &str,
    wait: Option<Duration>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    // A move it starts is waited for (--wait) or handed over: it runs on after the command exits.
    let after = wait.map_or(AfterRaw::HandOver, AfterRaw::Wait);
    let outcome = bus.raw_motion(drive, command, after).map_err(|e| error_for(args, e))?;
    if args.json {
        common::print_json(
            out,
            &identified(args, json!({"command": command, "reply": outcome.reply, "waited": outcome.waited})),
        )?;
    } else {
        match outcome.reply {
            Some(r) if r.is_empty() => writeln!(out, "(acknowledged)")?,
            Some(r) => writeln!(out, "{r}")?,
            None => writeln!(out, "(no reply due)")?,
        }
    }
    Ok(())
}

/// `send`: sends one command and prints it and the drive's reply as they went on the line, each explained.
pub(super) fn send(
    args: &Args,
    tap: &Tap,
    bus: &Client,
    drive: Address,
    words: &[String],
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let command = send_text(words)?;
    let telegrams = tap.telegrams().ok_or_else(|| CliError::usage("send: no tap on the link"))?;
    telegrams.clear();
    // A move it starts is waited for (a signal stops it), as `raw --wait` does.
    let result = bus.raw_motion(drive, &command, AfterRaw::Wait(Duration::from_secs(600)));
    let seen = telegrams.take();
    // The command's reply is the first telegram from the drive after it; the status polls of a wait
    // come after that reply and are told apart.
    let (sent, reply, after) = crate::tap::first_exchange(&seen, command.as_bytes());
    let polls = after.iter().filter(|a| a.direction == motionlink_link::describe::Direction::ToDevice).count();
    let (sent_json, reply_json) = crate::tap::print_exchange(out, args.json, sent.as_ref(), reply.as_ref())?;
    if args.json {
        let reply_text = result.as_ref().ok().and_then(|o| o.reply.clone());
        common::print_json(
            out,
            &identified(
                args,
                json!({"command": command, "request": sent_json, "reply": reply_json,
                       "reply_text": reply_text, "polls": polls, "ok": result.is_ok()}),
            ),
        )?;
    } else if polls > 0 {
        writeln!(out, "then {polls} status polls until the move ended (-v shows them)")?;
    }
    result.map_err(|e| error_for(args, e))?;
    Ok(())
}
