//! Captured COMPAX traffic explained, telegram by telegram: the family's
//! [`Describe`], which `motionlink decode compax`, the demo's
//! transcript and any capture writer call.
//!
//! Requests (ASCII and binary, with their flags and BCC) and replies (acknowledgements, `Exx` with its
//! meaning, `$`, comparator numbers, status values with their named bits) are told apart by their bytes
//! when the capture does not say which way they went. Bytes that are neither are reported as garbage.
//!
//! ```
//! use motionlink_compax::describe::Describer;
//! use motionlink_compax::wire::Mode;
//! use motionlink_link::chunk::{Chunk, Direction};
//! use motionlink_link::describe::Describe;
//! let mut d = Describer::new(Mode::from_p196(8).unwrap());
//! let mut out = Vec::new();
//! d.describe(Chunk::Bytes(b"1S1\rS"), Direction::Unknown, None, &mut out);
//! d.finish(&mut out);
//! assert_eq!(out[0].meaning, "request to drive 1: S1 read actual position, relative to the real zero [BCC 53 ok]");
//! assert_eq!(out[0].direction, Direction::ToDevice);
//! ```

use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::describe::{Annotation, Describe};
use motionlink_link::Timestamp;

use crate::model::{Command, ErrorCode, StatusId, StatusKind, StatusValue};
use crate::wire::binary::announced_len;
use crate::wire::reply::{ReplyDecoder, ReplyError, MAX_REPLY_LEN};
use crate::wire::request::{ParsedRequest, RequestDecoder, RequestError, RequestEvent};
use crate::wire::{Body, EscapedBytes, Mode, ReplyEventRef, ReplyKind, CR};

/// One telegram found in a capture.
struct Found {
    bytes: Vec<u8>,
    text: String,
    direction: Direction,
    /// For a request: its command was recognised (an `Execute`, a known command or binary telegram), even if
    /// its BCC is wrong.
    recognised: bool,
    /// Not a valid telegram (a bad BCC, a broken reply, a request that does not parse).
    bad: bool,
    /// For a request: its BCC is wrong (the drive answers E72).
    bad_bcc: bool,
}

/// The COMPAX decoder of captured traffic in mode P196 `mode`.
#[derive(Debug, Clone)]
pub struct Describer {
    mode: Mode,
    /// Bytes not yet explained, per direction (to device, from device, unknown).
    pending: [Vec<u8>; 3],
    at: [Option<Timestamp>; 3],
}

fn slot(d: Direction) -> usize {
    match d {
        Direction::ToDevice => 0,
        Direction::FromDevice => 1,
        Direction::Unknown => 2,
    }
}

impl Describer {
    /// A decoder for a bus in mode `mode` (P196: BCC, reply end, address prefix).
    pub fn new(mode: Mode) -> Self {
        Describer { mode, pending: Default::default(), at: [None; 3] }
    }

