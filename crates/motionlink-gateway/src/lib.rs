//! The fleet gateway: the devices of one machine on an MQTT broker (`motionlink gateway`).
//!
//! One process per machine serves every device of its file (`[device.NAME]` tables, as devices.toml has
//! them) to the broker under `motionlink/<gateway>/`: a retained `status`, each device's retained `state`,
//! its `cmd` requests and their replies, and its `events`. Every action runs on the family crate's
//! `AsyncClient` and replies with the family's serialised report, the object the command line's `--json`
//! prints; a motion lives only as long as its lease is renewed. The topics are a public interface: see
//! docs/fleet.md.

pub mod args;
pub mod config;
pub mod device;
pub mod error;
pub mod lease;
pub mod request;
pub mod topics;
