//! The gateway's file: a `[gateway]` table and the same `[device.NAME]` tables as devices.toml; the broker's
//! address and the security rules checked before any connection.

use std::collections::BTreeMap;
use std::net::IpAddr;
use std::path::{Path, PathBuf};

use crate::error::GatewayError;
use crate::topics::check_name;

/// The families a device may be of.
pub const FAMILIES: [&str; 3] = ["scu", "powercube", "compax"];

/// The environment variable that may hold the broker's password (the other place is `password_file`).
pub const PASSWORD_ENV: &str = "MOTIONLINK_MQTT_PASSWORD";

/// What the command line gives besides the file.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// `--config FILE`.
    pub config: PathBuf,
    /// `--broker URL`: instead of the file's `broker`.
    pub broker: Option<String>,
    /// `--name NAME`: instead of the file's `name`.
    pub name: Option<String>,
    /// `--insecure-broker`: allow a broker off this machine without TLS.
    pub insecure_broker: bool,
}

/// The broker's address: `mqtt://HOST:PORT` (TCP) or `mqtts://HOST:PORT` (TLS); the port defaults to 1883
/// and 8883.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrokerUrl {
    /// Host name or address (an IPv6 address without its brackets).
    pub host: String,
    /// TCP port.
    pub port: u16,
    /// `mqtts://`.
    pub tls: bool,
}

impl BrokerUrl {
    /// Parses `mqtt://HOST[:PORT]` or `mqtts://HOST[:PORT]`.
    pub fn parse(url: &str) -> Result<BrokerUrl, String> {
        let (tls, rest) = if let Some(r) = url.strip_prefix("mqtts://") {
            (true, r)
        } else if let Some(r) = url.strip_prefix("mqtt://") {
            (false, r)
        } else {
            return Err(format!("broker {url:?}: give mqtt://HOST:PORT or mqtts://HOST:PORT"));
        };
        let rest = rest.trim_end_matches('/');
        let (host, port) = if let Some(v6) = rest.strip_prefix('[') {
            let (host, after) = v6.split_once(']').ok_or_else(|| format!("broker {url:?}: no ] after the address"))?;
            // After `]` only nothing or `:PORT`: anything else is not taken for the default port.
            let port = match after {
                "" => None,
                _ => Some(after.strip_prefix(':').ok_or_else(|| {
                    format!("broker {url:?}: unexpected {after:?} after [{host}]: give [ADDRESS] or [ADDRESS]:PORT")
                })?),
            };
            (host, port)
        } else if rest.matches(':').count() > 1 {
            // `::1` would read as host ":" and port 1.
            return Err(format!("broker {url:?}: an IPv6 address goes in brackets: mqtt://[ADDRESS]:PORT"));
        } else {
            match rest.rsplit_once(':') {
                Some((h, p)) => (h, Some(p)),
                None => (rest, None),
            }
        };
        if host.is_empty() || host.contains(['/', '@', '?', ' ']) {
            return Err(format!("broker {url:?}: no host name or address"));
        }
        let port = match port {
            None => {
                if tls {
                    8883
                } else {
                    1883
                }
            }
            Some(p) => p
                .parse::<u16>()
                .ok()
                .filter(|p| *p > 0)
                .ok_or_else(|| format!("broker {url:?}: the port must be a number from 1 to 65535"))?,
        };
        Ok(BrokerUrl { host: host.to_string(), port, tls })
    }

    /// True when the host is this machine: `localhost`, 127.0.0.0/8 or ::1 (a name is not resolved: only
    /// `localhost` counts).
    pub fn is_loopback(&self) -> bool {
        self.host.eq_ignore_ascii_case("localhost") || self.host.parse::<IpAddr>().is_ok_and(|a| a.is_loopback())
    }
}

impl std::fmt::Display for BrokerUrl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let scheme = if self.tls { "mqtts" } else { "mqtt" };
        match self.host.contains(':') {
            true => write!(f, "{scheme}://[{}]:{}", self.host, self.port),
            false => write!(f, "{scheme}://{}:{}", self.host, self.port),
        }
    }
}

/// One `[device.NAME]` table.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceEntry {
    /// The table's name: the device's topic level.
    pub name: String,
    /// `scu`, `powercube` or `compax`.
    pub family: String,
    /// The port, as `--port` takes it (`sim` for an emulator in the gateway's process).
    pub port: String,
    /// The other keys, as the file gives them (keys spelt with `-` are the same keys with `_`).
    pub options: BTreeMap<String, toml::Value>,
}

