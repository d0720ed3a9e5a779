//! The client against the emulator, in-process, with an auto-advancing manual clock (the shared rig of
//! `motionlink-testkit`): the tests of the blocking client before the session became sans-IO, on the same
//! API (renamed: `Bus` is `Client`, `SimBus` is `Emulator`), asserting what they asserted.

mod basics;
mod checked;
mod close;
mod firmware;
mod modes;
mod setpoint;
mod variants;
mod watchdog;

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

/// Addresses as patterns match them.
const A1: Address = Address::checked(1);
const A9: Address = Address::checked(9);
const A17: Address = Address::checked(17);

use motionlink_link::can::{CanBus, CanBusConfig, CanLink};

use crate::client::PortLink;
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::{Direction, EmulatorHost, FaultControl, PipeConfig};
use motionlink_link::LinkError;
use motionlink_testkit::rig::{CanRig, Rig};

use crate::client::{Client, Config, ModuleInfo, MoveSpec};
use crate::model::{Address, ConfigWord, CubeState, Position, Velocity};
use crate::sim::SimConfig;
use crate::wire::{Reply, Request};
use crate::Emulator;

fn rs232(addresses: &[u8]) -> (ManualClock, EmulatorHost<Emulator>, Client, FaultControl) {
    rs232_with(addresses, Config::rs232())
}

fn rs232_with(addresses: &[u8], config: Config) -> (ManualClock, EmulatorHost<Emulator>, Client, FaultControl) {
    rs232_on(addresses, PipeConfig::paced(9_600), config)
}

/// Modules at `addresses` on an RS232 line configured by `pipe` (the shared rig), and a client.
fn rs232_on(
    addresses: &[u8],
    pipe: PipeConfig,
    config: Config,
) -> (ManualClock, EmulatorHost<Emulator>, Client, FaultControl) {
    let rig = Rig::new(Emulator::new(&SimConfig::with_addresses(addresses).unwrap()), pipe);
    let bus = Client::with_link(PortLink::Rs232(rig.link().unwrap()), rig.clock.shared(), config).unwrap();
    let faults = rig.faults();
    (rig.clock, rig.host, bus, faults)
}

/// The infos of a scan in which every module could be read.
fn scan_infos(bus: &Client) -> Vec<ModuleInfo> {
    bus.scan()
        .unwrap()
        .into_iter()
        .map(|e| e.info.unwrap_or_else(|err| panic!("module {}: {err}", e.address)))
        .collect()
}

fn can(addresses: &[u8]) -> (ManualClock, CanBus<Emulator>, Client) {
    let sim = Emulator::new_can(&SimConfig::with_addresses(addresses).unwrap());
    let rig = CanRig::new(sim, CanBusConfig::paced(1_000_000));
    let bus = Client::with_link(PortLink::Can(Box::new(rig.link())), rig.clock.shared(), Config::can()).unwrap();
    (rig.clock, rig.bus, bus)
}

/// The module address `n` (a valid one: the tests name 1..31).
fn addr(n: u8) -> Address {
    Address::new(n).unwrap()
}

/// The module addresses `ns`.
fn addrs(ns: &[u8]) -> Vec<Address> {
    ns.iter().map(|&n| addr(n)).collect()
}

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

fn can_host() -> (ManualClock, CanBus<Emulator>, Client) {
    can(&[1, 2])
}

/// State and position of module `a` at the clock's time, straight from the emulator.
fn device_view(canbus: &CanBus<Emulator>, clock: &ManualClock, a: u8) -> (CubeState, f32, bool, ConfigWord) {
    canbus
        .with_device(|d| {
            d.update(clock.now());
            let m = d.module(a).unwrap();
            (m.state(), m.position().value(), m.watchdog_online(), m.config_word())
        })
        .unwrap()
}

/// The length on the wire of `reply` from module `address` in an RS232 frame.
fn rs232_len(address: u8, reply: &Reply) -> u64 {
    let mut buf = [0u8; crate::wire::rs232::MAX_FRAME];
    crate::wire::rs232::encode(crate::wire::rs232::TelKind::Recv, address, &reply.encode(), &mut buf).unwrap() as u64
}

/// An RS232 session whose bytes arrive at once (no 9600 baud pacing): only the session's own timing counts.
fn rs232_instant(addresses: &[u8]) -> (ManualClock, EmulatorHost<Emulator>, Client, FaultControl) {
    rs232_on(addresses, PipeConfig::instant(), Config::rs232())
}

fn spec(target: f32) -> MoveSpec {
    MoveSpec {
        vel: Some(Velocity::native(1.0)),
        acc: Some(crate::model::Acceleration::native(2.0)),
        ..MoveSpec::to(Position::native(target))
    }
}

fn sim_module(host: &EmulatorHost<Emulator>, a: u8) -> (CubeState, f32) {
    host.with_device(|d| {
        let m = d.module(a).unwrap();
        (m.state(), m.position().value())
    })
}

/// The length of the RS232 frame of `request` to `address`, DLE escapes included.
fn rs232_request_len(address: u8, request: &Request) -> u64 {
    let mut buf = [0u8; crate::wire::rs232::MAX_FRAME];
    crate::wire::rs232::encode(crate::wire::rs232::TelKind::Send, address, &request.encode(), &mut buf).unwrap() as u64
}

/// The host dies: no more refresh, no halt, no goodbye (what SIGKILL, a power loss or a pulled adapter does
/// to a session).
fn kill(bus: Client) {
    bus.session(|s| s.die());
    drop(bus);
}
