//! Each report's JSON, as `motionlink powercube --json` prints it.

use serde_json::json;

use super::*;
use crate::error::Error;
use crate::model::{Address, CubeVersion, Dio, ShortState};

fn to_json<T: Serialize>(t: &T) -> serde_json::Value {
    serde_json::to_value(t).unwrap()
}

/// STATE_HOME_OK | STATE_HALTED | STATE_ERROR | bit 27 (two names) | an unknown bit 31.
const STATE: CubeState = CubeState(0x8800_0007);

fn state_json() -> serde_json::Value {
    json!({"word": 0x8800_0007_u32, "flags": ["STATE_ERROR", "STATE_HOME_OK", "STATE_HALTED", "STATE_LOGIC_VOLT"],
           "unknown_bits": 0x8000_0000_u32, "faults": ["STATE_ERROR", "STATE_LOGIC_VOLT"]})
}

fn info(kind: ModuleKind) -> ModuleInfo {
    ModuleInfo { address: Address::new(17).unwrap(), kind, version: CubeVersion(0x351D), serial: 1001, state: STATE }
}

#[test]
fn the_state_word_shows_its_flags_its_faults_and_its_unknown_bits() {
    assert_eq!(to_json(&StateReport(STATE)), state_json());
    assert_eq!(to_json(&StateReport(CubeState(0x2))), json!({"word": 2, "flags": ["STATE_HOME_OK"], "faults": []}));
}

#[test]
fn a_fault_flag_shows_its_bit_number_name_and_cause_as_the_scu_error_bits() {
    let faults: Vec<_> = STATE.faults().map(|f| to_json(&f)).collect();
    assert_eq!(faults[0]["bit"], json!(0), "STATE_ERROR is bit 0 (mask 0x1): {faults:?}");
    assert_eq!(faults[0]["name"], json!("STATE_ERROR"));
    assert_eq!(faults[0]["cause"], json!(StateFlag::Error.meaning()));
    assert_eq!(faults[1]["bit"], json!(27), "STATE_LOGIC_VOLT is bit 27: {faults:?}");
}

#[test]
fn a_value_is_a_number_or_the_fields_of_a_combined_read() {
    assert_eq!(to_json(&Value::F32(0.5)), json!(0.5));
    assert_eq!(to_json(&Value::I32(-3)), json!(-3));
    assert_eq!(to_json(&Value::U8(7)), json!(7));
    let dio = Value::PosStateDio { pos: 0.25, state: ShortState(0x01), dio: Dio(0x00) };
    let j = to_json(&dio);
    assert_eq!(j["position"], json!(0.25));
    assert_eq!((j["short_state"]["word"].clone(), j["dio"]["flags"].clone()), (json!(1), json!([])), "{j}");
    assert_eq!(to_json(&Value::PosTime { pos: 1.0, time_ms: 40 }), json!({"position": 1.0, "time_ms": 40}));
}

#[test]
fn a_module_found_shows_its_identity_and_one_that_failed_its_error() {
    let expected = json!({"module": 17, "kind": "linear", "version": "3.5.1D", "serial": 1001, "state": state_json()});
    assert_eq!(to_json(&info(ModuleKind::Linear)), expected);
    let found = ScanEntry { address: Address::new(17).unwrap(), info: Ok(info(ModuleKind::Linear)) };
    assert_eq!(to_json(&found), expected);
    let failed = ScanEntry { address: Address::new(3).unwrap(), info: Err(Error::NotSupported("no answer".into())) };
    assert_eq!(to_json(&failed), json!({"module": 3, "error": "no answer"}));
}

#[test]
fn a_move_names_its_positions_in_the_unit_of_the_module() {
    let report = MoveReport {
        kind: ModuleKind::Rotary,
        target: Position::rad(0.5),
        start: Position::rad(0.0),
        reached: Position::rad(0.5),
        state: CubeState(0x8002),
        verified: false,
        not_verifiable: vec!["TargetVel could not be read back".into()],
    };
    let j = to_json(&report);
    assert_eq!(
        j,
        json!({"target_rad": 0.5, "reached_rad": 0.5, "difference_rad": 0.0,
               "state": {"word": 0x8002, "flags": ["STATE_HOME_OK", "STATE_RAMP_END"], "faults": []}, "homed": true,
               "verified": false, "not_verifiable": ["TargetVel could not be read back"]})
    );
    let linear = to_json(&MoveReport { kind: ModuleKind::Linear, ..report });
    assert!(linear.get("reached_m").is_some() && linear.get("reached_rad").is_none(), "{linear}");
}

