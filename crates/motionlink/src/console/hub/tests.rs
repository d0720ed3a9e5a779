//! The hub's rules with a fake device: dead-man time, one controlling page, stops.

use super::*;
use crate::console::device::Motion as DeviceMotion;
use crate::console::device::{Action, BoxFuture, JogDirection, Naming, Param, Report, Sample};
use crate::console::traffic::Traffic;
use motionlink_link::clock::ManualClock;
use serde_json::json;
use std::sync::atomic::{AtomicUsize, Ordering};
use tokio::sync::mpsc;

/// A device whose motions run until dropped; each drop and each stop is reported.
struct Fake {
    dropped: mpsc::UnboundedSender<std::time::Instant>,
    running: mpsc::UnboundedSender<()>,
    stops: AtomicUsize,
    stop_started: AtomicUsize,
    /// Its stop is not confirmed (a silent line).
    stop_fails: std::sync::atomic::AtomicBool,
}

struct OnDrop(mpsc::UnboundedSender<std::time::Instant>);

impl Drop for OnDrop {
    fn drop(&mut self) {
        let _ = self.0.send(std::time::Instant::now());
    }
}

impl Fake {
    fn forever(&self) -> DeviceMotion {
        let tx = self.dropped.clone();
        let running = self.running.clone();
        Box::pin(async move {
            let _ = running.send(());
            // Made when the motion runs: a motion refused before it started reports no drop.
            let _guard = OnDrop(tx);
            std::future::pending::<()>().await;
            Ok(serde_json::Value::Null)
        })
    }
}

impl Device for Fake {
    fn naming(&self) -> Naming {
        Naming { family: "compax", unit_key: "drive", unit_numbers: 1..=31 }
    }

    fn port(&self) -> String {
        "fake".into()
    }
    fn discover(&self) -> BoxFuture<'_, Result<Vec<Unit>, ErrorReport>> {
        Box::pin(async { Ok(Vec::new()) })
    }
    fn sample<'a>(&'a self, _units: &'a [Unit]) -> BoxFuture<'a, Vec<Result<Sample, ErrorReport>>> {
        Box::pin(async { Vec::new() })
    }
    fn move_to(self: Arc<Self>, _unit: u8, _target: f64, _speed: Option<f64>) -> Result<DeviceMotion, ErrorReport> {
        Ok(self.forever())
    }
    fn jog(
        self: Arc<Self>,
        _unit: u8,
        _direction: JogDirection,
        _speed: Option<f64>,
    ) -> Result<DeviceMotion, ErrorReport> {
        Ok(self.forever())
    }
    fn stop(self: Arc<Self>, unit: u8) -> DeviceMotion {
        self.stops.fetch_add(1, Ordering::SeqCst);
        if self.stop_fails.load(Ordering::SeqCst) {
            let e = ErrorReport::new("timeout", format!("drive {unit}: no reply to S17"), 3);
            return Box::pin(async move { Err(e) });
        }
        Box::pin(async move { Ok(serde_json::json!({"action": "stop", "drive": unit})) })
    }
    fn stop_started(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        self.stop_started.fetch_add(1, Ordering::SeqCst);
        Box::pin(async { Ok(String::new()) })
    }
    fn actions(&self) -> Vec<Action> {
        Vec::new()
    }
    fn action(self: Arc<Self>, _unit: u8, name: &str) -> Result<DeviceMotion, ErrorReport> {
        Err(ErrorReport::usage(name))
    }
    fn params(&self) -> Vec<Param> {
        Vec::new()
    }
    fn read_param(self: Arc<Self>, _unit: u8, _name: String) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async { Err(ErrorReport::usage("none")) })
    }
    fn write_param(
        self: Arc<Self>,
        _unit: u8,
        _name: String,
        _value: String,
    ) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async { Err(ErrorReport::usage("none")) })
    }
    fn errors(self: Arc<Self>, _unit: u8) -> BoxFuture<'static, Result<Report, ErrorReport>> {
        Box::pin(async { Err(ErrorReport::usage("none")) })
    }
    fn close(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>> {
        Box::pin(async { Ok(String::new()) })
    }
}

type Dropped = mpsc::UnboundedReceiver<std::time::Instant>;
type Running = mpsc::UnboundedReceiver<()>;

fn hub() -> (Arc<Hub>, Arc<Fake>, Dropped, Running) {
    let (tx, rx) = mpsc::unbounded_channel();
    let (running, running_rx) = mpsc::unbounded_channel();
    let fake = Arc::new(Fake {
        dropped: tx,
        running,
        stops: AtomicUsize::new(0),
        stop_started: AtomicUsize::new(0),
        stop_fails: Default::default(),
    });
    let clock = ManualClock::new().shared();
    let traffic = Arc::new(Traffic::new(
        Box::new(motionlink_compax::describe::Describer::new(motionlink_compax::wire::Mode::from_p196(0).unwrap())),
        "fake",
        "can0",
        &clock,
    ));
    (Hub::new(Arc::clone(&fake) as Arc<dyn Device>, traffic), fake, rx, running_rx)
}

