//! Captured PowerCube traffic, explained: RS232 bytes (framed, unescaped, BCC and TELID length checked,
//! libm5api's broadcast form named) and CAN frames (by identifier role), through the one decoder signature
//! of every family ([`Describe`]). `motionlink decode powercube`, the demo's transcript and any capture
//! writer call it.
//!
//! ```
//! use motionlink_link::chunk::{Chunk, Direction};
//! use motionlink_link::describe::Describe;
//! use motionlink_powercube::describe::Describer;
//! let mut d = Describer::new();
//! let mut out = Vec::new();
//! d.describe(Chunk::Bytes(&[0x02, 0x06, 0x21, 0x01, 0x28, 0x03]), Direction::Unknown, None, &mut out);
//! assert_eq!(out[0].meaning, "to module 17: Home");
//! assert_eq!(out[0].direction, Direction::ToDevice);
//! ```

use motionlink_link::can::CanFrame;
use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::describe::{Annotation, Describe};
use motionlink_link::Timestamp;

use crate::model::{Broadcast, BroadcastForm, ConfigFlag, ConfigWord, ModuleKind, Param, Value};
use crate::wire::can::{self as can_wire, Role};
use crate::wire::rs232::{self, Rs232Decoder, Rs232Frame, TelKind};
use crate::wire::Payload;
use crate::wire::{Reply, Request};

/// The PowerCube describer: keeps the RS232 decoder's state between chunks, and the kind of each module
/// as its Config word goes by (so that a position read is shown in rad or m once that is known, and as
/// "rad|m" before).
#[derive(Debug, Clone, Default)]
pub struct Describer {
    decoder: Rs232Decoder,
    /// The bytes of the RS232 frame in progress, escapes included.
    frame: Vec<u8>,
    frames: u64,
    bytes: u64,
    kinds: [Option<ModuleKind>; 32],
}

