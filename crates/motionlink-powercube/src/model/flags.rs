//! Every bit set of the manual, each generated from one table by [`flag_set!`]: the module state
//! (CubeState), the short state of motion acknowledges, the Profibus short state, the DIO byte and word, and
//! the Setup and Config words. The macro is the one every family shares (`motionlink_link::flag_set!`): each
//! word type implements [`FlagWord`](motionlink_link::flags::FlagWord) and each flag enum
//! [`Flag`](motionlink_link::flags::Flag).

use motionlink_link::flag_set;
pub use motionlink_link::flags::FlagClass;

flag_set! {
    /// The module state word (parameter CubeState, 39).
    ///
    /// ```
    /// use motionlink_powercube::model::{CubeState, StateFlag};
    /// let s = CubeState(0x0000_0807);
    /// assert!(s.contains(StateFlag::HomeOk) && s.contains(StateFlag::Motion));
    /// assert_eq!(s.to_string(), "STATE_ERROR | STATE_HOME_OK | STATE_HALTED | STATE_MOTION");
    /// ```
    CubeState(u32);
    /// One flag of the module state word.
    StateFlag {
        Error = ("STATE_ERROR", 0x0000_0001, Error,
            "An error occurred; the module stopped and accepts no motion command until a Reset."),
        HomeOk = ("STATE_HOME_OK", 0x0000_0002, Information,
            "Homing finished successfully; the limits of the operating range are valid."),
        Halted = ("STATE_HALTED", 0x0000_0004, Information,
            "Emergency stop (Halt or an error): not moving, no motion commands until a Reset."),
        PowerFault = ("STATE_POWERFAULT", 0x0000_0008, Error,
            "Servo amplifier error (with STATE_ERROR); one of bits 18..23 says why."),
        TowError = ("STATE_TOW_ERROR", 0x0000_0010, Error,
            "Following error: the servo loop could not follow the target within MaxDeltaPos."),
        CommError = ("STATE_COMM_ERROR", 0x0000_0020, Error,
            "The watchdog was not refreshed in time."),
        Swr = ("STATE_SWR", 0x0000_0040, Information, "The home switch is active."),
        Sw1 = ("STATE_SW1", 0x0000_0080, Information, "Limit switch 1 is active."),
        Sw2 = ("STATE_SW2", 0x0000_0100, Information, "Limit switch 2 is active."),
        BrakeActive = ("STATE_BRAKEACTIVE", 0x0000_0200, Information,
            "The brake is active and the servo loop open."),
        CurLimit = ("STATE_CURLIMIT", 0x0000_0400, Information,
            "Warning: the servo loop reached the maximum current."),
        Motion = ("STATE_MOTION", 0x0000_0800, Information, "The drive is moving."),
        RampAcc = ("STATE_RAMP_ACC", 0x0000_1000, Information, "Ramp motion: accelerating."),
        RampSteady = ("STATE_RAMP_STEADY", 0x0000_2000, Information, "Ramp motion: constant speed."),
        RampDec = ("STATE_RAMP_DEC", 0x0000_4000, Information, "Ramp motion: decelerating."),
        RampEnd = ("STATE_RAMP_END", 0x0000_8000, Information, "The ramp motion profile has ended."),
        InProgress = ("STATE_INPROGRESS", 0x0001_0000, Information, "Step motion: a step is in progress."),
        FullBuffer = ("STATE_FULLBUFFER", 0x0002_0000, Information,
            "Step motion: a step command waits in the buffer."),
        PowVoltErr = ("STATE_POW_VOLT_ERR", 0x0004_0000, Error, "Motor supply voltage too low or too high."),
        PowFetTemp = ("STATE_POW_FET_TEMP", 0x0008_0000, Error, "The power transistors overheated."),
        PowWdgTemp = ("STATE_POW_WDG_TEMP", 0x0010_0000, Obsolete, "The motor overheated."),
        PowShortCur = ("STATE_POW_SHORTCUR", 0x0020_0000, Obsolete, "Short circuit in the servo amplifier."),
        PowHallErr = ("STATE_POW_HALLERR", 0x0040_0000, Obsolete, "Error reading the motor's hall sensors."),
        PowIntegralErr = ("STATE_POW_INTEGRAL-ERR", 0x0080_0000, Error,
            "The drive was overloaded (bit 23; the manual's table prints 0x00080000)."),
        CpuOverload = ("STATE_CPU_OVERLOAD", 0x0100_0000, Obsolete,
            "Communication breakdown between CPU and current controller."),
        BeyondHard = ("STATE_BEYOND_HARD", 0x0200_0000, Error, "The module reached a hard limit."),
        BeyondSoft = ("STATE_BEYOND_SOFT", 0x0400_0000, Error, "The module reached a soft limit."),
        LogicVolt = ("STATE_LOGIC_VOLT", 0x0800_0000, Error,
            "Logic supply voltage too low or too high (bit 27; STATE_POW_SETUP_ERR on OS 3.5.14..3.5.1D)."),
        PowSetupErr = ("STATE_POW_SETUP_ERR", 0x0800_0000, Obsolete,
            "Error initialising the current controller (OS 3.5.14..3.5.1D; shares bit 27 with STATE_LOGIC_VOLT)."),
    }
}

