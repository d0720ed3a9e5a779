//! The emulator's configuration file, and its robustness against arbitrary sessions and bytes.

use crate::bench;

use bench::*;

#[test]
fn config_from_toml() {
    let c = SimConfig::from_toml(
        r#"
        actuators = 3
        speed_mode = "counts_per_second"
        default_speed = 200
        [functions]
        F1 = [1, 3]
        [[actuator]]
        stroke_max_counts = 1000
        "#,
    )
    .unwrap();
    assert_eq!(c.actuators.len(), 3);
    assert_eq!(c.actuators[0].stroke_max_counts, 1000);
    assert_eq!(c.functions[0], vec![a(1), a(3)]);
    assert_eq!(c.functions[1], vec![a(2)], "the rest stays SCP11");
    let mut b = Bench::new(c);
    b.open(1);
    assert_eq!(b.set(0x3011, &1000u16.to_le_bytes()), Status::Ack, "counts/s allow up to 1000");
    assert_eq!(SimConfig::from_toml("preset = \"tlt\"").unwrap(), SimConfig::tlt());
    for bad in [
        "actuators = 7",
        "preset = \"nope\"",
        "[functions]\nF11 = [1]",
        "[functions]\nF1 = [5]",
        "colour = 1",
        "[[actuator]]\nstroke_min_counts = 900",
    ] {
        let err = SimConfig::from_toml(bad).unwrap_err();
        assert!(!err.0.is_empty(), "{bad}");
    }
}

/// One step of a random session: a well-formed request (with arbitrary, often wrong, parameters) after a pause.
#[derive(Debug, Clone)]
enum Step {
    Open(u8),
    Cyclic(u8, Vec<u8>),
    Get(u16),
    Transfer(u16, Vec<u8>),
    Execute(u8, [u8; 2]),
    Stop(u8, u8),
    Abort,
}

fn known_index() -> impl Strategy<Value = u16> {
    let indices: Vec<u16> = DATA_LIST.iter().map(|e| e.index().0).chain(GROUPS.iter().map(|g| g.index.0)).collect();
    prop_oneof![proptest::sample::select(indices), any::<u16>()]
}

fn step() -> impl Strategy<Value = Step> {
    let bytes = || proptest::collection::vec(any::<u8>(), 0..40);
    prop_oneof![
        (0..4u8).prop_map(Step::Open),
        (prop_oneof![Just(0xFFu8), 0..6u8], bytes()).prop_map(|(o, w)| Step::Cyclic(o, w)),
        known_index().prop_map(Step::Get),
        (known_index(), bytes()).prop_map(|(i, d)| Step::Transfer(i, d)),
        // Motion functions, directions 0..9 and a remote position above all: the unit moves.
        (0..23u8, prop_oneof![0..10u8, any::<u8>()], any::<u8>()).prop_map(|(f, d, p)| Step::Execute(f, [d, p])),
        (0..23u8, any::<u8>()).prop_map(|(f, p)| Step::Stop(f, p)),
        Just(Step::Abort),
    ]
}

