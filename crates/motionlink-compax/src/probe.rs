//! Commissioning (`motionlink probe compax`): the drives on the bus with their identification and interface
//! parameters (P194 address, P195 baud rate, P196 operating mode), how the link behaves, and every behaviour
//! beyond the manual's words that a harmless exchange can settle ([`probe`]); and the device profile of each
//! drive that lets a later session skip those probes ([`save_profile`], [`use_profile`]).
//!
//! Nothing moves. What is sent: S1 to each address asked for (the scan), then to the first drive found S1
//! once as it is (its reply shows the status value's form) and [`ProbeSetup::exchanges`] times more (the
//! link), then to each drive found S31 and S32 (identification), P194, P195 and P196 (reads), and S1 with
//! `?` (an echo
//! of a read, which a drive does not execute; at most twice, a plain S1 between) for the echo form. Storing
//! a command (`,`) replaces the drive's buffer and is not probed.

use motionlink_link::probe::{Check, CheckResult, ProbeReport, ProbeSetup, RoundTrips};
use motionlink_link::profile::{Lookup, ProfileEntry, ProfileError, ProfileUse, Profiles};

use crate::client::Client;
use crate::error::Error;
use crate::model::{ParamId, StatusId, StatusValue, BAUD_RATES};
use crate::session::{EchoForm, Op};
use crate::wire::Address;

/// The family's name in reports and profiles.
pub const FAMILY: &str = "compax";

/// `--baud` of a probe: `auto` (every rate P195 accepts, 9600 first) or one of them.
pub fn baud_choice(text: &str) -> Result<motionlink_link::probe::BaudChoice, String> {
    motionlink_link::probe::BaudChoice::parse(text, AUTO_BAUD_RATES, "a COMPAX drive (P195)")
}

/// The rates `--baud auto` tries: P195's, the default (9600) first, then the faster ones, then the slower.
pub const AUTO_BAUD_RATES: &[u32] = &[9_600, 19_200, 38_400, 57_600, 115_200, 4_800, 2_400, 1_200, 600, 300, 150];

/// `--drives` of a probe: addresses 1..31 as a list (`1,3`), ranges (`1-8`) or both; every address once, in
/// order.
pub fn parse_drives(text: &str) -> Result<Vec<Address>, String> {
    let mut found = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let number = |t: &str| {
            t.trim().parse::<u8>().ok().filter(|n| (1..=31).contains(n)).ok_or_else(|| {
                format!(
                    "--drives {text:?}: {t:?} is not a drive address 1..31 (give a list such as 1,3 or a range 1-8)"
                )
            })
        };
        let (from, to) = match part.split_once('-') {
            Some((a, b)) => (number(a)?, number(b)?),
            None => (number(part)?, number(part)?),
        };
        if from > to {
            return Err(format!("--drives {text:?}: the range {part} runs backwards"));
        }
        found.extend(from..=to);
    }
    if found.is_empty() {
        return Err(format!("--drives {text:?}: no address given"));
    }
    found.sort_unstable();
    found.dedup();
    Ok(found.into_iter().map(|n| Address::drive(n).expect("1..31")).collect())
}

/// The addresses a probe looks for drives at (`--drives`), as [`parse_drives`] reads them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DriveList(pub Vec<Address>);

impl std::str::FromStr for DriveList {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        parse_drives(text).map(DriveList)
    }
}

/// What a profile keeps of one drive.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriveCapabilities {
    /// How the drive echoes a telegram sent with `?`, if found out.
    pub echo_form: Option<EchoForm>,
}

/// One drive a probe found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CompaxDrive {
    /// Its address.
    pub address: u8,
    /// Device identification S31 and S32 (`None` where the drive refuses one).
    pub identification: [Option<String>; 2],
    /// P194 as stored (takes effect at the next power-on).
    pub p194_address: Option<f64>,
    /// P195 as stored, bit/s.
    pub p195_baud: Option<f64>,
    /// P196 as stored: the operating mode (BCC, reply end, address prefix ...), which takes effect at the next
    /// power-on.
    pub p196_mode: Option<f64>,
    /// The P196 the session frames telegrams with (`--mode`): the mode in use, since the drive answered so.
    pub mode_in_use: u32,
    /// What a profile is matched against: S31 and S32.
    pub identity: String,
    /// What the probes found (the profile keeps these).
    pub capabilities: DriveCapabilities,
}

