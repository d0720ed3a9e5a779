//! Tests of the emulator.

use super::*;
use crate::model::ParamId;
use motionlink_link::emulator::Emulator as _;

fn bus(addrs: &[u8], p196: u32) -> Emulator {
    Emulator::new(SimConfig::bus(addrs, p196, 9600)).unwrap()
}

fn ask(bus: &mut Emulator, now: u64, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    bus.receive(Timestamp::from_millis(now), bytes, &mut out);
    out
}

#[test]
fn the_manuals_example_with_and_without_bcc() {
    let mut b = bus(&[1, 5], 0);
    assert_eq!(ask(&mut b, 0, b"1S1\r"), b"S001: 0.000\r\n>");
    assert_eq!(ask(&mut b, 0, b"5S1\r"), b"S001: 0.000\r\n>");
    let mut b = bus(&[1, 5], 8);
    let mut want = b"S001: 0.000\r\n>".to_vec();
    want.push(crate::wire::bcc(b"S001: 0.000"));
    assert_eq!(ask(&mut b, 0, b"1S1\rS"), want);
    let mut e72 = b"E72\r\n>".to_vec();
    e72.push(crate::wire::bcc(b"E72"));
    assert_eq!(ask(&mut b, 0, b"1S1\rX"), e72);
}

#[test]
fn broadcast_buffer_execute_and_motion() {
    let mut b = bus(&[1, 5], 0);
    assert_eq!(ask(&mut b, 0, b"1POSA 10,\r"), b"\r\n>");
    assert_eq!(ask(&mut b, 0, b"5POSR -5,\r"), b"\r\n>");
    assert!(!b.drive(1).unwrap().is_moving());
    assert_eq!(ask(&mut b, 1, b"32!\r"), b"");
    assert!(b.drive(1).unwrap().is_moving() && b.drive(5).unwrap().is_moving());
    // 100 units/s, instant ramps: 10 units take 100 ms.
    assert_eq!(ask(&mut b, 50, b"1POSA 20\r"), b"E92\r\n>");
    let mut out = Vec::new();
    b.advance(Timestamp::from_millis(200), &mut out);
    assert_eq!(b.drive(1).unwrap().position(), 10.0);
    assert_eq!(b.drive(5).unwrap().position(), -5.0);
    assert_eq!(ask(&mut b, 201, b"32!\r"), b"", "the buffer is consumed by '!'");
    assert_eq!(ask(&mut b, 202, b"1!\r"), b"E90\r\n>");
}

#[test]
fn a_configuration_file_sets_each_drive() {
    let cfg = SimConfig::from_toml(
        r#"
        baud_rate = 19200
        p196 = 8
        max_speed_units_per_s = 50.0

        [[drive]]
        address = 1

        [[drive]]
        address = 5
        position = -12.5
        p196 = 72

        [[drive]]
        address = 9
        baud_rate = 9600
        "#,
    )
    .unwrap();
    assert_eq!((cfg.baud_rate, cfg.p196, cfg.max_speed_units_per_s), (19_200, 8, 50.0));
    let mut b = Emulator::new(cfg).unwrap();
    let one = b.drive(1).unwrap();
    assert_eq!((one.mode().to_p196(), one.baud_rate(), one.position()), (8, 19_200, 0.0));
    let five = b.drive(5).unwrap();
    assert_eq!((five.mode().to_p196(), five.position(), five.target()), (72, -12.5, -12.5));
    assert_eq!(five.param(ParamId::OPERATING_MODE), Some(72.0));
    assert_eq!(b.drive(9).unwrap().baud_rate(), 9600);
    // Each answers in its own mode: drive 5 with its address in front; drive 9 hears only noise.
    let with_bcc = |text: &[u8]| {
        let mut t = text.to_vec();
        t.push(crate::wire::bcc(&text[..text.len() - 1]));
        t
    };
    let mut want = b"5S001: -12.500\r\n>".to_vec();
    want.push(crate::wire::bcc(b"5S001: -12.500"));
    assert_eq!(ask(&mut b, 0, &with_bcc(b"5S1\r")), want);
    assert!(ask(&mut b, 1, &with_bcc(b"9S1\r")).is_empty());
    // SPEED 100 is 50 units/s: 10 units take 200 ms.
    assert_eq!(ask(&mut b, 2, &with_bcc(b"1POSA 10\r"))[..3], *b"\r\n>");
    let mut out = Vec::new();
    b.advance(Timestamp::from_millis(102), &mut out);
    assert!((b.drive(1).unwrap().position() - 5.0).abs() < 0.1, "{}", b.drive(1).unwrap().position());
    b.advance(Timestamp::from_millis(210), &mut out);
    assert_eq!(b.drive(1).unwrap().position(), 10.0);
    // Every key has a default.
    assert_eq!(SimConfig::from_toml("").unwrap(), SimConfig::default());
}

