//! Arguments as every front end takes them (the command line, the web console, Python): each is a validated
//! type with `FromStr` and, for a number, a checked constructor from any whole number, with one rule and one
//! message. A front end puts the argument's own name and the value given before the message (`--baud 5: an
//! SCU runs at 9600, 19200 or 38400 baud`, `baud 5: an SCU runs at ...`); a word that is not what it should be
//! is named in the message itself (`"F30" is not a function: ...`).
//!
//! ```
//! use motionlink_scu::args::{Baud, Checked};
//! use motionlink_scu::model::{Actuator, Function, MotionDirection, SafetyId};
//! assert_eq!("19200".parse::<Baud>().unwrap().get(), 19_200);
//! assert_eq!("9601".parse::<Baud>().unwrap_err().to_string(), Baud::RULE);
//! assert_eq!(Actuator::checked(7).unwrap_err().to_string(), "the actuator must be a whole number from 1 to 6");
//! assert_eq!("F11".parse::<Function>().unwrap(), Function::Buzzer);
//! assert!("sidewayz".parse::<MotionDirection>().is_err());
//! assert_eq!("2".parse::<SafetyId>().unwrap(), SafetyId::StopRemoteOnly);
//! ```

use std::str::FromStr;
use std::time::Duration;

use motionlink_link::table::{did_you_mean, nearest};

use crate::model::{
    Actuator, DataEntry, Function, Item, MotionDirection, MotionFunction, PositionCounts, SafetyId, Speed, SpeedMode,
};
use crate::session::RunAction;
use crate::value::Value;

mod targets;
mod unit;
pub use crate::model::Baud;
pub use targets::TargetLine;
pub use unit::{OptionError, UnitOptions};

/// An argument that breaks its rule; the message says what it must be.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ArgumentError(pub String);

impl From<ArgumentError> for crate::Error {
    fn from(e: ArgumentError) -> Self {
        crate::Error::InvalidArgument(e.0)
    }
}

/// A whole-number argument: its rule in words, and the check of any whole number against it.
pub trait Checked: Sized {
    /// What the value must be, as every front end says it.
    const RULE: &'static str;

    /// `n` if the rule allows it.
    fn checked(n: i64) -> Result<Self, ArgumentError>;

    /// A whole number written as text (blanks around it allowed), checked.
    fn parse_whole(text: &str) -> Result<Self, ArgumentError> {
        text.trim().parse::<i64>().map_err(|_| ArgumentError(Self::RULE.into())).and_then(Self::checked)
    }
}

/// The rule's error when `ok` is false.
fn rule<T: Checked>(ok: bool, value: impl FnOnce() -> Option<T>) -> Result<T, ArgumentError> {
    ok.then(value).flatten().ok_or_else(|| ArgumentError(T::RULE.into()))
}

/// `FromStr` of a [`Checked`] type: a whole number, checked.
macro_rules! from_whole {
    ($($t:ty),*) => {$(
        impl FromStr for $t {
            type Err = ArgumentError;
            fn from_str(s: &str) -> Result<Self, ArgumentError> {
                <$t as Checked>::parse_whole(s)
            }
        }
    )*};
}

impl Checked for Actuator {
    const RULE: &'static str = "the actuator must be a whole number from 1 to 6";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((1..=6).contains(&n), || Actuator::new(n as u8))
    }
}

impl Checked for MotionFunction {
    const RULE: &'static str = "the motion function must be a whole number from 1 to 10";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((1..=10).contains(&n), || MotionFunction::new(n as u8))
    }
}

impl Checked for SafetyId {
    const RULE: &'static str = "the Safety_ID must be a whole number from 0 to 2";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((0..=2).contains(&n), || SafetyId::from_code(n as u8))
    }
}

impl Checked for PositionCounts {
    const RULE: &'static str = "a position must be a whole number of counts, -2147483648 to 2147483647";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule(true, || i32::try_from(n).ok().map(PositionCounts))
    }
}

