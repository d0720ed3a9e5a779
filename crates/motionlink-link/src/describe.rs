//! The one decoder signature of every family: captured traffic in, annotated telegrams out. `motionlink
//! decode` (on the files the capture writer wrote, and on candump logs), the live wire trace (`-v`), `send`'s
//! printout and the web console's traffic log all call a family's [`Describe`] the same way; on live
//! traffic through one tap, [`DescribingTap`].
//!
//! A describer keeps state between calls: a telegram may arrive in pieces, and a reply is explained with
//! the request before it.

use crate::chunk::{Chunk, Direction};
use crate::clock::Timestamp;

/// One telegram (or a stretch of bytes that is none), explained.
#[derive(Debug, Clone, PartialEq)]
pub struct Annotation {
    /// When it was captured, if known.
    pub at: Option<Timestamp>,
    /// Which way it went (decided from the bytes when the capture did not say).
    pub direction: Direction,
    /// The CAN identifier, for a frame.
    pub can_id: Option<u32>,
    /// Its bytes (a frame's data).
    pub bytes: Vec<u8>,
    /// What it means, or what is wrong with it.
    pub meaning: String,
    /// True when it is not a valid telegram (garbage, a bad checksum, a truncated frame).
    pub bad: bool,
}

/// A family's decoder of captured traffic.
pub trait Describe {
    /// Explains `chunk`, which went `direction` at `at` (if known), appending one annotation per
    /// telegram completed (none while a telegram is still incomplete).
    fn describe(&mut self, chunk: Chunk<'_>, direction: Direction, at: Option<Timestamp>, out: &mut Vec<Annotation>);

    /// The capture ended: reports what is left incomplete.
    fn finish(&mut self, out: &mut Vec<Annotation>);
}

/// What a boxed [`DescribingTap`] does with the telegrams it explains.
pub type OnTelegrams = Box<dyn Fn(Timestamp, &mut Vec<Annotation>) + Send + Sync>;

/// A tap that explains the traffic as it passes: a family's [`Describe`] reads every chunk or frame, and each
/// telegram it completes is handed, annotated, to `on_telegrams` (with the time of the chunk that completed
/// it). The live wire trace (`-v`), `send`'s printout and the web console's traffic log are all one of these
/// with their own `on_telegrams`.
///
/// ```
/// use std::sync::{Arc, Mutex};
/// use motionlink_link::capture::TapSink;
/// use motionlink_link::chunk::{Chunk, Direction};
/// use motionlink_link::describe::{Annotation, Describe, DescribingTap};
/// use motionlink_link::Timestamp;
///
/// /// A toy family: every byte is a telegram.
/// struct Bytes;
/// impl Describe for Bytes {
///     fn describe(&mut self, c: Chunk<'_>, d: Direction, at: Option<Timestamp>, out: &mut Vec<Annotation>) {
///         if let Chunk::Bytes(b) = c {
///             for x in b {
///                 let meaning = format!("byte {x}");
///                 out.push(Annotation { at, direction: d, can_id: None, bytes: vec![*x], meaning, bad: false });
///             }
///         }
///     }
///     fn finish(&mut self, _: &mut Vec<Annotation>) {}
/// }
///
/// let seen = Arc::new(Mutex::new(Vec::new()));
/// let keep = Arc::clone(&seen);
/// let tap = DescribingTap::new(Box::new(Bytes), move |_, found: &mut Vec<Annotation>| {
///     keep.lock().unwrap().append(found)
/// });
/// tap.record(Timestamp::ZERO, Direction::ToDevice, Chunk::Bytes(&[1, 2]));
/// assert_eq!(seen.lock().unwrap().iter().map(|a| a.meaning.as_str()).collect::<Vec<_>>(), ["byte 1", "byte 2"]);
/// ```
pub struct DescribingTap<F = OnTelegrams> {
    describer: std::sync::Mutex<(Box<dyn Describe + Send>, Vec<Annotation>)>,
    on_telegrams: F,
}

impl<F> DescribingTap<F>
where
    F: Fn(Timestamp, &mut Vec<Annotation>) + Send + Sync,
{
    /// A tap explaining with `describer`; `on_telegrams` receives the telegrams completed by each chunk (it
    /// may take them out of the vector; what it leaves is dropped).
    pub fn new(describer: Box<dyn Describe + Send>, on_telegrams: F) -> Self {
        DescribingTap { describer: std::sync::Mutex::new((describer, Vec::new())), on_telegrams }
    }
}

impl<F> crate::capture::TapSink for DescribingTap<F>
where
    F: Fn(Timestamp, &mut Vec<Annotation>) + Send + Sync,
{
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        let mut state = crate::clock::lock(&self.describer);
        let (describer, found) = &mut *state;
        describer.describe(data, direction, Some(at), found);
        if !found.is_empty() {
            (self.on_telegrams)(at, found);
            found.clear();
        }
    }
}
