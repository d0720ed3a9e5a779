//! The SCU telegram codec: sans-IO, byte-exact, allocation-free.
//!
//! ```text
//! Request: <X><Y>[<P1>..<Pn>]<C1><C2>
//! Reply:   <X><Y><status>[<ctp lo><ctp hi><data..>]<C1><C2>
//! ```
//! `X Y` is the two-letter command (`RO`, `RA`, `RC`, `RG`, `RT`, `RE`, `RS`), parameters are little-endian, and
//! `C1 C2` is the CRC-16/XMODEM of everything before it, low byte first. A reply repeats the command letters, then
//! a status byte: ACK (0x06) or one of the error codes 0x80..0x84, which come alone, with no data.
//!
//! This layer knows the shape of telegrams, not what the numbers mean: function ids, data indices and values
//! are bytes here and get their meaning in [`crate::model`].
//!
//! ```
//! use motionlink_scu::wire::{Request, encode_request};
//! let mut buf = [0u8; 16];
//! let n = encode_request(&Request::Get { index: 0x0011 }, &mut buf).unwrap();
//! assert_eq!(&buf[..4], b"RG\x11\x00");
//! assert_eq!(n, 6);
//! ```

use std::fmt;

mod capture;
mod crc;
mod reply_decoder;
mod request_decoder;

pub use capture::{capture_step, CaptureDirection, CaptureItem, Telegram};
pub use crc::{crc16, CRC};
pub use reply_decoder::{ReplyDecoder, ReplyEvent};
pub use request_decoder::{Incoming, RequestDecoder, RequestEvent};

/// The longest request this codec builds or accepts: a command, a ctp, a data index and 250 data bytes, a CRC.
pub const MAX_REQUEST_LEN: usize = 2 + 2 + 2 + MAX_REQUEST_DATA + 2;
/// The most data bytes after ctp in an RT or RC request.
pub const MAX_REQUEST_DATA: usize = 250;
/// The longest reply: command, status, ctp, the 624 bytes of all six UserPositionData structures, CRC.
pub const MAX_REPLY_LEN: usize = 3 + 2 + MAX_REPLY_DATA + 2;
/// The most data bytes in a reply.
pub const MAX_REPLY_DATA: usize = 1024;
const REQUEST_BUF_LEN: usize = if MAX_REQUEST_LEN > MAX_UNKNOWN_LEN { MAX_REQUEST_LEN } else { MAX_UNKNOWN_LEN };
/// A telegram whose command is not known ends where its CRC matches, at most this many bytes after its start.
pub const MAX_UNKNOWN_LEN: usize = 64;

/// The seven commands of the SCU remote protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Command {
    /// `RO` remote mode open.
    Open,
    /// `RA` remote mode abort (back to normal mode).
    Abort,
    /// `RC` remote cyclic: the watchdog telegram, optionally carrying a cyclic object's data.
    Cyclic,
    /// `RG` remote data get.
    Get,
    /// `RT` remote data transfer (write).
    Transfer,
    /// `RE` remote execute function.
    Execute,
    /// `RS` remote stop function.
    Stop,
}

impl Command {
    /// Every command.
    pub const ALL: [Command; 7] = [
        Command::Open,
        Command::Abort,
        Command::Cyclic,
        Command::Get,
        Command::Transfer,
        Command::Execute,
        Command::Stop,
    ];

    /// The two command letters on the wire.
    pub const fn code(self) -> [u8; 2] {
        match self {
            Command::Open => *b"RO",
            Command::Abort => *b"RA",
            Command::Cyclic => *b"RC",
            Command::Get => *b"RG",
            Command::Transfer => *b"RT",
            Command::Execute => *b"RE",
            Command::Stop => *b"RS",
        }
    }

    /// The command with these letters.
    pub const fn from_code(x: u8, y: u8) -> Option<Command> {
        if x != b'R' {
            return None;
        }
        match y {
            b'O' => Some(Command::Open),
            b'A' => Some(Command::Abort),
            b'C' => Some(Command::Cyclic),
            b'G' => Some(Command::Get),
            b'T' => Some(Command::Transfer),
            b'E' => Some(Command::Execute),
            b'S' => Some(Command::Stop),
            _ => None,
        }
    }

