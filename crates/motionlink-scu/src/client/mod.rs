//! The session over a real link: [`Client`] for blocking callers and, with the `tokio` feature,
//! `AsyncClient` for async ones: the same operations and the same safety (both run the same
//! [`Session`](crate::Session) under the shared driver).
//!
//! ```no_run
//! use motionlink_scu::{Client, Config, FunctionMap};
//! use motionlink_scu::model::{Actuator, PositionCounts, Speed};
//! use motionlink_link::{url::PortUrl, RealClock};
//!
//! let port: PortUrl = "/dev/ttyUSB0".parse()?;
//! // The unit's parameterisation decides which actuators each function drives; tell the session.
//! let config = Config { function_map: FunctionMap::scp11(), ..Config::default() };
//! let client = Client::open(&port, RealClock::shared(), config)?;
//! let a1 = Actuator::new(1).unwrap();
//! let report = client.move_to(a1, PositionCounts(400), Speed::percent(80).unwrap(), &Default::default())?;
//! println!("actuator 1 at {}", report.position_counts); // "400 counts"
//! // Dropping the client stops anything it started (RS) and, once that is confirmed, leaves remote mode (RA).
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The typed API, as the README's "From Rust" (and docs/scu.md) shows it (the same code; positions are
//! [`PositionCounts`], speeds [`Speed`], actuator status 1
//! the flag word [`ActuatorStatus1`]):
//!
//! ```no_run
//! use motionlink_link::{url::PortUrl, RealClock};
//! use motionlink_scu::model::{Actuator, DataIndex, MotionFunction, PositionCounts, SafetyId, Speed, StopMode};
//! use motionlink_scu::{Client, Config, FunctionMap, MoveOptions};
//!
//! let port: PortUrl = "/dev/ttyUSB0".parse()?;
//! let config = Config { function_map: FunctionMap::liftkit(), safety_id: SafetyId::StopAll, ..Default::default() };
//! let client = Client::open(&port, RealClock::shared(), config)?;
//! let (a1, a2) = (Actuator::new(1).unwrap(), Actuator::new(2).unwrap());
//! let pct = |p| Speed::percent(p).unwrap();                     // percent and counts/s are different types
//! let at = PositionCounts;                                      // a position is counts, said so: at(400)
//! println!("{:?}", client.get(DataIndex(0x0010))?);             // every actuator's position, typed
//! let report = client.move_to(a1, at(400), pct(80), &MoveOptions::default())?;   // F1: actuator 1, verified
//! assert_eq!(report.position_counts, at(400));
//! let f8 = MotionFunction::new(8).unwrap();                     // both columns, each to its own target, one RE
//! let report = client.move_function(f8, &[(a1, at(300)), (a2, at(310))], pct(80), &MoveOptions::default())?;
//! for a in &report.actuators { println!("{} at {} ({:+})", a.actuator, a.position_counts, a.difference_counts()); }
//! let [p1, p2, ..] = client.positions()?;                       // [PositionCounts; 6]
//! let moving = client.statuses()?.iter().any(|s| s.moving());   // [ActuatorStatus1; 6], flag words
//! println!("{p1} {p2} moving: {moving}; A1: {}", client.status1(a1)?); // "available | in_position"
//! let mut stream = client.stream(f8, &[a1, a2], pct(60))?;      // streamed setpoints, 10..100 Hz
//! stream.set_targets(&[at(350), at(350)])?;
//! stream.set_speed(pct(40))?;
//! for (a, p) in stream.stop(StopMode::Soft)? { println!("{a} rests at {p}"); }
//! for code in client.error_history()? { println!("{code}"); }  // named bits
//! let stopped = client.close()?;                                // RS for anything it started, then RA: what it stopped
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A bare number is not a position: this does not compile (`PositionCounts(400)` does, above).
//!
//! ```compile_fail
//! # fn f(client: &motionlink_scu::Client) -> Result<(), motionlink_scu::Error> {
//! # use motionlink_scu::model::{Actuator, Speed};
//! let a1 = Actuator::new(1).unwrap();
//! client.move_to(a1, 400, Speed::percent(80).unwrap(), &Default::default())?;
//! # Ok(())
//! # }
//! ```

