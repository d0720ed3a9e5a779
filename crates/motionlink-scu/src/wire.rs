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

/// The CRC of SCU telegrams from the `crc` crate: CRC-16/XMODEM (polynomial 0x1021, initial value 0, no
/// reflection, no final xor), with its slice-by-16 tables.
pub const CRC: crc::Crc<u16, crc::Table<16>> = crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_XMODEM);

/// The `crc` crate's tables, built at compile time: `TABLES[k][b]` is the CRC of byte `b` followed by `k` zero
/// bytes. `TABLES[0]` is the manual's CRC_TABLE (chapter 6, code example 1).
static TABLES: [[u16; 256]; 16] = *CRC.table();

/// CRC-16/XMODEM of `bytes` (initial value 0, no reflection, no final xor), as the manual specifies.
///
/// Telegrams are short (4 to a few dozen bytes). [`CRC`]`.checksum` would take each 16-byte block in one step and
/// every byte after the last whole block one at a time, a long chain of dependent lookups for a 29-byte
/// telegram; this uses the same tables sixteen, eight and four bytes at a time. The tests check it against the `crc`
/// crate for every length, and against the manual's table.
///
/// ```
/// assert_eq!(motionlink_scu::wire::crc16(b"123456789"), 0x31C3);
/// ```
pub fn crc16(bytes: &[u8]) -> u16 {
    let t = &TABLES;
    let mut crc: u16 = 0;
    let mut blocks = bytes.chunks_exact(16);
    for c in &mut blocks {
        let [hi, lo] = crc.to_be_bytes();
        crc = (t[15][usize::from(c[0] ^ hi)]
            ^ t[14][usize::from(c[1] ^ lo)]
            ^ t[13][usize::from(c[2])]
            ^ t[12][usize::from(c[3])]
            ^ t[11][usize::from(c[4])]
            ^ t[10][usize::from(c[5])]
            ^ t[9][usize::from(c[6])]
            ^ t[8][usize::from(c[7])])
            ^ (t[7][usize::from(c[8])]
                ^ t[6][usize::from(c[9])]
                ^ t[5][usize::from(c[10])]
                ^ t[4][usize::from(c[11])]
                ^ t[3][usize::from(c[12])]
                ^ t[2][usize::from(c[13])]
                ^ t[1][usize::from(c[14])]
                ^ t[0][usize::from(c[15])]);
    }
    let mut chunks = blocks.remainder().chunks_exact(8);
    for c in &mut chunks {
        let [hi, lo] = crc.to_be_bytes();
        crc = t[7][usize::from(c[0] ^ hi)]
            ^ t[6][usize::from(c[1] ^ lo)]
            ^ t[5][usize::from(c[2])]
            ^ t[4][usize::from(c[3])]
            ^ t[3][usize::from(c[4])]
            ^ t[2][usize::from(c[5])]
            ^ t[1][usize::from(c[6])]
            ^ t[0][usize::from(c[7])];
    }
    let mut rest = chunks.remainder();
    if rest.len() >= 4 {
        let [hi, lo] = crc.to_be_bytes();
        crc = t[3][usize::from(rest[0] ^ hi)]
            ^ t[2][usize::from(rest[1] ^ lo)]
            ^ t[1][usize::from(rest[2])]
            ^ t[0][usize::from(rest[3])];
        rest = &rest[4..];
    }
    for &b in rest {
        crc = t[0][usize::from((crc >> 8) as u8 ^ b)] ^ (crc << 8);
    }
    crc
}

/// Continues a CRC over more bytes (byte by byte; for the rare unknown-command search).
fn crc16_update(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        crc = TABLES[0][usize::from((crc >> 8) as u8 ^ b)] ^ (crc << 8);
    }
    crc
}

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
    /// Command letters, status, CRC: the reply of RO, RA, RT, RE, RS and of RC without a cyclic object.
    StatusOnly,
    /// After an ACK: ctp and data. The reply of RG and of RC with a cyclic object.
    WithData,
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
    #[error("{command:?} telegram with a wrong CRC (received 0x{received:04X}, computed 0x{computed:04X})")]
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

