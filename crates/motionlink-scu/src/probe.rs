//! Commissioning (`motionlink probe scu`): what unit is on the line, how the link behaves, and every
//! behaviour beyond the manual's words that a harmless exchange can settle ([`probe`]); and the device
//! profile that lets a later session skip those probes ([`save_profile`], [`use_profile`]).
//!
//! Nothing moves. What each check sends:
//!
//! - identity: RG of 0x0001 (firmware info) and 0x0002 (configuration info);
//! - the link: RG of 0x0171 (status 1 of A1), [`ProbeSetup::exchanges`] times;
//! - `grouping_indices`: RG of 0x0170 (status 1 of every actuator; entry by entry where refused);
//! - `user_position_data`: RG of 0x2001.. (UserPositionData) of each connected actuator (of A1 if none is);
//! - `cyclic_objects` and `remote_read_back`: the session's cyclic object, as a `watch` defines it: RT of
//!   CyclicObj 5 (volatile remote data that only selects what an RC reads), RG of it back, one RC carrying it
//!   and one more that takes a sample, as `watch` does;
//!   where that is not tried, RG of 0x3011 (remote speed F1) for the read-back;
//! - `answers_first_telegram`: nothing more: whether the session's opening RO had to be sent again.
//!
//! The other behaviours of the list need a motion to show (error bits reset by the next motion, positions
//! after reaching the In end, a second RE without RS) or are taken in every form (the RC reply): their rows
//! say `skipped` and why.
//!
//! ```
//! use motionlink_link::{pipe::{EmulatorHost, PipeConfig}, link::Link, probe::{CheckResult, PortKind, ProbeSetup}};
//! use motionlink_link::{Clock, ManualClock};
//! use motionlink_scu::{Client, Config, Emulator, SimConfig, Variant};
//!
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let mut sim = SimConfig::default();
//! sim.add_variants([Variant::NoGroups]);
//! let unit = EmulatorHost::new(Emulator::new(sim)?, clock.shared(), PipeConfig::paced(38_400));
//! let connector = unit.connector();
//! let client = Client::with_connector(connector, clock.shared(), Config::default())?;
//! let report = motionlink_scu::probe::probe(&client, &ProbeSetup::new("sim", PortKind::Sim, 38_400))?;
//! assert_eq!(report.check("grouping_indices", None).unwrap().result, CheckResult::Unsupported);
//! assert_eq!(report.devices[0].capabilities.grouping_indices, Some(false));
//! client.close()?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use motionlink_link::probe::{Check, CheckResult, ProbeReport, ProbeSetup, RoundTrips};
use motionlink_link::profile::{ProfileEntry, ProfileError, ProfileUse, Profiles};

use crate::error::Error;
use crate::model::{Actuator, DataIndex};
use crate::session::Capabilities;
use crate::value::Value;
use crate::Client;

/// The baud rates an SCU may run at, in the order `--baud auto` tries them (the standard one first).
pub const BAUD_RATES: &[u32] = &[38_400, 19_200, 9_600];

/// `--baud` of a probe: `auto` (every rate of [`BAUD_RATES`]) or one of them.
pub fn baud_choice(text: &str) -> Result<motionlink_link::probe::BaudChoice, String> {
    motionlink_link::probe::BaudChoice::parse(text, BAUD_RATES, "an SCU")
}

/// The family's name in reports and profiles.
pub const FAMILY: &str = "scu";

/// The unit a probe found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ScuDevice {
    /// The edition: `ewellix` or `schaeffler` where the firmware or configuration text names it, else
    /// [`EITHER_EDITION`]: the protocol cannot tell them apart (see [`Self::edition_detail`]).
    pub edition: &'static str,
    /// How the edition was determined: which text names it, or why no read of the protocol can.
    pub edition_detail: String,
    /// Firmware info (0x0001): name, version, checksum.
    pub firmware: String,
    /// Configuration info (0x0002): name, version, checksum.
    pub configuration: String,
    /// The actuators status 1 shows connected (1..6).
    pub connected_actuators: Vec<u8>,
    /// What a profile is matched against: the firmware and configuration texts.
    pub identity: String,
    /// What the probes found (the profile keeps these).
    pub capabilities: Capabilities,
}

/// The report of a probe.
pub type ScuProbeReport = ProbeReport<ScuDevice>;