impl Describer {
    /// A describer that has seen nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    fn kind(&self, address: u8) -> Option<ModuleKind> {
        self.kinds.get(usize::from(address)).copied().flatten()
    }

    /// Learns a module's kind from its Config word going by.
    fn learn(&mut self, address: u8, reply: &Reply) {
        if let Reply::Get(Param::Config, Value::U32(w)) = reply {
            let kind =
                if ConfigWord(*w).contains(ConfigFlag::Linear) { ModuleKind::Linear } else { ModuleKind::Rotary };
            if let Some(slot) = self.kinds.get_mut(usize::from(address)) {
                *slot = Some(kind);
            }
        }
    }

    /// A payload that went as a broadcast; true when it is none the manual or libm5api knows.
    fn broadcast(payload: &Payload) -> (String, bool) {
        match Broadcast::decode_form(payload) {
            Ok((b, BroadcastForm::Manual)) => (format!("broadcast: {b}"), false),
            Ok((b, BroadcastForm::Padded)) => (format!("broadcast: {b} (command + 0x00, as libm5api sends it)"), false),
            Err(e) => (format!("broadcast: not understood ({e})"), true),
        }
    }

    /// An acknowledge from `address`, with the unit of its kind where known; true when it is not one.
    fn reply(&mut self, address: u8, payload: &Payload) -> (String, bool) {
        match Reply::decode(payload) {
            Ok(r) => {
                self.learn(address, &r);
                let text = match r {
                    Reply::Get(p, v) => format!("{p} = {}", v.show_in(p, self.kind(address))),
                    other => other.to_string(),
                };
                (text, false)
            }
            Err(e) => (format!("acknowledge not understood: {e}"), true),
        }
    }

    /// A command to `address`, a value it sets in the unit of the module's kind where known; true when it
    /// is not one.
    fn request(&self, address: u8, payload: &Payload) -> (String, bool) {
        match Request::decode(payload) {
            Ok(Request::Set(p, v)) => (format!("SetExtended {p} = {}", v.show_in(p, self.kind(address))), false),
            Ok(r) => (r.to_string(), false),
            Err(e) => (format!("command not understood: {e}"), true),
        }
    }

    /// One CAN frame: its role, module and meaning; the direction its identifier gives.
    /// The flag is true when the frame is not a valid PowerCube message.
    pub fn describe_frame(&mut self, frame: &CanFrame) -> (String, Direction, bool) {
        match can_wire::from_frame(frame) {
            Ok((Role::Ack(a), p)) => {
                let (text, bad) = self.reply(a, &p);
                (format!("ack from module {a}: {text}"), Direction::FromDevice, bad)
            }
            Ok((Role::Get(a), p)) => {
                let (text, bad) = self.request(a, &p);
                (format!("get to module {a}: {text}"), Direction::ToDevice, bad)
            }
            Ok((Role::Put(a), p)) => {
                let (text, bad) = self.request(a, &p);
                // The manual's table (chapter 8) shows a motion command's extended acknowledge on the put
                // identifier 0x0E0 + id, which some firmware sends it on (the client takes it there too).
                if bad && p.as_bytes().first() == Some(&crate::wire::cmd::SET_MOTION) {
                    if let (ack, false) = self.reply(a, &p) {
                        let text =
                            format!("ack from module {a} (on its put identifier, as the manual's table shows): {ack}");
                        return (text, Direction::FromDevice, false);
                    }
                }
                (format!("put to module {a}: {text}"), Direction::ToDevice, bad)
            }
            Ok((Role::Broadcast, p)) => {
                let (text, bad) = Self::broadcast(&p);
                (text, Direction::ToDevice, bad)
            }
            Err(e) => (format!("not PowerCube: {e}"), Direction::Unknown, true),
        }
    }

    /// One RS232 frame: to or from which module, its meaning, and what is wrong with it (BCC, TELID
    /// length).
    pub fn describe_rs232(&mut self, frame: &Rs232Frame) -> String {
        self.explain_rs232(frame).0
    }

    /// [`describe_rs232`](Self::describe_rs232), and true when the payload is no valid message.
    fn explain_rs232(&mut self, frame: &Rs232Frame) -> (String, bool) {
        let (mut text, bad) = match frame.kind {
            TelKind::Send if frame.address == 0 => {
                let (text, bad) = Self::broadcast(&frame.payload);
                (format!("to every module (address 0): {text}"), bad)
            }
            TelKind::Send => {
                let (text, bad) = self.request(frame.address, &frame.payload);
                (format!("to module {}: {text}", frame.address), bad)
            }
            TelKind::Recv => {
                let (text, bad) = self.reply(frame.address, &frame.payload);
                (format!("from module {}: {text}", frame.address), bad)
            }
        };
        if !frame.bcc_ok() {
            text.push_str(&format!(" [BCC 0x{:02X} wrong, expected 0x{:02X}]", frame.bcc_received, frame.bcc_computed));
        }
        if frame.manual_length_slip() {
            text.push_str(" [TELID length 6 for 3 bytes: the manual's own acknowledges, accepted]");
        } else if !frame.length_ok() {
            text.push_str(&format!(" [TELID length {} for {} bytes]", frame.declared_len, frame.payload.len()));
        }
        (text, bad)
    }

    fn bytes(&mut self, bytes: &[u8], direction: Direction, at: Option<Timestamp>, out: &mut Vec<Annotation>) {
        for &b in bytes {
            self.bytes += 1;
            self.frame.push(b);
            // The bytes before a new STX: what an error the STX reveals is about.
            let mut before = Vec::new();
            if b == rs232::STX && self.frame.len() > 1 {
                before = std::mem::replace(&mut self.frame, vec![b]);
                before.pop();
            }
            match self.decoder.push(b) {
                Some(Ok(f)) => {
                    self.frames += 1;
                    let from_bytes = match f.kind {
                        TelKind::Send => Direction::ToDevice,
                        TelKind::Recv => Direction::FromDevice,
                    };
                    let (meaning, not_understood) = self.explain_rs232(&f);
                    out.push(Annotation {
                        at,
                        direction: if direction == Direction::Unknown { from_bytes } else { direction },
                        can_id: None,
                        bytes: std::mem::take(&mut self.frame),
                        meaning,
                        bad: not_understood || !f.bcc_ok() || !(f.length_ok() || f.manual_length_slip()),
                    });
                }
                Some(Err(e)) => {
                    // The bytes the error is about: those before the STX that ended them, else those so far.
                    let bytes = if b == rs232::STX { before } else { std::mem::take(&mut self.frame) };
                    out.push(Annotation {
                        at,
                        direction,
                        can_id: None,
                        bytes,
                        meaning: format!("error: {e}"),
                        bad: true,
                    });
                }
                None => {}
            }
        }
    }
}

