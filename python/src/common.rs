//! What the three families' bindings share: where a client connects, records (dicts with the field names
//! of the command line's JSON), and the slot a client lives in until it is closed.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::lock;
use motionlink_link::url::PortUrl;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt, PyString};

use crate::errors::Failure;

/// `obj` as an argument's value is shown in a usage error: its `repr`.
fn shown(obj: &Borrowed<'_, '_, PyAny>) -> String {
    obj.repr().map(|r| r.to_string()).unwrap_or_else(|_| "the value".into())
}

/// The name of `obj`'s type with its article, for a usage error ("a str", "an int", "a NoneType").
fn type_name(obj: &Borrowed<'_, '_, PyAny>) -> String {
    let name = obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "object".into());
    let vowel = name.chars().next().is_some_and(|c| "aeiouAEIOU".contains(c));
    format!("{} {name}", if vowel { "an" } else { "a" })
}

/// An integer argument as Python passes it: any `int` (however wide), or something else, kept for the
/// usage error that names the argument and its range (instead of an `OverflowError` or a `TypeError`).
pub struct Int(Result<i64, String>);

impl<'a, 'py> FromPyObject<'a, 'py> for Int {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.is_instance_of::<PyBool>() {
            return Ok(Int(Err(format!("{} (a bool)", shown(&obj)))));
        }
        if obj.is_instance_of::<PyInt>() {
            return Ok(Int(obj.extract::<i64>().map_err(|_| shown(&obj))));
        }
        Ok(Int(Err(format!("{} ({}, not an int)", shown(&obj), type_name(&obj)))))
    }
}

/// A number argument as Python passes it: an `int` or a `float` (or anything else Python's `float()`
/// takes, a text aside), or something else, a bool included, kept for the usage error that names the
/// argument and its value (instead of a `TypeError`, or a bool taken as 0.0 or 1.0). The one extractor of
/// every float argument of the bindings.
pub struct Float(Result<f64, String>);

impl<'a, 'py> FromPyObject<'a, 'py> for Float {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.is_instance_of::<PyBool>() {
            return Ok(Float(Err(format!("{} (a bool)", shown(&obj)))));
        }
        Ok(Float(obj.extract::<f64>().map_err(|_| {
            if obj.is_instance_of::<PyInt>() {
                format!("{} (an int too large for a float)", shown(&obj))
            } else {
                format!("{} ({}, not a number)", shown(&obj), type_name(&obj))
            }
        })))
    }
}

impl Float {
    /// The number, or a usage error of `family` naming `name` and the value given.
    pub fn get(&self, family: &'static str, name: &str) -> Result<f64, Failure> {
        self.0.clone().map_err(|shown| Failure::usage(family, format!("{name} {shown}: give a number")))
    }
}

/// An optional number argument checked as [`Float::get`] does.
pub fn opt_float(v: Option<&Float>, family: &'static str, name: &str) -> Result<Option<f64>, Failure> {
    v.map(|f| f.get(family, name)).transpose()
}

/// A bool argument as Python passes it (`True`, `False`), or something else, kept for the usage error that
/// names the argument and its value (instead of a `TypeError`; a truthy value is no bool either).
pub struct Bool(Result<bool, String>);

impl<'a, 'py> FromPyObject<'a, 'py> for Bool {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        Ok(Bool(obj.extract::<bool>().map_err(|_| format!("{} ({}, not a bool)", shown(&obj), type_name(&obj)))))
    }
}

impl Bool {
    /// The bool, or a usage error of `family` naming `name` and the value given.
    pub fn get(&self, family: &'static str, name: &str) -> Result<bool, Failure> {
        self.0.clone().map_err(|shown| Failure::usage(family, format!("{name} {shown}: give True or False")))
    }
}

/// A text argument as Python passes it (a `str`), or something else, kept for the usage error that names
/// the argument and its value (instead of a `TypeError`).
pub struct Text(Result<String, String>);

impl<'a, 'py> FromPyObject<'a, 'py> for Text {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.is_instance_of::<PyString>() {
            return Ok(Text(obj.extract::<String>().map_err(|_| shown(&obj))));
        }
        Ok(Text(Err(format!("{} ({}, not a str)", shown(&obj), type_name(&obj)))))
    }
}

