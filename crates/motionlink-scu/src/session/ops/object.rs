//! The session's cyclic object, which lets every keepalive RC of a motion or a watch read the state: defined
//! once per session (RT of CyclicObj `slot`, read back) and probed with one RC carrying it, before anything
//! depends on it. A unit that refuses any of it is watched with reads, said once per session.

use super::basic::write;
use super::remote::opening_with;
use crate::error::Error;
use crate::model::{CyclicObject, DataIndex};
use crate::session::ctx::Ctx;
use crate::session::dispatch::snapshot_of;
use crate::session::request::{PreparedRequest, Req, Schedule};
use crate::session::{Snapshot, POLL_READ};
use crate::wire::{Command, Request};

/// What to do before a motion or a sample is watched: nothing when the session does not use its object,
/// the object is configured, or the unit did not take it; else the object is defined and probed. Its end:
/// the session's `poll` says whether the object is configured (motions are then watched through the
/// keepalive) or refused (with reads); `Err` only for what is no refusal (a link that failed).
pub(crate) async fn define_object(ctx: &Ctx) -> Result<(), Error> {
    let (slot, configured, known_refused, groups_refused) = {
        let core = ctx.core();
        (
            core.poll_slot(),
            core.poll.configured,
            core.probed.known().cyclic_objects == Some(false),
            POLL_READ.iter().any(|i| core.group_refused(*i)),
        )
    };
    let Some(slot) = slot else { return Ok(()) };
    if configured {
        return Ok(());
    }
    if known_refused {
        // Known (from a device profile) not to take the object: watched with reads, without asking again.
        ctx.core().poll.refused = true;
        return Ok(());
    }
    if groups_refused {
        // The object reads grouping indices, which the unit refuses (said once, with what follows).
        ctx.core().poll.refused = true;
        return Ok(());
    }
    match write(ctx, object_index(slot), &poll_object().to_bytes(), true).await {
        // Found in this session (remote mode opened again): the RC is not asked again. A device profile's
        // word is not enough: the RC below probes it (one keepalive's worth).
        Ok(None) if ctx.core().probed.caps.cyclic_objects == Some(true) => {
            ctx.core().poll.configured = true;
            return Ok(());
        }
        Ok(None) => {}
        Ok(Some(_)) => {
            ctx.core().poll.refuse(&format!("the unit does not read the definition of CyclicObj {slot} back"));
            return Ok(());
        }
        Err(Error::Refused { status, .. }) => {
            ctx.core().poll.refuse(&format!("the unit refused the definition of CyclicObj {slot} ({status})"));
            return Ok(());
        }
        Err(e) => return Err(e),
    }
    // One RC carries the object: does the unit answer it with the state?
    match ctx.send(Req::op(PreparedRequest::poll_object(slot))).await.and_then(|r| r.data(Command::Cyclic)) {
        Ok(data) => {
            snapshot_of(&data, ctx.now())?;
            let mut core = ctx.core();
            core.cyclic_objects(true);
            core.poll.configured = true;
            Ok(())
        }
        Err(Error::Refused { status, .. }) => {
            let mut core = ctx.core();
            core.cyclic_objects(false);
            core.poll.refuse(&format!("the unit refused an RC carrying CyclicObj {slot} ({status})"));
            Ok(())
        }
        Err(e) => Err(e),
    }
}

/// The definition of the session's cyclic object: it writes nothing and reads [`POLL_READ`].
fn poll_object() -> CyclicObject {
    CyclicObject::new(&[], &POLL_READ).expect("four read indices fit")
}

/// The data index of CyclicObj `slot` (1..5).
fn object_index(slot: u8) -> DataIndex {
    DataIndex(0x3000 + u16::from(slot))
}

