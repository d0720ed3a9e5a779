//! [`Follower`]: the policy of following a source of targets with a [`SetpointStream`] (what
//! `motionlink scu follow` does with stdin, and any caller with its own source): targets applied at most
//! `rate_hz` times a second, the newest pending one winning; at the end the newest pending target is applied,
//! the motion is let reach it and the stream ends along the ramp (soft RS); a cancel or an error ends it at
//! once (fast RS); success means each actuator the function drives ended within
//! [`Config::position_tolerance_counts`](crate::Config::position_tolerance_counts) of its last target (where
//! the function map does not know the function: the actuator asked for, and every other one that moved).

use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::Wake;
use motionlink_link::Timestamp;

use super::SetpointStream;
use crate::error::{Error, TargetMiss};
use crate::model::{Actuator, PositionCounts, Speed, StopMode};

/// Where a follow's actuators came to rest, and how many updates it applied.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FollowReport {
    /// Each actuator of the stream and where it came to rest, in the stream's order.
    pub rest: Vec<(Actuator, PositionCounts)>,
    /// How many updates of targets were applied.
    pub updates: u64,
}

/// Why [`Follower::finish`] failed, and, when the stream was stopped and the unit told where the actuators
/// came to rest, that report (a cancel during the settling, a last target missed).
#[derive(Debug, Clone, thiserror::Error)]
#[error("{error}")]
pub struct FollowFailure {
    /// What went wrong.
    pub error: Error,
    /// Where the actuators came to rest, if the stream was stopped and the unit confirmed it.
    pub stopped: Option<FollowReport>,
}

impl From<FollowFailure> for Error {
    fn from(f: FollowFailure) -> Self {
        f.error
    }
}

/// A [`SetpointStream`] that follows targets offered at any pace, at most `rate_hz` updates a second.
///
/// ```no_run
/// # fn f(client: &motionlink_scu::Client) -> Result<(), Box<dyn std::error::Error>> {
/// use motionlink_link::cancel::CancelToken;
/// use motionlink_scu::client::Follower;
/// use motionlink_scu::model::{Actuator, MotionFunction, PositionCounts, Speed};
/// let (a1, f1) = (Actuator::new(1).unwrap(), MotionFunction::new(1).unwrap());
/// let stream = client.stream(f1, &[a1], Speed::percent(60).unwrap())?;
/// let mut follower = Follower::new(stream, a1, 20)?;
/// for target in [100, 200, 300] {
///     follower.offer(vec![PositionCounts(target)]); // the newest pending target wins
///     if let Some(applied) = follower.apply_due()? {
///         println!("target {}", applied[0]);
///     }
/// }
/// let report = follower.finish(&CancelToken::new())?; // the last target, reached, then a soft stop
/// println!("{} update(s), rest {:?}", report.updates, report.rest);
/// # Ok(())
/// # }
/// ```
#[derive(Debug)]
pub struct Follower<'c> {
    stream: SetpointStream<'c>,
    primary: Actuator,
    /// Where the stream's actuators stood when the follow began, read where the function map does not know
    /// the function: one that moved since is one the function drives.
    start: Option<Vec<PositionCounts>>,
    gap: Duration,
    last_update: Option<Timestamp>,
    pending: Option<Vec<PositionCounts>>,
    last_targets: Option<Vec<PositionCounts>>,
    updates: u64,
}

impl<'c> Follower<'c> {
    /// Follows with `stream` at most `rate_hz` (at least 1) updates a second. `primary` is the actuator asked
    /// for: where [`Config::function_map`](crate::Config::function_map) does not know the stream's function,
    /// it is judged at the end, and so is every other actuator of the stream that moved (one the function
    /// drives, as a move judges them); their positions are read here for that.
    pub fn new(stream: SetpointStream<'c>, primary: Actuator, rate_hz: u32) -> Result<Self, Error> {
        if rate_hz == 0 {
            return Err(Error::invalid("a follow's rate is at least 1 update a second"));
        }
        let start = match stream.client().config().function_map.drives(stream.function()) {
            Some(_) => None,
            None => Some(stream.positions()?.into_iter().map(|(_, p, _)| p).collect()),
        };
        Ok(Follower {
            stream,
            primary,
            start,
            gap: Duration::from_secs(1) / rate_hz,
            last_update: None,
            pending: None,
            last_targets: None,
            updates: 0,
        })
    }

