//! What operations report: progress on the way, and how moves and runs ended.

use std::time::Duration;

use motionlink_link::Timestamp;

use crate::model::{Actuator, ActuatorStatus1, ErrorCode, Function, MotionFunction, PositionCounts, StopMode};

/// Where a move is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MoveProgress {
    /// The actuator the move is about (the one named to `move_to`, the first target of `move_function`).
    pub actuator: Actuator,
    /// Where it is.
    pub position_counts: PositionCounts,
    /// Where it started.
    pub start_counts: PositionCounts,
    /// Where it is going.
    pub target_counts: PositionCounts,
    /// Actuator status 1.
    pub status: ActuatorStatus1,
}

/// How one actuator of a move ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ActuatorOutcome {
    /// The actuator.
    pub actuator: Actuator,
    /// Its target.
    pub target_counts: PositionCounts,
    /// Where it started.
    pub start_counts: PositionCounts,
    /// Where it ended (read after the unit reported the end of the motion).
    pub position_counts: PositionCounts,
    /// Whether it moved (its motion bit was seen, or its position changed by more than the tolerance). An
    /// actuator of a function whose drives are unknown that did not move is not driven by it.
    pub moved: bool,
}

impl ActuatorOutcome {
    /// Position minus target, in counts.
    pub fn difference_counts(&self) -> i64 {
        self.position_counts.counts_from(self.target_counts)
    }
}

/// How a move ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MoveReport {
    /// The actuator the move is about (the one named to `move_to`, the first target of `move_function`).
    pub actuator: Actuator,
    /// The function that drove it.
    pub function: MotionFunction,
    /// Where that actuator ended.
    pub position_counts: PositionCounts,
    /// How long it took on the session's clock.
    pub duration: Duration,
    /// Every actuator whose remote position the move wrote, in actuator order.
    pub actuators: Vec<ActuatorOutcome>,
    /// Every check of the move was made: the targets against the strokes, the written remote positions and
    /// speed read back, where the actuators ended. False when the unit in use could not be asked for some
    /// of it (see `not_verifiable`); where the actuators ended is checked in any case.
    pub verified: bool,
    /// What could not be verified, and why, in plain words (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

/// How a write ended: the unit acknowledged the RT and, where it reads remote data back, the value read back
/// equals the one written (a value that reads back different is an error, not a report).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct SetReport {
    /// The value was read back and equals what was written.
    pub verified: bool,
    /// What could not be verified, and why (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

/// Where a function's run is: the state of every actuator at the last look.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunProgress {
    /// The function.
    pub function: Function,
    /// How long it has run.
    pub elapsed: Duration,
    /// Actuator status 1 of A1..A6 (empty where not read: a switching function).
    pub statuses: [ActuatorStatus1; 6],
    /// Positions of A1..A6 (zero where not read).
    pub positions: [PositionCounts; 6],
    /// A switching function: whether the status entry that shows it ([`Function::switch_status`]) showed it
    /// on after the RE (false: not verified; the run's report says why). `None` for a motion function.
    pub switched_on_shown: Option<bool>,
}

/// How a function's run ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunReport {
    /// The function.
    pub function: Function,
    /// How long it ran.
    pub duration: Duration,
    /// Where each connected actuator came to rest, read after the stop.
    pub rest: Vec<(Actuator, PositionCounts)>,
    /// A switching function: its status entry showed it on after the RE and off after the RS. A motion
    /// function: true (its stop is confirmed by the status of every actuator).
    pub verified: bool,
    /// What could not be verified, and why (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

/// How a switching function was switched ([`crate::Client::switch`]): the unit acknowledged the RE (on) or
/// RS (off), and the status entry that shows the function ([`Function::switch_status`]) was read afterwards.
/// A status that shows the other state is an error ([`crate::Error::SwitchNotShown`]), not a report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SwitchReport {
    /// The function.
    pub function: Function,
    /// Switched on (RE) or off (RS).
    pub on: bool,
    /// Its status entry showed the state asked for.
    pub verified: bool,
    /// Why it is not verified (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

