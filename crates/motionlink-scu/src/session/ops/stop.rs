//! Stopping a function and confirming that its actuators came to rest.

use std::time::Duration;

use motionlink_link::error::{Classify, ErrorClass};

use super::{positions, read_item, statuses, ItemRead, Output};
use crate::error::Error;
use crate::model::{Actuator, ActuatorStatus1, DataIndex, Function, MotionFunction, PositionCounts, StopMode};
use crate::session::ctx::Ctx;
use crate::session::report::{ActuatorRest, RefusedStop, StopReport};
use crate::session::request::{PreparedRequest, Req, Schedule};
use crate::wire::Command;

/// RS of a function (or of several, one after the other), then its actuators' status until none moves (at
/// most 500 ms after a fast stop, 3 s after a soft one, which follows the unit's stop ramp), then where they
/// came to rest. The RS goes out before anything else; the status is read through the keepalive RC when the
/// session polls motions that way. Of several functions, one whose RS the unit refuses is noted and the next
/// one is stopped all the same: the status read afterwards is what confirms the stop. A cancel does not cut
/// any of it short.
pub(crate) struct Stop {
    functions: Vec<Function>,
    mode: StopMode,
    watch: Vec<Actuator>,
}

/// Where a stop left the actuators: status 1 and position of A1..A6.
pub(crate) type Rest = ([ActuatorStatus1; 6], [PositionCounts; 6]);

/// Why a stop is not confirmed: words for the message, and the error underneath.
pub(crate) type Unconfirmed = (String, Error);

/// How a stop ended, and the RS the unit refused (only when stopping several functions; one function's
/// refused RS ends the stop as not confirmed), with its answer.
pub(crate) struct Stopped {
    pub rest: Result<Rest, Unconfirmed>,
    pub refused: Vec<(Function, String)>,
}

impl Stop {
    pub fn new(function: Function, mode: StopMode, watch: Vec<Actuator>) -> Self {
        Self::several(vec![function], mode, watch)
    }

    /// RS of each of `functions` in turn (none: only the status is read), then the status of `watch`.
    pub fn several(functions: Vec<Function>, mode: StopMode, watch: Vec<Actuator>) -> Self {
        Stop { functions, mode, watch }
    }

    /// The error of `cause` (what went wrong first) when this stop is then not confirmed (`detail`).
    /// A cause that says already that a stop was not confirmed (and what the unit's watchdog does) is that
    /// error: wrapped in a second one, the message would say it twice.
    pub(crate) fn unconfirmed(&self, cause: Error, detail: String) -> Error {
        if matches!(cause, Error::StopUnconfirmed { .. }) {
            return cause;
        }
        Error::StopUnconfirmed { cause: Box::new(cause), functions: self.functions.clone(), mode: self.mode, detail }
    }

    fn patience(&self) -> Duration {
        match self.mode {
            StopMode::Fast => Duration::from_millis(500),
            StopMode::Soft => Duration::from_secs(3),
        }
    }

    /// Sends the RS and waits until the actuators are at rest (or the patience is over).
    pub async fn run(&self, ctx: &Ctx) -> Stopped {
        let ctx = ctx.firm();
        let mut refused = Vec::new();
        for &function in &self.functions {
            let rs = Req::op(PreparedRequest::stop(function.id(), self.mode)).when(Schedule::Now);
            if let Err(e) = ctx.send(rs).await.and_then(|r| r.ack(Command::Stop)) {
                let answered = matches!(e.class(), ErrorClass::Refused | ErrorClass::Device);
                if !(answered && self.functions.len() > 1) {
                    tracing::info!("could not stop {function}: {e}");
                    ctx.core().stop_unconfirmed(&self.functions);
                    return Stopped { rest: Err((e.to_string(), e)), refused };
                }
                // The unit answered: the line works; the other functions are stopped all the same.
                tracing::warn!("the unit refused the RS of {function}: {e}");
                refused.push((function, e.to_string()));
            }
        }
        let rest = self.confirm(&ctx).await;
        match rest {
            Ok(_) => ctx.core().stop_confirmed(&self.functions, self.watch.len() == Actuator::all().count()),
            Err(_) => ctx.core().stop_unconfirmed(&self.functions),
        }
        Stopped { rest, refused }
    }

