//! The emulator's events, error bits, presets, and the bytes the public drivers send.

use crate::bench;

use bench::*;

#[test]
fn events_tell_what_the_unit_did() {
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    b.go(1, 100);
    b.keep_alive(2_000);
    b.wait(600); // no RC: the watchdog expires
    let events = b.unit.take_events();
    let expected = [
        "remote mode opened (Safety_ID 0)",
        "F1 started direction 9 (move to remote position): A1 -> 100",
        "A1 at rest 100 counts",
        "error bit 22 set (remote communication time out)",
        "remote mode ended by watchdog (Safety_ID 0): all motions stopped; remote motion locked until RO",
    ];
    assert_eq!(events, expected);
    assert!(b.unit.take_events().is_empty(), "each event is taken once");
}

#[test]
fn events_name_a_stop_and_where_each_actuator_came_to_rest() {
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.unit.take_events();
    b.set(0x3021, &400i32.to_le_bytes());
    b.set(0x3022, &400i32.to_le_bytes());
    b.status(Request::Execute { function: 0, params: [9, 0xFF] });
    b.keep_alive(1_000);
    b.status(Request::Stop { function: 0, param: 0 });
    let events = b.unit.take_events();
    assert_eq!(events[0], "F1 started direction 9 (move to remote position): A1 -> 400, A2 -> 400");
    assert_eq!(events[1], "F1 stopped (RS fast)");
    let p1 = b.position(1);
    let p2 = b.position(2);
    assert!(p1 > 50 && p1 < 400, "{p1}");
    assert_eq!(&events[2..], [format!("A1 at rest {p1} counts"), format!("A2 at rest {p2} counts")]);
}

#[test]
fn the_bits_the_manual_resets_on_the_next_motion_are_reset_when_it_starts_and_only_those() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    // Bits 12 (over-temperature), 14 (total current), 15 and 16 (drives 1 and 2), 21 (synchronisation), 22.
    let bits = [12u8, 14, 15, 16, 21, 22];
    let code = ErrorCode(bits.iter().map(|&n| ErrorCode::from_bit(n).0).sum());
    b.unit.inject_error(code);
    b.unit.inject_error(ErrorCode::from_bit(15)); // now Error_Code 1; the first code is history 1
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    b.unit.take_events();
    b.go(1, 50);
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "bit 15 of Error_Code 1 cleared when the motion started");
    assert_eq!(b.unit.take_events()[0], "error bit 15 reset by the next motion");
    let history = u32::from_le_bytes(b.get(0x00D2).try_into().unwrap());
    assert_eq!(history, code.0, "the history keeps what happened");
    // A code with bits of both kinds loses only 14..21.
    b.keep_alive(1_000);
    b.unit.inject_error(code);
    b.go(1, 10);
    assert_eq!(last_error(&mut b), ErrorCode(ErrorCode::from_bit(12).0 | ErrorCode::from_bit(22).0));
    // RE with direction 0 ("no motion") is no motion: nothing is reset.
    b.unit.inject_error(ErrorCode::from_bit(16));
    assert_eq!(b.status(Request::Execute { function: 1, params: [0, 0xFF] }), Status::Ack);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(16));
    assert_eq!(b.status(Request::Execute { function: 1, params: [2, 0xFF] }), Status::Ack);
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
}

#[test]
fn a_stalled_tlt_column_stops_with_its_drive_error_within_10_s_and_the_next_motion_clears_it() {
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.set(0x3012, &20u16.to_le_bytes()); // F2 (column 1 alone) at 20 %: below the 30 % a TLT needs
    b.set(0x3021, &400i32.to_le_bytes());
    b.status(Request::Execute { function: 1, params: [9, 0xFF] });
    b.keep_alive(4_000);
    assert_ne!(b.status1(1) & Status1Flag::Motion.mask(), 0, "stalled, the motion is still on");
    b.unit.take_events();
    b.keep_alive(6_000);
    assert_eq!(b.status1(1) & Status1Flag::Motion.mask(), 0, "the drive time-out stopped it");
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    assert_eq!(u32::from_le_bytes(b.get(0x0081).try_into().unwrap()), 1, "actuator error counter");
    let events = b.unit.take_events();
    assert!(events.contains(&"error bit 15 set (error with drive 1)".to_string()), "{events:?}");
    assert!(
        events.contains(&"A1 at rest 0 counts".to_string()) || events.contains(&"A1 at rest -3 counts".to_string()),
        "{events:?}"
    );
    b.status(Request::Stop { function: 1, param: 0 });
    b.set(0x3012, &100u16.to_le_bytes());
    b.status(Request::Execute { function: 1, params: [9, 0xFF] });
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "reset on the next motion");
    b.keep_alive(5_000);
    assert_eq!(b.position(1), 400);
}

