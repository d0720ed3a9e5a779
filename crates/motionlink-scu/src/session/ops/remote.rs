//! Remote mode: opening it (RO, RC), opening it again (after the unit ended it, or on a new port), and the
//! end of the session (RS for every function started, then RA). None of it is cut short by a cancel.

use motionlink_link::Timestamp;

use super::stop::Stop;
use super::Output;
use crate::error::Error;
use crate::model::{Actuator, Function, StopMode};
use crate::session::ctx::Ctx;
use crate::session::request::{OwnedReply, PreparedRequest, Req};
use crate::session::State;
use crate::wire::{Command, Request, Status};

/// RO with the configured Safety_ID, then RC. Returns the time the RC went out (the unit's watchdog runs
/// from when it received it).
async fn opening(ctx: &Ctx) -> Result<Timestamp, Error> {
    let (rc_sent, reply) = opening_with(ctx, PreparedRequest::keepalive()).await?;
    reply?.ack(Command::Cyclic)?;
    Ok(rc_sent)
}

/// RO with the configured Safety_ID (its refusal or failure is the `Err`), then `rc` (an RC): the time it
/// went out and its reply, whatever the unit answered.
pub(super) async fn opening_with(
    ctx: &Ctx,
    rc: PreparedRequest,
) -> Result<(Timestamp, Result<OwnedReply, Error>), Error> {
    let safety_id = ctx.core().config.safety_id.code();
    let ro = PreparedRequest::new(&Request::Open { safety_id })?;
    let reply = ctx.send(Req::internal(ro)).await;
    ctx.core().line.remote = false;
    reply.and_then(|r| r.ack(Command::Open))?;
    ctx.core().line.remote = true;
    let rc_sent = ctx.now();
    Ok((rc_sent, ctx.send(Req::internal(rc)).await))
}

/// RA, as the session's own request.
fn abort() -> Req {
    Req::internal(PreparedRequest::new(&Request::Abort).expect("RA encodes"))
}

/// RS of every function still started, one after the other (`checked`: a PE is looked into). Each failure
/// is logged and the others are stopped all the same; the first error comes back. With `until_ended`, a unit
/// that turns out to have ended remote mode ends the sequence (true then).
async fn stop_all(ctx: &Ctx, checked: bool, until_ended: bool) -> (Option<Error>, bool) {
    let left: Vec<u8> = ctx.core().started.iter().copied().collect();
    let mut first_error = None;
    for f in left {
        let mut req = Req::internal(PreparedRequest::stop(f, StopMode::Fast));
        req.checked = checked;
        match ctx.send(req).await.and_then(|r| r.ack(Command::Stop)) {
            Ok(_) => {}
            Err(Error::RemoteEnded(_)) if until_ended => return (first_error, true),
            Err(e @ Error::RemoteEnded(_)) => {
                first_error.get_or_insert(e);
            }
            Err(e) => {
                tracing::info!("RS of function id {f} failed: {e}");
                first_error.get_or_insert(e);
            }
        }
    }
    (first_error, false)
}

/// The start of a session ([`super::Op::Open`]): RO and RC; if that fails after the unit answered RO, one
/// short try of RA.
pub(crate) async fn open(ctx: &Ctx) -> Result<Output, Error> {
    let ctx = ctx.firm();
    match opening(&ctx).await {
        Ok(rc_sent) => {
            ctx.core().opened(rc_sent);
            Ok(Output::Done)
        }
        Err(e) => {
            let answered_ro = {
                let mut core = ctx.core();
                let answered = core.line.remote && core.link_up;
                if answered {
                    core.line.silent = true;
                }
                answered
            };
            if answered_ro {
                // Nothing was started; a unit that answered RO gets its RA (one short try).
                if let Err(ra) = ctx.send(abort()).await {
                    tracing::debug!("RA after a failed start: {ra}");
                }
                ctx.core().line.remote = false;
            }
            Err(e)
        }
    }
}

/// The automatic reconnection of a lost session: [`reopen`] on a new port.
pub(crate) async fn reconnect(ctx: Ctx) -> Result<Output, Error> {
    reopen(&ctx, true).await
}