impl Text {
    /// The text, or a usage error of `family` naming `name` and the value given.
    pub fn get(&self, family: &'static str, name: &str) -> Result<&str, Failure> {
        self.0.as_deref().map_err(|shown| Failure::usage(family, format!("{name} {shown}: give a str")))
    }
}

/// An optional text argument checked as [`Text::get`] does.
pub fn opt_text<'t>(v: Option<&'t Text>, family: &'static str, name: &str) -> Result<Option<&'t str>, Failure> {
    v.map(|t| t.get(family, name)).transpose()
}

impl Int {
    /// The integer as a `T` if it lies in `range`, else a usage error of `family` naming `name` and the
    /// range.
    pub fn within<T: TryFrom<i64>>(
        &self,
        family: &'static str,
        name: &str,
        range: std::ops::RangeInclusive<i64>,
    ) -> Result<T, Failure> {
        let out = || {
            let shown = match &self.0 {
                Ok(v) => v.to_string(),
                Err(s) => s.clone(),
            };
            Failure::usage(family, format!("{name} {shown}: give a whole number {}..={}", range.start(), range.end()))
        };
        match self.0 {
            Ok(v) if range.contains(&v) => T::try_from(v).map_err(|_| out()),
            _ => Err(out()),
        }
    }
}

/// An optional integer argument checked as [`Int::within`] does.
pub fn opt_within<T: TryFrom<i64>>(
    v: Option<&Int>,
    family: &'static str,
    name: &str,
    range: std::ops::RangeInclusive<i64>,
) -> Result<Option<T>, Failure> {
    v.map(|i| i.within(family, name, range)).transpose()
}

/// A float of the wire (f32) as Python sees it: the shortest decimal that reads back as the same f32
/// (0.05, not 0.05000000074505806).
pub fn f32_py(x: f32) -> f64 {
    if x.is_finite() {
        x.to_string().parse().unwrap_or(f64::from(x))
    } else {
        f64::from(x)
    }
}

/// A library report (anything that derives or implements `serde::Serialize`) as a JSON value with the
/// names its serialisation gives: the command line's `--json`. The one conversion of every result: the
/// report goes through its JSON text, so that a float of the wire (f32) reads as the command line prints
/// it (0.05, not 0.05000000074505806).
pub fn report_value<T: serde::Serialize + ?Sized>(report: &T) -> PyResult<serde_json::Value> {
    let bad = |e: serde_json::Error| {
        pyo3::exceptions::PyValueError::new_err(format!("a report that does not serialise: {e}"))
    };
    serde_json::from_str(&serde_json::to_string(report).map_err(bad)?).map_err(bad)
}

/// A library report as Python objects (see [`report_value`]).
pub fn report_py<'py, T: serde::Serialize + ?Sized>(py: Python<'py>, report: &T) -> PyResult<Bound<'py, PyAny>> {
    json_py(py, &report_value(report)?)
}

/// A record under construction: a dict with the names of naming.md.
pub struct Record<'py>(pub Bound<'py, PyDict>);

impl<'py> Record<'py> {
    /// An empty record.
    pub fn new(py: Python<'py>) -> Self {
        Record(PyDict::new(py))
    }

    /// The record of a library report (see [`report_py`]) whose serialisation is a map, with `family` first.
    pub fn of<T: serde::Serialize + ?Sized>(py: Python<'py>, family: &str, report: &T) -> PyResult<Self> {
        let fields = report_py(py, report)?.cast_into::<PyDict>()?;
        let r = Record::new(py);
        r.set("family", family)?;
        r.0.update(fields.as_mapping())?;
        Ok(r)
    }

    /// Sets `key` (conversion errors are Python errors).
    pub fn set<V: IntoPyObject<'py>>(&self, key: &str, value: V) -> PyResult<&Self> {
        self.0.set_item(key, value)?;
        Ok(self)
    }

    /// Names fields of this record that Python gives as attributes but leaves out of `to_dict()` (which
    /// has exactly the command line's `--json` keys): `motionlink.records.Record` takes the list out.
    pub fn extras(&self, names: &[&str]) -> PyResult<&Self> {
        self.set("_extras", names.to_vec())
    }

    /// The dict.
    pub fn done(self) -> Bound<'py, PyDict> {
        self.0
    }
}

