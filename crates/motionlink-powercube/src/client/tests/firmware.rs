//! The client against the firmware variants of older modules (`no-config-word`, `reset-clears-watchdog`,
//! `no-extended-ack`), on RS232 through the shared rig: what each operation sends, what it is refused with,
//! that nothing moves when it is refused, and what the default firmware does instead.

use super::*;
use crate::client::Guard;
use crate::error::Error;
use crate::model::{AckKind, ConfigFlag, ModuleKind, Motion, Param, StateFlag};
use crate::sim::{ModuleConfig, Variant};
use crate::wire::rs232::{Rs232Decoder, TelKind};
use crate::wire::{Action, ExtAck};

/// Module 1 of `kind` running `variants` on an RS232 line at 9600 baud (the shared rig, the test thread among
/// the clock's participants), and a client.
pub(super) fn module_of(kind: ModuleKind, variants: &[Variant]) -> (Rig<Emulator>, Client) {
    let config = SimConfig {
        modules: vec![ModuleConfig { kind, ..ModuleConfig::at(1) }],
        variants: variants.to_vec(),
        ..SimConfig::default()
    };
    let rig = Rig::new(Emulator::new(&config), PipeConfig::paced(9_600)).with_test_thread();
    let bus = Client::with_link(PortLink::Rs232(rig.link().unwrap()), rig.shared_clock(), Config::rs232()).unwrap();
    (rig, bus)
}

/// What went to the modules after the first `from` writes: (address, request), a broadcast at address 0 as
/// `None`.
fn sent_since(rig: &Rig<Emulator>, from: usize) -> Vec<(u8, Option<Request>)> {
    let mut decoder = Rs232Decoder::new();
    let bytes: Vec<u8> = rig.sent().into_iter().skip(from).flatten().collect();
    decoder
        .feed(&bytes)
        .map(|f| f.expect("the client sends whole frames"))
        .filter(|f| f.kind == TelKind::Send)
        .map(|f| (f.address, (f.address != 0).then(|| Request::decode(&f.payload).expect("a request"))))
        .collect()
}

/// The requests to module 1 in `sent`, broadcasts left out.
fn to_module_1(sent: &[(u8, Option<Request>)]) -> Vec<Request> {
    sent.iter().filter(|(a, _)| *a == 1).filter_map(|(_, r)| *r).collect()
}

fn writes_or_moves(requests: &[Request]) -> Vec<Request> {
    requests.iter().filter(|r| !matches!(r, Request::Get(_))).copied().collect()
}

#[test]
fn a_module_without_the_config_word_has_its_type_read_from_def_config() {
    // Linear, so that a type taken from nowhere (rotary, the Config word's bit clear) shows.
    let (rig, bus) = module_of(ModuleKind::Linear, &[Variant::NoConfigWord]);
    let m = bus.module(addr(1));
    assert_eq!(m.kind().unwrap(), ModuleKind::Linear);
    let config = Request::Get(Param::Config);
    let def_config = Request::Get(Param::DefConfig);
    // Three attempts at the Config word (a read is asked again), then its ROM default.
    assert_eq!(to_module_1(&sent_since(&rig, 0)), vec![config, config, config, def_config]);
    assert!(matches!(m.config_word(), Err(Error::Timeout { request: Request::Get(Param::Config), .. })));
    let info = m.info().unwrap();
    assert_eq!((info.kind, info.serial), (ModuleKind::Linear, 1001));
    // Positions come in metres.
    assert_eq!(m.position().unwrap().unit(), crate::model::AxisUnit::Metre);
    let stop = m.halt_confirmed().unwrap();
    assert_eq!(stop.kind, ModuleKind::Linear);
    bus.close().unwrap();

    // The default firmware: one read of the Config word, no DefConfig.
    let (rig, bus) = module_of(ModuleKind::Linear, &[]);
    assert_eq!(bus.module(addr(1)).kind().unwrap(), ModuleKind::Linear);
    assert_eq!(to_module_1(&sent_since(&rig, 0)), vec![config]);
    bus.close().unwrap();
}

