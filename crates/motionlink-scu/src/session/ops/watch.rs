//! Watching the state: a sample every interval of every actuator's status, position and current and of the
//! last error. Where the unit takes the session's cyclic object, each sample rides on a keepalive RC (so a
//! link whose round trips leave no room for any other request between two RCs can still be watched);
//! otherwise each sample is four reads, which go out only when there is room beside the keepalive. Where the
//! link leaves no room for the object's definition, it is written across one lapse of the unit's watchdog
//! while the session has started nothing ([`define_across_lapse`]).

use std::time::Duration;

use motionlink_link::Timestamp;

use super::object::{define_across_lapse, define_object};
use super::{currents, error_code, positions, read_item, statuses, ItemRead, Output, Progress};
use crate::error::Error;
use crate::model::{Actuator, DataIndex};
use crate::session::ctx::Ctx;
use crate::session::report::Snapshot;
use crate::wire::Command;

/// What a watch samples, and how often.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WatchSpec {
    /// Time between samples (the first is taken at once).
    pub interval: Duration,
    /// Stop after this many samples; `None`: until cancelled.
    pub count: Option<u64>,
}

/// The four reads of a sample taken with RG, in order.
const READS: [DataIndex; 4] = [DataIndex(0x0170), DataIndex(0x0010), DataIndex(0x00A0), DataIndex(0x00D1)];

/// A watch ([`super::Op::Watch`], [`crate::Client::watch`]): a sample at once and then every interval, until
/// the count is reached or a cancel ends it (which is no failure: the samples taken are the result).
pub(crate) async fn watch(ctx: &Ctx, spec: WatchSpec) -> Result<Output, Error> {
    let mut samples = 0;
    let mut last = None;
    let end = |samples, last| Ok(Output::Watched { samples, last });
    // On a link too slow for the definition beside the keepalive, it is made across one lapse of the
    // watchdog, and the RC that opens remote mode again brings the first sample.
    let mut first = None;
    match define_object(ctx).await {
        _ if ctx.cancelled() => return end(samples, last),
        Ok(()) => {}
        Err(e @ Error::NoRoom { .. }) => {
            // The first sample is the one the reopening RC brought.
            first = define_across_lapse(ctx, e).await?;
        }
        Err(e) => return Err(e),
    }
    // The first sample is taken now, once the object is defined; the next are due from now.
    let mut next_due = ctx.now();
    loop {
        let configured = {
            let core = ctx.core();
            core.poll_slot().is_some() && core.poll.configured
        };
        // Through the keepalive where the object is configured, else with reads.
        let sample = if let Some(s) = first.take() {
            s
        } else if configured {
            match ctx.snapshot_now().await {
                Some(Ok(s)) => s,
                Some(Err(e)) => return Err(e),
                None => return end(samples, last),
            }
        } else {
            match read_sample(ctx).await {
                Some(Ok(s)) => s,
                Some(Err(e)) => return Err(e),
                None => return end(samples, last),
            }
        };
        samples += 1;
        last = Some(sample);
        ctx.progress(Progress::Watch(sample));
        if ctx.cancelled() || spec.count.is_some_and(|c| samples >= c) {
            return end(samples, last);
        }
        // The next is due one interval after this one was (no drift); a sample that came back a little
        // before its time still takes its slot, and one that came late skips the slots it missed.
        let now = ctx.now();
        let interval = spec.interval.max(Duration::from_millis(1));
        next_due += interval;
        while next_due <= now {
            next_due += interval;
        }
        // Through the keepalive, the sample is asked for a round trip early: the RC that carries it then
        // comes back about when it is due (on a slow link the RC under way is waited for first).
        let lead = {
            let core = ctx.core();
            if core.poll.configured {
                core.line.recent_round_trip.unwrap_or(core.line.round_trip)
            } else {
                Duration::ZERO
            }
        };
        let ask_at = Timestamp::from_duration(next_due.since_origin().saturating_sub(lead));
        if ctx.pause_until(ask_at.max(now)).await {
            return end(samples, last);
        }
    }
}

/// A sample taken with reads (positions and currents of the connected actuators only). `None`: the watch
/// was cancelled meanwhile (nothing more is asked then).
async fn read_sample(ctx: &Ctx) -> Option<Result<Snapshot, Error>> {
    let reads = ctx.ending_on_cancel(Error::CancelledBeforeMotion(Command::Get));
    let data = read_item(&reads, ItemRead::all(READS[0])).await;
    if ctx.cancelled() {
        return None;
    }
    let statuses = match data.and_then(|d| statuses(&d)) {
        Ok(s) => s,
        Err(e) => return Some(Err(e)),
    };
    let connected: Vec<Actuator> =
        Actuator::all().filter(|a| statuses[usize::from(a.number() - 1)].available()).collect();
    let mut sample = Snapshot {
        at: ctx.now(),
        statuses,
        positions: Default::default(),
        currents_deci_amps: [0; 6],
        last_error: Default::default(),
    };
    for (i, index) in READS.iter().enumerate().skip(1) {
        let data = read_item(&reads, ItemRead::actuators(*index, connected.iter().copied())).await;
        if ctx.cancelled() {
            return None;
        }
        let parsed = data.and_then(|d| match i {
            1 => positions(&d).map(|p| sample.positions = p),
            2 => currents(&d).map(|c| sample.currents_deci_amps = c),
            _ => error_code(&d).map(|e| sample.last_error = e),
        });
        if let Err(e) = parsed {
            return Some(Err(e));
        }
    }
    sample.at = ctx.now();
    Some(Ok(sample))
}
