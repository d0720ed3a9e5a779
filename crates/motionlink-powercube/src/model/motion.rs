//! The 18 motion modes (chapter 4.5), from one table, and typed motion commands.
//!
//! ```
//! use motionlink_powercube::model::{AckKind, Motion, MotionId, Position};
//! let m = Motion::FRamp { pos: Position::rad(0.5) };
//! assert_eq!(m.id(AckKind::Simple), Some(MotionId::FRamp));
//! assert_eq!(m.id(AckKind::Extended), Some(MotionId::FRampAck));
//! assert_eq!(MotionId::FRampAck.code(), 14);
//! ```

use super::units::{Acceleration, Amperes, CurrentDigits, Millis, Position, Ticks, TicksPerSec, Velocity};

/// What a motion command's parameters are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MotionShape {
    /// A float position (rad or m).
    FPos,
    /// A float position and a UInt16 time in ms.
    FPosTime,
    /// A float velocity.
    FVel,
    /// A float current in A.
    FCur,
    /// An Int32 position in ticks.
    IPos,
    /// An Int32 position in ticks and a UInt16 time in ms.
    IPosTime,
    /// An Int32 velocity in ticks/s.
    IVel,
    /// An Int16 current in digits.
    ICur,
}

impl MotionShape {
    /// Bytes of parameters.
    pub fn size(self) -> usize {
        match self {
            MotionShape::FPos | MotionShape::FVel | MotionShape::FCur | MotionShape::IPos | MotionShape::IVel => 4,
            MotionShape::FPosTime | MotionShape::IPosTime => 6,
            MotionShape::ICur => 2,
        }
    }

    /// True if the extended acknowledge carries the position as a float.
    pub fn float_position(self) -> bool {
        matches!(self, MotionShape::FPos | MotionShape::FPosTime | MotionShape::FVel | MotionShape::FCur)
    }
}

/// Which acknowledge a motion command asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum AckKind {
    /// `[0x0b][motionID][0x64]`.
    #[default]
    Simple,
    /// `[0x0b][motionID][position][short state][dio]` (OS above 2.5.16 / 3.5.13).
    Extended,
}

macro_rules! motion_table {
    ( $( $var:ident = ($code:literal, $name:literal, $shape:ident, $ack:ident, $doc:literal) ),* $(,)? ) => {
        /// A MotionID: the mode of a SetMotion command.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum MotionId {
            $( #[doc = $doc] $var ),*
        }

        impl MotionId {
            /// All 18 modes.
            pub const ALL: &'static [MotionId] = &[$(MotionId::$var),*];

            /// The MotionID byte.
            pub fn code(self) -> u8 {
                match self { $(MotionId::$var => $code),* }
            }

            /// The manual's name.
            pub fn name(self) -> &'static str {
                match self { $(MotionId::$var => $name),* }
            }

            /// The parameters.
            pub fn shape(self) -> MotionShape {
                match self { $(MotionId::$var => MotionShape::$shape),* }
            }

            /// The acknowledge the mode gets.
            pub fn ack(self) -> AckKind {
                match self { $(MotionId::$var => AckKind::$ack),* }
            }

            /// The mode with this MotionID byte.
            pub fn from_code(code: u8) -> Option<MotionId> {
                match code { $($code => Some(MotionId::$var),)* _ => None }
            }
        }
    };
}

motion_table! {
    FRamp = (4, "FRAMP_MODE", FPos, Simple, "Ramp to a position (rad or m)."),
    FStep = (6, "FSTEP_MODE", FPosTime, Simple, "Step to a position in a given time."),
    FVel = (7, "FVEL_MODE", FVel, Simple, "Velocity (rad/s or m/s)."),
    FCur = (8, "FCUR_MODE", FCur, Simple, "Current (A)."),
    IRamp = (9, "IRAMP_MODE", IPos, Simple, "Ramp to a position in ticks."),
    IStep = (11, "ISTEP_MODE", IPosTime, Simple, "Step to a position in ticks in a given time."),
    IVel = (12, "IVEL_MODE", IVel, Simple, "Velocity in ticks/s."),
    ICur = (13, "ICUR_MODE", ICur, Simple, "Current in digits."),
    FRampAck = (14, "FRAMP_ACK", FPos, Extended, "FRAMP_MODE with extended acknowledge."),
    FStepAck = (16, "FSTEP_ACK", FPosTime, Extended, "FSTEP_MODE with extended acknowledge."),
    FVelAck = (17, "FVEL_ACK", FVel, Extended, "FVEL_MODE with extended acknowledge."),
    FCurAck = (18, "FCUR_ACK", FCur, Extended, "FCUR_MODE with extended acknowledge."),
    IRampAck = (19, "IRAMP_ACK", IPos, Extended, "IRAMP_MODE with extended acknowledge."),
    IStepAck = (21, "ISTEP_ACK", IPosTime, Extended, "ISTEP_MODE with extended acknowledge."),
    IVelAck = (22, "IVEL_ACK", IVel, Extended, "IVEL_MODE with extended acknowledge."),
    ICurAck = (23, "ICUR_ACK", ICur, Extended, "ICUR_MODE with extended acknowledge."),
    FCosLoop = (24, "FCOSLOOP", FPosTime, Simple, "Cosine loop to a position and back, period in ms (v4630)."),
    FRampLoop = (25, "FRAMPLOOP", FPos, Simple, "Ramp loop to a position and back (v4630)."),
}

