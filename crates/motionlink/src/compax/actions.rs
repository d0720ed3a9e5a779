//! The actions of `motionlink compax`: their arguments checked before the port is opened, then one function
//! per action. Each prints the library's report: as it serialises with `--json`, in words otherwise.

use motionlink_compax::report::{DrivePosition, ParamReading, StatusReport, StopResult};
use motionlink_compax::session::{Progress, RawOutcome, StartedMove};
use motionlink_compax::wire::request::check_raw;

use super::*;

/// What a COMPAX position is in, in text: the drive's own unit (set in the drive; the JSON keys say
/// `_units`).
pub(super) const UNITS: &str = "units";

/// The arguments of `move`, checked before anything is sent.
pub(super) struct MovePlan {
    pub(super) request: MoveRequest,
    pub(super) tolerance: Tolerance,
}

/// The arguments of an action that their types alone do not check, checked before the port is opened.
#[derive(Default)]
pub(super) struct Checked {
    /// `move`: the move, planned.
    pub(super) move_plan: Option<MovePlan>,
    /// The interval of the status polls (`move`, `raw --wait`).
    pub(super) poll: Option<Duration>,
    /// `raw --wait`: how long to wait for a move the command started.
    pub(super) raw_wait: Option<Duration>,
    /// `output`: the output and its state.
    pub(super) output: Option<(u16, OutputState)>,
    /// `status`: the values to read.
    pub(super) status_ids: Vec<StatusId>,
}

/// Checks every argument of the action: nothing is sent for an action that cannot be made.
pub(super) fn check(args: &Args) -> Result<Checked, CliError> {
    let mut checked = Checked::default();
    match &args.action {
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
            let target = MoveTarget::from_args(target.or(*abs), *rel).map_err(CliError::usage)?;
            let limits = TravelLimits::new(*min_pos, *max_pos)
                .map_err(|e| CliError::usage(format!("--min-pos / --max-pos: {e}")))?;
            let (speed, accel, binary, timeout) = (*speed, *accel, *binary, Some(timeout_s.duration()));
            let request = MoveRequest { target, speed, accel, binary, limits, timeout };
            checked.move_plan = Some(MovePlan { request, tolerance: *tolerance });
            checked.poll = Some(poll_ms.duration());
        }
        Action::Raw { command, wait, timeout_s, poll_ms, .. } => {
            check_raw(command).map_err(CliError::usage)?;
            if *wait {
                checked.raw_wait = Some(timeout_s.duration());
                checked.poll = Some(poll_ms.duration());
            }
        }
        // A command that cannot be sent (empty, too long, ...) is refused before the port is opened, with
        // no exchange printed.
        Action::Send { words } => check_raw(&send_text(words)?).map_err(CliError::usage)?,
        Action::Output { number, state } => {
            checked.output = Some((number.get(), state.for_output(*number).map_err(CliError::usage)?))
        }
        Action::Set { param, value } => param.check(*value).map_err(CliError::usage)?,
        Action::Status { values } if values.is_empty() => checked.status_ids = StatusId::OVERVIEW.to_vec(),
        Action::Status { values } => checked.status_ids = values.clone(),
        _ => {}
    }
    Ok(checked)
}

/// `scan`: lists the drives that answer on the bus; none is an error.
pub(super) fn scan(args: &Args, bus: &Client, out: &mut dyn Write) -> Result<(), CliError> {
    // A signal ends the scan between two addresses; each address without a drive waits out the reply
    // timeout twice, so the bar shows where the scan is.
    let bar = common::progress_bar(31, "scan");
    let scanned = bus.scan_with(1..=31, &mut |p| {
        if let Progress::Scan { drive, index, .. } = p {
            bar.set_position(*index as u64);
            bar.set_message(format!("scan: address {drive}"));
        }
    });
    bar.finish_and_clear();
    let found: Vec<DrivePosition> =
        scanned.map_err(|e| error_for(args, e))?.into_iter().map(DrivePosition::from).collect();
    if crate::term::json() {
        // A listing: one object per drive found (JSON Lines).
        for d in &found {
            Out { unit: None, ..args.out() }.print(out, d)?;
        }
    } else if found.is_empty() {
        writeln!(out, "no drive answered on {}", args.resolved_port)?;
    } else {
        let rows: Vec<Row> =
            found.iter().map(|d| (format!("drive {}", d.drive), format!("S1 = {} {UNITS}", d.position))).collect();
        common::print_table(out, &rows)?;
    }
    if found.is_empty() {
        return Err(CliError::transport("no drive answered"));
    }
    Ok(())
}

