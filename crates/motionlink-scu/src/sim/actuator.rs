//! The physical model of one actuator: ramps, speed, stroke ends, stalls, current.

use super::*;

/// Who started an actuator's motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Origin {
    /// RE over the serial line.
    Remote,
    /// The hand switch.
    Local,
}

#[derive(Debug, Clone)]
pub(super) struct ActuatorState {
    pub(super) cfg: ActuatorConfig,
    /// Position, counts.
    pub(super) position: f64,
    /// Signed velocity, counts/s.
    pub(super) velocity: f64,
    /// Where it is going, counts (None: standing).
    pub(super) target: Option<f64>,
    /// Commanded speed, counts/s.
    pub(super) commanded_speed: f64,
    /// Commanded speed in percent (for the speed entry and stalling).
    pub(super) commanded_percent: u16,
    /// Decelerating to a stop along the ramp.
    pub(super) soft_stopping: bool,
    pub(super) origin: Origin,
    /// The motion function (wire id 0..9) whose RE started the motion, if a remote one did.
    pub(super) function: Option<u8>,
    /// Too slow to move (below the stall speed).
    pub(super) stalled: bool,
    /// Pushing against the configured obstacle.
    pub(super) blocked: bool,
    /// How long it has been stalled or blocked with its motion on, s. A new RE or a new speed does not
    /// reset it: only moving does (or the end of the motion), so a client that repeats RE to a stalled drive
    /// still gets the drive error.
    pub(super) stalled_for: f64,
    /// Which side of the configured obstacle the drive is on: -1 below, +1 above, 0 not known (it started on
    /// it). Kept while the drive rests against the obstacle, so the next motion towards it is blocked again.
    pub(super) obstacle_side: f64,
    pub(super) cumulated_stroke: f64,
    pub(super) relay_in_cycles: u32,
    pub(super) relay_out_cycles: u32,
    pub(super) max_current: u16,
    pub(super) error_count: u32,
    /// Time before a motion just started begins, s: it stands, its motion bit clear
    /// ([`Variant::LateMotionBit`]).
    pub(super) start_delay_s: f64,
}

impl ActuatorState {
    pub(super) fn new(cfg: ActuatorConfig) -> Self {
        ActuatorState {
            position: f64::from(cfg.start_position_counts),
            velocity: 0.0,
            target: None,
            commanded_speed: 0.0,
            commanded_percent: 0,
            soft_stopping: false,
            origin: Origin::Remote,
            function: None,
            stalled: false,
            blocked: false,
            stalled_for: 0.0,
            // In f64: the start and the obstacle may lie further apart than an i32 holds.
            obstacle_side: cfg
                .obstacle_counts
                .map_or(0.0, |o| (f64::from(cfg.start_position_counts) - f64::from(o)).signum()),
            cumulated_stroke: 0.0,
            relay_in_cycles: 0,
            relay_out_cycles: 0,
            max_current: 0,
            error_count: 0,
            start_delay_s: 0.0,
            cfg,
        }
    }

    pub(super) fn moving(&self) -> bool {
        self.target.is_some() || self.velocity != 0.0
    }

    /// Acceleration along the ramp, counts/s².
    pub(super) fn acceleration(&self) -> f64 {
        let ramp = (self.cfg.ramp_ms.max(1) as f64) / 1000.0;
        self.cfg.counts_per_second_at_full_speed / ramp
    }

    /// The range a motion may reach: the stroke, narrowed by the virtual limits of UserPositionData (both 0:
    /// none set).
    pub(super) fn travel_range(&self) -> (i32, i32) {
        let v = &self.cfg.user_positions;
        let (mut lo, mut hi) = (self.cfg.stroke_min_counts, self.cfg.stroke_max_counts);
        if (v.virtual_limit_in_counts, v.virtual_limit_out_counts) != (0, 0) {
            lo = lo.max(v.virtual_limit_in_counts);
            hi = hi.min(v.virtual_limit_out_counts).max(lo);
        }
        (lo, hi)
    }

    pub(super) fn reported_position(&self) -> i32 {
        let p = self.position.round() as i32;
        if !self.moving() && p <= self.cfg.stroke_min_counts {
            // A stroke at the bottom of the counts range reads its lowest count.
            p.saturating_sub(self.cfg.in_end_undershoot_counts)
        } else {
            p
        }
    }

    /// Starts a motion to `target` (clamped to the travel range, as a unit stops at its limits). Returns false
    /// if the actuator is already there at rest and nothing moves; one that is leaving that place (a motion
    /// to elsewhere just began) turns back to it.
    pub(super) fn start(
        &mut self,
        target: i32,
        speed_counts_per_s: f64,
        percent: u16,
        origin: Origin,
        function: Option<u8>,
    ) -> bool {
        let (lo, hi) = self.travel_range();
        let target = target.clamp(lo, hi);
        let t = f64::from(target);
        if (t - self.position).abs() < 0.5 && !self.moving() {
            // Already there: nothing moves.
            return false;
        }
        if t < self.position {
            self.relay_in_cycles += 1;
        } else {
            self.relay_out_cycles += 1;
        }
        self.target = Some(t);
        self.soft_stopping = false;
        self.origin = origin;
        self.function = function;
        self.blocked = false;
        self.set_speed(speed_counts_per_s, percent);
        true
    }

    /// A new commanded speed; the motion follows it along the ramp.
    pub(super) fn set_speed(&mut self, speed_counts_per_s: f64, percent: u16) {
        self.commanded_speed = speed_counts_per_s;
        self.commanded_percent = percent;
        self.stalled = self.cfg.stall_below_percent > 0 && percent < self.cfg.stall_below_percent;
    }

