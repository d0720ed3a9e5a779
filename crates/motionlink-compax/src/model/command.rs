//! The commands of the drives' vocabulary: moves, settings, outputs, reads and writes, in their long and
//! short ASCII forms and the binary one.

use std::fmt;

use super::value::trim;
use super::{syntax, ModelError, OutputState, ParamId, Position, RampMs, SpeedPercent, StatusId};
use crate::wire::number::{parse_decimal_bytes, write_decimal, Fixed24, MAX_DECIMALS};
use crate::wire::{BinaryCommand, TextBuf, WireError, MAX_COMMAND_LEN};

/// Long (`POSA`) or short (`PA`) command names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CommandStyle {
    /// `POSA`, `POSR`, `SPEED`, `ACCEL`, `ACCEL-`, `OUTPUT`, `POSA HOME`.
    #[default]
    Long,
    /// `PA`, `PR`, `SD`, `AL`, `AL-`, `OT`, `PH`.
    Short,
}

/// A command of the drive's vocabulary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// `POSA value`: move to an absolute position.
    PosA(Position),
    /// `POSR value`: move by a distance.
    PosR(Position),
    /// `POSA HOME`: find machine zero.
    PosAHome,
    /// `SPEED value`: speed of the next positionings.
    Speed(SpeedPercent),
    /// `ACCEL value`: acceleration and braking time.
    Accel(RampMs),
    /// `ACCEL- value`: braking time alone.
    AccelBrake(RampMs),
    /// `OUTPUT Ox=y`.
    Output {
        /// Output number (0: the drive itself).
        output: u16,
        /// State.
        state: OutputState,
    },
    /// `POSR value OUTPUT Ox=y`: a comparator for the next positioning.
    PosROutput {
        /// Distance after which the output switches.
        distance: Position,
        /// Output number.
        output: u16,
        /// State.
        state: OutputState,
    },
    /// `POSR value1 SPEED value2`: a speed step for the next positioning.
    PosRSpeed {
        /// Distance after which the speed changes.
        distance: Position,
        /// The new speed.
        speed: SpeedPercent,
    },
    /// `Sn`: read a status value.
    ReadStatus(StatusId),
    /// `Pnnn`: read a parameter.
    ReadParam(ParamId),
    /// `Pnnn=value`: write a parameter.
    WriteParam(ParamId, f64),
}

/// A command string of at most 40 characters.
pub type CommandText = TextBuf<MAX_COMMAND_LEN>;

impl Command {
    /// The command that switches the drive off: `OUTPUT O0=0`, the stop this crate uses (see the crate's
    /// decisions).
    pub const SWITCH_OFF: Command = Command::Output { output: 0, state: OutputState::OFF };

    /// True for commands that start a motion (they take `$`, and E92 refuses them while the axis moves).
    pub fn is_move(&self) -> bool {
        matches!(self, Command::PosA(_) | Command::PosR(_) | Command::PosAHome)
    }

    /// True when sending the command twice has the same effect as once. A relative move is not, nor is a
    /// comparator or speed step (each adds one).
    pub fn is_idempotent(&self) -> bool {
        !matches!(self, Command::PosR(_) | Command::PosROutput { .. } | Command::PosRSpeed { .. })
    }

    /// The ASCII command string.
    #[inline]
    pub fn to_ascii(&self, style: CommandStyle) -> Result<CommandText, ModelError> {
        let mut t = CommandText::new();
        self.write_ascii_into(style, &mut t)?;
        Ok(t)
    }

    /// [`to_ascii`](Self::to_ascii) into `text`, replacing what it held (left empty on an error): no command
    /// string to copy out of a returned value, and one buffer can serve every request.
    ///
    /// ```
    /// use motionlink_compax::model::{Command, CommandStyle, CommandText, StatusId};
    /// let mut text = CommandText::new();
    /// Command::ReadStatus(StatusId::ACTUAL_POSITION).write_ascii_into(CommandStyle::Long, &mut text).unwrap();
    /// assert_eq!(text.as_str(), "S1");
    /// ```
    #[inline]
    pub fn write_ascii_into(&self, style: CommandStyle, text: &mut CommandText) -> Result<(), ModelError> {
        // The polled reads are written without the formatting machinery (the hot path).
        let fast = match self {
            Command::ReadStatus(s) => Some((b'S', u16::from(s.0))),
            Command::ReadParam(p) => Some((b'P', p.0)),
            _ => None,
        };
        if let Some((letter, n)) = fast {
            // `S1`, `S16` (no leading zeros), `P194`, `P003` (three digits): n <= 250.
            let digits = [letter, b'0' + (n / 100) as u8, b'0' + (n / 10 % 10) as u8, b'0' + (n % 10) as u8];
            match (letter, n) {
                (b'P', _) | (_, 100..) => text.set_ascii(digits, 4),
                (_, 10..) => text.set_ascii([letter, digits[2], digits[3]], 3),
                _ => text.set_ascii([letter, digits[3]], 2),
            }
            return Ok(());
        }
        text.clear();
        if self.write_ascii(style, text).is_err() {
            text.clear();
            return Err(WireError::TooLong(self.ascii_len(style)).into());
        }
        Ok(())
    }