/// `status`: reads and prints the status values `ids`.
pub(super) fn status(args: &Args, bus: &Client, ids: &[StatusId], out: &mut dyn Write) -> Result<(), CliError> {
    // A signal ends the reads between two values.
    let report = StatusReport::from(bus.read_statuses(args.drive, ids).map_err(|e| error_for(args, e))?);
    if crate::term::json() {
        args.out().print(out, &report)
    } else {
        common::print_table(out, &report.status.iter().map(status_row).collect::<Vec<_>>())
    }
}

/// `get`: reads and prints the parameters `params`.
pub(super) fn get(args: &Args, bus: &Client, params: &[ParamId], out: &mut dyn Write) -> Result<(), CliError> {
    let mut rows = Vec::new();
    for &id in params {
        let reading = ParamReading { id, value: bus.read_param(args.drive, id).map_err(|e| error_for(args, e))? };
        if crate::term::json() {
            args.out().print(out, reading)?;
        } else {
            let name = format!("{id} {}", id.description().unwrap_or("")).trim_end().to_string();
            rows.push((name, common::with_unit(reading.value, reading.unit())));
        }
    }
    if !crate::term::json() {
        common::print_table(out, &rows)?;
    }
    Ok(())
}

/// `set`: writes the parameter `id`, reads it back and prints both.
pub(super) fn set(args: &Args, bus: &Client, id: ParamId, value: f64, out: &mut dyn Write) -> Result<(), CliError> {
    // Written and read back: a value that reads back otherwise is an error (exit code 1).
    let written = bus.set_param(args.drive, id, value).map_err(|e| error_for(args, e))?;
    if crate::term::json() {
        return args.out().print(out, written);
    }
    let note = match (written.at_power_on(), written.power_on_note()) {
        (true, Some(warning)) => format!(" (takes effect at the drive's next power-on; {warning})"),
        (true, None) => " (takes effect at the drive's next power-on)".to_string(),
        (false, _) => String::new(),
    };
    writeln!(out, "{id} = {}, read back{note}", common::with_unit(value, written.written.unit()))?;
    Ok(())
}

/// `move --no-wait`'s result: the move the drive took, and where the axis was once it had taken it.
#[derive(serde::Serialize)]
struct HandedOver<'a> {
    #[serde(flatten)]
    started: &'a StartedMove,
    position_units: Position,
}

/// `move`: moves the axis and prints where it came to rest (with `no_wait`: starts the move and hands it
/// over once the drive has taken it).
pub(super) fn move_drive(
    args: &Args,
    bus: &Client,
    plan: Option<&MovePlan>,
    no_wait: bool,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let fail = |e: Error| error_for(args, e);
    let (plan, drive) = (plan.ok_or_else(|| CliError::usage("move: no plan"))?, args.drive);
    if no_wait {
        // Handed over once its target is read back: the move runs on after this command exits (a signal
        // before that stops it instead).
        let started = bus.start_and_release(drive, &plan.request).map_err(fail)?;
        let now = bus.read_position(drive);
        let now = now.map_err(|e| handed_over_then(args, &[drive], fail(e)))?;
        if crate::term::json() {
            args.out().print(out, &HandedOver { started: &started, position_units: now })?;
        } else {
            writeln!(out, "drive {drive}: target {} {UNITS}, position {now} {UNITS} (moving on)", started.target)?;
            common::not_verified(out, &started.not_verifiable)?;
        }
        return signal_after_hand_over(args, &[drive]);
    }
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
    let report = report.map_err(fail)?;
    if crate::term::json() {
        return args.out().print(out, &report);
    }
    writeln!(out, "drive {drive}: target {} {UNITS}, position {} {UNITS}", report.target, report.reached)?;
    common::not_verified(out, &report.not_verifiable)
}

