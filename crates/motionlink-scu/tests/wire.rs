//! Wire tests: the telegrams of both manuals' chapter 5 example, the CRC, error replies, resynchronisation.
//! The expected CRC bytes were computed independently, bit by bit, from the polynomial.

use motionlink_scu::wire::*;
use proptest::prelude::*;

/// The manual's CRC_TABLE (chapter 6, code example 1), as printed in the Schaeffler edition.
const MANUAL_CRC_TABLE: [u16; 256] = [
    0x0000, 0x1021, 0x2042, 0x3063, 0x4084, 0x50A5, 0x60C6, 0x70E7, 0x8108, 0x9129, 0xA14A, 0xB16B, 0xC18C, 0xD1AD,
    0xE1CE, 0xF1EF, 0x1231, 0x0210, 0x3273, 0x2252, 0x52B5, 0x4294, 0x72F7, 0x62D6, 0x9339, 0x8318, 0xB37B, 0xA35A,
    0xD3BD, 0xC39C, 0xF3FF, 0xE3DE, 0x2462, 0x3443, 0x0420, 0x1401, 0x64E6, 0x74C7, 0x44A4, 0x5485, 0xA56A, 0xB54B,
    0x8528, 0x9509, 0xE5EE, 0xF5CF, 0xC5AC, 0xD58D, 0x3653, 0x2672, 0x1611, 0x0630, 0x76D7, 0x66F6, 0x5695, 0x46B4,
    0xB75B, 0xA77A, 0x9719, 0x8738, 0xF7DF, 0xE7FE, 0xD79D, 0xC7BC, 0x48C4, 0x58E5, 0x6886, 0x78A7, 0x0840, 0x1861,
    0x2802, 0x3823, 0xC9CC, 0xD9ED, 0xE98E, 0xF9AF, 0x8948, 0x9969, 0xA90A, 0xB92B, 0x5AF5, 0x4AD4, 0x7AB7, 0x6A96,
    0x1A71, 0x0A50, 0x3A33, 0x2A12, 0xDBFD, 0xCBDC, 0xFBBF, 0xEB9E, 0x9B79, 0x8B58, 0xBB3B, 0xAB1A, 0x6CA6, 0x7C87,
    0x4CE4, 0x5CC5, 0x2C22, 0x3C03, 0x0C60, 0x1C41, 0xEDAE, 0xFD8F, 0xCDEC, 0xDDCD, 0xAD2A, 0xBD0B, 0x8D68, 0x9D49,
    0x7E97, 0x6EB6, 0x5ED5, 0x4EF4, 0x3E13, 0x2E32, 0x1E51, 0x0E70, 0xFF9F, 0xEFBE, 0xDFDD, 0xCFFC, 0xBF1B, 0xAF3A,
    0x9F59, 0x8F78, 0x9188, 0x81A9, 0xB1CA, 0xA1EB, 0xD10C, 0xC12D, 0xF14E, 0xE16F, 0x1080, 0x00A1, 0x30C2, 0x20E3,
    0x5004, 0x4025, 0x7046, 0x6067, 0x83B9, 0x9398, 0xA3FB, 0xB3DA, 0xC33D, 0xD31C, 0xE37F, 0xF35E, 0x02B1, 0x1290,
    0x22F3, 0x32D2, 0x4235, 0x5214, 0x6277, 0x7256, 0xB5EA, 0xA5CB, 0x95A8, 0x8589, 0xF56E, 0xE54F, 0xD52C, 0xC50D,
    0x34E2, 0x24C3, 0x14A0, 0x0481, 0x7466, 0x6447, 0x5424, 0x4405, 0xA7DB, 0xB7FA, 0x8799, 0x97B8, 0xE75F, 0xF77E,
    0xC71D, 0xD73C, 0x26D3, 0x36F2, 0x0691, 0x16B0, 0x6657, 0x7676, 0x4615, 0x5634, 0xD94C, 0xC96D, 0xF90E, 0xE92F,
    0x99C8, 0x89E9, 0xB98A, 0xA9AB, 0x5844, 0x4865, 0x7806, 0x6827, 0x18C0, 0x08E1, 0x3882, 0x28A3, 0xCB7D, 0xDB5C,
    0xEB3F, 0xFB1E, 0x8BF9, 0x9BD8, 0xABBB, 0xBB9A, 0x4A75, 0x5A54, 0x6A37, 0x7A16, 0x0AF1, 0x1AD0, 0x2AB3, 0x3A92,
    0xFD2E, 0xED0F, 0xDD6C, 0xCD4D, 0xBDAA, 0xAD8B, 0x9DE8, 0x8DC9, 0x7C26, 0x6C07, 0x5C64, 0x4C45, 0x3CA2, 0x2C83,
    0x1CE0, 0x0CC1, 0xEF1F, 0xFF3E, 0xCF5D, 0xDF7C, 0xAF9B, 0xBFBA, 0x8FD9, 0x9FF8, 0x6E17, 0x7E36, 0x4E55, 0x5E74,
    0x2E93, 0x3EB2, 0x0ED1, 0x1EF0,
];

