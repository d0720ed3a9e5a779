//! The command line end to end: the built binary against the emulators, one test binary for all of it
//! (one link instead of one per file).

mod common;

mod compax_cli;
mod console;
mod devices_cli;
mod general_cli;
mod messages_cli;
mod port_sim_cli;
mod powercube_cli;
mod probe_cli;
mod scu_cli;
mod shared_cli;
mod sim_server;
#[cfg(unix)]
mod stop_cli;