#[test]
fn a_module_without_the_config_word_refuses_the_guarded_motion_and_moves_without_the_watchdog() {
    let (rig, bus) = module_of(ModuleKind::Rotary, &[Variant::NoConfigWord]);
    let m = bus.module(addr(1));
    let start = rig.device(|d| d.module(1).unwrap().position().value());
    for attempt in 0..2 {
        let from = rig.sent().len();
        let err = if attempt == 0 {
            m.move_to_guarded(&spec(0.5), Guard::Watchdog, &mut |_| {}).unwrap_err()
        } else {
            m.home_guarded(secs(10), Guard::Watchdog, &mut |_| {}).unwrap_err()
        };
        let text = err.to_string();
        // The arming's read of the Config word failed: its error (a timeout), named, and what it means.
        assert!(text.starts_with("cannot arm the watchdog of module 1: module 1 did not answer GetExtended Config"));
        assert!(text.contains("a module before version 3.5.00 has no Config word"), "{text}");
        assert!(matches!(&err, Error::Context { source, .. } if matches!(**source, Error::Timeout { .. })), "{err}");
        assert!(err.is_transport(), "{attempt}: the read's class: {err}");
        // Only reads went out: no Config word written, no life sign, no motion, no Halt.
        let sent = sent_since(&rig, from);
        assert!(sent.iter().all(|(a, _)| *a == 1), "{attempt}: no broadcast (no refresh): {sent:?}");
        assert_eq!(writes_or_moves(&to_module_1(&sent)), vec![], "{attempt}");
        let (state, online, position) = rig.device(|d| {
            let m = d.module(1).unwrap();
            (m.state(), m.watchdog_online(), m.position().value())
        });
        assert!(!online && !state.contains(StateFlag::Halted) && !state.has_fault(), "{attempt}: {state}");
        assert_eq!(position, start, "{attempt}: nothing moved");
        assert!(bus.started().is_empty(), "{attempt}");
    }
    // A target beyond the limits is refused as such first (its type read from DefConfig: rad fits).
    let err = m.move_to_guarded(&spec(100.0), Guard::Watchdog, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxPos, .. }), "{err}");
    // Without the watchdog it moves, verified.
    let r = m.move_to_guarded(&spec(0.3), Guard::HaltOnly, &mut |_| {}).unwrap();
    assert!((r.reached.value() - 0.3).abs() < 1e-3 && r.verified, "{r:?}");
    bus.close().unwrap();
    assert!(!rig.device(|d| d.module(1).unwrap().state().has_fault()));
}

/// A host that armed the watchdog of module 1 and died: the module halted with STATE_COMM_ERROR, its
/// watchdog online. Returns the rig and a new client.
fn left_expired(variants: &[Variant]) -> (Rig<Emulator>, Client) {
    let (rig, dead) = module_of(ModuleKind::Rotary, variants);
    dead.enable_watchdog(&addrs(&[1])).unwrap();
    kill(dead);
    rig.sleep(200);
    let (state, online) = rig.device(|d| (d.module(1).unwrap().state(), d.module(1).unwrap().watchdog_online()));
    assert!(state.contains(StateFlag::CommError) && state.contains(StateFlag::Halted) && online, "{state}");
    let bus = Client::with_link(PortLink::Rs232(rig.link().unwrap()), rig.shared_clock(), Config::rs232()).unwrap();
    (rig, bus)
}

#[test]
fn a_reset_that_clears_the_watchdog_is_observed_and_nothing_more_is_sent() {
    let reset = Request::Action(Action::Reset);
    let state = Request::Get(Param::CubeState);
    let life_sign = Request::Action(Action::LifeSign);
    for (variants, released, expected) in [
        // The default: the Reset re-arms the expired watchdog, which expires again; a life sign switches
        // it offline and a second Reset clears it, confirmed by the state read after it and once more after
        // the time in which an online watchdog would have expired again.
        (&[][..], true, vec![state, reset, state, life_sign, reset, state, state]),
        // A Reset that switches the watchdog offline: 100 ms later it has not expired again; nothing more.
        (&[Variant::ResetClearsWatchdog][..], false, vec![state, reset, state]),
    ] {
        let (rig, bus) = left_expired(variants);
        let from = rig.sent().len();
        let before = rig.clock.now();
        assert_eq!(bus.module(addr(1)).reset_and_release_watchdog().unwrap(), released, "{variants:?}");
        assert!(rig.clock.now().saturating_since(before) >= Duration::from_millis(100), "{variants:?}: waited");
        let sent = sent_since(&rig, from);
        assert!(sent.iter().all(|(a, _)| *a == 1), "{variants:?}: {sent:?}");
        assert_eq!(to_module_1(&sent), expected, "{variants:?}");
        rig.sleep(1_000);
        let (state, online) = rig.device(|d| (d.module(1).unwrap().state(), d.module(1).unwrap().watchdog_online()));
        assert!(!online && !state.contains(StateFlag::Halted) && !state.has_fault(), "{variants:?}: {state}");
        // It moves again, under a watchdog of this session's.
        let r = bus.module(addr(1)).move_to_guarded(&spec(0.3), Guard::Watchdog, &mut |_| {}).unwrap();
        assert!((r.reached.value() - 0.3).abs() < 1e-3 && r.verified, "{variants:?}: {r:?}");
        bus.close().unwrap();
        assert!(!rig.device(|d| d.module(1).unwrap().watchdog_online()), "{variants:?}");
    }
}

