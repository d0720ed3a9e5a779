//! Every example of chapters 8 (CAN), 9 (RS232) and 10 (Profibus-DP) of "Data exchange with PowerCube",
//! byte for byte, in both directions, and answered by the emulator.

use motionlink_link::can::{CanEmulator, CanFrame};
use motionlink_link::emulator::Emulator as ByteEmulator;
use motionlink_link::Timestamp;
use motionlink_powercube::model::{
    AckKind, CubeState, Motion, Param, Position, ProfibusFlag, ProfibusState, StateFlag, Value,
};
use motionlink_powercube::sim::{Emulator, SimConfig};
use motionlink_powercube::wire::can::{self, Role};
use motionlink_powercube::wire::profibus::{InputImage, OutputWriter};
use motionlink_powercube::wire::rs232::{self, Rs232Decoder, TelKind};
use motionlink_powercube::wire::{AckPosition, Action, Reply, Request};
use motionlink_powercube::wire::{Payload, ACK_OK};

fn frame(text: &str) -> CanFrame {
    text.parse().unwrap()
}

// ---------------------------------------------------------------------------------------------------------
// Chapter 8: CAN, module 17

#[test]
fn chapter_8_can_commands_encode_as_printed() {
    let cases: [(Request, &str); 7] = [
        (Request::Action(Action::Home), "0F1#01"),
        (Request::Action(Action::Reset), "0F1#00"),
        (Request::Set(Param::TargetAcc, Value::F32(0.5)), "0F1#08500000003F"),
        (Request::Set(Param::TargetVel, Value::F32(0.08)), "0F1#084F0AD7A33D"),
        (Request::Motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Simple), "0F1#0B040000403F"),
        (Request::Get(Param::CubeState), "0D1#0A27"),
        (Request::Get(Param::ActPos), "0D1#0A3C"),
    ];
    for (req, text) in cases {
        let payload = req.encode();
        let f = can::to_frame(Role::for_command(17, &payload), &payload);
        assert_eq!(f.to_string(), text, "{req}");
        assert_eq!(usize::from(f.dlc()), payload.len());
        let (role, p) = can::from_frame(&frame(text)).unwrap();
        assert!(matches!(role, Role::Get(17) | Role::Put(17)));
        assert_eq!(Request::decode(&p).unwrap(), req);
    }
    // The extended acknowledge variant of the ramp: MotionID 0x0e.
    let req = Request::Motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Extended);
    assert_eq!(can::to_frame(Role::Put(17), &req.encode()).to_string(), "0F1#0B0E0000403F");
}

#[test]
fn chapter_8_can_acknowledges_decode_as_printed() {
    let cases: [(&str, Reply); 5] = [
        ("0B1#01", Reply::Action(Action::Home)),
        ("0B1#00", Reply::Action(Action::Reset)),
        ("0B1#085064", Reply::Set(Param::TargetAcc, ACK_OK)),
        ("0B1#084F64", Reply::Set(Param::TargetVel, ACK_OK)),
        (
            "0B1#0B0464",
            Reply::Motion { id: motionlink_powercube::model::MotionId::FRamp, status: Some(ACK_OK), ext: None },
        ),
    ];
    for (text, reply) in cases {
        let (role, p) = can::from_frame(&frame(text)).unwrap();
        assert_eq!(role, Role::Ack(17));
        assert_eq!(Reply::decode(&p).unwrap(), reply, "{text}");
    }
    // State and position: DLC 6, a UInt32 and a float.
    let (_, p) = can::from_frame(&frame("0B1#0A2702800000")).unwrap();
    assert_eq!(Reply::decode(&p).unwrap(), Reply::Get(Param::CubeState, Value::U32(0x8002)));
    let (_, p) = can::from_frame(&frame("0B1#0A3C0000403F")).unwrap();
    assert_eq!(Reply::decode(&p).unwrap(), Reply::Get(Param::ActPos, Value::F32(0.75)));
    // Extended acknowledge: DLC 8, actual position, state, DIO (on the acknowledge identifier).
    let (_, p) = can::from_frame(&frame("0B1#0B0E0000803E3100")).unwrap();
    let Reply::Motion { ext: Some(e), .. } = Reply::decode(&p).unwrap() else { panic!() };
    assert_eq!(e.position, AckPosition::Unit(Position::native(0.25)));
    assert_eq!(e.state.0, 0x31);
}

