//! Switching functions (F11 buzzer, F17/F18 binary outputs, F20 emergency stop, F21/F22 the operating unit's
//! LEDs): RE switches one on, RS off, and once the unit acknowledged it the session reads the data-list entry
//! that shows the function ([`SwitchStatus`]) and checks that it shows the state asked for. The entry is read
//! again every poll interval until it does, for at most [`crate::Config::start_grace`] after the acknowledge.
//!
//! - Where the manuals' own words tie the entry to the function (the buzzer, binary output 1), an entry that
//!   shows the other state is an error ([`Error::SwitchNotShown`]).
//! - Where the tie is this crate's reading (binary output 2, the LEDs, the emergency stop), the first switch
//!   is the probe: the entry is read before it too, and the session trusts the entry for the function once it
//!   has seen it show both states around the function's acknowledged RE and RS; from then on an entry that
//!   shows the other state is an error. An entry that does not follow the function before that is not read
//!   for it again in the session (one warning), and every switch of it says that it was not verified. The RE
//!   of the emergency stop is never delayed for the read before it: that read is made only when the line has
//!   room for it at once.
//! - A unit that refuses the entry (PDE) is switched all the same, and the switch says that its status was not
//!   read back (one warning; the entry is not asked for again in the session).

use super::basic::single;
use super::Output;
use crate::error::Error;
use crate::model::{DataIndex, Function, SwitchStatus, UNUSED};
use crate::session::ctx::Ctx;
use crate::session::report::SwitchReport;
use crate::session::request::PreparedRequest;
use crate::wire::{Command, Request, Status};

/// What the session found each switching function's status entry to do, by the function's wire id.
#[derive(Debug, Default)]
pub(crate) struct SwitchFindings([Finding; 22]);

#[derive(Debug, Default, Clone)]
struct Finding {
    /// The entry showed the function on (`[0]`) and off (`[1]`) around its acknowledged RE and RS.
    seen: [bool; 2],
    /// Why the entry is not read for the function any more in this session (the unit refused it, or it did
    /// not follow the function): what every switch of it says.
    plain: Option<String>,
}

impl SwitchFindings {
    fn of(&mut self, function: Function) -> &mut Finding {
        &mut self.0[usize::from(function.id()).min(21)]
    }
}

/// The RE (on) or RS (off) that switches a switching function.
pub(crate) fn switch_request(function: Function, on: bool) -> Result<Request<'static>, Error> {
    if let Function::Motion(m) = function {
        return Err(Error::invalid(format!("{m} is a motion function: use start_motion/stop_motion")));
    }
    let id = function.id();
    Ok(if on {
        Request::Execute { function: id, params: [UNUSED, UNUSED] }
    } else {
        Request::Stop { function: id, param: UNUSED }
    })
}

/// The entry as read before a switch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Before {
    /// Not read: the manuals tie the entry to the function, the session trusts it already, or does not read
    /// it for the function.
    NotRead,
    /// It showed the function on (true) or off.
    Shown(bool),
    /// Not read, for this reason.
    Skipped(String),
}

/// What the check after a switch found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Checked {
    /// The entry showed the state asked for.
    pub shown: bool,
    /// Why the switch is not verified (`None`: verified).
    pub why: Option<String>,
}

impl Checked {
    fn not(why: String) -> Checked {
        Checked { shown: false, why: Some(why) }
    }
}

/// "RE" for on, "RS" for off.
fn command(on: bool) -> Command {
    if on {
        Command::Execute
    } else {
        Command::Stop
    }
}

/// Switches `function` on (RE) or off (RS) and checks its status ([`super::Op::Switch`]).
pub(crate) async fn switch(ctx: &Ctx, function: Function, on: bool) -> Result<Output, Error> {
    let request = PreparedRequest::new(&switch_request(function, on)?)?;
    let before = before(ctx, function, on).await?;
    single(ctx, request).await?;
    let checked = check(ctx, function, on, &before).await?;
    Ok(Output::Switched(SwitchReport {
        function,
        on,
        verified: checked.why.is_none(),
        not_verifiable: checked.why.into_iter().collect(),
    }))
}

/// Reads the entry that shows `function` before its RE (`on`) or RS, where the session has yet to see the
/// entry follow the function (the probe). A read that fails holds nothing back (the switch goes out, an
/// emergency stop above all; the report then says the entry was not read before it); only a cancel ends
/// it, nothing switched.
pub(crate) async fn before(ctx: &Ctx, function: Function, on: bool) -> Result<Before, Error> {
    let Some(status) = function.switch_status() else { return Ok(Before::NotRead) };
    {
        let mut core = ctx.core();
        let room = core.room_at_once();
        let finding = core.switches.of(function);
        if status.reading.is_none() || finding.plain.is_some() || finding.seen == [true, true] {
            return Ok(Before::NotRead);
        }
        if function == Function::EmergencyStop && on && !room {
            return Ok(Before::Skipped(
                "the line had no room for it at once, and the emergency stop is not delayed for a read".into(),
            ));
        }
    }
    match read_word(ctx, status.index).await {
        Ok(word) => Ok(Before::Shown(status.shows_on(word))),
        Err(Error::Refused { status: Status::ParameterDataError, .. }) => {
            refused(ctx, &status);
            Ok(Before::NotRead)
        }
        Err(e @ Error::CancelledBeforeMotion(_)) => Err(e),
        Err(e) => Ok(Before::Skipped(e.to_string())),
    }
}

