//! Who holds a port, and a stop from another terminal.
//!
//! A serial port is opened exclusively, and a `motionlink sim` server or a ser2net port serves one client at
//! a time: while one command uses a port, another cannot. So that the other one can say who holds it, and so
//! that `motionlink FAMILY --port PORT stop` can stop the motion it runs, a command that opens such a port
//! (a serial device, `tcp://`, `slcan://`; not `sim`, not `socketcan://`, which many may share) first makes
//! a lock file: `$XDG_RUNTIME_DIR/motionlink/` (else `motionlink-UID` in the system's temporary directory),
//! named from the port (the path or address with every other character as `_`, and a hash of the whole),
//! holding JSON `{pid, port, family, command}`. The command holds an `flock` on it as long as it runs and
//! removes it when it ends; the kernel drops the `flock` when the process dies in any way, so a file whose
//! lock nobody holds (its pid dead, or reused) is stale and is taken over.
//!
//! `stop` on a port held by another motionlink writes `NAME.stop` (its own pid and command), sends the
//! holder SIGINT, which every motionlink command answers as it answers Ctrl-C (it stops what it started,
//! confirms it, and exits 130; an older motionlink without lock files does the same), and waits (at most
//! [`HANDOVER_TIMEOUT`]) until the port is free: the holder, seeing the request addressed to it, writes what
//! it ended with into `NAME.outcome` before it lets go of the lock. Then `stop` opens the port itself, stops
//! on the device what still moves and reads back that nothing does. SIGINT rather than a signal of its own
//! (SIGUSR1): the holder's stop is then the one path every signal already takes and the tests cover, its
//! exit code the contract's 128 + 2 on every Unix (SIGUSR1 is 10 on Linux, 30 on macOS), and a holder that
//! cannot read the request still stops as on Ctrl-C (SIGUSR1's default action would kill it without a stop).
//! The pid is signalled only while the lock is held (so the process that wrote it is alive) and, on Linux,
//! only if `/proc/PID/comm` says motionlink.

mod os;
#[cfg(test)]
mod tests;

use std::fs::File;
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::error::{Classify, ErrorClass, TransportKind};
use crate::url::PortUrl;

/// Why a port's lock could not be taken: another process holds the port, or a `stop` could not take it
/// from its holder. A transport error of the I/O kind (exit code 3 on the command line).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct PortLockError(pub String);

impl Classify for PortLockError {
    fn class(&self) -> ErrorClass {
        ErrorClass::Transport(TransportKind::Io)
    }
}

/// How long `stop` waits for the holder of a port to stop its motion and let go of the port after its
/// SIGINT: above the libraries' bound on a close (5 s) with room for the process to end.
pub const HANDOVER_TIMEOUT: Duration = Duration::from_secs(15);

/// The process that holds a port, as its lock file names it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    /// Its process id.
    pub pid: u32,
    /// The port, as it was given.
    pub port: String,
    /// `scu`, `powercube`, `compax`, or `console scu` ...
    pub family: String,
    /// Its command line after `motionlink`, without `--port`.
    pub command: String,
}

/// What a holder that was asked to stop ended with (`NAME.outcome`, written before it let go of the port).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Outcome {
    /// Its process id.
    pub pid: u32,
    /// Its command line after `motionlink`, without `--port`.
    pub command: String,
    /// Its exit code (130 after the SIGINT).
    pub exit_code: u8,
    /// Its last message: what it stopped and whether the device confirmed it (empty if it had none).
    pub message: String,
    /// The pid of the `stop` that asked.
    pub requested_by: u32,
}

/// A request to stop (`NAME.stop`), written by `stop` before its SIGINT.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StopRequest {
    /// The holder it is for.
    pub holder_pid: u32,
    /// The `stop` command's pid.
    pub pid: u32,
    /// The `stop` command's command line after `motionlink`, without `--port`.
    pub command: String,
}

/// What `stop` found holding the port, and what that holder said when it ended. In JSON (a stop's
/// `holder`): `pid`, `port`, `family`, `command`, and `outcome` (`exit_code`, `message`, ...) or `null`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Stopped {
    /// The holder.
    #[serde(flatten)]
    pub holder: Holder,
    /// Its outcome, if it wrote one.
    pub outcome: Option<Outcome>,
}

