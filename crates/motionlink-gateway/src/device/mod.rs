//! The devices a gateway serves: each opened on its family crate's `AsyncClient` (`port = "sim"`: an
//! emulator in this process), its requests turned into the library's operations with the family's checked
//! argument types, and its results and states the library's serialised reports.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};

use motionlink_link::profile::{ProfileUse, Profiles};
use serde_json::{Map, Value};

use crate::config::DeviceEntry;
use crate::error::{ErrorReport, GatewayErrors};

mod compax;
pub mod keys;
mod powercube;
mod scu;

/// What an operation ends with: the `--json` object of the same action, or the error of the reply.
pub type Outcome = Result<Value, ErrorReport>;

/// An operation, not yet started: nothing is sent before it is polled. Dropping it while it runs cancels
/// it, which stops any motion it started (the family's `AsyncClient` does that).
pub type Operation = Pin<Box<dyn Future<Output = Outcome> + Send>>;

/// A state sample: the object `watch --json` prints, and whether the device reports motion.
pub type Sampling = Pin<Box<dyn Future<Output = Result<(Value, bool), ErrorReport>> + Send>>;

/// What a request asks for, checked.
pub enum Action {
    /// A motion: it runs under a lease.
    Motion(Operation),
    /// `stop`: it needs no lease and always runs.
    Stop(Operation),
    /// A write (a parameter, a data entry, an output) or a scan of the bus (it holds the bus for up to 31
    /// replies' timeouts, which would hold up a motion's polls and keepalives): no lease, but refused while
    /// the device runs a motion of the gateway's, as the command line's is refused while another command
    /// holds the port.
    Write(Operation),
    /// Anything else: a read (no lease).
    Other(Operation),
}

/// A device's options, checked by the family crate's types before anything is opened.
#[derive(Debug, Clone)]
pub enum FamilyOptions {
    /// An SCU unit.
    Scu(motionlink_scu::args::UnitOptions),
    /// A PowerCube module.
    PowerCube(motionlink_powercube::args::ModuleOptions),
    /// A COMPAX drive.
    Compax(motionlink_compax::DriveOptions),
}

/// A device table, checked: the device's options, its defaults for the options of actions
/// ([`keys`]), and for an emulated SCU the unit of its `sim_config` file.
#[derive(Debug, Clone)]
pub struct Spec {
    /// The options of the device and its session.
    pub options: FamilyOptions,
    /// The device's defaults for the options of actions (`speed` of a move...), by key, as a request's
    /// `args` would give them: a request's own override them.
    pub defaults: Map<String, Value>,
    /// An SCU emulator's configuration (`sim_config`, `port = "sim"`): the unit as it stands.
    pub sim_config: Option<motionlink_scu::SimConfig>,
}

/// The text of a device table's value as the family's option takes it (one element each of a list).
fn texts(key: &str, value: &toml::Value) -> Result<Vec<String>, String> {
    match value {
        toml::Value::String(s) => Ok(vec![s.clone()]),
        toml::Value::Integer(i) => Ok(vec![i.to_string()]),
        toml::Value::Float(f) => Ok(vec![f.to_string()]),
        toml::Value::Boolean(b) => Ok(vec![b.to_string()]),
        toml::Value::Array(items) => {
            let mut all = Vec::new();
            for item in items {
                if matches!(item, toml::Value::Array(_) | toml::Value::Table(_)) {
                    return Err(format!("`{key}`: a list of plain values"));
                }
                all.extend(texts(key, item)?);
            }
            Ok(all)
        }
        other => Err(format!("`{key}` cannot be {}", other.type_str())),
    }
}

