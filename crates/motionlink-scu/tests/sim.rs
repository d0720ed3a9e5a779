//! The emulator, driven through its sans-IO interface with explicit timestamps: remote mode, motion, the
//! watchdog, checks of every command, the data list, functions.

use crate::bench;

use bench::*;
use motionlink_scu::model::Function;

#[test]
fn remote_commands_are_refused_outside_remote_mode() {
    let mut b = Bench::new(SimConfig::default());
    for r in [
        Request::Get { index: 0x0011 },
        Request::Cyclic { object: 0xFF, write: &[] },
        Request::Transfer { index: 0x3011, data: &[50, 0] },
        Request::Execute { function: 0, params: [9, 0xFF] },
        Request::Stop { function: 0, param: 1 },
    ] {
        assert_eq!(b.status(r), Status::PermissionError, "{r:?}");
    }
    assert_eq!(b.status(Request::Abort), Status::Ack, "RA is harmless outside remote mode");
}

#[test]
fn an_rc_must_come_before_any_other_command() {
    let mut b = Bench::new(SimConfig::default());
    assert_eq!(b.status(Request::Open { safety_id: 0 }), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError);
    assert_eq!(b.rc(), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::Ack);
    assert_eq!(b.unit.mode(), RemoteMode::Active(motionlink_scu::model::SafetyId::StopAllAndLock));
}

#[test]
fn ro_with_an_unknown_safety_id_is_a_data_error() {
    let mut b = Bench::new(SimConfig::default());
    assert_eq!(b.status(Request::Open { safety_id: 3 }), Status::ParameterDataError);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
}

#[test]
fn chapter5_routine_moves_actuator_1_and_reports_its_position() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    assert_eq!(b.set(0x3011, &100u16.to_le_bytes()), Status::Ack);
    assert_eq!(b.set(0x3021, &400i32.to_le_bytes()), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
    b.wait(100);
    assert_ne!(b.status1(1) & Status1Flag::Motion.mask(), 0, "status bit 4 is set while the motion is active");
    let mut t = 0;
    while b.status1(1) & Status1Flag::Motion.mask() != 0 {
        b.keep_alive(100);
        t += 100;
        assert!(t < 10_000, "the move never ended");
    }
    assert_eq!(b.position(1), 400);
    // 400 counts at 110 counts/s is 3.6 s plus the ramps.
    assert!((3_600..=4_300).contains(&t), "took {t} ms");
    assert_eq!(b.status(Request::Stop { function: 0, param: 1 }), Status::Ack);
    assert!(b.unit.executed_functions().is_empty());
    assert_eq!(b.status(Request::Abort), Status::Ack);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
    assert_eq!(b.get_after_open(0x0091), 400u32.to_le_bytes(), "cumulated stroke");
}

#[test]
fn speed_scales_the_motion() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.set(0x3012, &50u16.to_le_bytes());
    b.go(2, 300);
    b.keep_alive(2000);
    let p = b.position(2);
    // 55 counts/s at 50 %: about 100 counts in 2 s after the ramp.
    assert!((95..=112).contains(&p), "position {p}");
    assert_eq!(u16::from_le_bytes(b.get(0x00F2).try_into().unwrap()), 50, "speed A2 in percent");
    assert!(u16::from_le_bytes(b.get(0x00A2).try_into().unwrap()) > 0, "a moving actuator draws current");
    assert_eq!(b.position(1), 0, "actuator 1 is on another function");
}

#[test]
fn rs_fast_stops_at_once_and_soft_stops_along_the_ramp() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(1000);
    let (p1, p2) = (b.position(1), b.position(2));
    assert_eq!(b.status(Request::Stop { function: 0, param: 0 }), Status::Ack);
    assert_eq!(b.status(Request::Stop { function: 1, param: 1 }), Status::Ack);
    b.keep_alive(500);
    assert_eq!(b.position(1), p1, "fast stop: no further travel");
    let travel = b.position(2) - p2;
    // Soft stop from 110 counts/s over a 300 ms ramp: about 16 counts.
    assert!((10..=25).contains(&travel), "soft stop travelled {travel}");
    assert!(!b.unit.any_moving());
}

