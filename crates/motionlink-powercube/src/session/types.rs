//! What a session is configured with and what its operations take and give.

use std::time::Duration;

use crate::args::{Baud, CanBitRate};
use crate::error::Error;
use crate::model::{
    Acceleration, AckKind, Address, AxisUnit, CubeState, CubeVersion, ModuleKind, Motion, MotionId, Param, Position,
    StateFlag, Value, Velocity,
};
use crate::wire::{ExtAck, Request, RAW_CUR_MAX};

/// Timing and retry settings of a session; the defaults depend on the carrier.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// How long to wait for an acknowledge.
    pub reply_timeout: Duration,
    /// How often a read is repeated after a timeout or a corrupt answer (writes and motions never are).
    pub read_retries: u32,
    /// How long a scan waits for each address (RS232) or for all answers (CAN).
    pub scan_timeout: Duration,
    /// How often the watchdog refresh is broadcast while the watchdog is served (the modules wait 50 ms).
    pub watchdog_period: Duration,
    /// How often the state is polled while waiting for homing or a motion to end (10 ms by default): the
    /// polls are scheduled at this period from the first one (absolute deadlines), never faster, however
    /// quickly the line answers, so that a wait leaves the bus to the other modules and hosts on it.
    pub poll_interval: Duration,
    /// Let the session arm watchdogs on RS232 (default true). The manual lists the broadcasts for CAN only;
    /// on RS232 the refresh goes to module address 0 as the command followed by 0x00, the form Schunk's own
    /// library (libm5api, serveWatchdogAll) sends over RS232. Set false to refuse arming on RS232 for a
    /// chain known not to take it.
    pub watchdog_on_rs232: bool,
    /// The longest a client's `close()` (and its drop) waits for the close sequence (halt what still
    /// moves, switch the watchdogs off) before it gives up and says the stop was not confirmed
    /// ([`Error::CloseTimedOut`]); it returns at most one read slice of the driver (20 ms) later. 5 s by
    /// default. When it gives up, the watchdog refresh stops with the session: a module whose watchdog it
    /// armed halts itself within 50 ms.
    pub close_bound: Duration,
    /// After a motion command of this session, how long the module may take to show it (STATE_MOTION)
    /// before a state that shows an end (STATE_RAMP_END, STATE_HOME_OK, perhaps of an earlier motion) counts
    /// as this motion's end: the manual does not say how soon a module sets STATE_MOTION (a module with a
    /// brake may release it first). 1 s by default. Also how long after a motion command the close halts a
    /// module that does not show STATE_MOTION yet.
    pub start_grace: Duration,
    /// The RS232 line's rate, for [`Client::open`](crate::Client::open). Default 9600.
    pub baud: Baud,
    /// An SLCAN adapter's CAN bit rate, for [`Client::open`](crate::Client::open). Default 1 Mbit/s.
    pub can_bitrate: CanBitRate,
}

impl Config {
    /// RS232: a full frame takes up to 25 ms each way at 9600 baud; acknowledges within 200 ms.
    pub fn rs232() -> Self {
        Config {
            reply_timeout: Duration::from_millis(200),
            read_retries: 2,
            scan_timeout: Duration::from_millis(60),
            watchdog_period: Duration::from_millis(20),
            poll_interval: Duration::from_millis(10),
            watchdog_on_rs232: true,
            close_bound: Duration::from_secs(5),
            start_grace: Duration::from_secs(1),
            baud: Baud::DEFAULT,
            can_bitrate: CanBitRate::DEFAULT,
        }
    }

    /// CAN: acknowledges within 50 ms.
    pub fn can() -> Self {
        Config {
            reply_timeout: Duration::from_millis(50),
            read_retries: 2,
            scan_timeout: Duration::from_millis(50),
            watchdog_period: Duration::from_millis(20),
            poll_interval: Duration::from_millis(10),
            watchdog_on_rs232: true,
            close_bound: Duration::from_secs(5),
            start_grace: Duration::from_secs(1),
            baud: Baud::DEFAULT,
            can_bitrate: CanBitRate::DEFAULT,
        }
    }
}

