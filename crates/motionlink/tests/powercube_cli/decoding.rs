//! `decode powercube` and the demo, through the binary.

use super::*;

pub(super) fn decode(input: &str) -> Output {
    let mut child = Command::new(BIN)
        .args(["decode", "powercube"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input.as_bytes()).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
pub(super) fn a_hex_capture_with_comment_lines_is_not_taken_for_candump() {
    let out = decode("# Home to module 17, and its acknowledge\n02 06 21 01 28 03\n# ack:\n02 0a 21 01 2c 03\n");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("to module 17: Home"), "{text}");
    assert!(text.contains("from module 17: Home acknowledged"), "{text}");
    // And a candump log may have comment lines too.
    let out = decode("# candump -l can0\n(1700000000.000000) can0 0F1#01\n// ack\n(1700000000.000100) can0 0B1#01\n");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("put to module 17: Home") && text.contains("ack from module 17: Home acknowledged"),
        "{text}"
    );
    // One frame given as an argument.
    let out = Command::new(BIN).args(["decode", "powercube", "0D1#0A3C"]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("get to module 17: GetExtended ActPos"), "{out:?}");
}

#[test]
pub(super) fn decode_rs232_and_candump() {
    let out = decode("02 06 21 10 82 29 03\n02 0a 26 08 50 64 ec 03 ff 02 06 21 01 00 03\n");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("to module 17: Halt"), "{text}");
    // The manual's own acknowledge (TELID length 6 for 3 bytes), taken as the client takes it: no `!!`.
    assert!(
        text.contains(
            "<- 02 0A 26 08 50 64 EC 03                from module 17: TargetAcc set [TELID length 6 for 3 bytes: \
                       the manual's own acknowledges, accepted]"
        ),
        "{text}"
    );
    assert!(text.contains("error: 1 byte(s) outside a frame skipped"), "{text}");
    assert!(text.contains("Home [BCC 0x00 wrong, expected 0x28]"), "{text}");

    let out = decode("(1700000000.000000) can0 0F1#01\n(1700000000.000100) can0 0B1#01\n  can0  0D1   [2]  0A 3C\n(1.0) can0 100#07\n");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("put to module 17: Home"), "{text}");
    assert!(text.contains("ack from module 17: Home acknowledged"), "{text}");
    assert!(text.contains("get to module 17: GetExtended ActPos"), "{text}");
    assert!(text.contains("broadcast: Watchdog refresh"), "{text}");

    let out = decode("(1.0) can0 0F1#0\n");
    assert_eq!(code(&out), 2);
    let out = Command::new(BIN).args(["decode", "powercube", "02", "06", "21", "01", "28", "03"]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("to module 17: Home"));
}

#[test]
pub(super) fn demo_shows_the_manuals_examples() {
    let out = Command::new(BIN).args(["demo", "powercube"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "0F1#01",
        "0B1#01",
        "0F1#08500000003F",
        "0B1#085064",
        "0D1#0A27",
        "0F1#0B0E0000403F",
        "02 06 21 01 28 03",
        "02 0A 21 01 2C 03",
        "02 06 21 10 82 29 03",
    ] {
        assert!(text.contains(needle), "{needle} missing in\n{text}");
    }
}

/// candump `-x` marks the direction of each frame (`T` sent by this host, `R` received), in the log form
/// (`candump -l -x`) and the screen form (`TX - -`): `decode` keeps it, even where the identifier does not
/// tell it (a frame that is no PowerCube message).
#[test]
pub(super) fn candump_x_direction_marks_are_kept() {
    let input = "(1700000000.000000) can0 123#0102 T\n(1700000000.000100) can0 123#0102 R\n\
                 (1700000000.000200)  can0  TX - -  0F1   [1]  01\n  can0  RX - -  0B1   [1]  01\n";
    let o = common::run_with(&["--json", "decode", "powercube"], &[], input);
    assert!(o.status.success(), "{o:?}");
    let got: Vec<serde_json::Value> =
        String::from_utf8_lossy(&o.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let directions: Vec<&str> = got.iter().map(|v| v["direction"].as_str().unwrap()).collect();
    assert_eq!(directions, ["->", "<-", "->", "<-"], "{got:?}");
    assert_eq!((&got[2]["frame"], &got[2]["time_s"]), (&"0F1#01".into(), &1_700_000_000.000_2.into()), "{got:?}");
    assert_eq!(got[3]["meaning"], "ack from module 17: Home acknowledged", "{got:?}");
    let text = String::from_utf8_lossy(&decode(input).stdout).into_owned();
    assert!(
        text.lines().nth(2).unwrap().starts_with("(1700000000.000200) can0 0F1#01") && text.contains("-> put"),
        "{text}"
    );
}