#[test]
fn a_bad_configuration_file_says_what_is_wrong() {
    for (text, says) in [
        ("[[drive]]\naddress = 32\n", "address 32"),
        ("[[drive]]\naddress = 3\n[[drive]]\naddress = 3\n", "two drives have address 3"),
        ("p196 = 164\n", "COMTAC"),
        ("[[drive]]\naddress = 1\np196 = 200\n", "P196 = 200"),
        ("baud_rate = 1234\n", "1234"),
        ("[[drive]]\naddress = 1\nbaud_rate = 777\n", "777"),
        ("[[drive]]\naddress = 1\nposition = 1e9\n", "position"),
        ("max_speed_units_per_s = 0.0\n", "max_speed_units_per_s"),
        ("[[drive]]\naddress = 1\nspeed = 5\n", "unknown field `speed`"),
        ("drive = []\n", "0 drives"),
        ("baud_rate = \"fast\"\n", "baud_rate"),
    ] {
        let e = SimConfig::from_toml(text).unwrap_err();
        assert!(e.to_string().contains(says), "{text:?}: {e}");
    }
}

#[test]
fn unmodelled_parameters_and_status_values_are_refused_not_zero() {
    let mut b = bus(&[1], 0);
    // The manual defines P194..P196 only: others are refused, read or written.
    assert_eq!(ask(&mut b, 0, b"1P12\r"), b"E90\r\n>");
    assert_eq!(ask(&mut b, 1, b"1P12=3\r"), b"E90\r\n>");
    assert_eq!(ask(&mut b, 2, b"1P12\r"), b"E90\r\n>", "the refused write stored nothing");
    assert_eq!(b.drive(1).unwrap().param(ParamId::new(12).unwrap()), None);
    assert_eq!(ask(&mut b, 3, b"1P194\r"), b"P194=1\r\n>");
    // Status values the emulator does not model.
    for s in ["S4", "S11", "S20", "S30", "S40"] {
        assert_eq!(ask(&mut b, 4, format!("1{s}\r").as_bytes()), b"E90\r\n>", "{s}");
    }
    // A parameter the configuration lists is modelled.
    let cfg = SimConfig::bus(&[1], 0, 9600).with_param(ParamId::new(12).unwrap(), 1.5);
    let mut b = Emulator::new(cfg).unwrap();
    assert_eq!(ask(&mut b, 0, b"1P12\r"), b"P012=1.5\r\n>");
    assert_eq!(ask(&mut b, 1, b"1P12=-3\r"), b"\r\n>");
    assert_eq!(b.drive(1).unwrap().param(ParamId::new(12).unwrap()), Some(-3.0));
    let bad = SimConfig::bus(&[1], 0, 9600).with_param(ParamId::DEVICE_ADDRESS, 1.0);
    assert!(Emulator::new(bad).is_err(), "P194 comes from the drive's address");
    assert!(SimConfig::from_toml("params = { Q1 = 0.0 }").is_err());
}