/// How a guarded motion ([`Op::MoveGuarded`](super::Op::MoveGuarded), [`Op::HomeGuarded`](super::Op)) is
/// protected beyond the stop on cancellation and failure that every motion has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Guard {
    /// Arm the module's watchdog for the motion (where the link allows it: CAN, and RS232 unless
    /// [`Config::watchdog_on_rs232`] is false), so that a host that dies stops it within 50 ms; switch it
    /// off again after (that module's alone, and only if the guard switched it on). What `motionlink
    /// powercube move` and `home` do by default.
    #[default]
    Watchdog,
    /// Leave the watchdog and the Config word alone: a host that dies leaves the module moving. What
    /// `--no-watchdog` and an in-process emulator (which dies with the host) choose.
    HaltOnly,
}

impl Guard {
    /// The guard for the motions of a session whose modules are `modules`, when the user asked for
    /// `--no-watchdog` (or `watchdog=False`) if `no_watchdog`: the one rule every front end (the command line,
    /// the web console, the Python package) applies.
    ///
    /// The watchdog protects a motion against a host that dies; modules emulated in this process die with
    /// it, so they are not armed ([`Guard::HaltOnly`]), and neither are modules the user said to leave
    /// alone. Everything else is armed ([`Guard::Watchdog`]) where the link allows it (the session decides
    /// that: CAN, and RS232 unless [`Config::watchdog_on_rs232`] is false).
    pub fn for_motions(modules: ModulesAt, no_watchdog: bool) -> Guard {
        match (modules, no_watchdog) {
            (ModulesAt::Elsewhere, false) => Guard::Watchdog,
            (ModulesAt::Elsewhere, true) | (ModulesAt::ThisProcess, _) => Guard::HaltOnly,
        }
    }
}

/// Where the modules of a session are, as far as the watchdog is concerned (see [`Guard::for_motions`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModulesAt {
    /// Real modules, or an emulator served by another process (`motionlink sim`): they go on when this
    /// process dies, and their watchdog is what stops them then.
    Elsewhere,
    /// An emulator running in this process (`--port sim`, an in-process emulator object): it dies with the
    /// process, so no watchdog is needed to stop it.
    ThisProcess,
}

impl ModulesAt {
    /// [`ModulesAt::ThisProcess`] if the modules are emulated in this process (the front end started the
    /// emulator itself), [`ModulesAt::Elsewhere`] otherwise.
    pub fn emulated_in_process(in_process: bool) -> ModulesAt {
        if in_process {
            ModulesAt::ThisProcess
        } else {
            ModulesAt::Elsewhere
        }
    }

    /// Where the modules behind `url` are: `sim` is an emulator this process starts; every other port
    /// (a serial device, TCP, which may lead to a served emulator, SocketCAN, SLCAN) leads out of it.
    pub fn of_url(url: &motionlink_link::url::PortUrl) -> ModulesAt {
        ModulesAt::emulated_in_process(matches!(url, motionlink_link::url::PortUrl::Sim))
    }
}

/// A checked ramp move ([`Op::MoveTo`](super::Op::MoveTo)): where to, how fast, how close counts as
/// arrived, how long to wait.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveSpec {
    /// The target position: rad for a rotary module, m for a linear one, or the module's own unit.
    pub target: Position,
    /// Velocity to write to TargetVel first (above 0); `None` leaves the module's TargetVel as it is.
    pub vel: Option<Velocity>,
    /// Acceleration to write to TargetAcc first (above 0); `None` leaves the module's TargetAcc as it is.
    pub acc: Option<Acceleration>,
    /// The in-position tolerance: the move succeeds only if the final actual position is at most this far
    /// from the target (above 0). The manual offers no in-position window parameter, so this is the
    /// caller's; `None` is [`MoveSpec::DEFAULT_TOLERANCE`]; at most [`MoveSpec::MAX_TOLERANCE`].
    pub tolerance: Option<Position>,
    /// How long to wait for the end of the ramp before halting it.
    pub timeout: Duration,
}