#[test]
fn a_motion_of_any_mode_names_its_positions_in_the_unit_of_the_module_and_says_how_it_ended() {
    use crate::model::{Dio, MotionId, Ticks};
    use crate::session::{MotionEnding, MotionReport};
    use crate::wire::{AckPosition, ExtAck};
    let velocity = MotionReport {
        kind: ModuleKind::Rotary,
        mode: MotionId::FVel,
        start: Position::rad(0.05),
        target: None,
        reached: Position::rad(0.125),
        held: Some(std::time::Duration::from_millis(300)),
        ending: MotionEnding::VelocityZero,
        ext_ack: None,
        state: CubeState(0x2),
        verified: false,
        not_verifiable: vec!["the velocity the module took could not be read back".into()],
    };
    assert_eq!(
        to_json(&velocity),
        json!({"mode": "FVEL_MODE", "start_rad": 0.05_f32, "reached_rad": 0.125, "held_s": 0.3, "ended": "velocity_zero",
               "state": {"word": 2, "flags": ["STATE_HOME_OK"], "faults": []}, "homed": true, "verified": false,
               "not_verifiable": ["the velocity the module took could not be read back"]})
    );
    // A step on a linear module, with its extended acknowledge: a target, the difference, no hold.
    let ack = ExtAck { position: AckPosition::Unit(Position::m(0.1)), state: ShortState(0x10), dio: Dio(0x01) };
    let step = MotionReport {
        kind: ModuleKind::Linear,
        mode: MotionId::FStepAck,
        start: Position::m(0.1),
        target: Some(Position::m(0.25)),
        reached: Position::m(0.25),
        held: None,
        ending: MotionEnding::Reached,
        ext_ack: Some(ack),
        state: CubeState(0x0),
        verified: true,
        not_verifiable: vec![],
    };
    let j = to_json(&step);
    let mut expected = json!({"mode": "FSTEP_ACK", "start_m": 0.1_f32, "target_m": 0.25, "reached_m": 0.25,
        "difference_m": 0.0, "ended": "reached", "state": {"word": 0, "flags": [], "faults": []}, "homed": false,
        "verified": true, "not_verifiable": []});
    expected["ext_ack"] = json!({"position": 0.1_f32, "position_unit": "m", "short_state": to_json(&ShortState(0x10)),
                                 "dio": to_json(&Dio(0x01))});
    assert_eq!(j, expected);
    assert_eq!(j["ext_ack"]["short_state"]["flags"], json!(["SHORT_MOTION"]), "{j}");
    assert!(
        step.not_homed_note().is_some()
            && step.not_homed_note()
                == MoveReport {
                    kind: ModuleKind::Linear,
                    target: Position::m(0.0),
                    start: Position::m(0.0),
                    reached: Position::m(0.0),
                    state: CubeState(0),
                    verified: true,
                    not_verifiable: vec![]
                }
                .not_homed_note(),
        "one text"
    );
    // An IRAMP acknowledge gives ticks; a current mode ends halted.
    let ticks = ExtAck { position: AckPosition::Ticks(Ticks(-7)), ..ack };
    let halted = MotionReport {
        mode: MotionId::ICurAck,
        target: None,
        held: Some(std::time::Duration::from_millis(1500)),
        ending: MotionEnding::Halted,
        ext_ack: Some(ticks),
        ..step
    };
    let j = to_json(&halted);
    assert_eq!((j["ended"].clone(), j["held_s"].clone()), (json!("halted"), json!(1.5)), "{j}");
    assert_eq!((j["ext_ack"]["position"].clone(), j["ext_ack"]["position_unit"].clone()), (json!(-7), json!("ticks")));
    assert!(j.get("target_m").is_none() && j.get("difference_m").is_none(), "{j}");
}

#[test]
fn a_setpoint_names_its_mode_its_extended_acknowledge_when_one_came_and_its_watchdog() {
    use crate::model::{MotionId, Ticks};
    use crate::session::SetpointReport;
    use crate::wire::{AckPosition, ExtAck};
    let ack = ExtAck { position: AckPosition::Unit(Position::rad(0.25)), state: ShortState(0x11), dio: Dio(0x01) };
    let report =
        SetpointReport { kind: ModuleKind::Rotary, mode: MotionId::FVelAck, ext_ack: Some(ack), watchdog: true };
    let j = to_json(&report);
    assert_eq!(
        j,
        json!({"mode": "FVEL_ACK", "ext_ack": {"position": 0.25_f32, "position_unit": "rad",
               "short_state": to_json(&ShortState(0x11)), "dio": to_json(&Dio(0x01))}, "watchdog": true})
    );
    assert_eq!(j["ext_ack"]["short_state"]["flags"], json!(["SHORT_NOT_OK", "SHORT_MOTION"]), "{j}");
    // IVEL_ACK in ticks; the simple acknowledge has none.
    let ticks = SetpointReport {
        mode: MotionId::IVelAck,
        ext_ack: Some(ExtAck { position: AckPosition::Ticks(Ticks(4096)), ..ack }),
        ..report.clone()
    };
    let j = to_json(&ticks);
    assert_eq!(
        (j["ext_ack"]["position"].clone(), j["ext_ack"]["position_unit"].clone()),
        (json!(4096), json!("ticks"))
    );
    let simple = SetpointReport { mode: MotionId::FCur, ext_ack: None, watchdog: false, ..report };
    assert_eq!(to_json(&simple), json!({"mode": "FCUR_MODE", "watchdog": false}));
}

