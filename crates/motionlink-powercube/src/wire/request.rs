//! Commands, acknowledges and broadcasts, typed, with their payloads (chapter 4.4).
//!
//! ```
//! use motionlink_powercube::model::{Param, Value};
//! use motionlink_powercube::wire::{Reply, Request};
//! let req = Request::set(Param::TargetAcc, Value::F32(0.5)).unwrap();
//! assert_eq!(req.encode().as_bytes(), &[0x08, 0x50, 0x00, 0x00, 0x00, 0x3f]);
//! let ack = Reply::decode(&motionlink_powercube::wire::Payload::new(&[0x08, 0x50, 0x64]).unwrap()).unwrap();
//! assert!(ack.answers(&req));
//! // No writing to a read-only parameter, no reading a write-only one.
//! assert!(Request::set(Param::ActPos, Value::F32(0.0)).is_err());
//! assert!(Request::get(Param::TargetVel).is_err());
//! ```

use std::fmt;

use crate::model::Param;
use crate::model::ProfibusState;
use crate::model::{AckKind, Motion, MotionId};
use crate::model::{Millis, Ticks};
use crate::model::{Value, ValueError};
use crate::wire::{cmd, Payload};

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

    pub(crate) fn from_code(code: u8) -> Option<Action> {
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

/// The largest commanded current in digits, either way (RawCur, "[-500...+500]", manual 7.2).
pub const RAW_CUR_MAX: i16 = 500;

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
    /// A motion mode's name that is none of the manual's ([`MotionId::parse`](crate::model::MotionId::parse)).
    #[error(
        "unknown motion mode \"{0}\": one of FRAMP, FSTEP, FVEL, FCUR, IRAMP, ISTEP, IVEL, ICUR (any case, _MODE \
         optional; _ACK after any of them for the extended acknowledge), FCOSLOOP, FRAMPLOOP"
    )]
    UnknownMotionName(String),
    /// A motion command built from a mode and numbers ([`Motion::from_id`]) that the mode does not take:
    /// a time it has none of, no time where it needs one, a number that is no integer of its type.
    #[error("{mode} takes {takes}: {problem}")]
    MotionArgument {
        /// The manual's name of the mode (FSTEP_MODE).
        mode: &'static str,
        /// What the mode takes ([`MotionId::takes`]).
        takes: &'static str,
        /// What was wrong with what was given.
        problem: String,
    },
    /// A value outside the range the manual gives the parameter (RawCur: -500..500 digits).
    #[error("{param} {value} is outside the manual's range {range}")]
    OutOfRange {
        /// The parameter.
        param: Param,
        /// The value given.
        value: String,
        /// The manual's range.
        range: &'static str,
    },
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

/// A payload of `parts` (every request, reply and broadcast built in this crate is at most 8 bytes).
pub(crate) fn payload(parts: &[&[u8]]) -> Payload {
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
                    // "Commanded Current in Digits [-500...+500]" (7.2).
                    Value::I16(v) if param == Param::RawCur && !(-RAW_CUR_MAX..=RAW_CUR_MAX).contains(&v) => {
                        Err(ModelError::OutOfRange { param, value: v.to_string(), range: "-500..500 digits" })
                    }
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
            Request::Set(p, v) => write!(f, "SetExtended {p} = {}", v.show_in(*p, None)),
            Request::Motion(m, ack) => {
                let name = m.id(*ack).map_or("?", MotionId::name);
                write!(f, "SetMotion {name} {}", m.describe())
            }
            Request::IStep { pos, time } => write!(f, "SetIStep to {} ticks in {} ms", pos.0, time.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ValueError;
    use crate::model::{Acceleration, Position, Velocity};
    use crate::model::{Amperes, CurrentDigits, TicksPerSec};
    use crate::wire::Reply;

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
            Motion::FRamp { pos: Position::native(1.0) },
            Motion::FStep { pos: Position::native(1.0), time: Millis(10) },
            Motion::FVel { vel: Velocity::native(1.0) },
            Motion::FCur { cur: Amperes(1.0) },
            Motion::IRamp { pos: Ticks(1) },
            Motion::IStep { pos: Ticks(1), time: Millis(1) },
            Motion::IVel { vel: TicksPerSec(1) },
            Motion::ICur { cur: CurrentDigits(1) },
            Motion::FCosLoop { pos: Position::native(1.0), time: Millis(10) },
            Motion::FRampLoop { pos: Position::native(1.0) },
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
        let _ = Acceleration::native(0.0);
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
        assert!(Request::motion(Motion::FRampLoop { pos: Position::native(0.0) }, AckKind::Extended).is_err());
        assert!(Request::set(Param::TargetVel, Value::U32(1)).is_err());
    }

    #[test]
    fn validate_applies_the_constructors_rules_to_any_request() {
        let bad = [
            (Request::Set(Param::ActPos, Value::F32(0.0)), ModelError::NotWritable(Param::ActPos)),
            (Request::Get(Param::TargetVel), ModelError::NotReadable(Param::TargetVel)),
            (Request::Set(Param::TargetVel, Value::F32(f32::NAN)), ModelError::NotFinite("TargetVel")),
            (Request::Set(Param::MaxPos, Value::F32(f32::INFINITY)), ModelError::NotFinite("MaxPos")),
            // RawCur: "Commanded Current in Digits [-500...+500]".
            (
                Request::Set(Param::RawCur, Value::I16(501)),
                ModelError::OutOfRange { param: Param::RawCur, value: "501".into(), range: "-500..500 digits" },
            ),
            (
                Request::Set(Param::RawCur, Value::I16(-2000)),
                ModelError::OutOfRange { param: Param::RawCur, value: "-2000".into(), range: "-500..500 digits" },
            ),
            (
                Request::Motion(Motion::FCosLoop { pos: Position::native(1.0), time: Millis(10) }, AckKind::Extended),
                ModelError::NoExtendedAck("FCOSLOOP"),
            ),
            (
                Request::Motion(Motion::FRamp { pos: Position::native(f32::NAN) }, AckKind::Simple),
                ModelError::NotFinite("FRAMP_MODE"),
            ),
            (
                Request::Motion(Motion::FVel { vel: Velocity::native(f32::NEG_INFINITY) }, AckKind::Extended),
                ModelError::NotFinite("FVEL_ACK"),
            ),
        ];
        for (req, err) in bad {
            assert_eq!(req.validate(), Err(err), "{req}");
        }
        assert!(
            Request::set(Param::RawCur, Value::I16(-500)).is_ok()
                && Request::set(Param::RawCur, Value::I16(500)).is_ok()
        );
        assert!(matches!(
            Request::Set(Param::MaxVel, Value::U32(1)).validate(),
            Err(ModelError::Value(ValueError::Type { .. }))
        ));
        // The constructors say the same.
        assert_eq!(Request::set(Param::TargetVel, Value::F32(f32::NAN)), Err(ModelError::NotFinite("TargetVel")));
        assert!(Request::motion(Motion::FRamp { pos: Position::native(f32::INFINITY) }, AckKind::Simple).is_err());
        for good in [
            Request::Set(Param::TargetVel, Value::F32(0.5)),
            Request::Set(Param::Config, Value::U32(u32::MAX)),
            Request::Get(Param::ActPos),
            Request::Motion(Motion::IRamp { pos: Ticks(i32::MIN) }, AckKind::Extended),
            Request::Motion(Motion::FRampLoop { pos: Position::native(1.0) }, AckKind::Simple),
            Request::Action(Action::Halt),
            Request::IStep { pos: Ticks(5), time: Millis(0) },
        ] {
            assert_eq!(good.validate(), Ok(()), "{good}");
        }
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
