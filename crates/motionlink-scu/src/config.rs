//! The settings of a session ([`Config`]), which actuators each function drives ([`FunctionMap`]), and
//! the travel range of an actuator ([`StrokeLimits`]).

use std::time::Duration;

use crate::error::Error;
use crate::model::{timing, Actuator, Baud, MotionFunction, PositionCounts, SafetyId, SpeedMode};
use crate::wire::MAX_REQUEST_LEN;

/// The longest keepalive period accepted: the unit's watchdog is 500 ms, and a period must leave room for a
/// reply and the caller's requests in between.
pub const MAX_KEEPALIVE_PERIOD: Duration = Duration::from_millis(timing::WATCHDOG.as_millis() as u64 - 50);

/// The longest a reply is awaited in remote mode: twice the unit's watchdog.
pub const SESSION_REPLY_LIMIT: Duration = Duration::from_millis(2 * timing::WATCHDOG.as_millis() as u64);

/// On a silent line (a request got no byte of reply at all), the time each further request is given.
pub const SILENT_TRY: Duration = Duration::from_millis(300);

/// How many zero bytes are sent before a request is repeated after silence: enough to complete the longest
/// telegram the unit could be waiting for.
pub const FLUSH_LEN: usize = MAX_REQUEST_LEN;

/// How long a request waits for room on the line before it is given up (or, for a stop, sent anyway): room
/// means that its reply is expected back before the latest time the next RC must go out
/// ([`RC_DEADLINE`] after the last one), given the round trip measured so far.
pub const MAX_ROOM_WAIT: Duration = Duration::from_millis(1000);

/// The latest time after an RC that the next one must be sent: the unit's watchdog (500 ms from the last RC
/// it received) less 100 ms for jitter and for an estimate of the round trip that is a little short.
pub const RC_DEADLINE: Duration = Duration::from_millis(timing::WATCHDOG.as_millis() as u64 - 100);

/// The cyclic object a session defines for polling moves by default (CyclicObj 5, 0x3005).
pub const DEFAULT_POLL_SLOT: u8 = 5;

/// The default poll interval of moves: one RC carrying the session's cyclic object (60 bytes both ways, about
/// 16 ms at 38400 baud) every 50 ms uses about a third of the half-duplex line and leaves the rest to the
/// caller; the same RC is the keepalive.
pub const DEFAULT_POLL_INTERVAL: Duration = Duration::from_millis(50);

/// The silence after which a request is sent again, unless the reply timeout is shorter than twice this
/// ([`Config::effective_retry_after`]).
pub const DEFAULT_RETRY_AFTER: Duration = Duration::from_millis(150);

/// Which actuators each motion function F1..F10 drives: the unit's parameterisation, which the data list
/// does not show. A function may be *unknown* (the default for all): then [`crate::Client::move_to`] treats
/// every connected actuator as possibly driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FunctionMap([Option<u8>; 10]);

impl FunctionMap {
    /// Nothing known.
    pub const fn unknown() -> Self {
        FunctionMap([None; 10])
    }

    /// SCP11 (the manual's chapter 5): Fn drives An alone for n = 1..6; F7..F10 drive nothing.
    pub fn scp11() -> Self {
        FunctionMap(std::array::from_fn(|i| Some(if i < 6 { 1 << i } else { 0 })))
    }

    /// The emulator's `tlt` preset: F1 drives A1 and A2 together, F2 A1 alone, F3 A2 alone; the others
    /// nothing.
    pub fn tlt() -> Self {
        let mut m = [Some(0); 10];
        m[0] = Some(0b11);
        m[1] = Some(0b01);
        m[2] = Some(0b10);
        FunctionMap(m)
    }

    /// The mapping the public LIFTKIT/TLT drivers assume (the emulator's `liftkit` preset): F1 drives A1, F2
    /// A2, F8 both; the others nothing.
    pub fn liftkit() -> Self {
        let mut m = [Some(0); 10];
        m[0] = Some(0b01);
        m[1] = Some(0b10);
        m[7] = Some(0b11);
        FunctionMap(m)
    }