impl MoveSpec {
    /// The default in-position tolerance: 0.001 rad (0.057°) on a rotary module, 1 mm on a linear one.
    pub const DEFAULT_TOLERANCE: Position = Position::native(0.001);

    /// The largest in-position tolerance a move takes: 0.1 rad (5.7°) or 0.1 m. A wider window would count
    /// almost any end of the ramp as arrived, which is no check at all.
    pub const MAX_TOLERANCE: Position = Position::native(0.1);

    /// A move to `target` with the module's own TargetVel and TargetAcc, the default tolerance, and 60 s to
    /// get there.
    pub fn to(target: Position) -> MoveSpec {
        MoveSpec { target, vel: None, acc: None, tolerance: None, timeout: Duration::from_secs(60) }
    }

    /// The tolerance in force.
    pub fn tolerance(&self) -> Position {
        self.tolerance.unwrap_or(Self::DEFAULT_TOLERANCE)
    }

    /// Checks that every number makes sense (the rules of [`crate::args`]: a finite target; velocity,
    /// acceleration and tolerance above 0, the tolerance at most [`MoveSpec::MAX_TOLERANCE`]; a timeout
    /// above 0) and that the units agree with each other (rad and m are not mixed).
    pub fn validate(&self) -> Result<(), Error> {
        use crate::args::{MoveAcceleration, MoveVelocity, Target, Tolerance};
        Target::new(f64::from(self.target.value()))?;
        if let Some(v) = self.vel {
            MoveVelocity::new(f64::from(v.value()))?;
        }
        if let Some(a) = self.acc {
            MoveAcceleration::new(f64::from(a.value()))?;
        }
        Tolerance::new(f64::from(self.tolerance().value()))?;
        if self.timeout.is_zero() {
            return Err(Error::InvalidArgument {
                what: "the timeout",
                must: "a number of seconds above 0",
                value: format!("{:?}", self.timeout),
            });
        }
        let units = [
            Some(self.target.unit()),
            self.vel.map(|v| v.unit()),
            self.acc.map(|a| a.unit()),
            Some(self.tolerance().unit()),
        ];
        let said: Vec<AxisUnit> = units.into_iter().flatten().filter(|u| *u != AxisUnit::ModuleUnit).collect();
        if said.windows(2).any(|w| w[0] != w[1]) {
            return Err(Error::InvalidArgument {
                what: "the move's quantities",
                must: "all in rad or all in m",
                value: format!("{self:?}"),
            });
        }
        Ok(())
    }
}

/// How long [`Op::HaltConfirmed`](super::Op::HaltConfirmed) reads the state after the Halt for STATE_MOTION
/// to clear. The manual's Halt stops "at once"; this leaves a module room for a short braking.
pub const HALT_SETTLE: Duration = Duration::from_millis(500);

/// What a confirmed halt ([`Op::HaltConfirmed`](super::Op::HaltConfirmed)) found: the module acknowledged
/// the Halt, and then its state showed no STATE_MOTION.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HaltReport {
    /// Rotary or linear: the unit of `position` (read after the Halt, never before it).
    pub kind: ModuleKind,
    /// The state word read after the Halt (STATE_HALTED set, STATE_MOTION clear).
    pub state: CubeState,
    /// The actual position then (ActPos, in the unit of `kind`).
    pub position: Position,
}

/// What a checked move ([`Op::MoveTo`](super::Op::MoveTo)) did.
#[derive(Debug, Clone, PartialEq)]
pub struct MoveReport {
    /// Rotary or linear: the unit of every position here (read before the move).
    pub kind: ModuleKind,
    /// The target asked for.
    pub target: Position,
    /// Where the module stood before.
    pub start: Position,
    /// The final actual position, read from the module after the ramp ended (twice, both within the
    /// tolerance of the target).
    pub reached: Position,
    /// The state word at the end.
    pub state: CubeState,
    /// True when every check of what the module took could be made: the velocity and acceleration written
    /// read back through their Inc twins, and the motion's target through TargetPosInc. (The final position
    /// is always checked: a move that did not end within the tolerance is an error, never a report.)
    pub verified: bool,
    /// What could not be checked, and why, in plain words (empty when `verified`): on a module that keeps
    /// the Inc twins apart from the float targets, or where a twin already held the value, so that reading
    /// it proves nothing.
    pub not_verifiable: Vec<String>,
}

