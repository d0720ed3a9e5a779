//! The pieces of a commissioning report (`motionlink probe`) that every family shares: the report's shape
//! ([`ProbeReport`]), one row per check ([`Check`]), what was measured on the link ([`LinkReport`],
//! [`RoundTrips`]), the latency timer of a USB serial adapter on Linux ([`latency_timer`]) and the search for
//! the baud rate a device answers at ([`find_baud`]).
//!
//! A probe only reads, echoes a read, or writes a value the device already holds: nothing moves. Each family's
//! `probe` module runs its checks on an open client and returns a [`ProbeReport`] of its own device type; the
//! command line, the console and Python print or return it as it is.

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Serialize;

/// What a check found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CheckResult {
    /// The device does what the client relies on (or the link is as it should be).
    Ok,
    /// The device does not: the client runs the manual's plain form for it and says what it cannot verify.
    Unsupported,
    /// The check could not be made, or found something that needs fixing (the detail says what).
    Failed,
    /// Not checked: no harmless probe can settle it, it does not apply to this port, or an earlier finding
    /// leaves nothing to probe (the detail says which).
    Skipped,
}

impl CheckResult {
    /// The JSON name: `ok`, `unsupported`, `failed` or `skipped`.
    pub fn name(self) -> &'static str {
        match self {
            CheckResult::Ok => "ok",
            CheckResult::Unsupported => "unsupported",
            CheckResult::Failed => "failed",
            CheckResult::Skipped => "skipped",
        }
    }
}

impl Display for CheckResult {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One row of a report: a behaviour, what was found, and what the probe sent to find it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    /// The behaviour's name (`grouping_indices`, `echo_form`, `latency_timer`...).
    pub name: &'static str,
    /// The device (module or drive address) on a bus; absent for a whole unit or the link.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub address: Option<u8>,
    /// What was found.
    pub result: CheckResult,
    /// In words: what the device did, and what follows for the client.
    pub detail: String,
    /// What the probe sends (never anything that moves); empty when it sends nothing.
    pub sends: &'static str,
    /// The emulator variant (`motionlink sim FAMILY --variant NAME`) whose device behaves otherwise, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variant: Option<&'static str>,
}

impl Check {
    /// A check of the whole unit or link.
    pub fn new(name: &'static str, result: CheckResult, detail: impl Into<String>) -> Check {
        Check { name, address: None, result, detail: detail.into(), sends: "", variant: None }
    }

    /// The same check, of the device at `address`.
    pub fn at(mut self, address: u8) -> Check {
        self.address = Some(address);
        self
    }

    /// The same check, naming what its probe sends.
    pub fn sending(mut self, sends: &'static str) -> Check {
        self.sends = sends;
        self
    }

    /// The same check, naming the emulator variant that behaves otherwise.
    pub fn variant(mut self, variant: &'static str) -> Check {
        self.variant = Some(variant);
        self
    }
}

/// A commissioning report: what is on the line, how the link behaves, and every check. `D` is the family's
/// device (the SCU unit, a PowerCube module, a COMPAX drive) with its identity and what was probed.
#[derive(Debug, Clone, Serialize)]
pub struct ProbeReport<D> {
    /// `scu`, `powercube` or `compax`.
    pub family: &'static str,
    /// The port, as given.
    pub port: String,
    /// What answered.
    pub devices: Vec<D>,
    /// What was measured on the link.
    pub link: LinkReport,
    /// Every check, in the order they were made.
    pub checks: Vec<Check>,
    /// The profiles written with `--save` (`<path>#<key>`), one per device; empty when none was saved.
    pub saved: Vec<String>,
}

impl<D> ProbeReport<D> {
    /// The check named `name` (of the device at `address`, on a bus).
    pub fn check(&self, name: &str, address: Option<u8>) -> Option<&Check> {
        self.checks.iter().find(|c| c.name == name && c.address == address)
    }
}

