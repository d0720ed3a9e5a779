//! The Inc twins: TargetPos, TargetVel and TargetAcc are write-only floats; TargetPosInc, TargetVelInc and
//! TargetAccInc are readable integers in encoder ticks. Nothing in the manual says whether a module keeps one
//! value behind each pair (the twin then reads back what the float wrote, the only way to verify such a
//! write) or two. So the session finds out per module and pair, the first time a check depends on it, and
//! remembers it ([`ModuleFindings`](crate::session::ModuleFindings)):
//!
//! - It reads the twin before the write, writes the value asked for, and reads the twin again. The twin now
//!   shows the value written (and did not before): the module mirrors; it is as it was: the module keeps
//!   them apart; anything else: it mirrors but took another value, a real discrepancy, refused.
//! - Where the twin already showed the value asked for, the write alone cannot tell. For TargetVel and
//!   TargetAcc of a module at rest, the session first writes a value a few ticks off (half the value asked
//!   for) and reads the twin, then writes the value asked for: what the module ends with is what was asked,
//!   and a target value changed while nothing moves sets nothing in motion. TargetPos gets no such detour (a
//!   position target is not written on a guess), nor a module in motion: the write is then reported as not
//!   verifiable.
//! - Once a pair is known to mirror, every write is checked strictly (a twin that does not show the value
//!   written is [`Error::ReadBack`]); once known to be kept apart, writes are made as the manual describes
//!   them and their results say that they could not be read back.
//!
//! A module that mirrors but ignores a write it acknowledged looks, the first time, like one that keeps the
//! values apart; no probe can tell the two apart without reading the float, which the manual does not allow.

use crate::error::{unexpected, Error, TwinTicks};
use crate::model::{Param, StateFlag, Value};
use crate::session::ctx::Ctx;
use crate::wire::Request;

/// What one write through a twin showed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// The twin shows the value written (and did not before): one value behind both.
    Mirrors,
    /// The twin is as it was: the module keeps them apart.
    KeptApart,
    /// The twin showed the value written before the write too: the write tells nothing.
    Undecided,
    /// The twin changed, but not to the value written.
    Discrepancy,
}

/// Judges a twin read `after` a write that should give `expected` ticks (one tick allowed for rounding),
/// with the twin `before` the write if it was read, and what is known already.
pub(crate) fn judge(before: Option<f64>, after: f64, expected: f64, known: Option<bool>) -> Verdict {
    let near = |x: f64| (x - expected).abs() <= 1.0;
    match (known, before) {
        (Some(true), _) | (None, None) => {
            if near(after) {
                Verdict::Mirrors
            } else {
                Verdict::Discrepancy
            }
        }
        (Some(false), _) => Verdict::KeptApart,
        (None, Some(before)) if near(after) && near(before) => Verdict::Undecided,
        (None, Some(_)) if near(after) => Verdict::Mirrors,
        (None, Some(before)) if after == before => Verdict::KeptApart,
        (None, Some(_)) => Verdict::Discrepancy,
    }
}

/// A write of a twinned parameter: verified (the twin's value read), or why it is not.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum TwinCheck {
    Verified(Value),
    Unverified(String),
}

/// Why a write of `param` could not be read back on a module that keeps its twin apart.
pub(crate) fn kept_apart(param: Param) -> String {
    let twin = param.read_back_as().unwrap_or(param);
    if param == Param::TargetPos {
        return "the motion's target could not be read back: this module keeps TargetPosInc apart from the \
                target of a float motion command (TargetPosInc stayed as it was), and the manual has no other \
                way to read it"
            .into();
    }
    format!(
        "{param} could not be read back: this module keeps {twin} apart from it (a write of {param} left {twin} \
         as it was), and the manual has no other way to read {param}"
    )
}

/// Why a write of `param` could not be read back when its twin held the value already.
pub(crate) fn undecided(param: Param) -> String {
    let twin = param.read_back_as().unwrap_or(param);
    let what = if param == Param::TargetPos { "the motion's target".to_string() } else { param.to_string() };
    format!(
        "{what} could not be read back: {twin} already held that value before, so it cannot show whether the \
         module took it (that {twin} follows {param} on this module is not established in this session)"
    )
}

impl Ctx {
    /// What the session knows about the twin of `param` on module `a`.
    pub(crate) fn twin_known(&self, a: u8, param: Param) -> Option<bool> {
        self.core().findings.get(&a).and_then(|f| f.twin(param))
    }

    /// Remembers what a write showed about the twin of `param` on module `a`; a module found to keep them
    /// apart is said once per session.
    pub(crate) fn remember_twin(&self, a: u8, param: Param, mirrors: bool) {
        let mut core = self.core();
        if let Some(slot) = core.findings.entry(a).or_default().twin_mut(param) {
            *slot = Some(mirrors);
        }
        if !mirrors {
            let twin = param.read_back_as().unwrap_or(param);
            let what = if param == Param::TargetPos { "the target of float motion commands" } else { param.name() };
            // Said once per session and module, whichever twin shows it first.
            core.warn_once(a, "twins", || {
                format!(
                    "module {a} keeps {twin} apart from {what} (the manual does not say that one mirrors the \
                     other): what this session writes there is not read back, and each result says so"
                )
            });
        }
    }

    /// Reads an Inc twin: its value and its ticks.
    pub(crate) async fn read_ticks(&self, a: u8, twin: Param) -> Result<(Value, f64), Error> {
        let read = self.get(a, twin).await?;
        let ticks = read.as_f64().ok_or_else(|| unexpected(a, &Request::Get(twin), format!("{read:?}")))?;
        Ok((read, ticks))
    }

