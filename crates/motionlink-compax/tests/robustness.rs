//! Property tests: arbitrary bytes into the reply decoder, the request decoder and the emulator never panic,
//! and each recovers; the reply decoder finds the same in slices of any size as byte by byte.

use motionlink_compax::model::{StatusId, StatusValue};
use motionlink_compax::sim::{Emulator, SimConfig};
use motionlink_compax::wire::reply::encode_reply;
use motionlink_compax::wire::{bcc, Mode, ReplyDecoder, ReplyEvent, RequestDecoder, CR, LF, PROMPT, XOFF, XON};
use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::Emulator as _;
use proptest::prelude::*;

/// A piece of what drives send: garbage, a reply as a drive sends it (its text may hold flow control, be
/// longer than the decoder keeps, or not be ASCII), or characters that end or break replies.
#[derive(Debug, Clone)]
enum Piece {
    Bytes(Vec<u8>),
    Reply(u8, Vec<u8>),
}

fn piece() -> impl Strategy<Value = Piece> {
    let text_char = prop_oneof![8 => 0x20u8..0x7F, 1 => Just(XON), 1 => Just(XOFF), 1 => Just(LF), 1 => Just(0x80u8)];
    let special = proptest::sample::select(vec![CR, LF, PROMPT, XON, XOFF, b'$', b'1', b'E', b'S', 0]);
    prop_oneof![
        1 => proptest::collection::vec(any::<u8>(), 0..24).prop_map(Piece::Bytes),
        1 => proptest::collection::vec(special, 1..6).prop_map(Piece::Bytes),
        4 => (1u8..=31, proptest::collection::vec(text_char, 0..70)).prop_map(|(a, t)| Piece::Reply(a, t)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn decoding_slices_agrees_with_pushing_bytes(
        p196 in 0u32..=127,
        expected in proptest::option::of(1u8..=31),
        pieces in proptest::collection::vec(piece(), 0..10),
        cuts in proptest::collection::vec(1usize..24, 1..40),
    ) {
        let mode = Mode::from_p196(p196).unwrap();
        let mut wire = Vec::new();
        for p in pieces {
            match p {
                Piece::Bytes(b) => wire.extend_from_slice(&b),
                Piece::Reply(a, text) => encode_reply(&mut wire, &mode, a, &text),
            }
        }
        let (mut one, mut many) = (ReplyDecoder::new(&mode), ReplyDecoder::new(&mode));
        one.expect_from(expected);
        many.expect_from(expected);
        // Each event with the number of bytes read when it came.
        let (mut by_push, mut by_decode) = (Vec::new(), Vec::new());
        let mut at = 0;
        for cut in cuts.iter().cycle() {
            if at >= wire.len() {
                break;
            }
            let end = (at + cut).min(wire.len());
            for (i, &b) in wire[at..end].iter().enumerate() {
                if let Some(e) = one.push(b) {
                    by_push.push((at + i + 1, e));
                }
            }
            let mut chunk = &wire[at..end];
            while !chunk.is_empty() {
                let (used, event) = many.decode(chunk);
                prop_assert!((1..=chunk.len()).contains(&used), "used {} of {}", used, chunk.len());
                chunk = &chunk[used..];
                if let Some(e) = event {
                    by_decode.push((end - chunk.len(), ReplyEvent::from(e)));
                }
            }
            prop_assert_eq!(many.is_idle(), one.is_idle(), "after {} bytes", end);
            at = end;
        }
        prop_assert_eq!(many.decode(&[]).0, 0);
        prop_assert_eq!(by_decode, by_push);
    }

    #[test]
    fn reply_decoder_survives_garbage_and_recovers(p196 in 0u32..=127, garbage in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mode = Mode::from_p196(p196).unwrap();
        let mut d = ReplyDecoder::new(&mode);
        d.expect_from(Some(7));
        d.push_slice(&garbage, |_| {});
        let mut good = Vec::new();
        encode_reply(&mut good, &mode, 7, b"S001: 12.500");
        let mut last = None;
        for _ in 0..3 {
            d.push_slice(&good, |e| last = Some(e));
        }
        match last {
            Some(ReplyEvent::Reply(r)) => prop_assert_eq!(r.text(), b"S001: 12.500"),
            other => prop_assert!(false, "P196={} last event {:?}", p196, other),
        }
    }

    #[test]
    fn request_decoder_survives_garbage(p196 in 0u32..=127, garbage in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mode = Mode::from_p196(p196).unwrap();
        let mut d = RequestDecoder::new(&mode);
        for b in garbage {
            if let Some(motionlink_compax::wire::RequestEvent::Frame(f)) = d.push(b) {
                let _ = f.parse();
            }
        }
    }

    #[test]
    fn emulator_survives_garbage_and_answers_afterwards(
        p196 in 0u32..=127,
        chunks in proptest::collection::vec((proptest::collection::vec(any::<u8>(), 0..40), 0u64..20), 0..12),
    ) {
        let mode = Mode::from_p196(p196).unwrap();
        let mut bus = Emulator::new(SimConfig::bus(&[1, 12], p196, 9600)).unwrap();
        let mut out = Vec::new();
        let mut t = 0u64;
        for (bytes, gap) in chunks {
            t += gap;
            bus.receive(Timestamp::from_millis(t), &bytes, &mut out);
            bus.advance(Timestamp::from_millis(t), &mut out);
        }
        // Sixteen CRs end any telegram in progress (a binary one is at most 15 bytes, plus its BCC).
        t += 1;
        let mut recover = vec![b'\r'; 17];
        if mode.xon_xoff {
            recover.push(XON);
        }
        bus.receive(Timestamp::from_millis(t), &recover, &mut out);
        out.clear();
        let mut req = b"12S1".to_vec();
        let check = bcc(&req);
        req.push(b'\r');
        if mode.bcc {
            req.push(check);
        }
        bus.receive(Timestamp::from_millis(t + 1), &req, &mut out);
        let mut d = ReplyDecoder::new(&mode);
        d.expect_from(Some(12));
        let mut found = false;
        d.push_slice(&out, |e| if let ReplyEvent::Reply(r) = e {
            if r.text().starts_with(b"S001: ") && StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()).is_ok() {
                found = true;
            }
        });
        prop_assert!(found, "P196={} no S1 reply in {:?}", p196, String::from_utf8_lossy(&out));
    }
}

// ------------------------------------------------------------------------------------------------------
// Telegram-like input: what a host or a noisy bus sends, not only uniform random bytes. Long runs of
// address digits, real telegrams (whole, cut short, with a flipped byte), binary telegrams, flag and control
// characters.

/// A piece of what hosts send.
fn host_piece(mode: Mode) -> impl Strategy<Value = Vec<u8>> {
    let digit_run = prop_oneof![
        "[0-9]{1,200}".prop_map(String::into_bytes),
        (proptest::sample::select(vec![b'0', b'1', b'3', b'9']), 1usize..300).prop_map(|(d, n)| vec![d; n]),
    ];
    let command = proptest::sample::select(vec![
        "S1",
        "S17",
        "POSA 1.5",
        "POSR -2",
        "PR 3 OT O9=1",
        "SPEED 50",
        "ACCEL 100",
        "P194",
        "P012=-3.25",
        "OUTPUT O0=1",
        "PH",
        "NOPE",
    ]);
    let flags = proptest::sample::select(vec!["", "$", ",", "/", "?", "$,"]);
    let telegram = (1u8..=32, command, flags, proptest::option::of((0usize..20, any::<u8>())), 0usize..3).prop_map(
        move |(address, command, flags, flip, cut)| {
            let mut t = address.to_string().into_bytes();
            if command == "!" {
                t.push(b'!');
            } else {
                t.extend_from_slice(command.as_bytes());
            }
            t.extend_from_slice(flags.as_bytes());
            let check = bcc(&t);
            t.push(CR);
            if mode.bcc {
                t.push(check);
            }
            if let Some((at, xor)) = flip {
                let at = at % t.len();
                t[at] ^= xor;
            }
            let keep = t.len().saturating_sub(cut);
            t.truncate(keep);
            t
        },
    );
    let binary = (
        1u8..=32,
        proptest::sample::select(vec![0x88u8, 0x84, 0x85, 0x8C, 0x8F, 0x80, 0x81]),
        proptest::collection::vec(any::<u8>(), 0..16),
    )
        .prop_map(|(address, first, rest)| {
            let mut t = address.to_string().into_bytes();
            t.push(first);
            t.extend_from_slice(&rest);
            t
        });
    let special = proptest::collection::vec(
        proptest::sample::select(vec![CR, LF, XON, XOFF, b'!', b'$', b',', b'/', b'?', b' ', 0x80, 0x8F, 0xFF, 0]),
        1..8,
    );
    prop_oneof![
        3 => digit_run,
        4 => telegram,
        1 => binary,
        1 => special,
        1 => proptest::collection::vec(any::<u8>(), 0..24),
    ]
}

fn host_stream() -> impl Strategy<Value = (u32, Vec<Vec<u8>>)> {
    (0u32..=127).prop_flat_map(|p196| {
        let mode = Mode::from_p196(p196).unwrap();
        (Just(p196), proptest::collection::vec(host_piece(mode), 0..12))
    })
}

/// Bytes that end whatever telegram is in progress (a binary one is at most 15 bytes, plus its BCC).
fn recovery(mode: &Mode) -> Vec<u8> {
    let mut r = vec![CR; 17];
    if mode.xon_xoff {
        r.push(XON);
    }
    r
}

fn s1_request(address: u8, mode: &Mode) -> Vec<u8> {
    let mut req = format!("{address}S1").into_bytes();
    let check = bcc(&req);
    req.push(CR);
    if mode.bcc {
        req.push(check);
    }
    req
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn request_decoder_survives_telegram_like_input_and_resynchronises((p196, pieces) in host_stream()) {
        use motionlink_compax::wire::RequestEvent;
        let mode = Mode::from_p196(p196).unwrap();
        let mut d = RequestDecoder::new(&mode);
        let wire: Vec<u8> = pieces.concat();
        for &b in &wire {
            if let Some(RequestEvent::Frame(f)) = d.push(b) {
                // Every accessor the emulator and the capture decoder use.
                let _ = (f.address(), f.bytes(), f.command_bytes(), f.bcc(), f.is_binary());
                if let Ok(p) = f.parse() {
                    prop_assert!((1..=32).contains(&p.address), "{:?}", f);
                }
            }
            let _ = (d.partial_address(), d.past_address(), d.is_idle());
        }
        let mut after = recovery(&mode);
        after.extend_from_slice(&s1_request(12, &mode));
        let frames: Vec<_> = after.iter().filter_map(|&b| match d.push(b) {
            Some(RequestEvent::Frame(f)) => Some(f),
            _ => None,
        }).collect();
        let last = frames.last().expect("the good telegram is decoded");
        let p = last.parse();
        prop_assert!(p.is_ok(), "{:?} -> {:?}", last, p);
        let p = p.unwrap();
        prop_assert_eq!(p.address, 12);
        prop_assert_eq!(p.body, motionlink_compax::wire::Body::Command(b"S1"));
        prop_assert!(d.is_idle());
    }

    #[test]
    fn emulator_survives_telegram_like_input_and_answers_afterwards(
        (p196, pieces) in host_stream(),
        gaps in proptest::collection::vec(0u64..12, 12),
    ) {
        let mode = Mode::from_p196(p196).unwrap();
        let mut bus = Emulator::new(SimConfig::bus(&[1, 3, 12, 31], p196, 9600)).unwrap();
        let mut out = Vec::new();
        let mut t = 0u64;
        for (bytes, gap) in pieces.iter().zip(gaps.iter().cycle()) {
            t += gap;
            bus.receive(Timestamp::from_millis(t), bytes, &mut out);
            bus.advance(Timestamp::from_millis(t), &mut out);
        }
        // Whatever moves: let it finish (positions are small), so that nothing unsolicited follows.
        t += 60_000;
        bus.advance(Timestamp::from_millis(t), &mut out);
        bus.receive(Timestamp::from_millis(t), &recovery(&mode), &mut out);
        out.clear();
        bus.receive(Timestamp::from_millis(t + 1), &s1_request(12, &mode), &mut out);
        // Everything the drives send is decodable too.
        let mut d = ReplyDecoder::new(&mode);
        d.expect_from(Some(12));
        let mut found = false;
        d.push_slice(&out, |e| if let ReplyEvent::Reply(r) = e {
            if StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()).is_ok() {
                found = true;
            }
        });
        prop_assert!(found, "P196={} no S1 reply in {:?}", p196, String::from_utf8_lossy(&out));
    }

    #[test]
    fn reply_decoder_survives_telegram_like_input(
        (p196, pieces) in host_stream(),
        digits in "[0-9]{0,120}",
        address in 1u8..=31,
    ) {
        let mode = Mode::from_p196(p196).unwrap();
        let mut wire: Vec<u8> = pieces.concat();
        // Replies of nothing but digits (a comparator number, an address prefix) of any length.
        encode_reply(&mut wire, &mode, address, digits.as_bytes());
        let mut d = ReplyDecoder::new(&mode);
        d.expect_from(Some(address));
        d.push_slice(&wire, |e| if let ReplyEvent::Reply(r) = e {
            let _ = (r.kind(), r.text_str(), r.address(), r.line());
        });
        // Empty replies end whatever was in progress, in every mode (in CR + BCC mode a bare CR is a whole
        // reply and the next byte its BCC, so CRs alone would not do).
        let mut good = Vec::new();
        for _ in 0..3 {
            encode_reply(&mut good, &mode, 7, b"");
        }
        encode_reply(&mut good, &mode, 7, b"S001: 12.500");
        d.expect_from(Some(7));
        let mut last = None;
        d.push_slice(&good, |e| last = Some(e));
        match last {
            Some(ReplyEvent::Reply(r)) => prop_assert_eq!(r.text(), b"S001: 12.500"),
            other => prop_assert!(false, "P196={} last event {:?}", p196, other),
        }
    }

    #[test]
    fn status_and_parameter_replies_of_any_text(
        id in 1u8..=40,
        param in 1u16..=250,
        text in prop_oneof![
            any::<String>(),
            "\\PC{0,60}",
            ("S0[0-4][0-9]: ", "[a-zé€😀0-9 .-]{0,60}").prop_map(|(a, b)| a + &b),
            ("P[0-2][0-9][0-9][=:] ?", "[é€0-9 .-]{0,60}").prop_map(|(a, b)| a + &b),
        ],
        bytes in proptest::collection::vec(any::<u8>(), 0..80),
    ) {
        let id = StatusId::new(id).unwrap();
        let pid = motionlink_compax::model::ParamId::new(param).unwrap();
        for input in [text.as_bytes(), &bytes[..]] {
            if let Ok(StatusValue::Text(t)) = StatusValue::parse(id, input) {
                // A text value keeps as much of the reply as fits its 48 bytes, whole characters only.
                let s = std::str::from_utf8(input).unwrap();
                prop_assert!(t.as_str().len() <= 48);
                let rest = s.trim_matches(' ');
                prop_assert!(rest.contains(t.as_str()), "{:?} not in {:?}", t.as_str(), s);
                prop_assert!(t.as_str().len() + 4 > 48 || rest.ends_with(t.as_str()), "{:?} from {:?}", t.as_str(), s);
            }
            let _ = motionlink_compax::model::parse_param_reply(pid, input);
        }
    }
}