/// What kind of port a report is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PortKind {
    /// A serial device: the baud rate and a USB adapter's latency timer apply.
    Serial,
    /// A TCP byte stream (a serial gateway or an emulator server): the gateway sets the baud rate.
    Tcp,
    /// An emulator in this process.
    Sim,
    /// A CAN interface or adapter.
    Can,
}

impl PortKind {
    /// The kind of `port`.
    pub fn of(port: &crate::url::PortUrl) -> PortKind {
        use crate::url::PortUrl;
        match port {
            PortUrl::Serial(_) => PortKind::Serial,
            PortUrl::Tcp { .. } => PortKind::Tcp,
            PortUrl::Sim => PortKind::Sim,
            PortUrl::SocketCan(_) | PortUrl::Slcan(_) => PortKind::Can,
        }
    }

    /// Why a baud rate does not apply to this kind of port (`None` for a serial port).
    pub fn no_baud(self) -> Option<&'static str> {
        match self {
            PortKind::Serial => None,
            PortKind::Tcp => Some("a tcp:// port: the gateway (or emulator) behind it sets the line's baud rate"),
            PortKind::Sim => Some("an emulator in this process: there is no line"),
            PortKind::Can => Some("a CAN port: the bit rate is the interface's"),
        }
    }
}

/// Round trips in milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RoundTripMs {
    /// The shortest.
    pub min: f64,
    /// The mean.
    pub mean: f64,
    /// The longest.
    pub max: f64,
}

/// What was measured on the link: round trips and errors over a number of exchanges (each a read the
/// device answers), the baud rate and, for a USB serial adapter on Linux, its latency timer.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinkReport {
    /// The kind of port.
    pub kind: PortKind,
    /// The baud rate of a serial line (the one that answered, with `--baud auto`); `None` where none
    /// applies.
    pub baud: Option<u32>,
    /// Exchanges made to measure the link.
    pub exchanges: u32,
    /// Of those, how many failed (no reply, a corrupt one, a refusal).
    pub errors: u32,
    /// Requests the client sent again during the measurement (after silence or a corrupt reply).
    pub retries: u64,
    /// The round trips of the exchanges that succeeded, as the caller sees them (request to reply);
    /// `None` when none did.
    pub round_trip_ms: Option<RoundTripMs>,
    /// The adapter's latency timer, where the port is a USB serial adapter on Linux.
    pub latency_timer: Option<LatencyTimer>,
}

/// Collects round trips and errors.
#[derive(Debug, Clone, Default)]
pub struct RoundTrips {
    times: Vec<Duration>,
    errors: u32,
}

impl RoundTrips {
    /// One exchange that took `d`.
    pub fn add(&mut self, d: Duration) {
        self.times.push(d);
    }

    /// One exchange that failed.
    pub fn failed(&mut self) {
        self.errors += 1;
    }

    /// Times `exchange` `n` times on `clock`, counting its errors.
    pub fn measure<T, E>(
        &mut self,
        clock: &dyn crate::clock::Clock,
        n: u32,
        mut exchange: impl FnMut() -> Result<T, E>,
    ) {
        for _ in 0..n {
            let start = clock.now();
            match exchange() {
                Ok(_) => self.add(clock.now().saturating_since(start)),
                Err(_) => self.failed(),
            }
        }
    }

    /// Exchanges counted so far.
    pub fn exchanges(&self) -> u32 {
        self.times.len() as u32 + self.errors
    }

    /// Failed exchanges.
    pub fn errors(&self) -> u32 {
        self.errors
    }

    /// Shortest, mean and longest round trip in ms, if any exchange succeeded.
    pub fn summary(&self) -> Option<RoundTripMs> {
        let ms = |d: &Duration| d.as_secs_f64() * 1000.0;
        let min = self.times.iter().map(ms).fold(f64::INFINITY, f64::min);
        let max = self.times.iter().map(ms).fold(0.0, f64::max);
        let n = self.times.len();
        (n > 0).then(|| RoundTripMs { min, mean: self.times.iter().map(ms).sum::<f64>() / n as f64, max })
    }
}