impl Stopped {
    /// One line: who was stopped and what it said.
    pub fn describe(&self) -> String {
        let who = format!("motionlink pid {} ({})", self.holder.pid, self.holder.command);
        match &self.outcome {
            Some(o) if o.message.is_empty() => format!("stopped {who}: it ended with exit code {}", o.exit_code),
            Some(o) => format!("stopped {who}: it ended with exit code {}: {}", o.exit_code, o.message),
            None => format!(
                "{who} was sent SIGINT and let go of the port without saying what it stopped (it may have ended on \
                 its own); what this command read from the device follows"
            ),
        }
    }
}

/// The identity of the lock file of `port`: the canonical device path of a serial port (and of an SLCAN
/// adapter's), `tcp://host:port` with the host in lower case; `None` for the ports that are not exclusive
/// (`sim`, `socketcan://`).
pub fn lock_key(port: &PortUrl) -> Option<String> {
    let device =
        |path: &str| std::fs::canonicalize(path).map(|p| p.display().to_string()).unwrap_or_else(|_| path.to_string());
    match port {
        PortUrl::Serial(path) => Some(device(path)),
        PortUrl::Tcp { host, port } => Some(format!("tcp://{}:{port}", host.to_ascii_lowercase())),
        PortUrl::Slcan(inner) => match inner.parse::<PortUrl>() {
            Ok(tcp @ PortUrl::Tcp { .. }) => lock_key(&tcp),
            _ => Some(device(inner)),
        },
        PortUrl::Sim | PortUrl::SocketCan(_) => None,
    }
}

/// The name (without extension) of the lock file of `key`: the key with every character but ASCII letters,
/// digits, `.` and `-` as `_` (runs of them as one, at most 64 characters), then `-` and a 64-bit FNV-1a hash
/// of the whole key in hex, so that two keys that read the same once sanitised still differ.
pub fn file_stem(key: &str) -> String {
    let mut readable = String::new();
    for c in key.chars() {
        let c = if c.is_ascii_alphanumeric() || c == '.' || c == '-' { c } else { '_' };
        if !(c == '_' && readable.ends_with('_')) {
            readable.push(c);
        }
    }
    let readable: String = readable.trim_matches('_').chars().take(64).collect();
    let hash = key.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    format!("{readable}-{hash:016x}")
}

/// The directory of the lock files: `$XDG_RUNTIME_DIR/motionlink` where that is set (an absolute path),
/// else `motionlink-UID` in the system's temporary directory.
pub fn runtime_dir() -> PathBuf {
    match std::env::var_os("XDG_RUNTIME_DIR").map(PathBuf::from) {
        Some(dir) if dir.is_absolute() => dir.join("motionlink"),
        _ => std::env::temp_dir().join(format!("motionlink-{}", os::uid())),
    }
}

/// The lock files of one directory.
#[derive(Debug, Clone)]
pub struct LockDir {
    dir: PathBuf,
}

/// What trying to take a port's lock found.
#[derive(Debug)]
pub enum Acquired {
    /// This process holds the port now; `stale` names the holder of a lock file left behind, if any.
    Locked {
        /// The lock, released when dropped.
        lock: PortLock,
        /// Who the file named before (a process that ended without removing it).
        stale: Option<Holder>,
    },
    /// Another process holds it (`None`: its lock file names nobody readable).
    Held(Option<Holder>),
}

