//! The gateway's loop: requests from the broker to the devices, replies and events back, states at their
//! rate, leases watched, and every motion stopped when its lease lapses, on `stop`, when the broker is
//! lost and on SIGINT, SIGTERM, SIGHUP, SIGQUIT and SIGTSTP.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use rumqttc::v5::mqttbytes::v5::{Publish, PublishProperties};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::AsyncClient as Mqtt;
use serde_json::Value;
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

use crate::config::{DeviceEntry, GatewayConfig};
use crate::device::{Action, Device, Operation, Outcome, Spec};
use crate::error::{ErrorReport, GatewayError, GatewayErrors, StopReason};
use crate::events::{Event, Renewed};
use crate::lease::Leases;
use crate::mqtt::{self, Net, OFFLINE};
use crate::ports::PortLocks;
use crate::request::{self, Request, RequestId};
use crate::topics::{self, Topics};

mod handover;
mod presence;
mod reopen;
mod signals;

use presence::Presence;
use reopen::{Internal, Lost};
use signals::Signals;

/// How long the gateway waits for its motions to stop when it ends.
const STOP_BOUND: Duration = Duration::from_secs(10);

/// Where a reply goes: the request's `reply_to`, else the MQTT 5 response topic with its correlation data.
#[derive(Debug, Clone, Default)]
struct ReplyTo {
    topic: Option<String>,
    properties: Option<PublishProperties>,
}

/// A motion under way on a device.
struct Motion {
    id: RequestId,
    op: String,
    reply: ReplyTo,
    cancel: Option<oneshot::Sender<StopReason>>,
}

/// A device as the loop serves it.
struct Served {
    device: Arc<Device>,
    motion: Option<Motion>,
    moving: Arc<AtomicBool>,
    /// Its session's number (a new one each time the device is opened again).
    generation: u64,
}

/// An operation that ended.
struct Done {
    device: String,
    /// The session it ran on.
    generation: u64,
    motion_id: Option<RequestId>,
    id: Option<RequestId>,
    reply: ReplyTo,
    outcome: Outcome,
}

/// The gateway while it runs.
struct Gateway {
    topics: Topics,
    mqtt: Mqtt,
    devices: HashMap<String, Served>,
    leases: Leases,
    done: mpsc::UnboundedSender<Done>,
    /// The gateway's name (how it names itself as a port's holder).
    name: String,
    /// The locks of the real ports it serves.
    ports: PortLocks,
    /// Each device's table and options (to open it again once its port is back).
    entries: HashMap<String, (DeviceEntry, Spec)>,
    /// The devices whose port a `stop` from another process took: served again once it is free.
    released: Vec<String>,
    /// Each served device's state sampler.
    samplers: HashMap<String, tokio::task::JoinHandle<()>>,
    /// States a second while something moves.
    sample_hz: u32,
    /// The subscription and `online` on the current connection.
    presence: Presence,
    /// The number of the current connection to the broker (1 for the first), 0 while there is none: the
    /// samplers publish no state while it is 0 (it would wait in the queue to the broker, and fill it).
    link: Arc<AtomicU64>,
    /// The connections made so far.
    connections: u64,
    /// The gateway's start (states' `t_s`).
    started: Instant,
    /// The devices whose port failed, while it is opened again.
    lost: HashMap<String, Lost>,
    /// What the gateway's own tasks tell the loop.
    internal: mpsc::UnboundedSender<Internal>,
    /// The last session's number.
    generation: u64,
    /// The ids of the latest motion requests taken, per device and id ([`lease_key`]), oldest first (at most
    /// [`MOTION_IDS_KEPT`]): a motion request delivered again (MQTT's QoS 1 delivers at least once) is not
    /// run again.
    motion_ids: std::collections::VecDeque<String>,
}

/// How many motion request ids the gateway remembers to know a repeated delivery.
const MOTION_IDS_KEPT: usize = 4096;

