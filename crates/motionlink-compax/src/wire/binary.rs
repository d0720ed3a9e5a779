//! The binary commands (manual 4.4.1): every row of the table, as a typed command and its bytes.
//!
//! A binary telegram is `address (ASCII digits) + command bytes [+ BCC]`, no CR. The first command byte is
//! `0x80 | length` where the length counts every command byte, this one included (not the address, not the
//! BCC). The second is the command letter. Values are 24.24 fixed point (positions, speeds: LSB first) or
//! 16-bit integers (times, output numbers: MSB first).
//!
//! | command | bytes |
//! |---|---|
//! | POSA value | `88 41 xx xx xx xx xx xx` |
//! | POSR value | `88 52 xx xx xx xx xx xx` |
//! | SPEED value | `88 53 xx xx xx xx xx xx` |
//! | ACCEL value | `84 4C yy yy` |
//! | ACCEL- value | `84 44 yy yy` |
//! | OUTPUT Oyy=0 / =1 | `85 4F yy yy 30` / `... 31` |
//! | POSR value OUTPUT Oyy=0 / =1 | `8C 52 xx xx xx xx xx xx 4F yy yy 30` / `... 31` |
//! | POSR value1 SPEED value2 | `8F 52 xx xx xx xx xx xx 53 xx xx xx xx xx xx` |
//!
//! The manual's last row prints five `xx` after `53`; the length byte 0x8F (15) and "the binary format has
//! always to be transmitted in its whole length" say six, as for every other 24.24 value.

use std::fmt;

use super::number::{int16_from_be, int16_to_be, Fixed24};
use super::WireError;

/// The longest binary command: POSR + SPEED, 15 bytes.
pub const MAX_BINARY_LEN: usize = 15;

/// Letters of the binary command table.
mod letter {
    pub const POSA: u8 = 0x41; // 'A'
    pub const POSR: u8 = 0x52; // 'R'
    pub const SPEED: u8 = 0x53; // 'S'
    pub const ACCEL: u8 = 0x4C; // 'L'
    pub const ACCEL_BRAKE: u8 = 0x44; // 'D'
    pub const OUTPUT: u8 = 0x4F; // 'O'
}

/// One binary command of the manual's table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BinaryCommand {
    /// `POSA value`: absolute position.
    PosA(Fixed24),
    /// `POSR value`: relative position.
    PosR(Fixed24),
    /// `SPEED value`: speed in percent.
    Speed(Fixed24),
    /// `ACCEL value`: acceleration and braking time in ms.
    Accel(i16),
    /// `ACCEL- value`: braking time in ms.
    AccelBrake(i16),
    /// `OUTPUT Oyy=0|1`.
    Output {
        /// Output number.
        output: u16,
        /// Switched on.
        on: bool,
    },
    /// `POSR value OUTPUT Oyy=0|1`: a comparator for the next positioning.
    PosROutput {
        /// Distance after which the output switches.
        distance: Fixed24,
        /// Output number.
        output: u16,
        /// Switched on.
        on: bool,
    },
    /// `POSR value1 SPEED value2`: a speed step for the next positioning.
    PosRSpeed {
        /// Distance after which the speed changes.
        distance: Fixed24,
        /// The new speed in percent.
        speed: Fixed24,
    },
}

impl BinaryCommand {
    /// The total length (the low 7 bits of the first byte) of this command.
    pub fn len(&self) -> usize {
        match self {
            BinaryCommand::PosA(_) | BinaryCommand::PosR(_) | BinaryCommand::Speed(_) => 8,
            BinaryCommand::Accel(_) | BinaryCommand::AccelBrake(_) => 4,
            BinaryCommand::Output { .. } => 5,
            BinaryCommand::PosROutput { .. } => 12,
            BinaryCommand::PosRSpeed { .. } => 15,
        }
    }

    /// Never empty; for symmetry with [`BinaryCommand::len`].
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The command bytes (without address and BCC): `(bytes, length)`.
    pub fn encode(&self) -> ([u8; MAX_BINARY_LEN], usize) {
        let mut b = [0u8; MAX_BINARY_LEN];
        let len = self.len();
        b[0] = 0x80 | len as u8;
        match *self {
            BinaryCommand::PosA(v) => {
                b[1] = letter::POSA;
                b[2..8].copy_from_slice(&v.to_le_bytes());
            }
            BinaryCommand::PosR(v) => {
                b[1] = letter::POSR;
                b[2..8].copy_from_slice(&v.to_le_bytes());
            }
            BinaryCommand::Speed(v) => {
                b[1] = letter::SPEED;
                b[2..8].copy_from_slice(&v.to_le_bytes());
            }
            BinaryCommand::Accel(ms) => {
                b[1] = letter::ACCEL;
                b[2..4].copy_from_slice(&ms.to_be_bytes());
            }
            BinaryCommand::AccelBrake(ms) => {
                b[1] = letter::ACCEL_BRAKE;
                b[2..4].copy_from_slice(&ms.to_be_bytes());
            }
            BinaryCommand::Output { output, on } => {
                b[1] = letter::OUTPUT;
                b[2..4].copy_from_slice(&output.to_be_bytes());
                b[4] = if on { b'1' } else { b'0' };
            }
            BinaryCommand::PosROutput { distance, output, on } => {
                b[1] = letter::POSR;
                b[2..8].copy_from_slice(&distance.to_le_bytes());
                b[8] = letter::OUTPUT;
                b[9..11].copy_from_slice(&output.to_be_bytes());
                b[11] = if on { b'1' } else { b'0' };
            }
            BinaryCommand::PosRSpeed { distance, speed } => {
                b[1] = letter::POSR;
                b[2..8].copy_from_slice(&distance.to_le_bytes());
                b[8] = letter::SPEED;
                b[9..15].copy_from_slice(&speed.to_le_bytes());
            }
        }
        (b, len)
    }

