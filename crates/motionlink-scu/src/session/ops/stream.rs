//! Streamed setpoints: checks and the speed before the first target, then each update's remote positions and
//! RE.

use super::basic::{check_against_map, stroke, write};
use super::stop::Stop;
use super::{positions, read_item, statuses, ItemRead, Output};
use crate::error::Error;
use crate::model::{
    Actuator, DataIndex, Function, MotionDirection, MotionFunction, PositionCounts, Speed, StopMode, UNUSED,
};
use crate::session::ctx::Ctx;
use crate::session::request::{PreparedRequest, Req};
use crate::value::Value;
use crate::wire::{Command, Request, Status};

/// The checks of a stream ([`super::Op::StreamOpen`]): the actuators (connected; exactly the ones the
/// function map says the function drives, if it knows it), their strokes, the connected actuators not named
/// held (if the map does not know the function), and the speed (read back). A cancel ends it before
/// anything more is asked.
pub(crate) async fn open(
    ctx: &Ctx,
    function: MotionFunction,
    actuators: Vec<Actuator>,
    speed: Speed,
) -> Result<Output, Error> {
    let config = ctx.core().config.clone();
    let raw = speed.for_motion(config.speed_mode).map_err(Error::InvalidArgument)?;
    if actuators.is_empty() {
        return Err(Error::invalid("a stream needs at least one actuator"));
    }
    check_against_map(&config, function, &actuators)?;
    let ctx = ctx.ending_on_cancel(Error::CancelledBeforeMotion(Command::Execute));
    // A function the map does not know may drive actuators the stream does not name: those are held.
    let map_unknown = config.function_map.drives(function).is_none();
    let read = if map_unknown {
        ItemRead::all(DataIndex(0x0170))
    } else {
        ItemRead::actuators(DataIndex(0x0170), actuators.clone())
    };
    let status = statuses(&read_item(&ctx, read).await?)?;
    let available = |a: &Actuator| status[usize::from(a.number() - 1)].available();
    if let Some(a) = actuators.iter().find(|a| !available(a)) {
        return Err(Error::NotConnected(*a));
    }
    let mut strokes = Vec::with_capacity(actuators.len());
    for &a in &actuators {
        // A stream checks each target against its stroke, so a stroke that cannot be known ends it.
        match stroke(&ctx, a).await? {
            Ok(s) => strokes.push(s),
            Err(why) => {
                return Err(Error::NotSupported(format!(
                    "a stream checks every target against its actuator's stroke, which is not known: {why}"
                )))
            }
        }
    }
    if map_unknown {
        let held: Vec<Actuator> = Actuator::all().filter(|a| available(a) && !actuators.contains(a)).collect();
        hold(&ctx, &held).await?;
    }
    write(&ctx, function.remote_speed_index(), &raw.to_le_bytes(), true).await?;
    Ok(Output::Strokes(strokes))
}

/// Writes the remote position of each of `held` with where it stands (read back): a function the map does
/// not know may drive them, and would otherwise take them to whatever their remote positions held.
async fn hold(ctx: &Ctx, held: &[Actuator]) -> Result<(), Error> {
    if held.is_empty() {
        return Ok(());
    }
    let at = positions(&read_item(ctx, ItemRead::actuators(DataIndex(0x0010), held.to_vec())).await?)?;
    for &a in held {
        let here = at[usize::from(a.number() - 1)];
        write(ctx, a.remote_position_index(), &Value::RemotePosition(here.get()).to_bytes(), true).await?;
    }
    Ok(())
}

/// One update of a stream ([`super::Op::StreamTargets`]): the remote positions (not read back: that would
/// halve the rate; the CRC of every telegram and the unit's ACK are the check), then RE with direction 9.
/// Cancelled before the RE, nothing more is sent; cancelled while the RE was under way, the function is
/// stopped and the stop confirmed.
pub(crate) async fn targets(
    ctx: &Ctx,
    function: MotionFunction,
    targets: Vec<(Actuator, PositionCounts)>,
) -> Result<Output, Error> {
    for &(a, t) in &targets {
        let data = Value::RemotePosition(t.get()).to_bytes();
        let rt = PreparedRequest::new(&Request::Transfer { index: a.remote_position_index().0, data: &data })?;
        match ctx.send(Req::op(rt)).await {
            Err(e @ Error::CancelledBeforeMotion(_)) => return Err(e),
            reply => {
                reply.and_then(|r| r.ack(Command::Transfer))?;
            }
        }
        if ctx.cancelled() {
            return Err(Error::CancelledBeforeMotion(Command::Execute));
        }
    }
    let re = PreparedRequest::new(&Request::Execute {
        function: function.id(),
        params: [MotionDirection::RemotePosition.code(), UNUSED],
    })?;
    // A unit found to refuse an RE of a running function gets the RS the manual asks for after every RE first.
    if ctx.core().re_needs_rs && ctx.core().started.contains(&function.id()) {
        rs_before_re(ctx, function).await?;
    }
    let mut result = match ctx.send(Req::op(re.clone())).await {
        Err(e @ Error::CancelledBeforeMotion(_)) => return Err(e),
        reply => reply.and_then(|r| r.ack(Command::Execute)),
    };
    // The stream relies on a new RE retargeting a running function (beyond the manual's words, which say each
    // RE must be stopped with RS). A PE to it after an earlier RE of the function may be the unit asking for
    // that RS: it is sent (soft: the motion goes on to the new target at once), the RE again (an RE to remote
    // positions is absolute: sending it again repeats nothing); if that goes through, so does every later
    // update of the session. A PE to that RE too has another cause (an error that keeps motions from being
    // performed, say): the refusal is the result, and nothing is claimed of the RS.
    if matches!(result, Err(Error::Refused { command: Command::Execute, status: Status::PermissionError }))
        && !ctx.core().re_needs_rs
        && ctx.core().started.contains(&function.id())
        && !ctx.cancelled()
    {
        rs_before_re(ctx, function).await?;
        result = ctx.send(Req::op(re)).await.and_then(|r| r.ack(Command::Execute));
        if result.is_ok() {
            tracing::warn!(
                "the unit refused an RE of {function} while it ran (PE) and took it after an RS: it needs the RS \
                 the manual asks for after every RE; each new setpoint of this session goes out as RS then RE \
                 (the manual's plain form)"
            );
            ctx.core().re_needs_rs = true;
        }
    }
    if let Err(e) = &result {
        super::say_last_error_of_pe(ctx, e).await;
    }
    if ctx.cancelled() {
        let watch = targets.iter().map(|(a, _)| *a).collect();
        let stop = Stop::new(Function::Motion(function), StopMode::Fast, watch);
        return match stop.run(ctx).await.rest {
            Ok(_) => Err(Error::FunctionCancelled { function_id: function.id(), stopped: true }),
            Err((detail, _)) => {
                Err(stop.unconfirmed(Error::FunctionCancelled { function_id: function.id(), stopped: false }, detail))
            }
        };
    }
    result.map(|_| Output::Done)
}

/// The soft RS of `function` before its next RE, on a unit that needs it ([`targets`]).
async fn rs_before_re(ctx: &Ctx, function: MotionFunction) -> Result<(), Error> {
    let rs = Req::op(PreparedRequest::stop(function.id(), StopMode::Soft));
    ctx.firm().send(rs).await.and_then(|r| r.ack(Command::Stop)).map(|_| ())
}
