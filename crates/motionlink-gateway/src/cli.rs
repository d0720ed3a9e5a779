//! The command line of the gateway: `motionlink gateway` and the `motionlink-gateway` binary take it.

use std::path::PathBuf;

use crate::config::Options;

/// `motionlink gateway` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The gateway's file: a [gateway] table (name, broker, sample_hz, ca_file, username, password_file) and
    /// the [device.NAME] tables of devices.toml (port = "sim" serves an emulator).
    #[allow(rustdoc::broken_intra_doc_links)] // the text is the help of `--config`: [gateway] is a TOML table
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

impl Args {
    /// The options of [`crate::main`].
    pub fn options(&self) -> Options {
        Options {
            config: self.config.clone(),
            broker: self.broker.clone(),
            name: self.name.clone(),
            insecure_broker: self.insecure_broker,
        }
    }
}