/// The manual's CalculateChecksum (code example 3), for comparison.
fn manual_checksum(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &b in bytes {
        crc = MANUAL_CRC_TABLE[usize::from(((crc >> 8) as u8) ^ b)] ^ (crc << 8);
    }
    crc
}

fn encode(r: &Request<'_>) -> Vec<u8> {
    request_to_vec(r).unwrap()
}

fn decode_requests(bytes: &[u8]) -> Vec<Result<String, WireError>> {
    let mut dec = RequestDecoder::new();
    let mut out = Vec::new();
    let mut input = bytes;
    loop {
        let (n, ev) = dec.decode(input);
        input = &input[n..];
        match ev {
            Some(ev) => out.push(ev.map(|i| format!("{i:?}"))),
            None if input.is_empty() => break,
            None => {}
        }
    }
    out
}

/// A decoded reply: command, status, data.
type Decoded = Result<(Command, Status, Option<Vec<u8>>), WireError>;

fn decode_replies(dec: &mut ReplyDecoder, bytes: &[u8]) -> Vec<Decoded> {
    let mut out = Vec::new();
    let mut input = bytes;
    loop {
        let (n, ev) = dec.decode(input);
        input = &input[n..];
        match ev {
            Some(ev) => out.push(ev.map(|r| (r.command, r.status, r.data.map(<[u8]>::to_vec)))),
            None if input.is_empty() => break,
            None => {}
        }
    }
    out
}

#[test]
fn crc_check_value_is_0x31c3() {
    assert_eq!(crc16(b"123456789"), 0x31C3);
}

