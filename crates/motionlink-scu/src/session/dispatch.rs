//! How the session goes on: the operations' requests queued and picked for the line, exchanges ended and
//! their outcomes handed to the operations that wait for them (the reply, the next poll of a motion, the
//! port reopened), the keepalive's replies, a lost port.

use motionlink_link::exec::Ticket;
use motionlink_link::session::{Action, OpId};
use motionlink_link::{LinkError, Timestamp};

use super::ops;
use super::pe_guard::{PeGuarded, PeStep};
use super::request::{OwnedReply, Schedule};
use super::*;
use crate::config::MAX_ROOM_WAIT;
use crate::wire::{Command, Status};

impl Core {
    /// Queues request `req` of operation `op` (admitted); its outcome goes under the ticket returned.
    /// `cancellable`: a cancel of the operation takes it out of the queue.
    pub(super) fn enqueue(&mut self, op: OpId, req: Req, cancellable: bool) -> Ticket {
        let ticket = self.replies.open(op);
        self.queue.push_back(Queued { owner: op, ticket, req, at: self.now, cancellable });
        ticket
    }

    /// Operation `op` was cancelled: its request still in the queue, if a cancel may take it out, ends with
    /// [`Error::CancelledBeforeMotion`].
    pub(super) fn cancel_queued(&mut self, op: OpId) {
        let Some(i) = self.queue.iter().position(|q| q.owner == op && q.cancellable) else { return };
        let q = self.queue.remove(i).expect("found in the queue");
        self.replies.finish(q.ticket, Err(Error::CancelledBeforeMotion(q.req.request.command)));
    }

    /// Operation `op` waits for the next poll of a motion; the outcome goes under the ticket returned.
    pub(super) fn subscribe(&mut self, op: OpId) -> Ticket {
        if self.subscribers.is_empty() {
            // Polling starts: the next RC is due one poll interval from now at the latest.
            let first = self.now + self.config.poll_interval;
            self.keepalive_due = self.keepalive_due.min(first);
        }
        let ticket = self.snapshots.open(op);
        if let Some(old) = self.subscribers.insert(op, ticket) {
            self.snapshots.close(old);
        }
        ticket
    }

    /// Operation `op` waits no longer for the next poll.
    pub(super) fn unsubscribe(&mut self, op: OpId) {
        if let Some(ticket) = self.subscribers.remove(&op) {
            self.snapshots.close(ticket);
        }
    }

    /// Operation `op` has the port closed and opened again; the outcome goes under the ticket returned.
    pub(super) fn request_reopen(&mut self, op: OpId) -> Ticket {
        self.link_up = false;
        let ticket = self.reopens.open(op);
        self.reopen_waiter = Some((op, ticket));
        self.outbox.push_back(Action::Reopen);
        ticket
    }

    /// The driver reopened the port, or could not.
    pub(super) fn reopened(&mut self, result: Result<(), LinkError>) {
        let Some((_, ticket)) = self.reopen_waiter.take() else { return };
        let result = match result {
            Ok(()) => {
                self.reset_line();
                Ok(())
            }
            Err(e) => Err(Error::from(e)),
        };
        self.reopens.finish(ticket, result);
    }

    /// Forgets what operation `op` waited for (it ended, or was given up): its request in the queue is not
    /// sent, what it waited for is dropped when it comes.
    pub(super) fn forget(&mut self, op: OpId) {
        self.replies.forget(op);
        self.snapshots.forget(op);
        self.reopens.forget(op);
        self.subscribers.remove(&op);
        self.queue.retain(|q| q.owner != op);
    }

    /// Operation `op` was cancelled: its own exchange under way, if a repetition of it is all that would
    /// follow (an RG, or an RE that the cancel makes unwanted), is sent no more once its present sending
    /// goes unanswered, so the stop that answers the cancel goes out sooner on a line that lost a reply.
    /// A request of the part of an operation that stops what it started is never cut short.
    pub(super) fn cut_short(&mut self, op: OpId) {
        if let Some(f) = self.in_flight.as_mut() {
            if matches!(f.owner, Owner::Op { id, cancellable: true, .. } if id == op) {
                f.exchange.cut_short();
                if let Some(guard) = f.pe_guard.as_mut() {
                    guard.cancelled();
                }
            }
        }
    }

    /// True while operation `op` has an exchange under way or waits for the port to be reopened.
    pub(super) fn busy_for(&self, op: OpId) -> bool {
        matches!(self.in_flight.as_ref().map(|f| f.owner), Some(Owner::Op { id, .. }) if id == op)
            || self.reopen_waiter.is_some_and(|(o, _)| o == op)
    }

    /// Bytes came from the unit at `now`.
    pub(super) fn handle_bytes(&mut self, bytes: &[u8], now: Timestamp) {
        let Some(f) = self.in_flight.as_mut() else {
            self.line.take_unsolicited(bytes, now);
            return;
        };
        let outcome = f.exchange.on_input(bytes, &mut self.line, &self.config, &mut self.counts, now, &mut self.outbox);
        if let Some(result) = outcome {
            let f = self.in_flight.take().expect("checked above");
            let resent = f.exchange.sent_again_unanswered();
            self.exchange_done(f.owner, f.pe_guard, result, resent);
        }
    }

