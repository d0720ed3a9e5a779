//! Tests of the emulator's own details.

use super::*;
use crate::model::DataEntryExt;
use crate::model::DATA_LIST;

fn send(unit: &mut Emulator, at_ms: u64, r: Request<'_>) -> Vec<u8> {
    let mut out = Vec::new();
    unit.receive(Timestamp::from_millis(at_ms), &crate::wire::request_to_vec(&r).unwrap(), &mut out);
    out
}

#[test]
fn take_events_reports_switching_and_keeps_only_the_newest_when_nobody_takes_them() {
    let mut unit = Emulator::new(SimConfig::default()).unwrap();
    send(&mut unit, 0, Request::Open { safety_id: 2 });
    send(&mut unit, 0, Request::Cyclic { object: UNUSED, write: &[] });
    send(&mut unit, 1, Request::Execute { function: 10, params: [UNUSED, UNUSED] });
    send(&mut unit, 2, Request::Stop { function: 10, param: UNUSED });
    assert_eq!(unit.take_events(), ["remote mode opened (Safety_ID 2)", "F11 on (buzzer)", "F11 off (buzzer)"]);
    for i in 0..MAX_EVENTS as u64 {
        send(&mut unit, 3 + i / 10, Request::Execute { function: 20, params: [UNUSED, UNUSED] });
        send(&mut unit, 3 + i / 10, Request::Stop { function: 20, param: UNUSED });
        send(&mut unit, 3 + i / 10, Request::Cyclic { object: UNUSED, write: &[] });
    }
    let events = unit.take_events();
    assert_eq!(events.len(), MAX_EVENTS);
    assert_eq!(events.last().map(String::as_str), Some("F21 off (operating unit LED 1)"));
}

#[test]
fn next_wakeup_is_the_watchdog_while_idle_and_every_model_step_while_moving() {
    let mut unit = Emulator::new(SimConfig::default()).unwrap();
    assert_eq!(unit.next_wakeup(), None, "outside remote mode nothing happens by itself");
    send(&mut unit, 100, Request::Open { safety_id: 0 });
    assert_eq!(unit.next_wakeup(), Some(Timestamp::from_millis(600)));
    send(&mut unit, 200, Request::Cyclic { object: UNUSED, write: &[] });
    send(&mut unit, 200, Request::Execute { function: 0, params: [2, UNUSED] });
    assert_eq!(unit.next_wakeup(), Some(Timestamp::from_millis(205)));
    let mut out = Vec::new();
    unit.advance(Timestamp::from_millis(700), &mut out);
    assert!(out.is_empty());
    assert!(!unit.any_moving(), "the watchdog stopped it at 700 ms");
    assert_eq!(unit.next_wakeup(), None, "locked: nothing is due");
    let events = unit.take_events();
    assert!(events.iter().any(|e| e.starts_with("A1 at rest")), "{events:?}");
    assert!(events.iter().any(|e| e.starts_with("remote mode ended by watchdog (Safety_ID 0)")), "{events:?}");
}

#[test]
fn every_entry_of_the_data_list_has_a_modelled_value() {
    let unit = Emulator::new(SimConfig::scp11(6)).unwrap();
    for e in DATA_LIST {
        assert!(unit.entry_value(e).is_some(), "{} ({}) is not modelled", e.name, e.index());
    }
}

