//! The device's vocabulary as types: the parameter table, the motion modes, the state and configuration
//! flags, commands, acknowledges and broadcasts with their payloads, and the quantities with their units.
//! Each table is written once: [`Param`] and its rows in the shared [`Table`](motionlink_link::table::Table)
//! ([`PARAMS`]), [`MotionId`], and every flag word through the shared `flag_set!` macro.

/// How long a module waits for a watchdog refresh before it halts (chapter 13 of the manual).
pub const WATCHDOG_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(50);

mod broadcast;
mod flags;
mod motion;
mod params;
mod units;
mod value;

pub use broadcast::{Broadcast, BroadcastForm, CanBaud};
pub use flags::{
    ConfigFlag, ConfigWord, CubeState, Dio, DioFlag, DioWord, DioWordFlag, FlagClass, ProfibusFlag, ProfibusState,
    SetupFlag, SetupWord, ShortFlag, ShortState, StateFlag,
};
pub use motion::{AckKind, Motion, MotionId, MotionShape, Ramp};
pub use params::{Access, DataType, Param, ParamClass, ParamKind, Unit, UnknownParam, PARAMS, PARAM_ENTRIES};
pub use units::{
    Acceleration, Address, Amperes, AxisUnit, CubeVersion, CurrentDigits, InvalidAddress, Millis, ModuleKind,
    ParseAddressError, Position, Quantity, Ticks, TicksPerSec, Velocity,
};
pub use value::{Value, ValueError};