#[test]
fn the_error_history_s18_records_errors() {
    let mut b = bus(&[1], 8);
    let with_bcc = |text: &[u8]| {
        let mut t = text.to_vec();
        t.push(crate::wire::bcc(&text[..text.len() - 1]));
        t
    };
    let s18 = |b: &mut Emulator, now: u64| {
        let r = ask(b, now, &with_bcc(b"1S18\r"));
        String::from_utf8_lossy(&r[..r.len() - 4]).into_owned()
    };
    assert_eq!(s18(&mut b, 0), "S018: 99 99 99 99 99 99 99 99");
    // E72: a wrong BCC; acknowledged (99) by the next error-free transmission, the S18 read itself.
    assert_eq!(&ask(&mut b, 1, b"1S1\rX")[..3], b"E72");
    assert_eq!(s18(&mut b, 2), "S018: 99 72 99 99 99 99 99 99");
    // E92: a move while moving; E90: an empty buffer.
    assert_eq!(&ask(&mut b, 3, &with_bcc(b"1POSA 50\r"))[..3], b"\r\n>");
    assert_eq!(&ask(&mut b, 10, &with_bcc(b"1POSA 20\r"))[..3], b"E92");
    assert_eq!(&ask(&mut b, 11, &with_bcc(b"1!\r"))[..3], b"E90");
    assert_eq!(s18(&mut b, 12), "S018: 90 92 99 72 99 99 99 99");
    assert_eq!(b.drive(1).unwrap().history()[..2], [90, 92]);
}

#[test]
fn events_tell_what_each_drive_did() {
    let mut b = bus(&[1, 5], 0);
    assert!(b.take_events().is_empty(), "nothing happened yet");
    assert_eq!(ask(&mut b, 0, b"1POSA 10\r"), b"\r\n>");
    assert_eq!(b.take_events(), ["drive 1 motion started to 10.000 from 0.000"]);
    assert!(b.take_events().is_empty(), "taken once");
    // 100 units/s: at rest after 100 ms, with its position.
    let mut out = Vec::new();
    b.advance(Timestamp::from_millis(150), &mut out);
    assert_eq!(b.take_events(), ["drive 1 at rest 10.000"]);
    // A move while moving is refused: the error is an event.
    assert_eq!(ask(&mut b, 200, b"5POSA 100\r"), b"\r\n>");
    assert_eq!(ask(&mut b, 210, b"5POSA 50\r"), b"E92\r\n>");
    let ev = b.take_events();
    assert_eq!(ev[0], "drive 5 motion started to 100.000 from 0.000");
    assert!(ev[1].starts_with("drive 5 error E92"), "{ev:?}");
    // Switched off while moving: switched off, then at rest where it was.
    assert_eq!(ask(&mut b, 300, b"5OUTPUT O0=0\r"), b"\r\n>");
    assert_eq!(b.take_events(), ["drive 5 switched off (O0=0)", "drive 5 at rest 10.000"]);
    // Switched off, it refuses moves; switching off again is no event.
    assert_eq!(ask(&mut b, 310, b"5POSA 1\r"), b"E90\r\n>");
    assert_eq!(ask(&mut b, 311, b"5OUTPUT O0=0\r"), b"\r\n>");
    let ev = b.take_events();
    assert_eq!(ev.len(), 1, "{ev:?}");
    assert!(ev[0].starts_with("drive 5 error E90"), "{ev:?}");
    assert_eq!(ask(&mut b, 320, b"5OUTPUT O0=1\r"), b"\r\n>");
    assert_eq!(b.take_events(), ["drive 5 switched on (O0=1)"]);
    // A broadcast move: every drive tells.
    assert_eq!(ask(&mut b, 400, b"32POSR 1\r"), b"");
    assert_eq!(
        b.take_events(),
        ["drive 1 motion started to 11.000 from 10.000", "drive 5 motion started to 11.000 from 10.000"]
    );
    b.power_cycle(Timestamp::from_millis(401));
    let ev = b.take_events();
    assert_eq!(
        ev,
        [
            "drive 1 at rest 10.100",
            "drive 1 powered on (switched on, O0=1)",
            "drive 5 at rest 10.100",
            "drive 5 powered on (switched on, O0=1)"
        ]
    );
    assert_eq!(ask(&mut b, 500, b"1POSA HOME\r"), b"\r\n>");
    assert_eq!(b.take_events(), ["drive 1 homing started from 10.100"]);
}