fn motion(fake: &Arc<Fake>) -> DeviceMotion {
    fake.forever()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_jog_without_renewals_is_stopped_after_the_dead_man_time() {
    let (hub, fake, mut dropped, _running) = hub();
    let (page, role) = hub.page_opened();
    assert_eq!(role, Role::Control);
    let started = std::time::Instant::now();
    hub.start_motion(page, 1, "jog", true, motion(&fake)).unwrap();
    // Renewed for 400 ms: still running.
    let mut last = started;
    while started.elapsed() < Duration::from_millis(400) {
        assert!(hub.renew_jog(page));
        last = std::time::Instant::now();
        tokio::time::sleep(Duration::from_millis(50)).await;
        assert!(dropped.try_recv().is_err(), "dropped while renewed");
    }
    let at = dropped.recv().await.unwrap();
    let after = at.duration_since(last);
    assert!(after >= DEAD_MAN && after < DEAD_MAN + Duration::from_millis(150), "{after:?}");
    // The stop is asked again and confirmed.
    tokio::time::sleep(Duration::from_millis(20)).await;
    assert_eq!(fake.stops.load(Ordering::SeqCst), 1);
    assert!(!hub.renew_jog(page), "no jog left to renew");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_the_controlling_page_moves_and_its_going_stops_its_motion() {
    let (hub, fake, mut dropped, mut running) = hub();
    let (first, _) = hub.page_opened();
    let (second, role) = hub.page_opened();
    assert_eq!(role, Role::ReadOnly);
    let e = hub.start_motion(second, 1, "move", false, motion(&fake)).unwrap_err();
    assert!(e.message.contains("read-only"), "{e}");
    assert!(!hub.take_control(second));
    hub.start_motion(first, 1, "move", false, motion(&fake)).unwrap();
    running.recv().await.unwrap();
    // One motion at a time.
    assert!(hub.start_motion(first, 2, "move", false, motion(&fake)).is_err());
    // The read-only page going changes nothing; the owner going stops its motion.
    hub.page_closed(second);
    assert!(tokio::time::timeout(Duration::from_millis(300), dropped.recv()).await.is_err());
    hub.page_closed(first);
    tokio::time::timeout(Duration::from_secs(1), dropped.recv()).await.expect("stopped").unwrap();
    let (third, role) = hub.page_opened();
    assert_eq!(role, Role::Control, "control is free again");
    assert_eq!(hub.role_of(third).0, Role::Control);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stop_from_a_read_only_page_and_shutdown_stop_the_motion() {
    let (hub, fake, mut dropped, mut running) = hub();
    let (first, _) = hub.page_opened();
    let (second, _) = hub.page_opened();
    hub.start_motion(first, 1, "move", false, motion(&fake)).unwrap();
    running.recv().await.unwrap();
    let mut notices = hub.notices();
    let answer = hub.stop(Some(1)).await.unwrap().json();
    assert!(answer.get("report").is_none(), "the motion's own task reports the stop: {answer}");
    tokio::time::timeout(Duration::from_secs(1), dropped.recv()).await.expect("Stop stops it").unwrap();
    // The motion's end carries the report of the confirmed stop.
    let end = loop {
        let Ok(Ok(Notice::Json(m))) = tokio::time::timeout(Duration::from_secs(1), notices.recv()).await else {
            panic!("no notice of the stop");
        };
        let m: serde_json::Value = serde_json::from_str(&m).unwrap();
        if m["state"] == "stopped" {
            break m;
        }
    };
    assert_eq!((&end["ok"], &end["report"]), (&json!(true), &json!({"action": "stop", "drive": 1})), "{end}");
    assert!(end["message"].as_str().unwrap().contains("Stop pressed"), "{end}");
    // A unit the console did not set in motion is stopped at once, with the report of its stop.
    let other = hub.stop(Some(2)).await.unwrap().json();
    assert_eq!((&other["type"], &other["report"]), (&json!("stopped"), &json!({"action": "stop", "drive": 2})));
    let _ = second;
    // The ended motion's task clears its slot after the confirmed stop.
    while hub.start_motion(first, 1, "move", false, motion(&fake)).is_err() {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    running.recv().await.unwrap();
    hub.shutdown().await.unwrap();
    tokio::time::timeout(Duration::from_secs(1), dropped.recv()).await.expect("shutdown stops it").unwrap();
    assert_eq!(fake.stop_started.load(Ordering::SeqCst), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stop_the_device_does_not_confirm_is_said_with_its_error_flagged() {
    let (hub, fake, mut dropped, mut running) = hub();
    fake.stop_fails.store(true, Ordering::SeqCst);
    let (page, _) = hub.page_opened();
    hub.start_motion(page, 1, "move", false, motion(&fake)).unwrap();
    running.recv().await.unwrap();
    let mut notices = hub.notices();
    hub.page_closed(page);
    tokio::time::timeout(Duration::from_secs(1), dropped.recv()).await.expect("stopped").unwrap();
    let end = loop {
        let Ok(Ok(notice)) = tokio::time::timeout(Duration::from_secs(1), notices.recv()).await else {
            panic!("no notice of the stop");
        };
        // The page's going changes the roles first.
        let Notice::Json(m) = notice else { continue };
        let m: serde_json::Value = serde_json::from_str(&m).unwrap();
        if m["state"] == "stopped" {
            break m;
        }
    };
    assert_eq!((&end["ok"], end.get("report")), (&json!(false), None), "{end}");
    assert!(end["message"].as_str().unwrap().contains("the stop is not confirmed: drive 1: no reply to S17"), "{end}");
    let error = &end["error"];
    assert_eq!(
        (&error["kind"], &error["exit_code"], &error["stop_unconfirmed"]),
        (&json!("timeout"), &json!(3), &json!(true))
    );
}
