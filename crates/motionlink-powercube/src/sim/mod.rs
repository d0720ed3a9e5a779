//! An emulated bus of PowerCube modules, sans-IO.
//!
//! [`Emulator`] holds modules at their addresses and answers as they would. It implements
//! [`Emulator`] (RS232 framing on a byte stream, for TCP, a pty or an in-process
//! [`EmulatorHost`](motionlink_link::pipe::EmulatorHost)) and [`CanEmulator`] (frames on a CAN bus, for the
//! in-memory [`CanBus`](motionlink_link::can::CanBus) or an [`SlcanAdapter`](motionlink_link::can::SlcanAdapter)
//! on a pty), and exchanges Profibus-DP process images ([`Emulator::profibus_exchange`]).
//!
//! Each module's axis follows the profile of its last motion command as a function of time: nothing runs
//! between calls, everything is computed for the timestamp given (a watchdog that expired, a soft limit
//! crossed, a ramp that ended, all at the instant they happened). The emulator never reads a clock.
//!
//! ```
//! use motionlink_powercube::sim::{Emulator, SimConfig};
//! use motionlink_powercube::model::{Param, StateFlag, CubeState, Value};
//! use motionlink_powercube::wire::{Action, Reply, Request};
//! use motionlink_link::Timestamp;
//!
//! let mut bus = Emulator::new(&SimConfig::default());
//! let at = |ms| Timestamp::from_millis(ms);
//! assert!(bus.request(at(0), 1, &Request::Action(Action::Home)).is_some());
//! let Some(Reply::Get(_, Value::U32(state))) = bus.request(at(5_000), 1, &Request::Get(Param::CubeState)) else {
//!     panic!()
//! };
//! assert!(CubeState(state).contains(StateFlag::HomeOk));
//! ```

mod config;
mod module;
mod module_commands;
mod module_params;
pub(crate) mod profile;
mod variant;

use motionlink_link::can::{CanEmulator, CanFrame};
use motionlink_link::emulator::Emulator as ByteEmulator;
use motionlink_link::Timestamp;

pub use config::{ModuleConfig, SimConfig, SimConfigError};
pub use module::{SimModule, SERVO_LAG_S};
pub use motionlink_link::emulator::FirmwareVariant;
pub use variant::{UnknownVariant, Variant};

use crate::model::{Broadcast, ConfigFlag};
use crate::wire::can::{self as can_wire, Role};
use crate::wire::profibus::{InputImage, OutputImage};
use crate::wire::rs232::{self, Rs232Decoder, TelKind};
use crate::wire::Payload;
use crate::wire::{Reply, Request};

/// Counters of what the emulator received and could not use.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SimStats {
    /// Frames answered or acted upon.
    pub handled: u64,
    /// Malformed frames and garbage (RS232 decoder errors, foreign CAN frames).
    pub malformed: u64,
    /// Frames dropped for a wrong BCC (strict mode only).
    pub bad_bcc: u64,
    /// Frames with a length that differs from the TELID's (never interpreted, as the manual says).
    pub bad_length: u64,
    /// Commands the modules did not understand (unknown command, parameter or mode).
    pub not_understood: u64,
    /// Frames for addresses where no module is.
    pub nobody: u64,
}

/// A bus of emulated modules.
#[derive(Debug, Clone)]
pub struct Emulator {
    modules: Vec<SimModule>,
    decoder: Rs232Decoder,
    strict_bcc: bool,
    rs232_broadcasts: bool,
    stats: SimStats,
    last_image: Vec<(u8, OutputImage, InputImage)>,
    can_baud: Option<crate::model::CanBaud>,
    variants: Vec<Variant>,
}

fn secs(now: Timestamp) -> f64 {
    now.since_origin().as_secs_f64()
}

impl Emulator {
    /// The modules of `config`, as RS232 modules (the Setup word says RS232).
    pub fn new(config: &SimConfig) -> Self {
        Self::build(config, false)
    }

    /// The modules of `config`, as CAN modules (the Setup word says CAN).
    pub fn new_can(config: &SimConfig) -> Self {
        Self::build(config, true)
    }

    fn build(config: &SimConfig, can: bool) -> Self {
        Emulator {
            modules: config
                .modules
                .iter()
                .map(|m| {
                    let mut module = SimModule::new(m.address, m, config.watchdog_timeout_ms, can);
                    module.firmware = variant::Firmware::of(&config.variants);
                    module
                })
                .collect(),
            decoder: Rs232Decoder::new(),
            strict_bcc: false,
            rs232_broadcasts: true,
            stats: SimStats::default(),
            last_image: Vec::new(),
            can_baud: None,
            variants: config.variants.clone(),
        }
    }

    /// The firmware variants the modules run.
    pub fn variants(&self) -> &[Variant] {
        &self.variants
    }

    /// Runs every module as the firmware `variants` say from now on (what they hold stays as it is: Inc
    /// twins kept apart from now on start with the values they mirrored).
    pub fn set_variants(&mut self, variants: &[Variant]) {
        self.variants = variants.to_vec();
        let firmware = variant::Firmware::of(variants);
        for m in &mut self.modules {
            if firmware.no_twin_mirror && !m.firmware.no_twin_mirror {
                m.twins = [m.target_pos, m.target_vel, m.target_acc];
            }
            m.firmware = firmware;
        }
    }

