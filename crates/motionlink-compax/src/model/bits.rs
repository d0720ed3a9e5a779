//! The status bit words S16 and S17, through the shared [`flag_set!`](motionlink_link::flag_set).
//!
//! Bit `n` (1..=8) is mask `0x80 >> (n - 1)`: "bit 1 is on the left, the transmission starts with bit 1",
//! and "password 302 active: S17 = 0x80". The drives send the word as eight digits, bit 1 first
//! (`S017: 1000 0000`): [`BitPattern`] writes that form; `Display` of the words names the flags set.
//!
//! ```
//! use motionlink_compax::model::{S17Bits, S17Flag};
//! let s17 = S17Bits(0x20 | 0x02);
//! assert!(s17.contains(S17Flag::CommandActive));
//! assert_eq!(s17.pattern().to_string(), "0010 0010");
//! assert_eq!(s17.to_string(), "COMMAND_ACTIVE | RUN");
//! ```

use std::fmt::{self, Write as _};

/// The mask of bit `n` (1..=8) of S16 / S17.
pub const fn bit_mask(n: u8) -> u8 {
    0x80 >> (n - 1)
}

motionlink_link::flag_set! {
    /// The status bits of S16.
    S16Bits(u8);
    /// One bit of S16.
    S16Flag {
        NoFault = ("NO_FAULT", bit_mask(1), Information, "no fault"),
        NoWarning = ("NO_WARNING", bit_mask(2), Information, "no warning"),
        MachineZero = ("MACHINE_ZERO", bit_mask(3), Information, "machine zero has been approached"),
        ReadyForStart = ("READY_FOR_START", bit_mask(4), Information, "ready for start"),
        PositionReached = ("POSITION_REACHED", bit_mask(5), Information, "programmed nominal position reached"),
        IdleAfterStop = ("IDLE_AFTER_STOP", bit_mask(6), Information, "idle after stop"),
        O0Bit7 = ("O0_BIT7", bit_mask(7), Information, "O0 state bit 7 (set after OUTPUT O0=1)"),
        O0Bit8 = ("O0_BIT8", bit_mask(8), Information, "O0 state bit 8 (set after OUTPUT O0=2)"),
    }
}

motionlink_link::flag_set! {
    /// The status bits of S17.
    S17Bits(u8);
    /// One bit of S17.
    S17Flag {
        Password302 = ("PASSWORD_302", bit_mask(1), Information, "password 302 active"),
        ServicePassword = ("SERVICE_PASSWORD", bit_mask(2), Information, "service password active"),
        CommandActive = (
            "COMMAND_ACTIVE",
            bit_mask(3),
            Information,
            "command active (move commands are refused with E92)"
        ),
        ProgramRunning = ("PROGRAM_RUNNING", bit_mask(4), Information, "program memory running"),
        StopViaI6 = ("STOP_VIA_I6", bit_mask(5), Warning, "stop via input I6"),
        Run = ("RUN", bit_mask(7), Information, "RUN"),
    }
}

/// A bit word as the drives send it: eight digits, bit 1 first, a space after the fourth (`1000 0000`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BitPattern(pub u8);

impl fmt::Display for BitPattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for n in 1..=8u8 {
            if n == 5 {
                f.write_char(' ')?;
            }
            f.write_char(if self.0 & bit_mask(n) != 0 { '1' } else { '0' })?;
        }
        Ok(())
    }
}

impl S16Bits {
    /// The O0 state bits 7 and 8 as the OUTPUT O0 value they follow (0, 1 or 2).
    pub fn o0_state(self) -> u8 {
        match (self.contains(S16Flag::O0Bit7), self.contains(S16Flag::O0Bit8)) {
            (true, _) => 1,
            (false, true) => 2,
            (false, false) => 0,
        }
    }

    /// The word as transmitted (`1101 0010`).
    pub fn pattern(self) -> BitPattern {
        BitPattern(self.0)
    }

    /// The meanings of the flags set, in the manual's order.
    pub fn meanings(self) -> Vec<&'static str> {
        self.iter().map(S16Flag::meaning).collect()
    }
}

impl S17Bits {
    /// The word as transmitted (`0010 0010`).
    pub fn pattern(self) -> BitPattern {
        BitPattern(self.0)
    }

    /// The meanings of the flags set, in the manual's order.
    pub fn meanings(self) -> Vec<&'static str> {
        self.iter().map(S17Flag::meaning).collect()
    }
}

/// Reads eight digits `0` / `1` (spaces anywhere between them).
pub(crate) fn parse_bits(text: &[u8]) -> Option<u8> {
    let mut v = 0u8;
    let mut n = 0;
    for &c in text {
        match c {
            b'0' | b'1' if n < 8 => {
                v = (v << 1) | (c - b'0');
                n += 1;
            }
            b' ' => {}
            _ => return None,
        }
    }
    (n == 8).then_some(v)
}
