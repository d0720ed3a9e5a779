//! The session's state apart from its operations: admission of requests, the keepalive's rhythm, room on
//! the line, and what opening or ending remote mode changes.

use std::time::Duration;

use motionlink_link::Timestamp;

use super::line::{Exchange, Line};
use super::pe_guard::PeGuarded;
use super::request::{PreparedRequest, Req};
use super::*;
use crate::config::{MovePolling, RC_DEADLINE};
use crate::model::{Function, SafetyId};
use crate::wire::{Command, Request};

impl Core {
    /// The stop of `functions` was not confirmed: the end of the session stops them again and looks for
    /// rest before it leaves remote mode.
    pub fn stop_unconfirmed(&mut self, functions: &[Function]) {
        for f in functions {
            if !self.unconfirmed_stops.contains(f) {
                self.unconfirmed_stops.push(*f);
            }
        }
    }

    /// The stop of `functions` was confirmed (`every_actuator`: every actuator was found at rest, so no
    /// earlier stop is left unconfirmed either).
    pub fn stop_confirmed(&mut self, functions: &[Function], every_actuator: bool) {
        if every_actuator {
            self.unconfirmed_stops.clear();
        } else {
            self.unconfirmed_stops.retain(|f| !functions.contains(f));
        }
    }

    /// The error every request gets while the port is gone.
    pub fn lost_error(&self) -> Error {
        match &self.state {
            State::Lost(why) => Error::SessionLost(why.clone()),
            _ => Error::SessionLost("port not connected".into()),
        }
    }

    /// Checks whether `req` may be queued in the present state.
    pub(super) fn admit(&self, req: &Req) -> Result<(), Error> {
        if !self.link_up {
            return Err(self.lost_error());
        }
        if !req.needs_open {
            return Ok(());
        }
        match &self.state {
            State::Open | State::Opening => Ok(()),
            State::Ended(why) => Err(Error::RemoteEnded(why.clone())),
            State::Lost(why) => Err(Error::SessionLost(why.clone())),
            State::Closed => Err(Error::Closed),
        }
    }

    pub(super) fn keepalive_running(&self) -> bool {
        self.line.remote && self.state == State::Open && self.link_up
    }

    /// The RC rhythm: the keepalive period, or the poll interval while a motion is polled through the RC.
    pub(super) fn rc_period(&self) -> Duration {
        if self.subscribers.is_empty() {
            self.config.keepalive_period
        } else {
            self.config.poll_interval.min(self.config.keepalive_period)
        }
    }

    /// True if a request sent now is expected back before the next RC must go out.
    pub(super) fn has_room(&self, now: Timestamp) -> bool {
        if !self.keepalive_running() || self.line.silent {
            return true;
        }
        let expected = self.line.recent_round_trip.unwrap_or(self.line.round_trip);
        self.last_rc_sent.is_none_or(|t| now + expected <= t + RC_DEADLINE)
    }

    /// True if a request queued now goes out without waiting for room between the keepalives (behind at most
    /// the exchange under way).
    pub(crate) fn room_at_once(&self) -> bool {
        self.queue.is_empty() && self.has_room(self.now)
    }

    pub(super) fn advance_keepalive(&mut self, now: Timestamp) {
        let period = self.rc_period();
        while self.keepalive_due <= now {
            self.keepalive_due += period;
        }
    }

    /// Whether the session polls motions through its cyclic object (else with reads), and which slot.
    pub fn poll_slot(&self) -> Option<u8> {
        match self.config.move_polling {
            MovePolling::Cyclic { slot } if !self.poll.refused && self.cyclic.is_none() => Some(slot),
            _ => None,
        }
    }

    pub(super) fn send_keepalive(&mut self, now: Timestamp) {
        self.advance_keepalive(now);
        let poll = (!self.subscribers.is_empty() && self.poll.configured).then(|| self.poll_slot()).flatten();
        let (carries, request) = match (poll, &self.cyclic) {
            (Some(slot), _) => (Carries::PollObject, Ok(PreparedRequest::poll_object(slot))),
            (None, Some(c)) => {
                let read_len = c.object.read_size().and_then(|n| u16::try_from(n).ok());
                (
                    Carries::CallersObject,
                    PreparedRequest::with_reply_len(&Request::Cyclic { object: c.slot - 1, write: &c.write }, read_len),
                )
            }
            (None, None) => (Carries::Nothing, Ok(PreparedRequest::keepalive())),
        };
        match request {
            Ok(r) => self.start_exchange(Owner::Keepalive(carries), None, r),
            Err(e) => tracing::warn!("keepalive not sent: {e}"),
        }
    }

    pub(super) fn start_exchange(&mut self, owner: Owner, pe_guard: Option<PeGuarded>, request: PreparedRequest) {
        let now = self.now;
        let is_rc = request.command == Command::Cyclic;
        if is_rc {
            self.last_rc_sent = Some(now);
        }
        self.last_was_rc = is_rc;
        let exchange = Exchange::start(request, &mut self.line, &self.config, now, &mut self.outbox);
        self.in_flight = Some(InFlight { owner, pe_guard, exchange });
    }

    /// Counts a reopened remote mode.
    pub fn opened(&mut self, rc_sent: Timestamp) {
        self.state = State::Open;
        self.keepalive_due = rc_sent + self.config.keepalive_period;
        self.last_rc_sent = Some(rc_sent);
        self.poll.configured = false;
    }

    /// The unit ended remote mode.
    pub fn ended(&mut self, why: String) -> Error {
        tracing::info!("{why}");
        self.line.remote = false;
        self.state = State::Ended(why.clone());
        Error::RemoteEnded(why)
    }

    /// What the unit stops when its watchdog expires.
    pub fn lapse_stops(&self) -> &'static str {
        match self.config.safety_id {
            SafetyId::StopRemoteOnly => "the remote motions",
            _ => "every motion",
        }
    }

    /// The port was opened again: a fresh line.
    pub fn reset_line(&mut self) {
        self.line = Line {
            round_trip: self.line.round_trip,
            recent_round_trip: self.line.recent_round_trip,
            ..Line::default()
        };
        self.link_up = true;
    }
}
