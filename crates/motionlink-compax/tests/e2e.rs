//! The client against the emulator served over real TCP sockets and pseudo-terminals, in real time:
//! ASCII and binary end to end.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_compax::client::{Client, Config, MoveOptions};
use motionlink_compax::model::{Command, OutputState, ParamId, Position, SpeedPercent, StatusId, StatusValue};
use motionlink_compax::sim::{Emulator, SimConfig};
use motionlink_compax::wire::{Address, Mode};
use motionlink_link::emulator::{serve_tcp, Server};
use motionlink_link::url::PortUrl;
use motionlink_link::RealClock;

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

/// A session opened by the port's name, as a user's program opens it (`Client::open`, the mode's parity).
fn session(server: &Server, p196: u32, port: PortUrl) -> Client {
    let _ = server;
    Client::open(&port, RealClock::shared(), Config::new(Mode::from_p196(p196).unwrap(), 115_200)).unwrap()
}

#[test]
fn opening_by_name_refuses_sim_and_can_naming_what_to_do() {
    for (port, says) in [("sim", "give its link to `with_link`"), ("socketcan://can0", "not CAN")] {
        let err =
            Client::open(&port.parse().unwrap(), RealClock::shared(), Config::new(Mode::default(), 9600)).unwrap_err();
        let text = err.to_string();
        assert!(text.contains(port) && text.contains(says), "{text}");
        assert_eq!(motionlink_link::error::Classify::class(&err), motionlink_link::error::ErrorClass::Usage);
    }
}

fn exercise(bus: &Client) {
    // ASCII reads and writes.
    assert_eq!(bus.read_position(a(5)).unwrap(), pos(0.0));
    bus.write_param(a(5), ParamId::new(12).unwrap(), 42.5).unwrap();
    assert_eq!(bus.read_param(a(5), ParamId::new(12).unwrap()).unwrap(), 42.5);
    // Binary settings and moves (short distances: 100 units/s in real time).
    let bin = MoveOptions { binary: true, message: false };
    bus.set_speed(a(1), SpeedPercent::new(100.0).unwrap(), true).unwrap();
    bus.move_absolute(a(1), pos(1.5), bin).unwrap();
    bus.wait_reached(&[a(1)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
    bus.move_relative(a(1), pos(-0.25), bin).unwrap();
    bus.wait_reached(&[a(1)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(1.25));
    bus.set_output(a(1), 3, OutputState::ON, true).unwrap();
    // A synchronous start with the position-reached message.
    bus.sync_start(&[(a(1), Command::PosA(pos(0.5))), (a(5), Command::PosA(pos(0.5)))], true).unwrap();
    bus.wait_reached(&[a(1), a(5)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(5)).unwrap(), pos(0.5));
    assert!(matches!(bus.read_status(a(1), StatusId::STATUS_BITS_1).unwrap(), StatusValue::S16(_)));
}

#[test]
fn over_tcp_ascii_and_binary() {
    for p196 in [0, 8 + 64, 2 + 4 + 8 + 16 + 32] {
        let sim =
            Emulator::new(SimConfig::bus(&[1, 5], p196, 115_200).with_param(ParamId::new(12).unwrap(), 0.0)).unwrap();
        let device = Arc::new(Mutex::new(sim));
        let server = serve_tcp("127.0.0.1:0", Arc::clone(&device), RealClock::shared()).unwrap();
        let url: PortUrl = server.address().parse().unwrap();
        let bus = session(&server, p196, url);
        exercise(&bus);
        drop(bus);
        let d = device.lock().unwrap();
        assert_eq!(d.drive(1).unwrap().output(3), Some(1), "P196={p196}");
        assert!(d.drive(1).unwrap().telegrams() > 5);
    }
}

#[cfg(unix)]
#[test]
fn over_a_pty_ascii_and_binary() {
    let sim = Emulator::new(SimConfig::bus(&[1, 5], 8, 115_200).with_param(ParamId::new(12).unwrap(), 0.0)).unwrap();
    let server = motionlink_link::emulator::serve_pty(Arc::new(Mutex::new(sim)), RealClock::shared()).unwrap();
    let url = PortUrl::Serial(server.address().to_string());
    let bus = session(&server, 8, url);
    exercise(&bus);
}

#[test]
fn dropping_a_tcp_session_stops_the_axis() {
    let sim = Emulator::new(SimConfig::bus(&[1], 0, 115_200)).unwrap();
    let device = Arc::new(Mutex::new(sim));
    let server = serve_tcp("127.0.0.1:0", Arc::clone(&device), RealClock::shared()).unwrap();
    let bus = session(&server, 0, server.address().parse().unwrap());
    bus.move_absolute(a(1), pos(10_000.0), MoveOptions::default()).unwrap();
    drop(bus);
    let d = device.lock().unwrap();
    assert!(!d.drive(1).unwrap().is_moving());
    assert_eq!(d.drive(1).unwrap().o0(), 0);
}