#[test]
fn a_drive_blocked_by_a_configured_obstacle_stops_there_with_its_drive_error() {
    let config = SimConfig::from_toml("[[actuator]]\nobstacle_counts = 300\nstall_error_after_ms = 2000\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 600);
    b.keep_alive(4_000);
    assert_eq!(b.position(1), 300, "it cannot pass the obstacle");
    assert_ne!(b.status1(1) & Status1Flag::Motion.mask(), 0, "pushing");
    let current = u16::from_le_bytes(b.get(0x00A1).try_into().unwrap());
    assert_eq!(current, 60, "twice its full-speed current while blocked");
    b.keep_alive(2_000);
    assert_eq!(b.status1(1) & Status1Flag::Motion.mask(), 0);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    // Towards the obstacle again, from where it rests against it: blocked again, and the error comes again.
    b.go(1, 600);
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "reset on the next motion");
    b.keep_alive(1_000);
    assert_eq!(b.position(1), 300, "resting against the obstacle, it still cannot pass it");
    b.keep_alive(1_500);
    assert_eq!(b.status1(1) & Status1Flag::Motion.mask(), 0);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
    // Away from the obstacle it moves again, and the bit is gone.
    b.go(1, 100);
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
    b.keep_alive(3_000);
    assert_eq!(b.position(1), 100);
    // And back up to it from below: blocked at the obstacle once more.
    b.go(1, 600);
    b.keep_alive(3_000);
    assert_eq!(b.position(1), 300);
}

#[test]
fn a_stall_is_not_forgiven_by_repeating_re() {
    // A streaming client (or a ROS loop) repeats RE every 100 ms to a TLT column that is too slow to move:
    // the drive error still comes within 10 s.
    let mut b = Bench::new(SimConfig::tlt());
    b.open(1);
    b.set(0x3012, &20u16.to_le_bytes()); // F2 (column 1 alone) at 20 %: below the 30 % a TLT needs
    b.set(0x3021, &400i32.to_le_bytes());
    b.unit.take_events();
    let mut raised_after_ms = None;
    for n in 1..=100u32 {
        b.status(Request::Execute { function: 1, params: [9, 0xFF] });
        b.keep_alive(100);
        if b.unit.take_events().iter().any(|e| e == "error bit 15 set (error with drive 1)") {
            raised_after_ms = Some(n * 100);
            break;
        }
    }
    let after = raised_after_ms.expect("the drive error within 10 s of repeated RE");
    assert!(after <= 10_000, "{after} ms");
    assert_eq!(b.status1(1) & Status1Flag::Motion.mask(), 0, "the drive time-out stopped it");
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(15));
}

#[test]
fn a_drive_blocked_by_an_obstacle_gets_its_error_even_under_repeated_re() {
    let config = SimConfig::from_toml("[[actuator]]\nobstacle_counts = 300\nstall_error_after_ms = 2000\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.unit.take_events();
    let mut raised = false;
    for _ in 0..60 {
        b.go(1, 600);
        b.keep_alive(100);
        if b.unit.take_events().iter().any(|e| e == "error bit 15 set (error with drive 1)") {
            raised = true;
            break;
        }
    }
    assert!(raised, "blocked and pushing, the drive error comes although RE is repeated");
    assert_eq!(b.position(1), 300);
}

#[test]
fn a_total_current_above_the_configured_limit_sets_bit_14_and_stops_every_drive() {
    // Each drive takes 3.0 A at full speed: one alone stays under 5.0 A, two together do not.
    let config = SimConfig::from_toml("total_current_limit_deci_amps = 50\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.keep_alive(1_000);
    assert!(b.unit.is_moving(a(1)));
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
    b.go(2, 800);
    b.keep_alive(1_000);
    assert!(!b.unit.any_moving(), "bit 14 fast-stops every motion");
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(14));
    assert_eq!(u32::from_le_bytes(b.get(0x008F).try_into().unwrap()), 1, "Number_Total_Over_Current");
    b.go(1, 0);
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "reset on the next motion");
}

