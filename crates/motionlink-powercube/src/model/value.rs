//! Parameter values, typed by the parameter's data type: on the wire, parsed from text, shown with units.

use super::flags::{CubeState, Dio, ShortState};
use super::params::{DataType, Param};
use super::units::ModuleKind;

/// A parameter value, typed by its data type.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// A float.
    F32(f32),
    /// An unsigned 32-bit integer.
    U32(u32),
    /// A signed 32-bit integer.
    I32(i32),
    /// An unsigned 16-bit integer.
    U16(u16),
    /// A signed 16-bit integer.
    I16(i16),
    /// An unsigned byte.
    U8(u8),
    /// ActFPosStateDio: position, short state, DIO.
    PosStateDio {
        /// Actual position (rad or m).
        pos: f32,
        /// Short state.
        state: ShortState,
        /// Digital I/O.
        dio: Dio,
    },
    /// ActFPosTime: position and time stamp.
    PosTime {
        /// Actual position (rad or m).
        pos: f32,
        /// Milliseconds.
        time_ms: u16,
    },
}

/// A value that does not fit a parameter.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    /// The bytes are fewer than the data type needs.
    #[error("{param}: expected {expected} bytes of {ty}, got {got}")]
    Length {
        /// The parameter.
        param: &'static str,
        /// The data type's name.
        ty: &'static str,
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// A value of another type.
    #[error("{param} is {expected}, not {got}")]
    Type {
        /// The parameter.
        param: &'static str,
        /// The data type's name.
        expected: &'static str,
        /// The given value's type name.
        got: &'static str,
    },
    /// Text that is not a value of the type.
    #[error("{param}: {text:?} is not a valid {ty} value")]
    Parse {
        /// The parameter.
        param: &'static str,
        /// The data type's name.
        ty: &'static str,
        /// The text.
        text: String,
    },
}

impl Value {
    /// The data type of this value.
    pub fn data_type(&self) -> DataType {
        match self {
            Value::F32(_) => DataType::F32,
            Value::U32(_) => DataType::U32,
            Value::I32(_) => DataType::I32,
            Value::U16(_) => DataType::U16,
            Value::I16(_) => DataType::I16,
            Value::U8(_) => DataType::U8,
            Value::PosStateDio { .. } => DataType::PosStateDio,
            Value::PosTime { .. } => DataType::PosTime,
        }
    }

    /// Writes the little-endian bytes into `out` (at least 6 bytes); returns how many.
    pub fn encode(&self, out: &mut [u8; 6]) -> usize {
        match *self {
            Value::F32(v) => put(out, &v.to_le_bytes()),
            Value::U32(v) => put(out, &v.to_le_bytes()),
            Value::I32(v) => put(out, &v.to_le_bytes()),
            Value::U16(v) => put(out, &v.to_le_bytes()),
            Value::I16(v) => put(out, &v.to_le_bytes()),
            Value::U8(v) => put(out, &[v]),
            Value::PosStateDio { pos, state, dio } => {
                put(out, &pos.to_le_bytes());
                out[4] = state.0;
                out[5] = dio.0;
                6
            }
            Value::PosTime { pos, time_ms } => {
                put(out, &pos.to_le_bytes());
                out[4..6].copy_from_slice(&time_ms.to_le_bytes());
                6
            }
        }
    }

    /// Reads a value of `param`'s type from the start of `bytes`.
    pub fn decode(param: Param, bytes: &[u8]) -> Result<Value, ValueError> {
        let ty = param.data_type();
        let Some(b) = bytes.get(..ty.size()) else {
            return Err(ValueError::Length {
                param: param.name(),
                ty: ty.name(),
                expected: ty.size(),
                got: bytes.len(),
            });
        };
        let f4 = |b: &[u8]| [b[0], b[1], b[2], b[3]];
        Ok(match ty {
            DataType::F32 => Value::F32(f32::from_le_bytes(f4(b))),
            DataType::U32 => Value::U32(u32::from_le_bytes(f4(b))),
            DataType::I32 => Value::I32(i32::from_le_bytes(f4(b))),
            DataType::U16 => Value::U16(u16::from_le_bytes([b[0], b[1]])),
            DataType::I16 => Value::I16(i16::from_le_bytes([b[0], b[1]])),
            DataType::U8 => Value::U8(b[0]),
            DataType::PosStateDio => {
                Value::PosStateDio { pos: f32::from_le_bytes(f4(b)), state: ShortState(b[4]), dio: Dio(b[5]) }
            }
            DataType::PosTime => {
                Value::PosTime { pos: f32::from_le_bytes(f4(b)), time_ms: u16::from_le_bytes([b[4], b[5]]) }
            }
        })
    }

