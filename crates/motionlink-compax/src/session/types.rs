//! What a session is configured with, what it can be asked to do ([`Op`]), and what it answers
//! ([`Output`], [`Progress`]).

use std::ops::RangeInclusive;
use std::time::Duration;

use motionlink_link::link::char_time;

use crate::error::{Error, Result, StopReport};
use crate::model::{Command, CommandStyle, ModelError, ParamId, Position, S16Bits, S17Bits, StatusId, StatusValue};
use crate::wire::{Address, Mode};

/// The default of [`Config::in_position_tolerance`], in the drive's position unit.
pub const DEFAULT_IN_POSITION_TOLERANCE: f64 = 0.01;

/// How a session talks to the bus.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// P196 of the drives (they must all have the same).
    pub mode: Mode,
    /// P195 of the drives, bit/s (it sets the wire time the timeouts allow for).
    pub baud_rate: u32,
    /// Time a drive may take to start answering, on top of the wire time of request and reply. The manual
    /// gives none; 200 ms by default.
    pub reply_timeout: Duration,
    /// How often a telegram is sent again after E70, E72, E73, a timeout or a corrupt reply (idempotent
    /// commands).
    pub retries: u32,
    /// Silence after a broadcast before the next telegram (nobody answers a broadcast); 20 ms by default.
    pub broadcast_gap: Duration,
    /// Interval of status polls while waiting for a position (S17, and S1 for progress): a poll starts
    /// every `poll_interval`, counted from the start of the previous one (when a poll takes longer than
    /// that, as at 9600 baud with a short interval, the next one starts at once, never several to catch
    /// up). 50 ms by default: at 9600 baud the two reads of one poll take about 40 ms of line time.
    pub poll_interval: Duration,
    /// While a wait listens for `$` messages, how often it still reads each drive's state (a `$` may be lost
    /// to a line error, or the axis stopped by someone else, and then none comes); 1 s by default.
    pub message_check_interval: Duration,
    /// How long a wait for a position lasts when it is given no timeout; 600 s by default.
    pub wait_timeout: Duration,
    /// Long or short command names.
    pub style: CommandStyle,
    /// How far from its target an axis may come to rest for a move to count as done (a checked move), and
    /// how far the target a drive reports (S2) may be from the one sent. The manuals give no position
    /// window for the ASCII protocol; 0.01 by default (the user guide gives positions two decimals in mm).
    pub in_position_tolerance: Position,
    /// The longest closing the session (an explicit close, or dropping the client) waits for the stop of
    /// what it set in motion; 5 s by default. On a dead line one drive's stop takes about 1.3 s at 9600
    /// baud (an S17 read without retries, then `OUTPUT O0=0` with its retries).
    pub close_bound: Duration,
    /// The longest the driver reads the line in one go while an operation listens: a cancellation is seen
    /// within this time. 5 ms by default.
    pub read_slice: Duration,
}

impl Config {
    /// Defaults for drives with mode `mode` at `baud_rate`.
    pub fn new(mode: Mode, baud_rate: u32) -> Self {
        Config {
            mode,
            baud_rate,
            reply_timeout: Duration::from_millis(200),
            retries: 3,
            broadcast_gap: Duration::from_millis(20),
            poll_interval: Duration::from_millis(50),
            message_check_interval: Duration::from_secs(1),
            wait_timeout: Duration::from_secs(600),
            style: CommandStyle::Long,
            in_position_tolerance: Position::from_units_unchecked(DEFAULT_IN_POSITION_TOLERANCE),
            close_bound: Duration::from_secs(5),
            read_slice: Duration::from_millis(5),
        }
    }

    /// The time of one character on the line.
    pub fn char_time(&self) -> Duration {
        char_time(self.baud_rate, self.mode.parity)
    }
}

/// How a move is sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MoveOptions {
    /// Send the binary form (no ASCII conversion in the drive).
    pub binary: bool,
    /// Append `$`: the drive sends the position-reached message (ASCII only).
    pub message: bool,
}

/// Where a move goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoveTarget {
    /// To this position (POSA).
    Absolute(Position),
    /// By this distance from the drive's current target S2 (POSR).
    Relative(Position),
}

impl MoveTarget {
    /// What a move must be told: give the target one way, absolute or relative.
    pub const RULE: &'static str = "give the target: POSITION (the same as --abs POSITION) or --rel DISTANCE";