#[test]
fn an_error_scheduled_in_the_configuration_is_raised_at_its_time() {
    let config =
        SimConfig::from_toml("[[error]]\nbit = 12\nat_ms = 3000\n[[error]]\nbit = 16\nat_ms = 1000\n").unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(900);
    assert_eq!(last_error(&mut b), ErrorCode::NONE);
    b.keep_alive(200);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(16), "drive 2's error at 1 s");
    assert!(b.unit.is_moving(a(1)) && !b.unit.is_moving(a(2)), "it stops its own drive only");
    b.keep_alive(2_000);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(12), "over-temperature at 3 s");
    assert!(!b.unit.any_moving(), "bit 12 stops every motion");
    for bad in ["[[error]]\nbit = 33\nat_ms = 1", "[[error]]\nbit = 3", "[[error]]\nbit = 3\nat_ms = 1\ncolour = 2"] {
        assert!(SimConfig::from_toml(bad).is_err(), "{bad}");
    }
}

#[test]
fn a_new_remote_speed_changes_a_running_motion_along_the_ramp() {
    let mut b = Bench::new(SimConfig::default());
    b.open(1);
    b.go(1, 800);
    b.keep_alive(1_000);
    let speed = |b: &mut Bench| u16::from_le_bytes(b.get(0x00F1).try_into().unwrap());
    assert_eq!(speed(&mut b), 100);
    b.set(0x3011, &40u16.to_le_bytes());
    b.wait(100);
    let during = speed(&mut b);
    assert!(during < 100 && during > 40, "slowing along the ramp: {during} %");
    b.keep_alive(500);
    assert_eq!(speed(&mut b), 40);
    // A function's speed does not touch the motions of another.
    b.go(2, 800);
    b.keep_alive(500);
    b.set(0x3011, &60u16.to_le_bytes());
    b.keep_alive(500);
    assert_eq!(u16::from_le_bytes(b.get(0x00F2).try_into().unwrap()), 100);
}

#[test]
fn virtual_limits_bound_every_motion() {
    let config = SimConfig::from_toml(
        "[[actuator]]\n[actuator.user_positions]\nvirtual_limit_in_counts = 50\nvirtual_limit_out_counts = 500\n\
         users = [{memory_counts = [100, 300, 500, 700], intermediate_in_counts = 200, intermediate_out_counts = 600}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}]\n\
         start_position_counts = 100\n",
    )
    .unwrap();
    let mut b = Bench::new(config);
    b.open(1);
    b.go(1, 800);
    b.keep_alive(6_000);
    assert_eq!(b.position(1), 500);
    b.go(1, -100);
    b.keep_alive(6_000);
    assert_eq!(b.position(1), 50);
    let upd = b.get(0x2001);
    assert_eq!(&upd[96..104], [50i32.to_le_bytes(), 500i32.to_le_bytes()].concat(), "readable in UserPositionData");
}

#[test]
fn liftkit_preset_maps_f1_f2_and_f8_as_the_public_drivers_assume() {
    let c = SimConfig::liftkit();
    assert_eq!(c.functions[0], vec![a(1)]);
    assert_eq!(c.functions[1], vec![a(2)]);
    assert_eq!(c.functions[7], vec![a(1), a(2)]);
    assert!(c.functions.iter().enumerate().all(|(i, f)| [0, 1, 7].contains(&i) || f.is_empty()));
    assert_eq!(SimConfig::from_toml("preset = \"liftkit\"").unwrap(), c);
    assert_eq!(SimConfig::preset("liftkit"), Some(c));
}

