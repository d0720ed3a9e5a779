//! Tests of the request codec.

use super::*;

fn req(addr: u8, body: Body<'_>, flags: Flags) -> Request<'_> {
    Request { address: Address::new(addr).unwrap(), body, flags }
}

fn decode_all(mode: &Mode, bytes: &[u8]) -> Vec<RequestEvent> {
    let mut d = RequestDecoder::new(mode);
    bytes.iter().filter_map(|&b| d.push(b)).collect()
}

/// Chapter 4.5: "1S1" and "5S1", printed with a concluding CR, then (4.5.1) the BCC as a character.
#[test]
fn the_manuals_basic_routine() {
    let plain = Mode::default();
    let with_bcc = Mode::from_p196(8).unwrap();
    let s1 = |a| req(a, Body::Command(b"S1"), Flags::NONE);
    assert_eq!(s1(1).encode(&plain).unwrap().as_bytes(), b"1S1\r");
    assert_eq!(s1(5).encode(&plain).unwrap().as_bytes(), b"5S1\r");
    assert_eq!(s1(1).encode(&with_bcc).unwrap().as_bytes(), b"1S1\r\x53");
    assert_eq!(s1(5).encode(&with_bcc).unwrap().as_bytes(), b"5S1\r\x57");
}

#[test]
fn flags_execute_and_broadcast() {
    let m = Mode::default();
    let all = Flags { position_message: true, buffer: true, no_reply: true, echo: true };
    assert_eq!(req(12, Body::Command(b"POSA 100"), all).encode(&m).unwrap().as_bytes(), b"12POSA 100$,/?\r");
    assert_eq!(req(32, Body::Execute, Flags::NONE).encode(&m).unwrap().as_bytes(), b"32!\r");
    assert!(!req(32, Body::Execute, Flags::NONE).expects_reply());
    assert!(!req(3, Body::Command(b"S1"), Flags { no_reply: true, ..Flags::NONE }).expects_reply());
    assert!(req(3, Body::Command(b"S1"), Flags::NONE).expects_reply());
    assert!(req(1, Body::Execute, Flags { buffer: true, ..Flags::NONE }).encode(&m).is_err());
}

#[test]
fn binary_request_with_and_without_bcc() {
    let posa = BinaryCommand::PosA(crate::wire::Fixed24::from_f64(360.0).unwrap());
    let r = req(1, Body::Binary(posa), Flags::NONE);
    let want = [b'1', 0x88, 0x41, 0, 0, 0, 0x68, 0x01, 0];
    assert_eq!(r.encode(&Mode::default()).unwrap().as_bytes(), want);
    let mut with = want.to_vec();
    with.push(bcc(&want));
    assert_eq!(r.encode(&Mode::from_p196(8).unwrap()).unwrap().as_bytes(), &with[..]);
    assert!(req(1, Body::Binary(posa), Flags { echo: true, ..Flags::NONE }).encode(&Mode::default()).is_err());
}

#[test]
fn bad_commands_are_refused() {
    let m = Mode::default();
    let long = [b'A'; 41];
    assert_eq!(req(1, Body::Command(&long), Flags::NONE).encode(&m), Err(WireError::TooLong(41)));
    assert_eq!(req(1, Body::Command(&long[..40]), Flags::NONE).encode(&m).unwrap().len(), 42);
    let forty_with_flag = Flags { buffer: true, ..Flags::NONE };
    assert!(req(1, Body::Command(&long[..40]), forty_with_flag).encode(&m).is_err());
    assert_eq!(req(1, Body::Command(b"S\r1"), Flags::NONE).encode(&m), Err(WireError::BadChar(CR)));
    assert!(req(1, Body::Command(b"5S1"), Flags::NONE).encode(&m).is_err());
    assert!(req(1, Body::Command(b""), Flags::NONE).encode(&m).is_err());
    assert!(req(1, Body::Command(b"S1?"), Flags::NONE).encode(&m).is_err());
}

#[test]
fn decoder_splits_ascii_binary_and_garbage() {
    let m = Mode::from_p196(8).unwrap();
    let mut stream = b"xx\n".to_vec();
    stream.extend_from_slice(b"1S1\rS");
    stream.extend_from_slice(b"5S1\r\x00"); // wrong BCC
    let bin = req(7, Body::Binary(BinaryCommand::Accel(500)), Flags::NONE).encode(&m).unwrap();
    stream.extend_from_slice(bin.as_bytes());
    let ev = decode_all(&m, &stream);
    assert_eq!(ev.len(), 6, "{ev:?}");
    assert!(matches!(ev[0], RequestEvent::Garbage(b'x')));
    let RequestEvent::Frame(f) = ev[3] else { panic!("{ev:?}") };
    let p = f.parse().unwrap();
    assert_eq!((p.address, p.body, p.flags), (1, Body::Command(b"S1"), Flags::NONE));
    let RequestEvent::Frame(f) = ev[4] else { panic!("{ev:?}") };
    assert_eq!(f.parse(), Err(RequestError::Bcc { received: 0, computed: 0x57 }));
    let RequestEvent::Frame(f) = ev[5] else { panic!("{ev:?}") };
    assert!(f.is_binary());
    assert_eq!(f.parse().unwrap().body, Body::Binary(BinaryCommand::Accel(500)));
}

#[test]
fn decoder_reports_overflow_and_flow_control() {
    let m = Mode::from_p196(1).unwrap();
    let mut t = b"3".to_vec();
    t.extend_from_slice(&[b'A'; 45]);
    t.push(CR);
    let ev = decode_all(&m, &t);
    let RequestEvent::Frame(f) = ev[0] else { panic!() };
    assert_eq!(f.parse(), Err(RequestError::Overflow(45)));
    let ev = decode_all(&m, b"\x132S1\x11\r");
    assert_eq!(ev[0], RequestEvent::Flow(true));
    assert_eq!(ev[1], RequestEvent::Flow(false));
    let RequestEvent::Frame(f) = ev[2] else { panic!() };
    assert_eq!(f.parse().unwrap().body, Body::Command(b"S1"));
}

#[test]
fn an_address_longer_than_any_is_an_error_and_the_next_telegram_decodes() {
    for mode in [Mode::default(), Mode::from_p196(8 + 16).unwrap()] {
        for digits in [3usize, 59, 60, 61, 64, 65, 200, 5000] {
            let mut t = vec![b'1'; digits];
            t.extend_from_slice(b"S1");
            let check = bcc(&t);
            t.push(CR);
            if mode.bcc {
                t.push(check);
            }
            let mut d = RequestDecoder::new(&mode);
            let mut events = Vec::new();
            for (i, &b) in t.iter().enumerate() {
                events.extend(d.push(b));
                // What the emulator asks while a telegram comes in: no drive's address once it is too long.
                let want = match (d.is_idle(), (i + 1).min(digits)) {
                    (true, _) => 0,
                    (false, 1) => 1,
                    (false, 2) => 11,
                    _ => 0,
                };
                assert_eq!(d.partial_address(), want, "{digits} digits, byte {i}");
            }
            let [RequestEvent::Frame(f)] = events[..] else { panic!("{digits}: {events:?}") };
            assert_eq!(f.parse(), Err(RequestError::AddressTooLong(digits)), "{digits} digits");
            assert_eq!(f.address(), 0);
            assert_eq!(f.address_digits(), digits);
            assert_eq!(f.command_bytes(), b"S1");
            // The BCC covers every digit received, kept or not.
            if mode.bcc {
                let (received, computed) = f.bcc().unwrap();
                assert_eq!(received, computed);
            }
            assert!(d.is_idle());
            let good = req(5, Body::Command(b"S1"), Flags::NONE).encode(&mode).unwrap();
            let ev: Vec<_> = good.as_bytes().iter().filter_map(|&b| d.push(b)).collect();
            let [RequestEvent::Frame(f)] = ev[..] else { panic!("{ev:?}") };
            assert_eq!(f.parse().unwrap().address, 5);
        }
    }
}

#[test]
fn an_overflowing_telegram_with_a_good_bcc_is_an_overflow_not_a_bcc_error() {
    // The drive answers E71 for more than 40 characters; the BCC over all of them is right.
    let m = Mode::from_p196(8).unwrap();
    let mut t = b"4".to_vec();
    t.extend_from_slice(&[b'A'; 70]);
    let check = bcc(&t);
    t.push(CR);
    t.push(check);
    let ev = decode_all(&m, &t);
    let [RequestEvent::Frame(f)] = ev[..] else { panic!("{ev:?}") };
    assert_eq!(f.parse(), Err(RequestError::Overflow(70)));
    let mut bad = t.clone();
    *bad.last_mut().unwrap() ^= 1;
    let ev = decode_all(&m, &bad);
    let [RequestEvent::Frame(f)] = ev[..] else { panic!("{ev:?}") };
    assert!(matches!(f.parse(), Err(RequestError::Bcc { .. })));
}

#[test]
fn decoder_parses_flags_in_any_order_and_execute() {
    let m = Mode::default();
    let ev = decode_all(&m, b"4POSA1000$\r4PR 5/,\r32!\r1!?\r");
    let parsed: Vec<_> = ev
        .iter()
        .map(|e| match e {
            RequestEvent::Frame(f) => {
                let p = f.parse().unwrap();
                (p.address, format!("{:?}", p.body), p.flags)
            }
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(parsed[0].2, Flags { position_message: true, ..Flags::NONE });
    assert_eq!(parsed[1].2, Flags { buffer: true, no_reply: true, ..Flags::NONE });
    assert_eq!(parsed[2].1, "Execute");
    assert_eq!(parsed[2].0, 32);
    assert_eq!(parsed[3].2, Flags { echo: true, ..Flags::NONE });
}

/// A command telegram as it was built before the single-pass copy: every check in its order, every byte
/// pushed with a check of the room.
fn reference(req: &Request<'_>, mode: &Mode) -> Result<Vec<u8>, WireError> {
    let Body::Command(text) = req.body else { unreachable!() };
    if text.is_empty() {
        return Err(WireError::Flags("empty command"));
    }
    if let Some(&c) = text.iter().find(|&&c| !(0x20..=0x7E).contains(&c)) {
        return Err(WireError::BadChar(c));
    }
    if text[0].is_ascii_digit() || text[0] & 0x80 != 0 {
        return Err(WireError::Flags("a command cannot start with a digit (it would extend the address)"));
    }
    if !Flags::split(text).1.is_none() {
        return Err(WireError::Flags("the command text ends with a flag character; use the flags"));
    }
    let len = text.len() + req.flags.count();
    if len > MAX_COMMAND_LEN {
        return Err(WireError::TooLong(len));
    }
    let (digits, n) = req.address.digits();
    let mut f = Frame::default();
    f.extend(&digits[..n])?;
    f.extend(text)?;
    for (on, c) in [
        (req.flags.position_message, POSITION_MESSAGE),
        (req.flags.buffer, BUFFER),
        (req.flags.no_reply, NO_REPLY),
        (req.flags.echo, ECHO),
    ] {
        if on {
            f.push(c)?;
        }
    }
    f.push(CR)?;
    if mode.bcc {
        f.push(bcc(&f.as_bytes()[..f.len() - 1]))?;
    }
    Ok(f.as_bytes().to_vec())
}

#[test]
fn addresses_as_digits() {
    for a in 1..=BROADCAST {
        let text = a.to_string();
        let (digits, n) = Address::new(a).unwrap().digits();
        assert_eq!(&digits[..n], text.as_bytes());
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 2000, ..Default::default() })]

    #[test]
    fn command_telegrams_are_built_as_before(
        address in 1u8..=BROADCAST,
        p196 in 0u32..=Mode::MAX_P196,
        flags in proptest::array::uniform4(proptest::bool::ANY),
        text in proptest::collection::vec(
            proptest::prop_oneof![
                6 => 0x20u8..0x7F,
                1 => proptest::sample::select(vec![b'$', b',', b'/', b'?', b'0', b'9', CR, 0x7F, 0x80, 0]),
            ],
            0..46,
        ),
    ) {
        let mode = Mode::from_p196(p196).unwrap();
        let flags = Flags { position_message: flags[0], buffer: flags[1], no_reply: flags[2], echo: flags[3] };
        let r = req(address, Body::Command(&text), flags);
        let expected = reference(&r, &mode);
        proptest::prop_assert_eq!(r.encode(&mode).map(|f| f.as_bytes().to_vec()), expected.clone());
        // In place, over whatever the frame held.
        let mut frame = req(1, Body::Command(b"POSA 12345.678"), Flags::NONE).encode(&mode).unwrap();
        let result = r.encode_into(&mode, &mut frame);
        proptest::prop_assert_eq!(result.map(|()| frame.as_bytes().to_vec()), expected.clone());
        if expected.is_err() {
            proptest::prop_assert!(frame.is_empty());
        }
    }
}
