//! Reading a data-list item the way the unit in use answers: a group by its grouping index, or, where the
//! unit refuses grouping indices (PDE), entry by entry (the manual: "Values can be queried individually or
//! blockwise").

use crate::error::Error;
use crate::model::{item, Actuator, DataEntryExt, DataIndex, Item};
use crate::session::ctx::Ctx;
use crate::wire::{Command, Status};

/// What to read: an entry, or members of a group.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ItemRead {
    index: DataIndex,
    /// The members needed (bit i: the i-th member of the group).
    need: u64,
}

impl ItemRead {
    /// The whole item.
    pub fn all(index: DataIndex) -> Self {
        Self::of(index, u64::MAX)
    }

    /// The members of group `index` in `need` (bit i: the i-th member).
    pub fn of(index: DataIndex, need: u64) -> Self {
        ItemRead { index, need }
    }

    /// The members of a group of one entry per actuator (0x0010 positions, 0x0170 status 1, 0x00A0 currents)
    /// that belong to `actuators`.
    pub fn actuators(index: DataIndex, actuators: impl IntoIterator<Item = Actuator>) -> Self {
        Self::of(index, actuators.into_iter().fold(0, |m, a| m | 1 << (a.number() - 1)))
    }

    fn needs(&self, member: usize) -> bool {
        member < 64 && self.need & (1 << member) != 0
    }
}

/// Reads an entry with one RG; a group with one RG of its grouping index, or, once the unit refused that
/// index in this session, the members that are needed one by one (zeros stand for the others). A single
/// needed member is read alone in any case. The end: the item's bytes as the RG of the whole item gives
/// them.
pub(crate) async fn read_item(ctx: &Ctx, read: ItemRead) -> Result<Vec<u8>, Error> {
    let index = read.index;
    let Some(it) = item(index) else {
        return Err(Error::invalid(format!("{index} is not in the data list")));
    };
    let Item::Group(g) = it else { return ctx.get(index).await.and_then(|r| r.data(Command::Get)) };
    let members: Vec<_> = g.members().collect();
    let needed = (0..members.len()).filter(|&i| read.needs(i)).count();
    let refused = ctx.core().group_refused(index);
    if needed != 1 && !refused {
        match ctx.get(index).await.and_then(|r| r.data(Command::Get)) {
            Ok(data) => {
                ctx.core().group_answered();
                return Ok(data);
            }
            Err(Error::Refused { status: Status::ParameterDataError, .. }) => ctx.core().refuse_group(index),
            Err(e) => return Err(e),
        }
    }
    let mut data = vec![0; it.size()];
    let mut at = 0;
    for (k, member) in members.iter().enumerate() {
        let size = member.size();
        if read.needs(k) {
            let bytes = ctx.get(DataEntryExt::index(*member)).await.and_then(|r| r.data(Command::Get))?;
            if bytes.len() != size {
                return Err(Error::UnexpectedReply {
                    command: Command::Get,
                    detail: format!("{} is {size} byte(s), the unit sent {}", member.name, bytes.len()),
                });
            }
            data[at..at + size].copy_from_slice(&bytes);
        }
        at += size;
    }
    Ok(data)
}
