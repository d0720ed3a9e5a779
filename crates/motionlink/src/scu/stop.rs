//! `motionlink scu stop [FUNCTION] [--soft]`: RS to a function, or to every motion function, confirmed by
//! the status of every actuator; and what a motionlink that held the port said when it was stopped.

use std::io::Write;

use motionlink_scu::model::{Function, MotionFunction, StopMode};
use motionlink_scu::Client;
use serde_json::json;

use super::Report;
use crate::common::{self, CliError};

/// Stops `function` (`None`: every motion function, F1..F10): a motion function with RS (`soft`: along the
/// stop ramp) and the status read until no actuator moves, then where each connected actuator is; another
/// function (buzzer, outputs, emergency stop, LEDs) is switched off with RS.
pub(super) fn stop(
    client: &Client,
    function: Option<Function>,
    soft: bool,
    report: &Report<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let holder = report.stopped.as_ref();
    if let (Some(h), false) = (holder, report.json) {
        writeln!(out, "{}", h.describe())?;
    }
    let motions: Vec<MotionFunction> = match function {
        Some(Function::Motion(m)) => vec![m],
        None => MotionFunction::all().collect(),
        Some(f) => {
            client.switch(f, false).map_err(|e| common::classified(&e))?;
            return if report.json {
                report.print(
                    out,
                    json!({"action": "stop", "function": f.number(), "stopped": true, "mode": "off",
                                         "holder": holder}),
                )
            } else {
                writeln!(out, "{f} switched off (RS)")?;
                Ok(())
            };
        }
    };
    let mode = if soft { StopMode::Soft } else { StopMode::Fast };
    let stopped = client.stop_functions(&motions, mode).map_err(|e| common::classified(&e))?;
    if report.json {
        let mut fields = json!({"action": "stop", "stopped": true, "holder": holder});
        if let Some(f) = function {
            fields["function"] = json!(f.number());
        }
        if let (Some(map), Ok(serde_json::Value::Object(r))) = (fields.as_object_mut(), serde_json::to_value(&stopped))
        {
            map.extend(r);
        }
        return report.print(out, fields);
    }
    let how = match mode {
        StopMode::Fast => "fast RS",
        StopMode::Soft => "soft RS, along the stop ramp",
    };
    let names = match motions.as_slice() {
        [one] => one.to_string(),
        _ => "F1..F10".to_string(),
    };
    let rest: Vec<String> =
        stopped.at_rest.iter().map(|r| format!("{} {} counts", r.actuator, r.position_counts.0)).collect();
    let rest = if rest.is_empty() { "no actuator connected".to_string() } else { rest.join(", ") };
    writeln!(out, "stopped {names} ({how}); at rest (status read back): {rest}")?;
    for r in &stopped.refused {
        writeln!(out, "the unit refused the RS of {}: {}", r.function, r.reason)?;
    }
    Ok(())
}