/// A motion command's mode and parameters, typed. With an [`AckKind`] it makes one of the 18 MotionIDs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Ramp (trapezoid from TargetVel and TargetAcc) to a position.
    FRamp {
        /// Target position.
        pos: Position,
    },
    /// Step to a position in a time.
    FStep {
        /// Target position.
        pos: Position,
        /// Time to get there.
        time: Millis,
    },
    /// Move at a velocity.
    FVel {
        /// Velocity.
        vel: Velocity,
    },
    /// Drive a current.
    FCur {
        /// Current.
        cur: Amperes,
    },
    /// Ramp to a position in ticks.
    IRamp {
        /// Target position.
        pos: Ticks,
    },
    /// Step to a position in ticks in a time.
    IStep {
        /// Target position.
        pos: Ticks,
        /// Time to get there.
        time: Millis,
    },
    /// Move at a velocity in ticks/s.
    IVel {
        /// Velocity.
        vel: TicksPerSec,
    },
    /// Drive a current in digits.
    ICur {
        /// Current.
        cur: CurrentDigits,
    },
    /// Loop between the current position and `pos` on a cosine, period `time` (simple acknowledge only).
    FCosLoop {
        /// The far end of the loop.
        pos: Position,
        /// Period.
        time: Millis,
    },
    /// Ramp back and forth between the current position and `pos` (simple acknowledge only).
    FRampLoop {
        /// The far end of the loop.
        pos: Position,
    },
}

impl Motion {
    /// The MotionID for this mode with acknowledge `ack`; `None` for the loops with an extended one.
    pub fn id(&self, ack: AckKind) -> Option<MotionId> {
        use MotionId as M;
        let (simple, extended) = match self {
            Motion::FRamp { .. } => (M::FRamp, Some(M::FRampAck)),
            Motion::FStep { .. } => (M::FStep, Some(M::FStepAck)),
            Motion::FVel { .. } => (M::FVel, Some(M::FVelAck)),
            Motion::FCur { .. } => (M::FCur, Some(M::FCurAck)),
            Motion::IRamp { .. } => (M::IRamp, Some(M::IRampAck)),
            Motion::IStep { .. } => (M::IStep, Some(M::IStepAck)),
            Motion::IVel { .. } => (M::IVel, Some(M::IVelAck)),
            Motion::ICur { .. } => (M::ICur, Some(M::ICurAck)),
            Motion::FCosLoop { .. } => (M::FCosLoop, None),
            Motion::FRampLoop { .. } => (M::FRampLoop, None),
        };
        match ack {
            AckKind::Simple => Some(simple),
            AckKind::Extended => extended,
        }
    }

    /// False if a float parameter (position, velocity, current) is NaN or infinite.
    pub fn is_finite(&self) -> bool {
        match *self {
            Motion::FRamp { pos } | Motion::FRampLoop { pos } => pos.value().is_finite(),
            Motion::FStep { pos, .. } | Motion::FCosLoop { pos, .. } => pos.value().is_finite(),
            Motion::FVel { vel } => vel.value().is_finite(),
            Motion::FCur { cur } => cur.0.is_finite(),
            Motion::IRamp { .. } | Motion::IStep { .. } | Motion::IVel { .. } | Motion::ICur { .. } => true,
        }
    }

    /// Writes the parameters (little-endian) into `out`; returns how many bytes.
    pub fn encode_params(&self, out: &mut [u8; 6]) -> usize {
        let mut put = |parts: &[&[u8]]| {
            let mut n = 0;
            for p in parts {
                out[n..n + p.len()].copy_from_slice(p);
                n += p.len();
            }
            n
        };
        match *self {
            Motion::FRamp { pos } | Motion::FRampLoop { pos } => put(&[&pos.value().to_le_bytes()]),
            Motion::FStep { pos, time } | Motion::FCosLoop { pos, time } => {
                put(&[&pos.value().to_le_bytes(), &time.0.to_le_bytes()])
            }
            Motion::FVel { vel } => put(&[&vel.value().to_le_bytes()]),
            Motion::FCur { cur } => put(&[&cur.0.to_le_bytes()]),
            Motion::IRamp { pos } => put(&[&pos.0.to_le_bytes()]),
            Motion::IStep { pos, time } => put(&[&pos.0.to_le_bytes(), &time.0.to_le_bytes()]),
            Motion::IVel { vel } => put(&[&vel.0.to_le_bytes()]),
            Motion::ICur { cur } => put(&[&cur.0.to_le_bytes()]),
        }
    }

