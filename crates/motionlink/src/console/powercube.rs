//! The console over PowerCube modules: found by a scan, moved by checked ramp moves (dropped: halted), jogged
//! as a ramp towards the soft limit that is halted when the jog ends, homed and reset, their parameters.

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::url::PortUrl;
use motionlink_link::SharedClock;
use motionlink_powercube::args::{MotionTimeout, MoveVelocity, Target, Tolerance};
use motionlink_powercube::client::{Client, Guard, MoveSpec, PortLink};
use motionlink_powercube::model::{
    Address, AxisUnit, CubeState, ModuleKind, Param, Position, ShortFlag, ShortState, Value as CubeValue, Velocity,
    PARAMS,
};
use motionlink_powercube::report::{Acted, ParamReading, Released, SetReport, StateReport};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::{AsyncClient, Emulator, Error};

use super::device::{
    close_last, report, Action, BoxFuture, Device, ErrorReport, JogDirection, Motion, Naming, Param as Row, Report,
    Sample, Unit,
};
use super::traffic::Traffic;
use super::ServeArgs;
use crate::common::CliError;
use crate::tap::Tap;

/// `motionlink console powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device or tcp://HOST:PORT (RS232), socketcan://IF or slcan://PATH (CAN), or sim.
    /// Default: --device, else MOTIONLINK_PORT.
    #[arg(long, value_name = "PORT")]
    pub port: Option<String>,
    #[command(flatten)]
    pub device: super::DeviceArg,
    /// Only these module addresses (such as 1,17) instead of a scan of 1..31; with `--port sim`, the modules
    /// the emulated bus has (default: 1).
    #[arg(long, value_delimiter = ',')]
    pub modules: Vec<Address>,
    #[command(flatten)]
    pub bus: crate::powercube::BusArgs,
    /// In-position tolerance of a move (rad or m, above 0, at most 0.1; default 0.001), as `powercube move
    /// --tolerance` (a device's `tolerance` key): the move succeeds only if the final actual position is at
    /// most this far from the target.
    #[arg(long)]
    pub tolerance: Option<Tolerance>,
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// What a sample shows of a module besides its position and short state, read in turns: the last velocity
/// and current (None: not read yet, or not a number) and the last full state word.
#[derive(Debug, Clone, Copy, Default)]
struct Slow {
    velocity: Option<f64>,
    current: Option<f64>,
    state: Option<CubeState>,
    /// The last sample read the state word out of turn (its short state disagreed).
    forced: bool,
}

/// What the second request of a sample reads, in turn (the first reads position, short state and DIO
/// in one: ActFPosStateDio).
const TURNS: [Param; 3] = [Param::ActVel, Param::CubeState, Param::ActFMotorCurrent];

struct PowerCube {
    client: AsyncClient,
    port: String,
    modules: Vec<u8>,
    guard: Guard,
    /// A move's in-position tolerance (`--tolerance`; `None`: the library's default).
    tolerance: Option<Tolerance>,
    /// The kind of each module found (rotary or linear), by address.
    kinds: std::sync::Mutex<[Option<ModuleKind>; 32]>,
    /// Which of [`TURNS`] the next sample reads.
    turn: std::sync::atomic::AtomicU64,
    /// The last velocity, current and state word read of each module.
    slow: std::sync::Mutex<std::collections::HashMap<u8, Slow>>,
    /// The last emulator, kept alive with the session for `--port sim`.
    _host: Option<EmulatorHost<Emulator>>,
}

/// The numbers of `modules`.
fn addresses(modules: &[Address]) -> Vec<u8> {
    modules.iter().map(|a| a.get()).collect()
}