    /// How many characters the ASCII command string has, however long: what a message about one too long
    /// for the drive's input buffer names.
    #[cold]
    fn ascii_len(&self, style: CommandStyle) -> usize {
        /// Counts what is written.
        struct Count(usize);
        impl fmt::Write for Count {
            fn write_str(&mut self, s: &str) -> fmt::Result {
                self.0 += s.len();
                Ok(())
            }
        }
        let mut n = Count(0);
        // Counting cannot fail.
        let _ = self.write_ascii(style, &mut n);
        n.0
    }

    fn write_ascii(&self, style: CommandStyle, t: &mut impl fmt::Write) -> fmt::Result {
        let long = style == CommandStyle::Long;
        let name = |l: &'static str, s: &'static str| if long { l } else { s };
        match self {
            Command::PosA(p) => write!(t, "{} {p}", name("POSA", "PA")),
            Command::PosR(p) => write!(t, "{} {p}", name("POSR", "PR")),
            Command::PosAHome => t.write_str(name("POSA HOME", "PH")),
            Command::Speed(s) => write!(t, "{} {s}", name("SPEED", "SD")),
            Command::Accel(ms) => write!(t, "{} {}", name("ACCEL", "AL"), ms.0),
            Command::AccelBrake(ms) => write!(t, "{} {}", name("ACCEL-", "AL-"), ms.0),
            Command::Output { output, state } => write!(t, "{} O{output}={}", name("OUTPUT", "OT"), state.0),
            Command::PosROutput { distance, output, state } => {
                write!(t, "{} {distance} {} O{output}={}", name("POSR", "PR"), name("OUTPUT", "OT"), state.0)
            }
            Command::PosRSpeed { distance, speed } => {
                write!(t, "{} {distance} {} {speed}", name("POSR", "PR"), name("SPEED", "SD"))
            }
            Command::ReadStatus(s) => write!(t, "S{}", s.0),
            Command::ReadParam(p) => write!(t, "{p}"),
            Command::WriteParam(p, v) => {
                write!(t, "{p}=")?;
                write_decimal(t, *v, MAX_DECIMALS)
            }
        }
    }

    /// The binary form, for the commands of the binary table.
    pub fn to_binary(&self) -> Result<BinaryCommand, ModelError> {
        let out = |_output: u16, state: OutputState| match state.0 {
            0 | 1 => Ok(state.0 == 1),
            _ => Err(ModelError::NoBinary("OUTPUT O0=2")),
        };
        Ok(match *self {
            Command::PosA(p) => BinaryCommand::PosA(p.to_fixed()),
            Command::PosR(p) => BinaryCommand::PosR(p.to_fixed()),
            Command::Speed(s) => BinaryCommand::Speed(Fixed24::from_f64(s.0).map_err(WireError::from)?),
            Command::Accel(ms) => BinaryCommand::Accel(ms.0 as i16),
            Command::AccelBrake(ms) => BinaryCommand::AccelBrake(ms.0 as i16),
            Command::Output { output, state } => BinaryCommand::Output { output, on: out(output, state)? },
            Command::PosROutput { distance, output, state } => {
                BinaryCommand::PosROutput { distance: distance.to_fixed(), output, on: out(output, state)? }
            }
            Command::PosRSpeed { distance, speed } => BinaryCommand::PosRSpeed {
                distance: distance.to_fixed(),
                speed: Fixed24::from_f64(speed.0).map_err(WireError::from)?,
            },
            Command::PosAHome => return Err(ModelError::NoBinary("POSA HOME")),
            Command::ReadStatus(_) => return Err(ModelError::NoBinary("a status read")),
            Command::ReadParam(_) | Command::WriteParam(..) => return Err(ModelError::NoBinary("a parameter")),
        })
    }

    /// The command a binary telegram carries, checked against the model's ranges.
    pub fn from_binary(b: &BinaryCommand) -> Result<Command, ModelError> {
        let pos = |f: Fixed24| Position::new(f.to_f64());
        let ramp = |ms: i16| {
            RampMs::new(u32::try_from(ms).map_err(|_| ModelError::Range {
                what: "ramp time",
                value: format!("{ms} ms"),
                range: "0..=32767 ms",
            })?)
        };
        Ok(match *b {
            BinaryCommand::PosA(v) => Command::PosA(pos(v)?),
            BinaryCommand::PosR(v) => Command::PosR(pos(v)?),
            BinaryCommand::Speed(v) => Command::Speed(SpeedPercent::new(v.to_f64())?),
            BinaryCommand::Accel(ms) => Command::Accel(ramp(ms)?),
            BinaryCommand::AccelBrake(ms) => Command::AccelBrake(ramp(ms)?),
            BinaryCommand::Output { output, on } => Command::Output { output, state: OutputState(on.into()) },
            BinaryCommand::PosROutput { distance, output, on } => {
                Command::PosROutput { distance: pos(distance)?, output, state: OutputState(on.into()) }
            }
            BinaryCommand::PosRSpeed { distance, speed } => {
                Command::PosRSpeed { distance: pos(distance)?, speed: SpeedPercent::new(speed.to_f64())? }
            }
        })
    }