#[test]
fn motion_directions_go_to_the_stroke_ends_and_stored_positions() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.status(Request::Execute { function: 0, params: [2, 0xFF] }); // Out
    b.keep_alive(9_000);
    assert_eq!(b.position(1), 865);
    let s = b.status1(1);
    assert_ne!(s & Status1Flag::OutPosition.mask(), 0);
    assert_ne!(s & Status1Flag::LimitInOut.mask(), 0);
    assert_eq!(s & (Status1Flag::InPosition.mask() | Status1Flag::Motion.mask()), 0);
    b.status(Request::Stop { function: 0, param: 1 });
    b.status(Request::Execute { function: 0, params: [4, 0xFF] }); // Mem2
    b.keep_alive(9_000);
    assert_eq!(b.position(1), 300);
    b.status(Request::Execute { function: 0, params: [1, 0xFF] }); // In
    b.keep_alive(9_000);
    assert_eq!(b.position(1), 0);
    assert_ne!(b.status1(1) & Status1Flag::InPosition.mask(), 0);
    assert_eq!(u32::from_le_bytes(b.get(0x0071).try_into().unwrap()), 1, "relay out cycles: Out");
    assert_eq!(u32::from_le_bytes(b.get(0x0061).try_into().unwrap()), 2, "relay in cycles: Mem2 (865 -> 300), In");
}

#[test]
fn targets_beyond_the_stroke_stop_at_its_end() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 5000);
    b.keep_alive(10_000);
    assert_eq!(b.position(1), 865);
}

#[test]
fn watchdog_with_safety_id_0_stops_and_locks_until_ro() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    b.go(1, 800);
    b.keep_alive(1000);
    let p = b.position(1);
    assert!(b.unit.is_moving(a(1)));
    // Last RC at 1000 ms. At 1499 ms all is well; the watchdog fires at 1500 ms.
    b.at(1499);
    assert!(b.unit.is_moving(a(1)));
    assert_eq!(b.unit.stats().watchdog_expiries, 0);
    b.at(1500);
    assert!(!b.unit.is_moving(a(1)), "all motions stop on the watchdog");
    assert_eq!(b.unit.mode(), RemoteMode::Locked);
    assert_eq!(b.unit.last_error(), ErrorCode::from_bit(22));
    // Only RC, RA and RO are accepted now.
    assert_eq!(b.rc(), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
    b.wait(2000);
    assert!(!b.unit.is_moving(a(1)));
    assert!(b.unit.position(a(1)).unwrap() - p < 60, "stopped where the watchdog fired");
    b.open(0);
    assert_eq!(b.get(0x00D1), (1u32 << 21).to_le_bytes(), "error code 1 has bit 22 (mask 1 << 21) set");
}

/// Chapter 5: "If the RC communication should fail, the SCU will stop all drives in motion and deactivate
/// the remote mode" (E 591, S 550); RG, RT, RC, RE and RS "are only available if the remote function is
/// activated", which RO does (E 4.1). The RO row restricts commands only for Safety_ID 0.
#[test]
fn watchdog_with_safety_id_1_or_2_stops_and_deactivates_remote_mode_until_ro() {
    for safety in [1u8, 2] {
        let mut b = Bench::new(SimConfig::default());
        b.open(safety);
        b.go(1, 800);
        b.wait(600);
        assert!(!b.unit.is_moving(a(1)), "Safety_ID {safety}: the remote motion stopped");
        assert_eq!(b.unit.mode(), RemoteMode::Off, "Safety_ID {safety}");
        // Every remote command is refused, RC too: an RC does not bring remote mode back.
        assert_eq!(b.rc(), Status::PermissionError, "Safety_ID {safety}");
        assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError);
        assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
        let events = b.unit.take_events();
        let expiry = format!("remote mode ended by watchdog (Safety_ID {safety}): ");
        let said = events.iter().find(|e| e.starts_with(&expiry)).unwrap_or_else(|| panic!("{events:?}"));
        assert!(said.ends_with("remote mode deactivated until RO"), "{said}");
        // RO (and the first RC) opens it again; the motion can start again.
        b.open(safety);
        assert_eq!(b.get(0x00D1), (1u32 << 21).to_le_bytes(), "error code 1 has bit 22");
        assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
        b.keep_alive(300);
        assert!(b.unit.is_moving(a(1)), "Safety_ID {safety}: motion can start again after RO");
    }
}