    pub(super) fn fast_stop(&mut self) {
        self.start_delay_s = 0.0;
        self.target = None;
        self.velocity = 0.0;
        self.soft_stopping = false;
        self.stalled = false;
        self.blocked = false;
        self.stalled_for = 0.0;
    }

    pub(super) fn soft_stop(&mut self) {
        self.start_delay_s = 0.0;
        if self.moving() {
            self.soft_stopping = true;
            self.target = None;
        }
        self.stalled = false;
        self.blocked = false;
        self.stalled_for = 0.0;
        if self.velocity == 0.0 {
            self.soft_stopping = false;
        }
    }

    pub(super) fn current(&self) -> u16 {
        if (self.stalled || self.blocked) && self.target.is_some() {
            return self.cfg.current_at_full_speed_deci_amps.saturating_mul(2);
        }
        if !self.moving() {
            return 0;
        }
        let frac = (self.velocity.abs() / self.cfg.counts_per_second_at_full_speed).min(1.5);
        let base = f64::from(self.cfg.current_at_full_speed_deci_amps);
        (base / 3.0 + base * 2.0 / 3.0 * frac).round() as u16
    }

    pub(super) fn speed_percent(&self) -> u16 {
        ((self.velocity.abs() / self.cfg.counts_per_second_at_full_speed) * 100.0).round() as u16
    }

    /// Runs the model for `dt`. Returns true when the drive's stall time-out expired: the caller raises its
    /// drive error.
    pub(super) fn step(&mut self, dt: f64) -> bool {
        // A motion that has not begun yet stands (the rest of the step moves it).
        let waited = self.start_delay_s.min(dt);
        self.start_delay_s -= waited;
        let dt = dt - waited;
        if self.start_delay_s > 0.0 || dt <= 0.0 {
            return false;
        }
        let accel = self.acceleration();
        if self.soft_stopping {
            let dv = accel * dt;
            let new_v = if self.velocity > 0.0 { (self.velocity - dv).max(0.0) } else { (self.velocity + dv).min(0.0) };
            self.integrate((self.velocity + new_v) / 2.0 * dt);
            self.velocity = new_v;
            if self.velocity == 0.0 {
                self.soft_stopping = false;
            }
        } else if let Some(target) = self.target {
            if self.stalled || self.blocked {
                self.velocity = 0.0;
            } else {
                let before = self.position;
                let remaining = target - self.position;
                let dir = remaining.signum();
                // Slow down in time to stop at the target along the ramp; follow a lower commanded speed
                // along the ramp too.
                let brake_limit = (2.0 * accel * remaining.abs()).sqrt();
                let speed = self.velocity.abs();
                let wanted = self.commanded_speed.min(brake_limit);
                let new_speed = if wanted > speed {
                    (speed + accel * dt).min(wanted)
                } else if wanted < brake_limit {
                    (speed - accel * dt).max(wanted)
                } else {
                    wanted
                };
                let travel = ((speed + new_speed) / 2.0 * dt).max(new_speed * dt * 0.5);
                if travel >= remaining.abs() || remaining.abs() < 0.5 {
                    self.integrate(remaining);
                    self.position = target;
                    self.velocity = 0.0;
                    self.target = None;
                } else {
                    self.integrate(dir * travel);
                    self.velocity = dir * new_speed;
                }
                // An obstacle in the way stops the drive there, still pushing; a drive resting against it is
                // blocked again by the next motion towards it.
                if let Some(o) = self.cfg.obstacle_counts.map(f64::from) {
                    let side = if (before - o).abs() < 1e-9 { self.obstacle_side } else { (before - o).signum() };
                    let towards = dir * side < 0.0;
                    if towards && (self.position - o) * side <= 0.0 && (target - o).abs() >= 0.5 {
                        self.position = o;
                        self.velocity = 0.0;
                        self.blocked = true;
                        self.target = Some(target);
                    } else if (self.position - o).abs() >= 1e-9 {
                        self.obstacle_side = (self.position - o).signum();
                    } else {
                        self.obstacle_side = side;
                    }
                }
            }
        }
        // The ends of the stroke stop everything.
        let (lo, hi) = (f64::from(self.cfg.stroke_min_counts), f64::from(self.cfg.stroke_max_counts));
        if self.position <= lo && self.velocity < 0.0 || self.position >= hi && self.velocity > 0.0 {
            self.position = self.position.clamp(lo, hi);
            self.velocity = 0.0;
            self.target = None;
            self.soft_stopping = false;
        }
        self.max_current = self.max_current.max(self.current());
        if (self.stalled || self.blocked) && self.target.is_some() {
            self.stalled_for += dt;
            let limit = self.cfg.stall_error_after_ms as f64 / 1000.0;
            return self.cfg.stall_error_after_ms > 0 && self.stalled_for >= limit - 1e-9;
        }
        self.stalled_for = 0.0;
        false
    }

    pub(super) fn integrate(&mut self, delta: f64) {
        self.position += delta;
        self.cumulated_stroke += delta.abs();
    }

    pub(super) fn status1(&self) -> u8 {
        let p = self.position.round() as i32;
        let at_in = p <= self.cfg.stroke_min_counts;
        let at_out = p >= self.cfg.stroke_max_counts;
        let mut s = Status1Flag::Available.mask() | Status1Flag::StrokeDone.mask();
        if at_in || at_out {
            s |= Status1Flag::LimitInOut.mask();
        }
        if at_in {
            s |= Status1Flag::Switch1.mask() | Status1Flag::InPosition.mask();
        }
        if at_out {
            s |= Status1Flag::Switch2.mask() | Status1Flag::OutPosition.mask();
        }
        if self.moving() && self.start_delay_s <= 0.0 {
            s |= Status1Flag::Motion.mask();
        }
        s
    }
}
