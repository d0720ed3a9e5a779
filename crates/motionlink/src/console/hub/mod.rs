//! The console's rules, kept on the server whatever a page does: one page at a time controls (the others
//! are read-only); at most one motion runs, owned by the page that started it; a jog runs only while its page
//! renews it (a dead-man deadline of [`DEAD_MAN`]); a page that goes away (closed tab, lost WebSocket)
//! stops the motion it owns, and so does the end of the console.
//!
//! A motion is a future of the family's `AsyncClient` ([`Device`]): the hub stops it by dropping it, which
//! makes the library stop the axis; then it asks the device for the stop ([`Device::stop`]) and reports
//! what the device confirmed.

use motionlink_link::error::{ErrorClass, TransportKind};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::clock::lock;
use tokio::sync::{broadcast, oneshot, watch};
use tokio::task::JoinHandle;
use tokio::time::Instant;

use super::device::{Device, ErrorReport, Motion as DeviceMotion, Report, Unit};
use super::message::{Message, SampleEntry};
use super::traffic::Traffic;
use crate::common::Keyed;

/// How long a jog runs without a renewal from its page.
pub const DEAD_MAN: Duration = Duration::from_millis(200);
/// How often the device is sampled for the pages (25 Hz, when the line is fast enough).
pub const SAMPLE_PERIOD: Duration = Duration::from_millis(40);
/// How long the hub waits before it scans again after a scan found nothing or failed.
const RESCAN_AFTER: Duration = Duration::from_secs(2);
/// How long the end of the console waits for its pages to have been told to go (the stop's message and the
/// bye sent, the WebSocket closed) before the session closes and the process ends.
const PAGES_TOLD: Duration = Duration::from_secs(2);
/// What the pages are told when the console ends (the stop's reason, the bye, the WebSocket's close, a
/// request refused meanwhile).
pub const ENDING: &str = "the console is ending";

/// What the hub found on the link.
#[derive(Debug, Clone, PartialEq)]
pub enum Units {
    /// The scan is under way.
    Scanning,
    /// These units answered.
    Found(Vec<Unit>),
    /// The scan failed (it is tried again).
    Failed(ErrorReport),
}

/// Why a motion was stopped before it ended by itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// The Stop button (or Escape) of a page.
    StopButton,
    /// The jog button was let go.
    Released,
    /// The page did not renew its jog within [`DEAD_MAN`].
    DeadMan,
    /// The page that owned the motion went away (closed tab, lost WebSocket).
    PageGone,
    /// The console is ending (a signal).
    ConsoleEnding,
}

impl StopReason {
    fn text(self) -> &'static str {
        match self {
            StopReason::StopButton => "Stop pressed",
            StopReason::Released => "jog released",
            StopReason::DeadMan => "the page stopped renewing its jog (dead-man deadline passed)",
            StopReason::PageGone => "the page that started it went away",
            StopReason::ConsoleEnding => ENDING,
        }
    }
}

/// Something every page is told.
#[derive(Debug, Clone)]
pub enum Notice {
    /// A message as it is (JSON text).
    Json(Arc<String>),
    /// Who controls changed: each page tells its own role.
    RoleChanged,
    /// The units found changed.
    UnitsChanged,
}

struct Motion {
    id: u64,
    owner: u64,
    unit: u8,
    what: String,
    /// The dead-man deadline of a jog.
    deadline: Option<Instant>,
    cancel: Option<oneshot::Sender<StopReason>>,
    task: Option<JoinHandle<()>>,
}

struct State {
    controller: Option<u64>,
    next_page: u64,
    motion: Option<Motion>,
    next_motion: u64,
    /// The console is ending: no motion starts; the pages are told to go once the motion is stopped.
    ending: bool,
}

/// The console's shared state: the device, who controls, the motion under way, the latest sample.
pub struct Hub {
    device: Arc<dyn Device>,
    /// The link's traffic.
    pub traffic: Arc<Traffic>,
    units: watch::Sender<Units>,
    samples: watch::Sender<Option<Arc<String>>>,
    notices: broadcast::Sender<Notice>,
    shutdown: watch::Sender<bool>,
    /// How many pages are connected.
    pages_open: watch::Sender<usize>,
    state: Mutex<State>,
    started: Instant,
    poller: Mutex<Option<JoinHandle<()>>>,
}

/// A page's role.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// It may move the axes and write.
    Control,
    /// It sees, reads, and may press Stop.
    ReadOnly,
}

impl Role {
    /// "control" or "read_only".
    pub fn name(self) -> &'static str {
        match self {
            Role::Control => "control",
            Role::ReadOnly => "read_only",
        }
    }
}

