//! The port locks of the gateway ([`motionlink_link::portlock`]): the lock of every real port it serves (not
//! `sim`), taken before the port is opened, as the command line takes it; a port another motionlink holds
//! stops the start (exit 3, naming the holder). `motionlink FAMILY --port PORT stop` from another terminal
//! writes a request to stop into the lock's directory and sends the gateway SIGINT: the gateway then stops
//! that device's motion as a `stop` request does, closes its session and lets go of the port, telling the
//! `stop` what it stopped; the other devices are served on. It takes the port again once it is free.

use std::collections::HashMap;

use motionlink_link::portlock::{self, PortLock, StopRequest};

use crate::config::DeviceEntry;

/// The locks held, by device.
#[derive(Debug, Default)]
pub struct PortLocks {
    held: HashMap<String, PortLock>,
}

/// How the gateway names itself to another motionlink as the holder of a device's port.
pub fn holder_command(gateway: &str, device: &str) -> String {
    format!("gateway {gateway}: device {device}")
}

impl PortLocks {
    /// No lock held.
    pub fn new() -> PortLocks {
        PortLocks::default()
    }

    /// Takes the lock of `entry`'s port for the gateway `gateway` (none for `sim`, or where the port needs
    /// none); a port another process holds is the error that names it and its `stop`.
    pub fn claim(&mut self, gateway: &str, entry: &DeviceEntry) -> Result<(), String> {
        if entry.port == "sim" {
            return Ok(());
        }
        let command = holder_command(gateway, &entry.name);
        match portlock::claim(&entry.family, &entry.port, &command) {
            Ok(Some(lock)) => {
                self.held.insert(entry.name.clone(), lock);
                Ok(())
            }
            Ok(None) => Ok(()),
            Err(e) => Err(e.0),
        }
    }

    /// The devices whose port a `stop` asked this process to let go of, with that request.
    pub fn stop_requests(&self) -> Vec<(String, StopRequest)> {
        let mut asked: Vec<_> =
            self.held.iter().filter_map(|(device, lock)| Some((device.clone(), lock.stop_request()?))).collect();
        asked.sort_by(|a, b| a.0.cmp(&b.0));
        asked
    }

    /// Lets go of `device`'s port, telling the `stop` that asked how its motion ended (`exit_code`, 0 when the
    /// device confirmed it at rest, and `message`).
    pub fn release(&mut self, gateway: &str, device: &str, exit_code: u8, message: &str) {
        if let Some(lock) = self.held.remove(device) {
            lock.release(&holder_command(gateway, device), exit_code, message);
        }
    }

    /// Whether the gateway holds `device`'s port.
    pub fn holds(&self, device: &str) -> bool {
        self.held.contains_key(device)
    }
}