// ---------------------------------------------------------------------------------------------------------
// Request decoding (the unit's side)

/// `R?` with an unknown letter, an error status and a matching CRC: the unit's answer to an unknown command.
fn unknown_command_reply(b: &[u8]) -> Option<Telegram<'_>> {
    let t = b.get(..5)?;
    if t[0] != b'R' || Command::from_code(t[0], t[1]).is_some() {
        return None;
    }
    let status = Status::from_code(t[2]).filter(|s| *s != Status::Ack)?;
    check_crc(t).ok()?;
    Some(Telegram::UnknownCommandReply { code: [t[0], t[1]], status })
}

/// A decoded request, or an unknown command that arrived intact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Incoming<'a> {
    /// A request of a known command.
    Request(Request<'a>),
    /// A telegram of an unknown command `R?` whose CRC is right: the unit answers ICE.
    UnknownCommand {
        /// The command letters.
        code: [u8; 2],
    },
}

/// An event of the request decoder.
pub type RequestEvent<'a> = Result<Incoming<'a>, WireError>;

/// Incremental decoder of requests: feed it any chunk of bytes, get telegrams out.
///
/// Resynchronisation: bytes that cannot start a telegram (anything but `R` followed by an upper-case letter)
/// are skipped and reported as [`WireError::Garbage`]. A known command's length follows from its fixed fields
/// or its ctp; a CRC mismatch is reported with the command ([`WireError::Checksum`], answered with CSE) and
/// scanning resumes one byte after the bad telegram's start. A telegram with an unknown command ends where its
/// CRC matches, within [`MAX_UNKNOWN_LEN`] bytes; failing that, its first byte is garbage.
///
/// The decoder does not know time: the unit calls [`RequestDecoder::reset`] when the line was silent too long
/// inside a telegram (1000 ms).
///
/// ```
/// use motionlink_scu::wire::{Incoming, Request, RequestDecoder};
/// let mut dec = RequestDecoder::new();
/// let bytes = [b'x', b'R', b'A', 0x38, 0x30]; // garbage, then RA (CRC 0x3038)
/// let (n, ev) = dec.decode(&bytes);
/// assert!(ev.unwrap().is_err()); // the 'x'
/// let (_, ev) = dec.decode(&bytes[n..]);
/// assert_eq!(ev, Some(Ok(Incoming::Request(Request::Abort))));
/// ```
#[derive(Clone)]
pub struct RequestDecoder {
    framer: Framer<REQUEST_BUF_LEN>,
}

impl fmt::Debug for RequestDecoder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RequestDecoder").field("buffered", &self.framer.buffered()).finish()
    }
}

impl Default for RequestDecoder {
    fn default() -> Self {
        Self::new()
    }
}

/// The receive buffer both decoders frame telegrams in: bytes of a telegram that has not come whole yet.
#[derive(Clone)]
struct Framer<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// Bytes at the front of `buf` already emitted as part of an event; dropped on the next call.
    consumed_front: usize,
}

impl<const N: usize> Framer<N> {
    const fn new() -> Self {
        Framer { buf: [0; N], len: 0, consumed_front: 0 }
    }

    fn reset(&mut self) {
        self.len = 0;
        self.consumed_front = 0;
    }

    fn buffered(&self) -> &[u8] {
        &self.buf[self.consumed_front..self.len]
    }

    fn compact(&mut self) {
        if self.consumed_front > 0 {
            self.buf.copy_within(self.consumed_front..self.len, 0);
            self.len -= self.consumed_front;
            self.consumed_front = 0;
        }
    }