    /// The two letters as text.
    pub const fn mnemonic(self) -> &'static str {
        match self {
            Command::Open => "RO",
            Command::Abort => "RA",
            Command::Cyclic => "RC",
            Command::Get => "RG",
            Command::Transfer => "RT",
            Command::Execute => "RE",
            Command::Stop => "RS",
        }
    }

    /// What the command does, as the manual names it.
    pub const fn description(self) -> &'static str {
        match self {
            Command::Open => "remote mode open",
            Command::Abort => "remote mode abort",
            Command::Cyclic => "remote cyclic",
            Command::Get => "remote data get",
            Command::Transfer => "remote data transfer",
            Command::Execute => "remote execute function",
            Command::Stop => "remote stop function",
        }
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.mnemonic())
    }
}

/// The status byte of a reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Status {
    /// 0x06 ACK: request accepted.
    Ack,
    /// 0x80 CSE: error in the telegram checksum.
    ChecksumError,
    /// 0x81 PDE: error in the telegram data bytes.
    ParameterDataError,
    /// 0x82 PCE: wrong number of telegram data bytes.
    ParameterCountError,
    /// 0x83 ICE: unknown command code.
    InvalidCommand,
    /// 0x84 PE: command not possible in the unit's present mode or state.
    PermissionError,
}

impl Status {
    /// Every status.
    pub const ALL: [Status; 6] = [
        Status::Ack,
        Status::ChecksumError,
        Status::ParameterDataError,
        Status::ParameterCountError,
        Status::InvalidCommand,
        Status::PermissionError,
    ];

    /// The byte on the wire.
    pub const fn code(self) -> u8 {
        match self {
            Status::Ack => 0x06,
            Status::ChecksumError => 0x80,
            Status::ParameterDataError => 0x81,
            Status::ParameterCountError => 0x82,
            Status::InvalidCommand => 0x83,
            Status::PermissionError => 0x84,
        }
    }

    /// The status with this byte.
    pub const fn from_code(code: u8) -> Option<Status> {
        match code {
            0x06 => Some(Status::Ack),
            0x80 => Some(Status::ChecksumError),
            0x81 => Some(Status::ParameterDataError),
            0x82 => Some(Status::ParameterCountError),
            0x83 => Some(Status::InvalidCommand),
            0x84 => Some(Status::PermissionError),
            _ => None,
        }
    }

    /// The manual's abbreviation: ACK, CSE, PDE, PCE, ICE, PE.
    pub const fn abbreviation(self) -> &'static str {
        match self {
            Status::Ack => "ACK",
            Status::ChecksumError => "CSE",
            Status::ParameterDataError => "PDE",
            Status::ParameterCountError => "PCE",
            Status::InvalidCommand => "ICE",
            Status::PermissionError => "PE",
        }
    }

    /// The manual's description.
    pub const fn description(self) -> &'static str {
        match self {
            Status::Ack => "command acknowledged",
            Status::ChecksumError => "error in the telegram checksum",
            Status::ParameterDataError => "error in the telegram data bytes",
            Status::ParameterCountError => "wrong number of telegram data bytes",
            Status::InvalidCommand => "unknown command code",
            Status::PermissionError => "command not possible in the unit's present mode or state",
        }
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (0x{:02X}, {})", self.abbreviation(), self.code(), self.description())
    }
}

/// A request, as the host sends it. Data is borrowed: building and parsing requests never allocates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request<'a> {
    /// `RO Safety_ID`: open remote mode.
    Open {
        /// Safety_ID 0, 1 or 2: what a communication timeout does.
        safety_id: u8,
    },
    /// `RA`: leave remote mode.
    Abort,
    /// `RC ctp index write-data`: the watchdog telegram, with the write data of a cyclic object.
    Cyclic {
        /// Index of the cyclic object, 0 for CyclicObj 1 (data index 0x3001) .. 4; `0xFF` for none.
        object: u8,
        /// The write data of the cyclic object, in the order its definition lists them.
        write: &'a [u8],
    },
    /// `RG data_ID`: read a data-list entry or group.
    Get {
        /// The data index.
        index: u16,
    },
    /// `RT ctp data_ID data`: write a remote data entry (indices 0x3xxx).
    Transfer {
        /// The data index.
        index: u16,
        /// The value, little-endian.
        data: &'a [u8],
    },
    /// `RE fnc_ID para_ID[0] para_ID[1]`: execute a function.
    Execute {
        /// Index in the function list (0 for F1).
        function: u8,
        /// Function parameters; unused ones are 0xFF.
        params: [u8; 2],
    },
    /// `RS fnc_ID para_ID[0]`: stop a function.
    Stop {
        /// Index in the function list (0 for F1).
        function: u8,
        /// Function parameter (0 fast stop, 1 soft stop for F1..F10; 0xFF unused).
        param: u8,
    },
}

