//! The operations of a session, each an `async fn` over a [`Ctx`] that reads like the manual's routine: it
//! sends its requests, waits for the next poll of a motion or for a time on the session's clock, and goes
//! on with what came of it. The one executor of `motionlink-link` runs them; no thread, no I/O.

use std::time::Duration;

use super::ctx::Ctx;
use super::report::{MoveProgress, MoveReport, RunProgress, RunReport, SetReport, Snapshot, StopReport, SwitchReport};
use super::request::PreparedRequest;
use crate::config::StrokeLimits;
use crate::error::Error;
use crate::model::{
    Actuator, ActuatorStatus1, CyclicObject, DataIndex, ErrorCode, Function, MotionDirection, MotionFunction,
    PositionCounts, Speed, StopMode,
};
use crate::value::Value;
use crate::wire::{Command, Status};

pub(crate) mod basic;
mod motion;
mod object;
mod read;
mod remote;
mod run;
mod stop;
mod stream;
mod switch;
mod watch;

pub(crate) use read::{read_item, ItemRead};
pub(crate) use remote::{close, reconnect};
pub(crate) use switch::{switch_request, SwitchFindings};
pub use watch::WatchSpec;

/// An operation a caller starts: what the [`crate::Client`] methods run. See each method for what it does.
#[derive(Debug)]
pub enum Op {
    /// RO with the configured Safety_ID, then a first RC (the start of a session).
    Open,
    /// RO and RC after the unit ended remote mode, and RS for every function the session started: the
    /// caller's decision ([`crate::Client::reopen`]).
    Reopen,
    /// Opens the port again, then as [`Op::Reopen`] ([`crate::Client::reconnect`]).
    Reconnect,
    /// One request; its ACK's data. An RE that the caller gives up on before its reply is followed by RS.
    Request(PreparedRequest),
    /// RG of an entry, or of a group's grouping index; where the unit refuses grouping indices, of the
    /// group's entries one by one (the data is the same).
    Read(DataIndex),
    /// RT of `data` to `index`, then (if `verify`) RG of it: a value that reads back different is
    /// [`Error::ReadBack`]; a unit that refuses to read remote data back gets a [`SetReport`] that says so.
    Set {
        /// The data index.
        index: DataIndex,
        /// The bytes to write.
        data: Vec<u8>,
        /// Read the index back.
        verify: bool,
    },
    /// Actuator `0`'s travel range for targets ([`crate::Client::stroke_limits`]).
    StrokeLimits(Actuator),
    /// A verified move of the actuators of one function ([`crate::Client::move_function`]).
    Move(MoveSpec),
    /// From now on the keepalive RC carries CyclicObj `slot` with these values ([`crate::Client::use_cyclic`]).
    UseCyclic {
        /// CyclicObj 1..5.
        slot: u8,
        /// One value per entry the object writes.
        write: Vec<Value>,
    },
    /// One RC with CyclicObj `slot` ([`crate::Client::exchange_cyclic`]).
    ExchangeCyclic {
        /// CyclicObj 1..5.
        slot: u8,
        /// One value per entry the object writes.
        write: Vec<Value>,
    },
    /// Checks and prepares streamed setpoints ([`crate::Client::stream`]).
    StreamOpen {
        /// The function.
        function: MotionFunction,
        /// The actuators it drives.
        actuators: Vec<Actuator>,
        /// The speed.
        speed: Speed,
    },
    /// Writes new remote positions (not read back) and starts the function towards them.
    StreamTargets {
        /// The function.
        function: MotionFunction,
        /// Each actuator's new target.
        targets: Vec<(Actuator, PositionCounts)>,
    },
    /// RS of a function, then the status of `watch` until none moves ([`crate::SetpointStream::stop`]); with
    /// `after`, the stop that follows that failure (fast; the error to report comes back).
    Stop {
        /// The function.
        function: MotionFunction,
        /// How.
        mode: StopMode,
        /// The actuators to watch come to rest.
        watch: Vec<Actuator>,
        /// What went wrong, if the stop follows a failure.
        after: Option<Box<Error>>,
    },
    /// Switches a switching function on (RE) or off (RS), then reads the status entry that shows it and checks
    /// that it shows the state asked for ([`crate::Client::switch`]).
    Switch {
        /// The function (F11..F22).
        function: Function,
        /// On (RE) or off (RS).
        on: bool,
    },
    /// Runs a function until it ends, a time limit, or a cancel, then stops it ([`crate::Client::run`]).
    Run(RunSpec),
    /// RS of each of these motion functions (a refused one is noted, the others are stopped all the same),
    /// then the status of every actuator until none moves, then where they are ([`Output::Stopped`];
    /// [`crate::Client::stop_functions`]).
    StopMotions {
        /// The functions, stopped in this order.
        functions: Vec<MotionFunction>,
        /// How.
        mode: StopMode,
    },
    /// Samples the state every interval, through the keepalive RC where the unit takes the session's cyclic
    /// object ([`crate::Client::watch`]); a cancel ends it.
    Watch(WatchSpec),
}