/// Runs the gateway of `config` until a signal ends it (its exit code: 128 + its number: 130 SIGINT, 143
/// SIGTERM, 129 SIGHUP, 131 SIGQUIT, 148 SIGTSTP on Linux; 3 when a stop was not confirmed) or it cannot
/// start (a usage error, exit 2; a device or the broker that cannot be reached, exit 3).
pub async fn run(config: GatewayConfig) -> Result<u8, GatewayError> {
    let topics = Topics::new(&config.name);
    // Every device's options, checked before anything is opened.
    let mut specs = Vec::new();
    for entry in &config.devices {
        let spec = Spec::of(entry).map_err(|m| GatewayError::Usage(format!("[device.{}]: {m}", entry.name)))?;
        specs.push((entry, spec));
    }
    let options = mqtt::options(&config, &topics)?;
    let queue = mqtt::queue_length(|key| std::env::var(key).ok())?;
    let mut signals = Signals::new()?;
    // The lock of every real port before any is opened: one held by another process names it (exit 3).
    let mut ports = PortLocks::new();
    for (entry, _) in &specs {
        ports
            .claim(&config.name, entry)
            .map_err(|m| GatewayError::Transport(format!("[device.{}]: {m}", entry.name)))?;
    }
    let mut devices = HashMap::new();
    let mut generation = 0;
    for (entry, spec) in &specs {
        let device = Device::open(entry, spec).await.map_err(|e| {
            let m = format!("[device.{}] on {}: {}", entry.name, entry.port, e.message);
            if e.exit_code == 2 {
                GatewayError::Usage(m)
            } else {
                GatewayError::Transport(m)
            }
        })?;
        generation += 1;
        let moving = Arc::new(AtomicBool::new(false));
        devices.insert(entry.name.clone(), Served { device, motion: None, moving, generation });
    }
    let (mqtt, events) = Mqtt::new(options, queue);
    let (net_tx, mut net) = mpsc::unbounded_channel();
    let event_loop = tokio::spawn(mqtt::drive(events, net_tx));
    // The first connection: without it the gateway does not start.
    match net.recv().await {
        Some(Net::Connected) => {}
        Some(Net::Lost(e)) => {
            event_loop.abort();
            return Err(GatewayError::Transport(format!("the broker {}: {e}", config.broker)));
        }
        other => return Err(GatewayError::Transport(format!("the broker {}: {other:?}", config.broker))),
    }
    let (done_tx, mut done) = mpsc::unbounded_channel();
    let (internal, mut internal_rx) = mpsc::unbounded_channel();
    let entries = specs.iter().map(|(e, s)| (e.name.clone(), ((*e).clone(), s.clone()))).collect();
    let mut gw = Gateway {
        topics,
        mqtt,
        devices,
        leases: Leases::new(),
        done: done_tx,
        name: config.name.clone(),
        ports,
        entries,
        released: Vec::new(),
        samplers: HashMap::new(),
        sample_hz: config.sample_hz,
        presence: Presence::default(),
        link: Arc::new(AtomicU64::new(0)),
        connections: 0,
        started: Instant::now(),
        lost: HashMap::new(),
        internal,
        generation,
        motion_ids: std::collections::VecDeque::new(),
    };
    gw.connected();
    crate::notice::say!(
        "motionlink gateway {}: connected to {}, serving {} device(s) under {}",
        config.name,
        config.broker,
        gw.devices.len(),
        gw.topics.status().trim_end_matches("/status")
    );
    let names: Vec<String> = gw.devices.keys().cloned().collect();
    for name in names {
        gw.start_sampler(&name);
    }
    let mut retake = tokio::time::interval(Duration::from_secs(1));
    let far = || Instant::now() + Duration::from_secs(3600);
    let mut connected = true;
    let (number, name) = loop {
        let deadline = gw.leases.next_deadline().unwrap_or_else(far);
        tokio::select! {
            n = net.recv() => match n {
                Some(Net::Connected) => {
                    crate::notice::say!("motionlink gateway: connected to {} again", config.broker);
                    connected = true;
                    gw.connected();
                }
                Some(Net::Message(p)) => gw.on_message(&p),
                Some(Net::Subscribed(granted)) => gw.presence.suback(granted, &gw.mqtt, &gw.topics, Instant::now()),
                Some(Net::Lost(e)) => {
                    gw.link.store(0, Ordering::Relaxed);
                    gw.presence.lost();
                    // No lease can be renewed: every motion stops (said once per loss, not per retry).
                    let stopped = gw.stop_all(StopReason::BrokerLost);
                    if connected || stopped > 0 {
                        crate::notice::say!(
                            "motionlink gateway: lost the broker {} ({e}); stopping {stopped} motion(s); connecting \
                             again",
                            config.broker
                        );
                    }
                    connected = false;
                }
                Some(Net::Closed) | None => {
                    gw.stop_all(StopReason::BrokerLost);
                    break (0, "");
                }
            },
            Some(d) = done.recv() => gw.on_done(d),
            Some(i) = internal_rx.recv() => gw.on_internal(i),
            _ = tokio::time::sleep_until(deadline) => gw.on_leases(),
            _ = retake.tick() => {
                gw.presence.step(&gw.mqtt, &gw.topics, Instant::now());
                gw.retake_ports().await;
            }
            s = signals.next() => {
                // SIGINT from `motionlink FAMILY --port PORT stop`: that device's motion stops, its port is
                // let go of; the others are served on. Any other SIGINT (Ctrl-C) or SIGTERM ends the gateway.
                let asked = gw.ports.stop_requests();
                if s.0 == 2 && !asked.is_empty() {
                    gw.hand_over(asked, &mut done).await;
                    continue;
                }
                break s;
            }
        }
    };
    // The end: every motion stopped (and said on stderr), then `offline`, then the devices closed.
    #[cfg(unix)]
    if number == libc::SIGTSTP {
        crate::notice::say!(
            "motionlink gateway: SIGTSTP (Ctrl-Z) received: the gateway is not suspended (suspended, it would \
             watch no lease and leave every motion it started running); it stops every motion and ends"
        );
    }
    if number != 0 {
        gw.stop_all(StopReason::Signal { number, name });
    }
    let bound = Instant::now() + STOP_BOUND;
    // A stop that the device did not confirm (or that did not end in time): the exit code says so (3), as
    // the command line's does, not 128 + n, which says the motions were stopped.
    let mut unconfirmed = false;
    while gw.any_motion() {
        match tokio::time::timeout_at(bound, done.recv()).await {
            Ok(Some(d)) => {
                if let (Some(id), Err(e)) = (&d.motion_id, &d.outcome) {
                    crate::notice::say!("motionlink gateway: {name}: {} motion {id}: {}", d.device, e.message);
                    unconfirmed |= e.stop_unconfirmed;
                }
                gw.on_done(d);
            }
            _ => {
                let lost = gw.lost.iter().map(|(d, l)| (d, &l.motion));
                for (dev, motion) in gw.devices.iter().map(|(d, s)| (d, &s.motion)).chain(lost) {
                    if let Some(m) = motion {
                        crate::notice::say!(
                            "motionlink gateway: {name}: {dev} motion {}: its stop did not end within {} s: it \
                             may still be moving",
                            m.id,
                            STOP_BOUND.as_secs()
                        );
                        unconfirmed = true;
                    }
                }
                break;
            }
        }
    }
    // The samplers end before the sessions close (each holds its device); failed ports are not opened again.
    for (device, lost) in gw.lost.drain() {
        if let Some(motion) = &lost.stop_due {
            // Its stop was due once the port opened again: it never did.
            let without = gw.entries.get(&device).map(|(_, s)| s.without_host()).unwrap_or_default();
            crate::notice::say!(
                "motionlink gateway: {device}: its port failed while its motion {motion} ran and is not open again, \
                 so no stop reached the device ({without}): it may still be moving"
            );
            unconfirmed = true;
        }
        lost.give_up();
    }
    for (_, s) in gw.samplers.drain() {
        s.abort();
        let _ = s.await;
    }
    // `offline` and the DISCONNECT wait for room in the queue (a clean DISCONNECT discards the last will, so
    // `offline` must not be dropped before it); a connection that is gone leaves `offline` to the will.
    let bye = async {
        gw.mqtt.publish(gw.topics.status(), QoS::AtLeastOnce, true, OFFLINE).await?;
        gw.mqtt.disconnect().await
    };
    match tokio::time::timeout(Duration::from_secs(2), bye).await {
        Ok(Ok(())) => {}
        Ok(Err(e)) => tracing::warn!("offline: {e}"),
        Err(_) => tracing::warn!("offline: no room in the queue to the broker within 2 s"),
    }
    let _ = tokio::time::timeout(Duration::from_secs(3), event_loop).await;
    for (name, s) in gw.devices.drain() {
        if let Err(e) = s.device.close().await {
            crate::notice::say!("motionlink gateway: closing {name}: {e}");
        }
    }
    Ok(match (unconfirmed, number) {
        (true, _) => {
            crate::notice::say!(
                "motionlink gateway: a stop was not confirmed: what was moving may still be moving (exit 3)"
            );
            3
        }
        (false, 0) => 0,
        (false, n) => 128 + n as u8,
    })
}

