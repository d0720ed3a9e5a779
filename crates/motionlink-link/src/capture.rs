//! Captures of a session's traffic: a tap on any link ([`TapLink`], [`TapCanLink`]) hands every chunk or
//! frame, stamped, to a [`TapSink`]: an in-memory [`Transcript`](crate::transcript::Transcript), a capture file
//! ([`CaptureWriter`]) that `motionlink decode` reads back, or a live trace.
//!
//! The capture file format, one line per chunk or frame:
//!
//! - serial lines: `(<Unix time in s, 6 decimals>) <direction> <hex bytes>`, where the direction is `->`
//!   (host to device) or `<-` (device to host): `(1732470000.123456) -> 52 47 11 00 2C 30`;
//! - CAN: the `candump -l` log form, `(1732470000.123456) can0 0F1#01`; read back with candump `-x`'s direction
//!   marks too (`... can0 0F1#01 T`, the screen form `can0 TX - - 0F1 [1] 01`).
//!
//! Lines starting with `#` are comments (the writer starts with one naming the family and the port).
//!
//! ```
//! use motionlink_link::capture::{parse_line, CapturedLine};
//! use motionlink_link::chunk::Direction;
//! let line = parse_line("(1732470000.5) <- 52 47 06").unwrap().unwrap();
//! assert_eq!(line.direction, Direction::FromDevice);
//! assert_eq!(line.data, CapturedLine::Bytes(vec![0x52, 0x47, 0x06]));
//! ```

use std::io::Write;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use crate::can::{CanFrame, CanLink, CandumpLine};
use crate::chunk::{Chunk, Direction};
use crate::clock::{lock, SharedClock, Timestamp};
use crate::hex::{hex, parse_hex};
use crate::link::{Link, LinkError};

/// Where a tap sends what it sees.
pub trait TapSink: Send + Sync {
    /// `data` went `direction` at `at` (on the tap's clock).
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>);
}

impl<T: TapSink + ?Sized> TapSink for Arc<T> {
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        (**self).record(at, direction, data)
    }
}

/// Several sinks at once (a capture file and a live trace).
pub struct Fanout(pub Vec<Arc<dyn TapSink>>);

impl TapSink for Fanout {
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        for s in &self.0 {
            s.record(at, direction, data);
        }
    }
}

/// A byte link whose traffic goes to a [`TapSink`] as well.
pub struct TapLink<L> {
    inner: L,
    clock: SharedClock,
    sink: Arc<dyn TapSink>,
}

impl<L: Link> TapLink<L> {
    /// Wraps `inner`; what passes goes to `sink`, stamped by `clock`.
    pub fn new(inner: L, clock: SharedClock, sink: impl TapSink + 'static) -> Self {
        TapLink { inner, clock, sink: Arc::new(sink) }
    }
}

impl<L: Link> Link for TapLink<L> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        // Nothing sent, nothing recorded (a capture line has bytes).
        if !bytes.is_empty() {
            self.sink.record(self.clock.now(), Direction::ToDevice, Chunk::Bytes(bytes));
        }
        self.inner.send(bytes)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let n = self.inner.recv(buf, timeout)?;
        if n > 0 {
            self.sink.record(self.clock.now(), Direction::FromDevice, Chunk::Bytes(&buf[..n]));
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }
    fn send_break(&mut self, duration: Duration) -> Result<(), LinkError> {
        self.inner.send_break(duration)
    }
}

/// A CAN link whose frames go to a [`TapSink`] as well.
pub struct TapCanLink<L> {
    inner: L,
    clock: SharedClock,
    sink: Arc<dyn TapSink>,
}

impl<L: CanLink> TapCanLink<L> {
    /// Wraps `inner`; frames go to `sink`, stamped by `clock`.
    pub fn new(inner: L, clock: SharedClock, sink: impl TapSink + 'static) -> Self {
        TapCanLink { inner, clock, sink: Arc::new(sink) }
    }
}

