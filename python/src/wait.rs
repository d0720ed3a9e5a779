//! How the bindings wait: without the GIL, and for long operations with an eye on Python's signal
//! handlers (Ctrl-C), and the small tokio runtime the async clients open and close their sessions on.

use std::future::Future;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::OnceLock;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often a long operation's waiting thread looks at Python's signal handlers: Ctrl-C is seen within
/// this, the motion is stopped, and `KeyboardInterrupt` raised (well within 100 ms in all).
pub const SIGNAL_CHECK: Duration = Duration::from_millis(20);

/// Runs `op` on a worker thread while the calling thread, without the GIL, waits for it and runs Python's
/// signal handlers every [`SIGNAL_CHECK`]. When a handler raises (`KeyboardInterrupt` for Ctrl-C,
/// `SystemExit` from a SIGTERM handler that calls `sys.exit`), `token` is cancelled, which makes the
/// family's session stop the motion `op` started; once `op` has returned (with its stop confirmed or
/// not), the handler's exception is raised with `op`'s own outcome as its `__cause__`.
///
/// `describe` turns `op`'s result into that cause (`None` when it ended well after all).
pub fn interruptible<T: Send>(
    py: Python<'_>,
    token: Option<&CancelToken>,
    op: impl FnOnce() -> T + Send,
    describe: impl FnOnce(Python<'_>, &T) -> Option<PyErr>,
) -> PyResult<T> {
    std::thread::scope(|scope| {
        let (tx, rx) = mpsc::channel();
        let worker = std::thread::Builder::new()
            .name("motionlink-call".into())
            .spawn_scoped(scope, move || {
                let _ = tx.send(op());
            })
            .map_err(|e| PyRuntimeError::new_err(format!("cannot start the operation's thread: {e}")))?;
        let mut rx = rx;
        loop {
            // The receiver is not Sync: it goes into the GIL-free wait and comes back out.
            let (got, back) = py.detach(move || (rx.recv_timeout(SIGNAL_CHECK), rx));
            rx = back;
            match got {
                Ok(value) => return Ok(value),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(interrupt) = py.check_signals() {
                        if let Some(t) = token {
                            t.cancel();
                        }
                        let outcome = py.detach(move || rx.recv());
                        if let Some(t) = token {
                            t.reset();
                        }
                        if let Ok(value) = &outcome {
                            if let Some(cause) = describe(py, value) {
                                interrupt.set_cause(py, Some(cause));
                            }
                        }
                        return Err(interrupt);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    let why = match worker.join() {
                        Err(p) => p.downcast_ref::<String>().cloned().unwrap_or_else(|| "a panic".into()),
                        Ok(()) => "no result".into(),
                    };
                    return Err(PyRuntimeError::new_err(format!("the operation's thread ended with {why}")));
                }
            }
        }
    })
}

/// Runs `op`, which only reads (it sets nothing in motion), on a thread of its own while the calling
/// thread, without the GIL, waits for it and runs Python's signal handlers every [`SIGNAL_CHECK`]. When a
/// handler raises (Ctrl-C), `token` (if given) is cancelled, so that a library operation that checks it
/// (the COMPAX scan before each address, the PowerCube scan at once) ends at its next step, and the handler's exception is raised
/// at once: a read in flight is not waited for (it ends on its thread within its reply timeout, its
/// result dropped; it then resets `token`). Later calls on the same session queue behind it on the line.
pub fn interruptible_read<T: Send + 'static>(
    py: Python<'_>,
    token: Option<CancelToken>,
    op: impl FnOnce() -> T + Send + 'static,
) -> PyResult<T> {
    use std::sync::{Arc, Mutex};
    // What became of the call: 0 running, 1 ended, 2 abandoned (the worker then resets the token). One
    // lock decides, so a token is never left cancelled by a worker that ended just as Ctrl-C came.
    let state = Arc::new(Mutex::new(0u8));
    let (tx, rx) = mpsc::channel();
    let (shared, worker_token) = (Arc::clone(&state), token.clone());
    std::thread::Builder::new()
        .name("motionlink-read".into())
        .spawn(move || {
            let out = op();
            let mut s = motionlink_link::clock::lock(&shared);
            if *s == 2 {
                if let Some(t) = worker_token {
                    t.reset();
                }
            }
            *s = 1;
            drop(s);
            let _ = tx.send(out);
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start the operation's thread: {e}")))?;
    let mut rx = rx;
    loop {
        let (got, back) = py.detach(move || (rx.recv_timeout(SIGNAL_CHECK), rx));
        rx = back;
        match got {
            Ok(value) => return Ok(value),
            Err(RecvTimeoutError::Timeout) => {
                if let Err(interrupt) = py.check_signals() {
                    let mut s = motionlink_link::clock::lock(&state);
                    if *s == 0 {
                        *s = 2;
                        if let Some(t) = &token {
                            t.cancel();
                        }
                    }
                    return Err(interrupt);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err("the operation's thread ended without a result"));
            }
        }
    }
}

/// The runtime the async clients' operations run on (one thread; opening uses its blocking pool).
pub fn runtime() -> &'static tokio::runtime::Handle {
    static RT: OnceLock<tokio::runtime::Handle> = OnceLock::new();
    RT.get_or_init(|| {
        let rt = tokio::runtime::Builder::new_current_thread()
            .thread_name("motionlink-tokio")
            .build()
            .expect("a current-thread tokio runtime builds without I/O drivers");
        let handle = rt.handle().clone();
        std::thread::Builder::new()
            .name("motionlink-runtime".into())
            .spawn(move || rt.block_on(std::future::pending::<()>()))
            .expect("the runtime's thread starts");
        handle
    })
}

/// Runs `fut` on [`runtime`] and waits for it here, without the GIL (for closing an async client from
/// synchronous code: `atexit`, a dropped object).
pub fn block_on_runtime<T: Send + 'static>(
    py: Python<'_>,
    fut: impl Future<Output = T> + Send + 'static,
) -> PyResult<T> {
    let (tx, rx) = mpsc::channel();
    runtime().spawn(async move {
        let _ = tx.send(fut.await);
    });
    py.detach(move || rx.recv()).map_err(|_| PyRuntimeError::new_err("the runtime's task ended without a result"))
}

