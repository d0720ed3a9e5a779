//! The named bit sets of the data list, each a word of the shared [`flag_set!`](motionlink_link::flag_set)
//! mechanism, and [`Flags`]: any of them, chosen at run time by the data-list entry that holds it.

use std::fmt;

use motionlink_link::flag_set;
use motionlink_link::flags::Flag;

flag_set! {
    /// 0x0020: logic and input level of binary inputs 1..4.
    BinaryInputs(u8);
    /// One bit of [`BinaryInputs`].
    BinaryInput {
        Input1Logic = ("input1_logic", 1 << 0, Information, "active", "not active"),
        Input2Logic = ("input2_logic", 1 << 1, Information, "active", "not active"),
        Input3Logic = ("input3_logic", 1 << 2, Information, "active", "not active"),
        Input4Logic = ("input4_logic", 1 << 3, Information, "active", "not active"),
        Input1Level = ("input1_level", 1 << 4, Information, "active", "not active"),
        Input2Level = ("input2_level", 1 << 5, Information, "active", "not active"),
        Input3Level = ("input3_level", 1 << 6, Information, "active", "not active"),
        Input4Level = ("input4_level", 1 << 7, Information, "active", "not active"),
    }
}

flag_set! {
    /// 0x0040: keys K1..K20 of the hand switch, closed.
    Keys(u32);
    /// One key of [`Keys`].
    Key {
        K1 = ("k1", 1 << 0, Information, "closed", "open"),
        K2 = ("k2", 1 << 1, Information, "closed", "open"),
        K3 = ("k3", 1 << 2, Information, "closed", "open"),
        K4 = ("k4", 1 << 3, Information, "closed", "open"),
        K5 = ("k5", 1 << 4, Information, "closed", "open"),
        K6 = ("k6", 1 << 5, Information, "closed", "open"),
        K7 = ("k7", 1 << 6, Information, "closed", "open"),
        K8 = ("k8", 1 << 7, Information, "closed", "open"),
        K9 = ("k9", 1 << 8, Information, "closed", "open"),
        K10 = ("k10", 1 << 9, Information, "closed", "open"),
        K11 = ("k11", 1 << 10, Information, "closed", "open"),
        K12 = ("k12", 1 << 11, Information, "closed", "open"),
        K13 = ("k13", 1 << 12, Information, "closed", "open"),
        K14 = ("k14", 1 << 13, Information, "closed", "open"),
        K15 = ("k15", 1 << 14, Information, "closed", "open"),
        K16 = ("k16", 1 << 15, Information, "closed", "open"),
        K17 = ("k17", 1 << 16, Information, "closed", "open"),
        K18 = ("k18", 1 << 17, Information, "closed", "open"),
        K19 = ("k19", 1 << 18, Information, "closed", "open"),
        K20 = ("k20", 1 << 19, Information, "closed", "open"),
    }
}

flag_set! {
    /// 0x0100: mains, battery, charging.
    BatteryMains(u8);
    /// One bit of [`BatteryMains`].
    BatteryMainsFlag {
        MainsConnected = ("mains_connected", 1 << 0, Information, "mains connected", "mains not connected"),
        BatteryConnected = ("battery_connected", 1 << 1, Information, "battery connected", "battery disconnected"),
        ChargeController = ("charge_controller", 1 << 2, Information, "charge controller on", "charge controller off"),
        Charging = ("charging", 1 << 3, Information, "charging active", "charging inactive"),
    }
}

flag_set! {
    /// 0x0110: binary outputs.
    BinaryOutputs(u8);
    /// One output of [`BinaryOutputs`].
    BinaryOutput {
        Output1 = ("output1", 1 << 0, Information, "on", "off"),
        Output2 = ("output2", 1 << 1, Information, "on", "off"),
    }
}

flag_set! {
    /// 0x0120: LEDs of the hand switch (operating unit).
    HandSwitchLeds(u8);
    /// One LED of [`HandSwitchLeds`].
    HandSwitchLed {
        Led1 = ("led1", 1 << 0, Information, "on", "off"),
        Led2 = ("led2", 1 << 1, Information, "on", "off"),
    }
}

flag_set! {
    /// 0x0130: LEDs of the locking box.
    LockingBoxLeds(u8);
    /// One LED of [`LockingBoxLeds`].
    LockingBoxLed {
        Led1 = ("led1", 1 << 0, Information, "on", "off"),
        Led2 = ("led2", 1 << 1, Information, "on", "off"),
        Led3 = ("led3", 1 << 2, Information, "on", "off"),
        Led4 = ("led4", 1 << 3, Information, "on", "off"),
        Led5 = ("led5", 1 << 4, Information, "on", "off"),
        Led6 = ("led6", 1 << 5, Information, "on", "off"),
        Led7 = ("led7", 1 << 6, Information, "on", "off"),
        Led8 = ("led8", 1 << 7, Information, "on", "off"),
    }
}

