//! One emulated drive: its state, its status values, and its motion model.

use std::collections::{BTreeMap, VecDeque};

use std::fmt::Write as _;

use motionlink_link::clock::Timestamp;
use motionlink_link::link::char_time;

use super::config::{DriveConfig, SimConfig};
use super::{REFUSED, TICK, USER_GUIDE_EXAMPLE_PARAM};
use crate::model::{
    ErrorCode, HistoryEntry, ParamId, Position, S16Bits, S16Flag, S17Bits, S17Flag, StatusId, StatusValue,
};
use crate::wire::request::RequestDecoder;
use crate::wire::{Mode, TextBuf};

/// A command waiting in a drive's buffer (`,`) for `!`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Stored {
    Text(TextBuf<48>, bool),
}

impl Stored {
    /// The command's text (`POSA 12.5`).
    fn text(&self) -> &str {
        let Stored::Text(t, _) = self;
        std::str::from_utf8(t.as_bytes()).unwrap_or("")
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Comparator {
    pub(super) distance: f64,
    pub(super) output: u16,
    pub(super) state: u8,
    pub(super) number: u8,
}

/// The settings of the next positioning.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct MoveSettings {
    pub(super) speed_percent: f64,
    pub(super) accel_ms: u16,
    pub(super) brake_ms: u16,
    pub(super) comparators: Vec<Comparator>,
    pub(super) speed_step: Option<(f64, f64)>,
}

/// A positioning in progress.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Motion {
    pub(super) target: f64,
    pub(super) start: f64,
    /// Speed (units/s, >= 0, towards the target).
    pub(super) speed: f64,
    pub(super) last_tick: Timestamp,
    pub(super) settings: MoveSettings,
    pub(super) position_message: bool,
    pub(super) homing: bool,
}

/// One emulated drive.
#[derive(Debug, Clone)]
pub struct Drive {
    pub(super) params: BTreeMap<u16, f64>,
    pub(super) address: u8,
    pub(super) mode: Mode,
    pub(super) baud_rate: u32,
    /// Powered on with P196 = 164/165: the drive speaks the COMTAC fieldbus protocol, not ASCII (it takes no
    /// telegram of this crate's; only a configuration can give it ASCII again, as a fieldbus master would).
    pub(super) fieldbus: bool,
    pub(super) rx: RequestDecoder,
    pub(super) rx_last: Timestamp,
    pub(super) rx_parity_error: bool,
    /// The buffer: one command, or with [`Variant::BufferQueues`](super::Variant::BufferQueues) a queue of
    /// them, oldest first.
    pub(super) buffer: VecDeque<Stored>,
    pub(super) next: MoveSettings,
    pub(super) motion: Option<Motion>,
    pub(super) position: f64,
    pub(super) target: f64,
    pub(super) o0: u8,
    pub(super) outputs: [u8; 17],
    pub(super) homed: bool,
    pub(super) reached: bool,
    pub(super) idle_after_stop: bool,
    pub(super) motion_cycles: u64,
    pub(super) history: [u8; 8],
    /// The newest S18 entry is an RS485 error that the next error-free transmission acknowledges.
    pub(super) auto_ack: bool,
    pub(super) powered_at: Timestamp,
    /// Unsolicited messages waiting for the line to be free: texts such as `$` or a comparator number.
    pub(super) pending: Vec<TextBuf<4>>,
    pub(super) xoff: bool,
    pub(super) held: Vec<u8>,
    pub(super) max_speed: f64,
    pub(super) telegrams: u64,
    /// What happened since the last [`take_events`](motionlink_link::emulator::Emulator::take_events), one
    /// line each.
    pub(super) events: Vec<String>,
    /// The firmware variants this drive runs.
    pub(super) variants: Vec<super::Variant>,
}

impl Drive {
    pub(super) fn new(cfg: &DriveConfig, bus: &SimConfig) -> Self {
        let baud = cfg.baud_rate.unwrap_or(bus.baud_rate);
        let p196 = cfg.p196.unwrap_or(bus.p196);
        let mode = Mode::from_p196(p196).unwrap_or_default();
        let mut params = BTreeMap::new();
        params.insert(ParamId::DEVICE_ADDRESS.get(), f64::from(cfg.address));
        params.insert(ParamId::BAUD_RATE.get(), f64::from(baud));
        params.insert(ParamId::OPERATING_MODE.get(), f64::from(p196));
        // The user guide's example of a parameter write (`P003=-1055.88`): every drive models it.
        params.insert(USER_GUIDE_EXAMPLE_PARAM, 0.0);
        // Validated with the configuration.
        for (id, v) in bus.param_ids().unwrap_or_default() {
            params.insert(id.get(), v);
        }
        Drive {
            params,
            address: cfg.address,
            mode,
            baud_rate: baud,
            fieldbus: false,
            rx: RequestDecoder::for_drive(&mode),
            rx_last: Timestamp::ZERO,
            rx_parity_error: false,
            buffer: VecDeque::new(),
            next: MoveSettings {
                speed_percent: 100.0,
                accel_ms: 0,
                brake_ms: 0,
                comparators: Vec::new(),
                speed_step: None,
            },
            motion: None,
            position: cfg.position,
            target: cfg.position,
            o0: 1,
            outputs: [0; 17],
            homed: false,
            reached: true,
            idle_after_stop: false,
            motion_cycles: 0,
            history: [99; 8],
            auto_ack: false,
            powered_at: Timestamp::ZERO,
            pending: Vec::new(),
            xoff: false,
            held: Vec::new(),
            max_speed: bus.max_speed_units_per_s,
            telegrams: 0,
            events: Vec::new(),
            variants: bus.variants.clone(),
        }
    }