impl Spec {
    /// The keys of a device table, each through the family's own rule: an option of the device by the
    /// family's options type, an option of actions by its argument's type (the device's default for
    /// them), a key that means nothing to a gateway accepted ([`keys`]); an unknown key is named with the
    /// keys the family takes.
    pub fn of(entry: &DeviceEntry) -> Result<Spec, String> {
        let sim = entry.port == "sim";
        let family = keys::of(&entry.family)
            .ok_or_else(|| format!("family {:?} is not scu, powercube or compax", entry.family))?;
        // The device's options first (a default's rule may depend on one: an SCU's speed on speed_mode).
        let set = |set: &mut dyn FnMut(&str, &str) -> Result<bool, String>| {
            for (key, value) in &entry.options {
                if family.options.contains(&key.as_str()) {
                    for text in texts(key, value)? {
                        set(key, &text)?;
                    }
                }
            }
            Ok::<(), String>(())
        };
        let mut options = match entry.family.as_str() {
            "scu" => {
                let mut o = motionlink_scu::args::UnitOptions::default();
                set(&mut |k, t| o.set(k, t).map_err(|e| e.to_string()))?;
                o.check_port(sim).map_err(|e| e.to_string())?;
                o.config().map_err(|e| e.to_string())?;
                FamilyOptions::Scu(o)
            }
            "powercube" => {
                let mut o = motionlink_powercube::args::ModuleOptions::default();
                set(&mut |k, t| o.set(k, t).map_err(|e| e.to_string()))?;
                o.check_port(sim).map_err(|e| e.to_string())?;
                FamilyOptions::PowerCube(o)
            }
            _ => {
                let mut o = motionlink_compax::DriveOptions::default();
                set(&mut |k, t| o.set(k, t).map_err(|e| e.to_string()))?;
                o.check_port(sim).map_err(|e| e.to_string())?;
                FamilyOptions::Compax(o)
            }
        };
        let mut defaults = Map::new();
        let mut sim_config = None;
        for (key, value) in &entry.options {
            if family.options.contains(&key.as_str()) || family.ignored(key).is_some() {
                continue;
            }
            if let Some(d) = family.default_of(key) {
                let [text] =
                    texts(key, value)?.try_into().map_err(|_| format!("`{key}` takes one value, not a list"))?;
                let checked = match &options {
                    FamilyOptions::Scu(o) => scu::check_default(o, d.key, &text),
                    FamilyOptions::PowerCube(_) => powercube::check_default(d.key, &text),
                    FamilyOptions::Compax(_) => compax::check_default(d.key, &text),
                };
                checked.map_err(|e| format!("{key}: {text:?}: {e}"))?;
                defaults.insert(key.clone(), serde_json::to_value(value).map_err(|e| format!("`{key}`: {e}"))?);
            } else if key == keys::SCU_SIM_CONFIG && entry.family == "scu" {
                let [path] =
                    texts(key, value)?.try_into().map_err(|_| format!("`{key}` takes one file, not a list"))?;
                let FamilyOptions::Scu(o) = &mut options else { unreachable!("an scu device") };
                sim_config = Some(scu::sim_config(o, sim, &path)?);
            } else {
                return Err(format!(
                    "unknown key `{key}`; a {} device takes family, port, {}",
                    entry.family,
                    family.all(&entry.family).join(", ")
                ));
            }
        }
        if let FamilyOptions::Compax(_) = options {
            compax::check_defaults(&defaults)?;
        }
        if !sim {
            entry.port.parse::<motionlink_link::url::PortUrl>().map_err(|e| format!("port {:?}: {e}", entry.port))?;
        }
        Ok(Spec { options, defaults, sim_config })
    }
}

impl Spec {
    /// What the command line's `--json` puts after `family` and `port` for this device: its module or
    /// drive (nothing for an SCU unit).
    pub fn identity(&self) -> Vec<(&'static str, Value)> {
        match &self.options {
            FamilyOptions::Scu(_) => Vec::new(),
            FamilyOptions::PowerCube(o) => vec![("module", Value::from(o.module.get()))],
            FamilyOptions::Compax(o) => vec![("drive", Value::from(o.drive.get()))],
        }
    }

    /// What stops a motion of this device when its host can no longer reach it (a failed port, a dead
    /// machine): the device's own watchdog, as the family's Safety section says, or nothing.
    pub fn without_host(&self) -> &'static str {
        match &self.options {
            FamilyOptions::Scu(_) => "the SCU unit stops its remote motions 500 ms after the last keepalive (RC)",
            FamilyOptions::PowerCube(o) if o.no_watchdog => {
                "the module's watchdog is not armed for this device (no_watchdog): nothing stops the module"
            }
            FamilyOptions::PowerCube(_) => "the module's watchdog, armed for motions, halts it within 50 ms",
            FamilyOptions::Compax(_) => "a COMPAX drive has no watchdog: nothing stops it before its target",
        }
    }
}

/// The family's session with the device.
#[derive(Clone)]
enum Family {
    Scu(scu::Scu),
    PowerCube(powercube::PowerCube),
    Compax(compax::Compax),
}

