//! `motionlink_compax::probe` against the emulated bus and every firmware variant: the report says
//! `unsupported` for the behaviour a variant changes and what the default drives say otherwise; a saved
//! profile seeds a later session (whose echo probe disappears) only when the drive's identity matches.

use motionlink_compax::client::{Client, Config};
use motionlink_compax::model::StatusId;
use motionlink_compax::probe::{parse_drives, probe, save_profile, use_profile, CompaxProbeReport};
use motionlink_compax::session::{EchoForm, Op};
use motionlink_compax::sim::{Emulator, FirmwareVariant, SimConfig, Variant};
use motionlink_compax::wire::Mode;
use motionlink_link::pipe::PipeConfig;
use motionlink_link::probe::{CheckResult, PortKind, ProbeSetup};
use motionlink_link::profile::Profiles;

use crate::support::a;

/// The drives on the workspace's rig (the test thread among the clock's participants).
type Rig = motionlink_testkit::rig::Rig<Emulator>;

fn emulated(variants: &[Variant], p196: u32) -> (Rig, Client) {
    let mut cfg = SimConfig::bus(&[1, 3], p196, 9600);
    cfg.variants = variants.to_vec();
    let rig = Rig::new(Emulator::new(cfg).unwrap(), PipeConfig::paced(9600)).with_test_thread();
    let mut config = Config::new(Mode::from_p196(p196).unwrap(), 9600);
    if variants.contains(&Variant::SlowReplies) {
        // Drives that answer 300 ms late, given the reply timeout such drives need (`--timeout-ms 600`):
        // with the default one no drive answers in time (tests/variants.rs).
        config.reply_timeout = std::time::Duration::from_millis(600);
    }
    let client = Client::with_link(rig.link().unwrap(), rig.shared_clock(), config).unwrap();
    (rig, client)
}

fn probed(variants: &[Variant], p196: u32) -> CompaxProbeReport {
    let (_rig, client) = emulated(variants, p196);
    let report = probe(&client, &ProbeSetup::new("sim", PortKind::Sim, 9600), &parse_drives("1-4").unwrap()).unwrap();
    assert!(client.started().is_empty(), "nothing set in motion");
    client.close().unwrap();
    report
}

fn results(r: &CompaxProbeReport) -> Vec<(&'static str, Option<u8>, CheckResult)> {
    r.checks.iter().map(|c| (c.name, c.address, c.result)).collect()
}

#[test]
fn the_default_drives_are_found_identified_and_echo_in_full() {
    for p196 in [0, 8 + 64] {
        let r = probed(&[], p196);
        assert_eq!(r.devices.iter().map(|d| d.address).collect::<Vec<_>>(), vec![1, 3], "P196 {p196}");
        let d = &r.devices[0];
        assert_eq!(d.identity, "S31 COMPAX EMULATOR | S32 MOTIONLINK");
        assert_eq!((d.p196_mode, d.mode_in_use, d.p194_address), (Some(f64::from(p196)), p196, Some(1.0)));
        assert_eq!(d.capabilities.echo_form, Some(EchoForm::Full));
        for (name, address, result) in results(&r) {
            let expected = match name {
                "baud" | "latency_timer" | "echo_stores" | "command_bit" => CheckResult::Skipped,
                _ => CheckResult::Ok,
            };
            assert_eq!(result, expected, "{name} of {address:?}, P196 {p196}: {:?}", r.check(name, address));
        }
        assert_eq!((r.link.exchanges, r.link.errors), (20, 0));
    }
}

#[test]
fn each_variant_shows_as_unsupported_in_its_own_check_and_nowhere_else() {
    let base = results(&probed(&[], 0));
    for &v in Variant::ALL {
        let r = probed(&[v], 0);
        let changed: Vec<_> = results(&r).into_iter().zip(&base).filter(|(x, y)| x != *y).map(|(x, _)| x).collect();
        let unsupported =
            |name| vec![(name, Some(1), CheckResult::Unsupported), (name, Some(3), CheckResult::Unsupported)];
        let expected = match v {
            Variant::EchoWithoutAddress | Variant::EchoBare | Variant::NoEcho => unsupported("echo_form"),
            Variant::StatusValueOnly => vec![("status_value_form", Some(1), CheckResult::Unsupported)],
            // Storing is not harmless: not probed; nor is a move (for the '$' message, for S17's bit 3).
            Variant::EchoWithoutStore | Variant::BufferQueues | Variant::NoPositionMessage | Variant::NoCommandBit => {
                vec![]
            }
            // Given a reply timeout long enough, a slow drive is probed as any other.
            Variant::SlowReplies => vec![],
            // Whether '?' carries a move out is not probed (it would move the axis); a move sent with '?'
            // counts as started on every drive.
            Variant::EchoExecutes => vec![],
        };
        assert_eq!(changed, expected, "{}", v.name());
        if let Some((name, address, _)) = expected.first() {
            assert_eq!(r.check(name, *address).unwrap().variant, Some(v.name()), "{name}");
        }
    }
}