    /// The map of a preset by name: `scp11`, `tlt`, `liftkit`, or `unknown`.
    pub fn preset(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "scp11" => Some(Self::scp11()),
            "tlt" => Some(Self::tlt()),
            "liftkit" => Some(Self::liftkit()),
            "unknown" => Some(Self::unknown()),
            _ => None,
        }
    }

    /// `function` drives exactly `actuators` (an empty list: nothing).
    pub fn with(mut self, function: MotionFunction, actuators: &[Actuator]) -> Self {
        self.0[usize::from(function.id())] = Some(actuators.iter().fold(0, |m, a| m | 1 << (a.number() - 1)));
        self
    }

    /// The actuators `function` drives, if known.
    pub fn drives(&self, function: MotionFunction) -> Option<Vec<Actuator>> {
        let mask = self.0[usize::from(function.id())]?;
        Some(Actuator::all().filter(|a| mask & 1 << (a.number() - 1) != 0).collect())
    }

    /// Applies one specification: a preset name (`scp11`, `tlt`, `liftkit`, `unknown`) replaces the whole
    /// map; `F1=1,2` (or `F1=1+2`) says what one function drives, `F7=` that it drives nothing.
    pub fn apply(self, spec: &str) -> Result<Self, String> {
        let spec = spec.trim();
        if let Some(m) = Self::preset(spec) {
            return Ok(m);
        }
        let Some((f, list)) = spec.split_once('=') else {
            return Err(format!(
                "{spec:?}: give a preset (scp11, tlt, liftkit) or a function and its actuators (F1=1,2)"
            ));
        };
        let function = f
            .trim()
            .trim_start_matches(['F', 'f'])
            .parse::<u8>()
            .ok()
            .and_then(MotionFunction::new)
            .ok_or_else(|| format!("{spec:?}: {f:?} is not a motion function F1..F10"))?;
        let mut actuators = Vec::new();
        for part in list.split([',', '+', ' ']).map(str::trim).filter(|p| !p.is_empty()) {
            let a = part
                .trim_start_matches(['A', 'a'])
                .parse::<u8>()
                .ok()
                .and_then(Actuator::new)
                .ok_or_else(|| format!("{spec:?}: {part:?} is not an actuator 1..6"))?;
            if !actuators.contains(&a) {
                actuators.push(a);
            }
        }
        Ok(self.with(function, &actuators))
    }
}

impl FunctionMap {
    /// The map `specs` give, applied in order to an unknown map ([`FunctionMap::apply`]): what the front
    /// ends' repeated `--functions` / `functions=[...]` say.
    pub fn from_specs<S: AsRef<str>>(specs: &[S]) -> Result<Self, String> {
        specs.iter().try_fold(FunctionMap::unknown(), |map, spec| map.apply(spec.as_ref()))
    }
}

impl Default for FunctionMap {
    /// Nothing known: see [`FunctionMap::unknown`].
    fn default() -> Self {
        Self::unknown()
    }
}

/// The travel range of an actuator, both ends included.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StrokeLimits {
    /// The lowest position a target may have.
    pub min_counts: PositionCounts,
    /// The highest position a target may have.
    pub max_counts: PositionCounts,
}

/// How a move (and a motion function's run) watches the actuators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MovePolling {
    /// Through the RC keepalive: the session defines CyclicObj `slot` (1..5) to read the status 1, the
    /// position and the current of every actuator and Error_Code 1 (0x0170, 0x0010, 0x00A0, 0x00D1), and while
    /// a motion or a watch runs, the RCs carry it, one every [`Config::poll_interval`] at most: each
    /// exchange both feeds the unit's watchdog and reads the state. A unit that refuses the definition, its
    /// read-back or an RC carrying it is polled with reads instead. The default (slot
    /// [`DEFAULT_POLL_SLOT`]); while [`crate::Client::use_cyclic`] has the keepalive carry the caller's own
    /// object, moves poll with reads.
    Cyclic {
        /// The cyclic object the session defines, 1..5.
        slot: u8,
    },
    /// With RG: status 1, then the positions, every [`Config::poll_interval`]; the keepalive goes on
    /// beside them.
    Reads,
}

impl Default for MovePolling {
    fn default() -> Self {
        MovePolling::Cyclic { slot: DEFAULT_POLL_SLOT }
    }
}

