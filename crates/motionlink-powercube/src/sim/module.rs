//! One emulated module: its parameters, its state flags, and a physical model of the axis driven by the
//! timestamps it is given.

use std::collections::BTreeMap;

use super::config::ModuleConfig;
use super::profile::{self, Phase, Profile};
use crate::model::{
    AckKind, AckPosition, Action, ConfigFlag, ConfigWord, CubeState, Dio, DioWord, DioWordFlag, ExtAck, ModuleKind,
    Motion, Param, Position, Reply, Request, SetupWord, StateFlag, Ticks, Value,
};
use crate::wire::ACK_OK;

/// The following error of the emulated servo loop is the velocity times this lag (seconds).
pub const SERVO_LAG_S: f64 = 0.005;

/// The shortest leg of a ramp loop (FRAMPLOOP); a shorter loop ends after its first leg.
const MIN_LOOP_LEG_S: f64 = 0.001;

/// How many events a module keeps for [`SimModule::take_events`] when nobody takes them (an in-process
/// emulator that runs for days): the oldest are dropped beyond this.
const MAX_EVENTS: usize = 1_000;

/// The next thing the physical model does by itself, in the order they win a tie.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Change {
    WatchdogExpiry,
    TowError,
    SoftLimit,
    MotionEnd,
}