/// The latency timer of a USB serial adapter (Linux `usb-serial` devices such as FTDI chips): how long the
/// adapter holds received bytes before it sends a partial packet to the host. 16 ms by default on FTDI
/// chips, which turns an exchange of a few ms into about 20.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LatencyTimer {
    /// The sysfs file.
    pub path: String,
    /// Its value when read, in ms.
    pub ms: u32,
    /// The value written by `--low-latency` (1), when the write succeeded.
    pub set_to_ms: Option<u32>,
    /// Why `--low-latency` could not write it (permissions), when it could not.
    pub set_error: Option<String>,
    /// The command that sets it to 1 ms until the adapter is plugged in again, when it is above that.
    pub fix: Option<String>,
}

/// The latency timer worth having, in ms; above it a report says how to set it.
pub const LOW_LATENCY_MS: u32 = 1;

/// The environment variable that moves the root of sysfs (for tests): `MOTIONLINK_SYSFS_ROOT=/tmp/x` reads
/// `/tmp/x/sys/bus/usb-serial/...`.
pub const SYSFS_ROOT_VAR: &str = "MOTIONLINK_SYSFS_ROOT";

/// The root sysfs lies under: `MOTIONLINK_SYSFS_ROOT`, else `/`.
pub fn sysfs_root() -> PathBuf {
    std::env::var_os(SYSFS_ROOT_VAR).map(PathBuf::from).unwrap_or_else(|| PathBuf::from("/"))
}

/// Where the latency timer of serial port `port` (`/dev/ttyUSB0`, or a link to it such as
/// `/dev/serial/by-id/...`) would be under `root`: `sys/bus/usb-serial/devices/ttyUSB0/latency_timer`, else
/// `sys/class/tty/ttyUSB0/device/latency_timer`; `None` when neither exists (not a USB serial adapter).
pub fn latency_timer_path(root: &Path, port: &str) -> Option<PathBuf> {
    let given = Path::new(port);
    let real = std::fs::canonicalize(given).unwrap_or_else(|_| given.to_path_buf());
    let name = real.file_name()?.to_str()?.to_string();
    [
        root.join("sys/bus/usb-serial/devices").join(&name).join("latency_timer"),
        root.join("sys/class/tty").join(&name).join("device/latency_timer"),
    ]
    .into_iter()
    .find(|p| p.is_file())
}

/// Reads the latency timer of serial port `port` under sysfs `root`, and with `set_low` writes
/// [`LOW_LATENCY_MS`] where it is higher (saying so, or why it could not). `None`: `port` has no latency
/// timer (not a USB serial adapter, or not Linux); `Err`: the file exists but could not be read.
pub fn latency_timer(root: &Path, port: &str, set_low: bool) -> Option<Result<LatencyTimer, String>> {
    let path = latency_timer_path(root, port)?;
    let shown = path.display().to_string();
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) => return Some(Err(format!("cannot read {shown}: {e}"))),
    };
    let ms = match text.trim().parse::<u32>() {
        Ok(ms) => ms,
        Err(_) => return Some(Err(format!("{shown} holds {:?}, not a number of ms", text.trim()))),
    };
    let mut timer = LatencyTimer { path: shown.clone(), ms, set_to_ms: None, set_error: None, fix: None };
    if ms > LOW_LATENCY_MS {
        if set_low {
            match std::fs::write(&path, format!("{LOW_LATENCY_MS}\n")) {
                Ok(()) => timer.set_to_ms = Some(LOW_LATENCY_MS),
                Err(e) => timer.set_error = Some(format!("cannot write {shown}: {e}")),
            }
        }
        if timer.set_to_ms.is_none() {
            timer.fix = Some(format!("echo {LOW_LATENCY_MS} | sudo tee {shown}"));
        }
    }
    Some(Ok(timer))
}