/// `output`: switches the output to its state.
pub(super) fn output(
    args: &Args,
    bus: &Client,
    output: Option<(u16, OutputState)>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let (number, state) = output.ok_or_else(|| CliError::usage("output: not checked"))?;
    // O0 read back from S16 (another state is an error); another output cannot be read: said so.
    let switched = bus.switch_output(args.drive, number, state).map_err(|e| error_for(args, e))?;
    if crate::term::json() {
        return args.out().print(out, &switched);
    }
    let read = if switched.verified { " (S16 read back)" } else { "" };
    writeln!(out, "drive {}: OUTPUT O{number}={}{read}", args.drive, state.get())?;
    common::not_verified(out, &switched.not_verifiable)
}

/// `stop`: stops the drive if it moves (S17; `OUTPUT O0=0`, the only stop there is, switches it off; S17
/// again), reads where it stands, and prints that; first what the motionlink that held the port said when
/// it was stopped, if one was.
pub(super) fn stop(
    args: &Args,
    bus: &Client,
    stopped: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    args.out().holder(out, stopped)?;
    let drive = args.drive;
    // Not confirmed: the error says so (with how to switch on a drive it switched off), exit 3. Confirmed
    // by S17; then where the axis stands (S1) and whether the drive is switched on (S16: this stop, or an
    // earlier one, may have switched it off). What cannot be read is said.
    let stop = bus.stop_confirmed(drive).map_err(|e| error_for(args, e))?;
    if crate::term::json() {
        return args.out().print(out, StopResult::new(stopped, stop));
    }
    let report = &stop.report;
    match (&stop.position_units, &stop.position_not_read) {
        (Some(p), _) => writeln!(out, "{report}; at rest at {p} {UNITS} (S17 and S1 read back)")?,
        (None, why) => writeln!(
            out,
            "{report}; at rest (S17 read back), but the position could not be read: {}",
            why.as_deref().unwrap_or("no reply")
        )?,
    }
    match (stop.o0, &stop.o0_not_read) {
        (Some(1), _) => {}
        (Some(_), _) => writeln!(out, "{}", switch_on_hint(args, drive.get()))?,
        (None, why) => writeln!(
            out,
            "whether drive {drive} is switched on could not be read (S16): {}",
            why.as_deref().unwrap_or("no reply")
        )?,
    }
    Ok(())
}

/// `raw`'s result: the command as given, then what it did.
#[derive(serde::Serialize)]
struct Raw<'a> {
    command: &'a str,
    #[serde(flatten)]
    outcome: &'a RawOutcome,
}