/// The exact telegrams of the public Ewellix ROS drivers (field notes, "What the public drivers send"), and the
/// exact replies a unit gives them.
#[test]
fn the_bytes_the_public_ros_drivers_send_are_understood() {
    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace().map(|h| u8::from_str_radix(h, 16).unwrap()).collect()
    }
    let mut b = Bench::new(SimConfig::liftkit());
    let exchange = |b: &mut Bench, request: &str| -> Vec<u8> {
        let mut out = Vec::new();
        b.unit.receive(b.now, &hex(request), &mut out);
        out
    };
    let ack = |c: &[u8; 2]| {
        let mut r = vec![c[0], c[1], 0x06];
        let crc = crc16(&r);
        r.extend_from_slice(&crc.to_le_bytes());
        r
    };
    // RO with one Safety_ID byte, sent twice to wake the unit; the keepalive RC without a cyclic object.
    assert_eq!(exchange(&mut b, "52 4F 01 7D 3D"), ack(b"RO"));
    assert_eq!(exchange(&mut b, "52 4F 01 7D 3D"), ack(b"RO"));
    assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    // RS to every function they use "to clear flags" before an RE; F1 fast is 52 53 00 00 CD 9F.
    for rs in ["52 53 00 00 CD 9F", "52 53 01 00 FC AC", "52 53 07 00 5A 06"] {
        assert_eq!(exchange(&mut b, rs), ack(b"RS"));
    }
    // Remote speed of F1 = 100 %, remote position of A1 = 500 counts as INT32, RE F1 direction 9.
    assert_eq!(exchange(&mut b, "52 54 04 00 11 30 64 00 6A 06"), ack(b"RT"));
    assert_eq!(exchange(&mut b, "52 54 06 00 21 30 F4 01 00 00 CF 36"), ack(b"RT"));
    assert_eq!(exchange(&mut b, "52 45 00 09 FF 00 27"), ack(b"RE"));
    for _ in 0..60 {
        b.wait(100);
        assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    }
    // RG 0x0011 (A1's position) and 0x0171 (A1's status 1), as they poll them.
    let reply = |bytes: Vec<u8>| -> (Status, Vec<u8>) {
        let mut dec = ReplyDecoder::new();
        dec.expect(Command::Get, ReplyShape::WithData);
        match dec.decode(&bytes) {
            (n, Some(Ok(r))) if n == bytes.len() => (r.status, r.data.unwrap_or_default().to_vec()),
            other => panic!("{bytes:02X?}: {other:?}"),
        }
    };
    let (status, data) = reply(exchange(&mut b, "52 47 11 00 2C 30"));
    assert_eq!((status, data), (Status::Ack, 500i32.to_le_bytes().to_vec()));
    let (status, data) = reply(exchange(&mut b, "52 47 71 01 27 2B"));
    assert_eq!(status, Status::Ack);
    assert_eq!(data[0] & Status1Flag::Motion.mask(), 0, "at rest");
    // Drive 2 has an error; the drivers expect the next motion to clear it. RS everything, then RE F8
    // (function index 7) direction 2: both columns out.
    b.unit.inject_error(ErrorCode::from_bit(16));
    for rs in ["52 53 00 00 CD 9F", "52 53 01 00 FC AC", "52 53 07 00 5A 06"] {
        assert_eq!(exchange(&mut b, rs), ack(b"RS"));
    }
    assert_eq!(exchange(&mut b, "52 45 07 02 FF 6A 7E"), ack(b"RE"));
    assert_eq!(last_error(&mut b), ErrorCode::NONE, "the drive error bit was reset by the next motion");
    b.wait(50);
    assert!(b.unit.is_moving(a(1)) && b.unit.is_moving(a(2)), "F8 drives both columns");
    assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    // RS of F8 fast stops both.
    assert_eq!(exchange(&mut b, "52 53 07 00 5A 06"), ack(b"RS"));
    assert!(!b.unit.any_moving());
    // Column 1 to its In end (RE F1 direction 1): a TLT reads a few counts below zero there. The manual's
    // INT32 is -3; drivers that decode 16 bits read 65533.
    assert_eq!(exchange(&mut b, "52 45 00 01 FF A9 AE"), ack(b"RE"));
    for _ in 0..80 {
        b.wait(100);
        assert_eq!(exchange(&mut b, "52 43 01 00 FF 31 8D"), ack(b"RC"));
    }
    let (_, data) = reply(exchange(&mut b, "52 47 11 00 2C 30"));
    assert_eq!(data, (-3i32).to_le_bytes());
    assert_eq!(u16::from_le_bytes([data[0], data[1]]), 65533);
    assert_eq!(exchange(&mut b, "52 53 00 00 CD 9F"), ack(b"RS"));
    assert_eq!(exchange(&mut b, "52 41 38 30"), ack(b"RA"));
    assert_eq!(b.unit.mode(), RemoteMode::Off);
}