/// The `rc-rearms-watchdog` variant: a firmware that, after a lapse with Safety_ID 1 or 2, refuses commands
/// until the next RC, which re-arms the watchdog and restores remote mode without RO (chapter 5 calls the
/// first RC the "activation of remote mode").
#[test]
fn on_an_rc_rearms_watchdog_unit_a_lapse_with_safety_id_1_is_re_armed_by_the_next_rc() {
    let mut config = SimConfig::default();
    config.add_variants([motionlink_scu::Variant::RcRearmsWatchdog]);
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.wait(600);
    assert!(!b.unit.is_moving(a(1)));
    assert_eq!(b.unit.mode(), RemoteMode::TimedOut(motionlink_scu::model::SafetyId::StopAll));
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::PermissionError, "an RC first");
    assert_eq!(b.rc(), Status::Ack);
    assert_eq!(b.status(Request::Get { index: 0x0011 }), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
    b.keep_alive(300);
    assert!(b.unit.is_moving(a(1)), "motion can start again");
}

#[test]
fn watchdog_with_safety_id_2_stops_only_remote_motions() {
    let mut b = Bench::new(SimConfig::default());
    b.open(2);
    b.go(1, 800);
    b.unit.press_hand_switch(2, true);
    assert_ne!(b.get(0x0040)[0] & 0b1000, 0, "key K4 (F2 out) shows as pressed");
    b.wait(600);
    assert!(!b.unit.is_moving(a(1)), "the remote motion stopped");
    assert!(b.unit.is_moving(a(2)), "the hand-switch motion goes on");
    b.unit.release_hand_switch();
    b.wait(1000);
    assert!(!b.unit.is_moving(a(2)));
}

#[test]
fn watchdog_runs_from_ro_even_without_an_rc() {
    let mut b = Bench::new(SimConfig::default());
    assert_eq!(b.status(Request::Open { safety_id: 1 }), Status::Ack);
    b.wait(501);
    assert_eq!(b.unit.stats().watchdog_expiries, 1);
}

#[test]
fn a_session_with_rc_every_400_ms_never_times_out() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    for _ in 0..1500 {
        b.wait(400);
        assert_eq!(b.rc(), Status::Ack);
    }
    assert_eq!(b.unit.stats().watchdog_expiries, 0);
}

#[test]
fn rt_is_checked() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    assert_eq!(b.set(0x0011, &[1, 0, 0, 0]), Status::ParameterDataError, "not remote data");
    assert_eq!(b.set(0x3017, &[1, 0, 0]), Status::ParameterCountError, "wrong size");
    assert_eq!(b.set(0x3011, &101u16.to_le_bytes()), Status::ParameterDataError, "speed above 100 %");
    assert_eq!(b.set(0x3099, &[1, 0]), Status::ParameterDataError, "no such entry");
    assert_eq!(b.set(0x3011, &100u16.to_le_bytes()), Status::Ack);
    // A whole group, all or nothing.
    let mut speeds = Vec::new();
    for s in [10u16, 20, 30, 40, 50, 60, 70, 80, 90, 101] {
        speeds.extend_from_slice(&s.to_le_bytes());
    }
    assert_eq!(b.set(0x3010, &speeds), Status::ParameterDataError);
    assert_eq!(b.get(0x3011), 100u16.to_le_bytes(), "nothing of the refused group was written");
    speeds[18] = 100;
    assert_eq!(b.set(0x3010, &speeds), Status::Ack);
    assert_eq!(b.get(0x3013), 30u16.to_le_bytes());
}