/// Publishes the device's state (retained) at `sample_hz` while it moves (a motion of the gateway's, or
/// any motion the device reports), else once a second.
/// A sample that finds the device's port gone ends the sampler and tells the loop (`failed`, with the
/// session's `generation`). A sample that fails otherwise (the device does not answer over a port that is
/// fine: powered off, its cable out; or it refuses a read) publishes the unavailable state `unavailable`
/// makes in place of the last state (which would otherwise stand, retained, as if the device were at rest),
/// once, and tells the loop; the next sample that succeeds publishes the state again and tells the loop too.
#[allow(clippy::too_many_arguments)]
async fn sample_states(
    device: Arc<Device>,
    mqtt: Mqtt,
    topic: String,
    moving: Arc<AtomicBool>,
    sample_hz: u32,
    started: Instant,
    generation: u64,
    link: Arc<AtomicU64>,
    failed: mpsc::UnboundedSender<Internal>,
    unavailable: impl Fn(&ErrorReport, f64) -> Option<String> + Send,
) {
    let mut silent = false;
    // The connection on which the unavailable state went out (a broker that restarted lost it).
    let mut unavailable_on = 0;
    let fast = Duration::from_secs(1) / sample_hz.max(1);
    let slow = Duration::from_secs(1).max(fast);
    let mut due = Instant::now();
    loop {
        let t_s = started.elapsed().as_secs_f64();
        let mut reported = false;
        match device.sample(t_s).await {
            Ok((state, in_motion)) => {
                reported = in_motion;
                // While the broker is gone, no state is queued: it would be stale when it goes, and would
                // fill the queue that the subscription and `online` need once the broker is back.
                if link.load(Ordering::Relaxed) != 0 {
                    let _ = mqtt.try_publish(topic.clone(), QoS::AtMostOnce, true, state.to_string());
                }
                unavailable_on = 0;
                if std::mem::take(&mut silent) {
                    let _ = failed.send(Internal::Silent { device: device.name.clone(), generation, error: None });
                }
            }
            Err(e) if e.port_failed() => {
                let _ = failed.send(Internal::SampleFailed { device: device.name.clone(), generation, error: e });
                return;
            }
            Err(e) => {
                tracing::warn!("{}: state: {}", device.name, e.message);
                // Published once per connection (again after a reconnection: the broker may have lost it).
                let connection = link.load(Ordering::Relaxed);
                if connection != 0 && connection != unavailable_on {
                    if let Some(body) = unavailable(&e, t_s) {
                        if mqtt.try_publish(topic.clone(), QoS::AtLeastOnce, true, body).is_ok() {
                            unavailable_on = connection;
                        }
                    }
                }
                if !silent {
                    silent = true;
                    let _ = failed.send(Internal::Silent { device: device.name.clone(), generation, error: Some(e) });
                }
            }
        }
        let last = due;
        // The next sample on a fixed schedule (never in the past); a motion that starts meanwhile brings it
        // forward to one fast period after the last.
        due = (last + if reported || moving.load(Ordering::Relaxed) { fast } else { slow }).max(Instant::now());
        loop {
            let now = Instant::now();
            if now >= due {
                break;
            }
            if moving.load(Ordering::Relaxed) && last + fast < due {
                due = (last + fast).max(now);
                continue;
            }
            tokio::time::sleep_until(due.min(now + fast)).await;
        }
    }
}