impl Request<'_> {
    /// The command of this request.
    pub const fn command(&self) -> Command {
        match self {
            Request::Open { .. } => Command::Open,
            Request::Abort => Command::Abort,
            Request::Cyclic { .. } => Command::Cyclic,
            Request::Get { .. } => Command::Get,
            Request::Transfer { .. } => Command::Transfer,
            Request::Execute { .. } => Command::Execute,
            Request::Stop { .. } => Command::Stop,
        }
    }

    /// The length of the encoded telegram.
    pub const fn encoded_len(&self) -> usize {
        2 + match self {
            Request::Open { .. } => 1,
            Request::Abort => 0,
            Request::Cyclic { write, .. } => 3 + write.len(),
            Request::Get { .. } => 2,
            Request::Transfer { data, .. } => 4 + data.len(),
            Request::Execute { .. } => 3,
            Request::Stop { .. } => 2,
        } + 2
    }

    /// The shape of the reply the unit sends when it accepts this request.
    pub const fn reply_shape(&self) -> ReplyShape {
        match self {
            Request::Get { .. } => ReplyShape::WithData,
            Request::Cyclic { object, .. } if *object != 0xFF => ReplyShape::WithData,
            Request::Cyclic { .. } => ReplyShape::StatusOrData,
            _ => ReplyShape::StatusOnly,
        }
    }
}

/// Why a telegram could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// The output buffer is too small.
    #[error("output buffer too small: {needed} bytes needed, {available} available")]
    BufferTooSmall {
        /// Bytes the telegram needs.
        needed: usize,
        /// Bytes the buffer has.
        available: usize,
    },
    /// The data does not fit the telegram's byte counter or this codec's limit.
    #[error("{len} data bytes is more than the {max} a telegram can carry")]
    TooMuchData {
        /// Data bytes given.
        len: usize,
        /// The most allowed.
        max: usize,
    },
}

fn put_crc(out: &mut [u8], body_len: usize) -> usize {
    let crc = crc16(&out[..body_len]);
    out[body_len..body_len + 2].copy_from_slice(&crc.to_le_bytes());
    body_len + 2
}

/// Builds `request` into `out` and returns the telegram's length.
pub fn encode_request(request: &Request<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    let data_len = match request {
        Request::Cyclic { write, .. } => write.len(),
        Request::Transfer { data, .. } => data.len(),
        _ => 0,
    };
    if data_len > MAX_REQUEST_DATA - 2 {
        return Err(EncodeError::TooMuchData { len: data_len, max: MAX_REQUEST_DATA - 2 });
    }
    let needed = request.encoded_len();
    if out.len() < needed {
        return Err(EncodeError::BufferTooSmall { needed, available: out.len() });
    }
    out[..2].copy_from_slice(&request.command().code());
    let body_len = match *request {
        Request::Open { safety_id } => {
            out[2] = safety_id;
            3
        }
        Request::Abort => 2,
        Request::Cyclic { object, write } => {
            out[2..4].copy_from_slice(&(1 + write.len() as u16).to_le_bytes());
            out[4] = object;
            out[5..5 + write.len()].copy_from_slice(write);
            5 + write.len()
        }
        Request::Get { index } => {
            out[2..4].copy_from_slice(&index.to_le_bytes());
            4
        }
        Request::Transfer { index, data } => {
            out[2..4].copy_from_slice(&(2 + data.len() as u16).to_le_bytes());
            out[4..6].copy_from_slice(&index.to_le_bytes());
            out[6..6 + data.len()].copy_from_slice(data);
            6 + data.len()
        }
        Request::Execute { function, params } => {
            out[2] = function;
            out[3..5].copy_from_slice(&params);
            5
        }
        Request::Stop { function, param } => {
            out[2] = function;
            out[3] = param;
            4
        }
    };
    Ok(put_crc(out, body_len))
}

