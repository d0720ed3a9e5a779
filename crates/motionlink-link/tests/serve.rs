//! The emulator servers, end to end over real TCP sockets and pseudo-terminals.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::clock::{RealClock, Timestamp};
use motionlink_link::emulator::{serve_tcp, serve_tcp_with, Emulator, ServeOptions, BUSY_PREFIX};
use motionlink_link::error::Classify;
use motionlink_link::link::{Link, LinkError, SerialSettings};
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
    fn connection_closed(&mut self, _now: Timestamp) {
        self.line.clear();
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

#[test]
fn a_second_tcp_client_is_refused_with_a_line_and_the_next_one_is_served() {
    let server = serve_tcp("127.0.0.1:0", Arc::new(Mutex::new(Upper::default())), RealClock::shared()).unwrap();
    let url: PortUrl = server.address().parse().unwrap();
    let mut first = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
    first.send(b"one\n").unwrap();
    assert_eq!(read_line(&mut first), b"ONE\n");

    // A second client while the first is connected: the link knows the server's refusal (one line, then
    // the connection is closed), even with a request sent before it came.
    let mut second = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
    second.send(b"two\n").unwrap();
    let mut buf = [0u8; 8];
    let refused = second.recv(&mut buf, Duration::from_secs(2));
    match refused {
        Err(ref e @ LinkError::Busy { ref port }) => {
            assert_eq!(port, server.address());
            assert_eq!(e.to_string(), format!("{} is busy: another client is connected", server.address()));
            assert!(e.is_disconnect() && e.class().exit_code() == 3, "{e}");
        }
        other => panic!("the refusal was not known: {other:?}"),
    }

    // The first is still served; once it closes, a new client is.
    first.send(b"still\n").unwrap();
    assert_eq!(read_line(&mut first), b"STILL\n");
    drop(first);
    let mut third = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
    third.send(b"three\n").unwrap();
    assert_eq!(read_line(&mut third), b"THREE\n");
}

#[test]
fn a_line_half_sent_on_a_closed_connection_is_not_completed_by_the_next() {
    let server = serve_tcp("127.0.0.1:0", Arc::new(Mutex::new(Upper::default())), RealClock::shared()).unwrap();
    let url: PortUrl = server.address().parse().unwrap();
    let mut first = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
    first.send(b"half").unwrap();
    // Make sure the server has the half line before the connection goes.
    first.send(b"-done\n").unwrap();
    assert_eq!(read_line(&mut first), b"HALF-DONE\n");
    first.send(b"left").unwrap();
    std::thread::sleep(Duration::from_millis(50));
    drop(first);
    // The server may take a moment to see the close; a refused attempt is retried.
    let mut next = loop {
        let mut link = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
        link.send(b"new\n").unwrap();
        let mut buf = [0u8; 8];
        match link.recv(&mut buf, Duration::from_secs(2)) {
            Err(LinkError::Busy { .. }) => continue,
            Ok(n) => {
                let mut line = buf[..n].to_vec();
                if !line.ends_with(b"\n") {
                    line.extend(read_line(&mut link));
                }
                assert_eq!(line, b"NEW\n", "the half line of the closed connection was carried over");
                break link;
            }
            Err(e) => panic!("{e}"),
        }
    };
    next.send(b"x\n").unwrap();
    assert_eq!(read_line(&mut next), b"X\n");
}

/// Echoes what it receives, and panics on `!` as an emulator with a defect would.
struct Crashing;

impl Emulator for Crashing {
    fn receive(&mut self, _now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        if bytes.contains(&b'!') {
            panic!("the emulator's defect");
        }
        out.extend_from_slice(bytes);
    }
    fn advance(&mut self, _now: Timestamp, _out: &mut Vec<u8>) {}
    fn next_wakeup(&self) -> Option<Timestamp> {
        None
    }
    fn connection_closed(&mut self, _now: Timestamp) {}
}

/// Serves `device` over TCP with its events collected in the returned list.
fn serve_collecting<E: Emulator + 'static>(
    device: Arc<Mutex<E>>,
) -> (motionlink_link::emulator::Server, Arc<Mutex<Vec<String>>>) {
    let events = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&events);
    let options = ServeOptions { on_event: Some(Arc::new(move |e: &str| sink.lock().unwrap().push(e.to_string()))) };
    (serve_tcp_with("127.0.0.1:0", device, RealClock::shared(), options).unwrap(), events)
}

/// Connects to a crashed server until it is gone (the connection refused), within 2 s. A connection made
/// meanwhile is closed without a word: the server never claims another client is connected.
fn wait_until_gone(address: &str) {
    let addr: std::net::SocketAddr = address.trim_start_matches("tcp://").parse().unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(2);
    loop {
        assert!(std::time::Instant::now() < deadline, "the crashed server still accepts connections");
        let Ok(mut stream) = std::net::TcpStream::connect_timeout(&addr, Duration::from_millis(200)) else {
            return;
        };
        stream.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
        let mut got = Vec::new();
        let _ = std::io::Read::read_to_end(&mut stream, &mut got);
        assert!(!got.starts_with(BUSY_PREFIX.as_bytes()), "a crashed server said: {}", String::from_utf8_lossy(&got));
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What `Server::wait` passed on, as text.
fn wait_panic(server: motionlink_link::emulator::Server) -> String {
    let payload = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| server.wait()))
        .expect_err("wait passes the device's panic on");
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_default()
}

#[test]
fn a_panicking_emulator_ends_its_tcp_server_which_says_so_and_passes_the_panic_on() {
    let (server, events) = serve_collecting(Arc::new(Mutex::new(Crashing)));
    let url: PortUrl = server.address().parse().unwrap();
    let mut first = url.open_byte_link(SerialSettings::new(38_400)).unwrap();
    first.send(b"ok\n").unwrap();
    assert_eq!(read_line(&mut first), b"ok\n");
    first.send(b"!").unwrap();
    // The client's connection ends, and no later client is told the server is busy: it is gone.
    let mut buf = [0u8; 8];
    assert!(!matches!(first.recv(&mut buf, Duration::from_secs(2)), Ok(n) if n > 0));
    let address = server.address().to_string();
    wait_until_gone(&address);
    // The server's thread ended (joined by `wait`) before its events are looked at: the listener may be
    // gone a moment before the thread has said why.
    assert_eq!(wait_panic(server), "the emulator's defect");
    let said = events.lock().unwrap().clone();
    assert!(said.iter().any(|e| e.contains("the emulator crashed") && e.contains("the emulator's defect")), "{said:?}");
}

#[test]
fn a_device_whose_lock_another_thread_poisoned_is_not_served() {
    let device = Arc::new(Mutex::new(Upper::default()));
    let held = Arc::clone(&device);
    let _ = std::thread::spawn(move || {
        let _guard = held.lock().unwrap();
        panic!("a panic while holding the device");
    })
    .join();
    assert!(device.is_poisoned());
    let (server, events) = serve_collecting(device);
    let address = server.address().to_string();
    wait_until_gone(&address);
    // Joined first, as above: the event comes from the server's thread.
    assert!(wait_panic(server).contains("poisoned"));
    let said = events.lock().unwrap().clone();
    assert!(said.iter().any(|e| e.contains("the emulator crashed") && e.contains("poisoned")), "{said:?}");
}