impl CubeState {
    /// The flags set that are not information: the reasons a module stopped.
    pub fn faults(self) -> impl Iterator<Item = StateFlag> {
        self.iter().filter(|f| f.class() != FlagClass::Information)
    }

    /// True if an error flag (or an obsolete error flag) is set.
    pub fn has_fault(self) -> bool {
        self.faults().next().is_some()
    }

    /// The short state sent in extended motion acknowledges.
    pub fn short_state(self) -> ShortState {
        let mut s = ShortState::EMPTY;
        let not_ok =
            self.contains(StateFlag::Error) || !self.contains(StateFlag::HomeOk) || self.contains(StateFlag::Halted);
        s.set(ShortFlag::NotOk, not_ok);
        s.set(ShortFlag::Swr, self.contains(StateFlag::Swr));
        s.set(ShortFlag::Sw1, self.contains(StateFlag::Sw1));
        s.set(ShortFlag::Sw2, self.contains(StateFlag::Sw2));
        s.set(ShortFlag::Motion, self.contains(StateFlag::Motion));
        s.set(ShortFlag::RampEnd, self.contains(StateFlag::RampEnd));
        s.set(ShortFlag::InProgress, self.contains(StateFlag::InProgress));
        s.set(ShortFlag::FullBuffer, self.contains(StateFlag::FullBuffer));
        s
    }

    /// The short state word of the Profibus input image.
    pub fn profibus_state(self) -> ProfibusState {
        use ProfibusFlag as P;
        use StateFlag as S;
        let pairs = [
            (P::ErrorM4, S::Error),
            (P::ReadyToPos, S::HomeOk),
            (P::Moving, S::Motion),
            (P::Braked, S::BrakeActive),
            (P::CurrLimit, S::CurLimit),
            (P::EndMotion, S::RampEnd),
            (P::End0, S::Sw1),
            (P::End1, S::Sw2),
            (P::Sync, S::Swr),
            (P::PosTimeInProgress, S::InProgress),
            (P::PosTimeReceived, S::FullBuffer),
            (P::HaltM4, S::Halted),
        ];
        pairs.iter().fold(ProfibusState::EMPTY, |acc, (p, s)| if self.contains(*s) { acc.with(*p) } else { acc })
    }
}

flag_set! {
    /// The short module state in an extended motion acknowledge.
    ShortState(u8);
    /// One flag of the short state.
    ShortFlag {
        NotOk = ("SHORT_NOT_OK", 0x01, Error, "STATE_ERROR, or not STATE_HOME_OK, or STATE_HALTED."),
        Swr = ("SHORT_SWR", 0x02, Information, "STATE_SWR: home switch active."),
        Sw1 = ("SHORT_SW1", 0x04, Information, "STATE_SW1: limit switch 1 active."),
        Sw2 = ("SHORT_SW2", 0x08, Information, "STATE_SW2: limit switch 2 active."),
        Motion = ("SHORT_MOTION", 0x10, Information, "STATE_MOTION: moving."),
        RampEnd = ("SHORT_RAMP_END", 0x20, Information, "STATE_RAMP_END: ramp ended."),
        InProgress = ("SHORT_INPROGRESS", 0x40, Information, "STATE_INPROGRESS: a step is running."),
        FullBuffer = ("SHORT_FULLBUFFER", 0x80, Information, "STATE_FULLBUFFER: a step is buffered."),
    }
}

