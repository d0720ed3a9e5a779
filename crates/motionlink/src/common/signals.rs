//! Why a command stops before its action ends: SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGTSTP and a closed
//! stdout, and the one token they cancel.

#[cfg(not(unix))]
use std::sync::Arc;
use std::sync::{Mutex, OnceLock};

use motionlink_link::cancel::CancelToken;

use super::say;

/// SIGINT's number, the cause assumed when a cancellation has no recorded cause.
pub(super) const SIGINT: i32 = 2;

/// Why a command was asked to stop before its action ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopCause {
    /// A signal: SIGINT (Ctrl-C), SIGTERM (`kill`), SIGHUP (the terminal or SSH session went away), SIGQUIT
    /// (Ctrl-\\) or SIGTSTP (Ctrl-Z: a suspended command would leave the devices without a host, so it
    /// ends instead).
    Signal(i32),
    /// stdout was closed by its reader.
    OutputClosed,
}

impl StopCause {
    /// 128 + the signal's number; 0 for a closed stdout (`motionlink ... watch | head` ends quietly, as
    /// `seq 1000000 | head` does, once what the command started was stopped).
    pub fn exit_code(self) -> u8 {
        match self {
            StopCause::Signal(n) => u8::try_from(128 + n).unwrap_or(u8::MAX),
            StopCause::OutputClosed => 0,
        }
    }

    /// The cause as a user reads it: "SIGTERM", "stdout closed".
    pub fn name(self) -> String {
        match self {
            StopCause::Signal(n) => signal_name(n),
            StopCause::OutputClosed => "stdout closed".into(),
        }
    }
}

fn signal_name(n: i32) -> String {
    match n {
        1 => "SIGHUP".into(),
        2 => "SIGINT".into(),
        3 => "SIGQUIT".into(),
        13 => "SIGPIPE".into(),
        15 => "SIGTERM".into(),
        #[cfg(unix)]
        n if n == libc::SIGTSTP => "SIGTSTP".into(),
        n => format!("signal {n}"),
    }
}

static STOP_CAUSE: OnceLock<Mutex<Option<StopCause>>> = OnceLock::new();

/// The first reason the command was asked to stop, if any.
pub fn stop_cause() -> Option<StopCause> {
    *STOP_CAUSE.get_or_init(|| Mutex::new(None)).lock().unwrap_or_else(|e| e.into_inner())
}

/// Records why the command stops; the first cause wins.
pub(super) fn record_stop_cause(cause: StopCause) {
    if cause == StopCause::OutputClosed {
        crate::term::mark_output_closed();
    }
    let mut slot = STOP_CAUSE.get_or_init(|| Mutex::new(None)).lock().unwrap_or_else(|e| e.into_inner());
    slot.get_or_insert(cause);
}

/// The token that SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGTSTP and a closed stdout cancel; the handlers are
/// installed by the first call, which every command that may start a motion makes before it opens the port.
/// SIGTSTP (Ctrl-Z) ends the command like the others rather than suspend it: a suspended command sends
/// nothing, so a unit's watchdog would stop its drives as after a dead host, and a COMPAX drive, which has
/// none, would move on unwatched.
///
/// The first signal cancels the token (the running action stops its motion and returns; the command then
/// exits with 128 + the signal's number); a second one only says that the stop is under way (stopping the
/// motion matters more than a quick exit); a third exits at once, without waiting for the stop. A closed
/// stdout (its reader went away: `motionlink ... | head`) cancels the token as well.
pub fn interrupt_token() -> CancelToken {
    static TOKEN: OnceLock<CancelToken> = OnceLock::new();
    TOKEN
        .get_or_init(|| {
            let token = CancelToken::new();
            install_signal_handlers(token.clone());
            #[cfg(unix)]
            watch_stdout(token.clone());
            token
        })
        .clone()
}

