//! The half-duplex line: one exchange at a time, its repetitions after silence, corrupt or incomplete
//! replies, CSE and PCE, the zeros that complete a telegram whose length byte was corrupted, and the replies
//! still owed for the other sendings of a request. See the crate documentation, "Replies, retries and a dead
//! link".

use std::collections::VecDeque;
use std::time::Duration;

use motionlink_link::session::Action;
use motionlink_link::Timestamp;

use super::request::{OwnedReply, PreparedRequest};
use crate::config::{Config, FLUSH_LEN, SESSION_REPLY_LIMIT, SILENT_TRY};
use crate::error::Error;
use crate::wire::{Command, ReplyDecoder, ReplyShape, Status, WireError};

/// What the session knows about the line.
#[derive(Debug, Default)]
pub(crate) struct Line {
    pub decoder: ReplyDecoder,
    /// No byte came from the unit during a whole request: keepalives pause, and each request gets one
    /// sending and [`SILENT_TRY`], until the unit is heard again.
    pub silent: bool,
    /// The longest round trip measured lately (decaying): for the silence window.
    pub round_trip: Duration,
    /// The round trip of the latest exchanges that went out once (smoothed, RO left out): what a request is
    /// expected to take, for room on the line.
    pub recent_round_trip: Option<Duration>,
    /// RO was acknowledged: the unit is (as far as the session knows) in remote mode.
    pub remote: bool,
    /// Replies that may still arrive for a request that was sent more than once.
    pub late: Option<LateReplies>,
}

/// The replies still owed for the other sendings of a request that was answered.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LateReplies {
    /// How many.
    pub count: u32,
    /// They are awaited no longer than this.
    pub until: Timestamp,
    pub command: Command,
    pub shape: ReplyShape,
}

impl Line {
    /// True while a request of `command` must wait for late replies to an earlier one of the same command
    /// (they would otherwise be taken for its reply).
    pub fn held_by_late(&self, command: Command, now: Timestamp) -> bool {
        self.late.is_some_and(|l| l.command == command && l.count > 0 && now < l.until)
    }

    /// Bytes that came while no exchange is under way: late replies are counted and dropped.
    pub fn take_unsolicited(&mut self, mut input: &[u8], now: Timestamp) {
        let Some(late) = self.late.as_mut() else {
            tracing::trace!("{} byte(s) from the unit while nothing was asked; dropped", input.len());
            return;
        };
        if now >= late.until {
            self.late = None;
            self.decoder.reset();
            return;
        }
        self.decoder.expect(late.command, late.shape);
        while !input.is_empty() {
            let (used, event) = self.decoder.decode(input);
            input = &input[used..];
            if let Some(Ok(_)) = event {
                tracing::debug!("late reply to {} dropped", late.command);
                late.count = late.count.saturating_sub(1);
            }
            if used == 0 && event.is_none() {
                break;
            }
        }
        if late.count == 0 {
            self.late = None;
            self.decoder.reset();
        }
    }

    /// Forgets late replies whose time is over.
    pub fn expire_late(&mut self, now: Timestamp) {
        if self.late.is_some_and(|l| now >= l.until) {
            self.late = None;
            self.decoder.reset();
        }
    }
}

/// Why one sending of a request failed.
enum AttemptError {
    /// Not one byte of a reply in time. `stray`: bytes came, but none that started a reply.
    Silent {
        stray: bool,
    },
    /// A reply started and then stopped for longer than the silence window.
    Incomplete,
    Corrupt(WireError),
}

/// Counters an exchange updates.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct LineCounts {
    pub retries: u64,
    pub flushes: u64,
}

/// One request on the line, from its first sending to its reply or its failure.
#[derive(Debug)]
pub(crate) struct Exchange {
    pub request: PreparedRequest,
    first_sent: Timestamp,
    last_sent: Timestamp,
    deadline: Timestamp,
    limit: Duration,
    single_try: bool,
    attempts: u32,
    repairs: u32,
    silent_resends: u32,
    heard_anything: bool,
    flushed: bool,
    window: Duration,
    /// When the present sending was made, or the reply last advanced.
    progress_at: Timestamp,
    /// The reply to the present sending has started.
    heard: bool,
    /// Bytes came during the present sending.
    stray: bool,
    /// Its operation was cancelled: no sending after the present one ([`Exchange::cut_short`]).
    last_sending: bool,
    /// It went out again after a sending that got no clean answer (silence, a reply cut off or corrupt):
    /// the unit may have taken an earlier sending ([`Exchange::sent_again_unanswered`]).
    resent_unanswered: bool,
}

