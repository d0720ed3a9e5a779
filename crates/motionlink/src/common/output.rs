//! What a family command prints: tables, JSON lines with the result's identity, CSV, the `watch` formats.

use std::io::Write;
use std::sync::OnceLock;

use super::CliError;
pub use crate::json::{to_json, Keyed};

/// One row of a human-readable table: a name and a value.
pub type Row = (String, String);

/// Prints `rows` as an aligned two-column table.
pub fn print_table(out: &mut dyn Write, rows: &[Row]) -> Result<(), CliError> {
    let width = rows.iter().map(|(k, _)| k.chars().count()).max().unwrap_or(0);
    for (k, v) in rows {
        writeln!(out, "{k:<width$}  {v}")?;
    }
    Ok(())
}

/// Prints `value` as JSON on one line (keys in alphabetical order, as every JSON line of the command line).
pub fn print_json<T: serde::Serialize + ?Sized>(out: &mut dyn Write, value: &T) -> Result<(), CliError> {
    writeln!(out, "{}", to_json(value))?;
    Ok(())
}

/// The device profile the command's session took (`<path>#<key>`), once it looked for one.
static PROFILE: OnceLock<Option<String>> = OnceLock::new();

/// Records the device profile the command's session took (`None`: none): every JSON object of the command
/// names it from now on (`"profile"`).
pub fn set_profile(reference: Option<String>) {
    let _ = PROFILE.set(reference);
}

/// Prints a family command's result as one JSON object: `family`, `port` and `profile` first
/// , then `identity` (the unit the command names: `module`, `drive`), then the result's own
/// fields, as it serialises.
pub fn print_result<T: serde::Serialize + ?Sized>(
    out: &mut dyn Write,
    family: &str,
    port: &str,
    identity: &[(&str, serde_json::Value)],
    result: &T,
) -> Result<(), CliError> {
    // Once the session looked for a device profile, `profile` comes first (null: none taken).
    let profile = PROFILE.get().map(|p| ("profile", serde_json::Value::from(p.clone())));
    let keys: Vec<(&str, serde_json::Value)> = profile.into_iter().chain(identity.iter().cloned()).collect();
    // A report of plain fields always serialises; a failure would be a library defect, shown, not hidden.
    let shown = motionlink_link::result::identified(family, port, &keys, result)
        .unwrap_or_else(|e| serde_json::Value::String(format!("(not serialisable: {e})")));
    print_json(out, &shown)
}

/// How a family command prints its results: with `--json` each as the library's report serialises (the
/// identity keys first: [`print_result`]), else as text made from the same report.
#[derive(Debug, Clone, Copy)]
pub struct Out<'a> {
    /// `--json`.
    pub json: bool,
    /// "scu", "powercube" or "compax".
    pub family: &'static str,
    /// The port, as given or resolved.
    pub port: &'a str,
    /// The unit the command names (`("module", 3)`, `("drive", 1)`), where it names one.
    pub unit: Option<(&'static str, u8)>,
}

impl Out<'_> {
    /// Prints `result` as one JSON object: `family`, `port`, `profile`, the unit, then its own fields.
    pub fn print(&self, out: &mut dyn Write, result: impl serde::Serialize) -> Result<(), CliError> {
        let identity: Vec<(&str, serde_json::Value)> = self.unit.iter().map(|&(k, n)| (k, n.into())).collect();
        print_result(out, self.family, self.port, &identity, &result)
    }

    /// `result` as JSON (`--json`), else as `text` writes it.
    pub fn show<R: serde::Serialize>(
        &self,
        out: &mut dyn Write,
        result: &R,
        text: impl FnOnce(&mut dyn Write, &R) -> Result<(), CliError>,
    ) -> Result<(), CliError> {
        match self.json {
            true => self.print(out, result),
            false => text(out, result),
        }
    }

    /// `stop`: in text, first what the motionlink that held the port said when it was stopped, if one was.
    pub fn holder(
        &self,
        out: &mut dyn Write,
        stopped: Option<&motionlink_link::portlock::Stopped>,
    ) -> Result<(), CliError> {
        if let (Some(h), false) = (stopped, self.json) {
            writeln!(out, "{}", h.describe())?;
        }
        Ok(())
    }
}

/// What a motion could not verify, one line of text (nothing when it verified everything).
pub fn not_verified(out: &mut dyn Write, why: &[String]) -> Result<(), CliError> {
    if !why.is_empty() {
        writeln!(out, "not verified: {}", why.join("; "))?;
    }
    Ok(())
}

/// `number` followed by `unit` (no unit: the number alone).
pub fn with_unit(number: impl std::fmt::Display, unit: &str) -> String {
    if unit.is_empty() {
        number.to_string()
    } else {
        format!("{number} {unit}")
    }
}

/// How `watch` prints its samples: `--csv`, `--json` or text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WatchFormat {
    /// One line of text per sample.
    Text,
    /// One JSON object per sample.
    Json,
    /// A CSV header, then lines of values.
    Csv,
}

impl WatchFormat {
    /// The format `--csv` and `--json` ask for (not both).
    pub fn of(csv: bool, json: bool) -> Result<WatchFormat, CliError> {
        match (csv, json) {
            (true, true) => Err(CliError::usage("--csv and --json: give one of them")),
            (true, false) => Ok(WatchFormat::Csv),
            (false, true) => Ok(WatchFormat::Json),
            (false, false) => Ok(WatchFormat::Text),
        }
    }
}

/// One line of CSV: fields separated by commas, quoted when they hold a comma, a quote or a line break.
pub fn csv_line(fields: &[String]) -> String {
    let quoted: Vec<String> = fields
        .iter()
        .map(|f| if f.contains([',', '"', '\n', '\r']) { format!("\"{}\"", f.replace('"', "\"\"")) } else { f.clone() })
        .collect();
    quoted.join(",")
}

pub use crate::term::progress_bar;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_only_what_needs_it() {
        let line = csv_line(&["1.5".into(), "a,b".into(), "say \"hi\"".into(), String::new()]);
        assert_eq!(line, "1.5,\"a,b\",\"say \"\"hi\"\"\",");
    }
}
