//! The Profibus-DP carrier: the process image a DP master exchanges with a module every cycle.
//!
//! - Output (master to module), 8 bytes: the command in bytes 0..6 (0..7 for an 8-byte command); byte 7
//!   must change from one command to the next, or the module ignores the repeat, so it carries a rolling
//!   counter ([`OutputWriter`]).
//! - Input (module to master), 16 bytes: the acknowledge of the last command in bytes 0..7; byte 8 unused;
//!   bytes 9..12 the actual position in encoder ticks (Int32), 13..14 the Profibus short state (UInt16),
//!   15 a millisecond counter (0..255) usable as a life sign.
//!
//! ```
//! use motionlink_powercube::wire::{profibus::OutputWriter, Payload};
//! let mut w = OutputWriter::new();
//! let home = Payload::new(&[0x01]).unwrap();
//! let a = w.image(&home).unwrap();
//! let b = w.image(&home).unwrap();
//! assert_eq!(a.0[0], 0x01);
//! assert_ne!(a.0[7], b.0[7]); // the same command twice still changes the image
//! ```

use super::Payload;

/// Size of the output image.
pub const OUTPUT_LEN: usize = 8;
/// Size of the input image.
pub const INPUT_LEN: usize = 16;

/// The 8 output bytes of one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct OutputImage(pub [u8; OUTPUT_LEN]);

impl OutputImage {
    /// The command bytes (all 8; the caller knows how many the command has).
    pub fn command_bytes(&self) -> &[u8; OUTPUT_LEN] {
        &self.0
    }

    /// The rolling byte 7.
    pub fn counter(&self) -> u8 {
        self.0[7]
    }
}

/// Why an output image cannot be made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ProfibusError {
    /// An 8-byte command uses byte 7 itself; sent twice in a row the image would not change and the module
    /// would ignore the second one.
    #[error("an 8-byte command identical to the previous image would be ignored by the module")]
    RepeatIgnored,
}

/// Builds successive output images, keeping byte 7 changing.
#[derive(Debug, Clone, Default)]
pub struct OutputWriter {
    last: Option<[u8; OUTPUT_LEN]>,
    counter: u8,
}

impl OutputWriter {
    /// A writer whose first image has counter 1.
    pub fn new() -> Self {
        Self::default()
    }

    /// The image for `payload`. Commands of up to 7 bytes get the next counter value in byte 7; an 8-byte
    /// command fills byte 7 itself and is refused if the image would repeat the previous one.
    pub fn image(&mut self, payload: &Payload) -> Result<OutputImage, ProfibusError> {
        let mut image = [0u8; OUTPUT_LEN];
        image[..payload.len()].copy_from_slice(payload.as_bytes());
        if payload.len() < OUTPUT_LEN {
            self.counter = self.counter.wrapping_add(1);
            image[7] = self.counter;
            if self.last == Some(image) {
                // Only possible after 256 identical commands with an 8-byte one in between: skip a value.
                self.counter = self.counter.wrapping_add(1);
                image[7] = self.counter;
            }
        } else if self.last == Some(image) {
            return Err(ProfibusError::RepeatIgnored);
        }
        self.last = Some(image);
        Ok(OutputImage(image))
    }
}

/// The 16 input bytes of one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct InputImage(pub [u8; INPUT_LEN]);

impl InputImage {
    /// An image with the acknowledge `reply` in bytes 0..7 and the cyclic values.
    pub fn new(reply: &Payload, position_ticks: i32, short_state: u16, millis: u8) -> Self {
        let mut b = [0u8; INPUT_LEN];
        b[..reply.len()].copy_from_slice(reply.as_bytes());
        b[9..13].copy_from_slice(&position_ticks.to_le_bytes());
        b[13..15].copy_from_slice(&short_state.to_le_bytes());
        b[15] = millis;
        InputImage(b)
    }

    /// Bytes 0..7: the acknowledge of the last command (its length follows from the command).
    pub fn reply_bytes(&self) -> &[u8] {
        &self.0[..8]
    }

    /// The first `len` acknowledge bytes as a payload (`len` is capped at 8).
    pub fn reply(&self, len: usize) -> Payload {
        Payload::new(&self.0[..len.min(8)]).unwrap_or_default()
    }

    /// Bytes 9..12: the actual position in encoder ticks.
    pub fn position_ticks(&self) -> i32 {
        i32::from_le_bytes([self.0[9], self.0[10], self.0[11], self.0[12]])
    }

    /// Bytes 13..14: the Profibus short state word as a number. The flags, typed, are
    /// [`InputImage::short_state`] (a [`ProfibusState`](crate::model::ProfibusState); the meaning of the
    /// bits is the model's, so that method lives there).
    pub fn short_state_raw(&self) -> u16 {
        u16::from_le_bytes([self.0[13], self.0[14]])
    }

    /// Byte 15: the module's millisecond counter.
    pub fn millis(&self) -> u8 {
        self.0[15]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_byte_commands_must_change() {
        let mut w = OutputWriter::new();
        let step = Payload::new(&[0x0b, 0x06, 0, 0, 0x80, 0x3f, 0xe8, 0x03]).unwrap();
        assert_eq!(w.image(&step).unwrap().0, *step.as_bytes().first_chunk::<8>().unwrap());
        assert_eq!(w.image(&step), Err(ProfibusError::RepeatIgnored));
        let get = Payload::new(&[0x0a, 0x27]).unwrap();
        assert!(w.image(&get).is_ok());
        assert!(w.image(&step).is_ok(), "after another command the same step is a change again");
    }

    #[test]
    fn counter_rolls_over_and_never_repeats() {
        let mut w = OutputWriter::new();
        let get = Payload::new(&[0x0a, 0x27]).unwrap();
        let mut last = w.image(&get).unwrap();
        for _ in 0..600 {
            let next = w.image(&get).unwrap();
            assert_ne!(next, last);
            last = next;
        }
    }

    #[test]
    fn input_image_fields() {
        let img = InputImage::new(&Payload::new(&[0x01]).unwrap(), -1000, 0x8081, 42);
        assert_eq!(img.position_ticks(), -1000);
        assert_eq!(img.short_state_raw(), 0x8081);
        assert_eq!(img.millis(), 42);
        assert_eq!(img.reply(1).as_bytes(), &[0x01]);
        assert_eq!(img.0[8], 0);
    }
}