impl<'py> IntoPyObject<'py> for Record<'py> {
    type Target = PyDict;
    type Output = Bound<'py, PyDict>;
    type Error = std::convert::Infallible;

    fn into_pyobject(self, _py: Python<'py>) -> Result<Self::Output, Self::Error> {
        Ok(self.0)
    }
}

/// A client of any family, shared by the calls under way, until it is closed. A call takes a clone of the
/// `Arc` (so a close waits for nothing but the calls' own ends); closing takes the client out, so that no
/// new call starts, and cancels what still runs before it ends the session.
pub struct Slot<C> {
    client: Mutex<Option<Arc<C>>>,
    family: &'static str,
}

impl<C> Slot<C> {
    /// A slot holding `client`.
    pub fn new(client: C, family: &'static str) -> Self {
        Slot { client: Mutex::new(Some(Arc::new(client))), family }
    }

    /// The client, or a usage error once it is closed.
    pub fn get(&self) -> Result<Arc<C>, Failure> {
        lock(&self.client).clone().ok_or_else(|| Failure::usage(self.family, "the client is closed"))
    }

    /// The client, as a Python call takes it: a usage error once it is closed.
    pub fn client(&self, py: Python<'_>) -> PyResult<Arc<C>> {
        self.get().map_err(|f| crate::errors::to_pyerr(py, f))
    }

    /// True until [`Slot::take`].
    pub fn is_open(&self) -> bool {
        lock(&self.client).is_some()
    }

    /// Takes the client out for closing. Calls of other threads still under way are cancelled through
    /// `token` (their motions stop) and waited for, at most `bound`; `None` when it was closed already.
    /// If they have not ended by then, the client is returned anyway inside its `Arc`: the caller then
    /// stops what it started through it, and the session ends when the last call drops it.
    pub fn take(&self, token: &CancelToken, bound: Duration) -> Option<Result<C, Arc<C>>> {
        let arc = lock(&self.client).take()?;
        let deadline = Instant::now() + bound;
        let mut cancelled = false;
        let mut arc = arc;
        loop {
            match Arc::try_unwrap(arc) {
                Ok(c) => {
                    if cancelled {
                        token.reset();
                    }
                    return Some(Ok(c));
                }
                Err(shared) => {
                    if !cancelled {
                        token.cancel();
                        cancelled = true;
                    }
                    if Instant::now() >= deadline {
                        return Some(Err(shared));
                    }
                    std::thread::sleep(Duration::from_millis(2));
                    arc = shared;
                }
            }
        }
    }
}