/// Which actuators a move drives to which target.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MoveTargets {
    /// Exactly these (the function map knows the function, or the caller named them).
    Given(Vec<(Actuator, PositionCounts)>),
    /// The function's drives are not known: every connected actuator gets this target, and the ones that
    /// moved are reported.
    EveryConnected(PositionCounts),
}

/// A verified move.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MoveSpec {
    /// The function that drives the move.
    pub function: MotionFunction,
    /// The actuator the move is about (reported first, checked first).
    pub primary: Actuator,
    /// Where each actuator goes.
    pub targets: MoveTargets,
    /// How fast.
    pub speed: Speed,
}

/// What a run starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunAction {
    /// RE of a motion function in a direction; the run ends when the unit reports that nothing moves any more
    /// (or at the time limit).
    Motion(MotionFunction, MotionDirection),
    /// RE of a switching function (buzzer, outputs, LEDs, emergency stop); RS ends it.
    Switch(Function),
}

/// A function's run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunSpec {
    /// What to start.
    pub action: RunAction,
    /// Stop after this long (a switching function without a limit runs until cancelled).
    pub limit: Option<Duration>,
}

/// What an operation ends with.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Nothing to report.
    Done,
    /// The data of the reply, if it had any.
    Data(Option<Vec<u8>>),
    /// A stroke: limits and where they come from, or none.
    Stroke(Option<(StrokeLimits, &'static str)>),
    /// Each actuator's stroke, in the order given.
    Strokes(Vec<Option<(StrokeLimits, &'static str)>>),
    /// How a move ended.
    Move(MoveReport),
    /// The read data of an RC with a cyclic object, and the object.
    Cyclic {
        /// The object's definition, read from the unit.
        object: CyclicObject,
        /// Its read data.
        data: Vec<u8>,
    },
    /// Where each actuator came to rest.
    Rest(Vec<(Actuator, PositionCounts)>),
    /// How a run ended.
    Run(RunReport),
    /// How a stop of motion functions ended.
    Stopped(StopReport),
    /// How a write ended.
    Written(SetReport),
    /// How a switching function was switched.
    Switched(SwitchReport),
    /// How many samples a watch took, and the last.
    Watched {
        /// Samples taken.
        samples: u64,
        /// The last of them.
        last: Option<Snapshot>,
    },
}

/// What an operation reports on its way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// A move polled its actuators.
    Move(MoveProgress),
    /// A run looked at its actuators.
    Run(RunProgress),
    /// A watch took a sample.
    Watch(Snapshot),
}

/// Runs `op` to its end.
pub(crate) async fn run(ctx: Ctx, op: Op) -> Result<Output, Error> {
    match op {
        Op::Open => remote::open(&ctx).await,
        Op::Reopen => remote::reopen(&ctx, false).await,
        Op::Reconnect => remote::reopen(&ctx, true).await,
        Op::Request(r) => basic::single(&ctx, r).await,
        Op::Read(index) => read_item(&ctx, ItemRead::all(index)).await.map(|d| Output::Data(Some(d))),
        Op::Set { index, data, verify } => basic::set(&ctx, index, data, verify).await,
        Op::StrokeLimits(a) => basic::stroke_limits(&ctx, a).await,
        Op::Move(spec) => motion::move_function(&ctx, spec).await,
        Op::UseCyclic { slot, write } => basic::cyclic(&ctx, slot, write, true).await,
        Op::ExchangeCyclic { slot, write } => basic::cyclic(&ctx, slot, write, false).await,
        Op::StreamOpen { function, actuators, speed } => stream::open(&ctx, function, actuators, speed).await,
        Op::StreamTargets { function, targets } => stream::targets(&ctx, function, targets).await,
        Op::Stop { function, mode, watch, after } => stop::stop(&ctx, function, mode, watch, after).await,
        Op::Switch { function, on } => switch::switch(&ctx, function, on).await,
        Op::Run(spec) => run::run(&ctx, spec).await,
        Op::StopMotions { functions, mode } => stop::stop_motions(&ctx, functions, mode).await,
        Op::Watch(spec) => watch::watch(&ctx, spec).await,
    }
}

/// The six status-1 bytes of an RG of 0x0170.
pub(crate) fn statuses(data: &[u8]) -> Result<[ActuatorStatus1; 6], Error> {
    <[u8; 6]>::try_from(data).map(|raw| raw.map(ActuatorStatus1)).map_err(|_| Error::UnexpectedReply {
        command: crate::wire::Command::Get,
        detail: "status 1 is 6 x 1 byte".into(),
    })
}

/// The six positions of an RG of 0x0010.
pub(crate) fn positions(data: &[u8]) -> Result<[PositionCounts; 6], Error> {
    if data.len() != 24 {
        return Err(Error::UnexpectedReply {
            command: crate::wire::Command::Get,
            detail: "positions are 6 x 4 bytes".into(),
        });
    }
    Ok(std::array::from_fn(|i| {
        PositionCounts(i32::from_le_bytes([data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]]))
    }))
}

/// The six motor currents (0.1 A) of an RG of 0x00A0.
pub(crate) fn currents(data: &[u8]) -> Result<[u16; 6], Error> {
    if data.len() != 12 {
        return Err(Error::UnexpectedReply {
            command: crate::wire::Command::Get,
            detail: "currents are 6 x 2 bytes".into(),
        });
    }
    Ok(std::array::from_fn(|i| u16::from_le_bytes([data[2 * i], data[2 * i + 1]])))
}

/// An error code (4 bytes).
/// After an RE refused with PE ("command not possible with SCU mode/state"): reads the unit's last error and,
/// if one is set, says it (a warning): an error whose reaction is that motions are not performed keeps
/// every RE from being taken, and the refusal alone does not name it. Nothing is said of other errors.
pub(crate) async fn say_last_error_of_pe(ctx: &Ctx, e: &Error) {
    if !matches!(e, Error::Refused { command: Command::Execute, status: Status::PermissionError }) {
        return;
    }
    let read = ctx.firm().get(motion::poll::LAST_ERROR).await;
    if let Ok(code) = read.and_then(|r| r.data(Command::Get)).and_then(|d| error_code(&d)) {
        if code != ErrorCode::NONE {
            tracing::warn!(
                "the unit refused the RE with PE; its last error is {code} (the manual's reaction to some errors is \
                 that motions are not performed: `motionlink scu errors` lists the history)"
            );
        }
    }
}

pub(crate) fn error_code(data: &[u8]) -> Result<ErrorCode, Error> {
    <[u8; 4]>::try_from(data).map(|b| ErrorCode(u32::from_le_bytes(b))).map_err(|_| Error::UnexpectedReply {
        command: crate::wire::Command::Get,
        detail: "an error code is 4 bytes".into(),
    })
}