    /// The error of a twin that shows `ticks` after `param` was written as `value` (`expected` ticks).
    pub(crate) fn twin_mismatch(a: u8, param: Param, value: f32, expected: f64, ticks: f64, ratio: f64) -> Error {
        let twin = param.read_back_as().unwrap_or(param);
        Error::ReadBack {
            address: crate::model::Address::checked(a),
            param,
            wrote: Value::F32(value),
            read: Value::F32((ticks / ratio) as f32),
            twin: Some(TwinTicks { param: twin, expected_ticks: expected, read_ticks: ticks }),
        }
    }

    /// True when module `a` is not moving (a target value changed now sets nothing in motion).
    async fn at_rest(&self, a: u8) -> Result<bool, Error> {
        Ok(!self.state(a).await?.contains(StateFlag::Motion))
    }

    /// Writes `param` as `value` while it is not known whether its twin follows it, with the twin `before`
    /// the write; what the twin showed after it. A twin that stayed as it was is written once more and read
    /// again before that counts: one write whose value was corrupted on the way into just the old value
    /// (the modules ignore the BCC) would look the same.
    async fn probe_write(
        &self,
        a: u8,
        param: Param,
        value: f32,
        before: f64,
        ratio: f64,
    ) -> Result<(Verdict, Value, f64), Error> {
        let twin = param.read_back_as().unwrap_or(param);
        let expected = (f64::from(value) * ratio).round();
        let mut last = None;
        for _ in 0..2 {
            self.set(a, param, Value::F32(value)).await?;
            let (read, after) = self.read_ticks(a, twin).await?;
            let verdict = judge(Some(before), after, expected, None);
            tracing::debug!("module {a}: {param} written as {value}, {twin} {before} -> {after}: {verdict:?}");
            if verdict != Verdict::KeptApart {
                return Ok((verdict, read, after));
            }
            last = Some((verdict, read, after));
        }
        Ok(last.unwrap_or((Verdict::KeptApart, Value::U32(0), before)))
    }

    /// Writes the twinned parameter `param` (TargetPos, TargetVel, TargetAcc) as `value` and checks it
    /// through its Inc twin as far as the module allows (see the [module documentation](self)); `ratio` is
    /// the module's IncRatio.
    pub(crate) async fn write_twinned(
        &self,
        a: u8,
        param: Param,
        value: Value,
        ratio: f64,
    ) -> Result<TwinCheck, Error> {
        let (Some(twin), Some(v)) = (param.read_back_as(), value.as_f32()) else {
            self.set(a, param, value).await?;
            return Ok(TwinCheck::Unverified(format!("{param} has no twin to read back")));
        };
        let expected = (f64::from(v) * ratio).round();
        let near = |ticks: f64| (ticks - expected).abs() <= 1.0;
        let mut known = self.twin_known(a, param);
        if known.is_none() {
            let (_, before) = self.read_ticks(a, twin).await?;
            if !near(before) {
                // The write itself tells.
                let (verdict, read, after) = self.probe_write(a, param, v, before, ratio).await?;
                return match verdict {
                    Verdict::Mirrors => {
                        self.remember_twin(a, param, true);
                        Ok(TwinCheck::Verified(read))
                    }
                    Verdict::KeptApart => {
                        self.remember_twin(a, param, false);
                        Ok(TwinCheck::Unverified(kept_apart(param)))
                    }
                    Verdict::Undecided => Ok(TwinCheck::Unverified(undecided(param))),
                    Verdict::Discrepancy => {
                        self.remember_twin(a, param, true);
                        Err(Self::twin_mismatch(a, param, v, expected, after, ratio))
                    }
                };
            }
            // The twin already shows the value: a detour through a value a few ticks off tells, where it
            // sets nothing in motion (see the module documentation).
            if param != Param::TargetPos && v.is_finite() && v != 0.0 && self.at_rest(a).await? {
                let detour = if expected.abs() >= 4.0 { v / 2.0 } else { v * 4.0 };
                known = match self.probe_write(a, param, detour, before, ratio).await?.0 {
                    Verdict::KeptApart => Some(false),
                    Verdict::Mirrors | Verdict::Discrepancy => Some(true),
                    Verdict::Undecided => None,
                };
                if let Some(k) = known {
                    self.remember_twin(a, param, k);
                }
            }
        }
        self.set(a, param, value).await?;
        if known == Some(false) {
            return Ok(TwinCheck::Unverified(kept_apart(param)));
        }
        let (read, after) = self.read_ticks(a, twin).await?;
        match (near(after), known) {
            (true, Some(true)) => Ok(TwinCheck::Verified(read)),
            // Undecided: the twin showed the value before the write too.
            (true, _) => Ok(TwinCheck::Unverified(undecided(param))),
            (false, _) => Err(Self::twin_mismatch(a, param, v, expected, after, ratio)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_verdicts() {
        // First write, twin read before and after.
        assert_eq!(judge(Some(100.0), 500.0, 500.0, None), Verdict::Mirrors);
        assert_eq!(judge(Some(100.0), 501.0, 500.0, None), Verdict::Mirrors, "a tick of rounding");
        assert_eq!(judge(Some(100.0), 100.0, 500.0, None), Verdict::KeptApart);
        assert_eq!(judge(Some(500.0), 500.0, 500.0, None), Verdict::Undecided);
        assert_eq!(judge(Some(100.0), 300.0, 500.0, None), Verdict::Discrepancy);
        // Known to mirror: only the value written passes, whatever it was before.
        assert_eq!(judge(None, 500.0, 500.0, Some(true)), Verdict::Mirrors);
        assert_eq!(judge(Some(100.0), 100.0, 500.0, Some(true)), Verdict::Discrepancy, "never weakened");
        assert_eq!(judge(None, 1.0, 500.0, Some(false)), Verdict::KeptApart);
    }
}