    /// Takes bytes from `input` and returns how many it used and at most one complete telegram (or error), as
    /// `scan` delimits them. A telegram that lies whole in `input` while nothing is buffered is returned in
    /// place, without copying.
    fn next<'a>(
        &'a mut self,
        input: &'a [u8],
        scan: impl Fn(&[u8]) -> Scan,
    ) -> (usize, Option<Result<&'a [u8], WireError>>) {
        self.compact();
        if self.len == 0 && !input.is_empty() {
            match scan(input) {
                Scan::NeedMore => {}
                Scan::Complete(n) => return (n, Some(Ok(&input[..n]))),
                other => {
                    let (n, e) = scan_error(other);
                    return (n, Some(Err(e)));
                }
            }
        }
        let mut used = 0;
        loop {
            match scan(&self.buf[..self.len]) {
                Scan::NeedMore => {
                    let take = (N - self.len).min(input.len() - used);
                    if take == 0 {
                        return (used, None);
                    }
                    self.buf[self.len..self.len + take].copy_from_slice(&input[used..used + take]);
                    self.len += take;
                    used += take;
                }
                Scan::Complete(n) => {
                    self.consumed_front = n;
                    return (used, Some(Ok(&self.buf[..n])));
                }
                other => {
                    let (n, e) = scan_error(other);
                    self.consumed_front = n;
                    return (used, Some(Err(e)));
                }
            }
        }
    }
}

/// What the bytes at the start of a buffer are.
enum Scan {
    /// Not enough bytes yet to know.
    NeedMore,
    /// A complete telegram of this many bytes.
    Complete(usize),
    /// The first `n` bytes are garbage.
    Garbage(usize),
    /// A telegram with a wrong CRC, `len` bytes long.
    BadCrc { command: Option<Command>, received: u16, computed: u16 },
    /// A telegram whose length field is impossible.
    BadLength(WireError),
}

fn check_crc(frame: &[u8]) -> Result<(), (u16, u16)> {
    let n = frame.len();
    let received = u16::from_le_bytes([frame[n - 2], frame[n - 1]]);
    let computed = crc16(&frame[..n - 2]);
    if received == computed {
        Ok(())
    } else {
        Err((received, computed))
    }
}

/// The bytes to skip and the error for a scan that found no telegram.
fn scan_error(scan: Scan) -> (usize, WireError) {
    match scan {
        Scan::Garbage(n) => (n, WireError::Garbage { count: n }),
        Scan::BadCrc { command, received, computed } => (1, WireError::Checksum { command, received, computed }),
        Scan::BadLength(e) => (1, e),
        // Not errors; never passed here.
        Scan::NeedMore | Scan::Complete(_) => (1, WireError::Garbage { count: 1 }),
    }
}

fn known_or_crc(frame: &[u8], command: Option<Command>) -> Scan {
    match check_crc(frame) {
        Ok(()) => Scan::Complete(frame.len()),
        Err((received, computed)) => Scan::BadCrc { command, received, computed },
    }
}

fn scan_request(b: &[u8]) -> Scan {
    let Some(&x) = b.first() else { return Scan::NeedMore };
    if x != b'R' {
        let n = b.iter().position(|&c| c == b'R').unwrap_or(b.len());
        return Scan::Garbage(n);
    }
    let Some(&y) = b.get(1) else { return Scan::NeedMore };
    let Some(command) = Command::from_code(x, y) else {
        if !y.is_ascii_uppercase() {
            return Scan::Garbage(1);
        }
        // An unknown command: it ends where its CRC matches.
        let mut crc = crc16_update(0, &b[..2]);
        for end in 4..=b.len().min(MAX_UNKNOWN_LEN) {
            // crc holds the CRC of b[..end - 2].
            if u16::from_le_bytes([b[end - 2], b[end - 1]]) == crc {
                return Scan::Complete(end);
            }
            crc = crc16_update(crc, &b[end - 2..end - 1]);
        }
        return if b.len() >= MAX_UNKNOWN_LEN { Scan::Garbage(1) } else { Scan::NeedMore };
    };
    let fixed = match command {
        Command::Open => Some(5),
        Command::Abort => Some(4),
        Command::Get => Some(6),
        Command::Execute => Some(7),
        Command::Stop => Some(6),
        Command::Cyclic | Command::Transfer => None,
    };
    let len = match fixed {
        Some(n) => n,
        None => {
            if b.len() < 4 {
                return Scan::NeedMore;
            }
            let ctp = u16::from_le_bytes([b[2], b[3]]);
            let min = if command == Command::Cyclic { 1 } else { 2 };
            if usize::from(ctp) > MAX_REQUEST_DATA {
                return Scan::BadLength(WireError::Oversized { command, ctp, max: MAX_REQUEST_DATA });
            }
            if ctp < min {
                return Scan::BadLength(WireError::Undersized { command, ctp });
            }
            4 + usize::from(ctp) + 2
        }
    };
    if b.len() < len {
        return Scan::NeedMore;
    }
    known_or_crc(&b[..len], Some(command))
}