    fn has(&self, v: Variant) -> bool {
        self.variants.contains(&v)
    }

    /// Check the BCC of incoming RS232 frames and drop those that are wrong. Off by default: the manual says
    /// the modules do not check it.
    pub fn set_strict_bcc(&mut self, strict: bool) {
        self.strict_bcc = strict;
    }

    /// Take RS232 frames to address 0 as broadcasts to every module (the default), or ignore them, as real
    /// RS232 modules may: the manual defines no broadcast on RS232.
    pub fn set_rs232_broadcasts(&mut self, on: bool) {
        self.rs232_broadcasts = on;
    }

    /// The module at `address`.
    pub fn module(&self, address: u8) -> Option<&SimModule> {
        self.modules.iter().find(|m| m.address() == address)
    }

    /// The module at `address`, to change it (inputs, injected faults).
    pub fn module_mut(&mut self, address: u8) -> Option<&mut SimModule> {
        self.modules.iter_mut().find(|m| m.address() == address)
    }

    /// Every module.
    pub fn modules(&self) -> &[SimModule] {
        &self.modules
    }

    /// What was received and not used.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// What the modules did since the last call, oldest first, one line each: "module 1 motion started: ramp
    /// to 1.2000 rad", "module 1 at rest 1.2000 rad", "module 1 homed", "module 1 halted", "module 1 reset",
    /// "module 1 watchdog online" / "offline", "module 1 watchdog expired: STATE_COMM_ERROR", "module 1 error:
    /// STATE_TOW_ERROR", "module 1 position saved: 0.3000 rad", "module 1 ignored SetMotion ...: halted or
    /// not homed". Watchdog refreshes and reads are not events. `motionlink sim powercube --events` prints
    /// them.
    pub fn take_events(&mut self) -> Vec<String> {
        let mut all: Vec<(f64, String)> = self.modules.iter_mut().flat_map(SimModule::take_events).collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        all.into_iter().map(|(_, text)| text).collect()
    }

    /// The time of the next change a module makes by itself (a watchdog expiry, the end of a motion, a
    /// limit or tow error), rounded up to the nanosecond: a server that looks at the bus then sees it happen
    /// on time, and reports its event at once.
    pub fn next_change(&self) -> Option<Timestamp> {
        self.modules
            .iter()
            .filter_map(SimModule::next_change_at)
            .min_by(f64::total_cmp)
            .map(|t| Timestamp::from_duration(std::time::Duration::from_nanos((t.max(0.0) * 1e9).ceil() as u64)))
    }

    /// Brings every module to `now`.
    pub fn update(&mut self, now: Timestamp) {
        let t = secs(now);
        for m in &mut self.modules {
            m.update(t);
        }
    }

    /// A request to the module at `address` at `now`; its acknowledge, if it answers.
    pub fn request(&mut self, now: Timestamp, address: u8, request: &Request) -> Option<Reply> {
        self.update(now);
        let module = self.modules.iter_mut().find(|m| m.address() == address)?;
        module.handle(secs(now), request)
    }

    /// The CAN bit rate the last change-baud-rate broadcast switched the bus to (`None`: none came). The
    /// emulator only records it (each module too, [`SimModule::can_baud`]): the in-memory link keeps its
    /// pace, where a real bus would need every node and the host to switch together.
    pub fn can_baud(&self) -> Option<crate::model::CanBaud> {
        self.can_baud
    }

    /// A broadcast at `now` (no acknowledge).
    pub fn broadcast(&mut self, now: Timestamp, broadcast: &Broadcast) {
        self.update(now);
        if let Broadcast::ChangeBaudRate(b) = broadcast {
            self.can_baud = Some(*b);
        }
        for m in &mut self.modules {
            m.broadcast(secs(now), broadcast);
        }
    }

    /// A payload for `address` (0: a broadcast); the acknowledge payload, if any.
    fn payload(&mut self, now: Timestamp, address: u8, payload: &Payload, can: bool) -> Option<Payload> {
        if address == 0 {
            match Broadcast::decode(payload) {
                Ok(b) => {
                    self.stats.handled += 1;
                    self.broadcast(now, &b);
                }
                Err(e) => {
                    self.stats.not_understood += 1;
                    tracing::debug!("broadcast {payload:?}: {e}");
                }
            }
            return None;
        }
        if self.module(address).is_none() {
            self.stats.nobody += 1;
            return None;
        }
        let request = match Request::decode(payload) {
            Ok(r) => r,
            Err(e) => {
                self.stats.not_understood += 1;
                tracing::debug!("module {address}: {payload:?}: {e}");
                return None;
            }
        };
        self.stats.handled += 1;
        // The setting in force when the command arrives decides (so the write that sets it is acknowledged).
        let acks_off = can
            && !matches!(request, Request::Get(_))
            && self.module(address).is_some_and(|m| m.config_word().contains(ConfigFlag::DisableAck));
        let reply = self.request(now, address, &request)?;
        (!acks_off).then(|| reply.encode())
    }

