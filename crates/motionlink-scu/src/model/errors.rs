//! The SCU's 32-bit error code (table 7), as a word of the shared flag-set mechanism, with each bit's
//! condition and the unit's reaction.

use std::fmt;

use motionlink_link::flag_set;

flag_set! {
    /// The bits of an SCU error code, as [`ErrorCode`] holds them.
    ErrorBits(u32);
    /// One bit of the SCU error code (table 7). The manual numbers them 1..32: bit n is mask `1 << (n - 1)`
    /// ([`ErrorBit::number`]). Bits 9 and 23 are unused.
    ErrorBit {
        RomTest = ("rom_test", 1 << 0, Error, "CRC error with ROM test, faulty ROM"),
        RamTest = ("ram_test", 1 << 1, Error, "error with RAM test, faulty RAM"),
        CpuTest = ("cpu_test", 1 << 2, Error, "error with CPU test, faulty CPU"),
        StackOverrun = ("stack_overrun", 1 << 3, Error, "stack overrun detected"),
        ProgramSequence = ("program_sequence", 1 << 4, Error, "program sequence error, watchdog reset"),
        HandSwitchTest = ("hand_switch_test", 1 << 5, Error, "error with hand switch test, short in hand switch"),
        BinaryInputsTest = ("binary_inputs_test", 1 << 6, Error, "error with binary inputs, short between binary inputs"),
        RelayFetTest = ("relay_fet_test", 1 << 7, Error, "error with relay and FET tests, faulty relay or FET"),
        MoveEnableCommunication = ("move_enable_communication", 1 << 9, Error, "no reply from the MoveEnable controller"),
        MoveEnableOutput = ("move_enable_output", 1 << 10, Error, "the MoveEnable controller output is incorrect"),
        OverTemperature = ("over_temperature", 1 << 11, Error, "overtemperature at rectifier or FET"),
        BatteryDischarge = ("battery_discharge", 1 << 12, Error, "switched off due to excessive discharge of battery"),
        TotalCurrent = ("total_current", 1 << 13, Error, "total current exceeded"),
        Drive1 = ("drive1", 1 << 14, Error, "error with drive 1"),
        Drive2 = ("drive2", 1 << 15, Error, "error with drive 2"),
        Drive3 = ("drive3", 1 << 16, Error, "error with drive 3"),
        Drive4 = ("drive4", 1 << 17, Error, "error with drive 4"),
        Drive5 = ("drive5", 1 << 18, Error, "error with drive 5"),
        Drive6 = ("drive6", 1 << 19, Error, "error with drive 6"),
        PositionDifference = ("position_difference", 1 << 20, Error, "position difference between drives too great (synchronised parallel run)"),
        RemoteTimeout = ("remote_timeout", 1 << 21, Error, "remote communication time out"),
        LockingBoxI2c = ("locking_box_i2c", 1 << 23, Error, "locking box I2C communication error"),
        EepromConfigurationCrc = ("eeprom_configuration_crc", 1 << 24, Error, "RAM copy of EEPROM configuration data has a wrong CRC"),
        EepromUserCrc = ("eeprom_user_crc", 1 << 25, Error, "RAM copy of EEPROM user data has a wrong CRC"),
        EepromLockingBoxCrc = ("eeprom_locking_box_crc", 1 << 26, Error, "EEPROM locking box data has a wrong CRC"),
        EepromDynamicCrc = ("eeprom_dynamic_crc", 1 << 27, Error, "RAM copy of EEPROM dynamic data has a wrong CRC"),
        EepromCalibrationCrc = ("eeprom_calibration_crc", 1 << 28, Error, "RAM copy of EEPROM calibration data has a wrong CRC"),
        EepromHwSettingsCrc = ("eeprom_hw_settings_crc", 1 << 29, Error, "RAM copy of EEPROM hardware settings has a wrong CRC"),
        IoTest = ("io_test", 1 << 30, Error, "IO test failed"),
        OperatingSystem = ("operating_system", 1 << 31, Error, "IDF operating system error"),
    }
}

const STOP_RESET: &str = "motions are stopped and the control unit carries out a reset";
const FAST_STOP_RESET: &str = "motions are stopped (fast stop) and the control unit carries out a reset";
const FAST_STOP: &str = "motions are stopped (fast stop)";
const NOT_PERFORMED: &str = "motions are not performed or stopped";
const DRIVE_FAULT_CONDITION: &str =
    "peak current, short circuit current, sensor monitor, over current or time out (if not limit position)";
const DRIVE_FAULT_REACTION: &str = "drive stopped (fast stop); bit reset on next motion";

impl ErrorBit {
    /// The manual's bit number, 1..32.
    pub fn number(self) -> u8 {
        self.mask().trailing_zeros() as u8 + 1
    }