/// Builds `request` into a new vector (for code that is not on a hot path).
pub fn request_to_vec(request: &Request<'_>) -> Result<Vec<u8>, EncodeError> {
    let mut out = vec![0u8; request.encoded_len()];
    let n = encode_request(request, &mut out)?;
    out.truncate(n);
    Ok(out)
}

/// Whether a reply carries data (`ctp` and data bytes) after an ACK.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyShape {
    /// Command letters, status, CRC: the reply of RO, RA, RT, RE and RS.
    StatusOnly,
    /// After an ACK: ctp and data. The reply of RG and of RC with a cyclic object.
    WithData,
    /// Either: the reply of RC without a cyclic object, which the manual's example shows as the status
    /// alone and its command table as ACK, ctp and (no) read data. A telegram whose first five bytes carry a
    /// valid CRC is the status alone; otherwise bytes 3 and 4 are the ctp.
    StatusOrData,
}

/// A reply, as the unit sends it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reply<'a> {
    /// The command this answers.
    pub command: Command,
    /// ACK or an error.
    pub status: Status,
    /// The data after ctp, if the reply has a ctp.
    pub data: Option<&'a [u8]>,
}

impl<'a> Reply<'a> {
    /// A reply with no data.
    pub const fn status_only(command: Command, status: Status) -> Self {
        Reply { command, status, data: None }
    }

    /// An ACK with data.
    pub const fn with_data(command: Command, data: &'a [u8]) -> Self {
        Reply { command, status: Status::Ack, data: Some(data) }
    }

    /// The length of the encoded telegram.
    pub const fn encoded_len(&self) -> usize {
        match self.data {
            Some(d) => 3 + 2 + d.len() + 2,
            None => 5,
        }
    }
}

/// Builds `reply` into `out` and returns the telegram's length.
pub fn encode_reply(reply: &Reply<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    let data_len = reply.data.map_or(0, <[u8]>::len);
    if data_len > MAX_REPLY_DATA {
        return Err(EncodeError::TooMuchData { len: data_len, max: MAX_REPLY_DATA });
    }
    let needed = reply.encoded_len();
    if out.len() < needed {
        return Err(EncodeError::BufferTooSmall { needed, available: out.len() });
    }
    out[..2].copy_from_slice(&reply.command.code());
    out[2] = reply.status.code();
    let body_len = match reply.data {
        Some(d) => {
            out[3..5].copy_from_slice(&(d.len() as u16).to_le_bytes());
            out[5..5 + d.len()].copy_from_slice(d);
            5 + d.len()
        }
        None => 3,
    };
    Ok(put_crc(out, body_len))
}

/// Builds `reply` into a new vector.
pub fn reply_to_vec(reply: &Reply<'_>) -> Result<Vec<u8>, EncodeError> {
    let mut out = vec![0u8; reply.encoded_len()];
    let n = encode_reply(reply, &mut out)?;
    out.truncate(n);
    Ok(out)
}

/// Something wrong on the line, found while decoding. The decoder goes on with the next frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// Bytes that are not the start of a telegram were skipped.
    #[error("{count} byte(s) of garbage skipped")]
    Garbage {
        /// How many.
        count: usize,
    },
    /// A telegram's CRC does not match.
    #[error("{} telegram with a wrong CRC (received 0x{received:04X}, computed 0x{computed:04X})",
            command.map_or("a", |c| c.mnemonic()))]
    Checksum {
        /// The command letters of the telegram, if they were a known command.
        command: Option<Command>,
        /// The CRC in the telegram.
        received: u16,
        /// The CRC of its contents.
        computed: u16,
    },
    /// A telegram announced more data than any telegram carries.
    #[error("{command} telegram announces {ctp} data bytes, more than the {max} allowed")]
    Oversized {
        /// The command.
        command: Command,
        /// The ctp received.
        ctp: u16,
        /// The most allowed.
        max: usize,
    },
    /// A telegram's ctp is too small for its fixed fields.
    #[error("{command} telegram with ctp {ctp}, less than its fixed fields")]
    Undersized {
        /// The command.
        command: Command,
        /// The ctp received.
        ctp: u16,
    },
    /// A reply announces another number of data bytes than the request asks for (a corrupt length byte).
    #[error("{command} reply announces {ctp} data bytes; the request asks for {expected}")]
    UnexpectedLength {
        /// The command.
        command: Command,
        /// The ctp received.
        ctp: u16,
        /// The number of data bytes the request asks for.
        expected: u16,
    },
}