#[test]
fn the_user_guides_example_parameter_p003_is_modelled() {
    let mut b = bus(&[1], 0);
    assert_eq!(ask(&mut b, 0, b"1P003\r"), b"P003=0\r\n>");
    assert_eq!(ask(&mut b, 1, b"1P003=-1055.88\r"), b"\r\n>");
    assert_eq!(ask(&mut b, 2, b"1P3\r"), b"P003=-1055.88\r\n>");
    assert_eq!(b.drive(1).unwrap().param(ParamId::new(3).unwrap()), Some(-1055.88));
    // Its neighbours are not modelled.
    assert_eq!(ask(&mut b, 3, b"1P2\r"), b"E90\r\n>");
    assert_eq!(ask(&mut b, 4, b"1P4=1\r"), b"E90\r\n>");
}

#[test]
fn position_message_echo_and_no_reply() {
    let mut b = bus(&[3], 64);
    assert_eq!(ask(&mut b, 0, b"3POSA 1$\r"), b"3\r\n>");
    let mut out = Vec::new();
    b.advance(Timestamp::from_millis(100), &mut out);
    assert_eq!(out, b"3$\r\n>");
    assert_eq!(ask(&mut b, 100, b"3S1?\r"), b"33S1?\r\n>");
    assert_eq!(ask(&mut b, 100, b"3SPEED 50/\r"), b"");
    assert_eq!(b.drive(3).unwrap().move_settings().0, 50.0);
}

#[test]
fn a_command_stored_with_its_echo_is_sent_back_and_waits_for_execute() {
    let mut b = bus(&[1, 3], 0);
    // `,?`: stored as with `,` alone, and the telegram sent back in full; nothing moves yet.
    assert_eq!(ask(&mut b, 0, b"1POSA 10,?\r"), b"1POSA 10,?\r\n>");
    assert_eq!(b.drive(1).unwrap().buffered(), Some("POSA 10"));
    assert!(!b.drive(1).unwrap().is_moving());
    // The buffer holds one command: the next store replaces it (a store sent again leaves one copy).
    assert_eq!(ask(&mut b, 1, b"1POSR 5,?\r"), b"1POSR 5,?\r\n>");
    assert_eq!(ask(&mut b, 2, b"1POSR 5,?\r"), b"1POSR 5,?\r\n>");
    assert_eq!(b.drive(1).unwrap().buffered(), Some("POSR 5"));
    // `?` alone echoes and neither executes nor stores; a command the drive cannot read is echoed, not stored.
    assert_eq!(ask(&mut b, 3, b"1POSA 20?\r"), b"1POSA 20?\r\n>");
    assert_eq!(ask(&mut b, 4, b"1POSX 20,?\r"), b"1POSX 20,?\r\n>");
    assert_eq!(b.drive(1).unwrap().buffered(), Some("POSR 5"));
    // Another drive's store is its own.
    assert_eq!(ask(&mut b, 5, b"3POSA 7,?\r"), b"3POSA 7,?\r\n>");
    assert_eq!(b.drive(3).unwrap().buffered(), Some("POSA 7"));
    // `!` runs the one stored command once and empties the buffer.
    assert_eq!(ask(&mut b, 6, b"1!\r"), b"\r\n>");
    assert!(b.drive(1).unwrap().is_moving());
    assert_eq!(b.drive(1).unwrap().target(), 5.0);
    assert_eq!(b.drive(1).unwrap().buffered(), None);
    assert!(!b.drive(3).unwrap().is_moving());
}

