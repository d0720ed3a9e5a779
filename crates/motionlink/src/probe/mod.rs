//! `motionlink probe <family>`: commissioning. The family crates' `probe` modules do the work and return a
//! report ([`motionlink_link::probe::ProbeReport`]); this module parses the options, opens the port, prints
//! the report as text or one JSON object, and writes the device profile with `--save`. It also loads the
//! profiles for every other family command ([`use_profile`]).

use std::io::Write;

use motionlink_link::error::Classify;
use motionlink_link::probe::{BaudChoice, Check, CheckResult, PortKind, ProbeReport, ProbeSetup};
use motionlink_link::profile::{ProfileError, ProfileUse, Profiles};
use motionlink_link::url::PortUrl;
use serde::Serialize;

use crate::common::{self, CliError};

mod compax;
mod powercube;
mod scu;

/// `motionlink probe` families.
#[derive(clap::Subcommand, Debug)]
pub enum Family {
    /// Probe an SCU control unit: its firmware and configuration texts (the edition they name), the link,
    /// and what the unit does where the manual leaves it open.
    ///
    /// What is sent (nothing moves): RO and RC (the session), RG of 0x0001 and 0x0002 (identity), RG of
    /// 0x0171 N times (the link), RG of 0x0170 (grouping indices), RG of 0x2001.. (UserPositionData of each
    /// connected actuator), the session's cyclic object as `watch` defines it (RT of CyclicObj 5, volatile
    /// remote data that only selects what an RC reads, its RG back, one RC carrying it and one more that takes a
    /// sample as `watch` does; else RG of 0x3011),
    /// then RA. `--baud auto` opens the session at 38400, 19200 and 9600 in turn.
    ///
    /// Every check is named in `docs/commissioning.md`; each behaviour has an emulator variant
    /// (`motionlink sim scu --variant NAME`, `--sim-variant NAME` with `--port sim`) whose unit shows it as
    /// unsupported. `--save` writes a device profile (profiles.toml beside devices.toml) that later sessions
    /// on this port load when the unit gives the same firmware and configuration texts.
    Scu(scu::Args),
    /// Probe a bus of PowerCube modules: modules 1..31 with their kind, version and serial number, the link,
    /// and what each module does where the manual leaves it open.
    ///
    /// What is sent (nothing moves): GetExtended of DefCubeVersion (0x1D) to each address (the scan), then of
    /// the Config word, serial number and CubeState of each module found (identity), CubeState N times (the
    /// link), ActFPosStateDio (0x62) and the Config word once more of each module. The Inc twins, the RS232
    /// broadcast refresh and the life sign's acknowledge are not probed: each needs a write of another value
    /// or an armed watchdog.
    ///
    /// Each behaviour has an emulator variant (`motionlink sim powercube --variant NAME`). `--save` writes
    /// one profile per module (profiles.toml beside devices.toml), loaded by later sessions when the module
    /// gives the same version and serial number.
    Powercube(powercube::Args),
    /// Probe a bus of COMPAX drives: the drives at addresses 1..31 (or --drives), their identification
    /// texts and P194..P196 (P196: the operating mode), the link, and how each echoes.
    ///
    /// What is sent (nothing moves): S1 to each address (the scan), S1 N + 1 times to the first drive found
    /// (the link, and the status value's form), then to each drive S31 and S32 (identification), P194, P195
    /// and P196 (reads), S1 with `?` (an echo of a read: a drive does not execute what it echoes) twice at
    /// most, with a plain S1 between. Storing a command (`,`) is not probed.
    ///
    /// Each behaviour has an emulator variant (`motionlink sim compax --variant NAME`). `--save` writes one
    /// profile per drive (profiles.toml beside devices.toml), loaded by later sessions when the drive gives
    /// the same identification texts.
    Compax(compax::Args),
}

/// What every family's probe takes besides the port.
#[derive(clap::Args, Debug, Clone)]
pub struct Options {
    /// Write a device profile (profiles.toml beside devices.toml, one entry per port and device identity):
    /// later sessions on this port whose device gives the same identity take its findings and skip those
    /// probes; their --json results name it ("profile": "<path>#<key>").
    #[allow(rustdoc::invalid_html_tags)] // the text is the help of `--save`, not HTML
    #[arg(long)]
    pub save: bool,
    /// Set a USB serial adapter's latency timer to 1 ms where it is higher (Linux: writes
    /// /sys/bus/usb-serial/devices/<tty>/latency_timer; needs the right to write it, and lasts until the
    /// adapter is plugged in again). Without it the report gives the fix.
    #[allow(rustdoc::invalid_html_tags)] // the text is the help of `--low-latency`, not HTML
    #[arg(long)]
    pub low_latency: bool,
    /// Exchanges that measure the link (round trips and errors), 1..=1000.
    #[arg(long, default_value_t = ProbeSetup::DEFAULT_EXCHANGES, value_name = "N",
          value_parser = clap::value_parser!(u32).range(i64::from(*ProbeSetup::EXCHANGES.start())..=i64::from(*ProbeSetup::EXCHANGES.end())))]
    pub exchanges: u32,
}

/// `motionlink probe <family> ...`
pub fn run(family: Family, json: bool) -> Result<(), CliError> {
    match family {
        Family::Scu(args) => scu::run(args, json),
        Family::Powercube(args) => powercube::run(args, json),
        Family::Compax(args) => compax::run(args, json),
    }
}

