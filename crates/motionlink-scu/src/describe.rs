//! Telegrams described for people: the family's [`Describe`] (what `motionlink decode scu`, the demo's
//! transcript and any capture annotation use), and the one-line descriptions it is made of.
//!
//! ```
//! use motionlink_link::chunk::{Chunk, Direction};
//! use motionlink_link::describe::Describe;
//! use motionlink_scu::describe::{describe_request, Describer};
//! use motionlink_scu::wire::Request;
//! assert_eq!(
//!     describe_request(&Request::Get { index: 0x0011 }),
//!     "RG remote data get: actual_position_a1 (0x0011)"
//! );
//! // A capture of both directions, in pieces: the reply is explained with the request before it.
//! let mut d = Describer::new();
//! let mut out = Vec::new();
//! d.describe(Chunk::Bytes(&[0x52, 0x47, 0x11]), Direction::Unknown, None, &mut out);
//! d.describe(Chunk::Bytes(&[0x00, 0x2C, 0x30, 0x52, 0x47, 0x06, 0x04, 0x00]), Direction::Unknown, None, &mut out);
//! d.describe(Chunk::Bytes(&[0x90, 0x01, 0x00, 0x00, 0xA3, 0xAD]), Direction::Unknown, None, &mut out);
//! d.finish(&mut out);
//! assert_eq!(out.len(), 2);
//! assert_eq!(out[0].direction, Direction::ToDevice);
//! assert_eq!(out[1].meaning, "RG ACK: actual_position_a1 = 400 counts");
//! ```

use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::describe::{Annotation, Describe};
use motionlink_link::hex::hex;
use motionlink_link::transcript::Record;
use motionlink_link::Timestamp;

use crate::model::{item, DataIndex, Function, MotionDirection, SafetyId, StopMode, UNUSED};
use crate::value::decode_item;
use crate::wire::{
    capture_step, request_to_vec, CaptureDirection, CaptureItem, Command, Incoming, Reply, Request, Status, Telegram,
    WireError,
};

fn index_name(index: u16) -> String {
    match item(DataIndex(index)) {
        Some(it) => format!("{} ({})", it.name(), DataIndex(index)),
        None => format!("unknown index {}", DataIndex(index)),
    }
}

fn function_name(id: u8) -> String {
    match Function::from_id(id) {
        Some(f) => f.to_string(),
        None => format!("unknown function id {id}"),
    }
}

/// One line about a request.
pub fn describe_request(r: &Request<'_>) -> String {
    let head = format!("{} {}", r.command(), r.command().description());
    let detail = match *r {
        Request::Open { safety_id } => match SafetyId::from_code(safety_id) {
            Some(s) => format!("Safety_ID {safety_id} ({})", s.description()),
            None => format!("Safety_ID {safety_id} (not 0, 1 or 2)"),
        },
        Request::Abort => "back to normal mode".into(),
        Request::Cyclic { object: UNUSED, .. } => "keepalive, no cyclic object".into(),
        Request::Cyclic { object, write } => {
            format!("CyclicObj {} with {} byte(s) of write data [{}]", u16::from(object) + 1, write.len(), hex(write))
        }
        Request::Get { index } => index_name(index),
        Request::Transfer { index, data } => {
            let value = item(DataIndex(index))
                .and_then(|it| decode_item(it, data).ok())
                .map(|v| v.iter().map(|(e, v)| format!("{} = {v}", e.name)).collect::<Vec<_>>().join(", "));
            match value {
                Some(v) => v,
                None => format!("{} <- [{}]", index_name(index), hex(data)),
            }
        }
        Request::Execute { function, params } => {
            let f = function_name(function);
            match Function::from_id(function) {
                Some(Function::Motion(_)) => match MotionDirection::from_code(params[0]) {
                    Some(d) => format!("{f}, direction {}: {}", params[0], d.description()),
                    None => format!("{f}, direction {} (not 0..9)", params[0]),
                },
                _ => format!("{f} on"),
            }
        }
        Request::Stop { function, param } => {
            let f = function_name(function);
            match (Function::from_id(function), StopMode::from_code(param)) {
                (Some(Function::Motion(_)), Some(StopMode::Fast)) => format!("{f}, fast stop"),
                (Some(Function::Motion(_)), Some(StopMode::Soft)) => format!("{f}, soft stop"),
                (Some(Function::Motion(_)), None) => format!("{f}, stop mode {param} (not 0 or 1)"),
                _ => format!("{f} off"),
            }
        }
    };
    format!("{head}: {detail}")
}

/// One line about an incoming telegram (a request or an unknown command).
pub fn describe_incoming(i: &Incoming<'_>) -> String {
    match i {
        Incoming::Request(r) => describe_request(r),
        Incoming::UnknownCommand { code } => {
            format!("{}{}: unknown command (the unit answers ICE)", char::from(code[0]), char::from(code[1]))
        }
    }
}