/// Everything the gateway runs with, checked.
#[derive(Debug, Clone)]
pub struct GatewayConfig {
    /// The gateway's topic level: `--name`, the file's `name`, else the host name.
    pub name: String,
    /// Where the broker is.
    pub broker: BrokerUrl,
    /// State messages per second while something moves (1..=100).
    pub sample_hz: u32,
    /// The CA certificate(s) (PEM) that sign the broker's certificate; without it the system's roots.
    pub ca_file: Option<PathBuf>,
    /// The user name and password for the broker.
    pub credentials: Option<(String, String)>,
    /// The devices, by name.
    pub devices: Vec<DeviceEntry>,
}

/// The file's `[gateway]` table.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct GatewayTable {
    name: Option<String>,
    broker: Option<String>,
    sample_hz: Option<i64>,
    ca_file: Option<PathBuf>,
    username: Option<String>,
    password_file: Option<PathBuf>,
}

/// Reads and checks the configuration: the file `options.config` names, the command line over it, the
/// password from `password_file` or [`PASSWORD_ENV`] (`env`), and the security rule (a broker off this
/// machine needs TLS unless `--insecure-broker`). Every failure is a usage error (exit 2), before anything
/// connects.
pub fn load(options: &Options, env: impl Fn(&str) -> Option<String>) -> Result<GatewayConfig, GatewayError> {
    let shown = options.config.display().to_string();
    let text = std::fs::read_to_string(&options.config)
        .map_err(|e| GatewayError::Usage(format!("cannot read {shown}: {e}")))?;
    parse(&text, &shown, options, env, |p| std::fs::read_to_string(p))
}

/// [`load`] of the file's `text` (named `shown` in messages), reading the password file with `read`.
pub fn parse(
    text: &str,
    shown: &str,
    options: &Options,
    env: impl Fn(&str) -> Option<String>,
    read: impl Fn(&Path) -> std::io::Result<String>,
) -> Result<GatewayConfig, GatewayError> {
    let usage = |m: String| GatewayError::Usage(format!("{shown}: {m}"));
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct File {
        #[serde(default)]
        gateway: Option<toml::Table>,
        #[serde(default)]
        device: BTreeMap<String, toml::Table>,
    }
    let file: File = toml::from_str(text).map_err(|e| usage(e.to_string().trim().to_string()))?;
    let mut table = file.gateway.unwrap_or_default();
    if table.contains_key("password") {
        return Err(usage(format!(
            "[gateway]: `password` is not taken from the file: name a file holding it with `password_file`, or \
             set {PASSWORD_ENV}"
        )));
    }
    // Keys spelt with `-` are the same keys.
    table = table.into_iter().map(|(k, v)| (k.replace('-', "_"), v)).collect();
    let gateway: GatewayTable = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| usage(format!("[gateway]: {}", e.to_string().trim())))?;
    let name = match options.name.clone().or(gateway.name) {
        Some(n) => n,
        None => host_name().ok_or_else(|| usage("[gateway]: no `name`, and the host name cannot be read".into()))?,
    };
    check_name(&name).map_err(|e| {
        // A name given on the command line is not the file's mistake.
        let said = format!("the gateway's name {name:?}: {e}");
        if options.name.is_some() {
            GatewayError::Usage(format!("--name: {said}"))
        } else {
            usage(said)
        }
    })?;
    let url =
        options.broker.clone().or(gateway.broker).ok_or_else(|| {
            usage("[gateway]: no `broker` (mqtt://HOST:PORT or mqtts://HOST:PORT; or --broker)".into())
        })?;
    let broker = BrokerUrl::parse(&url).map_err(GatewayError::Usage)?;
    if !broker.tls && !broker.is_loopback() && !options.insecure_broker {
        return Err(GatewayError::Usage(format!(
            "{broker} is not on this machine and has no TLS: the commands and the devices' states would cross \
             the network in the clear. Use mqtts://, or give --insecure-broker to accept that"
        )));
    }
    let sample_hz = match gateway.sample_hz {
        None => 10,
        Some(hz @ 1..=100) => hz as u32,
        Some(hz) => return Err(usage(format!("[gateway]: sample_hz = {hz}: give a whole number from 1 to 100"))),
    };
    if gateway.ca_file.is_some() && !broker.tls {
        return Err(usage(format!("[gateway]: ca_file is for a TLS broker (mqtts://), not {broker}")));
    }
    let password = match &gateway.password_file {
        Some(p) => Some(
            read(p)
                .map_err(|e| usage(format!("[gateway]: password_file {}: {e}", p.display())))?
                .trim_end_matches(['\r', '\n'])
                .to_string(),
        ),
        None => env(PASSWORD_ENV).filter(|p| !p.is_empty()),
    };
    let credentials = match (gateway.username, password) {
        (Some(u), Some(p)) => Some((u, p)),
        (Some(u), None) => Some((u, String::new())),
        (None, Some(_)) => {
            return Err(usage("[gateway]: a password without `username`: name the user the broker knows".into()))
        }
        (None, None) => None,
    };
    let mut devices = Vec::new();
    for (dev, table) in file.device {
        devices.push(device(&dev, table).map_err(|m| usage(format!("[device.{dev}]: {m}")))?);
    }
    if devices.is_empty() {
        return Err(usage("no [device.NAME] table: the gateway would serve nothing".into()));
    }
    one_table_per_port(&devices).map_err(usage)?;
    Ok(GatewayConfig { name, broker, sample_hz, ca_file: gateway.ca_file, credentials, devices })
}

