//! The session's cyclic object, which lets every keepalive RC of a motion or a watch read the state: defined
//! once per session (RT of CyclicObj `slot`, read back) and probed with one RC carrying it, before anything
//! depends on it. A unit that refuses any of it is watched with reads, said once per session.

use super::basic::Write;
use super::{Cx, Next, Resume, Step};
use crate::error::Error;
use crate::model::{CyclicObject, DataIndex};
use crate::session::engine::snapshot_of;
use crate::session::request::{PreparedRequest, Req};
use crate::session::POLL_READ;
use crate::wire::Command;

enum Phase {
    /// The definition is written and read back.
    Write(Write),
    /// One RC carries the object: does the unit answer it with the state?
    Probe,
}

/// Defines the session's cyclic object and probes it. Its end: `cx.core.poll` says whether the object is
/// configured (motions are then watched through the keepalive) or refused (with reads); `Err` only for what
/// is no refusal (a link that failed).
pub(crate) struct DefineObject {
    slot: u8,
    phase: Phase,
}

impl DefineObject {
    /// What to do before a motion or a sample is watched: nothing (`None`) when the session does not use its
    /// object, the object is configured, or the unit did not take it; else the definition, started.
    pub fn start(cx: &mut Cx<'_>) -> Option<(DefineObject, Next)> {
        let slot = cx.core.poll_slot()?;
        if cx.core.poll.configured {
            return None;
        }
        if cx.core.probed.caps.cyclic_objects == Some(false) {
            // Known (from a device profile) not to take the object: watched with reads, without asking again.
            cx.core.poll.refused = true;
            return None;
        }
        if POLL_READ.iter().any(|i| cx.core.group_refused(*i)) {
            // The object reads grouping indices, which the unit refuses (said once, with what follows).
            cx.core.poll.refused = true;
            return None;
        }
        let object = CyclicObject::new(&[], &POLL_READ).expect("four read indices fit");
        let mut write = Write::new(DataIndex(0x3000 + u16::from(slot)), object.to_bytes().to_vec(), true);
        match write.step(cx, Resume::Start) {
            Step::Wait(next) => Some((DefineObject { slot, phase: Phase::Write(write) }, next)),
            Step::Done(_) => None,
        }
    }

    /// Goes on after `resume`.
    pub fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Step<Result<(), Error>> {
        let slot = self.slot;
        match &mut self.phase {
            Phase::Write(write) => match write.step(cx, resume) {
                Step::Wait(next) => Step::Wait(next),
                Step::Done(Ok(None)) if cx.core.probed.caps.cyclic_objects == Some(true) => {
                    cx.core.poll.configured = true;
                    Step::Done(Ok(()))
                }
                Step::Done(Ok(None)) => {
                    self.phase = Phase::Probe;
                    Step::Wait(Next::Send(Req::op(PreparedRequest::poll_object(slot))))
                }
                Step::Done(Ok(Some(_))) => {
                    cx.core.poll.refuse(&format!("the unit does not read the definition of CyclicObj {slot} back"));
                    Step::Done(Ok(()))
                }
                Step::Done(Err(Error::Refused { status, .. })) => {
                    cx.core.poll.refuse(&format!("the unit refused the definition of CyclicObj {slot} ({status})"));
                    Step::Done(Ok(()))
                }
                Step::Done(Err(e)) => Step::Done(Err(e)),
            },
            Phase::Probe => match resume {
                Resume::Reply(r) => match r.and_then(|r| r.data(Command::Cyclic)) {
                    Ok(data) => match snapshot_of(&data, cx.now()) {
                        Ok(_) => {
                            cx.core.cyclic_objects(true);
                            cx.core.poll.configured = true;
                            Step::Done(Ok(()))
                        }
                        Err(e) => Step::Done(Err(e)),
                    },
                    Err(Error::Refused { status, .. }) => {
                        cx.core.cyclic_objects(false);
                        cx.core.poll.refuse(&format!("the unit refused an RC carrying CyclicObj {slot} ({status})"));
                        Step::Done(Ok(()))
                    }
                    Err(e) => Step::Done(Err(e)),
                },
                Resume::Start | Resume::Wake | Resume::Snapshot(_) | Resume::Reopened(_) => {
                    Step::Done(Err(Error::CancelledBeforeSending(Command::Cyclic)))
                }
            },
        }
    }
}
