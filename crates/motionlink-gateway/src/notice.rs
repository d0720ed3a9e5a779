//! The gateway's notices on stderr (what it serves, a stop from another process, a port that failed): one
//! line each, as it is, or with `--json` as `{"log": "<line>"}`, the form of every motionlink command's
//! log lines, so that stderr carries JSON lines only.

use std::sync::atomic::{AtomicBool, Ordering};

static JSON: AtomicBool = AtomicBool::new(false);

/// Notices as JSON lines (`{"log": ...}`) from now on, or as plain lines (`--json` of the command line).
pub fn set_json(on: bool) {
    JSON.store(on, Ordering::Relaxed);
}

/// True when notices are JSON lines.
pub fn json() -> bool {
    JSON.load(Ordering::Relaxed)
}

/// Writes one notice line on stderr, in the form [`set_json`] chose, and ignores a failure: stderr closed,
/// or its terminal gone after SIGHUP, must not end the gateway before it has stopped and closed its devices
/// (`eprintln!` would panic).
pub fn line(text: &str) {
    let line = if json() { serde_json::json!({ "log": text }).to_string() } else { text.to_string() };
    write_stderr(&line);
}

/// Writes `line` and a line end on stderr, ignoring a failure (see [`line()`]).
pub fn write_stderr(line: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "{line}");
}

/// [`line`] with `format!` arguments.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::notice::line(&format!($($arg)*))
    };
}
pub(crate) use say;
