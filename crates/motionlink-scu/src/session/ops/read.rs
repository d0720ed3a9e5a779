//! Reading a data-list item the way the unit in use answers: a group by its grouping index, or, where the
//! unit refuses grouping indices (PDE), entry by entry (the manual: "Values can be queried individually or
//! blockwise").

use super::{get, Cx, Next, Operation, Output, Resume, Step};
use crate::error::Error;
use crate::model::{item, Actuator, DataEntry, DataEntryExt, DataIndex, Item};
use crate::wire::{Command, Status};

/// Reads an entry with one RG; a group with one RG of its grouping index, or, once the unit refused that
/// index in this session, the members that are needed one by one (zeros stand for the others). A single
/// needed member is read alone in any case.
pub(crate) struct ItemRead {
    index: DataIndex,
    /// The members needed (bit i: the i-th member of the group).
    need: u64,
    members: Vec<&'static DataEntry>,
    data: Vec<u8>,
    /// The member whose RG is under way, if not the whole item.
    at: Option<usize>,
}

impl ItemRead {
    /// The whole item.
    pub fn all(index: DataIndex) -> Self {
        Self::of(index, u64::MAX)
    }

    /// The members of group `index` in `need` (bit i: the i-th member).
    pub fn of(index: DataIndex, need: u64) -> Self {
        ItemRead { index, need, members: Vec::new(), data: Vec::new(), at: None }
    }

    /// The members of a group of one entry per actuator (0x0010 positions, 0x0170 status 1, 0x00A0 currents)
    /// that belong to `actuators`.
    pub fn actuators(index: DataIndex, actuators: impl IntoIterator<Item = Actuator>) -> Self {
        Self::of(index, actuators.into_iter().fold(0, |m, a| m | 1 << (a.number() - 1)))
    }

    fn offset(&self, k: usize) -> usize {
        self.members[..k].iter().map(|e| e.size()).sum()
    }

    /// The next needed member from `k` on, or the end.
    fn member_from(&mut self, k: usize) -> Step<Result<Vec<u8>, Error>> {
        let next = (k..self.members.len()).find(|&i| i < 64 && self.need & (1 << i) != 0);
        match next {
            Some(i) => {
                self.at = Some(i);
                Step::Wait(get(DataEntryExt::index(self.members[i])))
            }
            None => Step::Done(Ok(std::mem::take(&mut self.data))),
        }
    }

    /// Goes on after `resume`; its end is the item's bytes as the RG of the whole item gives them.
    pub fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Step<Result<Vec<u8>, Error>> {
        match resume {
            Resume::Start => {
                let Some(it) = item(self.index) else {
                    return Step::Done(Err(Error::invalid(format!("{} is not in the data list", self.index))));
                };
                let Item::Group(g) = it else { return Step::Wait(get(self.index)) };
                self.members = g.members().collect();
                self.data = vec![0; it.size()];
                let needed = (0..self.members.len()).filter(|&i| i < 64 && self.need & (1 << i) != 0).count();
                if needed == 1 || cx.core.group_refused(self.index) {
                    self.member_from(0)
                } else {
                    Step::Wait(get(self.index))
                }
            }
            Resume::Reply(result) => {
                let Some(k) = self.at else {
                    let group = matches!(item(self.index), Some(Item::Group(_)));
                    return match result.and_then(|r| r.data(Command::Get)) {
                        Ok(data) => {
                            if group {
                                cx.core.group_answered();
                            }
                            Step::Done(Ok(data))
                        }
                        Err(Error::Refused { status: Status::ParameterDataError, .. }) if group => {
                            cx.core.refuse_group(self.index);
                            self.member_from(0)
                        }
                        Err(e) => Step::Done(Err(e)),
                    };
                };
                match result.and_then(|r| r.data(Command::Get)) {
                    Ok(bytes) => {
                        let at = self.offset(k);
                        let size = self.members[k].size();
                        if bytes.len() != size {
                            return Step::Done(Err(Error::UnexpectedReply {
                                command: Command::Get,
                                detail: format!(
                                    "{} is {size} byte(s), the unit sent {}",
                                    self.members[k].name,
                                    bytes.len()
                                ),
                            }));
                        }
                        self.data[at..at + size].copy_from_slice(&bytes);
                        self.member_from(k + 1)
                    }
                    Err(e) => Step::Done(Err(e)),
                }
            }
            Resume::Wake | Resume::Snapshot(_) | Resume::Reopened(_) => {
                Step::Done(Err(Error::CancelledBeforeSending(Command::Get)))
            }
        }
    }
}

/// A read of the caller's ([`super::Op::Read`]).
pub(crate) struct ReadOp(pub ItemRead);

impl Operation for ReadOp {
    fn step(&mut self, cx: &mut Cx<'_>, resume: Resume) -> Next {
        match self.0.step(cx, resume) {
            Step::Wait(next) => next,
            Step::Done(r) => Next::Done(r.map(|d| Output::Data(Some(d)))),
        }
    }
}