impl StrokeLimits {
    /// Parses `ACTUATOR=MIN:MAX` in counts (`1=0:865`, `A2=-3:860`): an actuator's travel range.
    pub fn parse_for_actuator(spec: &str) -> Result<(Actuator, StrokeLimits), String> {
        let bad = || format!("{spec:?}: give ACTUATOR=MIN:MAX in counts, such as 1=0:865");
        let (a, range) = spec.split_once('=').ok_or_else(bad)?;
        let a = a.trim().trim_start_matches(['A', 'a']).parse::<u8>().ok().and_then(Actuator::new).ok_or_else(bad)?;
        let (lo, hi) = range.split_once(':').ok_or_else(bad)?;
        let lo: i32 = lo.trim().parse().map_err(|_| bad())?;
        let hi: i32 = hi.trim().parse().map_err(|_| bad())?;
        if lo > hi {
            return Err(format!("{spec:?}: {lo} is above {hi}"));
        }
        Ok((a, StrokeLimits { min_counts: PositionCounts(lo), max_counts: PositionCounts(hi) }))
    }

    /// The travel ranges `specs` give (`1=0:865`, one per actuator: an actuator given twice is an error,
    /// not a choice between two limits), as [`Config::stroke_limits`] takes them.
    pub fn per_actuator<S: AsRef<str>>(specs: &[S]) -> Result<[Option<StrokeLimits>; 6], String> {
        let mut limits = [None; 6];
        for spec in specs {
            let (a, l) = StrokeLimits::parse_for_actuator(spec.as_ref())?;
            let slot = &mut limits[usize::from(a.number() - 1)];
            if slot.is_some() {
                return Err(format!(
                    "the stroke of {a} is given twice ({:?}): give each actuator's once",
                    spec.as_ref()
                ));
            }
            *slot = Some(l);
        }
        Ok(limits)
    }
}

/// Settings of a session. The defaults follow the manual.
#[derive(Debug, Clone)]
pub struct Config {
    /// The serial line's rate, for [`Client::open`](crate::Client::open). Default 38400 (the manual's standard).
    pub baud: Baud,
    /// What the unit does when the watchdog expires (RO's Safety_ID). Default 0.
    pub safety_id: SafetyId,
    /// Time between RC keepalives. Default 200 ms; more than [`MAX_KEEPALIVE_PERIOD`] is refused.
    pub keepalive_period: Duration,
    /// How long to wait for the reply to RO. Default 2000 ms (the manual's maximum request delay). In remote
    /// mode replies are awaited at most [`SESSION_REPLY_LIMIT`], or this if it is shorter.
    pub reply_timeout: Duration,
    /// A request is sent again when not one byte of its reply has come this long after it was sent (or twice
    /// the longest round trip measured lately, if that is longer), then after twice this, four times this
    /// ... of silence, within the reply timeout. `None` (the default): [`DEFAULT_RETRY_AFTER`], or half the
    /// reply timeout if that is shorter, so that a short reply timeout brings a short retry with it
    /// ([`Config::effective_retry_after`]); a value set here must be below the reply timeout.
    pub retry_after: Option<Duration>,
    /// How many times a request is sent again after a corrupt reply, a CSE or a PCE. Default 2.
    pub retries: u32,
    /// Which actuators each function drives. Default: unknown for every function.
    pub function_map: FunctionMap,
    /// Whether remote speeds are percent or counts per second. Default percent.
    pub speed_mode: SpeedMode,
    /// How close to its target a move must end, in counts, for success. Default 5: real columns read a few
    /// counts off after homing, and 5 counts are 1.5 mm on a TLT column (about 3225 counts per metre).
    pub position_tolerance_counts: u32,
    /// Each actuator's travel range for targets; `None`: read from the unit (the virtual limits of its
    /// UserPositionData; a unit whose virtual limits are both 0 has none, and then only the unit's own ends
    /// bound the motion, which the final position check reports). Default: all `None`.
    pub stroke_limits: [Option<StrokeLimits>; 6],
    /// How often a move polls the actuators. Default [`DEFAULT_POLL_INTERVAL`] (50 ms); 5 ms .. 10 s.
    pub poll_interval: Duration,
    /// A move whose actuator does not advance for this long while its motion bit is set has stalled. Default 3 s.
    pub stall_timeout: Duration,
    /// The longest a move may take. Default 300 s.
    pub move_timeout: Duration,
    /// After RE, how long the motion bit may take to come up before a still-standing actuator is an error;
    /// after the RE or RS of a switching function, how long its status entry is read again before what it
    /// shows is judged ([`crate::model::SwitchStatus`]). Default 1 s.
    pub start_grace: Duration,
    /// Reconnect by itself when the port is lost (every [`Config::reconnect_interval`]). Default off.
    pub auto_reconnect: bool,
    /// Time between automatic reconnection attempts. Default 1 s.
    pub reconnect_interval: Duration,
    /// How moves watch the actuators. Default: through the RC keepalive's cyclic object 5.
    pub move_polling: MovePolling,
    /// The longest [`crate::Client::close`] (and dropping a client) waits for the end of the session (the RS
    /// of every started function, then RA) before it reports that the stop was not confirmed. Default 5 s; a
    /// dead link takes about 0.6 s (one short try of RS and of RA).
    pub close_bound: Duration,
    /// Whether a watch on a link too slow to define its cyclic object beside the keepalive (round trips near
    /// 290 ms) may define it across one lapse of the unit's 500 ms watchdog, while the session has started
    /// nothing: the unit then records error bit 22 and stops every motion under way (with Safety_ID 2 the
    /// remote ones only), a hand switch's included. Default false: such a watch ends with
    /// [`Error::NoRoom`].
    pub watch_may_lapse: bool,
    /// Before every opening of the port (the first and each reconnection), hold the unit's RxD at "space"
    /// this long (a break): a battery unit with `<Low Power> = Enabled` in low-power mode wakes so, "min. 100
    /// ms" (E 3, S 3: from FW V2B1). `None` (the default): no break. Only a serial line can send one.
    pub wake_break: Option<Duration>,
}