proptest! {
    /// Well-formed requests with arbitrary parameters, at arbitrary times: the unit never panics, answers
    /// every request with exactly one well-formed reply of the same command, keeps its actuators inside
    /// their strokes, and opens again at the end.
    #[test]
    fn random_sessions_of_valid_telegrams(steps in proptest::collection::vec((0..700u64, step()), 1..60)) {
        let mut b = Bench::new(SimConfig::default());
        let mut t = 0;
        for (pause, s) in &steps {
            t += pause;
            b.at(t);
            let request = match s {
                Step::Open(id) => Request::Open { safety_id: *id },
                Step::Cyclic(o, w) => Request::Cyclic { object: *o, write: w },
                Step::Get(i) => Request::Get { index: *i },
                Step::Transfer(i, d) => Request::Transfer { index: *i, data: d },
                Step::Execute(f, p) => Request::Execute { function: *f, params: *p },
                Step::Stop(f, p) => Request::Stop { function: *f, param: *p },
                Step::Abort => Request::Abort,
            };
            let answers = b.raw(&request_to_vec(&request).unwrap());
            prop_assert_eq!(answers.len(), 1, "{:?} got {:?}", s, answers);
            prop_assert_eq!(answers[0].command, request.command());
            for n in 1..=2 {
                let p = b.unit.position(a(n)).unwrap();
                prop_assert!((0..=865).contains(&p), "A{} at {}", n, p);
            }
        }
        b.wait(2000);
        b.open(1);
    }

    /// Arbitrary bytes never panic the emulator; after a pause the unit answers a good telegram again.
    #[test]
    fn arbitrary_bytes_never_panic_and_the_unit_recovers(chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..80), 0..20)) {
        let mut unit = Emulator::new(SimConfig::default()).unwrap();
        let mut out = Vec::new();
        let mut t = 0;
        for c in &chunks {
            t += 3;
            unit.receive(Timestamp::from_millis(t), c, &mut out);
        }
        // Every reply the unit made is a well-formed telegram: a reply of a known command, or the ICE answer
        // (`R?` with the unknown letters, 0x83, CRC) to an intact telegram of an unknown command.
        let mut dec = ReplyDecoder::new();
        let mut input = &out[..];
        loop {
            let unknown_command = input.len() >= 5
                && input[0] == b'R'
                && Command::from_code(input[0], input[1]).is_none()
                && input[2] == 0x83
                && crc16(&input[..3]) == u16::from_le_bytes([input[3], input[4]]);
            if unknown_command {
                input = &input[5..];
                continue;
            }
            let (n, ev) = dec.decode(input);
            input = &input[n..];
            match ev {
                Some(ev) => prop_assert!(ev.is_ok(), "{:?}", ev),
                None if input.is_empty() => break,
                None => {}
            }
        }
        out.clear();
        let later = Timestamp::from_millis(t) + Duration::from_millis(1500);
        unit.receive(later, &request_to_vec(&Request::Open { safety_id: 1 }).unwrap(), &mut out);
        prop_assert_eq!(&out[..3], b"RO\x06");
    }
}

/// An intact telegram of an unknown command (`RQ` whose CRC happens to match) is answered ICE with the
/// unknown letters, as the manual's table 2 says ("Unknown command code").
#[test]
fn an_unknown_command_is_answered_ice_with_its_letters() {
    let mut unit = Emulator::new(SimConfig::default()).unwrap();
    let mut out = Vec::new();
    unit.receive(Timestamp::from_millis(3), &[0x52, 0x51, 0x09, 0x22], &mut out);
    assert_eq!(out.len(), 5, "{out:02X?}");
    assert_eq!(&out[..3], b"RQ\x83");
    assert_eq!(crc16(&out[..3]).to_le_bytes(), [out[3], out[4]]);
}

#[test]
fn an_in_end_undershoot_outside_0_to_the_stroke_is_refused_naming_it() {
    for value in [i32::MIN, -1, 866, i32::MAX] {
        let err = SimConfig::from_toml(&format!("[[actuator]]\nin_end_undershoot_counts = {value}\n")).unwrap_err();
        assert!(err.0.contains(&format!("in_end_undershoot_counts = {value}")) && err.0.contains("0 to 865"), "{err}");
    }
    // The whole stroke is allowed: at rest on its In end the drive reads that far below it.
    let mut b = Bench::new(SimConfig::from_toml("[[actuator]]\nin_end_undershoot_counts = 865\n").unwrap());
    b.open(1);
    assert_eq!(b.position(1), -865);
    // A stroke at the bottom of the counts' range reads the lowest count, not a position past it.
    let low = SimConfig::from_toml(
        "[[actuator]]\nstroke_min_counts = -2147483648\nstroke_max_counts = -2147483638\n\
         start_position_counts = -2147483648\nin_end_undershoot_counts = 5\n",
    )
    .unwrap();
    let mut b = Bench::new(low);
    b.open(1);
    assert_eq!(b.position(1), i32::MIN);
}

