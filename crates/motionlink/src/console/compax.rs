//! The console over a bus of COMPAX drives: found by a scan (S1 of 1..31), moved by checked moves (dropped:
//! the drive is stopped with `OUTPUT O0=0`, confirmed by S17), jogged as a checked move towards the end of
//! the jog range that is stopped when the jog ends, switched on again, and their parameters.
//!
//! The drives report no speed and no current over RS485: the speed shown is the change of S1 between two
//! samples (units/s), and no current is shown.

use motionlink_link::error::{ErrorClass, TransportKind};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_compax::client::{MoveRequest, MoveTarget, TravelLimits};
use motionlink_compax::model::{
    OutputState, ParamId, PollInterval, Position, S16Bits, S17Bits, S17Flag, SpeedPercent, StatusId, StatusValue,
    Tolerance, WholeArg, PARAMS,
};
use motionlink_compax::report::{ErrorHistory, ParamReading, StopResult};
use motionlink_compax::session::WatchSample;
use motionlink_compax::wire::Address;
use motionlink_compax::AsyncClient;
use motionlink_compax::DriveOptions;
use motionlink_link::clock::{lock, SharedClock, Timestamp};
use motionlink_link::url::PortUrl;

use super::device::{
    close_last, report, Action, BoxFuture, Device, ErrorReport, JogDirection, Motion, Naming, Param, Report, Sample,
    Unit,
};
use super::traffic::Traffic;
use super::ServeArgs;
use crate::common::CliError;
use crate::tap::Tap;

/// `motionlink console compax` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device (/dev/ttyUSB0, COM3), tcp://HOST:PORT (a serial gateway or `motionlink sim
    /// compax`), or sim (an emulated drive in this process). Default: --device, else MOTIONLINK_PORT.
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    #[command(flatten)]
    pub device: super::DeviceArg,
    /// Only these drive addresses (such as 1,5) instead of a scan of 1..31; with `--port sim`, the drives
    /// the emulated bus has (default: 1).
    #[arg(long, value_delimiter = ',')]
    pub drives: Vec<Address>,
    #[command(flatten)]
    pub line: crate::compax::LineArgs,
    /// Refuse move targets below this position (drive's unit); a jog in the negative direction ends here.
    #[arg(long, allow_negative_numbers = true)]
    pub min_pos: Option<Position>,
    /// Refuse move targets above this position (drive's unit); a jog in the positive direction ends here.
    #[arg(long, allow_negative_numbers = true)]
    pub max_pos: Option<Position>,
    /// Without --min-pos / --max-pos, how far one jog may go at most from where it starts (drive's unit).
    #[arg(long, default_value_t = 1000.0)]
    pub jog_range: f64,
    /// How close to its target a move must come to rest to succeed, in the drive's unit (default 0.01), as
    /// `compax move --tolerance` (a device's `tolerance` key).
    #[arg(long)]
    pub tolerance: Option<Tolerance>,
    /// Interval of the status polls while a move is waited for, in ms (1..=10000; default 50), as `compax
    /// move --poll-ms` (a device's `poll_ms` key).
    #[arg(long)]
    pub poll_ms: Option<PollInterval>,
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// S16 and S17 (state flags) are read every this many samples (and at once when S1 says the axis started or
/// stopped moving); S1 (the position) every sample. A sample of one drive then costs about 30 bytes on the
/// line on average (S1: 18, S16 and S17: 23 each) instead of 64: 9600 baud (960 bytes/s) carries about 32
/// of them a second, above the page's 20 Hz (all three every time: 15 a second).
const FLAGS_EVERY: u64 = 4;

struct Compax {
    client: AsyncClient,
    port: String,
    drives: Vec<Address>,
    limits: TravelLimits,
    jog_range: f64,
    /// The last position of each drive and when it was read, for the speed shown.
    last: Mutex<HashMap<u8, (Timestamp, Position)>>,
    /// The last S16 and S17 of each drive.
    flags: Mutex<HashMap<u8, (S16Bits, S17Bits)>>,
    /// The number of samples taken, for reading S16 and S17 every [`FLAGS_EVERY`]-th time.
    turn: std::sync::atomic::AtomicU64,
    clock: SharedClock,
}

