//! The async client on tokio against the in-process emulator (two rotary modules on the in-memory CAN bus
//! at 1 Mbit/s, real time): the operations the blocking client has beyond the checked move, with the same
//! results. Waits are on the module's state, never fixed sleeps.

use motionlink_powercube::PortLink;
use std::future::Future;
use std::time::Duration;

use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::{RealClock, SharedClock};
use motionlink_powercube::client::{AsyncClient, Config, Guard, MoveSpec, StopOutcome};
use motionlink_powercube::model::{
    Acceleration, Address, AxisUnit, ConfigFlag, CubeState, ModuleKind, Param, Position, Ramp, ShortFlag, StateFlag,
    Value, Velocity,
};
use motionlink_powercube::session::Op;
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::wire::{Reply, Request};
use motionlink_powercube::{Emulator, Error};

async fn setup() -> (CanBus<Emulator>, AsyncClient) {
    let clock = RealClock::shared();
    let sim = Emulator::new_can(&SimConfig::with_addresses(&[1, 2]).unwrap());
    let bus = CanBus::with_emulator(sim, clock.clone(), CanBusConfig::paced(1_000_000));
    let client = AsyncClient::with_link(PortLink::Can(Box::new(bus.connect())), clock, Config::can()).await.unwrap();
    (bus, client)
}

fn run(test: impl std::future::Future<Output = ()>) {
    tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap().block_on(test)
}

fn a(n: u8) -> Address {
    Address::new(n).unwrap()
}

fn emulator_events(bus: &CanBus<Emulator>, prefix: &str) -> Vec<String> {
    bus.with_device(|d| d.take_events()).unwrap_or_default().into_iter().filter(|e| e.starts_with(prefix)).collect()
}

#[test]
fn async_home_starts_without_waiting_and_wait_home_sees_it_end() {
    run(async {
        let (_bus, client) = setup().await;
        let m = client.module(a(1));
        assert!(!m.state().await.unwrap().contains(StateFlag::HomeOk));
        m.home().await.unwrap();
        // `home` returned on the acknowledge: the module is still on its way to the home switch.
        let during = m.state().await.unwrap();
        assert!(during.contains(StateFlag::Motion) && !during.contains(StateFlag::HomeOk), "{during}");
        assert_eq!(client.started(), vec![a(1)], "a Home counts as setting the module in motion");
        let end = m.wait_home(Duration::from_secs(5)).await.unwrap();
        assert!(end.contains(StateFlag::HomeOk) && !end.contains(StateFlag::Motion), "{end}");
        assert!(client.started().is_empty(), "the wait saw it stop");
        client.close().await.unwrap();
    })
}

#[test]
fn async_move_ramp_runs_to_its_target_and_wait_motion_end_waits_for_it() {
    run(async {
        let (_bus, client) = setup().await;
        let m = client.module(a(1));
        m.home().await.unwrap();
        m.wait_home(Duration::from_secs(5)).await.unwrap();
        assert_eq!(m.kind().await.unwrap(), ModuleKind::Rotary);
        let ramp = Ramp { vel: Velocity::rad_per_s(1.0), acc: Acceleration::rad_per_s2(2.0) };
        m.move_ramp(Position::rad(0.3), Some(ramp)).await.unwrap();
        assert!(m.state().await.unwrap().contains(StateFlag::Motion), "the ramp runs after its acknowledge");
        let end = m.wait_motion_end(Duration::from_secs(5)).await.unwrap();
        assert!(!end.contains(StateFlag::Motion) && end.contains(StateFlag::RampEnd), "{end}");
        let at = m.position().await.unwrap();
        assert_eq!(at.unit(), AxisUnit::Radian);
        assert!((at.value() - 0.3).abs() < 1e-3, "{at}");
        // The other reads of the blocking module, on the same position.
        let (fpos, short, _dio) = m.position_state_dio().await.unwrap();
        assert!((fpos.value() - 0.3).abs() < 1e-3 && short.contains(ShortFlag::RampEnd), "{fpos} {short:?}");
        let ticks = m.position_ticks().await.unwrap();
        let ratio = 4096.0 * 100.0 / std::f64::consts::TAU; // the emulator's default encoder ticks per rad
        assert!((f64::from(ticks.0) - 0.3 * ratio).abs() < 0.01 * ratio, "{ticks:?}");
        assert!(!m.config_word().await.unwrap().contains(ConfigFlag::Linear));
        // A ramp in m to a rotary module is refused before anything is sent.
        assert!(matches!(m.move_ramp(Position::m(0.1), None).await, Err(Error::UnitMismatch { .. })));
        client.close().await.unwrap();
    })
}