impl MoveReport {
    /// True when the module showed STATE_HOME_OK at the end. A module not homed has the coordinates it took
    /// at power-on (its position then reads DefHomeOffset wherever the axis stands), and its MinPos/MaxPos,
    /// which the target was checked against, hold only after homing (manual 8: "Run motion commands only
    /// after a successful homing"); [`MoveReport::not_homed_note`] says so.
    pub fn homed(&self) -> bool {
        self.state.contains(crate::model::StateFlag::HomeOk)
    }

    /// What a move of a module not homed means, in plain words (`None` when it is homed).
    pub fn not_homed_note(&self) -> Option<&'static str> {
        not_homed_note(self.state)
    }
}

/// What a motion of a module that ended in `state` means when the module is not homed (`None` when it is):
/// the one text of [`MoveReport::not_homed_note`] and [`MotionReport::not_homed_note`].
fn not_homed_note(state: CubeState) -> Option<&'static str> {
    (!state.contains(StateFlag::HomeOk)).then_some(
        "the module is not homed (STATE_HOME_OK clear): its position is in the coordinates it took at \
         power-on, and MinPos/MaxPos, which the target was checked against, hold only after homing (the \
         manual: run motion commands only after a successful homing, else only at slow speed)",
    )
}

/// A motion command of any mode ([`Op::RunMotion`](super::Op::RunMotion)), run to its end and checked: the
/// position modes (FRAMP, FSTEP, IRAMP, ISTEP and their `_ACK` forms) to their target, the continuous ones
/// (velocity, current, FCOSLOOP, FRAMPLOOP) for [`MotionSpec::hold`] and then ended.
///
/// ```
/// use std::time::Duration;
/// use motionlink_powercube::model::{AxisUnit, Motion, MotionId, Velocity};
/// use motionlink_powercube::session::MotionSpec;
///
/// // FVEL at 0.2 rad/s for 2 s, then velocity 0 and the wait for rest.
/// let spec = MotionSpec {
///     hold: Some(Duration::from_secs(2)),
///     ..MotionSpec::new(Motion::FVel { vel: Velocity::rad_per_s(0.2) })
/// };
/// assert!(spec.continuous() && spec.validate().is_ok());
///
/// // FSTEP_ACK from its name and numbers: 0.5 in 800 ms, the extended acknowledge asked for.
/// let id = MotionId::parse("fstep_ack").unwrap();
/// let (motion, ack) = Motion::from_id(id, 0.5, Some(800), AxisUnit::ModuleUnit).unwrap();
/// let step = MotionSpec { ack, ..MotionSpec::new(motion) };
/// assert!(!step.continuous() && step.validate().is_ok());
/// // A position mode ends at its target: a hold is refused.
/// let held = MotionSpec { hold: Some(Duration::from_secs(1)), ..step };
/// assert!(held.validate().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionSpec {
    /// The mode and its numbers.
    pub motion: Motion,
    /// [`AckKind::Simple`], or [`AckKind::Extended`] for the `_ACK` MotionIDs (the loops have none).
    pub ack: AckKind,
    /// Continuous modes (velocity, current, the loops): how long the motion runs before it is ended;
    /// `None`: until the operation is cancelled (which halts it, as every motion). Must be `None` for the
    /// position modes ([`Error::InvalidArgument`] otherwise).
    pub hold: Option<Duration>,
    /// Position modes: how close the module must end to the target (above 0, at most
    /// [`MoveSpec::MAX_TOLERANCE`]); `None` is [`MoveSpec::DEFAULT_TOLERANCE`]. Must be `None` for the
    /// continuous modes, which have no target to be within.
    pub tolerance: Option<Position>,
    /// Position modes: how long the module may take to come to rest at its target; velocity modes: how
    /// long the stop from the velocity 0 sent after the hold may take. A wait that runs out halts the
    /// module. 60 s by [`MotionSpec::new`].
    pub timeout: Duration,
}