impl Gateway {
    /// A connection to the broker (the first, or again): states are published again, the subscription is
    /// asked for, and `online` follows once it is granted ([`Presence`]).
    fn connected(&mut self) {
        self.connections += 1;
        self.link.store(self.connections, Ordering::Relaxed);
        self.presence.connected();
        self.presence.step(&self.mqtt, &self.topics, Instant::now());
    }

    fn publish_reply(&self, reply: &ReplyTo, id: Option<&RequestId>, outcome: &Outcome, device: &str) {
        let body = request::reply(id, outcome).to_string();
        match &reply.topic {
            Some(topic) => {
                let r = match &reply.properties {
                    Some(p) => {
                        self.mqtt.try_publish_with_properties(topic.clone(), QoS::AtLeastOnce, false, body, p.clone())
                    }
                    None => self.mqtt.try_publish(topic.clone(), QoS::AtLeastOnce, false, body),
                };
                if let Err(e) = r {
                    tracing::warn!("reply to {topic}: {e}");
                }
            }
            None => {
                if let Err(error) = outcome {
                    self.event(device, &Event { error: Some(error), ..Event::new("error", id) });
                }
            }
        }
    }

    fn event(&self, device: &str, event: &Event<'_>) {
        let body = serde_json::to_string(event).unwrap_or_default();
        let _ = self.mqtt.try_publish(self.topics.events(device), QoS::AtLeastOnce, false, body);
    }