    /// The cause, as the manual gives it.
    pub fn cause(self) -> &'static str {
        self.meaning()
    }

    /// When the error can appear ("" where the manual says nothing).
    pub fn condition(self) -> &'static str {
        match self {
            ErrorBit::HandSwitchTest => "only if the hand switch is parameterised as safe",
            ErrorBit::BinaryInputsTest => {
                "only if binary inputs are parameterised as safe and no analogue input is parameterised"
            }
            ErrorBit::RelayFetTest => "test performed at start of motion",
            ErrorBit::TotalCurrent => "if motion in process",
            ErrorBit::Drive1
            | ErrorBit::Drive2
            | ErrorBit::Drive3
            | ErrorBit::Drive4
            | ErrorBit::Drive5
            | ErrorBit::Drive6 => DRIVE_FAULT_CONDITION,
            ErrorBit::PositionDifference => "only if synchronised parallel run is parameterised",
            ErrorBit::LockingBoxI2c => "only if the locking box is parameterised as safe",
            ErrorBit::IoTest => "performed if no motion is active",
            _ => "",
        }
    }

    /// What the unit does.
    pub fn reaction(self) -> &'static str {
        match self {
            ErrorBit::RomTest | ErrorBit::RamTest | ErrorBit::CpuTest => STOP_RESET,
            ErrorBit::StackOverrun | ErrorBit::ProgramSequence => FAST_STOP_RESET,
            ErrorBit::HandSwitchTest
            | ErrorBit::BinaryInputsTest
            | ErrorBit::MoveEnableCommunication
            | ErrorBit::MoveEnableOutput
            | ErrorBit::OverTemperature => FAST_STOP,
            ErrorBit::RelayFetTest => "motion not executed",
            ErrorBit::BatteryDischarge => "motions are stopped (fast stop); the control unit switches itself off",
            ErrorBit::TotalCurrent => "motions are stopped (fast stop); bit reset in the next motion",
            ErrorBit::Drive1
            | ErrorBit::Drive2
            | ErrorBit::Drive3
            | ErrorBit::Drive4
            | ErrorBit::Drive5
            | ErrorBit::Drive6 => DRIVE_FAULT_REACTION,
            ErrorBit::PositionDifference => "motion not started, or stopped (fast stop); bit reset on next motion",
            ErrorBit::RemoteTimeout => "depending on the Safety_ID",
            ErrorBit::LockingBoxI2c
            | ErrorBit::EepromConfigurationCrc
            | ErrorBit::EepromUserCrc
            | ErrorBit::EepromLockingBoxCrc
            | ErrorBit::EepromDynamicCrc
            | ErrorBit::EepromCalibrationCrc
            | ErrorBit::EepromHwSettingsCrc
            | ErrorBit::OperatingSystem => NOT_PERFORMED,
            ErrorBit::IoTest => "motions not performed",
        }
    }
}

/// The error bit with the manual's number `number` (1..32), if the manual defines it.
pub fn error_bit(number: u8) -> Option<ErrorBit> {
    ErrorBit::ALL.iter().copied().find(|b| b.number() == number)
}

/// Named error bits of the emulator and client.
pub mod error_bits {
    /// Bit 14: total current exceeded.
    pub const TOTAL_CURRENT: u8 = 14;
    /// Bit 15: error with drive 1 (drive n is bit 14 + n).
    pub const DRIVE1: u8 = 15;
    /// Bit 22: remote communication time out.
    pub const REMOTE_TIMEOUT: u8 = 22;
}

/// A 32-bit SCU error code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ErrorCode(pub u32);

impl ErrorCode {
    /// No error.
    pub const NONE: ErrorCode = ErrorCode(0);

    /// The code with only the manual's bit `number` set.
    pub const fn from_bit(number: u8) -> ErrorCode {
        ErrorCode(1 << (number - 1))
    }

    /// True if the manual's bit `number` is set.
    pub const fn has(self, number: u8) -> bool {
        number >= 1 && number <= 32 && self.0 & (1 << (number - 1)) != 0
    }

    /// The code as the shared flag word.
    pub const fn flags(self) -> ErrorBits {
        ErrorBits(self.0)
    }

    /// The known bits that are set.
    pub fn bits(self) -> impl Iterator<Item = ErrorBit> {
        self.flags().iter()
    }

    /// Set bits the manual does not define (9, 23).
    pub fn unknown_bits(self) -> u32 {
        self.flags().unknown_bits()
    }
}

/// As every result shows an error code: `code` (the 32-bit word) and `bits`, each set bit the manual names
/// as [`ErrorBit`] serialises.
impl serde::Serialize for ErrorCode {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(2))?;
        map.serialize_entry("code", &self.0)?;
        map.serialize_entry("bits", &self.bits().collect::<Vec<_>>())?;
        map.end()
    }
}

/// As results show an error bit: `bit` (the manual's number, 1..32), `name` and `cause`.
impl serde::Serialize for ErrorBit {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(3))?;
        map.serialize_entry("bit", &self.number())?;
        map.serialize_entry("name", motionlink_link::flags::Flag::name(*self))?;
        map.serialize_entry("cause", self.cause())?;
        map.end()
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:08X}", self.0)?;
        if self.0 == 0 {
            return f.write_str(" (no error)");
        }
        let mut first = true;
        for b in self.bits() {
            f.write_str(if first { " [" } else { "; " })?;
            first = false;
            write!(f, "bit {}: {}", b.number(), b.cause())?;
        }
        if self.unknown_bits() != 0 {
            f.write_str(if first { " [" } else { "; " })?;
            first = false;
            write!(f, "undefined bits 0x{:08X}", self.unknown_bits())?;
        }
        if !first {
            f.write_str("]")?;
        }
        Ok(())
    }
}
