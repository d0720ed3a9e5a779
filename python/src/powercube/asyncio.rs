//! The asyncio half of `motionlink.AsyncPowerCube`.

use super::*;

/// An async session with PowerCube modules (the native half of `motionlink.AsyncPowerCube`): the long
/// operations are coroutines; cancelling one (its task) halts the module.
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncPowerCubeClient {
    slot: Slot<AsyncClient>,
    guard: Guard,
    module: u8,
    port: String,
    profile: crate::common::ProfileUse,
}

impl AsyncPowerCubeClient {
    fn client(&self) -> Result<Arc<AsyncClient>, PyErr> {
        Python::attach(|py| self.slot.get().map_err(|f| to_pyerr(py, f)))
    }

    fn address(&self, py: Python<'_>, module: Option<Int>) -> PyResult<u8> {
        address_or(self.module, py, module)
    }
}

fn raise<T>(r: Result<T, Error>) -> Result<T, Failure> {
    r.map_err(|e| e.failure())
}

fn dict<F>(f: F) -> Outcome
where
    F: for<'py> FnOnce(Python<'py>) -> PyResult<Record<'py>> + Send + 'static,
{
    deliver(move |py| Ok(f(py)?.done().into_any().unbind()))
}

#[pymethods]
impl AsyncPowerCubeClient {
    /// Opens a session on the runtime (the port is opened on its blocking pool); `done(ok, client)`.
    #[staticmethod]
    fn open(
        py: Python<'_>,
        port: &Bound<'_, PyAny>,
        settings: &Bound<'_, PyAny>,
        done: Py<PyAny>,
    ) -> PyResult<NativeTask> {
        let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
        let s: Settings = settings.extract()?;
        Ok(spawn_task(done, async move {
            let module = module_address(&s.module)?;
            let watchdog = s.watchdog;
            let (client, in_process, profile) =
                crate::wait::on_blocking_pool(FAMILY, move || open_profiled(t, &s)).await?;
            let client = raise(AsyncClient::open(move || Ok(client)).await)?;
            let port = client.port().to_string();
            let guard = Guard::for_motions(ModulesAt::emulated_in_process(in_process), !watchdog);
            let native = AsyncPowerCubeClient { slot: Slot::new(client, FAMILY), guard, module, port, profile };
            deliver(move |py| Ok(Py::new(py, native)?.into_any()))
        }))
    }

    /// The port, as the link describes it.
    #[getter]
    fn port(&self) -> String {
        self.port.clone()
    }

    /// The device profile the session took for its module (`<path>#<key>`), or None.
    #[getter]
    fn profile(&self) -> Option<String> {
        self.profile.reference.clone()
    }

    /// One line for each profile the session did not take (another identity, a file it could not read).
    #[getter]
    fn profile_notices(&self) -> Vec<String> {
        self.profile.notices.clone()
    }

    /// The actual position: `done(ok, (value, unit))`.
    #[pyo3(signature = (module, done))]
    fn position(&self, py: Python<'_>, module: Option<Int>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client()?;
        let a = self.address(py, module)?;
        Ok(spawn_task(done, async move {
            let p = raise(
                async {
                    let m = c.module(Address::new(a)?);
                    let kind = m.kind().await?;
                    Ok(in_unit(m.position().await?, kind))
                }
                .await,
            )?;
            deliver(move |py| Ok((a, f32_py(p.value()), suffix(p.unit()).1).into_pyobject(py)?.into_any().unbind()))
        }))
    }

    /// The state word: `done(ok, dict)`.
    #[pyo3(signature = (module, done))]
    fn state(&self, py: Python<'_>, module: Option<Int>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client()?;
        let a = self.address(py, module)?;
        Ok(spawn_task(done, async move {
            let s = raise(async { c.module(Address::new(a)?).state().await }.await)?;
            dict(move |py| state_record(py, a, s))
        }))
    }

    /// Homes and waits; cancelling the task halts the module.
    #[pyo3(signature = (module, timeout_s, done))]
    fn home(&self, py: Python<'_>, module: Option<Int>, timeout_s: f64, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client()?;
        let a = self.address(py, module)?;
        let timeout = seconds(timeout_s).map_err(|f| to_pyerr(py, f))?;
        let guard = self.guard;
        Ok(spawn_task(done, async move {
            let r = raise(async { c.module(Address::new(a)?).home_guarded(timeout, guard).await }.await)?;
            dict(move |py| home_record(py, a, &r))
        }))
    }