#[test]
fn re_and_rs_parameters_are_checked() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    assert_eq!(b.status(Request::Execute { function: 0, params: [10, 0xFF] }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0] }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Execute { function: 12, params: [0xFF, 0xFF] }), Status::ParameterDataError, "F13");
    assert_eq!(
        b.status(Request::Execute { function: 5, params: [9, 0xFF] }),
        Status::PermissionError,
        "F6 drives nothing"
    );
    assert_eq!(b.status(Request::Stop { function: 0, param: 2 }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Stop { function: 10, param: 0 }), Status::ParameterDataError, "buzzer: -1");
    assert_eq!(b.status(Request::Execute { function: 0, params: [0, 0xFF] }), Status::Ack, "direction 0: no motion");
    assert!(!b.unit.any_moving());
}

#[test]
fn wrong_crc_gets_cse_and_unknown_command_gets_ice() {
    let mut b = Bench::new(SimConfig::default());
    let mut t = request_to_vec(&Request::Open { safety_id: 0 }).unwrap();
    t[4] ^= 0xFF;
    let answers = b.raw(&t);
    assert_eq!(answers, [Answer { command: Command::Open, status: Status::ChecksumError, data: None }]);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
    let mut unknown = b"RQ".to_vec();
    unknown.extend_from_slice(&crc16(b"RQ").to_le_bytes());
    let out = {
        let mut out = Vec::new();
        b.unit.receive(b.now, &unknown, &mut out);
        out
    };
    assert_eq!(&out[..3], &[b'R', b'Q', 0x83], "ICE, with the unknown letters repeated");
    assert_eq!(crc16(&out[..3]).to_le_bytes(), [out[3], out[4]]);
}

#[test]
fn a_telegram_left_incomplete_for_1000_ms_is_dropped() {
    let mut b = Bench::new(SimConfig::default());
    let t = request_to_vec(&Request::Open { safety_id: 0 }).unwrap();
    assert!(b.raw(&t[..2]).is_empty());
    b.wait(1001);
    // The rest arrives too late: the start was dropped, so these bytes are garbage and get no reply.
    assert!(b.raw(&t[2..]).is_empty());
    assert_eq!(b.unit.stats().dropped_partial, 1);
    assert_eq!(b.unit.mode(), RemoteMode::Off);
    // Within the limit, bytes may trickle in.
    assert!(b.raw(&t[..2]).is_empty());
    b.wait(999);
    assert_eq!(b.raw(&t[2..]).len(), 1);
    assert!(matches!(b.unit.mode(), RemoteMode::AwaitingRc(_)));
}

#[test]
fn rc_exchanges_the_data_of_a_cyclic_object() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let obj = CyclicObject::new(
        &[DataIndex(0x3021), DataIndex(0x3011)],
        &[DataIndex(0x0011), DataIndex(0x0171), DataIndex(0x0010)],
    )
    .unwrap();
    assert_eq!(b.set(0x3001, &obj.to_bytes()), Status::Ack);
    assert_eq!(b.get(0x3001), obj.to_bytes());
    let mut write = 250i32.to_le_bytes().to_vec();
    write.extend_from_slice(&80u16.to_le_bytes());
    let answer = b.send(Request::Cyclic { object: 0, write: &write });
    assert_eq!(answer.status, Status::Ack);
    let data = answer.data.unwrap();
    assert_eq!(data.len(), 4 + 1 + 24, "position, status, all six positions");
    assert_eq!(&data[..4], &0i32.to_le_bytes());
    assert_eq!(data[4] & Status1Flag::Available.mask(), Status1Flag::Available.mask());
    assert_eq!(b.get(0x3021), 250i32.to_le_bytes(), "the write data landed");
    assert_eq!(b.get(0x3011), 80u16.to_le_bytes());
    // Wrong write length, unknown object, data without object.
    assert_eq!(b.status(Request::Cyclic { object: 0, write: &write[..3] }), Status::ParameterCountError);
    assert_eq!(b.status(Request::Cyclic { object: 5, write: &[] }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Cyclic { object: 0xFF, write: &[1] }), Status::ParameterCountError);
    // An empty object answers with ctp 0.
    let empty = b.send(Request::Cyclic { object: 1, write: &[] });
    assert_eq!((empty.status, empty.data), (Status::Ack, Some(vec![])));
}