impl Describe for Describer {
    fn describe(
        &mut self,
        captured: Chunk<'_>,
        direction: Direction,
        at: Option<Timestamp>,
        out: &mut Vec<Annotation>,
    ) {
        match captured {
            Chunk::Bytes(bytes) => self.bytes(bytes, direction, at, out),
            Chunk::Frame(frame) => {
                let (meaning, from_id, bad) = self.describe_frame(frame);
                out.push(Annotation {
                    at,
                    direction: if direction == Direction::Unknown { from_id } else { direction },
                    can_id: Some(frame.id()),
                    bytes: frame.data().to_vec(),
                    meaning,
                    bad,
                });
            }
        }
    }

    fn finish(&mut self, out: &mut Vec<Annotation>) {
        if self.frames == 0 && self.bytes > 0 {
            out.push(Annotation {
                at: None,
                direction: Direction::Unknown,
                can_id: None,
                bytes: Vec::new(),
                meaning: format!("no complete RS232 frame in {} byte(s)", self.bytes),
                bad: true,
            });
        } else if self.frame.len() > 1 || self.frame.first().is_some_and(|b| *b != rs232::STX) {
            out.push(Annotation {
                at: None,
                direction: Direction::Unknown,
                can_id: None,
                bytes: std::mem::take(&mut self.frame),
                meaning: "incomplete frame at the end of the capture".into(),
                bad: true,
            });
        }
        self.decoder.reset();
        self.frame.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(d: &mut Describer, captured: Chunk<'_>) -> Vec<Annotation> {
        let mut out = Vec::new();
        d.describe(captured, Direction::Unknown, None, &mut out);
        out
    }

    #[test]
    fn rs232_in_pieces_with_garbage_and_a_bad_bcc() {
        let mut d = Describer::new();
        assert!(all(&mut d, Chunk::Bytes(&[0x02, 0x06, 0x21])).is_empty(), "a frame in progress");
        let a = all(&mut d, Chunk::Bytes(&[0x10, 0x82, 0x29, 0x03, 0xff, 0x02, 0x06, 0x21, 0x01, 0x00, 0x03]));
        assert_eq!(a.len(), 3, "{a:?}");
        assert_eq!((a[0].meaning.as_str(), a[0].bytes.len(), a[0].bad), ("to module 17: Halt", 7, false));
        assert_eq!(
            (a[1].meaning.as_str(), a[1].bytes.as_slice()),
            ("error: 1 byte(s) outside a frame skipped", &[0xff][..])
        );
        assert!(a[2].bad && a[2].meaning.ends_with("Home [BCC 0x00 wrong, expected 0x28]"), "{}", a[2].meaning);
        let mut tail = Vec::new();
        all(&mut d, Chunk::Bytes(&[0x02, 0x06]));
        d.finish(&mut tail);
        assert!(tail[0].bad && tail[0].meaning.contains("incomplete"), "{tail:?}");
    }

    #[test]
    fn positions_get_their_unit_once_the_config_word_went_by() {
        let mut d = Describer::new();
        let get = |p: &Reply| CanFrame::new(0x0A4, p.encode().as_bytes()).unwrap();
        let pos = Reply::Get(Param::ActPos, Value::F32(0.1));
        assert_eq!(d.describe_frame(&get(&pos)).0, "ack from module 4: ActPos = 0.100000 rad|m");
        d.describe_frame(&get(&Reply::Get(Param::Config, Value::U32(ConfigFlag::Linear.mask()))));
        let (text, direction, bad) = d.describe_frame(&get(&pos));
        assert_eq!(
            (text.as_str(), direction, bad),
            ("ack from module 4: ActPos = 0.100000 m", Direction::FromDevice, false)
        );
        // A value a command sets is shown in the module's unit too, once known.
        let set = Request::Set(Param::TargetPos, Value::F32(0.2)).encode();
        let put = can_wire::to_frame(Role::for_command(4, &set), &set);
        assert_eq!(d.describe_frame(&put).0, "put to module 4: SetExtended TargetPos = 0.200000 m");
        let put = can_wire::to_frame(Role::for_command(5, &set), &set);
        assert_eq!(d.describe_frame(&put).0, "put to module 5: SetExtended TargetPos = 0.200000 rad|m");
        let mut out = Vec::new();
        let frame = CanFrame::new(0x0C4, &[0x0a, 0x3c]).unwrap();
        d.describe(Chunk::Frame(&frame), Direction::Unknown, None, &mut out);
        assert_eq!((out[0].can_id, out[0].direction), (Some(0x0C4), Direction::ToDevice));
    }

    /// The manual's own frames that the client takes are not shown as bad: the extended acknowledge on the
    /// put identifier (chapter 8's table: `0x0f1 8 0x0b 0x0e actPos State DIO`; was: "put to module 17:
    /// command not understood", to the device, bad), and the RS232 acknowledges with TELID length 6 for 3
    /// bytes (chapter 9; was: flagged bad). Other length mismatches stay bad.
    #[test]
    fn the_manuals_own_acknowledges_are_read_as_acknowledges() {
        let mut d = Describer::new();
        let frame = CanFrame::new(0x0F1, &[0x0b, 0x0e, 0x00, 0x00, 0x40, 0x3f, 0x30, 0x00]).unwrap();
        let (text, direction, bad) = d.describe_frame(&frame);
        assert_eq!((direction, bad), (Direction::FromDevice, false), "{text}");
        assert!(text.starts_with("ack from module 17 (on its put identifier"), "{text}");
        // A command on the put identifier is still a command.
        let frame = CanFrame::new(0x0F1, &[0x02]).unwrap();
        assert_eq!(d.describe_frame(&frame), ("put to module 17: Halt".to_string(), Direction::ToDevice, false));
        // Chapter 9's acknowledge of SetExtended: TELID 0x0a 0x26 (length 6) for 3 bytes.
        let a = all(&mut d, Chunk::Bytes(&[0x02, 0x0a, 0x26, 0x08, 0x50, 0x64, 0xec, 0x03]));
        assert_eq!(a.len(), 1, "{a:?}");
        assert!(!a[0].bad && a[0].meaning.contains("the manual's own acknowledges, accepted"), "{a:?}");
        // Length 7 for 3 bytes, with a right BCC: corrupt all the same.
        use crate::wire::rs232;
        let telid = rs232::telid(TelKind::Recv, 4, 7);
        let payload = crate::wire::Payload::new(&[0x08, 0x50, 0x64]).unwrap();
        let bcc = rs232::bcc(&[&telid[..], payload.as_bytes()].concat());
        let mut frame = [0u8; rs232::MAX_FRAME];
        let n = rs232::encode_raw(telid, &payload, bcc, &mut frame);
        let a = all(&mut d, Chunk::Bytes(&frame[..n]));
        assert_eq!(a.len(), 1, "{a:?}");
        assert!(a[0].bad && a[0].meaning.contains("[TELID length 7 for 3 bytes]"), "{a:?}");
    }
}
