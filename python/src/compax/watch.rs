//! `Compax.watch`: the library's watch (`Op::Watch`: S1 and S17 on the drive's schedule), run on a thread
//! of its own with a cancel token of its own, its samples handed to Python one by one.

use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Mutex;
use std::thread::JoinHandle;
use std::time::Instant;

use motionlink_compax::report::Timed;
use motionlink_compax::session::{Op, Progress, WatchSample};
use motionlink_link::clock::lock;

use super::*;
use crate::wait::SIGNAL_CHECK;

/// How many samples wait for Python at most; a watch whose reader lags drops the newer ones.
const BACKLOG: usize = 64;

/// One sample, or how the watch ended.
type Item = Result<(f64, WatchSample), Failure>;

/// A running watch of one drive (the native half of `Compax.watch`'s iterator).
#[pyclass(frozen, module = "motionlink._native")]
pub struct CompaxWatch {
    rx: Mutex<Option<mpsc::Receiver<Item>>>,
    token: CancelToken,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl CompaxWatch {
    /// Starts `client`'s watch of `drive` every `interval`.
    pub fn start(client: Arc<Client>, drive: Address, interval: Duration) -> CompaxWatch {
        let token = CancelToken::new();
        let (tx, rx) = mpsc::sync_channel::<Item>(BACKLOG);
        let own = token.clone();
        let thread = std::thread::Builder::new()
            .name("motionlink-watch".into())
            .spawn(move || {
                let started = Instant::now();
                let mut report = |p: &Progress| {
                    if let Progress::Watch(s) = p {
                        let _ = tx.try_send(Ok((started.elapsed().as_secs_f64(), *s)));
                    }
                };
                let ended = client.driver().run_with(Op::Watch(drive, interval), &mut report, Some(&own));
                if let Err(e) = ended {
                    if !own.is_cancelled() {
                        let _ = tx.send(Err(e.failure()));
                    }
                }
            })
            .ok();
        CompaxWatch { rx: Mutex::new(Some(rx)), token, thread: Mutex::new(thread) }
    }

    /// The token that ends the watch.
    pub fn token(&self) -> CancelToken {
        self.token.clone()
    }

    fn end(&self) {
        self.token.cancel();
        let thread = lock(&self.thread).take();
        if let Some(t) = thread {
            let _ = t.join();
        }
    }
}

#[pymethods]
impl CompaxWatch {
    /// The next sample: `family`, `drive`, `t_s`, `position_units`, `s17` (a flag word with `pattern`) and
    /// `moving` (the library's `WatchSample::moving`). Waits without the GIL; Ctrl-C ends the watch and
    /// raises. A watch that ended raises what ended it.
    fn next<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let taken = if self.token.is_cancelled() { None } else { lock(&self.rx).take() };
        let Some(mut rx) = taken else {
            return Err(to_pyerr(py, usage("the watch has ended (closed, or its client was)")));
        };
        loop {
            let (got, back) = py.detach(move || (rx.recv_timeout(SIGNAL_CHECK), rx));
            rx = back;
            match got {
                Ok(Ok((t_s, s))) => {
                    *lock(&self.rx) = Some(rx);
                    return Ok(record(py, &Timed { t_s, sample: s })?.done());
                }
                Ok(Err(f)) => return Err(to_pyerr(py, f)),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(interrupt) = py.check_signals() {
                        py.detach(|| self.end());
                        return Err(interrupt);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(to_pyerr(py, usage("the watch has ended (its client was closed)")));
                }
            }
        }
    }

    /// Ends the watch (the library's watch op is cancelled; nothing is in motion by it).
    fn close(&self, py: Python<'_>) {
        py.detach(|| self.end());
    }
}

impl Drop for CompaxWatch {
    fn drop(&mut self) {
        self.token.cancel();
    }
}