fn parse_request(frame: &[u8]) -> Incoming<'_> {
    let body = &frame[..frame.len() - 2];
    let Some(command) = Command::from_code(body[0], body[1]) else {
        return Incoming::UnknownCommand { code: [body[0], body[1]] };
    };
    Incoming::Request(match command {
        Command::Open => Request::Open { safety_id: body[2] },
        Command::Abort => Request::Abort,
        Command::Get => Request::Get { index: u16::from_le_bytes([body[2], body[3]]) },
        Command::Execute => Request::Execute { function: body[2], params: [body[3], body[4]] },
        Command::Stop => Request::Stop { function: body[2], param: body[3] },
        Command::Cyclic => Request::Cyclic { object: body[4], write: &body[5..] },
        Command::Transfer => Request::Transfer { index: u16::from_le_bytes([body[4], body[5]]), data: &body[6..] },
    })
}

impl RequestDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        RequestDecoder { framer: Framer::new() }
    }

    /// Drops a partly received telegram (the line was silent too long).
    pub fn reset(&mut self) {
        self.framer.reset();
    }

    /// True while part of a telegram is buffered.
    pub fn is_mid_telegram(&self) -> bool {
        !self.framer.buffered().is_empty()
    }

    /// Takes bytes from `input` and returns how many it used and at most one event. Call it again with the rest
    /// of the input (and with an empty input, to drain events of bytes already buffered) until it returns
    /// `(0, None)`. A telegram that lies whole in `input` is decoded in place, without copying.
    pub fn decode<'a>(&'a mut self, input: &'a [u8]) -> (usize, Option<RequestEvent<'a>>) {
        let (used, event) = self.framer.next(input, scan_request);
        (used, event.map(|e| e.map(parse_request)))
    }
}

// ---------------------------------------------------------------------------------------------------------
// Reply decoding (the host's side)

/// An event of the reply decoder.
pub type ReplyEvent<'a> = Result<Reply<'a>, WireError>;

/// What the reply decoder waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Expectation {
    command: Command,
    shape: ReplyShape,
    /// The number of data bytes of an ACK with data, when the request fixes it.
    data_len: Option<u16>,
}

/// Incremental decoder of replies: feed it any chunk of bytes, get telegrams out.
///
/// A reply's length depends on the request it answers (an RC reply carries data only when the request named
/// a cyclic object). A client tells the decoder with [`ReplyDecoder::expect`]; then replies of other commands
/// are skipped as garbage. Without an expectation (reading a capture) every command is accepted and an
/// ambiguous RC reply is taken as status-only if its CRC matches that way, else as carrying data.
///
/// ```
/// use motionlink_scu::wire::{Command, Reply, ReplyDecoder, ReplyShape, Status};
/// let mut dec = ReplyDecoder::new();
/// dec.expect(Command::Get, ReplyShape::WithData);
/// let reply = [0x52, 0x47, 0x06, 0x01, 0x00, 0x31, 0xB3, 0xBB]; // RG ACK, 1 data byte (0x31)
/// let (_, ev) = dec.decode(&reply);
/// assert_eq!(ev, Some(Ok(Reply::with_data(Command::Get, &[0x31]))));
/// ```
#[derive(Clone)]
pub struct ReplyDecoder {
    framer: Framer<MAX_REPLY_LEN>,
    expect: Option<Expectation>,
}

impl fmt::Debug for ReplyDecoder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ReplyDecoder").field("buffered", &self.framer.buffered()).field("expect", &self.expect).finish()
    }
}

impl Default for ReplyDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl ReplyDecoder {
    /// An empty decoder that accepts replies of any command.
    pub const fn new() -> Self {
        ReplyDecoder { framer: Framer::new(), expect: None }
    }

