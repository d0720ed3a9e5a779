//! What the end-to-end tests of the built binary share: the binary, and a `motionlink sim` child process.

#![allow(dead_code)] // each test file uses a different part

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

/// The built `motionlink` binary.
pub const BIN: &str = env!("CARGO_BIN_EXE_motionlink");

/// A running `motionlink sim FAMILY ...`, killed when dropped.
pub struct Sim {
    child: Child,
    /// Where it serves: `tcp://127.0.0.1:PORT` or a pty's device path.
    pub address: String,
}

impl Sim {
    /// Starts `motionlink sim <family> <args>` and waits for its one `listening on ...` line.
    pub fn start(family: &str, args: &[&str]) -> Sim {
        let mut child = Command::new(BIN)
            .args(["sim", family])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start motionlink sim");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("piped stdout")).read_line(&mut line).expect("read its first line");
        let address = line
            .trim()
            .strip_prefix("listening on pty ")
            .or_else(|| line.trim().strip_prefix("listening on "))
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
            .to_string();
        Sim { child, address }
    }

    /// Starts `motionlink sim <family> --tcp 127.0.0.1:0`.
    pub fn tcp(family: &str) -> Sim {
        Sim::start(family, &["--tcp", "127.0.0.1:0"])
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
