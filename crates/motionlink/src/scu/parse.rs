//! The words and numbers of `motionlink scu`, checked before the port is opened: each error names what
//! was wrong (exit 2), and a misspelt name the nearest real one.

use std::time::Duration;

use motionlink_link::table::{did_you_mean, nearest};
use motionlink_scu::model::{
    find, suggest, Actuator, Function, Item, MotionDirection, MotionFunction, Speed, SpeedMode,
};
use motionlink_scu::StrokeLimits;

use crate::common::CliError;

/// `--baud`: the rates an SCU runs at.
pub(super) fn parse_baud(s: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(b @ (9_600 | 19_200 | 38_400)) => Ok(b),
        _ => Err("an SCU runs at 9600, 19200 or 38400 baud".to_string()),
    }
}

/// `--stroke 1=0:865`.
pub(super) fn parse_stroke(spec: &str) -> Result<(Actuator, StrokeLimits), CliError> {
    StrokeLimits::parse_for_actuator(spec).map_err(|e| CliError::usage(format!("--stroke {e}")))
}

/// `--speed` of a motion: a whole number from 1 to the speed mode's maximum (0 would never move).
pub(super) fn parse_speed(text: &str, mode: SpeedMode) -> Result<Speed, CliError> {
    Speed::parse(text, mode).map_err(|e| CliError::usage(format!("--speed {e}")))
}

/// `--rate` of `follow`: 1..100 updates per second.
pub(super) fn parse_rate(text: &str) -> Result<u32, CliError> {
    match text.trim().parse::<i64>() {
        Ok(v) if (1..=100).contains(&v) => Ok(v as u32),
        _ => Err(CliError::usage(format!(
            "--rate {text}: the update rate must be a whole number from 1 to 100 per second"
        ))),
    }
}

/// `--seconds` of `run`: a finite, non-negative number of seconds (at most a day).
pub(super) fn parse_seconds(text: &str) -> Result<Duration, CliError> {
    match text.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && (0.0..=86_400.0).contains(&s) => Ok(Duration::from_secs_f64(s)),
        _ => Err(CliError::usage(format!("--seconds {text}: the run time must be a number of seconds, 0 to 86400"))),
    }
}

/// The motion function of `move` and `follow`: `--function`, or the one with the actuator's number.
pub(super) fn motion_function(actuator: Actuator, function: Option<u8>) -> Result<MotionFunction, CliError> {
    let n = function.unwrap_or(actuator.number());
    MotionFunction::new(n).ok_or_else(|| CliError::usage(format!("--function {n}: the motion functions are F1..F10")))
}

/// A data-list entry or group by name or index; a misspelt name is answered with the nearest real one.
pub(super) fn parse_item(text: &str) -> Result<Item, CliError> {
    find(text).map_err(|e| {
        if suggest(text).is_empty() {
            CliError::usage(format!("{e} (`motionlink scu names` lists them)"))
        } else {
            CliError::usage(e)
        }
    })
}

/// An actuator, 1..6.
pub(super) fn parse_actuator(n: u8) -> Result<Actuator, CliError> {
    Actuator::new(n).ok_or_else(|| CliError::usage(format!("actuator {n}: actuators are 1..6")))
}

/// A function, F1..F22 (or 1..22).
pub(super) fn parse_function(text: &str) -> Result<Function, CliError> {
    Function::parse(text).ok_or_else(|| {
        CliError::usage(format!(
            "{text:?} is not a function: F1..F10 motion, F11 buzzer, F17/F18 outputs, F20 emergency stop, F21/F22 LEDs"
        ))
    })
}

/// A direction of a motion function; a misspelt one is answered with the nearest real one.
pub(super) fn parse_direction(text: &str) -> Result<MotionDirection, CliError> {
    MotionDirection::parse(text).ok_or_else(|| {
        let hint = did_you_mean(&nearest(text, MotionDirection::NAMES.iter().copied()))
            .unwrap_or_else(|| "in, out, mem1..mem4, int-in, int-out, remote, none, or 0..9".into());
        CliError::usage(format!("{text:?} is not a direction: {hint}"))
    })
}