/// `raw`: sends `command` as it is and prints the reply; `wait` is how long to wait for a move it starts.
pub(super) fn raw(
    args: &Args,
    bus: &Client,
    command: &str,
    broadcast: bool,
    wait: Option<Duration>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    // A move it starts is waited for (--wait) or handed over: it runs on after the command exits.
    let after = wait.map_or(AfterRaw::HandOver, AfterRaw::Wait);
    let to = if broadcast { Address::BROADCAST } else { args.drive };
    let outcome = bus.raw_motion(to, command, after).map_err(|e| error_for(args, e))?;
    let handed_over = if outcome.waited { &[][..] } else { &outcome.started[..] };
    if crate::term::json() {
        args.out().print(out, &Raw { command, outcome: &outcome })?;
    } else {
        match &outcome.reply {
            Some(r) if r.is_empty() => writeln!(out, "(acknowledged)")?,
            Some(r) => writeln!(out, "{r}")?,
            None => writeln!(out, "(no reply due)")?,
        }
    }
    if broadcast && motionlink_compax::client::raw_may_start_motion(command) {
        // No drive answers a broadcast: which of them took it (and move) this command cannot know.
        common::say(format!(
            "motionlink: sent to every drive (address 32, no drive answers): each drive that took it may be moving \
             on, not stopped by this command (COMPAX has no watchdog); `{} --drive N stop` stops drive N",
            super::same_line(args)
        ));
    } else if !handed_over.is_empty() {
        let mut said = moving_on(args, handed_over);
        if motionlink_compax::wire::Request::raw(args.drive, command).flags.echo {
            // The manual does not say whether a drive carries out what it echoes: the move is taken as started.
            said = said.replacen(
                " moving on:",
                " may be moving on (the manual does not say whether a drive carries out a command it echoes):",
                1,
            );
        }
        common::say(format!("motionlink: {said}"));
    }
    signal_after_hand_over(args, handed_over)
}

/// What a command that handed moves over says of them: they run on, and how to stop them (a command on the
/// same port and bus settings).
fn moving_on(args: &Args, drives: &[Address]) -> String {
    let list = drives.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ");
    let first = drives.first().map_or(1, |a| a.get());
    format!(
        "drive {list} moving on: handed over, not stopped by this command (COMPAX has no watchdog); `{} --drive \
         {first} stop` stops it",
        super::same_line(args)
    )
}

/// `e`, which came after the moves of `drives` were handed over: it says that they run on.
fn handed_over_then(args: &Args, drives: &[Address], e: CliError) -> CliError {
    e.map_message(|m| format!("{m}; {}", moving_on(args, drives)))
}

/// The end of a command that handed the moves of `drives` over: a signal that came meanwhile ends it (exit
/// 128 + n) saying that they were not stopped.
fn signal_after_hand_over(args: &Args, drives: &[Address]) -> Result<(), CliError> {
    match common::stop_cause() {
        Some(cause @ common::StopCause::Signal(_)) if !drives.is_empty() => Err(CliError::Interrupted(format!(
            "{} came after the move was handed over; {}",
            cause.name(),
            moving_on(args, drives)
        ))),
        _ => Ok(()),
    }
}

/// What `send --json` has besides the exchange ([`crate::tap::Sent`]): the reply's text and the status polls
/// of a wait after it.
#[derive(serde::Serialize)]
struct SentExtra {
    reply_text: Option<String>,
    polls: usize,
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
    // A move it starts is waited for (a signal stops it), as `raw --wait` does.
    let wait = AfterRaw::Wait(Duration::from_secs(600));
    let (result, seen) = tap.seen_during(|| bus.raw_motion(drive, &command, wait))?;
    // A usage error (a command that cannot be built) sent nothing: there is no exchange to print, only the
    // error.
    let result = match result {
        Err(e) if e.class() == ErrorClass::Usage => return Err(error_for(args, e)),
        r => r,
    };
    // The command's reply is the first telegram from the drive after it; the status polls of a wait
    // come after that reply and are told apart.
    let (sent, reply, after) = crate::tap::first_exchange(&seen, command.as_bytes());
    let polls = after.iter().filter(|a| a.direction == motionlink_link::chunk::Direction::ToDevice).count();
    let extra = SentExtra { reply_text: result.as_ref().ok().and_then(|o| o.reply.clone()), polls };
    crate::tap::print_sent(out, &args.out(), (sent, reply), &command, result.is_ok(), extra)?;
    if !crate::term::json() && polls > 0 {
        writeln!(out, "then {polls} status polls until the move ended (-v shows them)")?;
    }
    result.map_err(|e| error_for(args, e))?;
    Ok(())
}
