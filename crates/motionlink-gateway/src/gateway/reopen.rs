//! A device whose port failed (a USB adapter unplugged, a TCP server gone): its session is gone, so its
//! motion is cancelled (nothing can be sent over the port: what stops the device then is what it does
//! without its host, said in the `port_failed` event), its state becomes `"available": false` (retained),
//! requests to it are answered `unavailable`, and the port is opened again with backoff (0.5 s doubling to
//! 10 s); once open, the device is served again (`port_reopened`) and its state published. A port that failed
//! while a motion of the gateway's ran on the device (it may run on: a COMPAX drive has no watchdog) is
//! stopped over the new session, by the family's confirmed `stop`, before the device is served again, and
//! `port_reopened` says what that stop found. The gateway's other devices are served on meanwhile.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use rumqttc::v5::mqttbytes::QoS;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tokio::time::Instant;

use super::{lease_key, Gateway, Motion, Served};
use crate::config::DeviceEntry;
use crate::device::{Device, Spec};
use crate::error::{ErrorReport, GatewayErrors, StopReason};
use crate::events::{Event, Unavailable};

/// The first wait before a device's port is opened again; it doubles up to [`MAX_REOPEN_WAIT`].
pub const FIRST_REOPEN_WAIT: Duration = Duration::from_millis(500);
/// The longest wait between two openings of a failed port.
pub const MAX_REOPEN_WAIT: Duration = Duration::from_secs(10);

/// What the gateway's own tasks tell its loop.
pub(super) enum Internal {
    /// A state sample found the device's port gone.
    SampleFailed {
        /// The device.
        device: String,
        /// The session the sample was of.
        generation: u64,
        /// What the library said.
        error: ErrorReport,
    },
    /// A state sample failed over a port that is fine (`error`: what the library said: the device is silent,
    /// or refused the read), or (`None`) one succeeds again.
    Silent {
        /// The device.
        device: String,
        /// The session the sample was of.
        generation: u64,
        /// What the library said; `None`: it answers again.
        error: Option<ErrorReport>,
    },
    /// A failed device's port is open again.
    Reopened {
        /// The device.
        device: String,
        /// Its new session.
        opened: Arc<Device>,
        /// The device's stop over it, where one was due (its report in one line, or its error).
        stop: Option<Result<String, ErrorReport>>,
    },
}

/// A device whose port failed.
pub(super) struct Lost {
    /// Its motion, while its cancellation ends (its reply is still due).
    pub(super) motion: Option<Motion>,
    /// What failed.
    error: ErrorReport,
    /// When.
    since: Instant,
    /// The motion of the gateway's that ran when the port failed (`move "m1"`), which may run on: the device
    /// is stopped once its port is open again, before it is served.
    pub(super) stop_due: Option<String>,
    /// The task that opens the port again.
    reopen: JoinHandle<()>,
}

impl Lost {
    /// Stops opening the port again.
    pub(super) fn give_up(self) -> Option<Motion> {
        self.reopen.abort();
        self.motion
    }
}

impl Gateway {
    /// The device's motion slot, whether it is served or its port failed.
    pub(super) fn motion_of(&mut self, device: &str) -> Option<&mut Option<Motion>> {
        match self.devices.get_mut(device) {
            Some(s) => Some(&mut s.motion),
            None => self.lost.get_mut(device).map(|l| &mut l.motion),
        }
    }

    /// Whether any motion is still under way (served devices, and those whose port failed).
    pub(super) fn any_motion(&self) -> bool {
        self.devices.values().any(|s| s.motion.is_some()) || self.lost.values().any(|l| l.motion.is_some())
    }

    /// The answer to a request for a device whose port failed.
    pub(super) fn unavailable(&self, device: &str) -> Option<ErrorReport> {
        let lost = self.lost.get(device)?;
        let port = self.entries.get(device).map(|(e, _)| e.port.as_str()).unwrap_or("its port");
        let mut message = format!(
            "{device}: its port {port} failed {:.1} s ago ({}); the gateway is opening it again",
            lost.since.elapsed().as_secs_f64(),
            lost.error.message
        );
        if let Some(motion) = &lost.stop_due {
            message.push_str(&format!(
                ", and then stops the device before it serves it (its motion {motion} ran when the port failed)"
            ));
        }
        Some(ErrorReport::unavailable(message))
    }