    /// The target of a move's arguments: an absolute position (`move 100`, `--abs 100`) or a distance
    /// (`--rel 5`), exactly one of them; the error says which mistake was made (neither, or both).
    ///
    /// ```
    /// use motionlink_compax::model::Position;
    /// use motionlink_compax::session::MoveTarget;
    /// let p = |u| Some(Position::new(u).unwrap());
    /// assert!(matches!(MoveTarget::from_args(p(10.0), None), Ok(MoveTarget::Absolute(_))));
    /// assert!(MoveTarget::from_args(p(10.0), p(5.0)).unwrap_err().starts_with("both a target position and"));
    /// assert_eq!(MoveTarget::from_args(None, None).unwrap_err(), MoveTarget::RULE);
    /// ```
    pub fn from_args(absolute: Option<Position>, relative: Option<Position>) -> Result<MoveTarget, &'static str> {
        match (absolute, relative) {
            (Some(a), None) => Ok(MoveTarget::Absolute(a)),
            (None, Some(r)) => Ok(MoveTarget::Relative(r)),
            (Some(_), Some(_)) => Err("both a target position and a relative distance were given: give one of them"),
            (None, None) => Err(Self::RULE),
        }
    }
}

/// Travel limits the caller knows for an axis (the drive's own limits are not in the RS485 manual, and
/// the session does not read them): a target outside them is refused before anything moves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TravelLimits {
    /// The lowest target allowed.
    pub min: Option<Position>,
    /// The highest target allowed.
    pub max: Option<Position>,
}

impl TravelLimits {
    /// Limits; refused when `min` is above `max`.
    pub fn new(min: Option<Position>, max: Option<Position>) -> Result<Self, ModelError> {
        if let (Some(lo), Some(hi)) = (min, max) {
            if lo.units() > hi.units() {
                return Err(ModelError::Range {
                    what: "travel limits",
                    value: format!("minimum {lo} above maximum {hi}"),
                    range: "minimum at most the maximum",
                });
            }
        }
        Ok(TravelLimits { min, max })
    }

    /// `target` for `address` inside the limits, or [`Error::OutsideLimits`].
    pub fn check(&self, address: Address, target: Position) -> Result<()> {
        let t = target.units();
        let outside = |side, limit: Position| Error::OutsideLimits { address, target, side, limit };
        match (self.min, self.max) {
            (Some(lo), _) if t < lo.units() => Err(outside("below the minimum", lo)),
            (_, Some(hi)) if t > hi.units() => Err(outside("above the maximum", hi)),
            _ => Ok(()),
        }
    }
}

/// A checked move: checked, stored with its echo and executed once the echo matches, read back, waited
/// for, verified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveRequest {
    /// Where to.
    pub target: MoveTarget,
    /// SPEED for this move (the drive's current setting if `None`).
    pub speed: Option<crate::model::SpeedPercent>,
    /// ACCEL for this move (the drive's current setting if `None`).
    pub accel: Option<crate::model::RampMs>,
    /// Send the binary forms (which take no `,?`: the move is then checked by S2 after the start only).
    pub binary: bool,
    /// Targets outside these are refused before anything is sent.
    pub limits: TravelLimits,
    /// How long the wait may take ([`Config::wait_timeout`] if `None`); then the axis is stopped.
    pub timeout: Option<Duration>,
}

impl MoveRequest {
    /// A move to `target` with the drive's current settings, no limits and the default timeout.
    pub fn new(target: MoveTarget) -> Self {
        MoveRequest { target, speed: None, accel: None, binary: false, limits: TravelLimits::default(), timeout: None }
    }
}

/// A move the drive has taken, with its target confirmed by S2.
#[derive(Debug, Clone, PartialEq)]
pub struct StartedMove {
    /// The drive.
    pub address: Address,
    /// S1 before the move.
    pub start: Position,
    /// The absolute target (for a relative move: S2 before it plus the distance, as the drive computes it).
    pub target: Position,
    /// What could not be checked before the move started, in plain words: what the echo of the stored move
    /// could not show on this drive (see [`EchoForm::unchecked`]), or that the move went out unechoed (a
    /// drive that does not echo, or does not store a command sent with `,?`; a binary move,
    /// [`EchoForm::binary_unchecked`]); empty when the echo checked everything it checks on a drive that
    /// echoes in full.
    pub not_verifiable: Vec<String>,
}

