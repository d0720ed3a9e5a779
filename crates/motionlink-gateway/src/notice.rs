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

/// Writes one notice line on stderr, in the form [`set_json`] chose.
pub fn line(text: &str) {
    if json() {
        eprintln!("{}", serde_json::json!({ "log": text }));
    } else {
        eprintln!("{text}");
    }
}

/// [`line`] with `format!` arguments.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::notice::line(&format!($($arg)*))
    };
}
pub(crate) use say;