/// The `latency_timer` check of a port of `kind` named `port`, reading (and with `set_low` lowering) the
/// timer under sysfs `root`; also returns the timer for the [`LinkReport`].
pub fn latency_check(root: &Path, kind: PortKind, port: &str, set_low: bool) -> (Check, Option<LatencyTimer>) {
    const NAME: &str = "latency_timer";
    const SENDS: &str = "nothing: reads /sys/bus/usb-serial/devices/<tty>/latency_timer (--low-latency writes 1)";
    let why = match kind {
        PortKind::Serial => None,
        PortKind::Tcp => Some("a tcp:// port: a USB adapter's latency timer, if any, is the gateway's"),
        PortKind::Sim => Some("an emulator in this process: there is no line"),
        PortKind::Can => Some("a CAN port: no USB serial adapter's timer applies"),
    };
    if let Some(why) = why {
        return (Check::new(NAME, CheckResult::Skipped, format!("not a serial port: {why}")).sending(SENDS), None);
    }
    let timer = match latency_timer(root, port, set_low) {
        None => {
            let detail = format!("{port} has no latency timer (not a USB serial adapter, or not Linux)");
            return (Check::new(NAME, CheckResult::Skipped, detail).sending(SENDS), None);
        }
        Some(Err(e)) => return (Check::new(NAME, CheckResult::Failed, e).sending(SENDS), None),
        Some(Ok(t)) => t,
    };
    let (result, detail) = match (&timer.set_to_ms, &timer.set_error) {
        (Some(set), _) => (
            CheckResult::Ok,
            format!(
                "was {} ms, set to {set} ms (until the adapter is plugged in again; a udev rule keeps it)",
                timer.ms
            ),
        ),
        (None, _) if timer.ms <= LOW_LATENCY_MS => (CheckResult::Ok, format!("{} ms", timer.ms)),
        (None, error) => (
            CheckResult::Failed,
            format!(
                "{} ms: the adapter holds each reply up to {} ms before passing it on (16 ms is an FTDI chip's \
                 default, which turns a 4.4 ms SCU exchange into about 20 ms){}; fix: `{}` or `--low-latency`",
                timer.ms,
                timer.ms,
                error.as_ref().map(|e| format!("; --low-latency: {e}")).unwrap_or_default(),
                timer.fix.as_deref().unwrap_or_default()
            ),
        ),
    };
    (Check::new(NAME, result, detail).sending(SENDS), Some(timer))
}

/// How a probe is to be made on the link: what the family's `probe` function needs besides the client.
#[derive(Debug, Clone)]
pub struct ProbeSetup {
    /// The port, as given.
    pub port: String,
    /// Its kind.
    pub kind: PortKind,
    /// The line's baud rate (serial ports).
    pub baud: Option<u32>,
    /// The `baud` check of [`find_baud`], when the session was opened through it (else the rate counts as
    /// given).
    pub baud_check: Option<Check>,
    /// Exchanges that measure the link (round trips, errors).
    pub exchanges: u32,
    /// Where sysfs lies ([`sysfs_root`]).
    pub sysfs_root: PathBuf,
    /// Set a USB serial adapter's latency timer to 1 ms where it is higher (`--low-latency`).
    pub low_latency: bool,
}

impl ProbeSetup {
    /// Exchanges made to measure a link, unless told otherwise.
    pub const DEFAULT_EXCHANGES: u32 = 20;
    /// How many exchanges a probe may be asked to make (every front end's rule).
    pub const EXCHANGES: std::ops::RangeInclusive<u32> = 1..=1000;

    /// A probe of `port` at `baud` (kept for serial ports only), with the defaults: 20 exchanges, sysfs at
    /// [`sysfs_root`], the latency timer left as it is.
    pub fn new(port: &str, kind: PortKind, baud: u32) -> ProbeSetup {
        ProbeSetup {
            port: port.to_string(),
            kind,
            baud: (kind == PortKind::Serial).then_some(baud),
            baud_check: None,
            exchanges: Self::DEFAULT_EXCHANGES,
            sysfs_root: sysfs_root(),
            low_latency: false,
        }
    }

    /// The checks of the link that come before the device's: the baud rate and the latency timer; and the
    /// timer, for the [`LinkReport`].
    pub fn link_checks(&self) -> (Vec<Check>, Option<LatencyTimer>) {
        let baud = self.baud_check.clone().unwrap_or_else(|| {
            let (_, check) = find_baud(self.kind, &BaudChoice::Given(self.baud.unwrap_or(0)), Ok::<_, String>);
            check
        });
        let (latency, timer) = latency_check(&self.sysfs_root, self.kind, &self.port, self.low_latency);
        (vec![baud, latency], timer)
    }

