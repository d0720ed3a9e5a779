//! `motionlink sim --tcp` as a ser2net user expects it, with a real device's bytes: a second client is refused
//! with one line, a half-sent telegram dies with its connection, and listening on every interface is warned of.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use crate::common::Sim;

/// The manual's RO (Safety_ID 0) and the unit's ACK to it.
const RO: [u8; 5] = [0x52, 0x4F, 0x00, 0x5C, 0x2D];
const RO_ACK: [u8; 5] = [0x52, 0x4F, 0x06, 0x9A, 0x4D];

fn connect(sim: &Sim) -> TcpStream {
    let address = sim.address.strip_prefix("tcp://").expect("a tcp address");
    let stream = TcpStream::connect(address).expect("connect to the emulator");
    stream.set_nodelay(true).unwrap();
    stream
}

/// Everything the peer sends within `window` (or until it closes).
fn read_for(stream: &mut TcpStream, window: Duration) -> Vec<u8> {
    let end = Instant::now() + window;
    let mut got = Vec::new();
    let mut buf = [0u8; 256];
    while let Some(left) = end.checked_duration_since(Instant::now()).filter(|d| !d.is_zero()) {
        stream.set_read_timeout(Some(left)).unwrap();
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(_) => break,
        }
    }
    got
}

/// Reads until `n` bytes came or `timeout` passed.
fn read_n(stream: &mut TcpStream, n: usize, timeout: Duration) -> Vec<u8> {
    let end = Instant::now() + timeout;
    let mut got = Vec::new();
    let mut buf = [0u8; 64];
    while got.len() < n {
        let Some(left) = end.checked_duration_since(Instant::now()).filter(|d| !d.is_zero()) else { break };
        stream.set_read_timeout(Some(left)).unwrap();
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(k) => got.extend_from_slice(&buf[..k]),
        }
    }
    got
}

#[test]
fn a_second_client_gets_one_line_and_is_closed_while_the_first_is_served() {
    let sim = Sim::tcp("scu");
    let mut first = connect(&sim);
    first.write_all(&RO).unwrap();
    assert_eq!(read_n(&mut first, 5, Duration::from_secs(5)), RO_ACK, "the first client is served");
    let mut second = connect(&sim);
    let mut said = String::new();
    second.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    second.read_to_string(&mut said).expect("the busy line, then the end of the connection");
    assert_eq!(said, "motionlink sim: busy: another client is connected; this connection is closed\n");
    // The first one is still served.
    first.write_all(&RO).unwrap();
    assert_eq!(read_n(&mut first, 5, Duration::from_secs(5)), RO_ACK);
}

#[test]
fn a_telegram_half_sent_when_its_connection_closed_is_not_completed_by_the_next_connection() {
    let sim = Sim::tcp("scu");
    let mut first = connect(&sim);
    first.write_all(&RO[..3]).unwrap();
    first.flush().unwrap();
    drop(first);
    // The rest of the telegram, on a new connection: had the first half been kept, this would complete an RO
    // and the unit would ACK it.
    let mut second = connect(&sim);
    second.write_all(&RO[3..]).unwrap();
    let answered = read_for(&mut second, Duration::from_millis(300));
    assert!(!answered.windows(5).any(|w| w == RO_ACK), "the half telegram was carried over: {answered:02X?}");
    drop(second);
    // A whole telegram on a fresh connection is answered, once.
    let mut third = connect(&sim);
    third.write_all(&RO).unwrap();
    assert_eq!(read_n(&mut third, 5, Duration::from_secs(5)), RO_ACK);
    assert_eq!(read_for(&mut third, Duration::from_millis(100)), Vec::<u8>::new(), "nothing more");
}

#[test]
fn listening_on_every_interface_is_accepted_with_a_warning() {
    let sim = Sim::start("scu", &["--tcp", "0.0.0.0:0"]);
    assert!(sim.address.starts_with("tcp://"), "{}", sim.address);
    let warning = sim.stderr.wait_for(Duration::from_secs(5), |l| l.contains("warning"));
    let warning = warning.expect("a warning on stderr");
    assert!(warning.contains("every network interface") && warning.contains("network"), "{warning}");
    // It serves like any other address.
    let port = sim.address.rsplit(':').next().unwrap();
    let mut client = TcpStream::connect(("127.0.0.1", port.parse::<u16>().unwrap())).unwrap();
    client.write_all(&RO).unwrap();
    assert_eq!(read_n(&mut client, 5, Duration::from_secs(5)), RO_ACK);
}