/// An async operation running on [`runtime`], as Python sees it: its outcome is handed to a callback
/// (`done(ok, value)`, which the Python side turns into the result of an asyncio future), and
/// [`NativeTask::cancel`] drops the operation's future, which stops what it set in motion.
#[pyclass(frozen, module = "motionlink._native")]
pub struct NativeTask {
    handle: std::sync::Mutex<Option<tokio::task::JoinHandle<()>>>,
    /// For a task with a stop of its own ([`spawn_task_stopping`]): how `cancel` tells it.
    stop: Option<StopFlag>,
}

/// Set by [`NativeTask::cancel`] for a task of [`spawn_task_stopping`]; the waker wakes it to see that.
#[derive(Default)]
struct StopState {
    requested: bool,
    waker: Option<std::task::Waker>,
}

type StopFlag = std::sync::Arc<std::sync::Mutex<StopState>>;

/// What an async operation hands to Python: built, with the GIL, on the delivery thread.
pub type Deliver = Box<dyn for<'py> FnOnce(Python<'py>) -> PyResult<Py<PyAny>> + Send>;

/// The outcome of an async operation: a value to build in Python, or a failure.
pub type Outcome = Result<Deliver, crate::errors::Failure>;

/// An outcome and the callback that gets it.
type Delivery = (Py<PyAny>, Outcome);

/// Whether the delivery thread may still call into Python: true until [`stop_deliveries`]. The delivery
/// thread holds this lock for as long as it runs a callback, so that closing the gate waits for the
/// callback in flight.
static DELIVERING: std::sync::Mutex<bool> = std::sync::Mutex::new(true);

/// The thread that turns outcomes into Python objects and calls their `done` callbacks: the runtime's
/// thread never waits for the GIL (a session's timers, such as a watchdog's refresh, run there).
///
/// It is no Python thread: once the interpreter finalises, a thread that is not Python's own and asks for
/// the GIL back (a callback gives it up whenever it does I/O or runs long enough, and `loop.
/// call_soon_threadsafe` writes to a socket) is ended by CPython with `pthread_exit`, whose unwinding runs
/// pyo3's guard and aborts the process ("Fatal Python error: PyGILState_Release"). So the package's exit
/// handler calls [`stop_deliveries`] before the interpreter finalises, and this thread never touches Python
/// after that; an outcome that arrives later is dropped (nobody waits for it any more).
fn delivery() -> &'static std::sync::Mutex<mpsc::Sender<Delivery>> {
    static TX: OnceLock<std::sync::Mutex<mpsc::Sender<Delivery>>> = OnceLock::new();
    TX.get_or_init(|| {
        let (tx, rx) = mpsc::channel::<Delivery>();
        std::thread::Builder::new()
            .name("motionlink-deliver".into())
            .spawn(move || {
                for (done, outcome) in rx {
                    let open = motionlink_link::clock::lock(&DELIVERING);
                    if !*open {
                        // `done` is dropped without the GIL: pyo3 defers its reference count to a pool.
                        continue;
                    }
                    // `try_attach`: never attach to an interpreter that is finalising already.
                    Python::try_attach(|py| {
                        let built = match outcome {
                            Ok(make) => make(py),
                            Err(f) => Err(crate::errors::to_pyerr(py, f)),
                        };
                        let (ok, value) = match built {
                            Ok(v) => (true, v),
                            Err(e) => (false, e.into_value(py).into_any()),
                        };
                        if let Err(e) = done.call1(py, (ok, value)) {
                            e.write_unraisable(py, None);
                        }
                    });
                    drop(open);
                }
            })
            .expect("the delivery thread starts");
        std::sync::Mutex::new(tx)
    })
}

