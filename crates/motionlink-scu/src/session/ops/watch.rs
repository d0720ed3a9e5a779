//! Watching the state: a sample every interval of every actuator's status, position and current and of the
//! last error. Where the unit takes the session's cyclic object, each sample rides on a keepalive RC (so a
//! link whose round trips leave no room for any other request between two RCs can still be watched);
//! otherwise each sample is four reads, which go out only when there is room beside the keepalive.

use std::time::Duration;

use motionlink_link::Timestamp;

use super::object::DefineObject;
use super::{currents, error_code, positions, statuses, Cx, ItemRead, Next, Operation, Output, Progress, Resume, Step};
use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataIndex, PositionCounts};
use crate::session::report::Snapshot;
use crate::wire::Command;

/// What a watch samples, and how often.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WatchSpec {
    /// Time between samples (the first is taken at once).
    pub interval: Duration,
    /// Stop after this many samples; `None`: until cancelled.
    pub count: Option<u64>,
}

/// The four reads of a sample taken with RG, in order.
const READS: [DataIndex; 4] = [DataIndex(0x0170), DataIndex(0x0010), DataIndex(0x00A0), DataIndex(0x00D1)];

enum Phase {
    /// The session's cyclic object is defined and probed.
    Define(DefineObject),
    /// Waiting until the next sample is due.
    Pause,
    /// Waiting for the next keepalive RC that carries the object.
    Snapshot,
    /// Reading `READS[i]`.
    Read(usize, ItemRead),
}

/// A watch; see [`super::Op::Watch`] and [`crate::Client::watch`].
pub(crate) struct Watch {
    spec: WatchSpec,
    phase: Phase,
    next_due: Timestamp,
    samples: u64,
    last: Option<Snapshot>,
    /// What the reads of the sample under way gave so far.
    statuses: [ActuatorStatus1; 6],
    positions: [PositionCounts; 6],
    currents: [u16; 6],
}

impl Watch {
    pub fn new(spec: WatchSpec, now: Timestamp) -> Self {
        Watch {
            spec,
            phase: Phase::Pause,
            next_due: now,
            samples: 0,
            last: None,
            statuses: [ActuatorStatus1::EMPTY; 6],
            positions: [PositionCounts(0); 6],
            currents: [0; 6],
        }
    }

    fn end(&self) -> Next {
        Next::Done(Ok(Output::Watched { samples: self.samples, last: self.last }))
    }

    /// Takes a sample: through the keepalive where the object is configured, else with reads.
    fn sample(&mut self, cx: &mut Cx<'_>) -> Next {
        if cx.core.poll_slot().is_some() && cx.core.poll.configured {
            self.phase = Phase::Snapshot;
            return Next::Snapshot;
        }
        self.read(cx, 0)
    }

    /// Starts read `i` of a sample taken with reads (positions and currents of the connected actuators only).
    fn read(&mut self, cx: &mut Cx<'_>, i: usize) -> Next {
        let connected: Vec<Actuator> = Actuator::all().filter(|a| self.statuses[idx(*a)].available()).collect();
        let mut read = match i {
            0 => ItemRead::all(READS[0]),
            _ => ItemRead::actuators(READS[i], connected),
        };
        let step = read.step(cx, Resume::Start);
        self.phase = Phase::Read(i, read);
        self.after_read(cx, i, step)
    }

    fn after_read(&mut self, cx: &mut Cx<'_>, i: usize, step: Step<Result<Vec<u8>, Error>>) -> Next {
        let data = match step {
            // A cancel ends the watch before anything more is asked.
            Step::Wait(_) | Step::Done(_) if cx.cancelled => return self.end(),
            Step::Wait(next) => return next,
            Step::Done(Ok(data)) => data,
            Step::Done(Err(e)) => return Next::Done(Err(e)),
        };
        let parsed = match i {
            0 => statuses(&data).map(|s| self.statuses = s),
            1 => positions(&data).map(|p| self.positions = p),
            2 => currents(&data).map(|c| self.currents = c),
            _ => error_code(&data).map(|last_error| {
                self.last = Some(Snapshot {
                    at: cx.now(),
                    statuses: self.statuses,
                    positions: self.positions,
                    currents_deci_amps: self.currents,
                    last_error,
                })
            }),
        };
        if let Err(e) = parsed {
            return Next::Done(Err(e));
        }
        if i + 1 < READS.len() {
            return self.read(cx, i + 1);
        }
        match self.last {
            Some(s) => self.took(cx, s),
            None => Next::Done(Err(Error::UnexpectedReply { command: Command::Get, detail: "no sample".into() })),
        }
    }

    /// A sample was taken: reported; the next is due one interval after this one was (no drift).
    fn took(&mut self, cx: &mut Cx<'_>, s: Snapshot) -> Next {
        self.samples += 1;
        self.last = Some(s);
        cx.progress(Progress::Watch(s));
        if cx.cancelled || self.spec.count.is_some_and(|c| self.samples >= c) {
            return self.end();
        }
        let now = cx.now();
        while self.next_due <= now {
            self.next_due += self.spec.interval.max(Duration::from_millis(1));
        }
        self.phase = Phase::Pause;
        // Through the keepalive, the sample is asked for a round trip early: the RC that carries it then
        // comes back about when it is due (on a slow link the RC under way is waited for first).
        let lead = if cx.core.poll.configured {
            cx.core.line.recent_round_trip.unwrap_or(cx.core.line.round_trip)
        } else {
            Duration::ZERO
        };
        let ask_at = Timestamp::from_duration(self.next_due.since_origin().saturating_sub(lead));
        Next::Sleep(ask_at.max(now))
    }
}

fn idx(a: Actuator) -> usize {
    usize::from(a.number() - 1)
}

impl Operation for Watch {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        if cx.cancelled && matches!(resume, Resume::Wake) {
            return self.end();
        }
        match (std::mem::replace(&mut self.phase, Phase::Pause), resume) {
            (_, Resume::Start) => match DefineObject::start(cx) {
                Some((define, next)) => {
                    self.phase = Phase::Define(define);
                    next
                }
                None => self.sample(cx),
            },
            (Phase::Define(mut define), resume) => match define.step(cx, resume) {
                Step::Wait(next) => {
                    self.phase = Phase::Define(define);
                    next
                }
                Step::Done(Ok(())) if cx.cancelled => self.end(),
                Step::Done(Ok(())) => self.sample(cx),
                Step::Done(Err(_)) if cx.cancelled => self.end(),
                Step::Done(Err(e)) => Next::Done(Err(e)),
            },
            (Phase::Pause, Resume::Wake) => self.sample(cx),
            (Phase::Snapshot, Resume::Snapshot(Ok(s))) => self.took(cx, s),
            (Phase::Snapshot, Resume::Snapshot(Err(e))) => Next::Done(Err(e)),
            (Phase::Read(i, mut read), resume) => {
                let step = read.step(cx, resume);
                self.phase = Phase::Read(i, read);
                self.after_read(cx, i, step)
            }
            (phase, other) => {
                self.phase = phase;
                Next::Done(Err(Error::UnexpectedReply {
                    command: Command::Get,
                    detail: format!("{other:?} while watching"),
                }))
            }
        }
    }
}
