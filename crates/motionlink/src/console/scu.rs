//! The console over an SCU control unit: its connected actuators, moves through the remote position, jogs as
//! a run of the actuator's motion function in or out (RS when the future is dropped), the data list.

use motionlink_link::error::{ErrorClass, TransportKind};
use std::sync::Arc;

use motionlink_link::url::PortUrl;
use motionlink_link::SharedClock;
use motionlink_scu::args::{parse_write, Checked};
use motionlink_scu::describe::Describer;
use motionlink_scu::model::{
    Actuator, DataEntry, DataIndex, Function, Item, MotionDirection, MotionFunction, PositionCounts, Speed, SpeedMode,
    StopMode, TABLE,
};
use motionlink_scu::results::{ErrorHistory, RunOutcome, StopResult};
use motionlink_scu::session::RunAction;
use motionlink_scu::value::Value as ScuValue;
use motionlink_scu::{AsyncClient, FunctionMap};

use super::device::{
    close_last, finite, report, Action, BoxFuture, Device, ErrorReport, JogDirection, Motion, Naming, Param, Report,
    Sample, Unit,
};
use super::traffic::Traffic;
use super::ServeArgs;
use crate::common::CliError;
use crate::tap::Tap;

/// `motionlink console scu` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device (/dev/ttyUSB0, COM3), tcp://HOST:PORT (a serial gateway or `motionlink sim
    /// scu`), or sim (an emulator in this process). Default: --device, else MOTIONLINK_PORT.
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    #[command(flatten)]
    pub device: super::DeviceArg,
    #[command(flatten)]
    pub unit: crate::scu::UnitArgs,
    #[command(flatten)]
    pub serve: ServeArgs,
}

struct Scu {
    client: AsyncClient,
    port: String,
    functions: FunctionMap,
    speed_mode: SpeedMode,
}

/// Opens the session `args` ask for, its link tapped into the traffic log.
pub async fn open(args: &Args, port: &str, clock: &SharedClock) -> Result<(Arc<dyn Device>, Arc<Traffic>), CliError> {
    // The session's settings and the emulated unit by the rules of `motionlink scu` (its options).
    let config = crate::scu::client_config(&args.unit)?;
    let (functions, speed_mode) = (config.function_map, config.speed_mode);
    let url: PortUrl = port.parse()?;
    let traffic = Arc::new(Traffic::new(Box::new(Describer::new()), &format!("scu {port}"), "can0", clock));
    let unit = crate::scu::in_process(&args.unit, &url)?;
    let tap = Tap::into_sink(port, Arc::clone(&traffic) as _);
    let connector = crate::scu::connector(&url, &unit, args.unit.baud, &tap, clock)?;
    let client = AsyncClient::with_connector(connector, Arc::clone(clock), config)
        .await
        .map_err(|e| crate::common::classified(&e))?;
    // The device profile of the unit (`motionlink probe scu --save`), where one names the port.
    if let Some(profiles) = super::profiles() {
        super::note_profile(motionlink_scu::probe::use_profile_async(&client, &profiles, port).await);
    }
    let device = Scu { client, port: port.to_string(), functions, speed_mode };
    Ok((Arc::new(device), traffic))
}

fn actuator(n: u8) -> Result<Actuator, ErrorReport> {
    Actuator::checked(i64::from(n)).map_err(|e| ErrorReport::usage(format!("actuator {n}: {e}")))
}

