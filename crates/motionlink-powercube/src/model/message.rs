//! Commands, acknowledges and broadcasts, typed, with their payloads (chapter 4.4).
//!
//! ```
//! use motionlink_powercube::model::{Param, Reply, Request, Value};
//! let req = Request::set(Param::TargetAcc, Value::F32(0.5)).unwrap();
//! assert_eq!(req.encode().as_bytes(), &[0x08, 0x50, 0x00, 0x00, 0x00, 0x3f]);
//! let ack = Reply::decode(&motionlink_powercube::wire::Payload::new(&[0x08, 0x50, 0x64]).unwrap()).unwrap();
//! assert!(req.is_answered_by(&ack));
//! // No writing to a read-only parameter, no reading a write-only one.
//! assert!(Request::set(Param::ActPos, Value::F32(0.0)).is_err());
//! assert!(Request::get(Param::TargetVel).is_err());
//! ```

use std::fmt;

use super::flags::{Dio, ProfibusState, ShortState};
use super::motion::{AckKind, Motion, MotionId};
use super::params::{Param, Value, ValueError};
use super::units::{Millis, Position, Ticks};
use crate::wire::{cmd, Payload, ACK_OK};

/// A command that is its command byte alone, and whose acknowledge is that byte too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Action {
    /// Reset (0x00): clear the error state.
    Reset,
    /// Home (0x01): start homing.
    Home,
    /// Halt (0x02): stop immediately.
    Halt,
    /// RecalcPIDParam (0x09).
    RecalcPid,
    /// ResetTime (0x12): reset the module's millisecond clock.
    ResetTime,
    /// SaveParameters (0x10; vendor library, not in the manual).
    SaveParameters,
    /// The life sign (0x07) to one module: switches its watchdog on, and off when sent again.
    LifeSign,
}

impl Action {
    /// Every action.
    pub const ALL: [Action; 7] = [
        Action::Reset,
        Action::Home,
        Action::Halt,
        Action::RecalcPid,
        Action::ResetTime,
        Action::SaveParameters,
        Action::LifeSign,
    ];

    /// The command byte.
    pub fn code(self) -> u8 {
        match self {
            Action::Reset => cmd::RESET,
            Action::Home => cmd::HOME,
            Action::Halt => cmd::HALT,
            Action::RecalcPid => cmd::RECALC_PID,
            Action::ResetTime => cmd::RESET_TIME,
            Action::SaveParameters => cmd::SAVE_PARAMETERS,
            Action::LifeSign => cmd::WATCHDOG,
        }
    }

    /// The manual's name.
    pub fn name(self) -> &'static str {
        match self {
            Action::Reset => "Reset",
            Action::Home => "Home",
            Action::Halt => "Halt",
            Action::RecalcPid => "RecalcPIDParam",
            Action::ResetTime => "ResetTime",
            Action::SaveParameters => "SaveParameters",
            Action::LifeSign => "LifeSign (watchdog on/off)",
        }
    }

    fn from_code(code: u8) -> Option<Action> {
        Self::ALL.iter().copied().find(|a| a.code() == code)
    }
}

/// A command to one module.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// A one-byte command.
    Action(Action),
    /// GetExtended: read a parameter.
    Get(Param),
    /// SetExtended: write a parameter.
    Set(Param, Value),
    /// SetMotion.
    Motion(Motion, AckKind),
    /// SetIStep: a step in ticks.
    IStep {
        /// Target position.
        pos: Ticks,
        /// Time to get there.
        time: Millis,
    },
}

