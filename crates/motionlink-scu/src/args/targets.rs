//! A line of targets for a stream of setpoints, as `motionlink scu follow` reads them from stdin (and any
//! front end that takes targets as text).

use super::{ArgumentError, Checked};
use crate::model::{Actuator, PositionCounts, Speed, SpeedMode};

/// One line of targets for a stream that moves `actuators`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TargetLine {
    /// Nothing (a blank line or a comment).
    Skip,
    /// New targets, one per actuator of the stream, in its order.
    Targets(Vec<PositionCounts>),
    /// A new speed.
    Speed(Speed),
}

impl TargetLine {
    /// Parses `400` (one target for every actuator), `400 410` (one each, in order), `a1=400 a2=410` (each
    /// named), `speed 60` (a new speed on a unit of `mode`); `#` starts a comment.
    pub fn parse(line: &str, actuators: &[Actuator], mode: SpeedMode) -> Result<TargetLine, ArgumentError> {
        let text = line.split('#').next().unwrap_or("").trim();
        if text.is_empty() {
            return Ok(TargetLine::Skip);
        }
        let bad = |m: String| ArgumentError(m);
        if let Some(rest) = text.strip_prefix("speed") {
            let value = rest.trim().trim_start_matches('=').trim();
            return Speed::parse(value, mode).map(TargetLine::Speed).map_err(|e| bad(format!("speed {value}: {e}")));
        }
        let words: Vec<&str> = text.split([' ', '\t', ',']).filter(|w| !w.is_empty()).collect();
        let count = |w: &str| PositionCounts::parse_whole(w).map_err(|e| bad(format!("{w:?}: {e}")));
        if words.iter().all(|w| !w.contains('=')) {
            let values = words.iter().map(|w| count(w)).collect::<Result<Vec<_>, _>>()?;
            return match values.len() {
                1 => Ok(TargetLine::Targets(vec![values[0]; actuators.len()])),
                n if n == actuators.len() => Ok(TargetLine::Targets(values)),
                n => {
                    Err(bad(format!("{n} targets for {} actuator(s): give one for all, or one each", actuators.len())))
                }
            };
        }
        let mut targets = vec![None; actuators.len()];
        for w in words {
            let (name, value) =
                w.split_once('=').ok_or_else(|| bad(format!("{w:?}: give ACTUATOR=COUNTS, such as a1=400")))?;
            let a = name.trim_start_matches(['A', 'a']).parse::<u8>().ok().and_then(Actuator::new);
            let i = a.and_then(|a| actuators.iter().position(|x| *x == a)).ok_or_else(|| {
                let followed = actuators.iter().map(Actuator::to_string).collect::<Vec<_>>().join(", ");
                bad(format!("{name:?} is not one of the actuators followed ({followed})"))
            })?;
            if targets[i].is_some() {
                return Err(bad(format!("{} is given twice: give one target each", actuators[i])));
            }
            targets[i] = Some(count(value)?);
        }
        if let Some(i) = targets.iter().position(Option::is_none) {
            return Err(bad(format!("no target for {} (every actuator followed needs one)", actuators[i])));
        }
        Ok(TargetLine::Targets(targets.into_iter().flatten().collect()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_give_one_target_for_all_one_each_or_named_ones() {
        let a = |n| Actuator::new(n).unwrap();
        let two = [a(1), a(2)];
        let p = |l: &str| TargetLine::parse(l, &two, SpeedMode::Percent);
        let at = PositionCounts;
        assert_eq!(p("400"), Ok(TargetLine::Targets(vec![at(400), at(400)])));
        assert_eq!(p(" 400  410 "), Ok(TargetLine::Targets(vec![at(400), at(410)])));
        assert_eq!(p("a2=410 A1=-3"), Ok(TargetLine::Targets(vec![at(-3), at(410)])));
        assert_eq!(p("speed 60"), Ok(TargetLine::Speed(Speed::percent(60).unwrap())));
        assert_eq!(p("speed=60 # slower"), Ok(TargetLine::Speed(Speed::percent(60).unwrap())));
        assert_eq!(p("   # only a comment"), Ok(TargetLine::Skip));
        assert_eq!(p(""), Ok(TargetLine::Skip));
        for bad in ["400 410 420", "a1=400", "a3=1 a1=2 a2=3", "four hundred", "speed 0", "speed 101", "a1=x a2=1"] {
            assert!(p(bad).is_err(), "{bad}");
        }
        assert_eq!(p("a1=400").unwrap_err().0, "no target for A2 (every actuator followed needs one)");
        assert_eq!(p("a1=400 a1=500 a2=1").unwrap_err().0, "A1 is given twice: give one target each");
        assert!(p("speed 0").unwrap_err().0.starts_with("speed 0: a motion needs"));
    }
}