/// The setup of a probe of `port` (as given) at `baud`, with `options`.
fn setup(port: &str, baud: u32, options: &Options) -> Result<(ProbeSetup, PortUrl), CliError> {
    let url: PortUrl = port.parse()?;
    let mut setup = ProbeSetup::new(port, PortKind::of(&url), baud);
    setup.exchanges = options.exchanges;
    setup.low_latency = options.low_latency;
    Ok((setup, url))
}

/// The error of a probe whose session could not be opened: with `--baud auto`, naming every rate tried.
fn not_found(e: CliError, choice: &BaudChoice, check: &Check) -> CliError {
    match choice {
        BaudChoice::Auto(_) if check.result == CheckResult::Failed => e.map_message(|_| check.detail.clone()),
        _ => e,
    }
}

/// The profiles file `--save` writes.
fn profiles_for_save() -> Result<Profiles, CliError> {
    let Some(path) = motionlink_link::profile::profiles_path() else {
        return Err(CliError::usage("--save: no configuration directory is known (set MOTIONLINK_CONFIG)"));
    };
    Profiles::load(&path).map_err(|e| CliError::usage(format!("--save: {e}")))
}

/// Ends a probe: the session's end (`closed`) checked, the report saved as profiles with `--save` (by the
/// family's `save`), then printed ([`print_report`]).
fn finish<D: Serialize, E: Classify + std::fmt::Display, C>(
    (report, closed): (Result<ProbeReport<D>, E>, Result<C, E>),
    options: &Options,
    save: fn(&mut ProbeReport<D>, &mut Profiles) -> Result<(), ProfileError>,
    json: bool,
    device: impl Fn(&D) -> String,
) -> Result<(), CliError> {
    let mut report = report.map_err(|e| common::classified(&e))?;
    closed.map_err(|e| common::classified(&e))?;
    if options.save {
        save(&mut report, &mut profiles_for_save()?).map_err(|e| CliError::usage(format!("--save: {e}")))?;
    }
    print_report(&report, json, device, &mut std::io::stdout().lock())
}

/// Prints `report` (one JSON object with `--json`, else text with `device` giving each device's lines), and
/// ends with exit code 1 when a check failed.
fn print_report<D: Serialize>(
    report: &ProbeReport<D>,
    json: bool,
    device: impl Fn(&D) -> String,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    if json {
        let value = serde_json::to_value(report).map_err(|e| CliError::Device(format!("the report: {e}")))?;
        common::print_json(out, &value)?;
    } else {
        writeln!(out, "{} on {}", report.family, report.port)?;
        if report.devices.is_empty() {
            writeln!(out, "  no device answered")?;
        }
        for d in &report.devices {
            writeln!(out, "  {}", device(d))?;
        }
        let l = &report.link;
        let baud = l.baud.map(|b| format!(" at {b} baud")).unwrap_or_default();
        let trips = match &l.round_trip_ms {
            Some(r) => format!("round trip {:.1} / {:.1} / {:.1} ms (min / mean / max)", r.min, r.mean, r.max),
            None => "no round trip measured".into(),
        };
        writeln!(
            out,
            "link: {}{baud}, {} exchanges, {} errors, {} repeated; {trips}",
            serde_json::to_value(l.kind).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default(),
            l.exchanges,
            l.errors,
            l.retries
        )?;
        let width = report.checks.iter().map(|c| c.name.len() + c.address.map_or(0, |_| 4)).max().unwrap_or(0);
        for c in &report.checks {
            let name = match c.address {
                Some(a) => format!("{} @{a:<2}", c.name),
                None => c.name.to_string(),
            };
            writeln!(out, "  {:<11}  {name:<width$}  {}", c.result.name(), c.detail)?;
        }
        for s in &report.saved {
            writeln!(out, "saved: {s}")?;
        }
    }
    out.flush()?;
    let failed: Vec<String> = report
        .checks
        .iter()
        .filter(|c| c.result == CheckResult::Failed)
        .map(|c| c.address.map_or(c.name.to_string(), |a| format!("{} of {a}", c.name)))
        .collect();
    if failed.is_empty() {
        Ok(())
    } else {
        Err(CliError::Device(format!("{} check(s) failed: {}", failed.len(), failed.join(", "))))
    }
}

/// The device profiles (profiles.toml beside devices.toml): `None` where there is no file, or one that
/// cannot be read (said on stderr: the session then probes as without it).
pub fn profiles() -> Option<Profiles> {
    Profiles::load_default().unwrap_or_else(|e| {
        crate::term::note(&format!("device profiles not used: {e}"));
        None
    })
}

/// For a family command that opened a session on a port: loads the profiles (profiles.toml beside
/// devices.toml) and lets `apply` seed the session from the one of its device. Its notices go to stderr,
/// and the profile used (or null) goes into every `--json` result of the command. A file that cannot be
/// read is said and left alone: the session then probes as without it.
pub fn use_profile<E: Classify + std::fmt::Display>(
    apply: impl FnOnce(&Profiles) -> Result<ProfileUse, E>,
) -> Result<(), CliError> {
    let used = match profiles() {
        Some(profiles) => apply(&profiles).map_err(|e| common::classified(&e))?,
        None => ProfileUse::default(),
    };
    for n in &used.notices {
        crate::term::note(n);
    }
    common::set_profile(used.reference);
    Ok(())
}