#[test]
fn homing_and_a_halt_name_their_position_in_the_unit_of_the_module() {
    let homed = HomeReport {
        kind: ModuleKind::Linear,
        reached: Position::m(0.0),
        state: CubeState(0x2),
        verified: false,
        not_verifiable: vec!["the watchdog could not be armed".into()],
    };
    assert_eq!(
        to_json(&homed),
        json!({"reached_m": 0.0, "state": {"word": 2, "flags": ["STATE_HOME_OK"], "faults": []},
               "verified": false, "not_verifiable": ["the watchdog could not be armed"]})
    );
    let halted = HaltReport { kind: ModuleKind::Rotary, state: CubeState(0x6), position: Position::rad(0.25) };
    assert_eq!(
        to_json(&halted),
        json!({"position_rad": 0.25, "state": {"word": 6, "flags": ["STATE_HOME_OK", "STATE_HALTED"], "faults": []}})
    );
}

#[test]
fn a_parameter_read_and_one_written_show_their_unit_and_their_read_back() {
    let read = ParamReading { param: Param::MaxVel, kind: ModuleKind::Linear, value: Value::F32(0.5) };
    assert_eq!(to_json(&read), json!({"name": "MaxVel", "id": 0x48, "value": 0.5, "unit": "m/s", "access": "rw"}));
    // TargetVel is read back through TargetVelInc: the ticks read, converted into m/s.
    let twin = Readback { read_in_unit: Some(0.5), ..Readback::same(Value::I32(5000)) };
    let written = SetReport { param: Param::TargetVel, value: Value::F32(0.5), readback: twin };
    assert_eq!(
        to_json(&written),
        json!({"name": "TargetVel", "id": 0x4f, "value": 0.5, "ok": true, "read_back": 0.5, "verified": true,
               "not_verifiable": []})
    );
    let same = SetReport { param: Param::MaxVel, value: Value::F32(0.5), readback: Readback::same(Value::F32(0.5)) };
    assert_eq!(to_json(&same)["read_back"], json!(0.5));
    let unverified = SetReport { readback: Readback::unverified("keeps TargetVelInc apart"), ..written };
    let j = to_json(&unverified);
    assert_eq!((j["read_back"].clone(), j["verified"].clone()), (json!(null), json!(false)));
    assert_eq!(j["not_verifiable"], json!(["keeps TargetVelInc apart"]));
}

#[test]
fn the_details_of_a_module_carry_its_limits_with_their_units() {
    let d = ModuleDetails::new(
        info(ModuleKind::Rotary),
        [Value::F32(-3.0), Value::F32(3.0), Value::F32(1.5), Value::F32(4.0), Value::F32(0.25)],
    );
    let j = to_json(&d);
    let mut expected =
        json!({"module": 17, "kind": "rotary", "version": "3.5.1D", "serial": 1001, "state": state_json()});
    for (k, v) in [
        ("min_position_rad", -3.0),
        ("max_position_rad", 3.0),
        ("max_velocity_rad_per_s", 1.5),
        ("max_acceleration_rad_per_s2", 4.0),
        ("position_rad", 0.25),
    ] {
        expected[k] = json!(v);
    }
    assert_eq!(j, expected);
    assert_eq!(d.limits()[1], (Param::MaxPos, Value::F32(3.0)));
}

#[test]
fn a_sample_and_a_row_of_the_table() {
    let s = Sample { kind: ModuleKind::Rotary, position: Position::rad(0.5), state: CubeState(0x2) };
    assert_eq!(
        to_json(&s),
        json!({"position_rad": 0.5, "state": {"word": 2, "flags": ["STATE_HOME_OK"], "faults": []}})
    );
    let row = ParamRow(Param::ActPos.entry());
    assert_eq!(
        to_json(&row),
        json!({"id": 0x3c, "name": "ActPos", "type": "float", "unit": "rad|m", "access": "r", "class": "actual",
               "description": Param::ActPos.entry().title})
    );
}

#[test]
fn a_look_at_a_module_takes_every_flag_that_is_not_information_as_a_fault() {
    let look = axis_look(Some(ModuleKind::Linear), Position::rad(0.25), true, Some(CubeState(0x13)), Some(0.5), None);
    assert_eq!(
        to_json(&look),
        json!({"position_m": 0.25, "velocity_m_per_s": 0.5, "moving": true,
               "flags": ["STATE_ERROR", "STATE_HOME_OK", "STATE_TOW_ERROR"], "faults": ["STATE_ERROR", "STATE_TOW_ERROR"]})
    );
    // Before its kind and state word were read: plain names, no flags.
    let first = axis_look(None, Position::rad(0.5), false, None, None, Some(1.25));
    assert_eq!(
        to_json(&first),
        json!({"position": 0.5, "current_amps": 1.25, "flags": [], "faults": [], "moving": false})
    );
}
