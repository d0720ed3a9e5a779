//! The CAN carrier (the Amtec protocol, 11-bit identifiers): the identifier says who and why, the DLC how
//! many bytes.
//!
//! | identifier | role |
//! |---|---|
//! | `0x0A0 + address` | acknowledge from a module (CANID_CMDACK) |
//! | `0x0C0 + address` | GetExtended to a module (CANID_CMDGET) |
//! | `0x0E0 + address` | any other command to a module (CANID_CMDPUT) |
//! | `0x100` | broadcast to every module (CANID_CMDALL), never acknowledged |
//!
//! ```
//! use motionlink_powercube::wire::{can, Payload};
//! let f = can::to_frame(can::Role::Put(17), &Payload::new(&[0x01]).unwrap());
//! assert_eq!(f.to_string(), "0F1#01");
//! assert_eq!(can::from_frame(&f).unwrap(), (can::Role::Put(17), Payload::new(&[0x01]).unwrap()));
//! ```

use motionlink_link::can::CanFrame;

use super::{cmd, is_module_address, Payload};

/// Identifier base of acknowledges.
pub const ACK_BASE: u32 = 0x0A0;
/// Identifier base of GetExtended commands.
pub const GET_BASE: u32 = 0x0C0;
/// Identifier base of every other command.
pub const PUT_BASE: u32 = 0x0E0;
/// The broadcast identifier.
pub const BROADCAST: u32 = 0x100;

/// What a PowerCube CAN identifier means.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    /// An acknowledge from the module at this address.
    Ack(u8),
    /// A GetExtended to the module at this address.
    Get(u8),
    /// Another command to the module at this address.
    Put(u8),
    /// A command to every module.
    Broadcast,
}

impl Role {
    /// The identifier.
    pub fn id(self) -> u32 {
        match self {
            Role::Ack(a) => ACK_BASE + u32::from(a),
            Role::Get(a) => GET_BASE + u32::from(a),
            Role::Put(a) => PUT_BASE + u32::from(a),
            Role::Broadcast => BROADCAST,
        }
    }

    /// The meaning of `id`, if it is a PowerCube identifier (module addresses 1..31).
    pub fn from_id(id: u32) -> Option<Role> {
        let module = |base: u32| u8::try_from(id - base).ok().filter(|a| is_module_address(*a));
        match id {
            BROADCAST => Some(Role::Broadcast),
            0x0A0..=0x0BF => module(ACK_BASE).map(Role::Ack),
            0x0C0..=0x0DF => module(GET_BASE).map(Role::Get),
            0x0E0..=0x0FF => module(PUT_BASE).map(Role::Put),
            _ => None,
        }
    }

    /// The role a command to `address` travels in: GetExtended on the get identifier, the rest on put.
    pub fn for_command(address: u8, payload: &Payload) -> Role {
        if payload.command() == Some(cmd::GET_EXTENDED) {
            Role::Get(address)
        } else {
            Role::Put(address)
        }
    }
}

/// A frame that is not a PowerCube message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CanWireError {
    /// Not one of the PowerCube identifiers.
    #[error("CAN identifier {0:#05X} is not a PowerCube identifier")]
    ForeignId(u32),
    /// A 29-bit identifier or a remote frame.
    #[error("extended or remote frame {0:#X}: the PowerCube protocol uses 11-bit data frames")]
    NotDataFrame(u32),
    /// No data.
    #[error("empty frame on {0:#05X}")]
    Empty(u32),
}

/// The frame carrying `payload` in `role`.
pub fn to_frame(role: Role, payload: &Payload) -> CanFrame {
    CanFrame::new(role.id(), payload.as_bytes())
        .expect("identifiers up to 0x11F and payloads up to 8 bytes always make a valid frame")
}

/// The role and payload of a PowerCube frame.
pub fn from_frame(frame: &CanFrame) -> Result<(Role, Payload), CanWireError> {
    if frame.is_extended() || frame.is_remote() {
        return Err(CanWireError::NotDataFrame(frame.id()));
    }
    let role = Role::from_id(frame.id()).ok_or(CanWireError::ForeignId(frame.id()))?;
    if frame.data().is_empty() {
        return Err(CanWireError::Empty(frame.id()));
    }
    // A CAN frame carries at most 8 bytes: always a valid payload.
    let payload = Payload::new(frame.data()).map_err(|_| CanWireError::Empty(frame.id()))?;
    Ok((role, payload))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_of_module_17() {
        assert_eq!(Role::Ack(17).id(), 0x0B1);
        assert_eq!(Role::Get(17).id(), 0x0D1);
        assert_eq!(Role::Put(17).id(), 0x0F1);
        for a in 1..=31 {
            for r in [Role::Ack(a), Role::Get(a), Role::Put(a)] {
                assert_eq!(Role::from_id(r.id()), Some(r));
            }
        }
        assert_eq!(Role::from_id(0x0A0), None, "address 0 is not a module");
        assert_eq!(Role::from_id(0x100), Some(Role::Broadcast));
        assert_eq!(Role::from_id(0x580), None);
    }

    #[test]
    fn foreign_frames_are_errors() {
        let f = CanFrame::new(0x3E9, &[1]).unwrap();
        assert_eq!(from_frame(&f), Err(CanWireError::ForeignId(0x3E9)));
        let f = CanFrame::new_extended(0x0F1, &[1]).unwrap();
        assert!(matches!(from_frame(&f), Err(CanWireError::NotDataFrame(_))));
        let f = CanFrame::new(0x0F1, &[]).unwrap();
        assert_eq!(from_frame(&f), Err(CanWireError::Empty(0x0F1)));
    }
}
