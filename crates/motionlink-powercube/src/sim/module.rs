//! One emulated module: its parameters, its state flags, and a physical model of the axis driven by the
//! timestamps it is given.

use std::collections::BTreeMap;

use super::config::ModuleConfig;
use super::profile::{self, Phase, Profile};
use crate::model::{
    ConfigFlag, ConfigWord, CubeState, Dio, DioWord, DioWordFlag, ModuleKind, Position, SetupWord, StateFlag, Ticks,
    Value,
};
use crate::wire::Request;

/// The following error of the emulated servo loop is the velocity times this lag (seconds).
pub const SERVO_LAG_S: f64 = 0.005;

/// The shortest leg of a ramp loop (FRAMPLOOP); a shorter loop ends after its first leg.
const MIN_LOOP_LEG_S: f64 = 0.001;

/// How many events a module keeps for [`SimModule::take_events`] when nobody takes them (an in-process
/// emulator that runs for days): the oldest are dropped beyond this.
const MAX_EVENTS: usize = 1_000;

/// The next thing the physical model does by itself, in the order they win a tie.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Change {
    WatchdogExpiry,
    TowError,
    SoftLimit,
    MotionEnd,
    /// A motion command taken late (`late-motion-start`) starts.
    DelayedStart,
}

/// What kind of motion is running (for flags and for what happens at its end).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum MotionKind {
    Homing,
    Ramp,
    /// A ramp loop between two positions: after reaching `to`, head back to `from`.
    RampLoop {
        from: f64,
        to: f64,
    },
    Step,
    Velocity,
    CosLoop,
}

/// The state of one emulated module.
#[derive(Debug, Clone)]
pub struct SimModule {
    pub(super) address: u8,
    pub(super) cfg: ModuleConfig,
    pub(super) config: ConfigWord,
    pub(super) default_config: ConfigWord,
    pub(super) setup: SetupWord,
    /// Persistent flags (errors, HOME_OK, HALTED, RAMP_END, CURLIMIT); motion flags are derived.
    pub(super) flags: CubeState,
    // Limits and targets, in the module's unit.
    pub(super) min_pos: f64,
    pub(super) max_pos: f64,
    pub(super) max_vel: f64,
    pub(super) max_acc: f64,
    pub(super) max_cur: f64,
    pub(super) max_delta_pos: f64,
    pub(super) target_pos: f64,
    pub(super) target_vel: f64,
    pub(super) target_acc: f64,
    pub(super) home_offset: f64,
    /// Other writable parameters, kept as written.
    pub(super) store: BTreeMap<u8, Value>,
    pub(super) outputs: u8,
    // Motion.
    pub(super) t: f64,
    pub(super) pos: f64,
    pub(super) prev_pos: f64,
    pub(super) motion: Option<(MotionKind, Profile)>,
    pub(super) step_target: f64,
    pub(super) step_buffer: Option<(f64, f64)>,
    pub(super) move_mode: u8,
    pub(super) pending: Vec<Request>,
    /// A motion command acknowledged at rest and not yet started, and when it starts (`late-motion-start`).
    pub(super) delayed: Option<(f64, Request)>,
    /// On a CAN bus (CONFIGID_MOD_SYNC_MOTION and CONFIGID_MOD_DISABLE_ACK are valid only there).
    pub(super) can: bool,
    /// The bit rate the last change-baud-rate broadcast asked for, if any.
    pub(super) can_baud: Option<crate::model::CanBaud>,
    // Watchdog.
    pub(super) watchdog_online: bool,
    pub(super) last_refresh: f64,
    pub(super) watchdog_timeout: f64,
    pub(super) time_base: f64,
    pub(super) saved_pos: f64,
    /// Notable changes, with the module time they happened at, for [`SimModule::take_events`].
    pub(super) events: Vec<(f64, String)>,
    /// The firmware variant this module runs ([`Variant`](super::Variant)).
    pub(super) firmware: super::variant::Firmware,
    /// TargetPosInc, TargetVelInc and TargetAccInc (in the module's unit) of a module that keeps them apart
    /// from the float targets (`no-twin-mirror`); unused otherwise.
    pub(super) twins: [f64; 3],
}