/// How a stop of motion functions ended ([`crate::Client::stop_functions`]): the unit acknowledged the RS
/// of each function (or refused it: [`StopReport::refused`]), and the status read afterwards showed no
/// actuator moving.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct StopReport {
    /// The functions sent RS, in that order.
    pub functions: Vec<MotionFunction>,
    /// How: fast (without the stop ramp) or soft (along it).
    pub mode: StopMode,
    /// The RS the unit refused, with its answer (the other functions were stopped all the same; the status
    /// read afterwards confirms that nothing moves).
    pub refused: Vec<RefusedStop>,
    /// Every connected actuator ("drive available") and where it came to rest, read after the stop.
    pub at_rest: Vec<ActuatorRest>,
}

/// An RS the unit refused.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct RefusedStop {
    /// The function.
    pub function: MotionFunction,
    /// The unit's answer.
    pub reason: String,
}

/// Where an actuator is at rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ActuatorRest {
    /// The actuator (1..6).
    pub actuator: Actuator,
    /// Its position, in encoder counts.
    pub position_counts: PositionCounts,
}

/// The status, position and current of every actuator and the last error at one instant: the read data of
/// the session's cyclic object (which the keepalive RC carries), or reads of each of them one after the other
/// (a unit that does not take the object, a session that polls with reads).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Snapshot {
    /// When the data arrived.
    pub at: Timestamp,
    /// Actuator status 1 of A1..A6.
    pub statuses: [ActuatorStatus1; 6],
    /// Positions of A1..A6.
    pub positions: [PositionCounts; 6],
    /// Motor currents of A1..A6, in 0.1 A (as the data list holds them: `Value::CurrentDeciAmps` converts).
    pub currents_deci_amps: [u16; 6],
    /// Error_Code 1 (the most recent).
    pub last_error: ErrorCode,
}

impl Snapshot {
    /// Actuator `a`'s status 1.
    pub fn status(&self, a: Actuator) -> ActuatorStatus1 {
        self.statuses[usize::from(a.number() - 1)]
    }

    /// Actuator `a`'s position.
    pub fn position(&self, a: Actuator) -> PositionCounts {
        self.positions[usize::from(a.number() - 1)]
    }

    /// True if actuator `a` reports motion.
    pub fn moving(&self, a: Actuator) -> bool {
        self.status(a).moving()
    }

    /// Every connected actuator ("drive available") with its position.
    pub fn connected_positions(&self) -> Vec<(Actuator, PositionCounts)> {
        Actuator::all().filter(|a| self.status(*a).available()).map(|a| (a, self.position(a))).collect()
    }
}

/// Counters of a session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// RC keepalives acknowledged (the ones that polled a motion too).
    pub keepalives: u64,
    /// Requests sent again after silence, a corrupt reply, a CSE or a PCE.
    pub retries: u64,
    /// Times zero bytes were sent to complete a telegram the unit may have been waiting for.
    pub flushes: u64,
    /// Successful reconnections.
    pub reconnects: u64,
    /// Transactions completed (any outcome from the unit).
    pub transactions: u64,
    /// Times remote mode was opened again: by [`crate::Client::reopen`], or to send the RS of the end of a
    /// session.
    pub reopens: u64,
    /// Times the unit's watchdog was found expired and re-armed by an RC (Safety_ID 1 and 2).
    pub watchdog_lapses: u64,
    /// Times the session let the unit's watchdog lapse on purpose: a watch on a link too slow for any
    /// request between two RCs defined its cyclic object so, while the session had started nothing, and
    /// opened remote mode again with RO and an RC carrying the object (see the crate documentation, "Slow
    /// links").
    pub deliberate_lapses: u64,
    /// RC keepalives whose cyclic object read the state of a running motion.
    pub motion_polls: u64,
}
