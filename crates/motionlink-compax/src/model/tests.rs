//! Tests of the vocabulary.

use super::value::{strip_name, trim};
use super::*;
use crate::wire::{BinaryCommand, Fixed24, TextBuf};

fn p(v: f64) -> Position {
    Position::new(v).unwrap()
}

#[test]
fn the_manuals_a_spelling_of_outputs_is_read_and_written_as_o() {
    // Manual 4.4.1: `OUTPUT Ayy=0|1` and `POSR value OUTPUT Ayy=0|1`.
    let c = Command::parse(b"OUTPUT A09=1").unwrap();
    assert_eq!(c, Command::Output { output: 9, state: OutputState::ON });
    assert_eq!(c.to_ascii(CommandStyle::Long).unwrap().as_str(), "OUTPUT O9=1");
    let c = Command::parse(b"POSR 200 OUTPUT A9=0").unwrap();
    assert_eq!(c, Command::PosROutput { distance: p(200.0), output: 9, state: OutputState::new(9, 0).unwrap() });
    assert_eq!(c.to_ascii(CommandStyle::Short).unwrap().as_str(), "PR 200 OT O9=0");
    assert!(Command::parse(b"OUTPUT B9=1").is_err());
}

#[test]
fn commands_in_both_styles_round_trip() {
    let cmds = [
        (Command::PosA(p(2500.0)), "POSA 2500", "PA 2500"),
        (Command::PosR(p(-15.8)), "POSR -15.8", "PR -15.8"),
        (Command::PosAHome, "POSA HOME", "PH"),
        (Command::Speed(SpeedPercent::new(50.0).unwrap()), "SPEED 50", "SD 50"),
        (Command::Accel(RampMs::new(500).unwrap()), "ACCEL 500", "AL 500"),
        (Command::AccelBrake(RampMs::new(250).unwrap()), "ACCEL- 250", "AL- 250"),
        (Command::Output { output: 9, state: OutputState::ON }, "OUTPUT O9=1", "OT O9=1"),
        (
            Command::PosROutput { distance: p(200.0), output: 9, state: OutputState::ON },
            "POSR 200 OUTPUT O9=1",
            "PR 200 OT O9=1",
        ),
        (
            Command::PosRSpeed { distance: p(100.0), speed: SpeedPercent::new(50.0).unwrap() },
            "POSR 100 SPEED 50",
            "PR 100 SD 50",
        ),
        (Command::ReadStatus(StatusId::ACTUAL_POSITION), "S1", "S1"),
        (Command::ReadParam(ParamId::DEVICE_ADDRESS), "P194", "P194"),
        (Command::WriteParam(ParamId::new(3).unwrap(), -1055.88), "P003=-1055.88", "P003=-1055.88"),
    ];
    for (c, long, short) in cmds {
        assert_eq!(c.to_ascii(CommandStyle::Long).unwrap().as_str(), long);
        assert_eq!(c.to_ascii(CommandStyle::Short).unwrap().as_str(), short);
        assert_eq!(Command::parse(long.as_bytes()).unwrap(), c, "{long}");
        assert_eq!(Command::parse(short.as_bytes()).unwrap(), c, "{short}");
    }
    // The user guide writes values with and without a space.
    assert_eq!(Command::parse(b"POSA1000").unwrap(), Command::PosA(p(1000.0)));
    assert_eq!(Command::parse(b"POSR15.8").unwrap(), Command::PosR(p(15.8)));
    assert_eq!(
        Command::parse(b"PR 100 SD 50").unwrap().to_ascii(CommandStyle::Short).unwrap().as_str(),
        "PR 100 SD 50"
    );
}

