//! Test-only helpers of the motionlink workspace, kept out of the libraries' public API. Used as a
//! dev-dependency only.
//!
//! - [`alloc_count`]: a counting global allocator, for tests that prove a codec does not allocate.
//! - [`load`]: busy threads beside a benchmark (a loaded host).
//! - [`wired`]: any family's sans-IO session wired straight to its emulator on a time the test moves.
//! - [`rig`]: any family's client over an in-memory link to its emulator, on a manual clock.
//! - [`join2`]: two futures polled together (two operations of one async client at once).

#![warn(missing_docs)]

pub mod alloc_count;
pub mod load;
pub mod rig;
pub mod wired;

/// Two futures polled together until both are done (what `tokio::join!` does, without tokio's macros): their
/// outputs.
pub async fn join2<A: std::future::Future, B: std::future::Future>(a: A, b: B) -> (A::Output, B::Output) {
    use std::task::Poll;
    let (mut a, mut b) = (Box::pin(a), Box::pin(b));
    let (mut out_a, mut out_b) = (None, None);
    std::future::poll_fn(|cx| {
        if out_a.is_none() {
            if let Poll::Ready(v) = a.as_mut().poll(cx) {
                out_a = Some(v);
            }
        }
        if out_b.is_none() {
            if let Poll::Ready(v) = b.as_mut().poll(cx) {
                out_b = Some(v);
            }
        }
        match (out_a.take(), out_b.take()) {
            (Some(x), Some(y)) => Poll::Ready((x, y)),
            (x, y) => {
                (out_a, out_b) = (x, y);
                Poll::Pending
            }
        }
    })
    .await
}
