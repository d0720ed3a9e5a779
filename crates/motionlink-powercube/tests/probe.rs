//! `motionlink_powercube::probe` against the emulated bus and every firmware variant: the report says
//! `unsupported` for the behaviour a variant changes and what the default modules say otherwise; a saved
//! profile seeds a later session (whose probe exchange disappears) only when the module's identity matches.

use motionlink_powercube::PortLink;

use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::PipeConfig;
use motionlink_link::probe::{CheckResult, PortKind, ProbeSetup};
use motionlink_link::profile::Profiles;
use motionlink_powercube::client::{Client, Config};
use motionlink_powercube::model::Address;
use motionlink_powercube::probe::{probe, save_profile, use_profile, PowercubeProbeReport};
use motionlink_powercube::session::{ModuleFindings, Op};
use motionlink_powercube::sim::{FirmwareVariant, SimConfig, Variant};
use motionlink_powercube::Emulator;

/// The modules on the workspace's rig (the test thread among the clock's participants).
type Rig = motionlink_testkit::rig::Rig<Emulator>;

fn bus(config: &SimConfig) -> (Rig, Client) {
    let rig = Rig::new(Emulator::new(config), PipeConfig::paced(9_600)).with_test_thread();
    let client = Client::with_link(PortLink::Rs232(rig.link().unwrap()), rig.shared_clock(), Config::rs232()).unwrap();
    (rig, client)
}

fn config(variants: &[Variant]) -> SimConfig {
    let mut c = SimConfig::with_addresses(&[1, 17]).unwrap();
    c.variants = variants.to_vec();
    c
}

fn probed(variants: &[Variant]) -> PowercubeProbeReport {
    let (_rig, client) = bus(&config(variants));
    let report = probe(&client, &ProbeSetup::new("sim", PortKind::Sim, 9_600)).unwrap();
    assert!(client.started().is_empty(), "nothing set in motion");
    client.close().unwrap();
    report
}

fn results(r: &PowercubeProbeReport) -> Vec<(&'static str, Option<u8>, CheckResult)> {
    r.checks.iter().map(|c| (c.name, c.address, c.result)).collect()
}

#[test]
fn the_default_modules_are_found_identified_and_answer_the_harmless_probe() {
    let r = probed(&[]);
    assert_eq!(r.devices.iter().map(|m| m.address).collect::<Vec<_>>(), vec![1, 17]);
    for m in &r.devices {
        assert!(m.identity.starts_with("version ") && m.identity.contains(&m.serial.to_string()), "{}", m.identity);
        assert_eq!(m.findings, ModuleFindings { pos_state_dio: Some(true), ..Default::default() });
    }
    for (name, address, result) in results(&r) {
        let answered = ["pos_state_dio", "config_word"].contains(&name);
        let expected = if answered { CheckResult::Ok } else { CheckResult::Skipped };
        assert_eq!(result, expected, "{name} of {address:?}");
    }
    // Two link rows, then eight per module.
    assert_eq!(r.checks.len(), 2 + 2 * 8);
    assert_eq!((r.link.exchanges, r.link.errors), (20, 0));
    assert!(r.link.round_trip_ms.unwrap().min > 5.0, "9600 baud: {:?}", r.link.round_trip_ms);
    let broadcast = r.check("rs232_broadcast", Some(1)).unwrap();
    assert!(broadcast.detail.contains("watchdog armed"), "{}", broadcast.detail);
}

#[test]
fn each_variant_shows_as_unsupported_in_its_own_check_and_nowhere_else() {
    let base = results(&probed(&[]));
    for &v in Variant::ALL {
        let r = probed(&[v]);
        let changed: Vec<_> = results(&r).into_iter().zip(&base).filter(|(x, y)| x != *y).map(|(x, _)| x).collect();
        let expected = match v {
            Variant::NoPosStateDio => vec![
                ("pos_state_dio", Some(1), CheckResult::Unsupported),
                ("pos_state_dio", Some(17), CheckResult::Unsupported),
            ],
            Variant::NoConfigWord => vec![
                ("config_word", Some(1), CheckResult::Unsupported),
                ("config_word", Some(17), CheckResult::Unsupported),
            ],
            // Shown only with a write of another value or an armed watchdog, or taken in both forms.
            _ => vec![],
        };
        assert_eq!(changed, expected, "{}", v.name());
    }
}

#[test]
fn a_saved_profile_seeds_the_module_and_its_probe_exchange_disappears() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-profile-{}", std::process::id()));
    let path = dir.join("profiles.toml");
    let setup = ProbeSetup::new("/dev/ttyS9", PortKind::Sim, 9_600);
    let (_rig, client) = bus(&config(&[Variant::NoPosStateDio]));
    let mut report = probe(&client, &setup).unwrap();
    client.close().unwrap();
    let mut profiles = Profiles::load(&path).unwrap();
    save_profile(&mut report, &mut profiles).unwrap();
    assert_eq!(report.saved.len(), 2);

    let a1 = Address::new(1).unwrap();
    let (rig, client) = bus(&config(&[Variant::NoPosStateDio]));
    let used = use_profile(&client, &profiles, "/dev/ttyS9", a1).unwrap();
    assert_eq!(used.reference.as_deref(), Some(report.saved[0].as_str()));
    assert_eq!(client.session(|s| s.findings(a1)).pos_state_dio, Some(false));
    let before = rig.sent().len();
    client.run(Op::ProbePosStateDio(a1)).unwrap();
    assert_eq!(rig.sent().len(), before, "known from the profile: nothing sent");
    // Module 17 was not looked up: its probe is made (and sends).
    client.run(Op::ProbePosStateDio(Address::new(17).unwrap())).unwrap();
    assert!(rig.sent().len() > before);
    client.close().unwrap();

    // Another module at address 1 (another serial number): ignored, with a notice.
    let mut other = config(&[]);
    other.modules[0].serial += 1;
    let (_rig, client) = bus(&other);
    let used = use_profile(&client, &profiles, "/dev/ttyS9", a1).unwrap();
    assert_eq!(used.reference, None);
    assert!(used.notices[0].contains("not used") && used.notices[0].contains("(address 1)"), "{:?}", used.notices);
    assert_eq!(client.session(|s| s.findings(a1)), ModuleFindings::default());
    client.close().unwrap();
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn on_can_the_broadcast_is_the_manuals_and_not_probed() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let sim = Emulator::new_can(&SimConfig::with_addresses(&[3]).unwrap());
    let canbus = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
    let client = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    let r = probe(&client, &ProbeSetup::new("socketcan://can0", PortKind::Can, 0)).unwrap();
    assert_eq!(r.devices.len(), 1);
    assert_eq!(r.check("pos_state_dio", Some(3)).unwrap().result, CheckResult::Ok);
    assert!(r.check("rs232_broadcast", Some(3)).unwrap().detail.contains("CAN"));
    assert!(r.check("baud", None).unwrap().detail.contains("CAN port"));
    client.close().unwrap();
}