/// The report of a probe.
pub type CompaxProbeReport = ProbeReport<CompaxDrive>;

/// The identity a profile is matched against: S31 and S32 (`-` where refused).
pub fn identity(client: &Client, address: Address) -> Result<(String, [Option<String>; 2]), Error> {
    let mut read = Vec::with_capacity(2);
    for id in IDENTITY_STATUSES {
        read.push(client.read_status(address, id));
    }
    identity_from(read)
}

/// [`identity`] for an [`AsyncClient`](crate::AsyncClient).
#[cfg(feature = "tokio")]
pub async fn identity_async(
    client: &crate::AsyncClient,
    address: Address,
) -> Result<(String, [Option<String>; 2]), Error> {
    let drive = client.drive(address)?;
    let mut read = Vec::with_capacity(2);
    for id in IDENTITY_STATUSES {
        read.push(drive.read_status(id).await);
    }
    identity_from(read)
}

/// The status values that identify a drive: S31 and S32.
const IDENTITY_STATUSES: [StatusId; 2] = [StatusId::DEVICE_ID_1, StatusId::DEVICE_ID_2];

/// The identity from the reads of S31 and S32: a value the drive refuses is `-` (None).
fn identity_from(read: Vec<Result<StatusValue, Error>>) -> Result<(String, [Option<String>; 2]), Error> {
    let mut texts = [None, None];
    for (slot, r) in texts.iter_mut().zip(read) {
        *slot = match r {
            Ok(StatusValue::Text(t)) => Some(t.as_str().to_string()),
            Ok(other) => Some(format!("{other}")),
            Err(Error::Refused { .. }) => None,
            Err(e) => return Err(e),
        };
    }
    let shown = |t: &Option<String>| t.clone().unwrap_or_else(|| "-".into());
    Ok((format!("S31 {} | S32 {}", shown(&texts[0]), shown(&texts[1])), texts))
}

/// Probes the drives at `drives` on the bus of `client` (opened on `setup.port`): finds which answer,
/// identifies each, measures the link, and runs every harmless probe of each (see the [module
/// documentation](self)); the session keeps what was found. Nothing moves. `Err` only when the line fails.
pub fn probe(client: &Client, setup: &ProbeSetup, drives: &[Address]) -> Result<CompaxProbeReport, Error> {
    let (mut checks, timer) = setup.link_checks();
    let mut found = Vec::new();
    for a in drives {
        found.extend(client.scan(a.get()..=a.get())?.into_iter().map(|(a, _)| a));
    }
    let mode = client.config().mode.to_p196();
    if found.is_empty() {
        checks.push(
            Check::new(
                "drives",
                CheckResult::Failed,
                format!(
                    "no drive answered S1 at {} with P196 framing {mode} (--mode): a drive whose P196 differs \
                     (BCC 8, CR only 32, address prefix 64) or whose P195 differs (--baud) gives no reply this \
                     session can read",
                    list(drives)
                ),
            )
            .sending("S1 to each address"),
        );
    }
    let mut trips = RoundTrips::default();
    let mut status_form = None;
    if let Some(first) = found.first() {
        status_form = Some(client.raw(*first, "S1"));
        trips.measure(client.driver().clock().as_ref(), setup.exchanges, || {
            client.read_status(*first, StatusId::ACTUAL_POSITION)
        });
    }
    let link = setup.link_report(&trips, 0, timer);
    let mut devices = Vec::new();
    for (i, a) in found.iter().copied().enumerate() {
        let (identity, identification) = identity(client, a)?;
        let param = |id| client.read_param(a, id).ok();
        let (p194, p195, p196) =
            (param(ParamId::DEVICE_ADDRESS), param(ParamId::BAUD_RATE), param(ParamId::OPERATING_MODE));
        checks.push(mode_row(p196, mode).at(a.get()));
        checks.push(baud_row(p195, setup).at(a.get()));
        if i == 0 {
            checks.push(status_row(status_form.take().expect("read for the first drive")).at(a.get()));
        }
        checks.push(echo_row(client, a).at(a.get()));
        checks.push(
            Check::new(
                "echo_stores",
                CheckResult::Skipped,
                "storing a command (',') replaces what the drive's buffer holds: found out by the first checked move \
                 (a drive that echoes without storing refuses its '!', and nothing runs)",
            )
            .at(a.get())
            .variant("echo-without-store"),
        );
        checks.push(
            Check::new(
                "command_bit",
                CheckResult::Skipped,
                "whether S17 bit 3 (command active) shows a positioning needs one: until this session has seen it \
                 set, a drive whose S17 shows no command is taken to rest only once S1 holds still for a poll \
                 interval, at most 200 ms (waits, stops)",
            )
            .at(a.get())
            .variant("no-command-bit"),
        );
        devices.push(CompaxDrive {
            address: a.get(),
            identification,
            p194_address: p194,
            p195_baud: p195,
            p196_mode: p196,
            mode_in_use: mode,
            identity,
            capabilities: DriveCapabilities { echo_form: client.driver().with_session(|s| s.echo_form(a)) },
        });
    }
    Ok(ProbeReport { family: FAMILY, port: setup.port.clone(), devices, link, checks, saved: Vec::new() })
}