    /// Time has reached `now`: the exchange under way may have timed out, late replies are no longer awaited,
    /// requests that found no room fail.
    pub(super) fn handle_timeout(&mut self, now: Timestamp) {
        if let Some(f) = self.in_flight.as_mut() {
            if let Some(result) =
                f.exchange.on_timeout(&mut self.line, &self.config, &mut self.counts, now, &mut self.outbox)
            {
                let f = self.in_flight.take().expect("checked above");
                let resent = f.exchange.sent_again_unanswered();
                self.exchange_done(f.owner, f.pe_guard, result, resent);
            }
        }
        self.line.expire_late(now);
        self.fail_roomless(now);
    }

    /// When the engine next needs the time (the operations' own times apart).
    pub(super) fn poll_timeout(&self) -> Option<Timestamp> {
        let mut next: Option<Timestamp> = None;
        let mut consider = |t: Timestamp| next = Some(next.map_or(t, |n: Timestamp| n.min(t)));
        if let Some(f) = &self.in_flight {
            consider(f.exchange.timeout_at());
        } else if self.link_up && self.reopen_waiter.is_none() {
            if self.keepalive_running() {
                // An RC held back by late replies to an earlier RC goes out when they came or their time is up.
                match self.line.late {
                    Some(late) if self.line.held_by_late(Command::Cyclic, self.now) => {
                        consider(self.keepalive_due.max(late.until))
                    }
                    _ => consider(self.keepalive_due),
                }
            }
            if let Some(late) = self.line.late {
                consider(late.until);
            }
            for q in &self.queue {
                if q.req.schedule != Schedule::Now {
                    consider(q.at + MAX_ROOM_WAIT);
                }
            }
        }
        if matches!(self.state, State::Lost(_)) && self.config.auto_reconnect && !self.closing {
            consider(self.next_reconnect);
        }
        next
    }

    /// The exchange under way ended with `result`; `resent`: its request went out again after a sending
    /// that got no clean answer ([`super::line::Exchange::sent_again_unanswered`]).
    pub(super) fn exchange_done(
        &mut self,
        owner: Owner,
        pe_guard: Option<PeGuarded>,
        result: Result<OwnedReply, Error>,
        resent: bool,
    ) {
        match owner {
            Owner::Keepalive(carries) => self.keepalive_done(carries, result),
            Owner::Op { id, ticket, cancellable } => {
                let Some(mut pe_guard) = pe_guard else { return };
                match pe_guard.next(self, result, resent) {
                    PeStep::Again(request) => {
                        self.start_exchange(Owner::Op { id, ticket, cancellable }, Some(pe_guard), request);
                    }
                    PeStep::Finished(result) => {
                        self.replies.finish(ticket, result);
                    }
                }
            }
        }
    }

    pub(super) fn keepalive_done(&mut self, carries: Carries, result: Result<OwnedReply, Error>) {
        let now = self.now;
        let snapshot = match result {
            Ok(reply) if reply.status == Status::Ack => {
                self.stats.keepalives += 1;
                match carries {
                    Carries::CallersObject => {
                        if let Some(data) = reply.data {
                            self.last_cyclic_read = Some((now, data));
                        }
                        None
                    }
                    Carries::PollObject => {
                        self.stats.motion_polls += 1;
                        Some(snapshot_of(reply.data.as_deref().unwrap_or_default(), now))
                    }
                    Carries::Nothing => None,
                }
            }
            Ok(reply) => {
                tracing::info!("keepalive RC refused: {}", reply.status);
                let e = if reply.status == Status::PermissionError {
                    let why = "the unit has left remote mode: it refused even RC with PE (its communication \
                               watchdog lapsed, which ends remote mode with Safety_ID 1 or 2; or it was reset, or \
                               another host sent RA); the session does not open remote mode again by itself"
                        .to_string();
                    self.state = State::Ended(why.clone());
                    self.line.remote = false;
                    Error::RemoteEnded(why)
                } else {
                    Error::Refused { command: Command::Cyclic, status: reply.status }
                };
                (carries == Carries::PollObject).then_some(Err(e))
            }
            // A unit that did not answer (or answered garbage) is not a lost port: a caller learns of it from
            // its own request; the end of the session still sends RS and RA.
            Err(e) => {
                tracing::info!("keepalive failed: {e}");
                (carries == Carries::PollObject).then_some(Err(e))
            }
        };
        if let Some(snapshot) = snapshot {
            self.deliver_snapshots(snapshot);
        }
    }

    /// Hands `result` to every operation waiting for the next poll.
    fn deliver_snapshots(&mut self, result: Result<Snapshot, Error>) {
        for (_, ticket) in std::mem::take(&mut self.subscribers) {
            self.snapshots.finish(ticket, result.clone());
        }
    }

