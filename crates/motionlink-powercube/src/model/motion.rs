//! The 18 motion modes (chapter 4.5), from one table, and typed motion commands.
//!
//! ```
//! use motionlink_powercube::model::{AckKind, Motion, MotionId, Position};
//! let m = Motion::FRamp { pos: Position::rad(0.5) };
//! assert_eq!(m.id(AckKind::Simple), Some(MotionId::FRamp));
//! assert_eq!(m.id(AckKind::Extended), Some(MotionId::FRampAck));
//! assert_eq!(MotionId::FRampAck.code(), 14);
//! ```

use super::units::{Acceleration, Amperes, AxisUnit, CurrentDigits, Millis, Position, Ticks, TicksPerSec, Velocity};
use crate::wire::{ModelError, RAW_CUR_MAX};

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

impl MotionId {
    /// The mode named `name`: the manual's name, in any case, with or without `_MODE` ("fvel", "FVEL_MODE",
    /// "fvel_ack", "fcosloop", "FRAMPLOOP"). An `_ACK` name takes no `_MODE`. `None` for anything else.
    ///
    /// ```
    /// use motionlink_powercube::model::MotionId;
    /// assert_eq!(MotionId::parse("fvel"), Some(MotionId::FVel));
    /// assert_eq!(MotionId::parse("FStep_Ack"), Some(MotionId::FStepAck));
    /// assert_eq!(MotionId::parse("fvelx"), None);
    /// ```
    pub fn parse(name: &str) -> Option<MotionId> {
        let wanted = name.trim().to_ascii_uppercase();
        let (bare, with_mode) = match wanted.strip_suffix("_MODE") {
            Some(bare) => (bare, true),
            None => (wanted.as_str(), false),
        };
        MotionId::ALL.iter().copied().find(|id| {
            let base = id.name().strip_suffix("_MODE").unwrap_or(id.name());
            base == bare && !(with_mode && base.ends_with("_ACK"))
        })
    }

    /// What a command of this mode takes, in words (the manual's table, 4.5).
    pub fn takes(self) -> &'static str {
        match self.shape() {
            MotionShape::FPos if self.continuous() => "the loop's far end (rad or m) and no time",
            MotionShape::FPos => "a target position (rad or m) and no time",
            MotionShape::FPosTime if self.continuous() => {
                "the loop's far end (rad or m) and its period, a time in ms (1..65535)"
            }
            MotionShape::FPosTime => "a target position (rad or m) and a time in ms (1..65535)",
            MotionShape::FVel => "a velocity (rad/s or m/s) and no time",
            MotionShape::FCur => "a current in A and no time",
            MotionShape::IPos => "a target position in whole encoder ticks (Int32) and no time",
            MotionShape::IPosTime => "a target position in whole encoder ticks (Int32) and a time in ms (1..65535)",
            MotionShape::IVel => "a velocity in whole encoder ticks/s (Int32) and no time",
            MotionShape::ICur => "a current in whole digits within -500..500 and no time",
        }
    }

    /// True for a mode that takes a time besides its position: FSTEP, ISTEP (and their `_ACK` forms) and
    /// FCOSLOOP.
    pub fn takes_time(self) -> bool {
        matches!(self.shape(), MotionShape::FPosTime | MotionShape::IPosTime)
    }

    /// True for a mode that runs until something ends it: velocity, current and the two loops. False for
    /// the position modes (FRAMP, FSTEP, IRAMP, ISTEP and their `_ACK` forms), which end at their target.
    pub fn continuous(self) -> bool {
        !matches!(
            self,
            MotionId::FRamp
                | MotionId::FRampAck
                | MotionId::FStep
                | MotionId::FStepAck
                | MotionId::IRamp
                | MotionId::IRampAck
                | MotionId::IStep
                | MotionId::IStepAck
        )
    }
}