flag_set! {
    /// The short state word of the Profibus-DP input image (bytes 13..14).
    ProfibusState(u16);
    /// One flag of the Profibus short state.
    ProfibusFlag {
        ErrorM4 = ("STATE_ERRORM4", 0x0001, Error, "STATE_ERROR."),
        ReadyToPos = ("STATE_READYTOPOS", 0x0004, Information, "STATE_HOME_OK."),
        Moving = ("STATE_MOVING", 0x0010, Information, "STATE_MOTION."),
        Braked = ("STATE_BRAKED", 0x0020, Information, "STATE_BRAKEACTIVE."),
        CurrLimit = ("STATE_CURRLIMIT", 0x0040, Information, "STATE_CURLIMIT."),
        EndMotion = ("STATE_ENDMOTION", 0x0080, Information, "STATE_RAMP_END."),
        End0 = ("STATE_END0", 0x0100, Information, "STATE_SW1."),
        End1 = ("STATE_END1", 0x0200, Information, "STATE_SW2."),
        Sync = ("STATE_SYNC", 0x0400, Information, "STATE_SWR."),
        PosTimeInProgress = ("POSTIME_INPROGRESS_MASK", 0x1000, Information, "STATE_INPROGRESS."),
        PosTimeReceived = ("POSTIME_RECEIVED_MASK", 0x2000, Information, "STATE_FULLBUFFER."),
        HaltM4 = ("STATE_HALTM4", 0x8000, Information, "STATE_HALTED."),
    }
}

flag_set! {
    /// The digital I/O byte of an extended motion acknowledge.
    Dio(u8);
    /// One bit of the DIO byte.
    DioFlag {
        In0 = ("INBIT0", 0x01, Information, "State of input 0."),
        In1 = ("INBIT1", 0x02, Information, "State of input 1."),
        In2 = ("INBIT2", 0x04, Information, "State of input 2."),
        In3 = ("INBIT3", 0x08, Information, "State of input 3."),
        Out0 = ("OUTBIT0", 0x10, Information, "State of output 0."),
        Out1 = ("OUTBIT1", 0x20, Information, "State of output 1."),
        Out2 = ("OUTBIT2", 0x40, Information, "State of output 2."),
        Out3 = ("OUTBIT3", 0x80, Information, "State of output 3."),
    }
}

flag_set! {
    /// The digital I/O word (parameter DioSetup, 38).
    DioWord(u32);
    /// One bit of the DIO word.
    DioWordFlag {
        In0 = ("DIOID_MOD_INBIT0", 0x001, Information, "State of input 0."),
        In1 = ("DIOID_MOD_INBIT1", 0x002, Information, "State of input 1."),
        In2 = ("DIOID_MOD_INBIT2", 0x004, Information, "State of input 2."),
        In3 = ("DIOID_MOD_INBIT3", 0x008, Information, "State of input 3."),
        Out0 = ("DIOID_MOD_OUTBIT0", 0x010, Information, "State of output 0."),
        Out1 = ("DIOID_MOD_OUTBIT1", 0x020, Information, "State of output 1."),
        Out2 = ("DIOID_MOD_OUTBIT2", 0x040, Information, "State of output 2."),
        Out3 = ("DIOID_MOD_OUTBIT3", 0x080, Information, "State of output 3."),
        InSwr = ("DIOID_MOD_INSWR", 0x100, Information, "State of the home switch (1 = active)."),
        InSw1 = ("DIOID_MOD_INSW1", 0x200, Information, "State of limit switch 1 (1 = active)."),
        InSw2 = ("DIOID_MOD_INSW2", 0x400, Information, "State of limit switch 2 (1 = active)."),
    }
}

impl DioWord {
    /// The low byte as carried in motion acknowledges.
    pub fn to_dio(self) -> Dio {
        Dio((self.0 & 0xFF) as u8)
    }
}