impl MotionSpec {
    /// `motion` with the simple acknowledge, no hold (a continuous mode runs until cancelled), the default
    /// tolerance and 60 s.
    pub fn new(motion: Motion) -> MotionSpec {
        MotionSpec { motion, ack: AckKind::Simple, hold: None, tolerance: None, timeout: Duration::from_secs(60) }
    }

    /// True for a mode that runs until it is ended (velocity, current, the loops; [`MotionId::continuous`]).
    pub fn continuous(&self) -> bool {
        self.motion.continuous()
    }

    /// The MotionID sent: the mode with the acknowledge asked for (`None` for a loop with an extended one).
    pub fn id(&self) -> Option<MotionId> {
        self.motion.id(self.ack)
    }

    /// The tolerance in force (position modes).
    pub fn tolerance(&self) -> Position {
        self.tolerance.unwrap_or(MoveSpec::DEFAULT_TOLERANCE)
    }

    /// Checks what can be checked without the module: the mode has the acknowledge asked for; its numbers
    /// are finite; a time (FSTEP, ISTEP, FCOSLOOP) above 0 ms; ICUR within -500..500 digits
    /// ([`RAW_CUR_MAX`]); a hold only for a continuous mode and above 0; a tolerance only for a position
    /// mode, above 0 and at most [`MoveSpec::MAX_TOLERANCE`]; a timeout above 0; rad and m not mixed.
    pub fn validate(&self) -> Result<(), Error> {
        let refused =
            |what: &'static str, must: &'static str, value: String| Error::InvalidArgument { what, must, value };
        let number = match self.motion {
            Motion::FRamp { pos } | Motion::FStep { pos, .. } => Some(("the target position", pos.value())),
            Motion::FCosLoop { pos, .. } | Motion::FRampLoop { pos } => Some(("the loop's far end", pos.value())),
            Motion::FVel { vel } => Some(("the velocity", vel.value())),
            Motion::FCur { cur } => Some(("the current", cur.0)),
            _ => None,
        };
        if let Some((what, v)) = number.filter(|(_, v)| !v.is_finite()) {
            return Err(refused(what, "a finite number", v.to_string()));
        }
        // The mode has the acknowledge asked for (the loops have no `_ACK` form).
        Request::motion(self.motion, self.ack)?;
        let time = match self.motion {
            Motion::FStep { time, .. } => Some(("the time of FSTEP_MODE", time)),
            Motion::IStep { time, .. } => Some(("the time of ISTEP_MODE", time)),
            Motion::FCosLoop { time, .. } => Some(("the period of FCOSLOOP", time)),
            _ => None,
        };
        if let Some((what, _)) = time.filter(|(_, t)| t.0 == 0) {
            return Err(refused(what, "above 0 ms (a motion in no time cannot be done)", "0 ms".into()));
        }
        if let Motion::ICur { cur } = self.motion {
            if !(-RAW_CUR_MAX..=RAW_CUR_MAX).contains(&cur.0) {
                return Err(refused(
                    "the current of ICUR_MODE",
                    "within -500..500 digits (the commanded current's range, manual 7.2)",
                    format!("{} digits", cur.0),
                ));
            }
        }
        match (self.continuous(), self.hold) {
            (false, Some(hold)) => {
                return Err(refused(
                    "the hold",
                    "none for a position mode (FRAMP, FSTEP, IRAMP, ISTEP end at their target; a hold is for the \
                     velocity, current and loop modes)",
                    format!("{hold:?}"),
                ))
            }
            (true, Some(hold)) if hold.is_zero() => {
                return Err(refused("the hold", "above 0 (none: until the operation is cancelled)", "0 s".into()))
            }
            _ => {}
        }
        if let Some(tolerance) = self.tolerance {
            if self.continuous() {
                return Err(refused(
                    "the tolerance",
                    "none for a continuous mode (velocity, current and the loops have no target to end within)",
                    tolerance.to_string(),
                ));
            }
            crate::args::Tolerance::new(f64::from(tolerance.value()))?;
        }
        if self.timeout.is_zero() {
            return Err(refused("the timeout", "a number of seconds above 0", format!("{:?}", self.timeout)));
        }
        let position = match self.motion {
            Motion::FRamp { pos } | Motion::FStep { pos, .. } => Some(pos.unit()),
            _ => None,
        };
        let said: Vec<AxisUnit> = [position, self.tolerance.map(|t| t.unit())]
            .into_iter()
            .flatten()
            .filter(|u| *u != AxisUnit::ModuleUnit)
            .collect();
        if said.windows(2).any(|w| w[0] != w[1]) {
            return Err(refused("the motion's quantities", "all in rad or all in m", format!("{self:?}")));
        }
        Ok(())
    }
}