impl SimModule {
    /// A module at `address` configured by `cfg`, at time zero.
    pub fn new(address: u8, cfg: &ModuleConfig, watchdog_timeout_ms: u64, can: bool) -> Self {
        let mut config = ConfigWord::EMPTY;
        config.set(ConfigFlag::Linear, cfg.kind == ModuleKind::Linear);
        config.set(ConfigFlag::BrakePresent, cfg.brake);
        config.set(ConfigFlag::SwrEnabled, true);
        let mut setup = SetupWord(0x08); // 4 in, 4 out
        setup = SetupWord(setup.0 | if can { 0x200 } else { 0x40 });
        SimModule {
            address,
            cfg: cfg.clone(),
            config,
            default_config: config,
            setup,
            flags: CubeState::EMPTY,
            min_pos: cfg.min_pos,
            max_pos: cfg.max_pos,
            max_vel: cfg.max_vel,
            max_acc: cfg.max_acc,
            max_cur: cfg.max_cur,
            max_delta_pos: cfg.max_delta_pos,
            target_pos: 0.0,
            target_vel: cfg.max_vel / 2.0,
            target_acc: cfg.max_acc / 2.0,
            home_offset: 0.0,
            store: BTreeMap::new(),
            outputs: 0,
            t: 0.0,
            pos: cfg.start_position,
            prev_pos: cfg.start_position,
            motion: None,
            step_target: cfg.start_position,
            step_buffer: None,
            move_mode: 0,
            pending: Vec::new(),
            delayed: None,
            can,
            can_baud: None,
            watchdog_online: false,
            last_refresh: 0.0,
            watchdog_timeout: watchdog_timeout_ms as f64 / 1000.0,
            time_base: 0.0,
            saved_pos: 0.0,
            events: Vec::new(),
            firmware: super::variant::Firmware::default(),
            twins: [0.0, cfg.max_vel / 2.0, cfg.max_acc / 2.0],
        }
    }

    /// What the module did since the last call, oldest first, each with the module time (seconds) it
    /// happened at: "module 1 motion started: ramp to 1.2000 rad", "module 1 at rest 1.2000 rad",
    /// "module 1 halted", "module 1 watchdog expired: STATE_COMM_ERROR", ... (see
    /// [`Emulator`](super::Emulator)'s `take_events`).
    pub fn take_events(&mut self) -> Vec<(f64, String)> {
        std::mem::take(&mut self.events)
    }

    pub(super) fn event(&mut self, t: f64, what: impl std::fmt::Display) {
        if self.events.len() >= MAX_EVENTS {
            self.events.remove(0);
        }
        self.events.push((t, format!("module {} {what}", self.address)));
    }

    /// A position with the module's unit, for events.
    pub(super) fn show_pos(&self, p: f64) -> String {
        let unit = if self.kind() == ModuleKind::Linear { "m" } else { "rad" };
        format!("{p:.4} {unit}")
    }

    /// The module time (seconds) of the next change the physical model makes by itself (a watchdog that
    /// expires, a tow error, a soft limit reached, a motion that ends), if any: when a server has to look
    /// at the module again for it to happen on time.
    pub fn next_change_at(&self) -> Option<f64> {
        self.next_change().map(|(t, _)| t.max(self.t))
    }

    pub(super) fn next_change(&self) -> Option<(f64, Change)> {
        let watchdog = (self.watchdog_online && !self.flags.contains(StateFlag::CommError))
            .then_some(self.last_refresh + self.watchdog_timeout);
        let (end, outside, tow) = match &self.motion {
            Some((kind, p)) => {
                let outside = (self.homed() && *kind != MotionKind::Homing)
                    .then(|| p.first_outside(self.t, self.min_pos, self.max_pos))
                    .flatten();
                let tow = p.first_over_speed(self.t, self.max_delta_pos / SERVO_LAG_S);
                (p.end(), outside, tow)
            }
            None => (None, None, None),
        };
        [
            (watchdog, Change::WatchdogExpiry),
            (tow, Change::TowError),
            (outside, Change::SoftLimit),
            (end, Change::MotionEnd),
            (self.delayed.map(|(at, _)| at), Change::DelayedStart),
        ]
        .into_iter()
        .filter_map(|(t, c)| t.map(|t| (t, c)))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
    }

    /// The bus address.
    pub fn address(&self) -> u8 {
        self.address
    }

    /// Rotary or linear (from the Config word).
    pub fn kind(&self) -> ModuleKind {
        if self.config.contains(ConfigFlag::Linear) {
            ModuleKind::Linear
        } else {
            ModuleKind::Rotary
        }
    }

    /// The position at the module's last update.
    pub fn position(&self) -> Position {
        Position::native(self.pos_at(self.t) as f32)
    }

    /// The state word at the module's last update.
    pub fn state(&self) -> CubeState {
        self.state_at(self.t)
    }

    /// The DIO byte at the module's last update.
    pub fn dio(&self) -> Dio {
        self.dio_word(self.t).to_dio()
    }

    /// The position in encoder ticks at the module's last update.
    pub fn position_ticks(&self) -> Ticks {
        Ticks((self.pos_at(self.t) * self.inc_ratio()).round() as i32)
    }

