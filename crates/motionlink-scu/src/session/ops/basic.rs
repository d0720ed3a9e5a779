//! Single requests, verified writes, strokes and cyclic objects.

use super::Output;
use crate::config::{Config, StrokeLimits};
use crate::error::Error;
use crate::model::{
    item, Actuator, CyclicObject, DataEntry, DataIndex, Item, MotionFunction, PositionCounts, SpeedMode, StopMode,
};
use crate::session::ctx::Ctx;
use crate::session::request::{OwnedReply, PreparedRequest, Req, Schedule};
use crate::session::CyclicUse;
use crate::session::SetReport;
use crate::value::{decode_item, Value};
use crate::wire::{Command, Request, Status};

/// One request of the caller's ([`super::Op::Request`]). A stop goes out before anything else, even if its
/// caller gives up on it; an RE whose caller gave up before its reply came is followed by RS.
pub(crate) async fn single(ctx: &Ctx, request: PreparedRequest) -> Result<Output, Error> {
    let (command, starts) = (request.command, request.starts);
    let result = if command == Command::Stop {
        ctx.firm().send(Req::op(request).when(Schedule::Now)).await
    } else {
        ctx.send(Req::op(request).when(Schedule::Room)).await
    };
    let sent = !matches!(result, Err(Error::CancelledBeforeMotion(_)));
    if let (true, true, Some(f)) = (ctx.cancelled(), sent, starts) {
        // The caller gave up while its RE was under way: it may have started a motion.
        let function = crate::model::Function::from_id(f);
        let rs = Req::op(PreparedRequest::stop(f, StopMode::Fast)).when(Schedule::Now);
        return match ctx.firm().send(rs).await.and_then(|r| r.ack(Command::Stop)) {
            Ok(_) => Err(Error::FunctionCancelled { function_id: f, stopped: true }),
            Err(e) => {
                ctx.core().stop_unconfirmed(&Vec::from_iter(function));
                Err(Error::StopUnconfirmed {
                    cause: Box::new(Error::FunctionCancelled { function_id: f, stopped: false }),
                    functions: function.into_iter().collect(),
                    mode: StopMode::Fast,
                    detail: e.to_string(),
                })
            }
        };
    }
    result.and_then(|r| r.ack(command)).map(|r| Output::Data(r.data))
}

/// RT of `data` to `index`, then (with `verify`, where the data list has the index) the RG that reads it
/// back. Its end: `None` when the value was read back equal (or no read-back was asked), `Some(why)` when
/// the unit refuses to read remote data back (PDE; remembered for the session), so the value could not be
/// verified.
pub(crate) async fn write(ctx: &Ctx, index: DataIndex, data: &[u8], verify: bool) -> Result<Option<String>, Error> {
    let rt = PreparedRequest::new(&Request::Transfer { index: index.0, data })?;
    ctx.send(Req::op(rt)).await.and_then(|r| r.ack(Command::Transfer))?;
    if !verify || item(index).is_none() {
        return Ok(None);
    }
    let answered = ctx.core().probed.known().remote_read_back;
    if answered == Some(false) {
        return Ok(Some(not_read_back(index)));
    }
    match ctx.get(index).await.and_then(|r| r.data(Command::Get)) {
        // The first read of remote data in the session is the probe (also where a device profile said the unit
        // reads it back): refused, the session remembers it.
        Err(Error::Refused { status: Status::ParameterDataError, .. })
            if ctx.core().probed.caps.remote_read_back.is_none() =>
        {
            ctx.core().remote_read_back(false);
            Ok(Some(not_read_back(index)))
        }
        other => other.and_then(|read| compare(ctx, index, data, read)),
    }
}

/// The value read back, against the one written.
fn compare(ctx: &Ctx, index: DataIndex, written: &[u8], read: Vec<u8>) -> Result<Option<String>, Error> {
    ctx.core().remote_read_back(true);
    if read == written {
        return Ok(None);
    }
    let Some(it) = item(index) else { return Ok(None) };
    Err(Error::ReadBack { name: it.name(), index, wrote: written.to_vec(), read })
}