fn on_signal(token: &CancelToken, presses: &mut u32, n: i32) {
    record_stop_cause(StopCause::Signal(n));
    *presses += 1;
    // The stop first, then what is said about it.
    if *presses < 3 {
        token.cancel();
    }
    let name = signal_name(n);
    match *presses {
        1 => match crate::portlock::stop_request() {
            Some(r) => say(format!(
                "motionlink: {name} from `motionlink {}` (pid {}), stopping what this command started",
                r.command, r.pid
            )),
            #[cfg(unix)]
            None if n == libc::SIGTSTP => say(format!(
                "motionlink: {name} (Ctrl-Z) received: this command is not suspended (suspended, it would leave \
                 the devices without a host); it stops what it started and ends"
            )),
            None => say(format!("motionlink: {name} received, stopping what this command started")),
        },
        2 => say(format!("motionlink: {name}: still stopping the motion; once more exits without waiting")),
        _ => {
            // The stop is not waited for, so it is not confirmed: exit 3 and the flag, as every error after
            // which a stop was not confirmed (printed as main's end, which this exit skips, prints an error).
            let e = super::CliError::Interrupted(format!(
                "{name} again: exited before the stop was confirmed; what this command set in motion may still \
                 be moving"
            ))
            .stop_not_confirmed();
            crate::portlock::release(e.exit_code(), &e.to_string());
            super::print_final_error(&e);
            crate::term::flush_stderr(std::time::Duration::from_millis(200));
            std::process::exit(i32::from(e.exit_code()));
        }
    }
}

#[cfg(unix)]
fn install_signal_handlers(token: CancelToken) {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGTSTP};
    match signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGTSTP]) {
        Ok(mut signals) => {
            let spawned = std::thread::Builder::new().name("signals".into()).spawn(move || {
                let mut presses = 0;
                for n in signals.forever() {
                    on_signal(&token, &mut presses, n);
                }
            });
            if let Err(e) = spawned {
                tracing::warn!("cannot start the signal thread: {e}");
            }
        }
        Err(e) => tracing::warn!("cannot install the signal handlers: {e}"),
    }
}

#[cfg(not(unix))]
fn install_signal_handlers(token: CancelToken) {
    use std::sync::atomic::{AtomicBool, Ordering};
    let raised = Arc::new(AtomicBool::new(false));
    for n in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(n, Arc::clone(&raised)) {
            tracing::warn!("cannot install the handler of signal {n}: {e}");
        }
    }
    let _ = std::thread::Builder::new().name("signals".into()).spawn(move || {
        let mut presses = 0;
        loop {
            std::thread::sleep(std::time::Duration::from_millis(20));
            if raised.swap(false, Ordering::SeqCst) {
                on_signal(&token, &mut presses, SIGINT);
            }
        }
    });
}

/// When stdout is a pipe or a socket, a thread waits (in `poll`, without a timeout) for its reader to go
/// away, and then cancels `token`: a move whose output nobody reads any more is stopped like one
/// interrupted by a signal. A terminal that goes away sends SIGHUP instead; a file never closes.
#[cfg(unix)]
fn watch_stdout(token: CancelToken) {
    // SAFETY: fstat on descriptor 1 writes only into the zeroed struct we own.
    let kind = unsafe {
        let mut st: libc::stat = std::mem::zeroed();
        if libc::fstat(1, &mut st) != 0 {
            return;
        }
        st.st_mode & libc::S_IFMT
    };
    if kind != libc::S_IFIFO && kind != libc::S_IFSOCK {
        return;
    }
    let _ = std::thread::Builder::new().name("stdout-watch".into()).spawn(move || loop {
        let mut fd = libc::pollfd { fd: 1, events: 0, revents: 0 };
        // SAFETY: one valid pollfd; POLLERR and POLLHUP are reported whatever `events` asks for.
        let n = unsafe { libc::poll(&mut fd, 1, -1) };
        if n < 0 {
            if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            return;
        }
        if fd.revents & (libc::POLLERR | libc::POLLHUP | libc::POLLNVAL) != 0 {
            record_stop_cause(StopCause::OutputClosed);
            token.cancel();
            return;
        }
    });
}
