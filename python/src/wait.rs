//! How the bindings wait: without the GIL, and for long operations with an eye on Python's signal
//! handlers (Ctrl-C), and the small tokio runtime the async clients open and close their sessions on.

use std::future::Future;
use std::pin::Pin;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::task::{Poll, Waker};
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::lock;
use motionlink_link::driver::OpFuture;
use motionlink_link::session::Session;
use motionlink_link::LinkError;
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
    // What became of the call: 0 running, 1 ended, 2 abandoned (the worker then resets the token). One
    // lock decides, so a token is never left cancelled by a worker that ended just as Ctrl-C came.
    let state = Arc::new(Mutex::new(0u8));
    let (tx, rx) = mpsc::channel();
    let (shared, worker_token) = (Arc::clone(&state), token.clone());
    std::thread::Builder::new()
        .name("motionlink-read".into())
        .spawn(move || {
            let out = op();
            let mut s = lock(&shared);
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
                    let mut s = lock(&state);
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
/// [`NativeTask::cancel`] stops it: it returns once what the operation set in motion has stopped.
#[pyclass(frozen, module = "motionlink._native")]
pub struct NativeTask(Task);

/// What a task and its [`NativeTask`] share: the state, and the signal of its end.
type Task = Arc<(Mutex<TaskState>, Condvar)>;

#[derive(Default)]
struct TaskState {
    /// [`NativeTask::cancel`] was called.
    requested: bool,
    /// The task awaits an operation through [`stoppable`]: a cancel makes the session stop it, and the task
    /// awaits its end, instead of being dropped.
    in_op: bool,
    /// Wakes the task to see `requested`.
    waker: Option<Waker>,
    /// The task has ended, its future dropped (set by [`Ended`], a panic included).
    ended: bool,
    /// How a cancelled task's operation, or its stop, failed (for [`NativeTask::cancel`] to hand on).
    failed: Option<crate::errors::Failure>,
}

/// Marks its task ended when dropped, after the task's future.
struct Ended(Task);

impl Drop for Ended {
    fn drop(&mut self) {
        lock(&self.0 .0).ended = true;
        self.0 .1.notify_all();
    }
}

tokio::task_local! {
    /// The task being polled, for [`stoppable`].
    static TASK: Task;
}

/// What an async operation hands to Python: built, with the GIL, on the delivery thread.
pub type Deliver = Box<dyn for<'py> FnOnce(Python<'py>) -> PyResult<Py<PyAny>> + Send>;

/// The outcome of an async operation: a value to build in Python, or a failure.
pub type Outcome = Result<Deliver, crate::errors::Failure>;

/// An outcome and the callback that gets it.
type Delivery = (Py<PyAny>, Outcome);

/// Whether the delivery thread may still call into Python: true until [`stop_deliveries`]. The delivery
/// thread holds this lock for as long as it runs a callback, so that closing the gate waits for the
/// callback in flight.
static DELIVERING: Mutex<bool> = Mutex::new(true);

/// The thread that turns outcomes into Python objects and calls their `done` callbacks: the runtime's
/// thread never waits for the GIL (a session's timers, such as a watchdog's refresh, run there).
///
/// It is no Python thread: once the interpreter finalises, a thread that is not Python's own and asks for
/// the GIL back (a callback gives it up whenever it does I/O or runs long enough, and `loop.
/// call_soon_threadsafe` writes to a socket) is ended by CPython with `pthread_exit`, whose unwinding runs
/// pyo3's guard and aborts the process ("Fatal Python error: PyGILState_Release"). So the package's exit
/// handler calls [`stop_deliveries`] before the interpreter finalises, and this thread never touches Python
/// after that; an outcome that arrives later is dropped (nobody waits for it any more).
fn delivery() -> &'static Mutex<mpsc::Sender<Delivery>> {
    static TX: OnceLock<Mutex<mpsc::Sender<Delivery>>> = OnceLock::new();
    TX.get_or_init(|| {
        let (tx, rx) = mpsc::channel::<Delivery>();
        std::thread::Builder::new()
            .name("motionlink-deliver".into())
            .spawn(move || {
                for (done, outcome) in rx {
                    let open = lock(&DELIVERING);
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
        Mutex::new(tx)
    })
}

/// Ends the calls into Python from the delivery thread, for good: waits (without the GIL) for a callback
/// in flight to return, then makes the thread drop every later outcome. The package's exit handler calls
/// it (`motionlink._base`), after it has closed the clients still open, before the interpreter finalises.
#[pyfunction]
pub fn stop_deliveries(py: Python<'_>) {
    py.detach(|| *lock(&DELIVERING) = false);
}

/// A [`Deliver`] from a closure.
pub fn deliver(f: impl for<'py> FnOnce(Python<'py>) -> PyResult<Py<PyAny>> + Send + 'static) -> Outcome {
    Ok(Box::new(f))
}

/// Runs `fut` on [`runtime`] and calls `done(True, value)` or `done(False, exception)` with its outcome
/// (from the delivery thread). The family's futures are polled there, not by asyncio: their wake-ups
/// never wait for the GIL. Cancelling the task ([`NativeTask::cancel`]) drops `fut` (what it set in motion
/// stops as its futures' drops stop it), unless it awaits a [`stoppable`] operation.
pub fn spawn_task<F>(done: Py<PyAny>, fut: F) -> NativeTask
where
    F: Future<Output = Outcome> + Send + 'static,
{
    spawn_task_stopping(done, fut, async { Ok(()) })
}

/// As [`spawn_task`], for an operation whose own future, when dropped, does not stop the motion it waits
/// for (a wait for another call's motion): cancelling the task drops `fut`, then runs `stop` (a halt) to
/// its end, and only then does [`NativeTask::cancel`] return (with the stop's failure, if it failed).
pub fn spawn_task_stopping<F, S>(done: Py<PyAny>, fut: F, stop: S) -> NativeTask
where
    F: Future<Output = Outcome> + Send + 'static,
    S: Future<Output = Result<(), crate::errors::Failure>> + Send + 'static,
{
    let task: Task = Default::default();
    let seen = Arc::clone(&task);
    runtime().spawn(async move {
        let _ended = Ended(Arc::clone(&seen));
        let mut fut = Box::pin(TASK.scope(Arc::clone(&seen), fut));
        let out = std::future::poll_fn(|cx| {
            {
                let mut st = lock(&seen.0);
                if st.requested && !st.in_op {
                    return Poll::Ready(None);
                }
                st.waker = Some(cx.waker().clone());
            }
            fut.as_mut().poll(cx).map(Some)
        })
        .await;
        let failed = match out {
            Some(out) if !lock(&seen.0).requested => {
                let _ = lock(delivery()).send((done, out));
                return;
            }
            // Cancelled while a stoppable operation ran: it ended, stopped (or its stop failed).
            Some(out) => out.err(),
            None => {
                drop(fut);
                stop.await.err()
            }
        };
        lock(&seen.0).failed = failed;
    });
    NativeTask(task)
}

/// Awaits `op`, an operation of a family's session that sets something in motion, so that cancelling the
/// task ([`NativeTask::cancel`]) cancels the operation (`OpFuture::cancel`: the session stops what it set
/// in motion) and the task still awaits its end, whose outcome the cancel hands on: nothing when the stop
/// was confirmed, the error that says it was not. `take` takes the operation's result out of the output.
pub async fn stoppable<S: Session, T>(mut op: OpFuture<S>, take: fn(S::Output) -> Option<T>) -> Result<T, S::Error> {
    let task = TASK.try_with(Arc::clone).ok();
    let mut cancelled = false;
    let out = std::future::poll_fn(|cx| {
        if let Some(t) = &task {
            let mut st = lock(&t.0);
            st.in_op = true;
            if st.requested && !cancelled {
                cancelled = true;
                drop(st);
                op.cancel();
            }
        }
        Pin::new(&mut op).poll(cx)
    })
    .await;
    if let Some(t) = &task {
        lock(&t.0).in_op = false;
    }
    take(out?).ok_or_else(|| {
        let other = std::io::Error::other("the session answered with the output of another operation");
        LinkError::Io { port: String::new(), source: Arc::new(other) }.into()
    })
}

#[pymethods]
impl NativeTask {
    /// Cancels the operation and returns once it has ended (without the GIL; call it from a worker thread,
    /// not from the event loop): an operation awaited through [`stoppable`] once the session has stopped
    /// what it set in motion, any other once its future is dropped (and the task's own stop, if any, has
    /// run). The `done` callback is not called. Returns the exception of a cancelled operation, or its
    /// stop, that failed (a stop not confirmed: `stop_unconfirmed`), else None; a second cancel waits as
    /// well, and returns None.
    fn cancel(&self, py: Python<'_>) -> Option<Py<PyAny>> {
        let (state, ended) = &*self.0;
        let failed = py.detach(|| {
            let mut st = lock(state);
            st.requested = true;
            if let Some(w) = st.waker.take() {
                w.wake();
            }
            while !st.ended {
                st = ended.wait(st).unwrap_or_else(std::sync::PoisonError::into_inner);
            }
            st.failed.take()
        });
        failed.map(|f| crate::errors::to_pyerr(py, f).into_value(py).into_any())
    }

    /// True once the operation has ended (or was cancelled).
    #[getter]
    fn done(&self) -> bool {
        lock(&self.0 .0).ended
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