use motionlink_link::link::{Connector, SerialSettings};
use motionlink_link::url::PortUrl;
use motionlink_link::{Link, LinkError};

use crate::config::Config;
use crate::error::Error;
use crate::model::ActuatorStatus1;
use crate::model::{
    item, Actuator, DataEntry, DataIndex, ErrorCode, Function, Item, MotionFunction, PositionCounts, Speed,
};
use crate::session::ops::basic::{check_stroke, Stroke};
use crate::session::report::MoveProgress;
use crate::session::{MoveSpec, MoveTargets, Op, RunAction, RunSpec};
use crate::value::{decode_item, Value};
use crate::wire::Command;

#[cfg(feature = "tokio")]
mod asynch;
mod blocking;
mod follow;
mod reads;

#[cfg(feature = "tokio")]
pub use asynch::{AsyncClient, AsyncSetpointStream};
pub use blocking::{Client, SetpointStream};
pub use follow::{FollowFailure, FollowReport, Follower};

/// Options of a move (the blocking client's cancel token, [`Client::set_cancel`], cancels it: the actuators
/// are stopped).
#[derive(Default)]
pub struct MoveOptions<'a> {
    /// Called after every look at the actuators.
    pub progress: Option<&'a dyn Fn(&MoveProgress)>,
    /// For [`Client::move_to`]: use this function instead of the one with the actuator's number.
    pub function: Option<MotionFunction>,
}

/// Takes the expected variant out of an operation's output.
macro_rules! expect_output {
    ($result:expr, $pat:pat => $value:expr) => {
        match $result {
            Ok($pat) => Ok($value),
            Ok(other) => Err($crate::error::Error::UnexpectedReply {
                command: $crate::wire::Command::Get,
                detail: format!("the session answered {other:?}"),
            }),
            Err(e) => Err(e),
        }
    };
}
pub(crate) use expect_output;

/// The connector of [`Client::open`]: the serial line or TCP port `port` names, at [`Config::baud`]. `sim`
/// and CAN ports are refused, naming what to do instead.
pub fn port_connector(port: &PortUrl, config: &Config) -> Result<Connector, Error> {
    let refuse =
        |reason: &str| Err(Error::from(LinkError::InvalidPort { port: port.to_string(), reason: reason.into() }));
    match port {
        PortUrl::Sim => refuse("an emulator in this process: make one (`Emulator`) and give its link to `with_link`"),
        p if p.is_can() => refuse("the SCU speaks RS232, not CAN"),
        p => {
            let (p, settings) = (p.clone(), SerialSettings::new(config.baud.get()));
            Ok(Box::new(move || p.open_byte_link(settings)))
        }
    }
}

/// `connector`, sending each link it opens a break of `wake` first ([`Config::wake_break`]), or as it is.
pub(crate) fn waking(mut connector: Connector, wake: Option<std::time::Duration>) -> Connector {
    let Some(wake) = wake else { return connector };
    Box::new(move || {
        let mut link = connector()?;
        tracing::info!(
            "holding {}'s line at space for {} ms (a break: wakes a unit in low-power mode)",
            link.describe(),
            wake.as_millis()
        );
        link.send_break(wake)?;
        Ok(link)
    })
}

/// The connector of [`Client::with_link`]: `link` once; a reconnection after it is lost is refused.
pub(crate) fn link_connector(link: Box<dyn Link>) -> Connector {
    let name = link.describe();
    let mut link = Some(link);
    Box::new(move || {
        link.take().ok_or_else(|| LinkError::Open {
            port: name.clone(),
            reason: "a link given to with_link cannot be opened again (with_connector reconnects)".into(),
        })
    })
}

