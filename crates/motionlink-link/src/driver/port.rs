//! The port a driver runs a session over.

use std::time::Duration;

use crate::can::{CanFrame, CanLink};
use crate::link::{Link, LinkError};
use crate::session::Action;

/// The link a driver runs a session over.
pub enum Port {
    /// A byte stream: a serial port, a TCP gateway, a pty, an in-memory pipe.
    Bytes(Box<dyn Link>),
    /// A CAN bus.
    Can(Box<dyn CanLink>),
    /// No port: the last one was lost and could not be reopened. Every use fails as disconnected.
    Closed(String),
}

impl std::fmt::Debug for Port {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

/// One thing received from a port.
pub(super) enum Received {
    Bytes(usize),
    Frame(CanFrame),
}

impl Port {
    /// The port as a user would name it.
    pub fn describe(&self) -> String {
        match self {
            Port::Bytes(l) => l.describe(),
            Port::Can(l) => l.describe(),
            Port::Closed(name) => name.clone(),
        }
    }

    pub(super) fn gone(&self) -> LinkError {
        LinkError::Disconnected { port: self.describe(), reason: "the port is closed".into() }
    }

    pub(super) fn perform(&mut self, action: &Action) -> Result<(), LinkError> {
        match (self, action) {
            (Port::Bytes(l), Action::Send(bytes)) => l.send(bytes),
            (Port::Can(l), Action::SendFrame(frame)) => l.send(frame),
            (Port::Bytes(l), Action::DiscardInput) => l.discard_input(),
            (Port::Can(l), Action::DiscardInput) => l.discard_input(),
            (p @ Port::Closed(_), _) => Err(p.gone()),
            (p, a) => Err(LinkError::Io {
                port: p.describe(),
                source: std::sync::Arc::new(std::io::Error::other(format!("{a:?} does not fit this kind of port"))),
            }),
        }
    }

    pub(super) fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<Option<Received>, LinkError> {
        match self {
            Port::Bytes(l) => l.recv(buf, timeout).map(|n| (n > 0).then_some(Received::Bytes(n))),
            Port::Can(l) => l.recv(timeout).map(|f| f.map(Received::Frame)),
            Port::Closed(_) => Err(self.gone()),
        }
    }
}

/// Opens (and reopens, after a loss) a driver's port.
pub type PortOpener = Box<dyn FnMut() -> Result<Port, LinkError> + Send>;
