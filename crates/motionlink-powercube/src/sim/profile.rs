//! Motion profiles of the emulated modules: pieces of constant acceleration (and a cosine loop), evaluated
//! at any time, with the first time a position or a speed is crossed found analytically.

/// Which ramp phase a piece is (for the STATE_RAMP_* flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Phase {
    /// Speeding up.
    Acc,
    /// Constant speed.
    Steady,
    /// Slowing down.
    Dec,
}

/// A piece of constant acceleration: from `start` for `duration` seconds (may be infinite).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Segment {
    pub start: f64,
    pub duration: f64,
    pub p0: f64,
    pub v0: f64,
    pub a: f64,
    pub phase: Phase,
}

impl Segment {
    pub fn end(&self) -> f64 {
        self.start + self.duration
    }

    fn tau(&self, t: f64) -> f64 {
        // Not `clamp`: it panics on a NaN bound, and nothing here may panic on what came over a wire.
        (t - self.start).max(0.0).min(self.duration)
    }

    pub fn pos(&self, t: f64) -> f64 {
        let tau = self.tau(t);
        self.p0 + self.v0 * tau + 0.5 * self.a * tau * tau
    }

    pub fn vel(&self, t: f64) -> f64 {
        self.v0 + self.a * self.tau(t)
    }

    fn phase_of(v0: f64, a: f64) -> Phase {
        if a == 0.0 {
            Phase::Steady
        } else if v0 * a >= 0.0 {
            Phase::Acc
        } else {
            Phase::Dec
        }
    }

    /// A piece starting at (`t`, `p`, `v`) with acceleration `a` for `d` seconds; its phase follows from the
    /// signs.
    pub fn new(t: f64, p: f64, v: f64, a: f64, d: f64) -> Segment {
        let phase = if a == 0.0 {
            Phase::Steady
        } else if v == 0.0 || v.signum() == a.signum() {
            Phase::Acc
        } else {
            Self::phase_of(v, a)
        };
        Segment { start: t, duration: d.max(0.0), p0: p, v0: v, a, phase }
    }

    /// The first time in this piece at which the position reaches `level` coming from the side of `p0`.
    fn first_at_position(&self, level: f64) -> Option<f64> {
        let c = self.p0 - level;
        if c == 0.0 {
            return None;
        }
        // 0.5 a τ² + v0 τ + c = 0, smallest τ in (0, duration].
        let mut roots = [f64::NAN; 2];
        if self.a.abs() < 1e-12 {
            if self.v0 != 0.0 {
                roots[0] = -c / self.v0;
            }
        } else {
            let disc = self.v0 * self.v0 - 2.0 * self.a * c;
            if disc >= 0.0 {
                let s = disc.sqrt();
                roots = [(-self.v0 - s) / self.a, (-self.v0 + s) / self.a];
            }
        }
        roots
            .into_iter()
            .filter(|r| r.is_finite() && *r > 0.0 && *r <= self.duration)
            .fold(None, |best: Option<f64>, r| Some(best.map_or(r, |b| b.min(r))))
            .map(|tau| self.start + tau)
    }

    /// The first time in this piece at which the speed exceeds `speed` (> 0).
    fn first_over_speed(&self, speed: f64) -> Option<f64> {
        if self.v0.abs() > speed {
            return Some(self.start);
        }
        if self.a == 0.0 {
            return None;
        }
        let target = if self.a > 0.0 { speed } else { -speed };
        let tau = (target - self.v0) / self.a;
        (tau >= 0.0 && tau < self.duration).then_some(self.start + tau)
    }
}

/// A motion in progress.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Profile {
    /// Pieces in time order; the motion ends at the end of the last (which may be infinite).
    Pieces(Vec<Segment>),
    /// `p0 + (p1 - p0) (1 - cos(2π (t - start) / period)) / 2`, until stopped.
    Cos { start: f64, p0: f64, p1: f64, period: f64 },
}

impl Profile {
    fn piece(&self, t: f64) -> Option<&Segment> {
        match self {
            Profile::Pieces(s) => s.iter().find(|s| t < s.end()).or(s.last()),
            Profile::Cos { .. } => None,
        }
    }

    pub fn pos(&self, t: f64) -> f64 {
        match self {
            Profile::Pieces(_) => self.piece(t).map_or(0.0, |s| s.pos(t)),
            Profile::Cos { start, p0, p1, period } => {
                let phase = std::f64::consts::TAU * (t - start) / period;
                p0 + (p1 - p0) * (1.0 - phase.cos()) / 2.0
            }
        }
    }

    pub fn vel(&self, t: f64) -> f64 {
        match self {
            Profile::Pieces(_) => self.piece(t).map_or(0.0, |s| if t >= s.end() { 0.0 } else { s.vel(t) }),
            Profile::Cos { start, p0, p1, period } => {
                let w = std::f64::consts::TAU / period;
                (p1 - p0) / 2.0 * w * (w * (t - start)).sin()
            }
        }
    }

