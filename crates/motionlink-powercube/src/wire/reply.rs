//! Acknowledges from a module, typed (chapter 4.4).

use std::fmt;

use super::request::{payload, Action, ModelError, Request};
use crate::model::MotionId;
use crate::model::Param;
use crate::model::Value;
use crate::model::{Dio, ShortState};
use crate::model::{Position, Ticks};
use crate::wire::{cmd, Payload, ACK_OK};

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
    /// The acknowledge `request` gets in a Profibus input image, decoded with the right length.
    pub fn from_image(request: &Request, image: &crate::wire::profibus::InputImage) -> Result<Reply, ModelError> {
        Reply::decode(&image.reply(request.ack_len()))
    }

    /// True if this is the acknowledge of `request`.
    pub fn answers(&self, request: &Request) -> bool {
        match (request, self) {
            (Request::Action(a), Reply::Action(b)) => a == b,
            (Request::Get(p), Reply::Get(q, _)) => p == q,
            (Request::Set(p, _), Reply::Set(q, _)) => p == q,
            (Request::Motion(m, ack), Reply::Motion { id, .. }) => m.id(*ack) == Some(*id),
            (Request::IStep { .. }, Reply::IStep) => true,
            _ => false,
        }
    }

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
                        AckPosition::Unit(p) => p.value().to_le_bytes(),
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
                            AckPosition::Unit(Position::native(f32::from_le_bytes(raw)))
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
            Reply::Get(p, v) => write!(f, "{p} = {}", v.show_in(*p, None)),
            Reply::Set(p, s) if *s == ACK_OK => write!(f, "{p} set"),
            Reply::Set(p, s) => write!(f, "{p} set, status 0x{s:02X}"),
            Reply::Motion { id, ext: Some(e), .. } => {
                let pos = match e.position {
                    AckPosition::Unit(p) => p.to_string(),
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

#[cfg(test)]
mod tests {
    use super::*;

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
                ext: Some(ExtAck {
                    position: AckPosition::Unit(Position::native(0.5)),
                    state: ShortState(0x10),
                    dio: Dio(0),
                }),
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
}