    /// The status of the watched actuators until none moves, then where they are.
    async fn confirm(&self, ctx: &Ctx) -> Result<Rest, Unconfirmed> {
        let give_up = ctx.now() + self.patience();
        let (poll_interval, by_snapshot) = {
            let core = ctx.core();
            (core.config.poll_interval, core.poll_slot().is_some() && core.poll.configured)
        };
        loop {
            let (status, at) = if by_snapshot {
                match ctx.snapshot().await {
                    Some(Ok(s)) => (s.statuses, Some(s.positions)),
                    Some(Err(e)) => return Err((format!("the status could not be read: {e}"), e)),
                    // A firm wait is not cut short by a cancel; should it end anyway, the stop is not confirmed.
                    None => {
                        let e = Error::UnexpectedReply { command: Command::Stop, detail: "no status came".into() };
                        return Err((e.to_string(), e));
                    }
                }
            } else {
                let read = read_item(ctx, ItemRead::actuators(DataIndex(0x0170), self.watch.clone())).await;
                match read.and_then(|d| statuses(&d)) {
                    Ok(s) => (s, None),
                    Err(e) => return Err((format!("the status could not be read: {e}"), e)),
                }
            };
            let now = ctx.now();
            let moving: Vec<Actuator> =
                self.watch.iter().copied().filter(|a| status[usize::from(a.number() - 1)].moving()).collect();
            if moving.is_empty() {
                return match at {
                    Some(p) => Ok((status, p)),
                    None => {
                        let read = read_item(ctx, ItemRead::actuators(DataIndex(0x0010), self.watch.clone())).await;
                        match read.and_then(|d| positions(&d)) {
                            Ok(p) => Ok((status, p)),
                            Err(e) => Err((format!("the positions could not be read: {e}"), e)),
                        }
                    }
                };
            }
            if now >= give_up {
                let e = Error::StillMoving(moving);
                return Err((e.to_string(), e));
            }
            if !by_snapshot {
                ctx.pause_until(give_up.min(now + poll_interval)).await;
            }
        }
    }
}

/// The error to report after `cause` ended an action and the stop that followed ended with `stopped`:
/// `cause` (a cancel with the position where its actuator came to rest) when the stop was confirmed,
/// [`Error::StopUnconfirmed`] otherwise.
pub(crate) fn after_stop(cause: Error, stopped: Result<[PositionCounts; 6], Unconfirmed>, stop: &Stop) -> Error {
    match stopped {
        Ok(p) => match cause {
            Error::Cancelled { actuator, .. } => {
                Error::Cancelled { actuator, position_counts: p[usize::from(actuator.number() - 1)] }
            }
            other => other,
        },
        Err((detail, _)) => stop.unconfirmed(cause, detail),
    }
}

/// A stop of the caller's ([`super::Op::Stop`]); with `after`, the stop that follows that failure.
pub(crate) async fn stop(
    ctx: &Ctx,
    function: MotionFunction,
    mode: StopMode,
    watch: Vec<Actuator>,
    after: Option<Box<Error>>,
) -> Result<Output, Error> {
    let stop = Stop::new(Function::Motion(function), mode, watch);
    let stopped = stop.run(ctx).await.rest;
    match after {
        Some(cause) => Err(after_stop(*cause, stopped.map(|(_, p)| p), &stop)),
        None => match stopped {
            Ok((_, p)) => Ok(Output::Rest(stop.watch.iter().map(|a| (*a, p[usize::from(a.number() - 1)])).collect())),
            Err((detail, e)) => Err(stop.unconfirmed(e, detail)),
        },
    }
}

/// A stop of several motion functions, confirmed by the status of every actuator ([`super::Op::StopMotions`]).
pub(crate) async fn stop_motions(ctx: &Ctx, functions: Vec<MotionFunction>, mode: StopMode) -> Result<Output, Error> {
    let stop = Stop::several(functions.iter().map(|f| Function::Motion(*f)).collect(), mode, Actuator::all().collect());
    let stopped = stop.run(ctx).await;
    match stopped.rest {
        Ok((status, positions)) => {
            let refused = stopped
                .refused
                .iter()
                .filter_map(|(f, reason)| match f {
                    Function::Motion(m) => Some(RefusedStop { function: *m, reason: reason.clone() }),
                    _ => None,
                })
                .collect();
            let at_rest = Actuator::all()
                .filter(|a| status[usize::from(a.number() - 1)].available())
                .map(|a| ActuatorRest { actuator: a, position_counts: positions[usize::from(a.number() - 1)] })
                .collect();
            Ok(Output::Stopped(StopReport { functions, mode, refused, at_rest }))
        }
        Err((detail, e)) => Err(stop.unconfirmed(e, detail)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_unconfirmed_after_one_that_was_already_is_said_once() {
        let f1 = Function::from_id(0).unwrap();
        let stop = Stop::new(f1, StopMode::Fast, Vec::new());
        let first = stop.unconfirmed(Error::SessionLost("gone".into()), "no reply to RS".into());
        let again = stop.unconfirmed(first, "no reply to RS either".into());
        assert!(matches!(&again, Error::StopUnconfirmed { cause, .. } if matches!(**cause, Error::SessionLost(_))));
        assert_eq!(again.to_string().matches("its watchdog").count(), 1, "{again}");
    }
}