fn not_read_back(index: DataIndex) -> String {
    let name = item(index).map_or("the value", |it| it.name());
    format!(
        "{name} ({index}) was written (the unit acknowledged RT) but not read back: the unit refuses to read remote \
         data (RG: PDE)"
    )
}

/// Checks that `value` may be written to `index` (a remote entry, the value's kind, its range) and encodes it.
pub(crate) fn encode_for(
    index: DataIndex,
    value: &Value,
    mode: SpeedMode,
) -> Result<(&'static DataEntry, Vec<u8>), Error> {
    let Some(Item::Entry(e)) = item(index) else {
        return Err(Error::invalid(format!("{index} is not a single data-list entry")));
    };
    if !index.is_remote() {
        return Err(Error::invalid(format!(
            "{} ({index}) is read-only: only remote data (0x3xxx) can be written",
            e.name
        )));
    }
    if !value.fits(e.kind) {
        return Err(Error::invalid(format!(
            "{} is a {} entry; a {} value does not fit",
            e.name,
            e.kind.data_type(),
            value.kind_name()
        )));
    }
    value.check_range(mode).map_err(|err| Error::invalid(format!("{}: {err}", e.name)))?;
    let mut data = Vec::new();
    value.encode(e.kind, &mut data);
    Ok((e, data))
}

/// A write of the caller's ([`super::Op::Set`]). An index outside the data list is written, not read back:
/// what it holds, and so what a read of it would give, is not known; the report says so.
pub(crate) async fn set(ctx: &Ctx, index: DataIndex, data: Vec<u8>, verify: bool) -> Result<Output, Error> {
    let mut why = write(ctx, index, &data, verify).await?;
    if verify && item(index).is_none() {
        why = Some(format!("{index} is not in the data list: written, not read back (what it holds is not known)"));
    }
    Ok(Output::Written(SetReport { verified: why.is_none(), not_verifiable: why.into_iter().collect() }))
}