/// A move that ended at its target.
#[derive(Debug, Clone, PartialEq)]
pub struct MoveReport {
    /// The drive.
    pub address: Address,
    /// S1 before the move.
    pub start: Position,
    /// The target.
    pub target: Position,
    /// S1 at rest afterwards (within [`MoveReport::tolerance`] of the target).
    pub reached: Position,
    /// The in-position tolerance the position at rest was checked against
    /// ([`Config::in_position_tolerance`]).
    pub tolerance: Position,
    /// True when every check of what the drive took could be made: the echo of the stored move showed the
    /// address, the command and the flags sent (an ASCII move), and S2 the target. (The position at rest is
    /// always checked: a move that did not end within the tolerance is an error, never a report.)
    pub verified: bool,
    /// What could not be checked, and why, in plain words (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

/// How a drive echoes a telegram sent with `?`: the manual says only that it "will send the received data
/// back in full". Found per drive by a harmless probe (S1 sent with `?`, which the drive does not execute)
/// the first time a move is stored with its echo, and remembered for the session
/// ([`Session::echo_form`](super::Session::echo_form)). The forms below are the telegram as received
/// (everything before its CR) with or without the address digits and with or without the flag
/// characters; the command text itself must always come back exactly as sent. A device profile
/// (`motionlink probe --save`, [`crate::probe`]) keeps it as `full`, `without_address`, `without_flags`,
/// `bare` or `none`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EchoForm {
    /// `1S1?`: address, command and flags (what the emulator sends by default).
    Full,
    /// `S1?`: without the address digits.
    WithoutAddress,
    /// `1S1`: without the flag characters.
    WithoutFlags,
    /// `S1`: the command alone.
    Bare,
    /// No echo: the drive refused `?` or stayed silent, twice, answering a plain read in between. Moves are
    /// then sent as commands of their own (the manual's plain form), checked by S2 after the start only. (A
    /// drive that answers the read instead of echoing it is refused: it would take `,?` for something else.)
    None,
}

impl EchoForm {
    /// The echo a drive of this form sends for a telegram of `digits` (the address as sent), `command` and
    /// `flags` (the flag characters as sent); `None` for [`EchoForm::None`].
    pub fn render(self, digits: &[u8], command: &[u8], flags: &[u8]) -> Option<Vec<u8>> {
        let (address, flags) = match self {
            EchoForm::Full => (digits, flags),
            EchoForm::WithoutAddress => (&[][..], flags),
            EchoForm::WithoutFlags => (digits, &[][..]),
            EchoForm::Bare => (&[][..], &[][..]),
            EchoForm::None => return None,
        };
        Some([address, command, flags].concat())
    }

    /// The form in words: how the drive sends a telegram back.
    pub fn described(self) -> &'static str {
        match self {
            EchoForm::Full => "in full",
            EchoForm::WithoutAddress => "without its address digits",
            EchoForm::WithoutFlags => "without its flag characters",
            EchoForm::Bare => "as the command alone (no address digits, no flag characters)",
            EchoForm::None => "not at all",
        }
    }

    /// The form `echo` is in, for that telegram; `None` when it is in none (another command text).
    pub fn of(echo: &[u8], digits: &[u8], command: &[u8], flags: &[u8]) -> Option<EchoForm> {
        [EchoForm::Full, EchoForm::WithoutAddress, EchoForm::WithoutFlags, EchoForm::Bare]
            .into_iter()
            .find(|f| f.render(digits, command, flags).as_deref() == Some(echo))
    }

    /// What an echo of this form cannot show for `drive`, in plain words; `prefixed` when every reply
    /// starts with the drive's address (P196 has 64), which names the drive that echoed.
    pub fn unchecked(self, drive: Address, prefixed: bool) -> Vec<String> {
        let address = !prefixed && matches!(self, EchoForm::WithoutAddress | EchoForm::Bare);
        let flags = matches!(self, EchoForm::WithoutFlags | EchoForm::Bare);
        let mut why = Vec::new();
        if address {
            why.push(format!(
                "drive {drive} echoes without its address, and replies carry none (P196 without 64): that the \
                 drive which stored the move is the one addressed could not be checked"
            ));
        }
        if flags {
            why.push(format!(
                "drive {drive} echoes without the flag characters: that it stored the move (the ',' sent) \
                 rather than only echoing it could not be checked before '!'"
            ));
        }
        if self == EchoForm::None {
            why.push(format!(
                "drive {drive} does not echo a telegram sent with '?': the move was sent without being checked \
                 before it started (its target was read back after, from S2)"
            ));
        }
        why
    }

    /// What a binary move (which takes no flags, manual 4.4: no store, no echo) to `drive` could not show,
    /// in the terms of [`EchoForm::unchecked`].
    pub fn binary_unchecked(drive: Address) -> String {
        format!(
            "the move to drive {drive} was sent in binary, which takes no echo (manual 4.4): it was sent without \
             being checked before it started (its target was read back after, from S2)"
        )
    }
}