/// One line about a reply; `request` (the request it answers, if known) lets the data be decoded.
pub fn describe_reply(r: &Reply<'_>, request: Option<&Request<'_>>) -> String {
    let mut s = format!("{} {}", r.command, r.status.abbreviation());
    if r.status != Status::Ack {
        s.push_str(&format!(": {}", r.status.description()));
        return s;
    }
    let Some(data) = r.data else { return s };
    let decoded = match request {
        Some(Request::Get { index }) if r.command == Command::Get => item(DataIndex(*index))
            .and_then(|it| decode_item(it, data).ok())
            .map(|v| v.iter().map(|(e, v)| format!("{} = {v}", e.name)).collect::<Vec<_>>().join(", ")),
        _ => None,
    };
    match decoded {
        Some(d) => s.push_str(&format!(": {d}")),
        None => s.push_str(&format!(": {} data byte(s) [{}]", data.len(), hex(data))),
    }
    s
}

/// One line about a telegram (or bytes that are none) found in a capture; `last_request` (the bytes of the
/// request before it) lets a reply's data be decoded.
pub fn describe_item(item: &CaptureItem<'_>, raw_len: usize, last_request: Option<&[u8]>) -> String {
    match item {
        CaptureItem::Telegram(Telegram::Request(i)) => describe_incoming(i),
        CaptureItem::Telegram(Telegram::Reply(r)) => {
            let context = last_request.and_then(|b| match capture_step(b, CaptureDirection::FromHost).1 {
                CaptureItem::Telegram(Telegram::Request(Incoming::Request(req))) => Some(req),
                _ => None,
            });
            describe_reply(r, context.as_ref())
        }
        CaptureItem::Telegram(Telegram::UnknownCommandReply { code, status }) => format!(
            "{}{} {}: {} (the reply to an unknown command)",
            char::from(code[0]),
            char::from(code[1]),
            status.abbreviation(),
            status.description()
        ),
        CaptureItem::Error(WireError::Garbage { count }) => format!("{count} byte(s) that start no telegram"),
        CaptureItem::Error(e) => e.to_string(),
        CaptureItem::Truncated => format!("the capture ends inside a telegram ({raw_len} byte(s))"),
    }
}

/// The SCU's decoder of captured traffic: requests and replies in any chunks, one direction or both mixed
/// (a mixed capture is split by what the bytes are; see [`capture_step`]), each reply explained with the
/// request before it.
#[derive(Debug, Default)]
pub struct Describer {
    /// Bytes not yet whole telegrams, per direction (to the unit, from it, not known).
    pending: [Vec<u8>; 3],
    /// When the first pending byte of each direction came.
    pending_at: [Option<Timestamp>; 3],
    last_request: Option<Vec<u8>>,
}

fn slot(direction: Direction) -> (usize, CaptureDirection) {
    match direction {
        Direction::ToDevice => (0, CaptureDirection::FromHost),
        Direction::FromDevice => (1, CaptureDirection::FromUnit),
        Direction::Unknown => (2, CaptureDirection::Unknown),
    }
}

impl Describer {
    /// A decoder with nothing pending.
    pub fn new() -> Self {
        Self::default()
    }

