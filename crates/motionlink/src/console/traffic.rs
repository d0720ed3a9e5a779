//! The console's traffic log: a [`TapSink`] on the device's link that keeps every chunk or frame in the
//! capture format (`motionlink_link::capture`, what `motionlink decode` reads back) for the page's download,
//! and every telegram decoded by the family's [`Describe`] for the page's live log.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use motionlink_link::capture::{format_line, TapSink, UnixTime};
use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::clock::{lock, SharedClock, Timestamp};
use motionlink_link::describe::{Annotation, Describe, DescribingTap, OnTelegrams};
use motionlink_link::hex::hex;

/// How many capture lines the download keeps (the oldest go first).
pub const CAPTURE_LINES: usize = 200_000;
/// How many decoded telegrams the live log keeps for pages that fall behind.
pub const LOG_LINES: usize = 2_000;

/// One decoded telegram of the live log; serialises with `direction` by name and the bytes as `hex`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LogLine {
    /// Its place in the log (counts up from 1).
    pub seq: u64,
    /// Seconds since the console started.
    pub t_s: f64,
    /// Which way it went.
    #[serde(serialize_with = "direction_name")]
    pub direction: Direction,
    /// Its bytes (a CAN frame's data).
    #[serde(rename = "hex", serialize_with = "hex_string")]
    pub bytes: Vec<u8>,
    /// The CAN identifier, for a frame.
    pub can_id: Option<u32>,
    /// What it means.
    pub meaning: String,
    /// True when it is not a valid telegram.
    pub bad: bool,
}

fn direction_name<S: serde::Serializer>(d: &Direction, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(d.name())
}

fn hex_string<S: serde::Serializer>(bytes: &[u8], s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&hex(bytes))
}

struct Inner {
    capture: VecDeque<String>,
    capture_dropped: u64,
    log: VecDeque<LogLine>,
    next_seq: u64,
}

/// The traffic of one link, captured and decoded.
pub struct Traffic {
    inner: Arc<Mutex<Inner>>,
    decoded: DescribingTap,
    time: UnixTime,
    header: String,
    can_interface: String,
}

impl Traffic {
    /// A log of the link named `what` (family and port, for the capture's header), decoded by `describer`;
    /// `can_interface` names the interface in CAN lines; `clock` is the clock the tap stamps with.
    pub fn new(describer: Box<dyn Describe + Send>, what: &str, can_interface: &str, clock: &SharedClock) -> Self {
        let inner = Arc::new(Mutex::new(Inner {
            capture: VecDeque::new(),
            capture_dropped: 0,
            log: VecDeque::new(),
            next_seq: 1,
        }));
        let started = clock.now();
        let log = Arc::clone(&inner);
        let to_log: OnTelegrams = Box::new(move |at: Timestamp, found: &mut Vec<Annotation>| {
            let t_s = at.saturating_since(started).as_secs_f64();
            let mut inner = lock(&log);
            for a in found.drain(..) {
                let seq = inner.next_seq;
                inner.next_seq += 1;
                let t = a.at.map_or(t_s, |t| t.saturating_since(started).as_secs_f64());
                inner.log.push_back(LogLine {
                    seq,
                    t_s: t,
                    direction: a.direction,
                    bytes: a.bytes,
                    can_id: a.can_id,
                    meaning: a.meaning,
                    bad: a.bad,
                });
                if inner.log.len() > LOG_LINES {
                    inner.log.pop_front();
                }
            }
        });
        Traffic {
            inner,
            decoded: DescribingTap::new(describer, to_log),
            time: UnixTime::of(clock),
            header: format!("# motionlink capture: {what}"),
            can_interface: can_interface.to_string(),
        }
    }

    /// The decoded telegrams after `after` (a `seq`), at most `limit` of the newest.
    pub fn since(&self, after: u64, limit: usize) -> Vec<LogLine> {
        let inner = lock(&self.inner);
        let new: Vec<&LogLine> = inner.log.iter().filter(|l| l.seq > after).collect();
        let skip = new.len().saturating_sub(limit);
        new.into_iter().skip(skip).cloned().collect()
    }

    /// The newest `seq` so far (0 before the first telegram).
    pub fn last_seq(&self) -> u64 {
        lock(&self.inner).next_seq - 1
    }

    /// The capture file: the header line, a note if old lines were dropped, then every line kept.
    pub fn capture_file(&self) -> String {
        let inner = lock(&self.inner);
        let mut out = String::with_capacity(inner.capture.iter().map(|l| l.len() + 1).sum::<usize>() + 128);
        out.push_str(&self.header);
        out.push('\n');
        if inner.capture_dropped > 0 {
            out.push_str(&format!(
                "# the {} oldest lines were dropped (the console keeps the last {CAPTURE_LINES})\n",
                inner.capture_dropped
            ));
        }
        for l in &inner.capture {
            out.push_str(l);
            out.push('\n');
        }
        out
    }
}

impl TapSink for Traffic {
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        let line = format_line(self.time.at(at), direction, data, &self.can_interface);
        {
            let mut inner = lock(&self.inner);
            inner.capture.push_back(line);
            if inner.capture.len() > CAPTURE_LINES {
                inner.capture.pop_front();
                inner.capture_dropped += 1;
            }
        }
        self.decoded.record(at, direction, data);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motionlink_link::capture::{parse_line, CapturedLine};
    use motionlink_link::clock::ManualClock;

    #[test]
    fn the_download_reads_back_as_a_capture_and_the_log_is_decoded() {
        let clock = ManualClock::new();
        let shared = clock.shared();
        let traffic = Traffic::new(Box::new(motionlink_scu::describe::Describer::new()), "scu sim", "can0", &shared);
        // RG 0x0011 (the manual's example) and its ACK, the request in two chunks.
        traffic.record(shared.now(), Direction::ToDevice, Chunk::Bytes(&[0x52, 0x47]));
        traffic.record(shared.now(), Direction::ToDevice, Chunk::Bytes(&[0x11, 0x00, 0x2C, 0x30]));
        let file = traffic.capture_file();
        let mut lines = file.lines();
        assert_eq!(lines.next(), Some("# motionlink capture: scu sim"));
        let parsed: Vec<_> = lines.map(|l| parse_line(l).unwrap().unwrap()).collect();
        assert_eq!(parsed.len(), 2);
        assert_eq!(parsed[1].direction, Direction::ToDevice);
        assert_eq!(parsed[1].data, CapturedLine::Bytes(vec![0x11, 0x00, 0x2C, 0x30]));
        let log = traffic.since(0, 10);
        assert_eq!(log.len(), 1, "one telegram from two chunks: {log:?}");
        assert_eq!(log[0].bytes, vec![0x52, 0x47, 0x11, 0x00, 0x2C, 0x30]);
        assert!(!log[0].bad && log[0].meaning.contains("0x0011"), "{}", log[0].meaning);
        assert_eq!(traffic.last_seq(), 1);
        assert!(traffic.since(1, 10).is_empty());
    }
}