impl Checked for Baud {
    const RULE: &'static str = "an SCU runs at 9600, 19200 or 38400 baud";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule(matches!(n, 9_600 | 19_200 | 38_400), || Some(Baud(n as u32)))
    }
}

/// How close to its target a move must end to succeed, in encoder counts: 0..100 (100 counts are about 3 cm
/// on a TLT column).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ToleranceCounts(u32);

impl ToleranceCounts {
    /// The largest tolerance a session takes.
    pub const MAX: u32 = crate::config::MAX_TOLERANCE_COUNTS;

    /// The number of counts.
    pub const fn get(self) -> u32 {
        self.0
    }
}

impl Checked for ToleranceCounts {
    const RULE: &'static str = crate::config::TOLERANCE_RULE;
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((0..=i64::from(Self::MAX)).contains(&n), || Some(ToleranceCounts(n as u32)))
    }
}

/// How long to wait for the reply to RO: 1 ms .. 60 s, in whole ms (the manual allows the unit 2000 ms).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ReplyTimeout(Duration);

impl ReplyTimeout {
    /// The time.
    pub const fn get(self) -> Duration {
        self.0
    }
}

impl Checked for ReplyTimeout {
    const RULE: &'static str = "the reply timeout must be a whole number from 1 to 60000 ms";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((1..=60_000).contains(&n), || Some(ReplyTimeout(Duration::from_millis(n as u64))))
    }
}

/// How often a move or a run looks at the actuators: 5 ms .. 10 s, in whole ms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PollInterval(Duration);

impl PollInterval {
    /// The time.
    pub const fn get(self) -> Duration {
        self.0
    }
}

impl Checked for PollInterval {
    const RULE: &'static str = "the poll interval must be a whole number from 5 to 10000 ms";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((5..=10_000).contains(&n), || Some(PollInterval(Duration::from_millis(n as u64))))
    }
}

/// At most this many setpoint updates per second of a stream of targets: 1..100.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct UpdateRate(u32);

impl UpdateRate {
    /// Updates per second.
    pub const fn per_second(self) -> u32 {
        self.0
    }
}

impl Checked for UpdateRate {
    const RULE: &'static str = "the update rate must be a whole number from 1 to 100 per second";
    fn checked(n: i64) -> Result<Self, ArgumentError> {
        rule((1..=100).contains(&n), || Some(UpdateRate(n as u32)))
    }
}

from_whole!(
    Actuator,
    MotionFunction,
    SafetyId,
    PositionCounts,
    Baud,
    ToleranceCounts,
    ReplyTimeout,
    PollInterval,
    UpdateRate
);

/// The longest a function's run may take before it is stopped: 0 .. 86400 s (a day), any fraction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RunLimit(Duration);

impl RunLimit {
    /// What the run time must be.
    pub const RULE: &'static str = "the run time must be a number of seconds, 0 to 86400";

    /// `seconds` if finite and 0 .. 86400.
    pub fn seconds(seconds: f64) -> Result<Self, ArgumentError> {
        if seconds.is_finite() && (0.0..=86_400.0).contains(&seconds) {
            Ok(RunLimit(Duration::from_secs_f64(seconds)))
        } else {
            Err(ArgumentError(Self::RULE.into()))
        }
    }

    /// The time.
    pub const fn get(self) -> Duration {
        self.0
    }
}

impl FromStr for RunLimit {
    type Err = ArgumentError;
    fn from_str(s: &str) -> Result<Self, ArgumentError> {
        s.trim().parse::<f64>().map_err(|_| ArgumentError(Self::RULE.into())).and_then(RunLimit::seconds)
    }
}

impl Speed {
    /// What a motion's speed must be on a unit of `mode`: "a motion needs 1..100 %".
    pub fn rule(mode: SpeedMode) -> String {
        format!("a motion needs a whole number from 1 to {} {}", mode.max(), mode.unit())
    }

    /// A motion's speed `n` on a unit of `mode`: 1 up to the mode's maximum (0 would never move).
    pub fn checked(n: i64, mode: SpeedMode) -> Result<Speed, ArgumentError> {
        let zero = if n == 0 { " (0 would never move)" } else { "" };
        u16::try_from(n)
            .ok()
            .filter(|&v| v >= 1)
            .and_then(|v| Speed::of_mode(mode, v))
            .ok_or_else(|| ArgumentError(format!("{}{zero}", Speed::rule(mode))))
    }