    /// One Profibus-DP cycle with the module at `address`: the master's output image in, the input image
    /// out. As on a real module, an output image identical to the previous one is not interpreted again (the
    /// previous input image is repeated, with fresh position, state and milliseconds).
    pub fn profibus_exchange(&mut self, now: Timestamp, address: u8, output: &OutputImage) -> Option<InputImage> {
        self.update(now);
        let previous = self.last_image.iter().position(|(a, _, _)| *a == address);
        let reply = match previous {
            Some(i) if self.last_image[i].1 == *output => self.last_image[i].2.reply(8),
            _ => {
                // The command's length is not in the image: try the lengths a command can have.
                let request = (1..=8).find_map(|n| {
                    let p = Payload::new(&output.0[..n]).ok()?;
                    Request::decode(&p).ok()
                });
                match request.and_then(|r| self.request(now, address, &r)) {
                    Some(reply) => reply.encode(),
                    None => Payload::EMPTY,
                }
            }
        };
        let module = self.module(address)?;
        let image = InputImage::new(
            &reply,
            module.position_ticks().0,
            module.state().profibus_state().0,
            (module.millis_now() % 256) as u8,
        );
        match previous {
            Some(i) => self.last_image[i] = (address, *output, image),
            None => self.last_image.push((address, *output, image)),
        }
        Some(image)
    }
}

impl ByteEmulator for Emulator {
    fn receive(&mut self, now: Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        for &b in bytes {
            let Some(result) = self.decoder.push(b) else { continue };
            let frame = match result {
                Ok(f) => f,
                Err(e) => {
                    self.stats.malformed += 1;
                    tracing::debug!("RS232: {e}");
                    continue;
                }
            };
            if frame.kind != TelKind::Send {
                continue; // another module's answer on a shared line
            }
            if !frame.length_ok() {
                self.stats.bad_length += 1;
                continue;
            }
            if self.strict_bcc && !frame.bcc_ok() {
                self.stats.bad_bcc += 1;
                continue;
            }
            let pair = frame.payload.len() == 2 && self.has(Variant::NoBroadcastPair);
            if frame.address == 0 && (!self.rs232_broadcasts || pair) {
                self.stats.nobody += 1;
                continue;
            }
            if let Some(reply) = self.payload(now, frame.address, &frame.payload, false) {
                let mut buf = [0u8; rs232::MAX_FRAME];
                if reply.len() == 3 && self.has(Variant::AckLength6) {
                    // The manual's examples: TELID length 6 for a 3-byte acknowledge, the BCC over what is sent.
                    let id = rs232::telid(TelKind::Recv, frame.address, 6);
                    let bcc = rs232::bcc(&[&id[..], reply.as_bytes()].concat());
                    let n = rs232::encode_raw(id, &reply, bcc, &mut buf);
                    out.extend_from_slice(&buf[..n]);
                } else if let Ok(n) = rs232::encode(TelKind::Recv, frame.address, &reply, &mut buf) {
                    out.extend_from_slice(&buf[..n]);
                }
            }
        }
    }

    fn advance(&mut self, now: Timestamp, _out: &mut Vec<u8>) {
        self.update(now);
    }

    /// Modules never speak unasked, and their state is computed for whatever time they are asked at; the
    /// wake-up is the next change a module makes by itself ([`Emulator::next_change`]), so that a server
    /// reports its event when it happens.
    fn next_wakeup(&self) -> Option<Timestamp> {
        self.next_change()
    }

    /// A frame the host left half-sent is dropped; the modules, their motion and watchdogs run on.
    fn connection_closed(&mut self, _now: Timestamp) {
        self.decoder.reset();
    }

    fn take_events(&mut self) -> Vec<String> {
        Emulator::take_events(self)
    }
}

impl CanEmulator for Emulator {
    fn receive(&mut self, now: Timestamp, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        let (role, payload) = match can_wire::from_frame(frame) {
            Ok(x) => x,
            Err(e) => {
                self.stats.malformed += 1;
                tracing::debug!("CAN: {e}");
                return;
            }
        };
        let address = match role {
            Role::Get(a) | Role::Put(a) => a,
            Role::Broadcast => 0,
            Role::Ack(_) => return, // another module's acknowledge
        };
        if let Some(reply) = self.payload(now, address, &payload, true) {
            // An extended motion acknowledge (8 bytes, SetMotion) on the command identifier, as the manual's
            // last CAN table shows it, where the variant says so.
            let extended = reply.len() == 8 && reply.command() == Some(crate::wire::cmd::SET_MOTION);
            let role =
                if extended && self.has(Variant::ExtAckOnPutId) { Role::Put(address) } else { Role::Ack(address) };
            out.push(can_wire::to_frame(role, &reply));
        }
    }

    fn advance(&mut self, now: Timestamp, _out: &mut Vec<CanFrame>) {
        self.update(now);
    }

    fn next_wakeup(&self) -> Option<Timestamp> {
        self.next_change()
    }

    fn take_events(&mut self) -> Vec<String> {
        Emulator::take_events(self)
    }
}

#[cfg(test)]
mod tests;