/// After the unit acknowledged the RE (`on`) or RS of `function`: reads the entry that shows it until it
/// shows the state asked for, at most [`crate::Config::start_grace`] long, and judges it (see the module
/// documentation). `before`: what [`before`] read.
pub(crate) async fn check(ctx: &Ctx, function: Function, on: bool, before: &Before) -> Result<Checked, Error> {
    let command = command(on);
    let Some(status) = function.switch_status() else {
        return Ok(Checked::not(format!(
            "{function} was not verified by a status: no data-list entry shows it; the unit's acknowledge is all that \
             says it switched"
        )));
    };
    if let Some(why) = ctx.core().switches.of(function).plain.clone() {
        return Ok(Checked::not(why));
    }
    // What the unit acknowledged is not cut short by a cancel: the reads after it are made in any case.
    let ctx = ctx.firm();
    let acknowledged = ctx.now();
    let (grace, interval) = {
        let core = ctx.core();
        (core.config.start_grace, core.config.poll_interval)
    };
    let word = loop {
        match read_word(&ctx, status.index).await {
            Ok(word) if status.shows_on(word) == on || ctx.now() >= acknowledged + grace => break word,
            Ok(_) => {}
            Err(Error::Refused { status: Status::ParameterDataError, .. }) => {
                return Ok(Checked::not(refused(&ctx, &status)));
            }
            // The unit acknowledged the switch: a read that fails makes it not verified, not undone.
            Err(e) => {
                return Ok(Checked::not(format!(
                    "{function} was not verified by its status: {} was not read after the {command}: {e}",
                    status.place()
                )));
            }
        }
        let now = ctx.now();
        ctx.pause_until((now + interval).min(acknowledged + grace)).await;
    };
    let after = ctx.now() - acknowledged;
    let mut core = ctx.core();
    let finding = core.switches.of(function);
    let (what, asked, other) = (status.what, status.state(on), status.state(!on));
    if status.shows_on(word) == on {
        if let Before::Shown(b) = before {
            finding.seen[usize::from(!*b)] = true;
        }
        finding.seen[usize::from(!on)] = true;
        if status.reading.is_none() || finding.seen == [true, true] {
            return Ok(Checked { shown: true, why: None });
        }
        let when = match before {
            Before::Shown(_) => " as before it".to_string(),
            Before::Skipped(why) => format!(", and was not read before it ({why})"),
            Before::NotRead => String::new(),
        };
        let reading = status.reading.unwrap_or_default();
        return Ok(Checked {
            shown: true,
            why: Some(format!(
                "{function} was not verified by its status: {} shows {what} {asked} after the {command}{when}; \
                 {reading}, and this session has not seen the entry show {what} {other}",
                status.place()
            )),
        });
    }
    if status.reading.is_none() || finding.seen == [true, true] {
        return Err(Error::SwitchNotShown { function, command, word, after, switched_off: false });
    }
    let why = format!(
        "{function} was not verified by its status: {} did not show {what} {asked} after the acknowledged {command} \
         (last read {} ms after it); {}, so this session does not take the entry to show {function}",
        status.place(),
        after.as_millis(),
        status.reading.unwrap_or_default()
    );
    tracing::warn!("{why}");
    finding.plain = Some(why.clone());
    Ok(Checked::not(why))
}

/// The unit refused the entry that shows `status`'s function (PDE): said once, and not asked for again.
fn refused(ctx: &Ctx, status: &SwitchStatus) -> String {
    let function = status.function;
    let why = format!(
        "{function} was not verified by its status: the unit refuses {} ({}) (RG: PDE); the unit's acknowledge is \
         all that says it switched",
        status.name(),
        status.index
    );
    let mut core = ctx.core();
    let finding = core.switches.of(function);
    if finding.plain.is_none() {
        tracing::warn!("{why}");
        finding.plain = Some(why.clone());
    }
    why
}

/// RG of a flag entry of one or two bytes: its value.
async fn read_word(ctx: &Ctx, index: DataIndex) -> Result<u16, Error> {
    let data = ctx.get(index).await.and_then(|r| r.data(Command::Get))?;
    match data[..] {
        [b] => Ok(u16::from(b)),
        [lo, hi] => Ok(u16::from_le_bytes([lo, hi])),
        _ => Err(Error::UnexpectedReply {
            command: Command::Get,
            detail: format!("{index} is 1 or 2 bytes, the unit sent {}", data.len()),
        }),
    }
}

/// How a run of a switching function ended, from the checks after its RE (`on`) and its RS (`off`): verified
/// when the entry showed the function on after the RE and off after the RS and the session trusts it by then
/// (what the check after the RE could not say yet is settled by the one after the RS); else each reason once.
pub(crate) fn run_verified(on: &Checked, off: &Checked) -> (bool, Vec<String>) {
    if on.shown && off.why.is_none() {
        return (true, Vec::new());
    }
    let mut why: Vec<String> = Vec::new();
    for w in [&on.why, &off.why].into_iter().flatten() {
        if !why.contains(w) {
            why.push(w.clone());
        }
    }
    (why.is_empty(), why)
}
