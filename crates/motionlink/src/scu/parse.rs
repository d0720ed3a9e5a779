//! The words of `motionlink scu` that the library's argument types ([`motionlink_scu::args`]) do not parse
//! through clap, checked before the port is opened with the library's rules and messages (exit 2).

use motionlink_scu::model::{find, suggest, Item, Speed, SpeedMode};

use crate::common::CliError;

/// `--speed-mode`: the library's speed modes, by the names the command line lists.
pub(crate) fn speed_mode_parser() -> impl clap::builder::TypedValueParser<Value = SpeedMode> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(["percent", "counts-per-second"]).try_map(|s| s.parse::<SpeedMode>())
}

/// `--speed` of a motion, for a unit of `mode` (the rule is the mode's, so it is checked once the mode is
/// known).
pub(super) fn parse_speed(text: &str, mode: SpeedMode) -> Result<Speed, CliError> {
    Speed::parse(text, mode).map_err(|e| CliError::usage(format!("--speed {text}: {e}")))
}

/// A data-list entry or group by name or index; a misspelt name is answered with the nearest real one.
pub(super) fn parse_item(text: &str) -> Result<Item, CliError> {
    find(text).map_err(|e| match suggest(text).is_empty() {
        true => CliError::usage(format!("{e} (`motionlink scu names` lists them)")),
        false => CliError::usage(e),
    })
}
