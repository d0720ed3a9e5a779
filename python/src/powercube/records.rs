//! The records of `motionlink.PowerCube`'s results: dicts with the command line's `--json` names.

use super::*;

/// The name suffix of a position in `unit`: "_rad", "_m", or "" with `"unit": "module"`.
pub(super) fn suffix(unit: AxisUnit) -> (&'static str, &'static str) {
    match unit {
        AxisUnit::Radian => ("_rad", "rad"),
        AxisUnit::Metre => ("_m", "m"),
        AxisUnit::ModuleUnit => ("", "module"),
    }
}

/// Sets `unit` and `{base}_rad` / `{base}_m` (or `{base}` for a module of unknown kind) on `r`.
pub(super) fn put_position(r: &Record<'_>, base: &str, p: Position) -> PyResult<()> {
    let (s, unit) = suffix(p.unit());
    r.set("unit", unit)?;
    r.set(&format!("{base}{s}"), f32_py(p.value()))?;
    Ok(())
}

/// Sets the state word's fields on `r`: `word`, `flags`, `faults` (and `unknown_bits` when nonzero).
pub(super) fn put_state(r: &Record<'_>, s: CubeState) -> PyResult<()> {
    r.flag_word(s)?;
    r.set("faults", s.faults().map(|f| f.name()).collect::<Vec<_>>())?;
    Ok(())
}

/// The state word as the CLI's `powercube state --json` prints it (the module's fields at the top).
pub(super) fn state_record<'py>(py: Python<'py>, module: u8, s: CubeState) -> PyResult<Record<'py>> {
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("module", module)?;
    put_state(&r, s)?;
    Ok(r)
}

/// A record of `module` with its state nested as `state` (scan, info, move, home, watch).
pub(super) fn with_state<'py>(py: Python<'py>, module: u8, s: CubeState) -> PyResult<Record<'py>> {
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("module", module)?;
    let state = Record::new(py);
    put_state(&state, s)?;
    r.set("state", state.done())?;
    Ok(r)
}

pub(super) fn info_record<'py>(py: Python<'py>, i: &ModuleInfo) -> PyResult<Record<'py>> {
    let r = with_state(py, i.address.get(), i.state)?;
    r.set("kind", i.kind.name())?.set("unit", i.kind.unit())?;
    r.set("version", i.version.to_string())?.set("serial", i.serial)?;
    r.extras(&["unit"])?;
    Ok(r)
}

pub(super) fn value_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match *v {
        Value::F32(x) => f32_py(x).into_pyobject(py)?.into_any(),
        Value::U32(x) => x.into_pyobject(py)?.into_any(),
        Value::I32(x) => x.into_pyobject(py)?.into_any(),
        Value::U16(x) => x.into_pyobject(py)?.into_any(),
        Value::I16(x) => x.into_pyobject(py)?.into_any(),
        Value::U8(x) => x.into_pyobject(py)?.into_any(),
        Value::PosStateDio { pos, state, dio } => {
            let d = PyDict::new(py);
            d.set_item("position", f32_py(pos))?;
            d.set_item("short_state", state.0)?;
            d.set_item("dio", dio.0)?;
            d.into_any()
        }
        Value::PosTime { pos, time_ms } => {
            let d = PyDict::new(py);
            d.set_item("position", f32_py(pos))?;
            d.set_item("time_ms", time_ms)?;
            d.into_any()
        }
    })
}

pub(super) fn param_record<'py>(py: Python<'py>, module: u8, p: Param, kind: ModuleKind) -> PyResult<Record<'py>> {
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("module", module)?.set("name", p.name())?.set("id", p.id())?;
    r.set("unit", p.unit().symbol(kind))?.set("access", p.access().short())?;
    Ok(r)
}

/// `p` in the unit of a module of `kind` (a position the session reported in the module's own unit is
/// the same number: rad on a rotary module, m on a linear one).
pub(super) fn in_unit(p: Position, kind: ModuleKind) -> Position {
    if p.unit() == AxisUnit::ModuleUnit {
        Position::new(p.value(), kind.axis_unit())
    } else {
        p
    }
}

pub(super) fn move_record<'py>(py: Python<'py>, module: u8, m: &MoveReport) -> PyResult<Record<'py>> {
    let r = with_state(py, module, m.state)?;
    r.set("action", "reached")?;
    put_position(&r, "start", m.start)?;
    put_position(&r, "target", m.target)?;
    put_position(&r, "reached", m.reached)?;
    put_position(&r, "difference", Position::new(m.reached.value() - m.target.value(), m.kind.axis_unit()))?;
    r.set("verified", m.verified)?.set("not_verifiable", m.not_verifiable.clone())?;
    let (s, _) = suffix(m.kind.axis_unit());
    r.extras(&["unit", &format!("start{s}")])?;
    Ok(r)
}

/// The end of homing as the CLI's `powercube home --json` prints it.
pub(super) fn home_record<'py>(py: Python<'py>, module: u8, h: &HomeReport) -> PyResult<Record<'py>> {
    let r = with_state(py, module, h.state)?;
    r.set("action", "homed")?;
    put_position(&r, "reached", h.reached)?;
    r.set("verified", h.verified)?.set("not_verifiable", h.not_verifiable.clone())?;
    r.extras(&["unit"])?;
    Ok(r)
}

/// A parameter written as the CLI's `powercube set --json` prints it: what was written, `ok`, what the
/// module read back (in the parameter's unit) and whether that was verified (unit and access are
/// attributes, as `get` has them).
pub(super) fn set_record<'py>(py: Python<'py>, module: u8, kind: ModuleKind, w: &SetReport) -> PyResult<Record<'py>> {
    let r = param_record(py, module, w.param, kind)?;
    r.set("value", value_py(py, &w.value)?)?.set("ok", true)?;
    match (w.readback.read_in_unit, &w.readback.read) {
        (Some(in_unit), _) => r.set("read_back", in_unit)?,
        (None, Some(back)) => r.set("read_back", value_py(py, back)?)?,
        (None, None) => r.set("read_back", py.None())?,
    };
    r.set("verified", w.readback.verified)?.set("not_verifiable", w.readback.not_verifiable.clone())?;
    r.extras(&["unit", "access"])?;
    Ok(r)
}

/// A sample of `watch` as the CLI's `powercube watch --json` prints it (without `t_s`, which Python adds).
pub(super) fn sample_record<'py>(py: Python<'py>, module: u8, p: Position, s: CubeState) -> PyResult<Record<'py>> {
    let r = with_state(py, module, s)?;
    put_position(&r, "position", p)?;
    r.extras(&["unit"])?;
    Ok(r)
}