impl MoveReport {
    /// `reached - target`, in the drive's position unit.
    pub fn difference(&self) -> f64 {
        self.reached.units() - self.target.units()
    }
}

/// What to do with a motion that a raw command started ([`Op::RawMotion`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AfterRaw {
    /// Hand it over: the session forgets it, it runs on (nothing stops it).
    HandOver,
    /// Wait until it has ended (at most this long; then it is stopped).
    Wait(Duration),
}

/// What a raw command did ([`Op::RawMotion`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawOutcome {
    /// The reply text (empty for an acknowledgement), `None` when none was due.
    pub reply: Option<String>,
    /// The drives the command set in motion.
    pub started: Vec<Address>,
    /// True if the session waited for them to end.
    pub waited: bool,
}

/// One reading of [`Op::Watch`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WatchSample {
    /// The drive.
    pub drive: Address,
    /// S1.
    pub position: Position,
    /// S17.
    pub s17: S17Bits,
    /// S1 changed by more than the in-position tolerance since the watch's previous sample (false for its
    /// first): the drive moves, whatever S17 shows (a drive whose S17 does not show its positioning, or one
    /// moved by other means: an input, a program of its own).
    pub s1_moved: bool,
}

impl WatchSample {
    /// The sample of `drive` at `position` with `s17`, after the watch's `previous` position (`None` for
    /// its first sample), with the in-position `tolerance` of the session.
    pub fn after(
        previous: Option<Position>,
        drive: Address,
        position: Position,
        s17: S17Bits,
        tolerance: Position,
    ) -> Self {
        WatchSample { drive, position, s17, s1_moved: Self::s1_moved(previous, position, tolerance) }
    }

    /// Whether S1 went from `previous` (`None`: no earlier reading) to `now` by more than the in-position
    /// `tolerance`: the drive moves, whatever S17 shows. The rule of [`WatchSample::s1_moved`], for any
    /// live view that reads S1 again.
    pub fn s1_moved(previous: Option<Position>, now: Position, tolerance: Position) -> bool {
        previous.is_some_and(|p| (now.units() - p.units()).abs() > tolerance.units().abs())
    }

    /// True while the drive moves: S17 shows a command active, or S1 changed beyond the in-position
    /// tolerance since the previous sample (S17's bit 3 is the user guide's, not the RS485 manual's; a drive
    /// may move without it).
    pub fn moving(&self) -> bool {
        self.s17.contains(crate::model::S17Flag::CommandActive) || self.s1_moved
    }
}

/// What an operation reports on its way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Progress {
    /// A position polled while waiting for a move.
    Position {
        /// The drive.
        drive: Address,
        /// Its actual position S1.
        position: Position,
    },
    /// One reading of a watch.
    Watch(WatchSample),
    /// A scan is about to read S1 of `drive`, the `index`-th address of its range (from 0), `of` in all.
    Scan {
        /// The address asked next.
        drive: Address,
        /// How many addresses of the range were asked before it.
        index: usize,
        /// How many addresses the range has.
        of: usize,
    },
}

