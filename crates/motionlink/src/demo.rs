//! Where `motionlink demo` writes: text for a reader, or with `--json` one object per line: each telegram as
//! `{"family", "step", "time_s", "direction", "bytes", "meaning"}` (the fields of `decode`'s objects), every
//! other line of the text as `{"family", "note"}`.

use std::io::Write;

use crate::common::CliError;

/// The demo's output of one family.
pub struct DemoOut<'a> {
    out: &'a mut dyn Write,
    json: bool,
    family: &'static str,
    step: Option<String>,
    /// Text written through `Write` in JSON mode, up to its line end.
    pending: Vec<u8>,
}

/// One telegram of the demo, as it goes into the JSON object.
#[derive(serde::Serialize)]
pub struct DemoTelegram<'t> {
    /// Device time of the telegram, seconds, when the demo knows it.
    pub time_s: Option<f64>,
    /// `->` (to the device), `<-` (from it), `!!` (not a valid telegram).
    pub direction: &'t str,
    /// The bytes (or the CAN frame) in hex.
    pub bytes: &'t str,
    /// What the library's describer says it means.
    pub meaning: &'t str,
}

impl<'a> DemoOut<'a> {
    /// The output of `family`'s part of the demo into `out`, as text or JSON lines.
    pub fn new(out: &'a mut dyn Write, json: bool, family: &'static str) -> Self {
        DemoOut { out, json, family, step: None, pending: Vec::new() }
    }

    /// Whether the output is JSON (the text's decorations, such as colours, are then left out).
    pub fn is_json(&self) -> bool {
        self.json
    }

    /// Starts a named step: a line of its own in text, the `step` of the telegrams that follow in JSON.
    pub fn step(&mut self, name: &str) -> Result<(), CliError> {
        self.step = Some(name.to_string());
        if !self.json {
            writeln!(self.out, "  {name}")?;
        }
        Ok(())
    }

    /// Names the step of the telegrams that follow (JSON only: the text shows it otherwise), or none.
    pub fn set_step(&mut self, name: Option<&str>) {
        self.step = name.map(str::to_string);
    }

    /// One telegram: `text` is its line in text mode.
    pub fn telegram(&mut self, text: &str, t: &DemoTelegram<'_>) -> Result<(), CliError> {
        if self.json {
            #[derive(serde::Serialize)]
            struct Line<'a> {
                family: &'static str,
                step: &'a Option<String>,
                #[serde(flatten)]
                telegram: &'a DemoTelegram<'a>,
            }
            crate::common::print_json(self.out, &Line { family: self.family, step: &self.step, telegram: t })?;
        } else {
            writeln!(self.out, "{text}")?;
        }
        Ok(())
    }

    fn note(&mut self, line: &[u8]) -> std::io::Result<()> {
        let text = String::from_utf8_lossy(line);
        let text = text.trim();
        if text.is_empty() {
            return Ok(());
        }
        #[derive(serde::Serialize)]
        struct Note<'a> {
            family: &'static str,
            note: &'a str,
        }
        writeln!(self.out, "{}", crate::common::to_json(&Note { family: self.family, note: text }))
    }
}

impl Write for DemoOut<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if !self.json {
            return self.out.write(buf);
        }
        self.pending.extend_from_slice(buf);
        while let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.pending.drain(..=end).collect();
            self.note(&line)?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if self.json && !self.pending.is_empty() {
            let line = std::mem::take(&mut self.pending);
            self.note(&line)?;
        }
        self.out.flush()
    }
}

impl Drop for DemoOut<'_> {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}