/// The identity a profile is matched against: the firmware and configuration texts (RG of 0x0001 and
/// 0x0002), joined with ` | `.
pub fn identity(client: &Client) -> Result<(String, String), Error> {
    let text = |index| match client.get_value(DataIndex(index))? {
        Value::Text(t) => Ok(t),
        other => Err(Error::UnexpectedReply {
            command: crate::wire::Command::Get,
            detail: format!("{} is text, the unit sent {other:?}", DataIndex(index)),
        }),
    };
    Ok((text(0x0001)?, text(0x0002)?))
}

/// The edition of a unit whose texts name neither vendor: the two manuals describe one protocol.
pub const EITHER_EDITION: &str = "either: one protocol";

/// Why the protocol cannot tell the editions apart (the manuals compared).
pub const ONE_PROTOCOL: &str = "the Ewellix and the Schaeffler manual describe one protocol: the same commands, \
     acknowledge codes, data indices (0x0001..0x3026, none in one edition only), functions, parameters and error \
     bits, so no read answers differently by edition; neither manual shows what the firmware (0x0001) or \
     configuration (0x0002) text holds, and these texts name neither vendor";

/// The edition the firmware or configuration text names, and how that was determined.
fn edition(firmware: &str, configuration: &str) -> (&'static str, String) {
    for (vendor, name) in [("ewellix", "Ewellix"), ("schaeffler", "Schaeffler")] {
        for (which, text) in [("firmware", firmware), ("configuration", configuration)] {
            if text.to_ascii_lowercase().contains(vendor) {
                return (vendor, format!("the {which} text names {name} (the protocol of both editions is the same)"));
            }
        }
    }
    (EITHER_EDITION, ONE_PROTOCOL.to_string())
}

/// Probes the unit of `client` (opened on `setup.port`): identifies it, measures the link, and runs every
/// harmless probe (see the [module documentation](self)); the session keeps what was found. Nothing moves.
/// A refusal or a failed read ends as a `failed` check; `Err` only when the unit cannot be identified.
pub fn probe(client: &Client, setup: &ProbeSetup) -> Result<ScuProbeReport, Error> {
    let retries_at_open = client.stats().retries;
    let (mut checks, timer) = setup.link_checks();
    let (firmware, configuration) = identity(client)?;

    let mut trips = RoundTrips::default();
    let before = client.stats().retries;
    trips.measure(client.clock().as_ref(), setup.exchanges, || client.get_raw(DataIndex(0x0171)));
    let link = setup.link_report(&trips, client.stats().retries - before, timer);

    checks.push(first_telegram(retries_at_open));
    let statuses = client.statuses();
    let caps = client.capabilities();
    checks.push(
        match (&statuses, caps.grouping_indices) {
            (_, Some(true)) => {
                Check::new(NAMES[0], CheckResult::Ok, "RG of 0x0170 answered: groups are read in one telegram")
            }
            (_, Some(false)) => Check::new(
                NAMES[0],
                CheckResult::Unsupported,
                "RG of 0x0170 refused (PDE): every group is read entry by entry (more telegrams, nothing lost), and \
             the session's cyclic object (which names groups) is not used",
            ),
            (Err(e), None) => Check::new(NAMES[0], CheckResult::Failed, format!("RG of 0x0170: {e}")),
            (Ok(_), None) => Check::new(NAMES[0], CheckResult::Failed, "RG of 0x0170 answered without settling it"),
        }
        .sending("RG 0x0170")
        .variant("no-groups"),
    );
    let connected: Vec<Actuator> = statuses.as_ref().map(crate::client::connected).unwrap_or_default();
    checks.push(user_positions(client, &connected));
    checks.extend(cyclic_and_read_back(client));
    checks.extend(NOT_PROBED.iter().map(|(name, why, variant)| {
        let c = Check::new(name, CheckResult::Skipped, *why);
        match variant {
            Some(v) => c.variant(v),
            None => c,
        }
    }));

    let capabilities = client.capabilities();
    let (edition, edition_detail) = edition(&firmware, &configuration);
    let device = ScuDevice {
        edition,
        edition_detail,
        identity: format!("{firmware} | {configuration}"),
        firmware,
        configuration,
        connected_actuators: connected.iter().map(|a| a.number()).collect(),
        capabilities,
    };
    Ok(ProbeReport { family: FAMILY, port: setup.port.clone(), devices: vec![device], link, checks, saved: Vec::new() })
}

/// The names of the probed checks, in the report's order after `answers_first_telegram`.
const NAMES: [&str; 4] = ["grouping_indices", "user_position_data", "cyclic_objects", "remote_read_back"];

