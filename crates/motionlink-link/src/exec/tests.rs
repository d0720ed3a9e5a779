use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use super::*;

#[derive(Default)]
struct Core {
    jobs: Jobs<u32>,
    /// Tickets opened, in order.
    asked: Vec<Ticket>,
}

type Exec = Executor<Core, u32, Result<u32, &'static str>>;

fn exec() -> Exec {
    Executor::new(Core::default(), Timestamp::ZERO)
}

fn ms(n: u64) -> Timestamp {
    Timestamp::from_millis(n)
}

async fn ask(ctx: &Ctx<Core, u32>) -> u32 {
    let ticket = {
        let mut core = ctx.core();
        let t = core.jobs.open(ctx.id());
        core.asked.push(t);
        t
    };
    ctx.job(ticket, |c: &mut Core| &mut c.jobs).await
}

fn run(exec: &mut Exec) -> Vec<Report<u32, Result<u32, &'static str>>> {
    let mut out = Vec::new();
    exec.run(|r| out.push(r));
    out
}

/// Counts the polls of a future.
struct Counted<F> {
    inner: F,
    polls: Arc<AtomicUsize>,
}

impl<F: Future + Unpin> Future for Counted<F> {
    type Output = F::Output;
    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<F::Output> {
        self.polls.fetch_add(1, Ordering::SeqCst);
        Pin::new(&mut self.inner).poll(cx)
    }
}

#[test]
fn an_operation_sleeps_on_the_session_clock_and_is_polled_only_when_due() {
    let mut exec = exec();
    let polls = Arc::new(AtomicUsize::new(0));
    let id = exec.next_id();
    let counter = Arc::clone(&polls);
    exec.spawn(id, move |ctx| Counted {
        inner: Box::pin(async move {
            ctx.sleep_until(ms(100)).await;
            Ok(ctx.now().as_millis() as u32)
        }),
        polls: counter,
    });
    assert!(run(&mut exec).is_empty());
    assert_eq!(exec.poll_timeout(), Some(ms(100)));
    exec.handle_timeout(ms(50));
    assert!(run(&mut exec).is_empty());
    assert_eq!(polls.load(Ordering::SeqCst), 1, "not polled before its time");
    exec.handle_timeout(ms(100));
    assert_eq!(run(&mut exec), vec![Report::Done(id, Ok(100))]);
    assert_eq!(polls.load(Ordering::SeqCst), 2);
    assert!(exec.is_empty());
    assert_eq!(exec.poll_timeout(), None);
}

#[test]
fn a_finished_job_wakes_only_the_operation_that_awaits_it() {
    let mut exec = exec();
    let (a, b) = (exec.next_id(), exec.next_id());
    let polls_b = Arc::new(AtomicUsize::new(0));
    exec.spawn(a, |ctx| async move { Ok(ask(&ctx).await) });
    let counter = Arc::clone(&polls_b);
    exec.spawn(b, move |ctx| Counted { inner: Box::pin(async move { Ok(ask(&ctx).await * 2) }), polls: counter });
    assert!(run(&mut exec).is_empty());
    let asked = exec.core().asked.clone();
    assert_eq!(exec.core().jobs.owner(asked[0]), Some(a));
    assert!(exec.core().jobs.finish(asked[0], 7));
    assert_eq!(run(&mut exec), vec![Report::Done(a, Ok(7))]);
    assert_eq!(polls_b.load(Ordering::SeqCst), 1, "b was not woken");
    assert!(exec.core().jobs.finish(asked[1], 4));
    assert_eq!(run(&mut exec), vec![Report::Done(b, Ok(8))]);
    assert!(exec.core().jobs.is_empty());
}

#[test]
fn a_cancel_ends_an_interruptible_sleep_and_not_the_other() {
    let mut exec = exec();
    let (firm, soft) = (exec.next_id(), exec.next_id());
    exec.spawn(firm, |ctx| async move {
        ctx.sleep_until(ms(1000)).await;
        Ok(u32::from(ctx.cancelled()))
    });
    exec.spawn(soft, |ctx| async move {
        let cancelled = ctx.sleep_until_cancelled(ms(1000)).await;
        Ok(u32::from(cancelled) * 10 + ctx.now().as_millis() as u32)
    });
    assert!(run(&mut exec).is_empty());
    exec.set_now(ms(5));
    assert!(exec.cancel(soft) && exec.cancel(firm));
    assert!(!exec.cancel(OpId(99)));
    assert_eq!(run(&mut exec), vec![Report::Done(soft, Ok(15))]);
    assert_eq!(exec.poll_timeout(), Some(ms(1000)), "the firm sleep goes on");
    exec.handle_timeout(ms(1000));
    assert_eq!(run(&mut exec), vec![Report::Done(firm, Ok(1))]);
}

#[test]
fn progress_comes_before_the_end_and_an_aborted_operation_is_dropped_where_it_stands() {
    struct Flag(Arc<AtomicUsize>);
    impl Drop for Flag {
        fn drop(&mut self) {
            self.0.fetch_add(1, Ordering::SeqCst);
        }
    }
    let mut exec = exec();
    let dropped = Arc::new(AtomicUsize::new(0));
    let (a, b) = (exec.next_id(), exec.next_id());
    exec.spawn(a, |ctx| async move {
        ctx.progress(1);
        ctx.sleep_until(ms(10)).await;
        ctx.progress(2);
        Ok(3)
    });
    let flag = Flag(Arc::clone(&dropped));
    exec.spawn(b, move |ctx| async move {
        let _flag = flag;
        let v = ask(&ctx).await;
        ctx.progress(v);
        Err("not reached")
    });
    assert_eq!(run(&mut exec), vec![Report::Progress(a, 1)]);
    assert!(exec.abort(b));
    assert_eq!(dropped.load(Ordering::SeqCst), 1);
    let t = exec.core().asked[0];
    // The job's result has nobody to go to once the family forgets the operation's jobs.
    exec.core().jobs.forget(b);
    assert!(!exec.core().jobs.finish(t, 5));
    exec.handle_timeout(Timestamp::ZERO + Duration::from_millis(10));
    assert_eq!(run(&mut exec), vec![Report::Progress(a, 2), Report::Done(a, Ok(3))]);
    assert!(exec.is_empty() && !exec.has_ready());
}

#[test]
#[cfg(debug_assertions)]
#[should_panic(expected = "locked twice")]
fn a_guard_held_across_a_second_lock_panics_instead_of_waiting_forever() {
    let exec = exec();
    let _held = exec.core();
    let _ = exec.poll_timeout();
}