impl Hub {
    /// A hub over `device`, logging `traffic`. Call [`Hub::start`] to scan and sample.
    pub fn new(device: Arc<dyn Device>, traffic: Arc<Traffic>) -> Arc<Hub> {
        Arc::new(Hub {
            device,
            traffic,
            units: watch::channel(Units::Scanning).0,
            samples: watch::channel(None).0,
            notices: broadcast::channel(256).0,
            shutdown: watch::channel(false).0,
            pages_open: watch::channel(0).0,
            state: Mutex::new(State { controller: None, next_page: 1, motion: None, next_motion: 1, ending: false }),
            started: Instant::now(),
            poller: Mutex::new(None),
        })
    }

    /// The device.
    pub fn device(&self) -> &Arc<dyn Device> {
        &self.device
    }

    /// Seconds since the hub was made.
    pub fn t_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Starts the scan and then the sampling, on the current tokio runtime.
    pub fn start(self: &Arc<Self>) {
        let hub = Arc::clone(self);
        *lock(&self.poller) = Some(tokio::spawn(async move { hub.poll().await }));
    }

    /// The units found so far.
    pub fn units(&self) -> watch::Receiver<Units> {
        self.units.subscribe()
    }

    /// The latest sample frame (JSON text).
    pub fn samples(&self) -> watch::Receiver<Option<Arc<String>>> {
        self.samples.subscribe()
    }

    /// Notices for every page.
    pub fn notices(&self) -> broadcast::Receiver<Notice> {
        self.notices.subscribe()
    }

    /// Becomes true when the console ends.
    pub fn shutdown_signal(&self) -> watch::Receiver<bool> {
        self.shutdown.subscribe()
    }

    fn notify(&self, message: Message) {
        let _ = self.notices.send(Notice::Json(Arc::new(message.json().to_string())));
    }

    async fn poll(self: Arc<Self>) {
        let units = loop {
            self.units.send_replace(Units::Scanning);
            let _ = self.notices.send(Notice::UnitsChanged);
            match self.device.discover().await {
                Ok(found) if !found.is_empty() => break found,
                Ok(_) => {
                    let what = format!("no {} answered on {}", self.device.naming().unit_key, self.device.port());
                    self.units.send_replace(Units::Failed(ErrorReport::classed(
                        ErrorClass::Transport(TransportKind::Timeout),
                        what,
                    )));
                }
                Err(e) => {
                    self.units.send_replace(Units::Failed(e));
                }
            }
            let _ = self.notices.send(Notice::UnitsChanged);
            tokio::time::sleep(RESCAN_AFTER).await;
        };
        self.units.send_replace(Units::Found(units.clone()));
        let _ = self.notices.send(Notice::UnitsChanged);
        let key = self.device.naming().unit_key;
        let mut due = Instant::now();
        loop {
            let t_s = self.t_s();
            let results = self.device.sample(&units).await;
            let units = units.iter().zip(results).map(|(u, r)| SampleEntry::of(u, key, r)).collect();
            let frame = Message::Sample { t_s, units }.json();
            self.samples.send_replace(Some(Arc::new(frame.to_string())));
            // The next look on a fixed schedule; a slow line is not made up for with a burst.
            due += SAMPLE_PERIOD;
            let now = Instant::now();
            if due < now {
                due = now;
            }
            tokio::time::sleep_until(due).await;
        }
    }

    /// A page opened: its id and role (it controls if nobody does).
    pub fn page_opened(&self) -> (u64, Role) {
        let mut st = lock(&self.state);
        let id = st.next_page;
        st.next_page += 1;
        let role = if st.controller.is_none() {
            st.controller = Some(id);
            Role::Control
        } else {
            Role::ReadOnly
        };
        drop(st);
        self.pages_open.send_modify(|n| *n += 1);
        let _ = self.notices.send(Notice::RoleChanged);
        (id, role)
    }

    /// The role of page `page`, and whether control is free.
    pub fn role_of(&self, page: u64) -> (Role, bool) {
        let st = lock(&self.state);
        let role = if st.controller == Some(page) { Role::Control } else { Role::ReadOnly };
        (role, st.controller.is_none())
    }

    /// Page `page` asks for control: granted only if nobody has it.
    pub fn take_control(&self, page: u64) -> bool {
        let mut st = lock(&self.state);
        let granted = match st.controller {
            None => {
                st.controller = Some(page);
                true
            }
            Some(c) => c == page,
        };
        drop(st);
        if granted {
            let _ = self.notices.send(Notice::RoleChanged);
        }
        granted
    }