    /// The ramp phase at `t`, if any.
    pub fn phase(&self, t: f64) -> Option<Phase> {
        self.piece(t).filter(|s| t < s.end()).map(|s| s.phase)
    }

    /// When the motion ends by itself, if it does.
    pub fn end(&self) -> Option<f64> {
        match self {
            Profile::Pieces(s) => s.last().map(Segment::end).filter(|e| e.is_finite()),
            Profile::Cos { .. } => None,
        }
    }

    /// The end position of a finite motion.
    pub fn end_pos(&self) -> Option<f64> {
        self.end().map(|e| self.pos(e))
    }

    /// The first time after `from` at which the position leaves `[min, max]`.
    pub fn first_outside(&self, from: f64, min: f64, max: f64) -> Option<f64> {
        let Profile::Pieces(pieces) = self else { return None };
        pieces
            .iter()
            .filter(|s| s.end() > from)
            .filter_map(|s| {
                let over = s.first_at_position(max + 1e-6);
                let under = s.first_at_position(min - 1e-6);
                [over, under].into_iter().flatten().filter(|t| *t >= from).reduce(f64::min)
            })
            .reduce(f64::min)
    }

    /// The first time after `from` at which the speed exceeds `speed`.
    pub fn first_over_speed(&self, from: f64, speed: f64) -> Option<f64> {
        match self {
            Profile::Pieces(pieces) => pieces
                .iter()
                .filter(|s| s.end() > from)
                .filter_map(|s| s.first_over_speed(speed).map(|t| t.max(from)))
                .reduce(f64::min),
            Profile::Cos { start, p0, p1, period } => {
                let peak = (p1 - p0).abs() / 2.0 * std::f64::consts::TAU / period;
                (peak > speed).then_some(start.max(from))
            }
        }
    }
}

/// A trapezoid (or triangle) from position `p0` at velocity `v0` to rest at `target`, with speed at most
/// `vmax` and acceleration `amax`, starting at time `t0`. A motion the wrong way, or too fast to stop in
/// time, first stops and then comes back.
pub(crate) fn ramp(t0: f64, p0: f64, v0: f64, target: f64, vmax: f64, amax: f64) -> Vec<Segment> {
    let mut out = Vec::with_capacity(4);
    let vmax = vmax.abs().max(1e-9);
    let amax = amax.abs().max(1e-9);
    let mut t = t0;
    let mut p = p0;
    let mut v = v0;
    let d = target - p;
    let dir = if d != 0.0 { d.signum() } else { -v.signum() };
    let u = v * dir;
    if v != 0.0 && (u < 0.0 || u * u / (2.0 * amax) > d.abs() + 1e-12) {
        // Stop first.
        let a = -v.signum() * amax;
        let ts = v.abs() / amax;
        let seg = Segment { start: t, duration: ts, p0: p, v0: v, a, phase: Phase::Dec };
        p = seg.pos(t + ts);
        t += ts;
        v = 0.0;
        out.push(seg);
    }
    let d = target - p;
    if d.abs() < 1e-12 {
        return out;
    }
    let dir = d.signum();
    let dist = d.abs();
    let u = (v * dir).max(0.0);
    let peak = (amax * dist + u * u / 2.0).sqrt();
    let push = |out: &mut Vec<Segment>, dur: f64, a: f64, phase: Phase, p: &mut f64, v: &mut f64, t: &mut f64| {
        if dur > 0.0 {
            let seg = Segment { start: *t, duration: dur, p0: *p, v0: *v, a, phase };
            *p = seg.pos(*t + dur);
            *v = seg.vel(*t + dur);
            *t += dur;
            out.push(seg);
        }
    };
    if peak <= vmax {
        push(&mut out, (peak - u) / amax, dir * amax, Phase::Acc, &mut p, &mut v, &mut t);
        push(&mut out, peak / amax, -dir * amax, Phase::Dec, &mut p, &mut v, &mut t);
    } else {
        let (t_first, a_first, ph) = if u <= vmax {
            ((vmax - u) / amax, dir * amax, Phase::Acc)
        } else {
            ((u - vmax) / amax, -dir * amax, Phase::Dec)
        };
        let d_first = (vmax * vmax - u * u).abs() / (2.0 * amax);
        let d_dec = vmax * vmax / (2.0 * amax);
        let d_cruise = (dist - d_first - d_dec).max(0.0);
        push(&mut out, t_first, a_first, ph, &mut p, &mut v, &mut t);
        push(&mut out, d_cruise / vmax, 0.0, Phase::Steady, &mut p, &mut v, &mut t);
        push(&mut out, vmax / amax, -dir * amax, Phase::Dec, &mut p, &mut v, &mut t);
    }
    // Land exactly on the target whatever the rounding.
    if let Some(last) = out.last_mut() {
        let err = target - last.pos(last.end());
        last.p0 += err;
    }
    out
}

