//! Typed values of data-list entries: decoded from and encoded to their bytes, parsed from text, checked
//! against their range before they are sent.
//!
//! ```
//! use motionlink_scu::model::{lookup, Item};
//! use motionlink_scu::value::{SpeedMode, Value};
//! let Some(Item::Entry(speed)) = lookup("remote_speed_f1") else { unreachable!() };
//! let v = Value::parse(speed.kind, "80").unwrap();
//! assert_eq!(v, Value::RemoteSpeed(80));
//! assert!(v.check_range(SpeedMode::Percent).is_ok());
//! assert!(Value::RemoteSpeed(101).check_range(SpeedMode::Percent).is_err());
//! assert_eq!(v.to_bytes(), vec![80, 0]);
//! assert_eq!(v.show(SpeedMode::Percent), "80 %");
//! assert_eq!(v.show(SpeedMode::CountsPerSecond), "80 counts/s");
//! ```

use std::fmt;

pub use crate::model::SpeedMode;
use crate::model::{
    item, ActuatorErrorCount, CyclicObject, DataEntry, DataEntryExt, DataIndex, ErrorCode, Flags, Item, Kind,
    UserPositionData,
};

/// The value of one data-list entry.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A text (firmware or configuration info), without its zero padding.
    Text(String),
    /// A position in encoder counts.
    PositionCounts(i32),
    /// An event counter.
    Counter(u32),
    /// A stroke in encoder counts.
    StrokeCounts(u32),
    /// An actuator error counter.
    ActuatorErrors(ActuatorErrorCount),
    /// A current in 0.1 A.
    CurrentDeciAmps(u16),
    /// An analogue input in 0.01 V.
    AnalogueCentiVolts(u16),
    /// The battery voltage in 0.1 V.
    BatteryDeciVolts(u16),
    /// An actuator's speed in percent.
    SpeedPercent(u16),
    /// A temperature as a raw ADC value.
    TemperatureAdc(u8),
    /// A small number.
    Number(u8),
    /// A named bit set.
    Flags(Flags),
    /// An SCU error code.
    ErrorCode(ErrorCode),
    /// A conversion factor.
    ConversionFactor(f32),
    /// An actuator's stored positions.
    UserPositions(Box<UserPositionData>),
    /// A cyclic object definition.
    CyclicObject(CyclicObject),
    /// A function's remote speed (percent or counts per second, see [`SpeedMode`]).
    RemoteSpeed(u16),
    /// An actuator's remote target position in encoder counts.
    RemotePosition(i32),
}

/// Why a value could not be decoded, parsed or sent.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    /// The bytes do not have the entry's size.
    #[error("{what}: expected {expected} bytes, got {got}")]
    Size {
        /// What was decoded.
        what: String,
        /// Bytes expected.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
    /// Text that is not a value of this kind.
    #[error("{text:?} is not {expected}")]
    Parse {
        /// The text given.
        text: String,
        /// What was expected.
        expected: String,
    },
    /// A value outside the entry's range.
    #[error("{value} is out of range: {range}")]
    Range {
        /// The value.
        value: String,
        /// The allowed range.
        range: String,
    },
    /// The value is of another kind than the entry.
    #[error("a {got} value cannot be written to a {expected} entry")]
    Kind {
        /// The entry's kind.
        expected: &'static str,
        /// The value's kind.
        got: &'static str,
    },
}

fn le_u16(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}

fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