    /// The port failed: every exchange and request fails, the unit's watchdog stops the drives.
    pub(super) fn lost(&mut self, why: String) {
        if self.state == State::Opening && self.started.is_empty() {
            // Nothing was opened or started: the open fails with this, and its caller says so.
            tracing::debug!("SCU session lost while opening: {why}");
        } else {
            tracing::info!("SCU session lost: {why}");
        }
        self.link_up = false;
        self.line.remote = false;
        self.line.late = None;
        self.outbox.clear();
        if self.state != State::Closed {
            self.state = State::Lost(why.clone());
        }
        self.next_reconnect = self.now + self.config.reconnect_interval;
        let e = Error::SessionLost(why);
        if let Some(f) = self.in_flight.take() {
            self.exchange_done(f.owner, f.pe_guard.map(PeGuarded::abandon), Err(e.clone()), false);
        }
        let queued: Vec<Queued> = self.queue.drain(..).collect();
        for q in queued {
            self.replies.finish(q.ticket, Err(e.clone()));
        }
        self.deliver_snapshots(Err(e));
    }

    /// Starts what can go out now: a stop, the keepalive when due, or a request that has room.
    pub(super) fn schedule(&mut self, now: Timestamp) {
        if self.in_flight.is_some() || self.reopen_waiter.is_some() || !self.link_up {
            return;
        }
        let running = self.keepalive_running();
        let mut rc_due = running && now >= self.keepalive_due;
        if rc_due && self.line.silent && self.subscribers.is_empty() {
            // The unit has not been heard for a whole request: its watchdog is left to expire (it stops the
            // drives); the next request tries the line. (A motion watched through the RC still gets its RC:
            // one short try, whose failure ends the watch.)
            self.advance_keepalive(now);
            rc_due = false;
        }
        let room = self.has_room(now);
        let urgent = self.queue.iter().position(|q| {
            !self.line.held_by_late(q.req.request.command, now)
                && (q.req.schedule == Schedule::Now
                    || (q.req.schedule == Schedule::RoomOrLate && now >= q.at + MAX_ROOM_WAIT))
        });
        let polite = if room {
            self.queue.iter().position(|q| !self.line.held_by_late(q.req.request.command, now))
        } else {
            None
        };
        let rc_free = !self.line.held_by_late(Command::Cyclic, now);
        let pick = if let Some(i) = urgent {
            Some(i)
        } else if rc_due && rc_free && (!self.last_was_rc || polite.is_none()) {
            self.send_keepalive(now);
            return;
        } else {
            polite
        };
        let Some(i) = pick else { return };
        let q = self.queue.remove(i).expect("picked from the queue");
        let pe_guard = PeGuarded::new(q.req.clone());
        if let Some(f) = q.req.request.starts {
            // Counted as started before it is sent: a lost reply may hide a started motion.
            self.started.insert(f);
        }
        let owner = Owner::Op { id: q.owner, ticket: q.ticket, cancellable: q.cancellable };
        self.start_exchange(owner, Some(pe_guard), q.req.request);
    }

    /// What waits in vain ends: requests that waited too long for room, and waits for the next poll of a
    /// motion when no RC will come any more.
    pub(super) fn fail_waiting(&mut self, now: Timestamp) {
        self.fail_roomless(now);
        self.fail_watchers_without_keepalive();
    }

    /// Operations waiting for the next poll of a motion get an error when no RC will come any more (the
    /// session is no longer open: the unit ended remote mode).
    fn fail_watchers_without_keepalive(&mut self) {
        if self.subscribers.is_empty() || self.keepalive_running() || !self.link_up {
            return;
        }
        let e = match &self.state {
            State::Ended(why) => Error::RemoteEnded(why.clone()),
            State::Lost(why) => Error::SessionLost(why.clone()),
            _ => Error::Closed,
        };
        self.deliver_snapshots(Err(e));
    }

    /// Requests that waited too long for room: fail, or go anyway.
    fn fail_roomless(&mut self, now: Timestamp) {
        let expired: Vec<usize> = self
            .queue
            .iter()
            .enumerate()
            .filter(|(_, q)| q.req.schedule == Schedule::Room && now >= q.at + MAX_ROOM_WAIT)
            .map(|(i, _)| i)
            .collect();
        for i in expired.into_iter().rev() {
            let q = self.queue.remove(i).expect("index from the queue");
            let e = Error::NoRoom {
                command: q.req.request.command,
                round_trip: self.line.recent_round_trip.unwrap_or(self.line.round_trip),
                waited: now - q.at,
            };
            self.replies.finish(q.ticket, Err(e));
        }
    }
}

/// The state in the read data of the session's cyclic object ([`POLL_READ`]).
pub(crate) fn snapshot_of(data: &[u8], at: Timestamp) -> Result<Snapshot, Error> {
    if data.len() != POLL_READ_LEN {
        return Err(Error::UnexpectedReply {
            command: Command::Cyclic,
            detail: format!("{} bytes of read data; the session's cyclic object reads {POLL_READ_LEN}", data.len()),
        });
    }
    Ok(Snapshot {
        at,
        statuses: ops::statuses(&data[..6])?,
        positions: ops::positions(&data[6..30])?,
        currents_deci_amps: ops::currents(&data[30..42])?,
        last_error: ops::error_code(&data[42..46])?,
    })
}
