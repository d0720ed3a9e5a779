//! The signals that end the gateway.

use crate::error::GatewayError;

/// SIGINT, SIGTERM, SIGHUP (a closed terminal or session), SIGQUIT and SIGTSTP (Ctrl-Z): each ends the
/// gateway after it stopped every motion (none of them may kill it with a motion left running; a COMPAX drive
/// has no watchdog that would stop it). SIGTSTP ends it rather than suspend it, as it ends every motionlink
/// command: a suspended gateway watches no lease, and the motions it started would run on unwatched.
pub(super) struct Signals {
    #[cfg(unix)]
    int: tokio::signal::unix::Signal,
    #[cfg(unix)]
    term: tokio::signal::unix::Signal,
    #[cfg(unix)]
    hup: tokio::signal::unix::Signal,
    #[cfg(unix)]
    quit: tokio::signal::unix::Signal,
    #[cfg(unix)]
    tstp: tokio::signal::unix::Signal,
}

impl Signals {
    pub(super) fn new() -> Result<Signals, GatewayError> {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{signal, SignalKind};
            let fail = |e: std::io::Error| GatewayError::Transport(format!("signal handlers: {e}"));
            Ok(Signals {
                int: signal(SignalKind::interrupt()).map_err(fail)?,
                term: signal(SignalKind::terminate()).map_err(fail)?,
                hup: signal(SignalKind::hangup()).map_err(fail)?,
                quit: signal(SignalKind::quit()).map_err(fail)?,
                tstp: signal(SignalKind::from_raw(libc::SIGTSTP)).map_err(fail)?,
            })
        }
        #[cfg(not(unix))]
        Ok(Signals {})
    }

    /// The next signal: its number and name.
    pub(super) async fn next(&mut self) -> (i32, &'static str) {
        #[cfg(unix)]
        {
            tokio::select! {
                _ = self.int.recv() => (2, "SIGINT"),
                _ = self.term.recv() => (15, "SIGTERM"),
                _ = self.hup.recv() => (1, "SIGHUP"),
                _ = self.quit.recv() => (3, "SIGQUIT"),
                _ = self.tstp.recv() => (libc::SIGTSTP, "SIGTSTP"),
            }
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
            (2, "SIGINT")
        }
    }
}
