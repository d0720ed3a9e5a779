//! The async client on tokio against the emulator in this process (real clock, 38400 baud): the same
//! operations as the blocking client, and the same safety when futures and streams are dropped.

#![cfg(feature = "tokio")]

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::RealClock;
use motionlink_scu::model::{Actuator, DataIndex, MotionFunction, PositionCounts, Speed};
use motionlink_scu::sim::RemoteMode;
use motionlink_scu::value::Value;
use motionlink_scu::{AsyncClient, Config, Emulator, FunctionMap, SimConfig};

fn setup() -> (EmulatorHost<Emulator>, impl std::future::Future<Output = AsyncClient>) {
    let clock = RealClock::shared();
    let unit =
        EmulatorHost::new(Emulator::new(SimConfig::default()).unwrap(), Arc::clone(&clock), PipeConfig::paced(38_400));
    let host = unit.clone();
    let config = Config { function_map: FunctionMap::scp11(), ..Config::default() };
    let connector = host.connector();
    (unit, async move { AsyncClient::with_connector(connector, clock, config).await.unwrap() })
}

/// Waits (at most 2 s) until `done` says so.
async fn eventually(mut done: impl FnMut() -> bool) -> bool {
    for _ in 0..200 {
        if done() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    false
}

#[test]
fn a_session_opened_by_the_port_s_name_runs_over_tcp_and_its_close_says_what_it_stopped() {
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    let clock = RealClock::shared();
    let unit = Arc::new(std::sync::Mutex::new(Emulator::new(SimConfig::default()).unwrap()));
    let server = motionlink_link::emulator::serve_tcp("127.0.0.1:0", Arc::clone(&unit), clock.clone()).unwrap();
    runtime.block_on(async {
        let url = server.address().parse().unwrap();
        let config = Config { function_map: FunctionMap::scp11(), ..Config::default() };
        let client = AsyncClient::open(&url, clock, config).await.unwrap();
        let f1 = MotionFunction::new(1).unwrap();
        client.start_motion(f1, motionlink_scu::model::MotionDirection::Out).await.unwrap();
        assert_eq!(client.started().len(), 1);
        // The close stops F1 (RS) and says so.
        let stopped = client.close().await.unwrap();
        assert_eq!(stopped.iter().map(|f| f.id()).collect::<Vec<_>>(), [f1.id()]);
    });
    assert_eq!(unit.lock().unwrap().mode(), RemoteMode::Off);
    assert!(!unit.lock().unwrap().any_moving(), "F1 was stopped");
}

#[test]
fn writes_are_read_back_and_a_move_reaches_its_target() {
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    runtime.block_on(async {
        let (unit, client) = setup();
        let client = client.await;
        client.set(DataIndex(0x3012), &Value::RemoteSpeed(55)).await.unwrap();
        assert_eq!(client.get_value(DataIndex(0x3012)).await.unwrap(), Value::RemoteSpeed(55));
        // Raw bytes, read back as well (little-endian remote speed 40 %).
        client.set_raw(DataIndex(0x3012), &[40, 0]).await.unwrap();
        assert_eq!(client.get_value(DataIndex(0x3012)).await.unwrap(), Value::RemoteSpeed(40));
        // Any operation by `run`, as in every family: the same read as an `Op`.
        let read = client.run(motionlink_scu::Op::Read(DataIndex(0x3012))).await.unwrap();
        assert!(matches!(read, motionlink_scu::Output::Data(Some(ref d)) if d[..] == [40, 0]), "{read:?}");
        assert!(client.is_open() && client.not_open_reason().is_none());
        let a1 = Actuator::new(1).unwrap();
        let report = client.move_to(a1, PositionCounts(60), Speed::percent(100).unwrap(), None).await.unwrap();
        assert_eq!(report.position_counts, PositionCounts(60));
        assert_eq!(unit.with_device(|u| u.position(a1)), Some(60));
        client.close().await.unwrap();
        assert_eq!(unit.with_device(|u| u.mode()), RemoteMode::Off);
    })
}

#[test]
fn a_dropped_stream_stops_its_function_and_a_dropped_client_ends_the_session() {
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    runtime.block_on(async {
        let (unit, client) = setup();
        let client = client.await;
        let a1 = Actuator::new(1).unwrap();
        let f1 = MotionFunction::new(1).unwrap();
        let mut stream = client.stream(f1, &[a1], Speed::percent(100).unwrap()).await.unwrap();
        stream.set_targets(&[PositionCounts(800)]).await.unwrap();
        assert!(eventually(|| unit.with_device(|u| u.is_moving(a1))).await);
        drop(stream);
        assert!(eventually(|| !unit.with_device(|u| u.is_moving(a1))).await, "the dropped stream stopped F1");
        assert!(eventually(|| client.started().is_empty()).await);
        // A function left started when the client is dropped gets its RS, and the session its RA.
        client.start_motion(f1, motionlink_scu::model::MotionDirection::Out).await.unwrap();
        assert!(eventually(|| unit.with_device(|u| u.is_moving(a1))).await);
        drop(client);
        assert!(eventually(|| unit.with_device(|u| !u.any_moving() && u.mode() == RemoteMode::Off)).await);
        assert!(unit.with_device(|u| u.executed_functions().is_empty()));
    })
}

#[test]
fn a_switching_function_is_read_back_after_its_re_and_its_rs() {
    use motionlink_scu::model::Function;
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    runtime.block_on(async {
        let (unit, client) = setup();
        let client = client.await;
        let on = client.switch(Function::BinaryOutput2, true).await.unwrap();
        assert!(on.on && on.verified, "{on:?}");
        let off = client.switch(Function::BinaryOutput2, false).await.unwrap();
        assert!(!off.on && off.verified, "{off:?}");
        // An output that fails: the unit acknowledges the RE, binary_outputs shows it off.
        unit.with_device(|u| u.fail_switch(Function::BinaryOutput2));
        let e = client.switch(Function::BinaryOutput2, true).await.unwrap_err();
        assert!(matches!(e, motionlink_scu::Error::SwitchNotShown { .. }), "{e}");
        client.close().await.unwrap();
    })
}