#[test]
fn chapter_8_the_emulator_answers_each_example() {
    let mut bus = Emulator::new_can(&SimConfig::with_addresses(&[17]).unwrap());
    let mut t = 0u64;
    let mut ask = |text: &str| -> Vec<CanFrame> {
        let mut out = Vec::new();
        t += 1000;
        CanEmulator::receive(&mut bus, Timestamp::from_millis(t), &frame(text), &mut out);
        out
    };
    assert_eq!(ask("0F1#01"), vec![frame("0B1#01")]);
    assert_eq!(ask("0F1#00"), vec![frame("0B1#00")]);
    assert_eq!(ask("0F1#08500000003F"), vec![frame("0B1#085064")]);
    assert_eq!(ask("0F1#084F0AD7A33D"), vec![frame("0B1#084F64")]);
    assert_eq!(ask("0F1#0B040000403F"), vec![frame("0B1#0B0464")]);
    let state = ask("0D1#0A27");
    assert_eq!((state[0].id(), state[0].dlc()), (0x0B1, 6));
    let s = CubeState(u32::from_le_bytes(state[0].data()[2..6].try_into().unwrap()));
    assert!(s.contains(StateFlag::HomeOk) && s.contains(StateFlag::Motion), "{s}");
    let pos = ask("0D1#0A3C");
    assert_eq!((pos[0].id(), pos[0].dlc()), (0x0B1, 6));
    let ext = ask("0F1#0B0E0000403F");
    assert_eq!((ext[0].id(), ext[0].dlc()), (0x0B1, 8), "extended acknowledge on the acknowledge id");
    assert!(ask("100#07").is_empty(), "broadcasts are never acknowledged");
}

// ---------------------------------------------------------------------------------------------------------
// Chapter 9: RS232, module 17

const RS232_EXAMPLES: [(&[u8], &[u8]); 5] = [
    // Home
    (&[0x02, 0x06, 0x21, 0x01, 0x28, 0x03], &[0x02, 0x0a, 0x21, 0x01, 0x2c, 0x03]),
    // Reset
    (&[0x02, 0x06, 0x21, 0x00, 0x27, 0x03], &[0x02, 0x0a, 0x21, 0x00, 0x2b, 0x03]),
    // Set ramp motion acceleration 0.5 (the printed acknowledge says length 6 for 3 bytes)
    (
        &[0x02, 0x06, 0x26, 0x08, 0x50, 0x00, 0x00, 0x00, 0x3f, 0xc3, 0x03],
        &[0x02, 0x0a, 0x26, 0x08, 0x50, 0x64, 0xec, 0x03],
    ),
    // Set ramp motion velocity 0.08
    (
        &[0x02, 0x06, 0x26, 0x08, 0x4f, 0x0a, 0xd7, 0xa3, 0x3d, 0x46, 0x03],
        &[0x02, 0x0a, 0x26, 0x08, 0x4f, 0x64, 0xeb, 0x03],
    ),
    // Ramp motion command to 0.75
    (
        &[0x02, 0x06, 0x26, 0x0b, 0x04, 0x00, 0x00, 0x40, 0x3f, 0xba, 0x03],
        &[0x02, 0x0a, 0x26, 0x0b, 0x04, 0x64, 0xa3, 0x03],
    ),
];

#[test]
fn chapter_9_rs232_commands_encode_byte_for_byte() {
    let requests = [
        Request::Action(Action::Home),
        Request::Action(Action::Reset),
        Request::Set(Param::TargetAcc, Value::F32(0.5)),
        Request::Set(Param::TargetVel, Value::F32(0.08)),
        Request::Motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Simple),
    ];
    for (req, (send, _)) in requests.iter().zip(RS232_EXAMPLES) {
        let mut buf = [0u8; rs232::MAX_FRAME];
        let n = rs232::encode(TelKind::Send, 17, &req.encode(), &mut buf).unwrap();
        assert_eq!(&buf[..n], send, "{req}");
    }
}

