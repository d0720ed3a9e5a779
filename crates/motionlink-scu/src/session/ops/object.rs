//! The session's cyclic object, which lets every keepalive RC of a motion or a watch read the state: defined
//! once per session (RT of CyclicObj `slot`, read back) and probed with one RC carrying it, before anything
//! depends on it. A unit that refuses any of it is watched with reads, said once per session.

use super::basic::write;
use crate::error::Error;
use crate::model::{CyclicObject, DataIndex};
use crate::session::ctx::Ctx;
use crate::session::dispatch::snapshot_of;
use crate::session::request::{PreparedRequest, Req};
use crate::session::POLL_READ;
use crate::wire::Command;

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
            core.probed.caps.cyclic_objects == Some(false),
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
    let object = CyclicObject::new(&[], &POLL_READ).expect("four read indices fit");
    match write(ctx, DataIndex(0x3000 + u16::from(slot)), &object.to_bytes(), true).await {
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
