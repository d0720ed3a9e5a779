//! `motionlink_scu::probe` against the emulator and every firmware variant: the report says `unsupported`
//! for the behaviour a variant changes and what the default unit says otherwise; a saved profile seeds a
//! later session (whose probe exchanges disappear) only when the unit's identity matches; `--baud auto`
//! finds the rate the unit answers at.

use crate::rig;

use motionlink_link::probe::{find_baud, BaudChoice, CheckResult, PortKind, ProbeSetup};
use motionlink_link::profile::Profiles;
use motionlink_scu::probe::{probe, save_profile, use_profile, ScuProbeReport, BAUD_RATES};
use motionlink_scu::session::Capabilities;
use motionlink_scu::{FirmwareVariant, Variant};
use rig::*;

fn sim_setup() -> ProbeSetup {
    ProbeSetup::new("sim", PortKind::Sim, 38_400)
}

fn probed(variants: &[Variant]) -> ScuProbeReport {
    let rig = Rig::with_variants(SimConfig::default(), variants);
    // A unit in low-power mode is woken first (`--wake`); the probe then sees it as any other.
    let wake_break = variants.contains(&Variant::LowPower).then_some(motionlink_scu::config::WAKE_BREAK);
    let client = rig.client(Config { wake_break, ..Config::default() });
    let at = || rig.unit(|u| (u.position(a(1)), u.position(a(2))));
    let before = at();
    let report = probe(&client, &sim_setup()).unwrap();
    // Nothing moved, and nothing was left started.
    assert!(client.started().is_empty());
    assert_eq!(at(), before);
    client.close().unwrap();
    report
}

fn results(r: &ScuProbeReport) -> Vec<(&'static str, CheckResult)> {
    r.checks.iter().map(|c| (c.name, c.result)).collect()
}

#[test]
fn the_default_unit_answers_every_probe_and_is_identified() {
    let r = probed(&[]);
    assert_eq!((r.family, r.port.as_str()), ("scu", "sim"));
    let d = &r.devices[0];
    assert_eq!(d.firmware, "SCU V2B3 motionlink-sim");
    // The emulator's texts name no vendor (the manuals show no such text), and no read tells the editions
    // apart: the probe says so, with why.
    assert_eq!(d.edition, "either: one protocol");
    assert!(d.edition_detail.contains("one protocol") && d.edition_detail.contains("none in one edition only"));
    assert_eq!(d.connected_actuators, vec![1, 2]);
    assert!(d.identity.starts_with("SCU V2B3 motionlink-sim | "), "{}", d.identity);
    let yes = Some(true);
    let all =
        Capabilities { grouping_indices: yes, user_position_data: yes, cyclic_objects: yes, remote_read_back: yes };
    assert_eq!(d.capabilities, all);
    for (name, result) in results(&r) {
        let expected = match name {
            "baud"
            | "latency_timer"
            | "rc_reply_form"
            | "error_bits_reset_on_motion"
            | "in_end_position"
            | "second_re_without_rs"
            | "motion_bit_rises" => CheckResult::Skipped,
            _ => CheckResult::Ok,
        };
        assert_eq!(result, expected, "{name}: {:?}", r.check(name, None));
    }
    assert_eq!(r.checks.len(), 12);
    assert!(r.checks.iter().all(|c| !c.detail.is_empty()));
    assert_eq!((r.link.exchanges, r.link.errors, r.link.baud), (20, 0, None));
    let rt = r.link.round_trip_ms.unwrap();
    // RG 0x0171: 6 bytes out, 9 back at 38400 baud (about 3.9 ms of wire time).
    assert!(rt.min >= 3.5 && rt.max < 250.0, "{rt:?}");
    let json = serde_json::to_value(&r).unwrap();
    for key in ["family", "port", "devices", "link", "checks"] {
        assert!(json.get(key).is_some(), "{key} in {json}");
    }
    assert_eq!(json["checks"][2]["result"], "ok");
    assert_eq!(json["checks"][3]["variant"], "no-groups");
}

#[test]
fn each_variant_shows_as_unsupported_in_its_own_check_and_nowhere_else() {
    let base = probed(&[]);
    for &v in Variant::ALL {
        let r = probed(&[v]);
        let changed: Vec<_> = results(&r).into_iter().zip(results(&base)).filter(|(x, y)| x != y).collect();
        let expected: Vec<(&str, CheckResult)> = match v {
            Variant::NoGroups => vec![
                ("grouping_indices", CheckResult::Unsupported),
                // The session's object names groups: not tried on such a unit.
                ("cyclic_objects", CheckResult::Skipped),
            ],
            Variant::NoUserPositions => vec![("user_position_data", CheckResult::Unsupported)],
            Variant::NoCyclicObjects => vec![("cyclic_objects", CheckResult::Unsupported)],
            Variant::NoRemoteReadBack => {
                vec![("cyclic_objects", CheckResult::Skipped), ("remote_read_back", CheckResult::Unsupported)]
            }
            Variant::Sleepy => vec![("answers_first_telegram", CheckResult::Unsupported)],
            // Taken in both forms, or shown only by a motion or by switching a function: the probe cannot tell
            // these units apart.
            Variant::RcEmptyData
            | Variant::StickyErrors
            | Variant::InEndUndershoot
            | Variant::ReNeedsRs
            | Variant::LateMotionBit
            | Variant::SwitchStatusUnshown
            // Shown only by a unit with a standing error, or after a watchdog lapse.
            | Variant::AckWithoutMotion
            | Variant::RcRearmsWatchdog
            // Woken by the client's break before the probe: what it does then is the plain unit's.
            | Variant::LowPower => vec![],
        };
        let got: Vec<(&str, CheckResult)> = changed.iter().map(|(x, _)| *x).collect();
        assert_eq!(got, expected, "{}", v.name());
        for (name, _) in expected.iter().filter(|(_, r)| *r == CheckResult::Unsupported) {
            assert_eq!(r.check(name, None).unwrap().variant, Some(v.name()), "{name}");
        }
    }
}

