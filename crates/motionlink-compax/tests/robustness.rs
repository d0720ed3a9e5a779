//! Property tests: arbitrary bytes into the reply decoder, the request decoder and the emulator never panic,
//! and each recovers.

use motionlink_compax::model::{StatusId, StatusValue};
use motionlink_compax::sim::{CompaxBus, SimConfig};
use motionlink_compax::wire::reply::encode_reply;
use motionlink_compax::wire::{bcc, Mode, ReplyDecoder, ReplyEvent, RequestDecoder, XON};
use motionlink_link::clock::Timestamp;
use motionlink_link::emulator::Emulator;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

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