/// "Remote data item: Stored in volatile register. Initialized after reset with preset values" (E 469,
/// S 437), and bits 1..5: "the control unit carries out a reset" (E 518-522, S 484-490): remote speed "function
/// speed from configuration", remote position "memory 1 / user 1 position", CyclicObj "-1" (E 476-477,
/// S 442-448).
#[test]
fn a_reset_of_the_unit_initialises_its_remote_data_with_their_presets() {
    let object = CyclicObject::new(&[], &[DataIndex(0x0011)]).unwrap().to_bytes();
    let write = |b: &mut Bench| {
        assert_eq!(b.set(0x3011, &50u16.to_le_bytes()), Status::Ack);
        assert_eq!(b.set(0x3021, &400i32.to_le_bytes()), Status::Ack);
        assert_eq!(b.set(0x3002, &object), Status::Ack);
    };
    let written = |b: &mut Bench| (b.get(0x3011), b.get(0x3021), b.get(0x3002));
    for bit in 1..=5u8 {
        let mut b = Bench::new(SimConfig::default());
        b.open(0);
        write(&mut b);
        b.unit.take_events();
        b.unit.inject_error(ErrorCode::from_bit(bit));
        assert_eq!(b.unit.mode(), RemoteMode::Off, "bit {bit}: the reset ends remote mode");
        let events = b.unit.take_events();
        assert!(events.iter().any(|e| e.starts_with("reset: remote speeds, remote positions")), "{events:?}");
        b.open(0);
        let (speed, position, cyclic) = written(&mut b);
        assert_eq!(speed, 100u16.to_le_bytes(), "bit {bit}: F1's remote speed is the configured function speed");
        assert_eq!(position, 100i32.to_le_bytes(), "bit {bit}: A1's remote position is memory 1 of user 1");
        assert_eq!(cyclic, [0xFF; 24], "bit {bit}: CyclicObj 2 is -1 again");
        let rc = b.send(Request::Cyclic { object: 1, write: &[] });
        assert_eq!(rc.data, Some(vec![]), "bit {bit}: CyclicObj 2 reads nothing (it read A1's position before)");
        // RE to the remote position goes to the preset, at the preset speed (110 counts/s at 100 %).
        b.status(Request::Execute { function: 0, params: [9, 0xFF] });
        b.keep_alive(1_500);
        assert_eq!(b.position(1), 100, "bit {bit}");
    }
    // Another error stops the motions but resets nothing: what was written stays.
    let mut b = Bench::new(SimConfig::default());
    b.open(0);
    write(&mut b);
    b.unit.inject_error(ErrorCode::from_bit(12));
    let (speed, position, cyclic) = written(&mut b);
    assert_eq!(
        (speed, position, cyclic),
        (50u16.to_le_bytes().to_vec(), 400i32.to_le_bytes().to_vec(), object.to_vec())
    );
}

/// Error bits whose reaction is that motions are not performed: 8 "Motion not executed", 13 "Control unit
/// switches itself off", 24..30 and 32 "Motions not performed or stopped", 31 "Motions not performed" (E
/// 525-544, S 493-512). PE: "Command not possible with SCU mode/state" (E 341, S 321).
const NOT_PERFORMED: [u8; 11] = [8, 13, 24, 25, 26, 27, 28, 29, 30, 31, 32];

