//! Remote mode: opening it (RO, RC), opening it again (after the unit ended it, or on a new port), and the
//! end of the session (RS for every function started, then RA).

use motionlink_link::Timestamp;

use super::{Cx, Next, Operation, Output, Resume};
use crate::error::Error;
use crate::model::StopMode;
use crate::session::request::{PreparedRequest, Req};
use crate::session::State;
use crate::wire::{Command, Request, Status};

/// RO with the configured Safety_ID, then RC. Returns the time the RC went out (the unit's watchdog runs
/// from when it received it).
struct Opening {
    rc_sent: Option<Timestamp>,
}

impl Opening {
    fn new() -> Self {
        Opening { rc_sent: None }
    }

    fn start(&mut self, cx: &Cx<'_>) -> Next {
        self.rc_sent = None;
        let ro = Request::Open { safety_id: cx.config().safety_id.code() };
        match PreparedRequest::new(&ro) {
            Ok(r) => Next::Send(Req::internal(r)),
            Err(e) => Next::Done(Err(e)),
        }
    }

    /// The reply to RO or RC: the next request, or the outcome (the time of the RC).
    fn reply(
        &mut self,
        cx: &mut Cx<'_>,
        result: Result<crate::session::OwnedReply, Error>,
    ) -> Result<Option<Next>, Error> {
        match self.rc_sent {
            None => {
                cx.core.line.remote = false;
                result.and_then(|r| r.ack(Command::Open))?;
                cx.core.line.remote = true;
                self.rc_sent = Some(cx.now());
                Ok(Some(Next::Send(Req::internal(PreparedRequest::keepalive()))))
            }
            Some(_) => {
                result.and_then(|r| r.ack(Command::Cyclic))?;
                Ok(None)
            }
        }
    }
}

/// RS of every function still started, one after the other: each result, and the error of the first that
/// failed.
struct StopAll {
    left: Vec<u8>,
    first_error: Option<Error>,
    checked: bool,
}

impl StopAll {
    fn new(cx: &Cx<'_>, checked: bool) -> Self {
        StopAll { left: cx.core.started.iter().copied().collect(), first_error: None, checked }
    }

    fn next(&mut self) -> Option<Next> {
        let f = *self.left.first()?;
        let mut req = Req::internal(PreparedRequest::stop(f, StopMode::Fast));
        req.checked = self.checked;
        Some(Next::Send(req))
    }

    /// The reply to the RS under way; `Err` hands back a RemoteEnded that stops the sequence.
    fn reply(&mut self, result: Result<crate::session::OwnedReply, Error>) -> Result<(), Error> {
        let f = self.left.remove(0);
        match result.and_then(|r| r.ack(Command::Stop)) {
            Ok(_) => Ok(()),
            Err(e @ Error::RemoteEnded(_)) => Err(e),
            Err(e) => {
                tracing::info!("RS of function id {f} failed: {e}");
                self.first_error.get_or_insert(e);
                Ok(())
            }
        }
    }
}

/// The start of a session ([`super::Op::Open`]): RO and RC; if that fails after the unit answered RO, one
/// short try of RA.
pub(crate) struct Open {
    opening: Opening,
    failed: Option<Error>,
}

impl Open {
    pub fn new() -> Self {
        Open { opening: Opening::new(), failed: None }
    }
}