/// What kind of motion is running (for flags and for what happens at its end).
#[derive(Debug, Clone, Copy, PartialEq)]
enum MotionKind {
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
    address: u8,
    cfg: ModuleConfig,
    config: ConfigWord,
    default_config: ConfigWord,
    setup: SetupWord,
    /// Persistent flags (errors, HOME_OK, HALTED, RAMP_END, CURLIMIT); motion flags are derived.
    flags: CubeState,
    // Limits and targets, in the module's unit.
    min_pos: f64,
    max_pos: f64,
    max_vel: f64,
    max_acc: f64,
    max_cur: f64,
    max_delta_pos: f64,
    target_pos: f64,
    target_vel: f64,
    target_acc: f64,
    home_offset: f64,
    /// Other writable parameters, kept as written.
    store: BTreeMap<u8, Value>,
    outputs: u8,
    // Motion.
    t: f64,
    pos: f64,
    prev_pos: f64,
    motion: Option<(MotionKind, Profile)>,
    step_target: f64,
    step_buffer: Option<(f64, f64)>,
    move_mode: u8,
    pending: Vec<Request>,
    /// On a CAN bus (CONFIGID_MOD_SYNC_MOTION and CONFIGID_MOD_DISABLE_ACK are valid only there).
    can: bool,
    /// The bit rate the last change-baud-rate broadcast asked for, if any.
    can_baud: Option<crate::model::CanBaud>,
    // Watchdog.
    watchdog_online: bool,
    last_refresh: f64,
    watchdog_timeout: f64,
    time_base: f64,
    saved_pos: f64,
    /// Notable changes, with the module time they happened at, for [`SimModule::take_events`].
    events: Vec<(f64, String)>,
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
            can,
            can_baud: None,
            watchdog_online: false,
            last_refresh: 0.0,
            watchdog_timeout: watchdog_timeout_ms as f64 / 1000.0,
            time_base: 0.0,
            saved_pos: 0.0,
            events: Vec::new(),
        }
    }

    /// What the module did since the last call, oldest first, each with the module time (seconds) it
    /// happened at: "module 1 motion started: ramp to 1.2000 rad", "module 1 at rest 1.2000 rad",
    /// "module 1 halted", "module 1 watchdog expired: STATE_COMM_ERROR", ... (see
    /// [`Emulator`](super::Emulator)'s `take_events`).
    pub fn take_events(&mut self) -> Vec<(f64, String)> {
        std::mem::take(&mut self.events)
    }

    fn event(&mut self, t: f64, what: impl std::fmt::Display) {
        if self.events.len() >= MAX_EVENTS {
            self.events.remove(0);
        }
        self.events.push((t, format!("module {} {what}", self.address)));
    }

    /// A position with the module's unit, for events.
    fn show_pos(&self, p: f64) -> String {
        let unit = if self.kind() == ModuleKind::Linear { "m" } else { "rad" };
        format!("{p:.4} {unit}")
    }

    /// The module time (seconds) of the next change the physical model makes by itself (a watchdog that
    /// expires, a tow error, a soft limit reached, a motion that ends), if any: when a server has to look
    /// at the module again for it to happen on time.
    pub fn next_change_at(&self) -> Option<f64> {
        self.next_change().map(|(t, _)| t.max(self.t))
    }

    fn next_change(&self) -> Option<(f64, Change)> {
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

    /// Raises error flags as a fault of the module would (a test hook): STATE_ERROR and STATE_HALTED come
    /// with them and the motion stops.
    pub fn inject_fault(&mut self, flags: CubeState) {
        let t = self.t;
        self.event(t, format!("error injected: {}", CubeState(flags.0)));
        self.flags = CubeState(self.flags.0 | flags.0).with(StateFlag::Error).with(StateFlag::Halted);
        self.stop_at(t);
    }

    fn inc_ratio(&self) -> f64 {
        self.cfg.inc_ratio
    }

    fn homed(&self) -> bool {
        self.flags.contains(StateFlag::HomeOk)
    }

    fn pos_at(&self, t: f64) -> f64 {
        match &self.motion {
            Some((_, p)) => p.pos(t),
            None => self.pos,
        }
    }

    fn vel_at(&self, t: f64) -> f64 {
        match &self.motion {
            Some((_, p)) => p.vel(t),
            None => 0.0,
        }
    }

    fn state_at(&self, t: f64) -> CubeState {
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

    fn dio_word(&self, t: f64) -> DioWord {
        let mut w = DioWord(u32::from(self.cfg.inputs & 0x0F) | (u32::from(self.outputs & 0x0F) << 4));
        let s = self.state_at(t);
        w.set(DioWordFlag::InSwr, s.contains(StateFlag::Swr));
        w
    }

    fn stop_at(&mut self, t: f64) {
        self.pos = self.pos_at(t);
        let was_moving = self.motion.take().is_some();
        self.step_buffer = None;
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
            }
            self.t = t;
        }
        if now > self.t {
            self.prev_pos = self.pos_at(self.t);
            self.t = now;
        }
    }

    fn motion_ended(&mut self, t: f64) {
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

    fn ramp_vel(&self) -> f64 {
        self.target_vel.abs().min(self.max_vel).max(1e-6)
    }

    fn ramp_acc(&self) -> f64 {
        self.target_acc.abs().min(self.max_acc).max(1e-6)
    }

    fn clamp_target(&self, p: f64) -> f64 {
        if self.homed() {
            within(p, self.min_pos, self.max_pos)
        } else {
            p
        }
    }

    fn start(&mut self, t: f64, kind: MotionKind, profile: Profile) {
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

    fn start_step(&mut self, t: f64, target: f64, duration: f64) {
        let p = self.pos_at(t);
        let target = self.clamp_target(target);
        let duration = duration.max((target - p).abs() / self.max_vel.max(1e-9));
        self.step_target = target;
        self.start(t, MotionKind::Step, Profile::Pieces(profile::step(t, p, target, duration)));
    }

    fn accepts_motion(&self, request: &Request) -> bool {
        let homing = matches!(request, Request::Action(Action::Home));
        let stopped = self.flags.contains(StateFlag::Halted) || self.flags.contains(StateFlag::Error);
        // An M3 compatible module takes no motion command but Home until it is homed.
        let m3_waits_for_home = self.config.contains(ConfigFlag::M3Compatible) && !self.homed() && !homing;
        !stopped && !m3_waits_for_home
    }

    fn execute_motion(&mut self, t: f64, request: &Request) {
        if !self.accepts_motion(request) {
            self.event(t, format!("ignored {request}: halted or not homed"));
            return;
        }
        if matches!(request, Request::Motion(m, _) if !m.is_finite()) {
            // A NaN or infinite target cannot be limited to anything: ignored, like a value the module
            // cannot apply (the acknowledge still comes).
            return;
        }
        let p = self.pos_at(t);
        let v = self.vel_at(t);
        let ratio = self.inc_ratio();
        let velocity = |this: &mut Self, target_v: f64, mode: u8| {
            let v1 = within(target_v, -this.max_vel, this.max_vel);
            let prof = profile::to_velocity(t, p, v, v1, this.ramp_acc());
            this.move_mode = mode;
            if prof.is_empty() {
                this.stop_at(t);
            } else {
                this.start(t, MotionKind::Velocity, Profile::Pieces(prof));
            }
        };
        match *request {
            Request::Motion(motion, ack) => {
                let mode = motion.id(ack).map_or(0, |m| m.code());
                match motion {
                    Motion::FRamp { pos } => self.ramp_to(t, f64::from(pos.value()), mode),
                    Motion::IRamp { pos } => self.ramp_to(t, f64::from(pos.0) / ratio, mode),
                    Motion::FStep { pos, time } => {
                        self.step_to(t, f64::from(pos.value()), f64::from(time.0) / 1000.0, mode)
                    }
                    Motion::IStep { pos, time } => {
                        self.step_to(t, f64::from(pos.0) / ratio, f64::from(time.0) / 1000.0, mode)
                    }
                    Motion::FVel { vel } => velocity(self, f64::from(vel.value()), mode),
                    Motion::IVel { vel } => velocity(self, f64::from(vel.0) / ratio, mode),
                    Motion::FCur { cur } => {
                        let c = f64::from(cur.0);
                        self.flags.set(StateFlag::CurLimit, c.abs() > self.max_cur);
                        let c = within(c, -self.max_cur, self.max_cur);
                        velocity(self, c / self.max_cur.max(1e-9) * self.max_vel, mode)
                    }
                    Motion::ICur { cur } => {
                        let c = within(f64::from(cur.0), -500.0, 500.0) / 500.0;
                        velocity(self, c * self.max_vel, mode)
                    }
                    Motion::FCosLoop { pos, time } => {
                        let p1 = self.clamp_target(f64::from(pos.value()));
                        let period = (f64::from(time.0) / 1000.0).max(1e-3);
                        self.move_mode = mode;
                        self.start(t, MotionKind::CosLoop, Profile::Cos { start: t, p0: p, p1, period });
                    }
                    Motion::FRampLoop { pos } => {
                        let to = self.clamp_target(f64::from(pos.value()));
                        self.move_mode = mode;
                        let prof = profile::ramp(t, p, v, to, self.ramp_vel(), self.ramp_acc());
                        self.start(t, MotionKind::RampLoop { from: p, to }, Profile::Pieces(prof));
                    }
                }
            }
            Request::IStep { pos, time } => {
                self.step_to(t, f64::from(pos.0) / ratio, f64::from(time.0) / 1000.0, 11);
            }
            Request::Action(Action::Home) => {
                self.flags = self.flags.without(StateFlag::HomeOk);
                let prof = profile::ramp(t, p, v, 0.0, self.cfg.home_vel.abs(), self.cfg.home_acc);
                if prof.is_empty() {
                    self.stop_at(t);
                    self.motion_ended_homing_at_once(t);
                } else {
                    self.start(t, MotionKind::Homing, Profile::Pieces(prof));
                }
            }
            _ => {}
        }
    }

    fn motion_ended_homing_at_once(&mut self, t: f64) {
        self.pos = 0.0;
        self.flags = self.flags.with(StateFlag::HomeOk).with(StateFlag::RampEnd);
        self.event(t, "homed");
    }

    fn ramp_to(&mut self, t: f64, target: f64, mode: u8) {
        let target = self.clamp_target(target);
        self.target_pos = target;
        self.move_mode = mode;
        let prof = profile::ramp(t, self.pos_at(t), self.vel_at(t), target, self.ramp_vel(), self.ramp_acc());
        if prof.is_empty() {
            self.stop_at(t);
            self.flags = self.flags.with(StateFlag::RampEnd);
        } else {
            self.start(t, MotionKind::Ramp, Profile::Pieces(prof));
        }
    }

    fn step_to(&mut self, t: f64, target: f64, duration: f64, mode: u8) {
        self.move_mode = mode;
        if matches!(self.motion, Some((MotionKind::Step, _))) {
            // A step in progress: this one waits (a newer one replaces a waiting one).
            self.step_buffer = Some((target, duration));
        } else {
            self.start_step(t, target, duration);
        }
    }

    /// Handles a request addressed to this module at `now`; returns the acknowledge, if the module sends one.
    pub fn handle(&mut self, now: f64, request: &Request) -> Option<Reply> {
        self.update(now);
        let t = now;
        match *request {
            Request::Action(action) => {
                match action {
                    Action::Reset => self.reset(t),
                    Action::Halt => self.halt(t),
                    Action::Home => self.motion_or_pending(t, request),
                    Action::ResetTime => self.time_base = t,
                    Action::LifeSign => {
                        if self.config.contains(ConfigFlag::WatchdogEnable) {
                            self.watchdog_online = !self.watchdog_online;
                            self.last_refresh = t;
                            self.event(t, if self.watchdog_online { "watchdog online" } else { "watchdog offline" });
                        }
                    }
                    Action::RecalcPid | Action::SaveParameters => {}
                }
                Some(Reply::Action(action))
            }
            Request::Get(param) => self.get(t, param).map(|v| Reply::Get(param, v)),
            Request::Set(param, value) => {
                self.set(t, param, value);
                Some(Reply::Set(param, ACK_OK))
            }
            Request::Motion(motion, ack) => {
                self.motion_or_pending(t, request);
                let id = motion.id(ack)?;
                Some(match ack {
                    AckKind::Simple => Reply::Motion { id, status: Some(ACK_OK), ext: None },
                    AckKind::Extended => {
                        let p = self.pos_at(t);
                        let position = if id.shape().float_position() {
                            AckPosition::Unit(Position::native(p as f32))
                        } else {
                            AckPosition::Ticks(Ticks((p * self.inc_ratio()).round() as i32))
                        };
                        let state = self.state_at(t).short_state();
                        Reply::Motion {
                            id,
                            status: None,
                            ext: Some(ExtAck { position, state, dio: self.dio_word(t).to_dio() }),
                        }
                    }
                })
            }
            Request::IStep { .. } => {
                self.motion_or_pending(t, request);
                Some(Reply::IStep)
            }
        }
    }

    fn motion_or_pending(&mut self, t: f64, request: &Request) {
        // CONFIGID_MOD_SYNC_MOTION is "valid only for CAN-Bus": elsewhere the flag is stored but ignored.
        let sync = self.can && self.config.contains(ConfigFlag::SyncMotion);
        if sync && !matches!(request, Request::Action(Action::Home)) {
            self.pending.push(*request);
        } else {
            self.execute_motion(t, request);
        }
    }

    /// Reset: clears the errors that can be reset and STATE_HALTED.
    pub fn reset(&mut self, t: f64) {
        self.update(t);
        self.event(t, "reset");
        for f in [
            StateFlag::Error,
            StateFlag::Halted,
            StateFlag::TowError,
            StateFlag::CommError,
            StateFlag::BeyondSoft,
            StateFlag::BeyondHard,
            StateFlag::CurLimit,
            StateFlag::PowVoltErr,
            StateFlag::LogicVolt,
        ] {
            self.flags = self.flags.without(f);
        }
        if self.flags.contains(StateFlag::PowerFault) {
            // Power faults other than voltage need a power cycle.
            self.flags = self.flags.with(StateFlag::Error).with(StateFlag::Halted);
        }
        if self.watchdog_online {
            self.last_refresh = t;
        }
    }

    /// Halt: stop at once, STATE_HALTED until a Reset.
    pub fn halt(&mut self, t: f64) {
        self.update(t);
        self.event(t, "halted");
        self.flags = self.flags.with(StateFlag::Halted);
        self.stop_at(t);
        self.pending.clear();
    }

    /// A broadcast arrived at `now`.
    pub fn broadcast(&mut self, now: f64, b: &crate::model::Broadcast) {
        use crate::model::Broadcast as B;
        self.update(now);
        match b {
            B::Reset => self.reset(now),
            B::Home => self.execute_motion(now, &Request::Action(Action::Home)),
            B::Halt => self.halt(now),
            B::WatchdogRefresh => {
                if self.watchdog_online {
                    self.last_refresh = now;
                }
            }
            B::ChangeBaudRate(b) => {
                // Recorded only: the emulated link keeps its pace (see `SimModule::can_baud`).
                tracing::info!("module {}: CAN bit rate {} bit/s", self.address, b.bps());
                self.can_baud = Some(*b);
            }
            B::SavePosition => {
                self.saved_pos = self.pos_at(now);
                self.event(now, format!("position saved: {}", self.show_pos(self.saved_pos)));
            }
            B::StartMotion => {
                for r in std::mem::take(&mut self.pending) {
                    self.execute_motion(now, &r);
                }
            }
        }
    }

    fn get(&self, t: f64, param: Param) -> Option<Value> {
        let p = self.pos_at(t);
        let v = self.vel_at(t);
        let ratio = self.inc_ratio();
        let ticks = |x: f64| (x * ratio).round() as i32;
        let f = |x: f64| Value::F32(x as f32);
        let c = &self.cfg;
        use Param as P;
        Some(match param {
            P::DefHomeOffset => f(0.0),
            P::DefGearRatio => f(c.gear_ratio),
            P::DefLinRatio => f(if self.kind() == ModuleKind::Linear { 0.01 } else { 0.0 }),
            P::DefMinPos => f(c.min_pos),
            P::DefMaxPos => f(c.max_pos),
            P::DefMaxDeltaPos => f(c.max_delta_pos),
            P::DefMaxDeltaVel => f(c.max_vel / 2.0),
            P::DefTorqueRatio => f(1.0),
            P::DefCurRatio => f(1.0),
            P::DefMinVel => f(0.0),
            P::DefMaxVel => f(c.max_vel),
            P::DefMinAcc => f(0.0),
            P::DefMaxAcc => f(c.max_acc),
            P::DefMinCur => f(0.0),
            P::DefMaxCur => f(c.max_cur),
            P::DefHomeVel => f(c.home_vel),
            P::DefHomeAcc => f(c.home_acc),
            P::DefCubeSerial => Value::U32(c.serial),
            P::DefConfig => Value::U32(self.default_config.0),
            P::DefPulsesPerTurn => Value::U32(c.pulses_per_turn),
            P::DefCubeVersion => Value::U16(c.version),
            P::DefServiceInterval => Value::U16(1000),
            P::DefBrakeTimeOut => Value::U16(100),
            P::DefAddress => Value::U8(self.address),
            P::DefPrimBaud | P::DefScndBaud => Value::U8(3),
            P::PosCount | P::ActIPos => Value::I32(ticks(p)),
            P::RefPosCount | P::HomeToZeroInc => Value::I32(0),
            P::HomeOffsetInc => Value::I32(ticks(self.home_offset)),
            P::DioSetup => Value::U32(self.dio_word(t).0),
            P::CubeState => Value::U32(self.state_at(t).0),
            P::TargetPosInc => Value::I32(ticks(self.target_pos)),
            P::TargetVelInc => Value::U32(ticks(self.target_vel).unsigned_abs()),
            P::TargetAccInc => Value::U32(ticks(self.target_acc).unsigned_abs()),
            P::StepInc => Value::I32(ticks(self.step_target)),
            P::Config => Value::U32(self.config.0),
            P::MoveMode => Value::U8(self.move_mode),
            P::IncRatio => f(ratio),
            P::ActPos | P::IPolPos => f(p),
            P::PrevActPos => f(self.prev_pos),
            P::DeltaPos => f(v * SERVO_LAG_S),
            P::MaxDeltaPos => f(self.max_delta_pos),
            P::ActVel | P::IPolVel => f(v),
            P::MinPos => f(self.min_pos),
            P::MaxPos => f(self.max_pos),
            P::MaxVel => f(self.max_vel),
            P::MaxAcc => f(self.max_acc),
            P::MaxCur => f(self.max_cur),
            P::Cur | P::ActFMotorCurrent => f(if self.motion.is_some() { 0.5 + v.abs() } else { 0.1 }),
            P::Setup => Value::U32(self.setup.0),
            P::HomeOffset => f(self.home_offset),
            P::ActIMaxDeltaPos => Value::I32(ticks(self.max_delta_pos)),
            P::ActIMinPos => Value::I32(ticks(self.min_pos)),
            P::ActIMaxPos => Value::I32(ticks(self.max_pos)),
            P::ActIMaxVel => Value::I32(ticks(self.max_vel)),
            P::ActIMaxAcc => Value::I32(ticks(self.max_acc)),
            P::ActIVel | P::ActIIPolVel => Value::I32(ticks(v)),
            P::ActIDeltaPos => Value::I32(ticks(v * SERVO_LAG_S)),
            P::ActFPosStateDio => Value::PosStateDio {
                pos: p as f32,
                state: self.state_at(t).short_state(),
                dio: self.dio_word(t).to_dio(),
            },
            P::ActFSavedPos => f(self.saved_pos),
            P::ActFHomeVel => f(c.home_vel),
            P::ActIHomeVel => Value::I32(ticks(c.home_vel)),
            P::ActFPosTime => Value::PosTime { pos: p as f32, time_ms: self.millis(t) as u16 },
            P::ActFScanPosFallEdge | P::ActFScanPosRisgEdge => f(0.0),
            P::ActRawMotorCurrent => Value::U16(100),
            P::ActRawMotorSupply => Value::U16(2400),
            P::ActRawTemp => Value::I16(300),
            P::ActRawLogicSupply => Value::U16(2400),
            P::ActFMotorSupply | P::ActFLogicSupply => f(24.0),
            P::ActFTemp => f(30.0),
            P::DefC0 | P::ActC0 => self.stored(param, Value::I16(20)),
            P::DefDamp | P::ActDamp => self.stored(param, Value::I16(4)),
            P::DefA0 | P::ActA0 => self.stored(param, Value::I16(3)),
            P::DefBurnCount => Value::U8(1),
            P::RawCur => self.stored(param, Value::I16(0)),
            P::ActSyncTime => self.stored(param, Value::U16(0)),
            P::ActMinLogicSupply | P::ActMinMotorSupply => self.stored(param, f(18.0)),
            P::ActMaxLogicSupply | P::ActMaxMotorSupply => self.stored(param, f(30.0)),
            P::ActLogicUndershootTime
            | P::ActLogicOvershootTime
            | P::ActMotorUndershootTime
            | P::ActMotorOvershootTime => self.stored(param, Value::U32(100)),
            P::ActMaxTemp => self.stored(param, f(70.0)),
            P::ActMinTemp => self.stored(param, f(0.0)),
            P::TargetPos | P::TargetVel | P::TargetAcc => return None,
        })
    }

    /// A new lower soft limit: limited to the ROM default range (chapter 12: commanded values are limited);
    /// a limit above the upper one is not applied (the module keeps its old limit), so that
    /// `min_pos <= max_pos` always holds.
    fn set_min_pos(&mut self, p: f64) {
        let p = p.max(self.cfg.min_pos);
        if p <= self.max_pos {
            self.min_pos = p;
        } else {
            tracing::debug!("module {}: MinPos {p} above MaxPos {} ignored", self.address, self.max_pos);
        }
    }

    /// A new upper soft limit; see [`SimModule::set_min_pos`].
    fn set_max_pos(&mut self, p: f64) {
        let p = p.min(self.cfg.max_pos);
        if p >= self.min_pos {
            self.max_pos = p;
        } else {
            tracing::debug!("module {}: MaxPos {p} below MinPos {} ignored", self.address, self.min_pos);
        }
    }

    fn stored(&self, param: Param, default: Value) -> Value {
        self.store.get(&param.id()).copied().unwrap_or(default)
    }

    fn millis(&self, t: f64) -> u64 {
        ((t - self.time_base).max(0.0) * 1000.0) as u64
    }

    /// The module's millisecond counter (since power on or ResetTime).
    pub fn millis_now(&self) -> u64 {
        self.millis(self.t)
    }

    fn set(&mut self, _t: f64, param: Param, value: Value) {
        if !param.access().writable() || value.check_type(param).is_err() {
            // A real module ignores what it cannot apply; the acknowledge still comes.
            return;
        }
        let Some(fl) = value.as_f64().filter(|v| v.is_finite()) else {
            // NaN or infinite: nothing to limit it to; ignored the same way.
            return;
        };
        let ratio = self.inc_ratio();
        let c = self.cfg.clone();
        let from_ticks = fl / ratio;
        use Param as P;
        match param {
            P::DioSetup => self.outputs = ((value.as_u32().unwrap_or(0) >> 4) & 0x0F) as u8,
            P::TargetPosInc => self.target_pos = from_ticks,
            P::TargetVelInc => self.target_vel = from_ticks,
            P::TargetAccInc => self.target_acc = from_ticks,
            P::Config => self.config = ConfigWord(value.as_u32().unwrap_or(0)),
            P::MaxDeltaPos => self.max_delta_pos = fl.abs(),
            P::ActIMaxDeltaPos => self.max_delta_pos = from_ticks.abs(),
            P::MinPos => self.set_min_pos(fl),
            P::ActIMinPos => self.set_min_pos(from_ticks),
            P::MaxPos => self.set_max_pos(fl),
            P::ActIMaxPos => self.set_max_pos(from_ticks),
            P::MaxVel => self.max_vel = fl.abs().min(c.max_vel),
            P::ActIMaxVel => self.max_vel = from_ticks.abs().min(c.max_vel),
            P::MaxAcc => self.max_acc = fl.abs().min(c.max_acc),
            P::ActIMaxAcc => self.max_acc = from_ticks.abs().min(c.max_acc),
            P::MaxCur => self.max_cur = fl.abs().min(c.max_cur),
            P::TargetPos => self.target_pos = fl,
            P::TargetVel => self.target_vel = fl.abs(),
            P::TargetAcc => self.target_acc = fl.abs(),
            P::HomeOffset => self.home_offset = fl,
            _ => {
                self.store.insert(param.id(), value);
            }
        }
    }
}

fn kind_is_step(kind: MotionKind) -> bool {
    kind == MotionKind::Step
}

/// `x` limited to `[lo, hi]` without ever panicking (`f64::clamp` panics when `lo > hi` or a bound is NaN);
/// if `lo > hi`, `hi` wins. The emulator's limits keep `lo <= hi`; this is the second line of defence.
fn within(x: f64, lo: f64, hi: f64) -> f64 {
    x.max(lo).min(hi)
}
