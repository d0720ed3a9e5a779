//! The driver's background thread: started when a duty first needs it, then driving the port whenever a
//! deadline of the session is due or an async caller's operation is under way and nobody else drives it.

use std::thread;

use super::Shared;
use crate::clock::lock;
use crate::session::Session;

/// The background thread's state.
pub(super) enum Background {
    /// Not needed yet.
    NotStarted,
    Running(thread::JoinHandle<()>),
    /// Joined, or never to be started (the driver is closed).
    Done,
}

impl<S: Session> Shared<S> {
    /// Starts the background thread (a participant of the clock) unless it runs or the driver is closed.
    pub(super) fn start_background(&self) -> std::io::Result<()> {
        let mut slot = lock(&self.thread);
        if !matches!(*slot, Background::NotStarted) {
            return Ok(());
        }
        let Some(me) = self.this.upgrade() else { return Ok(()) };
        let ticket = self.clock.reserve_participant();
        let handle = thread::Builder::new().name("motionlink-driver".into()).spawn(move || {
            let _participant = ticket.enter();
            // The session's deadlines (keepalives, watchdog refreshes, reply timeouts) are met within a few µs
            // rather than the default timer slack's 50 µs.
            crate::clock::precise_timers();
            me.background_loop();
            me.exited_flag.store(true, std::sync::atomic::Ordering::SeqCst);
            me.exited.raise();
        })?;
        *slot = Background::Running(handle);
        Ok(())
    }

    /// Wakes the background thread, starting it first if it was not needed before.
    pub(super) fn wake_background(&self) {
        if let Err(e) = self.start_background() {
            // (An async caller's operation is refused before this: see Driver::start.) A deadline is then met
            // only while a blocking caller drives the port; a keepalive missed meanwhile lets the device's
            // watchdog stop its drives.
            tracing::error!("cannot start the driver's background thread: {e}; the session's deadlines are met only while a call runs");
        }
        self.background.raise();
    }

    fn background_loop(&self) {
        let me = self.background.clone();
        loop {
            let deadline = {
                let mut core = self.core();
                core.background_sleeps = None;
                if core.stop_thread {
                    return;
                }
                let now = self.clock.now();
                let due = core.session.poll_timeout().is_some_and(|t| t <= now);
                if core.port.is_some() && (due || !core.session.is_idle()) {
                    let port = core.port.take().expect("checked");
                    drop(core);
                    self.drive(port, &me, None, None, &|core, now| {
                        core.stop_thread
                            || (core.session.is_idle() && core.session.poll_timeout().is_none_or(|t| t > now))
                    });
                    continue;
                }
                let deadline = core.session.poll_timeout();
                core.background_sleeps = Some(deadline);
                if due && core.port.is_none() {
                    // A caller drives the port and meets the session's deadlines meanwhile: wait until it
                    // hands the port back (it raises the port's waiters), not at a deadline already due,
                    // which would make this loop spin for as long as the caller holds the port.
                    core.port_waiters.push(me.clone());
                    None
                } else {
                    deadline
                }
            };
            me.wait_until(deadline);
        }
    }
}