    /// One message on a `cmd` topic: a request is run unless it came retained or names a reply topic in the
    /// gateways' tree (both refused, and said).
    fn on_message(&mut self, p: &Publish) {
        let topic = String::from_utf8_lossy(&p.topic).to_string();
        let Some(device) = self.topics.device_of_cmd(&topic).map(str::to_string) else { return };
        if p.retain && p.payload.is_empty() {
            // A retained request cleared (an empty retained message): nothing to run nor answer.
            return;
        }
        let response_topic = p.properties.as_ref().and_then(|pp| pp.response_topic.clone());
        let properties = p.properties.as_ref().map(|pp| PublishProperties {
            correlation_data: pp.correlation_data.clone(),
            ..PublishProperties::default()
        });
        let request = request::parse(&p.payload);
        let (id, reply_to) = match &request {
            Ok(r) => (Some(r.id.clone()), r.reply_to.clone()),
            Err(bad) => (bad.id.clone(), bad.reply_to.clone()),
        };
        let which = if reply_to.is_some() { "reply_to" } else { "the response topic" };
        let reply = match reply_to {
            Some(t) => ReplyTo { topic: Some(t), properties: None },
            None => ReplyTo { topic: response_topic, properties },
        };
        // A reply topic in the gateways' tree: no reply is published there (it would pose as a status, a state,
        // an event or a request); the request is refused, as an `error` event.
        if let Some(t) = reply.topic.as_deref().filter(|t| topics::in_tree(t)) {
            let error = ErrorReport::usage(format!(
                "{which} {t:?} is in the gateways' topic tree ({}/...): a reply there would pose as a gateway's \
                 status, a device's state, an event or a request, so the request is refused and not run; give a \
                 reply topic outside it, such as motionlink-reply/<user>/<anything>",
                topics::ROOT
            ));
            self.publish_reply(&ReplyTo::default(), id.as_ref(), &Err(error), &device);
            return;
        }
        if p.retain {
            let op = request.as_ref().ok().map(|r| r.op.as_str());
            self.retained(&device, &topic, op, id.as_ref(), &reply);
            return;
        }
        match request {
            Err(bad) => self.publish_reply(&reply, bad.id.as_ref(), &Err(bad.error), &device),
            Ok(request) => {
                if let Err(e) = self.on_request(&device, &request, &reply) {
                    self.publish_reply(&reply, Some(&request.id), &Err(e), &device);
                }
            }
        }
    }

    /// A request delivered as a retained message (published with the retain flag: the broker keeps it and
    /// would send it again at every subscription, and a relative move would run again at every start of the
    /// gateway): not run; said on stderr and as a `retained` event, and answered with a usage error where the
    /// request names a reply topic.
    fn retained(&self, device: &str, topic: &str, op: Option<&str>, id: Option<&RequestId>, reply: &ReplyTo) {
        let message = format!(
            "a request delivered as a retained message is not run: it was published with the retain flag, and a \
             broker keeps such a message and sends it again at each subscription (a relative move would run \
             again at each start of the gateway); publish requests without the retain flag, and clear this one \
             by publishing an empty retained message to {topic}"
        );
        crate::notice::say!("motionlink gateway: {device}: {message}");
        self.event(device, &Event { op, message: Some(&message), ..Event::new("retained", id) });
        if reply.topic.is_some() {
            self.publish_reply(reply, id, &Err(ErrorReport::usage(message)), device);
        }
    }