    /// Accepts only replies to `command`, of `shape` when ACKed.
    pub fn expect(&mut self, command: Command, shape: ReplyShape) {
        self.expect = Some(Expectation { command, shape, data_len: None });
    }

    /// Like [`ReplyDecoder::expect`], and an ACK with data must carry exactly `data_len` bytes: a reply that
    /// announces another count (its length byte was corrupted) is reported at once as
    /// [`WireError::UnexpectedLength`] instead of being waited for.
    pub fn expect_len(&mut self, command: Command, shape: ReplyShape, data_len: u16) {
        self.expect = Some(Expectation { command, shape, data_len: Some(data_len) });
    }

    /// Accepts replies of any command again.
    pub fn expect_any(&mut self) {
        self.expect = None;
    }

    /// Drops buffered bytes.
    pub fn reset(&mut self) {
        self.framer.reset();
    }

    /// True while the start of an expected reply (its command letters at least) is buffered, after every event
    /// of the input was taken: the unit is answering.
    pub fn is_mid_telegram(&self) -> bool {
        self.framer.buffered().len() >= 2
    }

    /// Takes bytes from `input` and returns how many it used and at most one event. Call it again with the rest
    /// of the input (and with an empty input, to drain events of bytes already buffered) until it returns
    /// `(0, None)`. A telegram that lies whole in `input` is decoded in place, without copying.
    pub fn decode<'a>(&'a mut self, input: &'a [u8]) -> (usize, Option<ReplyEvent<'a>>) {
        let expect = self.expect;
        let (used, event) = self.framer.next(input, |b| scan_reply(b, expect));
        (used, event.map(|e| e.map(parse_reply)))
    }
}

/// A complete reply telegram whose CRC was checked.
fn parse_reply(f: &[u8]) -> Reply<'_> {
    let n = f.len();
    let command = Command::from_code(f[0], f[1]).unwrap_or(Command::Get);
    let status = Status::from_code(f[2]).unwrap_or(Status::Ack);
    let data = (n > 5).then(|| &f[5..n - 2]);
    Reply { command, status, data }
}

