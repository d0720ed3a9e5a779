//! The port lock of this process ([`motionlink_link::portlock`]): taken before a command opens its port, held
//! until the very end of the process (after the port was closed), when a `stop` that asked this command to
//! end learns how it ended.

use std::sync::Mutex;

use motionlink_link::portlock::{self, PortLock, StopRequest, Stopped};

use crate::common::{self, CliError};

/// The lock this process holds, released by [`release`] at the very end.
static HELD: Mutex<Option<PortLock>> = Mutex::new(None);

fn held() -> std::sync::MutexGuard<'static, Option<PortLock>> {
    HELD.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// This command's line after `motionlink`, without `--port PORT`: how a holder is named to others.
fn command_line() -> String {
    let mut words = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--port" {
            args.next();
        } else if !a.starts_with("--port=") {
            words.push(a);
        }
    }
    words.join(" ")
}

/// Takes the lock of `port` for a command of `family` before it opens the port: a port another motionlink
/// holds is a transport error (exit 3) naming that process and the `stop` that stops its motion.
pub fn claim(family: &str, port: &str) -> Result<(), CliError> {
    *held() = portlock::claim(family, port, &command_line()).map_err(|e| common::classified(&e))?;
    Ok(())
}

/// Takes the lock of `port` for a family command: for `stop` (`stop` true) from its holder as
/// [`claim_for_stop`] does (returning that holder), else as [`claim`] does.
pub fn claim_as(family: &str, port: &str, stop: bool) -> Result<Option<Stopped>, CliError> {
    match stop {
        true => claim_for_stop(family, port),
        false => claim(family, port).map(|()| None),
    }
}

/// Takes the lock of `port` for `stop`, from the motionlink that holds it if one does (asked to stop its
/// motion first); returns that holder and what it said.
pub fn claim_for_stop(family: &str, port: &str) -> Result<Option<Stopped>, CliError> {
    let (lock, stopped) = portlock::claim_for_stop(family, port, &command_line(), |m| common::say(m))
        .map_err(|e| common::classified(&e))?;
    *held() = lock;
    Ok(stopped)
}

/// The request to stop addressed to this process, if a `stop` sent one (for the note its SIGINT prints).
pub fn stop_request() -> Option<StopRequest> {
    held().as_ref().and_then(PortLock::stop_request)
}

/// Lets go of the port this process holds, if any, at the very end: a `stop` that asked this process to stop
/// learns `exit_code` and `message` first.
pub fn release(exit_code: u8, message: &str) {
    if let Some(lock) = held().take() {
        lock.release(&command_line(), exit_code, message);
    }
}