#[test]
fn crc_matches_the_crc_crate_for_every_length_and_offset() {
    let reference = crc::Crc::<u16>::new(&crc::CRC_16_XMODEM);
    let sample: Vec<u8> = (0..700u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
    for start in 0..17 {
        for end in start..sample.len() {
            assert_eq!(crc16(&sample[start..end]), reference.checksum(&sample[start..end]), "{start}..{end}");
        }
    }
}

#[test]
fn crc_matches_the_manual_table_and_its_algorithm() {
    for b in 0..=255u8 {
        assert_eq!(crc16(&[b]), MANUAL_CRC_TABLE[usize::from(b)], "table entry {b}");
    }
    let sample: Vec<u8> = (0..300u32).map(|i| (i * 31 + 7) as u8).collect();
    for len in 0..sample.len() {
        assert_eq!(crc16(&sample[..len]), manual_checksum(&sample[..len]));
    }
}

#[test]
fn a_received_telegram_checks_to_zero_with_c2_then_c1_appended() {
    // The manual's CheckResponseChecksum appends crcByte2 then crcByte1 and expects 0.
    let t = encode(&Request::Get { index: 0x0011 });
    let (body, c) = t.split_at(t.len() - 2);
    let mut check = body.to_vec();
    check.extend_from_slice(&[c[1], c[0]]);
    assert_eq!(manual_checksum(&check), 0);
}

// Chapter 5, "Move to position and read current position with SCP11 parameterization", tables 8..13.

#[test]
fn chapter5_ro_with_safety_id_0() {
    assert_eq!(encode(&Request::Open { safety_id: 0 }), [0x52, 0x4F, 0x00, 0x5C, 0x2D]);
}

#[test]
fn chapter5_rc_without_cyclic_object() {
    // "RC 01 00 -1": ctp 1, index -1.
    assert_eq!(encode(&Request::Cyclic { object: 0xFF, write: &[] }), [0x52, 0x43, 0x01, 0x00, 0xFF, 0x31, 0x8D]);
}

#[test]
fn chapter5_rt_remote_speed_f1_writes_the_value_1() {
    // "RT 04 00 11 30 01 00": the caption says 100h, the bytes (little-endian) say 1. The bytes are the truth.
    let t = encode(&Request::Transfer { index: 0x3011, data: &1u16.to_le_bytes() });
    assert_eq!(t, [0x52, 0x54, 0x04, 0x00, 0x11, 0x30, 0x01, 0x00, 0xB5, 0xF2]);
}

#[test]
fn chapter5_re_function_1_to_remote_position() {
    // "RE 00 09 -1".
    let t = encode(&Request::Execute { function: 0, params: [9, 0xFF] });
    assert_eq!(t, [0x52, 0x45, 0x00, 0x09, 0xFF, 0x00, 0x27]);
}

#[test]
fn chapter5_rg_status_and_position_of_actuator_1() {
    assert_eq!(encode(&Request::Get { index: 0x0171 }), [0x52, 0x47, 0x71, 0x01, 0x27, 0x2B]);
    assert_eq!(encode(&Request::Get { index: 0x0011 }), [0x52, 0x47, 0x11, 0x00, 0x2C, 0x30]);
}

#[test]
fn chapter5_ra() {
    assert_eq!(encode(&Request::Abort), [0x52, 0x41, 0x38, 0x30]);
}

#[test]
fn rs_soft_stop_of_f1() {
    assert_eq!(encode(&Request::Stop { function: 0, param: 1 }), [0x52, 0x53, 0x00, 0x01, 0xEC, 0x8F]);
}

#[test]
fn an_rc_without_object_is_answered_with_the_status_alone_or_with_ctp_0_and_both_decode() {
    let request = Request::Cyclic { object: 0xFF, write: &[] };
    assert_eq!(request.reply_shape(), ReplyShape::StatusOrData);
    let status_alone = [0x52, 0x43, 0x06, 0xF7, 0x08];
    let mut with_ctp = vec![0x52, 0x43, 0x06, 0x00, 0x00];
    with_ctp.extend_from_slice(&crc16(&with_ctp).to_le_bytes());
    // The first five bytes of the ctp form never pass as the status alone: their CRC does not check.
    assert_ne!(crc16(&with_ctp[..5]), 0);
    for (reply, data) in [(&status_alone[..], None), (&with_ctp[..], Some(vec![]))] {
        let mut dec = ReplyDecoder::new();
        dec.expect_len(Command::Cyclic, ReplyShape::StatusOrData, 0);
        // Whole, and byte by byte.
        assert_eq!(decode_replies(&mut dec, reply), [Ok((Command::Cyclic, Status::Ack, data.clone()))]);
        dec.expect_len(Command::Cyclic, ReplyShape::StatusOrData, 0);
        let mut got = Vec::new();
        for b in reply {
            got.extend(decode_replies(&mut dec, std::slice::from_ref(b)));
        }
        assert_eq!(got, [Ok((Command::Cyclic, Status::Ack, data))]);
    }
    // An error reply is the status alone in either case.
    let mut dec = ReplyDecoder::new();
    dec.expect(Command::Cyclic, ReplyShape::StatusOrData);
    let mut pe = vec![0x52, 0x43, 0x84];
    pe.extend_from_slice(&crc16(&pe).to_le_bytes());
    assert_eq!(decode_replies(&mut dec, &pe), [Ok((Command::Cyclic, Status::PermissionError, None))]);
}

#[test]
fn chapter5_replies_decode() {
    let mut dec = ReplyDecoder::new();
    // RO ACK.
    assert_eq!(decode_replies(&mut dec, &[0x52, 0x4F, 0x06, 0x9A, 0x4D]), [Ok((Command::Open, Status::Ack, None))]);
    // RC ACK without data (no cyclic object), as the manual's example shows.
    dec.expect(Command::Cyclic, ReplyShape::StatusOnly);
    assert_eq!(decode_replies(&mut dec, &[0x52, 0x43, 0x06, 0xF7, 0x08]), [Ok((Command::Cyclic, Status::Ack, None))]);
    // RG 0x0171: ACK 01 00 status (bits 0, 4 and 7: available, moving, stroke done).
    dec.expect(Command::Get, ReplyShape::WithData);
    assert_eq!(
        decode_replies(&mut dec, &[0x52, 0x47, 0x06, 0x01, 0x00, 0x91, 0x59, 0x0E]),
        [Ok((Command::Get, Status::Ack, Some(vec![0x91])))]
    );
    // RG 0x0011: ACK 04 00 and the position, 400 counts.
    assert_eq!(
        decode_replies(&mut dec, &[0x52, 0x47, 0x06, 0x04, 0x00, 0x90, 0x01, 0x00, 0x00, 0xA3, 0xAD]),
        [Ok((Command::Get, Status::Ack, Some(400i32.to_le_bytes().to_vec())))]
    );
}

#[test]
fn chapter5_acks_of_rt_re_rs_ra_byte_for_byte() {
    // The manual gives these replies as "ACK" only: the bytes are command, 0x06 and the CRC-16/XMODEM of the
    // three (computed independently of this codec), low byte first as in the manual's replies.
    let acks: [(Command, [u8; 5]); 4] = [
        (Command::Transfer, [0x52, 0x54, 0x06, 0x13, 0x92]),
        (Command::Execute, [0x52, 0x45, 0x06, 0x51, 0xA2]),
        (Command::Stop, [0x52, 0x53, 0x06, 0x84, 0x0B]),
        (Command::Abort, [0x52, 0x41, 0x06, 0x95, 0x6E]),
    ];
    for (command, bytes) in acks {
        assert_eq!(reply_to_vec(&Reply::status_only(command, Status::Ack)).unwrap(), bytes, "{command}");
        let mut dec = ReplyDecoder::new();
        dec.expect(command, ReplyShape::StatusOnly);
        assert_eq!(decode_replies(&mut dec, &bytes), [Ok((command, Status::Ack, None))], "{command}");
    }
}

#[test]
fn replies_encode_to_the_same_bytes() {
    let v = reply_to_vec(&Reply::with_data(Command::Get, &400i32.to_le_bytes())).unwrap();
    assert_eq!(v, [0x52, 0x47, 0x06, 0x04, 0x00, 0x90, 0x01, 0x00, 0x00, 0xA3, 0xAD]);
    assert_eq!(reply_to_vec(&Reply::status_only(Command::Open, Status::Ack)).unwrap(), [0x52, 0x4F, 0x06, 0x9A, 0x4D]);
}

#[test]
fn error_replies_have_no_data_even_for_rg() {
    let mut dec = ReplyDecoder::new();
    dec.expect(Command::Get, ReplyShape::WithData);
    // RG refused with PE: status alone.
    assert_eq!(
        decode_replies(&mut dec, &[0x52, 0x47, 0x84, 0xF9, 0x75]),
        [Ok((Command::Get, Status::PermissionError, None))]
    );
    for status in Status::ALL {
        let t = reply_to_vec(&Reply::status_only(Command::Transfer, status)).unwrap();
        assert_eq!(t.len(), 5);
        assert_eq!(t[2], status.code());
        assert_eq!(Status::from_code(status.code()), Some(status));
    }
    assert_eq!(Status::ALL.map(Status::code), [0x06, 0x80, 0x81, 0x82, 0x83, 0x84]);
}

#[test]
fn every_request_round_trips_through_the_request_decoder() {
    let write = [1u8, 2, 3, 4];
    let requests = [
        Request::Open { safety_id: 2 },
        Request::Abort,
        Request::Cyclic { object: 0xFF, write: &[] },
        Request::Cyclic { object: 0, write: &write },
        Request::Get { index: 0x2000 },
        Request::Transfer { index: 0x3021, data: &write },
        Request::Execute { function: 19, params: [0xFF, 0xFF] },
        Request::Stop { function: 3, param: 0 },
    ];
    let mut stream = Vec::new();
    for r in &requests {
        stream.extend(encode(r));
    }
    let decoded = decode_requests(&stream);
    let expected: Vec<Result<String, WireError>> =
        requests.iter().map(|r| Ok(format!("{:?}", Incoming::Request(*r)))).collect();
    assert_eq!(decoded, expected);
}

#[test]
fn a_corrupt_request_is_a_checksum_error_and_the_next_one_decodes() {
    let mut stream = encode(&Request::Get { index: 0x0011 });
    stream[2] ^= 0x01;
    stream.extend(encode(&Request::Abort));
    let decoded = decode_requests(&stream);
    assert!(matches!(decoded[0], Err(WireError::Checksum { command: Some(Command::Get), .. })), "{decoded:?}");
    assert_eq!(decoded.last(), Some(&Ok(format!("{:?}", Incoming::Request(Request::Abort)))));
}

#[test]
fn an_unknown_command_ends_where_its_crc_matches() {
    let mut t = b"RX\x01\x02".to_vec();
    let crc = crc16(&t);
    t.extend_from_slice(&crc.to_le_bytes());
    t.extend(encode(&Request::Abort));
    let decoded = decode_requests(&t);
    assert_eq!(decoded[0], Ok(format!("{:?}", Incoming::UnknownCommand { code: *b"RX" })));
    assert_eq!(decoded[1], Ok(format!("{:?}", Incoming::Request(Request::Abort))));
}

#[test]
fn garbage_before_a_request_is_reported_and_skipped() {
    let mut t = vec![0x00, 0xFF, b'x'];
    t.extend(encode(&Request::Open { safety_id: 1 }));
    let decoded = decode_requests(&t);
    assert_eq!(decoded[0], Err(WireError::Garbage { count: 3 }));
    assert_eq!(decoded[1], Ok(format!("{:?}", Incoming::Request(Request::Open { safety_id: 1 }))));
}

#[test]
fn an_oversized_ctp_is_an_error_not_a_hang() {
    let t = [b'R', b'T', 0xFF, 0xFF, 0x11, 0x30];
    let decoded = decode_requests(&t);
    assert!(matches!(decoded[0], Err(WireError::Oversized { command: Command::Transfer, .. })), "{decoded:?}");
}

#[test]
fn replies_split_in_single_bytes_decode_the_same() {
    let t = reply_to_vec(&Reply::with_data(Command::Get, &[1, 2, 3, 4, 5])).unwrap();
    let mut dec = ReplyDecoder::new();
    let mut got = Vec::new();
    for b in &t {
        got.extend(decode_replies(&mut dec, std::slice::from_ref(b)));
    }
    assert_eq!(got, [Ok((Command::Get, Status::Ack, Some(vec![1, 2, 3, 4, 5])))]);
}

#[test]
fn a_reply_decoder_expecting_rg_skips_a_stale_re_reply() {
    let mut stream = reply_to_vec(&Reply::status_only(Command::Execute, Status::Ack)).unwrap();
    stream.extend(reply_to_vec(&Reply::with_data(Command::Get, &[7])).unwrap());
    let mut dec = ReplyDecoder::new();
    dec.expect(Command::Get, ReplyShape::WithData);
    let got = decode_replies(&mut dec, &stream);
    assert_eq!(got.last(), Some(&Ok((Command::Get, Status::Ack, Some(vec![7])))));
    assert!(got[..got.len() - 1].iter().all(|e| matches!(e, Err(WireError::Garbage { .. }))));
}

#[test]
fn without_expectation_an_rc_reply_is_told_apart_by_its_crc() {
    let short = reply_to_vec(&Reply::status_only(Command::Cyclic, Status::Ack)).unwrap();
    let long = reply_to_vec(&Reply::with_data(Command::Cyclic, &[9, 8, 7])).unwrap();
    let mut stream = short.clone();
    stream.extend(&long);
    let mut dec = ReplyDecoder::new();
    assert_eq!(
        decode_replies(&mut dec, &stream),
        [Ok((Command::Cyclic, Status::Ack, None)), Ok((Command::Cyclic, Status::Ack, Some(vec![9, 8, 7])))]
    );
}

#[test]
fn encode_refuses_a_small_buffer_and_too_much_data() {
    let mut small = [0u8; 4];
    assert!(matches!(encode_request(&Request::Get { index: 1 }, &mut small), Err(EncodeError::BufferTooSmall { .. })));
    let big = [0u8; 400];
    let mut out = [0u8; 512];
    assert!(matches!(
        encode_request(&Request::Transfer { index: 0x3001, data: &big }, &mut out),
        Err(EncodeError::TooMuchData { .. })
    ));
}

proptest! {
    /// Arbitrary bytes never panic the request decoder, and a valid request sent after them is found.
    #[test]
    fn request_decoder_survives_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut stream = garbage.clone();
        // A pause (the unit's 1000 ms inter-byte limit) would reset a partial telegram; here the decoder must
        // find the request by itself after a bounded amount of junk, so repeat it.
        let ra = encode(&Request::Abort);
        for _ in 0..40 {
            stream.extend(&ra);
        }
        let decoded = decode_requests(&stream);
        let ok = format!("{:?}", Incoming::Request(Request::Abort));
        prop_assert!(decoded.iter().any(|e| e.as_ref().is_ok_and(|s| *s == ok)));
    }

    /// Arbitrary bytes never panic the reply decoder, with or without an expectation, and it recovers.
    #[test]
    fn reply_decoder_survives_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..1200), expect in 0..3u8) {
        let mut dec = ReplyDecoder::new();
        match expect {
            0 => dec.expect(Command::Get, ReplyShape::WithData),
            1 => dec.expect(Command::Cyclic, ReplyShape::StatusOnly),
            _ => dec.expect_any(),
        }
        let _ = decode_replies(&mut dec, &garbage);
        dec.reset();
        dec.expect(Command::Get, ReplyShape::WithData);
        let good = reply_to_vec(&Reply::with_data(Command::Get, &[1, 2])).unwrap();
        prop_assert_eq!(decode_replies(&mut dec, &good), vec![Ok((Command::Get, Status::Ack, Some(vec![1, 2])))]);
    }

    /// After arbitrary bytes, a stream of replies is found again without any reset: once the decoder is back
    /// in step, every following reply decodes.
    #[test]
    fn reply_stream_recovers_without_a_reset(garbage in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut dec = ReplyDecoder::new();
        dec.expect_any();
        let good = reply_to_vec(&Reply::with_data(Command::Get, &[1, 2])).unwrap();
        let mut stream = garbage.clone();
        // Enough copies to outlast the longest telegram the garbage could seem to start.
        let copies = MAX_REPLY_LEN / good.len() + 20;
        for _ in 0..copies {
            stream.extend(&good);
        }
        let decoded = decode_replies(&mut dec, &stream);
        let want = Ok((Command::Get, Status::Ack, Some(vec![1, 2])));
        let last_bad = decoded.iter().rposition(|r| *r != want);
        let good_tail = decoded.len() - last_bad.map_or(0, |i| i + 1);
        prop_assert!(good_tail >= 10, "only {} good replies at the end of {:?}", good_tail, decoded);
    }

    /// Any request round-trips.
    #[test]
    fn requests_round_trip(index in any::<u16>(), data in proptest::collection::vec(any::<u8>(), 0..40), f in any::<u8>(), p in any::<[u8; 2]>()) {
        let requests = [
            Request::Get { index },
            Request::Transfer { index, data: &data },
            Request::Cyclic { object: f, write: &data },
            Request::Execute { function: f, params: p },
            Request::Stop { function: f, param: p[0] },
            Request::Open { safety_id: f },
        ];
        for r in requests {
            let decoded = decode_requests(&encode(&r));
            prop_assert_eq!(decoded, vec![Ok(format!("{:?}", Incoming::Request(r)))]);
        }
    }
}