/// Opens the session `args` ask for, its link tapped into the traffic log.
pub async fn open(args: &Args, port: &str, clock: &SharedClock) -> Result<(Arc<dyn Device>, Arc<Traffic>), CliError> {
    let url: PortUrl = port.parse()?;
    let traffic = Arc::new(Traffic::new(
        Box::new(motionlink_powercube::describe::Describer::new()),
        &format!("powercube {port}"),
        match &url {
            PortUrl::SocketCan(i) => i.as_str(),
            _ => "can0",
        },
        clock,
    ));
    // The session's settings and the guard of its motions by the rules of `motionlink powercube` (its
    // options); the modules are the console's own (`--modules`).
    let options = crate::powercube::bus_options(&args.bus);
    if options.check_port(matches!(url, PortUrl::Sim)).is_err() {
        return Err(CliError::usage(
            "--sim-variant is for --port sim (a served emulator takes `sim powercube --variant`)",
        ));
    }
    let tap = Tap::into_sink(port, Arc::clone(&traffic) as _);
    // Opening a serial device or an SLCAN adapter blocks: on the blocking pool.
    let (baud, bitrate, c2, opening) = (args.bus.baud, args.bus.bitrate, Arc::clone(clock), url.clone());
    let opened = tokio::task::spawn_blocking(move || PortLink::open(&opening, baud, bitrate, &c2))
        .await
        .map_err(|e| CliError::transport(format!("the opening task failed: {e}")))?
        .map_err(|e| crate::common::classified(&e))?;
    let mut host = None;
    let c = Arc::clone(clock);
    let client = match opened {
        Some(PortLink::Rs232(link)) => Client::with_link(tap.link(link, &c), c, options.config(false)),
        Some(PortLink::Can(link)) => Client::with_link(tap.can_link(link, &c), c, options.config(true)),
        None => {
            let modules = if args.modules.is_empty() { vec![1] } else { addresses(&args.modules) };
            let mut bus = SimConfig::with_addresses(&modules).map_err(CliError::usage)?;
            bus.variants = options.sim_variants.clone();
            let h = EmulatorHost::new(Emulator::new(&bus), Arc::clone(clock), PipeConfig::paced(baud.get()));
            let link = tap.link(Box::new(h.connect().0), &c);
            host = Some(h);
            Client::with_link(link, c, options.config(false))
        }
    };
    let client = AsyncClient::from_client(client.map_err(|e| crate::common::classified(&e))?);
    // The device profile of each module (`motionlink probe powercube --save`), where one names the port.
    if let Some(profiles) = super::profiles() {
        let profiled = match args.modules.is_empty() {
            true => vec![Address::new(1).map_err(|e| CliError::usage(e.to_string()))?],
            false => args.modules.clone(),
        };
        for a in profiled {
            super::note_profile(motionlink_powercube::probe::use_profile_async(&client, &profiles, port, a).await);
        }
    }
    let guard = options.guard(host.is_some());
    let device = PowerCube {
        client,
        port: port.to_string(),
        modules: addresses(&args.modules),
        guard,
        tolerance: args.tolerance,
        kinds: std::sync::Mutex::new([None; 32]),
        turn: std::sync::atomic::AtomicU64::new(0),
        slow: std::sync::Mutex::new(std::collections::HashMap::new()),
        _host: host,
    };
    Ok((Arc::new(device), traffic))
}

fn keys(
    kind: Option<ModuleKind>,
) -> (&'static str, &'static str, &'static str, &'static str, &'static str, &'static str) {
    // The names of the position and velocity are the library's look's.
    let (pos, vel) = motionlink_powercube::report::look_keys(kind);
    match kind {
        Some(ModuleKind::Rotary) => (pos, "target_rad", "rad", vel, "rad/s", "rotary"),
        Some(ModuleKind::Linear) => (pos, "target_m", "m", vel, "m/s", "linear"),
        None => (pos, "target", "module unit", vel, "module unit/s", "kind not read"),
    }
}

fn f32_of(v: CubeValue) -> Option<f64> {
    match v {
        CubeValue::F32(x) => Some(f64::from(x)),
        _ => None,
    }
}

/// True when the short state `short` says what the state word `state` would: the state word read last is
/// still good for the flags shown.
fn agrees(state: CubeState, short: ShortState) -> bool {
    state.short_state() == short
}

impl PowerCube {
    fn kind(&self, address: u8) -> Option<ModuleKind> {
        motionlink_link::clock::lock(&self.kinds).get(usize::from(address)).copied().flatten()
    }

    fn unit(&self, address: u8, kind: Option<ModuleKind>, detail: String) -> Unit {
        let (pos, target, unit, vel, vel_unit, _) = keys(kind);
        Unit {
            id: address,
            label: format!("module {address}"),
            detail,
            position_key: pos,
            target_key: target,
            position_unit: unit,
            speed_key: vel,
            speed_unit: vel_unit,
            command_speed_key: vel,
            command_speed_unit: vel_unit,
            current_key: Some("current_amps"),
            // A move or jog with no speed writes no TargetVel (`MoveSpec::vel` None).
            move_speed_when_empty: "the module's TargetVel as it is".into(),
            jog_speed_when_empty: "the module's TargetVel as it is".into(),
        }
    }

    fn module(&self, address: u8) -> Result<motionlink_powercube::client::AsyncModule<'_>, ErrorReport> {
        Ok(self.client.module(Address::new(address).map_err(Error::from)?))
    }

    /// The unit the page shows module `address`'s numbers in (that of the kind found), read from the module
    /// if it was not found: the positions and velocities sent are built in it, so the library checks it.
    async fn unit_of(&self, m: &motionlink_powercube::client::AsyncModule<'_>) -> Result<AxisUnit, ErrorReport> {
        match self.kind(m.address().get()) {
            Some(kind) => Ok(kind.axis_unit()),
            None => Ok(m.kind().await?.axis_unit()),
        }
    }

    /// The velocity of a move or jog, checked as every front end checks it.
    fn speed(speed: Option<f64>) -> Result<Option<MoveVelocity>, ErrorReport> {
        speed.map(MoveVelocity::new).transpose().map_err(ErrorReport::from)
    }
}