fn list(drives: &[Address]) -> String {
    drives.iter().map(|a| a.get().to_string()).collect::<Vec<_>>().join(",")
}

fn mode_row(stored: Option<f64>, in_use: u32) -> Check {
    let c = match stored {
        Some(v) if v == f64::from(in_use) => {
            Check::new("p196_mode", CheckResult::Ok, format!("P196 = {in_use}: replies are framed as --mode {in_use}"))
        }
        Some(v) => Check::new(
            "p196_mode",
            CheckResult::Failed,
            format!(
                "P196 holds {v}, but the drive answers framed as {in_use} (--mode): the stored value takes effect at \
                 the next power-on, after which --mode {v} is needed"
            ),
        ),
        None => Check::new("p196_mode", CheckResult::Failed, "P196 could not be read"),
    };
    c.sending("P196 (a read)")
}

fn baud_row(stored: Option<f64>, setup: &ProbeSetup) -> Check {
    let c = match (stored, setup.baud) {
        (None, _) => Check::new("p195_baud", CheckResult::Failed, "P195 could not be read"),
        (Some(v), Some(line)) if v == f64::from(line) => {
            Check::new("p195_baud", CheckResult::Ok, format!("P195 = {v} bit/s, the line's rate"))
        }
        (Some(v), Some(line)) => Check::new(
            "p195_baud",
            CheckResult::Failed,
            format!("P195 holds {v} bit/s while the drive answers at {line}: the stored rate takes effect at the next power-on"),
        ),
        (Some(v), None) if BAUD_RATES.contains(&(v as u32)) => Check::new(
            "p195_baud",
            CheckResult::Ok,
            format!("P195 = {v} bit/s; no line rate to compare it with ({})", setup.kind.no_baud().unwrap_or_default()),
        ),
        (Some(v), None) => Check::new("p195_baud", CheckResult::Failed, format!("P195 holds {v}, not a rate of the manual")),
    };
    c.sending("P195 (a read)")
}

fn status_row(reply: Result<Option<String>, Error>) -> Check {
    let c = match reply {
        Ok(Some(text)) if text.trim_start().starts_with('S') => Check::new(
            "status_value_form",
            CheckResult::Ok,
            format!("status values come with their name ({:?})", text.trim()),
        ),
        Ok(Some(text)) => Check::new(
            "status_value_form",
            CheckResult::Unsupported,
            format!("status values come without their name ({:?}): read all the same", text.trim()),
        ),
        Ok(None) => Check::new("status_value_form", CheckResult::Failed, "no reply to S1"),
        Err(e) => Check::new("status_value_form", CheckResult::Failed, format!("S1: {e}")),
    };
    c.sending("S1 (a read)").variant("status-value-only")
}

