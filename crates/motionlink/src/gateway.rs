//! `motionlink gateway`: the devices of this machine on an MQTT broker (the `motionlink-gateway` crate does
//! the work and owns the arguments; docs/fleet.md describes the topics).

use motionlink_gateway::GatewayError;

use crate::common::CliError;

pub use motionlink_gateway::cli::Args;

/// Serves until SIGINT, SIGTERM, SIGHUP, SIGQUIT or SIGTSTP (every motion stopped first; exit 128 + the signal's
/// number).
pub fn run(args: Args) -> Result<(), CliError> {
    // With `--json`, the gateway's notices are JSON lines too, as every command's logs.
    motionlink_gateway::notice::set_json(crate::term::output().json);
    match motionlink_gateway::main(&args.options()) {
        Ok(0) => Ok(()),
        // Ended by a signal after its motions were stopped and `offline` published (said on stderr).
        Ok(code) => {
            crate::term::flush_stderr(std::time::Duration::from_secs(2));
            std::process::exit(i32::from(code))
        }
        Err(GatewayError::Usage(m)) => Err(CliError::usage(m)),
        Err(GatewayError::Transport(m)) => Err(CliError::transport(m)),
    }
}

#[cfg(test)]
mod tests {
    /// A gateway's `[device.NAME]` table takes exactly the keys the command line takes from the same table
    /// of devices.toml: every option of `motionlink FAMILY`, of its actions and of `motionlink console
    /// FAMILY` (clap's declarations), but those never taken from a file (and `port`, which every table has).
    #[test]
    fn a_gateway_device_table_takes_the_keys_of_devices_toml() {
        let cli = <crate::Cli as clap::CommandFactory>::command();
        for family in ["scu", "powercube", "compax"] {
            let mut from_the_cli = crate::devices::family_keys(&cli, family);
            from_the_cli.retain(|k| k != "port");
            let keys = motionlink_gateway::device::keys::of(family).expect("a family");
            assert_eq!(keys.all(family), from_the_cli, "{family}");
        }
    }
}
