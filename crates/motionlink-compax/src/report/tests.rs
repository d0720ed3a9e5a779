//! The JSON of every report: the names and shapes the command line's `--json` prints (its tests and
//! Python's compare against the binary; these pin each report on its own).

use serde_json::json;

use super::*;
use crate::error::{StopOutcome, StopReport};
use crate::model::{HistoryEntry, S16Flag, S17Flag};

const D5: Address = Address::drive_const(5);

fn p(units: f64) -> Position {
    Position::new(units).unwrap()
}

fn to_json(v: &impl Serialize) -> serde_json::Value {
    serde_json::to_value(v).unwrap()
}

#[test]
fn a_drive_position_and_a_scan_entry() {
    assert_eq!(to_json(&DrivePosition::from((D5, p(12.5)))), json!({"drive": 5, "position_units": 12.5}));
}

#[test]
fn status_values_are_numbers_flag_words_with_their_pattern_or_text() {
    let s16 = S16Bits(0b1101_1010);
    assert!(s16.contains(S16Flag::NoFault));
    let history = [HistoryEntry::Error(crate::model::ErrorCode(92)); 8];
    let values = vec![
        (StatusId::new(1).unwrap(), StatusValue::Position(p(-0.5))),
        (StatusId::new(6).unwrap(), StatusValue::Number(31.0)),
        (StatusId::new(16).unwrap(), StatusValue::S16(s16)),
        (StatusId::new(17).unwrap(), StatusValue::S17(S17Bits(0b0010_0010))),
        (StatusId::new(18).unwrap(), StatusValue::History(history)),
    ];
    let report = to_json(&StatusReport::from(values));
    let status = report["status"].as_array().unwrap();
    assert_eq!(status[0], json!({"status": "S1", "name": "actual position", "unit": "unit", "value": -0.5}));
    assert_eq!(status[1]["value"], json!(31.0));
    assert_eq!(
        status[2]["value"],
        json!({"word": 218, "flags": ["NO_FAULT", "NO_WARNING", "READY_FOR_START", "POSITION_REACHED", "O0_BIT7"],
               "pattern": "1101 1010"})
    );
    assert!(S17Bits(0b0010_0010).contains(S17Flag::CommandActive));
    assert_eq!(status[3]["value"]["pattern"], "0010 0010");
    assert_eq!(status[4]["value"], "92 92 92 92 92 92 92 92");
    assert_eq!(status[4]["name"], "error history");
}

#[test]
fn a_bit_no_name_covers_is_counted_apart() {
    // S16 names every bit; S17's bit 6 and bit 8 have none.
    let v = to_json(&WithPattern(S17Bits(0b0000_1101)));
    assert_eq!(v, json!({"word": 13, "flags": ["STOP_VIA_I6"], "unknown_bits": 5, "pattern": "0000 1101"}));
}

#[test]
fn a_parameter_read_and_written() {
    let read = ParamReading { id: ParamId::BAUD_RATE, value: 9600.0 };
    assert_eq!(to_json(&read), json!({"name": "P195", "id": 195, "value": 9600.0, "unit": "bit/s", "access": "rw"}));
    let written =
        ParamWritten { written: ParamReading { id: ParamId::new(3).unwrap(), value: -1055.88 }, read_back: -1055.88 };
    assert_eq!(
        to_json(&written),
        json!({"name": "P003", "id": 3, "value": -1055.88, "unit": written.written.unit(),
               "access": "rw", "read_back": -1055.88, "verified": true, "not_verifiable": []})
    );
    assert!(!written.at_power_on());
    assert!(ParamWritten { written: read, read_back: 9600.0 }.at_power_on());
}

#[test]
fn a_move_waited_for_and_one_handed_over() {
    let report = MoveReport {
        address: D5,
        start: p(0.0),
        target: p(10.0),
        reached: p(10.004),
        tolerance: p(0.01),
        verified: false,
        not_verifiable: vec!["drive 5 echoes without its address".into()],
    };
    let v = to_json(&report);
    assert_eq!(
        v,
        json!({"drive": 5, "target_units": 10.0, "reached_units": 10.004, "difference_units": report.difference(),
               "tolerance_units": 0.01, "waited": true, "verified": false,
               "not_verifiable": ["drive 5 echoes without its address"]})
    );
    let started = StartedMove { address: D5, start: p(0.0), target: p(5.0), not_verifiable: Vec::new() };
    assert_eq!(
        to_json(&started),
        json!({"drive": 5, "target_units": 5.0, "waited": false, "verified": true, "not_verifiable": []})
    );
}

