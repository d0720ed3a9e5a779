use super::*;
use crate::clock::{Clock, ManualClock, RealClock};

#[test]
fn instant_pipe_carries_bytes_both_ways() {
    let clock = RealClock::shared();
    let (mut a, mut b, _) = pipe(clock, PipeConfig::instant());
    a.send(b"hello").unwrap();
    let mut buf = [0u8; 16];
    assert_eq!(b.recv(&mut buf, Duration::from_millis(100)).unwrap(), 5);
    assert_eq!(&buf[..5], b"hello");
    b.send(b"ok").unwrap();
    assert_eq!(a.recv(&mut buf, Duration::from_millis(100)).unwrap(), 2);
    assert_eq!(a.recv(&mut buf, Duration::from_millis(1)).unwrap(), 0, "timeout reads nothing");
}

#[test]
fn paced_pipe_delivers_at_wire_time() {
    let clock = ManualClock::new();
    let (mut a, mut b, _) = pipe(clock.shared(), PipeConfig::paced(9_600));
    a.send(&[1, 2, 3]).unwrap();
    let mut buf = [0u8; 8];
    // One byte is 10 bits at 9600 baud: 1.0417 ms.
    assert_eq!(b.recv(&mut buf, Duration::ZERO).unwrap(), 0);
    clock.advance(Duration::from_micros(1042));
    assert_eq!(b.recv(&mut buf, Duration::ZERO).unwrap(), 1);
    clock.advance(Duration::from_micros(2084));
    assert_eq!(b.recv(&mut buf, Duration::ZERO).unwrap(), 2);
    assert_eq!(&buf[..2], &[2, 3]);
}

#[test]
fn faults_drop_delay_and_disconnect() {
    let clock = ManualClock::new();
    let (mut a, mut b, faults) = pipe(clock.shared(), PipeConfig::instant());
    faults.drop_next(Direction::HostToDevice, 2);
    a.send(b"abcd").unwrap();
    let mut buf = [0u8; 8];
    assert_eq!(b.recv(&mut buf, Duration::ZERO).unwrap(), 2);
    assert_eq!(&buf[..2], b"cd");
    faults.delay_next(Direction::DeviceToHost, Duration::from_millis(50));
    b.send(b"x").unwrap();
    assert_eq!(a.recv(&mut buf, Duration::ZERO).unwrap(), 0);
    clock.advance(Duration::from_millis(50));
    assert_eq!(a.recv(&mut buf, Duration::ZERO).unwrap(), 1);
    faults.disconnect();
    assert!(a.send(b"y").unwrap_err().is_disconnect());
    assert!(b.recv(&mut buf, Duration::ZERO).unwrap_err().is_disconnect());
}

#[test]
fn scheduled_disconnect_fires_at_its_byte() {
    let clock = ManualClock::new();
    let (mut a, mut b, faults) = pipe(clock.shared(), PipeConfig::instant());
    faults.inject(Direction::HostToDevice, 3, Fault::Disconnect);
    a.send(b"abc").unwrap();
    a.send(b"d").unwrap();
    assert!(faults.is_disconnected());
    let mut buf = [0u8; 8];
    assert!(b.recv(&mut buf, Duration::ZERO).unwrap_err().is_disconnect());
}

#[test]
fn dropping_one_end_disconnects_the_other_after_draining() {
    let clock = RealClock::shared();
    let (mut a, b, _) = pipe(clock, PipeConfig::instant());
    drop(b);
    assert!(a.send(b"x").unwrap_err().is_disconnect());
    let mut buf = [0u8; 4];
    assert!(a.recv(&mut buf, Duration::from_millis(1)).unwrap_err().is_disconnect());
}

/// Echoes every byte back incremented, and says "T" by itself at 100 ms (events: each byte received, and
/// "told").
#[derive(Default)]
struct Echo {
    received_at: Vec<Timestamp>,
    told: bool,
    events: Vec<String>,
}

impl Emulator for Echo {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        self.received_at.push(now);
        self.events.extend(bytes.iter().map(|b| format!("got {b}")));
        out.extend(bytes.iter().map(|b| b + 1));
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<u8>) {
        if !self.told && now >= Timestamp::from_millis(100) {
            self.told = true;
            self.events.push("told".into());
            out.push(b'T');
        }
    }
    fn take_events(&mut self) -> Vec<String> {
        std::mem::take(&mut self.events)
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        (!self.told).then_some(Timestamp::from_millis(100))
    }
    fn connection_closed(&mut self, _now: Timestamp) {}
}

#[test]
fn emulator_sees_each_byte_at_its_arrival_time() {
    let clock = ManualClock::new();
    let host = EmulatorHost::new(Echo::default(), clock.shared(), PipeConfig::paced(10_000));
    let (mut link, _) = host.connect();
    link.send(&[1, 2]).unwrap();
    clock.advance(Duration::from_millis(10));
    let mut buf = [0u8; 8];
    // Each byte is 1 ms; the echo of byte 1 arrives at 2 ms, of byte 2 at 3 ms.
    assert_eq!(link.recv(&mut buf, Duration::ZERO).unwrap(), 2);
    assert_eq!(&buf[..2], &[2, 3]);
    let stamps = host.with_device(|d| d.received_at.clone());
    assert_eq!(stamps, vec![Timestamp::from_millis(1), Timestamp::from_millis(2)]);
}

#[test]
fn kept_events_carry_the_time_the_device_produced_them() {
    let clock = ManualClock::new();
    let host = EmulatorHost::new(Echo::default(), clock.shared(), PipeConfig::paced(10_000));
    host.keep_event_times();
    let (mut link, _) = host.connect();
    link.send(&[1, 2]).unwrap();
    // Nothing looks at the device until 250 ms: the events keep the times of the bytes and the timer.
    clock.advance(Duration::from_millis(250));
    let events = host.take_timed_events();
    let expected = [(1, "got 1"), (2, "got 2"), (100, "told")];
    assert_eq!(events, expected.map(|(ms, e)| (Timestamp::from_millis(ms), e.to_string())));
    assert!(host.take_timed_events().is_empty(), "taken once");
    assert!(host.with_device(|d| d.take_events()).is_empty(), "kept by the host, not left in the device");
}

#[test]
fn emulator_timer_output_wakes_a_waiting_reader() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(Echo::default(), clock.shared(), PipeConfig::instant());
    let (mut link, _) = host.connect();
    let mut buf = [0u8; 8];
    assert_eq!(link.recv(&mut buf, Duration::from_secs(1)).unwrap(), 1);
    assert_eq!(buf[0], b'T');
    assert_eq!(clock.now(), Timestamp::from_millis(100));
}
