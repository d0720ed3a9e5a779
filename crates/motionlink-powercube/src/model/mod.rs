//! The device's vocabulary as types: the parameter table, the motion modes, the state and configuration
//! flags, and commands, acknowledges and broadcasts with their payloads. Each table is written once
//! ([`Param`], [`MotionId`] and every flag set come from one `macro_rules!` table each).

/// How long a module waits for a watchdog refresh before it halts (chapter 13 of the manual).
pub const WATCHDOG_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(50);

mod flags;
mod message;
mod motion;
mod params;
mod units;

pub use flags::{
    ConfigFlag, ConfigWord, CubeState, Dio, DioFlag, DioWord, DioWordFlag, FlagClass, ProfibusFlag, ProfibusState,
    SetupFlag, SetupWord, ShortFlag, ShortState, StateFlag,
};
pub use message::{AckPosition, Action, Broadcast, BroadcastForm, CanBaud, ExtAck, ModelError, Reply, Request};
pub use motion::{AckKind, Motion, MotionId, MotionShape, Ramp};
pub use params::{Access, DataType, Param, ParamClass, Unit, UnknownParam, Value, ValueError};
pub use units::{
    Acceleration, Amperes, CubeVersion, CurrentDigits, Millis, ModuleKind, Position, Ticks, TicksPerSec, Velocity,
};
