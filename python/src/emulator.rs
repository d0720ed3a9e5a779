//! Emulators from Python: any family's emulator in this process (the clients connect to it directly), or
//! served on a TCP port or a pseudo-terminal (any client connects to its port URL), with the events the
//! emulated device reports.

use std::sync::{Arc, Mutex, OnceLock};
use std::time::{SystemTime, UNIX_EPOCH};

use motionlink_link::can::{CanBus, CanBusConfig, SlcanAdapter};
use motionlink_link::clock::lock;
use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::{serve_tcp_with, Emulator as EmulatorTrait, FirmwareVariant, ServeOptions, Server};
use motionlink_link::link::{Connector, Link};
use motionlink_link::pipe::{EmulatorHost, EmulatorLink, FaultControl, PipeConfig};
use motionlink_link::{LinkError, RealClock, SharedClock};
use pyo3::prelude::*;

use crate::common::{opt_text, opt_within, Bool, Float, Int, Text};
use crate::errors::{to_pyerr, Failure};

/// Addresses 1..31 (`name`: "modules" or "drives") as the settings give them.
fn addresses(family: &'static str, name: &str, list: &Option<Vec<Int>>) -> Result<Option<Vec<u8>>, Failure> {
    list.as_ref().map(|l| l.iter().map(|a| a.within(family, &format!("{name}: address"), 1..=31)).collect()).transpose()
}

/// The one real clock of every session and emulator the bindings make.
pub fn clock() -> SharedClock {
    static CLOCK: OnceLock<SharedClock> = OnceLock::new();
    Arc::clone(CLOCK.get_or_init(RealClock::shared))
}

fn unix_now() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs_f64()).unwrap_or_default()
}

/// The connections made to an emulator in this process (each one's fault control), until it is closed.
type Plugs = Arc<Mutex<Option<Vec<FaultControl>>>>;

/// A device behind an in-process line, and the connections clients made to it: closing the emulator
/// breaks them (each client then gets `Disconnected` from its next call), and refuses new ones (a client
/// that reconnects, as an SCU session does, finds the line gone).
pub struct Hosted<E> {
    host: EmulatorHost<E>,
    plugs: Plugs,
}

impl<E> Clone for Hosted<E> {
    fn clone(&self) -> Self {
        Hosted { host: self.host.clone(), plugs: Arc::clone(&self.plugs) }
    }
}

impl<E: EmulatorTrait + 'static> Hosted<E> {
    fn new(device: E) -> Self {
        let host = EmulatorHost::new(device, clock(), PipeConfig::instant());
        host.keep_event_times();
        Hosted { host, plugs: Arc::new(Mutex::new(Some(Vec::new()))) }
    }

    /// A new connection to the device (a `Disconnected` error once the emulator is closed).
    pub fn connect(&self) -> Result<EmulatorLink<E>, LinkError> {
        let mut plugs = lock(&self.plugs);
        let Some(plugs) = plugs.as_mut() else {
            return Err(LinkError::Disconnected {
                port: "sim (in-process emulator)".into(),
                reason: "the emulator was closed".into(),
            });
        };
        let (link, control) = self.host.connect();
        plugs.push(control);
        Ok(link)
    }

    /// A connector that makes a new connection at each call ([`Hosted::connect`]).
    pub fn connector(&self) -> Connector {
        let hosted = self.clone();
        Box::new(move || hosted.connect().map(|l| Box::new(l) as Box<dyn Link>))
    }

    /// Breaks every connection made, and refuses new ones.
    fn close(&self) {
        if let Some(plugs) = lock(&self.plugs).take() {
            plugs.iter().for_each(FaultControl::disconnect);
        }
    }
}

/// An emulator in this process, as a client reaches it.
#[derive(Clone)]
pub enum InProcess {
    /// An SCU control unit on an RS232 line.
    Scu(Hosted<motionlink_scu::Emulator>),
    /// PowerCube modules on an RS232 line.
    PowerCube(Hosted<motionlink_powercube::Emulator>),
    /// PowerCube modules on a CAN bus.
    PowerCubeCan(CanBus<motionlink_powercube::Emulator>),
    /// COMPAX drives on an RS485 bus.
    Compax(Hosted<motionlink_compax::Emulator>),
}

