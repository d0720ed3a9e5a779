//! `motionlink scu follow`: targets read from stdin become streamed setpoints. The library's
//! [`Follower`] keeps the policy (the rate and the newest target, the end along the ramp or at once, the check
//! against the tolerance); this reads and parses the lines, prints, and maps errors to exit codes.

use std::io::Write;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_scu::args::TargetLine;
use motionlink_scu::client::FollowFailure;
use motionlink_scu::model::{Actuator, MotionFunction, PositionCounts, Speed};
use motionlink_scu::results::{FollowStart, TargetsApplied};
use motionlink_scu::{Client, Follower};

use crate::common::Out;
use crate::common::{self, CliError};

fn names(actuators: &[Actuator]) -> String {
    actuators.iter().map(Actuator::to_string).collect::<Vec<_>>().join(", ")
}

/// What the stdin reader hands over.
enum Input {
    Line(String),
    /// A line that is not UTF-8 (as far as it can be shown).
    NotText(String),
    End,
    Failed(String),
}

/// `scu follow`: targets from stdin, applied at most `rate_hz` times a second while the motion runs.
#[allow(clippy::too_many_arguments)]
pub(super) fn follow(
    client: &Client,
    actuator: Actuator,
    function: MotionFunction,
    speed: Speed,
    rate_hz: u32,
    report: &Out<'_>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let actuators = match client.config().function_map.drives(function) {
        Some(drives) if drives.contains(&actuator) => drives,
        Some(drives) => {
            return Err(CliError::usage(format!(
                "{function} does not drive {actuator} (--functions says it drives {})",
                names(&drives)
            )))
        }
        // Not known: every connected actuator follows, so that none runs to a stale remote position.
        None => client.connected_actuators().map_err(|e| common::classified(&e))?,
    };
    let mode = client.config().speed_mode;
    // The library keeps the rate, the newest target, the end along the ramp or at once, and the check.
    let stream = client.stream(function, &actuators, speed).map_err(|e| common::classified(&e))?;
    let mut follower = Follower::new(stream, actuator, rate_hz).map_err(|e| common::classified(&e))?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("follow-stdin".into())
        .spawn(move || {
            use std::io::BufRead;
            for line in std::io::stdin().lock().split(b'\n') {
                let message = match line.map(String::from_utf8) {
                    Ok(Ok(mut l)) => {
                        if l.ends_with('\r') {
                            l.pop();
                        }
                        Input::Line(l)
                    }
                    Ok(Err(e)) => Input::NotText(String::from_utf8_lossy(e.as_bytes()).into_owned()),
                    Err(e) => Input::Failed(e.to_string()),
                };
                let failed = matches!(message, Input::Failed(_) | Input::NotText(_));
                if tx.send(message).is_err() || failed {
                    return;
                }
            }
            let _ = tx.send(Input::End);
        })
        .map_err(|e| CliError::transport(format!("cannot read stdin: {e}")))?;
    report.show(out, &FollowStart { function, actuators: actuators.clone() }, |out, _| {
        writeln!(out, "following {function} ({}): targets from stdin", names(&actuators)).map_err(CliError::from)
    })?;
    out.flush()?;
    let failure: Option<Result<CliError, motionlink_scu::Error>> = loop {
        if interrupt.is_cancelled() {
            break Some(Ok(CliError::Interrupted(format!("interrupted; {function} stopped"))));
        }
        match rx.recv_timeout(Duration::from_millis(10)) {
            Ok(Input::Line(line)) => match TargetLine::parse(&line, &actuators, mode) {
                Ok(TargetLine::Skip) => {}
                Ok(TargetLine::Targets(t)) => follower.offer(t),
                Ok(TargetLine::Speed(s)) => {
                    if let Err(e) = follower.set_speed(s) {
                        break Some(Err(e));
                    }
                }
                Err(e) => break Some(Ok(CliError::usage(format!("stdin line {line:?}: {e}")))),
            },
            Ok(Input::End) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break None,
            Ok(Input::Failed(e)) => break Some(Ok(CliError::transport(format!("reading stdin: {e}")))),
            Ok(Input::NotText(line)) => {
                break Some(Ok(CliError::usage(format!("stdin line {line:?}: not UTF-8 text"))));
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
        match follower.apply_due() {
            Ok(Some(targets)) => print_targets(&actuators, targets, report, out)?,
            Ok(None) => {}
            // A target outside the stroke is a bad line: refused, and the motion of the lines before it is
            // stopped (not "nothing was moved", which holds for a move only).
            Err(e) => match e.stroke_refusal() {
                Some(refused) => break Some(Ok(CliError::usage(format!("{refused}; {function} stopped")))),
                None => break Some(Err(e)),
            },
        }
    };
    let (stopped, error) = match failure {
        // End of input: the newest target still waiting is applied (and printed), the motion reaches it, the
        // function ends along the ramp, and each actuator it drives is checked against its last target.
        None => {
            match follower.flush() {
                Ok(Some(targets)) => print_targets(&actuators, targets, report, out)?,
                Ok(None) => {}
                Err(e) => return Err(common::classified(&follower.abort(e))),
            }
            match follower.finish(interrupt) {
                Ok(stopped) => (stopped, None),
                Err(FollowFailure { error, stopped: Some(stopped) }) => (stopped, Some(common::classified(&error))),
                Err(FollowFailure { error, stopped: None }) => return Err(common::classified(&error)),
            }
        }
        // A signal, a bad line, stdin failing: the motion stops at once.
        Some(Ok(cli)) => (follower.stop_fast().map_err(|e| common::classified(&e))?, Some(cli)),
        Some(Err(scu)) => return Err(common::classified(&follower.abort(scu))),
    };
    report.show(out, &stopped, |out, r| {
        let text: Vec<String> = r.rest.iter().map(|(a, p)| format!("{a}={}", p.get())).collect();
        writeln!(out, "stopped after {} update(s): {} counts", r.updates, text.join(" ")).map_err(CliError::from)
    })?;
    error.map_or(Ok(()), Err)
}

/// Prints one update of targets.
fn print_targets(
    actuators: &[Actuator],
    targets: &[PositionCounts],
    report: &Out<'_>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let applied = TargetsApplied(actuators.iter().copied().zip(targets.iter().copied()).collect());
    report.show(out, &applied, |out, t| {
        let text: Vec<String> = t.0.iter().map(|(a, p)| format!("{a}={}", p.get())).collect();
        writeln!(out, "target {} counts", text.join(" ")).map_err(CliError::from)
    })?;
    out.flush()?;
    Ok(())
}