    /// Parses text as a value for `param`: a number in the parameter's type (integers also as `0x` hex).
    pub fn parse(param: Param, text: &str) -> Result<Value, ValueError> {
        let ty = param.data_type();
        let t = text.trim();
        let err = || ValueError::Parse { param: param.name(), ty: ty.name(), text: text.to_string() };
        let int = |t: &str| -> Option<i64> {
            let (neg, digits) = match t.strip_prefix('-') {
                Some(d) => (true, d),
                None => (false, t),
            };
            let v = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
                Some(h) => i64::from_str_radix(h, 16).ok()?,
                None => digits.parse::<i64>().ok()?,
            };
            Some(if neg { -v } else { v })
        };
        Ok(match ty {
            DataType::F32 => {
                let v: f32 = t.parse().map_err(|_| err())?;
                if !v.is_finite() {
                    return Err(err());
                }
                Value::F32(v)
            }
            DataType::U32 => Value::U32(int(t).and_then(|v| u32::try_from(v).ok()).ok_or_else(err)?),
            DataType::I32 => Value::I32(int(t).and_then(|v| i32::try_from(v).ok()).ok_or_else(err)?),
            DataType::U16 => Value::U16(int(t).and_then(|v| u16::try_from(v).ok()).ok_or_else(err)?),
            DataType::I16 => Value::I16(int(t).and_then(|v| i16::try_from(v).ok()).ok_or_else(err)?),
            DataType::U8 => Value::U8(int(t).and_then(|v| u8::try_from(v).ok()).ok_or_else(err)?),
            DataType::PosStateDio | DataType::PosTime => return Err(err()),
        })
    }

    /// The value as a number, for the single-number types.
    pub fn as_f64(&self) -> Option<f64> {
        Some(match *self {
            Value::F32(v) => f64::from(v),
            Value::U32(v) => f64::from(v),
            Value::I32(v) => f64::from(v),
            Value::U16(v) => f64::from(v),
            Value::I16(v) => f64::from(v),
            Value::U8(v) => f64::from(v),
            Value::PosStateDio { .. } | Value::PosTime { .. } => return None,
        })
    }

    /// The value as an unsigned word, for the unsigned integer types.
    pub fn as_u32(&self) -> Option<u32> {
        match *self {
            Value::U32(v) => Some(v),
            Value::U16(v) => Some(u32::from(v)),
            Value::U8(v) => Some(u32::from(v)),
            _ => None,
        }
    }

    /// The value as a float, if it is one.
    pub fn as_f32(&self) -> Option<f32> {
        match *self {
            Value::F32(v) => Some(v),
            _ => None,
        }
    }

    /// The value as a signed integer, if it is one.
    pub fn as_i32(&self) -> Option<i32> {
        match *self {
            Value::I32(v) => Some(v),
            Value::I16(v) => Some(i32::from(v)),
            _ => None,
        }
    }

    /// Formats the value of `param` for a person: with its unit, flag words decoded, versions as x.y.zz.
    pub fn show(&self, param: Param, kind: ModuleKind) -> String {
        self.show_in(param, Some(kind))
    }

    /// Formats the value of `param` with the unit of `kind`, or, where the kind is not known, with both
    /// ("rad|m").
    pub fn show_in(&self, param: Param, kind: Option<ModuleKind>) -> String {
        use super::flags::{ConfigWord, DioWord, SetupWord};
        use super::units::CubeVersion;
        let unit = kind.map_or(param.unit().generic_symbol(), |k| param.unit().symbol(k));
        let pos_unit = kind.map_or("rad|m", ModuleKind::unit);
        let with_unit = |s: String| if unit.is_empty() { s } else { format!("{s} {unit}") };
        match (*self, param) {
            (Value::U32(v), Param::CubeState) => format!("{v:#010x} ({})", CubeState(v)),
            (Value::U32(v), Param::Config | Param::DefConfig) => format!("{v:#010x} ({})", ConfigWord(v)),
            (Value::U32(v), Param::Setup) => format!("{v:#010x} ({})", SetupWord(v)),
            (Value::U32(v), Param::DioSetup) => format!("{v:#010x} ({})", DioWord(v)),
            (Value::U16(v), Param::DefCubeVersion) => format!("{} ({v:#06x})", CubeVersion(v)),
            (Value::F32(v), _) => with_unit(format!("{v:.6}")),
            (Value::PosStateDio { pos, state, dio }, _) => {
                format!("{pos:.6} {pos_unit}, state {state}, dio {dio}")
            }
            (Value::PosTime { pos, time_ms }, _) => format!("{pos:.6} {pos_unit} at {time_ms} ms"),
            (v, _) => with_unit(v.as_f64().map_or_else(String::new, |n| format!("{n}"))),
        }
    }

    fn type_name(&self) -> &'static str {
        self.data_type().name()
    }

    /// Checks that this value has `param`'s data type.
    pub fn check_type(&self, param: Param) -> Result<(), ValueError> {
        if self.data_type() == param.data_type() {
            Ok(())
        } else {
            Err(ValueError::Type { param: param.name(), expected: param.data_type().name(), got: self.type_name() })
        }
    }
}