/// From velocity `v0` to velocity `v1` at acceleration `amax`, then on at `v1` for ever (or stop there if
/// `v1` is zero).
pub(crate) fn to_velocity(t0: f64, p0: f64, v0: f64, v1: f64, amax: f64) -> Vec<Segment> {
    let amax = amax.abs().max(1e-9);
    let dv = v1 - v0;
    let mut out = Vec::with_capacity(2);
    let mut t = t0;
    let mut p = p0;
    if dv != 0.0 {
        let d = dv.abs() / amax;
        let seg = Segment::new(t, p, v0, dv.signum() * amax, d);
        p = seg.pos(t + d);
        t += d;
        out.push(seg);
    }
    if v1 != 0.0 {
        out.push(Segment { start: t, duration: f64::INFINITY, p0: p, v0: v1, a: 0.0, phase: Phase::Steady });
    }
    out
}

/// A constant-speed move from `p0` to `p1` in `duration` seconds.
pub(crate) fn step(t0: f64, p0: f64, p1: f64, duration: f64) -> Vec<Segment> {
    let duration = duration.max(1e-3);
    vec![Segment { start: t0, duration, p0, v0: (p1 - p0) / duration, a: 0.0, phase: Phase::Steady }]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_lands(segs: &[Segment], target: f64) {
        let last = segs.last().unwrap();
        assert!((last.pos(last.end()) - target).abs() < 1e-9);
        assert!(last.vel(last.end()).abs() < 1e-9);
        // Continuous.
        for w in segs.windows(2) {
            assert!((w[0].pos(w[0].end()) - w[1].p0).abs() < 1e-9);
            assert!((w[0].vel(w[0].end()) - w[1].v0).abs() < 1e-9);
            assert!((w[0].end() - w[1].start).abs() < 1e-12);
        }
    }

    #[test]
    fn trapezoid_and_triangle() {
        // 1 rad at 1 rad/s, 2 rad/s²: 0.5 s up, 0.5 s cruise, 0.5 s down.
        let s = ramp(0.0, 0.0, 0.0, 1.0, 1.0, 2.0);
        assert_eq!(s.len(), 3);
        assert_eq!(s.iter().map(|s| s.phase).collect::<Vec<_>>(), vec![Phase::Acc, Phase::Steady, Phase::Dec]);
        assert!((s[2].end() - 1.5).abs() < 1e-9);
        check_lands(&s, 1.0);
        // 0.1 rad: a triangle peaking at sqrt(0.2).
        let s = ramp(0.0, 0.0, 0.0, -0.1, 1.0, 2.0);
        assert_eq!(s.len(), 2);
        check_lands(&s, -0.1);
    }

    #[test]
    fn replanning_while_moving() {
        // Moving the wrong way: stop, then come back.
        let s = ramp(0.0, 0.0, 1.0, -1.0, 1.0, 2.0);
        assert_eq!(s[0].phase, Phase::Dec);
        check_lands(&s, -1.0);
        // Too fast to stop in time: overshoot and come back.
        let s = ramp(0.0, 0.0, 1.0, 0.1, 1.0, 2.0);
        check_lands(&s, 0.1);
        // Faster than the new vmax: slow down to it first.
        let s = ramp(0.0, 0.0, 1.0, 2.0, 0.5, 2.0);
        assert_eq!(s[0].phase, Phase::Dec);
        check_lands(&s, 2.0);
    }

    #[test]
    fn crossings_are_found() {
        let p = Profile::Pieces(to_velocity(0.0, 0.0, 0.0, 1.0, 2.0));
        // Reaches 1 rad/s at 0.5 s (0.25 rad), then 1 rad/s: 2.0 rad at 2.25 s.
        let t = p.first_outside(0.0, -3.0, 2.0).unwrap();
        assert!((t - 2.25).abs() < 1e-5, "{t}");
        let t = p.first_over_speed(0.0, 0.5).unwrap();
        assert!((t - 0.25).abs() < 1e-9);
        assert_eq!(p.end(), None);
        let r = Profile::Pieces(ramp(0.0, 0.0, 0.0, 1.0, 1.0, 2.0));
        assert_eq!(r.first_outside(0.0, -1.0, 1.0), None, "a ramp to the limit stays inside");
        assert_eq!(r.phase(0.1), Some(Phase::Acc));
        assert_eq!(r.phase(2.0), None);
        assert!((r.end_pos().unwrap() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn cosine_loop() {
        let c = Profile::Cos { start: 0.0, p0: 0.0, p1: 1.0, period: 2.0 };
        assert!((c.pos(1.0) - 1.0).abs() < 1e-9);
        assert!((c.pos(2.0)).abs() < 1e-9);
        assert!(c.first_over_speed(0.0, 2.0).is_none());
        assert!(c.first_over_speed(0.0, 1.0).is_some());
    }
}
