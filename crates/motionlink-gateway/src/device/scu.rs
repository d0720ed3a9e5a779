//! An SCU unit on the gateway: `move`, `run`, `stop`, `info`, `errors`, `get`, `set` and the state samples,
//! as the command line's `motionlink scu` does them, on [`AsyncClient`].

use std::sync::Arc;

use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::profile::Profiles;
use motionlink_link::url::PortUrl;
use motionlink_link::RealClock;
use motionlink_scu::args::{Checked, RunLimit, UnitOptions};
use motionlink_scu::model::{find, Actuator, Function, Item, MotionFunction, PositionCounts, Speed, StopMode};
use motionlink_scu::results::{ErrorHistory, RunOutcome, SampleReport, StopResult, StopScope, SwitchedOff};
use motionlink_scu::session::RunAction;
use motionlink_scu::{AsyncClient, Emulator, SimConfig};

use serde_json::Value;

use super::{failed, identified, unknown_op, Action, Outcome, Sampling};
use crate::args::Args;
use crate::error::ErrorReport;

/// The actions served.
const OPS: [&str; 7] = ["move", "run", "stop", "info", "errors", "get", "set"];

/// A session with one unit.
#[derive(Clone)]
pub(super) struct Scu {
    client: Arc<AsyncClient>,
    port: String,
    /// The device profile the session took (null: none).
    profile: Value,
}

impl Scu {
    /// Opens the unit on `port` (`sim`: the emulated unit `sim_config` describes, else the one the options
    /// name).
    pub(super) async fn open(
        options: &UnitOptions,
        sim_config: Option<SimConfig>,
        port: &str,
        profiles: Option<&Profiles>,
        name: &str,
    ) -> Result<Scu, ErrorReport> {
        let config = options.config().map_err(|e| ErrorReport::usage(e.to_string()))?;
        let url: PortUrl = port.parse().map_err(|e| ErrorReport::usage(format!("port {port:?}: {e}")))?;
        let clock = RealClock::shared();
        let client = match url {
            PortUrl::Sim => {
                let unit = match sim_config {
                    Some(unit) => unit,
                    None => options.emulated().map_err(|e| ErrorReport::usage(e.to_string()))?,
                };
                let sim = Emulator::new(unit).map_err(|e| ErrorReport::usage(e.to_string()))?;
                let host = EmulatorHost::new(sim, Arc::clone(&clock), PipeConfig::paced(options.baud.get()));
                AsyncClient::with_connector(host.connector(), clock, config).await
            }
            url => AsyncClient::open(&url, clock, config).await,
        }
        .map_err(failed)?;
        // The unit's device profile, where the profiles name the port (two RG), as every command takes it.
        let profile = match profiles {
            Some(p) => super::took_profile(name, motionlink_scu::probe::use_profile_async(&client, p, port).await),
            None => Value::Null,
        };
        Ok(Scu { client: Arc::new(client), port: port.to_string(), profile })
    }

    fn result(&self, report: &impl serde::Serialize) -> Outcome {
        identified("scu", &self.port, &[("profile", self.profile.clone())], report)
    }