    /// Decodes the command bytes of one binary telegram (from the `0x8n` byte on, without address and BCC).
    pub fn decode(bytes: &[u8]) -> Result<BinaryCommand, WireError> {
        let (&first, _) = bytes.split_first().ok_or(WireError::Binary("empty"))?;
        if first & 0x80 == 0 {
            return Err(WireError::Binary("the first byte must have bit 7 set"));
        }
        let len = usize::from(first & 0x7F);
        if len != bytes.len() {
            return Err(WireError::Binary("the length byte does not match the telegram"));
        }
        let fixed = |at: usize| {
            let mut six = [0u8; 6];
            six.copy_from_slice(&bytes[at..at + 6]);
            Fixed24::from_le_bytes(six)
        };
        let u16be = |at: usize| u16::from_be_bytes([bytes[at], bytes[at + 1]]);
        let on_off = |b: u8| match b {
            b'0' => Ok(false),
            b'1' => Ok(true),
            _ => Err(WireError::Binary("an output state must be '0' (30h) or '1' (31h)")),
        };
        let letter = bytes.get(1).copied().ok_or(WireError::Binary("no command letter"))?;
        match (len, letter) {
            (8, letter::POSA) => Ok(BinaryCommand::PosA(fixed(2))),
            (8, letter::POSR) => Ok(BinaryCommand::PosR(fixed(2))),
            (8, letter::SPEED) => Ok(BinaryCommand::Speed(fixed(2))),
            (4, letter::ACCEL) => Ok(BinaryCommand::Accel(int16_from_be([bytes[2], bytes[3]]))),
            (4, letter::ACCEL_BRAKE) => Ok(BinaryCommand::AccelBrake(int16_from_be([bytes[2], bytes[3]]))),
            (5, letter::OUTPUT) => Ok(BinaryCommand::Output { output: u16be(2), on: on_off(bytes[4])? }),
            (12, letter::POSR) if bytes[8] == letter::OUTPUT => {
                Ok(BinaryCommand::PosROutput { distance: fixed(2), output: u16be(9), on: on_off(bytes[11])? })
            }
            (15, letter::POSR) if bytes[8] == letter::SPEED => {
                Ok(BinaryCommand::PosRSpeed { distance: fixed(2), speed: fixed(9) })
            }
            _ => Err(WireError::Binary("not a command of the binary table")),
        }
    }

    /// An ACCEL / ACCEL- command from a time in ms, refused if it does not fit the 16-bit format.
    pub fn accel_ms(ms: i64, brake_only: bool) -> Result<BinaryCommand, WireError> {
        let v = int16_from_be(int16_to_be(ms)?);
        Ok(if brake_only { BinaryCommand::AccelBrake(v) } else { BinaryCommand::Accel(v) })
    }
}

impl fmt::Display for BinaryCommand {
    /// The command as the manual writes it in ASCII (`POSA 360`, `OUTPUT O9=1`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = |on: bool| if on { 1 } else { 0 };
        match self {
            BinaryCommand::PosA(v) => write!(f, "POSA {v}"),
            BinaryCommand::PosR(v) => write!(f, "POSR {v}"),
            BinaryCommand::Speed(v) => write!(f, "SPEED {v}"),
            BinaryCommand::Accel(v) => write!(f, "ACCEL {v}"),
            BinaryCommand::AccelBrake(v) => write!(f, "ACCEL- {v}"),
            BinaryCommand::Output { output, on } => write!(f, "OUTPUT O{output}={}", b(*on)),
            BinaryCommand::PosROutput { distance, output, on } => {
                write!(f, "POSR {distance} OUTPUT O{output}={}", b(*on))
            }
            BinaryCommand::PosRSpeed { distance, speed } => write!(f, "POSR {distance} SPEED {speed}"),
        }
    }
}