/// A host without a BCC scanning a bus whose drives check one (P196 8 on the drives, 0 on the host): drive
/// 1 takes the `2` of "2S1" for the BCC of "1S1" and answers E72 once. What follows, "S1\r3S1\r...", is
/// addressed to no drive: the emulator, like a drive that reads its address at the start of a telegram,
/// answers none of it (it once took the `1` of each "S1" for drive 1's address and answered E72 for every
/// address asked, drives it does not have).
#[test]
fn a_telegram_that_does_not_start_with_an_address_is_no_drives() {
    let mut b = bus(&[1], 8);
    let scan: Vec<u8> = (1..=9).flat_map(|a| format!("{a}S1\r").into_bytes()).collect();
    let mut e72 = b"E72\r\n>".to_vec();
    e72.push(crate::wire::bcc(b"E72"));
    assert_eq!(String::from_utf8_lossy(&ask(&mut b, 0, &scan)), String::from_utf8_lossy(&e72), "drive 1's, once");
    // Without a BCC too: a telegram that starts with no address is skipped to its CR, whatever digits it
    // holds; an LF between telegrams is skipped by itself.
    let mut b = bus(&[1], 0);
    assert_eq!(ask(&mut b, 0, b"S1\r"), b"");
    assert_eq!(ask(&mut b, 0, b"X 1S1\r"), b"");
    assert_eq!(ask(&mut b, 0, b"\n1S1\r"), b"S001: 0.000\r\n>");
}

fn bus_of(addrs: &[u8], p196: u32, variants: &[Variant]) -> Emulator {
    let mut cfg = SimConfig::bus(addrs, p196, 9600);
    cfg.variants = variants.to_vec();
    Emulator::new(cfg).unwrap()
}

#[test]
fn a_drive_without_the_position_message_runs_the_move_and_says_nothing_when_it_ends() {
    let mut b = bus_of(&[3], 64, &[Variant::NoPositionMessage]);
    assert_eq!(ask(&mut b, 0, b"3POSA 1$\r"), b"3\r\n>", "taken (with its '$')");
    assert!(b.drive(3).unwrap().is_moving());
    let mut out = Vec::new();
    b.advance(Timestamp::from_millis(100), &mut out);
    assert!(out.is_empty(), "{out:?}");
    assert_eq!(b.drive(3).unwrap().position(), 1.0, "it ran to its end");
    assert!(!b.drive(3).unwrap().is_moving());
    // Stored and executed the same.
    assert_eq!(ask(&mut b, 200, b"3POSR 1$,\r"), b"3\r\n>");
    assert_eq!(ask(&mut b, 201, b"3!\r"), b"3\r\n>");
    b.advance(Timestamp::from_millis(400), &mut out);
    assert!(out.is_empty(), "{out:?}");
    assert_eq!(b.drive(3).unwrap().position(), 2.0);
}

#[test]
fn a_slow_drive_sends_everything_300_ms_late_in_order() {
    let mut b = bus_of(&[1, 3], 0, &[Variant::SlowReplies]);
    // Executed at once, answered 300 ms later.
    assert_eq!(ask(&mut b, 0, b"1POSA 1$\r"), b"");
    assert!(b.drive(1).unwrap().is_moving());
    assert_eq!(ask(&mut b, 5, b"3S1\r"), b"");
    let mut out = Vec::new();
    // Drive 1 reaches 1.0 at 10 ms: its '$' is due 300 ms later, after drive 3's reply.
    b.advance(Timestamp::from_millis(20), &mut out);
    assert!(!b.drive(1).unwrap().is_moving());
    b.advance(Timestamp::from_millis(299), &mut out);
    assert!(out.is_empty(), "{out:?}");
    assert_eq!(b.next_wakeup(), Some(Timestamp::from_millis(300)));
    b.advance(Timestamp::from_millis(300), &mut out);
    assert_eq!(out, b"\r\n>", "the acknowledgement");
    out.clear();
    b.advance(Timestamp::from_millis(400), &mut out);
    assert_eq!(String::from_utf8_lossy(&out), "S001: 0.000\r\n>$\r\n>");
    // A closed connection loses what was still to come.
    assert_eq!(ask(&mut b, 500, b"1S1\r"), b"");
    b.connection_closed(Timestamp::from_millis(501));
    assert_eq!(b.next_wakeup(), None);
    out.clear();
    b.advance(Timestamp::from_millis(900), &mut out);
    assert!(out.is_empty(), "{out:?}");
}