impl Value {
    /// Decodes the bytes of an entry of kind `kind`.
    pub fn decode(kind: Kind, bytes: &[u8]) -> Result<Value, ValueError> {
        if bytes.len() != kind.size() {
            return Err(ValueError::Size { what: kind.data_type().into(), expected: kind.size(), got: bytes.len() });
        }
        Ok(match kind {
            Kind::Text(_) => {
                let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
                Value::Text(String::from_utf8_lossy(&bytes[..end]).trim_end().to_string())
            }
            Kind::PositionCounts => Value::PositionCounts(le_u32(bytes) as i32),
            Kind::Counter => Value::Counter(le_u32(bytes)),
            Kind::StrokeCounts => Value::StrokeCounts(le_u32(bytes)),
            Kind::ActuatorErrorCounter => Value::ActuatorErrors(ActuatorErrorCount::from_u32(le_u32(bytes))),
            Kind::CurrentDeciAmps => Value::CurrentDeciAmps(le_u16(bytes)),
            Kind::AnalogueCentiVolts => Value::AnalogueCentiVolts(le_u16(bytes)),
            Kind::BatteryDeciVolts => Value::BatteryDeciVolts(le_u16(bytes)),
            Kind::SpeedPercent => Value::SpeedPercent(le_u16(bytes)),
            Kind::TemperatureAdc => Value::TemperatureAdc(bytes[0]),
            Kind::Number => Value::Number(bytes[0]),
            Kind::Flags(set) => {
                let bits = match set.size() {
                    1 => u32::from(bytes[0]),
                    2 => u32::from(le_u16(bytes)),
                    _ => le_u32(bytes),
                };
                Value::Flags(Flags { set, bits })
            }
            Kind::ErrorCode => Value::ErrorCode(ErrorCode(le_u32(bytes))),
            Kind::ConversionFactor => {
                Value::ConversionFactor(f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
            }
            Kind::UserPositions => {
                Value::UserPositions(Box::new(UserPositionData::from_bytes(bytes).unwrap_or_default()))
            }
            Kind::CyclicObject => Value::CyclicObject(CyclicObject::from_bytes(bytes).unwrap_or_default()),
            Kind::RemoteSpeed => Value::RemoteSpeed(le_u16(bytes)),
            Kind::RemotePosition => Value::RemotePosition(le_u32(bytes) as i32),
        })
    }

    /// The kind of entry this value belongs to (text of any length matches any text kind).
    pub fn kind_name(&self) -> &'static str {
        match self {
            Value::Text(_) => "text",
            Value::PositionCounts(_) => "position",
            Value::Counter(_) => "counter",
            Value::StrokeCounts(_) => "stroke",
            Value::ActuatorErrors(_) => "actuator error counter",
            Value::CurrentDeciAmps(_) => "current",
            Value::AnalogueCentiVolts(_) => "analogue input",
            Value::BatteryDeciVolts(_) => "battery voltage",
            Value::SpeedPercent(_) => "speed",
            Value::TemperatureAdc(_) => "temperature",
            Value::Number(_) => "number",
            Value::Flags(_) => "bit set",
            Value::ErrorCode(_) => "error code",
            Value::ConversionFactor(_) => "conversion factor",
            Value::UserPositions(_) => "user positions",
            Value::CyclicObject(_) => "cyclic object",
            Value::RemoteSpeed(_) => "remote speed",
            Value::RemotePosition(_) => "remote position",
        }
    }

    /// True if this value can be stored in an entry of `kind`.
    pub fn fits(&self, kind: Kind) -> bool {
        matches!(
            (self, kind),
            (Value::Text(_), Kind::Text(_))
                | (Value::PositionCounts(_), Kind::PositionCounts)
                | (Value::Counter(_), Kind::Counter)
                | (Value::StrokeCounts(_), Kind::StrokeCounts)
                | (Value::ActuatorErrors(_), Kind::ActuatorErrorCounter)
                | (Value::CurrentDeciAmps(_), Kind::CurrentDeciAmps)
                | (Value::AnalogueCentiVolts(_), Kind::AnalogueCentiVolts)
                | (Value::BatteryDeciVolts(_), Kind::BatteryDeciVolts)
                | (Value::SpeedPercent(_), Kind::SpeedPercent)
                | (Value::TemperatureAdc(_), Kind::TemperatureAdc)
                | (Value::Number(_), Kind::Number)
                | (Value::ErrorCode(_), Kind::ErrorCode)
                | (Value::ConversionFactor(_), Kind::ConversionFactor)
                | (Value::UserPositions(_), Kind::UserPositions)
                | (Value::CyclicObject(_), Kind::CyclicObject)
                | (Value::RemoteSpeed(_), Kind::RemoteSpeed)
                | (Value::RemotePosition(_), Kind::RemotePosition)
        ) || matches!((self, kind), (Value::Flags(f), Kind::Flags(set)) if f.set == set)
    }