/// One device, open.
pub struct Device {
    /// Its name: its topic level.
    pub name: String,
    family: Family,
    /// The keys of its family's device tables.
    keys: &'static keys::FamilyKeys,
    /// Its defaults for the options of actions.
    defaults: Map<String, Value>,
    /// The emulator's host for `port = "sim"`, kept as long as the session.
    host: Mutex<Option<Box<dyn std::any::Any + Send>>>,
}

impl std::fmt::Debug for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Device").field("name", &self.name).finish()
    }
}

impl Device {
    /// Opens the device of `entry` (its options `spec`), as the command line opens its port, and takes its
    /// device profile from the profiles every command loads ([`profiles`]).
    pub async fn open(entry: &DeviceEntry, spec: &Spec) -> Result<Arc<Device>, ErrorReport> {
        Device::open_with(entry, spec, profiles().as_ref()).await
    }

    /// [`Device::open`] with the device profiles `profiles` (`motionlink probe ... --save`): the one of the
    /// device, where its identity matches, seeds the session (those probes are skipped) and every result
    /// names it (`"profile"`, null for none), as the command line's `--json` does.
    pub async fn open_with(
        entry: &DeviceEntry,
        spec: &Spec,
        profiles: Option<&Profiles>,
    ) -> Result<Arc<Device>, ErrorReport> {
        let name = entry.name.as_str();
        let (family, host, keys) = match &spec.options {
            FamilyOptions::Scu(o) => {
                let d = scu::Scu::open(o, spec.sim_config.clone(), &entry.port, profiles, name).await?;
                (Family::Scu(d), None, &keys::SCU)
            }
            FamilyOptions::PowerCube(o) => {
                let (d, host) = powercube::PowerCube::open(o, &entry.port, profiles, name).await?;
                (Family::PowerCube(d), host, &keys::POWERCUBE)
            }
            FamilyOptions::Compax(o) => {
                let (d, host) = compax::Compax::open(o, &entry.port, profiles, name).await?;
                (Family::Compax(d), host, &keys::COMPAX)
            }
        };
        let defaults = spec.defaults.clone();
        Ok(Arc::new(Device { name: entry.name.clone(), family, keys, defaults, host: Mutex::new(host) }))
    }

    /// The action `op` with its `args` (over the device's defaults for it), checked: an error names what is
    /// wrong and nothing is sent.
    pub fn action(&self, op: &str, args: Map<String, Value>) -> Result<Action, ErrorReport> {
        let args = crate::args::Args::new(op, self.keys.with_defaults(op, &self.defaults, args));
        match &self.family {
            Family::Scu(d) => d.action(op, args),
            Family::PowerCube(d) => d.action(op, args),
            Family::Compax(d) => d.action(op, args),
        }
    }

    /// One sample, the object `watch --json` prints (`t_s`: seconds since the gateway started), and whether
    /// the device reports motion (any motion, the gateway's or not).
    pub fn sample(&self, t_s: f64) -> Sampling {
        match &self.family {
            Family::Scu(d) => d.sample(t_s),
            Family::PowerCube(d) => d.sample(t_s),
            Family::Compax(d) => d.sample(t_s),
        }
    }

    /// `stop` with no arguments: every motion of the device, confirmed as the command line's `stop`.
    pub fn stop(&self) -> Operation {
        match self.action("stop", Map::new()) {
            Ok(Action::Stop(op)) => op,
            Ok(_) | Err(_) => Box::pin(async { Err(ErrorReport::usage("stop: not a stop")) }),
        }
    }

    /// Ends the session: the family's close (it stops what was started), then the emulator goes.
    pub async fn close(self: Arc<Device>) -> Result<(), String> {
        let Ok(device) = Arc::try_unwrap(self) else {
            // Still held by a task that is ending: the last one to go closes the session as it drops.
            return Err("still in use by an operation that is ending; its session closes when that ends".into());
        };
        let r = match device.family {
            Family::Scu(d) => d.close().await,
            Family::PowerCube(d) => d.close().await,
            Family::Compax(d) => d.close().await,
        };
        drop(device.host);
        r
    }
}

/// The device profiles every command loads (`motionlink probe ... --save` writes them: profiles.toml beside
/// devices.toml); `None` where there is none, or a file that cannot be read (said on stderr: the devices are
/// then probed as without it).
pub fn profiles() -> Option<Profiles> {
    Profiles::load_default().unwrap_or_else(|e| {
        crate::notice::say!("motionlink gateway: device profiles not used: {e}");
        None
    })
}

