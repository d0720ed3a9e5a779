//! One request of an operation, with what a PE answer leads to: see the crate documentation, "A session the
//! unit ended". A unit answers PE to RG, RT, RE and RS when it is not in remote mode; the session then sends
//! an RC (with Safety_ID 1 and 2 the unit's next RC re-arms its watchdog) and tries once more. Still PE: the
//! unit ended remote mode, and the session says so ([`Error::RemoteEnded`]) without sending RO. Accepted
//! after the RC: the watchdog had lapsed; the functions the session had started (which the unit stopped) get
//! their RS, and the caller learns once that its motion was stopped.

use super::request::{OwnedReply, PreparedRequest, Req};
use super::Core;
use crate::error::Error;
use crate::model::{Actuator, Function, StopMode};
use crate::wire::{Command, Status};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Main,
    /// The request was answered PE: an RC.
    PeRc,
    /// The RC was accepted: the request again, or a read that only remote mode allows.
    PeProbe,
    /// The probe was answered: the RE or RC itself again.
    PeRetry,
    /// The watchdog had lapsed: RS for what the session had started.
    LapseStops,
    /// An RE that went out again after a lost answer was refused with PE even after the RC: the unit took
    /// an earlier sending and refuses a second RE of a running function (see [`PeGuarded::next`]). The soft
    /// RS the manual asks for after every RE.
    ReStop,
    /// The RS was acknowledged: the RE once more.
    ReAgain,
}

/// A request of an operation and its follow-ups.
#[derive(Debug)]
pub(crate) struct PeGuarded {
    req: Req,
    phase: Phase,
    stops: Vec<u8>,
    abandoned: bool,
    /// The request went out again after a sending that got no clean answer.
    resent: bool,
    /// Its operation was cancelled: nothing is started again.
    cancelled: bool,
    /// The unit's PE to an RE that went out again, reported if the RS and RE after it do not go through.
    refusal: Option<OwnedReply>,
}

/// What follows an exchange of a transaction.
pub(crate) enum PeStep {
    /// This request goes out next, at once.
    Again(PreparedRequest),
    /// The transaction's outcome.
    Finished(Result<OwnedReply, Error>),
}

impl PeGuarded {
    pub fn new(req: Req) -> PeGuarded {
        PeGuarded {
            req,
            phase: Phase::Main,
            stops: Vec::new(),
            abandoned: false,
            resent: false,
            cancelled: false,
            refusal: None,
        }
    }

    /// The operation was cancelled: a refused RE is not followed by RS and RE.
    pub fn cancelled(&mut self) {
        self.cancelled = true;
    }

    /// The motion function this request starts (an RE of a motion function).
    fn starts_motion(&self) -> Option<u8> {
        self.req.request.starts.filter(|&id| matches!(Function::from_id(id), Some(Function::Motion(_))))
    }

    /// The port is gone: the transaction ends with the error that comes.
    pub fn abandon(mut self) -> PeGuarded {
        self.abandoned = true;
        self
    }

    fn command(&self) -> Command {
        self.req.request.command
    }

