//! Broadcasts: commands to every module at once (chapter 4.1.2), in the manual's form and in the form
//! Schunk's libm5api sends over RS232.

use std::fmt;

use crate::wire::{cmd, Payload};
use crate::wire::{payload, ModelError};

/// The CAN bit rates of the change-baud-rate broadcast.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CanBaud {
    /// 1: 250 kbit/s.
    K250,
    /// 2: 500 kbit/s.
    K500,
    /// 3: 1 Mbit/s.
    M1,
}

impl CanBaud {
    /// The code in the broadcast.
    pub fn code(self) -> u8 {
        match self {
            CanBaud::K250 => 1,
            CanBaud::K500 => 2,
            CanBaud::M1 => 3,
        }
    }

    /// Bits per second.
    pub fn bps(self) -> u32 {
        match self {
            CanBaud::K250 => 250_000,
            CanBaud::K500 => 500_000,
            CanBaud::M1 => 1_000_000,
        }
    }

    /// The setting for a code.
    pub fn from_code(code: u8) -> Option<CanBaud> {
        [CanBaud::K250, CanBaud::K500, CanBaud::M1].into_iter().find(|b| b.code() == code)
    }
}

/// A command to every module at once; modules never acknowledge it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Broadcast {
    /// Reset all (0x00).
    Reset,
    /// Home all (0x01).
    Home,
    /// Halt all (0x02).
    Halt,
    /// Refresh the watchdog of all (0x07), at least every 50 ms while it is on.
    WatchdogRefresh,
    /// Change the CAN bit rate (0x09 + code).
    ChangeBaudRate(CanBaud),
    /// Store the actual position in ActFSavedPos (0x0e).
    SavePosition,
    /// Start the motion commanded last, in synchronised mode (0x0f).
    StartMotion,
}

/// How a broadcast's payload is laid out: the manual's form, or the form Schunk's own library sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BroadcastForm {
    /// The manual's table (chapter 4.1.2): the command byte alone (with its parameter for Change baud
    /// rate). What this client sends on CAN.
    Manual,
    /// The command byte followed by a 0x00 byte, as Schunk's libm5api sends haltAll, resetAll, homeAll,
    /// serveWatchdogAll, savePosAll and startMotionAll over RS232 (to module address 0). What this client
    /// sends on RS232: it is the form real modules are known to act on there, and a bit flipped in its
    /// address cannot turn it into a command to one module (a one-byte 0x07 to one module is the life sign
    /// that toggles its watchdog; `[0x07, 0x00]` to one module is no command at all).
    Padded,
}

impl Broadcast {
    /// The payload in the manual's form ([`BroadcastForm::Manual`]).
    pub fn encode(&self) -> Payload {
        self.encode_as(BroadcastForm::Manual)
    }

    /// The payload in `form`. Change baud rate has its parameter byte in both forms (it is two bytes long
    /// already), so it is the same in both.
    pub fn encode_as(&self, form: BroadcastForm) -> Payload {
        let code = match self {
            Broadcast::Reset => cmd::RESET,
            Broadcast::Home => cmd::HOME,
            Broadcast::Halt => cmd::HALT,
            Broadcast::WatchdogRefresh => cmd::WATCHDOG,
            Broadcast::ChangeBaudRate(b) => return payload(&[&[cmd::CHANGE_BAUD, b.code()]]),
            Broadcast::SavePosition => cmd::SAVE_POSITION,
            Broadcast::StartMotion => cmd::START_MOTION,
        };
        match form {
            BroadcastForm::Manual => payload(&[&[code]]),
            BroadcastForm::Padded => payload(&[&[code, 0x00]]),
        }
    }

    /// The broadcast in `payload`, in either form ([`Broadcast::decode_form`] says which).
    pub fn decode(payload: &Payload) -> Result<Broadcast, ModelError> {
        Self::decode_form(payload).map(|(b, _)| b)
    }