    /// What the gateway's tasks said.
    pub(super) fn on_internal(&mut self, i: Internal) {
        match i {
            Internal::SampleFailed { device, generation, error } => self.port_failed(&device, generation, error, None),
            Internal::Reopened { device, opened, stop } => self.reopened(&device, opened, stop),
            Internal::Silent { device, generation, error } => self.silent(&device, generation, error),
        }
    }

    /// The state samples of `device` (its session `generation`) failed (`error`) or succeed again:
    /// `device_silent` (a timeout), `state_failed` (any other failure) or `device_answers` said (its state was
    /// published by the sampler).
    fn silent(&self, device: &str, generation: u64, error: Option<ErrorReport>) {
        if self.devices.get(device).is_none_or(|s| s.generation != generation) {
            return;
        }
        let event = match &error {
            Some(e) => {
                // A timeout is a device that does not answer; anything else (a refusal, a corrupt answer) is
                // a state that could not be read.
                let (event, what) = match e.kind.as_ref() {
                    "timeout" => ("device_silent", "does not answer"),
                    _ => ("state_failed", "its state could not be read"),
                };
                let message = format!(
                    "{device}: {what} ({}); its state is unavailable until a state sample succeeds again, and \
                     requests to it are sent and answered as the device answers them",
                    e.message
                );
                crate::notice::say!("motionlink gateway: {message}");
                serde_json::to_string(&Event { message: Some(&message), error: Some(e), ..Event::new(event, None) })
            }
            None => {
                let message = format!("{device}: its state is read again");
                crate::notice::say!("motionlink gateway: {message}");
                serde_json::to_string(&Event { message: Some(&message), ..Event::new("device_answers", None) })
            }
        };
        let _ = self.mqtt.try_publish(self.topics.events(device), QoS::AtLeastOnce, false, event.unwrap_or_default());
    }

    /// The port of `device` (its session `generation`) failed with `error`: its motion is cancelled (or
    /// `ended`, `(op, id)`, has just ended with the failure), its sampler ended, `port_failed` said, the
    /// unavailable state published, and its port opened again.
    pub(super) fn port_failed(
        &mut self,
        device: &str,
        generation: u64,
        error: ErrorReport,
        ended: Option<(String, crate::request::RequestId)>,
    ) {
        if self.devices.get(device).is_none_or(|s| s.generation != generation) {
            return; // An older session's, or the device is already handled.
        }
        let Some((entry, spec)) = self.entries.get(device).cloned() else { return };
        let mut served = self.devices.remove(device).expect("served");
        if let Some(task) = self.samplers.remove(device) {
            task.abort();
        }
        let mut message = format!(
            "{device}: its port {} failed ({}): the gateway's session with it is gone",
            entry.port, error.message
        );
        // A motion that ran (or has just ended with the failure) may run on: the device is stopped once the
        // port is open again.
        let stop_due = match (&served.motion, &ended) {
            (Some(m), _) => Some(format!("{} {:?}", m.op, m.id)),
            (None, Some((op, id))) => Some(format!("{op} {id:?}")),
            (None, None) => None,
        };
        if let Some(m) = served.motion.as_mut() {
            // No lease can help a motion that cannot be stopped over its port: its lease ends here.
            self.leases.end(&lease_key(device, &m.id));
            if let Some(c) = m.cancel.take() {
                let _ = c.send(StopReason::PortFailed { error: error.message.clone() });
            }
            message.push_str(&format!(
                "; its motion {} {:?} is cancelled, but no stop can reach the device over a failed port: {}",
                m.op,
                m.id,
                spec.without_host()
            ));
        } else if let Some((op, id)) = ended {
            message.push_str(&format!(
                "; its motion {op} {id:?} ended with that failure, and no stop can reach the device over a failed \
                 port: {}",
                spec.without_host()
            ));
        }
        message.push_str(&format!(
            "; the gateway opens the port again ({} s, doubling to {} s)",
            FIRST_REOPEN_WAIT.as_secs_f64(),
            MAX_REOPEN_WAIT.as_secs()
        ));
        if stop_due.is_some() {
            message.push_str(", and stops the device over it before it serves it again");
        }
        crate::notice::say!("motionlink gateway: {message}");
        self.event(device, &Event { message: Some(&message), error: Some(&error), ..Event::new("port_failed", None) });
        let state = Unavailable { available: false, error: &error, t_s: self.started.elapsed().as_secs_f64() };
        match motionlink_link::result::identified(&entry.family, &entry.port, &spec.identity(), &state) {
            Ok(body) => {
                let _ = self.mqtt.try_publish(self.topics.state(device), QoS::AtLeastOnce, true, body.to_string());
            }
            Err(e) => tracing::warn!("{device}: the unavailable state: {e}"),
        }
        // The old session goes on its own (its close cannot reach the device; it ends with its last user).
        let old = served.device;
        tokio::spawn(async move {
            let _ = Device::close(old).await;
        });
        let reopen = tokio::spawn(reopen(entry, spec, stop_due.is_some(), self.internal.clone()));
        let lost = Lost { motion: served.motion.take(), error, since: Instant::now(), stop_due, reopen };
        self.lost.insert(device.to_string(), lost);
    }

