//! What `motionlink compax` prints: status rows, `send` text and `watch`.

use motionlink_compax::report::{StatusReading, Timed};

use super::*;

/// A status value as a row of `status`: "S16 status bits S16", then the value in words.
pub(super) fn status_row(r: &StatusReading) -> Row {
    let shown = match &r.value {
        StatusValue::S16(b) => format!("{}  [{}]", b.pattern(), b.meanings().join(", ")),
        StatusValue::S17(b) => format!("{}  [{}]", b.pattern(), b.meanings().join(", ")),
        // A position is in the drive's own unit (the table says "unit"): "units" in text, as in the JSON keys.
        v @ StatusValue::Position(_) => format!("{v} {}", super::actions::UNITS),
        v @ StatusValue::Number(_) => format!("{v} {}", r.unit()).trim_end().to_string(),
        other => other.to_string(),
    };
    (format!("{} {}", r.id, r.name()), shown)
}

/// The text of `send`'s command: words joined by spaces, or characters given in hex (printable ASCII).
pub(super) fn send_text(words: &[String]) -> Result<String, CliError> {
    let joined = words.join(" ");
    let looks_hex = words.iter().all(|w| w.len() == 2 && w.chars().all(|c| c.is_ascii_hexdigit()));
    if !looks_hex {
        return Ok(joined);
    }
    let bytes = motionlink_link::hex::parse_hex(&joined).map_err(CliError::usage)?;
    let text: String = bytes.iter().map(|&b| char::from(b)).collect();
    let text = text.trim_end_matches(['\r', '\n']).to_string();
    if text.is_empty() || !text.chars().all(|c| c.is_ascii_graphic() || c == ' ') {
        return Err(CliError::usage(format!("{joined:?}: the characters of a command in hex (printable ASCII)")));
    }
    Ok(text)
}

/// `watch`: samples of one drive until `count` is reached, a signal arrives or nobody reads any more.
pub(super) fn watch(
    args: &Args,
    bus: &Client,
    clock: &SharedClock,
    interval: Duration,
    count: &Option<u64>,
    csv: bool,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let token = common::interrupt_token();
    let (drive, started) = (args.drive, clock.now());
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
        } else if crate::term::json() {
            let mut line = Vec::new();
            match args.out().print(&mut line, Timed { t_s, sample: *s }) {
                Ok(()) => String::from_utf8_lossy(&line).trim_end().to_string(),
                Err(e) => e.to_string(),
            }
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
