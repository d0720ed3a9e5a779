//! A COMPAX drive on the gateway: `move`, `stop`, `status`, `get`, `set`, `output`, `scan` and the state samples, as the command line's
//! `motionlink compax` does them, on [`AsyncClient`].

use std::sync::Arc;

use motionlink_compax::model::{
    OutputNumber, OutputState, ParamId, ParamWrite, Position, RampMs, SpeedPercent, StatusId, TimeLimit,
};
use motionlink_compax::report::{DrivePosition, ParamReading, StatusReport, StopResult, Timed};
use motionlink_compax::session::{MoveRequest, MoveTarget, TravelLimits, WatchSample};
use motionlink_compax::wire::Address;
use motionlink_compax::{AsyncClient, DriveOptions, Emulator};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::profile::Profiles;
use motionlink_link::url::PortUrl;
use motionlink_link::RealClock;
use serde_json::Value;

use super::{failed, identified, unknown_op, Action, Outcome, Sampling};
use crate::args::Args;
use crate::error::{ErrorReport, GatewayErrors};

/// The actions served.
const OPS: [&str; 7] = ["move", "stop", "status", "get", "set", "output", "scan"];

/// The command line's `--timeout-s` of a move when none is given, in s.
const MOVE_TIMEOUT_S: f64 = 600.0;

/// A session with one drive.
#[derive(Clone)]
pub(super) struct Compax {
    client: Arc<AsyncClient>,
    drive: Address,
    port: String,
    /// The device profile the session took (null: none).
    profile: Value,
    /// The position of the previous state sample (`None` before the first): S1 moving says the drive moves.
    last_sample: Arc<std::sync::Mutex<Option<Position>>>,
}

impl Compax {
    /// Opens the drive's bus on `port` (`sim`: an emulated bus with the drive the options name); the
    /// emulator's host comes with it.
    pub(super) async fn open(
        options: &DriveOptions,
        port: &str,
        profiles: Option<&Profiles>,
        name: &str,
    ) -> Result<(Compax, Option<Box<dyn std::any::Any + Send>>), ErrorReport> {
        let url: PortUrl = port.parse().map_err(|e| ErrorReport::usage(format!("port {port:?}: {e}")))?;
        let clock = RealClock::shared();
        let baud = options.baud.bits_per_s();
        let (client, host): (AsyncClient, Option<Box<dyn std::any::Any + Send>>) = match url {
            PortUrl::Sim => {
                let bus = Emulator::new(options.emulated()).map_err(|e| ErrorReport::usage(e.to_string()))?;
                let host = EmulatorHost::new(bus, Arc::clone(&clock), PipeConfig::paced(baud));
                let link = Box::new(host.connect().0);
                (AsyncClient::with_link(link, clock, options.config()).await.map_err(failed)?, Some(Box::new(host)))
            }
            url => (AsyncClient::open(&url, clock, options.config()).await.map_err(failed)?, None),
        };
        // The drive's device profile, where the profiles name it (S31 and S32), as every command takes it.
        let profile = match profiles {
            Some(p) => super::took_profile(
                name,
                motionlink_compax::probe::use_profile_async(&client, p, port, options.drive).await,
            ),
            None => Value::Null,
        };
        Ok((
            Compax {
                client: Arc::new(client),
                drive: options.drive,
                port: port.to_string(),
                profile,
                last_sample: Default::default(),
            },
            host,
        ))
    }

    fn result(&self, report: &impl serde::Serialize) -> Outcome {
        let identity = [("profile", self.profile.clone()), ("drive", Value::from(self.drive.get()))];
        identified("compax", &self.port, &identity, report)
    }