/// Where an actuator's stroke comes from, and what it is.
pub(crate) type Stroke = Option<(StrokeLimits, &'static str)>;

/// What is known of an actuator's stroke: limits (`Ok(Some)`), none set on the unit (`Ok(None)`: its
/// virtual limits are both 0), or why it is not known (`Err`: the unit refuses UserPositionData and none are
/// configured).
pub(crate) type StrokeFound = Result<Stroke, String>;

/// Why actuator `a`'s target could not be checked against a stroke.
fn stroke_unknown(a: Actuator) -> String {
    stroke_unchecked(a, &format!("the unit refuses UserPositionData ({}, PDE)", user_positions(a)))
}

/// Why actuator `a`'s target could not be checked against a stroke where the unit has none set for it.
pub(crate) fn stroke_not_set(a: Actuator) -> String {
    stroke_unchecked(
        a,
        &format!("the virtual limits of its UserPositionData ({}) are 0 / 0 (none set)", user_positions(a)),
    )
}

/// The data index of actuator `a`'s UserPositionData (0x2001..0x2006).
fn user_positions(a: Actuator) -> DataIndex {
    DataIndex(0x2000 + u16::from(a.number()))
}

/// "`a`'s target was not checked against a stroke: `why` and no stroke limits are configured for it".
fn stroke_unchecked(a: Actuator, why: &str) -> String {
    format!(
        "{a}'s target was not checked against a stroke: {why} and no stroke limits are configured for {a} \
         (--stroke {}=MIN:MAX); the unit's own limits bound the motion",
        a.number()
    )
}

/// Actuator `a`'s travel range for targets: configured, or the virtual limits of its UserPositionData.
pub(crate) async fn stroke(ctx: &Ctx, a: Actuator) -> Result<StrokeFound, Error> {
    let (configured, answered) = {
        let core = ctx.core();
        (core.config.stroke_limits[usize::from(a.number() - 1)], core.probed.known().user_position_data)
    };
    if let Some(s) = configured {
        return Ok(Ok(Some((s, "as configured"))));
    }
    if answered == Some(false) {
        return Ok(Err(stroke_unknown(a)));
    }
    match ctx.get(user_positions(a)).await.and_then(|r| r.data(Command::Get)) {
        // The first read of UserPositionData in the session is the probe (also where a device profile said the
        // unit answers it): refused, the session remembers it.
        Err(Error::Refused { status: Status::ParameterDataError, .. })
            if ctx.core().probed.caps.user_position_data.is_none() =>
        {
            ctx.core().user_positions_answered(false);
            Ok(Err(stroke_unknown(a)))
        }
        other => other.and_then(|data| stroke_limits_of(ctx, a, data)),
    }
}

/// The virtual limits in actuator `a`'s UserPositionData.
fn stroke_limits_of(ctx: &Ctx, a: Actuator, data: Vec<u8>) -> Result<StrokeFound, Error> {
    ctx.core().user_positions_answered(true);
    let it = item(user_positions(a)).expect("UserPositionData is in the data list");
    let values = decode_item(it, &data).map_err(|e| Error::UnexpectedReply {
        command: Command::Get,
        detail: format!("UserPositionData of {a}: {e}"),
    })?;
    match values.first().map(|(_, v)| v) {
        Some(Value::UserPositions(u)) => {
            let (lo, hi) = (u.virtual_limit_in_counts, u.virtual_limit_out_counts);
            if (lo, hi) == (0, 0) {
                Ok(Ok(None))
            } else if lo > hi {
                Err(Error::UnexpectedReply {
                    command: Command::Get,
                    detail: format!("{a}'s virtual limits {lo}..{hi} are reversed"),
                })
            } else {
                Ok(Ok(Some((
                    StrokeLimits { min_counts: PositionCounts(lo), max_counts: PositionCounts(hi) },
                    "the virtual limits of its UserPositionData",
                ))))
            }
        }
        other => {
            Err(Error::UnexpectedReply { command: Command::Get, detail: format!("UserPositionData of {a}: {other:?}") })
        }
    }
}

/// Refuses `target` for `a` if it lies outside `stroke`.
pub(crate) fn check_stroke(a: Actuator, target: PositionCounts, stroke: &Stroke) -> Result<(), Error> {
    if let Some((s, limits_from)) = stroke {
        if !(s.min_counts..=s.max_counts).contains(&target) {
            return Err(Error::OutsideLimits {
                actuator: a,
                target_counts: target,
                min_counts: s.min_counts,
                max_counts: s.max_counts,
                limits_from,
            });
        }
    }
    Ok(())
}

/// The caller's stroke query ([`super::Op::StrokeLimits`]).
pub(crate) async fn stroke_limits(ctx: &Ctx, a: Actuator) -> Result<Output, Error> {
    stroke(ctx, a).await.and_then(|s| s.map_err(Error::NotSupported)).map(Output::Stroke)
}

/// The data index of CyclicObj `slot`, 1..5.
pub(crate) fn cyclic_index(slot: u8) -> Result<DataIndex, Error> {
    if (1..=5).contains(&slot) {
        Ok(DataIndex(0x3000 + u16::from(slot)))
    } else {
        Err(Error::invalid(format!("cyclic object {slot}: there are CyclicObj 1..5")))
    }
}

/// The entries a cyclic object writes, groups expanded into their members, in order.
fn cyclic_write_entries(object: &CyclicObject) -> Result<Vec<&'static DataEntry>, Error> {
    let mut entries = Vec::new();
    for idx in object.write_indices() {
        match item(idx) {
            Some(Item::Entry(e)) => entries.push(e),
            Some(Item::Group(g)) => entries.extend(g.members()),
            None => return Err(Error::invalid(format!("cyclic write index {idx} is not in the data list"))),
        }
    }
    Ok(entries)
}