impl InProcess {
    /// The device's events since the last call, each at the Unix time (s) it happened.
    fn take_events(&self) -> Vec<(f64, String)> {
        let events = match self {
            InProcess::Scu(h) => h.host.take_timed_events(),
            InProcess::PowerCube(h) => h.host.take_timed_events(),
            InProcess::PowerCubeCan(b) => b.take_timed_events(),
            InProcess::Compax(h) => h.host.take_timed_events(),
        };
        let (now, unix) = (clock().now(), unix_now());
        // A CAN bus may have run its device a little ahead of the clock (to the arrival of a frame).
        let at = |t: Timestamp| unix + t.saturating_since(now).as_secs_f64() - now.saturating_since(t).as_secs_f64();
        events.into_iter().map(|(t, e)| (at(t), e)).collect()
    }

    /// Ends the emulator for the clients connected to it: their lines break (a CAN bus: the bus).
    fn close(&self) {
        match self {
            InProcess::Scu(h) => h.close(),
            InProcess::PowerCube(h) => h.close(),
            InProcess::PowerCubeCan(b) => b.disconnect(),
            InProcess::Compax(h) => h.close(),
        }
    }
}

enum Running {
    InProcess(InProcess),
    // Held so that the server runs (it stops when dropped).
    Served(#[allow(dead_code)] Server),
}

/// A running emulator (the native half of `motionlink.Emulator`).
#[pyclass(frozen, module = "motionlink._native")]
pub struct NativeEmulator {
    family: &'static str,
    port: String,
    running: Mutex<Option<Running>>,
    /// Events of a served device, as its server reported them (time, text).
    served_events: Arc<Mutex<Vec<(f64, String)>>>,
}

/// The settings of an emulator, as `motionlink.Emulator` passes them.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct EmulatorArgs {
    preset: Option<Text>,
    config: Option<Text>,
    modules: Option<Vec<Int>>,
    drives: Option<Vec<Int>>,
    mode: Option<Int>,
    baud: Option<Int>,
    params: Option<Vec<(String, Float)>>,
    strict: Bool,
    can: Bool,
    serve: Option<Text>,
    bind: Option<Text>,
    variant: Option<Vec<String>>,
}

/// The settings of an emulator, each of a type it can have (checked from [`EmulatorArgs`]).
pub struct EmulatorSettings {
    preset: Option<String>,
    config: Option<String>,
    modules: Option<Vec<Int>>,
    drives: Option<Vec<Int>>,
    mode: Option<Int>,
    baud: Option<Int>,
    params: Option<Vec<(String, f64)>>,
    strict: bool,
    can: bool,
    serve: Option<String>,
    bind: Option<String>,
    variant: Option<Vec<String>>,
}

impl EmulatorArgs {
    /// The settings, or a usage error naming the first that has a value of another type.
    fn checked(self) -> Result<EmulatorSettings, Failure> {
        let text = |t: Option<Text>, name: &str| opt_text(t.as_ref(), "", name).map(|t| t.map(str::to_string));
        let params = match self.params {
            Some(list) => Some(
                list.into_iter()
                    .map(|(name, value)| value.get("", &format!("params {name}")).map(|v| (name, v)))
                    .collect::<Result<Vec<_>, Failure>>()?,
            ),
            None => None,
        };
        Ok(EmulatorSettings {
            preset: text(self.preset, "preset")?,
            config: text(self.config, "config")?,
            modules: self.modules,
            drives: self.drives,
            mode: self.mode,
            baud: self.baud,
            params,
            strict: self.strict.get("", "strict")?,
            can: self.can.get("", "can")?,
            serve: text(self.serve, "serve")?,
            bind: text(self.bind, "bind")?,
            variant: self.variant,
        })
    }
}

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage("", msg)
}

