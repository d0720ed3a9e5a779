//! The typed calls both clients make: an [`Op`] and how to take the typed result out of the session's
//! [`Output`]. Written once, so that [`Client`](super::Client) and the async client offer the same
//! operations with the same results.

use std::time::Duration;

use crate::error::Error;
use crate::model::{
    Acceleration, AckKind, Address, ConfigWord, CubeState, Dio, Millis, ModuleKind, Motion, Param, Position,
    ShortState, Ticks, Value, Velocity,
};
use crate::session::{
    Guard, HaltReport, HomeReport, ModuleInfo, MotionReport, MotionSpec, MoveReport, MoveSpec, Op, Output, Readback,
    ScanEntry, SetpointReport, Until,
};
use crate::wire::{Action, ExtAck, Reply, Request};

/// An operation and the typed result it ends with.
pub(crate) struct Call<T> {
    pub op: Op,
    pub take: fn(Output) -> Result<T, Output>,
}

impl<T> Call<T> {
    /// The typed result of `output` (an output of another kind never comes from the session; should it,
    /// it is an error naming it rather than a panic).
    pub fn result(&self, output: Result<Output, Error>) -> Result<T, Error> {
        (self.take)(output?).map_err(|other| Error::NotSupported(format!("the session answered {other:?}")))
    }
}

macro_rules! call {
    ($op:expr, $pat:pat => $value:expr) => {
        Call {
            op: $op,
            take: |o| match o {
                $pat => Ok($value),
                other => Err(other),
            },
        }
    };
}

pub(crate) fn done(op: Op) -> Call<()> {
    call!(op, Output::Done => ())
}

pub(crate) fn request(a: Address, r: Request) -> Call<Reply> {
    call!(Op::Request(a, r), Output::Reply(r) => r)
}

pub(crate) fn request_many(rs: Vec<(Address, Request)>) -> Call<Vec<Result<Reply, Error>>> {
    call!(Op::RequestMany(rs), Output::Replies(r) => r)
}

pub(crate) fn read_many(addresses: Vec<Address>, p: Param) -> Call<Vec<Result<Value, Error>>> {
    call!(Op::ReadMany(addresses, p), Output::Values(v) => v)
}

pub(crate) fn positions(addresses: Vec<Address>) -> Call<Vec<Result<Position, Error>>> {
    call!(Op::Positions(addresses), Output::Positions(v) => v)
}

pub(crate) fn scan() -> Call<Vec<ScanEntry>> {
    call!(Op::Scan, Output::Scan(v) => v)
}

pub(crate) fn get(a: Address, p: Param) -> Call<Value> {
    call!(Op::Get(a, p), Output::Value(v) => v)
}

pub(crate) fn set_checked(a: Address, p: Param, v: Value) -> Call<Readback> {
    call!(Op::SetChecked(a, p, v), Output::Readback(r) => r)
}

pub(crate) fn position(a: Address) -> Call<Position> {
    call!(Op::Position(a), Output::Position(p) => p)
}

pub(crate) fn position_ticks(a: Address) -> Call<Ticks> {
    call!(Op::PositionTicks(a), Output::Ticks(t) => t)
}

pub(crate) fn state(a: Address) -> Call<CubeState> {
    call!(Op::State(a), Output::State(s) => s)
}

pub(crate) fn position_state_dio(a: Address) -> Call<(Position, ShortState, Dio)> {
    call!(Op::PositionStateDio(a), Output::PositionStateDio(p, s, d) => (p, s, d))
}

pub(crate) fn look(a: Address) -> Call<(Position, ShortState, Option<CubeState>)> {
    call!(Op::Look(a), Output::Look(p, s, w) => (p, s, w))
}

pub(crate) fn config_word(a: Address) -> Call<ConfigWord> {
    call!(Op::ConfigWord(a), Output::ConfigWord(w) => w)
}

pub(crate) fn kind(a: Address) -> Call<ModuleKind> {
    call!(Op::Kind(a), Output::Kind(k) => k)
}

pub(crate) fn info(a: Address) -> Call<ModuleInfo> {
    call!(Op::Info(a), Output::Info(i) => i)
}

pub(crate) fn action(a: Address, action: Action) -> Call<()> {
    done(Op::Action(a, action))
}

pub(crate) fn motion(a: Address, m: Motion, ack: AckKind) -> Call<Option<ExtAck>> {
    call!(Op::Motion(a, m, ack), Output::ExtAck(e) => e)
}

pub(crate) fn istep(a: Address, pos: Ticks, time: Millis) -> Call<()> {
    done(Op::IStep(a, pos, time))
}

pub(crate) fn move_ramp(a: Address, pos: Position, vel: Option<Velocity>, acc: Option<Acceleration>) -> Call<()> {
    done(Op::MoveRamp { address: a, pos, vel, acc })
}

pub(crate) fn wait(a: Address, until: Until, timeout: Duration) -> Call<CubeState> {
    call!(Op::Wait(a, until, timeout), Output::State(s) => s)
}

pub(crate) fn home_and_wait(a: Address, timeout: Duration, guard: Option<Guard>) -> Call<HomeReport> {
    let op = match guard {
        Some(g) => Op::HomeGuarded(a, timeout, g),
        None => Op::HomeAndWait(a, timeout),
    };
    call!(op, Output::Homed(r) => r)
}

pub(crate) fn move_to(a: Address, spec: MoveSpec, guard: Option<Guard>) -> Call<MoveReport> {
    let op = match guard {
        Some(g) => Op::MoveGuarded(a, spec, g),
        None => Op::MoveTo(a, spec),
    };
    call!(op, Output::Moved(r) => r)
}

pub(crate) fn run_motion(a: Address, spec: MotionSpec, guard: Option<Guard>) -> Call<MotionReport> {
    call!(Op::RunMotion(a, spec, guard), Output::MotionRun(r) => r)
}

pub(crate) fn setpoint(a: Address, m: Motion, ack: AckKind, guard: Guard) -> Call<SetpointReport> {
    call!(Op::Setpoint(a, m, ack, guard), Output::Setpoint(r) => r)
}

pub(crate) fn halt_confirmed(a: Address) -> Call<HaltReport> {
    call!(Op::HaltConfirmed(a), Output::Halted(r) => r)
}

pub(crate) fn stop_motion(a: Address) -> Call<crate::error::StopOutcome> {
    call!(Op::StopMotion(a), Output::Stop(s) => s)
}

pub(crate) fn reset_and_release_watchdog(a: Address) -> Call<bool> {
    call!(Op::ResetAndReleaseWatchdog(a), Output::Released(b) => b)
}