#[test]
fn a_raw_command_a_switched_output_and_a_stop() {
    let raw = RawOutcome { reply: Some("S001: 0.000".into()), started: vec![D5], waited: false };
    assert_eq!(to_json(&raw), json!({"reply": "S001: 0.000", "started": [5], "waited": false}));
    let none = RawOutcome { reply: None, started: Vec::new(), waited: true };
    assert_eq!(to_json(&none), json!({"reply": null, "started": [], "waited": true}));
    let on = OutputSwitched::checked(D5, 0, OutputState::ON, Some(Ok(1))).unwrap();
    assert_eq!(to_json(&on), json!({"output": 0, "state": 1, "read_back": 1, "verified": true, "not_verifiable": []}));
    let e = OutputSwitched::checked(D5, 0, OutputState::ON, Some(Ok(0))).unwrap_err();
    assert!(matches!(e, crate::Error::OutputNotTaken { wrote: 1, read: 0, .. }), "{e:?}");
    assert!(e.to_string().contains("acknowledged OUTPUT O0=1 but S16 read afterwards shows O0=0"), "{e}");
    let unread = OutputSwitched::checked(D5, 0, OutputState::OFF, Some(Err(crate::Error::CancelledBeforeMotion)));
    let unread = unread.unwrap();
    assert!(!unread.verified && unread.read_back.is_none() && unread.not_verifiable[0].starts_with("S16 could not"));
    let other = OutputSwitched::checked(D5, 3, OutputState::ON, None).unwrap();
    assert_eq!(
        to_json(&other)["not_verifiable"],
        json!(["output O3 is not read back: of the outputs, the status values show O0 only (S16)"])
    );
    let every = OutputSwitched::checked(Address::BROADCAST, 0, OutputState::OFF, None).unwrap();
    assert!(!every.verified && every.not_verifiable[0].contains("address 32"), "{every:?}");
    let stop = StopReport {
        drives: vec![
            (D5, StopOutcome::SwitchedOff),
            (Address::drive_const(6), StopOutcome::NotConfirmed { reason: "no reply".into() }),
        ],
    };
    assert_eq!(
        to_json(&stop),
        json!({"drives": [{"drive": 5, "outcome": "switched_off"},
                          {"drive": 6, "outcome": "not_confirmed", "reason": "no reply"}],
               "confirmed": false})
    );
}

#[test]
fn a_watch_sample_with_its_time() {
    let sample = WatchSample { drive: D5, position: p(2.5), s17: S17Bits(0b0010_0010), s1_moved: false };
    assert_eq!(
        to_json(&Timed { t_s: 0.25, sample }),
        json!({"t_s": 0.25, "drive": 5, "position_units": 2.5, "moving": true,
               "s17": {"word": 34, "flags": ["COMMAND_ACTIVE", "RUN"], "pattern": "0010 0010"}})
    );
}

#[test]
fn a_look_at_a_drive_takes_a_clear_no_fault_bit_as_its_fault_and_moves_while_a_command_is_active() {
    use crate::model::bit_mask;
    let at = Position::new(12.5).unwrap();
    let look = axis_look(at, Some(2.0), S16Bits(bit_mask(5)), S17Bits(bit_mask(3)), false);
    assert_eq!(
        to_json(&look),
        json!({"position_units": 12.5, "speed_units_per_s": 2.0, "moving": true,
               "flags": ["POSITION_REACHED", "COMMAND_ACTIVE"], "faults": ["FAULT (S16 NO_FAULT clear)"]})
    );
    let fine = axis_look(at, None, S16Bits(bit_mask(1)), S17Bits(0), false);
    assert!(fine.faults.is_empty() && !fine.moving && fine.speed.is_none(), "{fine:?}");
    // S1 moved while S17 shows no command (a drive without bit 3, or moved by an input): moving.
    assert!(axis_look(at, Some(3.0), S16Bits(bit_mask(1)), S17Bits(0), true).moving);
}

#[test]
fn a_watch_sample_moves_while_s17_shows_a_command_or_s1_changed_beyond_the_tolerance() {
    let tolerance = p(0.1);
    let first = WatchSample::after(None, D5, p(2.5), S17Bits(0), tolerance);
    assert!(!first.moving(), "the first sample has nothing to compare with");
    assert!(!WatchSample::after(Some(p(2.45)), D5, p(2.5), S17Bits(0), tolerance).moving(), "within the tolerance");
    let by_s1 = WatchSample::after(Some(p(2.0)), D5, p(2.5), S17Bits(0), tolerance);
    assert!(by_s1.moving() && by_s1.s1_moved);
    assert_eq!(to_json(&by_s1)["moving"], json!(true));
    let by_s17 = WatchSample::after(Some(p(2.5)), D5, p(2.5), S17Bits(crate::model::bit_mask(3)), tolerance);
    assert!(by_s17.moving() && !by_s17.s1_moved);
}