    fn on_request(&mut self, device: &str, r: &Request, reply: &ReplyTo) -> Result<(), ErrorReport> {
        if self.released.iter().any(|d| d == device) {
            return Err(ErrorReport::busy(format!(
                "{device}: a stop from another process took its port; the gateway serves it again once the port is \
                 free"
            )));
        }
        if let Some(e) = self.unavailable(device) {
            if r.op == "keepalive" {
                let lapsed = format!("no motion {:?} holds a lease on {device}: its port failed", r.id);
                return Err(ErrorReport::new("no_lease", lapsed, 2));
            }
            return Err(e);
        }
        if !self.devices.contains_key(device) {
            let names = self.devices.keys().cloned().collect::<Vec<_>>().join(", ");
            return Err(ErrorReport::usage(format!("no device {device:?} on this gateway; it serves {names}")));
        }
        if r.op == "keepalive" {
            if !r.args.is_empty() {
                return Err(ErrorReport::usage("keepalive takes no args: give the motion's id as \"id\""));
            }
            let key = lease_key(device, &r.id);
            return match self.leases.renew(&key, Instant::now()) {
                Some(lease) if reply.topic.is_some() => {
                    let renewed = Renewed { renewed: true, lease_ms: lease.as_millis() as u64 };
                    let outcome = serde_json::to_value(renewed).map_err(|e| ErrorReport::transport(e.to_string()));
                    self.publish_reply(reply, Some(&r.id), &outcome, device);
                    Ok(())
                }
                Some(_) => Ok(()),
                None => Err(ErrorReport::new(
                    "no_lease",
                    format!("no motion {:?} holds a lease on {device} (it ended, or its lease lapsed)", r.id),
                    2,
                )),
            };
        }
        let action = self.devices[device].device.action(&r.op, r.args.clone())?;
        match action {
            Action::Motion(_) if self.motion_ids.contains(&lease_key(device, &r.id)) => {
                // A repeated delivery (or an id used again): not run again, and not answered (the reply of the
                // first is the answer); said as an event and on stderr.
                let message = format!(
                    "a motion request with id {:?} was taken already for {device}: not run again (a request \
                     delivered twice runs once; give each motion request an id of its own)",
                    r.id
                );
                crate::notice::say!("{message}");
                self.event(
                    device,
                    &Event { op: Some(&r.op), message: Some(&message), ..Event::new("repeated", Some(&r.id)) },
                );
            }
            Action::Motion(op) => {
                let served = self.devices.get_mut(device).expect("checked above");
                if let Some(m) = &served.motion {
                    return Err(ErrorReport::busy(format!(
                        "{device} is running {} {:?}: stop it, or wait for its end",
                        m.op, m.id
                    )));
                }
                if self.motion_ids.len() >= MOTION_IDS_KEPT {
                    self.motion_ids.pop_front();
                }
                self.motion_ids.push_back(lease_key(device, &r.id));
                let (cancel, cancelled) = oneshot::channel();
                served.motion =
                    Some(Motion { id: r.id.clone(), op: r.op.clone(), reply: reply.clone(), cancel: Some(cancel) });
                served.moving.store(true, Ordering::Relaxed);
                let (device_handle, tx, generation) =
                    (Arc::clone(&served.device), self.done.clone(), served.generation);
                self.leases.start(&lease_key(device, &r.id), r.lease, Instant::now());
                let lease_ms = r.lease.as_millis() as u64;
                self.event(
                    device,
                    &Event { op: Some(&r.op), lease_ms: Some(lease_ms), ..Event::new("motion_started", Some(&r.id)) },
                );
                let (name, id) = (device.to_string(), r.id.clone());
                tokio::spawn(async move {
                    let outcome = run_motion(op, cancelled, &device_handle).await;
                    // Let go of the device before the loop hears of the end: it may close the session next.
                    drop(device_handle);
                    let _ = tx.send(Done {
                        device: name,
                        generation,
                        motion_id: Some(id.clone()),
                        id: Some(id),
                        reply: ReplyTo::default(),
                        outcome,
                    });
                });
            }
            Action::Stop(op) => {
                if let Some(m) = self.devices.get_mut(device).and_then(|s| s.motion.as_mut()) {
                    if let Some(c) = m.cancel.take() {
                        let _ = c.send(StopReason::StopRequest { id: r.id.to_string() });
                    }
                }
                self.spawn_reply(device, r, reply, op);
            }
            Action::Write(op) => {
                if let Some(m) = &self.devices[device].motion {
                    return Err(ErrorReport::busy(format!(
                        "{device} is running {} {:?}: {} is served once it has ended (or stop it)",
                        m.op, m.id, r.op
                    )));
                }
                self.spawn_reply(device, r, reply, op)
            }
            Action::Other(op) => self.spawn_reply(device, r, reply, op),
        }
        Ok(())
    }