/// The break [`Config::wake_break`] takes when asked for without a length (the command line's `--wake`):
/// 150 ms, the manual's 100 ms with room for a USB adapter's timing.
pub const WAKE_BREAK: Duration = Duration::from_millis(150);

/// The shortest break that wakes a unit in low-power mode (E 3, S 3: "min. 100 ms").
pub const MIN_WAKE_BREAK: Duration = Duration::from_millis(100);

/// The largest position tolerance a session takes, in counts ([`crate::args::ToleranceCounts`]).
pub const MAX_TOLERANCE_COUNTS: u32 = 100;

/// The rule of a position tolerance, as messages say it.
pub const TOLERANCE_RULE: &str = "the position tolerance must be a whole number from 0 to 100 counts";

impl Default for Config {
    fn default() -> Self {
        Config {
            baud: Baud::STANDARD,
            safety_id: SafetyId::StopAllAndLock,
            keepalive_period: Duration::from_millis(200),
            reply_timeout: timing::MAX_REPLY_DELAY,
            retry_after: None,
            retries: 2,
            function_map: FunctionMap::default(),
            speed_mode: SpeedMode::Percent,
            position_tolerance_counts: 5,
            stroke_limits: [None; 6],
            poll_interval: DEFAULT_POLL_INTERVAL,
            stall_timeout: Duration::from_secs(3),
            move_timeout: Duration::from_secs(300),
            start_grace: Duration::from_secs(1),
            auto_reconnect: false,
            reconnect_interval: Duration::from_secs(1),
            move_polling: MovePolling::default(),
            close_bound: Duration::from_secs(5),
            watch_may_lapse: false,
            wake_break: None,
        }
    }
}

impl Config {
    /// The silence after which a request is sent again: [`Config::retry_after`] as set, or
    /// [`DEFAULT_RETRY_AFTER`], or half the reply timeout if that is shorter.
    pub fn effective_retry_after(&self) -> Duration {
        self.retry_after.unwrap_or_else(|| DEFAULT_RETRY_AFTER.min(self.reply_timeout / 2))
    }