/// The behaviours of the list that no harmless exchange shows: name, why, variant.
const NOT_PROBED: [(&str, &str, Option<&str>); 5] = [
    (
        "rc_reply_form",
        "nothing to probe: an RC without cyclic object is taken as the status alone or with ctp 0",
        Some("rc-empty-data"),
    ),
    (
        "error_bits_reset_on_motion",
        "needs a motion: no check depends on it (a move that misses reports Error_Code 1 as read then)",
        Some("sticky-errors"),
    ),
    (
        "in_end_position",
        "needs a motion to the In end: the in-position tolerance (5 counts) takes a few counts below it",
        Some("in-end-undershoot"),
    ),
    (
        "second_re_without_rs",
        "needs a motion (an RE moves): a stream on a unit that refuses it ends with the unit's PE",
        Some("re-needs-rs"),
    ),
    (
        "motion_bit_rises",
        "needs a motion (an RE moves): a move or run waits up to 1 s after the RE for the motion bit before \
         it judges where the actuators stand",
        Some("late-motion-bit"),
    ),
];

fn first_telegram(retries_at_open: u64) -> Check {
    let c = if retries_at_open == 0 {
        Check::new("answers_first_telegram", CheckResult::Ok, "the unit answered the session's first RO at once")
    } else {
        Check::new(
            "answers_first_telegram",
            CheckResult::Unsupported,
            format!(
                "the session's opening needed {retries_at_open} repetition(s): the unit sleeps after a silence (or the \
                 first telegram was lost); the client sends a request again after 150 ms of silence, which costs \
                 about 0.2 s at the start of a session"
            ),
        )
    };
    c.sending("nothing more (the session's RO)").variant("sleepy")
}

fn user_positions(client: &Client, connected: &[Actuator]) -> Check {
    const SENDS: &str = "RG 0x2001..0x2006 (UserPositionData) of each connected actuator";
    let one = [Actuator::new(1).expect("A1 exists")];
    let actuators = if connected.is_empty() { &one[..] } else { connected };
    if client.config().stroke_limits.iter().any(Option::is_some) {
        return Check::new(NAMES[1], CheckResult::Skipped, "stroke limits are configured (--stroke): not read")
            .sending(SENDS);
    }
    let mut limits = Vec::new();
    for a in actuators {
        match client.stroke_limits(*a) {
            Ok(Some((l, _))) => limits.push(format!("{a} {}..{}", l.min_counts.0, l.max_counts.0)),
            Ok(None) => limits.push(format!("{a} none set (0 / 0)")),
            Err(e) if client.capabilities().user_position_data == Some(false) => {
                tracing::debug!("UserPositionData of {a}: {e}");
                break;
            }
            Err(e) => return Check::new(NAMES[1], CheckResult::Failed, format!("{a}: {e}")).sending(SENDS),
        }
    }
    let c = match client.capabilities().user_position_data {
        Some(true) => Check::new(
            NAMES[1],
            CheckResult::Ok,
            format!("answered: move targets are checked against the virtual limits ({})", limits.join(", ")),
        ),
        Some(false) => Check::new(
            NAMES[1],
            CheckResult::Unsupported,
            "refused (PDE): move targets are checked against --stroke only; without it a move says its target was \
             not checked",
        ),
        None => Check::new(NAMES[1], CheckResult::Failed, "not settled"),
    };
    c.sending(SENDS).variant("no-user-positions")
}