    /// Appends the value's bytes to `out`.
    pub fn encode(&self, kind: Kind, out: &mut Vec<u8>) {
        match self {
            Value::Text(t) => {
                let mut bytes = t.as_bytes().to_vec();
                bytes.resize(kind.size(), 0);
                out.extend_from_slice(&bytes);
            }
            Value::PositionCounts(v) | Value::RemotePosition(v) => out.extend_from_slice(&v.to_le_bytes()),
            Value::Counter(v) | Value::StrokeCounts(v) => out.extend_from_slice(&v.to_le_bytes()),
            Value::ActuatorErrors(c) => out.extend_from_slice(&c.to_u32().to_le_bytes()),
            Value::CurrentDeciAmps(v)
            | Value::AnalogueCentiVolts(v)
            | Value::BatteryDeciVolts(v)
            | Value::SpeedPercent(v)
            | Value::RemoteSpeed(v) => out.extend_from_slice(&v.to_le_bytes()),
            Value::TemperatureAdc(v) | Value::Number(v) => out.push(*v),
            Value::Flags(f) => out.extend_from_slice(&f.bits.to_le_bytes()[..f.set.size()]),
            Value::ErrorCode(c) => out.extend_from_slice(&c.0.to_le_bytes()),
            Value::ConversionFactor(v) => out.extend_from_slice(&v.to_le_bytes()),
            Value::UserPositions(p) => p.write_to(out),
            Value::CyclicObject(o) => out.extend_from_slice(&o.to_bytes()),
        }
    }

    /// The value's bytes in its own natural kind.
    pub fn to_bytes(&self) -> Vec<u8> {
        let kind = match self {
            Value::Text(t) => Kind::Text(t.len()),
            Value::Flags(f) => Kind::Flags(f.set),
            Value::CyclicObject(_) => Kind::CyclicObject,
            Value::UserPositions(_) => Kind::UserPositions,
            _ => Kind::Counter,
        };
        let mut out = Vec::new();
        self.encode(kind, &mut out);
        out
    }