/// Remote mode opened again ([`super::Op::Reopen`], [`super::Op::Reconnect`], an automatic reconnection):
/// (the port,) RO, RC, and RS for every function the session started.
pub(crate) async fn reopen(ctx: &Ctx, reconnect: bool) -> Result<Output, Error> {
    let ctx = ctx.firm();
    let failed = |e: Error| {
        if reconnect {
            // Without a port the session is lost (and the keepalive sleeps until the next attempt).
            let mut core = ctx.core();
            core.link_up = false;
            core.line.remote = false;
            core.state = State::Lost(format!("reconnect failed: {e}"));
        }
        Err(e)
    };
    if reconnect {
        // Close the old port first: a serial device can be opened only once.
        if let Err(e) = ctx.reopen_port().await {
            return failed(e);
        }
    } else {
        let mut core = ctx.core();
        if !core.link_up {
            return Err(Error::SessionLost("port not connected".into()));
        }
        tracing::info!("opening remote mode again (RO, RC)");
        core.line.silent = false;
    }
    let rc_sent = match opening(&ctx).await {
        Ok(t) => t,
        Err(e) => return failed(e),
    };
    {
        let mut core = ctx.core();
        if reconnect {
            core.stats.reconnects += 1;
        } else {
            core.stats.reopens += 1;
        }
        core.opened(rc_sent);
    }
    // Every RE needs its RS, even when the unit already stopped the drive (the watchdog did).
    match stop_all(&ctx, false, false).await {
        (Some(e), _) => Err(e),
        (None, _) => Ok(Output::Done),
    }
}

/// The end of the session: RS for every started function (motions fast), then RA; where a stop was not
/// confirmed, RS again and the status of every actuator before RA, which is not sent while they are not
/// found at rest (the unit then stays in remote mode, where its watchdog stops them). Where the unit ended
/// remote mode and a function still needs the RS the manual asks for after every RE, remote mode is opened
/// only to send it, and left at once.
pub(crate) async fn close(ctx: &Ctx) -> Result<Output, Error> {
    let ctx = ctx.firm();
    let (link_up, mut ended) = {
        let core = ctx.core();
        (core.link_up, matches!(core.state, State::Ended(_)))
    };
    if !link_up {
        return Err(Error::SessionLost("port not connected: the unit's watchdog stops the drives".into()));
    }
    let mut first_error = None;
    // What this session started and has not seen stop: its RS below is acknowledged, and then confirmed like
    // any stop not yet confirmed (the status of every actuator until none moves) before RA: an acknowledged RS
    // does not say that the drives are at rest, and the manual does not say what RA does to a motion.
    let stopping: Vec<Function> = ctx.core().started.iter().filter_map(|f| Function::from_id(*f)).collect();
    if !ended {
        (first_error, ended) = stop_all(&ctx, true, true).await;
    }
    ctx.core().stop_unconfirmed(&stopping);
    let still_started = !ctx.core().started.is_empty();
    if ended && still_started {
        tracing::info!("the unit ended remote mode; opening it to send the RS of what this session started");
        ctx.core().line.silent = false;
        match opening(&ctx).await {
            Ok(rc_sent) => {
                {
                    let mut core = ctx.core();
                    core.stats.reopens += 1;
                    core.opened(rc_sent);
                }
                if let (Some(e), _) = stop_all(&ctx, false, true).await {
                    first_error.get_or_insert(e);
                }
            }
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    // A stop this session could not confirm: RS again, and the status of every actuator. Until they are
    // found at rest, remote mode is not left: in it the unit stops the motions by itself 500 ms after the last
    // RC (the manual says so of remote mode; of RA it says only that it sets normal mode).
    let unconfirmed = ctx.core().unconfirmed_stops.clone();
    if !unconfirmed.is_empty() && !ended {
        let stop = Stop::several(unconfirmed.clone(), StopMode::Fast, Actuator::all().collect());
        if let Err((_, e)) = stop.run(&ctx).await.rest {
            first_error = Some(Error::CloseUnconfirmed { functions: unconfirmed, cause: Box::new(e) });
        }
    }
    let at_rest = { ctx.core().unconfirmed_stops.is_empty() && ctx.core().started.is_empty() };
    if !at_rest && !ended {
        tracing::warn!(
            "RA is not sent: the stop of what this session started is not confirmed, so the unit stays in remote \
             mode, where it stops the motions by itself 500 ms after the last RC (this one's)"
        );
        ctx.core().line.remote = false;
        return Err(first_error.unwrap_or_else(|| Error::SessionLost("the stop is not confirmed".into())));
    }
    match ctx.send(abort()).await {
        Ok(r) if r.status == Status::Ack => {}
        Ok(r) => {
            first_error.get_or_insert(Error::Refused { command: Command::Abort, status: r.status });
        }
        Err(e) => {
            first_error.get_or_insert(e);
        }
    }
    ctx.core().line.remote = false;
    match first_error {
        Some(e) => Err(e),
        None => Ok(Output::Done),
    }
}