    /// A motion's speed written as text, for a unit of `mode`: a whole number from 1 to the mode's maximum.
    pub fn parse(text: &str, mode: SpeedMode) -> Result<Speed, ArgumentError> {
        match text.trim().parse::<i64>() {
            Ok(n) => Speed::checked(n, mode),
            Err(_) => Err(ArgumentError(Speed::rule(mode))),
        }
    }
}

impl FromStr for SpeedMode {
    type Err = ArgumentError;

    /// `percent`, or `counts-per-second` (also `counts_per_second`, `counts_per_s`, `counts/s`).
    fn from_str(s: &str) -> Result<Self, ArgumentError> {
        match s.trim().to_ascii_lowercase().replace('_', "-").as_str() {
            "percent" | "%" => Ok(SpeedMode::Percent),
            "counts-per-second" | "counts-per-s" | "counts/s" => Ok(SpeedMode::CountsPerSecond),
            _ => Err(ArgumentError(format!("{s:?} is not a speed mode: give percent or counts-per-second"))),
        }
    }
}

impl FromStr for Function {
    type Err = ArgumentError;

    /// `F1`..`F22` or `1`..`22` (the manual's function numbers).
    fn from_str(s: &str) -> Result<Self, ArgumentError> {
        Function::parse(s).ok_or_else(|| {
            ArgumentError(format!(
                "{s:?} is not a function: F1..F10 motion, F11 buzzer, F17/F18 outputs, F20 emergency stop, F21/F22 LEDs"
            ))
        })
    }
}

impl FromStr for MotionDirection {
    type Err = ArgumentError;

    /// A direction's name or code ([`MotionDirection::parse`]); a misspelt one is answered with the nearest.
    fn from_str(s: &str) -> Result<Self, ArgumentError> {
        MotionDirection::parse(s).ok_or_else(|| {
            let hint = did_you_mean(&nearest(s, MotionDirection::NAMES.iter().copied()))
                .unwrap_or_else(|| "in, out, mem1..mem4, int-in, int-out, remote, none, or 0..9".into());
            ArgumentError(format!("{s:?} is not a direction: {hint}"))
        })
    }
}

impl RunAction {
    /// What `run FUNCTION DIRECTION` asks for: a motion function with a direction, or another function
    /// with `on`.
    pub fn parse(function: &str, direction: &str) -> Result<RunAction, ArgumentError> {
        match function.parse::<Function>()? {
            Function::Motion(m) => Ok(RunAction::Motion(m, direction.parse()?)),
            f if direction.trim().eq_ignore_ascii_case("on") => Ok(RunAction::Switch(f)),
            f => Err(ArgumentError(format!("{f} is switched with \"on\", not {direction:?}"))),
        }
    }

    /// The function it runs.
    pub fn function(self) -> Function {
        match self {
            RunAction::Motion(m, _) => Function::Motion(m),
            RunAction::Switch(f) => f,
        }
    }
}

/// What writing `text` into `item` asks for: the entry (a remote data entry 0x3xxx, not a group) and the
/// value, parsed in the entry's unit.
pub fn parse_write(item: Item, text: &str) -> Result<(&'static DataEntry, Value), ArgumentError> {
    let Item::Entry(e) = item else {
        return Err(ArgumentError(format!("{} is a group; set its entries one by one", item.name())));
    };
    if !e.access.writable() {
        return Err(ArgumentError(format!("{} is read-only: RT writes the remote data (0x3xxx)", e.name)));
    }
    let value = Value::parse(e.kind, text).map_err(|err| ArgumentError(format!("{}: {err}", e.name)))?;
    Ok((e, value))
}

