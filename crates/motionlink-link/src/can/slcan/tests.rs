use super::*;

fn decode_all(bytes: &[u8]) -> Vec<Result<SlcanMessage, SlcanError>> {
    let mut d = SlcanDecoder::new();
    d.feed(bytes).collect()
}

#[test]
fn frames_encode_and_decode() {
    let frames = [
        CanFrame::new(0x0F1, &[0x01]).unwrap(),
        CanFrame::new(0x0B1, &[0x0b, 0x0e, 0, 0, 0x80, 0x3f, 0x31, 0x10]).unwrap(),
        CanFrame::new_extended(0x1234_5678, &[]).unwrap(),
        CanFrame::new_remote(0x0D1, false, 2).unwrap(),
        CanFrame::new_remote(0x100, true, 0).unwrap(),
    ];
    let expected: [&[u8]; 5] = [b"t0F1101\r", b"t0B180B0E0000803F3110\r", b"T123456780\r", b"r0D12\r", b"R000001000\r"];
    for (f, want) in frames.iter().zip(expected) {
        let mut buf = [0u8; MAX_LINE];
        let n = encode_frame(f, &mut buf);
        assert_eq!(&buf[..n], want);
        assert_eq!(decode_all(want), vec![Ok(SlcanMessage::Frame { frame: *f, timestamp_ms: None })]);
    }
}

#[test]
fn answers_commands_and_time_stamps() {
    let got = decode_all(b"\rz\rZ\r\x07S8\rO\rC\rV\rV1013\rF\rF0A\rZ1\rt0F110112AB\r");
    assert_eq!(
        got,
        vec![
            Ok(SlcanMessage::Ok),
            Ok(SlcanMessage::Sent { extended: false }),
            Ok(SlcanMessage::Sent { extended: true }),
            Ok(SlcanMessage::Bell),
            Ok(SlcanMessage::Bitrate(SlcanBitrate::M1)),
            Ok(SlcanMessage::Open),
            Ok(SlcanMessage::Close),
            Ok(SlcanMessage::Version(None)),
            Ok(SlcanMessage::Version(Some(*b"1013"))),
            Ok(SlcanMessage::Status(None)),
            Ok(SlcanMessage::Status(Some(0x0A))),
            Ok(SlcanMessage::Timestamps(true)),
            Ok(SlcanMessage::Frame { frame: CanFrame::new(0xF1, &[1]).unwrap(), timestamp_ms: Some(0x12AB) }),
        ]
    );
}

#[test]
fn malformed_lines_are_errors_and_the_next_line_decodes() {
    let mut input = Vec::new();
    input.extend_from_slice(b"t0F1\r"); // no length
    input.extend_from_slice(b"t0F1201\r"); // too few data digits
    input.extend_from_slice(b"t8001\r"); // id too large? 0x800 > 0x7FF
    input.extend_from_slice(b"S9\r");
    input.extend_from_slice(&[b'x'; 40]);
    input.push(CR);
    input.extend_from_slice(b"t0F1101\r");
    let got = decode_all(&input);
    assert_eq!(got.len(), 6);
    assert!(got[..5].iter().all(Result::is_err), "{got:?}");
    assert_eq!(got[4], Err(SlcanError::TooLong));
    assert!(matches!(got[5], Ok(SlcanMessage::Frame { .. })));
}

#[test]
fn bitrates_map_both_ways() {
    assert_eq!(SlcanBitrate::from_bps(1_000_000), Some(SlcanBitrate::M1));
    assert_eq!(SlcanBitrate::M1.digit(), 8);
    assert_eq!(SlcanBitrate::K250.bps(), 250_000);
    assert_eq!(SlcanBitrate::from_bps(300_000), None);
}
