//! What `motionlink compax` prints: status rows, parameters as JSON, `send` text and `watch`.

use super::*;

pub(super) fn status_rows(id: StatusId, v: &StatusValue) -> (Row, serde_json::Value) {
    let info = id.info();
    let name = info.map_or("(meaning not documented)", |i| i.title);
    let unit = info.map_or("", |i| i.unit);
    let (shown, js) = match v {
        StatusValue::S16(b) => {
            let bits = b.pattern().to_string();
            (format!("{bits}  [{}]", b.meanings().join(", ")), bits_json(*b, bits))
        }
        StatusValue::S17(b) => {
            let bits = b.pattern().to_string();
            (format!("{bits}  [{}]", b.meanings().join(", ")), bits_json(*b, bits))
        }
        // A position is in the drive's own unit (the table says "unit"): "units" in text, as in the JSON keys.
        StatusValue::Position(p) => (format!("{v} {}", super::actions::UNITS), json!(p.units())),
        StatusValue::Number(n) => (format!("{v} {unit}").trim_end().to_string(), json!(n)),
        other => (other.to_string(), json!(other.to_string())),
    };
    ((format!("{id} {name}"), shown), json!({"status": id.to_string(), "name": name, "unit": unit, "value": js}))
}

/// S16 or S17 as JSON: the flag word (`word`, `flags`, `unknown_bits`) and `pattern`, the drive's own bit
/// string ("1101 1010").
pub(super) fn bits_json<W: motionlink_link::flags::FlagWord>(word: W, pattern: String) -> serde_json::Value {
    let mut v = common::flag_word_json(word);
    v["pattern"] = json!(pattern);
    v
}

/// A parameter as JSON: name, id, value, unit and access (naming.md).
pub(super) fn param_json(id: ParamId, value: serde_json::Value) -> serde_json::Value {
    let info = id.info();
    json!({"name": id.to_string(), "id": id.get(), "value": value, "unit": info.map_or("", |i| i.unit),
           "access": info.map_or("rw", |i| i.access.short())})
}

/// The text of `send`'s command: words joined by spaces, or characters given in hex (printable ASCII).
pub(super) fn send_text(words: &[String]) -> Result<String, CliError> {
    let joined = words.join(" ");
    let looks_hex = words.iter().all(|w| w.len() == 2 && w.chars().all(|c| c.is_ascii_hexdigit()));
    if !looks_hex {
        return Ok(joined);
    }
    let bytes = common::parse_hex(&joined)?;
    let text: String = bytes.iter().map(|&b| char::from(b)).collect();
    let text = text.trim_end_matches(['\r', '\n']).to_string();
    if text.is_empty() || !text.chars().all(|c| c.is_ascii_graphic() || c == ' ') {
        return Err(CliError::usage(format!("{joined:?}: the characters of a command in hex (printable ASCII)")));
    }
    Ok(text)
}

/// `watch`: samples of one drive until `count` is reached, a signal arrives or nobody reads any more.
#[allow(clippy::too_many_arguments)]
pub(super) fn watch(
    args: &Args,
    bus: &Client,
    drive: Address,
    clock: &SharedClock,
    interval: Duration,
    count: &Option<u64>,
    csv: bool,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let token = common::interrupt_token();
    let started = clock.now();
    let mut written =
        if csv { writeln!(out, "t_s,drive,position_units,moving,s17").and_then(|()| out.flush()) } else { Ok(()) };
    let mut n = 0u64;
    let watched = bus.watch(drive, interval, &mut |s| {
        if count.is_some_and(|c| n >= c) {
            return;
        }
        let t_s = (clock.now() - started).as_secs_f64();
        let line = if csv {
            let fields = [
                format!("{t_s:.3}"),
                drive.get().to_string(),
                s.position.units().to_string(),
                s.moving().to_string(),
                s.s17.pattern().to_string(),
            ];
            common::csv_line(&fields)
        } else if args.json {
            identified(
                args,
                json!({"t_s": t_s, "position_units": s.position.units(),
                       "s17": bits_json(s.s17, s.s17.pattern().to_string()), "moving": s.moving()}),
            )
            .to_string()
        } else {
            let rest = if s.moving() { "moving" } else { "at rest" };
            format!("drive {drive}  S1 = {} {}  {rest}", s.position, super::actions::UNITS)
        };
        if written.is_ok() {
            written = writeln!(out, "{line}").and_then(|()| out.flush());
            n += 1;
            if written.is_err() || count.is_some_and(|c| n >= c) {
                // Nobody reads any more, or enough samples: the watch ends.
                token.cancel();
            }
        }
    });
    let counted = count.is_some_and(|c| n >= c) && common::stop_cause().is_none();
    match watched {
        Err(e) if !counted => return Err(error_for(args, e)),
        _ => {}
    }
    written?;
    // Interrupted: a signal ends the command with 128 + n (main), a closed stdout quietly.
    if common::stop_cause() == Some(common::StopCause::OutputClosed) {
        return Err(CliError::OutputClosed);
    }
    Ok(())
}