/// Opens the session `args` ask for, its link tapped into the traffic log.
pub async fn open(args: &Args, port: &str, clock: &SharedClock) -> Result<(Arc<dyn Device>, Arc<Traffic>), CliError> {
    let mode = args.line.mode;
    let limits = TravelLimits::new(args.min_pos, args.max_pos).map_err(CliError::usage)?;
    if !(args.jog_range.is_finite() && args.jog_range > 0.0) {
        return Err(CliError::usage(format!("--jog-range {}: give a distance above 0", args.jog_range)));
    }
    let url: PortUrl = port.parse()?;
    let traffic = Arc::new(Traffic::new(
        Box::new(motionlink_compax::describe::Describer::new(mode)),
        &format!("compax {port}"),
        "can0",
        clock,
    ));
    let tap = Tap::into_sink(port, Arc::clone(&traffic) as _);
    let sim_drives: Vec<u8> =
        if args.drives.is_empty() { vec![1] } else { args.drives.iter().map(|a| a.get()).collect() };
    // The session's settings and its link by the rules of `motionlink compax` (its options); the drives are
    // the console's own (`--drives`). Opening a serial device blocks: on the blocking pool.
    let options =
        DriveOptions { tolerance: args.tolerance, poll_ms: args.poll_ms, ..crate::compax::line_options(&args.line) };
    let (o, c) = (options.clone(), Arc::clone(clock));
    let link = tokio::task::spawn_blocking(move || crate::compax::link(&o, url, &sim_drives, &tap, &c))
        .await
        .map_err(|e| CliError::transport(format!("the opening task failed: {e}")))??;
    let client = AsyncClient::with_link(link, Arc::clone(clock), options.config())
        .await
        .map_err(|e| crate::common::classified(&e))?;
    // The device profile of each drive (`motionlink probe compax --save`), where one names the port.
    if let Some(profiles) = super::profiles() {
        let drives = match args.drives.is_empty() {
            true => vec![Address::new(1).map_err(CliError::usage)?],
            false => args.drives.clone(),
        };
        for drive in drives {
            super::note_profile(motionlink_compax::probe::use_profile_async(&client, &profiles, port, drive).await);
        }
    }
    let device = Compax {
        client,
        port: port.to_string(),
        drives: args.drives.clone(),
        limits,
        jog_range: args.jog_range,
        last: Mutex::new(HashMap::new()),
        flags: Mutex::new(HashMap::new()),
        turn: std::sync::atomic::AtomicU64::new(0),
        clock: Arc::clone(clock),
    };
    Ok((Arc::new(device), traffic))
}

fn position(v: f64) -> Result<Position, ErrorReport> {
    Position::new(v).map_err(ErrorReport::usage)
}

fn address(n: u8) -> Result<Address, ErrorReport> {
    Address::from_whole(n.into()).map_err(ErrorReport::usage)
}

fn speed(v: Option<f64>) -> Result<Option<SpeedPercent>, ErrorReport> {
    v.map(SpeedPercent::new).transpose().map_err(ErrorReport::usage)
}

fn stop_text(report: motionlink_compax::client::StopReport) -> Result<String, ErrorReport> {
    let report = report.confirmed()?;
    Ok(if report.is_empty() { String::new() } else { report.to_string() })
}

impl Compax {
    fn unit(&self, n: u8, detail: String) -> Unit {
        Unit {
            id: n,
            label: format!("drive {n}"),
            detail,
            position_key: motionlink_compax::report::LOOK_KEYS.0,
            target_key: "target_units",
            position_unit: "units",
            speed_key: motionlink_compax::report::LOOK_KEYS.1,
            speed_unit: "units/s",
            command_speed_key: "speed_percent",
            command_speed_unit: "%",
            current_key: None,
            // A move or jog with no speed sends no SPEED (`MoveRequest::speed` None).
            move_speed_when_empty: "the drive's SPEED setting as it is".into(),
            jog_speed_when_empty: "the drive's SPEED setting as it is".into(),
        }
    }