/// An operation of a COMPAX session. Each ends with one [`Output`] (named below) or an [`Error`].
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    /// How drive `address` echoes ([`EchoForm`]), found out once with S1 sent with `?` (a drive does not
    /// execute what it echoes) and remembered ([`Session::echo_form`](super::Session::echo_form)).
    /// [`Output::Done`].
    ProbeEcho(Address),
    /// A status value ([`Output::Status`]); read again when the reply does not read as the value.
    ReadStatus(Address, StatusId),
    /// Several status values of one drive, in order ([`Output::Statuses`]); a cancel ends it between two.
    ReadStatuses(Address, Vec<StatusId>),
    /// A parameter ([`Output::Number`]).
    ReadParam(Address, ParamId),
    /// A parameter written (its range checked first) and read back ([`Output::Done`]); [`Error::ReadBack`]
    /// when it reads back otherwise.
    WriteParam(Address, ParamId, f64),
    /// A command other than a move ([`Output::Text`]: the reply text, empty for an acknowledgement).
    Command(Address, Command),
    /// A setting (SPEED, ACCEL, ACCEL-, OUTPUT), ASCII or binary ([`Output::Done`]).
    Setting(Address, Command, bool),
    /// Text sent as it is, flags at its end as flags ([`Output::Reply`]); sent again only after E70, E72,
    /// E73. A move or `!` counts as started.
    Raw(Address, String),
    /// Text sent as it is, and what it set in motion handed over or waited for ([`Output::Raw`]). Cancelled
    /// while it is sent, what it started is stopped instead.
    RawMotion(Address, String, AfterRaw),
    /// `text?`: the drive sends it back ([`Output::Text`]).
    Echo(Address, String),
    /// POSA, POSR or POSA HOME to one drive ([`Output::Done`] once the drive has taken it). A POSR whose
    /// reply is lost is never sent again blind: S2 tells whether it arrived.
    Move(Address, Command, MoveOptions),
    /// POSA HOME to one drive, the wait until its positioning ended (as [`Op::Wait`]), then S16 and S1
    /// ([`Output::Homed`]: where it rests); [`Error::NotHomed`] when S16 does not show machine zero
    /// approached.
    Home(Address, Option<Duration>),
    /// Moves stored in each drive's buffer, then one `32!` ([`Output::Done`]).
    SyncStart(Vec<(Address, Command)>, bool),
    /// A command to every drive, no reply ([`Output::Done`]).
    Broadcast(Command),
    /// Waits until the drives' positionings have ended ([`Output::Done`]), reporting
    /// [`Progress::Position`]; stops them when it fails or is cancelled.
    Wait(Vec<Address>, Option<Duration>),
    /// A checked move: limits, S16 / S17, the move stored with its echo and executed once the echo is the
    /// telegram sent, S2 read back, the wait, the position at rest
    /// ([`Output::Moved`]).
    MoveTo(Address, MoveRequest),
    /// The first half of [`Op::MoveTo`], up to the target read back ([`Output::Started`]); with `true`,
    /// the move is then handed over (the session forgets it and does not stop it).
    StartMove(Address, MoveRequest, bool),
    /// The second half of [`Op::MoveTo`] ([`Output::Moved`]).
    FinishMove(StartedMove, Option<Duration>),
    /// S1 of every address in the range ([`Output::Found`]); a cancel ends it between two addresses.
    Scan(RangeInclusive<u8>),
    /// `OUTPUT O0=0` to one drive (or to every drive with 32), acknowledged ([`Output::Done`]).
    Stop(Address),
    /// Stops every drive the session set in motion that still moves, confirmed by S17
    /// ([`Output::Stopped`]).
    StopStarted,
    /// Stops each of these drives that still moves, whoever set it in motion: S17 first; a drive at rest is
    /// left switched on; one that moves (or whose S17 cannot be read) gets `OUTPUT O0=0`, confirmed by S17
    /// ([`Output::Stopped`]). The broadcast address is refused ([`Error::Broadcast`]).
    StopIfMoving(Vec<Address>),
    /// S1 and S17 of a drive every interval, reported as [`Progress::Watch`], until cancelled
    /// ([`Output::Done`]).
    Watch(Address, Duration),
    /// Listens for this long (`$` and comparator messages are handled) ([`Output::Done`]); a cancel ends it.
    Pause(Duration),
}

/// What an operation ended with.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Nothing but success.
    Done,
    /// A status value.
    Status(StatusValue),
    /// Status values, in the order asked.
    Statuses(Vec<(StatusId, StatusValue)>),
    /// A number (a parameter value).
    Number(f64),
    /// A reply text.
    Text(String),
    /// A reply text, or `None` when none was due.
    Reply(Option<String>),
    /// What a raw command did.
    Raw(RawOutcome),
    /// A move taken, its target confirmed.
    Started(StartedMove),
    /// A checked move that ended at its target.
    Moved(MoveReport),
    /// A homing that ended at machine zero: where the drive rests (S1).
    Homed(Position),
    /// The drives that answered a scan, with their positions.
    Found(Vec<(Address, Position)>),
    /// What a stop did.
    Stopped(StopReport),
}

impl Output {
    /// The variant's name, for the message of a mismatch.
    pub(crate) fn name(&self) -> &'static str {
        match self {
            Output::Done => "Done",
            Output::Status(_) => "Status",
            Output::Statuses(_) => "Statuses",
            Output::Number(_) => "Number",
            Output::Text(_) => "Text",
            Output::Reply(_) => "Reply",
            Output::Raw(_) => "Raw",
            Output::Started(_) => "Started",
            Output::Moved(_) => "Moved",
            Output::Found(_) => "Found",
            Output::Homed(_) => "Homed",
            Output::Stopped(_) => "Stopped",
        }
    }
}

/// The S16 and S17 words of a status value, for the operations that need them.
pub(crate) fn s16_of(v: &StatusValue) -> Option<S16Bits> {
    match v {
        StatusValue::S16(b) => Some(*b),
        _ => None,
    }
}

pub(crate) fn s17_of(v: &StatusValue) -> Option<S17Bits> {
    match v {
        StatusValue::S17(b) => Some(*b),
        _ => None,
    }
}