/// A command or acknowledge that breaks the manual's rules.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// GetExtended of a write-only parameter.
    #[error("{0} cannot be read (it is write-only)")]
    NotReadable(Param),
    /// SetExtended of a read-only parameter.
    #[error("{0} cannot be written (it is read-only)")]
    NotWritable(Param),
    /// A value that does not fit the parameter.
    #[error(transparent)]
    Value(#[from] ValueError),
    /// An extended acknowledge asked of a loop mode.
    #[error("{0} has no mode with extended acknowledge")]
    NoExtendedAck(&'static str),
    /// A float that is not a number (NaN or infinite) as a value or a motion parameter.
    #[error("{0} is not a finite number")]
    NotFinite(&'static str),
    /// An empty payload.
    #[error("empty message")]
    Empty,
    /// An unknown command byte.
    #[error("unknown command 0x{0:02X}")]
    UnknownCommand(u8),
    /// An unknown ParameterID.
    #[error("unknown parameter 0x{0:02X}")]
    UnknownParam(u8),
    /// An unknown MotionID.
    #[error("unknown motion mode {0}")]
    UnknownMotion(u8),
    /// The wrong number of bytes for the command.
    #[error("{what}: {got} bytes, expected {expected}")]
    Length {
        /// The command.
        what: &'static str,
        /// What the manual says.
        expected: &'static str,
        /// What came.
        got: usize,
    },
}

fn payload(parts: &[&[u8]]) -> Payload {
    let mut p = Payload::EMPTY;
    for part in parts {
        // Every request and reply built here is at most 8 bytes (checked by the tests of every kind).
        let _ = p.push(part);
    }
    p
}

impl Request {
    /// GetExtended of `param`, if it can be read.
    pub fn get(param: Param) -> Result<Request, ModelError> {
        Request::Get(param).validated()
    }

    /// SetExtended of `param` to `value`, if it can be written, the value has its type and is a finite
    /// number (for a float).
    pub fn set(param: Param, value: Value) -> Result<Request, ModelError> {
        Request::Set(param, value).validated()
    }

    /// SetMotion in `motion`'s mode with acknowledge `ack`, if the mode has that acknowledge and its float
    /// parameters are finite.
    pub fn motion(motion: Motion, ack: AckKind) -> Result<Request, ModelError> {
        Request::Motion(motion, ack).validated()
    }

    /// Checks a request against the manual's rules, as the constructors do: a parameter is read only if it
    /// is readable and written only if it is writable, with a value of its type; a motion has a MotionID for
    /// the acknowledge asked (the loops have no extended one); floats are finite numbers. The variants are
    /// public, so a request built without a constructor may break them: the client checks every request
    /// with this before sending it.
    pub fn validate(&self) -> Result<(), ModelError> {
        match *self {
            Request::Action(_) | Request::IStep { .. } => Ok(()),
            Request::Get(param) if param.access().readable() => Ok(()),
            Request::Get(param) => Err(ModelError::NotReadable(param)),
            Request::Set(param, _) if !param.access().writable() => Err(ModelError::NotWritable(param)),
            Request::Set(param, value) => {
                value.check_type(param)?;
                match value {
                    Value::F32(v) if !v.is_finite() => Err(ModelError::NotFinite(param.name())),
                    _ => Ok(()),
                }
            }
            Request::Motion(motion, ack) => {
                let Some(id) = motion.id(ack) else {
                    return Err(ModelError::NoExtendedAck(motion.id(AckKind::Simple).map_or("?", |m| m.name())));
                };
                if motion.is_finite() {
                    Ok(())
                } else {
                    Err(ModelError::NotFinite(id.name()))
                }
            }
        }
    }

    fn validated(self) -> Result<Request, ModelError> {
        self.validate().map(|()| self)
    }

    /// The payload.
    pub fn encode(&self) -> Payload {
        let mut buf = [0u8; 6];
        match *self {
            Request::Action(a) => payload(&[&[a.code()]]),
            Request::Get(p) => payload(&[&[cmd::GET_EXTENDED, p.id()]]),
            Request::Set(p, v) => {
                let n = v.encode(&mut buf);
                payload(&[&[cmd::SET_EXTENDED, p.id()], &buf[..n]])
            }
            Request::Motion(m, ack) => {
                // A loop mode has no extended acknowledge ([`Request::validate`] refuses that combination);
                // encoding stays total and sends the simple mode.
                let id = m.id(ack).or(m.id(AckKind::Simple)).map_or(0, MotionId::code);
                let n = m.encode_params(&mut buf);
                payload(&[&[cmd::SET_MOTION, id], &buf[..n]])
            }
            Request::IStep { pos, time } => payload(&[&[cmd::SET_ISTEP], &pos.0.to_le_bytes(), &time.0.to_le_bytes()]),
        }
    }

    /// The request in `payload` (what a module receives).
    pub fn decode(payload: &Payload) -> Result<Request, ModelError> {
        let b = payload.as_bytes();
        let (&command, rest) = b.split_first().ok_or(ModelError::Empty)?;
        let len_err = |what, expected| ModelError::Length { what, expected, got: b.len() };
        match command {
            cmd::GET_EXTENDED => {
                let [id] = rest else { return Err(len_err("GetExtended", "2")) };
                Param::from_id(*id).map(Request::Get).ok_or(ModelError::UnknownParam(*id))
            }
            cmd::SET_EXTENDED => {
                let (&id, data) = rest.split_first().ok_or(len_err("SetExtended", "3..6"))?;
                let param = Param::from_id(id).ok_or(ModelError::UnknownParam(id))?;
                if data.len() != param.data_type().size() {
                    return Err(len_err("SetExtended", "2 + the parameter's size"));
                }
                Ok(Request::Set(param, Value::decode(param, data)?))
            }
            cmd::SET_MOTION => {
                let (&code, data) = rest.split_first().ok_or(len_err("SetMotion", "4..8"))?;
                let id = MotionId::from_code(code).ok_or(ModelError::UnknownMotion(code))?;
                let motion = Motion::decode_params(id, data).ok_or(len_err("SetMotion", "2 + the mode's size"))?;
                Ok(Request::Motion(motion, id.ack()))
            }
            cmd::SET_ISTEP => {
                if rest.len() != 6 {
                    return Err(len_err("SetIStep", "7"));
                }
                Ok(Request::IStep {
                    pos: Ticks(i32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]])),
                    time: Millis(u16::from_le_bytes([rest[4], rest[5]])),
                })
            }
            code => {
                let action = Action::from_code(code).ok_or(ModelError::UnknownCommand(code))?;
                if !rest.is_empty() {
                    return Err(len_err(action.name(), "1"));
                }
                Ok(Request::Action(action))
            }
        }
    }

    /// True for requests that may be repeated without effect (reads): the only ones a client retries.
    pub fn is_idempotent(&self) -> bool {
        matches!(self, Request::Get(_))
    }

    /// True for requests that set the module in motion.
    pub fn starts_motion(&self) -> bool {
        matches!(self, Request::Action(Action::Home) | Request::Motion(..) | Request::IStep { .. })
    }

    /// True if `reply` is the acknowledge of this request.
    pub fn is_answered_by(&self, reply: &Reply) -> bool {
        match (self, reply) {
            (Request::Action(a), Reply::Action(b)) => a == b,
            (Request::Get(p), Reply::Get(q, _)) => p == q,
            (Request::Set(p, _), Reply::Set(q, _)) => p == q,
            (Request::Motion(m, ack), Reply::Motion { id, .. }) => m.id(*ack) == Some(*id),
            (Request::IStep { .. }, Reply::IStep) => true,
            _ => false,
        }
    }

    /// The length of the acknowledge (for the Profibus image, which has no length).
    pub fn ack_len(&self) -> usize {
        match self {
            Request::Action(_) | Request::IStep { .. } => 1,
            Request::Get(p) => 2 + p.data_type().size(),
            Request::Set(..) => 3,
            Request::Motion(_, AckKind::Simple) => 3,
            Request::Motion(_, AckKind::Extended) => 8,
        }
    }

    /// The acknowledge this request gets in a Profibus input image, decoded with the right length.
    pub fn reply_from_image(&self, image: &crate::wire::profibus::InputImage) -> Result<Reply, ModelError> {
        Reply::decode(&image.reply(self.ack_len()))
    }
}

