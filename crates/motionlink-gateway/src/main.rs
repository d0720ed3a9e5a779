//! `motionlink-gateway`: the fleet gateway alone, the same as `motionlink gateway`.

use std::process::ExitCode;

/// The gateway's command line.
#[derive(clap::Parser, Debug)]
#[command(name = "motionlink-gateway", about = "Serve the devices of this machine on an MQTT broker")]
struct Cli {
    #[command(flatten)]
    args: motionlink_gateway::cli::Args,
    /// Notices and the final error on stderr as JSON lines (`{"log": ...}`; the error as
    /// `{"exit_code", "kind", "message"}`), as `motionlink --json gateway` writes them.
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    let cli = <Cli as clap::Parser>::parse();
    motionlink_gateway::notice::set_json(cli.json);
    match motionlink_gateway::main(&cli.args.options()) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            let line = if cli.json {
                serde_json::to_string(&e.report()).unwrap_or_else(|_| e.to_string())
            } else {
                format!("motionlink gateway: {e}")
            };
            motionlink_gateway::notice::write_stderr(&line);
            ExitCode::from(e.exit_code())
        }
    }
}
