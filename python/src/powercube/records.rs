//! The records of `motionlink.PowerCube`'s results: the library's reports as they serialise (the command
//! line's `--json` names), with the module, and a few attributes that are not in `to_dict()`.

use super::*;
use motionlink_powercube::report::{Acted, Sample, StateReport};

/// The name suffix of a position in `unit`: "_rad", "_m", or "" with `"unit": "module"`.
pub(super) fn suffix(unit: AxisUnit) -> (&'static str, &'static str) {
    match unit {
        AxisUnit::Radian => ("_rad", "rad"),
        AxisUnit::Metre => ("_m", "m"),
        AxisUnit::ModuleUnit => ("", "module"),
    }
}

/// The record of `report` about `module`; `unit` (the module's kind's, as "rad" or "m") is an attribute
/// when given, as are `extras` (attributes only: not in `to_dict()`).
pub(super) fn record<'py, T: serde::Serialize>(
    py: Python<'py>,
    module: u8,
    report: &T,
    kind: Option<ModuleKind>,
    extras: &[(&str, f64)],
) -> PyResult<Record<'py>> {
    let r = Record::of(py, FAMILY, report)?;
    r.set("module", module)?;
    let mut hidden = Vec::new();
    if let Some(kind) = kind {
        r.set("unit", kind.unit())?;
        hidden.push("unit");
    }
    for (name, value) in extras {
        r.set(name, *value)?;
        hidden.push(*name);
    }
    if !hidden.is_empty() {
        r.extras(&hidden)?;
    }
    Ok(r)
}

/// The state word as the CLI's `powercube state --json` prints it (the module's fields at the top).
pub(super) fn state_record<'py>(py: Python<'py>, module: u8, s: CubeState) -> PyResult<Record<'py>> {
    record(py, module, &StateReport(s), None, &[])
}

pub(super) fn get_record<'py>(py: Python<'py>, module: u8, reading: &ParamReading) -> PyResult<Record<'py>> {
    record(py, module, reading, None, &[])
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

/// A checked move as the CLI's `powercube move --json` prints it, with where the module stood before (`start_rad` / `start_m`) as an attribute.
pub(super) fn move_record<'py>(py: Python<'py>, module: u8, m: &MoveReport) -> PyResult<Record<'py>> {
    let start = format!("start_{}", m.kind.unit());
    record(py, module, &Acted::reached(m), Some(m.kind), &[(&start, f32_py(m.start.value()))])
}

/// A motion of any mode as the CLI's `powercube motion --json` prints it.
pub(super) fn motion_record<'py>(py: Python<'py>, module: u8, m: &MotionReport) -> PyResult<Record<'py>> {
    record(py, module, &Acted::ran(m), Some(m.kind), &[])
}

/// A streamed setpoint's acknowledge: `{mode, ext_ack, watchdog}` with the module.
pub(super) fn setpoint_record<'py>(py: Python<'py>, module: u8, r: &SetpointReport) -> PyResult<Record<'py>> {
    record(py, module, r, Some(r.kind), &[])
}

/// A confirmed halt as the CLI's `powercube stop --json` prints it, but `holder` (the command line's own).
pub(super) fn halt_record<'py>(py: Python<'py>, module: u8, h: &HaltReport) -> PyResult<Record<'py>> {
    let halted = Acted { holder: None::<Option<()>>, ..Acted::halted(h, None::<()>) };
    record(py, module, &halted, Some(h.kind), &[])
}

/// The end of homing as the CLI's `powercube home --json` prints it.
pub(super) fn home_record<'py>(py: Python<'py>, module: u8, h: &HomeReport) -> PyResult<Record<'py>> {
    record(py, module, &Acted::homed(h), Some(h.kind), &[])
}

/// A parameter written as the CLI's `powercube set --json` prints it; its unit and access are attributes,
/// as `get` has them.
pub(super) fn set_record<'py>(py: Python<'py>, module: u8, kind: ModuleKind, w: &SetReport) -> PyResult<Record<'py>> {
    let r = record(py, module, w, None, &[])?;
    r.set("unit", w.param.unit().symbol(kind))?.set("access", w.param.access().short())?;
    r.extras(&["unit", "access"])?;
    Ok(r)
}

/// A sample of `watch` as the CLI's `powercube watch --json` prints it (without `t_s`, which Python adds).
pub(super) fn sample_record<'py>(
    py: Python<'py>,
    module: u8,
    kind: ModuleKind,
    position: Position,
    state: CubeState,
) -> PyResult<Record<'py>> {
    record(py, module, &Sample { kind, position, state }, Some(kind), &[])
}