/// The write data of `object` from one value per entry it writes (a group counting each of its members).
pub(crate) fn encode_cyclic_write(object: &CyclicObject, write: &[Value], mode: SpeedMode) -> Result<Vec<u8>, Error> {
    let entries = cyclic_write_entries(object)?;
    if entries.len() != write.len() {
        return Err(Error::invalid(format!(
            "the cyclic object writes {} value(s) (a group counts each of its entries); {} given",
            entries.len(),
            write.len()
        )));
    }
    let mut bytes = Vec::new();
    for (e, v) in entries.iter().zip(write) {
        if !crate::model::DataEntryExt::index(*e).is_remote() {
            return Err(Error::invalid(format!("{}: cyclic write data must be remote data", e.name)));
        }
        if !v.fits(e.kind) {
            return Err(Error::invalid(format!("{}: a {} value does not fit", e.name, v.kind_name())));
        }
        v.check_range(mode).map_err(|err| Error::invalid(format!("{}: {err}", e.name)))?;
        v.encode(e.kind, &mut bytes);
    }
    Ok(bytes)
}

/// The read data of an RC with `object`, decoded (groups member by member).
pub fn decode_cyclic_read(object: &CyclicObject, data: &[u8]) -> Result<Vec<(&'static DataEntry, Value)>, Error> {
    let mut out = Vec::new();
    let mut at = 0;
    for idx in object.read_indices() {
        let it = item(idx).ok_or_else(|| Error::invalid(format!("{idx} is not in the data list")))?;
        let end = at + it.size();
        let chunk = data.get(at..end).ok_or_else(|| Error::UnexpectedReply {
            command: Command::Cyclic,
            detail: format!("{} bytes of read data, the object needs more", data.len()),
        })?;
        out.extend(
            decode_item(it, chunk)
                .map_err(|e| Error::UnexpectedReply { command: Command::Cyclic, detail: e.to_string() })?,
        );
        at = end;
    }
    Ok(out)
}

fn definition(reply: Result<OwnedReply, Error>) -> Result<CyclicObject, Error> {
    let data = reply.and_then(|r| r.data(Command::Get))?;
    CyclicObject::from_bytes(&data)
        .ok_or(Error::UnexpectedReply { command: Command::Get, detail: "not a cyclic object".into() })
}

/// Uses CyclicObj `slot` for the keepalive (`keep`), or exchanges it once: reads its definition first.
pub(crate) async fn cyclic(ctx: &Ctx, slot: u8, write: Vec<Value>, keep: bool) -> Result<Output, Error> {
    let index = cyclic_index(slot)?;
    let object = definition(ctx.get(index).await)?;
    let mode = ctx.core().config.speed_mode;
    let bytes = encode_cyclic_write(&object, &write, mode)?;
    if keep {
        // Keepalive writes are not read back.
        let mut core = ctx.core();
        core.cyclic = Some(CyclicUse { slot, object, write: bytes });
        core.last_cyclic_read = None;
        return Ok(Output::Done);
    }
    if ctx.cancelled() {
        return Err(Error::CancelledBeforeMotion(Command::Cyclic));
    }
    let read_len = object.read_size().and_then(|n| u16::try_from(n).ok());
    let rc = PreparedRequest::with_reply_len(&Request::Cyclic { object: slot - 1, write: &bytes }, read_len)?;
    ctx.send(Req::op(rc))
        .await
        .and_then(|r| r.ack(Command::Cyclic))
        .map(|r| Output::Cyclic { object, data: r.data.unwrap_or_default() })
}

/// The function-map check of a move or a stream: no actuator twice, and exactly the ones the map says the
/// function drives, if it knows the function.
pub(crate) fn check_against_map(
    config: &Config,
    function: MotionFunction,
    actuators: &[Actuator],
) -> Result<(), Error> {
    for (i, a) in actuators.iter().enumerate() {
        if actuators[..i].contains(a) {
            return Err(Error::invalid(format!("{a} is named twice")));
        }
    }
    if let Some(drives) = config.function_map.drives(function) {
        if let Some(a) = actuators.iter().find(|a| !drives.contains(a)) {
            return Err(Error::invalid(format!(
                "{function} does not drive {a}: the function map says it drives {}",
                crate::model::Actuator::list(&drives)
            )));
        }
        if let Some(d) = drives.iter().find(|d| !actuators.contains(d)) {
            return Err(Error::invalid(format!(
                "{function} also drives {d} (the function map says it drives {}): give {d} a target too",
                crate::model::Actuator::list(&drives)
            )));
        }
    }
    Ok(())
}