#[test]
fn chapter_9_rs232_acknowledges_decode_with_their_printed_bcc() {
    for (_, ack) in RS232_EXAMPLES {
        let f = Rs232Decoder::new().feed(ack).next().unwrap().unwrap();
        assert_eq!((f.kind, f.address), (TelKind::Recv, 17));
        assert!(f.bcc_ok(), "{ack:02x?}");
        assert!(Reply::decode(&f.payload).is_ok());
    }
    // The manual's TELID example: SetExtended to 17 is 0x06 0x26, its answer 0x0a 0x26.
    assert_eq!(rs232::telid(TelKind::Send, 17, 6), [0x06, 0x26]);
    assert_eq!(rs232::telid(TelKind::Recv, 17, 6), [0x0a, 0x26]);
}

#[test]
fn chapter_9_the_escaped_halt() {
    let mut buf = [0u8; rs232::MAX_FRAME];
    let n = rs232::encode(TelKind::Send, 17, &Request::Action(Action::Halt).encode(), &mut buf).unwrap();
    assert_eq!(&buf[..n], &[0x02, 0x06, 0x21, 0x10, 0x82, 0x29, 0x03]);
    let f = Rs232Decoder::new().feed(&buf[..n]).next().unwrap().unwrap();
    assert_eq!(f.payload.as_bytes(), &[0x02]);
    assert_eq!(f.bcc_received, 0x29);
}

#[test]
fn chapter_9_the_emulator_answers_with_the_true_length() {
    let mut bus = Emulator::new(&SimConfig::with_addresses(&[17]).unwrap());
    for (i, (send, printed_ack)) in RS232_EXAMPLES.iter().enumerate() {
        let mut out = Vec::new();
        ByteEmulator::receive(&mut bus, Timestamp::from_millis(1000 * i as u64), send, &mut out);
        let f = Rs232Decoder::new().feed(&out).next().unwrap().unwrap();
        let printed = Rs232Decoder::new().feed(printed_ack).next().unwrap().unwrap();
        assert_eq!(f.payload, printed.payload, "same acknowledge data");
        assert!(f.length_ok() && f.bcc_ok());
        if printed.length_ok() {
            assert_eq!(&out, printed_ack);
        }
    }
    let mut out = Vec::new();
    ByteEmulator::receive(
        &mut bus,
        Timestamp::from_millis(9000),
        &[0x02, 0x06, 0x21, 0x10, 0x82, 0x29, 0x03],
        &mut out,
    );
    assert_eq!(out, vec![0x02, 0x0a, 0x21, 0x10, 0x82, 0x2d, 0x03], "the Halt acknowledge is escaped too");
}

// ---------------------------------------------------------------------------------------------------------
// Chapter 10: Profibus-DP

/// Chapter 10's examples: the command's output bytes 0..6 (byte 7 is "X", the rolling counter) and the
/// acknowledge in input bytes 0..7, as printed ("-" is 0x00).
const PROFIBUS_EXAMPLES: [([u8; 7], [u8; 8]); 5] = [
    // Home
    ([0x01, 0, 0, 0, 0, 0, 0], [0x01, 0, 0, 0, 0, 0, 0, 0]),
    // Reset
    ([0x00, 0, 0, 0, 0, 0, 0], [0x00, 0, 0, 0, 0, 0, 0, 0]),
    // Set ramp motion acceleration (0.5)
    ([0x08, 0x50, 0x00, 0x00, 0x00, 0x3f, 0], [0x08, 0x50, 0x64, 0, 0, 0, 0, 0]),
    // Set ramp motion velocity (0.08)
    ([0x08, 0x4f, 0x0a, 0xd7, 0xa3, 0x3d, 0], [0x08, 0x4f, 0x64, 0, 0, 0, 0, 0]),
    // Ramp motion command (0.75)
    ([0x0b, 0x04, 0x00, 0x00, 0x40, 0x3f, 0], [0x0b, 0x04, 0x64, 0, 0, 0, 0, 0]),
];