    /// The address in force (P194 at the last power-on).
    pub fn address(&self) -> u8 {
        self.address
    }

    /// The mode in force (P196 at the last power-on).
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The baud rate in force (P195 at the last power-on).
    pub fn baud_rate(&self) -> u32 {
        self.baud_rate
    }

    /// The actual position (S1).
    pub fn position(&self) -> f64 {
        self.position
    }

    /// The target position (S2).
    pub fn target(&self) -> f64 {
        self.target
    }

    /// The current speed in units/s (0 when idle).
    pub fn speed(&self) -> f64 {
        self.motion.as_ref().map_or(0.0, |m| m.speed)
    }

    /// True while a positioning runs (S17 "command active").
    pub fn is_moving(&self) -> bool {
        self.motion.is_some()
    }

    /// The O0 state: 1 switched on (the power-on state), 0 switched off.
    pub fn o0(&self) -> u8 {
        self.o0
    }

    /// The state of output `n` (1..=16).
    pub fn output(&self, n: u16) -> Option<u8> {
        self.outputs.get(usize::from(n)).copied()
    }

    /// A parameter as stored (written values of P194..P196 take effect at power-on); `None` for one the drive
    /// does not model (see [`SimConfig::params`]).
    pub fn param(&self, id: ParamId) -> Option<f64> {
        self.params.get(&id.get()).copied()
    }

    /// The error history S18, newest first (99: acknowledged).
    pub fn history(&self) -> [u8; 8] {
        self.history
    }

    /// Records error `code` in S18. The RS485 errors E70..E73 need no acknowledgement (manual chapter 6):
    /// the next error-free transmission acknowledges them, which S18 shows as 99.
    pub(super) fn record(&mut self, code: ErrorCode) {
        self.event(format!("error {code}"));
        self.history.rotate_right(1);
        self.history[0] = code.0;
        self.auto_ack = (70..=73).contains(&code.0);
    }

    /// Notes an event of this drive (`drive N ...`) for [`Emulator::take_events`].
    pub(super) fn event(&mut self, what: String) {
        self.events.push(format!("drive {} {what}", self.address));
    }

    /// Number of telegrams addressed to this drive (or broadcast) that it executed or answered.
    pub fn telegrams(&self) -> u64 {
        self.telegrams
    }

    /// The command held in the buffer (stored with `,`, executed by `!`), if any: `POSA 12.5`. Where the
    /// buffer is a queue ([`Variant::BufferQueues`](super::Variant::BufferQueues)), the oldest: the one the
    /// next `!` executes.
    pub fn buffered(&self) -> Option<&str> {
        self.buffer.front().map(Stored::text)
    }

    /// Every command held in the buffer, oldest first (more than one only where the buffer is a queue).
    pub fn buffered_all(&self) -> Vec<&str> {
        self.buffer.iter().map(Stored::text).collect()
    }

    /// The speed and ramp settings for the next positioning: (percent, accel ms, brake ms).
    pub fn move_settings(&self) -> (f64, u16, u16) {
        (self.next.speed_percent, self.next.accel_ms, self.next.brake_ms)
    }

    pub(super) fn s16(&self) -> S16Bits {
        let mut b = S16Bits(0);
        b.set(S16Flag::NoFault, true);
        b.set(S16Flag::NoWarning, true);
        b.set(S16Flag::MachineZero, self.homed);
        b.set(S16Flag::ReadyForStart, self.o0 == 1 && self.motion.is_none());
        b.set(S16Flag::PositionReached, self.reached && self.motion.is_none());
        b.set(S16Flag::IdleAfterStop, self.idle_after_stop);
        b.set(S16Flag::O0Bit7, self.o0 == 1);
        b.set(S16Flag::O0Bit8, self.o0 == 2);
        b
    }

    pub(super) fn s17(&self) -> S17Bits {
        let mut b = S17Bits(0);
        let shows_command = !self.variants.contains(&super::Variant::NoCommandBit);
        b.set(S17Flag::CommandActive, self.motion.is_some() && shows_command);
        b.set(S17Flag::Run, self.o0 == 1);
        b
    }

