//! How the session goes on: operations resumed and what they want next, exchanges ended, the keepalive's
//! replies handed out, a lost port, and the choice of what goes out next on the line.

use std::collections::BTreeMap;

use motionlink_link::session::{Action, Event, OpId};
use motionlink_link::Timestamp;

use super::ops::{self, Next, Operation, Resume};
use super::request::{OwnedReply, Schedule};
use super::txn::{Txn, TxnStep};
use super::*;
use crate::config::MAX_ROOM_WAIT;
use crate::wire::{Command, Status};

impl Session {
    pub(super) fn add_op(&mut self, op: Box<dyn Operation>, kind: Kind) -> OpId {
        let id = self.core.ids.next_id();
        self.ops.insert(id, Slot { op, waiting: Waiting::Nothing, kind, cancelled: false });
        self.advance(id, Resume::Start);
        id
    }

    /// Resumes operation `id` with `resume` and does what it wants next, until it waits for something.
    pub(super) fn advance(&mut self, id: OpId, mut resume: Resume) {
        loop {
            let Some(slot) = self.ops.get_mut(&id) else { return };
            let mut cx = Cx { core: &mut self.core, id, cancelled: slot.cancelled };
            let next = slot.op.step(&mut cx, resume);
            self.core.subscribers.remove(&id);
            match next {
                Next::Send(req) => {
                    if let Err(e) = self.core.admit(&req) {
                        resume = Resume::Reply(Err(e));
                        continue;
                    }
                    self.core.queue.push_back(Queued { owner: id, req, at: self.core.now });
                    slot_mut(&mut self.ops, id).waiting = Waiting::Queued;
                }
                Next::Sleep(t) => {
                    if t <= self.core.now {
                        resume = Resume::Wake;
                        continue;
                    }
                    slot_mut(&mut self.ops, id).waiting = Waiting::Until(t);
                }
                Next::Snapshot => {
                    if !self.core.link_up {
                        resume = Resume::Snapshot(Err(self.core.lost_error()));
                        continue;
                    }
                    if self.core.subscribers.is_empty() {
                        // Polling starts: the next RC is due one poll interval from now at the latest.
                        let first = self.core.now + self.core.config.poll_interval;
                        self.core.keepalive_due = self.core.keepalive_due.min(first);
                    }
                    self.core.subscribers.insert(id);
                    slot_mut(&mut self.ops, id).waiting = Waiting::Snapshot;
                }
                Next::Reopen => {
                    self.core.link_up = false;
                    self.core.reopen_waiter = Some(id);
                    self.core.outbox.push_back(Action::Reopen);
                    slot_mut(&mut self.ops, id).waiting = Waiting::Reopen;
                }
                Next::Done(result) => {
                    let slot = self.ops.remove(&id).expect("the slot was just used");
                    match slot.kind {
                        Kind::Public => self.core.events.push_back(Event::Done(id, result)),
                        Kind::Close => {
                            self.core.state = State::Closed;
                            self.core.line.remote = false;
                            self.core.events.push_back(Event::Closed(result.map(|_| ())));
                        }
                        Kind::Internal => {
                            if let Err(e) = result {
                                tracing::info!("{e}");
                            }
                        }
                    }
                    self.maybe_start_close();
                }
            }
            return;
        }
    }

    /// Once every caller's operation has ended, the end of the session begins.
    pub(super) fn maybe_start_close(&mut self) {
        if !self.core.closing || self.core.state == State::Closed {
            return;
        }
        if self.ops.values().any(|s| s.kind == Kind::Public || s.kind == Kind::Close) {
            return;
        }
        // An automatic reconnection under way is given up (once its exchange, if any, has ended).
        if self
            .ops
            .values()
            .any(|s| s.kind == Kind::Internal && matches!(s.waiting, Waiting::InFlight | Waiting::Reopen))
        {
            return;
        }
        let internal: Vec<OpId> =
            self.ops.iter().filter(|(_, s)| s.kind == Kind::Internal).map(|(id, _)| *id).collect();
        for id in internal {
            self.ops.remove(&id);
            self.core.queue.retain(|q| q.owner != id);
        }
        self.add_op(Box::new(ops::Close::new()), Kind::Close);
    }