impl<L: CanLink> CanLink for TapCanLink<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.sink.record(self.clock.now(), Direction::ToDevice, Chunk::Frame(frame));
        self.inner.send(frame)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let frame = self.inner.recv(timeout)?;
        if let Some(f) = &frame {
            self.sink.record(self.clock.now(), Direction::FromDevice, Chunk::Frame(f));
        }
        Ok(frame)
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }
}

/// Maps a clock's timestamps to Unix time: the Unix time of the clock's origin, taken when made.
#[derive(Debug, Clone, Copy)]
pub struct UnixTime {
    origin: Duration,
}

impl UnixTime {
    /// The mapping for `clock`, read now.
    pub fn of(clock: &SharedClock) -> Self {
        let wall = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
        UnixTime { origin: wall.saturating_sub(clock.now().since_origin()) }
    }

    /// The Unix time of `at`.
    pub fn at(self, at: Timestamp) -> Duration {
        self.origin + at.since_origin()
    }
}

/// Formats a Unix time as a capture does: `(1732470000.123456)`.
pub fn format_time(unix: Duration) -> String {
    format!("({}.{:06})", unix.as_secs(), unix.subsec_micros())
}

/// One line of a capture file, formatted.
pub fn format_line(unix: Duration, direction: Direction, data: Chunk<'_>, can_interface: &str) -> String {
    match data {
        Chunk::Bytes(b) => format!("{} {} {}", format_time(unix), direction.arrow(), hex(b)),
        Chunk::Frame(f) => format!("{} {can_interface} {f}", format_time(unix)),
    }
}

/// Writes a capture file (see the [module documentation](self)); a failed write is logged once and the
/// session goes on.
pub struct CaptureWriter {
    out: Mutex<(Box<dyn Write + Send>, bool)>,
    time: UnixTime,
    can_interface: String,
}

impl CaptureWriter {
    /// Writes to `out`, starting with a `#` line that says `what` (family and port). `can_interface` names
    /// the interface in CAN lines (`can0`).
    pub fn new(
        mut out: Box<dyn Write + Send>,
        clock: &SharedClock,
        what: &str,
        can_interface: &str,
    ) -> std::io::Result<Self> {
        writeln!(out, "# motionlink capture: {what}")?;
        Ok(CaptureWriter {
            out: Mutex::new((out, false)),
            time: UnixTime::of(clock),
            can_interface: can_interface.into(),
        })
    }

    /// Flushes what was written.
    pub fn flush(&self) -> std::io::Result<()> {
        lock(&self.out).0.flush()
    }
}

impl TapSink for CaptureWriter {
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        let line = format_line(self.time.at(at), direction, data, &self.can_interface);
        let mut out = lock(&self.out);
        let (w, failed) = &mut *out;
        if let Err(e) = writeln!(w, "{line}").and_then(|_| w.flush()) {
            if !*failed {
                tracing::warn!("cannot write the capture: {e}");
                *failed = true;
            }
        }
    }
}

/// What one line of a capture holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CapturedLine {
    /// Bytes of a serial line.
    Bytes(Vec<u8>),
    /// A CAN frame, with the interface the line names.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// The interface (`can0`), if named.
        interface: Option<String>,
    },
}

/// One parsed line of a capture.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParsedLine {
    /// The Unix time the line gives, if any.
    pub unix: Option<Duration>,
    /// The direction the line gives: the capture file's `->` / `<-`, candump `-x`'s `T` / `TX` (to the device)
    /// and `R` / `RX` (from it); `Unknown` for plain hex and candump lines without a mark.
    pub direction: Direction,
    /// Its bytes or frame.
    pub data: CapturedLine,
}