    /// Reads the parameters of mode `id` from `bytes` (exactly the mode's size). Positions and velocities
    /// are in the module's own unit ([`AxisUnit::ModuleUnit`](super::AxisUnit::ModuleUnit)): the bytes do not
    /// say which.
    pub fn decode_params(id: MotionId, bytes: &[u8]) -> Option<Motion> {
        if bytes.len() != id.shape().size() {
            return None;
        }
        let f = || f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        let i = || i32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        let t = || Millis(u16::from_le_bytes([bytes[4], bytes[5]]));
        use MotionId as M;
        Some(match id {
            M::FRamp | M::FRampAck => Motion::FRamp { pos: Position::native(f()) },
            M::FStep | M::FStepAck => Motion::FStep { pos: Position::native(f()), time: t() },
            M::FVel | M::FVelAck => Motion::FVel { vel: Velocity::native(f()) },
            M::FCur | M::FCurAck => Motion::FCur { cur: Amperes(f()) },
            M::IRamp | M::IRampAck => Motion::IRamp { pos: Ticks(i()) },
            M::IStep | M::IStepAck => Motion::IStep { pos: Ticks(i()), time: t() },
            M::IVel | M::IVelAck => Motion::IVel { vel: TicksPerSec(i()) },
            M::ICur | M::ICurAck => Motion::ICur { cur: CurrentDigits(i16::from_le_bytes([bytes[0], bytes[1]])) },
            M::FCosLoop => Motion::FCosLoop { pos: Position::native(f()), time: t() },
            M::FRampLoop => Motion::FRampLoop { pos: Position::native(f()) },
        })
    }

    /// A short description: `FRAMP to 0.5`.
    pub fn describe(&self) -> String {
        match *self {
            Motion::FRamp { pos } => format!("ramp to {}", pos.value()),
            Motion::FStep { pos, time } => format!("step to {} in {} ms", pos.value(), time.0),
            Motion::FVel { vel } => format!("velocity {}", vel.value()),
            Motion::FCur { cur } => format!("current {} A", cur.0),
            Motion::IRamp { pos } => format!("ramp to {} ticks", pos.0),
            Motion::IStep { pos, time } => format!("step to {} ticks in {} ms", pos.0, time.0),
            Motion::IVel { vel } => format!("velocity {} ticks/s", vel.0),
            Motion::ICur { cur } => format!("current {} digits", cur.0),
            Motion::FCosLoop { pos, time } => format!("cosine loop to {} period {} ms", pos.value(), time.0),
            Motion::FRampLoop { pos } => format!("ramp loop to {}", pos.value()),
        }
    }
}

/// Ramp parameters for a move: velocity and acceleration in the module's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    /// Velocity (TargetVel).
    pub vel: Velocity,
    /// Acceleration (TargetAcc).
    pub acc: Acceleration,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eighteen_modes_with_distinct_codes() {
        assert_eq!(MotionId::ALL.len(), 18);
        for m in MotionId::ALL {
            assert_eq!(MotionId::from_code(m.code()), Some(*m));
            // SetMotion is 6..8 bytes.
            assert!((4..=8).contains(&(2 + m.shape().size())), "{m:?}");
        }
        assert_eq!(MotionId::from_code(5), None);
    }

    #[test]
    fn parameters_round_trip_in_every_mode() {
        let motions = [
            Motion::FRamp { pos: Position::native(0.5) },
            Motion::FStep { pos: Position::native(-0.25), time: Millis(1000) },
            Motion::FVel { vel: Velocity::native(0.1) },
            Motion::FCur { cur: Amperes(1.5) },
            Motion::IRamp { pos: Ticks(-4096) },
            Motion::IStep { pos: Ticks(100), time: Millis(20) },
            Motion::IVel { vel: TicksPerSec(-300) },
            Motion::ICur { cur: CurrentDigits(-250) },
            Motion::FCosLoop { pos: Position::native(1.0), time: Millis(2000) },
            Motion::FRampLoop { pos: Position::native(1.0) },
        ];
        let mut ids = 0;
        for m in motions {
            for ack in [AckKind::Simple, AckKind::Extended] {
                let Some(id) = m.id(ack) else { continue };
                ids += 1;
                assert_eq!(id.ack(), ack);
                let mut buf = [0u8; 6];
                let n = m.encode_params(&mut buf);
                assert_eq!(n, id.shape().size());
                assert_eq!(Motion::decode_params(id, &buf[..n]), Some(m));
            }
        }
        assert_eq!(ids, 18, "every MotionID is reachable");
    }
}
