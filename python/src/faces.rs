//! One declaration per operation for both faces of a family's native client: [`faces!`] turns each into
//! the blocking method (the family's `Client`, run without the GIL, Ctrl-C watched) and the async method
//! (the family's `AsyncClient`, spawned on the runtime, its outcome handed to a `done` callback).

use pyo3::prelude::*;
use pyo3::IntoPyObjectExt;

/// The Python object of an operation's record.
pub fn to_py<'py, T: IntoPyObject<'py>>(py: Python<'py>, record: PyResult<T>) -> PyResult<Py<PyAny>> {
    record?.into_py_any(py)
}

/// Declares the operations of a family's blocking native client `B` and async native client `A` once:
///
/// ```text
/// faces! {
///     B / A, Error;
///     both { methods of B and A } blocking { other methods of B } asynch { other methods of A }
///     /// Doc.
///     motion wait(me, py, module: Option<Int>, timeout_s: f64) {
///         let a = me.address(py, module)?;          // arguments checked (both faces)
///     } |c| { w!(c.module(..) => wait_motion_end(t); &mut |_| {}) }   // the operation
///     else |c| { .. }                               // async only: what a cancelled task stops
///     => |py, state| state_record(py, a, state);    // the record (a PyResult)
///     /// Doc.
///     blocking read info(me, py) {} |c| { c.info() } => |py, i| info_record(py, &i);  // B only
/// }
/// ```
///
/// In the operation, `w!(call)` is the call on the blocking client and `call.await` on the async one;
/// `w!(recv => method(args); p, .. => q, ..)` passes `p, ..` (a progress callback, a cancel token) to the
/// blocking client's method only and `q, ..` to the async client's only; `w!(call; async op => Output::V)`
/// is `call` on the blocking client and, on the async one, the operation `op` (an `OpFuture`) awaited
/// through [`crate::wait::stoppable`], its result that of the output `V`. The blocking face runs it as its
/// kind says: `read` on a thread of its own, Ctrl-C raising at once ([`crate::wait::interruptible_read`]);
/// `scan` so too, Ctrl-C also cancelling the client's token (`me.token`: the library's scan ends at its
/// next step); `motion` on a worker while Ctrl-C is watched, which cancels the token (the family's client
/// stops the motion) and waits for the end ([`crate::wait::interruptible`]); `quick` without the GIL. The
/// async face spawns it: cancelling the task lets a [`crate::wait::stoppable`] motion stop and end, else
/// drops its future (the family's client stops what it set in motion) and runs the `else` future (whose
/// error is the cancel's). An operation marked `blocking` is the blocking client's only.
/// Both classes get the getters `port`, `profile` and `profile_notices` of their fields of those names,
/// `is_open`, `started` and `close` (the async class `close_blocking`) from the family's
/// [`crate::session::Session`] / [`crate::session::AsyncSession`] over their field `slot` (the blocking
/// class's `token` and `close_bound` too), and a `Drop` that ends a session its owner did not close.
/// (A `let` among the argument checks takes no type annotation, which the macro's `stmt` does not parse: a
/// turbofish says the type instead.)
macro_rules! faces {
    // An operation of the blocking client: its method.
    (@munch ($d:tt) [$blocking:ident $asynch:ident $err:ty] {$($b:tt)*} {$($a:tt)*}
        $(#[doc = $doc:literal])*
        blocking $kind:ident $name:ident ($me:ident, $py:ident $(, $arg:ident : $ty:ty)*)
            { $($prep:stmt;)* }
            |$c:ident| $body:block
            $(else |$sc:ident| $stop:block)?
            => |$rpy:ident, $out:pat_param| $record:expr;
        $($rest:tt)*
    ) => {
        faces!(@munch ($d) [$blocking $asynch $err] {
            $($b)*
            $(#[doc = $doc])*
            #[allow(clippy::too_many_arguments, clippy::redundant_locals, unused_braces, clippy::let_unit_value)]
            fn $name(&self, $py: Python<'_>, $($arg: $ty),*) -> PyResult<Py<PyAny>> {
                let $me = self;
                let $c = $me.slot.client($py)?;
                $($prep;)*
                #[allow(unused_macros)]
                macro_rules! w {
                    ($d b:expr; async $d op:expr => $d out:path) => { $d b };
                    (
                        $d r:expr => $d m:ident($d ($d a:expr),*)
                        $d (; $d ($d p:expr),+)? $d (=> $d ($d q:expr),+)?
                    ) => {
                        $d r.$d m($d ($d a,)* $d ($d ($d p),+)?)
                    };
                    ($d e:expr) => { $d e };
                }
                let run = move || -> Result<_, $err> { $body };
                let $out = faces!(@blocking $kind, $me, $py, run).or_raise($py)?;
                let $rpy = $py;
                crate::faces::to_py($py, $record)
            }
        } {$($a)*} $($rest)*);
    };
    // An operation of both clients: the async client's method, then the blocking client's.
    (@munch ($d:tt) [$blocking:ident $asynch:ident $err:ty] {$($b:tt)*} {$($a:tt)*}
        $(#[doc = $doc:literal])*
        $kind:ident $name:ident ($me:ident, $py:ident $(, $arg:ident : $ty:ty)*)
            { $($prep:stmt;)* }
            |$c:ident| $body:block
            $(else |$sc:ident| $stop:block)?
            => |$rpy:ident, $out:pat_param| $record:expr;
        $($rest:tt)*
    ) => {
        faces!(@munch ($d) [$blocking $asynch $err] {$($b)*} {
            $($a)*
            $(#[doc = $doc])*
            #[allow(clippy::too_many_arguments, clippy::redundant_locals, unused_braces, clippy::let_unit_value)]
            fn $name(&self, $py: Python<'_>, $($arg: $ty,)* done: Py<PyAny>) -> PyResult<NativeTask> {
                let $me = self;
                let $c = $me.slot.client($py)?;
                $($prep;)*
                #[allow(unused_macros)]
                macro_rules! w {
                    ($d b:expr; async $d op:expr => $d out:path) => {
                        crate::wait::stoppable($d op, |o| match o { $d out(r) => Some(r), _ => None }).await
                    };
                    (
                        $d r:expr => $d m:ident($d ($d a:expr),*)
                        $d (; $d ($d p:expr),+)? $d (=> $d ($d q:expr),+)?
                    ) => {
                        $d r.$d m($d ($d a,)* $d ($d ($d q),+)?).await
                    };
                    ($d e:expr) => { $d e.await };
                }
                $(let $sc = std::sync::Arc::clone(&$c);)?
                let run = async move {
                    let out: Result<_, $err> = async move $body.await;
                    let $out = out.map_err(|e| e.failure())?;
                    crate::wait::deliver(move |$rpy| crate::faces::to_py($rpy, $record))
                };
                faces!(@spawn done, run $(, async move {
                    let stopped: Result<_, $err> = async move $stop.await;
                    stopped.map(drop).map_err(|e| e.failure())
                })?)
            }
        }
            $(#[doc = $doc])*
            blocking $kind $name ($me, $py $(, $arg : $ty)*) { $($prep;)* } |$c| $body => |$rpy, $out| $record;
            $($rest)*
        );
    };
    // Every operation declared: the two classes' methods.
    (@munch ($d:tt) [$blocking:ident $asynch:ident $err:ty] {$($b:tt)*} {$($a:tt)*}) => {
        #[pymethods]
        impl $blocking {
            $($b)*
        }

        #[pymethods]
        impl $asynch {
            $($a)*
        }
    };
    (@blocking read, $me:ident, $py:ident, $run:ident) => {
        crate::wait::interruptible_read($py, None, $run)?
    };
    (@blocking scan, $me:ident, $py:ident, $run:ident) => {
        crate::wait::interruptible_read($py, Some($me.token.clone()), $run)?
    };
    (@blocking quick, $me:ident, $py:ident, $run:ident) => {
        $py.detach($run)
    };
    (@blocking motion, $me:ident, $py:ident, $run:ident) => {
        crate::wait::interruptible($py, Some(&$me.token), $run, |py, r| {
            r.as_ref().err().map(|e| crate::errors::to_pyerr(py, e.failure()))
        })?
    };
    (@spawn $done:ident, $run:ident) => {
        Ok(crate::wait::spawn_task($done, $run))
    };
    (@spawn $done:ident, $run:ident, $stop:expr) => {
        Ok(crate::wait::spawn_task_stopping($done, $run, $stop))
    };
    (@start $heads:tt both { $($both:tt)* } blocking { $($bextra:tt)* } asynch { $($aextra:tt)* } $($ops:tt)*) => {
        faces!(@munch ($) $heads { $($both)* $($bextra)* } { $($both)* $($aextra)* } $($ops)*);
    };
    ($blocking:ident / $asynch:ident, $err:ty; both { $($both:tt)* } blocking { $($bextra:tt)* } asynch { $($aextra:tt)* } $($rest:tt)*) => {
        impl Drop for $blocking {
            fn drop(&mut self) {
                crate::faces::Closing::closing(self);
                crate::session::drop_unclosed(&self.slot, &self.token, self.close_bound);
            }
        }

        impl Drop for $asynch {
            fn drop(&mut self) {
                crate::session::drop_unclosed_async(&self.slot);
            }
        }

        faces!(@start [$blocking $asynch $err]
            both {
                /// The port, as the link describes it.
                #[getter]
                fn port(&self) -> String {
                    self.port.clone()
                }

                /// The device profile the session took (`<path>#<key>`), or None.
                #[getter]
                fn profile(&self) -> Option<String> {
                    self.profile.reference.clone()
                }

                /// One line for each profile the session did not take (another identity, a file it could
                /// not read).
                #[getter]
                fn profile_notices(&self) -> Vec<String> {
                    self.profile.notices.clone()
                }

                /// True until closed.
                #[getter]
                fn is_open(&self) -> bool {
                    self.slot.is_open()
                }

                $($both)*
            }
            blocking {
                /// The ids of what this session set in motion and has not seen stop (SCU motion function
                /// numbers 1..10, PowerCube module and COMPAX drive addresses).
                fn started(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
                    Ok(crate::session::Session::started_ids(&*self.slot.client(py)?))
                }

                /// Ends the session: stops what it set in motion (the family's `close`); the ids of what it
                /// stopped (an exception if that was not confirmed). Closing twice does nothing.
                fn close(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
                    crate::faces::Closing::closing(self);
                    crate::session::close(py, &self.slot, &self.token, self.close_bound)
                }

                $($bextra)*
            }
            asynch {
                /// The ids of what this session set in motion and has not seen stop.
                fn started(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
                    Ok(crate::session::AsyncSession::started_ids(&*self.slot.client(py)?))
                }

                /// Ends the session (stops what it set in motion), waiting without the GIL (`aclose` calls it on
                /// a worker thread, the exit handler directly): the ids of what it stopped.
                fn close_blocking(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
                    crate::session::close_async_blocking(py, &self.slot)
                }

                $($aextra)*
            }
            $($rest)*
        );
    };
}

/// What a blocking native client ends before its session closes (COMPAX: the watches still running).
pub trait Closing {
    /// Called by `close()` and by a drop of a client not closed, before the session ends.
    fn closing(&self) {}
}
