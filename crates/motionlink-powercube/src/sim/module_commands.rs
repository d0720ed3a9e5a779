//! What an emulated module does with the commands it receives: motion commands (or their buffering for a
//! synchronised start), Reset, Halt, broadcasts, and the acknowledge it answers with.

use super::module::{within, MotionKind, SimModule};
use super::profile::{self, Profile};
use crate::model::{AckKind, ConfigFlag, Motion, Position, StateFlag, Ticks};
use crate::wire::ACK_OK;
use crate::wire::{AckPosition, Action, ExtAck, Reply, Request};

impl SimModule {
    pub(super) fn accepts_motion(&self, request: &Request) -> bool {
        let homing = matches!(request, Request::Action(Action::Home));
        let stopped = self.flags.contains(StateFlag::Halted) || self.flags.contains(StateFlag::Error);
        // An M3 compatible module takes no motion command but Home until it is homed.
        let m3_waits_for_home = self.config.contains(ConfigFlag::M3Compatible) && !self.homed() && !homing;
        !stopped && !m3_waits_for_home
    }

    pub(super) fn execute_motion(&mut self, t: f64, request: &Request) {
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

    pub(super) fn motion_ended_homing_at_once(&mut self, t: f64) {
        self.pos = 0.0;
        self.flags = self.flags.with(StateFlag::HomeOk).with(StateFlag::RampEnd);
        self.event(t, "homed");
    }

    pub(super) fn ramp_to(&mut self, t: f64, target: f64, mode: u8) {
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

    pub(super) fn step_to(&mut self, t: f64, target: f64, duration: f64, mode: u8) {
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
                        if self.firmware.life_sign_unacknowledged {
                            return None;
                        }
                    }
                    Action::RecalcPid | Action::SaveParameters => {}
                }
                Some(Reply::Action(action))
            }
            Request::Get(param) => self.get(t, param).map(|v| Reply::Get(param, v)),
            // A module before version 3.5.00 does not know the Config word: nothing written, no acknowledge.
            Request::Set(crate::model::Param::Config, _) if self.firmware.no_config_word => None,
            Request::Set(param, value) => {
                self.set(t, param, value);
                Some(Reply::Set(param, ACK_OK))
            }
            Request::Motion(motion, ack) => {
                self.motion_or_pending(t, request);
                let id = motion.id(ack)?;
                // A firmware before extended acknowledges answers every motion command simply, with the
                // MotionID it received.
                let ack = if self.firmware.no_extended_ack { AckKind::Simple } else { ack };
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

    pub(super) fn motion_or_pending(&mut self, t: f64, request: &Request) {
        // CONFIGID_MOD_SYNC_MOTION is "valid only for CAN-Bus": elsewhere the flag is stored but ignored.
        let sync = self.can && self.config.contains(ConfigFlag::SyncMotion);
        if sync && !matches!(request, Request::Action(Action::Home)) {
            self.pending.push(*request);
        } else if self.firmware.late_motion_start && self.motion.is_none() && self.accepts_motion(request) {
            // This firmware starts a motion from rest later; the state stays as it was until then. A ramp's
            // target is taken at once (TargetPos shows it).
            match *request {
                Request::Motion(Motion::FRamp { pos }, _) if pos.value().is_finite() => {
                    self.target_pos = self.clamp_target(f64::from(pos.value()));
                }
                Request::Motion(Motion::IRamp { pos }, _) => {
                    self.target_pos = self.clamp_target(f64::from(pos.0) / self.inc_ratio());
                }
                _ => {}
            }
            self.delayed = Some((t + super::variant::LATE_START_S, *request));
        } else {
            self.delayed = None;
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
            // Manual 5: a fault of the servo amplifier whose cause is flagged by bits 19..23 is reset only by
            // switching the module off; one of the supply voltage (STATE_POW_VOLT_ERR, the voltage being
            // back in this emulator) by a Reset.
            let power_off = [
                StateFlag::PowFetTemp,
                StateFlag::PowWdgTemp,
                StateFlag::PowShortCur,
                StateFlag::PowHallErr,
                StateFlag::PowIntegralErr,
            ];
            if power_off.iter().any(|f| self.flags.contains(*f)) {
                self.flags = self.flags.with(StateFlag::Error).with(StateFlag::Halted);
            } else {
                self.flags = self.flags.without(StateFlag::PowerFault);
            }
        }
        // STATE_CPU_OVERLOAD (the CPU lost the current controller): "Power must be switched off" (manual 5).
        if self.flags.contains(StateFlag::CpuOverload) {
            self.flags = self.flags.with(StateFlag::Error).with(StateFlag::Halted);
        }
        if self.watchdog_online && self.firmware.reset_clears_watchdog {
            self.watchdog_online = false;
            self.event(t, "watchdog offline");
        } else if self.watchdog_online {
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
}