#[test]
fn an_extended_acknowledge_asked_of_an_older_firmware_comes_back_simple_and_the_motion_runs() {
    let motion = Motion::FRamp { pos: Position::native(0.4) };
    // The default: the extended acknowledge, position 0.05 rad at the start.
    let (rig, bus) = module_of(ModuleKind::Rotary, &[]);
    let ext: Option<ExtAck> = bus.module(addr(1)).motion(motion, AckKind::Extended).unwrap();
    let ext = ext.expect("an extended acknowledge");
    assert!(matches!(ext.position, crate::wire::AckPosition::Unit(p) if (p.value() - 0.05).abs() < 1e-3), "{ext:?}");
    bus.close().unwrap();
    drop(rig);

    let (rig, bus) = module_of(ModuleKind::Rotary, &[Variant::NoExtendedAck]);
    let m = bus.module(addr(1));
    let from = rig.sent().len();
    assert_eq!(m.motion(motion, AckKind::Extended).unwrap(), None, "the simple acknowledge");
    // Sent as asked, with the extended-acknowledge MotionID (FRAMP_ACK, 14).
    let sent = to_module_1(&sent_since(&rig, from));
    assert_eq!(sent.last(), Some(&Request::Motion(motion, AckKind::Extended)), "{sent:?}");
    // The module took it: it moves, and the session counts it as started, so the close halts it.
    assert_eq!(bus.started(), addrs(&[1]));
    rig.sleep(300);
    let (state, p) = rig.device(|d| (d.module(1).unwrap().state(), d.module(1).unwrap().position().value()));
    assert!(state.contains(StateFlag::Motion) && p > 0.06, "{state} at {p}");
    // The checked move and homing use the simple acknowledge: unchanged.
    m.halt().unwrap();
    m.reset().unwrap();
    let r = m.move_to(&spec(0.2), &mut |_| {}).unwrap();
    assert!((r.reached.value() - 0.2).abs() < 1e-3 && r.verified, "{r:?}");
    m.motion(motion, AckKind::Extended).unwrap();
    bus.close().unwrap();
    let state = rig.device(|d| d.module(1).unwrap().state());
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "halted by the close: {state}");
    // The Config word was left as it was by all of it.
    assert!(!rig.device(|d| d.module(1).unwrap().config_word().contains(ConfigFlag::WatchdogEnable)));
}

#[test]
fn a_reset_of_a_module_whose_watchdog_this_session_serves_is_refused() {
    // On a module whose Reset switches the watchdog offline, it would leave a guarded motion unguarded and
    // the session's second life sign would switch the watchdog on again (the module halted 50 ms after a
    // close that said it switched it off). Refused on every module: the session cannot tell them apart.
    for variants in [&[][..], &[Variant::ResetClearsWatchdog][..]] {
        let (rig, bus) = module_of(ModuleKind::Rotary, variants);
        bus.enable_watchdog(&addrs(&[1])).unwrap();
        let m = bus.module(addr(1));
        let from = rig.sent().len();
        let err = m.reset_and_release_watchdog().unwrap_err();
        assert!(matches!(err, Error::NotSupported(_)) && err.is_usage(), "{variants:?}: {err}");
        assert!(err.to_string().contains("module 1's watchdog is armed by this session"), "{err}");
        // The plain Reset too.
        let err = m.reset().unwrap_err();
        assert!(err.to_string().contains("module 1's watchdog is armed by this session"), "{err}");
        assert_eq!(to_module_1(&sent_since(&rig, from)), vec![], "{variants:?}: nothing sent to it");
        rig.sleep(200);
        assert!(rig.device(|d| d.module(1).unwrap().watchdog_online()), "{variants:?}: still online, served");
        bus.disable_watchdog().unwrap();
        rig.sleep(200);
        let (state, online) = rig.device(|d| (d.module(1).unwrap().state(), d.module(1).unwrap().watchdog_online()));
        assert!(!online && !state.has_fault() && !state.contains(StateFlag::Halted), "{variants:?}: {state}");
        // Once switched off, the module is reset as usual.
        assert!(!m.reset_and_release_watchdog().unwrap(), "{variants:?}");
        bus.close().unwrap();
    }
}