impl crate::wire::profibus::InputImage {
    /// Bytes 13..14: the Profibus short state, typed (the raw word is
    /// [`InputImage::short_state_raw`](crate::wire::profibus::InputImage::short_state_raw)).
    ///
    /// ```
    /// use motionlink_powercube::model::{ProfibusFlag, ProfibusState};
    /// use motionlink_powercube::wire::{profibus::InputImage, Payload};
    /// let img = InputImage::new(&Payload::new(&[0x02]).unwrap(), 0, 0x8004, 0);
    /// assert_eq!(img.short_state(), ProfibusState(0x8004));
    /// assert!(img.short_state().contains(ProfibusFlag::HaltM4));
    /// ```
    pub fn short_state(&self) -> ProfibusState {
        ProfibusState(self.short_state_raw())
    }
}

impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Request::Action(a) => f.write_str(a.name()),
            Request::Get(p) => write!(f, "GetExtended {p}"),
            Request::Set(p, v) => write!(f, "SetExtended {p} = {}", v.show(*p, super::ModuleKind::Rotary)),
            Request::Motion(m, ack) => {
                let name = m.id(*ack).map_or("?", MotionId::name);
                write!(f, "SetMotion {name} {}", m.describe())
            }
            Request::IStep { pos, time } => write!(f, "SetIStep to {} ticks in {} ms", pos.0, time.0),
        }
    }
}

