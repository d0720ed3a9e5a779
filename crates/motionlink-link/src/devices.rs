//! The configuration file of named devices, `devices.toml` ([`devices_path`](crate::profile::devices_path):
//! in the configuration directory, or the file `MOTIONLINK_CONFIG` names), and where a front end's port
//! comes from: `--port`, else a named device (`--device lift`), else the `MOTIONLINK_PORT` environment
//! variable.
//!
//! ```toml
//! [device.lift]
//! family = "scu"
//! port = "/dev/ttyUSB0"
//! functions = "tlt"          # any option of the family's commands, named as the option without `--`
//! stroke = ["1=0:865", "2=0:865"]
//! ```
//!
//! A device's other keys are options of the family's front ends: this module keeps them as the file gives
//! them; each front end checks and applies the ones it has.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::error::{Classify, ErrorClass};

/// The families a device may be of.
pub const FAMILIES: [&str; 3] = ["scu", "powercube", "compax"];

/// What is wrong with the configuration file or the device asked for: a usage error (exit code 2).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ConfigError(pub String);

impl Classify for ConfigError {
    fn class(&self) -> ErrorClass {
        ErrorClass::Usage
    }
}

/// One named device.
#[derive(Debug, Clone, PartialEq)]
pub struct Device {
    /// `scu`, `powercube` or `compax`.
    pub family: String,
    /// The port to use.
    pub port: String,
    /// The other options, by key (`functions`, `module`, `timeout_ms`...), as the file gives them; a key
    /// spelt as on the command line (`timeout-ms`) is the same key.
    pub options: BTreeMap<String, toml::Value>,
}

/// The options of a device table (this file's, or a gateway's) by key: a key spelt as on the command line
/// (`timeout-ms`) is the same key (`timeout_ms`), and `sim_variant` (the option `--sim-variant`) is
/// `sim_variants` (its id, the key every front end reads). One key given twice so is an error, not a silent
/// choice of one of the values.
pub fn options_of(table: toml::Table) -> Result<BTreeMap<String, toml::Value>, String> {
    let mut options = BTreeMap::new();
    for (written, value) in table {
        let key = match written.replace('-', "_") {
            k if k == "sim_variant" => "sim_variants".to_string(),
            k => k,
        };
        if options.insert(key.clone(), value).is_some() {
            return Err(format!("`{written}` is given twice (as `{key}` too): give it once"));
        }
    }
    Ok(options)
}

/// The devices of the configuration file `text` (named `path` in messages).
pub fn parse(text: &str, path: &str) -> Result<BTreeMap<String, Device>, ConfigError> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct File {
        #[serde(default)]
        device: BTreeMap<String, toml::Table>,
    }
    let file: File = toml::from_str(text).map_err(|e| ConfigError(format!("{path}: {e}")))?;
    let mut devices = BTreeMap::new();
    for (name, mut table) in file.device {
        let mut text_of = |key: &str| match table.remove(key) {
            Some(toml::Value::String(s)) => Ok(s),
            Some(other) => {
                Err(ConfigError(format!("{path}: [device.{name}]: `{key}` must be a string, not {}", shown(&other))))
            }
            None => Err(ConfigError(format!("{path}: [device.{name}]: `{key}` is missing"))),
        };
        let family = text_of("family")?;
        let port = text_of("port")?;
        if !FAMILIES.contains(&family.as_str()) {
            return Err(ConfigError(format!(
                "{path}: device {name:?}: family {family:?} is not scu, powercube or compax"
            )));
        }
        let options = options_of(table).map_err(|e| ConfigError(format!("{path}: [device.{name}]: {e}")))?;
        devices.insert(name, Device { family, port, options });
    }
    Ok(devices)
}