    /// A checked move, waited for; cancelling the task halts the module.
    #[pyo3(signature = (target, module, velocity, acceleration, tolerance, timeout_s, done))]
    #[allow(clippy::too_many_arguments)]
    fn move_to(
        &self,
        py: Python<'_>,
        target: f64,
        module: Option<Int>,
        velocity: Option<f64>,
        acceleration: Option<f64>,
        tolerance: Option<f64>,
        timeout_s: f64,
        done: Py<PyAny>,
    ) -> PyResult<NativeTask> {
        let c = self.client()?;
        let a = self.address(py, module)?;
        let spec = move_spec(target, velocity, acceleration, tolerance, timeout_s).map_err(|f| to_pyerr(py, f))?;
        let guard = self.guard;
        Ok(spawn_task(done, async move {
            let report = raise(async { c.module(Address::new(a)?).move_to_guarded(&spec, guard).await }.await)?;
            dict(move |py| move_record(py, a, &report))
        }))
    }

    /// Waits until the module stands still (no STATE_MOTION); cancelling the task halts it (the wait's
    /// future stops nothing when dropped: the motion may be another call's, so the module is halted here).
    #[pyo3(signature = (module, timeout_s, done))]
    fn wait(&self, py: Python<'_>, module: Option<Int>, timeout_s: f64, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client()?;
        let a = self.address(py, module)?;
        let timeout = seconds(timeout_s).map_err(|f| to_pyerr(py, f))?;
        let halting = Arc::clone(&c);
        let halt = async move {
            if let Err(e) = async { halting.module(Address::new(a)?).halt().await }.await {
                crate::wait::say_stop_failed(&format!("module {a}: the halt after a cancelled wait failed: {e}"));
            }
        };
        Ok(spawn_task_stopping(
            done,
            async move {
                let s = raise(async { c.module(Address::new(a)?).wait_motion_end(timeout).await }.await)?;
                dict(move |py| state_record(py, a, s))
            },
            halt,
        ))
    }

    /// Halts the module.
    #[pyo3(signature = (module, done))]
    fn stop(&self, py: Python<'_>, module: Option<Int>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client()?;
        let a = self.address(py, module)?;
        Ok(spawn_task(done, async move {
            raise(async { c.module(Address::new(a)?).halt().await }.await)?;
            deliver(|py| Ok(py.None()))
        }))
    }

    /// Ends the session (halts what it set in motion): `done(ok, None)`.
    fn close(&self, done: Py<PyAny>) -> NativeTask {
        let taken = self.slot.take(&CancelToken::new(), Duration::ZERO);
        spawn_task(done, async move {
            match taken {
                None => {}
                Some(Ok(client)) => raise(client.close().await)?,
                Some(Err(shared)) => raise(shared.halt_started().await)?,
            }
            deliver(|py| Ok(py.None()))
        })
    }

    /// Ends the session from synchronous code (atexit), waiting without the GIL.
    fn close_blocking(&self, py: Python<'_>) -> PyResult<()> {
        let Some(taken) = self.slot.take(&CancelToken::new(), Duration::ZERO) else { return Ok(()) };
        let r = match taken {
            Ok(client) => block_on_runtime(py, client.close())?,
            Err(shared) => block_on_runtime(py, async move { shared.halt_started().await })?,
        };
        r.or_raise(py)
    }
}

impl Drop for AsyncPowerCubeClient {
    fn drop(&mut self) {
        // Not closed by its owner: the session ends on the runtime's blocking pool (stopping what it
        // started), not on the thread that happens to drop the object (which may hold the GIL).
        if let Some(taken) = self.slot.take(&CancelToken::new(), Duration::ZERO) {
            crate::wait::runtime().spawn(async move { drop(taken) });
        }
    }
}

impl Drop for PowerCubeClient {
    fn drop(&mut self) {
        // Not closed by its owner (garbage-collected): the session ends here, stopping what it started as
        // the family's client does when dropped, without holding the GIL while it waits for the device.
        if let Some(taken) = self.slot.take(&self.token, self.close_bound) {
            Python::attach(|py| py.detach(move || drop(taken)));
        }
    }
}