/// The position in an extended motion acknowledge: a float for the float modes, ticks for the integer ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AckPosition {
    /// rad or m.
    Unit(Position),
    /// Encoder ticks.
    Ticks(Ticks),
}

/// The extended acknowledge of a motion command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtAck {
    /// Actual position.
    pub position: AckPosition,
    /// Short state.
    pub state: ShortState,
    /// Digital I/O.
    pub dio: Dio,
}

/// An acknowledge from a module.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reply {
    /// The acknowledge of a one-byte command.
    Action(Action),
    /// The acknowledge of GetExtended, with the value.
    Get(Param, Value),
    /// The acknowledge of SetExtended, with its status byte (0x64: done).
    Set(Param, u8),
    /// The acknowledge of SetMotion.
    Motion {
        /// The mode.
        id: MotionId,
        /// The status byte (0x64) of a simple acknowledge.
        status: Option<u8>,
        /// Position, state and DIO of an extended one.
        ext: Option<ExtAck>,
    },
    /// The acknowledge of SetIStep.
    IStep,
}

impl Reply {
    /// The payload.
    pub fn encode(&self) -> Payload {
        let mut buf = [0u8; 6];
        match *self {
            Reply::Action(a) => payload(&[&[a.code()]]),
            Reply::Get(p, v) => {
                let n = v.encode(&mut buf);
                payload(&[&[cmd::GET_EXTENDED, p.id()], &buf[..n]])
            }
            Reply::Set(p, status) => payload(&[&[cmd::SET_EXTENDED, p.id(), status]]),
            Reply::Motion { id, status, ext } => match ext {
                Some(e) => {
                    let pos = match e.position {
                        AckPosition::Unit(p) => p.0.to_le_bytes(),
                        AckPosition::Ticks(t) => t.0.to_le_bytes(),
                    };
                    payload(&[&[cmd::SET_MOTION, id.code()], &pos, &[e.state.0, e.dio.0]])
                }
                None => payload(&[&[cmd::SET_MOTION, id.code(), status.unwrap_or(ACK_OK)]]),
            },
            Reply::IStep => payload(&[&[cmd::SET_ISTEP]]),
        }
    }

    /// The acknowledge in `payload` (what a client receives).
    pub fn decode(payload: &Payload) -> Result<Reply, ModelError> {
        let b = payload.as_bytes();
        let (&command, rest) = b.split_first().ok_or(ModelError::Empty)?;
        let len_err = |what, expected| ModelError::Length { what, expected, got: b.len() };
        match command {
            cmd::GET_EXTENDED => {
                let (&id, data) = rest.split_first().ok_or(len_err("GetExtended acknowledge", "3..8"))?;
                let param = Param::from_id(id).ok_or(ModelError::UnknownParam(id))?;
                if data.len() != param.data_type().size() {
                    return Err(len_err("GetExtended acknowledge", "2 + the parameter's size"));
                }
                Ok(Reply::Get(param, Value::decode(param, data)?))
            }
            cmd::SET_EXTENDED => {
                let [id, status] = rest else { return Err(len_err("SetExtended acknowledge", "3")) };
                let param = Param::from_id(*id).ok_or(ModelError::UnknownParam(*id))?;
                Ok(Reply::Set(param, *status))
            }
            cmd::SET_MOTION => {
                let (&code, data) = rest.split_first().ok_or(len_err("SetMotion acknowledge", "3 or 8"))?;
                let id = MotionId::from_code(code).ok_or(ModelError::UnknownMotion(code))?;
                match data {
                    [status] => Ok(Reply::Motion { id, status: Some(*status), ext: None }),
                    [p0, p1, p2, p3, state, dio] => {
                        let raw = [*p0, *p1, *p2, *p3];
                        let position = if id.shape().float_position() {
                            AckPosition::Unit(Position(f32::from_le_bytes(raw)))
                        } else {
                            AckPosition::Ticks(Ticks(i32::from_le_bytes(raw)))
                        };
                        Ok(Reply::Motion {
                            id,
                            status: None,
                            ext: Some(ExtAck { position, state: ShortState(*state), dio: Dio(*dio) }),
                        })
                    }
                    _ => Err(len_err("SetMotion acknowledge", "3 or 8")),
                }
            }
            cmd::SET_ISTEP if rest.is_empty() => Ok(Reply::IStep),
            cmd::SET_ISTEP => Err(len_err("SetIStep acknowledge", "1")),
            code => {
                let action = Action::from_code(code).ok_or(ModelError::UnknownCommand(code))?;
                if !rest.is_empty() {
                    return Err(len_err(action.name(), "1"));
                }
                Ok(Reply::Action(action))
            }
        }
    }
}

