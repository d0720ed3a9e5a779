//! Requests as the session keeps them: their bytes and what their reply must look like, when they may go
//! out, and what they mean for the functions the session started.

use crate::error::Error;
use crate::model::{item, DataIndex, StopMode, UNUSED};
use crate::wire::{request_to_vec, Command, ReplyShape, Request, Status};

/// A request the session owns: its telegram and what its reply must look like.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PreparedRequest {
    pub(crate) bytes: Vec<u8>,
    pub(crate) command: Command,
    pub(crate) shape: ReplyShape,
    /// The number of data bytes of the ACK, when the request fixes it.
    pub(crate) reply_len: Option<u16>,
    /// RE of this function id (marked started before it is sent).
    pub(crate) starts: Option<u8>,
    /// RS of this function id (unmarked when acknowledged).
    pub(crate) stops: Option<u8>,
}

impl PreparedRequest {
    /// Encodes `request`; an RG expects exactly the size of its data-list item.
    pub fn new(request: &Request<'_>) -> Result<Self, Error> {
        let reply_len = match request {
            Request::Get { index } => item(DataIndex(*index)).and_then(|it| u16::try_from(it.size()).ok()),
            _ => None,
        };
        Self::with_reply_len(request, reply_len)
    }

    /// Encodes `request`, whose ACK carries exactly `reply_len` data bytes if given.
    pub fn with_reply_len(request: &Request<'_>, reply_len: Option<u16>) -> Result<Self, Error> {
        let bytes = request_to_vec(request).map_err(|e| Error::InvalidArgument(e.to_string()))?;
        Ok(PreparedRequest {
            bytes,
            command: request.command(),
            shape: request.reply_shape(),
            reply_len,
            starts: match request {
                Request::Execute { function, .. } => Some(*function),
                _ => None,
            },
            stops: match request {
                Request::Stop { function, .. } => Some(*function),
                _ => None,
            },
        })
    }

    /// The request's command.
    pub fn command(&self) -> Command {
        self.command
    }

    /// The telegram.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// RC without a cyclic object: the keepalive. Its ACK is the status alone or carries ctp 0 (both forms
    /// are taken: see [`crate::wire::ReplyShape::StatusOrData`]).
    pub(crate) fn keepalive() -> Self {
        Self::with_reply_len(&Request::Cyclic { object: UNUSED, write: &[] }, Some(0))
            .expect("an RC without object encodes")
    }

    /// RC carrying the session's cyclic object, CyclicObj `slot` (1..5): it writes nothing and reads
    /// [`super::POLL_READ`].
    pub(crate) fn poll_object(slot: u8) -> Self {
        Self::with_reply_len(&Request::Cyclic { object: slot - 1, write: &[] }, Some(super::POLL_READ_LEN as u16))
            .expect("an RC without write data encodes")
    }

    /// RG of `index`.
    pub(crate) fn get(index: DataIndex) -> Self {
        Self::new(&Request::Get { index: index.0 }).expect("an RG encodes")
    }

    /// RS of function id `f`: a fast stop for a motion function.
    pub(crate) fn stop(f: u8, mode: StopMode) -> Self {
        let param = if f <= 9 { mode.code() } else { UNUSED };
        Self::new(&Request::Stop { function: f, param }).expect("an RS encodes")
    }
}

/// A reply as the session hands it on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct OwnedReply {
    pub status: Status,
    pub data: Option<Vec<u8>>,
}

impl OwnedReply {
    /// The reply if the unit acknowledged `command`, else [`Error::Refused`].
    pub fn ack(self, command: Command) -> Result<OwnedReply, Error> {
        if self.status == Status::Ack {
            Ok(self)
        } else {
            Err(Error::Refused { command, status: self.status })
        }
    }

    /// The data of an acknowledged reply.
    pub fn data(self, command: Command) -> Result<Vec<u8>, Error> {
        let reply = self.ack(command)?;
        reply.data.ok_or(Error::UnexpectedReply { command, detail: "ACK without data".into() })
    }
}

/// When a request may go out, given the unit's watchdog: it must not hold the line past the time the next RC
/// must be sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Schedule {
    /// At once, before any keepalive that is due: stops, RA, RO.
    Now,
    /// When there is room; after [`crate::config::MAX_ROOM_WAIT`] without room, it is sent anyway (the RS
    /// that ends a motion that has ended: the manual wants it, and it must not be left out).
    RoomOrLate,
    /// When there is room; after [`crate::config::MAX_ROOM_WAIT`] without room, it fails with
    /// [`Error::NoRoom`].
    Room,
}

/// A request of an operation, and how the session handles it.
#[derive(Debug, Clone)]
pub(crate) struct Req {
    pub request: PreparedRequest,
    pub schedule: Schedule,
    /// A PE is looked into (RC, probe): see the crate documentation, "A session the unit ended".
    pub checked: bool,
    /// Refused at once unless the session is open (not ended by the unit, not lost, not closed).
    pub needs_open: bool,
}

impl Req {
    /// A request of a caller's operation: checked, only in an open session, when there is room.
    pub fn op(request: PreparedRequest) -> Self {
        Req { request, schedule: Schedule::Room, checked: true, needs_open: true }
    }

    /// A request of the session's own sequences (open, reopen, the end): unchecked, in any state, at once.
    pub fn internal(request: PreparedRequest) -> Self {
        Req { request, schedule: Schedule::Now, checked: false, needs_open: false }
    }

    /// The same request, sent as `schedule` says.
    pub fn when(mut self, schedule: Schedule) -> Self {
        self.schedule = schedule;
        self
    }
}
