//! Each report's JSON, key for key, as the command line's `--json` prints it (its tests pin the same keys
//! through the binary).

use std::time::Duration;

use motionlink_link::Timestamp;
use serde_json::{json, to_value};

use super::*;
use crate::model::{find, FlagSet, Flags, MotionFunction, StopMode};
use crate::session::{ActuatorRest, RefusedStop, StopReport};

fn a(n: u8) -> Actuator {
    Actuator::new(n).unwrap()
}

fn f(n: u8) -> MotionFunction {
    MotionFunction::new(n).unwrap()
}

#[test]
fn values_show_converted_units_flag_words_and_error_codes() {
    assert_eq!(to_value(Value::CurrentDeciAmps(30)).unwrap(), json!(3.0), "30 deci-amps are 3 A, not 0.3");
    assert_eq!(to_value(Value::BatteryDeciVolts(240)).unwrap(), json!(24.0));
    assert_eq!(to_value(Value::AnalogueCentiVolts(512)).unwrap(), json!(5.12));
    assert_eq!(to_value(Value::RemotePosition(-3)).unwrap(), json!(-3));
    assert_eq!(to_value(Value::Text("SCU V2B3".into())).unwrap(), json!("SCU V2B3"));
    let flags = Value::Flags(Flags { set: FlagSet::ActuatorStatus1, bits: 0x91 });
    assert_eq!(to_value(&flags).unwrap(), json!({"word": 0x91, "flags": ["available", "motion", "stroke_done"]}));
    let unknown = Value::Flags(Flags { set: FlagSet::BinaryOutputs, bits: 0x05 });
    assert_eq!(to_value(&unknown).unwrap(), json!({"word": 5, "flags": ["output1"], "unknown_bits": 4}));
    let code = Value::ErrorCode(ErrorCode::from_bit(15));
    let cause = "error with drive 1";
    assert_eq!(
        to_value(&code).unwrap(),
        json!({"code": 0x4000, "bits": [{"bit": 15, "name": "drive1", "cause": cause}]})
    );
    let object = Value::parse(crate::model::Kind::CyclicObject, "0x3011;0x0011").unwrap();
    let shown = to_value(&object).unwrap();
    assert_eq!(
        (&shown["write"][0], &shown["read"][0], &shown["read"][1]),
        (&json!("0x3011"), &json!("0x0011"), &json!("0xFFFF"))
    );
}

#[test]
fn info_lists_the_connected_actuators_with_their_status_word() {
    let report = InfoReport {
        firmware: "SCU V2B3".into(),
        configuration: "SCP11".into(),
        battery_mains: Flags { set: FlagSet::BatteryMains, bits: 1 },
        last_error: ErrorCode::NONE,
        actuators: vec![ActuatorState::new(a(2), PositionCounts(-3), ActuatorStatus1(0x11), None)],
    };
    assert_eq!(
        to_value(&report).unwrap(),
        json!({"firmware": "SCU V2B3", "configuration": "SCP11",
               "battery_mains": {"word": 1, "flags": ["mains_connected"]}, "last_error": {"code": 0, "bits": []},
               "actuators": [{"actuator": 2, "position_counts": -3, "word": 17, "flags": ["available", "motion"],
                              "moving": true}]})
    );
}

#[test]
fn a_read_gives_the_value_in_the_unit_it_names() {
    let entry = |n: &str| match find(n).unwrap() {
        Item::Entry(e) => e,
        Item::Group(_) => unreachable!(),
    };
    let speed = GetReport {
        item: find("remote_speed_f1").unwrap(),
        values: vec![(entry("remote_speed_f1"), Value::RemoteSpeed(400))],
        speed_mode: SpeedMode::CountsPerSecond,
    };
    assert_eq!(
        to_value(&speed).unwrap(),
        json!({"name": "remote_speed_f1", "id": 0x3011, "value": 400, "unit": "counts/s", "access": "rw"})
    );
    let current = GetReport {
        item: find("current_a1").unwrap(),
        values: vec![(entry("current_a1"), Value::CurrentDeciAmps(25))],
        speed_mode: SpeedMode::Percent,
    };
    assert_eq!(to_value(&current).unwrap()["unit"], "A");
    let group = GetReport {
        item: find("info").unwrap(),
        values: vec![
            (entry("firmware_info"), Value::Text("F".into())),
            (entry("configuration_info"), Value::Text("C".into())),
        ],
        speed_mode: SpeedMode::Percent,
    };
    assert_eq!(
        to_value(&group).unwrap(),
        json!({"name": "info", "id": 0, "value": {"firmware_info": "F", "configuration_info": "C"}, "unit": "",
               "access": "r"})
    );
}