#[test]
fn async_stop_motion_halts_a_running_ramp_and_says_the_module_confirmed_it() {
    run(async {
        let (bus, client) = setup().await;
        let m = client.module(a(1));
        m.home().await.unwrap();
        m.wait_home(Duration::from_secs(5)).await.unwrap();
        let ramp = Ramp { vel: Velocity::rad_per_s(0.2), acc: Acceleration::rad_per_s2(2.0) };
        m.move_ramp(Position::rad(2.0), Some(ramp)).await.unwrap();
        assert!(m.state().await.unwrap().contains(StateFlag::Motion));
        assert_eq!(m.stop_motion().await, StopOutcome::Confirmed);
        let after = m.state().await.unwrap();
        assert!(after.contains(StateFlag::Halted) && !after.contains(StateFlag::Motion), "{after}");
        assert!(m.position().await.unwrap().value() < 1.0, "stopped on its way");
        assert!(client.started().is_empty());
        assert!(emulator_events(&bus, "module 1").iter().any(|e| e == "module 1 halted"));
        // Halted stays halted until a reset; the reset clears it.
        m.reset().await.unwrap();
        assert!(!m.state().await.unwrap().contains(StateFlag::Halted));
        client.close().await.unwrap();
    })
}

#[test]
fn async_request_many_answers_each_request_and_refuses_a_bad_one_alone() {
    run(async {
        let (_bus, client) = setup().await;
        let serial = Request::get(Param::DefCubeSerial).unwrap();
        let write_read_only = Request::Set(Param::DefCubeSerial, Value::U32(7));
        let replies =
            client.request_many(&[(a(1), serial), (a(2), serial), (a(1), write_read_only), (a(2), serial)]).await;
        assert_eq!(replies.len(), 4);
        assert_eq!(replies[0].as_ref().unwrap(), &Reply::Get(Param::DefCubeSerial, Value::U32(1001)));
        assert_eq!(replies[1].as_ref().unwrap(), &Reply::Get(Param::DefCubeSerial, Value::U32(1002)));
        assert!(matches!(replies[2], Err(Error::Model(_))), "{:?}", replies[2]);
        assert_eq!(replies[3].as_ref().unwrap(), &Reply::Get(Param::DefCubeSerial, Value::U32(1002)));
        assert_eq!(client.known(), vec![a(1), a(2)]);
        assert!(client.started().is_empty(), "reads set nothing in motion");
        client.close().await.unwrap();
    })
}

/// A move of a rotary module to `target` rad at 1 rad/s and 2 rad/s².
fn spec(target: f32) -> MoveSpec {
    MoveSpec {
        vel: Some(Velocity::rad_per_s(1.0)),
        acc: Some(Acceleration::rad_per_s2(2.0)),
        ..MoveSpec::to(Position::rad(target))
    }
}

/// State, position and whether the watchdog is online of module `n`, straight from the emulator, now.
fn device(bus: &CanBus<Emulator>, clock: &SharedClock, n: u8) -> (CubeState, f32, bool) {
    bus.with_device(|d| {
        d.update(clock.now());
        let m = d.module(n).unwrap();
        (m.state(), m.position().value(), m.watchdog_online())
    })
    .unwrap()
}

#[test]
fn two_guarded_moves_at_once_on_the_async_client_each_end_only_their_own_module() {
    run(async {
        let (bus, client) = setup().await;
        let clock = client.clock().clone();
        let (m1, m2) = (client.module(a(1)), client.module(a(2)));
        let (one, two) = motionlink_testkit::join2(
            m1.move_to_guarded(&spec(0.3), Guard::Watchdog),
            m2.move_to_guarded(&spec(1.2), Guard::Watchdog),
        )
        .await;
        for (n, target, result) in [(1, 0.3, one), (2, 1.2, two)] {
            let report = result.unwrap_or_else(|e| panic!("module {n}: {e}"));
            assert!((report.reached.value() - target).abs() <= 0.001 && report.verified, "module {n}: {report:?}");
        }
        assert!(!client.watchdog_served());
        assert_eq!(client.close().await.map_err(|e| e.to_string()), Ok(vec![]));
        tokio::time::sleep(Duration::from_millis(300)).await;
        for (n, target) in [(1, 0.3), (2, 1.2)] {
            let (state, position, online) = device(&bus, &clock, n);
            assert!(!state.contains(StateFlag::Halted) && !state.has_fault() && !online, "module {n}: {state}");
            assert!((position - target).abs() <= 0.001, "module {n}: {position}");
        }
    })
}

#[test]
fn two_guarded_moves_cancelled_on_the_async_client_halt_both_and_leave_no_watchdog_online() {
    run(async {
        let (bus, client) = setup().await;
        let clock = client.clock().clone();
        let one = client.start(Op::MoveGuarded(a(1), spec(1.2), Guard::Watchdog));
        let two = client.start(Op::MoveGuarded(a(2), spec(1.5), Guard::Watchdog));
        tokio::time::sleep(Duration::from_millis(400)).await;
        assert!(device(&bus, &clock, 1).0.contains(StateFlag::Motion) && device(&bus, &clock, 2).2, "under way");
        one.cancel();
        two.cancel();
        let (one, two) = motionlink_testkit::join2(one, two).await;
        for (n, result) in [(1, one), (2, two)] {
            assert!(
                matches!(result, Err(Error::Cancelled { address, stop: StopOutcome::Confirmed }) if address == a(n)),
                "module {n}: {result:?}"
            );
            let (state, _, online) = device(&bus, &clock, n);
            assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "module {n}: {state}");
            assert!(!online, "module {n}: watchdog offline");
        }
        // The moves halted their modules: the close has nothing left to halt, and says so truly.
        assert_eq!(client.close().await.map_err(|e| e.to_string()), Ok(vec![]));
        tokio::time::sleep(Duration::from_secs(1)).await;
        for n in [1, 2] {
            let (state, _, online) = device(&bus, &clock, n);
            assert!(!online && !state.contains(StateFlag::CommError), "module {n}: {state}");
        }
    })
}

