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