    /// The action `op`, its arguments checked by the library's types.
    pub(super) fn action(&self, op: &str, mut args: Args) -> Result<Action, ErrorReport> {
        let me = self.clone();
        let (client, drive) = (Arc::clone(&self.client), self.drive);
        match op {
            "move" => {
                let position: Option<Position> = args.get("position")?;
                let abs: Option<Position> = args.get("abs")?;
                let rel: Option<Position> = args.get("rel")?;
                let speed: Option<SpeedPercent> = args.get("speed")?;
                let accel: Option<RampMs> = args.get("accel")?;
                let binary = args.flag("binary")?;
                let timeout = match args.get::<TimeLimit>("timeout_s")? {
                    Some(t) => t,
                    None => TimeLimit::from_secs(MOVE_TIMEOUT_S).map_err(|e| ErrorReport::usage(e.to_string()))?,
                };
                let min_pos: Option<Position> = args.get("min_pos")?;
                let max_pos: Option<Position> = args.get("max_pos")?;
                args.finish()?;
                if position.is_some() && abs.is_some() {
                    return Err(ErrorReport::usage("move: give position or abs, not both"));
                }
                let target = MoveTarget::from_args(position.or(abs), rel).map_err(ErrorReport::usage)?;
                let limits = TravelLimits::new(min_pos, max_pos)
                    .map_err(|e| ErrorReport::usage(format!("move min_pos / max_pos: {e}")))?;
                let request = MoveRequest { target, speed, accel, binary, limits, timeout: Some(timeout.duration()) };
                Ok(Action::Motion(Box::pin(async move {
                    let report = client.move_to(drive, &request).await.map_err(failed)?;
                    me.result(&report)
                })))
            }
            "stop" => {
                args.finish()?;
                Ok(Action::Stop(Box::pin(async move {
                    let stop = client.stop_confirmed(drive).await.map_err(failed)?;
                    me.result(&StopResult::new(None::<String>, stop))
                })))
            }
            "status" => {
                // Without "values", the overview (an empty list is refused by `list`).
                let mut ids: Vec<StatusId> = args.list("values")?;
                args.finish()?;
                if ids.is_empty() {
                    ids = StatusId::OVERVIEW.to_vec();
                }
                Ok(Action::Other(Box::pin(async move {
                    me.result(&StatusReport::from(client.read_statuses(drive, &ids).await.map_err(failed)?))
                })))
            }
            "get" => {
                // One parameter (its object), or several (a list of their objects, as the command line
                // prints one per line); every name is checked before anything is read.
                let (ids, list) = args.one_or_many_parsed("param", "params", str::parse::<ParamId>)?;
                args.finish()?;
                Ok(Action::Other(Box::pin(async move {
                    let mut read = Vec::new();
                    for id in ids {
                        let value = client.read_param(drive, id).await.map_err(failed)?;
                        read.push(me.result(&ParamReading { id, value })?);
                    }
                    super::one_or_listed(read, list)
                })))
            }
            "scan" => {
                args.finish()?;
                Ok(Action::Write(Box::pin(async move {
                    // Every drive on the bus (S1 of addresses 1..=31), as `compax scan --json` lists them;
                    // none at all is an error, as there.
                    let found = client.scan(1..=31).await.map_err(failed)?;
                    if found.is_empty() {
                        return Err(ErrorReport::transport(format!("no drive answered on {}", me.port)));
                    }
                    let listed = found
                        .into_iter()
                        .map(|d| identified("compax", &me.port, &[], &DrivePosition::from(d)))
                        .collect::<Result<_, _>>()?;
                    super::listed(listed)
                })))
            }
            "set" => {
                let id: ParamId = args.need("param")?;
                let text: String = args.need("value")?;
                args.finish()?;
                // The library's rule: a finite number within the parameter's known range.
                let write = ParamWrite::parse(id, &text).map_err(|e| ErrorReport::usage(format!("set value: {e}")))?;
                Ok(Action::Write(Box::pin(async move {
                    // Written and read back: a value that reads back otherwise is an error.
                    me.result(&client.set_param(drive, write.id(), write.value()).await.map_err(failed)?)
                })))
            }
            "output" => {
                let number: OutputNumber = args.need("number")?;
                let state: OutputState = args.need("state")?;
                args.finish()?;
                let state = state.for_output(number).map_err(|e| ErrorReport::usage(format!("output state: {e}")))?;
                let output = number.get();
                Ok(Action::Write(Box::pin(async move {
                    me.result(&client.switch_output(drive, output, state).await.map_err(failed)?)
                })))
            }
            other => Err(unknown_op("compax", other, &OPS)),
        }
    }

    /// One sample as `watch --json` prints it.
    pub(super) fn sample(&self, t_s: f64) -> Sampling {
        let me = self.clone();
        Box::pin(async move {
            let position = me.client.read_position(me.drive).await.map_err(failed)?;
            let s17 = me.client.read_s17(me.drive).await.map_err(failed)?;
            let previous = motionlink_link::clock::lock(&me.last_sample).replace(position);
            let tolerance = me.client.config().in_position_tolerance;
            let sample = WatchSample::after(previous, me.drive, position, s17, tolerance);
            Ok((me.result(&Timed { t_s, sample })?, sample.moving()))
        })
    }

    /// Ends the session (what still moves is stopped).
    pub(super) async fn close(self) -> Result<(), String> {
        super::close_client(self.client, |c| c.close()).await
    }
}

/// Checks the device's default `key` (an option of actions, [`super::keys::COMPAX`]) by its argument's rule.
pub(super) fn check_default(key: &str, text: &str) -> Result<(), String> {
    match key {
        "speed" => super::parses::<SpeedPercent>(text),
        "accel" => super::parses::<RampMs>(text),
        "binary" => super::flag(text),
        "timeout_s" => super::parses::<TimeLimit>(text),
        "min_pos" | "max_pos" => super::parses::<Position>(text),
        other => Err(format!("{other} is no option of an action")),
    }
}

/// Checks the device's defaults together: `min_pos` below `max_pos`, as a move checks them.
pub(super) fn check_defaults(defaults: &serde_json::Map<String, Value>) -> Result<(), String> {
    let limit = |key: &str| -> Option<Position> {
        let text = match defaults.get(key)? {
            Value::String(s) => s.clone(),
            other => other.to_string(),
        };
        text.parse().ok()
    };
    TravelLimits::new(limit("min_pos"), limit("max_pos")).map(drop).map_err(|e| format!("min_pos / max_pos: {e}"))
}
