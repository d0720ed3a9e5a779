//! Where the port comes from: `--port`, a named device of the configuration file (`--device lift`), or the
//! `MOTIONLINK_PORT` environment variable, in that order.
//!
//! The configuration file is `devices.toml` in the platform's configuration directory
//! (`$XDG_CONFIG_HOME/motionlink/` or `~/.config/motionlink/` on Linux and other Unix systems,
//! `~/Library/Application Support/motionlink/` on macOS, `%APPDATA%\motionlink\` on Windows), or the file
//! `MOTIONLINK_CONFIG` names:
//!
//! ```toml
//! [device.lift]
//! family = "scu"
//! port = "/dev/ttyUSB0"
//!
//! [device.arm]
//! family = "powercube"
//! port = "socketcan://can0"
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use crate::common::CliError;

/// One named device.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Device {
    /// `scu`, `powercube` or `compax`.
    pub family: String,
    /// The `--port` to use.
    pub port: String,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    device: BTreeMap<String, Device>,
}

/// The configuration file's path: `MOTIONLINK_CONFIG`, else `devices.toml` in the platform's directory.
pub fn config_path() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("MOTIONLINK_CONFIG") {
        return Some(PathBuf::from(p));
    }
    let home = || std::env::var_os("HOME").map(PathBuf::from);
    let dir = if cfg!(windows) {
        std::env::var_os("APPDATA").map(PathBuf::from)
    } else if cfg!(target_os = "macos") {
        home().map(|h| h.join("Library/Application Support"))
    } else {
        std::env::var_os("XDG_CONFIG_HOME").map(PathBuf::from).or_else(|| home().map(|h| h.join(".config")))
    };
    dir.map(|d| d.join("motionlink").join("devices.toml"))
}

/// The devices of the configuration file `text` (named `path` in messages).
fn parse(text: &str, path: &str) -> Result<BTreeMap<String, Device>, CliError> {
    let file: File = toml::from_str(text).map_err(|e| CliError::usage(format!("{path}: {e}")))?;
    for (name, d) in &file.device {
        if !["scu", "powercube", "compax"].contains(&d.family.as_str()) {
            return Err(CliError::usage(format!(
                "{path}: device {name:?}: family {:?} is not scu, powercube or compax",
                d.family
            )));
        }
    }
    Ok(file.device)
}

/// Picks the port for a `family` command: `--port`, else `--device` from the configuration file (which
/// must be of this family), else `MOTIONLINK_PORT`.
pub fn resolve(family: &str, port: Option<&str>, device: Option<&str>) -> Result<String, CliError> {
    resolve_with(family, port, device, std::env::var("MOTIONLINK_PORT").ok().as_deref(), config_path(), |p| {
        std::fs::read_to_string(p)
    })
}

fn resolve_with(
    family: &str,
    port: Option<&str>,
    device: Option<&str>,
    env_port: Option<&str>,
    path: Option<PathBuf>,
    read: impl Fn(&PathBuf) -> std::io::Result<String>,
) -> Result<String, CliError> {
    if let Some(p) = port {
        return Ok(p.to_string());
    }
    if let Some(name) = device {
        let path = path
            .ok_or_else(|| CliError::usage("--device: no configuration directory is known (set MOTIONLINK_CONFIG)"))?;
        let shown = path.display().to_string();
        let text = read(&path).map_err(|e| CliError::usage(format!("--device {name}: cannot read {shown}: {e}")))?;
        let devices = parse(&text, &shown)?;
        let d = devices.get(name).ok_or_else(|| {
            let known: Vec<&str> = devices.keys().map(String::as_str).collect();
            CliError::usage(format!("--device {name}: {shown} names no such device (it names: {})", known.join(", ")))
        })?;
        if d.family != family {
            return Err(CliError::usage(format!("--device {name} is a {} device in {shown}, not {family}", d.family)));
        }
        return Ok(d.port.clone());
    }
    match env_port {
        Some(p) if !p.trim().is_empty() => Ok(p.trim().to_string()),
        _ => Err(CliError::usage(
            "no port: give --port PORT, --device NAME (from the configuration file), or set MOTIONLINK_PORT",
        )),
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
    ) -> Result<String, CliError> {
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
    }
}