#[test]
fn a_cyclic_object_may_not_write_read_only_data() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let bad = CyclicObject::new(&[DataIndex(0x0011)], &[]).unwrap();
    assert_eq!(b.set(0x3002, &bad.to_bytes()), Status::ParameterDataError);
}

#[test]
fn a_cyclic_object_whose_data_would_not_fit_one_reply_is_refused() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    // Six times all UserPositionData (624 bytes each): more than one reply carries.
    let huge = CyclicObject::new(&[], &[DataIndex(0x2000); 6]).unwrap();
    assert_eq!(b.set(0x3001, &huge.to_bytes()), Status::ParameterDataError);
    // The largest that fits still works: one group of 624 bytes, answered with every RC.
    let big = CyclicObject::new(&[], &[DataIndex(0x2000)]).unwrap();
    assert_eq!(b.set(0x3001, &big.to_bytes()), Status::Ack);
    let answer = b.send(Request::Cyclic { object: 0, write: &[] });
    assert_eq!(answer.status, Status::Ack);
    assert_eq!(answer.data.map(|d| d.len()), Some(624));
}

#[test]
fn every_index_of_the_data_list_answers_with_its_size() {
    let mut b = Bench::new(SimConfig::scp11(6));
    b.open(1);
    for e in DATA_LIST {
        assert_eq!(b.get(e.index().0).len(), e.size(), "{}", e.name);
    }
    for g in GROUPS {
        assert_eq!(b.get(g.index.0).len(), g.size(), "{}", g.name);
    }
    assert_eq!(b.status(Request::Get { index: 0x0017 }), Status::ParameterDataError);
    assert_eq!(b.status(Request::Get { index: 0x4000 }), Status::ParameterDataError);
    let fw = b.get(0x0001);
    assert!(fw.starts_with(b"SCU V2B3"));
    assert_eq!(b.get(0x3021), 100i32.to_le_bytes(), "remote position defaults to memory 1 of user 1");
    assert_eq!(b.get(0x3011), 100u16.to_le_bytes(), "remote speed defaults to the function speed");
    assert_eq!(b.get(0x0100)[0] & 1, 1, "mains connected");
    // The collection indices of the manual's first column.
    assert_eq!(b.get(0x1000), b.get(0x1010), "the 1000 collection is the conversion factors");
    assert_eq!(b.get(0x1000).len(), 6 * 4);
    assert_eq!(b.get(0x3000).len(), 5 * 24 + 10 * 2 + 6 * 4, "cyclic objects, remote speeds, remote positions");
}