fn put(out: &mut [u8; 6], bytes: &[u8]) -> usize {
    out[..bytes.len()].copy_from_slice(bytes);
    bytes.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_and_parse() {
        let mut buf = [0u8; 6];
        for (p, v) in [
            (Param::TargetAcc, Value::F32(0.5)),
            (Param::CubeState, Value::U32(0x8002)),
            (Param::ActIPos, Value::I32(-12345)),
            (Param::DefCubeVersion, Value::U16(0x351D)),
            (Param::RawCur, Value::I16(-500)),
            (Param::DefAddress, Value::U8(17)),
            (Param::ActFPosStateDio, Value::PosStateDio { pos: 1.0, state: ShortState(0x20), dio: Dio(0x11) }),
            (Param::ActFPosTime, Value::PosTime { pos: -1.0, time_ms: 999 }),
        ] {
            let n = v.encode(&mut buf);
            assert_eq!(n, p.data_type().size());
            assert_eq!(Value::decode(p, &buf[..n]).unwrap(), v);
            assert!(v.check_type(p).is_ok());
        }
        assert_eq!(Value::parse(Param::TargetAcc, "0.5").unwrap(), Value::F32(0.5));
        assert_eq!(Value::parse(Param::Config, "0x01000000").unwrap(), Value::U32(0x0100_0000));
        assert_eq!(Value::parse(Param::ActIMinPos, "-100").unwrap(), Value::I32(-100));
        assert!(Value::parse(Param::DefAddress, "256").is_err());
        assert!(Value::parse(Param::MaxVel, "fast").is_err());
        assert!(Value::parse(Param::MaxVel, "inf").is_err());
        assert!(Value::decode(Param::ActPos, &[1, 2]).is_err());
        assert!(Value::U8(1).check_type(Param::ActPos).is_err());
    }

    #[test]
    fn values_show_units_and_flags() {
        assert_eq!(Value::F32(1.0).show(Param::ActPos, ModuleKind::Rotary), "1.000000 rad");
        assert_eq!(Value::F32(1.0).show(Param::ActVel, ModuleKind::Linear), "1.000000 m/s");
        assert_eq!(Value::U16(0x351D).show(Param::DefCubeVersion, ModuleKind::Rotary), "3.5.1D (0x351d)");
        assert_eq!(
            Value::U32(0x8002).show(Param::CubeState, ModuleKind::Rotary),
            "0x00008002 (STATE_HOME_OK | STATE_RAMP_END)"
        );
    }
}
