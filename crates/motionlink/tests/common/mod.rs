//! What the end-to-end tests of the built binary share: the binary, a `motionlink sim` child process whose
//! device events can be waited for, and a running command that can be sent signals.
//!
//! Tests that send signals or wait for motion do so on events (a line on the command's stderr, an event of
//! the emulated device), never after a fixed sleep.

#![allow(dead_code)] // each test file uses a different part

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The built `motionlink` binary.
pub const BIN: &str = env!("CARGO_BIN_EXE_motionlink");

/// Seconds since the Unix epoch, as `motionlink sim --events` stamps its events.
pub fn unix_now() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default().as_secs_f64()
}

/// Lines read from a child's pipe, as they arrive, with a way to wait for one.
#[derive(Clone, Default)]
pub struct Lines(Arc<(Mutex<Received>, Condvar)>);

/// The lines so far, and whether the pipe has ended.
type Received = (Vec<String>, bool);

impl Lines {
    /// Reads `pipe` on a thread until it ends.
    fn follow(pipe: impl std::io::Read + Send + 'static) -> Lines {
        let lines = Lines::default();
        let filler = lines.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                let (m, cv) = &*filler.0;
                m.lock().unwrap().0.push(line);
                cv.notify_all();
            }
            let (m, cv) = &*filler.0;
            m.lock().unwrap().1 = true;
            cv.notify_all();
        });
        lines
    }

    /// Every line so far.
    pub fn all(&self) -> Vec<String> {
        self.0 .0.lock().unwrap().0.clone()
    }

    /// Every line so far, joined, for assertion messages.
    pub fn text(&self) -> String {
        self.all().join("\n")
    }

    /// Waits up to `timeout` until `n` lines (among all lines so far, from the first) satisfy `pred`;
    /// returns the `n`th.
    pub fn wait_for_nth(&self, timeout: Duration, n: usize, pred: impl Fn(&str) -> bool) -> Option<String> {
        let deadline = Instant::now() + timeout;
        let (m, cv) = &*self.0;
        let mut g = m.lock().unwrap();
        loop {
            if let Some(l) = g.0.iter().filter(|l| pred(l)).nth(n.saturating_sub(1)) {
                return Some(l.clone());
            }
            let now = Instant::now();
            if g.1 || now >= deadline {
                return None;
            }
            g = cv.wait_timeout(g, deadline - now).unwrap().0;
        }
    }

    /// Waits up to `timeout` for a line (among all lines so far, from the first) for which `pred` holds.
    pub fn wait_for(&self, timeout: Duration, pred: impl Fn(&str) -> bool) -> Option<String> {
        let deadline = Instant::now() + timeout;
        let (m, cv) = &*self.0;
        let mut g = m.lock().unwrap();
        loop {
            if let Some(l) = g.0.iter().find(|l| pred(l)) {
                return Some(l.clone());
            }
            let now = Instant::now();
            if g.1 || now >= deadline {
                return None;
            }
            g = cv.wait_timeout(g, deadline - now).unwrap().0;
        }
    }
}

/// One event of the emulated device: `event <unix time> <text>` on `motionlink sim --events`' stderr.
#[derive(Debug, Clone)]
pub struct Event {
    /// When the emulator saw it, in seconds since the Unix epoch.
    pub at: f64,
    /// What happened, as the emulator says it.
    pub text: String,
}

fn parse_event(line: &str) -> Option<Event> {
    let rest = line.strip_prefix("event ")?;
    let (at, text) = rest.split_once(' ')?;
    Some(Event { at: at.parse().ok()?, text: text.to_string() })
}

/// A running `motionlink sim FAMILY ... --events`, killed when dropped.
pub struct Sim {
    child: Child,
    /// Where it serves: `tcp://127.0.0.1:PORT` or a pty's device path.
    pub address: String,
    /// Its stderr: warnings and `event ...` lines.
    pub stderr: Lines,
}

