//! Commissioning (`motionlink probe powercube`): the modules on the bus with their kind, version and serial
//! number, how the link behaves, and every behaviour beyond the manual's words that a harmless exchange can
//! settle ([`probe`]); and the device profile of each module that lets a later session skip those probes
//! ([`save_profile`], [`use_profile`]).
//!
//! Nothing moves. What is sent: the scan (GetExtended of DefCubeVersion, 0x1D, to addresses 1..31; then the
//! Config word, DefCubeSerial and CubeState of each module that answers), CubeState of the first module
//! [`ProbeSetup::exchanges`] times (the link), ActFPosStateDio (0x62) of each module (`pos_state_dio`), and
//! its Config word once more (`config_word`: a module before version 3.5.00 has none, and no watchdog a
//! guarded motion can enable).
//! The other behaviours of the list need a write of another value (the Inc twins), an armed watchdog (the
//! RS232 broadcast refresh, the life sign's acknowledge), or are taken in every form (the acknowledge's
//! length, the identifier of an extended acknowledge): their rows say `skipped` and why.

use motionlink_link::probe::{Check, CheckResult, ProbeReport, ProbeSetup, RoundTrips};
use motionlink_link::profile::{ProfileEntry, ProfileError, ProfileUse, Profiles};

use crate::client::Client;
use crate::error::Error;
use crate::model::{Address, ModuleKind};
use crate::session::{ModuleFindings, ModuleInfo, Op};

/// The RS232 baud rates of the modules, in the order `--baud auto` tries them (the modules' default first).
pub const BAUD_RATES: &[u32] = &[9_600, 19_200, 38_400, 57_600, 115_200, 4_800, 2_400, 1_200];

/// The family's name in reports and profiles.
pub const FAMILY: &str = "powercube";

/// `--baud` of a probe: `auto` (every rate of [`BAUD_RATES`]) or one of them.
pub fn baud_choice(text: &str) -> Result<motionlink_link::probe::BaudChoice, String> {
    motionlink_link::probe::BaudChoice::parse(text, BAUD_RATES, "a PowerCube module (RS232)")
}

/// One module a probe found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PowercubeModule {
    /// Its address, 1..31.
    pub address: u8,
    /// Rotary or linear.
    pub kind: ModuleKind,
    /// Firmware version, as `4.6.12`.
    pub version: String,
    /// Serial number.
    pub serial: u32,
    /// The names of the CubeState flags set when it was read.
    pub state: Vec<String>,
    /// What a profile is matched against: version, serial number and kind.
    pub identity: String,
    /// What the probes found (the profile keeps these).
    pub findings: ModuleFindings,
}

/// The report of a probe.
pub type PowercubeProbeReport = ProbeReport<PowercubeModule>;

/// The identity of a module as its profile keeps it.
pub fn identity_of(info: &ModuleInfo) -> String {
    format!("version {}, serial {}, {}", info.version, info.serial, info.kind.name())
}

/// The behaviours of the list that no harmless exchange shows: name, why, variant.
const NOT_PROBED: [(&str, &str, &str); 5] = [
    (
        "twin_mirror",
        "needs a write of another value (TargetVel, TargetAcc, TargetPos are write-only): found out by the first \
         set or move that depends on it",
        "no-twin-mirror",
    ),
    (
        "life_sign_acknowledged",
        "needs the watchdog armed: found out by the first guarded home or move",
        "life-sign-unacknowledged",
    ),
    ("ack_length", "nothing to probe: an acknowledge of 3 bytes is taken with length 3 or 6", "ack-length-6"),
    (
        "ext_ack_identifier",
        "nothing to probe: an extended acknowledge is taken on 0x0A0 + address and on 0x0E0 + address",
        "ext-ack-on-put-id",
    ),
    (
        "motion_shown_at_once",
        "needs a motion: a checked move or homing takes an end flag for its own only once it saw STATE_MOTION, \
         or stands at its target, or 1 s (the start grace) has passed; the close waits as long for a motion \
         command it sent",
        "late-motion-start",
    ),
];

/// Probes the bus of `client` (opened on `setup.port`): scans it, identifies each module, measures the link,
/// and runs every harmless probe of each module (see the [module documentation](self)); the session keeps
/// what was found. Nothing moves. `Err` only when the line fails.
pub fn probe(client: &Client, setup: &ProbeSetup) -> Result<PowercubeProbeReport, Error> {
    let (mut checks, timer) = setup.link_checks();
    let mut modules = Vec::new();
    let found = client.scan()?;
    if found.is_empty() {
        checks.push(Check::new("modules", CheckResult::Failed, "no module answered at addresses 1..31").sending(SCAN));
    }
    for entry in found {
        match entry.info {
            Ok(info) => modules.push(info),
            Err(e) => checks.push(
                Check::new("identity", CheckResult::Failed, format!("answered the scan, then: {e}"))
                    .at(entry.address.get())
                    .sending(SCAN),
            ),
        }
    }
    let mut trips = RoundTrips::default();
    if let Some(first) = modules.first() {
        let m = client.module(first.address);
        trips.measure(client.clock().as_ref(), setup.exchanges, || m.state());
    }
    let link = setup.link_report(&trips, 0, timer);
    let mut devices = Vec::new();
    for info in &modules {
        let a = info.address;
        checks.push(pos_state_dio(client, a));
        checks.push(config_word(client, a));
        checks.push(broadcast_row(client.is_can()).at(a.get()));
        for (name, why, variant) in NOT_PROBED {
            checks.push(Check::new(name, CheckResult::Skipped, why).at(a.get()).variant(variant));
        }
        devices.push(PowercubeModule {
            address: a.get(),
            kind: info.kind,
            version: info.version.to_string(),
            serial: info.serial,
            state: info.state.iter().map(|f| f.label()).collect(),
            identity: identity_of(info),
            findings: client.session(|s| s.findings(a)),
        });
    }
    Ok(ProbeReport { family: FAMILY, port: setup.port.clone(), devices, link, checks, saved: Vec::new() })
}