/// A JSON value of a family's table (`Value::to_json`) as the Python object `json.loads` would make.
pub fn json_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::types::PyList;
    Ok(match v {
        serde_json::Value::Null => py.None().into_bound(py),
        serde_json::Value::Bool(b) => pyo3::types::PyBool::new(py, *b).to_owned().into_any(),
        serde_json::Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        serde_json::Value::String(s) => s.into_pyobject(py)?.into_any(),
        serde_json::Value::Array(a) => {
            let list = PyList::empty(py);
            for x in a {
                list.append(json_py(py, x)?)?;
            }
            list.into_any()
        }
        serde_json::Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// What a client made of the device profiles (profiles.toml beside devices.toml) when it opened: the
/// profile it took (`<path>#<key>`) and the notices about those it did not take.
pub type ProfileUse = motionlink_link::profile::ProfileUse;

/// The profiles a client's `profile` setting names: `None` or `"auto"` the default file (profiles.toml
/// beside devices.toml), `"off"` none, anything else the path of a profiles file. A file that cannot be read
/// is a notice, not a failure: the session then probes as without it.
pub fn profiles(setting: Option<&str>) -> Result<Option<motionlink_link::profile::Profiles>, String> {
    use motionlink_link::profile::Profiles;
    let loaded = match setting {
        Some("off") => return Ok(None),
        None | Some("auto") => Profiles::load_default(),
        Some(path) => Profiles::load(std::path::Path::new(path)).map(Some),
    };
    loaded.map_err(|e| format!("device profiles not used: {e}"))
}

/// Where to look up the profile of the client's device on `port` (`None`: an emulator in this process, which
/// has no profile): `Ok((profiles, port))` for the family's `use_profile`, or `Err` with what the client
/// makes of profiles without looking (none, or the notice of a file it could not read).
pub fn profile_lookup(
    setting: Option<&str>,
    port: Option<&str>,
) -> Result<(motionlink_link::profile::Profiles, String), ProfileUse> {
    let Some(port) = port else { return Err(ProfileUse::default()) };
    match profiles(setting) {
        Ok(Some(p)) => Ok((p, port.to_string())),
        Ok(None) => Err(ProfileUse::default()),
        Err(notice) => Err(ProfileUse { reference: None, notices: vec![notice] }),
    }
}

/// The setup of a probe of the client's port (`None`: an emulator in this process) at `baud`, with the
/// probe's arguments `exchanges` (the library's rule, [`motionlink_link::probe::ProbeSetup::EXCHANGES`]) and
/// `low_latency` checked.
pub fn probe_setup(
    family: &'static str,
    port: Option<&str>,
    baud: u32,
    exchanges: &Int,
    low_latency: &Bool,
) -> Result<motionlink_link::probe::ProbeSetup, Failure> {
    use motionlink_link::probe::{PortKind, ProbeSetup};
    let range = ProbeSetup::EXCHANGES;
    let exchanges: u32 = exchanges.within(family, "exchanges", i64::from(*range.start())..=i64::from(*range.end()))?;
    let low_latency = low_latency.get(family, "low_latency")?;
    let kind = port.and_then(|p| p.parse::<PortUrl>().ok()).map_or(PortKind::Sim, |u| PortKind::of(&u));
    let mut setup = ProbeSetup::new(port.unwrap_or("in-process emulator"), kind, baud);
    setup.exchanges = exchanges;
    setup.low_latency = low_latency;
    Ok(setup)
}

/// A probe's report (nothing moves) as Python objects: `probe` runs without the GIL; with `save` (`""`: the
/// default profiles file, else a path) `save_profile` then writes the profile of each device it found there,
/// keyed by `port` (the port as given; `None`, an emulator object in this process, has none: refused).
pub fn probe_py<'py, R: serde::Serialize>(
    py: Python<'py>,
    family: &'static str,
    port: Option<&str>,
    save: Option<String>,
    probe: impl FnOnce() -> Result<R, Failure> + Send,
    save_profile: fn(
        &mut R,
        &mut motionlink_link::profile::Profiles,
    ) -> Result<(), motionlink_link::profile::ProfileError>,
) -> PyResult<Bound<'py, PyAny>> {
    let usage = |e: String| Failure::usage(family, e);
    if save.is_some() && port.is_none() {
        return Err(crate::errors::to_pyerr(
            py,
            usage(
                "save: a motionlink.Emulator object has no port to key a profile by (no later session could take \
                 it); probe port=\"sim\", or the emulator served (serve=\"tcp\") by its URL"
                    .into(),
            ),
        ));
    }
    let report = py
        .detach(|| {
            let mut report = probe()?;
            if let Some(save) = save {
                let mut profiles = profiles_for_save(family, &save)?;
                save_profile(&mut report, &mut profiles).map_err(|e| usage(format!("save: {e}")))?;
            }
            serde_json::to_value(&report).map_err(|e| usage(e.to_string()))
        })
        .map_err(|f| crate::errors::to_pyerr(py, f))?;
    json_py(py, &report)
}

/// The profiles file `save` names: `""` the default one (profiles.toml beside devices.toml), else a path.
pub fn profiles_for_save(family: &'static str, save: &str) -> Result<motionlink_link::profile::Profiles, Failure> {
    use motionlink_link::profile::{profiles_path, Profiles};
    let path = if save.is_empty() {
        profiles_path().ok_or_else(|| {
            Failure::usage(family, "save: no configuration directory is known (set MOTIONLINK_CONFIG)")
        })?
    } else {
        std::path::PathBuf::from(save)
    };
    Profiles::load(&path).map_err(|e| Failure::usage(family, format!("save: {e}")))
}
