//! `motionlink decode <family>`: a capture read back line by line ([`capture::parse_line`]: capture files
//! that `--capture` wrote, candump logs, plain hex) and every telegram explained by the family's
//! [`Describe`]. The output repeats each line's own form (time stamp, direction mark or CAN interface and
//! frame) and adds the meaning, so that it can be cut back into a capture.

use std::io::{Read, Write};

use motionlink_link::capture::{self, CapturedLine};
use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::describe::{Annotation, Describe};
use motionlink_link::Timestamp;

use crate::common::{self, CliError};
use crate::json::Telegram;

/// Input of `motionlink decode`.
#[derive(clap::Args, Debug, Clone)]
pub struct CaptureArgs {
    /// Capture lines: hex bytes ("52 47 11 00 2C 30", one telegram or a piece of one), lines of a `--capture`
    /// file ("(1732470000.123456) <- 52 47 06 ..."), or candump lines ("(1700000000.000000) can0 0F1#01",
    /// "0F1#01"). Read from stdin if none are given; `#` and `//` start comment lines.
    #[arg(value_name = "LINE")]
    pub lines: Vec<String>,
    /// Read the capture from FILE (a `--capture` file, a candump log, hex) instead of the arguments or stdin.
    #[arg(long, short = 'i', value_name = "FILE", conflicts_with = "lines")]
    pub input: Option<std::path::PathBuf>,
    /// The capture (stdin or --input) holds raw bytes, not text.
    #[arg(long)]
    pub raw: bool,
}

/// Seconds since the Unix epoch, as a capture line gives them: `(1732470000.123456)`.
fn stamp(at: Option<Timestamp>) -> String {
    at.map(|t| format!("{} ", capture::format_time(t.since_origin()))).unwrap_or_default()
}

/// The mark of an annotation: `!!` for what is not a valid telegram, else its direction.
fn mark(a: &Annotation) -> &'static str {
    if a.bad {
        "!!"
    } else {
        a.direction.arrow()
    }
}

/// One annotation as text: the line as a capture holds it, then its meaning.
pub fn annotation_text(a: &Annotation, frame: Option<(&str, &motionlink_link::can::CanFrame)>) -> String {
    match frame {
        Some((interface, f)) => {
            let iface = if interface.is_empty() { String::new() } else { format!("{interface} ") };
            format!("{}{iface}{:<24} {} {}", stamp(a.at), f.to_string(), mark(a), a.meaning)
        }
        None => format!("{}{} {:<38} {}", stamp(a.at), mark(a), motionlink_link::hex::hex(&a.bytes), a.meaning),
    }
}

/// Prints what `describer` found, as text or JSON lines.
fn print(
    out: &mut dyn Write,
    json: bool,
    found: &mut Vec<Annotation>,
    frame: Option<(&str, &motionlink_link::can::CanFrame)>,
) -> Result<(), CliError> {
    for a in found.drain(..) {
        if json {
            common::print_json(out, &Telegram::of(&a, frame))?;
        } else {
            writeln!(out, "{}", annotation_text(&a, frame))?;
        }
    }
    Ok(())
}

/// Reads the capture `args` name and prints every telegram `describer` finds in it; lines without a direction
/// mark went `default` (`Unknown`: the describer decides from the bytes). A line that cannot be read is
/// reported in place and makes the command end with a usage error (exit 2) after the rest was decoded.
pub fn run(args: &CaptureArgs, json: bool, describer: &mut dyn Describe, default: Direction) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    let mut found = Vec::new();
    let text = if !args.lines.is_empty() {
        args.lines.join("\n")
    } else {
        let mut input = Vec::new();
        match &args.input {
            Some(path) => {
                input = std::fs::read(path).map_err(|e| CliError::usage(format!("--input {}: {e}", path.display())))?
            }
            None => {
                std::io::stdin().read_to_end(&mut input)?;
            }
        }
        if args.raw {
            describer.describe(Chunk::Bytes(&input), default, None, &mut found);
            describer.finish(&mut found);
            return print(&mut out, json, &mut found, None);
        }
        String::from_utf8(input).map_err(|_| CliError::usage("the capture is not text (use --raw for raw bytes)"))?
    };
    let mut unreadable = 0;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("//") {
            continue;
        }
        let parsed = match capture::parse_line(line) {
            Ok(Some(p)) => p,
            Ok(None) => continue,
            Err(e) => {
                unreadable += 1;
                let message = format!("line {}: {e}", i + 1);
                if json {
                    #[derive(serde::Serialize)]
                    struct Unreadable {
                        bad: bool,
                        line: usize,
                        meaning: String,
                    }
                    common::print_json(&mut out, &Unreadable { bad: true, line: i + 1, meaning: message })?;
                } else {
                    writeln!(out, "!! {message}")?;
                }
                continue;
            }
        };
        let at = parsed.unix.map(Timestamp::from_duration);
        let direction = if parsed.direction == Direction::Unknown { default } else { parsed.direction };
        match &parsed.data {
            CapturedLine::Bytes(bytes) => {
                describer.describe(Chunk::Bytes(bytes), direction, at, &mut found);
                print(&mut out, json, &mut found, None)?;
            }
            CapturedLine::Frame { frame, interface } => {
                describer.describe(Chunk::Frame(frame), direction, at, &mut found);
                print(&mut out, json, &mut found, Some((interface.as_deref().unwrap_or(""), frame)))?;
            }
        }
    }
    describer.finish(&mut found);
    print(&mut out, json, &mut found, None)?;
    if unreadable > 0 {
        return Err(CliError::usage(format!("{unreadable} line(s) of the capture could not be read")));
    }
    Ok(())
}