    /// The [`LinkReport`] of the measured `trips` (with `retries` sent meanwhile) and `timer`.
    pub fn link_report(&self, trips: &RoundTrips, retries: u64, timer: Option<LatencyTimer>) -> LinkReport {
        LinkReport {
            kind: self.kind,
            baud: self.baud,
            exchanges: trips.exchanges(),
            errors: trips.errors(),
            retries,
            round_trip_ms: trips.summary(),
            latency_timer: timer,
        }
    }
}

/// How the baud rate of a report was chosen.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BaudChoice {
    /// The rate given.
    Given(u32),
    /// Try `rates` in order (`--baud auto`) and take the first that answers.
    Auto(&'static [u32]),
}

impl BaudChoice {
    /// `auto` (every rate of `rates`, in order) or one of `rates`; the error names them. `family` names the
    /// device in the message ("an SCU").
    pub fn parse(text: &str, rates: &'static [u32], family: &str) -> Result<BaudChoice, String> {
        let t = text.trim();
        if t.eq_ignore_ascii_case("auto") {
            return Ok(BaudChoice::Auto(rates));
        }
        match t.parse::<u32>() {
            Ok(b) if rates.contains(&b) => Ok(BaudChoice::Given(b)),
            _ => {
                let list: Vec<String> = rates.iter().map(u32::to_string).collect();
                Err(format!("{text:?}: {family} runs at {}, or give auto to try each", list.join(", ")))
            }
        }
    }

    /// The first rate tried.
    pub fn first(&self) -> u32 {
        match self {
            BaudChoice::Given(b) => *b,
            BaudChoice::Auto(rates) => rates.first().copied().unwrap_or(0),
        }
    }
}

