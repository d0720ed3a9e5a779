//! `motionlink gateway`: the devices of this machine on an MQTT broker (the `motionlink-gateway` crate does
//! the work; docs/fleet.md describes the topics).

use std::path::PathBuf;

use motionlink_gateway::{GatewayError, Options};

use crate::common::CliError;

/// `motionlink gateway` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The gateway's file: a [gateway] table (name, broker, sample_hz, ca_file, username, password_file) and
    /// the [device.NAME] tables of devices.toml (port = "sim" serves an emulator).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// The broker, mqtt://HOST:PORT or mqtts://HOST:PORT, instead of the file's.
    #[arg(long, value_name = "URL")]
    pub broker: Option<String>,
    /// The gateway's name (its topic level, motionlink/NAME/...), instead of the file's (default: the host
    /// name).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Accept a broker off this machine without TLS (commands and states then cross the network in the
    /// clear).
    #[arg(long)]
    pub insecure_broker: bool,
}

/// Serves until SIGINT or SIGTERM (every motion stopped first; exit 130 or 143).
pub fn run(args: Args) -> Result<(), CliError> {
    let options =
        Options { config: args.config, broker: args.broker, name: args.name, insecure_broker: args.insecure_broker };
    match motionlink_gateway::main(&options) {
        Ok(0) => Ok(()),
        // Ended by a signal after its motions were stopped and `offline` published (said on stderr).
        Ok(code) => std::process::exit(i32::from(code)),
        Err(GatewayError::Usage(m)) => Err(CliError::usage(m)),
        Err(GatewayError::Transport(m)) => Err(CliError::transport(m)),
    }
}
