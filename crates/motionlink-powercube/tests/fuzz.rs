//! Arbitrary bytes into the RS232 decoder, the SLCAN decoder and the emulators: never a panic, and a good
//! frame after the garbage is still found. And well-formed requests with arbitrary parameters and values
//! (every parameter, every motion mode, NaN and infinite floats, extreme integers) into the emulator in
//! arbitrary states, over every carrier: never a panic, and the soft limits never cross.

use motionlink_link::can::slcan::{self, SlcanDecoder, SlcanMessage};
use motionlink_link::can::{CanEmulator, CanFrame, SlcanAdapter};
use motionlink_link::emulator::Emulator as ByteEmulator;
use motionlink_link::Timestamp;
use motionlink_powercube::model::{Broadcast, CanBaud, CubeState, DataType, Motion, MotionId, Param, Value};
use motionlink_powercube::sim::{Emulator, SimConfig};
use motionlink_powercube::wire::can::{self as can_wire, Role};
use motionlink_powercube::wire::profibus::OutputWriter;
use motionlink_powercube::wire::rs232::{self, Rs232Decoder, TelKind};
use motionlink_powercube::wire::Payload;
use motionlink_powercube::wire::{Action, Reply, Request};
use proptest::prelude::*;

const HOME_17: [u8; 6] = [0x02, 0x06, 0x21, 0x01, 0x28, 0x03];

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn rs232_decoder_survives_garbage_and_resynchronises(garbage in proptest::collection::vec(any::<u8>(), 0..200),
                                                          data in proptest::collection::vec(any::<u8>(), 0..=8),
                                                          address in 0u8..32) {
        let mut d = Rs232Decoder::new();
        let _ = d.feed(&garbage).count();
        let mut buf = [0u8; rs232::MAX_FRAME];
        let n = rs232::encode(TelKind::Recv, address, &Payload::new(&data).unwrap(), &mut buf).unwrap();
        let got: Vec<_> = d.feed(&buf[..n]).collect();
        let last = got.last().unwrap().as_ref().unwrap();
        prop_assert_eq!(last.payload.as_bytes(), &data[..]);
        prop_assert_eq!(last.address, address);
        prop_assert!(last.bcc_ok() && last.length_ok());
    }

    #[test]
    fn slcan_decoder_survives_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..200),
                                      id in 0u32..0x800, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
        let mut d = SlcanDecoder::new();
        let _ = d.feed(&garbage).count();
        let frame = CanFrame::new(id, &data).unwrap();
        let mut line = [0u8; slcan::MAX_LINE];
        let n = slcan::encode_frame(&frame, &mut line);
        // A carriage return ends whatever line the garbage left open.
        let got: Vec<_> = d.feed(b"\r").chain(std::iter::empty()).collect();
        prop_assert!(got.len() <= 1);
        let got: Vec<_> = d.feed(&line[..n]).collect();
        prop_assert_eq!(got, vec![Ok(SlcanMessage::Frame { frame, timestamp_ms: None })]);
    }

    #[test]
    fn the_rs232_emulator_survives_garbage_and_still_answers(garbage in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut bus = Emulator::new(&SimConfig::with_addresses(&[1, 17]).unwrap());
        let mut out = Vec::new();
        ByteEmulator::receive(&mut bus, Timestamp::from_millis(1), &garbage, &mut out);
        ByteEmulator::advance(&mut bus, Timestamp::from_millis(100), &mut out);
        out.clear();
        // An ETX closes any frame the garbage opened; then the manual's Home is answered.
        ByteEmulator::receive(&mut bus, Timestamp::from_millis(200), &[0x03], &mut out);
        out.clear();
        ByteEmulator::receive(&mut bus, Timestamp::from_millis(300), &HOME_17, &mut out);
        prop_assert_eq!(&out[..], &[0x02, 0x0a, 0x21, 0x01, 0x2c, 0x03]);
    }

    #[test]
    fn the_can_emulator_survives_any_frame(frames in proptest::collection::vec((0u32..0x800, proptest::collection::vec(any::<u8>(), 0..=8)), 0..60)) {
        let mut bus = Emulator::new_can(&SimConfig::with_addresses(&[1, 2]).unwrap());
        let mut out = Vec::new();
        for (i, (id, data)) in frames.iter().enumerate() {
            CanEmulator::receive(&mut bus, Timestamp::from_millis(i as u64 * 10), &CanFrame::new(*id, data).unwrap(), &mut out);
        }
        CanEmulator::advance(&mut bus, Timestamp::from_secs_for_test(3600), &mut out);
        out.clear();
        CanEmulator::receive(&mut bus, Timestamp::from_secs_for_test(3601), &"0C1#0A27".parse().unwrap(), &mut out);
        prop_assert_eq!(out.len(), 1);
        prop_assert_eq!(out[0].id(), 0x0A1);
    }

    #[test]
    fn the_slcan_adapter_survives_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut adapter = SlcanAdapter::new(Emulator::new_can(&SimConfig::default()));
        let mut out = Vec::new();
        ByteEmulator::receive(&mut adapter, Timestamp::from_millis(1), &garbage, &mut out);
        out.clear();
        ByteEmulator::receive(&mut adapter, Timestamp::from_millis(2), b"\rC\rS8\rO\rt0C120A27\r", &mut out);
        let text = String::from_utf8_lossy(&out).to_string();
        // (time stamps may be on if the garbage said Z1)
        prop_assert!(text.contains("z\rt0A160A2700000000"), "{:?}", text);
    }
}