#[test]
fn a_saved_profile_seeds_the_next_session_and_its_probe_exchanges_disappear() {
    let dir = std::env::temp_dir().join(format!("motionlink-scu-profile-{}", std::process::id()));
    let path = dir.join("profiles.toml");
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::NoGroups, Variant::NoUserPositions]);
    let client = rig.client(Config::default());
    let mut report = probe(&client, &ProbeSetup::new("lift", PortKind::Sim, 38_400)).unwrap();
    client.close().unwrap();
    let mut profiles = Profiles::load(&path).unwrap();
    save_profile(&mut report, &mut profiles).unwrap();
    assert_eq!(report.saved.len(), 1);
    assert!(report.saved[0].starts_with(&format!("{}#scu:lift:", path.display())), "{:?}", report.saved);

    // What a move reads before it moves, counted by the requests' first bytes: RG 0x0170 / 0x2001 refused.
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    rig.on_request(move |bytes, _| log.lock().unwrap().push(bytes.to_vec()));
    let refused_reads = |sent: &[Vec<u8>]| {
        sent.iter().filter(|b| b.starts_with(b"RG") && (b[2..4] == [0x70, 0x01] || b[2..4] == [0x01, 0x20])).count()
    };
    let profiles = Profiles::load(&path).unwrap();
    let fresh = rig.client(Config::default());
    fresh.statuses().unwrap();
    fresh.stroke_limits(a(1)).unwrap_err();
    assert_eq!(refused_reads(&sent.lock().unwrap()), 2, "without the profile the session probes");
    fresh.close().unwrap();

    sent.lock().unwrap().clear();
    let seeded = rig.client(Config::default());
    let used = use_profile(&seeded, &profiles, "lift").unwrap();
    assert_eq!(used.reference.as_deref(), Some(report.saved[0].as_str()));
    assert!(used.notices.is_empty());
    assert_eq!(seeded.capabilities().grouping_indices, Some(false));
    assert_eq!(seeded.capabilities().cyclic_objects, None, "not settled by the probe: not in the profile");
    seeded.statuses().unwrap();
    seeded.stroke_limits(a(1)).unwrap_err();
    assert_eq!(refused_reads(&sent.lock().unwrap()), 0, "the profile's findings are not probed again");
    seeded.close().unwrap();

    // Another unit on the same port: the profile is left unused, with a notice.
    let other = Rig::new(SimConfig { firmware_info: "SCU V2B4 other".into(), ..SimConfig::default() });
    let client = other.client(Config::default());
    let used = use_profile(&client, &profiles, "lift").unwrap();
    assert_eq!(used.reference, None);
    assert!(used.notices[0].contains("V2B4") && used.notices[0].contains("not used"), "{:?}", used.notices);
    assert_eq!(client.capabilities(), Capabilities::default());
    // No profile for the port: nothing is read.
    assert_eq!(use_profile(&client, &profiles, "/dev/ttyUSB9").unwrap(), Default::default());
    client.close().unwrap();
    std::fs::remove_dir_all(dir).unwrap();
}

/// A link to a unit running at `unit_baud`, opened at `baud`: at another rate every byte arrives garbled
/// (as a UART reads a frame of the wrong rate).
struct AtRate {
    inner: Box<dyn Link>,
    garble: bool,
}

impl Link for AtRate {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let n = self.inner.recv(buf, timeout)?;
        if self.garble {
            buf[..n].iter_mut().for_each(|b| *b = b.rotate_left(3) ^ 0x5A);
        }
        Ok(n)
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

#[test]
fn baud_auto_finds_the_rate_the_unit_answers_at() {
    let rig = Rig::new(SimConfig::default());
    let open = |baud: u32| {
        let host = rig.host.clone();
        let connector: Connector = Box::new(move || {
            let (link, _) = host.connect();
            Ok(Box::new(AtRate { inner: Box::new(link), garble: baud != 19_200 }) as Box<dyn Link>)
        });
        Client::with_connector(connector, rig.clock.shared(), Config::default())
    };
    let (found, check) = find_baud(PortKind::Serial, &BaudChoice::Auto(BAUD_RATES), open);
    let (client, baud) = found.unwrap();
    assert_eq!((baud, check.result), (19_200, CheckResult::Ok));
    assert!(check.detail.contains("38400") && check.detail.starts_with("answers at 19200"), "{}", check.detail);
    let mut setup = ProbeSetup::new("/dev/ttyUSB0", PortKind::Serial, baud);
    setup.baud_check = Some(check);
    setup.sysfs_root = std::env::temp_dir().join("motionlink-no-sysfs");
    let report = probe(&client, &setup).unwrap();
    assert_eq!(report.link.baud, Some(19_200));
    assert_eq!(report.checks[0].name, "baud");
    assert_eq!(report.check("latency_timer", None).unwrap().result, CheckResult::Skipped);
    client.close().unwrap();
}