#[test]
fn bad_commands_and_ranges() {
    for bad in [
        &b"POSA"[..],
        b"POSA x",
        b"SPEED 0",
        b"SPEED 101",
        b"ACCEL 40000",
        b"ACCEL -1",
        b"OUTPUT O9=2",
        b"OUTPUT 9=1",
        b"S41",
        b"S0",
        b"P251=1",
        b"P0",
        b"XYZ",
        b"PH 5",
        b"PR 1 OT",
        b"PR 1 XX 5",
        b"",
    ] {
        assert!(Command::parse(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
    }
    assert!(Command::parse(b"OUTPUT O0=2").is_ok());
    assert!(Position::new(1e7).is_err());
    assert!(SpeedPercent::new(f64::NAN).is_err());
    assert!(RampMs::new(32_768).is_err());
}

#[test]
fn binary_forms() {
    let c = Command::PosA(p(360.0));
    assert_eq!(Command::from_binary(&c.to_binary().unwrap()).unwrap(), c);
    assert!(Command::PosAHome.to_binary().is_err());
    assert!(Command::Output { output: 0, state: OutputState::new(0, 2).unwrap() }.to_binary().is_err());
    assert!(Command::from_binary(&BinaryCommand::Accel(-5)).is_err());
    assert!(Command::from_binary(&BinaryCommand::Speed(Fixed24::from_f64(150.0).unwrap())).is_err());
}

#[test]
fn status_values() {
    let v = StatusValue::parse(StatusId::ACTUAL_POSITION, b"S001: -12.500").unwrap();
    assert_eq!(v, StatusValue::Position(p(-12.5)));
    assert_eq!(StatusValue::parse(StatusId::ACTUAL_POSITION, b"+0360.000").unwrap(), StatusValue::Position(p(360.0)));
    // The user guide's example: password 302 active is S17 = "1000 0000" = 0x80.
    let StatusValue::S17(b) = StatusValue::parse(StatusId::STATUS_BITS_2, b"S017: 1000 0000").unwrap() else {
        panic!()
    };
    assert_eq!(b.0, 0x80);
    assert!(b.contains(S17Flag::Password302));
    assert_eq!(b.meanings(), ["password 302 active"]);
    // The user guide's S18 example.
    let h = StatusValue::parse(StatusId::ERROR_HISTORY, b"S018: 99 55 10 99 53 98 10 99").unwrap();
    let StatusValue::History(h) = h else { panic!() };
    assert_eq!(h[1], HistoryEntry::Error(ErrorCode::EMERGENCY_STOP));
    assert_eq!(h[5], HistoryEntry::PowerOn);
    assert!(StatusValue::parse(StatusId::STATUS_BITS_1, b"S016: 1000").is_err());
    assert!(StatusValue::parse(StatusId::ACTUAL_POSITION, b"S002: 1").is_err());
    let mut out = TextBuf::<48>::new();
    StatusValue::Position(p(360.0)).write_reply(StatusId::ACTUAL_POSITION, &mut out).unwrap();
    assert_eq!(out.as_str(), "S001: 360.000");
    out.clear();
    StatusValue::S16(S16Bits(0b1101_0010)).write_reply(StatusId::STATUS_BITS_1, &mut out).unwrap();
    assert_eq!(out.as_str(), "S016: 1101 0010");
    let u = StatusId::new(4).unwrap();
    assert_eq!(u.kind(), StatusKind::Text);
}

#[test]
fn long_text_values_are_cut_between_characters() {
    let id = StatusId::DEVICE_ID_1;
    // 'a' and then two-byte characters: byte 48 falls inside one.
    let text = format!("a{}", "é".repeat(30));
    let StatusValue::Text(t) = StatusValue::parse(id, text.as_bytes()).unwrap() else { panic!() };
    assert_eq!(t.as_str(), format!("a{}", "é".repeat(23)));
    assert_eq!(t.as_str().len(), 47);
    let text = "€".repeat(20); // three bytes each: 48 is a boundary
    let StatusValue::Text(t) = StatusValue::parse(id, text.as_bytes()).unwrap() else { panic!() };
    assert_eq!(t.as_str(), "€".repeat(16));
    let StatusValue::Text(t) = StatusValue::parse(id, b"S031: COMPAX 0260M").unwrap() else { panic!() };
    assert_eq!(t.as_str(), "COMPAX 0260M");
}

#[test]
fn errors_and_params() {
    assert_eq!(
        ErrorCode(72).to_string(),
        "E72 (block-check character error: the telegram was discarded, retransmit it)"
    );
    assert!(ErrorCode(73).is_retransmit() && !ErrorCode(74).is_retransmit());
    assert!(ErrorCode(70).is_retransmit() && ErrorCode(72).is_retransmit());
    assert!(!ErrorCode(71).is_retransmit(), "E71: retransmit with fewer characters, not the same telegram");
    assert_eq!(ErrorCode(10).meaning(), None);
    assert_eq!(parse_param_reply(ParamId::DEVICE_ADDRESS, b"P194=5").unwrap(), 5.0);
    assert_eq!(parse_param_reply(ParamId::DEVICE_ADDRESS, b"5").unwrap(), 5.0);
    assert_eq!(parse_param_reply(ParamId::new(3).unwrap(), b"P003: -1055.88").unwrap(), -1055.88);
    assert!(parse_param_reply(ParamId::DEVICE_ADDRESS, b"P195=9600").is_err());
    assert!(ParamId::BAUD_RATE.check(9600.0).is_ok());
    assert!(ParamId::BAUD_RATE.check(9601.0).is_err());
    assert!(ParamId::OPERATING_MODE.check(127.0).is_ok());
    // 164 / 165 select the COMTAC fieldbus protocol: the manual's instruction (3.3.2), written like any value.
    assert!(ParamId::OPERATING_MODE.check(164.0).is_ok() && ParamId::OPERATING_MODE.check(165.0).is_ok());
    assert!(ParamId::OPERATING_MODE.check(128.0).is_err() && ParamId::OPERATING_MODE.check(166.0).is_err());
    // The fieldbus's baud rates (chapter 5): only those beyond the ASCII list.
    for rate in [28_800.0, 172_800.0, 345_600.0] {
        assert!(ParamId::BAUD_RATE.check(rate).is_ok(), "{rate}");
    }
    assert!(ParamId::BAUD_RATE.check(14_400.0).is_err());
    assert!(ParamId::DEVICE_ADDRESS.check(32.0).is_err());
    let mut t = TextBuf::<40>::new();
    write_param_reply(ParamId::BAUD_RATE, 9600.0, &mut t).unwrap();
    assert_eq!(t.as_str(), "P195=9600");
    assert_eq!(ParamId::parse("p3").unwrap(), ParamId::new(3).unwrap());
    assert_eq!(StatusId::parse("S016").unwrap(), StatusId::STATUS_BITS_1);
}

/// A value the command `P003=value` would carry as another number (six decimals) is refused before anything
/// is sent, naming the value and what it would be sent as; one that makes the command longer than the input
/// buffer is refused with the real length of the command.
#[test]
fn a_parameter_value_the_command_does_not_carry_is_refused() {
    let p3 = ParamId::new(3).unwrap();
    assert_eq!(
        p3.check(0.0000001).unwrap_err().to_string(),
        "parameter value P003=0.0000001 has more decimals than a command carries (6): it would be sent as P003=0"
    );
    assert_eq!(
        ParamWrite::new(p3, -1.23456789).unwrap_err().to_string(),
        "parameter value P003=-1.23456789 has more decimals than a command carries (6): it would be sent as \
         P003=-1.234568"
    );
    for fine in [-1055.88, 0.000001, 0.1 + 0.2, 123456.123456, 0.0] {
        assert!(p3.check(fine).is_ok(), "{fine}");
    }
    // "P003=" and 309 digits; "P003=" and 42.
    let too_long = |v: f64| p3.check(v).unwrap_err();
    assert_eq!(too_long(1e308), ModelError::Wire(crate::wire::WireError::TooLong(314)));
    assert_eq!(
        too_long("123456789012345678901234567890123456789012".parse().unwrap()).to_string(),
        "command string of 47 characters is longer than the drive's input buffer (40)"
    );
    assert_eq!(
        Command::WriteParam(p3, 1e308).to_ascii(CommandStyle::Long).unwrap_err(),
        ModelError::Wire(crate::wire::WireError::TooLong(314))
    );
    // 40 characters fit, 41 do not.
    assert!(p3.check(12345678901234567890123456789012345.0).is_ok());
    assert_eq!(too_long(123456789012345678901234567890123456.0).to_string(), {
        "command string of 41 characters is longer than the drive's input buffer (40)"
    });
}

#[test]
fn a_misspelt_name_is_answered_with_the_nearest_one() {
    let e = ParamId::parse("devce_address").unwrap_err().to_string();
    assert_eq!(e, "\"devce_address\" is not a parameter: did you mean device_address?");
    let e = StatusId::parse("actual_postion").unwrap_err().to_string();
    assert_eq!(e, "\"actual_postion\" is not a status value: did you mean actual_position?");
    let e = ParamId::parse("banana").unwrap_err().to_string();
    assert!(e.contains("give P1..P250"), "{e}");
    assert!(StatusId::parse("S99").unwrap_err().to_string().contains("S1..=S40"));
}

#[test]
fn status_lookup_is_the_table() {
    for n in 0..=StatusId::MAX {
        let id = StatusId(n);
        assert_eq!(id.info(), STATUS.iter().find(|i| i.id == u32::from(id.get())), "S{n}");
        assert_eq!(id.kind(), id.info().map_or(StatusKind::Text, |i| i.kind.kind), "S{n}");
    }
    assert_eq!(StatusId(200).info(), None);
}

#[test]
fn command_text_in_place() {
    let cmds = [
        Command::ReadStatus(StatusId::ACTUAL_POSITION),
        Command::ReadStatus(StatusId::STATUS_BITS_2),
        Command::ReadStatus(StatusId::new(40).unwrap()),
        Command::ReadParam(ParamId::new(3).unwrap()),
        Command::ReadParam(ParamId::OPERATING_MODE),
        Command::WriteParam(ParamId::new(250).unwrap(), -1055.88),
        Command::PosROutput { distance: p(-8_388_608.0), output: 65_535, state: OutputState::ON },
        Command::PosA(p(0.5)),
        Command::PosAHome,
    ];
    // One buffer for all, so that a short text follows a long one.
    let mut text = CommandText::new();
    for style in [CommandStyle::Long, CommandStyle::Short] {
        for c in cmds.iter().chain(cmds.iter().rev()) {
            let owned = c.to_ascii(style).unwrap();
            c.write_ascii_into(style, &mut text).unwrap();
            assert_eq!(text, owned, "{c:?}");
            assert_eq!(text.as_str(), owned.as_str());
            assert!(!text.overflowed());
        }
    }
}

/// The name stripping as it was before the three-digit form was compared at once.
fn strip_name_reference(text: &[u8], letter: u8, number: u16) -> &[u8] {
    let t = trim(text);
    if t.first().is_some_and(|c| c.eq_ignore_ascii_case(&letter)) {
        let digits = t[1..].iter().take_while(|c| c.is_ascii_digit()).count();
        let n = t[1..1 + digits].iter().fold(0u32, |a, d| a.saturating_mul(10).saturating_add(u32::from(d - b'0')));
        if digits > 0 && n == u32::from(number) {
            let mut rest = &t[1 + digits..];
            if let [b':' | b'=', r @ ..] = rest {
                rest = r;
            }
            return trim(rest);
        }
    }
    t
}

#[test]
fn names_at_the_edges_of_the_three_digit_form() {
    for (text, number, value) in [
        (&b"S001: 5"[..], 1, &b"5"[..]),
        (b" s001= 5 ", 1, b"5"),
        (b"S001", 1, b""),
        (b"S0011: 5", 1, b"S0011: 5"),
        (b"S0011: 5", 11, b"5"),
        (b"S001: 5", 1001, b"S001: 5"),
        (b"S1001: 5", 1001, b"5"),
        (b"S000: 5", 0, b"5"),
        (b"S01: 5", 1, b"5"),
        (b"P194=5", 194, b"5"),
    ] {
        let letter = text.trim_ascii_start()[0].to_ascii_uppercase();
        assert_eq!(strip_name(text, letter, number), value, "{:?} {number}", String::from_utf8_lossy(text));
        assert_eq!(strip_name_reference(text, letter, number), value);
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 3000, ..Default::default() })]

    #[test]
    fn names_are_stripped_as_before(
        number in proptest::prop_oneof![0u16..=300, proptest::num::u16::ANY],
        letter in proptest::sample::select(vec![b'S', b'P']),
        // A name made for the number (zero-padded, perhaps more digits, the other case) or any text.
        name in (0usize..7, "[0-9]{0,2}", proptest::bool::ANY, "[ ]{0,2}", "[:=]?", "[ ]{0,3}"),
        value in "[-+0-9. a]{0,8}[ ]{0,2}",
        noise in proptest::option::of("[ ]{0,2}[SsPpx]?[0-9]{0,7}[:=]?[ ]{0,3}[-+0-9. a]{0,8}[ ]{0,2}"),
    ) {
        let (width, extra, lower, lead, sep, gap) = name;
        let l = if lower { letter.to_ascii_lowercase() } else { letter } as char;
        let text = noise.unwrap_or_else(|| format!("{lead}{l}{number:0width$}{extra}{sep}{gap}{value}"));
        proptest::prop_assert_eq!(
            strip_name(text.as_bytes(), letter, number),
            strip_name_reference(text.as_bytes(), letter, number)
        );
    }
}