    /// Checks every setting; the error names the one that is out of range.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |what: String| Err(Error::InvalidArgument(what));
        if self.keepalive_period.is_zero() || self.keepalive_period > MAX_KEEPALIVE_PERIOD {
            return bad(format!(
                "keepalive period {:?} refused: it must be above 0 and at most {:?} (the unit's watchdog is 500 ms)",
                self.keepalive_period, MAX_KEEPALIVE_PERIOD
            ));
        }
        if self.reply_timeout.is_zero() || self.reply_timeout > Duration::from_secs(60) {
            return bad(format!("reply timeout {:?}: it must be above 0 and at most 60 s", self.reply_timeout));
        }
        if let Some(r) = self.retry_after {
            if r.is_zero() || r >= self.reply_timeout {
                return bad(format!(
                    "retry_after {r:?}: it must be above 0 and below the reply timeout {:?}",
                    self.reply_timeout
                ));
            }
        }
        if self.retries > 10 {
            return bad(format!("retries {}: at most 10", self.retries));
        }
        if let Some(b) = self.wake_break {
            if !(MIN_WAKE_BREAK..=Duration::from_secs(2)).contains(&b) {
                return bad(format!(
                    "wake break {b:?}: 100 ms (the manual's least) to 2 s (the unit's longest request delay)"
                ));
            }
        }
        if self.position_tolerance_counts > MAX_TOLERANCE_COUNTS {
            return bad(format!("position tolerance {} counts: {TOLERANCE_RULE}", self.position_tolerance_counts));
        }
        if !(Duration::from_millis(5)..=Duration::from_secs(10)).contains(&self.poll_interval) {
            return bad(format!("poll interval {:?}: 5 ms to 10 s", self.poll_interval));
        }
        for (what, d) in [
            ("stall timeout", self.stall_timeout),
            ("move timeout", self.move_timeout),
            ("start grace", self.start_grace),
            ("reconnect interval", self.reconnect_interval),
            ("close bound", self.close_bound),
        ] {
            if d.is_zero() {
                return bad(format!("{what} must be above 0"));
            }
        }
        if let MovePolling::Cyclic { slot } = self.move_polling {
            if !(1..=5).contains(&slot) {
                return bad(format!("move polling through cyclic object {slot}: there are CyclicObj 1..5"));
            }
        }
        for (i, s) in self.stroke_limits.iter().enumerate() {
            if let Some(s) = s {
                if s.min_counts > s.max_counts {
                    return bad(format!(
                        "stroke of A{}: {} is above {} (give MIN:MAX)",
                        i + 1,
                        s.min_counts,
                        s.max_counts
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_retry_follows_a_short_reply_timeout_unless_it_was_set() {
        let mut c = Config { reply_timeout: Duration::from_millis(100), ..Config::default() };
        assert_eq!(c.effective_retry_after(), Duration::from_millis(50), "half of a short reply timeout");
        assert!(c.validate().is_ok(), "{:?}", c.validate());
        assert_eq!(Config::default().effective_retry_after(), DEFAULT_RETRY_AFTER);
        c.retry_after = Some(Duration::from_millis(150));
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("retry_after 150ms") && e.contains("100ms"), "a setting made is checked: {e}");
        c.retry_after = Some(Duration::from_millis(20));
        assert_eq!(c.effective_retry_after(), Duration::from_millis(20));
    }

    #[test]
    fn specifications_apply_in_order_with_the_library_s_messages() {
        let a = |n| Actuator::new(n).unwrap();
        let map = FunctionMap::from_specs(&["tlt", "F4=1"]).unwrap();
        assert_eq!(map.drives(MotionFunction::new(1).unwrap()), Some(vec![a(1), a(2)]));
        assert_eq!(map.drives(MotionFunction::new(4).unwrap()), Some(vec![a(1)]));
        assert!(FunctionMap::from_specs(&["lift"]).unwrap_err().contains("give a preset (scp11, tlt, liftkit) or"));
        let limits = StrokeLimits::per_actuator(&["1=0:865", "A2=-3:860"]).unwrap();
        assert_eq!(limits[1].map(|l| l.min_counts), Some(PositionCounts(-3)));
        assert!(limits[2].is_none());
        assert!(StrokeLimits::per_actuator(&["1=9:1"]).unwrap_err().contains("9 is above 1"));
        let twice = StrokeLimits::per_actuator(&["1=0:100", "A1=0:865"]).unwrap_err();
        assert!(twice.contains("A1") && twice.contains("twice") && twice.contains("A1=0:865"), "{twice}");
    }
}