fn scu_device(s: &EmulatorSettings, served: bool) -> Result<motionlink_scu::Emulator, Failure> {
    use motionlink_scu::{FirmwareVariant, SimConfig, Variant};
    let variants = variant_names(s).map(|n| Variant::list(&n)).transpose().map_err(|e| usage(e.to_string()))?;
    // The preset is where the TOML configuration starts (a text that names another preset is refused, naming both), as `motionlink sim
    // scu --preset P --config FILE` takes them: one rule, the library's.
    let text = s.config.as_deref().unwrap_or("");
    let config = SimConfig::from_toml_over(text, s.preset.as_deref(), &variants.unwrap_or_default())
        .map_err(|e| usage(format!("SCU emulator: {e}")))?;
    if served {
        config.check_servable().map_err(|e| usage(format!("SCU emulator: {e}")))?;
    }
    motionlink_scu::Emulator::new(config).map_err(|e| usage(e.to_string()))
}

/// The names of `variant=` (each may itself separate names with commas), as one text for the family's
/// parser.
fn variant_names(s: &EmulatorSettings) -> Option<String> {
    s.variant.as_ref().map(|names| names.join(","))
}

fn powercube_config(s: &EmulatorSettings) -> Result<motionlink_powercube::sim::SimConfig, Failure> {
    use motionlink_powercube::sim::Variant;
    let mut config = powercube_modules(s)?;
    if let Some(names) = variant_names(s) {
        config.add_variants(Variant::list(&names).map_err(|e| usage(e.to_string()))?);
    }
    Ok(config)
}

fn powercube_modules(s: &EmulatorSettings) -> Result<motionlink_powercube::sim::SimConfig, Failure> {
    use motionlink_powercube::sim::SimConfig;
    match (&s.config, &s.modules) {
        (Some(_), Some(_)) => Err(usage("give the modules either in the TOML configuration or as modules=, not both")),
        (Some(text), None) => SimConfig::from_toml(text).map_err(|e| usage(e.to_string())),
        (None, Some(_)) => {
            let m = addresses("powercube", "modules", &s.modules)?.unwrap_or_default();
            SimConfig::with_addresses(&m).map_err(|e| usage(e.to_string()))
        }
        (None, None) => Ok(SimConfig::default()),
    }
}

fn compax_device(s: &EmulatorSettings) -> Result<motionlink_compax::Emulator, Failure> {
    use motionlink_compax::model::ParamId;
    use motionlink_compax::sim::SimConfig;
    let mut cfg = match &s.config {
        Some(text) => SimConfig::from_toml(text).map_err(|e| usage(e.to_string()))?,
        None => SimConfig::default(),
    };
    let drives = addresses("compax", "drives", &s.drives)?;
    let mode = opt_within::<u32>(s.mode.as_ref(), "compax", "mode (P196)", 0..=i64::from(u32::MAX))?;
    if let Some(m) = mode {
        motionlink_compax::wire::Mode::from_p196(m).map_err(|e| usage(format!("mode (P196) {m}: {e}")))?;
    }
    let baud = opt_within::<u32>(s.baud.as_ref(), "compax", "baud", 1..=4_000_000)?;
    cfg = cfg.overridden(drives.as_deref(), mode, baud);
    for (name, value) in s.params.iter().flatten() {
        let id = ParamId::parse(name).map_err(|e| usage(format!("params {name}: {e}")))?;
        cfg = cfg.with_param(id, *value);
    }
    if let Some(names) = variant_names(s) {
        let variants = motionlink_compax::sim::Variant::list(&names).map_err(|e| usage(e.to_string()))?;
        cfg.add_variants(variants);
    }
    motionlink_compax::Emulator::new(cfg).map_err(|e| usage(e.to_string()))
}

fn check_family_options(family: &str, s: &EmulatorSettings) -> Result<(), Failure> {
    let given = |name: &'static str, yes: bool| if yes { Some(name) } else { None };
    let foreign: Vec<&str> = match family {
        "scu" => [
            given("modules", s.modules.is_some()),
            given("drives", s.drives.is_some()),
            given("mode", s.mode.is_some()),
            given("baud", s.baud.is_some()),
            given("params", s.params.is_some()),
            given("strict", s.strict),
            given("can", s.can),
        ]
        .into_iter()
        .flatten()
        .collect(),
        "powercube" => [
            given("preset", s.preset.is_some()),
            given("drives", s.drives.is_some()),
            given("mode", s.mode.is_some()),
            given("baud", s.baud.is_some()),
            given("params", s.params.is_some()),
        ]
        .into_iter()
        .flatten()
        .collect(),
        _ => [
            given("preset", s.preset.is_some()),
            given("modules", s.modules.is_some()),
            given("strict", s.strict),
            given("can", s.can),
        ]
        .into_iter()
        .flatten()
        .collect(),
    };
    match foreign.first() {
        Some(name) => Err(usage(format!("{name}= is not a setting of the {family} emulator"))),
        None => Ok(()),
    }
}