    /// A checked move of drive `n` to `target`: limits checked before anything is sent, the target read
    /// back, the position at rest checked; dropped, the drive is stopped.
    fn checked_move(
        self: Arc<Self>,
        n: u8,
        target: Position,
        speed: Option<SpeedPercent>,
        timeout: Duration,
    ) -> Motion {
        Box::pin(async move {
            let a = address(n)?;
            let request = MoveRequest {
                speed,
                limits: self.limits,
                timeout: Some(timeout),
                ..MoveRequest::new(MoveTarget::Absolute(target))
            };
            Ok(report(&self.client.move_to(a, &request).await?))
        })
    }
}

impl Device for Compax {
    fn naming(&self) -> Naming {
        // The numbers `Address::drive` takes: below the broadcast address.
        Naming { family: "compax", unit_key: "drive", unit_numbers: 1..=motionlink_compax::wire::BROADCAST - 1 }
    }

    fn port(&self) -> String {
        self.port.clone()
    }

    fn discover(&self) -> BoxFuture<'_, Result<Vec<Unit>, ErrorReport>> {
        Box::pin(async move {
            let mut units = Vec::new();
            if self.drives.is_empty() {
                for (a, p) in self.client.scan(1..=31).await? {
                    units.push(self.unit(a.get(), format!("answered the scan at {:.3} units", p.units())));
                }
            } else {
                for &a in &self.drives {
                    match self.client.read_position(a).await {
                        Ok(p) => units.push(self.unit(a.get(), format!("at {:.3} units", p.units()))),
                        Err(e) if motionlink_link::error::Classify::class(&e).name() == "timeout" => continue,
                        Err(e) => return Err(e.into()),
                    }
                }
            }
            Ok(units)
        })
    }

    fn sample<'a>(&'a self, units: &'a [Unit]) -> BoxFuture<'a, Vec<Result<Sample, ErrorReport>>> {
        Box::pin(async move {
            let turn = self.turn.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let mut out = Vec::new();
            for u in units {
                let look = async {
                    let a = Address::drive(u.id).map_err(|e| ErrorReport::usage(e.to_string()))?;
                    let position = self.client.read_position(a).await?;
                    let p = position.units();
                    let at = self.clock.now();
                    let before = lock(&self.last).insert(u.id, (at, position));
                    let known = lock(&self.flags).get(&u.id).copied();
                    // S1 every time; S16 and S17 every FLAGS_EVERY-th sample, and at once when the position
                    // says the axis started or stopped moving and the flags do not say so yet.
                    let moved = before.is_some_and(|(_, p0)| p0.units() != p);
                    let (s16, s17) = match known {
                        Some((s16, s17))
                            if turn % FLAGS_EVERY != 0 && moved == s17.contains(S17Flag::CommandActive) =>
                        {
                            (s16, s17)
                        }
                        _ => {
                            let s16 = self.client.read_s16(a).await?;
                            let s17 = self.client.read_s17(a).await?;
                            lock(&self.flags).insert(u.id, (s16, s17));
                            (s16, s17)
                        }
                    };
                    Ok::<_, ErrorReport>((position, p, at, before, s16, s17))
                };
                out.push(look.await.map(|(position, p, at, before, s16, s17)| {
                    let speed = before.and_then(|(t0, p0)| {
                        let dt = at.saturating_since(t0).as_secs_f64();
                        (dt > 0.0).then(|| (p - p0.units()) / dt)
                    });
                    let tolerance = self.client.config().in_position_tolerance;
                    let s1_moved = WatchSample::s1_moved(before.map(|(_, p0)| p0), position, tolerance);
                    motionlink_compax::report::axis_look(position, speed, s16, s17, s1_moved)
                }));
            }
            out
        })
    }

    fn move_to(self: Arc<Self>, unit: u8, target: f64, speed_percent: Option<f64>) -> Result<Motion, ErrorReport> {
        address(unit)?;
        let target = position(target)?;
        let speed = speed(speed_percent)?;
        self.limits.check(address(unit)?, target)?;
        Ok(self.checked_move(unit, target, speed, Duration::from_secs(600)))
    }

    fn jog(
        self: Arc<Self>,
        unit: u8,
        direction: JogDirection,
        speed_percent: Option<f64>,
    ) -> Result<Motion, ErrorReport> {
        let a = address(unit)?;
        let speed = speed(speed_percent)?;
        Ok(Box::pin(async move {
            // A checked move to the end of the jog range; it runs until the jog ends (the future dropped: the
            // drive is switched off, confirmed by S17) or the end is reached.
            let here = self.client.read_position(a).await?.units();
            let end = match direction {
                JogDirection::Positive => self.limits.max.map_or(here + self.jog_range, |m| m.units()),
                JogDirection::Negative => self.limits.min.map_or(here - self.jog_range, |m| m.units()),
            };
            let target = position(end)?;
            Arc::clone(&self).checked_move(unit, target, speed, Duration::from_secs(3600)).await
        }))
    }

    fn stop(self: Arc<Self>, unit: u8) -> Motion {
        Box::pin(async move {
            // As `motionlink compax stop`: OUTPUT O0=0 if S17 says it moves, confirmed by S17; then S1 and S16.
            let a = address(unit)?;
            Ok(report(&StopResult::new(None::<()>, self.client.stop_confirmed(a).await?)))
        })
    }

    fn stop_started(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        Box::pin(async move {
            let report = self.client.stop_started().await;
            stop_text(report)
        })
    }

    fn actions(&self) -> Vec<Action> {
        vec![Action { name: "switch_on", label: "Switch on (OUTPUT O0=1)", moves: false }]
    }

    fn action(self: Arc<Self>, unit: u8, name: &str) -> Result<Motion, ErrorReport> {
        let a = address(unit)?;
        match name {
            "switch_on" => {
                Ok(Box::pin(async move { Ok(report(&self.client.switch_output(a, 0, OutputState::ON).await?)) }))
            }
            other => Err(ErrorReport::usage(format!("no action {other:?}"))),
        }
    }

    fn params(&self) -> Vec<Param> {
        Param::rows(&PARAMS)
    }

    fn read_param(self: Arc<Self>, unit: u8, name: String) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move {
            let id: ParamId = name.parse().map_err(ErrorReport::usage)?;
            Ok(report(&ParamReading { id, value: self.client.read_param(address(unit)?, id).await? }))
        })
    }

    fn write_param(
        self: Arc<Self>,
        unit: u8,
        name: String,
        value: String,
    ) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move {
            let id: ParamId = name.parse().map_err(ErrorReport::usage)?;
            let v: f64 = value
                .trim()
                .parse()
                .map_err(|_| ErrorReport::usage(format!("P{} value {value:?}: give a number", id.get())))?;
            id.check(v).map_err(ErrorReport::usage)?;
            // The library writes, compares what it reads back (a difference is an error) and reads once more.
            Ok(report(&self.client.set_param(address(unit)?, id, v).await?))
        })
    }

    fn errors(self: Arc<Self>, unit: u8) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move {
            let v = self.client.read_status(address(unit)?, StatusId::ERROR_HISTORY).await?;
            let StatusValue::History(h) = v else {
                return Err(ErrorReport::classed(
                    ErrorClass::Transport(TransportKind::Corrupt),
                    format!("S18 read as {v}, not a history"),
                ));
            };
            Ok(report(&ErrorHistory(h)))
        })
    }

    fn close(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        close_last(self, |me| async move { stop_text(me.client.close().await?) })
    }
}
