//! The console over PowerCube modules: found by a scan, moved by checked ramp moves (dropped: halted), jogged
//! as a ramp towards the soft limit that is halted when the jog ends, homed and reset, their parameters.

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::can::{CanLink, SlcanBitrate};
use motionlink_link::capture::{TapCanLink, TapLink};
use motionlink_link::link::Link;
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::url::PortUrl;
use motionlink_link::{SerialSettings, SharedClock};
use motionlink_powercube::client::{BusConfig, Client, Guard, ModulesAt, MoveSpec, Readback};
use motionlink_powercube::model::{
    Address, AxisUnit, CubeState, ModuleKind, Param, Position, StateFlag, Value as CubeValue, Velocity, PARAMS,
};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::{AsyncClient, Emulator, Error};
use serde_json::{json, Value};

use super::device::{
    finite, Action, BoxFuture, Device, Failure, JogDirection, Motion, Param as Row, ParamValue, Sample, Unit,
};
use super::traffic::Traffic;
use super::ServeArgs;
use crate::common::CliError;

/// `motionlink console powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device or tcp://HOST:PORT (RS232), socketcan://IF or slcan://PATH (CAN), or sim.
    #[arg(long, value_name = "PORT")]
    pub port: String,
    /// Only these module addresses (such as 1,17) instead of a scan of 1..31.
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u8).range(1..=31))]
    pub modules: Vec<u8>,
    /// RS232 baud rate.
    #[arg(long, default_value_t = 9600, value_parser = clap::value_parser!(u32).range(1..))]
    pub baud: u32,
    /// CAN bit rate of an SLCAN adapter (10000 .. 1000000).
    #[arg(long, default_value_t = 1_000_000)]
    pub bitrate: u32,
    /// Acknowledge timeout in ms, 1 to 60000 (default: 200 on RS232, 50 on CAN).
    #[arg(long, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub timeout_ms: Option<u64>,
    /// Do not arm the module watchdog for moves, jogs and homing (a console that dies then leaves the module
    /// moving). A closed page, Stop and the end of the console still halt it.
    #[arg(long)]
    pub no_watchdog: bool,
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// The last velocity and current read of a module (None: not read yet, or not a number).
type VelocityCurrent = (Option<f64>, Option<f64>);

struct PowerCube {
    client: AsyncClient,
    port: String,
    modules: Vec<u8>,
    guard: Guard,
    /// The kind of each module found (rotary or linear), by address.
    kinds: std::sync::Mutex<[Option<ModuleKind>; 32]>,
    /// Which of velocity and current the next sample reads.
    turn: std::sync::atomic::AtomicU64,
    /// The last velocity and current read of each module.
    last_vel_current: std::sync::Mutex<std::collections::HashMap<u8, VelocityCurrent>>,
    /// The last emulator, kept alive with the session for `--port sim`.
    _host: Option<EmulatorHost<Emulator>>,
}

