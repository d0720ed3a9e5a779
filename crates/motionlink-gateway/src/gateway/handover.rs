//! A device's port handed over to `motionlink FAMILY --port PORT stop` from another process (through the
//! port's lock, [`crate::ports`]), and taken back once it is free; each device's state sampler.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use motionlink_link::portlock::StopRequest;
use tokio::sync::mpsc;
use tokio::time::Instant;

use super::{sample_states, summary, Done, Gateway, Served, STOP_BOUND};
use crate::device::Device;
use crate::error::{ErrorReport, StopReason};
use crate::events::{Event, Unavailable};

impl Gateway {
    /// Starts publishing `device`'s state.
    pub(super) fn start_sampler(&mut self, device: &str) {
        let Some(served) = self.devices.get(device) else { return };
        let Some((entry, spec)) = self.entries.get(device) else { return };
        let (family, port, identity) = (entry.family.clone(), entry.port.clone(), spec.identity());
        let unavailable = move |error: &ErrorReport, t_s: f64| {
            let state = Unavailable { available: false, error, t_s };
            motionlink_link::result::identified(&family, &port, &identity, &state).ok().map(|v| v.to_string())
        };
        let task = tokio::spawn(sample_states(
            Arc::clone(&served.device),
            self.mqtt.clone(),
            self.topics.state(device),
            Arc::clone(&served.moving),
            self.sample_hz,
            self.started,
            served.generation,
            Arc::clone(&self.link),
            self.internal.clone(),
            unavailable,
        ));
        self.samplers.insert(device.to_string(), task);
    }

    /// Answers each `stop` that asked for a device's port: the device's motion is stopped as a `stop` request
    /// stops it (its motion cancelled, the device's stop confirming it at rest), its session closed, and its
    /// port let go of with what was stopped told to the `stop`.
    pub(super) async fn hand_over(
        &mut self,
        asked: Vec<(String, StopRequest)>,
        done: &mut mpsc::UnboundedReceiver<Done>,
    ) {
        for (device, request) in asked {
            let who = format!("motionlink pid {} ({})", request.pid, request.command);
            if let Some(lost) = self.lost.remove(&device) {
                // Its port had failed: no session of the gateway's to stop it with; the stop gets the port.
                lost.give_up();
                let without = self.entries.get(&device).map(|(_, s)| s.without_host()).unwrap_or_default();
                let message = format!(
                    "gateway {}: {device}: its port had failed, so the gateway had no session with it ({without}); \
                     its port is let go of",
                    self.name
                );
                self.ports.release(&self.name, &device, 3, &message);
                crate::notice::say!("motionlink gateway: stop from {who}: {message}");
                self.event(&device, &Event { message: Some(&message), ..Event::new("port_released", None) });
                self.released.push(device);
                continue;
            }
            let Some(served) = self.devices.get_mut(&device) else { continue };
            let mut ended: Option<(u8, String)> = None;
            if let Some(c) = served.motion.as_mut().and_then(|m| m.cancel.take()) {
                let _ = c.send(StopReason::PortStop { who: who.clone() });
                let bound = Instant::now() + STOP_BOUND;
                while self.devices.get(&device).is_some_and(|s| s.motion.is_some()) {
                    match tokio::time::timeout_at(bound, done.recv()).await {
                        Ok(Some(d)) => {
                            if d.device == device && d.motion_id.is_some() {
                                if let Err(e) = &d.outcome {
                                    ended = Some((e.exit_code, e.message.clone()));
                                }
                            }
                            self.on_done(d);
                        }
                        _ => break,
                    }
                }
            }
            let Some(served) = self.devices.remove(&device) else { continue };
            if let Some(task) = self.samplers.remove(&device) {
                task.abort();
                let _ = task.await;
            }
            let (exit_code, message) = match (ended, served.motion.is_some()) {
                (_, true) => (1, format!("its motion's stop did not end within {} s", STOP_BOUND.as_secs())),
                (Some((code, message)), false) => (code, message),
                // No motion of the gateway's: the device's `stop`, as a `stop` request makes it.
                (None, false) => match served.device.stop().await {
                    Ok(stop) => (0, format!("no motion of the gateway's; the device's stop: {}", summary(&stop))),
                    Err(e) => (e.exit_code, format!("the device's stop failed: {}", e.message)),
                },
            };
            let message = format!("gateway {}: {device}: {message}; its port is let go of", self.name);
            if let Err(e) = Device::close(served.device).await {
                crate::notice::say!("motionlink gateway: closing {device}: {e}");
            }
            self.ports.release(&self.name, &device, exit_code, &message);
            crate::notice::say!("motionlink gateway: stop from {who}: {message}");
            self.event(&device, &Event { message: Some(&message), ..Event::new("port_released", None) });
            self.released.push(device);
        }
    }

    /// Takes back the ports a `stop` took once they are free, and serves their devices again.
    pub(super) async fn retake_ports(&mut self) {
        let mut still = Vec::new();
        for device in std::mem::take(&mut self.released) {
            let Some((entry, spec)) = self.entries.get(&device).cloned() else { continue };
            if self.ports.claim(&self.name, &entry).is_err() {
                still.push(device);
                continue;
            }
            match Device::open(&entry, &spec).await {
                Ok(opened) => {
                    let generation = self.next_generation();
                    let moving = Arc::new(AtomicBool::new(false));
                    let served = Served { device: opened, motion: None, moving, generation };
                    self.devices.insert(device.clone(), served);
                    self.start_sampler(&device);
                    let message = format!("{device} on {} is served again", entry.port);
                    crate::notice::say!("motionlink gateway: {message}");
                    self.event(&device, &Event { message: Some(&message), ..Event::new("port_taken", None) });
                }
                Err(e) => {
                    // Let go of the port and try again later.
                    self.ports.release(&self.name, &device, 3, &e.message);
                    tracing::warn!("{device}: opening {} again: {}", entry.port, e.message);
                    still.push(device);
                }
            }
        }
        self.released = still;
    }
}