flag_set! {
    /// 0x0140: the buzzer.
    BuzzerState(u8);
    /// The bit of [`BuzzerState`].
    BuzzerFlag {
        On = ("buzzer", 1 << 0, Information, "on", "off"),
    }
}

flag_set! {
    /// 0x0150: the sensor supply.
    SensorSupply(u8);
    /// The bit of [`SensorSupply`].
    SensorSupplyFlag {
        On = ("sensor_supply", 1 << 0, Information, "on", "off"),
    }
}

flag_set! {
    /// 0x0162: motion functions F1..F10 locked.
    LockStatus(u16);
    /// One function of [`LockStatus`].
    FunctionLock {
        F1 = ("f1_locked", 1 << 0, Warning, "locked", "unlocked"),
        F2 = ("f2_locked", 1 << 1, Warning, "locked", "unlocked"),
        F3 = ("f3_locked", 1 << 2, Warning, "locked", "unlocked"),
        F4 = ("f4_locked", 1 << 3, Warning, "locked", "unlocked"),
        F5 = ("f5_locked", 1 << 4, Warning, "locked", "unlocked"),
        F6 = ("f6_locked", 1 << 5, Warning, "locked", "unlocked"),
        F7 = ("f7_locked", 1 << 6, Warning, "locked", "unlocked"),
        F8 = ("f8_locked", 1 << 7, Warning, "locked", "unlocked"),
        F9 = ("f9_locked", 1 << 8, Warning, "locked", "unlocked"),
        F10 = ("f10_locked", 1 << 9, Warning, "locked", "unlocked"),
    }
}

flag_set! {
    /// 0x0171..0x0176: actuator status 1.
    ActuatorStatus1(u8);
    /// One bit of [`ActuatorStatus1`].
    Status1Flag {
        Available = ("available", 1 << 0, Information, "drive available", "drive unavailable"),
        LimitInOut = ("limit_in_out", 1 << 1, Information, "signal limit_in_out active",
            "signal limit_in_out inactive"),
        Switch1 = ("switch1", 1 << 2, Information, "signal switch 1 active", "signal switch 1 inactive"),
        Switch2 = ("switch2", 1 << 3, Information, "signal switch 2 active", "signal switch 2 inactive"),
        Motion = ("motion", 1 << 4, Information, "motion active", "motion inactive"),
        InPosition = ("in_position", 1 << 5, Information, "in position reached",
            "in position not reached"),
        OutPosition = ("out_position", 1 << 6, Information, "out position reached",
            "out position not reached"),
        StrokeDone = ("stroke_done", 1 << 7, Information, "stroke done", "stroke not done"),
    }
}

flag_set! {
    /// 0x00E1..0x00E6: actuator status 2.
    ActuatorStatus2(u8);
    /// One bit of [`ActuatorStatus2`].
    Status2Flag {
        Initialized = ("initialized", 1 << 0, Information, "initialized", "not initialized"),
        ReleaseRetraction = ("release_retraction", 1 << 1, Information,
            "released for retraction", "no release for retraction"),
        ReleaseExtension = ("release_extension", 1 << 2, Information,
            "released for extension", "no release for extension"),
    }
}

impl ActuatorStatus1 {
    /// True while the actuator is connected ("drive available").
    pub fn available(self) -> bool {
        self.contains(Status1Flag::Available)
    }

    /// True while the actuator moves ("motion active").
    pub fn moving(self) -> bool {
        self.contains(Status1Flag::Motion)
    }
}

impl From<ActuatorStatus1> for Flags {
    /// The word as the data list's value of an actuator's status 1 (0x0171..0x0176).
    fn from(s: ActuatorStatus1) -> Flags {
        Flags { set: FlagSet::ActuatorStatus1, bits: u32::from(s.bits()) }
    }
}

impl From<ActuatorStatus2> for Flags {
    /// The word as the data list's value of an actuator's status 2 (0x00E1..0x00E6).
    fn from(s: ActuatorStatus2) -> Flags {
        Flags { set: FlagSet::ActuatorStatus2, bits: u32::from(s.bits()) }
    }
}

/// One named bit of a [`FlagSet`], as the data list shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FlagBit {
    /// Bit number, 0 = least significant.
    pub bit: u8,
    /// Name for JSON and tables.
    pub name: &'static str,
    /// Meaning when set.
    pub set: &'static str,
    /// Meaning when clear.
    pub clear: &'static str,
}