#[test]
fn a_wrong_mode_finds_no_drive_and_says_why() {
    let (rig, client) = emulated(&[], 8);
    // The drives want a BCC (P196 8); this session sends none.
    let bus =
        Client::with_link(rig.link().unwrap(), rig.shared_clock(), Config::new(Mode::from_p196(0).unwrap(), 9600))
            .unwrap();
    drop(client);
    let r = probe(&bus, &ProbeSetup::new("sim", PortKind::Sim, 9600), &parse_drives("1").unwrap()).unwrap();
    assert!(r.devices.is_empty());
    let c = r.check("drives", None).unwrap();
    assert!(c.result == CheckResult::Failed && c.detail.contains("BCC 8"), "{c:?}");
    bus.close().unwrap();
}

#[test]
fn drives_are_a_list_or_ranges_and_bad_ones_are_named() {
    let n = |t: &str| parse_drives(t).map(|v| v.iter().map(|a| a.get()).collect::<Vec<_>>());
    assert_eq!(n("3,1-2, 3"), Ok(vec![1, 2, 3]));
    assert_eq!(n("1-31").unwrap().len(), 31);
    for bad in ["0", "32", "5-2", "", "x", "1-"] {
        assert!(n(bad).unwrap_err().contains("--drives"), "{bad}");
    }
}

#[test]
fn a_saved_profile_seeds_the_drive_and_its_echo_probe_disappears() {
    let dir = std::env::temp_dir().join(format!("motionlink-compax-profile-{}", std::process::id()));
    let path = dir.join("profiles.toml");
    let (rig, client) = emulated(&[Variant::EchoWithoutAddress], 0);
    let mut report =
        probe(&client, &ProbeSetup::new("bus", PortKind::Sim, 9600), &parse_drives("1,3").unwrap()).unwrap();
    client.close().unwrap();
    let mut profiles = Profiles::load(&path).unwrap();
    save_profile(&mut report, &mut profiles).unwrap();
    assert_eq!(report.saved.len(), 2);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("echo_form = \"without_address\""), "{text}");

    let fresh = || {
        Client::with_link(rig.link().unwrap(), rig.shared_clock(), Config::new(Mode::from_p196(0).unwrap(), 9600))
            .unwrap()
    };
    let client = fresh();
    let used = use_profile(&client, &profiles, "bus", a(3)).unwrap();
    assert_eq!(used.reference.as_deref(), Some(report.saved[1].as_str()));
    assert_eq!(client.driver().with_session(|s| s.echo_form(a(3))), Some(EchoForm::WithoutAddress));
    let echoes = || rig.sent().len();
    let before = echoes();
    client.run(Op::ProbeEcho(a(3))).unwrap();
    assert_eq!(echoes(), before, "known from the profile: no echo asked for");
    client.run(Op::ProbeEcho(a(1))).unwrap();
    assert!(echoes() > before, "drive 1 was not looked up: probed");
    client.close().unwrap();

    // Another drive at 3 (another identification): ignored with a notice.
    let mut edited = Profiles::load(&path).unwrap();
    let entries: Vec<_> = edited.entries().values().cloned().collect();
    edited = Profiles::empty(path.clone());
    for mut e in entries {
        e.identity = e.identity.replace("MOTIONLINK", "ELSEWHERE");
        edited.insert(e);
    }
    let client = fresh();
    let used = use_profile(&client, &edited, "bus", a(3)).unwrap();
    assert_eq!(used.reference, None);
    assert!(used.notices[0].contains("not used") && used.notices[0].contains("ELSEWHERE"), "{:?}", used.notices);
    assert_eq!(client.driver().with_session(|s| s.echo_form(a(3))), None);
    assert!(client.read_status(a(3), StatusId::ACTUAL_POSITION).is_ok());
    client.close().unwrap();
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn an_echo_without_the_address_where_replies_carry_it_is_ok_and_says_why() {
    // P196 64: every reply starts with the drive's address, which names the drive that echoed.
    let r = probed(&[Variant::EchoWithoutAddress], 64);
    let c = r.check("echo_form", Some(1)).unwrap();
    assert_eq!(c.result, CheckResult::Ok, "{c:?}");
    assert!(c.detail.contains("without its address digits, but every reply starts with the drive's address"), "{c:?}");
    assert!(!c.detail.trim_end().ends_with(':'), "{c:?}");
}