impl LockDir {
    /// The lock files in `dir`.
    pub fn new(dir: impl Into<PathBuf>) -> LockDir {
        LockDir { dir: dir.into() }
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    fn file(&self, key: &str, extension: &str) -> PathBuf {
        self.dir.join(format!("{}.{extension}", file_stem(key)))
    }

    /// The lock file of `key`.
    pub fn lock_path(&self, key: &str) -> PathBuf {
        self.file(key, "lock")
    }

    /// Takes the lock of `key` for `holder`, or says who holds it.
    pub fn acquire(&self, key: &str, holder: &Holder) -> std::io::Result<Acquired> {
        os::private_dir(&self.dir)?;
        let path = self.lock_path(key);
        loop {
            let mut file = os::open(&path)?;
            if os::try_lock(&file)? == os::Try::Held {
                return Ok(Acquired::Held(read_holder(&mut file)));
            }
            // The holder before may have removed the file between our open and our lock: then the lock is on
            // a file nobody else will look at; start again on the one the path names now.
            if !os::same_file(&file, &path) {
                continue;
            }
            let stale = read_json::<Holder>(&mut file);
            file.set_len(0)?;
            file.rewind()?;
            file.write_all(serde_json::to_string(holder).map_err(std::io::Error::other)?.as_bytes())?;
            file.flush()?;
            let lock = PortLock {
                path,
                stop_path: self.file(key, "stop"),
                outcome_path: self.file(key, "outcome"),
                pid: holder.pid,
                _file: file,
            };
            return Ok(Acquired::Locked { lock, stale });
        }
    }

    /// Writes the request to stop that `stop` (pid `pid`, `command`) sends the holder of `key`.
    pub fn request_stop(&self, key: &str, request: &StopRequest) -> std::io::Result<()> {
        write_atomically(&self.file(key, "stop"), request)
    }

    /// Takes (reads and removes) the outcome the holder `pid` of `key` wrote, if it wrote one; a request to
    /// stop left behind is removed too.
    pub fn take_outcome(&self, key: &str, pid: u32) -> Option<Outcome> {
        let _ = std::fs::remove_file(self.file(key, "stop"));
        let path = self.file(key, "outcome");
        let outcome = std::fs::File::open(&path).ok().and_then(|mut f| read_json::<Outcome>(&mut f));
        let _ = std::fs::remove_file(&path);
        outcome.filter(|o| o.pid == pid)
    }
}

/// Reads the holder a lock file names; the holder may be between taking the lock and writing its name, so
/// an empty file is read again for a little while.
fn read_holder(file: &mut File) -> Option<Holder> {
    let deadline = Instant::now() + Duration::from_millis(200);
    loop {
        if let Some(h) = read_json(file) {
            return Some(h);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn read_json<T: serde::de::DeserializeOwned>(file: &mut File) -> Option<T> {
    let mut text = String::new();
    file.rewind().ok()?;
    file.read_to_string(&mut text).ok()?;
    serde_json::from_str(&text).ok()
}

/// Writes `value` as JSON to `path` through a file beside it, renamed: a reader sees all of it or nothing.
fn write_atomically<T: Serialize>(path: &Path, value: &T) -> std::io::Result<()> {
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, serde_json::to_string(value).map_err(std::io::Error::other)?)?;
    std::fs::rename(&tmp, path)
}

/// A port's lock, held by this process; dropping it removes the lock file (then closes it, which lets go of
/// the `flock`).
#[derive(Debug)]
pub struct PortLock {
    path: PathBuf,
    stop_path: PathBuf,
    outcome_path: PathBuf,
    pid: u32,
    _file: File,
}

impl PortLock {
    /// The request to stop addressed to this holder, if `stop` wrote one.
    pub fn stop_request(&self) -> Option<StopRequest> {
        let mut f = File::open(&self.stop_path).ok()?;
        read_json::<StopRequest>(&mut f).filter(|r| r.holder_pid == self.pid)
    }

    /// Lets go of the port; if a `stop` asked this holder to stop, first tells it how the command ended.
    pub fn release(self, command: &str, exit_code: u8, message: &str) {
        if let Some(request) = self.stop_request() {
            let outcome = Outcome {
                pid: self.pid,
                command: command.to_string(),
                exit_code,
                message: message.to_string(),
                requested_by: request.pid,
            };
            if let Err(e) = write_atomically(&self.outcome_path, &outcome) {
                tracing::warn!("cannot tell the stop (pid {}) how this command ended: {e}", request.pid);
            }
        }
    }
}

impl Drop for PortLock {
    fn drop(&mut self) {
        if let Err(e) = std::fs::remove_file(&self.path) {
            tracing::warn!("cannot remove the lock file {}: {e}", self.path.display());
        }
    }
}

/// The lock of `port` for a process's command of `family` (`scu`, ..., `console scu`), or who holds it.
/// `Ok(None)` for a port that needs none, where lock files cannot be made (not Unix; a runtime directory
/// that is not private: said in a warning), or a port that does not parse (the connection says why).
fn take(family: &str, port: &str, command: &str) -> Result<Option<(LockDir, String, Acquired)>, PortLockError> {
    if !os::SUPPORTED {
        return Ok(None);
    }
    let Some(key) = port.parse::<PortUrl>().ok().as_ref().and_then(lock_key) else { return Ok(None) };
    let dir = LockDir::new(runtime_dir());
    let me = Holder { pid: std::process::id(), port: port.to_string(), family: family.into(), command: command.into() };
    match dir.acquire(&key, &me) {
        Ok(acquired) => Ok(Some((dir, key, acquired))),
        Err(e) => {
            tracing::warn!(
                "no lock file for {port} in {} ({e}): another motionlink cannot see that this one uses it",
                dir.path().display()
            );
            Ok(None)
        }
    }
}

/// `lock`, kept; says so if it replaced a stale one.
fn keep(lock: PortLock, stale: Option<Holder>) -> Option<PortLock> {
    if let Some(s) = stale {
        tracing::info!("replaced the lock file left by pid {} ({}), which no longer holds it", s.pid, s.command);
    }
    Some(lock)
}

/// The family whose `stop` a holder answers: `scu` for `scu` and for a console's `console scu`.
fn stop_family(holder: &Holder) -> &str {
    holder.family.rsplit(' ').next().unwrap_or(&holder.family)
}

/// The error of a command that finds `port` held by another process.
fn in_use(port: &str, holder: Option<&Holder>) -> PortLockError {
    PortLockError(match holder {
        Some(h) => format!(
            "{port} is in use by motionlink pid {} ({}); `motionlink {} --port {port} stop` stops its motion",
            h.pid,
            h.command,
            stop_family(h)
        ),
        None => format!("{port} is in use by another motionlink process (its lock file names none)"),
    })
}

/// Takes the lock of `port` for this process's `command` (its command line, as a holder names it) of
/// `family` before it opens the port: a port another motionlink holds is an error naming that process and
/// the `stop` that stops its motion. The lock is held until the [`PortLock`] is dropped (`None`: the port
/// needs none).
pub fn claim(family: &str, port: &str, command: &str) -> Result<Option<PortLock>, PortLockError> {
    match take(family, port, command)? {
        None => Ok(None),
        Some((_, _, Acquired::Locked { lock, stale })) => Ok(keep(lock, stale)),
        Some((_, _, Acquired::Held(holder))) => Err(in_use(port, holder.as_ref())),
    }
}

/// Takes the lock of `port` for `stop`: a port another motionlink holds is taken from it: that process is
/// asked to stop its motion (SIGINT, after `NAME.stop` names this command), `notify` is told so, and the port
/// is taken once it let go (at most [`HANDOVER_TIMEOUT`]). Returns the lock and the holder that was stopped
/// with what it said, if any.
pub fn claim_for_stop(
    family: &str,
    port: &str,
    command: &str,
    notify: impl FnOnce(&str),
) -> Result<(Option<PortLock>, Option<Stopped>), PortLockError> {
    let Some((dir, key, first)) = take(family, port, command)? else { return Ok((None, None)) };
    let holder = match first {
        Acquired::Locked { lock, stale } => return Ok((keep(lock, stale), None)),
        Acquired::Held(None) => return Err(in_use(port, None)),
        Acquired::Held(Some(h)) => h,
    };
    if !os::alive(holder.pid) {
        return Err(PortLockError(format!(
            "{port} is held, but the pid its lock file names ({}, {}) no longer runs: not signalled",
            holder.pid, holder.command
        )));
    }
    if os::is_motionlink(holder.pid) == Some(false) {
        return Err(PortLockError(format!(
            "{port} is held by pid {}, which its lock file names as motionlink ({}) but which runs another \
             program now: not signalled",
            holder.pid, holder.command
        )));
    }
    let request = StopRequest { holder_pid: holder.pid, pid: std::process::id(), command: command.into() };
    dir.request_stop(&key, &request)
        .map_err(|e| PortLockError(format!("cannot ask motionlink pid {} to stop: {e}", holder.pid)))?;
    os::interrupt(holder.pid).map_err(|e| {
        PortLockError(format!("cannot send SIGINT to motionlink pid {} ({}): {e}", holder.pid, holder.command))
    })?;
    notify(&format!(
        "motionlink: {port} is held by motionlink pid {} ({}): asked it to stop its motion (SIGINT)",
        holder.pid, holder.command
    ));
    let me = Holder { pid: std::process::id(), port: port.to_string(), family: family.into(), command: command.into() };
    let deadline = Instant::now() + HANDOVER_TIMEOUT;
    loop {
        match dir.acquire(&key, &me) {
            Ok(Acquired::Locked { lock, stale }) => {
                let outcome = dir.take_outcome(&key, holder.pid);
                return Ok((keep(lock, stale), Some(Stopped { holder, outcome })));
            }
            Ok(Acquired::Held(_)) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
            Ok(Acquired::Held(now)) => {
                let still = now.map_or("a process".to_string(), |h| format!("pid {} ({})", h.pid, h.command));
                return Err(PortLockError(format!(
                    "motionlink pid {} ({}) was sent SIGINT but {port} is still held by {still} {} s later: its \
                     motion may still be running",
                    holder.pid,
                    holder.command,
                    HANDOVER_TIMEOUT.as_secs()
                )));
            }
            Err(e) => return Err(PortLockError(format!("the lock file of {port}: {e}"))),
        }
    }
}
