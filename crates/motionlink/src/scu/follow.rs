//! `motionlink scu follow`: targets read from stdin become streamed setpoints (the library checks each one
//! and stops the function when the stream ends).

use std::io::Write;
use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_scu::model::{Actuator, MotionFunction, PositionCounts, Speed, SpeedMode, StopMode};
use motionlink_scu::Client;
use serde_json::json;

use super::{parse_speed, Report};
use crate::common::{self, CliError};

/// One line of `follow`'s input.
#[derive(Debug, PartialEq)]
pub(super) enum FollowLine {
    /// Nothing (blank or a comment).
    Skip,
    /// New targets, one per actuator of the stream.
    Targets(Vec<PositionCounts>),
    /// A new speed.
    Speed(Speed),
}

/// Parses a line of `follow`'s input for a stream of `actuators`: `400` (all), `400 410` (one each, in
/// order), `a1=400 a2=410` (each named), `speed 60`; `#` starts a comment.
pub(super) fn parse_follow_line(line: &str, actuators: &[Actuator], mode: SpeedMode) -> Result<FollowLine, String> {
    let text = line.split('#').next().unwrap_or("").trim();
    if text.is_empty() {
        return Ok(FollowLine::Skip);
    }
    let words: Vec<&str> = text.split([' ', '\t', ',']).filter(|w| !w.is_empty()).collect();
    if let Some(rest) = text.strip_prefix("speed") {
        let value = rest.trim().trim_start_matches('=').trim();
        return parse_speed(value, mode).map(FollowLine::Speed).map_err(|e| e.to_string());
    }
    let count =
        |w: &str| w.parse::<i32>().map(PositionCounts).map_err(|_| format!("{w:?} is not a position in counts"));
    if words.iter().all(|w| !w.contains('=')) {
        let values = words.iter().map(|w| count(w)).collect::<Result<Vec<_>, _>>()?;
        return match values.len() {
            1 => Ok(FollowLine::Targets(vec![values[0]; actuators.len()])),
            n if n == actuators.len() => Ok(FollowLine::Targets(values)),
            n => Err(format!("{n} targets for {} actuator(s): give one for all, or one each", actuators.len())),
        };
    }
    let mut targets = vec![None; actuators.len()];
    for w in words {
        let (name, value) = w.split_once('=').ok_or_else(|| format!("{w:?}: give ACTUATOR=COUNTS, such as a1=400"))?;
        let a = name.trim_start_matches(['A', 'a']).parse::<u8>().ok().and_then(Actuator::new);
        let i = a
            .and_then(|a| actuators.iter().position(|x| *x == a))
            .ok_or_else(|| format!("{name:?} is not one of the actuators followed ({})", names(actuators)))?;
        targets[i] = Some(count(value)?);
    }
    if let Some(i) = targets.iter().position(Option::is_none) {
        return Err(format!("no target for {} (every actuator followed needs one)", actuators[i]));
    }
    Ok(FollowLine::Targets(targets.into_iter().flatten().collect()))
}

fn names(actuators: &[Actuator]) -> String {
    actuators.iter().map(Actuator::to_string).collect::<Vec<_>>().join(", ")
}

