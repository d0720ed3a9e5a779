//! Firmware variants of the emulated modules: each models one behaviour the manual leaves open the other
//! plausible way, so that the client is tried against modules that do not behave as our default emulator
//! does (`motionlink sim powercube --variant NAME`, `variants = [...]` in the emulator's TOML).
//!
//! | variant | what the modules do differently |
//! |---|---|
//! | `no-twin-mirror` | TargetPosInc, TargetVelInc and TargetAccInc are values of their own: writing TargetPos / TargetVel / TargetAcc (or a float motion command's target) leaves them as they were, and writing them changes no float target. Motions use the float targets. |
//! | `no-broadcast-pair` | On RS232, a frame to address 0 with two data bytes (libm5api's broadcast form, the command followed by 0x00) is ignored; the one-byte form is still taken. |
//! | `ack-length-6` | On RS232, a 3-byte acknowledge carries TELID length 6, as the manual's examples print it. |
//! | `ext-ack-on-put-id` | On CAN, the extended acknowledge of a motion command comes on the command identifier `0x0E0 + address`, as the manual's last CAN table shows, instead of `0x0A0 + address`. |
//! | `no-pos-state-dio` | GetExtended of ActFPosStateDio (0x62, a later firmware's parameter) gets no acknowledge, as any parameter a module does not know. |
//! | `life-sign-unacknowledged` | The individual life sign (0x07) switches the watchdog as usual but is not acknowledged. |
//! | `no-config-word` | The Config word (parameter 57, from module version 3.5.00) is not known: GetExtended and SetExtended of it get no acknowledge, as any parameter a module does not know (DefConfig, the ROM default, is still answered). |
//! | `reset-clears-watchdog` | A Reset (addressed or broadcast) also switches an online watchdog offline, so that an unrefreshed watchdog does not expire again after it. |
//! | `no-extended-ack` | Motion commands with an extended-acknowledge MotionID (FRAMP_ACK ... ICUR_ACK, from PowerCube-OS 2.5.16 / 3.5.13) run as their plain mode does and get the simple acknowledge `[0x0b][motionID][0x64]`. |
//! | `late-motion-start` | A motion command (or Home) to a module at rest starts the motion [`LATE_START_S`] (0.3 s) after its acknowledge; until then the state is as before it (STATE_RAMP_END and STATE_HOME_OK of an earlier motion included), as a module releasing its brake first might show. |

use motionlink_link::emulator::FirmwareVariant;

/// How long after its acknowledge a motion from rest starts on a module of the `late-motion-start` variant
/// ([`Variant::LateMotionStart`]), in seconds.
pub const LATE_START_S: f64 = 0.3;
pub use motionlink_link::emulator::UnknownVariant;

/// One firmware variant of the emulated modules (see the module documentation of `sim::variant`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Deserialize)]
#[serde(try_from = "String")]
pub enum Variant {
    /// The Inc twins are kept apart from TargetPos / TargetVel / TargetAcc.
    NoTwinMirror,
    /// RS232 broadcasts in libm5api's two-byte form at address 0 are ignored.
    NoBroadcastPair,
    /// RS232 acknowledges of 3 bytes declare length 6.
    AckLength6,
    /// CAN extended motion acknowledges come on `0x0E0 + address`.
    ExtAckOnPutId,
    /// ActFPosStateDio (0x62) is not known: no acknowledge.
    NoPosStateDio,
    /// The individual life sign is not acknowledged.
    LifeSignUnacknowledged,
    /// The Config word (parameter 57) is not known: no acknowledge.
    NoConfigWord,
    /// A Reset also switches an online watchdog offline.
    ResetClearsWatchdog,
    /// Motion commands get only the simple acknowledge.
    NoExtendedAck,
    /// A motion from rest starts 0.3 s after its acknowledge, the state unchanged until then.
    LateMotionStart,
}