    fn spawn_reply(&self, device: &str, r: &Request, reply: &ReplyTo, op: Operation) {
        let tx = self.done.clone();
        let generation = self.devices.get(device).map_or(0, |s| s.generation);
        let (name, id, reply) = (device.to_string(), r.id.clone(), reply.clone());
        tokio::spawn(async move {
            let outcome = op.await;
            let _ = tx.send(Done { device: name, generation, motion_id: None, id: Some(id), reply, outcome });
        });
    }

    /// An operation ended: its reply; a motion's end is an event too.
    fn on_done(&mut self, d: Done) {
        let mut reply = d.reply;
        let mut ended = None;
        if let Some(id) = &d.motion_id {
            self.leases.end(&lease_key(&d.device, id));
            if let Some(slot) = self.motion_of(&d.device) {
                if slot.as_ref().is_some_and(|m| &m.id == id) {
                    let m = slot.take().expect("a motion");
                    if let Some(served) = self.devices.get(&d.device) {
                        served.moving.store(false, Ordering::Relaxed);
                    }
                    reply = m.reply;
                    ended = Some((m.op.clone(), m.id.clone()));
                    let event = Event {
                        op: Some(&m.op),
                        ok: Some(d.outcome.is_ok()),
                        error: d.outcome.as_ref().err(),
                        ..Event::new("motion_ended", Some(id))
                    };
                    self.event(&d.device, &event);
                }
            }
        }
        self.publish_reply(&reply, d.id.as_ref(), &d.outcome, &d.device);
        // An operation that found the port gone: the device's session must be opened again.
        if let Err(e) = d.outcome {
            if e.port_failed() {
                self.port_failed(&d.device, d.generation, e, ended);
            }
        }
    }

    /// Leases that lapsed: their motions are stopped.
    fn on_leases(&mut self) {
        for (key, lease) in self.leases.expired(Instant::now()) {
            let Some((device, id)) = key.split_once('\0') else { continue };
            let lease_ms = lease.as_millis() as u64;
            let motion = self.devices.get_mut(device).and_then(|s| s.motion.as_mut()).filter(|m| *m.id == *id);
            // The event names the motion's id as its request gave it (a number as a number).
            let id = match motion {
                Some(m) => {
                    if let Some(c) = m.cancel.take() {
                        let _ = c.send(StopReason::LeaseExpired { lease_ms });
                    }
                    m.id.clone()
                }
                None => RequestId::text(id),
            };
            self.event(device, &Event { lease_ms: Some(lease_ms), ..Event::new("lease_expired", Some(&id)) });
        }
    }

    /// Stops every motion for `reason`; how many were asked to stop.
    fn stop_all(&mut self, reason: StopReason) -> usize {
        let mut n = 0;
        for s in self.devices.values_mut() {
            if let Some(c) = s.motion.as_mut().and_then(|m| m.cancel.take()) {
                let _ = c.send(reason.clone());
                n += 1;
            }
        }
        n
    }
}

/// A lease's key: the device and the motion's id (ids are the clients', unique per device only).
fn lease_key(device: &str, id: &str) -> String {
    format!("{device}\0{id}")
}

/// Runs a motion until it ends, or until it is cancelled: then the operation is dropped (the library
/// stops the motion it started, as on Ctrl-C) and the device's `stop` confirms it at rest; the error says
/// why it was stopped and what the stop found.
async fn run_motion(mut op: Operation, cancelled: oneshot::Receiver<StopReason>, device: &Device) -> Outcome {
    let reason = tokio::select! {
        outcome = &mut op => return outcome,
        reason = cancelled => reason,
    };
    drop(op);
    let reason = reason.unwrap_or(StopReason::BrokerLost);
    Err(ErrorReport::stopped(&reason, device.stop().await.map(|stop| summary(&stop))))
}

/// A stop's report in one line (its JSON without the identity).
fn summary(stop: &Value) -> String {
    match stop {
        Value::Object(m) => {
            let mut m = m.clone();
            for k in ["family", "port", "module", "drive", "holder"] {
                m.remove(k);
            }
            Value::Object(m).to_string()
        }
        other => other.to_string(),
    }
}
