//! Property tests: arbitrary bytes into the reply decoder, the request decoder and the emulator never panic,
//! and each recovers; the reply decoder finds the same in slices of any size as byte by byte.

use motionlink_compax::model::{StatusId, StatusValue};
use motionlink_compax::sim::{CompaxBus, SimConfig};
use motionlink_compax::wire::reply::encode_reply;
use motionlink_compax::wire::{bcc, Mode, ReplyDecoder, ReplyEvent, RequestDecoder, CR, LF, PROMPT, XOFF, XON};
use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::Emulator;
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
        let mut bus = CompaxBus::new(SimConfig::bus(&[1, 12], p196, 9600)).unwrap();
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