    /// The stream underneath.
    pub fn stream(&self) -> &SetpointStream<'c> {
        &self.stream
    }

    /// The actuators, in the order targets are given.
    pub fn actuators(&self) -> &[Actuator] {
        self.stream.actuators()
    }

    /// How many updates were applied so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// New targets (one per actuator, in the stream's order), applied by the next [`Follower::apply_due`]
    /// that is due; they replace any not applied yet (the newest wins).
    pub fn offer(&mut self, targets: Vec<PositionCounts>) {
        self.pending = Some(targets);
    }

    /// A new speed for the running motion, at once ([`SetpointStream::set_speed`]).
    pub fn set_speed(&mut self, speed: impl Into<Speed>) -> Result<(), Error> {
        self.stream.set_speed(speed)
    }

    /// Applies the pending targets if there are any and the last update is at least `1 / rate_hz` ago on the
    /// session's clock; returns what was applied. On an error, end the follow with [`Follower::abort`].
    pub fn apply_due(&mut self) -> Result<Option<&[PositionCounts]>, Error> {
        let now = self.stream.client().clock().now();
        if self.pending.is_none() || self.last_update.is_some_and(|t| now - t < self.gap) {
            return Ok(None);
        }
        self.apply(now)
    }

    /// Applies the pending targets now, whatever the rate (end of input); returns what was applied.
    pub fn flush(&mut self) -> Result<Option<&[PositionCounts]>, Error> {
        let now = self.stream.client().clock().now();
        self.apply(now)
    }

    fn apply(&mut self, now: Timestamp) -> Result<Option<&[PositionCounts]>, Error> {
        let Some(targets) = self.pending.take() else { return Ok(None) };
        self.stream.set_targets(&targets)?;
        self.last_update = Some(now);
        self.updates += 1;
        Ok(Some(self.last_targets.insert(targets)))
    }

    /// Ends the follow as its input ended: applies the newest pending target, waits until no actuator of the
    /// stream moves (looking every [`Config::poll_interval`](crate::Config::poll_interval) on the
    /// session's clock), stops the function along the ramp (soft RS), and checks that each actuator the
    /// function drives ended within the tolerance of its last target ([`Error::NotReached`] if not). A
    /// `cancel` while it waits stops the function at once (fast RS) and fails with [`Error::FunctionCancelled`]; a
    /// device error stops it at once too.
    pub fn finish(mut self, cancel: &CancelToken) -> Result<FollowReport, FollowFailure> {
        let failed = |error| FollowFailure { error, stopped: None };
        if let Err(e) = self.flush() {
            return Err(failed(self.abort(e)));
        }
        let mut cancelled = false;
        if self.last_targets.is_some() {
            match self.settle(cancel) {
                Ok(c) => cancelled = c,
                Err(e) => return Err(failed(self.abort(e))),
            }
        }
        let function = self.stream.function();
        let mode = if cancelled { StopMode::Fast } else { StopMode::Soft };
        let (stream, updates, last_targets, primary, start) =
            (self.stream, self.updates, self.last_targets, self.primary, self.start);
        let client = stream.client();
        let report = FollowReport { rest: stream.stop(mode).map_err(failed)?, updates };
        if cancelled {
            let error = Error::FunctionCancelled { function_id: function.id(), stopped: true };
            return Err(FollowFailure { error, stopped: Some(report) });
        }
        let Some(targets) = last_targets else { return Ok(report) };
        let tolerance_counts = client.config().position_tolerance_counts;
        let drives = client.config().function_map.drives(function);
        let moved = |i: usize, p: PositionCounts| {
            start.as_ref().is_some_and(|s| p.counts_from(s[i]).abs() > i64::from(tolerance_counts))
        };
        let driven = |i: usize, a: &Actuator, p: PositionCounts| {
            drives.as_ref().map_or(*a == primary || moved(i, p), |d| d.contains(a))
        };
        let misses: Vec<TargetMiss> = report
            .rest
            .iter()
            .zip(targets)
            .enumerate()
            .filter(|(i, ((a, p), _))| driven(*i, a, *p))
            .map(|(_, pair)| pair)
            .filter(|((_, p), t)| p.counts_from(*t).abs() > i64::from(tolerance_counts))
            .map(|(&(actuator, reached_counts), target_counts)| TargetMiss { actuator, target_counts, reached_counts })
            .collect();
        if misses.is_empty() {
            Ok(report)
        } else {
            Err(FollowFailure { error: Error::NotReached { tolerance_counts, misses }, stopped: Some(report) })
        }
    }

    /// Waits until no actuator of the stream moves: `Ok(true)` if `cancel` came first.
    fn settle(&self, cancel: &CancelToken) -> Result<bool, Error> {
        let client = self.stream.client();
        let clock = client.clock();
        let poll = client.config().poll_interval;
        let signal = clock.signal();
        cancel.watch(&signal);
        let settled = loop {
            match self.stream.positions() {
                Ok(p) if p.iter().all(|(_, _, moving)| !moving) => break Ok(false),
                Ok(_) => {}
                Err(e) => break Err(e),
            }
            let next = clock.now() + poll;
            while !cancel.is_cancelled() && signal.wait_until(Some(next)) == Wake::Raised {}
            if cancel.is_cancelled() {
                break Ok(true);
            }
        };
        cancel.unwatch(&signal);
        settled
    }

    /// Ends the follow at once (a cancel, bad input: anything of the caller's): fast RS, then the status until
    /// no actuator moves; where each came to rest. A stop the unit did not confirm is
    /// [`Error::StopUnconfirmed`].
    pub fn stop_fast(self) -> Result<FollowReport, Error> {
        let updates = self.updates;
        Ok(FollowReport { rest: self.stream.stop(StopMode::Fast)?, updates })
    }

    /// Ends the follow after `cause` (an error of the stream) ended it: fast RS and the status; the error to
    /// report ([`SetpointStream::abort`]).
    pub fn abort(self, cause: Error) -> Error {
        self.stream.abort(cause)
    }
}
