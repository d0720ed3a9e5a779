//! A PowerCube module on the gateway: `move`, `motion`, `home`, `stop`, `reset`, `state`, `info`, `get`, `set`, `scan` and the state
//! samples, as the command line's `motionlink powercube` does them, on [`AsyncClient`].

use std::sync::Arc;

use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::profile::Profiles;
use motionlink_link::url::PortUrl;
use motionlink_link::Link;
use motionlink_link::RealClock;
use motionlink_powercube::args::{ModuleOptions, MotionTimeout, MoveAcceleration, MoveVelocity, Target, Tolerance};
use motionlink_powercube::model::{Address, MotionId, Param, StateFlag, Value as ParamValue};
use motionlink_powercube::report::{Acted, ParamReading, Released, Sample, SetReport, StateReport, Timed};
use motionlink_powercube::session::{Guard, MotionSpec, MoveSpec};
use motionlink_powercube::{AsyncClient, Emulator};
use serde_json::Value;

use super::{failed, identified, unknown_op, Action, Outcome, Sampling};
use crate::args::Args;
use crate::error::{ErrorReport, GatewayErrors};

/// The actions served.
const OPS: [&str; 10] = ["move", "motion", "home", "stop", "reset", "state", "info", "get", "set", "scan"];

/// A session with one module.
#[derive(Clone)]
pub(super) struct PowerCube {
    client: Arc<AsyncClient>,
    module: Address,
    guard: Guard,
    port: String,
    /// The device profile the session took (null: none).
    profile: Value,
}

impl PowerCube {
    /// Opens the module's bus on `port` (`sim`: an emulated bus with the module the options name); the
    /// emulator's host comes with it.
    pub(super) async fn open(
        options: &ModuleOptions,
        port: &str,
        profiles: Option<&Profiles>,
        name: &str,
    ) -> Result<(PowerCube, Option<Box<dyn std::any::Any + Send>>), ErrorReport> {
        let url: PortUrl = port.parse().map_err(|e| ErrorReport::usage(format!("port {port:?}: {e}")))?;
        let clock = RealClock::shared();
        let in_process = matches!(url, PortUrl::Sim);
        let (client, host): (AsyncClient, Option<Box<dyn std::any::Any + Send>>) = if in_process {
            let bus = options.emulated().map_err(|e| ErrorReport::usage(e.to_string()))?;
            let host =
                EmulatorHost::new(Emulator::new(&bus), Arc::clone(&clock), PipeConfig::paced(options.baud.get()));
            let link: Box<dyn Link> = Box::new(host.connect().0);
            (AsyncClient::with_link(link, clock, options.config(false)).await.map_err(failed)?, Some(Box::new(host)))
        } else {
            (AsyncClient::open(&url, clock, options.config(url.is_can())).await.map_err(failed)?, None)
        };
        // The module's device profile, where the profiles name it (a few reads), as every command takes it.
        let profile = match profiles {
            Some(p) => super::took_profile(
                name,
                motionlink_powercube::probe::use_profile_async(&client, p, port, options.module).await,
            ),
            None => Value::Null,
        };
        let me = PowerCube {
            client: Arc::new(client),
            module: options.module,
            guard: options.guard(in_process),
            port: port.to_string(),
            profile,
        };
        Ok((me, host))
    }

    fn result(&self, report: &impl serde::Serialize) -> Outcome {
        let identity = [("profile", self.profile.clone()), ("module", Value::from(self.module.get()))];
        identified("powercube", &self.port, &identity, report)
    }