    /// Explains the bytes of `direction` held so far; with `last`, all of them (garbage included),
    /// otherwise up to the first one that may start a telegram not yet complete.
    fn drain(&mut self, direction: Direction, last: bool, out: &mut Vec<Annotation>) {
        let i = slot(direction);
        let bytes = std::mem::take(&mut self.pending[i]);
        let at = self.at[i];
        let mut pos = 0;
        let mut garbage = Vec::new();
        let flush = |garbage: &mut Vec<u8>, out: &mut Vec<Annotation>| {
            if !garbage.is_empty() {
                out.push(Annotation {
                    at,
                    direction,
                    can_id: None,
                    meaning: format!("garbage: {}", EscapedBytes(garbage)),
                    bytes: std::mem::take(garbage),
                    bad: true,
                });
            }
        };
        while pos < bytes.len() {
            match self.find(&bytes[pos..], direction) {
                // A bad telegram is one only where no good one starts inside it: else its first byte is
                // garbage (a stray byte before a request), and the next frame is found. A telegram does not
                // start inside the address digits that open another (`33S1`, `032S1`): a drive reads the
                // digits as one address (33: no drive), as the emulator does, so neither does `decode`.
                Some(f)
                    if !f.bytes.is_empty()
                        && (!f.bad
                            || (pos + 1..pos + f.bytes.len())
                                .filter(|&j| !bytes[pos..j].iter().all(u8::is_ascii_digit))
                                .all(|j| self.find(&bytes[j..], direction).is_none_or(|g| g.bad))) =>
                {
                    flush(&mut garbage, out);
                    pos += f.bytes.len();
                    let direction = if direction == Direction::Unknown { f.direction } else { direction };
                    out.push(Annotation { at, direction, can_id: None, bytes: f.bytes, meaning: f.text, bad: f.bad });
                }
                Some(f) if f.bad => {
                    garbage.push(bytes[pos]);
                    pos += 1;
                }
                // Nothing starts here though more bytes follow than any telegram has: garbage.
                _ if bytes.len() - pos > LONGEST_TELEGRAM => {
                    garbage.push(bytes[pos]);
                    pos += 1;
                }
                // Incomplete: garbage up to where a telegram starts later on, if one does (looked for once,
                // not again for every byte before it); else it waits for more (or, at the end, is garbage).
                _ => match (pos + 1..bytes.len()).find(|&j| self.find(&bytes[j..], direction).is_some()) {
                    Some(next) => {
                        garbage.extend_from_slice(&bytes[pos..next]);
                        pos = next;
                    }
                    None if !last => break,
                    None => {
                        garbage.extend_from_slice(&bytes[pos..]);
                        pos = bytes.len();
                    }
                },
            }
        }
        flush(&mut garbage, out);
        self.pending[i] = bytes[pos..].to_vec();
    }

    /// The first telegram at the start of `rest`, read as `direction` says (both ways when unknown).
    fn find(&self, rest: &[u8], direction: Direction) -> Option<Found> {
        let mode = &self.mode;
        match direction {
            Direction::ToDevice => annotate_request(rest, mode),
            Direction::FromDevice => annotate_reply(rest, mode),
            Direction::Unknown => {
                let looks_like_request = rest[0].is_ascii_digit()
                    && rest
                        .iter()
                        .skip(1)
                        .find(|b| !b.is_ascii_digit())
                        .is_some_and(|&b| b != CR || announced_len(b).is_some());
                let req = if looks_like_request { annotate_request(rest, mode) } else { None };
                match req {
                    Some(f) if f.recognised && !f.bad_bcc => Some(f),
                    // A recognised request whose BCC alone is wrong is that request, unless the bytes also
                    // read as a good reply.
                    Some(f) if f.recognised => match annotate_reply(rest, mode) {
                        Some(r) if r.recognised => Some(r),
                        _ => Some(f),
                    },
                    other => annotate_reply(rest, mode).or(other),
                }
            }
        }
    }
}

impl Describe for Describer {
    fn describe(
        &mut self,
        captured: Chunk<'_>,
        direction: Direction,
        at: Option<Timestamp>,
        out: &mut Vec<Annotation>,
    ) {
        let Chunk::Bytes(bytes) = captured else {
            out.push(Annotation {
                at,
                direction,
                can_id: None,
                bytes: Vec::new(),
                meaning: "a CAN frame: COMPAX is a serial bus".into(),
                bad: true,
            });
            return;
        };
        let i = slot(direction);
        if self.pending[i].is_empty() {
            self.at[i] = at;
        }
        self.pending[i].extend_from_slice(bytes);
        self.drain(direction, false, out);
    }

    fn finish(&mut self, out: &mut Vec<Annotation>) {
        for d in [Direction::ToDevice, Direction::FromDevice, Direction::Unknown] {
            self.drain(d, true, out);
        }
    }
}

/// More bytes than any telegram has: a request's address, its command of at most [`MAX_COMMAND_LEN`](crate::wire::MAX_COMMAND_LEN)
/// characters, its flags, BCC and CR; a reply of at most [`MAX_REPLY_LEN`] characters and its frame. Where
/// nothing is found within this many bytes, nothing starts there.
const LONGEST_TELEGRAM: usize = 2 * MAX_REPLY_LEN;