impl Exchange {
    /// Sends `request` (its first sending goes into `out`).
    pub fn start(
        request: PreparedRequest,
        line: &mut Line,
        config: &Config,
        now: Timestamp,
        out: &mut VecDeque<Action>,
    ) -> Exchange {
        let mut limit = config.reply_timeout;
        if line.remote && request.command != Command::Open {
            limit = limit.min(SESSION_REPLY_LIMIT);
        }
        let single_try = line.silent;
        if single_try {
            limit = limit.min(SILENT_TRY);
        }
        let window =
            if single_try { limit } else { config.effective_retry_after().max(line.round_trip.saturating_mul(2)) };
        if line.late.is_some_and(|l| l.command != request.command) {
            // Late replies of another command cannot be taken for this reply (the decoder skips them).
        } else {
            line.late = None;
        }
        let mut exchange = Exchange {
            request,
            first_sent: now,
            last_sent: now,
            deadline: now + limit,
            limit,
            single_try,
            attempts: 0,
            repairs: 0,
            silent_resends: 0,
            heard_anything: false,
            flushed: false,
            window,
            progress_at: now,
            heard: false,
            stray: false,
            last_sending: false,
            resent_unanswered: false,
        };
        exchange.send(line, now, out);
        exchange
    }

    /// The operation that sent this request was cancelled: a read (RG) or an RE (which the cancel makes
    /// unwanted: a repeat could start the motion that is being stopped) is not sent again; when the present
    /// sending goes unanswered, the exchange fails at once. Other requests (RT, RS, RO, RA, RC) go on.
    pub fn cut_short(&mut self) {
        if matches!(self.request.command, Command::Get | Command::Execute) {
            self.last_sending = true;
        }
    }

    /// True when the request went out again after a sending that got no clean answer: a reply (a PE to an
    /// RE, say) may then answer a repeat of what the unit took from an earlier sending.
    pub fn sent_again_unanswered(&self) -> bool {
        self.resent_unanswered
    }

    /// When it first went out.
    fn send(&mut self, line: &mut Line, now: Timestamp, out: &mut VecDeque<Action>) {
        self.attempts += 1;
        self.last_sent = now;
        self.progress_at = now;
        self.heard = false;
        self.stray = false;
        line.decoder.reset();
        match self.request.reply_len {
            Some(n) => line.decoder.expect_len(self.request.command, self.request.shape, n),
            None => line.decoder.expect(self.request.command, self.request.shape),
        }
        out.push_back(Action::Send(self.request.bytes.clone()));
    }

    /// When [`Exchange::on_timeout`] must be called.
    pub fn timeout_at(&self) -> Timestamp {
        (self.progress_at + self.window).min(self.deadline)
    }

    /// Bytes arrived. Returns the outcome once the exchange has one.
    pub fn on_input(
        &mut self,
        mut input: &[u8],
        line: &mut Line,
        config: &Config,
        counts: &mut LineCounts,
        now: Timestamp,
        out: &mut VecDeque<Action>,
    ) -> Option<Result<OwnedReply, Error>> {
        self.stray |= !input.is_empty();
        loop {
            let (used, event) = line.decoder.decode(input);
            input = &input[used..];
            match event {
                Some(Ok(reply)) => {
                    let reply = OwnedReply { status: reply.status, data: reply.data.map(<[u8]>::to_vec) };
                    return self.replied(reply, line, config, counts, now, out);
                }
                Some(Err(WireError::Garbage { count })) => tracing::trace!("{count} stray byte(s) skipped"),
                Some(Err(e)) => return self.failed(AttemptError::Corrupt(e), line, config, counts, now, out),
                None if input.is_empty() => break,
                None => {}
            }
        }
        // The unit is answering once the start of a reply is in; each byte of it restarts the window.
        if line.decoder.is_mid_telegram() {
            self.heard = true;
            self.progress_at = now;
        }
        None
    }

    /// Time has reached `now`.
    pub fn on_timeout(
        &mut self,
        line: &mut Line,
        config: &Config,
        counts: &mut LineCounts,
        now: Timestamp,
        out: &mut VecDeque<Action>,
    ) -> Option<Result<OwnedReply, Error>> {
        if now < self.timeout_at() {
            return None;
        }
        let e = if self.heard { AttemptError::Incomplete } else { AttemptError::Silent { stray: self.stray } };
        self.failed(e, line, config, counts, now, out)
    }