/// Reads the configuration file at `path` (with `read`) and returns the device `name`, which must be of
/// `family`, and the path as messages show it.
pub fn load_with(
    family: &str,
    name: &str,
    path: Option<PathBuf>,
    read: impl Fn(&PathBuf) -> std::io::Result<String>,
) -> Result<(Device, String), ConfigError> {
    let path = path
        .ok_or_else(|| ConfigError("--device: no configuration directory is known (set MOTIONLINK_CONFIG)".into()))?;
    let shown = path.display().to_string();
    let text = read(&path).map_err(|e| ConfigError(format!("--device {name}: cannot read {shown}: {e}")))?;
    let mut devices = parse(&text, &shown)?;
    let known: Vec<String> = devices.keys().cloned().collect();
    let d = devices.remove(name).ok_or_else(|| {
        ConfigError(format!("--device {name}: {shown} names no such device (it names: {})", known.join(", ")))
    })?;
    if d.family != family {
        return Err(ConfigError(format!("--device {name} is a {} device in {shown}, not {family}", d.family)));
    }
    Ok((d, shown))
}

/// The device `name` of `family` in the configuration file, and the file's path as messages show it.
pub fn load(family: &str, name: &str) -> Result<(Device, String), ConfigError> {
    load_with(family, name, crate::profile::devices_path(), |p| std::fs::read_to_string(p))
}

/// The port of a `family` front end: `port`, else that of the configured `device` (which must be of this
/// family), else `MOTIONLINK_PORT`.
pub fn resolve(family: &str, port: Option<&str>, device: Option<&str>) -> Result<String, ConfigError> {
    let env_port = std::env::var("MOTIONLINK_PORT").ok();
    resolve_with(family, port, device, env_port.as_deref(), crate::profile::devices_path(), |p| {
        std::fs::read_to_string(p)
    })
}

/// [`resolve`] with the environment's port and the file given.
pub fn resolve_with(
    family: &str,
    port: Option<&str>,
    device: Option<&str>,
    env_port: Option<&str>,
    path: Option<PathBuf>,
    read: impl Fn(&PathBuf) -> std::io::Result<String>,
) -> Result<String, ConfigError> {
    if let Some(p) = port {
        return Ok(p.to_string());
    }
    // A port from elsewhere than the command line is checked here, so that its error says where it came from.
    let checked = |port: String, from: &dyn Fn() -> String| match port.parse::<crate::url::PortUrl>() {
        Ok(_) => Ok(port),
        Err(e) => Err(ConfigError(format!("{}: {e}", from()))),
    };
    if let Some(name) = device {
        let (d, shown) = load_with(family, name, path, read)?;
        return checked(d.port, &|| format!("{shown}: [device.{name}]: `port`"));
    }
    match env_port {
        Some(p) if !p.trim().is_empty() => checked(p.trim().to_string(), &|| "MOTIONLINK_PORT".to_string()),
        _ => Err(ConfigError(
            "no port: give --port PORT, --device NAME (from the configuration file), or set MOTIONLINK_PORT".into(),
        )),
    }
}

/// A value of the file as a message shows it: a string quoted, a number or switch as written, else its kind.
pub fn shown(value: &toml::Value) -> String {
    match value {
        toml::Value::String(s) => format!("{s:?}"),
        toml::Value::Integer(i) => i.to_string(),
        toml::Value::Float(f) => f.to_string(),
        toml::Value::Boolean(b) => b.to_string(),
        toml::Value::Array(_) => "a list".into(),
        toml::Value::Table(_) => "a table".into(),
        toml::Value::Datetime(_) => "a date".into(),
    }
}