impl Operation for Open {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        match resume {
            Resume::Start => self.opening.start(cx),
            Resume::Reply(result) if self.failed.is_some() => {
                if let Err(e) = result {
                    tracing::debug!("RA after a failed start: {e}");
                }
                cx.core.line.remote = false;
                Next::Done(Err(self.failed.take().expect("checked")))
            }
            Resume::Reply(result) => match self.opening.reply(cx, result) {
                Ok(Some(next)) => next,
                Ok(None) => {
                    cx.core.opened(self.opening.rc_sent.unwrap_or(cx.now()));
                    Next::Done(Ok(Output::Done))
                }
                Err(e) if cx.core.line.remote && cx.core.link_up => {
                    // Nothing was started; a unit that answered RO gets its RA (one short try).
                    self.failed = Some(e);
                    cx.core.line.silent = true;
                    Next::Send(Req::internal(PreparedRequest::new(&Request::Abort).expect("RA encodes")))
                }
                Err(e) => Next::Done(Err(e)),
            },
            Resume::Wake | Resume::Snapshot(_) | Resume::Reopened(_) => {
                Next::Done(Err(Error::CancelledBeforeSending(Command::Open)))
            }
        }
    }

    fn interruptible(&self) -> bool {
        false
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ReopenPhase {
    Port,
    Remote,
    Stops,
}

/// Remote mode opened again ([`super::Op::Reopen`], [`super::Op::Reconnect`], an automatic reconnection):
/// (the port,) RO, RC, and RS for every function the session started.
pub(crate) struct Reopen {
    reconnect: bool,
    phase: ReopenPhase,
    opening: Opening,
    stops: Option<StopAll>,
}

impl Reopen {
    pub fn new(reconnect: bool) -> Self {
        Reopen { reconnect, phase: ReopenPhase::Port, opening: Opening::new(), stops: None }
    }

    fn failed(&self, cx: &mut Cx<'_>, e: Error) -> Next {
        if self.reconnect {
            // Without a port the session is lost (and the keepalive sleeps until the next attempt).
            cx.core.link_up = false;
            cx.core.line.remote = false;
            cx.core.state = State::Lost(format!("reconnect failed: {e}"));
        }
        Next::Done(Err(e))
    }

    fn next_stop(&mut self) -> Next {
        match self.stops.as_mut().and_then(StopAll::next) {
            Some(next) => next,
            None => Next::Done(match self.stops.take().and_then(|s| s.first_error) {
                Some(e) => Err(e),
                None => Ok(Output::Done),
            }),
        }
    }
}

impl Operation for Reopen {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        match (self.phase, resume) {
            (ReopenPhase::Port, Resume::Start) if self.reconnect => {
                // Close the old port first: a serial device can be opened only once.
                Next::Reopen
            }
            (ReopenPhase::Port, Resume::Start) => {
                if !cx.core.link_up {
                    return Next::Done(Err(Error::SessionLost("port not connected".into())));
                }
                tracing::info!("opening remote mode again (RO, RC)");
                cx.core.line.silent = false;
                self.phase = ReopenPhase::Remote;
                self.opening.start(cx)
            }
            (ReopenPhase::Port, Resume::Reopened(Ok(()))) => {
                self.phase = ReopenPhase::Remote;
                self.opening.start(cx)
            }
            (ReopenPhase::Port, Resume::Reopened(Err(e))) => self.failed(cx, e),
            (ReopenPhase::Remote, Resume::Reply(result)) => match self.opening.reply(cx, result) {
                Ok(Some(next)) => next,
                Ok(None) => {
                    if self.reconnect {
                        cx.core.stats.reconnects += 1;
                    } else {
                        cx.core.stats.reopens += 1;
                    }
                    cx.core.opened(self.opening.rc_sent.unwrap_or(cx.now()));
                    // Every RE needs its RS, even when the unit already stopped the drive (the watchdog did).
                    self.phase = ReopenPhase::Stops;
                    self.stops = Some(StopAll::new(cx, false));
                    self.next_stop()
                }
                Err(e) => self.failed(cx, e),
            },
            (ReopenPhase::Stops, Resume::Reply(result)) => {
                if let Some(stops) = self.stops.as_mut() {
                    if let Err(e) = stops.reply(result) {
                        stops.first_error.get_or_insert(e);
                    }
                }
                self.next_stop()
            }
            (_, other) => Next::Done(Err(Error::UnexpectedReply {
                command: Command::Open,
                detail: format!("{other:?} while opening remote mode again"),
            })),
        }
    }

    fn interruptible(&self) -> bool {
        false
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ClosePhase {
    Stops,
    Reopening,
    StopsAfterReopen,
    Abort,
}

/// The end of the session: RS for every started function (motions fast), then RA. Where the unit ended
/// remote mode and a function still needs the RS the manual asks for after every RE, remote mode is opened
/// only to send it, and left at once.
pub(crate) struct Close {
    phase: ClosePhase,
    stops: Option<StopAll>,
    opening: Opening,
    first_error: Option<Error>,
}

impl Close {
    pub fn new() -> Self {
        Close { phase: ClosePhase::Stops, stops: None, opening: Opening::new(), first_error: None }
    }

    fn after_stops(&mut self, cx: &mut Cx<'_>, ended: bool) -> Next {
        if let Some(e) = self.stops.take().and_then(|s| s.first_error) {
            self.first_error.get_or_insert(e);
        }
        if ended && !cx.core.started.is_empty() && self.phase == ClosePhase::Stops {
            tracing::info!("the unit ended remote mode; opening it to send the RS of what this session started");
            self.phase = ClosePhase::Reopening;
            cx.core.line.silent = false;
            return self.opening.start(cx);
        }
        self.phase = ClosePhase::Abort;
        Next::Send(Req::internal(PreparedRequest::new(&Request::Abort).expect("RA encodes")))
    }
}

impl Operation for Close {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        match (self.phase, resume) {
            (_, Resume::Start) => {
                if !cx.core.link_up {
                    return Next::Done(Err(Error::SessionLost(
                        "port not connected: the unit's watchdog stops the drives".into(),
                    )));
                }
                let ended = matches!(cx.core.state, State::Ended(_));
                if ended {
                    return self.after_stops(cx, true);
                }
                self.stops = Some(StopAll::new(cx, true));
                match self.stops.as_mut().and_then(StopAll::next) {
                    Some(next) => next,
                    None => self.after_stops(cx, false),
                }
            }
            (ClosePhase::Stops | ClosePhase::StopsAfterReopen, Resume::Reply(result)) => {
                let stops = self.stops.as_mut().expect("stopping");
                if stops.reply(result).is_err() {
                    return self.after_stops(cx, true);
                }
                match stops.next() {
                    Some(next) => next,
                    None => self.after_stops(cx, false),
                }
            }
            (ClosePhase::Reopening, Resume::Reply(result)) => match self.opening.reply(cx, result) {
                Ok(Some(next)) => next,
                Ok(None) => {
                    cx.core.stats.reopens += 1;
                    cx.core.opened(self.opening.rc_sent.unwrap_or(cx.now()));
                    self.phase = ClosePhase::StopsAfterReopen;
                    self.stops = Some(StopAll::new(cx, false));
                    match self.stops.as_mut().and_then(StopAll::next) {
                        Some(next) => next,
                        None => self.after_stops(cx, false),
                    }
                }
                Err(e) => {
                    self.first_error.get_or_insert(e);
                    self.phase = ClosePhase::Abort;
                    Next::Send(Req::internal(PreparedRequest::new(&Request::Abort).expect("RA encodes")))
                }
            },
            (ClosePhase::Abort, Resume::Reply(result)) => {
                match result {
                    Ok(r) if r.status == Status::Ack => {}
                    Ok(r) => {
                        self.first_error.get_or_insert(Error::Refused { command: Command::Abort, status: r.status });
                    }
                    Err(e) => {
                        self.first_error.get_or_insert(e);
                    }
                }
                cx.core.line.remote = false;
                Next::Done(match self.first_error.take() {
                    Some(e) => Err(e),
                    None => Ok(Output::Done),
                })
            }
            (_, other) => Next::Done(Err(Error::UnexpectedReply {
                command: Command::Abort,
                detail: format!("{other:?} while ending the session"),
            })),
        }
    }

    fn interruptible(&self) -> bool {
        false
    }
}