    /// Parses an ASCII command string (upper case, long or short names, the space before a value optional):
    /// `POSA1000`, `PR 200 OT O9=1`, `SD 50`, `S16`, `P003=-1055.88`.
    pub fn parse(text: &[u8]) -> Result<Command, ModelError> {
        let t = trim(text);
        let bad = || syntax("a command", text);
        let number = |s: &[u8]| parse_decimal_bytes(s).ok_or_else(bad);
        // Longest names first, so that `POSA HOME` is not `POSA`, `ACCEL-` not `ACCEL`, `SD` not `S`.
        if let Some(rest) = strip(t, &[b"POSA HOME", b"POSAHOME", b"PH"]) {
            return if rest.is_empty() { Ok(Command::PosAHome) } else { Err(bad()) };
        }
        if let Some(rest) = strip(t, &[b"POSA", b"PA"]) {
            return Ok(Command::PosA(Position::new(number(rest)?)?));
        }
        if let Some(rest) = strip(t, &[b"POSR", b"PR"]) {
            let rest = trim(rest);
            let split = rest.iter().position(|c| c.is_ascii_alphabetic()).unwrap_or(rest.len());
            let distance = Position::new(number(&rest[..split])?)?;
            let tail = trim(&rest[split..]);
            if tail.is_empty() {
                return Ok(Command::PosR(distance));
            }
            if let Some(out) = strip(tail, &[b"OUTPUT", b"OT"]) {
                let (output, state) = parse_output(trim(out)).ok_or_else(bad)?;
                return Ok(Command::PosROutput { distance, output, state });
            }
            if let Some(sp) = strip(tail, &[b"SPEED", b"SD"]) {
                return Ok(Command::PosRSpeed { distance, speed: SpeedPercent::new(number(sp)?)? });
            }
            return Err(bad());
        }
        if let Some(rest) = strip(t, &[b"SPEED", b"SD"]) {
            return Ok(Command::Speed(SpeedPercent::new(number(rest)?)?));
        }
        let ramp = |rest: &[u8]| {
            let v = number(rest)?;
            if v.fract() != 0.0 || v < 0.0 {
                return Err(ModelError::Range { what: "ramp time", value: format!("{v}"), range: "0..=32767 ms" });
            }
            RampMs::new(v.min(u32::MAX as f64) as u32)
        };
        if let Some(rest) = strip(t, &[b"ACCEL-", b"AL-"]) {
            return Ok(Command::AccelBrake(ramp(rest)?));
        }
        if let Some(rest) = strip(t, &[b"ACCEL", b"AL"]) {
            return Ok(Command::Accel(ramp(rest)?));
        }
        if let Some(rest) = strip(t, &[b"OUTPUT", b"OT"]) {
            let (output, state) = parse_output(trim(rest)).ok_or_else(bad)?;
            return Ok(Command::Output { output, state });
        }
        if let [b'S', digits @ ..] = t {
            let n = small_number(digits).ok_or_else(bad)?;
            return Ok(Command::ReadStatus(StatusId::new(u8::try_from(n).map_err(|_| bad())?)?));
        }
        if let [b'P', rest @ ..] = t {
            let eq = rest.iter().position(|&c| c == b'=');
            let (digits, value) = match eq {
                Some(i) => (&rest[..i], Some(&rest[i + 1..])),
                None => (rest, None),
            };
            let id = ParamId::new(small_number(trim(digits)).ok_or_else(bad)?)?;
            return match value {
                None => Ok(Command::ReadParam(id)),
                Some(v) => Ok(Command::WriteParam(id, number(v)?)),
            };
        }
        Err(bad())
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write_ascii(CommandStyle::Long, f)
    }
}

fn strip<'a>(t: &'a [u8], names: &[&[u8]]) -> Option<&'a [u8]> {
    names.iter().find_map(|n| t.strip_prefix(*n))
}

fn small_number(digits: &[u8]) -> Option<u16> {
    if digits.is_empty() || digits.len() > 4 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    Some(digits.iter().fold(0u16, |a, d| a * 10 + u16::from(d - b'0')))
}

/// `O9=1` → (9, 1). The RS485 manual's binary table (4.4.1) writes the output as `Ayy` (`OUTPUT Ayy=0`),
/// while its binary code is `4F` (`O`) and the user guide writes `O9=1`: both spellings are read; the
/// command is always written back with `O`.
fn parse_output(t: &[u8]) -> Option<(u16, OutputState)> {
    let rest = t.strip_prefix(b"O").or_else(|| t.strip_prefix(b"A"))?;
    let eq = rest.iter().position(|&c| c == b'=')?;
    let output = small_number(trim(&rest[..eq]))?;
    let state = small_number(trim(&rest[eq + 1..]))?;
    Some((output, OutputState::new(output, u8::try_from(state).ok()?).ok()?))
}