#[test]
fn an_obstacle_outside_the_stroke_is_refused_naming_it() {
    for value in [-1, 866, i32::MIN] {
        let err = SimConfig::from_toml(&format!("[[actuator]]\nobstacle_counts = {value}\n")).unwrap_err();
        assert!(err.0.contains(&format!("obstacle_counts = {value}")) && err.0.contains("0 to 865"), "{err}");
    }
    for value in [0, 865] {
        let c = SimConfig::from_toml(&format!("[[actuator]]\nobstacle_counts = {value}\n")).unwrap();
        assert_eq!(c.actuators[0].obstacle_counts, Some(value), "an obstacle on a stroke end is in the stroke");
    }
}

#[test]
fn an_obstacle_a_whole_counts_range_from_the_start_is_modelled() {
    let c = SimConfig::from_toml(
        "[[actuator]]\nstroke_min_counts = -10\nstroke_max_counts = 2147483647\n\
         start_position_counts = 2147483647\nobstacle_counts = -10\n",
    )
    .unwrap();
    let mut b = Bench::new(c);
    b.open(1);
    assert_eq!(b.position(1), i32::MAX);
}

#[test]
fn two_drives_at_the_highest_current_read_the_total_entrys_maximum() {
    // 2 x 4000.0 A is more than the UINT16 total-current entry (0x00BF) holds: it reads its maximum.
    let both = "[[actuator]]\ncurrent_at_full_speed_deci_amps = 40000\n\
                [[actuator]]\ncurrent_at_full_speed_deci_amps = 40000\n";
    let mut b = Bench::new(SimConfig::from_toml(both).unwrap());
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(1_000);
    assert!(b.unit.is_moving(a(1)) && b.unit.is_moving(a(2)));
    assert_eq!(u16::from_le_bytes(b.get(0x00BF).try_into().unwrap()), u16::MAX);
    assert_eq!(u16::from_le_bytes(b.get(0x00A1).try_into().unwrap()), 40000);
    // The limit compares the true total: 8000.0 A is above 6553.5 A.
    let limited = format!("total_current_limit_deci_amps = 65535\n{both}");
    let mut b = Bench::new(SimConfig::from_toml(&limited).unwrap());
    b.open(1);
    b.go(1, 800);
    b.go(2, 800);
    b.keep_alive(1_000);
    assert!(!b.unit.any_moving(), "bit 14 fast-stops every motion");
    assert_eq!(last_error(&mut b), ErrorCode::from_bit(14));
}

#[test]
fn a_preset_in_the_text_that_differs_from_the_one_given_is_refused_naming_both() {
    let err = SimConfig::from_toml_over("preset = \"liftkit\"\n", Some("tlt"), &[]).unwrap_err();
    assert!(err.0.contains("preset = \"liftkit\"") && err.0.contains("\"tlt\""), "{err}");
    // The same preset in both, or either alone, is that preset.
    assert_eq!(SimConfig::from_toml_over("preset = \"liftkit\"\n", Some("liftkit"), &[]), Ok(SimConfig::liftkit()));
    assert_eq!(SimConfig::from_toml_over("preset = \"liftkit\"\n", None, &[]), Ok(SimConfig::liftkit()));
    assert_eq!(SimConfig::from_toml_over("", Some("tlt"), &[]), Ok(SimConfig::tlt()));
}

#[test]
fn an_info_text_longer_than_its_entry_is_refused_naming_it() {
    let err = SimConfig::from_toml(&format!("firmware_info = \"{}\"\n", "x".repeat(32))).unwrap_err();
    assert!(err.0.contains("firmware_info") && err.0.contains("32 bytes") && err.0.contains("31"), "{err}");
    // Counted in bytes: 19 two-byte characters are 38 bytes.
    let err = SimConfig::from_toml(&format!("configuration_info = \"{}\"\n", "é".repeat(19))).unwrap_err();
    assert!(err.0.contains("configuration_info") && err.0.contains("38 bytes") && err.0.contains("36"), "{err}");
    let err = Emulator::new(SimConfig { firmware_info: "ü".repeat(16), ..SimConfig::default() }).unwrap_err();
    assert!(err.0.contains("firmware_info") && err.0.contains("32 bytes"), "{err}");
    // A text that fills its entry is read in full.
    let full = "F".repeat(31);
    let mut b = Bench::new(SimConfig::from_toml(&format!("firmware_info = \"{full}\"\n")).unwrap());
    assert_eq!(b.get_after_open(0x0001), full.as_bytes());
}