flag_set! {
    /// The read-only Setup word (parameter 88).
    SetupWord(u32);
    /// One flag of the Setup word.
    SetupFlag {
        EncoderFeedback = ("SETUPID_MOD_ENCODER_FEEDBACK", 0x0000_0001, Information, "Not used."),
        ResolverFeedback = ("SETUPID_MOD_RESOLVER_FEEDBACK", 0x0000_0002, Information, "Not used."),
        AbsoluteFeedback = ("SETUPID_MOD_ABSOLUTE_FEEDBACK", 0x0000_0004, Information, "Not used."),
        FourInFourOut = ("SETUPID_MOD_4IN_4OUT", 0x0000_0008, Information,
            "The 15-pole connector carries 4 I/O signals."),
        ThreeInEncoderIn = ("SETUPID_MOD_3IN_ENCODER_IN", 0x0000_0010, Information,
            "The 15-pole connector is an encoder input."),
        ThreeInEncoderOut = ("SETUPID_MOD_3IN_ENCODER_OUT", 0x0000_0020, Information,
            "The 15-pole connector is an encoder output."),
        Rs232 = ("SETUPID_MOD_RS232", 0x0000_0040, Information, "RS232 communication is active."),
        Can = ("SETUPID_MOD_CAN", 0x0000_0200, Information, "CAN communication is active."),
        Profibus = ("SETUPID_MOD_PROFIBUS", 0x0000_0400, Information, "Profibus communication is active."),
        UseM3Id = ("SETUPID_MOD_USE_M3ID", 0x0000_0800, Information, "CAN identifiers for MoRSE3."),
        UseM4Id = ("SETUPID_MOD_USE_M4ID", 0x0000_1000, Information, "CAN identifiers for MoRSE4."),
        UseCanOpen = ("SETUPID_MOD_USE_CANOPEN", 0x0000_2000, Information, "The CANopen interface is active."),
        Sw2AsEnable = ("SETUPID_MOD_USE_SW2_AS_ENABLE", 0x0000_8000, Information,
            "Limit switch 2 input is an enable signal."),
        Sw2AsBrake = ("SETUPID_MOD_USE_SW2_AS_BRAKE", 0x0001_0000, Information,
            "Limit switch 2 input releases the brake."),
        ErrorToOut0 = ("SETUPID_MOD_ERROR_TO_OUT0", 0x0002_0000, Information, "Errors are signalled on output 0."),
    }
}