fn serve<E: EmulatorTrait + 'static>(
    device: E,
    how: &str,
    bind: &str,
    events: &Arc<Mutex<Vec<(f64, String)>>>,
) -> Result<Server, Failure> {
    let sink = Arc::clone(events);
    let options =
        ServeOptions { on_event: Some(Arc::new(move |text: &str| lock(&sink).push((unix_now(), text.to_string())))) };
    let device = Arc::new(Mutex::new(device));
    match how {
        "tcp" => serve_tcp_with(bind, device, clock(), options).map_err(|e| {
            Failure::new(
                motionlink_link::error::ErrorClass::Transport(motionlink_link::error::TransportKind::Io),
                "",
                format!("cannot listen on {bind}: {e}"),
            )
        }),
        #[cfg(unix)]
        "pty" => motionlink_link::emulator::serve_pty_with(device, clock(), options).map_err(|e| {
            Failure::new(
                motionlink_link::error::ErrorClass::Transport(motionlink_link::error::TransportKind::Io),
                "",
                format!("cannot create a pseudo-terminal: {e}"),
            )
        }),
        other => {
            Err(usage(format!("serve={other:?}: give \"tcp\" or \"pty\" (or None for an emulator in this process)")))
        }
    }
}

impl NativeEmulator {
    fn start(family: &str, s: &EmulatorSettings) -> Result<NativeEmulator, Failure> {
        let family: &'static str = match family {
            "scu" => "scu",
            "powercube" => "powercube",
            "compax" => "compax",
            other => return Err(usage(format!("family {other:?}: give \"scu\", \"powercube\" or \"compax\""))),
        };
        check_family_options(family, s)?;
        let events = Arc::new(Mutex::new(Vec::new()));
        let bind = s.bind.as_deref().unwrap_or("127.0.0.1:0");
        let (running, port) = match s.serve.as_deref() {
            None => {
                let running = match family {
                    "scu" => InProcess::Scu(Hosted::new(scu_device(s, false)?)),
                    "powercube" if s.can => {
                        let cfg = powercube_config(s)?;
                        let device = motionlink_powercube::Emulator::new_can(&cfg);
                        let bus = CanBus::with_emulator(device, clock(), CanBusConfig::instant());
                        bus.keep_event_times();
                        InProcess::PowerCubeCan(bus)
                    }
                    "powercube" => {
                        let mut device = motionlink_powercube::Emulator::new(&powercube_config(s)?);
                        device.set_strict_bcc(s.strict);
                        InProcess::PowerCube(Hosted::new(device))
                    }
                    _ => InProcess::Compax(Hosted::new(compax_device(s)?)),
                };
                (Running::InProcess(running), String::new())
            }
            Some(how) => {
                let server = match family {
                    "scu" => serve(scu_device(s, true)?, how, bind, &events)?,
                    "powercube" if s.can => {
                        if s.strict {
                            return Err(usage("strict= is about RS232 BCCs; it has no meaning with can=True"));
                        }
                        let cfg = powercube_config(s)?;
                        serve(SlcanAdapter::new(motionlink_powercube::Emulator::new_can(&cfg)), how, bind, &events)?
                    }
                    "powercube" => {
                        let mut device = motionlink_powercube::Emulator::new(&powercube_config(s)?);
                        device.set_strict_bcc(s.strict);
                        serve(device, how, bind, &events)?
                    }
                    _ => serve(compax_device(s)?, how, bind, &events)?,
                };
                let address = server.address().to_string();
                // A served CAN bus sits behind an emulated SLCAN adapter: its URL says so.
                let port = if s.can { format!("slcan://{address}") } else { address };
                (Running::Served(server), port)
            }
        };
        Ok(NativeEmulator { family, port, running: Mutex::new(Some(running)), served_events: events })
    }

    /// The emulator in this process, for a client of `family` (an error naming why not, otherwise).
    pub fn in_process(&self, family: &str) -> Result<InProcess, Failure> {
        if family != self.family {
            return Err(usage(format!("this emulator is a {} emulator, not a {family} one", self.family)));
        }
        match lock(&self.running).as_ref() {
            Some(Running::InProcess(h)) => Ok(h.clone()),
            Some(Running::Served(_)) => {
                Err(usage(format!("this emulator is served on {}: connect to that port", self.port)))
            }
            None => Err(usage("this emulator is closed")),
        }
    }

    /// The port URL of a served emulator (None for one in this process).
    pub fn served_port(&self) -> Option<String> {
        match lock(&self.running).as_ref() {
            Some(Running::Served(_)) => Some(self.port.clone()),
            _ => None,
        }
    }
}

