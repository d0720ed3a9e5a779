//! `motionlink decode powercube`: RS232 bytes (hex or raw) or candump lines, each telegram explained by the
//! library's describer.

use std::io::{Read, Write};

use motionlink_link::can::CandumpLine;
use motionlink_link::describe::{Annotation, Captured, Describe, Direction};
use motionlink_powercube::describe::Describer;

use crate::common::{self, CaptureArgs, CliError};

/// `motionlink decode powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
}

/// Reads the decode input as text (or raw bytes with --raw).
fn read_input(args: &CaptureArgs) -> Result<Result<String, Vec<u8>>, CliError> {
    if !args.hex.is_empty() {
        // Hex bytes or one candump frame; `decode` tells them apart by their shape.
        return Ok(Ok(args.hex.join(" ")));
    }
    let mut input = Vec::new();
    std::io::stdin().read_to_end(&mut input)?;
    if args.raw {
        return Ok(Err(input));
    }
    String::from_utf8(input).map(Ok).map_err(|_| CliError::usage("stdin is not text (use --raw for raw bytes)"))
}

/// A comment line of a capture: `# ...` or `// ...`.
fn is_comment(line: &str) -> bool {
    let line = line.trim_start();
    line.starts_with('#') || line.starts_with("//")
}

/// True if `line` has the shape of a candump line: a log line `(1700000000.000000) can0 0F1#01`, a frame
/// `0F1#01` or `can0 0F1#01`, or a screen line `can0  0F1   [1]  01`. A hex capture (with `#` comment lines)
/// never has it: its words are hex bytes, none with a `#` inside.
fn looks_like_candump(line: &str) -> bool {
    if is_comment(line) {
        return false;
    }
    let words: Vec<&str> = line.split_whitespace().collect();
    let frame_word =
        |w: &str| w.split_once('#').is_some_and(|(id, _)| !id.is_empty() && id.chars().all(|c| c.is_ascii_hexdigit()));
    match words.as_slice() {
        [first, ..] if first.starts_with('(') && first.ends_with(')') => true,
        [frame] => frame_word(frame),
        [_, frame, ..] if frame_word(frame) => true,
        [_, _, len, ..] => len.starts_with('[') && len.ends_with(']'),
        _ => false,
    }
}

/// One annotated RS232 telegram as `decode` and the demo print it: its bytes, then what they mean.
pub fn rs232_line(a: &Annotation) -> String {
    format!("{:<36}  {}", common::hex(&a.bytes), a.meaning)
}

/// `motionlink decode powercube`.
pub fn decode(args: DecodeArgs) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    let mut describer = Describer::new();
    let mut notes = Vec::new();
    let bytes = match read_input(&args.capture)? {
        Ok(text) if text.lines().any(looks_like_candump) => {
            let mut bad = 0;
            for (i, line) in text.lines().enumerate() {
                let line = line.trim();
                if line.is_empty() || is_comment(line) {
                    continue;
                }
                match line.parse::<CandumpLine>() {
                    Ok(l) => {
                        describer.describe(Captured::Frame(&l.frame), Direction::Unknown, None, &mut notes);
                        for a in notes.drain(..) {
                            writeln!(out, "{:<24}  {}", l.frame.to_string(), a.meaning)?;
                        }
                    }
                    Err(e) => {
                        bad += 1;
                        writeln!(out, "line {}: {e}", i + 1)?;
                    }
                }
            }
            if bad > 0 {
                return Err(CliError::usage(format!("{bad} line(s) are not candump lines")));
            }
            return Ok(());
        }
        Ok(text) => common::parse_hex(&text)?,
        Err(raw) => raw,
    };
    describer.describe(Captured::Bytes(&bytes), Direction::Unknown, None, &mut notes);
    describer.finish(&mut notes);
    for a in &notes {
        writeln!(out, "{}", rs232_line(a))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use motionlink_link::describe::Annotation;

    #[test]
    fn an_rs232_line_is_bytes_then_meaning() {
        let a = Annotation {
            at: None,
            direction: motionlink_link::describe::Direction::ToDevice,
            can_id: None,
            bytes: vec![0x02, 0x06],
            meaning: "x".into(),
            bad: false,
        };
        assert!(super::rs232_line(&a).starts_with("02 06 ") && super::rs232_line(&a).ends_with("  x"));
    }
}