#[test]
fn a_write_says_what_was_read_back_or_why_not() {
    let Item::Entry(e) = find("remote_speed_f1").unwrap() else { unreachable!() };
    let checked = WriteReport {
        entry: e,
        value: Value::RemoteSpeed(80),
        read_back: Some(Value::RemoteSpeed(80)),
        set: SetReport { verified: true, not_verifiable: vec![] },
        speed_mode: SpeedMode::Percent,
    };
    assert_eq!(
        to_value(&checked).unwrap(),
        json!({"name": "remote_speed_f1", "id": 0x3011, "value": 80, "unit": "%", "access": "rw", "read_back": 80,
               "verified": true, "not_verifiable": []})
    );
    let unchecked = WriteReport {
        read_back: None,
        set: SetReport { verified: false, not_verifiable: vec!["not read back".into()] },
        ..checked
    };
    let v = to_value(&unchecked).unwrap();
    assert_eq!(
        (&v["read_back"], &v["verified"], &v["not_verifiable"]),
        (&json!(null), &json!(false), &json!(["not read back"]))
    );
}

#[test]
fn a_move_reports_the_target_and_difference_of_its_actuator() {
    let outcome = |n, target, reached, moved| ActuatorOutcome {
        actuator: a(n),
        target_counts: PositionCounts(target),
        start_counts: PositionCounts(0),
        position_counts: PositionCounts(reached),
        moved,
    };
    let report = MoveReport {
        actuator: a(1),
        function: f(1),
        position_counts: PositionCounts(298),
        duration: Duration::from_millis(3_250),
        actuators: vec![outcome(1, 300, 298, true), outcome(2, 300, 0, false)],
        verified: false,
        not_verifiable: vec!["the target was not checked".into()],
    };
    assert_eq!(
        to_value(&report).unwrap(),
        json!({"actuator": 1, "function": 1, "reached_counts": 298, "target_counts": 300, "difference_counts": -2,
               "time_s": 3.25, "verified": false, "not_verifiable": ["the target was not checked"],
               "actuators": [
                   {"actuator": 1, "target_counts": 300, "reached_counts": 298, "difference_counts": -2, "moved": true},
                   {"actuator": 2, "target_counts": 300, "reached_counts": 0, "difference_counts": -300, "moved": false}]})
    );
}

#[test]
fn a_stop_names_the_functions_how_and_where_each_actuator_rests() {
    let report = StopReport {
        functions: vec![f(1), f(2)],
        mode: StopMode::Soft,
        refused: vec![RefusedStop { function: f(2), reason: "PE".into() }],
        at_rest: vec![ActuatorRest { actuator: a(1), position_counts: PositionCounts(12) }],
    };
    assert_eq!(
        to_value(&report).unwrap(),
        json!({"functions": [1, 2], "mode": "soft", "refused": [{"function": 2, "reason": "PE"}],
               "at_rest": [{"actuator": 1, "position_counts": 12}]})
    );
}