/// The move of [`Client::move_to`]: the function, and which actuators get the target.
pub(crate) fn move_spec(
    config: &Config,
    actuator: Actuator,
    target: PositionCounts,
    speed: Speed,
    function: Option<MotionFunction>,
) -> Result<MoveSpec, Error> {
    let function = match function {
        Some(f) => f,
        None => MotionFunction::new(actuator.number())
            .ok_or_else(|| Error::invalid(format!("{actuator} has no function of its number")))?,
    };
    let targets = match config.function_map.drives(function) {
        Some(drives) => {
            if !drives.contains(&actuator) {
                return Err(Error::invalid(format!(
                    "{function} does not drive {actuator}: the function map says it drives {}; name the function \
                     that does",
                    crate::model::Actuator::list(&drives)
                )));
            }
            MoveTargets::Given(drives.iter().map(|a| (*a, target)).collect())
        }
        None => MoveTargets::EveryConnected(target),
    };
    Ok(MoveSpec { function, primary: actuator, targets, speed })
}

/// A run's specification, checked.
pub(crate) fn run_spec(action: RunAction, limit: Option<std::time::Duration>) -> Result<RunSpec, Error> {
    if let RunAction::Switch(Function::Motion(m)) = action {
        return Err(Error::invalid(format!("{m} is a motion function: run it with a direction")));
    }
    Ok(RunSpec { action, limit })
}

/// The operation that switches a switching function on (RE) or off (RS) and checks its status.
pub(crate) fn switch_op(function: Function, on: bool) -> Result<Op, Error> {
    crate::session::ops::switch_request(function, on)?;
    Ok(Op::Switch { function, on })
}

pub(crate) fn data(reply: Option<Vec<u8>>) -> Result<Vec<u8>, Error> {
    reply.ok_or(Error::UnexpectedReply { command: Command::Get, detail: "ACK without data".into() })
}

pub(crate) fn item_of(index: DataIndex) -> Result<Item, Error> {
    item(index).ok_or_else(|| Error::invalid(format!("{index} is not in the data list")))
}

pub(crate) fn entry_of(index: DataIndex) -> Result<&'static DataEntry, Error> {
    match item(index) {
        Some(Item::Entry(e)) => Ok(e),
        Some(Item::Group(g)) => Err(Error::invalid(format!("{index} is the group {}; use get() for groups", g.name))),
        None => Err(Error::invalid(format!("{index} is not in the data list"))),
    }
}

pub(crate) fn decode(it: Item, data: &[u8]) -> Result<Vec<(&'static DataEntry, Value)>, Error> {
    decode_item(it, data)
        .map_err(|e| Error::UnexpectedReply { command: Command::Get, detail: format!("{}: {e}", it.name()) })
}

pub(crate) fn position(value: Value) -> Result<PositionCounts, Error> {
    match value {
        Value::PositionCounts(p) => Ok(PositionCounts(p)),
        other => Err(Error::UnexpectedReply { command: Command::Get, detail: format!("position {other:?}") }),
    }
}

pub(crate) fn status1(data: &[u8]) -> Result<ActuatorStatus1, Error> {
    let [bits] = data[..] else {
        return Err(Error::UnexpectedReply { command: Command::Get, detail: "status is one byte".into() });
    };
    Ok(ActuatorStatus1(bits))
}

pub(crate) fn connected(status: &[ActuatorStatus1; 6]) -> Vec<Actuator> {
    Actuator::all().filter(|a| status[usize::from(a.number() - 1)].available()).collect()
}

pub(crate) fn error_history(data: &[u8]) -> Result<[ErrorCode; 5], Error> {
    if data.len() != 20 {
        return Err(Error::UnexpectedReply { command: Command::Get, detail: "error codes are 5 x 4 bytes".into() });
    }
    Ok(std::array::from_fn(|i| {
        ErrorCode(u32::from_le_bytes([data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]]))
    }))
}