#[test]
fn a_queueing_buffer_executes_the_oldest_command_first() {
    let mut b = bus_of(&[1], 0, &[Variant::BufferQueues]);
    // A store sent twice (its echo lost, say) leaves two copies.
    assert_eq!(ask(&mut b, 0, b"1POSR 5,?\r"), b"1POSR 5,?\r\n>");
    assert_eq!(ask(&mut b, 1, b"1POSR 5,?\r"), b"1POSR 5,?\r\n>");
    assert_eq!(ask(&mut b, 2, b"1POSA 20,\r"), b"\r\n>");
    assert_eq!(b.drive(1).unwrap().buffered_all(), ["POSR 5", "POSR 5", "POSA 20"]);
    assert_eq!(ask(&mut b, 3, b"1!\r"), b"\r\n>");
    assert_eq!(b.drive(1).unwrap().target(), 5.0, "the oldest");
    let mut out = Vec::new();
    b.advance(Timestamp::from_millis(200), &mut out);
    assert_eq!(ask(&mut b, 200, b"1!\r"), b"\r\n>");
    assert_eq!(b.drive(1).unwrap().target(), 10.0, "the relative move a second time");
    b.advance(Timestamp::from_millis(400), &mut out);
    assert_eq!(b.drive(1).unwrap().buffered(), Some("POSA 20"));
    assert_eq!(ask(&mut b, 400, b"1!\r"), b"\r\n>");
    assert_eq!(ask(&mut b, 401, b"1!\r"), b"E90\r\n>", "empty");
    // It holds QUEUE_DEPTH commands; a store beyond is refused and stores nothing.
    b.power_cycle(Timestamp::from_millis(1000));
    for i in 0..QUEUE_DEPTH {
        assert_eq!(ask(&mut b, 1001 + i as u64, format!("1POSA {i},\r").as_bytes()), b"\r\n>");
    }
    assert_eq!(ask(&mut b, 1100, b"1POSA 99,\r"), b"E90\r\n>");
    assert_eq!(b.drive(1).unwrap().buffered_all().len(), QUEUE_DEPTH);
    assert_eq!(b.drive(1).unwrap().buffered(), Some("POSA 0"));
    // The default drive keeps one: the next store replaces it.
    let mut b = bus(&[1], 0);
    assert_eq!(ask(&mut b, 0, b"1POSR 5,\r"), b"\r\n>");
    assert_eq!(ask(&mut b, 1, b"1POSR 5,\r"), b"\r\n>");
    assert_eq!(b.drive(1).unwrap().buffered_all(), ["POSR 5"]);
}

/// P196 = 164 written (the manual's setting for the COMTAC fieldbus, 3.3.2) is acknowledged and read back
/// like any value; from the next power-on the drive speaks the fieldbus protocol and answers no ASCII
/// telegram, and says so. The other drive on the bus answers as before.
#[test]
fn a_drive_powered_on_with_the_fieldbus_mode_answers_no_ascii() {
    let mut b = bus(&[1, 5], 0);
    assert_eq!(ask(&mut b, 0, b"1P196=164\r"), b"\r\n>");
    assert_eq!(ask(&mut b, 1, b"1P196\r"), b"P196=164\r\n>");
    assert_eq!(ask(&mut b, 2, b"1S1\r"), b"S001: 0.000\r\n>", "at once: the mode in force is the old one");
    b.power_cycle(Timestamp::from_millis(10));
    let ev = b.take_events();
    assert!(
        ev.contains(
            &"drive 1 speaks the COMTAC fieldbus protocol (P196=164): no ASCII telegram is answered".to_string()
        ),
        "{ev:?}"
    );
    assert_eq!(ask(&mut b, 20, b"1S1\r"), b"");
    assert_eq!(ask(&mut b, 30, b"5S1\r"), b"S001: 0.000\r\n>");
    // A mode that is neither ASCII nor the fieldbus's is refused (E90) and not stored.
    assert_eq!(ask(&mut b, 40, b"5P196=166\r"), b"E90\r\n>");
    assert_eq!(ask(&mut b, 50, b"5P196\r"), b"P196=0\r\n>");
}