/// What device `name` took of the profiles: the reference its results name (`"profile"`, null for none).
/// Its notices (a profile of another identity) go to stderr; a profile that could not be looked up (the
/// device did not give its identity) is said there too, and the session probes as without it.
fn took_profile<E: std::fmt::Display>(name: &str, used: Result<ProfileUse, E>) -> Value {
    match used {
        Ok(used) => {
            for n in &used.notices {
                crate::notice::say!("motionlink gateway: [device.{name}] profile: {n}");
            }
            if let Some(r) = &used.reference {
                crate::notice::say!("motionlink gateway: [device.{name}] profile: {r}");
            }
            used.reference.map_or(Value::Null, Value::from)
        }
        Err(e) => {
            crate::notice::say!("motionlink gateway: [device.{name}] device profile not used: {e}");
            Value::Null
        }
    }
}

/// An object as the command line's `--json` prints it: the identity (`family`, `port`, and `extra`, such as
/// the module or the drive) first, then the report's fields.
pub fn identified(family: &str, port: &str, extra: &[(&str, Value)], report: &impl serde::Serialize) -> Outcome {
    motionlink_link::result::identified(family, port, extra, report)
        .map_err(|e| ErrorReport::transport(format!("the report: {e}")))
}

/// The objects of an action that reads several items (`get` of several names, in order), or lists what
/// it found (`scan`): a JSON list of the objects the command line's `--json` prints, one per line.
pub fn listed(objects: Vec<Value>) -> Outcome {
    Ok(Value::Array(objects))
}

/// The result of a get of one name (its object) or of a list of names (the list of their objects, as the
/// command line prints one per line).
pub fn one_or_listed(mut objects: Vec<Value>, list: bool) -> Outcome {
    match list || objects.len() != 1 {
        true => listed(objects),
        false => Ok(objects.remove(0)),
    }
}

/// A library error in a reply, by its class.
pub fn failed<E: motionlink_link::error::Classify + std::fmt::Display>(e: E) -> ErrorReport {
    ErrorReport::of(&e)
}

/// An action the family does not serve through the gateway.
pub fn unknown_op(family: &str, op: &str, ops: &[&str]) -> ErrorReport {
    ErrorReport::usage(format!(
        "{op:?} is not an action of a {family} device here; give one of {}, keepalive",
        ops.join(", ")
    ))
}

/// Whether `text` is a value of `T` by `T`'s own rule (a device table's default for an action's option).
pub(super) fn parses<T: std::str::FromStr>(text: &str) -> Result<(), String>
where
    T::Err: std::fmt::Display,
{
    text.parse::<T>().map(drop).map_err(|e| e.to_string())
}

/// Whether `text` is a flag's value (a device table's default for an action's flag).
pub(super) fn flag(text: &str) -> Result<(), String> {
    text.parse::<bool>().map(drop).map_err(|_| "give true or false".into())
}

