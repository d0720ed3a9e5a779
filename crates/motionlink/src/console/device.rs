//! What the console asks of a device family: one [`Device`] per family, a thin adapter over that family's
//! `AsyncClient`. Every motion is a future that the console's [`Hub`](super::hub::Hub) owns: dropping it
//! stops the motion (the family library does that, as for every other user of its `AsyncClient`).

use std::future::Future;
use std::ops::RangeInclusive;
use std::pin::Pin;
use std::sync::Arc;

use motionlink_link::table::Entry;
use serde::Serialize;
use serde_json::Value;

/// A boxed future that can move between threads.
pub type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// A motion (or any action, or a stop) under way: it ends with the family library's report of what the
/// device did (the object `motionlink <family> ... --json` prints for it); dropping it before it ends stops
/// what it set in motion.
pub type Motion = BoxFuture<'static, Result<Report, ErrorReport>>;

/// Why a request to the device failed: the error's report, as the command line's `--json` and the gateway
/// give it (`{"kind", "message", "exit_code"}`).
pub use motionlink_link::error::ErrorReport;

/// One addressable unit found on the link: an SCU actuator, a PowerCube module, a COMPAX drive. It
/// serialises without its number, which the page gets under the family's key ([`Numbered`](super::message::Numbered)).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unit {
    /// Its number: actuator 1..6, module or drive address 1..31.
    #[serde(skip)]
    pub id: u8,
    /// How the page names it ("A1", "module 3", "drive 1").
    pub label: String,
    /// What else is known of it (type, version, the function that drives it).
    pub detail: String,
    /// The JSON name of its position (`position_counts`, `position_rad`, `position_m`, `position_units`,
    /// `position` when the unit is not known).
    pub position_key: &'static str,
    /// The JSON name of a move's target (`target_counts`, ...).
    pub target_key: &'static str,
    /// The unit of positions as the page shows it ("counts", "rad", "m", "units").
    pub position_unit: &'static str,
    /// The JSON name of the speed in a sample (`speed_percent`, `velocity_rad_per_s`, ...).
    pub speed_key: &'static str,
    /// The unit of that speed ("%", "rad/s", ...).
    pub speed_unit: &'static str,
    /// The JSON name of the speed a move or jog is asked to go at.
    pub command_speed_key: &'static str,
    /// The unit of that speed.
    pub command_speed_unit: &'static str,
    /// `Some("current_amps")` when samples carry the motor current.
    pub current_key: Option<&'static str>,
    /// What a move given no speed goes at, in words ("100 %", "the drive's SPEED setting as it is"): the
    /// page says it where the speed is typed.
    pub move_speed_when_empty: String,
    /// What a jog given no speed goes at, in words.
    pub jog_speed_when_empty: String,
}

/// One look at a unit, as the page gets it (with the unit's number, [`SampleEntry`](super::message::SampleEntry)):
/// the library's look of an axis, which each family makes from its readings.
pub type Sample = motionlink_link::result::AxisLook;

/// One row of the family's parameter table or data list.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Param {
    /// Its name (as the CLI takes it).
    pub name: &'static str,
    /// Its number on the wire.
    pub id: u32,
    /// Its unit ("" when none).
    pub unit: &'static str,
    /// "r", "w" or "rw".
    pub access: &'static str,
    /// The manual's name or description.
    pub title: &'static str,
}

impl Param {
    /// The rows of a family's table.
    pub fn rows<K>(table: &motionlink_link::table::Table<K>) -> Vec<Param> {
        let row =
            |e: &Entry<K>| Param { name: e.name, id: e.id, unit: e.unit, access: e.access.short(), title: e.title };
        table.iter().map(row).collect()
    }
}

/// A library's report as it serialises: the object `motionlink <family> ... --json` prints for the same
/// action (without the identity fields `family`, `port`, `profile` and the unit's number, which the page
/// knows).
pub type Report = Value;

/// The report `r` as it serialises.
pub fn report(r: &impl Serialize) -> Report {
    crate::common::to_json(r)
}

/// An action of the family besides move, jog and stop (PowerCube home and reset, COMPAX switch on).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Action {
    /// Its name in requests.
    pub name: &'static str,
    /// Its button's label.
    pub label: &'static str,
    /// True if it sets the axis in motion: it is then owned like a move (Stop and a lost page stop it).
    pub moves: bool,
}

/// A direction of a jog.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JogDirection {
    /// Towards larger positions (SCU: out).
    Positive,
    /// Towards smaller positions (SCU: in).
    Negative,
}