    /// Status value `id`, or [`REFUSED`] for one the emulator does not model.
    pub(super) fn status(&self, id: StatusId, now: Timestamp) -> Result<StatusValue, ErrorCode> {
        let pos = |v: f64| StatusValue::Position(Position::new(v).unwrap_or_default());
        let text = |s: &str| {
            let mut t = TextBuf::new();
            let _ = t.write_str(s);
            StatusValue::Text(t)
        };
        Ok(match id {
            StatusId::ACTUAL_POSITION | StatusId::ABSOLUTE_SENSOR => pos(self.position),
            StatusId::TARGET_POSITION => pos(self.target),
            StatusId::CONTOUR_ERROR => pos(0.0),
            StatusId::TEMPERATURE => StatusValue::Number(35.0),
            StatusId::CONTROL_VOLTAGE => StatusValue::Number(24.0),
            StatusId::DC_LINK_VOLTAGE => StatusValue::Number(560.0),
            StatusId::MOTION_CYCLES => StatusValue::Number(self.motion_cycles as f64),
            StatusId::OPERATING_HOURS => {
                StatusValue::Number(now.saturating_since(self.powered_at).as_secs_f64() / 3600.0)
            }
            StatusId::STATUS_BITS_1 => StatusValue::S16(self.s16()),
            StatusId::STATUS_BITS_2 => StatusValue::S17(self.s17()),
            StatusId::ERROR_HISTORY => StatusValue::History(self.history.map(HistoryEntry::from_number)),
            StatusId::DEVICE_ID_1 => text("COMPAX EMULATOR"),
            StatusId::DEVICE_ID_2 => text("MOTIONLINK"),
            // Not modelled (S4, S5, S11 without programs, S13..S15, S19..S30, S33..S40): refused, not 0.
            _ => return Err(REFUSED),
        })
    }

    /// Runs the motion model up to `now`.
    pub(super) fn update(&mut self, now: Timestamp) {
        while let Some(m) = self.motion.as_mut() {
            let tick_at = m.last_tick + TICK;
            if tick_at > now {
                break;
            }
            m.last_tick = tick_at;
            let dt = TICK.as_secs_f64();
            let remaining = (m.target - self.position).abs();
            let dir = if m.target >= self.position { 1.0 } else { -1.0 };
            let travelled = (self.position - m.start).abs();
            let mut percent = m.settings.speed_percent;
            if let Some((at, step)) = m.settings.speed_step {
                if travelled >= at {
                    percent = step;
                }
            }
            let cruise = self.max_speed * percent / 100.0;
            let rate = |ms: u16| if ms == 0 { f64::INFINITY } else { self.max_speed / (f64::from(ms) / 1000.0) };
            let accel = rate(m.settings.accel_ms);
            let brake = rate(m.settings.brake_ms);
            let stoppable = (2.0 * brake * remaining).sqrt();
            let want = cruise.min(stoppable);
            m.speed = if m.speed < want { (m.speed + accel * dt).min(want) } else { (m.speed - brake * dt).max(want) };
            let step = m.speed * dt;
            let finished = step >= remaining || remaining < 1e-9;
            let new_pos = if finished { m.target } else { self.position + dir * step };
            let new_travelled = (new_pos - m.start).abs();
            for c in m.settings.comparators.iter().filter(|c| travelled < c.distance && new_travelled >= c.distance) {
                if let Some(o) = self.outputs.get_mut(usize::from(c.output)) {
                    *o = c.state;
                }
                let mut t = TextBuf::new();
                let _ = write!(t, "{}", c.number);
                self.pending.push(t);
            }
            self.position = new_pos;
            if finished {
                let m = self.motion.take().expect("checked above");
                self.reached = true;
                self.motion_cycles += 1;
                self.event(format!("at rest {:.3}", self.position));
                if m.homing {
                    self.homed = true;
                }
                if m.position_message && !self.variants.contains(&super::Variant::NoPositionMessage) {
                    let mut t = TextBuf::new();
                    let _ = t.write_str("$");
                    self.pending.push(t);
                }
            }
        }
    }

    pub(super) fn next_wakeup(&self) -> Option<Timestamp> {
        let tick = self.motion.as_ref().map(|m| m.last_tick + TICK);
        let timeout = self.rx_deadline();
        [tick, timeout].into_iter().flatten().min()
    }

    pub(super) fn rx_deadline(&self) -> Option<Timestamp> {
        (self.mode.timeout_supervision && !self.rx.is_idle() && self.could_be_mine())
            .then(|| self.rx_last + char_time(self.baud_rate, self.mode.parity) * 5)
    }

    /// True while the telegram being received may be addressed to this drive (its address digits so far).
    pub(super) fn could_be_mine(&self) -> bool {
        let a = self.rx.partial_address();
        self.address != 0 && (a == self.address || (!self.rx.past_address() && a != 0 && self.address / 10 == a))
    }
}