/// What the stdin reader hands over.
enum Input {
    Line(String),
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
    report: &Report<'_>,
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
    let mut stream = client.stream(function, &actuators, speed).map_err(|e| common::classified(&e))?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("follow-stdin".into())
        .spawn(move || {
            use std::io::BufRead;
            for line in std::io::stdin().lock().lines() {
                let message = match line {
                    Ok(l) => Input::Line(l),
                    Err(e) => Input::Failed(e.to_string()),
                };
                let failed = matches!(message, Input::Failed(_));
                if tx.send(message).is_err() || failed {
                    return;
                }
            }
            let _ = tx.send(Input::End);
        })
        .map_err(|e| CliError::transport(format!("cannot read stdin: {e}")))?;
    if report.json {
        let list: Vec<u8> = actuators.iter().map(|a| a.number()).collect();
        report.print(out, json!({"function": function.number(), "following": true, "actuators": list}))?;
    } else {
        writeln!(out, "following {function} ({}): targets from stdin", names(&actuators))?;
    }
    out.flush()?;
    let clock = Arc::clone(client.clock());
    let gap = Duration::from_secs(1) / rate_hz;
    let mut last_update: Option<motionlink_link::Timestamp> = None;
    let mut pending: Option<Vec<PositionCounts>> = None;
    let mut updates = 0u64;
    let mut last_targets: Option<Vec<PositionCounts>> = None;
    let mut failure: Option<Result<CliError, motionlink_scu::Error>> = loop {
        if interrupt.is_cancelled() {
            break Some(Ok(CliError::Interrupted(format!("interrupted; {function} stopped"))));
        }
        match rx.recv_timeout(Duration::from_millis(10)) {
            Ok(Input::Line(line)) => match parse_follow_line(&line, &actuators, mode) {
                Ok(FollowLine::Skip) => {}
                Ok(FollowLine::Targets(t)) => pending = Some(t),
                Ok(FollowLine::Speed(s)) => {
                    if let Err(e) = stream.set_speed(s) {
                        break Some(Err(e));
                    }
                }
                Err(e) => break Some(Ok(CliError::usage(format!("stdin line {line:?}: {e}")))),
            },
            Ok(Input::End) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break None,
            Ok(Input::Failed(e)) => break Some(Ok(CliError::transport(format!("reading stdin: {e}")))),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
        let now = clock.now();
        if pending.is_some() && last_update.is_none_or(|t| now - t >= gap) {
            let targets = pending.take().unwrap_or_default();
            if let Err(e) = apply(&mut stream, &targets, report, out)? {
                break Some(Err(e));
            }
            last_update = Some(now);
            updates += 1;
            last_targets = Some(targets);
        }
    };
    // End of input: the newest target still waiting is applied (the newest wins, even the last one), and the
    // stream follows it to the end of its motion before it ends; a signal meanwhile stops it at once.
    if failure.is_none() {
        if let Some(targets) = pending.take() {
            if let Err(e) = apply(&mut stream, &targets, report, out)? {
                failure = Some(Err(e));
            } else {
                updates += 1;
                last_targets = Some(targets);
            }
        }
    }
    if failure.is_none() && last_targets.is_some() {
        failure = settle(&stream, &clock, client.config().poll_interval, interrupt)
            .map(|e| e.map(|()| CliError::Interrupted(format!("interrupted; {function} stopped"))));
    }
    // The stream ends: on EOF along the ramp, on anything else at once; where each actuator came to rest.
    let (mode, error) = match failure {
        None => (StopMode::Soft, None),
        Some(Ok(cli)) => (StopMode::Fast, Some(cli)),
        Some(Err(scu)) => return Err(common::classified(&stream.abort(scu))),
    };
    let rest = stream.stop(mode).map_err(|e| common::classified(&e))?;
    let text: Vec<String> = rest.iter().map(|(a, p)| format!("{a}={}", p.get())).collect();
    if report.json {
        let list: Vec<_> = rest.iter().map(|(a, p)| json!({"actuator": a.number(), "reached_counts": p})).collect();
        report.print(out, json!({"stopped": true, "actuators": list, "updates": updates}))?;
    } else {
        writeln!(out, "stopped after {updates} update(s): {}", text.join(" "))?;
    }
    if let Some(e) = error {
        return Err(e);
    }
    // As `move`: success means each actuator the function drives ended within the tolerance of the last target
    // it was given (without --functions only the actuator asked for is known to be driven by it).
    let tolerance = i64::from(client.config().position_tolerance_counts);
    let driven = |a: &Actuator| match client.config().function_map.drives(function) {
        Some(drives) => drives.contains(a),
        None => *a == actuator,
    };
    if let Some(targets) = &last_targets {
        let missed: Vec<String> = rest
            .iter()
            .zip(targets)
            .filter(|((a, _), _)| driven(a))
            .filter(|((_, p), t)| p.counts_from(**t).abs() > tolerance)
            .map(|((a, p), t)| {
                format!("{a}: target {}, reached {}, difference {}", t.get(), p.get(), p.counts_from(*t))
            })
            .collect();
        if !missed.is_empty() {
            return Err(CliError::Device(format!(
                "the last target was not reached within {tolerance} counts: {}",
                missed.join("; ")
            )));
        }
    }
    Ok(())
}

/// Writes one update of targets and prints it. The outer error is the output's, the inner the device's.
fn apply(
    stream: &mut motionlink_scu::client::SetpointStream<'_>,
    targets: &[PositionCounts],
    report: &Report<'_>,
    out: &mut dyn Write,
) -> Result<Result<(), motionlink_scu::Error>, CliError> {
    if let Err(e) = stream.set_targets(targets) {
        return Ok(Err(e));
    }
    let actuators = stream.actuators();
    if report.json {
        let list: Vec<_> =
            actuators.iter().zip(targets).map(|(a, t)| json!({"actuator": a.number(), "target_counts": t})).collect();
        report.print(out, json!({"targets": list}))?;
    } else {
        let text: Vec<String> = actuators.iter().zip(targets).map(|(a, t)| format!("{a}={}", t.get())).collect();
        writeln!(out, "target {}", text.join(" "))?;
    }
    out.flush()?;
    Ok(Ok(()))
}

/// Waits until no actuator of the stream moves, looking every `poll`: `None` when they are at rest,
/// `Some(Ok(()))` when a signal came first, `Some(Err(..))` when the device could not be read.
fn settle(
    stream: &motionlink_scu::client::SetpointStream<'_>,
    clock: &Arc<dyn motionlink_link::Clock>,
    poll: Duration,
    interrupt: &CancelToken,
) -> Option<Result<(), motionlink_scu::Error>> {
    loop {
        match stream.positions() {
            Ok(p) if p.iter().all(|(_, _, moving)| !moving) => return None,
            Ok(_) => {}
            Err(e) => return Some(Err(e)),
        }
        let next = clock.now() + poll;
        while clock.now() < next {
            if interrupt.is_cancelled() {
                return Some(Ok(()));
            }
            std::thread::sleep(Duration::from_millis(5).min(poll));
        }
    }
}