fn scan_reply(b: &[u8], expect: Option<Expectation>) -> Scan {
    let is_start = |x: u8, y: u8| match (Command::from_code(x, y), expect) {
        (Some(c), Some(e)) => c == e.command,
        (Some(_), None) => true,
        (None, _) => false,
    };
    let Some(&x) = b.first() else { return Scan::NeedMore };
    if x != b'R' {
        let n = b.iter().position(|&c| c == b'R').unwrap_or(b.len());
        return Scan::Garbage(n);
    }
    let Some(&y) = b.get(1) else { return Scan::NeedMore };
    if !is_start(x, y) {
        return Scan::Garbage(1);
    }
    let command = Command::from_code(x, y).unwrap_or(Command::Get);
    let Some(&s) = b.get(2) else { return Scan::NeedMore };
    let Some(status) = Status::from_code(s) else { return Scan::Garbage(1) };
    if status != Status::Ack {
        return if b.len() < 5 { Scan::NeedMore } else { known_or_crc(&b[..5], Some(command)) };
    }
    let shape = match (expect, command) {
        (Some(e), _) => e.shape,
        (None, Command::Get) => ReplyShape::WithData,
        (None, Command::Cyclic) => {
            // Ambiguous without the request: status-only if that CRC matches, else with data.
            if b.len() < 5 {
                return Scan::NeedMore;
            }
            if check_crc(&b[..5]).is_ok() {
                return Scan::Complete(5);
            }
            ReplyShape::WithData
        }
        (None, _) => ReplyShape::StatusOnly,
    };
    match shape {
        ReplyShape::StatusOnly => {
            if b.len() < 5 {
                Scan::NeedMore
            } else {
                known_or_crc(&b[..5], Some(command))
            }
        }
        ReplyShape::WithData => {
            if b.len() < 5 {
                return Scan::NeedMore;
            }
            let ctp = u16::from_le_bytes([b[3], b[4]]);
            if let Some(expected) = expect.and_then(|e| e.data_len).filter(|&n| n != ctp) {
                return Scan::BadLength(WireError::UnexpectedLength { command, ctp, expected });
            }
            if usize::from(ctp) > MAX_REPLY_DATA {
                return Scan::BadLength(WireError::Oversized { command, ctp, max: MAX_REPLY_DATA });
            }
            let len = 5 + usize::from(ctp) + 2;
            if b.len() < len {
                Scan::NeedMore
            } else {
                known_or_crc(&b[..len], Some(command))
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Captures: both directions in one stream

/// A telegram found in a capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Telegram<'a> {
    /// Host to unit.
    Request(Incoming<'a>),
    /// Unit to host.
    Reply(Reply<'a>),
    /// Unit to host: the error reply (ICE) to a command it does not know, which repeats the unknown letters.
    UnknownCommandReply {
        /// The letters of the unknown command.
        code: [u8; 2],
        /// The error status (ICE).
        status: Status,
    },
}

/// What [`capture_step`] found at the start of its input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CaptureItem<'a> {
    /// A telegram with a valid CRC.
    Telegram(Telegram<'a>),
    /// Bytes that belong to no telegram, or a telegram with a wrong CRC.
    Error(WireError),
    /// The input ends inside a telegram.
    Truncated,
}

/// Which way the bytes of a capture went, if known.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureDirection {
    /// Host to unit: requests.
    FromHost,
    /// Unit to host: replies.
    FromUnit,
    /// Both directions mixed in one stream.
    Unknown,
}

/// Finds the telegram at the start of `bytes` in a capture and returns its length and what it is.
///
/// In a capture that mixes both directions ([`CaptureDirection::Unknown`]) a request and a reply can start
/// alike: the reading with a valid CRC wins, and when both are valid (an RO ACK is byte for byte an RO with
/// Safety_ID 6, which no unit accepts) the reply does.
///
/// ```
/// use motionlink_scu::wire::{capture_step, CaptureDirection, CaptureItem, Telegram};
/// let capture = [0x52, 0x4F, 0x00, 0x5C, 0x2D, 0x52, 0x4F, 0x06, 0x9A, 0x4D]; // RO 00, then its ACK
/// let (n, first) = capture_step(&capture, CaptureDirection::Unknown);
/// assert!(matches!(first, CaptureItem::Telegram(Telegram::Request(_))));
/// let (_, second) = capture_step(&capture[n..], CaptureDirection::Unknown);
/// assert!(matches!(second, CaptureItem::Telegram(Telegram::Reply(_))));
/// ```
pub fn capture_step(bytes: &[u8], direction: CaptureDirection) -> (usize, CaptureItem<'_>) {
    if bytes.is_empty() {
        return (0, CaptureItem::Truncated);
    }
    if direction != CaptureDirection::FromHost {
        if let Some(t) = unknown_command_reply(bytes) {
            return (5, CaptureItem::Telegram(t));
        }
    }
    let as_request = if direction == CaptureDirection::FromUnit { Scan::Garbage(1) } else { scan_request(bytes) };
    let as_reply = if direction == CaptureDirection::FromHost { Scan::Garbage(1) } else { scan_reply(bytes, None) };
    let reply = |n: usize| (n, CaptureItem::Telegram(Telegram::Reply(parse_reply(&bytes[..n]))));
    match (&as_request, &as_reply) {
        (_, Scan::Complete(n)) => reply(*n),
        (Scan::Complete(n), _) => (*n, CaptureItem::Telegram(Telegram::Request(parse_request(&bytes[..*n])))),
        (Scan::NeedMore, _) | (_, Scan::NeedMore) => (bytes.len(), CaptureItem::Truncated),
        (Scan::BadCrc { command, received, computed }, _) | (_, Scan::BadCrc { command, received, computed }) => {
            (1, CaptureItem::Error(WireError::Checksum { command: *command, received: *received, computed: *computed }))
        }
        (Scan::BadLength(e), _) | (_, Scan::BadLength(e)) => (1, CaptureItem::Error(*e)),
        (Scan::Garbage(a), Scan::Garbage(b)) => {
            let n = (*a).min(*b).max(1);
            (n, CaptureItem::Error(WireError::Garbage { count: n }))
        }
    }
}
