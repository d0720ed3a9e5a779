//! `motionlink-gateway`: the fleet gateway alone, the same as `motionlink gateway`.

use std::process::ExitCode;

/// The gateway's command line.
#[derive(clap::Parser, Debug)]
#[command(name = "motionlink-gateway", about = "Serve the devices of this machine on an MQTT broker")]
struct Cli {
    #[command(flatten)]
    args: motionlink_gateway::cli::Args,
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    match motionlink_gateway::main(&cli.args.options()) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("motionlink gateway: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