fn annotate_request(bytes: &[u8], mode: &Mode) -> Option<Found> {
    let mut d = RequestDecoder::new(mode);
    for (i, &b) in bytes.iter().take(LONGEST_TELEGRAM).enumerate() {
        match d.push(b) {
            None => {}
            Some(RequestEvent::Frame(f)) => {
                let found = |text: String, recognised: bool, bad: bool, bad_bcc: bool| {
                    Some(Found {
                        bytes: bytes[..=i].to_vec(),
                        text,
                        direction: Direction::ToDevice,
                        recognised,
                        bad,
                        bad_bcc,
                    })
                };
                return match f.parse() {
                    Ok(p) => {
                        let bcc = match f.bcc() {
                            Some((r, _)) => format!(" [BCC {r:02X} ok]"),
                            None => String::new(),
                        };
                        let (what, recognised) = describe_request(&p);
                        found(format!("{what}{bcc}"), recognised, false, false)
                    }
                    Err(RequestError::Bcc { received, computed }) => match f.parse_ignoring_bcc() {
                        // What it says, and that the drive refuses it for its BCC.
                        Ok(p) => {
                            let (what, recognised) = describe_request(&p);
                            let bcc =
                                format!(" [BCC {received:02X} wrong, computed {computed:02X}: the drive answers E72]");
                            found(format!("{what}{bcc}"), recognised, true, true)
                        }
                        Err(e) => found(format!("request, bad: {e}"), false, true, true),
                    },
                    Err(e) => found(format!("request, bad: {e}"), false, true, false),
                };
            }
            Some(_) => return None,
        }
    }
    None
}

/// `request to drive 1: S1 read ...` and whether the command was recognised.
fn describe_request(p: &ParsedRequest<'_>) -> (String, bool) {
    let who = if p.address == 32 { "all drives".to_string() } else { format!("drive {}", p.address) };
    let (what, recognised) = match p.body {
        Body::Execute => ("! execute the buffered command".to_string(), true),
        Body::Binary(b) => match Command::from_binary(&b) {
            Ok(c) => (format!("binary {c}"), true),
            Err(e) => (format!("binary {b} ({e})"), false),
        },
        Body::Command(t) => match Command::parse(t) {
            Ok(c) => (describe_command(&c), true),
            Err(_) => (format!("{} (not a known command)", plain(t)), false),
        },
    };
    let mut flags = Vec::new();
    if p.flags.position_message {
        flags.push("$ position-reached message");
    }
    if p.flags.buffer {
        flags.push(", store in buffer");
    }
    if p.flags.no_reply {
        flags.push("/ no reply");
    }
    if p.flags.echo {
        flags.push("? echo");
    }
    let flags = if flags.is_empty() { String::new() } else { format!(" [{}]", flags.join(", ")) };
    (format!("request to {who}: {what}{flags}"), recognised)
}

fn describe_command(c: &Command) -> String {
    match c {
        Command::ReadStatus(id) => format!("{c} read {}", id.description().unwrap_or("a status value")),
        Command::ReadParam(id) => format!("{c} read {}", id.description().unwrap_or("a parameter")),
        Command::WriteParam(id, _) => format!("{c} write {}", id.description().unwrap_or("a parameter")),
        other => other.to_string(),
    }
}

fn annotate_reply(bytes: &[u8], mode: &Mode) -> Option<Found> {
    let mut d = ReplyDecoder::new(mode);
    // The first event, and the bytes up to the one that completed it.
    let (used, event) = d.decode(bytes);
    let found = |text: String, recognised: bool, bad: bool| Found {
        bytes: bytes[..used].to_vec(),
        text,
        direction: Direction::FromDevice,
        recognised,
        bad,
        bad_bcc: false,
    };
    let text = match event? {
        ReplyEventRef::Reply(r) if !r.line().iter().all(|c| (0x20..0x7F).contains(c)) => return None,
        ReplyEventRef::Reply(r) => {
            let who = r.address().map_or(String::new(), |a| format!(" from drive {a}"));
            let what = match r.kind() {
                ReplyKind::Ack => "acknowledged".to_string(),
                ReplyKind::Error(c) => format!("error {}", ErrorCode(c)),
                ReplyKind::PositionReached => "$ position reached".to_string(),
                ReplyKind::Comparator(n) => format!("comparator {n} switched"),
                ReplyKind::Text(t) => describe_reply_text(t),
            };
            let bcc = if mode.bcc { " [BCC ok]" } else { "" };
            format!("reply{who}: {what}{bcc}")
        }
        ReplyEventRef::Error(e) => {
            let mut f = found(format!("reply, bad: {e}"), false, true);
            f.bad_bcc = matches!(e, ReplyError::Bcc { .. });
            return Some(f);
        }
        ReplyEventRef::Flow(x) => (if x { "XOFF" } else { "XON" }).to_string(),
    };
    // A reply that decoded cleanly.
    Some(found(text, true, false))
}