    /// Checks the value against its entry's range (remote speeds per `speed_mode`, cyclic object indices).
    pub fn check_range(&self, speed_mode: SpeedMode) -> Result<(), ValueError> {
        match self {
            Value::RemoteSpeed(v) if *v > speed_mode.max() => Err(ValueError::Range {
                value: format!("{v} {}", speed_mode.unit()),
                range: format!("a remote speed is 0..{} {}", speed_mode.max(), speed_mode.unit()),
            }),
            Value::CyclicObject(obj) => {
                for idx in obj.write_indices() {
                    match item(idx) {
                        Some(it) if it.is_writable() => {}
                        Some(_) => {
                            return Err(ValueError::Range {
                                value: idx.to_string(),
                                range: "cyclic write data must be remote data (0x3xxx)".into(),
                            })
                        }
                        None => {
                            return Err(ValueError::Range {
                                value: idx.to_string(),
                                range: "not an index of the data list".into(),
                            })
                        }
                    }
                }
                if let Some(bad) = obj.read_indices().find(|i| item(*i).is_none()) {
                    return Err(ValueError::Range {
                        value: bad.to_string(),
                        range: "not an index of the data list".into(),
                    });
                }
                // The exchange must fit one RC request and one reply.
                let write_size = obj.write_size().unwrap_or(0);
                if write_size > crate::wire::MAX_REQUEST_DATA {
                    return Err(ValueError::Range {
                        value: format!("{write_size} bytes of write data"),
                        range: format!("an RC carries at most {} bytes", crate::wire::MAX_REQUEST_DATA),
                    });
                }
                let read_size = obj.read_size().unwrap_or(0);
                if read_size > crate::wire::MAX_REPLY_DATA {
                    return Err(ValueError::Range {
                        value: format!("{read_size} bytes of read data"),
                        range: format!("an RC reply carries at most {} bytes", crate::wire::MAX_REPLY_DATA),
                    });
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// Parses text given for an entry of kind `kind` (the command line's `set`).
    ///
    /// Numbers are plain integers in the entry's raw unit (counts, percent, 0.1 A...); bit sets take a
    /// number (decimal or 0x-hex); a cyclic object takes `WRITE;READ`, each a comma-separated list of up to
    /// six data indices or names, such as `0x3021;0x0011,actuator_status1_a1`.
    pub fn parse(kind: Kind, text: &str) -> Result<Value, ValueError> {
        let t = text.trim();
        let err = |expected: &str| ValueError::Parse { text: t.to_string(), expected: expected.to_string() };
        fn int<T: TryFrom<i64>>(t: &str) -> Option<T> {
            let v = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
                Some(h) => i64::from_str_radix(h, 16).ok()?,
                None => t.parse::<i64>().ok()?,
            };
            T::try_from(v).ok()
        }
        let range = |what: &str| ValueError::Range { value: t.to_string(), range: what.to_string() };
        Ok(match kind {
            Kind::Text(n) => {
                if t.len() > n {
                    return Err(range(&format!("at most {n} bytes of text")));
                }
                Value::Text(t.to_string())
            }
            Kind::PositionCounts => Value::PositionCounts(int(t).ok_or_else(|| err("a position in counts (INT32)"))?),
            Kind::RemotePosition => Value::RemotePosition(int(t).ok_or_else(|| err("a position in counts (INT32)"))?),
            Kind::Counter => Value::Counter(int(t).ok_or_else(|| err("a count (UINT32)"))?),
            Kind::StrokeCounts => Value::StrokeCounts(int(t).ok_or_else(|| err("a stroke in counts (UINT32)"))?),
            Kind::ActuatorErrorCounter => {
                Value::ActuatorErrors(ActuatorErrorCount::from_u32(int(t).ok_or_else(|| err("a UINT32"))?))
            }
            Kind::CurrentDeciAmps => Value::CurrentDeciAmps(int(t).ok_or_else(|| err("a current in 0.1 A (UINT16)"))?),
            Kind::AnalogueCentiVolts => Value::AnalogueCentiVolts(int(t).ok_or_else(|| err("a voltage in 0.01 V"))?),
            Kind::BatteryDeciVolts => Value::BatteryDeciVolts(int(t).ok_or_else(|| err("a voltage in 0.1 V"))?),
            Kind::SpeedPercent => Value::SpeedPercent(int(t).ok_or_else(|| err("a speed in percent"))?),
            Kind::RemoteSpeed => Value::RemoteSpeed(int(t).ok_or_else(|| err("a speed (UINT16)"))?),
            Kind::TemperatureAdc => Value::TemperatureAdc(int(t).ok_or_else(|| err("an ADC value 0..255"))?),
            Kind::Number => Value::Number(int(t).ok_or_else(|| err("a number 0..255"))?),
            Kind::Flags(set) => {
                let bits: u32 = int(t).ok_or_else(|| err("a bit set as a number"))?;
                if set.size() < 4 && bits >> (8 * set.size()) != 0 {
                    return Err(range(&format!("{} byte(s)", set.size())));
                }
                Value::Flags(Flags { set, bits })
            }
            Kind::ErrorCode => Value::ErrorCode(ErrorCode(int(t).ok_or_else(|| err("an error code (UINT32)"))?)),
            Kind::ConversionFactor => Value::ConversionFactor(t.parse().map_err(|_| err("a number"))?),
            Kind::UserPositions => return Err(err("writable (UserPositionData is read-only)")),
            Kind::CyclicObject => {
                let (w, r) = t.split_once(';').unwrap_or((t, ""));
                let list = |s: &str| -> Result<Vec<DataIndex>, ValueError> {
                    s.split(',')
                        .map(str::trim)
                        .filter(|p| !p.is_empty())
                        .map(|p| {
                            if p == "-" || p == "-1" {
                                Ok(DataIndex::NONE)
                            } else {
                                crate::model::lookup(p)
                                    .map(|it| it.index())
                                    .ok_or_else(|| err("WRITE;READ lists of data indices"))
                            }
                        })
                        .collect()
                };
                let obj = CyclicObject::new(&list(w)?, &list(r)?)
                    .ok_or_else(|| range("at most six write and six read indices"))?;
                Value::CyclicObject(obj)
            }
        })
    }

    /// The value as a person reads it, with its unit: as [`fmt::Display`] gives it, and a remote speed in
    /// the unit of `mode` (the unit's speed mode, which the value itself does not carry): `80 %`,
    /// `500 counts/s`.
    pub fn show(&self, mode: crate::model::SpeedMode) -> String {
        match self {
            Value::RemoteSpeed(v) => format!("{v} {}", mode.unit()),
            v => v.to_string(),
        }
    }

    /// The value in engineering units, if it has one (A, V, counts, percent).
    pub fn as_f64(&self) -> Option<f64> {
        Some(match self {
            Value::PositionCounts(v) | Value::RemotePosition(v) => f64::from(*v),
            Value::Counter(v) | Value::StrokeCounts(v) => f64::from(*v),
            Value::CurrentDeciAmps(v) | Value::BatteryDeciVolts(v) => f64::from(*v) / 10.0,
            Value::AnalogueCentiVolts(v) => f64::from(*v) / 100.0,
            Value::SpeedPercent(v) | Value::RemoteSpeed(v) => f64::from(*v),
            Value::TemperatureAdc(v) | Value::Number(v) => f64::from(*v),
            Value::ConversionFactor(v) => f64::from(*v),
            _ => return None,
        })
    }
}

/// A value as every result shows it (the `--json` of the command line, Python, the console): a number in
/// the unit [`shown_unit`] names (deci-amps as amperes, centi- and deci-volts as volts, the rest raw), a
/// flag word as `{word, flags, unknown_bits}`, an error code as `{code, bits}`, a text as a string.
impl serde::Serialize for Value {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        match self {
            Value::Text(t) => s.serialize_str(t),
            Value::PositionCounts(v) | Value::RemotePosition(v) => s.serialize_i32(*v),
            Value::Counter(v) | Value::StrokeCounts(v) => s.serialize_u32(*v),
            Value::ActuatorErrors(c) => c.serialize(s),
            Value::CurrentDeciAmps(_) | Value::AnalogueCentiVolts(_) | Value::BatteryDeciVolts(_) => {
                s.serialize_f64(self.as_f64().unwrap_or(f64::NAN))
            }
            Value::SpeedPercent(v) | Value::RemoteSpeed(v) => s.serialize_u16(*v),
            Value::TemperatureAdc(v) | Value::Number(v) => s.serialize_u8(*v),
            Value::Flags(f) => f.serialize(s),
            Value::ErrorCode(c) => c.serialize(s),
            Value::ConversionFactor(v) => s.serialize_f32(*v),
            Value::UserPositions(p) => p.serialize(s),
            Value::CyclicObject(o) => {
                let names = |v: &[DataIndex]| v.iter().map(|i| i.to_string()).collect::<Vec<_>>();
                let mut map = s.serialize_map(Some(2))?;
                map.serialize_entry("write", &names(&o.write))?;
                map.serialize_entry("read", &names(&o.read))?;
                map.end()
            }
        }
    }
}

/// The unit of `e`'s value as results give it ([`Value`]'s serialisation, [`Value::show`]): A and V for
/// the entries the data list holds in 0.1 A, 0.01 V and 0.1 V, a remote speed's in the unit of `mode`
/// (the unit's speed mode), else the data list's.
pub fn shown_unit(e: &DataEntry, mode: crate::model::SpeedMode) -> &'static str {
    match e.kind {
        Kind::CurrentDeciAmps => "A",
        Kind::BatteryDeciVolts | Kind::AnalogueCentiVolts => "V",
        Kind::RemoteSpeed => mode.unit(),
        _ => e.unit,
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Text(t) => write!(f, "{t:?}"),
            Value::PositionCounts(v) | Value::RemotePosition(v) => write!(f, "{v} counts"),
            Value::Counter(v) => write!(f, "{v}"),
            Value::StrokeCounts(v) => write!(f, "{v} counts"),
            Value::ActuatorErrors(c) => {
                write!(f, "{} errors, {} peak current, {} short circuit", c.errors, c.peak_current, c.short_circuit)
            }
            Value::CurrentDeciAmps(v) => write!(f, "{:.1} A", f64::from(*v) / 10.0),
            Value::AnalogueCentiVolts(v) => write!(f, "{:.2} V", f64::from(*v) / 100.0),
            Value::BatteryDeciVolts(v) => write!(f, "{:.1} V", f64::from(*v) / 10.0),
            Value::SpeedPercent(v) => write!(f, "{v} %"),
            Value::RemoteSpeed(v) => write!(f, "{v}"),
            Value::TemperatureAdc(v) => write!(f, "{v} (ADC)"),
            Value::Number(v) => write!(f, "{v}"),
            Value::Flags(x) => write!(f, "{x}"),
            Value::ErrorCode(c) => write!(f, "{c}"),
            Value::ConversionFactor(v) => write!(f, "{v}"),
            Value::UserPositions(p) => {
                for (i, u) in p.users.iter().enumerate() {
                    write!(
                        f,
                        "user {}: mem {:?} int-in {} int-out {}; ",
                        i + 1,
                        u.memory_counts,
                        u.intermediate_in_counts,
                        u.intermediate_out_counts
                    )?;
                }
                write!(f, "virtual limits {}..{}", p.virtual_limit_in_counts, p.virtual_limit_out_counts)
            }
            Value::CyclicObject(o) => {
                let list = |v: &[DataIndex]| v.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(",");
                write!(f, "write [{}] read [{}]", list(&o.write), list(&o.read))
            }
        }
    }
}