fn cyclic_and_read_back(client: &Client) -> [Check; 2] {
    const SENDS_OBJECT: &str =
        "RT of CyclicObj 5 (the session's definition), RG of it back, one RC carrying it, one more with a sample";
    const SENDS_READ: &str = "RG of remote data (the definition written, else 0x3011)";
    let sampled = client.sample();
    let mut caps = client.capabilities();
    let mut read_error = None;
    if caps.remote_read_back.is_none() {
        // The object was not tried (groups refused): the read-back is probed by reading remote speed F1.
        match client.get_raw(DataIndex(0x3011)) {
            Ok(_) => client.seed_capabilities(Capabilities { remote_read_back: Some(true), ..Default::default() }),
            Err(Error::Refused { status: crate::wire::Status::ParameterDataError, .. }) => {
                client.seed_capabilities(Capabilities { remote_read_back: Some(false), ..Default::default() })
            }
            Err(e) => read_error = Some(e),
        }
        caps = client.capabilities();
    }
    let object = match (caps.cyclic_objects, &sampled) {
        (Some(true), _) => Check::new(
            NAMES[2],
            CheckResult::Ok,
            "taken: every keepalive RC of a motion or a watch reads the state too",
        ),
        (Some(false), _) => Check::new(
            NAMES[2],
            CheckResult::Unsupported,
            "an RC carrying CyclicObj 5 is refused (PDE): motions and samples are read with RG",
        ),
        (None, Err(e)) => Check::new(NAMES[2], CheckResult::Failed, format!("a sample: {e}")),
        (None, Ok(_)) if caps.grouping_indices == Some(false) => Check::new(
            NAMES[2],
            CheckResult::Skipped,
            "not tried: the object reads grouping indices, which the unit refuses",
        ),
        (None, Ok(_)) => Check::new(
            NAMES[2],
            CheckResult::Skipped,
            "not tried: the definition cannot be read back (remote data is not read back), so the session does \
             not use it",
        ),
    }
    .sending(SENDS_OBJECT)
    .variant("no-cyclic-objects");
    let read = match (caps.remote_read_back, read_error) {
        (Some(true), _) => {
            Check::new(NAMES[3], CheckResult::Ok, "remote data reads back: every RT is checked by an RG")
        }
        (Some(false), _) => Check::new(
            NAMES[3],
            CheckResult::Unsupported,
            "RG of remote data refused (PDE): writes are checked by the unit's ACK only, and results say so",
        ),
        (None, Some(e)) => Check::new(NAMES[3], CheckResult::Failed, format!("RG of 0x3011: {e}")),
        (None, None) => Check::new(NAMES[3], CheckResult::Failed, "not settled"),
    }
    .sending(SENDS_READ)
    .variant("no-remote-readback");
    [object, read]
}

/// Writes the profile of the unit `report` found into `profiles` (replacing the one of the same port and
/// identity), saves the file, and names it in `report.saved`.
pub fn save_profile(report: &mut ScuProbeReport, profiles: &mut Profiles) -> Result<(), ProfileError> {
    for d in &report.devices {
        let mut entry = ProfileEntry {
            family: FAMILY.into(),
            port: report.port.clone(),
            address: None,
            identity: d.identity.clone(),
            baud: report.link.baud,
            capabilities: Default::default(),
        };
        entry.set_capabilities(&d.capabilities)?;
        report.saved.push(profiles.insert(entry));
    }
    profiles.save()
}

/// The firmware and configuration texts as one identity.
fn joined(texts: (String, String)) -> String {
    format!("{} | {}", texts.0, texts.1)
}

/// [`use_profile`] for an [`AsyncClient`](crate::AsyncClient) (the console's).
#[cfg(feature = "tokio")]
pub async fn use_profile_async(
    client: &crate::AsyncClient,
    profiles: &Profiles,
    port: &str,
) -> Result<ProfileUse, Error> {
    let mut used = ProfileUse::default();
    if profiles.has(FAMILY, port, None) {
        let mut texts = Vec::new();
        for index in [0x0001, 0x0002] {
            texts.push(match client.get_value(DataIndex(index)).await? {
                Value::Text(t) => t,
                other => format!("{other:?}"),
            });
        }
        let lookup = profiles.lookup(FAMILY, port, None, &texts.join(" | "));
        used.take(lookup, |caps: Capabilities| client.seed_capabilities(caps));
    }
    Ok(used)
}

/// Looks up the profile of the unit of `client` on `port`: where `profiles` holds one for the port, reads the
/// unit's identity (two RG) and, when it matches, seeds the session's capabilities from it (those probes are
/// skipped); another identity leaves it unused with a notice. Nothing is read where no profile names the port.
pub fn use_profile(client: &Client, profiles: &Profiles, port: &str) -> Result<ProfileUse, Error> {
    let mut used = ProfileUse::default();
    if profiles.has(FAMILY, port, None) {
        let lookup = profiles.lookup(FAMILY, port, None, &joined(identity(client)?));
        used.take(lookup, |caps: Capabilities| client.seed_capabilities(caps));
    }
    Ok(used)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_edition_is_the_vendor_a_text_names_else_either_with_the_reason() {
        let (e, why) = edition("SCU V2B3 Ewellix", "SCP11");
        assert_eq!(e, "ewellix");
        assert!(why.contains("firmware text names Ewellix"), "{why}");
        let (e, why) = edition("SCU V2B3", "SCHAEFFLER SCP11 1.0");
        assert_eq!(e, "schaeffler");
        assert!(why.contains("configuration text names Schaeffler"), "{why}");
        let (e, why) = edition("SCU V2B3 motionlink-sim", "SCP11");
        assert_eq!(e, EITHER_EDITION);
        assert_eq!(why, ONE_PROTOCOL);
    }
}