flag_set! {
    /// The Config word (parameter 57, read and write; DefConfig 27 its default).
    ConfigWord(u32);
    /// One flag of the Config word.
    ConfigFlag {
        BrakePresent = ("CONFIGID_MOD_BRAKE_PRESENT", 0x0000_0008, Information, "A brake is present."),
        BrakeAtPowerOn = ("CONFIGID_MOD_BRAKE_AT_POWERON", 0x0000_0010, Information,
            "0: the brake is released at power on."),
        SwrWithEncoderZero = ("CONFIGID_MOD_SWR_WITH_ENCODERZERO", 0x0000_0020, Information,
            "Homing uses the encoder index."),
        SwrAtFallingEdge = ("CONFIGID_MOD_SWR_AT_FALLING_EDGE", 0x0000_0040, Information,
            "Homing on the falling edge of the switch."),
        ChangeSwrToLimit = ("CONFIGID_MOD_CHANGE_SWR_TO_LIMIT", 0x0000_0080, Information,
            "The home switch is a limit switch except while homing."),
        SwrEnabled = ("CONFIGID_MOD_SWR_ENABLED", 0x0000_0100, Information, "The home switch is enabled."),
        SwrLowActive = ("CONFIGID_MOD_SWR_LOW_ACTIVE", 0x0000_0200, Information, "The home switch is low active."),
        SwrUseExternal = ("CONFIGID_MOD_SWR_USE_EXTERNAL", 0x0000_0400, Information, "An external home switch."),
        Sw1Enabled = ("CONFIGID_MOD_SW1_ENABLED", 0x0000_0800, Information, "Limit switch 1 is enabled."),
        Sw1LowActive = ("CONFIGID_MOD_SW1_LOW_ACTIVE", 0x0000_1000, Information, "Limit switch 1 is low active."),
        Sw1UseExternal = ("CONFIGID_MOD_SW1_USE_EXTERNAL", 0x0000_2000, Information, "An external limit switch 1."),
        Sw2Enabled = ("CONFIGID_MOD_SW2_ENABLED", 0x0000_4000, Information, "Limit switch 2 is enabled."),
        Sw2LowActive = ("CONFIGID_MOD_SW2_LOW_ACTIVE", 0x0000_8000, Information, "Limit switch 2 is low active."),
        Sw2UseExternal = ("CONFIGID_MOD_SW2_USE_EXTERNAL", 0x0001_0000, Information, "An external limit switch 2."),
        Linear = ("CONFIGID_MOD_LINEAR", 0x0002_0000, Information, "The module is a linear type."),
        AllowFullCur = ("CONFIGID_MOD_ALLOW_FULL_CUR", 0x0008_0000, Information,
            "0: commanded current is limited to the nominal current."),
        M3Compatible = ("CONFIGID_MOD_M3_COMPATIBLE", 0x0010_0000, Information,
            "M3 compatible: no motion commands unless homed."),
        LinearScrew = ("CONFIGID_MOD_LINEAR_SCREW", 0x0020_0000, Information, "Linear, driven by a ball screw."),
        DisableOnHalt = ("CONFIGID_MOD_DISABLE_ON_HALT", 0x0080_0000, Information,
            "Motor power is disabled in case of an error."),
        WatchdogEnable = ("CONFIGID_MOD_WATCHDOG_ENABLE", 0x0100_0000, Information,
            "The watchdog is enabled; the first life sign activates it."),
        ZeroMoveAfterHok = ("CONFIGID_MOD_ZERO_MOVE_AFTER_HOK", 0x0200_0000, Information,
            "After homing the module moves to zero."),
        DisableAck = ("CONFIGID_MOD_DISABLE_ACK", 0x0400_0000, Information,
            "All acknowledges except those of Get commands are disabled (CAN only)."),
        SyncMotion = ("CONFIGID_MOD_SYNC_MOTION", 0x0800_0000, Information,
            "Motion commands wait for the start-motion broadcast (CAN only)."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_slips_are_fixed_and_bit_numbers_kept() {
        assert_eq!(StateFlag::PowIntegralErr.mask(), 1 << 23);
        assert_eq!(StateFlag::LogicVolt.mask(), 1 << 27);
        assert_eq!(StateFlag::PowSetupErr.mask(), 1 << 27);
        // Bit 27 is named once, by its current name.
        assert_eq!(CubeState(1 << 27).iter().collect::<Vec<_>>(), vec![StateFlag::LogicVolt]);
        assert_eq!(CubeState(1 << 27).faults().collect::<Vec<_>>(), vec![StateFlag::LogicVolt]);
        // Every bit 0..27 is named, 28..31 are not.
        for bit in 0..32 {
            let named = CubeState(1 << bit).unknown_bits() == 0;
            assert_eq!(named, bit < 28, "bit {bit}");
        }
    }

    #[test]
    fn bit_27_is_one_fault_listed_under_both_names() {
        let s = CubeState(1 << 27).with(StateFlag::Error);
        assert_eq!(s.faults().count(), 2, "STATE_ERROR and bit 27, not bit 27 twice");
        assert_eq!(s.to_string(), "STATE_ERROR | STATE_LOGIC_VOLT (STATE_POW_SETUP_ERR)");
        assert_eq!(StateFlag::LogicVolt.label(), "STATE_LOGIC_VOLT (STATE_POW_SETUP_ERR)");
        assert_eq!(StateFlag::PowSetupErr.label(), "STATE_POW_SETUP_ERR (STATE_LOGIC_VOLT)");
        assert_eq!(StateFlag::Error.label(), "STATE_ERROR");
        assert_eq!(StateFlag::from_name("state_pow_setup_err"), Some(StateFlag::PowSetupErr));
        assert_eq!(StateFlag::from_name("STATE_LOGIC_VOLT"), Some(StateFlag::LogicVolt));
    }

    #[test]
    fn masks_are_unique_except_bit_27() {
        for (i, a) in StateFlag::ALL.iter().enumerate() {
            for b in &StateFlag::ALL[i + 1..] {
                if a.mask() == b.mask() {
                    assert_eq!((*a, *b), (StateFlag::LogicVolt, StateFlag::PowSetupErr));
                }
            }
        }
    }

    #[test]
    fn short_states_follow_the_full_state() {
        let s = CubeState::EMPTY.with(StateFlag::HomeOk).with(StateFlag::RampEnd);
        assert_eq!(s.short_state(), ShortState(0x20));
        assert_eq!(CubeState::EMPTY.short_state(), ShortState(0x01), "not homed is NOT_OK");
        let s = CubeState::EMPTY.with(StateFlag::HomeOk).with(StateFlag::Halted).with(StateFlag::Motion);
        assert_eq!(s.short_state(), ShortState(0x11));
        assert_eq!(s.profibus_state(), ProfibusState(0x8014));
        assert_eq!(CubeState(0x40).profibus_state(), ProfibusState(0x0400), "STATE_SWR is STATE_SYNC");
    }

    #[test]
    fn display_names_and_unknown_bits() {
        assert_eq!(CubeState(0).to_string(), "-");
        assert_eq!(CubeState(0x8000_0011).to_string(), "STATE_ERROR | STATE_TOW_ERROR | 0x80000000");
        assert_eq!(StateFlag::from_name("state_tow_error"), Some(StateFlag::TowError));
        let faults: Vec<_> = CubeState(0x0400_0807).faults().collect();
        assert_eq!(faults, vec![StateFlag::Error, StateFlag::BeyondSoft]);
    }
}
