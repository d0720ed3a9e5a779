//! `motionlink gateway`: the devices of this machine on an MQTT broker (the `motionlink-gateway` crate does
//! the work and owns the arguments; docs/fleet.md describes the topics).

use motionlink_gateway::GatewayError;

use crate::common::CliError;

pub use motionlink_gateway::cli::Args;

/// Serves until SIGINT, SIGTERM, SIGHUP or SIGQUIT (every motion stopped first; exit 128 + the signal's number).
pub fn run(args: Args) -> Result<(), CliError> {
    match motionlink_gateway::main(&args.options()) {
        Ok(0) => Ok(()),
        // Ended by a signal after its motions were stopped and `offline` published (said on stderr).
        Ok(code) => std::process::exit(i32::from(code)),
        Err(GatewayError::Usage(m)) => Err(CliError::usage(m)),
        Err(GatewayError::Transport(m)) => Err(CliError::transport(m)),
    }
}