    /// A failed device's port is open again (and the device stopped over it, where a motion of the gateway's
    /// ran when the port failed: `stop`): it is served (its motion slot as it was: a cancelled motion may still
    /// be ending), its state published again by its sampler, `port_reopened` said with what the stop found.
    fn reopened(&mut self, device: &str, opened: Arc<Device>, stop: Option<Result<String, ErrorReport>>) {
        let Some(lost) = self.lost.remove(device) else {
            // No longer waited for (its port handed to a stop): the new session goes.
            tokio::spawn(async move {
                let _ = Device::close(opened).await;
            });
            return;
        };
        let generation = self.next_generation();
        let moving = Arc::new(AtomicBool::new(lost.motion.is_some()));
        self.devices.insert(device.to_string(), Served { device: opened, motion: lost.motion, moving, generation });
        self.start_sampler(device);
        let port = self.entries.get(device).map(|(e, _)| e.port.clone()).unwrap_or_default();
        let mut message = format!(
            "{device} on {port} is served again ({:.1} s after its port failed)",
            lost.since.elapsed().as_secs_f64()
        );
        let motion = lost.stop_due.as_deref().unwrap_or("");
        let (ok, error) = match &stop {
            None => (None, None),
            Some(Ok(summary)) => {
                message.push_str(&format!(
                    "; its motion {motion} ran when the port failed, so the gateway stopped the device first: the \
                     device's stop: {summary}"
                ));
                (Some(true), None)
            }
            Some(Err(e)) => {
                message.push_str(&format!(
                    "; its motion {motion} ran when the port failed, so the gateway stopped the device first, but \
                     the device's stop failed ({}): the axis may still be moving",
                    e.message
                ));
                (Some(false), Some(e))
            }
        };
        crate::notice::say!("motionlink gateway: {message}");
        self.event(device, &Event { message: Some(&message), ok, error, ..Event::new("port_reopened", None) });
    }

    /// A new session's number.
    pub(super) fn next_generation(&mut self) -> u64 {
        self.generation += 1;
        self.generation
    }
}

/// Opens the port of `entry` again until it opens: after [`FIRST_REOPEN_WAIT`], doubling up to
/// [`MAX_REOPEN_WAIT`]; with `stop`, the device's `stop` then runs over the new session (a port that fails
/// again meanwhile is opened again, and the stop with it); the new session goes to the loop, with what the stop
/// found.
async fn reopen(entry: DeviceEntry, spec: Spec, stop: bool, tx: mpsc::UnboundedSender<Internal>) {
    let mut wait = FIRST_REOPEN_WAIT;
    loop {
        tokio::time::sleep(wait).await;
        match Device::open(&entry, &spec).await {
            Ok(opened) => {
                let stopped = match stop {
                    false => None,
                    true => match opened.stop().await {
                        Err(e) if e.port_failed() => {
                            tracing::info!("{}: stopping it over {} again: {}", entry.name, entry.port, e.message);
                            let _ = Device::close(opened).await;
                            wait = (wait * 2).min(MAX_REOPEN_WAIT);
                            continue;
                        }
                        outcome => Some(outcome.map(|report| super::summary(&report))),
                    },
                };
                let _ = tx.send(Internal::Reopened { device: entry.name.clone(), opened, stop: stopped });
                return;
            }
            Err(e) => {
                tracing::info!("{}: opening {} again: {}", entry.name, entry.port, e.message);
                wait = (wait * 2).min(MAX_REOPEN_WAIT);
            }
        }
    }
}