fn profibus_requests() -> [Request; 5] {
    [
        Request::Action(Action::Home),
        Request::Action(Action::Reset),
        Request::Set(Param::TargetAcc, Value::F32(0.5)),
        Request::Set(Param::TargetVel, Value::F32(0.08)),
        Request::Motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Simple),
    ]
}

#[test]
fn chapter_10_profibus_images() {
    let mut w = OutputWriter::new();
    let expected_replies = [
        Reply::Action(Action::Home),
        Reply::Action(Action::Reset),
        Reply::Set(Param::TargetAcc, ACK_OK),
        Reply::Set(Param::TargetVel, ACK_OK),
        Reply::Motion { id: motionlink_powercube::model::MotionId::FRamp, status: Some(ACK_OK), ext: None },
    ];
    let mut counters = Vec::new();
    for ((req, (send, ack)), reply) in profibus_requests().iter().zip(PROFIBUS_EXAMPLES).zip(expected_replies) {
        let image = w.image(&req.encode()).unwrap();
        assert_eq!(&image.0[..7], &send, "{req}");
        counters.push(image.counter());
        // The printed acknowledge in input bytes 0..7, with the cyclic bytes 8..15 after it.
        let input = InputImage::new(&Payload::new(&ack[..req.ack_len()]).unwrap(), 123_456, 0x0084, 17);
        assert_eq!(input.reply_bytes(), &ack, "{req}");
        assert_eq!(Reply::from_image(req, &input).unwrap(), reply, "{req}");
        assert_eq!(input.0[8], 0, "byte 8 is unused");
        assert_eq!(&input.0[9..13], &123_456i32.to_le_bytes());
        assert_eq!(&input.0[13..15], &[0x84, 0x00]);
        assert_eq!(input.0[15], 17);
        assert_eq!((input.position_ticks(), input.short_state_raw(), input.millis()), (123_456, 0x0084, 17));
        assert_eq!(input.short_state(), ProfibusState(0x0084));
        assert!(input.short_state().contains(ProfibusFlag::ReadyToPos));
        assert!(input.short_state().contains(ProfibusFlag::EndMotion));
    }
    // X: byte 7 changes with every command.
    assert!(counters.windows(2).all(|w| w[0] != w[1]), "{counters:?}");
}

#[test]
fn chapter_10_the_emulator_exchanges_images() {
    let mut bus = Emulator::new(&SimConfig::with_addresses(&[17]).unwrap());
    let mut w = OutputWriter::new();
    let at = Timestamp::from_millis;
    // Each example command in turn, one second apart: the acknowledge bytes are the manual's, byte for byte.
    for (i, (req, (_, ack))) in profibus_requests().iter().zip(PROFIBUS_EXAMPLES).enumerate() {
        let img = bus.profibus_exchange(at(1000 * i as u64), 17, &w.image(&req.encode()).unwrap()).unwrap();
        assert_eq!(img.reply_bytes(), &ack, "{req}");
        assert!(Reply::from_image(req, &img).is_ok(), "{req}");
        assert_eq!(img.0[8], 0, "byte 8 is unused");
    }
    let req = Request::Get(Param::CubeState);
    let img = bus.profibus_exchange(at(20_000), 17, &w.image(&req.encode()).unwrap()).unwrap();
    let Reply::Get(_, Value::U32(s)) = Reply::from_image(&req, &img).unwrap() else { panic!() };
    let s = CubeState(s);
    assert!(s.contains(StateFlag::HomeOk) && s.contains(StateFlag::RampEnd), "{s}");
    // The cyclic bytes follow the module: homed, at rest at 0.75 rad, the short state mapped from CubeState.
    assert_eq!(img.short_state(), s.profibus_state());
    assert!(img.short_state().contains(ProfibusFlag::ReadyToPos), "STATE_READYTOPOS: {}", img.short_state());
    let ticks = bus.module(17).unwrap().position_ticks().0;
    assert_eq!(img.position_ticks(), ticks);
    assert!(ticks > 0);
    assert_eq!(img.millis(), (20_000 % 256) as u8);
}