#[pymethods]
impl NativeEmulator {
    #[new]
    #[pyo3(signature = (family, settings))]
    fn py_new(py: Python<'_>, family: Text, settings: EmulatorArgs) -> PyResult<Self> {
        let started = family.get("", "family").and_then(|family| NativeEmulator::start(family, &settings.checked()?));
        started.map_err(|f| to_pyerr(py, f))
    }

    /// The family: "scu", "powercube" or "compax".
    #[getter]
    fn family(&self) -> &'static str {
        self.family
    }

    /// The port URL clients connect to (served emulators), or "" for one in this process.
    #[getter]
    fn port(&self) -> String {
        self.port.clone()
    }

    /// True while the emulator runs.
    #[getter]
    fn running(&self) -> bool {
        lock(&self.running).is_some()
    }

    /// The events since the last call, oldest first: (Unix time in s, text).
    fn take_events(&self, py: Python<'_>) -> Vec<(f64, String)> {
        py.detach(|| {
            let in_process = match lock(&self.running).as_ref() {
                Some(Running::InProcess(h)) => Some(h.clone()),
                _ => None,
            };
            match in_process {
                Some(h) => h.take_events(),
                None => std::mem::take(&mut *lock(&self.served_events)),
            }
        })
    }

    /// Stops the emulator: the clients connected to one in this process get `Disconnected` from their next
    /// call (their lines break, and they cannot reconnect); a served one stops listening and closes its
    /// connection.
    fn close(&self, py: Python<'_>) {
        let running = lock(&self.running).take();
        py.detach(move || {
            if let Some(Running::InProcess(h)) = &running {
                h.close();
            }
            drop(running)
        });
    }
}

/// Where a client connects: a port URL, or an emulator in this process.
pub enum Target {
    /// A port URL (`sim` included).
    Url(motionlink_link::url::PortUrl),
    /// An emulator in this process.
    InProcess(InProcess),
}

/// `port` as `motionlink` passes it: a port URL (str) or a native emulator.
pub fn target(port: &Bound<'_, PyAny>, family: &'static str) -> Result<Target, Failure> {
    if let Ok(emulator) = port.cast::<NativeEmulator>() {
        let emulator = emulator.get();
        return match emulator.served_port() {
            Some(url) => url.parse().map(Target::Url).map_err(|e| Failure::of(family, &e)),
            None => emulator.in_process(family).map(Target::InProcess),
        };
    }
    let text: String = port.extract().map_err(|_| {
        Failure::usage(family, "port must be a port URL (str), such as \"sim\", \"tcp://HOST:PORT\" or \"/dev/ttyUSB0\", or a motionlink.Emulator")
    })?;
    text.parse().map(Target::Url).map_err(|e| Failure::of(family, &e))
}

impl Target {
    /// The port as profiles key it (a URL, `sim` included, as the command line keys it): `None` for an
    /// emulator object in this process.
    pub fn profile_port(&self) -> Option<String> {
        match self {
            Target::Url(u) => Some(u.to_string()),
            Target::InProcess(_) => None,
        }
    }
}