    /// Page `page` went away (closed, reloaded, its WebSocket lost): the motion it owns is stopped and
    /// control is free again if it had it.
    pub fn page_closed(&self, page: u64) {
        let mut st = lock(&self.state);
        if st.controller == Some(page) {
            st.controller = None;
        }
        let owned = st.motion.as_mut().filter(|m| m.owner == page).and_then(|m| m.cancel.take());
        drop(st);
        if let Some(cancel) = owned {
            let _ = cancel.send(StopReason::PageGone);
        }
        self.pages_open.send_modify(|n| *n = n.saturating_sub(1));
        let _ = self.notices.send(Notice::RoleChanged);
    }

    /// Checks that `page` controls.
    pub fn check_control(&self, page: u64) -> Result<(), ErrorReport> {
        if lock(&self.state).controller == Some(page) {
            Ok(())
        } else {
            Err(ErrorReport::usage("this page is read-only: another page controls the console"))
        }
    }

    /// Starts `motion` on `unit` for page `page`, which must control and must not have a motion under
    /// way. A jog (`jog: true`) runs only while [`Hub::renew_jog`] renews it within [`DEAD_MAN`].
    pub fn start_motion(
        self: &Arc<Self>,
        page: u64,
        unit: u8,
        what: &str,
        jog: bool,
        motion: DeviceMotion,
    ) -> Result<(), ErrorReport> {
        let mut st = lock(&self.state);
        if st.ending {
            return Err(ErrorReport::usage(ENDING));
        }
        if st.controller != Some(page) {
            return Err(ErrorReport::usage("this page is read-only: another page controls the console"));
        }
        if let Some(m) = &st.motion {
            return Err(ErrorReport::usage(format!("{} of {} is under way: stop it first", m.what, m.unit)));
        }
        let id = st.next_motion;
        st.next_motion += 1;
        let (cancel, cancelled) = oneshot::channel();
        let deadline = jog.then(|| Instant::now() + DEAD_MAN);
        st.motion =
            Some(Motion { id, owner: page, unit, what: what.to_string(), deadline, cancel: Some(cancel), task: None });
        let hub = Arc::clone(self);
        let what = what.to_string();
        let task = tokio::spawn(async move { hub.run_motion(id, unit, what, motion, cancelled).await });
        if let Some(m) = st.motion.as_mut().filter(|m| m.id == id) {
            m.task = Some(task);
        }
        Ok(())
    }

    /// The dead-man deadline of motion `id`, if it is a jog still under way.
    fn deadline_of(&self, id: u64) -> Option<Instant> {
        lock(&self.state).motion.as_ref().filter(|m| m.id == id).and_then(|m| m.deadline)
    }

