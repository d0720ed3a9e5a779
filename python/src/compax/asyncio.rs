//! The asyncio half of `motionlink.AsyncCompax`.

use super::*;

/// An async session with COMPAX drives (the native half of `motionlink.AsyncCompax`): cancelling a move's,
/// a homing's or a wait's task drops its future, which stops the drive (OUTPUT O0=0, confirmed by S17).
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncCompaxClient {
    slot: Slot<AsyncClient>,
    drive: Address,
    port: String,
    profile: crate::common::ProfileUse,
}

impl AsyncCompaxClient {
    fn client(&self, py: Python<'_>) -> PyResult<Arc<AsyncClient>> {
        self.slot.get().map_err(|f| to_pyerr(py, f))
    }

    fn drive(&self, py: Python<'_>, drive: Option<Int>) -> PyResult<Address> {
        drive.map_or(Ok(self.drive), |d| whole(&d, "drive")).map_err(|f| to_pyerr(py, f))
    }
}

fn fail<T>(r: Result<T, Error>) -> Result<T, Failure> {
    r.map_err(|e| e.failure())
}

fn units(p: Position) -> crate::wait::Outcome {
    deliver(move |py| Ok(p.units().into_pyobject(py)?.into_any().unbind()))
}

fn at(a: Address, p: Position) -> crate::wait::Outcome {
    deliver(move |py| Ok(position_record(py, a, p)?.done().into_any().unbind()))
}

#[pymethods]
impl AsyncCompaxClient {
    /// Opens a session on the runtime (the port on its blocking pool): `done(ok, client)`.
    #[staticmethod]
    fn open(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings, done: Py<PyAny>) -> PyResult<NativeTask> {
        let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
        let port = match &t {
            Target::InProcess(_) => "in-process emulator".to_string(),
            Target::Url(u) => u.to_string(),
        };
        let lookup =
            crate::common::profile_lookup(settings.profile.as_deref(), crate::common::profile_port(&t).as_deref());
        Ok(spawn_task(done, async move {
            let drive = whole(&settings.drive, "drive")?;
            let (link, cfg) = crate::wait::on_blocking_pool(FAMILY, move || link(t, &settings)).await?;
            let client = fail(AsyncClient::new(link, clock(), cfg))?;
            let profile = match lookup {
                Ok((p, port)) => fail(motionlink_compax::probe::use_profile_async(&client, &p, &port, drive).await)?,
                Err(used) => used,
            };
            let native = AsyncCompaxClient { slot: Slot::new(client, FAMILY), drive, port, profile };
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

    /// The actual position S1: `done(ok, float)`.
    #[pyo3(signature = (drive, done))]
    fn position(&self, py: Python<'_>, drive: Option<Int>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        Ok(spawn_task(done, async move { units(fail(c.read_position(a).await)?) }))
    }

    /// A checked move, waited for; cancelling the task stops the drive.
    #[pyo3(signature = (target, distance, drive, speed_percent, ramp_ms, min_units, max_units, timeout_s, done))]
    #[allow(clippy::too_many_arguments)]
    fn move_to(
        &self,
        py: Python<'_>,
        target: Option<f64>,
        distance: Option<f64>,
        drive: Option<Int>,
        speed_percent: Option<f64>,
        ramp_ms: Option<Int>,
        min_units: Option<f64>,
        max_units: Option<f64>,
        timeout_s: f64,
        done: Py<PyAny>,
    ) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let request =
            move_request(target, distance, speed_percent, ramp_ms.as_ref(), (min_units, max_units), timeout_s)
                .map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            let report = fail(c.move_to(a, &request).await)?;
            deliver(move |py| Ok(move_record(py, &report)?.done().into_any().unbind()))
        }))
    }

    /// POSA HOME, waited for; cancelling the task stops the drive.
    #[pyo3(signature = (drive, timeout_s, done))]
    fn home(&self, py: Python<'_>, drive: Option<Int>, timeout_s: f64, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let timeout = seconds(timeout_s).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            match fail(c.start(Op::Move(a, Command::PosAHome, MoveOptions::default())).await)? {
                Output::Done => {}
                other => {
                    return Err(Failure::new(
                        motionlink_link::error::ErrorClass::Transport(motionlink_link::error::TransportKind::Corrupt),
                        FAMILY,
                        format!("the session answered {other:?} to POSA HOME"),
                    ))
                }
            }
            fail(c.wait_reached(&[a], Some(timeout)).await)?;
            at(a, fail(c.read_position(a).await)?)
        }))
    }

    /// Waits until the drive's positioning ended; its position then. Cancelling the task stops the drive.
    #[pyo3(signature = (drive, timeout_s, done))]
    fn wait(&self, py: Python<'_>, drive: Option<Int>, timeout_s: f64, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let timeout = seconds(timeout_s).map_err(|f| to_pyerr(py, f))?;
        // The wait's future stops nothing when dropped (the motion may be another call's): a cancelled wait
        // stops the drive here (OUTPUT O0=0, confirmed by S17).
        let stopping = Arc::clone(&c);
        let stop = async move {
            if let Err(e) = stopping.stop(a).await {
                crate::wait::say_stop_failed(&format!("drive {a}: the stop after a cancelled wait failed: {e}"));
            }
        };
        Ok(crate::wait::spawn_task_stopping(
            done,
            async move {
                fail(c.wait_reached(&[a], Some(timeout)).await)?;
                at(a, fail(c.read_position(a).await)?)
            },
            stop,
        ))
    }

    /// Stops the drive (OUTPUT O0=0).
    #[pyo3(signature = (drive, done))]
    fn stop(&self, py: Python<'_>, drive: Option<Int>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        Ok(spawn_task(done, async move {
            fail(c.stop(a).await)?;
            deliver(|py| Ok(py.None()))
        }))
    }

    /// Ends the session (stops what it set in motion that still moves): `done(ok, None)`.
    fn close(&self, done: Py<PyAny>) -> NativeTask {
        let taken = self.slot.take(&CancelToken::new(), Duration::ZERO);
        spawn_task(done, async move {
            match taken {
                None => {}
                Some(Ok(client)) => {
                    fail(client.close().await)?;
                }
                Some(Err(shared)) => {
                    let report = shared.stop_started().await;
                    if !report.all_confirmed() {
                        return Err(Failure::new(
                            motionlink_link::error::ErrorClass::Device,
                            FAMILY,
                            format!("closing: {report}"),
                        ));
                    }
                }
            }
            deliver(|py| Ok(py.None()))
        })
    }

    /// Ends the session from synchronous code (atexit), waiting without the GIL.
    fn close_blocking(&self, py: Python<'_>) -> PyResult<()> {
        let Some(taken) = self.slot.take(&CancelToken::new(), Duration::ZERO) else { return Ok(()) };
        match taken {
            Ok(client) => block_on_runtime(py, client.close())?.or_raise(py).map(|_| ()),
            Err(shared) => {
                block_on_runtime(py, async move { shared.stop_started().await })?;
                Ok(())
            }
        }
    }
}