fn echo_row(client: &Client, a: Address) -> Check {
    let run = client.run(Op::ProbeEcho(a));
    let prefixed = client.config().mode.reply_address;
    let form = client.driver().with_session(|s| s.echo_form(a));
    let (result, detail) = match (run, form) {
        (_, Some(EchoForm::Full)) => {
            (CheckResult::Ok, "echoes in full (address, command and flags): a stored move is checked before '!'".into())
        }
        (_, Some(f)) => match f.unchecked(a, prefixed) {
            // Without its address, where every reply carries P196's address prefix: the prefix names the
            // drive that echoed, and the move is checked as on a drive that echoes in full.
            why if why.is_empty() => (
                CheckResult::Ok,
                format!(
                    "echoes {}, but every reply starts with the drive's address (P196 has 64), which names the \
                     drive that echoed: a stored move is checked before '!' all the same",
                    f.described()
                ),
            ),
            why => (CheckResult::Unsupported, format!("echoes {}: {}", f.described(), why.join("; "))),
        },
        (Err(e), None) => (CheckResult::Failed, e.to_string()),
        (Ok(_), None) => (CheckResult::Failed, "not settled".into()),
    };
    let variant = match form {
        Some(EchoForm::None) => "no-echo",
        Some(EchoForm::Bare) => "echo-bare",
        _ => "echo-without-address",
    };
    Check::new("echo_form", result, detail).sending("S1 with '?' (an echo of a read)").variant(variant)
}

/// Writes the profile of each drive `report` found into `profiles` (replacing those of the same port,
/// address and identity), saves the file, and names them in `report.saved`.
pub fn save_profile(report: &mut CompaxProbeReport, profiles: &mut Profiles) -> Result<(), ProfileError> {
    for d in &report.devices {
        let mut entry = ProfileEntry {
            family: FAMILY.into(),
            port: report.port.clone(),
            address: Some(d.address),
            identity: d.identity.clone(),
            baud: report.link.baud,
            capabilities: Default::default(),
        };
        entry.set_capabilities(&d.capabilities)?;
        report.saved.push(profiles.insert(entry));
    }
    profiles.save()
}

/// Looks up the profile of drive `address` on `port`: where `profiles` holds one, reads the drive's identity
/// (S31, S32) and, when it matches, seeds the session with its findings (the echo probe is skipped); another
/// identity leaves it unused with a notice. Nothing is read where no profile names the drive.
pub fn use_profile(client: &Client, profiles: &Profiles, port: &str, address: Address) -> Result<ProfileUse, Error> {
    if !profiles.has(FAMILY, port, Some(address.get())) {
        return Ok(ProfileUse::default());
    }
    let (identity, _) = identity(client, address)?;
    Ok(take_profile(client.driver(), profiles, port, address, &identity))
}

/// [`use_profile`] for an [`AsyncClient`](crate::AsyncClient) (the console's, Python's `AsyncCompax`).
#[cfg(feature = "tokio")]
pub async fn use_profile_async(
    client: &crate::AsyncClient,
    profiles: &Profiles,
    port: &str,
    address: Address,
) -> Result<ProfileUse, Error> {
    if !profiles.has(FAMILY, port, Some(address.get())) {
        return Ok(ProfileUse::default());
    }
    let (identity, _) = identity_async(client, address).await?;
    Ok(take_profile(client.driver().driver(), profiles, port, address, &identity))
}

/// Takes the profile of the drive with `identity`, where one matches: the session is seeded with its echo form
/// (which a drive that then behaves otherwise has found out again, with a warning naming the profile).
fn take_profile(
    driver: &motionlink_link::driver::Driver<crate::session::Session>,
    profiles: &Profiles,
    port: &str,
    address: Address,
    identity: &str,
) -> ProfileUse {
    let mut used = ProfileUse::default();
    let lookup = profiles.lookup(FAMILY, port, Some(address.get()), identity);
    let reference = match &lookup {
        Lookup::Found { reference, .. } => reference.clone(),
        _ => String::new(),
    };
    used.take(lookup, |caps: DriveCapabilities| {
        if let Some(form) = caps.echo_form {
            driver.with_session(|s| s.seed_echo_form(address, form, &reference));
        }
    });
    used
}