#[test]
fn a_reply_whose_length_byte_disagrees_with_the_request_is_rejected_at_once() {
    // The manual's RG 0x0011 reply (400 counts) with its ctp corrupted to 0x84: without the expected length the
    // decoder would wait for 128 more bytes.
    let good = [0x52, 0x47, 0x06, 0x04, 0x00, 0x90, 0x01, 0x00, 0x00, 0xA3, 0xAD];
    let mut bad = good;
    bad[3] ^= 0x80;
    let mut dec = ReplyDecoder::new();
    dec.expect(Command::Get, ReplyShape::WithData);
    assert!(decode_replies(&mut dec, &bad).is_empty(), "waits for 132 data bytes");
    let mut dec = ReplyDecoder::new();
    dec.expect_len(Command::Get, ReplyShape::WithData, 4);
    let events = decode_replies(&mut dec, &bad);
    assert_eq!(
        events[0],
        Err(WireError::UnexpectedLength { command: Command::Get, ctp: 0x84, expected: 4 }),
        "{events:?}"
    );
    // The next good reply is found.
    dec.reset();
    dec.expect_len(Command::Get, ReplyShape::WithData, 4);
    assert_eq!(decode_replies(&mut dec, &good), [Ok((Command::Get, Status::Ack, Some(400i32.to_le_bytes().to_vec())))]);
    // An error status has no length byte: a PE is taken as such.
    assert_eq!(
        decode_replies(&mut dec, &[0x52, 0x47, 0x84, 0xF9, 0x75]),
        [Ok((Command::Get, Status::PermissionError, None))]
    );
}