/// Ends a family's session held in `client` by the family's `close` (which stops what the session started);
/// a session still shared by a task that is ending closes when that task drops it.
async fn close_client<C, T, E, F>(client: Arc<C>, close: impl FnOnce(C) -> F) -> Result<(), String>
where
    E: std::fmt::Display,
    F: std::future::Future<Output = Result<T, E>>,
{
    match Arc::try_unwrap(client) {
        Ok(client) => close(client).await.map(|_| ()).map_err(|e| e.to_string()),
        Err(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(family: &str, port: &str, options: &[(&str, toml::Value)]) -> DeviceEntry {
        DeviceEntry {
            name: "d".into(),
            family: family.into(),
            port: port.into(),
            options: options.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
        }
    }

    /// Profiles at a fresh path, with the profile `probe` saves of the device the options emulate on port
    /// `sim` (the family's probe on a blocking client over its own emulator of the same options).
    fn saved_profile(family: &str) -> (Profiles, String) {
        use motionlink_link::pipe::{EmulatorHost, PipeConfig};
        use motionlink_link::probe::{PortKind, ProbeSetup};
        let dir = std::env::temp_dir().join(format!("motionlink-gw-profile-{family}-{}", std::process::id()));
        let mut profiles = Profiles::empty(dir.join("profiles.toml"));
        let clock = motionlink_link::RealClock::shared();
        let setup = ProbeSetup::new("sim", PortKind::Sim, 38_400);
        let saved = match family {
            "scu" => {
                use motionlink_scu::{probe, Client, Emulator};
                let unit = Emulator::new(motionlink_scu::args::UnitOptions::default().emulated().unwrap()).unwrap();
                let host = EmulatorHost::new(unit, clock.clone(), PipeConfig::instant());
                let client = Client::with_connector(host.connector(), clock, Default::default()).unwrap();
                let mut report = probe::probe(&client, &setup).unwrap();
                client.close().unwrap();
                probe::save_profile(&mut report, &mut profiles).unwrap();
                report.saved
            }
            "powercube" => {
                use motionlink_powercube::{probe, Client, Emulator};
                let options = motionlink_powercube::args::ModuleOptions::default();
                let host = EmulatorHost::new(
                    Emulator::new(&options.emulated().unwrap()),
                    clock.clone(),
                    PipeConfig::instant(),
                );
                let link: Box<dyn motionlink_link::Link> = Box::new(host.connect().0);
                let client = Client::with_link(link, clock, options.config(false)).unwrap();
                let mut report = probe::probe(&client, &setup).unwrap();
                client.close().unwrap();
                probe::save_profile(&mut report, &mut profiles).unwrap();
                report.saved
            }
            _ => {
                use motionlink_compax::{probe, Client, Emulator};
                let options = motionlink_compax::DriveOptions::default();
                let host =
                    EmulatorHost::new(Emulator::new(options.emulated()).unwrap(), clock.clone(), PipeConfig::instant());
                let client = Client::with_link(Box::new(host.connect().0), clock, options.config()).unwrap();
                let mut report = probe::probe(&client, &setup, &[options.drive]).unwrap();
                client.close().unwrap();
                probe::save_profile(&mut report, &mut profiles).unwrap();
                report.saved
            }
        };
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(saved.len(), 1, "{saved:?}");
        (profiles, saved[0].clone())
    }

    /// A device takes its saved profile as every command does, and every result and sample names it
    /// (`"profile"`, as the command line's `--json`); without a profile for the device it is null.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_device_takes_its_saved_profile_and_its_results_name_it() {
        for (family, op) in [("scu", "info"), ("powercube", "state"), ("compax", "status")] {
            let (profiles, saved) = saved_profile(family);
            let e = entry(family, "sim", &[]);
            let spec = Spec::of(&e).unwrap();
            let device = Device::open_with(&e, &spec, Some(&profiles)).await.unwrap();
            let Ok(Action::Other(read)) = device.action(op, Map::new()) else { panic!("{family} {op}: a read") };
            let result = read.await.unwrap();
            assert_eq!(result["profile"], Value::from(saved.clone()), "{family}: {result}");
            let (sample, _) = device.sample(0.0).await.unwrap();
            assert_eq!(sample["profile"], Value::from(saved), "{family}: {sample}");
            device.close().await.unwrap();
            // None saved for this device (another port): null, as the command line prints it.
            let none = Profiles::empty(std::env::temp_dir().join("motionlink-gw-no-profile.toml"));
            let device = Device::open_with(&e, &spec, Some(&none)).await.unwrap();
            let Ok(Action::Other(read)) = device.action(op, Map::new()) else { panic!("{family} {op}: a read") };
            assert_eq!(read.await.unwrap()["profile"], Value::Null, "{family}");
            device.close().await.unwrap();
        }
    }

    /// A `port = "sim"` device's emulator is behind a line paced to the device's baud rate, in every family: a
    /// read takes at least the wire time of its telegrams (a PowerCube's state: 7 + 11 bytes at 9600 baud,
    /// 18.75 ms; a COMPAX drive's status, S1 first: 4 + 13 bytes at 9600, 17.7 ms; an SCU's info, its first
    /// RG and reply: 6 + 11 bytes at 38400, 4.4 ms).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_sim_device_s_line_takes_the_time_of_its_baud_rate() {
        for (family, op, wire_ms) in [("powercube", "state", 18.0), ("compax", "status", 17.0), ("scu", "info", 4.0)] {
            let e = entry(family, "sim", &[]);
            let spec = Spec::of(&e).unwrap();
            let device = Device::open_with(&e, &spec, None).await.unwrap();
            let Ok(Action::Other(read)) = device.action(op, Map::new()) else { panic!("{family} {op}: a read") };
            let started = std::time::Instant::now();
            read.await.unwrap();
            let took_ms = started.elapsed().as_secs_f64() * 1e3;
            assert!(took_ms >= wire_ms, "{family} {op}: {took_ms:.1} ms, less than its wire time");
            device.close().await.unwrap();
        }
    }

    #[test]
    fn a_device_s_options_go_through_the_family_s_rules() {
        let s = Spec::of(&entry("scu", "sim", &[("functions", "tlt".into()), ("stroke", vec!["1=0:865"].into())]));
        assert!(
            matches!(s.map(|s| s.options), Ok(FamilyOptions::Scu(o)) if o.functions == ["tlt"] && o.stroke == ["1=0:865"])
        );
        let s = Spec::of(&entry("powercube", "/dev/ttyUSB0", &[("module", 3.into()), ("no_watchdog", false.into())]));
        assert!(matches!(s.map(|s| s.options), Ok(FamilyOptions::PowerCube(o)) if o.module.get() == 3));
        let s = Spec::of(&entry("compax", "tcp://127.0.0.1:4001", &[("drive", 2.into()), ("tolerance", 0.5.into())]));
        assert!(matches!(s.map(|s| s.options), Ok(FamilyOptions::Compax(o)) if o.drive.get() == 2));
    }

    #[test]
    fn a_bad_option_is_named_with_the_family_s_rule() {
        let e = Spec::of(&entry("scu", "sim", &[("modul", 3.into())])).unwrap_err();
        assert!(e.contains("unknown key `modul`") && e.contains("functions"), "{e}");
        let e = Spec::of(&entry("powercube", "sim", &[("module", 40.into())])).unwrap_err();
        assert!(e.starts_with("module: \"40\": "), "{e}");
        let e = Spec::of(&entry("compax", "/dev/ttyUSB0", &[("sim_variants", "no-echo".into())])).unwrap_err();
        assert!(e.contains("only for port sim"), "{e}");
        let e = Spec::of(&entry("scu", "sim", &[("functions", toml::Value::Table(toml::Table::new()))])).unwrap_err();
        assert!(e.contains("`functions` cannot be"), "{e}");
        let e = Spec::of(&entry("compax", "nonsense://x", &[])).unwrap_err();
        assert!(e.starts_with("port \"nonsense://x\""), "{e}");
        // A key the command line refuses from a file (a move's target) is refused here too.
        let e = Spec::of(&entry("compax", "sim", &[("abs", 5.into())])).unwrap_err();
        assert!(e.contains("unknown key `abs`") && e.contains("max_pos"), "{e}");
    }

    #[test]
    fn an_action_s_options_are_the_device_s_defaults_checked_by_their_rules() {
        let s = Spec::of(&entry(
            "scu",
            "sim",
            &[("speed", 40.into()), ("soft", true.into()), ("function", 2.into()), ("csv", true.into())],
        ))
        .unwrap();
        assert_eq!(Value::Object(s.defaults), serde_json::json!({"function": 2, "soft": true, "speed": 40}));
        let s = Spec::of(&entry(
            "powercube",
            "sim",
            &[("vel", 0.3.into()), ("timeout_s", 9.into()), ("modules", vec![1, 2].into())],
        ))
        .unwrap();
        assert_eq!(Value::Object(s.defaults), serde_json::json!({"timeout_s": 9, "vel": 0.3}));
        let s = Spec::of(&entry(
            "compax",
            "sim",
            &[("speed", 10.into()), ("max_pos", 500.into()), ("jog_range", 5.into())],
        ))
        .unwrap();
        assert_eq!(Value::Object(s.defaults), serde_json::json!({"max_pos": 500, "speed": 10}));
        // Each by its argument's rule, named with the key.
        let e = Spec::of(&entry("scu", "sim", &[("speed", 150.into())])).unwrap_err();
        assert!(e.starts_with("speed: \"150\": "), "{e}");
        let e = Spec::of(&entry("powercube", "sim", &[("vel", (-1).into())])).unwrap_err();
        assert!(e.starts_with("vel: \"-1\": "), "{e}");
        let e = Spec::of(&entry("compax", "sim", &[("min_pos", 10.into()), ("max_pos", 5.into())])).unwrap_err();
        assert!(e.contains("min_pos"), "{e}");
        let e = Spec::of(&entry("compax", "sim", &[("speed", vec![1, 2].into())])).unwrap_err();
        assert!(e.contains("not a list"), "{e}");
        // An SCU speed in counts/s where the unit takes them.
        let s = Spec::of(&entry("scu", "sim", &[("speed", 800.into()), ("speed_mode", "counts-per-second".into())]));
        assert!(s.is_ok(), "{s:?}");
    }
}