    /// The CAN bit rate the last change-baud-rate broadcast asked for (`None`: none came). Only recorded:
    /// the in-memory link keeps its pace, as switching a real bus needs every node and the host to switch
    /// together.
    pub fn can_baud(&self) -> Option<crate::model::CanBaud> {
        self.can_baud
    }

    /// True while the watchdog is online (switched on by a life sign).
    pub fn watchdog_online(&self) -> bool {
        self.watchdog_online
    }

    /// The Config word.
    pub fn config_word(&self) -> ConfigWord {
        self.config
    }

    /// Sets the digital inputs 0..3 (as the outside world would).
    pub fn set_inputs(&mut self, inputs: u8) {
        self.cfg.inputs = inputs & 0x0F;
    }

    /// Raises a flag without anything else (a warning such as STATE_CURLIMIT), for tests.
    #[cfg(test)]
    pub(crate) fn set_flag_for_test(&mut self, flag: crate::model::StateFlag) {
        self.flags = self.flags.with(flag);
    }

    /// Raises error flags as a fault of the module would (a test hook): STATE_ERROR and STATE_HALTED come
    /// with them and the motion stops.
    pub fn inject_fault(&mut self, flags: CubeState) {
        let t = self.t;
        self.event(t, format!("error injected: {}", CubeState(flags.0)));
        self.flags = CubeState(self.flags.0 | flags.0).with(StateFlag::Error).with(StateFlag::Halted);
        self.stop_at(t);
    }

    pub(super) fn inc_ratio(&self) -> f64 {
        self.cfg.inc_ratio
    }

    pub(super) fn homed(&self) -> bool {
        self.flags.contains(StateFlag::HomeOk)
    }

    pub(super) fn pos_at(&self, t: f64) -> f64 {
        match &self.motion {
            Some((_, p)) => p.pos(t),
            None => self.pos,
        }
    }

    pub(super) fn vel_at(&self, t: f64) -> f64 {
        match &self.motion {
            Some((_, p)) => p.vel(t),
            None => 0.0,
        }
    }

    pub(super) fn state_at(&self, t: f64) -> CubeState {
        let mut s = self.flags;
        if let Some((kind, profile)) = &self.motion {
            s = s.with(StateFlag::Motion);
            if matches!(kind, MotionKind::Ramp | MotionKind::RampLoop { .. } | MotionKind::Homing) {
                match profile.phase(t) {
                    Some(Phase::Acc) => s = s.with(StateFlag::RampAcc),
                    Some(Phase::Steady) => s = s.with(StateFlag::RampSteady),
                    Some(Phase::Dec) => s = s.with(StateFlag::RampDec),
                    None => {}
                }
            }
            if *kind == MotionKind::Step {
                s = s.with(StateFlag::InProgress);
            }
        }
        if self.step_buffer.is_some() {
            s = s.with(StateFlag::FullBuffer);
        }
        if self.config.contains(ConfigFlag::BrakePresent) && self.motion.is_none() {
            s = s.with(StateFlag::BrakeActive);
        }
        if self.homed() && self.pos_at(t).abs() < 1e-4 {
            s = s.with(StateFlag::Swr);
        }
        s
    }

    pub(super) fn dio_word(&self, t: f64) -> DioWord {
        let mut w = DioWord(u32::from(self.cfg.inputs & 0x0F) | (u32::from(self.outputs & 0x0F) << 4));
        let s = self.state_at(t);
        w.set(DioWordFlag::InSwr, s.contains(StateFlag::Swr));
        w
    }

    pub(super) fn stop_at(&mut self, t: f64) {
        self.pos = self.pos_at(t);
        let was_moving = self.motion.take().is_some();
        self.step_buffer = None;
        self.delayed = None;
        if was_moving {
            self.event(t, format!("at rest {}", self.show_pos(self.pos)));
        }
    }

    /// Brings the physical model to `now`: motion ends, soft limits, following errors and the watchdog, in
    /// the order they happen.
    pub fn update(&mut self, now: f64) {
        while let Some((t, change)) = self.next_change().filter(|(t, _)| *t <= now) {
            let t = t.max(self.t);
            match change {
                Change::WatchdogExpiry => {
                    // The manual (STATE_COMM_ERROR): the drive follows the emergency stop routine and enters
                    // an error state, so STATE_ERROR too (which Profibus shows as STATE_ERRORM4).
                    self.event(t, "watchdog expired: STATE_COMM_ERROR");
                    self.flags = self.flags.with(StateFlag::CommError).with(StateFlag::Error).with(StateFlag::Halted);
                    self.stop_at(t);
                }
                Change::TowError => {
                    self.event(t, "error: STATE_TOW_ERROR");
                    self.flags = self.flags.with(StateFlag::TowError).with(StateFlag::Error).with(StateFlag::Halted);
                    self.stop_at(t);
                }
                Change::SoftLimit => {
                    let p = within(self.pos_at(t), self.min_pos, self.max_pos);
                    self.event(t, "error: STATE_BEYOND_SOFT");
                    self.flags = self.flags.with(StateFlag::BeyondSoft).with(StateFlag::Error).with(StateFlag::Halted);
                    self.motion = None;
                    self.step_buffer = None;
                    self.pos = p;
                    self.event(t, format!("at rest {}", self.show_pos(p)));
                }
                Change::MotionEnd => self.motion_ended(t),
                Change::DelayedStart => {
                    if let Some((_, request)) = self.delayed.take() {
                        self.execute_motion(t, &request);
                    }
                }
            }
            self.t = t;
        }
        if now > self.t {
            self.prev_pos = self.pos_at(self.t);
            self.t = now;
        }
    }