trait FromSecs {
    fn from_secs_for_test(s: u64) -> Timestamp;
}

impl FromSecs for Timestamp {
    fn from_secs_for_test(s: u64) -> Timestamp {
        Timestamp::from_millis(s * 1000)
    }
}

/// Floats as they may come over a wire: anything at all, and the awkward ones often.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -5.0f32..5.0,
        2 => any::<u32>().prop_map(f32::from_bits),
        1 => prop::sample::select(vec![
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            -f32::MAX,
            f32::MIN_POSITIVE,
            0.0,
            -0.0,
            1e-7,
        ]),
    ]
}

/// A value of `ty`.
fn value_of(ty: DataType) -> BoxedStrategy<Value> {
    match ty {
        DataType::F32 => any_f32().prop_map(Value::F32).boxed(),
        DataType::U32 => prop_oneof![any::<u32>(), 0u32..0x1000].prop_map(Value::U32).boxed(),
        DataType::I32 => prop_oneof![any::<i32>(), -100_000i32..100_000].prop_map(Value::I32).boxed(),
        DataType::U16 => any::<u16>().prop_map(Value::U16).boxed(),
        DataType::I16 => any::<i16>().prop_map(Value::I16).boxed(),
        DataType::U8 => any::<u8>().prop_map(Value::U8).boxed(),
        DataType::PosStateDio | DataType::PosTime => Just(Value::U8(0)).boxed(),
    }
}

/// A well-formed request: a read or a write of any parameter with a value of its type, a motion in any of
/// the 18 modes with any parameters, a step, a one-byte command.
fn request() -> impl Strategy<Value = Request> {
    let param = prop::sample::select(Param::ALL.to_vec());
    prop_oneof![
        param.clone().prop_map(Request::Get),
        param.prop_flat_map(|p| value_of(p.data_type()).prop_map(move |v| match p.data_type() {
            DataType::PosStateDio | DataType::PosTime => Request::Get(p),
            _ => Request::Set(p, v),
        })),
        (prop::sample::select(MotionId::ALL.to_vec()), any_f32(), any::<i32>(), any::<u16>()).prop_map(
            |(id, f, i, t)| {
                let mut bytes = Vec::new();
                bytes.extend_from_slice(&if id.shape().float_position() { f.to_le_bytes() } else { i.to_le_bytes() });
                bytes.extend_from_slice(&t.to_le_bytes());
                let motion = Motion::decode_params(id, &bytes[..id.shape().size()]).unwrap();
                Request::Motion(motion, id.ack())
            }
        ),
        (any::<i32>(), any::<u16>()).prop_map(|(p, t)| Request::IStep {
            pos: motionlink_powercube::model::Ticks(p),
            time: motionlink_powercube::model::Millis(t)
        }),
        prop::sample::select(Action::ALL.to_vec()).prop_map(Request::Action),
    ]
}

#[derive(Debug, Clone)]
enum Carrier {
    Direct,
    Can,
    Rs232,
    Profibus,
}

#[derive(Debug, Clone)]
enum Step {
    /// A request to a module (or an address where none is) over a carrier.
    Request(u8, Request, Carrier),
    Broadcast(Broadcast),
    /// An error flag raised as a fault of the module would.
    Fault(u8, u32),
}