#[test]
fn while_an_error_stands_after_which_motions_are_not_performed_no_motion_starts_and_re_is_refused_with_pe() {
    for bit in NOT_PERFORMED {
        let mut b = Bench::new(SimConfig::default());
        b.open(1);
        b.go(1, 800);
        b.keep_alive(500);
        b.unit.inject_error(ErrorCode::from_bit(bit));
        assert!(!b.unit.any_moving(), "bit {bit}: the running motion is stopped");
        let at = b.position(1);
        assert_eq!(b.unit.standing_errors(), ErrorCode::from_bit(bit));
        b.unit.take_events();
        for direction in [9u8, 2, 1, 3] {
            let re = Request::Execute { function: 0, params: [direction, 0xFF] };
            assert_eq!(b.status(re), Status::PermissionError, "bit {bit}, direction {direction}");
        }
        let events = b.unit.take_events();
        assert_eq!(events[0], format!("F1 RE refused (PE): motions are not performed while error bit {bit} stands"));
        // Neither does the hand switch move anything; the rest of remote mode works.
        b.unit.press_hand_switch(2, true);
        b.keep_alive(1_000);
        assert!(!b.unit.any_moving(), "bit {bit}");
        assert_eq!(b.position(1), at, "bit {bit}");
        assert_eq!(b.status(Request::Stop { function: 0, param: 0 }), Status::Ack);
        assert_eq!(b.set(0x3021, &100i32.to_le_bytes()), Status::Ack);
        // A later error, even one that replaces it in Error_Code 1, does not make it go away.
        b.unit.inject_error(ErrorCode::from_bit(15));
        assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
        assert_eq!(last_error(&mut b), ErrorCode::from_bit(15), "bit 15 is not reset: no motion started");
        // Nor does a reset of the unit (bits 1..5).
        b.unit.inject_error(ErrorCode::from_bit(5));
        b.open(1);
        assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
        assert_eq!(b.unit.standing_errors(), ErrorCode::from_bit(bit));
    }
}

#[test]
fn errors_that_only_stop_motions_let_the_next_one_start() {
    // 6, 7, 10, 11, 12 "Motions stopped (fast stop)"; 14..21 also "Bit reset on next motion"; 22 the watchdog.
    for bit in [6u8, 7, 10, 11, 12, 14, 15, 21, 22] {
        let mut b = Bench::new(SimConfig::default());
        b.open(1);
        b.unit.inject_error(ErrorCode::from_bit(bit));
        assert_eq!(b.unit.standing_errors(), ErrorCode::NONE, "bit {bit}");
        b.go(1, 200);
        b.keep_alive(500);
        assert!(b.unit.is_moving(a(1)), "bit {bit}");
    }
}

#[test]
fn an_error_scheduled_in_the_configuration_after_which_motions_are_not_performed_refuses_every_re_from_then_on() {
    let mut b = Bench::new(SimConfig::from_toml("[[error]]\nbit = 25\nat_ms = 1\n").unwrap());
    b.open(1);
    b.keep_alive(100);
    assert_eq!(b.set(0x3021, &400i32.to_le_bytes()), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::PermissionError);
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(25));
}

/// The `ack-without-motion` variant: the other reading of "motions not performed", an RE acknowledged and
/// nothing moving; the function counts as started until its RS.
#[test]
fn on_an_ack_without_motion_unit_re_is_acknowledged_while_the_error_stands_and_nothing_moves() {
    let mut config = SimConfig::default();
    config.add_variants([motionlink_scu::Variant::AckWithoutMotion]);
    let mut b = Bench::new(config);
    b.open(1);
    b.unit.inject_error(ErrorCode::from_bit(25));
    b.unit.take_events();
    assert_eq!(b.set(0x3021, &400i32.to_le_bytes()), Status::Ack);
    assert_eq!(b.status(Request::Execute { function: 0, params: [9, 0xFF] }), Status::Ack);
    assert_eq!(b.unit.executed_functions(), [1]);
    assert_eq!(
        b.unit.take_events(),
        ["F1 RE acknowledged, nothing moves: motions are not performed while error bit 25 stands"]
    );
    b.keep_alive(2_000);
    assert_eq!((b.position(1), b.status1(1) & Status1Flag::Motion.mask()), (0, 0), "nothing moved");
    assert_eq!(b.status(Request::Stop { function: 0, param: 0 }), Status::Ack);
    assert!(b.unit.executed_functions().is_empty());
}