/// The unit an emulator in the front end's own process (`--port sim`, `port="sim"`) stands for: the unit the
/// function specifications describe, as the session is told it is. It starts from `preset` (scp11, tlt,
/// liftkit; else the default, SCP11 with two actuators); the specifications apply in order, as they do to the
/// session's [`FunctionMap`](crate::FunctionMap): a preset replaces the unit (unless `preset` was given,
/// which wins), `F1=1,2` makes one function drive those actuators (actuators are added to reach the highest
/// one named). The unit takes remote speeds as `speed_mode` says.
pub fn emulated_unit<S: AsRef<str>>(
    preset: Option<&str>,
    specs: &[S],
    speed_mode: SpeedMode,
) -> Result<crate::SimConfig, String> {
    use crate::SimConfig;
    let known = |name: &str| SimConfig::preset(&name.trim().to_ascii_lowercase());
    let mut unit = match preset {
        Some(p) => known(p).ok_or_else(|| format!("{p:?} is not a preset: {}", SimConfig::PRESETS.join(", ")))?,
        None => SimConfig::default(),
    };
    for spec in specs.iter().map(|s| s.as_ref()) {
        match known(spec) {
            Some(named) if preset.is_none() => unit = named,
            Some(_) => {}
            None => {
                let one = crate::FunctionMap::unknown().apply(spec)?;
                for f in MotionFunction::all() {
                    let Some(drives) = one.drives(f) else { continue };
                    let highest = drives.iter().map(|a| usize::from(a.number())).max().unwrap_or(0);
                    if highest > unit.actuators.len() {
                        unit.actuators.resize(highest, Default::default());
                    }
                    unit.functions[usize::from(f.id())] = drives;
                }
            }
        }
    }
    unit.speed_mode = speed_mode;
    unit.validate().map_err(|e| e.to_string())?;
    Ok(unit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_checked_against_one_rule_each() {
        assert_eq!(Actuator::checked(6).unwrap().number(), 6);
        for bad in [0, 7, -1, i64::MAX] {
            assert_eq!(Actuator::checked(bad).unwrap_err().0, Actuator::RULE, "{bad}");
        }
        assert_eq!(" 3 ".parse::<MotionFunction>().unwrap().number(), 3);
        assert_eq!("11".parse::<MotionFunction>().unwrap_err().0, MotionFunction::RULE);
        assert_eq!("x".parse::<SafetyId>().unwrap_err().0, SafetyId::RULE);
        assert_eq!("-12".parse::<PositionCounts>().unwrap(), PositionCounts(-12));
        assert!(PositionCounts::checked(1 << 40).is_err());
        for bad in ["0", "9601", "-1", "115200", "fast"] {
            assert_eq!(bad.parse::<Baud>().unwrap_err().0, Baud::RULE, "{bad}");
        }
        assert_eq!("100".parse::<ToleranceCounts>().unwrap().get(), 100);
        assert!("101".parse::<ToleranceCounts>().is_err() && "-1".parse::<ToleranceCounts>().is_err());
        assert_eq!("60000".parse::<ReplyTimeout>().unwrap().get(), Duration::from_secs(60));
        assert!("0".parse::<ReplyTimeout>().is_err() && "4".parse::<PollInterval>().is_err());
        assert!("0".parse::<UpdateRate>().is_err() && "101".parse::<UpdateRate>().is_err());
        assert_eq!("0.5".parse::<RunLimit>().unwrap().get(), Duration::from_millis(500));
        for bad in ["NaN", "-1", "86401", "inf", ""] {
            assert_eq!(bad.parse::<RunLimit>().unwrap_err().0, RunLimit::RULE, "{bad}");
        }
    }

    #[test]
    fn speeds_are_whole_numbers_from_1_to_the_mode_maximum() {
        assert_eq!(Speed::parse("100", SpeedMode::Percent).unwrap().raw(), 100);
        assert_eq!(Speed::parse("1000", SpeedMode::CountsPerSecond).unwrap().raw(), 1000);
        let zero = Speed::parse("0", SpeedMode::Percent).unwrap_err().0;
        assert_eq!(zero, "a motion needs a whole number from 1 to 100 % (0 would never move)");
        for bad in ["-1", "101", "NaN", "50.5", "", "1e2"] {
            assert_eq!(Speed::parse(bad, SpeedMode::Percent).unwrap_err().0, Speed::rule(SpeedMode::Percent));
        }
        assert!(Speed::checked(1001, SpeedMode::CountsPerSecond).unwrap_err().0.contains("1000 counts/s"));
        assert_eq!("counts_per_s".parse::<SpeedMode>().unwrap(), SpeedMode::CountsPerSecond);
        assert_eq!("Counts-Per-Second".parse::<SpeedMode>().unwrap(), SpeedMode::CountsPerSecond);
        assert!("fast".parse::<SpeedMode>().unwrap_err().0.contains("percent or counts-per-second"));
    }

    #[test]
    fn words_name_themselves_and_the_nearest_real_one() {
        let e = "F30".parse::<Function>().unwrap_err().0;
        assert!(e.starts_with("\"F30\" is not a function: F1..F10 motion"), "{e}");
        assert_eq!(
            "int-ot".parse::<MotionDirection>().unwrap_err().0,
            "\"int-ot\" is not a direction: did you mean int-out?"
        );
        assert_eq!(
            RunAction::parse("F2", "out").unwrap(),
            RunAction::Motion(MotionFunction::new(2).unwrap(), MotionDirection::Out)
        );
        assert_eq!(RunAction::parse("11", " ON").unwrap(), RunAction::Switch(Function::Buzzer));
        assert_eq!(RunAction::parse("F11", "off").unwrap_err().0, "F11 (buzzer) is switched with \"on\", not \"off\"");
    }

    #[test]
    fn a_write_names_its_entry_and_value() {
        let item = |n: &str| crate::model::find(n).unwrap();
        let (e, v) = parse_write(item("remote_speed_f1"), "80").unwrap();
        assert_eq!((e.name, v), ("remote_speed_f1", Value::RemoteSpeed(80)));
        assert_eq!(
            parse_write(item("remote_speeds"), "1").unwrap_err().0,
            "remote_speeds is a group; set its entries one by one"
        );
        assert!(parse_write(item("actual_position_a1"), "1").unwrap_err().0.contains("read-only"));
        assert!(parse_write(item("remote_speed_f1"), "fast").unwrap_err().0.starts_with("remote_speed_f1: "));
    }

    #[test]
    fn the_emulated_unit_is_the_one_the_functions_name() {
        use crate::SimConfig;
        let unit = |specs: &[&str], preset| emulated_unit(preset, specs, SpeedMode::Percent);
        let a = |n| Actuator::new(n).unwrap();
        assert_eq!(unit(&[], None).unwrap(), SimConfig::default());
        assert_eq!(unit(&["tlt"], None).unwrap(), SimConfig::tlt());
        assert_eq!(unit(&["TLT", "liftkit"], None).unwrap(), SimConfig::liftkit());
        assert_eq!(unit(&["tlt"], Some("liftkit")).unwrap(), SimConfig::liftkit(), "the preset asked for wins");
        let c = unit(&["F1=1,2", "F7=3"], None).unwrap();
        assert_eq!(c.actuators.len(), 3);
        assert_eq!((c.functions[0].clone(), c.functions[6].clone()), (vec![a(1), a(2)], vec![a(3)]));
        assert_eq!(c.functions[1], vec![a(2)], "the others keep the preset's");
        let c = unit(&["tlt", "F8=1,2"], None).unwrap();
        assert_eq!((c.functions[0].clone(), c.functions[7].clone()), (vec![a(1), a(2)], vec![a(1), a(2)]));
        assert_eq!(unit(&["F8=1,2", "tlt"], None).unwrap(), SimConfig::tlt(), "a preset replaces the unit, as the map");
        assert_eq!(
            emulated_unit(None, &["tlt"], SpeedMode::CountsPerSecond).unwrap().speed_mode,
            SpeedMode::CountsPerSecond
        );
        assert!(unit(&["F11=1"], None).unwrap_err().contains("F11"));
        assert!(unit(&[], Some("lift")).unwrap_err().contains("tlt"));
    }
}