impl Sim {
    /// Starts `motionlink sim <family> <args> --events` and waits for its one `listening on ...` line.
    pub fn start(family: &str, args: &[&str]) -> Sim {
        let mut child = Command::new(BIN)
            .args(["sim", family])
            .args(args)
            .arg("--events")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start motionlink sim");
        let stderr = Lines::follow(child.stderr.take().expect("piped stderr"));
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("piped stdout")).read_line(&mut line).expect("read its first line");
        // `listening on ADDRESS`, or with --json `{"listening": ADDRESS, ...}`.
        let from_json = serde_json::from_str::<serde_json::Value>(&line)
            .ok()
            .and_then(|v| v["listening"].as_str().map(str::to_string));
        let address = from_json
            .as_deref()
            .or_else(|| line.trim().strip_prefix("listening on pty "))
            .or_else(|| line.trim().strip_prefix("listening on "))
            .unwrap_or_else(|| panic!("unexpected first line {line:?}; stderr: {}", stderr.text()))
            .to_string();
        Sim { child, address, stderr }
    }

    /// Starts `motionlink sim <family> --tcp 127.0.0.1:0`.
    pub fn tcp(family: &str) -> Sim {
        Sim::start(family, &["--tcp", "127.0.0.1:0"])
    }

    /// The process id (to stop the emulator with SIGSTOP: a link that carries nothing any more).
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Stops the emulator process (SIGSTOP) until the guard drops (SIGCONT): its link stays up and carries
    /// nothing, as a cut cable behind a serial gateway. Returns once every thread of it has stopped: a
    /// group stop reaches the threads one by one, and a request sent at once is answered in most cases
    /// (measured: 195 of 200) by a thread the stop has not reached yet.
    #[cfg(unix)]
    pub fn freeze(&self) -> Frozen {
        // SAFETY: kill(2) on our own child.
        assert_eq!(unsafe { libc::kill(self.pid() as i32, libc::SIGSTOP) }, 0, "SIGSTOP to the emulator");
        let frozen = Frozen(self.pid());
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while !all_threads_stopped(self.pid()) {
            assert!(std::time::Instant::now() < deadline, "the emulator did not stop within 5 s of SIGSTOP");
            std::thread::sleep(Duration::from_micros(500));
        }
        frozen
    }

    /// Every device event so far.
    pub fn events(&self) -> Vec<Event> {
        self.stderr.all().iter().filter_map(|l| parse_event(l)).collect()
    }

    /// Waits up to `timeout` for a device event (from the first) whose text satisfies `pred`.
    pub fn wait_event(&self, timeout: Duration, pred: impl Fn(&str) -> bool) -> Option<Event> {
        self.stderr.wait_for(timeout, |l| parse_event(l).is_some_and(|e| pred(&e.text))).and_then(|l| parse_event(&l))
    }

    /// Waits up to `timeout` for a device event after Unix time `after` whose text satisfies `pred`.
    pub fn wait_event_after(&self, after: f64, timeout: Duration, pred: impl Fn(&str) -> bool) -> Option<Event> {
        self.stderr
            .wait_for(timeout, |l| parse_event(l).is_some_and(|e| e.at >= after && pred(&e.text)))
            .and_then(|l| parse_event(&l))
    }
}

/// True when every thread of process `pid` is stopped (state `T` in /proc/PID/task/*/stat).
#[cfg(target_os = "linux")]
fn all_threads_stopped(pid: u32) -> bool {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else { return false };
    tasks.filter_map(Result::ok).all(|t| {
        let stat = std::fs::read_to_string(t.path().join("stat")).unwrap_or_default();
        // The state follows the command name's closing parenthesis.
        let state = stat.rsplit_once(')').and_then(|(_, rest)| rest.split_whitespace().next());
        matches!(state, Some("T" | "t"))
    })
}

/// Without /proc: a stop is taken to have reached every thread after 100 ms.
#[cfg(all(unix, not(target_os = "linux")))]
fn all_threads_stopped(_pid: u32) -> bool {
    std::thread::sleep(Duration::from_millis(100));
    true
}

/// An emulator stopped by [`Sim::freeze`]; it runs again when this drops.
#[cfg(unix)]
pub struct Frozen(u32);

