//! Tests of the reply codec.

use super::*;

fn events(mode: &Mode, bytes: &[u8]) -> Vec<ReplyEvent> {
    let mut d = ReplyDecoder::new(mode);
    let mut v = Vec::new();
    d.push_slice(bytes, |e| v.push(e));
    v
}

fn replies(mode: &Mode, bytes: &[u8]) -> Vec<(Option<u8>, String)> {
    events(mode, bytes)
        .into_iter()
        .map(|e| match e {
            ReplyEvent::Reply(r) => (r.address(), r.text_str().to_string()),
            other => panic!("{other:?}"),
        })
        .collect()
}

/// Chapter 4.5.1 reads the value up to CR, then LF and ">", then the BCC over the value.
#[test]
fn the_manuals_read_routine() {
    let text = b"S001: 12.5";
    let mut wire = text.to_vec();
    wire.extend_from_slice(b"\r\n>");
    assert_eq!(replies(&Mode::default(), &wire), [(None, "S001: 12.5".into())]);
    wire.push(bcc(text));
    assert_eq!(replies(&Mode::from_p196(8).unwrap(), &wire), [(None, "S001: 12.5".into())]);
}

#[test]
fn every_p196_combination_encodes_and_decodes() {
    for p196 in 0..=Mode::MAX_P196 {
        let m = Mode::from_p196(p196).unwrap();
        for (addr, text) in [(1u8, &b""[..]), (5, b"S001: -3.25"), (31, b"E72"), (12, b"$"), (7, b"7S1?")] {
            let mut out = Vec::new();
            encode_reply(&mut out, &m, addr, text);
            let mut d = ReplyDecoder::new(&m);
            d.expect_from(Some(addr));
            let mut got = Vec::new();
            // Byte by byte and in odd chunks: the decoder is incremental.
            for chunk in out.chunks(3) {
                d.push_slice(chunk, |e| got.push(e));
            }
            assert_eq!(got.len(), 1, "P196={p196} {got:?}");
            let ReplyEvent::Reply(r) = got[0] else { panic!("P196={p196}: {got:?}") };
            assert_eq!(r.text(), text, "P196={p196}");
            assert_eq!(r.address(), m.reply_address.then_some(addr), "P196={p196}");
            assert!(d.is_idle());
        }
    }
}

#[test]
fn reply_formats_on_the_wire() {
    let mut out = Vec::new();
    encode_reply(&mut out, &Mode::default(), 1, b"");
    assert_eq!(out, b"\r\n>");
    out.clear();
    encode_reply(&mut out, &Mode::from_p196(32 + 64 + 8).unwrap(), 12, b"E92");
    assert_eq!(out, [b'1', b'2', b'E', b'9', b'2', CR, bcc(b"12E92")]);
}

#[test]
fn kinds() {
    let m = Mode::default();
    let kinds: Vec<String> = events(&m, b"\r\n>E72\r\n>$\r\n>2\r\n>P194=5\r\n>")
        .iter()
        .map(|e| match e {
            ReplyEvent::Reply(r) => format!("{:?}", r.kind()),
            other => format!("{other:?}"),
        })
        .collect();
    assert_eq!(kinds, ["Ack", "Error(72)", "PositionReached", "Comparator(2)", "Text(\"P194=5\")"]);
}

#[test]
fn bad_bcc_and_broken_ends_resynchronise() {
    let m = Mode::from_p196(8).unwrap();
    let mut wire = b"S001: 1\r\n>\x00S001: 2\r\n>".to_vec();
    wire.push(bcc(b"S001: 2"));
    let ev = events(&m, &wire);
    assert!(matches!(ev[0], ReplyEvent::Error(ReplyError::Bcc { received: 0, .. })), "{ev:?}");
    let ReplyEvent::Reply(r) = ev[1] else { panic!("{ev:?}") };
    assert_eq!(r.text(), b"S001: 2");
    let m = Mode::default();
    let ev = events(&m, b"abc\rXS1\r\n>");
    assert_eq!(ev[0], ReplyEvent::Error(ReplyError::Framing(b'X')));
    let ReplyEvent::Reply(r) = ev[1] else { panic!("{ev:?}") };
    assert_eq!(r.text(), b"XS1");
    // The tail of a reply whose start was lost is skipped.
    assert_eq!(replies(&m, b"\n>E70\r\n>"), [(None, "E70".into())]);
    let long = [b'x'; 100];
    let mut t = long.to_vec();
    t.extend_from_slice(b"\r\n>E71\r\n>");
    let ev = events(&m, &t);
    assert_eq!(ev[0], ReplyEvent::Error(ReplyError::TooLong));
    let ReplyEvent::Reply(r) = ev[1] else { panic!("{ev:?}") };
    assert_eq!(r.kind(), ReplyKind::Error(71));
}

#[test]
fn address_prefix_resolution() {
    assert_eq!(split_address(b"12$", Some(1)), Some((12, 2)));
    assert_eq!(split_address(b"1$", None), Some((1, 1)));
    assert_eq!(split_address(b"11S1?", Some(1)), Some((1, 1)));
    assert_eq!(split_address(b"5S001: 1", Some(5)), Some((5, 1)));
    assert_eq!(split_address(b"31E72", None), Some((31, 2)));
    assert_eq!(split_address(b"S001", None), None);
    assert_eq!(split_address(b"0E72", None), None);
    let m = Mode::from_p196(64).unwrap();
    assert_eq!(events(&m, b"E72\r\n>"), [ReplyEvent::Error(ReplyError::NoAddress)]);
}

#[test]
fn flow_control_characters_are_not_text() {
    let m = Mode::from_p196(1).unwrap();
    let ev = events(&m, b"S0\x1301\x11: 1\r\n>");
    assert_eq!(ev[0], ReplyEvent::Flow(true));
    assert_eq!(ev[1], ReplyEvent::Flow(false));
    let ReplyEvent::Reply(r) = ev[2] else { panic!() };
    assert_eq!(r.text(), b"S001: 1");
    // With BCC, a BCC byte that happens to be XON is the BCC, not flow control.
    let m = Mode::from_p196(1 + 8).unwrap();
    let mut out = Vec::new();
    let text = [b'A', b'A' ^ XON];
    encode_reply(&mut out, &m, 1, &text);
    assert_eq!(*out.last().unwrap(), XON);
    assert!(matches!(events(&m, &out)[..], [ReplyEvent::Reply(_)]));
}