/// The definition of the session's cyclic object for a watch on a link too slow for it (`no_room`: the
/// definition found no room between two RCs). The manual gives no form that fits: the RT and RG it needs
/// come only after the first RC, and the RC alone feeds the watchdog, so an RC, one other request and the
/// next RC reach the unit two round trips apart, beyond its 500 ms. So, only where the user allowed it
/// ([`Config::watch_may_lapse`](crate::Config::watch_may_lapse)) and while the session has started
/// nothing, the RT goes out at once and the watchdog lapses after it (the unit records error bit 22 and
/// stops the motions its Safety_ID says, none of them this session's); then RO and an RC that carries the
/// object open remote mode again, and that RC's reply (the object's read data, of the length its
/// definition gives) is the check that the unit holds the definition (there is no room to read it back).
/// The cyclic objects are remote data, kept until a reset, which neither the lapse nor RO is.
///
/// Its end: `Ok(Some(sample))`, the state read by that RC (the object is configured); `Ok(None)`, the unit
/// refused the object (remote mode is open again, the session watches with reads, which find no room);
/// `Err(no_room)` where the lapse is not allowed or the session started a function (nothing lapses then); another `Err` if remote mode
/// could not be opened again (the session is then ended).
pub(crate) async fn define_across_lapse(ctx: &Ctx, no_room: Error) -> Result<Option<Snapshot>, Error> {
    let (slot, started, round_trip, may_lapse) = {
        let core = ctx.core();
        let round_trip = core.line.recent_round_trip.unwrap_or(core.line.round_trip);
        (core.poll_slot(), !core.started.is_empty(), round_trip, core.config.watch_may_lapse)
    };
    let Some(slot) = slot.filter(|_| !started && may_lapse) else { return Err(no_room) };
    tracing::warn!(
        "round trips of {} ms leave no room beside the keepalive for the definition of CyclicObj {slot}: it is \
         written now and the unit's 500 ms watchdog lapses once, while this session has started nothing (the unit \
         records error bit 22, remote communication time out, and stops every motion under way, with \
         Safety_ID 2 the remote ones only); then RO and an RC carrying the object open remote mode again",
        round_trip.as_millis()
    );
    // Nothing may cut this short once the RT is on its way: remote mode must be opened again.
    let ctx = ctx.firm();
    let rt = PreparedRequest::new(&Request::Transfer { index: object_index(slot).0, data: &poll_object().to_bytes() })?;
    let mut req = Req::op(rt).when(Schedule::Now);
    req.checked = false;
    let written = ctx.send(req).await.and_then(|r| r.ack(Command::Transfer));
    ctx.core().stats.deliberate_lapses += 1;
    let reopened = opening_with(&ctx, PreparedRequest::poll_object(slot)).await;
    let (rc_sent, reply) = match reopened {
        Ok(r) => r,
        Err(e) => {
            return Err(ctx.core().ended(format!(
                "the unit's watchdog lapsed (as intended, to define CyclicObj {slot} on a slow link) and RO was \
                 not acknowledged: {e}"
            )))
        }
    };
    let sample = reply.and_then(|r| r.data(Command::Cyclic)).and_then(|data| snapshot_of(&data, ctx.now()));
    let why = match (&written, sample) {
        (Ok(_), Ok(sample)) => {
            let mut core = ctx.core();
            core.opened(rc_sent);
            core.cyclic_objects(true);
            core.poll.configured = true;
            return Ok(Some(sample));
        }
        (Err(e), _) => format!("the unit refused the definition of CyclicObj {slot} ({e})"),
        (Ok(_), Err(e)) => format!("the unit did not answer an RC carrying CyclicObj {slot} with its data ({e})"),
    };
    // The RC that carried the object may not have opened remote mode: a plain one does.
    let rc_sent = ctx.now();
    if let Err(e) = ctx.send(Req::internal(PreparedRequest::keepalive())).await.and_then(|r| r.ack(Command::Cyclic)) {
        return Err(ctx.core().ended(format!("remote mode was not opened again after the lapse: {e}")));
    }
    let mut core = ctx.core();
    core.opened(rc_sent);
    if written.is_ok() {
        core.cyclic_objects(false);
    }
    core.poll.refuse(&why);
    Ok(None)
}
