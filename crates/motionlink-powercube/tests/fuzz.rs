//! Arbitrary bytes into the RS232 decoder, the SLCAN decoder and the emulators: never a panic, and a good
//! frame after the garbage is still found.

use motionlink_link::can::slcan::{self, SlcanDecoder, SlcanMessage};
use motionlink_link::can::{CanEmulator, CanFrame, SlcanAdapter};
use motionlink_link::emulator::Emulator;
use motionlink_link::Timestamp;
use motionlink_powercube::sim::{SimBus, SimConfig};
use motionlink_powercube::wire::rs232::{self, Rs232Decoder, TelKind};
use motionlink_powercube::wire::Payload;
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
        let mut bus = SimBus::new(&SimConfig::with_addresses(&[1, 17]).unwrap());
        let mut out = Vec::new();
        Emulator::receive(&mut bus, Timestamp::from_millis(1), &garbage, &mut out);
        Emulator::advance(&mut bus, Timestamp::from_millis(100), &mut out);
        out.clear();
        // An ETX closes any frame the garbage opened; then the manual's Home is answered.
        Emulator::receive(&mut bus, Timestamp::from_millis(200), &[0x03], &mut out);
        out.clear();
        Emulator::receive(&mut bus, Timestamp::from_millis(300), &HOME_17, &mut out);
        prop_assert_eq!(&out[..], &[0x02, 0x0a, 0x21, 0x01, 0x2c, 0x03]);
    }

    #[test]
    fn the_can_emulator_survives_any_frame(frames in proptest::collection::vec((0u32..0x800, proptest::collection::vec(any::<u8>(), 0..=8)), 0..60)) {
        let mut bus = SimBus::new_can(&SimConfig::with_addresses(&[1, 2]).unwrap());
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
        let mut adapter = SlcanAdapter::new(SimBus::new_can(&SimConfig::default()));
        let mut out = Vec::new();
        Emulator::receive(&mut adapter, Timestamp::from_millis(1), &garbage, &mut out);
        out.clear();
        Emulator::receive(&mut adapter, Timestamp::from_millis(2), b"\rC\rS8\rO\rt0C120A27\r", &mut out);
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