/// Parses one line of a capture: a capture line with time and direction, a candump line (log or screen
/// form), or plain hex (pairs of digits, optionally separated by spaces, `,`, `:` or `-`, each optionally
/// with `0x`). `Ok(None)` for a blank or `#` comment line; an error names what is wrong.
pub fn parse_line(line: &str) -> Result<Option<ParsedLine>, String> {
    let t = line.trim();
    if t.is_empty() || t.starts_with('#') {
        return Ok(None);
    }
    let (unix, rest) = match t.strip_prefix('(').and_then(|r| r.split_once(')')) {
        Some((time, rest)) => {
            (Some(parse_unix(time).ok_or_else(|| format!("{time:?} is not a time stamp"))?), rest.trim())
        }
        None => (None, t),
    };
    for (arrow, direction) in [("->", Direction::ToDevice), ("<-", Direction::FromDevice)] {
        if let Some(hex_text) = rest.strip_prefix(arrow) {
            if hex_text.trim().is_empty() {
                return Err(format!("no bytes after {arrow}"));
            }
            return Ok(Some(ParsedLine { unix, direction, data: CapturedLine::Bytes(parse_hex(hex_text)?) }));
        }
    }
    if unix.is_some() && rest.is_empty() {
        return Err("a time stamp without bytes".into());
    }
    let (rest, direction) = candump_direction(rest);
    if looks_like_candump(&rest) {
        // The candump parser reads the line with its time stamp, without the direction mark.
        let stamp = match t.split_once(')') {
            Some((time, _)) if t.starts_with('(') => format!("{time}) "),
            _ => String::new(),
        };
        let c: CandumpLine = format!("{stamp}{rest}").parse().map_err(|e| format!("{e}"))?;
        return Ok(Some(ParsedLine {
            unix: c.timestamp,
            direction,
            data: CapturedLine::Frame { frame: c.frame, interface: c.interface },
        }));
    }
    Ok(Some(ParsedLine { unix, direction: Direction::Unknown, data: CapturedLine::Bytes(parse_hex(&rest)?) }))
}

/// The direction mark of a candump line made with `-x` (a line without its time stamp), and the line without
/// it: the log form `can0 0F1#01 T` (`T` sent by this host: to the device; `R` received: from it) and the
/// screen form `can0 TX - - 0F1 [1] 01` (`TX` / `RX`, then the BRS and ESI flags of CAN FD). Other lines
/// are returned as they are, direction `Unknown`.
fn candump_direction(rest: &str) -> (String, Direction) {
    let words: Vec<&str> = rest.split_whitespace().collect();
    let of = |mark: &str| match mark {
        "T" | "TX" => Some(Direction::ToDevice),
        "R" | "RX" => Some(Direction::FromDevice),
        _ => None,
    };
    match words.as_slice() {
        [iface, frame, mark] if frame.contains('#') => match of(mark) {
            Some(d) => (format!("{iface} {frame}"), d),
            None => (rest.to_string(), Direction::Unknown),
        },
        [iface, mark, brs, esi, id, len, data @ ..]
            if len.starts_with('[') && [brs, esi].iter().all(|f| f.len() == 1) && of(mark).is_some() =>
        {
            let d = of(mark).unwrap_or(Direction::Unknown);
            (format!("{iface} {id} {len} {}", data.join(" ")).trim_end().to_string(), d)
        }
        _ => (rest.to_string(), Direction::Unknown),
    }
}

/// True if `rest` (a line without its time stamp) has the shape of a candump line: `can0 0F1#01`,
/// `0F1#01`, or the screen form `can0  0F1   [1]  01`.
fn looks_like_candump(rest: &str) -> bool {
    let words: Vec<&str> = rest.split_whitespace().collect();
    match words.as_slice() {
        [frame] => frame.contains('#'),
        [_, frame, ..] if frame.contains('#') => true,
        [_, _, len, ..] => len.starts_with('[') && len.ends_with(']'),
        _ => false,
    }
}