/// A family's name and what it calls its units.
#[derive(Debug, Clone)]
pub struct Naming {
    /// "scu", "powercube" or "compax".
    pub family: &'static str,
    /// The JSON name of a unit's number: "actuator", "module" or "drive".
    pub unit_key: &'static str,
    /// The numbers a unit of the family can have (SCU actuators 1..6, PowerCube modules and COMPAX drives
    /// 1..31): a request naming another is refused, saying so.
    pub unit_numbers: RangeInclusive<u8>,
}

/// A device family as the console drives it. Every motion (`move_to`, `jog`, an action that moves) is a
/// future: it ends when the motion has ended, and dropping it before stops the motion (the family's
/// library sends the stop and checks it).
pub trait Device: Send + Sync + 'static {
    /// The family's name and what it calls its units.
    fn naming(&self) -> Naming;
    /// The port, as the user gave it.
    fn port(&self) -> String;
    /// Finds the units on the link (SCU: the connected actuators; PowerCube, COMPAX: a scan).
    fn discover(&self) -> BoxFuture<'_, Result<Vec<Unit>, ErrorReport>>;
    /// One look at each of `units`.
    fn sample<'a>(&'a self, units: &'a [Unit]) -> BoxFuture<'a, Vec<Result<Sample, ErrorReport>>>;
    /// Moves `unit` to `target` (its position unit) at `speed` (its command speed unit; None: the device's
    /// setting). Checked before the future is made: a bad request is an error at once.
    fn move_to(self: Arc<Self>, unit: u8, target: f64, speed: Option<f64>) -> Result<Motion, ErrorReport>;
    /// Moves `unit` in `direction` until the future is dropped (or the axis reaches its end of travel).
    fn jog(self: Arc<Self>, unit: u8, direction: JogDirection, speed: Option<f64>) -> Result<Motion, ErrorReport>;
    /// The Stop button: stops `unit` (whoever started its motion) as the command line's `stop` does, confirmed
    /// by the device: the library's report of that stop.
    fn stop(self: Arc<Self>, unit: u8) -> Motion;
    /// Stops everything this console's session set in motion (the end of the console), and says what it
    /// stopped in words (empty: nothing).
    fn stop_started(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>>;
    /// The family's other actions.
    fn actions(&self) -> Vec<Action>;
    /// Runs action `name` on `unit`.
    fn action(self: Arc<Self>, unit: u8, name: &str) -> Result<Motion, ErrorReport>;
    /// The parameter table or data list.
    fn params(&self) -> Vec<Param>;
    /// Reads entry `name` (a name or a number) of `unit`: the family's report of `get`.
    fn read_param(self: Arc<Self>, unit: u8, name: String) -> BoxFuture<'static, Result<Report, ErrorReport>>;
    /// Writes entry `name` of `unit` and reads it back: the family's report of `set`.
    fn write_param(
        self: Arc<Self>,
        unit: u8,
        name: String,
        value: String,
    ) -> BoxFuture<'static, Result<Report, ErrorReport>>;
    /// The error history of `unit`, decoded: the family's report (SCU: that of `errors`; PowerCube: the state
    /// word, that of `state`; COMPAX: S18 decoded).
    fn errors(self: Arc<Self>, unit: u8) -> BoxFuture<'static, Result<Report, ErrorReport>>;
    /// Ends the session (the library stops what it started and says whether that was confirmed). Called
    /// once, with the last reference.
    fn close(self: Arc<Self>) -> BoxFuture<'static, Result<String, ErrorReport>>;
}

/// The end of the session `device` holds: `close` with the device itself once nothing else holds it; while a
/// request still does, the session ends (its library stops what it started) with that request, and this
/// says so.
pub fn close_last<D, F>(
    device: Arc<D>,
    close: impl FnOnce(D) -> F + Send + 'static,
) -> BoxFuture<'static, Result<String, ErrorReport>>
where
    D: Send + Sync + 'static,
    F: Future<Output = Result<String, ErrorReport>> + Send + 'static,
{
    Box::pin(async move {
        match Arc::try_unwrap(device) {
            Ok(me) => close(me).await,
            Err(shared) => {
                drop(shared);
                Ok("the session ends with its last request".into())
            }
        }
    })
}

/// A finite number from the page, or an error naming `what`.
pub fn finite(what: &str, v: f64) -> Result<f64, ErrorReport> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ErrorReport::usage(format!("{what}: {v} is not a number")))
    }
}