/// The targets of a stream update, checked: one per actuator, each within its stroke.
pub(crate) fn stream_targets(
    function: MotionFunction,
    actuators: &[Actuator],
    limits: &[Stroke],
    targets: &[PositionCounts],
) -> Result<Vec<(Actuator, PositionCounts)>, Error> {
    if targets.len() != actuators.len() {
        return Err(Error::invalid(format!(
            "{} target(s) given; {function} drives {}: one each",
            targets.len(),
            crate::model::Actuator::list(actuators)
        )));
    }
    for ((a, stroke), &t) in actuators.iter().zip(limits).zip(targets) {
        check_stroke(*a, t, stroke)?;
    }
    Ok(actuators.iter().copied().zip(targets.iter().copied()).collect())
}

pub(crate) fn stream_positions(
    actuators: &[Actuator],
    status: &[ActuatorStatus1; 6],
    positions: &[PositionCounts; 6],
) -> Vec<(Actuator, PositionCounts, bool)> {
    actuators
        .iter()
        .map(|a| {
            let i = usize::from(a.number() - 1);
            (*a, positions[i], status[i].moving())
        })
        .collect()
}

/// What the end of a session ([`Client::close`]) says about the functions that were still started when it
/// began.
#[derive(Debug)]
pub enum Ending {
    /// Nothing was left started, and the session ended cleanly.
    Clean,
    /// The end of the session stopped what was left started, and the unit acknowledged the RS: a note to add
    /// to what the caller reports ("F1 stopped (the unit acknowledged RS)").
    Stopped(String),
    /// The end of the session failed; nothing was left started.
    Failed(Error),
    /// The stop of what was left started is not confirmed: the actuators may still move
    /// ([`Error::CloseUnconfirmed`]).
    Unconfirmed(Error),
}

/// Says what `closed` (the result of [`Client::close`]: the functions it stopped) means.
pub fn ending(closed: Result<Vec<Function>, Error>) -> Ending {
    match closed {
        Ok(stopped) if stopped.is_empty() => Ending::Clean,
        Ok(stopped) => {
            Ending::Stopped(format!("{} stopped (the unit acknowledged RS)", crate::model::function_list(&stopped)))
        }
        Err(e @ Error::CloseUnconfirmed { .. }) => Ending::Unconfirmed(e),
        Err(e) => Ending::Failed(e),
    }
}

/// The result of a close that found `started` left started: those functions stopped, or the error, which
/// names them when there were some ([`Error::CloseUnconfirmed`]).
pub(crate) fn closed(started: Vec<Function>, result: Result<(), Error>) -> Result<Vec<Function>, Error> {
    match result {
        Ok(()) => Ok(started),
        Err(e @ Error::CloseUnconfirmed { .. }) => Err(e),
        Err(e) if started.is_empty() => Err(e),
        Err(e) => Err(Error::CloseUnconfirmed { functions: started, cause: Box::new(e) }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_close_says_what_it_stopped_or_names_what_it_could_not_confirm() {
        let f1 = Function::from_id(0).unwrap();
        assert_eq!(closed(vec![f1], Ok(())).unwrap(), vec![f1]);
        let lost = || Error::SessionLost("port gone".into());
        let e = closed(vec![f1], Err(lost())).unwrap_err();
        assert!(matches!(&e, Error::CloseUnconfirmed { functions, .. } if *functions == vec![f1]), "{e}");
        assert!(matches!(closed(Vec::new(), Err(lost())), Err(Error::SessionLost(_))));
        // Already unconfirmed by the session: not wrapped twice.
        let once = closed(vec![f1], Err(e)).unwrap_err();
        assert!(matches!(&once, Error::CloseUnconfirmed { cause, .. } if matches!(**cause, Error::SessionLost(_))));
        assert!(matches!(ending(Ok(vec![f1])), Ending::Stopped(n) if n.contains("F1")));
        assert!(matches!(ending(Ok(Vec::new())), Ending::Clean));
        assert!(matches!(ending(closed(vec![f1], Err(lost()))), Ending::Unconfirmed(_)));
        assert!(matches!(ending(Err(lost())), Ending::Failed(_)));
    }
}