/// Ends the calls into Python from the delivery thread, for good: waits (without the GIL) for a callback
/// in flight to return, then makes the thread drop every later outcome. The package's exit handler calls
/// it (`motionlink._base`), after it has closed the clients still open, before the interpreter finalises.
#[pyfunction]
pub fn stop_deliveries(py: Python<'_>) {
    py.detach(|| *motionlink_link::clock::lock(&DELIVERING) = false);
}

/// A [`Deliver`] from a closure.
pub fn deliver(f: impl for<'py> FnOnce(Python<'py>) -> PyResult<Py<PyAny>> + Send + 'static) -> Outcome {
    Ok(Box::new(f))
}

/// Runs `fut` on [`runtime`] and calls `done(True, value)` or `done(False, exception)` with its outcome
/// (from the delivery thread). The family's futures are polled there, not by asyncio: their wake-ups
/// never wait for the GIL.
pub fn spawn_task<F>(done: Py<PyAny>, fut: F) -> NativeTask
where
    F: Future<Output = Outcome> + Send + 'static,
{
    let handle = runtime().spawn(async move {
        let out = fut.await;
        let _ = motionlink_link::clock::lock(delivery()).send((done, out));
    });
    NativeTask { handle: std::sync::Mutex::new(Some(handle)), stop: None }
}

/// Says on stderr that the stop after a cancelled operation failed (nobody awaits the task any more to get
/// it as an exception).
pub fn say_stop_failed(message: &str) {
    eprintln!("motionlink: {message}");
}

/// As [`spawn_task`], for an operation whose own future, when dropped, does not stop the motion it waits
/// for (a wait for another call's motion): cancelling the task drops `fut`, then runs `stop` (a halt) to
/// its end, and only then does [`NativeTask::cancel`] return.
pub fn spawn_task_stopping<F, S>(done: Py<PyAny>, fut: F, stop: S) -> NativeTask
where
    F: Future<Output = Outcome> + Send + 'static,
    S: Future<Output = ()> + Send + 'static,
{
    use motionlink_link::clock::lock;
    let flag: StopFlag = Default::default();
    let seen = std::sync::Arc::clone(&flag);
    let handle = runtime().spawn(async move {
        let mut fut = Box::pin(fut);
        let out = std::future::poll_fn(|cx| {
            {
                let mut st = lock(&seen);
                if st.requested {
                    return std::task::Poll::Ready(None);
                }
                st.waker = Some(cx.waker().clone());
            }
            fut.as_mut().poll(cx).map(Some)
        })
        .await;
        match out {
            Some(out) => {
                let _ = lock(delivery()).send((done, out));
            }
            None => {
                drop(fut);
                stop.await;
            }
        }
    });
    NativeTask { handle: std::sync::Mutex::new(Some(handle)), stop: Some(flag) }
}

#[pymethods]
impl NativeTask {
    /// Cancels the operation: its future is dropped (a motion it started is stopped, as the family's
    /// async client does for a dropped future), and this returns once that has happened (without the GIL;
    /// call it from a worker thread, not from the event loop). The `done` callback is not called.
    fn cancel(&self, py: Python<'_>) {
        let handle = motionlink_link::clock::lock(&self.handle).take();
        if let Some(h) = handle {
            match &self.stop {
                // The task drops its operation and runs its stop; this waits for both.
                Some(flag) => {
                    let waker = {
                        let mut st = motionlink_link::clock::lock(flag);
                        st.requested = true;
                        st.waker.take()
                    };
                    if let Some(w) = waker {
                        w.wake();
                    }
                }
                None => h.abort(),
            }
            let (tx, rx) = mpsc::channel();
            runtime().spawn(async move {
                let _ = h.await;
                let _ = tx.send(());
            });
            let _ = py.detach(move || rx.recv());
        }
    }

    /// True once the operation has ended (or was cancelled).
    #[getter]
    fn done(&self) -> bool {
        motionlink_link::clock::lock(&self.handle).as_ref().is_none_or(|h| h.is_finished())
    }
}

/// Runs the blocking `work` (opening a port) on tokio's blocking pool; a task that failed to run is a
/// transport error of `family`.
pub async fn on_blocking_pool<T: Send + 'static>(
    family: &'static str,
    work: impl FnOnce() -> Result<T, crate::errors::Failure> + Send + 'static,
) -> Result<T, crate::errors::Failure> {
    tokio::task::spawn_blocking(work).await.map_err(|e| {
        crate::errors::Failure::new(
            motionlink_link::error::ErrorClass::Transport(motionlink_link::error::TransportKind::Io),
            family,
            format!("the opening task failed: {e}"),
        )
    })?
}