fn parse_unix(text: &str) -> Option<Duration> {
    let (secs, frac) = text.split_once('.').unwrap_or((text, ""));
    let secs: u64 = secs.parse().ok()?;
    if frac.len() > 9 || !frac.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    let nanos: u32 = if frac.is_empty() { 0 } else { format!("{frac:0<9}").parse().ok()? };
    Some(Duration::new(secs, nanos))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::ManualClock;

    /// A sink that keeps the formatted lines.
    #[derive(Default)]
    struct Lines(Mutex<Vec<String>>);

    impl TapSink for Lines {
        fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
            let unix = Duration::from_secs(1_732_470_000) + at.since_origin();
            lock(&self.0).push(format_line(unix, direction, data, "can0"));
        }
    }

    #[test]
    fn what_is_written_is_read_back() {
        let clock = ManualClock::new();
        let frame = CanFrame::new(0x0F1, &[0x01]).unwrap();
        let sink = Lines::default();
        sink.record(Timestamp::from_micros(1_500), Direction::ToDevice, Chunk::Bytes(&[0x52, 0x47]));
        sink.record(Timestamp::from_micros(2_000_250), Direction::FromDevice, Chunk::Frame(&frame));
        let lines = lock(&sink.0).clone();
        assert_eq!(lines, vec!["(1732470000.001500) -> 52 47", "(1732470002.000250) can0 0F1#01"]);
        let first = parse_line(&lines[0]).unwrap().unwrap();
        assert_eq!(first.unix, Some(Duration::new(1_732_470_000, 1_500_000)));
        assert_eq!(first.direction, Direction::ToDevice);
        assert_eq!(first.data, CapturedLine::Bytes(vec![0x52, 0x47]));
        let second = parse_line(&lines[1]).unwrap().unwrap();
        assert_eq!(second.data, CapturedLine::Frame { frame, interface: Some("can0".into()) });
        let _ = clock;
    }

    #[test]
    fn plain_hex_comments_and_bad_lines() {
        assert_eq!(parse_line("# note").unwrap(), None);
        assert_eq!(parse_line("   ").unwrap(), None);
        let plain = parse_line("0x52,47:11-00").unwrap().unwrap();
        assert_eq!((plain.direction, plain.data), (Direction::Unknown, CapturedLine::Bytes(vec![0x52, 0x47, 0x11, 0])));
        assert!(parse_line("(12x) -> 52").unwrap_err().contains("time stamp"));
        assert!(parse_line("-> 5").unwrap_err().contains("not hex"));
        assert_eq!(parse_line("(1) <-").unwrap_err(), "no bytes after <-");
        assert_eq!(parse_line("(1)").unwrap_err(), "a time stamp without bytes");
        let screen = parse_line("  can0  0F1   [1]  01").unwrap().unwrap();
        assert!(matches!(screen.data, CapturedLine::Frame { .. }));
    }

    #[test]
    fn candump_x_direction_marks_are_kept() {
        let frame = |id: u32, data: &[u8]| CapturedLine::Frame {
            frame: CanFrame::new(id, data).unwrap(),
            interface: Some("can0".into()),
        };
        let unix = Some(Duration::new(1_700_000_000, 500_000_000));
        let sent = parse_line("(1700000000.500000) can0 0F1#01 T").unwrap().unwrap();
        assert_eq!(sent, ParsedLine { unix, direction: Direction::ToDevice, data: frame(0x0F1, &[1]) });
        let received = parse_line("(1700000000.500000) can0 0B1#0A3C R").unwrap().unwrap();
        assert_eq!(received, ParsedLine { unix, direction: Direction::FromDevice, data: frame(0x0B1, &[0x0A, 0x3C]) });
        let screen = parse_line("(1700000000.500000)  can0  TX - -  0F1   [1]  01").unwrap().unwrap();
        assert_eq!(screen, ParsedLine { unix, direction: Direction::ToDevice, data: frame(0x0F1, &[1]) });
        let screen = parse_line("  can0  RX - -  0B1   [2]  0A 3C").unwrap().unwrap();
        assert_eq!(
            screen,
            ParsedLine { unix: None, direction: Direction::FromDevice, data: frame(0x0B1, &[0x0A, 0x3C]) }
        );
        // Without -x: no direction.
        assert_eq!(parse_line("can0 0F1#01").unwrap().unwrap().direction, Direction::Unknown);
    }
}