/// The length announced by a binary telegram's first command byte, or `None` for an ASCII byte.
pub fn announced_len(first: u8) -> Option<usize> {
    (first & 0x80 != 0).then_some(usize::from(first & 0x7F))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fx(v: f64) -> Fixed24 {
        Fixed24::from_f64(v).unwrap()
    }

    fn bytes(c: BinaryCommand) -> Vec<u8> {
        let (b, n) = c.encode();
        b[..n].to_vec()
    }

    /// Every row of the manual's table 4.4.1, with values chosen so each field is visible.
    #[test]
    fn every_row_of_the_binary_table() {
        let rows: Vec<(BinaryCommand, Vec<u8>)> = vec![
            (BinaryCommand::PosA(fx(360.0)), vec![0x88, 0x41, 0x00, 0x00, 0x00, 0x68, 0x01, 0x00]),
            (BinaryCommand::PosR(fx(-1.0)), vec![0x88, 0x52, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF]),
            (BinaryCommand::Speed(fx(50.5)), vec![0x88, 0x53, 0x00, 0x00, 0x80, 0x32, 0x00, 0x00]),
            (BinaryCommand::Accel(500), vec![0x84, 0x4C, 0x01, 0xF4]),
            (BinaryCommand::AccelBrake(1000), vec![0x84, 0x44, 0x03, 0xE8]),
            (BinaryCommand::Output { output: 9, on: false }, vec![0x85, 0x4F, 0x00, 0x09, 0x30]),
            (BinaryCommand::Output { output: 258, on: true }, vec![0x85, 0x4F, 0x01, 0x02, 0x31]),
            (
                BinaryCommand::PosROutput { distance: fx(200.0), output: 9, on: false },
                vec![0x8C, 0x52, 0x00, 0x00, 0x00, 0xC8, 0x00, 0x00, 0x4F, 0x00, 0x09, 0x30],
            ),
            (
                BinaryCommand::PosROutput { distance: fx(100.0), output: 10, on: true },
                vec![0x8C, 0x52, 0x00, 0x00, 0x00, 0x64, 0x00, 0x00, 0x4F, 0x00, 0x0A, 0x31],
            ),
            (
                BinaryCommand::PosRSpeed { distance: fx(100.0), speed: fx(50.0) },
                vec![0x8F, 0x52, 0x00, 0x00, 0x00, 0x64, 0x00, 0x00, 0x53, 0x00, 0x00, 0x00, 0x32, 0x00, 0x00],
            ),
        ];
        for (cmd, want) in rows {
            assert_eq!(bytes(cmd), want, "{cmd}");
            assert_eq!(usize::from(want[0] & 0x7F), want.len(), "length byte of {cmd}");
            assert_eq!(BinaryCommand::decode(&want).unwrap(), cmd);
        }
    }

    /// "For POSA 256,0 you get the following string: 88 41 00 00 00 01 00" has one byte too few: the
    /// length byte 0x88 says eight bytes and 256 is 00 00 00 00 01 00 least significant byte first.
    #[test]
    fn posa_256_with_the_missing_byte_restored() {
        assert_eq!(bytes(BinaryCommand::PosA(fx(256.0))), [0x88, 0x41, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00]);
        let printed = [0x88, 0x41, 0x00, 0x00, 0x00, 0x01, 0x00];
        assert!(BinaryCommand::decode(&printed).is_err(), "the manual's 7-byte string is not a telegram");
    }

    #[test]
    fn posa_360() {
        assert_eq!(bytes(BinaryCommand::PosA(fx(360.0))), [0x88, 0x41, 0x00, 0x00, 0x00, 0x68, 0x01, 0x00]);
    }

    #[test]
    fn negative_and_fractional_values_round_trip() {
        for v in [-0.5, -450.5, 8_388_607.5, -8_388_608.0, 1.0 / 16_777_216.0] {
            let c = BinaryCommand::PosR(fx(v));
            assert_eq!(BinaryCommand::decode(&bytes(c)).unwrap(), c);
        }
        assert_eq!(bytes(BinaryCommand::Accel(-2)), [0x84, 0x4C, 0xFF, 0xFE]);
        assert!(BinaryCommand::accel_ms(40_000, false).is_err());
        assert_eq!(BinaryCommand::accel_ms(300, true).unwrap(), BinaryCommand::AccelBrake(300));
    }

    #[test]
    fn malformed_telegrams_are_refused() {
        for bad in [
            &[][..],
            &[0x08, 0x41],
            &[0x88, 0x41, 0, 0],
            &[0x84, 0x58, 0, 0],
            &[0x85, 0x4F, 0, 1, 0x32],
            &[0x8C, 0x52, 0, 0, 0, 0, 0, 0, 0x53, 0, 1, 0x30],
            &[0x81],
        ] {
            assert!(BinaryCommand::decode(bad).is_err(), "{bad:02X?}");
        }
    }
}