/// An option of a device (a device table's key such as `module`, `drive`, `functions`; the command line's
/// option `--module`...) that cannot be used: its key, or none where the options together are wrong, and
/// what is wrong. Every family's options (`UnitOptions`, `ModuleOptions`, `DriveOptions`) refuse with it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OptionError {
    /// The option's key, if one option is to blame.
    pub key: Option<&'static str>,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for OptionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.key {
            Some(key) => write!(f, "{key}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

impl std::error::Error for OptionError {}

impl OptionError {
    /// The option `key`'s `text` parsed by its type's rule (`FromStr`); a refusal names the key and the text.
    pub fn parsed<T: std::str::FromStr>(key: &'static str, text: &str) -> Result<T, OptionError>
    where
        T::Err: std::fmt::Display,
    {
        text.parse::<T>().map_err(|e| OptionError { key: Some(key), message: format!("{text:?}: {e}") })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = "[device.lift]\nfamily = \"scu\"\nport = \"/dev/ttyUSB0\"\n\n[device.arm]\nfamily = \"powercube\"\nport = \"socketcan://can0\"\n";

    fn resolve_in(
        family: &str,
        port: Option<&str>,
        device: Option<&str>,
        env: Option<&str>,
    ) -> Result<String, ConfigError> {
        resolve_with(family, port, device, env, Some(PathBuf::from("/cfg/devices.toml")), |_| Ok(FILE.to_string()))
    }

    #[test]
    fn port_then_device_then_environment() {
        assert_eq!(resolve_in("scu", Some("sim"), Some("lift"), Some("tcp://x:1")).unwrap(), "sim");
        assert_eq!(resolve_in("scu", None, Some("lift"), Some("tcp://x:1")).unwrap(), "/dev/ttyUSB0");
        assert_eq!(resolve_in("powercube", None, Some("arm"), None).unwrap(), "socketcan://can0");
        assert_eq!(resolve_in("compax", None, None, Some("tcp://x:1")).unwrap(), "tcp://x:1");
    }

    #[test]
    fn a_wrong_device_names_what_is_wrong() {
        let e = resolve_in("scu", None, Some("arm"), None).unwrap_err().to_string();
        assert!(e.contains("powercube device") && e.contains("not scu"), "{e}");
        let e = resolve_in("scu", None, Some("nope"), None).unwrap_err().to_string();
        assert!(e.contains("arm, lift"), "{e}");
        let e = resolve_in("scu", None, None, None).unwrap_err().to_string();
        assert!(e.contains("MOTIONLINK_PORT"), "{e}");
        let bad = resolve_with("scu", None, Some("x"), None, Some(PathBuf::from("f")), |_| {
            Ok("[device.x]\nfamily = \"plc\"\nport = \"p\"\n".into())
        });
        assert!(bad.unwrap_err().to_string().contains("not scu, powercube or compax"));
        let bad = resolve_with("scu", None, Some("x"), None, Some(PathBuf::from("f")), |_| {
            Ok("[device.x]\nfamily = \"scu\"\nport = 7\n".into())
        });
        assert!(bad.unwrap_err().to_string().contains("`port` must be a string, not 7"));
        // A port that is no port says where it came from: the file and device, or the environment.
        let bad = resolve_with("scu", None, Some("x"), None, Some(PathBuf::from("f")), |_| {
            Ok("[device.x]\nfamily = \"scu\"\nport = \"\"\n".into())
        });
        assert!(bad.unwrap_err().to_string().starts_with("f: [device.x]: `port`: invalid port \"\""));
        let e = resolve_in("scu", None, None, Some("tcp://x")).unwrap_err().to_string();
        assert!(e.starts_with("MOTIONLINK_PORT: invalid port \"tcp://x\""), "{e}");
    }

    #[test]
    fn keys_spelt_as_options_are_the_same_keys() {
        let d = parse("[device.a]\nfamily = \"compax\"\nport = \"sim\"\ntimeout-ms = 9\n", "f").unwrap();
        assert_eq!(d["a"].options.get("timeout_ms"), Some(&toml::Value::Integer(9)));
        let twice = parse("[device.a]\nfamily = \"compax\"\nport = \"sim\"\ntimeout-ms = 9\ntimeout_ms = 8\n", "f");
        assert!(twice.unwrap_err().to_string().contains("is given twice"));
    }
}
