//! `motionlink console <family> --port PORT`: a commissioning page in the browser, served by this binary on
//! 127.0.0.1, over the family's `AsyncClient`.
//!
//! - [`server`]: the HTTP routes (the page and its assets, embedded; the capture download; the WebSocket),
//!   the token and the Origin check.
//! - [`hub`]: the rules that hold whatever a page does: one page controls, a jog needs its page's renewals
//!   (dead-man), a page that goes away or the end of the console stops the motion it started.
//! - [`device`]: what the console asks of a family; [`scu`], [`powercube`], [`compax`] answer it.
//! - [`traffic`]: the decoded traffic log and the capture download.

use std::io::Write;
use std::net::SocketAddr;
use std::sync::Arc;

use motionlink_link::clock::RealClock;

use crate::common::{self, CliError};

mod compax;
pub mod device;
pub mod hub;
pub mod message;
mod powercube;
mod scu;
mod server;
mod token;
pub mod traffic;

/// `motionlink console` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The family of the device.
    #[command(subcommand)]
    pub family: Family,
}

/// Which family the console drives.
#[derive(clap::Subcommand, Debug)]
pub enum Family {
    /// An Ewellix / Schaeffler SCU control unit (its connected actuators).
    Scu(scu::Args),
    /// Schunk / Amtec PowerCube modules (found by a scan of addresses 1..31).
    Powercube(powercube::Args),
    /// Parker COMPAX drives (found by a scan of addresses 1..31).
    Compax(compax::Args),
}

/// `--device NAME`: a device of the configuration file, whose port and options the console takes.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct DeviceArg {
    /// A device named in the configuration file (devices.toml in the platform's configuration directory, or
    /// the file MOTIONLINK_CONFIG names), instead of --port: its port, and its options where the command line
    /// gives none. Without either, MOTIONLINK_PORT is the port.
    #[arg(long, value_name = "NAME")]
    pub device: Option<String>,
}

/// Where the console serves.
#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// The address the page is served on, such as 127.0.0.1:8080 (port 0: any free port).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:0")]
    pub listen: String,
    /// Allow a --listen address that is not loopback: anyone who can reach it and has the token can move
    /// the axes, and the token travels unencrypted (plain HTTP).
    #[arg(long)]
    pub listen_any: bool,
}

/// The address to serve on, checked: a non-loopback address needs `--listen-any`.
fn listen_address(args: &ServeArgs) -> Result<SocketAddr, CliError> {
    let addr: SocketAddr = args.listen.parse().map_err(|e| {
        CliError::usage(format!("--listen {:?}: give an IP address and port such as 127.0.0.1:8080 ({e})", args.listen))
    })?;
    if !addr.ip().is_loopback() {
        if !args.listen_any {
            return Err(CliError::usage(format!(
                "--listen {addr}: not a loopback address; anyone who can reach it could move the axes. Add \
                 --listen-any to mean it"
            )));
        }
        common::say(format!(
            "motionlink console: warning: serving on {addr}, reachable from other machines: whoever has the \
             token can move the axes, and the token and all traffic travel unencrypted (plain HTTP)"
        ));
    }
    Ok(addr)
}

/// The `Host` values a request may carry: the loopback names of the port, or any when serving on every
/// interface or on another address.
fn allowed_hosts(local: SocketAddr) -> Option<Vec<String>> {
    if !local.ip().is_loopback() {
        return None;
    }
    let port = local.port();
    let mut hosts = vec![local.to_string(), format!("localhost:{port}")];
    if local.is_ipv4() {
        hosts.push(format!("127.0.0.1:{port}"));
    } else {
        hosts.push(format!("[::1]:{port}"));
    }
    Some(hosts)
}

use crate::probe::profiles;

/// Says on stderr what the session made of its device's profile: the one taken, the ones not taken and why,
/// or why none could be looked up (the session then probes as without it).
fn note_profile<E: std::fmt::Display>(used: Result<motionlink_link::profile::ProfileUse, E>) {
    match used {
        Ok(used) => {
            for n in used.notices.iter().chain(used.reference.iter()) {
                crate::term::note(&format!("profile: {n}"));
            }
        }
        Err(e) => crate::term::note(&format!("device profile not used: {e}")),
    }
}

/// `motionlink console ...`
pub fn run(args: Args) -> Result<(), CliError> {
    let serve = match &args.family {
        Family::Scu(a) => &a.serve,
        Family::Powercube(a) => &a.serve,
        Family::Compax(a) => &a.serve,
    };
    let addr = listen_address(serve)?;
    // Installed before the port opens: a signal from here on ends the console, stopping what it started.
    let interrupt = common::interrupt_token();
    // Found by another motionlink as the holder of the port: its `stop` ends the console (SIGINT).
    let (family, port) = match &args.family {
        Family::Scu(a) => ("scu", port_of("scu", &a.port, &a.device)?),
        Family::Powercube(a) => ("powercube", port_of("powercube", &a.port, &a.device)?),
        Family::Compax(a) => ("compax", port_of("compax", &a.port, &a.device)?),
    };
    crate::portlock::claim(&format!("console {family}"), &port)?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| CliError::transport(format!("cannot start the console's runtime: {e}")))?;
    let result = runtime.block_on(async move {
        let clock = RealClock::shared();
        let (device, traffic) = match &args.family {
            Family::Scu(a) => scu::open(a, &port, &clock).await?,
            Family::Powercube(a) => powercube::open(a, &port, &clock).await?,
            Family::Compax(a) => compax::open(a, &port, &clock).await?,
        };
        serve_until_interrupted(device, traffic, addr, &interrupt, &clock, crate::term::json()).await
    });
    // What is left on the blocking pool (a close that outlived the console) gets a bounded wait.
    runtime.shutdown_timeout(std::time::Duration::from_secs(6));
    result
}