/// [`MotionId::parse`], with an error naming the modes there are.
impl std::str::FromStr for MotionId {
    type Err = ModelError;
    fn from_str(name: &str) -> Result<MotionId, ModelError> {
        MotionId::parse(name).ok_or_else(|| ModelError::UnknownMotionName(name.to_string()))
    }
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
        let simple = self.mode();
        match ack {
            AckKind::Simple => Some(simple),
            AckKind::Extended => match simple {
                M::FRamp => Some(M::FRampAck),
                M::FStep => Some(M::FStepAck),
                M::FVel => Some(M::FVelAck),
                M::FCur => Some(M::FCurAck),
                M::IRamp => Some(M::IRampAck),
                M::IStep => Some(M::IStepAck),
                M::IVel => Some(M::IVelAck),
                M::ICur => Some(M::ICurAck),
                _ => None,
            },
        }
    }

    /// The motion command of mode `id` with the number `value` and, for the modes that take one
    /// ([`MotionId::takes_time`]), the time `time_ms`; with the acknowledge the MotionID asks for (the
    /// `_ACK` ids: [`AckKind::Extended`]). `unit` is the unit of a float position or velocity (rad, m, or
    /// the module's own); the tick, digit and ampere modes have their own.
    ///
    /// Refused, naming the mode and what it takes ([`ModelError::MotionArgument`]): no time for a mode that
    /// needs one, or a time of 0 ms; a time for a mode that takes none; a number that is not finite, beyond
    /// a 32-bit float, or for the I modes not a whole number within its type (ICUR: -500..500 digits,
    /// [`RAW_CUR_MAX`]).
    ///
    /// ```
    /// use motionlink_powercube::model::{AckKind, AxisUnit, Millis, Motion, MotionId, Position};
    /// let (m, ack) = Motion::from_id(MotionId::FStepAck, 0.5, Some(800), AxisUnit::Radian).unwrap();
    /// assert_eq!((m, ack), (Motion::FStep { pos: Position::rad(0.5), time: Millis(800) }, AckKind::Extended));
    /// let e = Motion::from_id(MotionId::FStep, 0.5, None, AxisUnit::ModuleUnit).unwrap_err();
    /// assert!(e.to_string().starts_with("FSTEP_MODE takes a target position"), "{e}");
    /// ```
    pub fn from_id(
        id: MotionId,
        value: f64,
        time_ms: Option<u16>,
        unit: AxisUnit,
    ) -> Result<(Motion, AckKind), ModelError> {
        let bad = |problem: String| ModelError::MotionArgument { mode: id.name(), takes: id.takes(), problem };
        let time = match (id.takes_time(), time_ms) {
            (true, None) => return Err(bad("no time was given".into())),
            (true, Some(0)) => return Err(bad("a time of 0 ms was given (a motion in no time cannot be done)".into())),
            (true, Some(t)) => Millis(t),
            (false, Some(t)) => {
                return Err(bad(format!("a time of {t} ms was given (only FSTEP, ISTEP and FCOSLOOP take a time)")))
            }
            (false, None) => Millis(0),
        };
        if !value.is_finite() {
            return Err(bad(format!("{value} is not a finite number")));
        }
        let float = || {
            let narrow = value as f32;
            if narrow.is_finite() {
                Ok(narrow)
            } else {
                Err(bad(format!("{value:e} is beyond the module's 32-bit float range (about 3.4e38)")))
            }
        };
        let whole = |min: i64, max: i64| {
            if value.fract() != 0.0 {
                Err(bad(format!("{value} is not a whole number")))
            } else if value < min as f64 || value > max as f64 {
                Err(bad(format!("{value} is outside {min}..{max}")))
            } else {
                Ok(value as i64)
            }
        };
        let int32 = || whole(i64::from(i32::MIN), i64::from(i32::MAX)).map(|v| v as i32);
        use MotionId as M;
        let motion = match id {
            M::FRamp | M::FRampAck => Motion::FRamp { pos: Position::new(float()?, unit) },
            M::FStep | M::FStepAck => Motion::FStep { pos: Position::new(float()?, unit), time },
            M::FVel | M::FVelAck => Motion::FVel { vel: Velocity::new(float()?, unit) },
            M::FCur | M::FCurAck => Motion::FCur { cur: Amperes(float()?) },
            M::IRamp | M::IRampAck => Motion::IRamp { pos: Ticks(int32()?) },
            M::IStep | M::IStepAck => Motion::IStep { pos: Ticks(int32()?), time },
            M::IVel | M::IVelAck => Motion::IVel { vel: TicksPerSec(int32()?) },
            M::ICur | M::ICurAck => {
                let max = i64::from(RAW_CUR_MAX);
                Motion::ICur { cur: CurrentDigits(whole(-max, max)? as i16) }
            }
            M::FCosLoop => Motion::FCosLoop { pos: Position::new(float()?, unit), time },
            M::FRampLoop => Motion::FRampLoop { pos: Position::new(float()?, unit) },
        };
        Ok((motion, id.ack()))
    }

    /// The MotionID of this mode with the simple acknowledge (FRAMP_MODE for [`Motion::FRamp`]).
    pub fn mode(&self) -> MotionId {
        match self {
            Motion::FRamp { .. } => MotionId::FRamp,
            Motion::FStep { .. } => MotionId::FStep,
            Motion::FVel { .. } => MotionId::FVel,
            Motion::FCur { .. } => MotionId::FCur,
            Motion::IRamp { .. } => MotionId::IRamp,
            Motion::IStep { .. } => MotionId::IStep,
            Motion::IVel { .. } => MotionId::IVel,
            Motion::ICur { .. } => MotionId::ICur,
            Motion::FCosLoop { .. } => MotionId::FCosLoop,
            Motion::FRampLoop { .. } => MotionId::FRampLoop,
        }
    }

    /// True for a motion that runs until something ends it (see [`MotionId::continuous`]).
    pub fn continuous(&self) -> bool {
        self.mode().continuous()
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

    #[test]
    fn modes_parse_by_the_manuals_names_in_any_case_with_or_without_mode() {
        for (name, id) in [
            ("fvel", MotionId::FVel),
            ("FVEL_MODE", MotionId::FVel),
            ("fvel_ack", MotionId::FVelAck),
            ("fcosloop", MotionId::FCosLoop),
            ("FCOSLOOP_MODE", MotionId::FCosLoop),
            ("FRAMPLOOP", MotionId::FRampLoop),
            (" iStep_Mode ", MotionId::IStep),
            ("ICUR_ACK", MotionId::ICurAck),
        ] {
            assert_eq!(MotionId::parse(name), Some(id), "{name}");
        }
        for bad in ["fvelx", "", "_MODE", "FVEL_ACK_MODE", "ramp", "4", "FRAMP_MODE_MODE"] {
            assert_eq!(MotionId::parse(bad), None, "{bad}");
        }
        assert_eq!("Fvel_Ack".parse::<MotionId>(), Ok(MotionId::FVelAck));
        let e = "velocity".parse::<MotionId>().unwrap_err().to_string();
        assert!(e.starts_with("unknown motion mode \"velocity\": one of FRAMP, FSTEP, FVEL"), "{e}");
        for id in MotionId::ALL {
            assert_eq!(MotionId::parse(id.name()), Some(*id), "every name of the table parses");
            assert_eq!(MotionId::parse(&id.name().to_lowercase()), Some(*id));
        }
    }

    #[test]
    fn a_motion_is_built_from_a_mode_and_numbers_or_refused_naming_the_mode() {
        let unit = AxisUnit::ModuleUnit;
        assert_eq!(
            Motion::from_id(MotionId::FVel, -0.25, None, AxisUnit::Radian).unwrap(),
            (Motion::FVel { vel: Velocity::rad_per_s(-0.25) }, AckKind::Simple)
        );
        assert_eq!(
            Motion::from_id(MotionId::IStepAck, -4096.0, Some(20), unit).unwrap(),
            (Motion::IStep { pos: Ticks(-4096), time: Millis(20) }, AckKind::Extended)
        );
        assert_eq!(
            Motion::from_id(MotionId::ICurAck, -500.0, None, unit).unwrap(),
            (Motion::ICur { cur: CurrentDigits(-500) }, AckKind::Extended)
        );
        assert_eq!(
            Motion::from_id(MotionId::FCosLoop, 1.0, Some(2000), unit).unwrap(),
            (Motion::FCosLoop { pos: Position::native(1.0), time: Millis(2000) }, AckKind::Simple)
        );
        let says = |id, value, time| Motion::from_id(id, value, time, unit).unwrap_err().to_string();
        assert_eq!(
            says(MotionId::FStep, 0.5, None),
            "FSTEP_MODE takes a target position (rad or m) and a time in ms (1..65535): no time was given"
        );
        assert_eq!(
            says(MotionId::FVel, 0.5, Some(500)),
            "FVEL_MODE takes a velocity (rad/s or m/s) and no time: a time of 500 ms was given (only FSTEP, ISTEP \
             and FCOSLOOP take a time)"
        );
        assert!(says(MotionId::FCosLoop, 0.5, Some(0)).starts_with("FCOSLOOP takes the loop's far end"));
        assert!(says(MotionId::IStep, 1.0, Some(0)).contains("a time of 0 ms"));
        assert!(says(MotionId::IRamp, 1.5, None).ends_with("1.5 is not a whole number"));
        assert!(says(MotionId::IVel, 3e9, None).ends_with("3000000000 is outside -2147483648..2147483647"));
        assert_eq!(
            says(MotionId::ICur, 501.0, None),
            "ICUR_MODE takes a current in whole digits within -500..500 and no time: 501 is outside -500..500"
        );
        assert!(says(MotionId::FCur, f64::NAN, None).ends_with("NaN is not a finite number"));
        assert!(says(MotionId::FRamp, 1e39, None).contains("32-bit float range"));
    }
}