/// Opens a session at each rate of `choice` in turn with `open` until one answers. Returns the session and
/// its rate (`None` when none answered) and the `baud` check saying what was tried. Over a port without a
/// baud rate (`kind` other than serial) only the first rate is tried and the check is skipped, saying why.
/// `open`'s last error is returned when nothing answered (the check says so too).
pub fn find_baud<C, E: Display>(
    kind: PortKind,
    choice: &BaudChoice,
    mut open: impl FnMut(u32) -> Result<C, E>,
) -> (Result<(C, u32), E>, Check) {
    const NAME: &str = "baud";
    const SENDS: &str = "the session's opening at each rate tried (--baud auto)";
    let rates: Vec<u32> = match choice {
        BaudChoice::Given(b) => vec![*b],
        BaudChoice::Auto(rates) => rates.to_vec(),
    };
    if let Some(why) = kind.no_baud() {
        let first = rates.first().copied().unwrap_or(0);
        let opened = open(first).map(|c| (c, first));
        return (opened, Check::new(NAME, CheckResult::Skipped, format!("no baud rate: {why}")).sending(SENDS));
    }
    let mut tried = Vec::new();
    let mut last = None;
    for rate in rates {
        match open(rate) {
            Ok(c) => {
                let detail = match choice {
                    BaudChoice::Given(_) => format!("answers at {rate} baud (as given)"),
                    BaudChoice::Auto(_) if tried.is_empty() => format!("answers at {rate} baud (the first tried)"),
                    BaudChoice::Auto(_) => format!("answers at {rate} baud; {}", tried.join("; ")),
                };
                return (Ok((c, rate)), Check::new(NAME, CheckResult::Ok, detail).sending(SENDS));
            }
            Err(e) => {
                tried.push(format!("{rate}: {e}"));
                last = Some(e);
            }
        }
    }
    let detail = format!("no answer at any rate tried: {}", tried.join("; "));
    let e = last.expect("at least one rate is tried");
    (Err(e), Check::new(NAME, CheckResult::Failed, detail).sending(SENDS))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fake_sysfs(ms: &str) -> (PathBuf, PathBuf) {
        let root = std::env::temp_dir().join(format!("motionlink-sysfs-{}-{}", std::process::id(), ms.trim()));
        let dir = root.join("sys/bus/usb-serial/devices/ttyUSB7");
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("latency_timer");
        std::fs::write(&file, ms).unwrap();
        (root, file)
    }

    #[test]
    fn a_16_ms_latency_timer_fails_with_the_fix_and_low_latency_sets_1() {
        let (root, file) = fake_sysfs("16\n");
        let (check, timer) = latency_check(&root, PortKind::Serial, "/dev/ttyUSB7", false);
        assert_eq!(check.result, CheckResult::Failed, "{check:?}");
        let timer = timer.unwrap();
        assert_eq!(timer.ms, 16);
        assert_eq!(timer.fix.as_deref(), Some(format!("echo 1 | sudo tee {}", file.display()).as_str()));
        assert!(check.detail.contains("--low-latency") && check.detail.contains("16 ms"), "{}", check.detail);
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "16\n", "nothing written without --low-latency");
        let (check, timer) = latency_check(&root, PortKind::Serial, "/dev/ttyUSB7", true);
        assert_eq!((check.result, timer.unwrap().set_to_ms), (CheckResult::Ok, Some(1)), "{check:?}");
        assert_eq!(std::fs::read_to_string(&file).unwrap().trim(), "1");
        let (check, _) = latency_check(&root, PortKind::Serial, "/dev/ttyUSB7", false);
        assert_eq!((check.result, check.detail.as_str()), (CheckResult::Ok, "1 ms"));
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn other_ports_have_no_latency_timer_and_bad_contents_fail() {
        let (root, _) = fake_sysfs("fast");
        let (check, _) = latency_check(&root, PortKind::Serial, "/dev/ttyUSB7", false);
        assert_eq!(check.result, CheckResult::Failed);
        assert!(check.detail.contains("not a number"), "{}", check.detail);
        let (check, t) = latency_check(&root, PortKind::Serial, "/dev/ttyS0", false);
        assert_eq!((check.result, t), (CheckResult::Skipped, None));
        let (check, _) = latency_check(&root, PortKind::Tcp, "tcp://127.0.0.1:1", false);
        assert!(check.result == CheckResult::Skipped && check.detail.contains("latency timer"), "{check:?}");
        assert!(!check.detail.contains("baud"), "{check:?}");
        std::fs::remove_dir_all(root).unwrap();
    }

    #[test]
    fn the_baud_search_takes_the_first_rate_that_answers_and_says_what_failed() {
        let open = |b: u32| if b == 19_200 { Ok(b) } else { Err(format!("no answer at {b}")) };
        let (got, check) = find_baud(PortKind::Serial, &BaudChoice::Auto(&[38_400, 19_200, 9_600]), open);
        assert_eq!(got.unwrap(), (19_200, 19_200));
        assert_eq!(check.result, CheckResult::Ok);
        assert!(check.detail.contains("38400: no answer"), "{}", check.detail);
        let (got, check) = find_baud(PortKind::Serial, &BaudChoice::Auto(&[38_400, 9_600]), open);
        assert!(got.is_err() && check.result == CheckResult::Failed, "{check:?}");
        let mut tried = Vec::new();
        let (got, check) = find_baud(PortKind::Tcp, &BaudChoice::Auto(&[38_400, 9_600]), |b| {
            tried.push(b);
            Ok::<_, String>(b)
        });
        assert_eq!((got.unwrap().1, check.result, tried), (38_400, CheckResult::Skipped, vec![38_400]));
    }

    #[test]
    fn round_trips_summarise_and_count_errors() {
        let mut r = RoundTrips::default();
        assert_eq!(r.summary(), None);
        r.add(Duration::from_millis(4));
        r.add(Duration::from_millis(6));
        r.failed();
        let s = r.summary().unwrap();
        assert_eq!((s.min, s.mean, s.max, r.exchanges(), r.errors()), (4.0, 5.0, 6.0, 3, 1));
    }
}