/// One device table, its family and port taken out.
fn device(name: &str, table: toml::Table) -> Result<DeviceEntry, String> {
    check_name(name).map_err(|e| format!("the name {name:?}: {e}"))?;
    // The keys as devices.toml takes them (`-` as `_`, sim_variant as sim_variants, none twice).
    let mut options = motionlink_link::devices::options_of(table)?;
    let mut text_of = |key: &str| match options.remove(key) {
        Some(toml::Value::String(s)) => Ok(s),
        Some(other) => Err(format!("`{key}` must be a string, not {other}")),
        None => Err(format!("`{key}` is missing")),
    };
    let family = text_of("family")?;
    let port = text_of("port")?;
    if !FAMILIES.contains(&family.as_str()) {
        return Err(format!("family {family:?} is not scu, powercube or compax"));
    }
    Ok(DeviceEntry { name: name.to_string(), family, port, options })
}

/// Refuses two tables on one port (not `sim`, of which each table has its own emulator): the gateway opens a
/// session of its own for each table, and a port takes one session at a time (a serial port or a TCP serial
/// server is one line; on a CAN bus two sessions would see each other's frames and broadcasts). Ports are the
/// same as their locks are ([`motionlink_link::portlock::lock_key`]: `/dev/ttyUSB0` and a link to it, `HOST`
/// in any case); a port that does not parse is left to the device's own check.
fn one_table_per_port(devices: &[DeviceEntry]) -> Result<(), String> {
    use motionlink_link::url::PortUrl;
    let mut seen: BTreeMap<String, &DeviceEntry> = BTreeMap::new();
    for d in devices {
        let Ok(url) = d.port.parse::<PortUrl>() else { continue };
        if url == PortUrl::Sim {
            continue;
        }
        let key = motionlink_link::portlock::lock_key(&url).unwrap_or_else(|| url.to_string());
        if let Some(first) = seen.insert(key, d) {
            let same = if first.port == d.port { String::new() } else { format!(" (as {:?})", first.port) };
            return Err(format!(
                "[device.{}] and [device.{}] both name the port {:?}{same}: a gateway serves one device per port \
                 (it opens a session of its own for each table, and a port takes one session at a time), so two \
                 drives or modules of one bus cannot both be served; remove one of the tables, or give each \
                 device a port (a line) of its own",
                first.name, d.name, d.port
            ));
        }
    }
    Ok(())
}

/// This machine's host name, if it can be read.
pub fn host_name() -> Option<String> {
    #[cfg(unix)]
    {
        let mut buf = [0u8; 256];
        // SAFETY: the buffer is valid for its length; gethostname writes at most that many bytes.
        let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
        if rc == 0 {
            let end = buf.iter().position(|b| *b == 0).unwrap_or(buf.len());
            let name = String::from_utf8_lossy(&buf[..end]).trim().to_string();
            if !name.is_empty() {
                return Some(name);
            }
        }
        None
    }
    #[cfg(not(unix))]
    {
        std::env::var("COMPUTERNAME").ok().filter(|n| !n.is_empty())
    }
}

#[cfg(test)]
mod tests;