#[test]
fn the_3000_collection_is_written_whole_or_not_at_all() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let mut block = b.get(0x3000);
    // Remote speed F2 (after the five 24-byte cyclic objects and F1's speed) and remote position A1.
    block[5 * 24 + 2..5 * 24 + 4].copy_from_slice(&40u16.to_le_bytes());
    block[5 * 24 + 20..5 * 24 + 24].copy_from_slice(&321i32.to_le_bytes());
    assert_eq!(b.set(0x3000, &block), Status::Ack);
    assert_eq!(b.get(0x3012), 40u16.to_le_bytes());
    assert_eq!(b.get(0x3021), 321i32.to_le_bytes());
    // A speed out of range anywhere refuses the whole block.
    block[5 * 24..5 * 24 + 2].copy_from_slice(&101u16.to_le_bytes());
    block[5 * 24 + 20..5 * 24 + 24].copy_from_slice(&5i32.to_le_bytes());
    assert_eq!(b.set(0x3000, &block), Status::ParameterDataError);
    assert_eq!(b.get(0x3021), 321i32.to_le_bytes(), "nothing written");
    assert_eq!(b.set(0x3000, &block[1..]), Status::ParameterCountError);
}

#[test]
fn switching_functions_show_in_the_data_list() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    let on = |f: u8| Request::Execute { function: f, params: [0xFF, 0xFF] };
    let off = |f: u8| Request::Stop { function: f, param: 0xFF };
    for (f, index, bit) in [(10u8, 0x0140u16, 0u8), (16, 0x0110, 0), (17, 0x0110, 1), (20, 0x0120, 0), (21, 0x0120, 1)]
    {
        assert_eq!(b.status(on(f)), Status::Ack);
        assert_ne!(b.get(index)[0] & (1 << bit), 0, "F{} on", f + 1);
        assert_eq!(b.status(off(f)), Status::Ack);
        assert_eq!(b.get(index)[0] & (1 << bit), 0, "F{} off", f + 1);
    }
}

#[test]
fn a_unit_of_the_switch_status_unshown_variant_switches_f18_f20_f21_f22_without_showing_them() {
    let mut config = SimConfig::default();
    config.add_variants([motionlink_scu::Variant::SwitchStatusUnshown]);
    let mut b = Bench::new(config);
    b.open(1);
    let on = |f: u8| Request::Execute { function: f, params: [0xFF, 0xFF] };
    // Binary output 1 and the buzzer show as ever; output 2, the LEDs and the emergency stop do not.
    for f in [10u8, 16, 17, 19, 20, 21] {
        assert_eq!(b.status(on(f)), Status::Ack, "F{}", f + 1);
    }
    assert_eq!((b.get(0x0140), b.get(0x0110), b.get(0x0120)), (vec![1], vec![0b01], vec![0]));
    assert_eq!(b.get(0x0162), [0, 0], "lock_status shows no emergency stop");
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError, "engaged");
}

#[test]
fn a_failed_switch_is_acknowledged_and_its_status_stays_as_it_is() {
    let config = SimConfig::from_toml("failed_switches = [\"F17\", \"20\"]").unwrap();
    assert_eq!(config.failed_switches, [Function::BinaryOutput1, Function::EmergencyStop]);
    let mut b = Bench::new(config);
    b.open(1);
    assert_eq!(b.status(Request::Execute { function: 16, params: [0xFF, 0xFF] }), Status::Ack);
    assert_eq!(b.get(0x0110), [0], "binary output 1 did not switch on");
    assert_eq!(b.unit.executed_functions(), [17], "the RE was taken");
    assert_eq!(b.status(Request::Execute { function: 19, params: [0xFF, 0xFF] }), Status::Ack);
    assert_eq!(b.get(0x0162), [0, 0]);
    let events = b.unit.take_events();
    assert!(events.iter().any(|e| e.starts_with("F17 RE acknowledged, but its output has failed")), "{events:?}");
    b.unit.fail_switch(Function::Buzzer);
    b.unit.fail_switch(Function::Buzzer);
    assert_eq!(b.unit.config().failed_switches.len(), 3, "each once");
    let e = SimConfig::from_toml("failed_switches = [\"F1\"]").unwrap_err();
    assert!(e.to_string().contains("\"F1\" is not a switching function (F11, F17, F18, F20, F21, F22)"), "{e}");
    // An entry refused on purpose (a unit without it).
    b.unit.refuse_reads(DataIndex(0x0140));
    assert_eq!(b.status(Request::Get { index: 0x0140 }), Status::ParameterDataError);
}