const SCAN: &str = "GetExtended DefCubeVersion (0x1D) to 1..31; Config, DefCubeSerial, CubeState of each found";

fn pos_state_dio(client: &Client, a: Address) -> Check {
    let result = client.run(Op::ProbePosStateDio(a));
    let c = match (result, client.session(|s| s.findings(a)).pos_state_dio) {
        (_, Some(true)) => Check::new(
            "pos_state_dio",
            CheckResult::Ok,
            "answered: waits read the position and the short state in one exchange",
        ),
        (_, Some(false)) => Check::new(
            "pos_state_dio",
            CheckResult::Unsupported,
            "not answered (a later firmware's parameter): waits poll CubeState and ActPos instead; nothing is lost",
        ),
        (Err(e), None) => Check::new("pos_state_dio", CheckResult::Failed, e.to_string()),
        (Ok(_), None) => Check::new("pos_state_dio", CheckResult::Failed, "not settled"),
    };
    c.at(a.get()).sending("GetExtended ActFPosStateDio (0x62)").variant("no-pos-state-dio")
}

/// Whether the module answers the Config word (parameter 57, "available from module version 3.5.00",
/// manual 7.2), where a guarded motion enables the watchdog.
fn config_word(client: &Client, a: Address) -> Check {
    let c = match client.module(a).config_word() {
        Ok(_) => Check::new("config_word", CheckResult::Ok, "answered: a guarded home or move can enable the watchdog"),
        Err(Error::Timeout { .. }) => Check::new(
            "config_word",
            CheckResult::Unsupported,
            "not answered (from module version 3.5.00): the module's type is read from DefConfig; its watchdog \
             cannot be enabled, so a guarded home or move is refused (`--no-watchdog` moves it)",
        ),
        Err(e) => Check::new("config_word", CheckResult::Failed, e.to_string()),
    };
    c.at(a.get()).sending("GetExtended Config (0x39)").variant("no-config-word")
}

fn broadcast_row(can: bool) -> Check {
    let why = if can {
        "the manual's broadcast on CAN: nothing to probe"
    } else {
        "needs the watchdog armed: found out by the first guarded home or move on RS232 (a module that ignores \
         the refresh then runs its motions without a watchdog, and says so)"
    };
    Check::new("rs232_broadcast", CheckResult::Skipped, why).variant("no-broadcast-pair")
}

/// Writes the profile of each module `report` found into `profiles` (replacing those of the same port,
/// address and identity), saves the file, and names them in `report.saved`.
pub fn save_profile(report: &mut PowercubeProbeReport, profiles: &mut Profiles) -> Result<(), ProfileError> {
    for m in &report.devices {
        let mut entry = ProfileEntry {
            family: FAMILY.into(),
            port: report.port.clone(),
            address: Some(m.address),
            identity: m.identity.clone(),
            baud: report.link.baud,
            capabilities: Default::default(),
        };
        entry.set_capabilities(&m.findings)?;
        report.saved.push(profiles.insert(entry));
    }
    profiles.save()
}

/// Looks up the profile of module `address` on `port`: where `profiles` holds one, reads the module's
/// identity (its type, version, serial number and state) and, when it matches, seeds the session's findings
/// from it (those probes are skipped); another identity leaves it unused with a notice. Nothing is read
/// where no profile names the module.
pub fn use_profile(client: &Client, profiles: &Profiles, port: &str, address: Address) -> Result<ProfileUse, Error> {
    if !profiles.has(FAMILY, port, Some(address.get())) {
        return Ok(ProfileUse::default());
    }
    let info = client.module(address).info()?;
    Ok(take_profile(profiles, port, &info, |f| client.session(|s| s.seed_findings(address, f))))
}

/// [`use_profile`] for an [`AsyncClient`](crate::AsyncClient) (the console's and the gateway's).
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
    let info = client.module(address).info().await?;
    Ok(take_profile(profiles, port, &info, |f| client.session(|s| s.seed_findings(address, f))))
}

/// Takes the profile of the module `info` describes, where one matches: `seed` gets its findings.
fn take_profile(profiles: &Profiles, port: &str, info: &ModuleInfo, seed: impl FnOnce(ModuleFindings)) -> ProfileUse {
    let mut used = ProfileUse::default();
    used.take(profiles.lookup(FAMILY, port, Some(info.address.get()), &identity_of(info)), seed);
    used
}