impl FirmwareVariant for Variant {
    const FAMILY: &'static str = "PowerCube";
    /// Every variant, in the order of the table above.
    const ALL: &'static [Variant] = &[
        Variant::NoTwinMirror,
        Variant::NoBroadcastPair,
        Variant::AckLength6,
        Variant::ExtAckOnPutId,
        Variant::NoPosStateDio,
        Variant::LifeSignUnacknowledged,
        Variant::NoConfigWord,
        Variant::ResetClearsWatchdog,
        Variant::NoExtendedAck,
        Variant::LateMotionStart,
    ];

    /// The name the command line, the TOML configuration and Python take.
    fn name(self) -> &'static str {
        match self {
            Variant::NoTwinMirror => "no-twin-mirror",
            Variant::NoBroadcastPair => "no-broadcast-pair",
            Variant::AckLength6 => "ack-length-6",
            Variant::ExtAckOnPutId => "ext-ack-on-put-id",
            Variant::NoPosStateDio => "no-pos-state-dio",
            Variant::LifeSignUnacknowledged => "life-sign-unacknowledged",
            Variant::NoConfigWord => "no-config-word",
            Variant::ResetClearsWatchdog => "reset-clears-watchdog",
            Variant::NoExtendedAck => "no-extended-ack",
            Variant::LateMotionStart => "late-motion-start",
        }
    }

    /// What the modules do differently, in one sentence.
    fn description(self) -> &'static str {
        match self {
            Variant::NoTwinMirror => {
                "TargetPosInc, TargetVelInc and TargetAccInc are values of their own, apart from TargetPos, \
                 TargetVel and TargetAcc"
            }
            Variant::NoBroadcastPair => {
                "RS232 frames to address 0 with two data bytes (libm5api's broadcasts) are ignored"
            }
            Variant::AckLength6 => {
                "RS232 acknowledges of 3 data bytes declare TELID length 6, as the manual prints them"
            }
            Variant::ExtAckOnPutId => "CAN extended motion acknowledges come on 0x0E0 + address",
            Variant::NoPosStateDio => "ActFPosStateDio (0x62) is not known: it gets no acknowledge",
            Variant::LifeSignUnacknowledged => "the individual life sign (0x07) is not acknowledged",
            Variant::NoConfigWord => {
                "the Config word (parameter 57, from module version 3.5.00) is not known: it gets no acknowledge"
            }
            Variant::ResetClearsWatchdog => "a Reset also switches an online watchdog offline",
            Variant::NoExtendedAck => {
                "motion commands get the simple acknowledge, also with an extended-acknowledge MotionID (before \
                 PowerCube-OS 2.5.16 / 3.5.13)"
            }
            Variant::LateMotionStart => {
                "a motion from rest starts 0.3 s after its acknowledge; until then the state is as before it \
                 (RAMP_END, HOME_OK)"
            }
        }
    }
}

motionlink_link::firmware_variant_traits!(Variant);

/// The variants one module runs, as flags (what the emulator's code asks).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Firmware {
    pub no_twin_mirror: bool,
    pub life_sign_unacknowledged: bool,
    pub no_pos_state_dio: bool,
    pub no_config_word: bool,
    pub reset_clears_watchdog: bool,
    pub no_extended_ack: bool,
    pub late_motion_start: bool,
}

impl Firmware {
    pub fn of(variants: &[Variant]) -> Firmware {
        Firmware {
            no_twin_mirror: variants.contains(&Variant::NoTwinMirror),
            life_sign_unacknowledged: variants.contains(&Variant::LifeSignUnacknowledged),
            no_pos_state_dio: variants.contains(&Variant::NoPosStateDio),
            no_config_word: variants.contains(&Variant::NoConfigWord),
            reset_clears_watchdog: variants.contains(&Variant::ResetClearsWatchdog),
            no_extended_ack: variants.contains(&Variant::NoExtendedAck),
            late_motion_start: variants.contains(&Variant::LateMotionStart),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_and_unknown_ones_are_refused_with_the_list() {
        for &v in Variant::ALL {
            assert_eq!(v.name().parse::<Variant>(), Ok(v));
            assert!(v.description().len() > 10 && v.to_string() == v.name(), "{v}");
        }
        assert_eq!(
            Variant::list(" ack-length-6, no-twin-mirror,,ack-length-6").unwrap(),
            vec![Variant::NoTwinMirror, Variant::AckLength6]
        );
        let e = "no-such".parse::<Variant>().unwrap_err().to_string();
        assert!(
            e.contains("\"no-such\"") && e.contains("no-twin-mirror") && e.contains("life-sign-unacknowledged"),
            "{e}"
        );
        assert!(Variant::list("no-twin-mirror,bad").is_err());
    }
}
