//! What the session found the unit in use to do where the manual leaves it open: each behaviour is probed the
//! first time a check depends on it (by a read, or an RC that only reads), remembered for the session, and
//! warned about once when the unit does not behave so (the operation then runs in the manual's plain form and
//! says what it could not verify). The crate documentation lists them ("What the client relies on beyond the
//! manual").

use super::Core;
use crate::model::DataIndex;

/// What the session found the unit in use to do beyond the manual's words. Each is `None` until the
/// session needed it and probed it, `Some(true)` when the unit did it, `Some(false)` when it refused (PDE).
///
/// A device profile (`motionlink probe --save`, [`crate::probe`]) keeps them, and
/// [`Session::seed_capabilities`](super::Session::seed_capabilities) gives them to a later session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Capabilities {
    /// RG of grouping indices (0x0010 every position, 0x0170 every status 1, ...): `Some(false)` once one
    /// was refused; its entries are then read one by one.
    pub grouping_indices: Option<bool>,
    /// RG of UserPositionData (0x2001..0x2006), whose virtual limits bound the targets of moves.
    pub user_position_data: Option<bool>,
    /// RC with the session's cyclic object (defined in CyclicObj 1..5 and read back), which watches motions
    /// through the keepalive.
    pub cyclic_objects: Option<bool>,
    /// RG of remote data (0x3xxx): what RT wrote is read back.
    pub remote_read_back: Option<bool>,
}

impl Capabilities {
    /// These, with every finding `self` has not settled taken from `known` (what was settled stays).
    pub fn or(self, known: Capabilities) -> Capabilities {
        Capabilities {
            grouping_indices: self.grouping_indices.or(known.grouping_indices),
            user_position_data: self.user_position_data.or(known.user_position_data),
            cyclic_objects: self.cyclic_objects.or(known.cyclic_objects),
            remote_read_back: self.remote_read_back.or(known.remote_read_back),
        }
    }
}

/// The session's memory of what the unit answered (`caps`), and what a device profile said of it
/// (`seeded`). A behaviour the profile says the unit lacks is not asked for (the plain form is used); one it
/// says the unit has is still probed where that costs no more than the check itself (the first RG of
/// remote data or UserPositionData, the RC of the cyclic object): a unit that refuses it is taken as the
/// probe found it, with a warning naming the profile, never failed on the profile's word.
#[derive(Debug, Default)]
pub(crate) struct Probed {
    pub caps: Capabilities,
    pub seeded: Capabilities,
}

impl Probed {
    /// What is known: the session's findings, then the profile's where the session has none.
    pub fn known(&self) -> Capabilities {
        self.caps.or(self.seeded)
    }

    /// ", though the device profile said it does" where the profile said `said` of a behaviour the unit
    /// refused; else nothing.
    fn contradicted(said: Option<bool>) -> &'static str {
        if said == Some(true) {
            " (the device profile said it does: the unit in use differs from the one probed)"
        } else {
            ""
        }
    }
}

impl Core {
    /// True if the unit refused a grouping index in this session: every group is then read entry by entry
    /// (a firmware that does not know one grouping index is taken not to know the others).
    pub fn group_refused(&self, _index: DataIndex) -> bool {
        self.probed.known().grouping_indices == Some(false)
    }

    /// The unit answered RG of a grouping index.
    pub fn group_answered(&mut self) {
        self.probed.caps.grouping_indices.get_or_insert(true);
    }

    /// The unit refused RG of grouping index `index` with PDE: from now on its entries are read one by one.
    pub fn refuse_group(&mut self, index: DataIndex) {
        if self.probed.caps.grouping_indices != Some(false) {
            tracing::warn!(
                "the unit refused the grouping index {index} (PDE){}: this session reads the entries of every group \
                 one by one instead (the manual's plain form), and watches motions with such reads",
                Probed::contradicted(self.probed.seeded.grouping_indices)
            );
        }
        self.probed.caps.grouping_indices = Some(false);
    }

    /// Records whether the unit answered RG of UserPositionData; warns the first time it refused.
    pub fn user_positions_answered(&mut self, answered: bool) {
        if !answered && self.probed.caps.user_position_data != Some(false) {
            tracing::warn!(
                "the unit refused UserPositionData (PDE){}: move targets are checked against the configured stroke \
                 limits only (--stroke); where none are configured, the move says that its target was not checked",
                Probed::contradicted(self.probed.seeded.user_position_data)
            );
        }
        self.probed.caps.user_position_data = Some(answered);
    }

    /// Records whether the unit read remote data back; warns the first time it refused.
    pub fn remote_read_back(&mut self, answered: bool) {
        if !answered && self.probed.caps.remote_read_back != Some(false) {
            tracing::warn!(
                "the unit refused to read remote data back (RG of 0x3xxx: PDE){}: this session's writes are checked \
                 by the unit's ACK only, and its results say so",
                Probed::contradicted(self.probed.seeded.remote_read_back)
            );
        }
        self.probed.caps.remote_read_back = Some(answered);
    }

    /// Records whether the unit took the session's cyclic object (the caller warns, once: see
    /// [`crate::session::PollObject`]).
    pub fn cyclic_objects(&mut self, answered: bool) {
        if !answered && self.probed.seeded.cyclic_objects == Some(true) {
            tracing::warn!(
                "the unit refused the session's cyclic object{}",
                Probed::contradicted(self.probed.seeded.cyclic_objects)
            );
        }
        self.probed.caps.cyclic_objects = Some(answered);
    }
}