impl fmt::Display for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reply::Action(a) => write!(f, "{} acknowledged", a.name()),
            Reply::Get(p, v) => write!(f, "{p} = {}", v.show(*p, super::ModuleKind::Rotary)),
            Reply::Set(p, s) if *s == ACK_OK => write!(f, "{p} set"),
            Reply::Set(p, s) => write!(f, "{p} set, status 0x{s:02X}"),
            Reply::Motion { id, ext: Some(e), .. } => {
                let pos = match e.position {
                    AckPosition::Unit(p) => format!("{}", p.0),
                    AckPosition::Ticks(t) => format!("{} ticks", t.0),
                };
                write!(f, "{} acknowledged: position {pos}, state {}, dio {}", id.name(), e.state, e.dio)
            }
            Reply::Motion { id, status, .. } => {
                write!(f, "{} acknowledged (0x{:02X})", id.name(), status.unwrap_or(ACK_OK))
            }
            Reply::IStep => f.write_str("SetIStep acknowledged"),
        }
    }
}

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
    use crate::model::units::{Acceleration, Velocity};
    use crate::model::{Amperes, CurrentDigits, TicksPerSec};

    #[test]
    fn every_request_round_trips() {
        let mut requests = vec![
            Request::IStep { pos: Ticks(-1000), time: Millis(50) },
            Request::Set(Param::TargetVel, Value::F32(0.08)),
            Request::Set(Param::Config, Value::U32(0x0100_0000)),
            Request::Set(Param::RawCur, Value::I16(-100)),
        ];
        requests.extend(Action::ALL.iter().map(|a| Request::Action(*a)));
        requests.extend(Param::ALL.iter().filter(|p| p.access().readable()).map(|p| Request::Get(*p)));
        let motions = [
            Motion::FRamp { pos: Position(1.0) },
            Motion::FStep { pos: Position(1.0), time: Millis(10) },
            Motion::FVel { vel: Velocity(1.0) },
            Motion::FCur { cur: Amperes(1.0) },
            Motion::IRamp { pos: Ticks(1) },
            Motion::IStep { pos: Ticks(1), time: Millis(1) },
            Motion::IVel { vel: TicksPerSec(1) },
            Motion::ICur { cur: CurrentDigits(1) },
            Motion::FCosLoop { pos: Position(1.0), time: Millis(10) },
            Motion::FRampLoop { pos: Position(1.0) },
        ];
        for m in motions {
            requests.push(Request::motion(m, AckKind::Simple).unwrap());
            if let Ok(r) = Request::motion(m, AckKind::Extended) {
                requests.push(r);
            }
        }
        for r in requests {
            let p = r.encode();
            assert_eq!(Request::decode(&p).unwrap(), r, "{r}");
        }
        let _ = Acceleration(0.0);
    }

    #[test]
    fn every_reply_round_trips() {
        let replies = [
            Reply::Action(Action::Home),
            Reply::Get(Param::ActPos, Value::F32(0.25)),
            Reply::Get(Param::ActFPosStateDio, Value::PosStateDio { pos: 1.0, state: ShortState(1), dio: Dio(2) }),
            Reply::Set(Param::TargetAcc, ACK_OK),
            Reply::Motion { id: MotionId::FRamp, status: Some(ACK_OK), ext: None },
            Reply::Motion {
                id: MotionId::FRampAck,
                status: None,
                ext: Some(ExtAck { position: AckPosition::Unit(Position(0.5)), state: ShortState(0x10), dio: Dio(0) }),
            },
            Reply::Motion {
                id: MotionId::IRampAck,
                status: None,
                ext: Some(ExtAck { position: AckPosition::Ticks(Ticks(-7)), state: ShortState(0x20), dio: Dio(0x80) }),
            },
            Reply::IStep,
        ];
        for r in replies {
            assert_eq!(Reply::decode(&r.encode()).unwrap(), r, "{r}");
        }
    }

    #[test]
    fn malformed_messages_are_named_errors() {
        let p = |b: &[u8]| Payload::new(b).unwrap();
        assert_eq!(Request::decode(&p(&[])), Err(ModelError::Empty));
        assert_eq!(Request::decode(&p(&[0x33])), Err(ModelError::UnknownCommand(0x33)));
        assert_eq!(Request::decode(&p(&[0x0a, 0x11])), Err(ModelError::UnknownParam(0x11)));
        assert!(matches!(Request::decode(&p(&[0x0a])), Err(ModelError::Length { .. })));
        assert!(matches!(Request::decode(&p(&[0x08, 0x50, 0, 0])), Err(ModelError::Length { .. })));
        assert_eq!(Request::decode(&p(&[0x0b, 0x05, 0, 0, 0, 0])), Err(ModelError::UnknownMotion(5)));
        assert!(matches!(Request::decode(&p(&[0x01, 0x00])), Err(ModelError::Length { .. })));
        assert!(matches!(Reply::decode(&p(&[0x0b, 0x04, 0x64, 0])), Err(ModelError::Length { .. })));
        assert!(Request::motion(Motion::FRampLoop { pos: Position(0.0) }, AckKind::Extended).is_err());
        assert!(Request::set(Param::TargetVel, Value::U32(1)).is_err());
    }

    #[test]
    fn validate_applies_the_constructors_rules_to_any_request() {
        let bad = [
            (Request::Set(Param::ActPos, Value::F32(0.0)), ModelError::NotWritable(Param::ActPos)),
            (Request::Get(Param::TargetVel), ModelError::NotReadable(Param::TargetVel)),
            (Request::Set(Param::TargetVel, Value::F32(f32::NAN)), ModelError::NotFinite("TargetVel")),
            (Request::Set(Param::MaxPos, Value::F32(f32::INFINITY)), ModelError::NotFinite("MaxPos")),
            (
                Request::Motion(Motion::FCosLoop { pos: Position(1.0), time: Millis(10) }, AckKind::Extended),
                ModelError::NoExtendedAck("FCOSLOOP"),
            ),
            (
                Request::Motion(Motion::FRamp { pos: Position(f32::NAN) }, AckKind::Simple),
                ModelError::NotFinite("FRAMP_MODE"),
            ),
            (
                Request::Motion(Motion::FVel { vel: Velocity(f32::NEG_INFINITY) }, AckKind::Extended),
                ModelError::NotFinite("FVEL_ACK"),
            ),
        ];
        for (req, err) in bad {
            assert_eq!(req.validate(), Err(err), "{req}");
        }
        assert!(matches!(
            Request::Set(Param::MaxVel, Value::U32(1)).validate(),
            Err(ModelError::Value(ValueError::Type { .. }))
        ));
        // The constructors say the same.
        assert_eq!(Request::set(Param::TargetVel, Value::F32(f32::NAN)), Err(ModelError::NotFinite("TargetVel")));
        assert!(Request::motion(Motion::FRamp { pos: Position(f32::INFINITY) }, AckKind::Simple).is_err());
        for good in [
            Request::Set(Param::TargetVel, Value::F32(0.5)),
            Request::Set(Param::Config, Value::U32(u32::MAX)),
            Request::Get(Param::ActPos),
            Request::Motion(Motion::IRamp { pos: Ticks(i32::MIN) }, AckKind::Extended),
            Request::Motion(Motion::FRampLoop { pos: Position(1.0) }, AckKind::Simple),
            Request::Action(Action::Halt),
            Request::IStep { pos: Ticks(5), time: Millis(0) },
        ] {
            assert_eq!(good.validate(), Ok(()), "{good}");
        }
    }

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

    #[test]
    fn only_reads_are_retried_and_motions_are_known() {
        assert!(Request::Get(Param::ActPos).is_idempotent());
        assert!(!Request::Action(Action::Home).is_idempotent());
        assert!(!Request::Set(Param::TargetVel, Value::F32(1.0)).is_idempotent());
        assert!(Request::Action(Action::Home).starts_motion());
        assert!(!Request::Action(Action::Halt).starts_motion());
    }
}
