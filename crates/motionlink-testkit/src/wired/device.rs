//! The device end of a wired session: what goes over the line, and the emulators at the other end.

use std::ops::{Deref, DerefMut};

use motionlink_link::can::{CanEmulator, CanFrame};
use motionlink_link::emulator::Emulator;
use motionlink_link::Timestamp;

/// What goes over the line: bytes of a serial line, or one CAN frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Telegram {
    /// Bytes of a serial line.
    Bytes(Vec<u8>),
    /// A CAN frame.
    Frame(CanFrame),
}

impl Telegram {
    /// The frame's identifier, for a CAN frame.
    pub fn frame_id(&self) -> Option<u32> {
        match self {
            Telegram::Frame(f) => Some(f.id()),
            Telegram::Bytes(_) => None,
        }
    }

    /// The bytes as text (lossy), for line protocols in ASCII.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(self).into_owned()
    }
}

/// The bytes of a serial telegram, the data of a frame.
impl Deref for Telegram {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Telegram::Bytes(b) => b,
            Telegram::Frame(f) => f.data(),
        }
    }
}

/// The device end of the line: an emulator that takes telegrams at a time and answers.
pub trait Device {
    /// `telegram` arrived at `now`; answers go to `out`.
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>);
    /// Time has reached `now`; what the device says by itself goes to `out`.
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>);
    /// When the device next wants [`Device::advance`].
    fn next_wakeup(&self) -> Option<Timestamp>;
    /// What the device did since the last call (the lines `motionlink sim --events` prints).
    fn take_events(&mut self) -> Vec<String>;
}

/// An emulator on a serial line.
#[derive(Debug)]
pub struct Serial<E>(pub E);

/// An emulator on a CAN bus.
#[derive(Debug)]
pub struct Can<E>(pub E);

macro_rules! wrapper_deref {
    ($w:ident) => {
        impl<E> Deref for $w<E> {
            type Target = E;
            fn deref(&self) -> &E {
                &self.0
            }
        }
        impl<E> DerefMut for $w<E> {
            fn deref_mut(&mut self) -> &mut E {
                &mut self.0
            }
        }
    };
}
wrapper_deref!(Serial);
wrapper_deref!(Can);

/// What an emulator on a serial line answers to `telegram` at `now`.
fn serial_receive<E: Emulator + ?Sized>(e: &mut E, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
    let mut bytes = Vec::new();
    e.receive(now, telegram, &mut bytes);
    if !bytes.is_empty() {
        out.push(Telegram::Bytes(bytes));
    }
}

/// What an emulator on a serial line says by itself at `now`.
fn serial_advance<E: Emulator + ?Sized>(e: &mut E, now: Timestamp, out: &mut Vec<Telegram>) {
    let mut bytes = Vec::new();
    e.advance(now, &mut bytes);
    if !bytes.is_empty() {
        out.push(Telegram::Bytes(bytes));
    }
}

/// What an emulator on a CAN bus answers to `telegram` (a frame; bytes never reach it) at `now`.
fn can_receive<E: CanEmulator + ?Sized>(e: &mut E, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
    let Telegram::Frame(frame) = telegram else { return };
    let mut frames = Vec::new();
    e.receive(now, frame, &mut frames);
    out.extend(frames.into_iter().map(Telegram::Frame));
}

/// What an emulator on a CAN bus says by itself at `now`.
fn can_advance<E: CanEmulator + ?Sized>(e: &mut E, now: Timestamp, out: &mut Vec<Telegram>) {
    let mut frames = Vec::new();
    e.advance(now, &mut frames);
    out.extend(frames.into_iter().map(Telegram::Frame));
}

impl<E: Emulator> Device for Serial<E> {
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
        serial_receive(&mut self.0, now, telegram, out);
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>) {
        serial_advance(&mut self.0, now, out);
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        Emulator::next_wakeup(&self.0)
    }
    fn take_events(&mut self) -> Vec<String> {
        Emulator::take_events(&mut self.0)
    }
}

impl<E: CanEmulator> Device for Can<E> {
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
        can_receive(&mut self.0, now, telegram, out);
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>) {
        can_advance(&mut self.0, now, out);
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        CanEmulator::next_wakeup(&self.0)
    }
    fn take_events(&mut self) -> Vec<String> {
        CanEmulator::take_events(&mut self.0)
    }
}

/// An emulator that speaks on a serial line or on a CAN bus, whichever it was wired to (a family whose
/// devices have both; tests of either carrier share one harness type).
#[derive(Debug, Clone)]
pub enum SerialOrCan<E> {
    /// On a serial line.
    Serial(E),
    /// On a CAN bus.
    Can(E),
}

impl<E> Deref for SerialOrCan<E> {
    type Target = E;
    fn deref(&self) -> &E {
        match self {
            SerialOrCan::Serial(e) | SerialOrCan::Can(e) => e,
        }
    }
}

impl<E> DerefMut for SerialOrCan<E> {
    fn deref_mut(&mut self) -> &mut E {
        match self {
            SerialOrCan::Serial(e) | SerialOrCan::Can(e) => e,
        }
    }
}

impl<E: Emulator + CanEmulator> Device for SerialOrCan<E> {
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
        match self {
            SerialOrCan::Serial(e) => serial_receive(e, now, telegram, out),
            SerialOrCan::Can(e) => can_receive(e, now, telegram, out),
        }
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>) {
        match self {
            SerialOrCan::Serial(e) => serial_advance(e, now, out),
            SerialOrCan::Can(e) => can_advance(e, now, out),
        }
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        match self {
            SerialOrCan::Serial(e) => Emulator::next_wakeup(e),
            SerialOrCan::Can(e) => CanEmulator::next_wakeup(e),
        }
    }
    fn take_events(&mut self) -> Vec<String> {
        match self {
            SerialOrCan::Serial(e) => Emulator::take_events(e),
            SerialOrCan::Can(e) => CanEmulator::take_events(e),
        }
    }
}