/// Opens the session `args` ask for, its link tapped into the traffic log.
pub async fn open(args: &Args, clock: &SharedClock) -> Result<(Arc<dyn Device>, Arc<Traffic>), CliError> {
    let url: PortUrl = args.port.parse()?;
    let traffic = Arc::new(Traffic::new(
        Box::new(motionlink_powercube::describe::Describer::new()),
        &format!("powercube {}", args.port),
        match &url {
            PortUrl::SocketCan(i) => i.as_str(),
            _ => "can0",
        },
        clock,
    ));
    let settings = {
        let timeout = args.timeout_ms;
        move |mut c: BusConfig| {
            if let Some(t) = timeout {
                c.reply_timeout = Duration::from_millis(t);
            }
            c
        }
    };
    let clock2 = Arc::clone(clock);
    let tap = Arc::clone(&traffic);
    let byte_link =
        |link: Box<dyn Link>| -> Box<dyn Link> { Box::new(TapLink::new(link, Arc::clone(&clock2), Arc::clone(&tap))) };
    let clock3 = Arc::clone(clock);
    let tap2 = Arc::clone(&traffic);
    let can_link = move |link: Box<dyn CanLink>| -> Box<dyn CanLink> {
        Box::new(TapCanLink::new(link, Arc::clone(&clock3), Arc::clone(&tap2)))
    };
    let mut host = None;
    let c = Arc::clone(clock);
    let client: Result<Client, Error> = match &url {
        PortUrl::Serial(_) | PortUrl::Tcp { .. } => {
            let url = url.clone();
            let baud = args.baud;
            let link = tokio::task::spawn_blocking(move || {
                url.open_byte_link(SerialSettings { dtr_rts_on: false, ..SerialSettings::new(baud) })
            })
            .await
            .map_err(|e| CliError::transport(format!("the opening task failed: {e}")))??;
            Client::rs232(byte_link(link), c, settings(BusConfig::rs232()))
        }
        PortUrl::Sim => {
            let h = EmulatorHost::new(Emulator::new(&SimConfig::default()), Arc::clone(clock), PipeConfig::instant());
            let link: Box<dyn Link> = Box::new(h.connect().0);
            host = Some(h);
            Client::rs232(byte_link(link), c, settings(BusConfig::rs232()))
        }
        PortUrl::Slcan(path) => {
            let rate = SlcanBitrate::from_bps(args.bitrate)
                .ok_or_else(|| CliError::usage(format!("{} bit/s is not an SLCAN bit rate", args.bitrate)))?;
            let path = path.clone();
            let c2 = Arc::clone(clock);
            let link = tokio::task::spawn_blocking(move || motionlink_link::url::open_slcan(&path, c2, rate))
                .await
                .map_err(|e| CliError::transport(format!("the opening task failed: {e}")))??;
            Client::can(can_link(Box::new(link)), c, settings(BusConfig::can()))
        }
        PortUrl::SocketCan(ifname) => {
            #[cfg(target_os = "linux")]
            {
                let link = motionlink_link::can::socketcan::SocketCanLink::open(ifname)?;
                Client::can(can_link(Box::new(link)), c, settings(BusConfig::can()))
            }
            #[cfg(not(target_os = "linux"))]
            {
                let _ = ifname;
                return Err(CliError::usage("socketcan:// ports need Linux"));
            }
        }
    };
    let client = client.map_err(|e| crate::common::classified(&e))?;
    let client = AsyncClient::open(move || Ok(client)).await.map_err(|e| crate::common::classified(&e))?;
    let guard = Guard::for_motions(ModulesAt::emulated_in_process(host.is_some()), args.no_watchdog);
    let device = PowerCube {
        client,
        port: args.port.clone(),
        modules: args.modules.clone(),
        guard,
        kinds: std::sync::Mutex::new([None; 32]),
        turn: std::sync::atomic::AtomicU64::new(0),
        last_vel_current: std::sync::Mutex::new(std::collections::HashMap::new()),
        _host: host,
    };
    Ok((Arc::new(device), traffic))
}

fn failure(e: Error) -> Failure {
    Failure::of(&e)
}

fn keys(
    kind: Option<ModuleKind>,
) -> (&'static str, &'static str, &'static str, &'static str, &'static str, &'static str) {
    match kind {
        Some(ModuleKind::Rotary) => ("position_rad", "target_rad", "rad", "velocity_rad_per_s", "rad/s", "rotary"),
        Some(ModuleKind::Linear) => ("position_m", "target_m", "m", "velocity_m_per_s", "m/s", "linear"),
        None => ("position", "target", "module unit", "velocity", "module unit/s", "kind not read"),
    }
}

fn f32_of(v: CubeValue) -> Option<f64> {
    match v {
        CubeValue::F32(x) => Some(f64::from(x)),
        _ => None,
    }
}

fn state_names(s: CubeState) -> (Vec<&'static str>, Vec<&'static str>, u64) {
    use motionlink_link::flags::FlagWord;
    (s.names(), s.faults().map(|f| f.name()).collect(), s.unknown())
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
            command_speed: (vel, vel_unit),
            has_current: true,
        }
    }

    fn module(&self, address: u8) -> Result<motionlink_powercube::client::AsyncModule<'_>, Failure> {
        Ok(self.client.module(Address::new(address).map_err(|e| failure(e.into()))?))
    }

    /// The unit the page shows module `address`'s numbers in (that of the kind found), read from the module
    /// if it was not found: the positions and velocities sent are built in it, so the library checks it.
    async fn unit_of(&self, m: &motionlink_powercube::client::AsyncModule<'_>) -> Result<AxisUnit, Failure> {
        match self.kind(m.address().get()) {
            Some(kind) => Ok(kind.axis_unit()),
            None => Ok(m.kind().await.map_err(failure)?.axis_unit()),
        }
    }

    fn speed(speed: Option<f64>) -> Result<Option<f32>, Failure> {
        match speed {
            None => Ok(None),
            Some(v) if finite("velocity", v)? > 0.0 => Ok(Some(v as f32)),
            Some(v) => Err(Failure::usage(format!("velocity {v}: give a number above 0"))),
        }
    }
}