/// How a motion run by [`Op::RunMotion`](super::Op::RunMotion) ended. Serialises as `"reached"`,
/// `"velocity_zero"` or `"halted"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionEnding {
    /// A position mode: at rest within the tolerance of its target.
    Reached,
    /// A velocity mode after its hold: the same mode with velocity 0 was sent and the module came to rest.
    VelocityZero,
    /// A current or loop mode after its hold: Halt, confirmed by the state read back (the module takes no
    /// motion command until a reset).
    Halted,
}

/// How the motion ended, in words: "reached", "ended with velocity 0, at rest", "halted (it takes no motion
/// until reset)".
impl std::fmt::Display for MotionEnding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            MotionEnding::Reached => "reached",
            MotionEnding::VelocityZero => "ended with velocity 0, at rest",
            MotionEnding::Halted => "halted (it takes no motion until reset)",
        })
    }
}

/// What a motion run by [`Op::RunMotion`](super::Op::RunMotion) did.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionReport {
    /// Rotary or linear: the unit of every position here (read before the motion).
    pub kind: ModuleKind,
    /// The MotionID sent.
    pub mode: MotionId,
    /// Where the module stood before the command (read).
    pub start: Position,
    /// Position modes: the target (IRAMP / ISTEP targets converted from ticks with the module's IncRatio).
    pub target: Option<Position>,
    /// Where the module came to rest at the end (read back; for a position mode twice, both within the
    /// tolerance of the target).
    pub reached: Position,
    /// Continuous modes: how long the motion ran, from its command to the one that ended it.
    pub held: Option<Duration>,
    /// How it ended.
    pub ending: MotionEnding,
    /// The extended acknowledge of the motion command, when one was asked for and given (a firmware before
    /// PowerCube-OS 2.5.16 / 3.5.13 answers with the simple one: `None`).
    pub ext_ack: Option<ExtAck>,
    /// The state word at the end.
    pub state: CubeState,
    /// True when every check of what the module took could be made (see `not_verifiable`). The end is
    /// always checked: a position mode that did not end within the tolerance, a velocity that did not come
    /// to rest, a halt not confirmed is an error, never a report.
    pub verified: bool,
    /// What could not be checked, and why, in plain words (empty when `verified`): a target the module
    /// gives no way to read back, the value of a velocity or current command (the manual has no parameter
    /// that shows it), what a guard could not do.
    pub not_verifiable: Vec<String>,
}

impl MotionReport {
    /// True when the module showed STATE_HOME_OK at the end (see [`MoveReport::homed`]).
    pub fn homed(&self) -> bool {
        self.state.contains(StateFlag::HomeOk)
    }

    /// What a motion of a module not homed means, in plain words (`None` when it is homed); the text of
    /// [`MoveReport::not_homed_note`].
    pub fn not_homed_note(&self) -> Option<&'static str> {
        not_homed_note(self.state)
    }
}

