//! The drives' error messages `Exx`.

use std::fmt;

/// An error message `Exx` of the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ErrorCode(pub u8);

macro_rules! error_table {
    ($( $code:literal => $konst:ident, $desc:literal; )*) => {
        impl ErrorCode {
            $(
                #[doc = concat!("E", stringify!($code), ": ", $desc, ".")]
                pub const $konst: ErrorCode = ErrorCode($code);
            )*

            /// Every error whose meaning is known: (code, meaning).
            pub const KNOWN: &'static [(ErrorCode, &'static str)] = &[ $( (ErrorCode($code), $desc), )* ];
        }
    };
}

error_table! {
    55 => EMERGENCY_STOP, "emergency stop";
    57 => WARNING, "warning (S16 bit 2 is 0)";
    70 => PARITY, "parity error: the telegram was discarded, retransmit it";
    71 => BUFFER_OVERFLOW, "buffer overflow: more than 40 characters, retransmit with fewer";
    72 => BCC, "block-check character error: the telegram was discarded, retransmit it";
    73 => TIMEOUT, "timeout: five character times of silence inside a telegram, retransmit it";
    74 => BUSY, "busy error (acknowledged by power on)";
    92 => COMMAND_ACTIVE, "command active: a move command is refused while the axis moves";
}

impl ErrorCode {
    /// The meaning, where known.
    pub fn meaning(self) -> Option<&'static str> {
        Self::KNOWN.iter().find(|(c, _)| *c == self).map(|(_, m)| *m)
    }

    /// E70..E74: an error of the RS485 line (parity, buffer overflow, BCC, timeout, busy), not a refusal of
    /// what the telegram asked.
    pub fn is_line_error(self) -> bool {
        (70..=74).contains(&self.0)
    }

    /// E70, E72, E73: the drive discarded the telegram (parity, BCC, timeout); sending the same telegram
    /// again is safe and is what the manual asks for. Not E71: its measure is "retransmit with fewer
    /// characters", and the same telegram would overflow the buffer again.
    pub fn is_retransmit(self) -> bool {
        matches!(self.0, 70 | 72 | 73)
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "E{:02} ({})", self.0, self.meaning().unwrap_or("meaning not documented in our sources"))
    }
}
