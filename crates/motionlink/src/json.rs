//! The JSON forms the command line writes (one object per line): a value under a name known at run time, a
//! result as a JSON value, a telegram of a capture or of the wire trace. A leaf: the terminal, the output
//! and the decoder all write through it.

use motionlink_link::describe::Annotation;

/// `value` under a name known only at run time (`"module": 3`, `{"log": "..."}`): the link crate's.
pub use motionlink_link::result::Named as Keyed;

/// A result (a library report, which serialises with the names `--json` shows) as a JSON value.
pub fn to_json<T: serde::Serialize + ?Sized>(result: &T) -> serde_json::Value {
    // A report of plain fields always serialises; a failure would be a library defect, shown, not hidden.
    serde_json::to_value(result).unwrap_or_else(|e| serde_json::Value::String(format!("(not serialisable: {e})")))
}

/// One annotation as `--json` shows it (the names of docs/cli.md, "JSON output").
#[derive(Debug, serde::Serialize)]
pub struct Telegram<'a> {
    /// Seconds since the Unix epoch, when known.
    pub time_s: Option<f64>,
    /// `->`, `<-` or `?`.
    pub direction: &'static str,
    /// The bytes (a frame's data) in hex.
    pub bytes: String,
    /// What it means, or what is wrong with it.
    pub meaning: &'a str,
    /// True when it is not a valid telegram.
    pub bad: bool,
    /// The CAN identifier: with a frame of a capture, and always in the wire trace (null for serial bytes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub can_id: Option<Option<u32>>,
    /// The CAN interface of a frame of a capture ("" when the line names none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interface: Option<&'a str>,
    /// The frame of a capture as candump writes it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame: Option<String>,
}

impl<'a> Telegram<'a> {
    /// Annotation `a`, of `frame` (its interface and the frame) when it came from a CAN frame of a capture.
    pub fn of(a: &'a Annotation, frame: Option<(&'a str, &motionlink_link::can::CanFrame)>) -> Telegram<'a> {
        Telegram {
            time_s: a.at.map(|t| t.since_origin().as_secs_f64()),
            direction: a.direction.arrow(),
            bytes: motionlink_link::hex::hex(&a.bytes),
            meaning: &a.meaning,
            bad: a.bad,
            can_id: frame.map(|(_, f)| Some(f.id())),
            interface: frame.map(|(i, _)| i),
            frame: frame.map(|(_, f)| f.to_string()),
        }
    }
}
