//! The asyncio half of `motionlink.AsyncScu`.

use super::*;

/// An async session with an SCU (the native half of `motionlink.AsyncScu`): the operations run on the
/// library's runtime; cancelling a move's or a run's task drops its future, which stops the function
/// (fast RS, confirmed).
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncScuClient {
    slot: Slot<AsyncClient>,
    port: String,
    speed_mode: SpeedMode,
    profile: crate::common::ProfileUse,
}

impl AsyncScuClient {
    fn client(&self, py: Python<'_>) -> PyResult<Arc<AsyncClient>> {
        self.slot.get().map_err(|f| to_pyerr(py, f))
    }
}

pub(super) fn fail<T>(r: Result<T, Error>) -> Result<T, Failure> {
    r.map_err(|e| e.failure())
}

#[pymethods]
impl AsyncScuClient {
    /// Opens a session on the runtime: `done(ok, client)`.
    #[staticmethod]
    fn open(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings, done: Py<PyAny>) -> PyResult<NativeTask> {
        let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
        let lookup = crate::common::profile_lookup(settings.profile.as_deref(), port_url(&t).as_deref());
        let (connector, config) = connector(t, &settings).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            let client = fail(AsyncClient::open(connector, clock(), config).await)?;
            let profile = match lookup {
                Ok((p, port)) => fail(motionlink_scu::probe::use_profile_async(&client, &p, &port).await)?,
                Err(used) => used,
            };
            let port = client.port().to_string();
            let speed_mode = client.config().speed_mode;
            let native = AsyncScuClient { slot: Slot::new(client, FAMILY), port, speed_mode, profile };
            deliver(move |py| Ok(Py::new(py, native)?.into_any()))
        }))
    }

    /// The port.
    #[getter]
    fn port(&self) -> String {
        self.port.clone()
    }

    /// The device profile the session took (`<path>#<key>`), or None.
    #[getter]
    fn profile(&self) -> Option<String> {
        self.profile.reference.clone()
    }

    /// One line for each profile the session did not take (another identity, a file it could not read).
    #[getter]
    fn profile_notices(&self) -> Vec<String> {
        self.profile.notices.clone()
    }

    /// The position of an actuator in counts: `done(ok, int)`.
    fn position(&self, py: Python<'_>, actuator: Int, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self::actuator(&actuator).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            let p = fail(c.position(a).await)?;
            deliver(move |py| Ok(p.get().into_pyobject(py)?.into_any().unbind()))
        }))
    }

    /// A verified move; cancelling the task stops the function.
    #[pyo3(signature = (actuator, target_counts, speed, function, done))]
    fn move_to(
        &self,
        py: Python<'_>,
        actuator: Int,
        target_counts: Int,
        speed: Int,
        function: Option<Int>,
        done: Py<PyAny>,
    ) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let (a, target, f, speed) = move_args(&actuator, &target_counts, function.as_ref(), &speed, self.speed_mode)
            .map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            let report = fail(c.move_to(a, target, speed, f).await)?;
            deliver(move |py| Ok(move_py(py, &report)?.unbind()))
        }))
    }

    /// Runs a function until it ends (or `seconds`), then stops it; cancelling the task stops it.
    #[pyo3(signature = (function, direction, seconds, done))]
    fn run(
        &self,
        py: Python<'_>,
        function: &str,
        direction: &str,
        seconds: Option<f64>,
        done: Py<PyAny>,
    ) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let (action, limit) = run_args(function, direction, seconds).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            let report = fail(c.run_function(action, limit).await)?;
            deliver(move |py| Ok(run_py(py, &report)?.unbind()))
        }))
    }

    /// Stops what moves, as [`ScuClient::stop`]: `done(ok, report)` with no function (every motion function,
    /// confirmed), `done(ok, None)` with one.
    #[pyo3(signature = (function, soft, done))]
    fn stop(&self, py: Python<'_>, function: Option<&str>, soft: bool, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let what = stop_what(function, soft).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            match what {
                StopWhat::Every(mode) => {
                    let all: Vec<MotionFunction> = MotionFunction::all().collect();
                    let report = fail(c.stop_functions(&all, mode).await)?;
                    deliver(move |py| Ok(report_py(py, &report, |_| {})?.unbind()))
                }
                StopWhat::One(f, mode) => {
                    fail(match f {
                        Function::Motion(m) => c.stop_motion(m, mode).await,
                        f => c.switch(f, false).await,
                    })?;
                    deliver(|py| Ok(py.None()))
                }
            }
        }))
    }

    /// Ends the session (RS for what it started, then RA): `done(ok, None)`.
    fn close(&self, done: Py<PyAny>) -> NativeTask {
        let taken = self.slot.take(&CancelToken::new(), Duration::ZERO);
        spawn_task(done, async move {
            match taken {
                None => {}
                Some(Ok(client)) => fail(client.close().await)?,
                // A call still under way holds the session: it ends (RS, RA) when that call ends.
                Some(Err(shared)) => drop(shared),
            }
            deliver(|py| Ok(py.None()))
        })
    }

    /// Ends the session from synchronous code (atexit), waiting without the GIL.
    fn close_blocking(&self, py: Python<'_>) -> PyResult<()> {
        let Some(taken) = self.slot.take(&CancelToken::new(), Duration::ZERO) else { return Ok(()) };
        match taken {
            Ok(client) => block_on_runtime(py, client.close())?.or_raise(py),
            Err(shared) => {
                drop(shared);
                Ok(())
            }
        }
    }
}