    pub(super) fn motion_ended(&mut self, t: f64) {
        let Some((kind, profile)) = self.motion.take() else { return };
        self.pos = profile.end_pos().unwrap_or_else(|| profile.pos(t));
        match kind {
            MotionKind::Homing => {
                self.pos = 0.0;
                self.flags = self.flags.with(StateFlag::HomeOk).with(StateFlag::RampEnd);
                self.event(t, "homed");
            }
            MotionKind::Ramp => {
                // A module that does not settle on its target (configured, for testing in-position checks).
                self.pos += self.cfg.settle_offset;
                self.flags = self.flags.with(StateFlag::RampEnd);
            }
            MotionKind::RampLoop { from, to } => {
                let back = profile::ramp(t, self.pos, 0.0, from, self.ramp_vel(), self.ramp_acc());
                let leg = back.last().map_or(0.0, |s| s.end() - t);
                if leg >= MIN_LOOP_LEG_S {
                    self.motion = Some((MotionKind::RampLoop { from: to, to: from }, Profile::Pieces(back)));
                } else {
                    // A loop this short would turn round thousands of times a second: it ends here.
                    self.flags = self.flags.with(StateFlag::RampEnd);
                }
            }
            MotionKind::Step => {
                if let Some((target, duration)) = self.step_buffer.take() {
                    self.start_step(t, target, duration);
                }
            }
            MotionKind::Velocity | MotionKind::CosLoop => {}
        }
        if self.motion.is_none() {
            self.event(t, format!("at rest {}", self.show_pos(self.pos)));
        }
    }

    pub(super) fn ramp_vel(&self) -> f64 {
        self.target_vel.abs().min(self.max_vel).max(1e-6)
    }

    pub(super) fn ramp_acc(&self) -> f64 {
        self.target_acc.abs().min(self.max_acc).max(1e-6)
    }

    pub(super) fn clamp_target(&self, p: f64) -> f64 {
        if self.homed() {
            within(p, self.min_pos, self.max_pos)
        } else {
            p
        }
    }

    pub(super) fn start(&mut self, t: f64, kind: MotionKind, profile: Profile) {
        if matches!(&profile, Profile::Pieces(p) if p.is_empty()) {
            self.stop_at(t);
            return;
        }
        self.pos = self.pos_at(t);
        self.flags = self.flags.without(StateFlag::RampEnd);
        if !kind_is_step(kind) {
            self.step_buffer = None;
        }
        let what = match kind {
            MotionKind::Homing => "homing".to_string(),
            MotionKind::Ramp => format!("ramp to {}", self.show_pos(self.target_pos)),
            MotionKind::RampLoop { to, .. } => format!("ramp loop to {}", self.show_pos(to)),
            MotionKind::Step => format!("step to {}", self.show_pos(self.step_target)),
            MotionKind::Velocity => "velocity or current mode".to_string(),
            MotionKind::CosLoop => "cosine loop".to_string(),
        };
        self.event(t, format!("motion started: {what}"));
        self.motion = Some((kind, profile));
    }

    pub(super) fn start_step(&mut self, t: f64, target: f64, duration: f64) {
        let p = self.pos_at(t);
        let target = self.clamp_target(target);
        let duration = duration.max((target - p).abs() / self.max_vel.max(1e-9));
        self.step_target = target;
        self.start(t, MotionKind::Step, Profile::Pieces(profile::step(t, p, target, duration)));
    }
}

fn kind_is_step(kind: MotionKind) -> bool {
    kind == MotionKind::Step
}

/// `x` limited to `[lo, hi]` without ever panicking (`f64::clamp` panics when `lo > hi` or a bound is NaN);
/// if `lo > hi`, `hi` wins. The emulator's limits keep `lo <= hi`; this is the second line of defence.
pub(super) fn within(x: f64, lo: f64, hi: f64) -> f64 {
    x.max(lo).min(hi)
}