    /// The action `op`, its arguments checked by the library's types.
    pub(super) fn action(&self, op: &str, mut args: Args) -> Result<Action, ErrorReport> {
        let me = self.clone();
        let client = Arc::clone(&self.client);
        match op {
            "move" => {
                let actuator: Actuator = args.need("actuator")?;
                let position: PositionCounts = args.need("position")?;
                let mode = client.config().speed_mode;
                let speed = match args.text("speed")? {
                    Some(speed) => Speed::parse(&speed, mode)
                        .map_err(|e| ErrorReport::usage(format!("move speed {speed:?}: {e}")))?,
                    None => Speed::default_for(mode),
                };
                let function = match args.get::<MotionFunction>("function")? {
                    Some(f) => f,
                    None => MotionFunction::checked(i64::from(actuator.number()))
                        .map_err(|e| ErrorReport::usage(e.to_string()))?,
                };
                args.finish()?;
                Ok(Action::Motion(Box::pin(async move {
                    let report = client.move_to(actuator, position, speed, Some(function)).await.map_err(failed)?;
                    me.result(&report)
                })))
            }
            "run" => {
                let function: String = args.need("function")?;
                let direction: String = args.need("direction")?;
                let seconds: Option<RunLimit> = args.get("seconds")?;
                args.finish()?;
                let action =
                    RunAction::parse(&function, &direction).map_err(|e| ErrorReport::usage(format!("run: {e}")))?;
                Ok(Action::Motion(Box::pin(async move {
                    // To its end of travel (or `seconds`); dropped, the library stops the function (RS).
                    let report = client.run_function(action, seconds.map(RunLimit::get)).await;
                    me.result(&RunOutcome::of(report).map_err(failed)?)
                })))
            }
            "stop" => {
                let function: Option<Function> = args.get("function")?;
                let soft = args.flag("soft")?;
                args.finish()?;
                Ok(Action::Stop(Box::pin(async move {
                    match StopScope::of(function) {
                        StopScope::Motions(motions) => {
                            let mode = if soft { StopMode::Soft } else { StopMode::Fast };
                            let report = client.stop_functions(&motions, mode).await.map_err(failed)?;
                            me.result(&StopResult::new(None::<String>, function, report))
                        }
                        StopScope::Switch(f) => {
                            let switched = client.switch(f, false).await.map_err(failed)?;
                            me.result(&StopResult::new(None::<String>, function, SwitchedOff::from(switched)))
                        }
                    }
                })))
            }
            "info" => {
                args.finish()?;
                Ok(Action::Other(Box::pin(async move { me.result(&client.info().await.map_err(failed)?) })))
            }
            "errors" => {
                args.finish()?;
                Ok(Action::Other(Box::pin(async move {
                    me.result(&ErrorHistory { errors: client.error_history().await.map_err(failed)? })
                })))
            }
            "get" => {
                // One item (its object), or several (a list of their objects, as the command line prints
                // one per line); every name is checked before anything is read.
                let (items, list) = args.one_or_many_parsed("item", "items", find)?;
                args.finish()?;
                Ok(Action::Other(Box::pin(async move {
                    let mut read = Vec::new();
                    for item in items {
                        read.push(me.result(&client.read(item).await.map_err(failed)?)?);
                    }
                    super::one_or_listed(read, list)
                })))
            }
            "set" => {
                let item = item(&mut args)?;
                let value =
                    args.text("value")?.ok_or_else(|| ErrorReport::usage("set: the argument \"value\" is missing"))?;
                args.finish()?;
                let (entry, value) = motionlink_scu::args::parse_write(item, &value)
                    .map_err(|e| ErrorReport::usage(format!("set: {e}")))?;
                Ok(Action::Write(Box::pin(
                    async move { me.result(&client.write(entry, value).await.map_err(failed)?) },
                )))
            }
            other => Err(unknown_op("scu", other, &OPS)),
        }
    }

    /// One sample as `watch --json` prints it.
    pub(super) fn sample(&self, t_s: f64) -> Sampling {
        let me = self.clone();
        Box::pin(async move {
            let snapshot = me.client.sample().await.map_err(failed)?;
            let report = SampleReport::new(&snapshot, t_s);
            let moving = report.actuators.iter().any(|a| a.status.moving());
            Ok((me.result(&report)?, moving))
        })
    }

    /// Ends the session (RS for every started function, then RA).
    pub(super) async fn close(self) -> Result<(), String> {
        super::close_client(self.client, |c| c.close()).await
    }
}

/// The data-list entry or group `item` of `get` / `set`, by name or index (the library's rule and message).
fn item(args: &mut Args) -> Result<Item, ErrorReport> {
    let text = args.text("item")?.ok_or_else(|| ErrorReport::usage("the argument \"item\" is missing"))?;
    find(&text).map_err(|e| ErrorReport::usage(format!("item: {e}")))
}

/// Checks the device's default `key` (an option of actions, [`super::keys::SCU`]) by its argument's rule.
pub(super) fn check_default(options: &UnitOptions, key: &str, text: &str) -> Result<(), String> {
    match key {
        "speed" => Speed::parse(text, options.speed_mode).map(drop).map_err(|e| e.to_string()),
        "function" => super::parses::<MotionFunction>(text),
        "soft" => super::flag(text),
        "seconds" => super::parses::<RunLimit>(text),
        other => Err(format!("{other} is no option of an action")),
    }
}

/// The emulated unit of `sim_config = FILE` (`port = "sim"` only), as the command line's `--sim-config`
/// reads it: `sim_preset` is its starting point where the file names no preset of its own, and the
/// `sim_variants` are added to the file's.
pub(super) fn sim_config(options: &UnitOptions, sim: bool, path: &str) -> Result<SimConfig, String> {
    if !sim {
        return Err("sim_config is only for port sim".into());
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("sim_config: cannot read {path}: {e}"))?;
    SimConfig::from_toml_over(&text, options.sim_preset.as_deref(), &options.sim_variants)
        .map_err(|e| format!("sim_config: {path}: {e}"))
}
