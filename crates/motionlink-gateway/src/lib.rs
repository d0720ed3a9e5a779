//! The fleet gateway: the devices of one machine on an MQTT broker (`motionlink gateway`).
//!
//! One process per machine serves every device of its file (`[device.NAME]` tables, as devices.toml has
//! them) to the broker under `motionlink/<gateway>/`: a retained `status`, each device's retained `state`,
//! its `cmd` requests and their replies, and its `events`. Every action runs on the family crate's
//! `AsyncClient` and replies with the family's serialised report, the object the command line's `--json`
//! prints; a motion lives only as long as its lease is renewed. The topics are a public interface: see
//! docs/fleet.md.

#![warn(missing_docs)]

pub mod args;
pub mod cli;
pub mod config;
pub mod device;
pub mod error;
pub mod events;
pub mod gateway;
pub mod lease;
pub mod mqtt;
pub mod notice;
pub mod ports;
pub mod request;
pub mod topics;

pub use config::Options;
pub use error::GatewayError;

/// Runs the gateway the command line describes: reads and checks the file (the password from
/// `password_file` or [`config::PASSWORD_ENV`]), opens every device, connects, and serves until SIGINT,
/// SIGTERM, SIGHUP, SIGQUIT or SIGTSTP (Ctrl-Z: not suspended); then every motion is stopped and `offline`
/// published. `Ok` holds the exit code (128 + the signal's number: 130, 143, 129, 131, 148 on Linux);
/// an error is a usage error (exit 2) or a device or broker that cannot be reached (exit 3), found before
/// anything was served.
pub fn main(options: &Options) -> Result<u8, GatewayError> {
    let config = config::load(options, |key| std::env::var(key).ok())?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| GatewayError::Transport(format!("the async runtime: {e}")))?;
    runtime.block_on(gateway::run(config))
}