/// The named bit sets of the data list: which of the words above an entry holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FlagSet {
    /// 0x0020: [`BinaryInputs`].
    BinaryInputs,
    /// 0x0040: [`Keys`].
    Keys,
    /// 0x0100: [`BatteryMains`].
    BatteryMains,
    /// 0x0110: [`BinaryOutputs`].
    BinaryOutputs,
    /// 0x0120: [`HandSwitchLeds`].
    LedHandSwitch,
    /// 0x0130: [`LockingBoxLeds`].
    LedLockingBox,
    /// 0x0140: [`BuzzerState`].
    Buzzer,
    /// 0x0150: [`SensorSupply`].
    SensorSupply,
    /// 0x0162: [`LockStatus`].
    LockStatus,
    /// 0x0171..0x0176: [`ActuatorStatus1`].
    ActuatorStatus1,
    /// 0x00E1..0x00E6: [`ActuatorStatus2`].
    ActuatorStatus2,
}

/// The bits of one flag table, in its order.
fn bits_of<F: Flag>(all: &[F], clear: impl Fn(F) -> Option<&'static str>) -> Vec<FlagBit> {
    all.iter()
        .map(|&f| FlagBit {
            bit: f.mask_u64().trailing_zeros() as u8,
            name: f.name(),
            set: f.meaning(),
            clear: clear(f).unwrap_or(""),
        })
        .collect()
}

impl FlagSet {
    /// Size in bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            FlagSet::Keys => 4,
            FlagSet::LockStatus => 2,
            _ => 1,
        }
    }

    /// The named bits, from the set's flag table.
    pub fn bits(self) -> Vec<FlagBit> {
        match self {
            FlagSet::BinaryInputs => bits_of(BinaryInput::ALL, BinaryInput::clear_meaning),
            FlagSet::Keys => bits_of(Key::ALL, Key::clear_meaning),
            FlagSet::BatteryMains => bits_of(BatteryMainsFlag::ALL, BatteryMainsFlag::clear_meaning),
            FlagSet::BinaryOutputs => bits_of(BinaryOutput::ALL, BinaryOutput::clear_meaning),
            FlagSet::LedHandSwitch => bits_of(HandSwitchLed::ALL, HandSwitchLed::clear_meaning),
            FlagSet::LedLockingBox => bits_of(LockingBoxLed::ALL, LockingBoxLed::clear_meaning),
            FlagSet::Buzzer => bits_of(BuzzerFlag::ALL, BuzzerFlag::clear_meaning),
            FlagSet::SensorSupply => bits_of(SensorSupplyFlag::ALL, SensorSupplyFlag::clear_meaning),
            FlagSet::LockStatus => bits_of(FunctionLock::ALL, FunctionLock::clear_meaning),
            FlagSet::ActuatorStatus1 => bits_of(Status1Flag::ALL, Status1Flag::clear_meaning),
            FlagSet::ActuatorStatus2 => bits_of(Status2Flag::ALL, Status2Flag::clear_meaning),
        }
    }

    /// The bit named `name`.
    pub fn bit(self, name: &str) -> Option<FlagBit> {
        self.bits().into_iter().find(|b| b.name == name)
    }
}

/// A value of one of the named bit sets, chosen by the data-list entry that holds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Flags {
    /// Which set.
    pub set: FlagSet,
    /// The raw bits.
    pub bits: u32,
}

impl Flags {
    /// True if the bit named `name` is set.
    pub fn is_set(&self, name: &str) -> bool {
        self.set.bit(name).is_some_and(|b| self.bits & (1 << b.bit) != 0)
    }

    /// Names of the set bits, in the table's order.
    pub fn set_names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.set.bits().into_iter().filter(move |b| self.bits & (1 << b.bit) != 0).map(|b| b.name)
    }
}

/// As every result shows a flag word ([`motionlink_link::flags::WordView`]): `word`, `flags` (the names of the
/// bits set) and `unknown_bits` (the bits the set does not name), only when nonzero.
impl serde::Serialize for Flags {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let known = self.set.bits().into_iter().fold(0u32, |m, b| m | (1 << b.bit));
        let unknown = self.bits & !known;
        let mut map = s.serialize_map(Some(if unknown != 0 { 3 } else { 2 }))?;
        map.serialize_entry("word", &self.bits)?;
        map.serialize_entry("flags", &self.set_names().collect::<Vec<_>>())?;
        if unknown != 0 {
            map.serialize_entry("unknown_bits", &unknown)?;
        }
        map.end()
    }
}

impl fmt::Display for Flags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let width = self.set.size() * 2;
        write!(f, "0x{:0width$X}", self.bits)?;
        let names: Vec<_> = self.set_names().collect();
        if !names.is_empty() {
            write!(f, " [{}]", names.join(", "))?;
        }
        Ok(())
    }
}
