//! Firmware variants of the emulated unit: for each behaviour the client relies on beyond the manual's words,
//! the plausible other behaviour of a real unit (`motionlink sim scu --variant NAME`, `variants = [...]` in
//! the TOML configuration). The README's "What motionlink assumes beyond the manuals" lists them with the
//! probe that tells them apart.

use std::time::Duration;

use motionlink_link::emulator::FirmwareVariant;
pub use motionlink_link::emulator::UnknownVariant;

use crate::model::{item, DataIndex, Item};

/// One way a real unit may differ from the emulator's default reading of the manual.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Deserialize)]
#[serde(try_from = "String")]
pub enum Variant {
    /// RG of a grouping index (0x0010, 0x0170, 0x00A0, 0x00D0 ... and the collections) is refused with PDE, as
    /// is a cyclic object or an RT naming one: only individual indices answer.
    NoGroups,
    /// RG of UserPositionData (0x2001..0x2006, and the collection 0x2000) is refused with PDE, as is a cyclic
    /// object naming it.
    NoUserPositions,
    /// RC with a cyclic object index (0..4) is refused with PDE (it still feeds the watchdog); the
    /// definitions 0x3001..0x3005 can be written and read like any remote data.
    NoCyclicObjects,
    /// RG of remote data (0x3xxx) is refused with PDE: what RT writes cannot be read back.
    NoRemoteReadBack,
    /// RC without a cyclic object is answered with ACK, ctp 0 and no data (the command table's reply form)
    /// instead of the status alone (the example's).
    RcEmptyData,
    /// The first telegram after 2 s without a byte (and after power-on) only wakes the unit: it is not
    /// answered (why public drivers send RO twice).
    Sleepy,
    /// The error bits "reset on next motion" (14..21) stay in Error_Code 1 when the next motion starts.
    StickyErrors,
    /// Every actuator reads 3 counts below its In end after reaching it (real columns after homing).
    InEndUndershoot,
    /// RE of a motion function that was started and not yet ended with RS is refused with PE (a new RE needs
    /// an RS first, as the public drivers' habit of sending RS before every RE suggests).
    ReNeedsRs,
    /// After an RE, actuators at rest start 0.4 s after the ACK, and their motion bit rises only
    /// then (a unit whose relays or soft start take that long; the manual does not say when the bit rises).
    LateMotionBit,
    /// The entries this crate takes to show F18, F21/F22 and F20 (binary_outputs bit 1, led_hand_switch,
    /// lock_status) do not follow those functions: they stay as they are (a unit that shows them elsewhere,
    /// or not at all). The functions still switch (the emergency stop still stops every motion).
    SwitchStatusUnshown,
    /// While an error stands after which motions are not performed (error bits 8, 13, 24..32), an RE of a
    /// motion function is acknowledged and nothing moves (the function counts as started, to be ended with
    /// RS), instead of being refused with PE.
    AckWithoutMotion,
    /// After a watchdog expiry with Safety_ID 1 or 2, RG, RT, RE and RS are refused with PE until the next
    /// RC, which re-arms the watchdog and restores remote mode without RO (instead of remote mode being
    /// deactivated, RO needed, as chapter 5 says).
    RcRearmsWatchdog,
    /// A battery unit with `<Low Power> = Enabled` (E 3, S 3, from FW V2B1): in low-power mode from power-on,
    /// after a watchdog lapse in remote mode, and 2 s after its last byte outside remote mode, it takes no
    /// telegram until its RxD is held at space for at least 100 ms (a break: `--wake`).
    LowPower,
}