impl Device for PowerCube {
    fn naming(&self) -> Naming {
        // The numbers `Address::new` takes.
        Naming { family: "powercube", unit_key: "module", unit_numbers: 1..=motionlink_powercube::wire::MAX_ADDRESS }
    }

    fn port(&self) -> String {
        self.port.clone()
    }

    fn discover(&self) -> BoxFuture<'_, Result<Vec<Unit>, ErrorReport>> {
        Box::pin(async move {
            let mut found = Vec::new();
            if self.modules.is_empty() {
                for e in self.client.scan().await? {
                    found.push((e.address.get(), e.info.map_err(ErrorReport::from)));
                }
            } else {
                for &a in &self.modules {
                    let info = self.module(a)?.info().await.map_err(ErrorReport::from);
                    if let Err(e) = &info {
                        if e.kind == "timeout" {
                            continue;
                        }
                    }
                    found.push((a, info));
                }
            }
            let mut units = Vec::new();
            for (address, info) in found {
                let (kind, detail) = match info {
                    Ok(i) => {
                        (Some(i.kind), format!("{}, version {}, serial {}", keys(Some(i.kind)).5, i.version, i.serial))
                    }
                    Err(e) => (None, format!("answered, then: {}", e.message)),
                };
                if let Some(slot) = motionlink_link::clock::lock(&self.kinds).get_mut(usize::from(address)) {
                    *slot = kind;
                }
                units.push(self.unit(address, kind, detail));
            }
            Ok(units)
        })
    }

    fn sample<'a>(&'a self, units: &'a [Unit]) -> BoxFuture<'a, Vec<Result<Sample, ErrorReport>>> {
        Box::pin(async move {
            let mut out = Vec::new();
            for u in units {
                // Two requests a sample: ActFPosStateDio (position, short state) every time, and in turn the
                // velocity, the full state word or the current. The state word is read at once when the short
                // state disagrees with the last one read (a fault, a halt, a motion begun or ended), but not two
                // samples running: a module whose short state never agrees still gets its velocity and current
                // read. About 38 bytes a sample on RS232: 9600 baud carries about 25 a second.
                let turn = TURNS[(self.turn.fetch_add(1, std::sync::atomic::Ordering::Relaxed) % 3) as usize];
                let look = async {
                    let m = self.client.module(Address::new(u.id)?);
                    // One ActFPosStateDio where the module has it; else CubeState and ActPos (the library's
                    // probe), whose state word is then as fresh as the position.
                    let (position, short, full) = m.look().await?;
                    let last = motionlink_link::clock::lock(&self.slow).get(&u.id).copied().unwrap_or_default();
                    let stale = full.is_none() && last.state.is_none_or(|k| !agrees(k, short)) && !last.forced;
                    let param = match (stale, full.is_some() && turn == Param::CubeState) {
                        (true, _) => Param::CubeState,
                        // The state word came with the look: the turn's read is not needed.
                        (false, true) => return Ok((position, short, full, turn, None)),
                        (false, false) => turn,
                    };
                    let other = m.get(param).await?;
                    Ok::<_, Error>((position, short, full, param, Some(other)))
                };
                out.push(match look.await {
                    Ok((position, short, full, param, other)) => {
                        let slow = {
                            let mut all = motionlink_link::clock::lock(&self.slow);
                            let slot = all.entry(u.id).or_default();
                            if let Some(w) = full {
                                slot.state = Some(w);
                            }
                            slot.forced = param == Param::CubeState && param != turn;
                            match (param, other) {
                                (Param::CubeState, Some(CubeValue::U32(w))) => slot.state = Some(CubeState(w)),
                                (Param::ActVel, Some(v)) => slot.velocity = f32_of(v),
                                (Param::ActFMotorCurrent, Some(v)) => slot.current = f32_of(v),
                                _ => {}
                            }
                            *slot
                        };
                        Ok(motionlink_powercube::report::axis_look(
                            self.kind(u.id),
                            position,
                            short.contains(ShortFlag::Motion),
                            slow.state,
                            slow.velocity,
                            slow.current,
                        ))
                    }
                    Err(e) => Err(e.into()),
                });
            }
            out
        })
    }

    fn move_to(self: Arc<Self>, unit: u8, target: f64, speed: Option<f64>) -> Result<Motion, ErrorReport> {
        let target = Target::new(target)?;
        let vel = Self::speed(speed)?;
        self.module(unit)?;
        Ok(Box::pin(async move {
            let m = self.module(unit)?;
            let axis = self.unit_of(&m).await?;
            let vel = vel.map(|v| Velocity::new(v.value(), axis));
            let tolerance = self.tolerance.map(|t| t.position());
            let spec = MoveSpec { vel, tolerance, ..MoveSpec::to(Position::new(target.value(), axis)) };
            // Limits, read-backs and the final position checked; dropped, the module is halted.
            Ok(report(&Acted::reached(m.move_to_guarded(&spec, self.guard).await?)))
        }))
    }

    fn jog(self: Arc<Self>, unit: u8, direction: JogDirection, speed: Option<f64>) -> Result<Motion, ErrorReport> {
        let vel = Self::speed(speed)?;
        self.module(unit)?;
        Ok(Box::pin(async move {
            let m = self.module(unit)?;
            let axis = self.unit_of(&m).await?;
            let vel = vel.map(|v| Velocity::new(v.value(), axis));
            // A checked ramp to the soft limit in the jog's direction; it runs until the jog ends (the future
            // dropped: the module is halted) or the limit is reached.
            let limit = match direction {
                JogDirection::Positive => Param::MaxPos,
                JogDirection::Negative => Param::MinPos,
            };
            let target = f32_of(m.get(limit).await?)
                .ok_or_else(|| ErrorReport::usage(format!("{} is not a number", limit.name())))?;
            let spec = MoveSpec {
                vel,
                timeout: Duration::from_secs(3600),
                ..MoveSpec::to(Position::new(target as f32, axis))
            };
            Ok(report(&Acted::reached(m.move_to_guarded(&spec, self.guard).await?)))
        }))
    }

    fn stop(self: Arc<Self>, unit: u8) -> Motion {
        Box::pin(async move {
            // As `motionlink powercube stop`: Halt, confirmed by the state, and where the module stands.
            Ok(report(&Acted::halted(self.module(unit)?.halt_confirmed().await?, None::<()>)))
        })
    }

    fn stop_started(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        Box::pin(async move {
            let started = self.client.started();
            if started.is_empty() {
                return Ok(String::new());
            }
            self.client.halt_started().await?;
            let list: Vec<String> = started.iter().map(|a| a.get().to_string()).collect();
            Ok(format!("halted what still moved of module(s) {} (set in motion by this console)", list.join(", ")))
        })
    }

    fn actions(&self) -> Vec<Action> {
        vec![
            Action { name: "home", label: "Home", moves: true },
            Action { name: "reset", label: "Reset", moves: false },
        ]
    }

    fn action(self: Arc<Self>, unit: u8, name: &str) -> Result<Motion, ErrorReport> {
        self.module(unit)?;
        match name {
            "home" => Ok(Box::pin(async move {
                let timeout = MotionTimeout::DEFAULT.get();
                Ok(report(&Acted::homed(self.module(unit)?.home_guarded(timeout, self.guard).await?)))
            })),
            "reset" => Ok(Box::pin(async move {
                let watchdog_released = self.module(unit)?.reset_and_release_watchdog().await?;
                Ok(report(&Acted::reset(Released { watchdog_released })))
            })),
            other => Err(ErrorReport::usage(format!("no action {other:?}"))),
        }
    }

    fn params(&self) -> Vec<Row> {
        Row::rows(&PARAMS)
    }

    fn read_param(self: Arc<Self>, unit: u8, name: String) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move {
            let param: Param = name.trim().parse().map_err(ErrorReport::usage)?;
            let m = self.module(unit)?;
            let value = m.get(param).await?;
            // The unit depends on the module type (rad or m): read where the scan did not.
            let kind = match self.kind(unit) {
                Some(k) => k,
                None => m.kind().await?,
            };
            Ok(report(&ParamReading { param, kind, value }))
        })
    }

    fn write_param(
        self: Arc<Self>,
        unit: u8,
        name: String,
        value: String,
    ) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async move {
            let param: Param = name.trim().parse().map_err(ErrorReport::usage)?;
            let value = CubeValue::parse(param, &value).map_err(ErrorReport::usage)?;
            // Targets beyond their limits are refused; what was written is read back where the module allows it.
            let readback = self.module(unit)?.set_checked(param, value).await?;
            Ok(report(&SetReport { param, value, readback }))
        })
    }

    fn errors(self: Arc<Self>, unit: u8) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        // PowerCube modules keep no error history: the state word now, as `state` reports it.
        Box::pin(async move { Ok(report(&StateReport(self.module(unit)?.state().await?))) })
    }

    fn close(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        close_last(self, |me| async move {
            let PowerCube { client, _host, .. } = me;
            let r = client.close().await.map_err(ErrorReport::from).map(|_| String::new());
            // The in-process emulator goes only after the session's end.
            drop(_host);
            r
        })
    }
}