fn step() -> impl Strategy<Value = Step> {
    let carrier = prop::sample::select(vec![Carrier::Direct, Carrier::Can, Carrier::Rs232, Carrier::Profibus]);
    prop_oneof![
        8 => (prop::sample::select(vec![1u8, 2, 9]), request(), carrier).prop_map(|(a, r, c)| Step::Request(a, r, c)),
        1 => prop::sample::select(vec![
            Broadcast::Reset,
            Broadcast::Home,
            Broadcast::Halt,
            Broadcast::WatchdogRefresh,
            Broadcast::SavePosition,
            Broadcast::StartMotion,
            Broadcast::ChangeBaudRate(CanBaud::M1),
        ])
        .prop_map(Step::Broadcast),
        1 => (1u8..=2, any::<u32>()).prop_map(|(a, f)| Step::Fault(a, f)),
    ]
}

/// The module's own view of `param`, asked directly.
fn read(bus: &mut Emulator, now: Timestamp, a: u8, param: Param) -> Value {
    match bus.request(now, a, &Request::Get(param)) {
        Some(Reply::Get(p, v)) if p == param && v.data_type() == param.data_type() => v,
        other => panic!("module {a}, {param}: {other:?}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn the_emulator_takes_any_well_formed_request_in_any_state(
        homed in any::<bool>(),
        config in prop_oneof![Just(None), any::<u32>().prop_map(Some)],
        steps in proptest::collection::vec((step(), 0u64..3_000), 1..40),
    ) {
        let mut bus = Emulator::new_can(&SimConfig::with_addresses(&[1, 2]).unwrap());
        let mut now = Timestamp::from_millis(0);
        // A random starting state: homed or not, any Config word (watchdog, synchronised motion, M3
        // compatibility, linear, disabled acknowledges...), a watchdog switched on.
        for a in [1, 2] {
            if homed {
                bus.request(now, a, &Request::Action(Action::Home));
            }
            if let Some(word) = config {
                bus.request(now, a, &Request::Set(Param::Config, Value::U32(word)));
                bus.request(now, a, &Request::Action(Action::LifeSign));
            }
        }
        now = Timestamp::from_millis(5_000);
        let mut writer = OutputWriter::new();
        let mut out = Vec::new();
        for (step, wait) in steps {
            now = Timestamp::from_millis(now.as_millis() as u64 + wait);
            match step {
                Step::Request(a, r, Carrier::Direct) => {
                    let reply = bus.request(now, a, &r);
                    if let Some(reply) = reply {
                        prop_assert!(reply.answers(&r), "{r} answered by {reply}");
                    }
                }
                Step::Request(a, r, Carrier::Can) => {
                    let p = r.encode();
                    CanEmulator::receive(&mut bus, now, &can_wire::to_frame(Role::for_command(a, &p), &p), &mut Vec::new());
                }
                Step::Request(a, r, Carrier::Rs232) => {
                    let mut buf = [0u8; rs232::MAX_FRAME];
                    let n = rs232::encode(TelKind::Send, a, &r.encode(), &mut buf).unwrap();
                    ByteEmulator::receive(&mut bus, now, &buf[..n], &mut out);
                    out.clear();
                }
                Step::Request(a, r, Carrier::Profibus) => {
                    if let Ok(image) = writer.image(&r.encode()) {
                        let _ = bus.profibus_exchange(now, a, &image);
                    }
                }
                Step::Broadcast(b) => bus.broadcast(now, &b),
                Step::Fault(a, flags) => {
                    if let Some(m) = bus.module_mut(a) {
                        m.inject_fault(CubeState(flags));
                    }
                }
            }
            for a in [1, 2] {
                let Value::F32(min) = read(&mut bus, now, a, Param::MinPos) else { unreachable!() };
                let Value::F32(max) = read(&mut bus, now, a, Param::MaxPos) else { unreachable!() };
                prop_assert!(min <= max, "module {a}: MinPos {min} > MaxPos {max}");
                let Value::F32(pos) = read(&mut bus, now, a, Param::ActPos) else { unreachable!() };
                prop_assert!(!pos.is_nan(), "module {a}");
                read(&mut bus, now, a, Param::CubeState);
                read(&mut bus, now, a, Param::ActFPosStateDio);
            }
        }
        // Time runs on with whatever motion is left: an hour later, still no panic.
        bus.update(Timestamp::from_millis(now.as_millis() as u64 + 3_600_000));
        for a in [1, 2] {
            read(&mut bus, Timestamp::from_millis(now.as_millis() as u64 + 3_600_000), a, Param::CubeState);
        }
    }
}