impl FirmwareVariant for Variant {
    const FAMILY: &'static str = "SCU";
    /// Every variant, in the order `--help` lists them.
    const ALL: &'static [Variant] = &[
        Variant::NoGroups,
        Variant::NoUserPositions,
        Variant::NoCyclicObjects,
        Variant::NoRemoteReadBack,
        Variant::RcEmptyData,
        Variant::Sleepy,
        Variant::StickyErrors,
        Variant::InEndUndershoot,
        Variant::ReNeedsRs,
        Variant::LateMotionBit,
        Variant::SwitchStatusUnshown,
        Variant::AckWithoutMotion,
        Variant::RcRearmsWatchdog,
        Variant::LowPower,
    ];

    /// Its name, as `--variant` takes it.
    fn name(self) -> &'static str {
        match self {
            Variant::NoGroups => "no-groups",
            Variant::NoUserPositions => "no-user-positions",
            Variant::NoCyclicObjects => "no-cyclic-objects",
            Variant::NoRemoteReadBack => "no-remote-readback",
            Variant::RcEmptyData => "rc-empty-data",
            Variant::Sleepy => "sleepy",
            Variant::StickyErrors => "sticky-errors",
            Variant::InEndUndershoot => "in-end-undershoot",
            Variant::ReNeedsRs => "re-needs-rs",
            Variant::LateMotionBit => "late-motion-bit",
            Variant::SwitchStatusUnshown => "switch-status-unshown",
            Variant::AckWithoutMotion => "ack-without-motion",
            Variant::RcRearmsWatchdog => "rc-rearms-watchdog",
            Variant::LowPower => "low-power",
        }
    }

    /// What the unit does differently, in one sentence.
    fn description(self) -> &'static str {
        match self {
            Variant::NoGroups => "RG of a grouping index (and a cyclic object or an RT naming one) is refused with PDE",
            Variant::NoUserPositions => "RG of UserPositionData (0x2000..0x2006) is refused with PDE",
            Variant::NoCyclicObjects => {
                "RC with a cyclic object index is refused with PDE (it still feeds the watchdog)"
            }
            Variant::NoRemoteReadBack => {
                "RG of remote data (0x3xxx) is refused with PDE: what RT writes cannot be read back"
            }
            Variant::RcEmptyData => "RC without a cyclic object is answered with ACK, ctp 0 and no data",
            Variant::Sleepy => "the first telegram after 2 s of silence only wakes the unit and is not answered",
            Variant::StickyErrors => "the error bits reset on the next motion (14..21) stay set when it starts",
            Variant::InEndUndershoot => "every actuator reads 3 counts below its In end after reaching it",
            Variant::ReNeedsRs => "RE of a motion function started and not yet ended with RS is refused with PE",
            Variant::LateMotionBit => {
                "after an RE, actuators at rest start, and their motion bit rises, 0.4 s after the ACK"
            }
            Variant::SwitchStatusUnshown => {
                "binary_outputs bit 1, led_hand_switch and lock_status do not follow F18, F21/F22 and F20 (the \
                 functions still switch)"
            }
            Variant::AckWithoutMotion => {
                "while an error bit whose reaction is \"motions not performed\" stands (8, 13, 24..32), an RE of a \
                 motion function is acknowledged and nothing moves (instead of PE)"
            }
            Variant::RcRearmsWatchdog => {
                "after a watchdog expiry with Safety_ID 1 or 2, commands are refused (PE) until the next RC, which \
                 restores remote mode without RO"
            }
            Variant::LowPower => {
                "a battery unit in low-power mode (from power-on, after a watchdog lapse, 2 s idle outside remote \
                 mode): no telegram is answered until a break of at least 100 ms (--wake)"
            }
        }
    }
}

motionlink_link::firmware_variant_traits!(Variant);

/// How long the line must be silent before a [`Variant::Sleepy`] unit dozes off.
pub const SLEEP_AFTER: Duration = Duration::from_secs(2);

/// How long after an RE's ACK the actuators of a [`Variant::LateMotionBit`] unit start from rest.
pub const LATE_START: Duration = Duration::from_millis(400);

/// True if `index` is a grouping index (a group of the data list, or one of the collections).
pub(super) fn is_group(index: DataIndex) -> bool {
    matches!(item(index), Some(Item::Group(_)))
}

/// True if `index` reads UserPositionData (an entry 0x2001..0x2006 or the collection 0x2000).
pub(super) fn is_user_positions(index: DataIndex) -> bool {
    (0x2000..=0x2006).contains(&index.0)
}

/// True if a unit of `variants` refuses an RG of `index` (with PDE).
pub(super) fn refuses_get(variants: &[Variant], index: DataIndex) -> bool {
    (variants.contains(&Variant::NoGroups) && is_group(index))
        || (variants.contains(&Variant::NoUserPositions) && is_user_positions(index))
        || (variants.contains(&Variant::NoRemoteReadBack) && index.is_remote())
}

/// True if a unit of `variants` refuses a cyclic object definition that names `index`.
pub(super) fn refuses_in_object(variants: &[Variant], index: DataIndex) -> bool {
    (variants.contains(&Variant::NoGroups) && is_group(index))
        || (variants.contains(&Variant::NoUserPositions) && is_user_positions(index))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_one_by_one_or_comma_separated_and_unknown_ones_list_the_known_ones() {
        for &v in Variant::ALL {
            assert_eq!(v.name().parse::<Variant>(), Ok(v));
            assert!(v.description().len() > 10 && v.to_string() == v.name(), "{v}");
        }
        let both = Variant::list("sleepy, no-groups,sleepy").unwrap();
        assert_eq!(both, [Variant::NoGroups, Variant::Sleepy], "each once, in the order of ALL");
        let e = Variant::list("no-groups,no-group").unwrap_err();
        assert!(e.to_string().contains("\"no-group\"") && e.to_string().contains("no-cyclic-objects"), "{e}");
        assert!(Variant::list("").unwrap().is_empty());
        // In the configuration file.
        let c = crate::sim::SimConfig::from_toml("variants = [\"sleepy\", \"no-groups\"]").unwrap();
        assert_eq!(c.variants, [Variant::NoGroups, Variant::Sleepy]);
        let e = crate::sim::SimConfig::from_toml("variants = [\"sleep\"]").unwrap_err();
        assert!(e.to_string().contains("\"sleep\"") && e.to_string().contains("re-needs-rs"), "{e}");
    }
}