    /// The exchange under way ended with `result`.
    pub(super) fn exchange_done(&mut self, owner: Owner, txn: Option<Txn>, result: Result<OwnedReply, Error>) {
        match owner {
            Owner::Keepalive(carries) => self.keepalive_done(carries, result),
            Owner::Op(id) => {
                let Some(mut txn) = txn else { return };
                match txn.next(&mut self.core, result) {
                    TxnStep::Again(request) => {
                        self.core.start_exchange(Owner::Op(id), Some(txn), request);
                    }
                    TxnStep::Finished(result) => {
                        if let Some(slot) = self.ops.get_mut(&id) {
                            slot.waiting = Waiting::Nothing;
                        }
                        self.advance(id, Resume::Reply(result));
                    }
                }
            }
        }
    }

    pub(super) fn keepalive_done(&mut self, carries: Carries, result: Result<OwnedReply, Error>) {
        let now = self.core.now;
        let snapshot = match result {
            Ok(reply) if reply.status == Status::Ack => {
                self.core.stats.keepalives += 1;
                match carries {
                    Carries::CallersObject => {
                        if let Some(data) = reply.data {
                            self.core.last_cyclic_read = Some((now, data));
                        }
                        None
                    }
                    Carries::PollObject => {
                        self.core.stats.motion_polls += 1;
                        Some(snapshot_of(reply.data.as_deref().unwrap_or_default(), now))
                    }
                    Carries::Nothing => None,
                }
            }
            Ok(reply) => {
                tracing::info!("keepalive RC refused: {}", reply.status);
                let e = if reply.status == Status::PermissionError {
                    let why = "the unit has left remote mode: it refused even RC with PE (it was reset, or another \
                               host sent RA); the session does not open remote mode again by itself"
                        .to_string();
                    self.core.state = State::Ended(why.clone());
                    self.core.line.remote = false;
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
            let waiting: Vec<OpId> = std::mem::take(&mut self.core.subscribers).into_iter().collect();
            for id in waiting {
                if let Some(slot) = self.ops.get_mut(&id) {
                    slot.waiting = Waiting::Nothing;
                }
                self.advance(id, Resume::Snapshot(snapshot.clone()));
            }
        }
    }

    /// The port failed: every exchange and request fails, the unit's watchdog stops the drives.
    pub(super) fn lost(&mut self, why: String) {
        if self.core.state == State::Opening && self.core.started.is_empty() {
            // Nothing was opened or started: the open fails with this, and its caller says so.
            tracing::debug!("SCU session lost while opening: {why}");
        } else {
            tracing::info!("SCU session lost: {why}");
        }
        let core = &mut self.core;
        core.link_up = false;
        core.line.remote = false;
        core.line.late = None;
        core.outbox.clear();
        if core.state != State::Closed {
            core.state = State::Lost(why.clone());
        }
        core.next_reconnect = core.now + core.config.reconnect_interval;
        let e = Error::SessionLost(why);
        if let Some(f) = core.in_flight.take() {
            self.exchange_done(f.owner, f.txn.map(Txn::abandon), Err(e.clone()));
        }
        let queued: Vec<Queued> = self.core.queue.drain(..).collect();
        for q in queued {
            if let Some(slot) = self.ops.get_mut(&q.owner) {
                slot.waiting = Waiting::Nothing;
            }
            self.advance(q.owner, Resume::Reply(Err(e.clone())));
        }
        let waiting: Vec<OpId> = std::mem::take(&mut self.core.subscribers).into_iter().collect();
        for id in waiting {
            self.advance(id, Resume::Snapshot(Err(e.clone())));
        }
    }

    /// Starts what can go out now: a stop, the keepalive when due, or a request that has room.
    pub(super) fn schedule(&mut self) {
        let now = self.core.now;
        self.fail_roomless(now);
        self.fail_watchers_without_keepalive();
        let core = &mut self.core;
        if core.in_flight.is_some() || core.reopen_waiter.is_some() || !core.link_up {
            return;
        }
        let running = core.keepalive_running();
        let mut rc_due = running && now >= core.keepalive_due;
        if rc_due && core.line.silent && core.subscribers.is_empty() {
            // The unit has not been heard for a whole request: its watchdog is left to expire (it stops the
            // drives); the next request tries the line. (A motion watched through the RC still gets its RC:
            // one short try, whose failure ends the watch.)
            core.advance_keepalive(now);
            rc_due = false;
        }
        let room = core.has_room(now);
        let urgent = core.queue.iter().position(|q| {
            !core.line.held_by_late(q.req.request.command, now)
                && (q.req.schedule == Schedule::Now
                    || (q.req.schedule == Schedule::RoomOrLate && now >= q.at + MAX_ROOM_WAIT))
        });
        let polite = if room {
            core.queue.iter().position(|q| !core.line.held_by_late(q.req.request.command, now))
        } else {
            None
        };
        let rc_free = !core.line.held_by_late(Command::Cyclic, now);
        let pick = if let Some(i) = urgent {
            Some(i)
        } else if rc_due && rc_free && (!core.last_was_rc || polite.is_none()) {
            core.send_keepalive(now);
            return;
        } else {
            polite
        };
        let Some(i) = pick else { return };
        let q = core.queue.remove(i).expect("picked from the queue");
        if let Some(slot) = self.ops.get_mut(&q.owner) {
            slot.waiting = Waiting::InFlight;
        }
        let txn = Txn::new(q.req.clone());
        if let Some(f) = q.req.request.starts {
            // Counted as started before it is sent: a lost reply may hide a started motion.
            self.core.started.insert(f);
        }
        self.core.start_exchange(Owner::Op(q.owner), Some(txn), q.req.request);
    }

    /// Operations waiting for the next poll of a motion get an error when no RC will come any more (the
    /// session is no longer open: the unit ended remote mode).
    fn fail_watchers_without_keepalive(&mut self) {
        if self.core.subscribers.is_empty() || self.core.keepalive_running() || !self.core.link_up {
            return;
        }
        let e = match &self.core.state {
            State::Ended(why) => Error::RemoteEnded(why.clone()),
            State::Lost(why) => Error::SessionLost(why.clone()),
            _ => Error::Closed,
        };
        let waiting: Vec<OpId> = std::mem::take(&mut self.core.subscribers).into_iter().collect();
        for id in waiting {
            if let Some(slot) = self.ops.get_mut(&id) {
                slot.waiting = Waiting::Nothing;
            }
            self.advance(id, Resume::Snapshot(Err(e.clone())));
        }
    }

    /// Requests that waited too long for room: fail, or go anyway.
    pub(super) fn fail_roomless(&mut self, now: Timestamp) {
        let expired: Vec<usize> = self
            .core
            .queue
            .iter()
            .enumerate()
            .filter(|(_, q)| q.req.schedule == Schedule::Room && now >= q.at + MAX_ROOM_WAIT)
            .map(|(i, _)| i)
            .collect();
        for i in expired.into_iter().rev() {
            let q = self.core.queue.remove(i).expect("index from the queue");
            let e = Error::NoRoom {
                command: q.req.request.command,
                round_trip: self.core.line.recent_round_trip.unwrap_or(self.core.line.round_trip),
                waited: now - q.at,
            };
            if let Some(slot) = self.ops.get_mut(&q.owner) {
                slot.waiting = Waiting::Nothing;
            }
            self.advance(q.owner, Resume::Reply(Err(e)));
        }
    }
}

pub(super) fn slot_mut(ops: &mut BTreeMap<OpId, Slot>, id: OpId) -> &mut Slot {
    ops.get_mut(&id).expect("the operation's slot")
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