    /// The exchange of the present phase ended with `result` (`resent`: its request went out again after a
    /// sending that got no clean answer).
    ///
    /// An RE of a motion function that went out again after a lost answer and is refused with PE, even
    /// after the RC and once more, may be refused because the unit took an earlier sending: a unit may refuse
    /// a second RE of a function it runs until the RS the manual asks for after every RE (the
    /// `re-needs-rs` variant). The soft RS goes out (the motion ramps down, or goes on at once to the same
    /// target), then the RE again (to remote positions: absolute; in a direction: the same motion), unless the
    /// operation was cancelled; a unit that takes it is known to need the RS before every new RE.
    pub fn next(&mut self, core: &mut Core, result: Result<OwnedReply, Error>, resent: bool) -> PeStep {
        if self.abandoned {
            return PeStep::Finished(result);
        }
        let command = self.command();
        if self.phase == Phase::Main {
            self.resent = resent;
        }
        match self.phase {
            Phase::Main => match result {
                Ok(reply)
                    if reply.status == Status::PermissionError
                        && self.req.checked
                        && !matches!(command, Command::Open | Command::Abort) =>
                {
                    // An RC is accepted in every state of remote mode (and re-arms the watchdog with Safety_ID 1
                    // and 2); a unit that refuses it has left remote mode altogether.
                    self.phase = Phase::PeRc;
                    PeStep::Again(PreparedRequest::keepalive())
                }
                other => self.finish(core, other),
            },
            Phase::PeRc => match result {
                Ok(rc) if rc.status == Status::PermissionError => {
                    let e = core.ended(format!(
                        "the unit has left remote mode: it refused {command} and even RC with PE (its communication \
                         watchdog lapsed, which ends remote mode with Safety_ID 1 or 2; or it was reset, or another \
                         host sent RA); the session does not open remote mode again by itself"
                    ));
                    PeStep::Finished(Err(e))
                }
                Ok(_) => {
                    self.phase = Phase::PeProbe;
                    let probe = match command {
                        Command::Get | Command::Transfer | Command::Stop => self.req.request.clone(),
                        _ => PreparedRequest::get(
                            Actuator::new(1).map_or(crate::model::DataIndex(0x0171), |a| a.status1_index()),
                        ),
                    };
                    PeStep::Again(probe)
                }
                Err(e) => PeStep::Finished(Err(e)),
            },
            Phase::PeProbe => match result {
                Ok(again) if again.status == Status::PermissionError => {
                    let e = core.ended(format!(
                        "the unit ended remote mode: it takes RC but refuses {command} with PE, as after a \
                         communication time-out with Safety_ID 0 (the unit then stops every motion and accepts \
                         remote motion only after a new RO); the session does not open remote mode again by itself"
                    ));
                    PeStep::Finished(Err(e))
                }
                Ok(again) => match command {
                    // The unit answers again after the RC: its watchdog had expired (Safety_ID 1 or 2) and the
                    // RC re-armed it; or, for an RE, remote mode is fine and the unit refuses that function for
                    // its own reasons.
                    Command::Execute | Command::Cyclic => {
                        self.phase = Phase::PeRetry;
                        PeStep::Again(self.req.request.clone())
                    }
                    _ => self.lapse(core, again),
                },
                Err(e) => PeStep::Finished(Err(e)),
            },
            Phase::PeRetry => match result {
                Ok(r) if command == Command::Execute && r.status == Status::PermissionError => {
                    match self.starts_motion() {
                        Some(f) if self.resent && !self.cancelled => {
                            tracing::warn!(
                                "the unit refused an RE that went out again after a lost answer (PE): it may have \
                                 taken the first and refuse a second RE of a running function; sending the soft RS \
                                 the manual asks for after every RE, then the RE again"
                            );
                            self.refusal = Some(r);
                            self.phase = Phase::ReStop;
                            PeStep::Again(PreparedRequest::stop(f, StopMode::Soft))
                        }
                        _ => self.finish(core, Ok(r)),
                    }
                }
                Ok(r) => self.lapse(core, r),
                Err(e) => PeStep::Finished(Err(e)),
            },
            Phase::ReStop => match result {
                Ok(r) if r.status == Status::Ack && !self.cancelled => {
                    self.phase = Phase::ReAgain;
                    PeStep::Again(self.req.request.clone())
                }
                // The RS did not go through (or the operation was cancelled): the refusal stands, and the
                // operation stops the function as after any refused RE.
                _ => {
                    let refusal = self.refusal.take().expect("kept for the RS");
                    self.finish(core, Ok(refusal))
                }
            },
            Phase::ReAgain => {
                if matches!(&result, Ok(r) if r.status == Status::Ack) {
                    core.re_needs_rs = true;
                }
                self.finish(core, result)
            }
            Phase::LapseStops => {
                let f = self.stops.remove(0);
                match result {
                    Ok(r) if r.status == Status::Ack => {
                        core.started.remove(&f);
                    }
                    Ok(r) => tracing::info!("RS of function id {f} after the watchdog lapse: {}", r.status),
                    Err(e) => tracing::info!("RS of function id {f} after the watchdog lapse: {e}"),
                }
                match self.stops.first() {
                    Some(&next) => PeStep::Again(PreparedRequest::stop(next, StopMode::Fast)),
                    None => PeStep::Finished(Err(Error::RemoteEnded(format!(
                        "the unit's communication watchdog had expired (it refused {command} with PE until an RC \
                         re-armed it, as with Safety_ID {}): it stopped {}, including what this session had \
                         started",
                        core.config.safety_id.code(),
                        core.lapse_stops()
                    )))),
                }
            }
        }
    }

    /// The watchdog had lapsed and an RC re-armed it.
    fn lapse(&mut self, core: &mut Core, reply: OwnedReply) -> PeStep {
        core.stats.watchdog_lapses += 1;
        let starts = self.req.request.starts;
        self.stops = core.started.iter().copied().filter(|f| Some(*f) != starts).collect();
        match self.stops.first() {
            Some(&f) => {
                // The unit stopped them; each still gets the RS the manual asks for after every RE.
                self.phase = Phase::LapseStops;
                PeStep::Again(PreparedRequest::stop(f, StopMode::Fast))
            }
            None => {
                tracing::info!("the unit's watchdog had expired while the session was idle; an RC re-armed it");
                self.finish(core, Ok(reply))
            }
        }
    }

    fn finish(&mut self, core: &mut Core, result: Result<OwnedReply, Error>) -> PeStep {
        if let Ok(reply) = &result {
            if reply.status == Status::Ack {
                if let Some(f) = self.req.request.stops {
                    core.started.remove(&f);
                }
            }
            core.stats.transactions += 1;
        }
        PeStep::Finished(result)
    }
}