fn describe_reply_text(t: &str) -> String {
    // "S016: 1000 0000" and the like: name the value.
    if let Some(rest) = t.strip_prefix('S') {
        let n: String = rest.chars().take_while(char::is_ascii_digit).collect();
        if let Ok(id) = n.parse::<u8>().map_err(|_| ()).and_then(|n| StatusId::new(n).map_err(|_| ())) {
            if let Ok(v) = StatusValue::parse(id, t.as_bytes()) {
                let extra = match (id.kind(), v) {
                    (StatusKind::BitsS16, StatusValue::S16(b)) => format!(" [{}]", b.meanings().join(", ")),
                    (StatusKind::BitsS17, StatusValue::S17(b)) => format!(" [{}]", b.meanings().join(", ")),
                    _ => String::new(),
                };
                let name = id.info().map_or("status value", |i| i.title);
                return format!("{id} ({name}) = {v}{extra}");
            }
        }
    }
    plain(t.as_bytes())
}

/// Characters as the user reads them: in double quotes, each byte that is not printable ASCII as its two
/// hex digits in angle brackets (`"Q<01>X"`); never a programming language's escapes.
fn plain(bytes: &[u8]) -> String {
    let mut text = String::from("\"");
    for &b in bytes {
        if b == b' ' || b.is_ascii_graphic() {
            text.push(char::from(b));
        } else {
            text.push_str(&format!("<{b:02X}>"));
        }
    }
    text.push('"');
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unprintable_characters_are_shown_in_hex_not_as_escapes() {
        assert_eq!(plain(b"Q\x01X"), "\"Q<01>X\"");
        assert_eq!(plain(b"P12 = 3"), "\"P12 = 3\"");
    }

    /// Every annotation of `bytes` read in one piece, as `motionlink decode` prints it.
    fn lines(bytes: &[u8], mode: &Mode, direction: Direction) -> Vec<String> {
        let mut d = Describer::new(*mode);
        let mut out = Vec::new();
        d.describe(Chunk::Bytes(bytes), direction, None, &mut out);
        d.finish(&mut out);
        out.iter().map(|a| format!("{} {}", EscapedBytes(&a.bytes), a.meaning)).collect()
    }

    #[test]
    fn both_directions_of_the_manuals_example() {
        let mode = Mode::from_p196(8).unwrap();
        let mut bytes = b"1S1\r\x53".to_vec();
        bytes.extend_from_slice(b"S001: 0.000\r\n>");
        bytes.push(crate::wire::bcc(b"S001: 0.000"));
        let lines = lines(&bytes, &mode, Direction::Unknown);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].contains("request to drive 1: S1 read actual position"), "{lines:?}");
        assert!(lines[0].contains("BCC 53 ok"), "{lines:?}");
        assert!(lines[1].contains("S1 (actual position) = 0"), "{lines:?}");
    }

    #[test]
    fn a_request_with_a_bad_bcc_is_read_as_that_request() {
        let mode = Mode::from_p196(8).unwrap();
        // The manual's `1S1` with a wrong BCC ('X', not 0x53), then the drive's E72.
        let mut bytes = b"1S1\rX".to_vec();
        bytes.extend_from_slice(b"E72\r\n>");
        bytes.push(crate::wire::bcc(b"E72"));
        let lines = lines(&bytes, &mode, Direction::Unknown);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].contains("request to drive 1: S1 read actual position"), "{lines:?}");
        assert!(lines[0].contains("BCC 58 wrong, computed 53"), "{lines:?}");
        assert!(lines[1].contains("E72"), "{lines:?}");
        // An unknown command with a bad BCC is still not taken for a request.
        let lines = self::lines(b"1XYZ\rQ", &mode, Direction::Unknown);
        assert!(!lines.iter().any(|l| l.contains("request to drive 1")), "{lines:?}");
    }

    #[test]
    fn binary_and_garbage() {
        let mode = Mode::default();
        let bytes = [0xFF, b'1', 0x88, 0x41, 0, 0, 0, 0x68, 0x01, 0, b'E', b'9', b'2', CR, b'\n', b'>'];
        let lines = lines(&bytes, &mode, Direction::Unknown);
        assert!(lines[0].contains("garbage"), "{lines:?}");
        assert!(lines[1].contains("binary POSA 360"), "{lines:?}");
        assert!(lines[2].contains("E92"), "{lines:?}");
    }

    #[test]
    fn a_stray_byte_before_requests_is_garbage_and_the_requests_are_found() {
        let mode = Mode::default();
        for stray in [0x00, b'A', CR] {
            let mut bytes = vec![stray];
            bytes.extend_from_slice(b"1S1\r1S1\r");
            let lines = lines(&bytes, &mode, Direction::Unknown);
            assert_eq!(lines.len(), 3, "{lines:?}");
            assert!(lines[0].contains("garbage"), "{lines:?}");
            assert!(lines[1..].iter().all(|l| l.contains("request to drive 1: S1")), "{lines:?}");
        }
    }

    /// A telegram whose address no drive has (`33`, `45`, three digits, a leading zero) is one bad request,
    /// as the drives read it (none answers), not a stray digit before a request to another drive (was:
    /// `33S1` shown as a request to drive 3, `032S1` as one to all drives).
    #[test]
    fn a_telegram_to_an_address_no_drive_has_is_one_bad_request() {
        let mode = Mode::default();
        for telegram in [&b"33S1\r"[..], b"45S1\r", b"123S1\r", b"032S1\r"] {
            let lines = lines(telegram, &mode, Direction::ToDevice);
            assert_eq!(lines.len(), 1, "{lines:?}");
            assert!(!lines[0].contains("request to"), "{lines:?}");
        }
        // A stray byte that is no digit is still garbage before a good request.
        let lines = lines(b"X1S1\r", &mode, Direction::ToDevice);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[1].contains("request to drive 1: S1"), "{lines:?}");
    }

    #[test]
    fn a_long_capture_without_a_telegram_is_garbage_to_its_last_byte() {
        // 120 kB of another family's telegrams, read in 4 kB pieces as `decode` reads a file: every byte is
        // in an annotation, none of them a telegram. (Nothing starts where more bytes follow than any
        // telegram has, so a byte is not looked at again for every later one: 1.2 MB took 7.6 s before.)
        let bytes: Vec<u8> = [0x52, 0x47, 0x11, 0x00, 0x2C, 0x30].repeat(20_000);
        let mut d = Describer::new(Mode::default());
        let mut out = Vec::new();
        for piece in bytes.chunks(4096) {
            d.describe(Chunk::Bytes(piece), Direction::Unknown, None, &mut out);
        }
        d.finish(&mut out);
        assert_eq!(out.iter().map(|a| a.bytes.len()).sum::<usize>(), bytes.len());
        assert!(out.iter().all(|a| a.bad), "nothing in it is a COMPAX telegram");
    }

    #[test]
    fn a_telegram_in_pieces_is_one_annotation_with_its_direction() {
        let mode = Mode::default();
        let mut d = Describer::new(mode);
        let mut out = Vec::new();
        for piece in [&b"S001: 1"[..], b"2.500\r", b"\n>"] {
            d.describe(Chunk::Bytes(piece), Direction::FromDevice, None, &mut out);
        }
        d.describe(Chunk::Bytes(b"5S"), Direction::ToDevice, None, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert_eq!(out[0].meaning, "reply: S1 (actual position) = 12.5");
        assert_eq!((out[0].direction, out[0].bad), (Direction::FromDevice, false));
        d.describe(Chunk::Bytes(b"17\r"), Direction::ToDevice, None, &mut out);
        d.finish(&mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(out[1].meaning.starts_with("request to drive 5: S17 read status bits"), "{out:?}");
        // A half telegram at the end is reported, not lost.
        let mut out = Vec::new();
        d.describe(Chunk::Bytes(b"3PO"), Direction::ToDevice, None, &mut out);
        assert!(out.is_empty());
        d.finish(&mut out);
        assert!(out.iter().all(|a| a.bad) && !out.is_empty(), "{out:?}");
    }
}
