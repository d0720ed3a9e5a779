//! `motionlink scu stop [FUNCTION] [--soft]`: RS to a function, or to every motion function, confirmed by
//! the status of every actuator; and what a motionlink that held the port said when it was stopped.

use std::io::Write;

use motionlink_scu::model::{Function, StopMode};
use motionlink_scu::results::{StopResult, StopScope, SwitchedOff};
use motionlink_scu::session::StopReport;
use motionlink_scu::Client;

use crate::common::Out;
use crate::common::{self, CliError};

/// Stops `function` (`None`: every motion function, F1..F10): a motion function with RS (`soft`: along the
/// stop ramp) and the status read until no actuator moves, then where each connected actuator is; another
/// function (buzzer, outputs, emergency stop, LEDs) is switched off with RS, and the status entry that shows
/// it is read back.
pub(super) fn stop(
    client: &Client,
    function: Option<Function>,
    soft: bool,
    report: &Out<'_>,
    holder: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    report.holder(out, holder)?;
    let motions = match StopScope::of(function) {
        StopScope::Motions(m) => m,
        StopScope::Switch(f) => {
            let switched = client.switch(f, false).map_err(|e| common::classified(&e))?;
            let printed = StopResult::new(holder, function, SwitchedOff::from(switched));
            return report.show(out, &printed, |out, p| {
                writeln!(out, "{f} switched off (RS)")?;
                let verified = match (p.stop.report.verified, f.switch_status()) {
                    (true, Some(s)) => format!("yes: read back from {}: {}", s.place(), s.state(false)),
                    (true, None) => "yes".into(),
                    (false, _) => format!("no: {}", p.stop.report.not_verifiable.join("; ")),
                };
                common::print_table(out, &[("verified".into(), verified)])
            });
        }
    };
    let mode = if soft { StopMode::Soft } else { StopMode::Fast };
    let stopped = client.stop_functions(&motions, mode).map_err(|e| common::classified(&e))?;
    let printed = StopResult::new(holder, function, stopped);
    report.show(out, &printed, |out, p| print_stop_text(out, &p.stop.report))
}

/// How the stop went, in words (the console says it so too).
pub(crate) fn print_stop_text(out: &mut dyn Write, stopped: &StopReport) -> Result<(), CliError> {
    let how = match stopped.mode {
        StopMode::Fast => "fast RS",
        StopMode::Soft => "soft RS, along the stop ramp",
    };
    let names = match stopped.functions.as_slice() {
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