#[test]
fn a_guarded_move_future_dropped_while_another_runs_leaves_the_other_going_to_its_target() {
    run(async {
        let (bus, client) = setup().await;
        let clock = client.clock().clone();
        let (m1, m2) = (client.module(a(1)), client.module(a(2)));
        let (far, near) = (spec(1.2), spec(0.9));
        let mut one = Box::pin(m1.move_to_guarded(&far, Guard::Watchdog));
        let mut two = Box::pin(m2.move_to_guarded(&near, Guard::Watchdog));
        let mut a_while = Box::pin(tokio::time::sleep(Duration::from_millis(400)));
        // Both polled for a while (neither ends), then the first dropped: what `select!` does to a losing branch.
        std::future::poll_fn(|cx| {
            assert!(one.as_mut().poll(cx).is_pending() && two.as_mut().poll(cx).is_pending(), "ended too soon");
            a_while.as_mut().poll(cx)
        })
        .await;
        drop(one);
        let report = two.await.unwrap_or_else(|e| panic!("module 2: {e}"));
        assert!((report.reached.value() - 0.9).abs() <= 0.001 && report.verified, "{report:?}");
        let (state, position, online) = device(&bus, &clock, 2);
        assert!(!state.contains(StateFlag::Halted) && !state.has_fault() && !online, "{state}");
        assert!((position - 0.9).abs() <= 0.001, "{position}");
        client.close().await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
        let (state, _, online) = device(&bus, &clock, 1);
        assert!(state.contains(StateFlag::Halted) && !online && !state.contains(StateFlag::CommError), "{state}");
    })
}

#[test]
fn async_run_motion_holds_a_velocity_and_ends_it_and_a_guarded_step_reaches_its_target() {
    use motionlink_powercube::client::{MotionEnding, MotionSpec};
    use motionlink_powercube::model::{AckKind, Millis, Motion, MotionId};
    run(async {
        let (bus, client) = setup().await;
        let m = client.module(a(1));
        let spec = MotionSpec {
            ack: AckKind::Extended,
            hold: Some(Duration::from_millis(200)),
            ..MotionSpec::new(Motion::FVel { vel: Velocity::rad_per_s(0.2) })
        };
        let report = m.run_motion(&spec).await.unwrap();
        assert_eq!((report.mode, report.ending), (MotionId::FVelAck, MotionEnding::VelocityZero));
        assert!(report.ext_ack.is_some() && report.held.unwrap() >= Duration::from_millis(200), "{report:?}");
        assert!(report.reached.value() > report.start.value(), "{report:?}");
        assert!(!m.state().await.unwrap().contains(StateFlag::Halted));
        let step = MotionSpec::new(Motion::FStep { pos: Position::rad(0.1), time: Millis(300) });
        let report = m.run_motion_guarded(&step, Guard::Watchdog).await.unwrap();
        assert_eq!(report.ending, MotionEnding::Reached);
        assert!((report.reached.value() - 0.1).abs() <= 1e-3 && report.verified, "{report:?}");
        assert!(emulator_events(&bus, "module 1 watchdog").iter().any(|e| e.ends_with("offline")));
        client.close().await.unwrap();
    })
}

#[test]
fn async_setpoints_stream_a_velocity_with_the_watchdog_held_until_the_close() {
    use motionlink_powercube::model::{AckKind, Motion, MotionId};
    use motionlink_powercube::wire::AckPosition;
    run(async {
        let (bus, client) = setup().await;
        let m = client.module(a(1));
        let vel = Motion::FVel { vel: Velocity::rad_per_s(0.2) };
        let mut positions = Vec::new();
        for _ in 0..20 {
            let report = m.setpoint(vel, AckKind::Extended, Guard::Watchdog).await.unwrap();
            assert_eq!((report.mode, report.kind, report.watchdog), (MotionId::FVelAck, ModuleKind::Rotary, true));
            match report.ext_ack.map(|e| e.position) {
                Some(AckPosition::Unit(p)) => positions.push(p.value()),
                other => panic!("{other:?}"),
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert!(positions.windows(2).skip(1).all(|w| w[1] > w[0]), "{positions:?}");
        assert!(client.watchdog_armed(a(1)), "armed after the calls returned");
        assert_eq!(client.close().await.map_err(|e| e.to_string()), Ok(vec![a(1)]));
        let events = emulator_events(&bus, "module 1");
        assert!(events.iter().any(|e| e.ends_with("halted")), "{events:?}");
        assert!(events.last().is_some_and(|e| e.ends_with("watchdog offline")), "{events:?}");
    })
}