    /// The broadcast in `payload` and the form it came in: the command alone, as the manual lists it, or the
    /// command followed by 0x00, as libm5api sends it over RS232. Both mean the same to a module.
    pub fn decode_form(payload: &Payload) -> Result<(Broadcast, BroadcastForm), ModelError> {
        let bytes = payload.as_bytes();
        let (&code, rest) = bytes.split_first().ok_or(ModelError::Empty)?;
        if code == cmd::CHANGE_BAUD {
            return match rest {
                [c] => CanBaud::from_code(*c)
                    .map(|b| (Broadcast::ChangeBaudRate(b), BroadcastForm::Manual))
                    .ok_or(ModelError::UnknownCommand(*c)),
                _ => Err(ModelError::Length { what: "Change baud rate", expected: "2", got: bytes.len() }),
            };
        }
        let broadcast = match code {
            cmd::RESET => Broadcast::Reset,
            cmd::HOME => Broadcast::Home,
            cmd::HALT => Broadcast::Halt,
            cmd::WATCHDOG => Broadcast::WatchdogRefresh,
            cmd::SAVE_POSITION => Broadcast::SavePosition,
            cmd::START_MOTION => Broadcast::StartMotion,
            c => return Err(ModelError::UnknownCommand(c)),
        };
        match rest {
            [] => Ok((broadcast, BroadcastForm::Manual)),
            [0x00] => Ok((broadcast, BroadcastForm::Padded)),
            _ => {
                Err(ModelError::Length { what: broadcast.name(), expected: "1, or 2 ending in 0x00", got: bytes.len() })
            }
        }
    }

    /// The manual's name.
    pub fn name(&self) -> &'static str {
        match self {
            Broadcast::Reset => "Reset all",
            Broadcast::Home => "Home all",
            Broadcast::Halt => "Halt all",
            Broadcast::WatchdogRefresh => "Watchdog refresh",
            Broadcast::ChangeBaudRate(_) => "Change baud rate",
            Broadcast::SavePosition => "Save position",
            Broadcast::StartMotion => "Start synchronised motion",
        }
    }
}

impl fmt::Display for Broadcast {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Broadcast::ChangeBaudRate(b) => write!(f, "{} to {} bit/s", self.name(), b.bps()),
            _ => f.write_str(self.name()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broadcasts_round_trip() {
        for b in [
            Broadcast::Reset,
            Broadcast::Home,
            Broadcast::Halt,
            Broadcast::WatchdogRefresh,
            Broadcast::ChangeBaudRate(CanBaud::K500),
            Broadcast::SavePosition,
            Broadcast::StartMotion,
        ] {
            assert_eq!(Broadcast::decode(&b.encode()).unwrap(), b);
        }
        assert_eq!(Broadcast::ChangeBaudRate(CanBaud::M1).encode().as_bytes(), &[0x09, 0x03]);
        assert!(Broadcast::decode(&Payload::new(&[0x09, 0x07]).unwrap()).is_err());
    }

    #[test]
    fn broadcasts_in_libm5api_form_are_the_same_broadcasts() {
        let p = |b: &[u8]| Payload::new(b).unwrap();
        for (bytes, b) in [
            (&[0x02, 0x00][..], Broadcast::Halt),
            (&[0x00, 0x00], Broadcast::Reset),
            (&[0x01, 0x00], Broadcast::Home),
            (&[0x07, 0x00], Broadcast::WatchdogRefresh),
            (&[0x0e, 0x00], Broadcast::SavePosition),
            (&[0x0f, 0x00], Broadcast::StartMotion),
        ] {
            assert_eq!(Broadcast::decode_form(&p(bytes)).unwrap(), (b, BroadcastForm::Padded), "{bytes:02X?}");
            assert_eq!(Broadcast::decode_form(&p(&bytes[..1])).unwrap(), (b, BroadcastForm::Manual));
            assert_eq!(b.encode_as(BroadcastForm::Padded).as_bytes(), bytes);
            assert_eq!(b.encode().as_bytes(), &bytes[..1]);
        }
        // Anything else after the command is not a broadcast.
        assert!(Broadcast::decode(&p(&[0x02, 0x01])).is_err());
        assert!(Broadcast::decode(&p(&[0x07, 0x00, 0x00])).is_err());
        assert!(Broadcast::decode(&p(&[0x09])).is_err());
        assert_eq!(Broadcast::ChangeBaudRate(CanBaud::K250).encode_as(BroadcastForm::Padded).as_bytes(), &[0x09, 1]);
    }
}
