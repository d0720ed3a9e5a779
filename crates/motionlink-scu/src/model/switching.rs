//! Where the data list shows the state of a switching function (F11 buzzer, F17/F18 binary outputs, F20
//! emergency stop, F21/F22 the operating unit's LEDs): the entry and the bits the session reads after the RE
//! that switches the function on and the RS that switches it off.
//!
//! The manuals tie two of them to their function in so many words: F11 "Buzzer" and 0x0140 "Bit 0 0/1:
//! Buzzer off/on"; F17 "Binary Output 1" and 0x0110 "Bit 0 0/1: Binary Output 1 off/on". The others are this
//! crate's reading ([`SwitchStatus::reading`] says why): both editions name bit 1 of 0x0110 "Binary Output 1"
//! again; F21/F22 are the "Operating unit Led1/Led2" (the Schaeffler edition "LED1" for both), and the data
//! list has LEDs of the hand switch (0x0120) and of the locking box (0x0130); no entry names the emergency
//! stop.
//!
//! ```
//! use motionlink_scu::model::{DataIndex, Function};
//! let buzzer = Function::Buzzer.switch_status().unwrap();
//! assert_eq!((buzzer.index, buzzer.mask, buzzer.reading), (DataIndex(0x0140), 0x01, None));
//! assert!(buzzer.shows_on(0x01) && !buzzer.shows_on(0x00));
//! let stop = Function::EmergencyStop.switch_status().unwrap();
//! assert!(stop.shows_on(0x03FF) && !stop.shows_on(0x01FF) && stop.reading.is_some());
//! assert_eq!(stop.state(true), "engaged");
//! ```

use super::{item, DataIndex, Function};

/// The data-list entry that shows a switching function, and which of its bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SwitchStatus {
    /// The function.
    pub function: Function,
    /// The data-list entry (read with RG).
    pub index: DataIndex,
    /// The bits that show the function on: on while every one of them is set, off while any is clear.
    pub mask: u16,
    /// What the function switches, as messages name it: "the buzzer", "binary output 2".
    pub what: &'static str,
    /// `None` where the manuals' own words tie the bits to the function (the buzzer, binary output 1): a
    /// status that shows the other state after an acknowledged RE or RS is an error. Otherwise why the tie
    /// is this crate's reading: the session trusts the entry for the function only once it has seen it show
    /// both states around the function's acknowledged RE and RS, and says so where it has not.
    pub reading: Option<&'static str>,
}

impl SwitchStatus {
    /// True if `word`, the entry's value, shows the function on.
    pub const fn shows_on(&self, word: u16) -> bool {
        word & self.mask == self.mask
    }

    /// The function's state in words: "on" / "off", for the emergency stop "engaged" / "released".
    pub const fn state(&self, on: bool) -> &'static str {
        match (self.function, on) {
            (Function::EmergencyStop, true) => "engaged",
            (Function::EmergencyStop, false) => "released",
            (_, true) => "on",
            (_, false) => "off",
        }
    }

    /// The entry's name in the data list ("buzzer", "lock_status").
    pub fn name(&self) -> &'static str {
        item(self.index).map_or("?", |it| it.name())
    }

    /// The bits of [`SwitchStatus::mask`] in words, as messages name them: "bit 0", "bits 0..9".
    pub fn bits(&self) -> String {
        let (low, high) = (self.mask.trailing_zeros(), 15 - self.mask.leading_zeros());
        if low == high {
            format!("bit {low}")
        } else {
            format!("bits {low}..{high}")
        }
    }

    /// The entry and its bits: "buzzer (0x0140, bit 0)", "lock_status (0x0162, bits 0..9)".
    pub fn place(&self) -> String {
        format!("{} ({}, {})", self.name(), self.index, self.bits())
    }

    /// What `word` shows, in words: "buzzer (0x0140, bit 0) is set (0x01)", "lock_status (0x0162) shows every
    /// motion function F1..F10 locked (0x03FF)".
    pub fn detail(&self, word: u16) -> String {
        match (self.function, self.shows_on(word)) {
            (Function::EmergencyStop, true) => {
                format!("{} ({}) shows every motion function F1..F10 locked (0x{word:04X})", self.name(), self.index)
            }
            (Function::EmergencyStop, false) => {
                format!("{} ({}) is 0x{word:04X}, not every motion function F1..F10 locked", self.name(), self.index)
            }
            (_, on) => format!("{} is {} (0x{word:02X})", self.place(), if on { "set" } else { "clear" }),
        }
    }
}

/// Binary output 2: the data list names both bits of 0x0110 "Binary Output 1".
const OUTPUT2: &str = "both editions of the manual name bit 1 of binary_outputs \"Binary Output 1\", as bit 0 \
                       (taken to be binary output 2)";

/// The operating unit's LEDs: the hand switch's or the locking box's.
const LEDS: &str = "the manuals call F21 and F22 the \"Operating unit\" LED1 and LED2 without saying whether they are \
                    the hand switch's (led_hand_switch, 0x0120) or the locking box's (led_locking_box, 0x0130; the \
                    hand switch's are taken)";

/// The emergency stop: no entry names it.
const EMERGENCY_STOP: &str = "the manuals tie no data-list entry to the emergency stop (every motion function \
                              locked in lock_status is taken to show it)";

impl Function {
    /// Where the data list shows this switching function's state; `None` for a motion function.
    pub const fn switch_status(self) -> Option<SwitchStatus> {
        let (index, mask, what, reading) = match self {
            Function::Motion(_) => return None,
            Function::Buzzer => (0x0140, 0x01, "the buzzer", None),
            Function::BinaryOutput1 => (0x0110, 0x01, "binary output 1", None),
            Function::BinaryOutput2 => (0x0110, 0x02, "binary output 2", Some(OUTPUT2)),
            Function::EmergencyStop => (0x0162, 0x03FF, "the emergency stop", Some(EMERGENCY_STOP)),
            Function::Led1 => (0x0120, 0x01, "LED 1 of the operating unit", Some(LEDS)),
            Function::Led2 => (0x0120, 0x02, "LED 2 of the operating unit", Some(LEDS)),
        };
        Some(SwitchStatus { function: self, index: DataIndex(index), mask, what, reading })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{entry, Kind};

    #[test]
    fn each_switching_function_is_shown_by_a_flag_entry_of_the_data_list() {
        for id in 10..=21 {
            let Some(f) = Function::from_id(id) else { continue };
            let s = f.switch_status().unwrap();
            let e = entry(s.index).unwrap();
            assert!(matches!(e.kind, Kind::Flags(_)), "{f}: {}", e.name);
            assert!(usize::from(s.mask) < 1 << (8 * e.kind.size()), "{f}");
            assert_eq!(s.function, f);
        }
        assert!(Function::from_id(0).unwrap().switch_status().is_none());
        let out2 = Function::BinaryOutput2.switch_status().unwrap();
        assert_eq!(out2.detail(0x02), "binary_outputs (0x0110, bit 1) is set (0x02)");
        assert_eq!(Function::EmergencyStop.switch_status().unwrap().place(), "lock_status (0x0162, bits 0..9)");
        let stop = Function::EmergencyStop.switch_status().unwrap();
        assert_eq!(stop.detail(0), "lock_status (0x0162) is 0x0000, not every motion function F1..F10 locked");
    }
}