/// What a streamed setpoint ([`Op::Setpoint`](super::Op::Setpoint)) did: the command was acknowledged; with
/// an `_ACK` mode, where the module stood then. Serialises as `{mode, ext_ack, watchdog}` (`ext_ack` only
/// when one came).
#[derive(Debug, Clone, PartialEq)]
pub struct SetpointReport {
    /// Rotary or linear: the unit of a float position in `ext_ack`.
    pub kind: ModuleKind,
    /// The MotionID sent.
    pub mode: MotionId,
    /// The extended acknowledge: the module's position (rad or m for the float modes, encoder ticks for
    /// the I modes), short state and DIO when it took the command. `None` for the simple acknowledge, or
    /// when a firmware before PowerCube-OS 2.5.16 / 3.5.13 answered an `_ACK` MotionID with the simple one.
    pub ext_ack: Option<ExtAck>,
    /// True when the module's watchdog is armed and refreshed by this session ([`Guard::Watchdog`] on a
    /// link that allows it, or an earlier [`Op::EnableWatchdog`](super::Op::EnableWatchdog)): a host that
    /// dies stops the module within 50 ms.
    pub watchdog: bool,
}

/// What homing ([`Op::HomeAndWait`](super::Op::HomeAndWait), [`Op::HomeGuarded`](super::Op::HomeGuarded))
/// did: the module showed STATE_HOME_OK and stood still.
#[derive(Debug, Clone, PartialEq)]
pub struct HomeReport {
    /// Rotary or linear: the unit of `reached` (read before homing).
    pub kind: ModuleKind,
    /// The actual position after homing.
    pub reached: Position,
    /// The state word at the end.
    pub state: CubeState,
    /// True when homing ran as it was asked to: under a [`Guard::Watchdog`] that could not arm the
    /// module's watchdog, false.
    pub verified: bool,
    /// What the guard could not do, and why, in plain words (empty when `verified`): a module that ignores
    /// the RS232 broadcast refresh homes without its watchdog.
    pub not_verifiable: Vec<String>,
}

/// How a parameter written with [`Op::SetChecked`](super::Op::SetChecked) was verified.
#[derive(Debug, Clone, PartialEq)]
pub struct Readback {
    /// The value read back and found as written: the parameter itself, or for the write-only TargetPos /
    /// TargetVel / TargetAcc their encoder-tick twin ([`Param::read_back_as`](crate::model::Param::read_back_as)),
    /// as read (ticks for a twin: [`Param::from_read_back_ticks`](crate::model::Param::from_read_back_ticks)
    /// converts it into the written parameter's unit). `None` when nothing could be read back that shows
    /// the value written.
    pub read: Option<Value>,
    /// For TargetPos / TargetVel / TargetAcc read back through their tick twin: the ticks read, in the
    /// written parameter's own unit (ticks / IncRatio, [`Param::from_read_back_ticks`](crate::model::Param::from_read_back_ticks)).
    /// `None` otherwise (`read` is then in the parameter's unit already).
    pub read_in_unit: Option<f64>,
    /// True when the value was read back and found as written.
    pub verified: bool,
    /// Why the value could not be verified, in plain words (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

impl Readback {
    /// Read back and found as written.
    pub fn same(read: Value) -> Readback {
        Readback { read: Some(read), read_in_unit: None, verified: true, not_verifiable: Vec::new() }
    }

    /// Not verifiable, for the reason given.
    pub fn unverified(why: impl Into<String>) -> Readback {
        Readback { read: None, read_in_unit: None, verified: false, not_verifiable: vec![why.into()] }
    }
}

/// What a session has established about one module where the manual is silent: each found by a harmless
/// probe the first time a check depends on it, and remembered for the session ([`Session::findings`](super::Session::findings)).
/// `None`: not established (yet). A device profile (`motionlink probe --save`, [`crate::probe`]) keeps them, and
/// [`Session::seed_findings`](super::Session::seed_findings) gives them to a later session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModuleFindings {
    /// TargetPosInc follows the target written as TargetPos or sent in a float motion command (`true`), or
    /// the module keeps it apart (`false`).
    pub target_pos_twin: Option<bool>,
    /// TargetVelInc follows TargetVel.
    pub target_vel_twin: Option<bool>,
    /// TargetAccInc follows TargetAcc.
    pub target_acc_twin: Option<bool>,
    /// The module answers GetExtended of ActFPosStateDio (0x62); without it, waits poll CubeState and
    /// ActPos.
    pub pos_state_dio: Option<bool>,
    /// On RS232: the module takes the broadcast watchdog refresh at address 0 in libm5api's two-byte form
    /// (its watchdog, armed and refreshed, stayed online past the 50 ms it waits).
    pub rs232_broadcast: Option<bool>,
}