#[test]
fn emergency_stop_stops_everything_and_blocks_motion_until_released() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(500);
    assert!(b.unit.is_moving(a(1)));
    assert_eq!(b.status(Request::Execute { function: 19, params: [0xFF, 0xFF] }), Status::Ack);
    assert!(!b.unit.any_moving());
    assert_eq!(b.get(0x0162), 0x03FFu16.to_le_bytes(), "all functions locked");
    assert_eq!(b.get(0x00E1)[0] & 0b110, 0, "no release flags");
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
    assert_eq!(b.status(Request::Stop { function: 19, param: 0xFF }), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
}

#[test]
fn a_drive_error_fast_stops_its_drive_and_enters_the_history() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(500);
    b.unit.inject_error(ErrorCode::from_bit(15));
    assert!(!b.unit.is_moving(a(1)));
    assert!(b.unit.is_moving(a(2)));
    b.unit.inject_error(ErrorCode::from_bit(12));
    let codes = b.get(0x00D0);
    assert_eq!(&codes[..4], &(1u32 << 11).to_le_bytes(), "last recent: bit 12");
    assert_eq!(&codes[4..8], &(1u32 << 14).to_le_bytes(), "history 1: bit 15");
    assert_eq!(u32::from_le_bytes(b.get(0x0081).try_into().unwrap()), 1, "actuator error counter");
}

#[test]
fn total_current_is_counted_and_its_maximum_is_of_the_sum_at_one_time() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(1500);
    let current = |b: &mut Bench, index: u16| u16::from_le_bytes(b.get(index).try_into().unwrap());
    let max_a1 = current(&mut b, 0x00B1);
    assert!(max_a1 > 0);
    // Only actuator 1 has moved: the highest total is its own highest current.
    assert_eq!(current(&mut b, 0x00BF), max_a1);
    b.go(2, 800);
    b.keep_alive(500);
    let total_now = current(&mut b, 0x00A1) + current(&mut b, 0x00A2);
    assert!(current(&mut b, 0x00BF) >= total_now);
    assert_eq!(u16::from_le_bytes(b.get(0x008F)[..2].try_into().unwrap()), 0);
    b.unit.inject_error(ErrorCode::from_bit(14));
    assert!(!b.unit.any_moving(), "a total over-current fast-stops every drive");
    assert_eq!(u16::from_le_bytes(b.get(0x008F)[..2].try_into().unwrap()), 1, "Number_Total_Over_Current");
}

#[test]
fn ra_ends_remote_mode_and_stops_remote_motions() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(300);
    assert_eq!(b.status(Request::Abort), Status::Ack);
    assert!(!b.unit.any_moving());
    b.wait(2000);
    assert_eq!(b.unit.stats().watchdog_expiries, 0, "no watchdog outside remote mode");
}

#[test]
fn tlt_preset_drives_two_columns_on_f1_stalls_below_30_percent_and_reads_below_zero_at_the_in_end() {
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.set(0x3021, &300i32.to_le_bytes());
    b.set(0x3022, &300i32.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [9, 0xFF] });
    b.keep_alive(5_000);
    assert_eq!((b.position(1), b.position(2)), (300, 300));
    b.status(Request::Stop { function: 0, param: 1 });
    b.set(0x3011, &20u16.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [1, 0xFF] });
    b.keep_alive(3_000);
    assert_eq!(b.position(1), 300, "stalled at 20 %");
    assert_ne!(b.status1(1) & Status1Flag::Motion.mask(), 0, "the motion bit stays set while stalled");
    b.status(Request::Stop { function: 0, param: 0 });
    b.set(0x3011, &100u16.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [1, 0xFF] });
    b.keep_alive(5_000);
    assert_eq!(b.position(1), -3, "a few counts below zero at the In end");
}