    async fn run_motion(
        self: Arc<Self>,
        id: u64,
        unit: u8,
        what: String,
        mut motion: DeviceMotion,
        mut cancelled: oneshot::Receiver<StopReason>,
    ) {
        let key = Keyed(self.device.naming().unit_key, unit);
        let motion_message = |state, ok, reason, error, message, report| Message::Motion {
            state,
            what: what.clone(),
            unit: key,
            ok,
            reason,
            error,
            message,
            report,
        };
        self.notify(motion_message("running", None, None, None, None, None));
        enum End {
            Done(Result<Report, ErrorReport>),
            Stopped(StopReason),
        }
        let end = loop {
            let deadline = self.deadline_of(id);
            let dead_man = async {
                match deadline {
                    Some(d) => tokio::time::sleep_until(d).await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                r = &mut motion => break End::Done(r),
                reason = &mut cancelled => break End::Stopped(reason.unwrap_or(StopReason::ConsoleEnding)),
                () = dead_man => {
                    // Renewed meanwhile: wait for the new deadline.
                    if self.deadline_of(id).is_none_or(|d| d <= Instant::now()) {
                        break End::Stopped(StopReason::DeadMan);
                    }
                }
            }
        };
        // Dropping the motion's future is what stops it: the library sends the stop at once.
        drop(motion);
        let ended = match end {
            End::Done(Ok(report)) => {
                let msg = format!("{what} of {} {unit} ended", key.0);
                motion_message("ended", Some(true), None, None, Some(msg), Some(report))
            }
            End::Done(Err(e)) => {
                let msg = e.message.clone();
                motion_message("ended", Some(false), None, Some(e), Some(msg), None)
            }
            End::Stopped(reason) => {
                // The stop the library sent when the future was dropped, asked again and confirmed.
                let confirmed = Arc::clone(&self.device).stop(unit).await;
                let (ok, msg, report, error) = match confirmed {
                    Ok(r) => (true, format!("{what} stopped: {}; the stop confirmed", reason.text()), Some(r), None),
                    Err(e) => {
                        let msg = format!("{what} stopped ({}), but the stop is not confirmed: {e}", reason.text());
                        // Whatever failed, the axis may still be moving.
                        (false, msg, None, Some(ErrorReport { stop_unconfirmed: true, ..e }))
                    }
                };
                motion_message("stopped", Some(ok), Some(reason.text()), error, Some(msg), report)
            }
        };
        let mut st = lock(&self.state);
        if st.motion.as_ref().is_some_and(|m| m.id == id) {
            st.motion = None;
        }
        drop(st);
        self.notify(ended);
    }

    /// Renews the jog of page `page`; false if it has none (it ended or was stopped).
    pub fn renew_jog(&self, page: u64) -> bool {
        let mut st = lock(&self.state);
        match st.motion.as_mut() {
            Some(m) if m.owner == page && m.deadline.is_some() && m.cancel.is_some() => {
                m.deadline = Some(Instant::now() + DEAD_MAN);
                true
            }
            _ => false,
        }
    }

    /// The jog of page `page` is let go: true if it had one under way (now stopping).
    pub fn release_jog(&self, page: u64) -> bool {
        let mut st = lock(&self.state);
        let jog = st.motion.as_mut().filter(|m| m.owner == page && m.deadline.is_some());
        let had = jog.is_some();
        let cancel = jog.and_then(|m| m.cancel.take());
        drop(st);
        if let Some(c) = cancel {
            let _ = c.send(StopReason::Released);
        }
        had
    }

    /// Stops the console's motion under way, whichever page started it (as Stop does): its unit and what it
    /// is, if one runs; its task stops the unit and reports the stop.
    pub fn stop_motion(&self) -> Option<(u8, String)> {
        let running = lock(&self.state).motion.as_mut().map(|m| (m.unit, m.what.clone(), m.cancel.take()));
        let (unit, what, cancel) = running?;
        if let Some(c) = cancel {
            let _ = c.send(StopReason::StopButton);
        }
        Some((unit, what))
    }

    /// The Stop button of any page (a read-only page may stop too: a stop never sets anything in motion).
    /// Stops the console's motion, and `unit` if the motion was not its own (or none ran); the answer to the
    /// page (the motion's own end is told by its task, with the report of its stop).
    pub async fn stop(self: &Arc<Self>, unit: Option<u8>) -> Result<Message, ErrorReport> {
        let motion_unit = self.stop_motion().map(|(u, _)| u);
        let key = self.device.naming().unit_key;
        match unit {
            // The motion's task stops its unit and reports it.
            Some(u) if Some(u) != motion_unit => {
                let report = Arc::clone(&self.device).stop(u).await?;
                Ok(Message::Stopped { ok: true, message: format!("{key} {u} stopped"), report: Some(report) })
            }
            None if motion_unit.is_none() => {
                let mut message = Arc::clone(&self.device).stop_started().await?;
                if message.is_empty() {
                    message = "nothing this console set in motion was moving".into();
                }
                Ok(Message::Stopped { ok: true, message, report: None })
            }
            _ => Ok(Message::Stopped { ok: true, message: "stopping the motion under way".into(), report: None }),
        }
    }

    /// True once the console is ending ([`Hub::shutdown`]): requests other than Stop are refused.
    pub fn ending(&self) -> bool {
        lock(&self.state).ending
    }

    /// Ends the console: no motion starts any more, the motion under way is stopped (and its stop awaited:
    /// the pages get its `motion` message, "the console is ending"), then the pages are told to go (waited
    /// for, at most 2 s), sampling ends, and whatever the session still has in motion is stopped. Returns
    /// what was stopped.
    pub async fn shutdown(self: &Arc<Self>) -> Result<String, ErrorReport> {
        let motion = {
            let mut st = lock(&self.state);
            st.ending = true;
            st.motion.as_mut().map(|m| (m.cancel.take(), m.task.take()))
        };
        if let Some((cancel, task)) = motion {
            if let Some(c) = cancel {
                let _ = c.send(StopReason::ConsoleEnding);
            }
            if let Some(t) = task {
                let _ = t.await;
            }
        }
        self.shutdown.send_replace(true);
        // Each page sends what it has and the bye, and closes its WebSocket, on its own task: waited for
        // (bounded), so that the end of the process does not cut a page off before it was told.
        let mut pages = self.pages_open.subscribe();
        let _ = tokio::time::timeout(PAGES_TOLD, pages.wait_for(|n| *n == 0)).await;
        let poller = lock(&self.poller).take();
        if let Some(p) = poller {
            p.abort();
            let _ = p.await;
        }
        Arc::clone(&self.device).stop_started().await
    }
}

#[cfg(test)]
mod tests;