/// The console's port: `--port`, else the one of `--device`, else MOTIONLINK_PORT.
fn port_of(family: &str, port: &Option<String>, device: &DeviceArg) -> Result<String, CliError> {
    motionlink_link::devices::resolve(family, port.as_deref(), device.device.as_deref())
        .map_err(|e| common::classified(&e))
}

/// Waits on a thread for the interrupt token, then completes.
fn interrupted(
    token: &motionlink_link::cancel::CancelToken,
    clock: &motionlink_link::SharedClock,
) -> tokio::sync::oneshot::Receiver<()> {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let signal = clock.signal();
    token.watch(&signal);
    let token = token.clone();
    let spawned = std::thread::Builder::new().name("console-interrupt".into()).spawn(move || {
        while !token.is_cancelled() {
            signal.wait_until(None);
        }
        let _ = tx.send(());
    });
    if let Err(e) = spawned {
        tracing::warn!("cannot start the interrupt watcher: {e}");
    }
    rx
}

async fn serve_until_interrupted(
    device: Arc<dyn device::Device>,
    traffic: Arc<traffic::Traffic>,
    addr: SocketAddr,
    interrupt: &motionlink_link::cancel::CancelToken,
    clock: &motionlink_link::SharedClock,
    json: bool,
) -> Result<(), CliError> {
    let hub = hub::Hub::new(Arc::clone(&device), traffic);
    drop(device);
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|e| CliError::transport(format!("cannot listen on {addr}: {e}")))?;
    let local = listener.local_addr().map_err(|e| CliError::transport(format!("cannot listen on {addr}: {e}")))?;
    let token = token::new_token();
    let app = Arc::new(server::App { hub: Arc::clone(&hub), token: token.clone(), hosts: allowed_hosts(local) });
    let router = axum::Router::new().fallback(server::handle).with_state(app);
    hub.start();
    let mut stdout = std::io::stdout().lock();
    // Bound to every address (0.0.0.0, [::]), the address to open is this machine's, by its host name.
    let shown = match motionlink_gateway::config::host_name() {
        Some(host) if local.ip().is_unspecified() => format!("{host}:{}", local.port()),
        _ => local.to_string(),
    };
    let url = format!("http://{shown}/?token={token}");
    if json {
        common::print_json(&mut stdout, &common::Keyed("console", &url))?;
    } else {
        writeln!(stdout, "console on {url}")?;
    }
    stdout.flush()?;
    drop(stdout);
    let ended = interrupted(interrupt, clock);
    let mut shutdown = hub.shutdown_signal();
    let server = tokio::spawn(async move {
        axum::serve(listener, router)
            .with_graceful_shutdown(async move {
                let _ = shutdown.wait_for(|down| *down).await;
            })
            .await
    });
    // Until interrupted; or until a busy `motionlink sim` refuses the first connection (the scans would fail
    // for ever): nothing was started, and the console ends with that one line (exit code 3).
    let refused = tokio::select! {
        _ = ended => false,
        _ = crate::tap::refused_as_busy_notice() => true,
    };
    // The motion under way stops first (its future dropped, the stop confirmed), then the session's.
    let stopped = hub.shutdown().await;
    match &stopped {
        Ok(msg) if !msg.is_empty() => common::say(format!("motionlink console: {msg}")),
        Ok(_) => {}
        // Said also with -q: what was moving may still be moving.
        Err(e) => common::say_error(format!("motionlink console: the stop at the end is not confirmed: {e}")),
    }
    let _ = server.await;
    let device = Arc::clone(hub.device());
    drop(hub);
    let closed = device.close().await;
    match closed {
        Ok(msg) if !msg.is_empty() => common::say(format!("motionlink console: {msg}")),
        Ok(_) => {}
        Err(e) if !refused => {
            let message = e.to_string();
            let closing = match message.starts_with("closing the session") {
                true => CliError::transport(message),
                false => CliError::transport(format!("closing the session: {message}")),
            };
            return Err(match e.stop_unconfirmed || stopped.is_err() {
                true => closing.stop_not_confirmed(),
                false => closing,
            });
        }
        Err(_) => {}
    }
    if refused {
        // Made the one busy line by `main` (tap::refused_as_busy).
        return Err(CliError::transport("the port is busy"));
    }
    // (A stop at the end that was not confirmed, followed by a clean close: the close stopped what the session
    // started, confirmed, as every family's close does.)
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_non_loopback_address_needs_listen_any() {
        let args = |listen: &str, any: bool| ServeArgs { listen: listen.into(), listen_any: any };
        assert!(listen_address(&args("127.0.0.1:0", false)).is_ok());
        assert!(listen_address(&args("[::1]:0", false)).is_ok());
        let e = listen_address(&args("0.0.0.0:0", false)).unwrap_err();
        assert!(matches!(&e, CliError::Usage(m) if m.contains("--listen-any")), "{e}");
        assert!(listen_address(&args("0.0.0.0:0", true)).is_ok());
        assert!(matches!(listen_address(&args("localhost", false)), Err(CliError::Usage(_))));
    }

    #[test]
    fn hosts_of_a_loopback_address() {
        let hosts = allowed_hosts("127.0.0.1:8080".parse().unwrap()).unwrap();
        assert!(hosts.contains(&"localhost:8080".to_string()) && hosts.contains(&"127.0.0.1:8080".to_string()));
        assert_eq!(allowed_hosts("0.0.0.0:8080".parse().unwrap()), None);
    }
}