#[test]
fn each_variant_refuses_or_answers_as_its_firmware_would() {
    use crate::model::CyclicObject;
    let open = |variants: Vec<Variant>| {
        let mut unit = Emulator::new(SimConfig { variants, ..SimConfig::default() }).unwrap();
        send(&mut unit, 0, Request::Open { safety_id: 0 });
        send(&mut unit, 0, Request::Cyclic { object: UNUSED, write: &[] });
        unit
    };
    let status = |reply: &[u8]| Status::from_code(reply[2]).unwrap();
    let v = |v: Variant| vec![v];
    // Grouping indices: refused to RG, to RT, and in a cyclic object's definition; entries answer.
    let mut unit = open(v(Variant::NoGroups));
    assert_eq!(status(&send(&mut unit, 1, Request::Get { index: 0x0010 })), Status::ParameterDataError);
    assert_eq!(status(&send(&mut unit, 1, Request::Get { index: 0x0170 })), Status::ParameterDataError);
    assert_eq!(send(&mut unit, 1, Request::Get { index: 0x0011 }).len(), 11);
    let speeds = [50u8, 0].repeat(10);
    assert_eq!(
        status(&send(&mut unit, 1, Request::Transfer { index: 0x3010, data: &speeds })),
        Status::ParameterDataError
    );
    let object = CyclicObject::new(&[], &[DataIndex(0x0170)]).unwrap().to_bytes();
    assert_eq!(
        status(&send(&mut unit, 1, Request::Transfer { index: 0x3005, data: &object })),
        Status::ParameterDataError
    );
    // UserPositionData.
    let mut unit = open(v(Variant::NoUserPositions));
    assert_eq!(status(&send(&mut unit, 1, Request::Get { index: 0x2001 })), Status::ParameterDataError);
    assert_eq!(status(&send(&mut unit, 1, Request::Get { index: 0x0010 })), Status::Ack);
    // Cyclic objects: the definition is remote data like any other, the RC that carries it is refused (and
    // still feeds the watchdog).
    let mut unit = open(v(Variant::NoCyclicObjects));
    let object = CyclicObject::new(&[], &[DataIndex(0x0011)]).unwrap().to_bytes();
    assert_eq!(status(&send(&mut unit, 1, Request::Transfer { index: 0x3001, data: &object })), Status::Ack);
    assert_eq!(status(&send(&mut unit, 400, Request::Cyclic { object: 0, write: &[] })), Status::ParameterDataError);
    assert_eq!(status(&send(&mut unit, 800, Request::Get { index: 0x0011 })), Status::Ack, "no watchdog expiry");
    // Remote data is not read back.
    let mut unit = open(v(Variant::NoRemoteReadBack));
    assert_eq!(status(&send(&mut unit, 1, Request::Transfer { index: 0x3011, data: &[40, 0] })), Status::Ack);
    assert_eq!(status(&send(&mut unit, 1, Request::Get { index: 0x3011 })), Status::ParameterDataError);
    // RC without an object: ACK, ctp 0.
    let mut unit = open(v(Variant::RcEmptyData));
    let reply = send(&mut unit, 1, Request::Cyclic { object: UNUSED, write: &[] });
    assert_eq!(&reply[..5], b"RC\x06\x00\x00");
    assert_eq!(reply.len(), 7);
    // Sleepy: the first telegram after power-on and after 2 s of silence is not answered.
    let mut unit = Emulator::new(SimConfig { variants: v(Variant::Sleepy), ..SimConfig::default() }).unwrap();
    assert!(send(&mut unit, 0, Request::Open { safety_id: 0 }).is_empty());
    assert!(!send(&mut unit, 150, Request::Open { safety_id: 0 }).is_empty());
    assert!(!send(&mut unit, 1_000, Request::Abort).is_empty());
    assert!(send(&mut unit, 3_000, Request::Open { safety_id: 0 }).is_empty());
    // A new RE of a started function needs its RS first.
    let mut unit = open(v(Variant::ReNeedsRs));
    let re = Request::Execute { function: 0, params: [2, UNUSED] };
    assert_eq!(status(&send(&mut unit, 1, re)), Status::Ack);
    assert_eq!(status(&send(&mut unit, 2, re)), Status::PermissionError);
    assert_eq!(status(&send(&mut unit, 3, Request::Stop { function: 0, param: 0 })), Status::Ack);
    assert_eq!(status(&send(&mut unit, 4, re)), Status::Ack);
}

#[test]
fn a_new_target_where_a_motion_just_began_turns_the_actuator_back_to_it() {
    let mut cfg = SimConfig::default().actuators[0].clone();
    cfg.start_position_counts = 460;
    let mut a = actuator::ActuatorState::new(cfg);
    let start = a.reported_position();
    assert!(a.start(start - 40, 1000.0, 100, Origin::Remote, Some(0)));
    a.step(0.001); // on its way, still within half a count of where it started
    assert!((a.reported_position() - start).abs() < 1, "{}", a.reported_position());
    // The newest target is where it started: it goes back there (follow's last line), not on to the first.
    assert!(a.start(start, 1000.0, 100, Origin::Remote, Some(0)));
    for _ in 0..5000 {
        a.step(0.001);
    }
    assert!(!a.moving());
    assert_eq!(a.reported_position(), start);
    // At rest there, the same target moves nothing.
    assert!(!a.start(start, 1000.0, 100, Origin::Remote, Some(0)));
}
