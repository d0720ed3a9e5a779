//! Runs each [`Op`] on its state machine.

use crate::error::Error;
use crate::model::{AckKind, Address, Motion, Param, Position, Quantity, Ticks, Value};
use crate::session::ctx::Ctx;
use crate::session::{Op, Output};
use crate::wire::{Action, Request};

/// Runs `op` to its end.
pub(crate) async fn run(ctx: Ctx, op: Op) -> Result<Output, Error> {
    Ok(match op {
        Op::Request(a, r) => Output::Reply(ctx.raw_request(a.get(), r).await?),
        Op::RequestMany(rs) => {
            let rs: Vec<(u8, Request)> = rs.into_iter().map(|(a, r)| (a.get(), r)).collect();
            let replies = ctx.request_many(&rs).await;
            if ctx.cancelled() {
                for (a, r) in rs.iter().filter(|(_, r)| r.starts_motion()) {
                    let stop = ctx.stop_motion(*a).await;
                    tracing::warn!("module {a}: {r} cancelled: {stop}");
                }
            }
            Output::Replies(replies)
        }
        Op::ReadMany(addresses, p) => Output::Values(ctx.read_many(&numbers(&addresses), p).await),
        Op::Positions(addresses) => Output::Positions(ctx.positions(&numbers(&addresses)).await),
        Op::Broadcast(b) => {
            ctx.broadcast(b).await?;
            Output::Done
        }
        Op::Scan => Output::Scan(ctx.scan().await?),
        Op::ProbePosStateDio(a) => {
            ctx.probe_pos_state_dio(a.get()).await?;
            Output::Done
        }
        Op::Get(a, p) => Output::Value(ctx.get(a.get(), p).await?),
        Op::Set(a, p, v) => {
            ctx.set(a.get(), p, v).await?;
            Output::Done
        }
        Op::SetChecked(a, p, v) => Output::Readback(ctx.set_checked(a.get(), p, v).await?),
        Op::Position(a) => Output::Position(ctx.position(a.get()).await?),
        Op::PositionTicks(a) => Output::Ticks(Ticks(ctx.get_as(a.get(), Param::ActIPos, Value::as_i32).await?)),
        Op::State(a) => Output::State(ctx.state(a.get()).await?),
        Op::PositionStateDio(a) => {
            let kind = ctx.known_kind(a.get());
            let (pos, state, dio) = ctx
                .get_as(a.get(), Param::ActFPosStateDio, |v| match *v {
                    Value::PosStateDio { pos, state, dio } => Some((pos, state, dio)),
                    _ => None,
                })
                .await?;
            Output::PositionStateDio(Position::native(pos).resolved(kind), state, dio)
        }
        Op::Look(a) => {
            let a = a.get();
            ctx.probe_pos_state_dio(a).await?;
            let kind = ctx.known_kind(a);
            if ctx.lacks_pos_state_dio(a) {
                let state = ctx.state(a).await?;
                let pos = ctx.get_f32(a, Param::ActPos).await?;
                Output::Look(Position::native(pos).resolved(kind), state.short_state(), Some(state))
            } else {
                let (pos, short) = ctx
                    .get_as(a, Param::ActFPosStateDio, |v| match *v {
                        Value::PosStateDio { pos, state, .. } => Some((pos, state)),
                        _ => None,
                    })
                    .await?;
                Output::Look(Position::native(pos).resolved(kind), short, None)
            }
        }
        Op::ConfigWord(a) => Output::ConfigWord(ctx.config_word(a.get()).await?),
        Op::Kind(a) => Output::Kind(ctx.kind(a.get()).await?),
        Op::Info(a) => Output::Info(ctx.info(a.get()).await?),
        Op::Action(a, action) => {
            if action == Action::Reset {
                ctx.refuse_reset_while_served(a.get())?;
            }
            ctx.raw_request(a.get(), Request::Action(action)).await?;
            Output::Done
        }
        Op::Halt(a) => {
            ctx.halt(a.get()).await?;
            Output::Done
        }
        Op::HaltConfirmed(a) => Output::Halted(ctx.halt_confirmed(a.get()).await?),
        Op::Motion(a, m, ack) => Output::ExtAck(ctx.motion(a.get(), m, ack).await?),
        Op::IStep(a, pos, time) => {
            ctx.raw_request(a.get(), Request::IStep { pos, time }).await?;
            Output::Done
        }
        Op::MoveRamp { address, pos, vel, acc } => {
            let a = address.get();
            let motion = Request::motion(Motion::FRamp { pos }, AckKind::Simple)?;
            let vel_req = vel.map(|v| Request::set(Param::TargetVel, Value::F32(v.value()))).transpose()?;
            let acc_req = acc.map(|x| Request::set(Param::TargetAcc, Value::F32(x.value()))).transpose()?;
            let mut units = vec![("the target position", Quantity::Position(pos))];
            units.extend(vel.map(|v| ("the velocity", Quantity::Velocity(v))));
            units.extend(acc.map(|x| ("the acceleration", Quantity::Acceleration(x))));
            ctx.check_units(a, &units).await?;
            for r in [vel_req, acc_req].into_iter().flatten() {
                ctx.request(a, r).await?;
            }
            ctx.raw_request(a, motion).await?;
            Output::Done
        }
        Op::Wait(a, until, timeout) => Output::State(ctx.wait(a.get(), until, timeout).await?),
        Op::HomeAndWait(a, timeout) => Output::Homed(ctx.home_and_wait(a.get(), timeout).await?),
        Op::MoveTo(a, spec) => Output::Moved(ctx.move_to(a.get(), &spec).await?),
        Op::HomeGuarded(a, timeout, guard) => {
            // What the guard could not do (no watchdog) is said in the report, as a move's is.
            let (mut report, notes) = ctx.guarded(a.get(), guard, ctx.home_and_wait(a.get(), timeout)).await?;
            report.verified &= notes.is_empty();
            report.not_verifiable.extend(notes);
            Output::Homed(report)
        }
        Op::MoveGuarded(a, spec, guard) => {
            // A move the module would refuse (a target beyond MaxPos) is refused as such, before the guard
            // arms anything.
            let kind = ctx.check_move(a.get(), &spec).await?;
            let (mut report, notes) = ctx.guarded(a.get(), guard, ctx.move_checked(a.get(), &spec, kind)).await?;
            report.verified &= notes.is_empty();
            report.not_verifiable.extend(notes);
            Output::Moved(report)
        }
        Op::RunMotion(a, spec, guard) => {
            let a = a.get();
            // A motion the module would limit (a velocity beyond MaxVel) is refused as such, before the guard
            // arms anything.
            let fit = ctx.check_motion(a, &spec).await?;
            let report = match guard {
                None => ctx.run_motion_checked(a, &spec, fit).await?,
                Some(guard) => {
                    let (mut report, notes) = ctx.guarded(a, guard, ctx.run_motion_checked(a, &spec, fit)).await?;
                    report.verified &= notes.is_empty();
                    report.not_verifiable.extend(notes);
                    report
                }
            };
            Output::MotionRun(report)
        }
        Op::Setpoint(a, motion, ack, guard) => Output::Setpoint(ctx.setpoint(a.get(), motion, ack, guard).await?),
        Op::StopMotion(a) => Output::Stop(ctx.stop_motion(a.get()).await),
        Op::HaltStarted => {
            ctx.halt_started().await?;
            Output::Done
        }
        Op::EnableWatchdog(addresses) => {
            ctx.enable_watchdog_held(&numbers(&addresses)).await?;
            Output::Done
        }
        Op::DisableWatchdog => {
            ctx.disable_watchdog().await?;
            Output::Done
        }
        Op::ResetAndReleaseWatchdog(a) => Output::Released(ctx.reset_and_release_watchdog(a.get()).await?),
    })
}

/// The numbers of `addresses`, as the session's steps take them.
fn numbers(addresses: &[Address]) -> Vec<u8> {
    addresses.iter().map(|a| a.get()).collect()
}
