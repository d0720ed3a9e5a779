//! The emulator servers, end to end over real TCP sockets and pseudo-terminals.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::clock::{RealClock, Timestamp};
use motionlink_link::emulator::{serve_tcp, Emulator};
use motionlink_link::link::{Link, SerialSettings};
use motionlink_link::url::PortUrl;

/// Answers every line with the line upper-cased.
#[derive(Default)]
struct Upper {
    line: Vec<u8>,
}

impl Emulator for Upper {
    fn receive(&mut self, _now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        for &b in bytes {
            self.line.push(b);
            if b == b'\n' {
                out.extend(self.line.drain(..).map(|c| c.to_ascii_uppercase()));
            }
        }
    }
    fn advance(&mut self, _now: Timestamp, _out: &mut Vec<u8>) {}
    fn next_wakeup(&self) -> Option<Timestamp> {
        None
    }
}

fn read_line(link: &mut dyn Link) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 64];
    while !got.ends_with(b"\n") {
        let n = link.recv(&mut buf, Duration::from_secs(2)).unwrap();
        assert!(n > 0, "timed out after {got:?}");
        got.extend_from_slice(&buf[..n]);
    }
    got
}

#[test]
fn tcp_server_serves_one_client_after_another() {
    let server = serve_tcp("127.0.0.1:0", Arc::new(Mutex::new(Upper::default())), RealClock::shared()).unwrap();
    let url: PortUrl = server.address().parse().unwrap();
    for round in 0..3 {
        let mut link = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
        link.send(format!("hello {round}\n").as_bytes()).unwrap();
        assert_eq!(read_line(&mut link), format!("HELLO {round}\n").into_bytes());
    }
}

#[cfg(unix)]
#[test]
fn pty_server_serves_a_client_that_reopens_the_port() {
    let server =
        motionlink_link::emulator::serve_pty(Arc::new(Mutex::new(Upper::default())), RealClock::shared()).unwrap();
    assert!(server.address().starts_with("/dev/"), "{}", server.address());
    for round in 0..2 {
        let mut link = PortUrl::Serial(server.address().into()).open_byte_link(SerialSettings::new(38_400)).unwrap();
        link.send(format!("pty {round}\n").as_bytes()).unwrap();
        assert_eq!(read_line(&mut link), format!("PTY {round}\n").into_bytes());
    }
}
