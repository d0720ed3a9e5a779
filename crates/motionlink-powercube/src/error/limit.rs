//! The message of a value beyond a module's limit ([`Error::OutsideLimits`](super::Error::OutsideLimits)).

use super::number;
use crate::model::{Address, Param};

/// The message of [`Error::OutsideLimits`]: the value and the limit (or the whole range) with their unit,
/// and, for a value in rad that is plainly no angle in radians (beyond a full turn) but would be within the
/// limits as degrees, what it is in rad: "module 1: the target position 90 rad is outside MinPos..MaxPos =
/// -3.14..3.14 rad (90 degrees is 1.5708 rad)".
pub(super) fn beyond_limit_text(
    address: Address,
    what: &str,
    value: f64,
    limit: Param,
    limit_value: f64,
    unit: &str,
    other_limit: Option<(Param, f64)>,
) -> String {
    let u = if unit.is_empty() { String::new() } else { format!(" {unit}") };
    let (mut text, low, high) = match other_limit {
        Some((other, other_value)) => {
            let ((low_param, low), (high_param, high)) = if limit_value <= other_value {
                ((limit, limit_value), (other, other_value))
            } else {
                ((other, other_value), (limit, limit_value))
            };
            let text = format!(
                "module {address}: {what} {}{u} is outside {low_param}..{high_param} = {}..{}{u}",
                number(value),
                number(low),
                number(high)
            );
            (text, low, high)
        }
        None => {
            let text = format!(
                "module {address}: {what} {}{u} is outside the module's limit {limit} = {}{u}",
                number(value),
                number(limit_value)
            );
            (text, -limit_value.abs(), limit_value.abs())
        }
    };
    if let Some(per) = unit.strip_prefix("rad") {
        let radians = value.to_radians();
        if value.abs() > std::f64::consts::TAU && (low..=high).contains(&radians) {
            text.push_str(&format!(" ({} degrees{per} is {radians:.4} {unit})", number(value)));
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::super::Error;
    use super::*;

    #[test]
    fn a_value_beyond_a_limit_is_named_with_its_unit_the_range_and_a_degrees_hint() {
        let beyond = |value, limit, limit_value, unit, other_limit| {
            Error::OutsideLimits {
                address: Address::checked(1),
                what: "the target position".into(),
                value,
                limit,
                limit_value,
                unit,
                other_limit,
            }
            .to_string()
        };
        let e = beyond(90.0, Param::MaxPos, 3.0, "rad", Some((Param::MinPos, -3.0)));
        assert_eq!(
            e,
            "module 1: the target position 90 rad is outside MinPos..MaxPos = -3..3 rad (90 degrees is 1.5708 rad)"
        );
        let e = beyond(4.0, Param::MaxPos, 3.0, "rad", Some((Param::MinPos, -3.0)));
        assert_eq!(e, "module 1: the target position 4 rad is outside MinPos..MaxPos = -3..3 rad", "no turn: no hint");
        let e = beyond(-0.5, Param::MinPos, 0.0, "m", Some((Param::MaxPos, 0.3)));
        assert_eq!(e, "module 1: the target position -0.5 m is outside MinPos..MaxPos = 0..0.3 m", "no degrees in m");
        let e = beyond(30.0, Param::MaxVel, 1.0, "rad/s", None);
        assert_eq!(e, "module 1: the target position 30 rad/s is outside the module's limit MaxVel = 1 rad/s (30 degrees/s is 0.5236 rad/s)");
        let e = beyond(400.0, Param::MaxPos, 3.0, "rad", Some((Param::MinPos, -3.0)));
        assert!(!e.contains("degrees"), "400 degrees is beyond the limits too: {e}");
    }
}