impl Device for PowerCube {
    fn family(&self) -> &'static str {
        "powercube"
    }

    fn unit_key(&self) -> &'static str {
        "module"
    }

    fn port(&self) -> String {
        self.port.clone()
    }

    fn discover(&self) -> BoxFuture<'_, Result<Vec<Unit>, Failure>> {
        Box::pin(async move {
            let mut found = Vec::new();
            if self.modules.is_empty() {
                for e in self.client.scan().await.map_err(failure)? {
                    found.push((e.address.get(), e.info.map_err(failure)));
                }
            } else {
                for &a in &self.modules {
                    let info = self.module(a)?.info().await.map_err(failure);
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

    fn sample<'a>(&'a self, units: &'a [Unit]) -> BoxFuture<'a, Vec<Result<Sample, Failure>>> {
        Box::pin(async move {
            let mut out = Vec::new();
            for u in units {
                // Position and state every time; velocity and current take turns (each at half the rate),
                // so that a 9600-baud line still gives positions at 20 Hz.
                let turn = self.turn.fetch_add(1, std::sync::atomic::Ordering::Relaxed) % 2 == 0;
                let look = async {
                    let m = self.client.module(Address::new(u.id)?);
                    let position = m.position().await?;
                    let state = m.state().await?;
                    let other = m.get(if turn { Param::ActVel } else { Param::ActFMotorCurrent }).await?;
                    Ok::<_, Error>((position, state, other))
                };
                out.push(match look.await {
                    Ok((position, state, other)) => {
                        let (flags, faults, unknown_bits) = state_names(state);
                        let (velocity, current) = {
                            let mut last = motionlink_link::clock::lock(&self.last_vel_current);
                            let slot = last.entry(u.id).or_insert((None, None));
                            if turn {
                                slot.0 = f32_of(other);
                            } else {
                                slot.1 = f32_of(other);
                            }
                            *slot
                        };
                        Ok(Sample {
                            id: u.id,
                            position: f64::from(position.value()),
                            speed: velocity,
                            current_amps: current,
                            flags,
                            faults,
                            unknown_bits,
                            moving: state.contains(StateFlag::Motion),
                        })
                    }
                    Err(e) => Err(failure(e)),
                });
            }
            out
        })
    }

    fn move_to(self: Arc<Self>, unit: u8, target: f64, speed: Option<f64>) -> Result<Motion, Failure> {
        let target = finite("target", target)?;
        let vel = Self::speed(speed)?;
        self.module(unit)?;
        Ok(Box::pin(async move {
            let m = self.module(unit)?;
            let axis = self.unit_of(&m).await?;
            let vel = vel.map(|v| Velocity::new(v, axis));
            let spec = MoveSpec { vel, ..MoveSpec::to(Position::new(target as f32, axis)) };
            // Limits, read-backs and the final position checked; dropped, the module is halted.
            let r = m.move_to_guarded(&spec, self.guard).await.map_err(failure)?;
            Ok(format!("module {unit} at {:.4} (target {target}), state {}", r.reached.value(), r.state))
        }))
    }

    fn jog(self: Arc<Self>, unit: u8, direction: JogDirection, speed: Option<f64>) -> Result<Motion, Failure> {
        let vel = Self::speed(speed)?;
        self.module(unit)?;
        Ok(Box::pin(async move {
            let m = self.module(unit)?;
            let axis = self.unit_of(&m).await?;
            let vel = vel.map(|v| Velocity::new(v, axis));
            // A checked ramp to the soft limit in the jog's direction; it runs until the jog ends (the future
            // dropped: the module is halted) or the limit is reached.
            let limit = match direction {
                JogDirection::Positive => Param::MaxPos,
                JogDirection::Negative => Param::MinPos,
            };
            let target = f32_of(m.get(limit).await.map_err(failure)?)
                .ok_or_else(|| Failure::usage(format!("{} is not a number", limit.name())))?;
            let spec = MoveSpec {
                vel,
                timeout: Duration::from_secs(3600),
                ..MoveSpec::to(Position::new(target as f32, axis))
            };
            let r = m.move_to_guarded(&spec, self.guard).await.map_err(failure)?;
            Ok(format!("module {unit} reached its {} at {:.4}", limit.name(), r.reached.value()))
        }))
    }

    fn stop(self: Arc<Self>, unit: u8) -> Motion {
        Box::pin(async move {
            self.module(unit)?.halt().await.map_err(failure)?;
            Ok(format!("module {unit} halted (acknowledged; it stays halted until a reset)"))
        })
    }

    fn stop_started(self: Arc<Self>) -> Motion {
        Box::pin(async move {
            self.client.halt_started().await.map_err(failure)?;
            Ok(String::new())
        })
    }

    fn actions(&self) -> Vec<Action> {
        vec![
            Action { name: "home", label: "Home", moves: true },
            Action { name: "reset", label: "Reset", moves: false },
        ]
    }

    fn action(self: Arc<Self>, unit: u8, name: &str) -> Result<Motion, Failure> {
        self.module(unit)?;
        match name {
            "home" => Ok(Box::pin(async move {
                let (p, s) =
                    self.module(unit)?.home_guarded(Duration::from_secs(60), self.guard).await.map_err(failure)?;
                Ok(format!("module {unit} homed at {:.4}, state {s}", p.value()))
            })),
            "reset" => Ok(Box::pin(async move {
                let released = self.module(unit)?.reset_and_release_watchdog().await.map_err(failure)?;
                Ok(if released {
                    format!("module {unit} reset (its watchdog had expired with no host serving it: switched offline)")
                } else {
                    format!("module {unit} reset")
                })
            })),
            other => Err(Failure::usage(format!("no action {other:?}"))),
        }
    }

    fn params(&self) -> Vec<Row> {
        PARAMS
            .iter()
            .map(|e| Row { name: e.name, id: e.id, unit: e.unit, access: e.access.short(), title: e.title })
            .collect()
    }

    fn read_param(self: Arc<Self>, unit: u8, name: String) -> BoxFuture<'static, Result<ParamValue, Failure>> {
        Box::pin(async move {
            let p: Param = name.trim().parse().map_err(Failure::usage)?;
            let v = self.module(unit)?.get(p).await.map_err(failure)?;
            let kind = self.kind(unit);
            Ok(ParamValue {
                name: p.name().to_string(),
                id: u32::from(p.id()),
                value: v.show_in(p, kind),
                unit: kind.map_or(String::new(), |k| p.unit().symbol(k).to_string()),
                read_back: None,
                note: String::new(),
            })
        })
    }

    fn write_param(
        self: Arc<Self>,
        unit: u8,
        name: String,
        value: String,
    ) -> BoxFuture<'static, Result<ParamValue, Failure>> {
        Box::pin(async move {
            let p: Param = name.trim().parse().map_err(Failure::usage)?;
            let v = CubeValue::parse(p, &value).map_err(Failure::usage)?;
            let kind = self.kind(unit);
            let (read_back, note) = match self.module(unit)?.set_checked(p, v).await.map_err(failure)? {
                Readback::Same(r) => (Some(r.show_in(p, kind)), String::new()),
                Readback::NotReadable(why) => (None, format!("not read back: {why}")),
            };
            Ok(ParamValue {
                name: p.name().to_string(),
                id: u32::from(p.id()),
                value: v.show_in(p, kind),
                unit: kind.map_or(String::new(), |k| p.unit().symbol(k).to_string()),
                read_back,
                note,
            })
        })
    }

    fn errors(self: Arc<Self>, unit: u8) -> BoxFuture<'static, Result<Value, Failure>> {
        Box::pin(async move {
            let s = self.module(unit)?.state().await.map_err(failure)?;
            let bits: Vec<Value> = s
                .faults()
                .map(|f| json!({"bit": f.mask().trailing_zeros(), "name": f.name(), "cause": f.meaning()}))
                .collect();
            let entries = vec![json!({"label": "CubeState now", "code": s.0, "text": format!("0x{:08X}", s.0),
                                      "bits": bits, "unknown_bits": 0})];
            Ok(json!({"title": "PowerCube modules keep no error history: the fault flags of the state word now",
                      "entries": entries}))
        })
    }

    fn close(self: Arc<Self>) -> BoxFuture<'static, Result<String, Failure>> {
        Box::pin(async move {
            match Arc::try_unwrap(self) {
                Ok(me) => {
                    let PowerCube { client, _host, .. } = me;
                    let r = client.close().await.map_err(failure).map(|()| String::new());
                    // The in-process emulator goes only after the session's end.
                    drop(_host);
                    r
                }
                Err(shared) => {
                    drop(shared);
                    Ok("the session ends with its last request".into())
                }
            }
        })
    }
}