#[test]
fn runs_and_streams_say_where_the_actuators_came_to_rest() {
    let rest = vec![(a(1), PositionCounts(5)), (a(2), PositionCounts(7))];
    let ran = RunReport {
        function: Function::Motion(f(2)),
        duration: Duration::from_secs(1),
        rest: rest.clone(),
        verified: true,
        not_verifiable: Vec::new(),
    };
    let expected = |interrupted: bool| {
        json!({"function": 2, "stopped": true, "interrupted": interrupted,
               "actuators": [{"actuator": 1, "reached_counts": 5}, {"actuator": 2, "reached_counts": 7}]})
    };
    assert_eq!(to_value(RunOutcome::of(Ok(ran)).unwrap()).unwrap(), expected(false));
    let cancelled = Error::RunCancelled {
        function: Function::Motion(f(2)),
        rest: rest.clone(),
        verified: true,
        not_verifiable: Vec::new(),
    };
    assert_eq!(to_value(RunOutcome::of(Err(cancelled)).unwrap()).unwrap(), expected(true));
    assert!(RunOutcome::of(Err(Error::Closed)).is_err(), "other errors stay errors");
    // A switching function's run says whether its status showed it on after the RE and off after the RS.
    let why = vec!["F11 (buzzer) was not verified by its status: ...".to_string()];
    let switched = RunOutcome {
        function: Function::Buzzer,
        interrupted: false,
        rest: vec![],
        verified: false,
        not_verifiable: why,
    };
    assert_eq!(
        to_value(&switched).unwrap(),
        json!({"function": 11, "stopped": true, "interrupted": false, "actuators": [], "verified": false,
               "not_verifiable": ["F11 (buzzer) was not verified by its status: ..."]})
    );

    let followed = FollowReport { rest: rest.clone(), updates: 3 };
    assert_eq!(
        to_value(&followed).unwrap(),
        json!({"stopped": true, "updates": 3,
               "actuators": [{"actuator": 1, "reached_counts": 5}, {"actuator": 2, "reached_counts": 7}]})
    );
    let start = FollowStart { function: f(1), actuators: vec![a(1), a(2)] };
    assert_eq!(to_value(&start).unwrap(), json!({"function": 1, "following": true, "actuators": [1, 2]}));
    let targets = TargetsApplied(vec![(a(1), PositionCounts(400))]);
    assert_eq!(to_value(&targets).unwrap(), json!({"targets": [{"actuator": 1, "target_counts": 400}]}));
}

#[test]
fn a_sample_has_the_connected_actuators_with_their_current_in_amperes() {
    let mut statuses = [ActuatorStatus1(0); 6];
    statuses[0] = ActuatorStatus1(0x01);
    let mut positions = [PositionCounts(0); 6];
    positions[0] = PositionCounts(400);
    let snapshot = Snapshot {
        at: Timestamp::ZERO,
        statuses,
        positions,
        currents_deci_amps: [25, 0, 0, 0, 0, 0],
        last_error: ErrorCode::from_bit(22),
    };
    let v = to_value(SampleReport::new(&snapshot, 0.25)).unwrap();
    assert_eq!(
        v["actuators"],
        json!([{"actuator": 1, "position_counts": 400, "current_amps": 2.5, "word": 1, "flags": ["available"],
                "moving": false}])
    );
    assert_eq!(
        (&v["t_s"], &v["last_error"]["code"], &v["last_error"]["bits"][0]["bit"]),
        (&json!(0.25), &json!(1 << 21), &json!(22))
    );
}

#[test]
fn names_list_entries_then_groups_with_the_unit_results_use() {
    let items: Vec<DataItemInfo> = data_items(SpeedMode::CountsPerSecond).collect();
    assert_eq!(items.len(), DATA_LIST.len() + GROUPS.len());
    let speed = items.iter().find(|i| i.name == "remote_speed_f1").unwrap();
    assert_eq!(
        to_value(speed).unwrap(),
        json!({"name": "remote_speed_f1", "id": 0x3011, "unit": "counts/s", "access": "rw", "title": speed.title,
               "size": 2})
    );
    let group = items.iter().find(|i| i.name == "actual_positions").unwrap();
    assert_eq!((group.title.as_str(), group.size, group.access), ("group 0x0011..0x0016", 24, "r"));
}

#[test]
fn a_look_at_an_actuator_names_its_flags_and_moves_with_its_motion_bit() {
    let look = axis_look(PositionCounts(120), ActuatorStatus1(0x11), Some(80.0), Some(1.5));
    assert_eq!(
        to_value(&look).unwrap(),
        json!({"position_counts": 120.0, "speed_percent": 80.0, "current_amps": 1.5,
               "flags": ["available", "motion"], "faults": [], "moving": true})
    );
}