/// Decodes the data of an entry or group: one `(entry, value)` per member.
pub fn decode_item(it: Item, bytes: &[u8]) -> Result<Vec<(&'static DataEntry, Value)>, ValueError> {
    if bytes.len() != it.size() {
        return Err(ValueError::Size { what: it.name().to_string(), expected: it.size(), got: bytes.len() });
    }
    match it {
        Item::Entry(e) => Ok(vec![(e, Value::decode(e.kind, bytes)?)]),
        Item::Group(g) => {
            let mut at = 0;
            g.members()
                .map(|e| {
                    let v = Value::decode(e.kind, &bytes[at..at + e.size()]);
                    at += e.size();
                    v.map(|v| (e, v))
                })
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{lookup, FlagSet};

    #[test]
    fn every_kind_round_trips_through_bytes() {
        for e in crate::model::DATA_LIST {
            let bytes: Vec<u8> = (0..e.size()).map(|i| (i * 7 + 1) as u8).collect();
            let v = Value::decode(e.kind, &bytes).unwrap();
            assert!(v.fits(e.kind), "{}", e.name);
            let mut out = Vec::new();
            v.encode(e.kind, &mut out);
            if !matches!(e.kind, Kind::Text(_)) {
                assert_eq!(out, bytes, "{}", e.name);
            }
        }
    }

    #[test]
    fn sizes_are_checked() {
        assert!(matches!(Value::decode(Kind::PositionCounts, &[1, 2, 3]), Err(ValueError::Size { .. })));
    }

    #[test]
    fn text_is_unpadded() {
        let mut b = b"SCU V2B3".to_vec();
        b.resize(31, 0);
        assert_eq!(Value::decode(Kind::Text(31), &b).unwrap(), Value::Text("SCU V2B3".into()));
    }

    #[test]
    fn parse_rejects_bad_text_with_a_reason() {
        assert!(Value::parse(Kind::RemoteSpeed, "fast").unwrap_err().to_string().contains("fast"));
        assert!(Value::parse(Kind::RemoteSpeed, "-1").is_err(), "a UINT16 is not negative");
        assert!(Value::parse(Kind::RemotePosition, "99999999999").is_err());
        assert_eq!(Value::parse(Kind::RemotePosition, "-12").unwrap(), Value::RemotePosition(-12));
        assert!(Value::parse(Kind::Flags(FlagSet::Buzzer), "0x100").is_err());
    }

    #[test]
    fn speed_range_depends_on_speed_mode() {
        assert!(Value::RemoteSpeed(100).check_range(SpeedMode::Percent).is_ok());
        assert!(Value::RemoteSpeed(101).check_range(SpeedMode::Percent).is_err());
        assert!(Value::RemoteSpeed(1000).check_range(SpeedMode::CountsPerSecond).is_ok());
        assert!(Value::RemoteSpeed(1001).check_range(SpeedMode::CountsPerSecond).is_err());
    }

    #[test]
    fn cyclic_objects_parse_and_check_their_indices() {
        let v = Value::parse(Kind::CyclicObject, "remote_position_a1,0x3011;0x0011,-,actuator_status1_a1").unwrap();
        let Value::CyclicObject(o) = &v else { panic!() };
        assert_eq!(o.write[..2], [DataIndex(0x3021), DataIndex(0x3011)]);
        assert_eq!(o.read[..3], [DataIndex(0x0011), DataIndex::NONE, DataIndex(0x0171)]);
        assert!(v.check_range(SpeedMode::Percent).is_ok());
        let bad = Value::parse(Kind::CyclicObject, "0x0011;").unwrap();
        assert!(bad.check_range(SpeedMode::Percent).unwrap_err().to_string().contains("0x3xxx"));
    }

    #[test]
    fn groups_decode_member_by_member() {
        let g = lookup("actual_positions").unwrap();
        let mut bytes = Vec::new();
        for p in [10i32, -3, 0, 0, 0, 0] {
            bytes.extend_from_slice(&p.to_le_bytes());
        }
        let values = decode_item(g, &bytes).unwrap();
        assert_eq!(values.len(), 6);
        assert_eq!(values[1].0.name, "actual_position_a2");
        assert_eq!(values[1].1, Value::PositionCounts(-3));
        assert!(decode_item(g, &bytes[..20]).is_err());
    }

    #[test]
    fn display_uses_units() {
        assert_eq!(Value::CurrentDeciAmps(25).to_string(), "2.5 A");
        assert_eq!(Value::AnalogueCentiVolts(512).to_string(), "5.12 V");
        assert_eq!(Value::BatteryDeciVolts(240).to_string(), "24.0 V");
        let f = Value::Flags(Flags { set: FlagSet::ActuatorStatus1, bits: 0x91 });
        assert_eq!(f.to_string(), "0x91 [available, motion, stroke_done]");
    }
}