/// The numbers of a group read (`AsyncClient::get`), decoded by the data list (currents in A), by actuator
/// number (an entry 0x00F3 is actuator 3's).
fn by_actuator(group: &[(&'static DataEntry, ScuValue)]) -> [Option<f64>; 6] {
    let mut out = [None; 6];
    for (entry, value) in group {
        let n = (entry.id & 0x0F) as usize;
        if (1..=6).contains(&n) {
            out[n - 1] = value.as_f64();
        }
    }
    out
}

impl Scu {
    /// The motion function that moves actuator `a` alone: the one the map says drives only it, else Fn.
    fn function_of(&self, a: Actuator) -> Result<MotionFunction, ErrorReport> {
        for n in 1..=10 {
            let Some(f) = MotionFunction::new(n) else { continue };
            if self.functions.drives(f).is_some_and(|d| d == [a]) {
                return Ok(f);
            }
        }
        MotionFunction::new(a.number()).ok_or_else(|| ErrorReport::usage(format!("{a} has no motion function")))
    }

    fn speed(&self, speed: Option<f64>) -> Result<Option<Speed>, ErrorReport> {
        let Some(s) = speed else { return Ok(None) };
        let s = finite("speed", s)?;
        // The page sends numbers: the rule is the library's, for the whole numbers it takes.
        Speed::parse(&s.to_string(), self.speed_mode)
            .map(Some)
            .map_err(|e| ErrorReport::usage(format!("speed {s}: {e}")))
    }

    fn speed_key(&self) -> (&'static str, &'static str) {
        match self.speed_mode {
            SpeedMode::Percent => ("speed_percent", "%"),
            SpeedMode::CountsPerSecond => ("speed_counts_per_s", "counts/s"),
        }
    }
}

/// The data list's name of the remote speed of function `f` (`remote_speed_f1`), which a jog with no speed
/// leaves as it is.
fn remote_speed_name(f: MotionFunction) -> String {
    let index = f.remote_speed_index();
    motionlink_scu::model::entry(index)
        .map_or_else(|| format!("remote speed of {f} ({index:?})"), |e| e.name.to_string())
}

fn lookup_entry(name: &str) -> Result<Item, ErrorReport> {
    motionlink_scu::model::find(name).map_err(ErrorReport::usage)
}

impl Device for Scu {
    fn naming(&self) -> Naming {
        // The numbers `Actuator::new` takes.
        Naming { family: "scu", unit_key: "actuator", unit_numbers: 1..=6 }
    }

    fn port(&self) -> String {
        self.port.clone()
    }

    fn discover(&self) -> BoxFuture<'_, Result<Vec<Unit>, ErrorReport>> {
        Box::pin(async move {
            let found = self.client.connected_actuators().await?;
            let mut units = Vec::new();
            for a in found {
                let f = self.function_of(a)?;
                units.push(Unit {
                    id: a.number(),
                    label: format!("A{}", a.number()),
                    detail: format!("moved and jogged with {f}"),
                    position_key: motionlink_scu::results::LOOK_KEYS.0,
                    target_key: "target_counts",
                    position_unit: "counts",
                    speed_key: motionlink_scu::results::LOOK_KEYS.1,
                    speed_unit: "%",
                    command_speed_key: self.speed_key().0,
                    command_speed_unit: self.speed_key().1,
                    current_key: Some("current_amps"),
                    // As `move_to` and `jog` do with no speed.
                    move_speed_when_empty: Speed::default_for(self.speed_mode).to_string(),
                    jog_speed_when_empty: format!("the unit's {} as it is", remote_speed_name(f)),
                });
            }
            Ok(units)
        })
    }

    fn sample<'a>(&'a self, units: &'a [Unit]) -> BoxFuture<'a, Vec<Result<Sample, ErrorReport>>> {
        Box::pin(async move {
            // Four reads of groups cover every actuator at once, each decoded by the library.
            let read = async {
                let positions = self.client.positions().await?;
                let status = self.client.statuses().await?;
                let speeds = by_actuator(&self.client.get(DataIndex(0x00F0)).await?);
                let currents = by_actuator(&self.client.get(DataIndex(0x00A0)).await?);
                Ok::<_, motionlink_scu::Error>((positions, status, speeds, currents))
            };
            match read.await {
                Err(e) => units.iter().map(|_| Err(ErrorReport::from(e.clone()))).collect(),
                Ok((positions, status, speeds, currents)) => units
                    .iter()
                    .map(|u| {
                        let i = usize::from(u.id.saturating_sub(1)).min(5);
                        Ok(motionlink_scu::results::axis_look(positions[i], status[i], speeds[i], currents[i]))
                    })
                    .collect(),
            }
        })
    }

    fn move_to(self: Arc<Self>, unit: u8, target: f64, speed: Option<f64>) -> Result<Motion, ErrorReport> {
        let a = actuator(unit)?;
        let target = finite("target", target)?;
        let position = PositionCounts::parse_whole(&target.to_string())
            .map_err(|e| ErrorReport::usage(format!("target {target}: {e}")))?;
        // No speed given: the default of every front end (the command line's `--speed 100`), not the maximum.
        let speed = self.speed(speed)?.unwrap_or(Speed::default_for(self.speed_mode));
        let function = self.function_of(a)?;
        let op = self.client.move_to_op(a, position, speed, Some(function))?;
        Ok(Box::pin(async move {
            match self.client.start(op).await? {
                motionlink_scu::Output::Move(r) => Ok(report(&r)),
                other => Err(ErrorReport::classed(
                    ErrorClass::Transport(TransportKind::Corrupt),
                    format!("a move ended with {other:?}"),
                )),
            }
        }))
    }

    fn jog(self: Arc<Self>, unit: u8, direction: JogDirection, speed: Option<f64>) -> Result<Motion, ErrorReport> {
        let a = actuator(unit)?;
        let speed = self.speed(speed)?;
        let function = self.function_of(a)?;
        let dir = match direction {
            JogDirection::Positive => MotionDirection::Out,
            JogDirection::Negative => MotionDirection::In,
        };
        Ok(Box::pin(async move {
            let mut speed_unverified = Vec::new();
            if let Some(s) = speed {
                let raw = s.for_motion(self.speed_mode).map_err(ErrorReport::usage)?;
                let set = self.client.set(function.remote_speed_index(), &ScuValue::RemoteSpeed(raw)).await?;
                // A speed the unit did not read back is said with the jog's result, not dropped.
                speed_unverified = set.not_verifiable.into_iter().map(|w| format!("the jog's speed: {w}")).collect();
            }
            // Runs until the unit reports the end of travel; dropped, the session sends RS (fast) and checks it.
            let r = self.client.run_function(RunAction::Motion(function, dir), None).await?;
            let mut outcome = RunOutcome::from(&r);
            if !speed_unverified.is_empty() {
                outcome.verified = false;
                outcome.not_verifiable.extend(speed_unverified);
            }
            Ok(report(&outcome))
        }))
    }

    fn stop(self: Arc<Self>, unit: u8) -> Motion {
        Box::pin(async move {
            let a = actuator(unit)?;
            let f = self.function_of(a)?;
            // As `motionlink scu stop F`: RS, then the status read until no actuator moves.
            let stopped = self.client.stop_functions(&[f], StopMode::Fast).await?;
            Ok(report(&StopResult::new(None::<()>, Some(Function::Motion(f)), stopped)))
        })
    }

    fn stop_started(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        Box::pin(async move {
            let started = self.client.started();
            let motions: Vec<MotionFunction> =
                started.iter().filter_map(|f| if let Function::Motion(m) = f { Some(*m) } else { None }).collect();
            if motions.is_empty() {
                return Ok(String::new());
            }
            // As `motionlink scu stop`: RS, confirmed by the status; said as it says it.
            let stopped = self.client.stop_functions(&motions, StopMode::Fast).await?;
            let mut text = Vec::new();
            crate::scu::print_stop_text(&mut text, &stopped)
                .map_err(|e| ErrorReport::classed(ErrorClass::Transport(TransportKind::Io), e.to_string()))?;
            Ok(String::from_utf8_lossy(&text).trim_end().to_string())
        })
    }

    fn actions(&self) -> Vec<Action> {
        Vec::new()
    }

    fn action(self: Arc<Self>, _unit: u8, name: &str) -> Result<Motion, ErrorReport> {
        Err(ErrorReport::usage(format!("the SCU console has no action {name:?}")))
    }

    fn params(&self) -> Vec<Param> {
        Param::rows(&TABLE)
    }

    fn read_param(self: Arc<Self>, _unit: u8, name: String) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move { Ok(report(&self.client.read(lookup_entry(&name)?).await?)) })
    }

    fn write_param(
        self: Arc<Self>,
        _unit: u8,
        name: String,
        value: String,
    ) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move {
            let (e, v) = parse_write(lookup_entry(&name)?, &value).map_err(ErrorReport::usage)?;
            // The library writes with RT, reads the entry back and compares (a difference is an error), then
            // reads what the unit holds; a unit that does not read remote data back says so in the report.
            Ok(report(&self.client.write(e, v).await?))
        })
    }

    fn errors(self: Arc<Self>, _unit: u8) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move { Ok(report(&ErrorHistory { errors: self.client.error_history().await? })) })
    }

    fn close(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        // While a request still holds the session, it ends (RS, RA) when that ends.
        close_last(self, |me| async move {
            match motionlink_scu::ending(me.client.close().await) {
                motionlink_scu::Ending::Clean => Ok(String::new()),
                motionlink_scu::Ending::Stopped(note) => Ok(note),
                motionlink_scu::Ending::Failed(e) | motionlink_scu::Ending::Unconfirmed(e) => Err(e.into()),
            }
        })
    }
}