    fn replied(
        &mut self,
        reply: OwnedReply,
        line: &mut Line,
        config: &Config,
        counts: &mut LineCounts,
        now: Timestamp,
        out: &mut VecDeque<Action>,
    ) -> Option<Result<OwnedReply, Error>> {
        line.silent = false;
        // A clean sample when the request went out once; else the time since the first sending (an upper
        // bound: the reply may answer a later sending).
        let sample = now - self.first_sent;
        line.round_trip = if sample > line.round_trip { sample } else { (line.round_trip * 7 + sample) / 8 };
        if self.attempts == 1 && self.request.command != Command::Open {
            line.recent_round_trip = Some(line.recent_round_trip.map_or(sample, |r| (r + sample) / 2));
        }
        if matches!(reply.status, Status::ChecksumError | Status::ParameterCountError)
            && self.repairs < config.retries
            && now < self.deadline
        {
            // The unit did not execute the request (a CSE, or a PCE for a count that a corrupt byte changed).
            tracing::debug!("{} answered {}; sending again", self.request.command, reply.status);
            self.repairs += 1;
            self.repeat(line, counts, now, out);
            return None;
        }
        if self.silent_resends > 0 || self.flushed {
            // The unit may answer the other sendings too, as late as it answered this one.
            let late_by = now - self.first_sent;
            line.late = Some(LateReplies {
                count: self.silent_resends,
                until: self.last_sent + late_by + config.effective_retry_after(),
                command: self.request.command,
                shape: self.request.shape,
            });
        }
        Some(Ok(reply))
    }

    /// Sends again after a corrupt or incomplete reply, a CSE or a PCE: what came is discarded.
    fn repeat(&mut self, line: &mut Line, counts: &mut LineCounts, now: Timestamp, out: &mut VecDeque<Action>) {
        counts.retries += 1;
        out.push_back(Action::DiscardInput);
        self.send(line, now, out);
    }

    fn failed(
        &mut self,
        e: AttemptError,
        line: &mut Line,
        config: &Config,
        counts: &mut LineCounts,
        now: Timestamp,
        out: &mut VecDeque<Action>,
    ) -> Option<Result<OwnedReply, Error>> {
        let command = self.request.command;
        let again = !self.single_try && !self.last_sending && now < self.deadline;
        let may_repair = again && self.repairs < config.retries;
        // A cut-short exchange says how long it waited, not the timeout it would have waited.
        let timeout = if self.last_sending { now.saturating_since(self.first_sent) } else { self.limit };
        match e {
            AttemptError::Silent { stray } if again => {
                self.heard_anything |= stray;
                tracing::debug!("no reply to {command} yet; sending again");
                if !self.flushed {
                    // Zeros complete a telegram the unit holds half-received (its length byte was corrupted,
                    // so it waits for more) and are skipped as garbage otherwise.
                    out.push_back(Action::Send(vec![0u8; FLUSH_LEN]));
                    counts.flushes += 1;
                    self.flushed = true;
                }
                if !stray {
                    self.silent_resends += 1;
                }
                self.window = self.window.saturating_mul(2);
                counts.retries += 1;
                self.resent_unanswered = true;
                // Nothing is discarded: the reply to the first sending may still come, and counts.
                self.send(line, now, out);
                None
            }
            AttemptError::Incomplete if may_repair => {
                self.heard_anything = true;
                tracing::debug!("the reply to {command} stopped in the middle; sending again");
                self.repairs += 1;
                self.resent_unanswered = true;
                self.repeat(line, counts, now, out);
                None
            }
            AttemptError::Corrupt(error) if may_repair => {
                self.heard_anything = true;
                tracing::debug!("corrupt reply to {command} ({error}); sending again");
                self.repairs += 1;
                self.resent_unanswered = true;
                self.repeat(line, counts, now, out);
                None
            }
            AttemptError::Silent { stray } => {
                // One sending cut short proves no silent line: the stop that follows gets its repetitions.
                if !stray && !self.heard_anything && !self.last_sending {
                    line.silent = true;
                }
                Some(Err(Error::Timeout { command, timeout, attempts: self.attempts }))
            }
            AttemptError::Incomplete => Some(Err(Error::Timeout { command, timeout, attempts: self.attempts })),
            AttemptError::Corrupt(error) => Some(Err(Error::Corrupt { command, error, attempts: self.attempts })),
        }
    }
}