    /// The action `op`, its arguments checked by the library's types.
    pub(super) fn action(&self, op: &str, mut args: Args) -> Result<Action, ErrorReport> {
        let me = self.clone();
        let (client, module, guard) = (Arc::clone(&self.client), self.module, self.guard);
        match op {
            "move" => {
                let target: Target = args.need("position")?;
                let vel: Option<MoveVelocity> = args.get("vel")?;
                let acc: Option<MoveAcceleration> = args.get("acc")?;
                let timeout = args.get::<MotionTimeout>("timeout_s")?.unwrap_or(MotionTimeout::DEFAULT);
                let tolerance = args.get::<Tolerance>("tolerance")?.unwrap_or(Tolerance::DEFAULT);
                args.finish()?;
                let spec = MoveSpec::from_args(target, vel, acc, tolerance, timeout);
                Ok(Action::Motion(Box::pin(async move {
                    let report = client.module(module).move_to_guarded(&spec, guard).await.map_err(failed)?;
                    me.result(&Acted::reached(report))
                })))
            }
            "motion" => {
                // The command line's `powercube motion MODE VALUE`, checked by the same rules.
                let mode: MotionId = args.need("mode")?;
                let value: f64 = args.need("value")?;
                let time_ms: Option<u16> = args.get("time_ms")?;
                let hold: Option<MotionTimeout> = args.get("for_s")?;
                let tolerance: Option<Tolerance> = args.get("tolerance")?;
                let timeout = args.get::<MotionTimeout>("timeout_s")?.unwrap_or(MotionTimeout::DEFAULT);
                args.finish()?;
                let spec = MotionSpec::from_args(mode, value, time_ms, hold, tolerance, timeout).map_err(failed)?;
                Ok(Action::Motion(Box::pin(async move {
                    let report = client.module(module).run_motion_guarded(&spec, guard).await.map_err(failed)?;
                    me.result(&Acted::ran(report))
                })))
            }
            "home" => {
                let timeout = args.get::<MotionTimeout>("timeout_s")?.unwrap_or(MotionTimeout::DEFAULT);
                args.finish()?;
                Ok(Action::Motion(Box::pin(async move {
                    let report = client.module(module).home_guarded(timeout.get(), guard).await.map_err(failed)?;
                    me.result(&Acted::homed(report))
                })))
            }
            "stop" => {
                args.finish()?;
                Ok(Action::Stop(Box::pin(async move {
                    let halted = client.module(module).halt_confirmed().await.map_err(failed)?;
                    me.result(&Acted::halted(halted, None::<String>))
                })))
            }
            "reset" => {
                args.finish()?;
                Ok(Action::Other(Box::pin(async move {
                    let released = client.module(module).reset_and_release_watchdog().await.map_err(failed)?;
                    me.result(&Acted::reset(Released { watchdog_released: released }))
                })))
            }
            "state" | "info" => {
                args.finish()?;
                let info = op == "info";
                Ok(Action::Other(Box::pin(async move {
                    let m = client.module(module);
                    match info {
                        true => me.result(&m.details().await.map_err(failed)?),
                        false => me.result(&StateReport(m.state().await.map_err(failed)?)),
                    }
                })))
            }
            "get" => {
                // One parameter (its object), or several (a list of their objects, as the command line
                // prints one per line); every name is checked before anything is read.
                let (params, list) = args.one_or_many_parsed("param", "params", str::parse::<Param>)?;
                args.finish()?;
                Ok(Action::Other(Box::pin(async move {
                    let m = client.module(module);
                    let mut read = Vec::new();
                    for param in params {
                        let value = m.get(param).await.map_err(failed)?;
                        // The unit depends on the module type (rad or m): no guessing when it cannot be read.
                        let kind = m.kind().await.map_err(failed)?;
                        read.push(me.result(&ParamReading { param, kind, value })?);
                    }
                    super::one_or_listed(read, list)
                })))
            }
            "scan" => {
                args.finish()?;
                Ok(Action::Write(Box::pin(async move {
                    // Every module on the bus, as `powercube scan --json` lists them (no module of the
                    // device's own: each object names its address); none at all is an error, as there.
                    let found = client.scan().await.map_err(failed)?;
                    if found.is_empty() {
                        return Err(ErrorReport::transport(format!("no module answered on {}", me.port)));
                    }
                    let listed =
                        found.iter().map(|e| identified("powercube", &me.port, &[], e)).collect::<Result<_, _>>()?;
                    super::listed(listed)
                })))
            }
            "set" => {
                let param: Param = args.need("param")?;
                let text: String = args.need("value")?;
                args.finish()?;
                let value = ParamValue::parse(param, &text)
                    .map_err(|e| ErrorReport::usage(format!("set value {text:?}: {e}")))?;
                Ok(Action::Write(Box::pin(async move {
                    // Targets beyond their limits are refused; what was written is read back where it can be.
                    let readback = client.module(module).set_checked(param, value).await.map_err(failed)?;
                    me.result(&SetReport { param, value, readback })
                })))
            }
            other => Err(unknown_op("powercube", other, &OPS)),
        }
    }

    /// One sample as `watch --json` prints it.
    pub(super) fn sample(&self, t_s: f64) -> Sampling {
        let me = self.clone();
        Box::pin(async move {
            let m = me.client.module(me.module);
            let kind = m.kind().await.map_err(failed)?;
            let state = m.state().await.map_err(failed)?;
            let position = m.position().await.map_err(failed)?;
            let moving = state.contains(StateFlag::Motion);
            Ok((me.result(&Timed { t_s, sample: Sample { kind, position, state } })?, moving))
        })
    }

    /// Ends the session (what still moves is halted, the watchdog switched off).
    pub(super) async fn close(self) -> Result<(), String> {
        super::close_client(self.client, |c| c.close()).await
    }
}

/// Checks the device's default `key` (an option of actions, [`super::keys::POWERCUBE`]) by its argument's
/// rule.
pub(super) fn check_default(key: &str, text: &str) -> Result<(), String> {
    match key {
        "vel" => super::parses::<MoveVelocity>(text),
        "acc" => super::parses::<MoveAcceleration>(text),
        "tolerance" => super::parses::<Tolerance>(text),
        "timeout_s" => super::parses::<MotionTimeout>(text),
        other => Err(format!("{other} is no option of an action")),
    }
}