impl ModuleFindings {
    /// These, with every finding `self` has not established taken from `known` (what was established stays).
    pub fn or(self, known: ModuleFindings) -> ModuleFindings {
        ModuleFindings {
            target_pos_twin: self.target_pos_twin.or(known.target_pos_twin),
            target_vel_twin: self.target_vel_twin.or(known.target_vel_twin),
            target_acc_twin: self.target_acc_twin.or(known.target_acc_twin),
            pos_state_dio: self.pos_state_dio.or(known.pos_state_dio),
            rs232_broadcast: self.rs232_broadcast.or(known.rs232_broadcast),
        }
    }

    /// The finding about the Inc twin of `param` (TargetPos, TargetVel, TargetAcc), if it has one.
    pub fn twin(&self, param: Param) -> Option<bool> {
        match param {
            Param::TargetPos => self.target_pos_twin,
            Param::TargetVel => self.target_vel_twin,
            Param::TargetAcc => self.target_acc_twin,
            _ => None,
        }
    }

    pub(crate) fn twin_mut(&mut self, param: Param) -> Option<&mut Option<bool>> {
        match param {
            Param::TargetPos => Some(&mut self.target_pos_twin),
            Param::TargetVel => Some(&mut self.target_vel_twin),
            Param::TargetAcc => Some(&mut self.target_acc_twin),
            _ => None,
        }
    }
}

/// What a wait waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Until {
    /// The end of homing: STATE_HOME_OK, not moving.
    Home,
    /// The module at rest: no STATE_MOTION.
    Motion,
    /// The end of a ramp: STATE_RAMP_END, not moving.
    Ramp,
}

impl Until {
    /// What is waited for, in words.
    pub fn what(self) -> &'static str {
        match self {
            Until::Home => "the end of homing",
            Until::Motion => "the end of the motion",
            Until::Ramp => "the end of the ramp",
        }
    }

    /// True when `s` shows it.
    pub fn reached(self, s: CubeState) -> bool {
        !s.contains(StateFlag::Motion)
            && match self {
                Until::Home => s.contains(StateFlag::HomeOk),
                Until::Motion => true,
                Until::Ramp => s.contains(StateFlag::RampEnd),
            }
    }
}

/// A motion a wait waits for the end of, started by this operation ([`Config::start_grace`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Begun {
    /// When its command was sent.
    pub at: motionlink_link::Timestamp,
    /// Where it goes and the tolerance, in the module's unit, where known: a module already there has
    /// nothing to show.
    pub target: Option<(f32, f32)>,
}

/// One poll while waiting for homing or a motion: position and state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// The module.
    pub address: Address,
    /// Its position (rad or m where the session knows the module's kind).
    pub position: Position,
    /// Its state: the last state word read. In the middle of a motion a wait reads it in full at least
    /// every 100 ms and whenever the short state that comes with every position (ActFPosStateDio)
    /// changes; between those reads the flags the short state carries (motion, ramp end, switches, not
    /// ok) are as read now, the others (such as the ramp phase STATE_RAMP_ACC / STEADY / DEC) are those
    /// of the last full read, at most 100 ms old.
    pub state: CubeState,
    /// Time waited so far.
    pub elapsed: Duration,
}

/// What a scan finds at one address.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModuleInfo {
    /// The address.
    pub address: Address,
    /// Rotary or linear (from the Config word).
    pub kind: ModuleKind,
    /// Firmware version.
    pub version: CubeVersion,
    /// Serial number.
    pub serial: u32,
    /// The state word.
    pub state: CubeState,
}

/// One module a scan found: its address, and its type, version, serial number and state, or the error that
/// kept the session from reading them (the module answered the scan, so it is there; the rest of the scan
/// goes on without it).
#[derive(Debug)]
pub struct ScanEntry {
    /// The address that answered.
    pub address: Address,
    /// What was read, or why it could not be (also a scan answer that stayed corrupt on every retry).
    pub info: Result<ModuleInfo, Error>,
}