    /// Describes what is whole in buffer `i`; with `all`, also what is left (the capture ended).
    fn drain(&mut self, i: usize, dir: CaptureDirection, all: bool, out: &mut Vec<Annotation>) {
        let mut at = 0;
        let at_time = self.pending_at[i];
        // The last bad annotation of this call that garbage right after it joins (a telegram with a wrong CRC
        // and the rest of its bytes, or a run of garbage): one line, not one per byte. `true` for garbage.
        let mut run: Option<(usize, bool)> = None;
        while at < self.pending[i].len() {
            let bytes = &self.pending[i][at..];
            let (n, found) = match capture_step(bytes, dir) {
                // The capture ended inside what looked like the start of a telegram, but a whole one follows:
                // that start was a stray byte (`R` and a letter no command has), and the next frame is found.
                (_, CaptureItem::Truncated)
                    if all
                        && (1..bytes.len())
                            .any(|j| matches!(capture_step(&bytes[j..], dir).1, CaptureItem::Telegram(_))) =>
                {
                    (1, CaptureItem::Error(WireError::Garbage { count: 1 }))
                }
                step => step,
            };
            if matches!(found, CaptureItem::Truncated) && !all {
                break;
            }
            let n = n.max(1).min(bytes.len());
            let raw = bytes[..n].to_vec();
            let meaning = describe_item(&found, raw.len(), self.last_request.as_deref());
            let (direction, bad) = match &found {
                CaptureItem::Telegram(Telegram::Request(_)) => {
                    self.last_request = Some(raw.clone());
                    (Direction::ToDevice, false)
                }
                CaptureItem::Telegram(_) => (Direction::FromDevice, false),
                CaptureItem::Error(_) | CaptureItem::Truncated => (
                    match dir {
                        CaptureDirection::FromHost => Direction::ToDevice,
                        CaptureDirection::FromUnit => Direction::FromDevice,
                        CaptureDirection::Unknown => Direction::Unknown,
                    },
                    true,
                ),
            };
            let garbage = matches!(found, CaptureItem::Error(WireError::Garbage { .. }));
            match run {
                Some((k, was_garbage)) if garbage && k < out.len() => {
                    out[k].bytes.extend_from_slice(&raw);
                    if was_garbage {
                        out[k].meaning = format!("{} byte(s) that start no telegram", out[k].bytes.len());
                    }
                }
                _ => {
                    let joins =
                        matches!(found, CaptureItem::Error(WireError::Garbage { .. } | WireError::Checksum { .. }));
                    run = joins.then_some((out.len(), garbage));
                    out.push(Annotation { at: at_time, direction, can_id: None, bytes: raw, meaning, bad });
                }
            }
            at += n;
        }
        self.pending[i].drain(..at);
        if self.pending[i].is_empty() {
            self.pending_at[i] = None;
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
        let bytes = match captured {
            Chunk::Bytes(b) => b,
            Chunk::Frame(f) => {
                out.push(Annotation {
                    at,
                    direction,
                    can_id: None,
                    bytes: Vec::new(),
                    meaning: format!("a CAN frame ({f}): the SCU speaks RS232, not CAN"),
                    bad: true,
                });
                return;
            }
        };
        let (i, dir) = slot(direction);
        if self.pending[i].is_empty() {
            self.pending_at[i] = at;
        }
        self.pending[i].extend_from_slice(bytes);
        self.drain(i, dir, false, out);
    }

    fn finish(&mut self, out: &mut Vec<Annotation>) {
        for direction in [Direction::ToDevice, Direction::FromDevice, Direction::Unknown] {
            let (i, dir) = slot(direction);
            self.drain(i, dir, true, out);
        }
    }
}

/// One line of a session's transcript as the demo shows it.
#[derive(Debug, Clone, PartialEq)]
pub enum TranscriptLine {
    /// A telegram, explained.
    Telegram(Annotation),
    /// Exchanges left out, said in words ("… 12 RC keepalive(s), each answered ACK").
    Folded(String),
}

/// A session's recorded traffic, explained: every exchange once; keepalives after the first folded into a
/// count; an exchange repeated without change (a status poll) collapsed into one line.
pub fn fold_transcript(records: &[Record]) -> Vec<TranscriptLine> {
    let keepalive = request_to_vec(&Request::Cyclic { object: UNUSED, write: &[] }).unwrap_or_default();
    let mut d = Describer::new();
    let mut lines: Vec<Annotation> = Vec::new();
    for r in records {
        d.describe(Chunk::Bytes(&r.bytes), r.direction, Some(r.at), &mut lines);
    }
    d.finish(&mut lines);
    let mut out = Vec::new();
    let mut keepalives_shown = false;
    let mut keepalives_folded = 0;
    let mut previous: Option<(Vec<u8>, Vec<u8>)> = None;
    let mut repeats = 0;
    let mut last_repeat_at = Timestamp::ZERO;
    let mut i = 0;
    while i < lines.len() {
        let exchange = lines.get(i..i + 2).filter(|p| {
            p[0].direction == Direction::ToDevice && p[1].direction == Direction::FromDevice && !p[0].bad && !p[1].bad
        });
        let Some(pair) = exchange else {
            out.push(TranscriptLine::Telegram(lines[i].clone()));
            i += 1;
            continue;
        };
        if pair[0].bytes == keepalive {
            if keepalives_shown {
                keepalives_folded += 1;
                i += 2;
                continue;
            }
            keepalives_shown = true;
        }
        let key = (pair[0].bytes.clone(), pair[1].bytes.clone());
        if previous.as_ref() == Some(&key) {
            repeats += 1;
            last_repeat_at = pair[1].at.unwrap_or_default();
            i += 2;
            continue;
        }
        if repeats > 0 {
            out.push(TranscriptLine::Folded(format!(
                "… the same exchange {repeats} more time(s), until {:.3} s",
                last_repeat_at.since_origin().as_secs_f64()
            )));
            repeats = 0;
        }
        if keepalives_folded > 0 {
            out.push(TranscriptLine::Folded(format!("… {keepalives_folded} RC keepalive(s), each answered ACK")));
            keepalives_folded = 0;
        }
        out.push(TranscriptLine::Telegram(pair[0].clone()));
        out.push(TranscriptLine::Telegram(pair[1].clone()));
        previous = Some(key);
        i += 2;
    }
    out
}