#[cfg(unix)]
impl Drop for Frozen {
    fn drop(&mut self) {
        // SAFETY: kill(2) on our own child.
        unsafe { libc::kill(self.0 as i32, libc::SIGCONT) };
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A `motionlink` command running in the background, its stdout and stderr followed line by line.
pub struct Running {
    child: Child,
    /// Its stdout.
    pub stdout: Lines,
    /// Its stderr (with `-v`: the log).
    pub stderr: Lines,
}

/// What a [`Running`] command ended with.
#[derive(Debug)]
pub struct Ended {
    /// Its exit status.
    pub status: ExitStatus,
    /// Everything it printed on stdout.
    pub stdout: String,
    /// Everything it printed on stderr.
    pub stderr: String,
}

impl Ended {
    /// The exit code (-1 when ended by a signal).
    pub fn code(&self) -> i32 {
        self.status.code().unwrap_or(-1)
    }

    /// The JSON object a `--json` command printed last on stderr: its error.
    pub fn json_error(&self) -> serde_json::Value {
        let line = self.stderr.lines().last().unwrap_or_else(|| panic!("no error on stderr: {self:?}"));
        serde_json::from_str(line).unwrap_or_else(|e| panic!("not a JSON object ({e}): {}", self.stderr))
    }
}

impl Running {
    /// `motionlink <args>` spawned with `stdin` and piped stdout and stderr.
    fn spawn(args: &[&str], stdin: Stdio) -> std::process::Child {
        Self::spawn_env(args, stdin, &[])
    }

    /// `motionlink <args>` spawned with `env` set (and MOTIONLINK_PORT / MOTIONLINK_CONFIG removed unless
    /// `env` sets them, when `env` is not empty), `stdin` and piped stdout and stderr.
    fn spawn_env(args: &[&str], stdin: Stdio, env: &[(&str, &str)]) -> std::process::Child {
        let mut cmd = Command::new(BIN);
        if !env.is_empty() {
            cmd.env_remove("MOTIONLINK_PORT").env_remove("MOTIONLINK_CONFIG");
        }
        cmd.args(args)
            .envs(env.iter().copied())
            .stdin(stdin)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start motionlink")
    }

    /// Starts `motionlink <args>`.
    pub fn start(args: &[&str]) -> Running {
        Self::start_env(args, &[])
    }

    /// Starts `motionlink <args>` with `env` set.
    pub fn start_env(args: &[&str], env: &[(&str, &str)]) -> Running {
        let mut child = Self::spawn_env(args, Stdio::null(), env);
        let stdout = Lines::follow(child.stdout.take().expect("piped stdout"));
        let stderr = Lines::follow(child.stderr.take().expect("piped stderr"));
        Running { child, stdout, stderr }
    }

    /// Starts `motionlink <args>` with a pipe to its stdin, which the caller writes and closes.
    pub fn start_with_stdin(args: &[&str]) -> (Running, std::process::ChildStdin) {
        let mut child = Self::spawn(args, Stdio::piped());
        let stdin = child.stdin.take().expect("piped stdin");
        let stdout = Lines::follow(child.stdout.take().expect("piped stdout"));
        let stderr = Lines::follow(child.stderr.take().expect("piped stderr"));
        (Running { child, stdout, stderr }, stdin)
    }

    /// Starts `motionlink <args>` with its stdout a pipe that the caller holds and may close (its reader going
    /// away); stderr is followed.
    pub fn start_with_stdout(args: &[&str]) -> (Running, std::process::ChildStdout) {
        let mut child = Self::spawn(args, Stdio::null());
        let stdout = child.stdout.take().expect("piped stdout");
        let stderr = Lines::follow(child.stderr.take().expect("piped stderr"));
        // Nothing follows stdout here: its lines are the caller's.
        let none = Lines::default();
        none.0 .0.lock().unwrap().1 = true;
        (Running { child, stdout: none, stderr }, stdout)
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Sends signal `sig` (such as `libc::SIGTERM`) and returns the Unix time just before it was sent.
    #[cfg(unix)]
    pub fn signal(&self, sig: i32) -> f64 {
        let at = unix_now();
        // SAFETY: kill(2) on our own child's pid.
        let rc = unsafe { libc::kill(self.child.id() as i32, sig) };
        assert_eq!(rc, 0, "kill({}, {sig}) failed", self.child.id());
        at
    }

    /// SIGKILL: the process ends at once, without a chance to stop anything.
    pub fn kill(&mut self) -> f64 {
        let at = unix_now();
        self.child.kill().expect("kill the command");
        at
    }

    /// Waits up to `timeout` for the command to end; kills it and panics with its output if it does not.
    pub fn wait(mut self, timeout: Duration) -> Ended {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("wait for the command") {
                // Let the readers see the end of both pipes.
                self.stdout.wait_for(Duration::from_secs(2), |_| false);
                self.stderr.wait_for(Duration::from_secs(2), |_| false);
                return Ended { status, stdout: self.stdout.text(), stderr: self.stderr.text() };
            }
            if Instant::now() >= deadline {
                let _ = self.child.kill();
                let _ = self.child.wait();
                panic!(
                    "the command did not end within {timeout:?}\nstdout:\n{}\nstderr:\n{}",
                    self.stdout.text(),
                    self.stderr.text()
                );
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs `motionlink <args>` to its end with `env` set (and MOTIONLINK_PORT / MOTIONLINK_CONFIG removed unless
/// `env` sets them), `stdin` written to its stdin.
pub fn run_with(args: &[&str], env: &[(&str, &str)], stdin: &str) -> std::process::Output {
    use std::io::Write;
    let mut cmd = Command::new(BIN);
    cmd.args(args).env_remove("MOTIONLINK_PORT").env_remove("MOTIONLINK_CONFIG");
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child =
        cmd.stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("start motionlink");
    let mut input = child.stdin.take().expect("piped stdin");
    input.write_all(stdin.as_bytes()).expect("write stdin");
    drop(input);
    child.wait_with_output().expect("wait for motionlink")
}

/// The one JSON object a `--json` command printed on stderr for its error.
pub fn json_error(out: &std::process::Output) -> serde_json::Value {
    let text = String::from_utf8_lossy(&out.stderr);
    let line = text.lines().last().unwrap_or_else(|| panic!("no error on stderr: {out:?}"));
    serde_json::from_str(line).unwrap_or_else(|e| panic!("stderr is not one JSON object ({e}): {text}"))
}

/// `motionlink <args>` (a `watch` printing a line at a time) with its stdout read as `... | head -1` does:
/// one line, then the pipe closed. Returns that line and how the command ended.
pub fn head_1(args: &[&str]) -> (String, Ended) {
    let (running, stdout) = Running::start_with_stdout(args);
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).expect("read the first line"); // dropped: the pipe closes
    (line, running.wait(Duration::from_secs(10)))
}

/// A temporary file path unique to this test process and `name`.
pub fn temp_path(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("motionlink-test-{}-{name}", std::process::id()))
}

/// CPU time (user + system) a command used, in seconds, measured by the kernel when it ended.
#[cfg(target_os = "linux")]
pub fn cpu_seconds_of(child: std::process::Child) -> (i32, f64) {
    let pid = child.id() as i32;
    let mut status = 0;
    // SAFETY: an all-zero rusage is valid; wait4 on our own child fills it in.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(rc, pid);
    std::mem::forget(child); // reaped here, not by Child's drop
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 / 1e6;
    (libc::WEXITSTATUS(status), secs(usage.ru_utime) + secs(usage.ru_stime))
}

/// Asserts that `text` has no programming-language debug text: `Some(`, `None`, `\u{` escapes, or a
/// CamelCase name glued to a parenthesis (`Get(ActPos)`, `CanFrame(123#0102)`).
pub fn assert_no_debug_text(what: &str, text: &str) {
    assert!(!text.contains("Some(") && !text.contains("None"), "{what}: {text}");
    assert!(!text.contains("\\u{"), "{what}: a Rust escape: {text}");
    for word in text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '(')) {
        if let Some((name, _)) = word.split_once('(') {
            let camel = name.starts_with(|c: char| c.is_ascii_uppercase())
                && name.chars().any(|c| c.is_ascii_lowercase())
                && name.chars().all(|c| c.is_ascii_alphanumeric());
            assert!(!camel, "{what}: debug form {word:?} in {text}");
        }
    }
}
