//! The COMPAX vocabulary as types: commands, status values S1..S40, the status bit words S16 / S17, the
//! error history S18, parameters Pnnn, and error codes Exx.
//!
//! Each table is written once and everything else (the session, the emulator, the command line, the capture
//! decoder) reads it: status values and parameters are rows of the shared
//! [`Table`](motionlink_link::table::Table) ([`STATUS`], [`PARAMS`]), the bit words S16 / S17 are shared
//! [`flag_set!`](motionlink_link::flag_set) words ([`S16Bits`], [`S17Bits`]).
//!
//! - [`units`]: [`Position`] (the drive's position unit), [`SpeedPercent`], [`RampMs`], [`OutputState`].
//! - [`args`]: the rules of the arguments a front end takes ([`FromStr`](std::str::FromStr), [`WholeArg`]).
//! - [`status`]: [`StatusId`] and its table; [`value`]: [`StatusValue`] as read; [`bits`]: S16 / S17.
//! - [`param`]: [`ParamId`] and its table; [`error_code`]: [`ErrorCode`]; [`command`]: [`Command`].
//!
//! ```
//! use motionlink_compax::model::{Command, CommandStyle, Position};
//! let c = Command::PosA(Position::new(360.0).unwrap());
//! assert_eq!(c.to_ascii(CommandStyle::Long).unwrap().as_str(), "POSA 360");
//! assert_eq!(c.to_ascii(CommandStyle::Short).unwrap().as_str(), "PA 360");
//! assert_eq!(Command::parse(b"PR 200 OT O9=1").unwrap().to_ascii(CommandStyle::Long).unwrap().as_str(),
//!            "POSR 200 OUTPUT O9=1");
//! ```

pub mod args;
pub mod bits;
pub mod command;
pub mod error_code;
pub mod param;
pub mod status;
#[cfg(test)]
mod tests;
pub mod units;
pub mod value;

pub use args::{
    whole_number, BaudRate, OutputNumber, PollInterval, ReplyTimeout, TimeLimit, Tolerance, WatchInterval, WholeArg,
};
pub use bits::{bit_mask, BitPattern, S16Bits, S16Flag, S17Bits, S17Flag};
pub use command::{Command, CommandStyle, CommandText};
pub use error_code::ErrorCode;
pub(crate) use param::param_reply_decimals;
pub use param::{
    parse_param_reply, write_param_reply, ParamDetail, ParamId, ParamWrite, ValidFrom, BAUD_RATES, FIELDBUS_BAUD_RATES,
    FIELDBUS_MODES, PARAMS,
};
pub use status::{StatusDetail, StatusId, StatusKind, STATUS};
pub use units::{OutputState, Position, RampMs, SpeedPercent};
pub use value::{HistoryEntry, StatusValue};

use crate::wire::WireError;

/// A value or text the model cannot accept.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ModelError {
    /// A value outside its range.
    #[error("{what} {value} is out of range ({range})")]
    Range {
        /// What the value is.
        what: &'static str,
        /// The value as given.
        value: String,
        /// The allowed range.
        range: &'static str,
    },
    /// A number that is not finite (`inf`, `nan`, `1e400`) where a finite one is needed.
    #[error("{what} must be a finite number, not {text}")]
    NotFinite {
        /// What the value is.
        what: &'static str,
        /// The text.
        text: String,
    },
    /// Text that is not a command or a value of the expected form.
    #[error("cannot read {what} from {text:?}")]
    Syntax {
        /// What was expected.
        what: &'static str,
        /// The text.
        text: String,
    },
    /// A name that is in no table (and no number either); `hint` says what to give instead: the nearest
    /// names when it looks misspelt.
    #[error("{text:?} is not {what}: {hint}")]
    UnknownName {
        /// What was expected ("a parameter").
        what: &'static str,
        /// The text.
        text: String,
        /// The nearest names ("did you mean device_address?"), or the forms that are taken.
        hint: String,
    },
    /// A value the command's decimal text would carry as another number: it has more decimals that matter
    /// than a command carries ([`MAX_DECIMALS`](crate::wire::number::MAX_DECIMALS)).
    #[error("{what} {value} has more decimals than a command carries (6): it would be sent as {sent}")]
    Precision {
        /// What the value is.
        what: &'static str,
        /// The value as given.
        value: String,
        /// What the command would carry instead.
        sent: String,
    },
    /// The command has no binary form.
    #[error("{0} has no binary form")]
    NoBinary(&'static str),
    /// A wire format limit.
    #[error(transparent)]
    Wire(#[from] WireError),
}

/// `text`, neither a number nor a name of `table`: [`ModelError::UnknownName`] with the nearest names of
/// `table`, or `forms` when none is near.
pub(crate) fn unknown_name<K>(
    what: &'static str,
    text: &str,
    table: &motionlink_link::table::Table<K>,
    forms: &str,
) -> ModelError {
    let hint = motionlink_link::table::did_you_mean(&table.suggest(text)).unwrap_or_else(|| forms.to_string());
    ModelError::UnknownName { what, text: text.to_string(), hint }
}

/// `v` as a message names a value: as Rust writes it (`-1055.88`, `0.0000001`), or with an exponent where
/// that would be long (`1e-300`, `1e308`: Rust writes no exponent, so a tiny or huge value would be hundreds of
/// digits).
pub(crate) fn shown(v: f64) -> String {
    let plain = v.to_string();
    if plain.len() > 24 {
        format!("{v:e}")
    } else {
        plain
    }
}

pub(crate) fn syntax(what: &'static str, text: &[u8]) -> ModelError {
    ModelError::Syntax { what, text: String::from_utf8_lossy(text).into_owned() }
}
