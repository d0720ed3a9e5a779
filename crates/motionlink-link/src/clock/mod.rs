//! Time for protocol logic: a [`Clock`] trait with a real and a manual implementation.
//!
//! Every timeout, period and emulator in motionlink reads time from a [`Clock`] and blocks through a
//! [`Signal`] made by that clock, never through `std::thread::sleep`. With [`RealClock`] that is ordinary
//! wall time. With [`ManualClock`] time only moves when a test says so ([`ManualClock::advance`]) or, in
//! auto-advance mode, when every registered thread is blocked on the clock: then the clock jumps straight to
//! the earliest deadline anyone waits for. A client session that sends a keepalive every 200 ms can so be
//! run for ten minutes of device time in a few milliseconds, deterministically.
//!
//! ```
//! use motionlink_link::clock::{Clock, ManualClock, Timestamp};
//! use std::time::Duration;
//!
//! let clock = ManualClock::new();
//! assert_eq!(clock.now(), Timestamp::ZERO);
//! clock.advance(Duration::from_millis(250));
//! assert_eq!(clock.now(), Timestamp::from_millis(250));
//! ```

use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::ops::{Add, AddAssign, Sub};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, Once, Weak};
use std::time::{Duration, Instant};

/// A point in time on a [`Clock`]: the time elapsed since the clock's origin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp(Duration);

impl Timestamp {
    /// The clock's origin.
    pub const ZERO: Timestamp = Timestamp(Duration::ZERO);

    /// A timestamp `since_origin` after the clock's origin.
    pub const fn from_duration(since_origin: Duration) -> Self {
        Timestamp(since_origin)
    }

    /// A timestamp `ms` milliseconds after the clock's origin.
    pub const fn from_millis(ms: u64) -> Self {
        Timestamp(Duration::from_millis(ms))
    }

    /// A timestamp `us` microseconds after the clock's origin.
    pub const fn from_micros(us: u64) -> Self {
        Timestamp(Duration::from_micros(us))
    }

    /// Time since the clock's origin.
    pub const fn since_origin(self) -> Duration {
        self.0
    }

    /// Milliseconds since the clock's origin, truncated.
    pub fn as_millis(self) -> u128 {
        self.0.as_millis()
    }

    /// The time from `earlier` to `self`, or zero if `earlier` is later.
    pub fn saturating_since(self, earlier: Timestamp) -> Duration {
        self.0.saturating_sub(earlier.0)
    }
}

impl Add<Duration> for Timestamp {
    type Output = Timestamp;
    fn add(self, rhs: Duration) -> Timestamp {
        Timestamp(self.0.saturating_add(rhs))
    }
}

impl AddAssign<Duration> for Timestamp {
    fn add_assign(&mut self, rhs: Duration) {
        self.0 = self.0.saturating_add(rhs);
    }
}

impl Sub<Timestamp> for Timestamp {
    type Output = Duration;
    /// Saturating: a later `rhs` gives zero.
    fn sub(self, rhs: Timestamp) -> Duration {
        self.saturating_since(rhs)
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.3} s", self.0.as_secs_f64())
    }
}

/// Why a [`Signal::wait_until`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// The signal was raised.
    Raised,
    /// The deadline passed.
    Deadline,
}

/// A source of time and the only way protocol code blocks.
pub trait Clock: Send + Sync + fmt::Debug {
    /// The current time.
    fn now(&self) -> Timestamp;

    /// A new, lowered signal whose waits are timed by this clock.
    fn signal(&self) -> Signal;

    /// Counts a thread, from now on, as a participant of this clock (see [`ManualClock::new_auto`]). Call
    /// it before spawning the thread and [`ParticipantTicket::enter`] inside it. A no-op for [`RealClock`].
    fn reserve_participant(&self) -> ParticipantTicket {
        ParticipantTicket::none()
    }

    /// Blocks until `deadline` has passed on this clock.
    fn sleep_until(&self, deadline: Timestamp) {
        let signal = self.signal();
        while signal.wait_until(Some(deadline)) == Wake::Raised {}
    }

    /// Blocks for `duration` of this clock's time.
    fn sleep(&self, duration: Duration) {
        self.sleep_until(self.now() + duration);
    }
}

/// A clock shared between a session, its I/O thread and its link.
pub type SharedClock = Arc<dyn Clock>;

/// A one-shot, re-armable wake-up: one thread waits on it with a deadline, others raise it.
///
/// Raising a signal that nobody waits on is remembered: the next wait returns at once and lowers it.
#[derive(Clone)]
pub struct Signal(Arc<dyn RawSignal>);

impl fmt::Debug for Signal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Signal")
    }
}

impl Signal {
    /// Wakes the waiter (or the next one to wait).
    pub fn raise(&self) {
        self.0.raise()
    }

    /// Blocks until the signal is raised or `deadline` passes (`None`: no deadline). Lowers the signal.
    pub fn wait_until(&self, deadline: Option<Timestamp>) -> Wake {
        self.0.wait_until(deadline)
    }

    /// True when `other` is a handle to this same signal.
    pub fn same_as(&self, other: &Signal) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }

    /// [`Signal::wait_until`], except that a real clock sleeps all the way to the deadline instead of
    /// spinning through its last 100 µs: the wake-up comes as late as the operating system makes it (its
    /// timer slack, a busy CPU), and the thread leaves the CPU to others meanwhile. For waits whose
    /// lateness costs nothing more than the wait itself, such as an in-memory link waiting for a frame that
    /// is read whenever the reader wakes. A manual clock waits exactly as [`Signal::wait_until`] does.
    pub fn wait_until_sleeping(&self, deadline: Option<Timestamp>) -> Wake {
        self.0.wait_until_sleeping(deadline)
    }
}

trait RawSignal: Send + Sync {
    fn raise(&self);
    fn wait_until(&self, deadline: Option<Timestamp>) -> Wake;
    fn wait_until_sleeping(&self, deadline: Option<Timestamp>) -> Wake {
        self.wait_until(deadline)
    }
}

/// Hands a participant slot of an auto-advancing [`ManualClock`] to the thread that will use it.
#[must_use = "a ticket that is never entered holds the clock still until it is dropped"]
pub struct ParticipantTicket {
    slot: Option<(Arc<ManualShared>, u64)>,
}

impl fmt::Debug for ParticipantTicket {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ParticipantTicket").field("counted", &self.slot.is_some()).finish()
    }
}

impl ParticipantTicket {
    fn none() -> Self {
        ParticipantTicket { slot: None }
    }

    /// Marks the calling thread as the participant; it stays one until the guard is dropped.
    pub fn enter(mut self) -> ParticipantGuard {
        if let Some((shared, clock_id)) = self.slot.take() {
            free_clocks_on_panic();
            PARTICIPANT_OF.with(|p| p.borrow_mut().push((clock_id, Arc::downgrade(&shared))));
            ParticipantGuard { slot: Some((shared, clock_id)), _not_send: std::marker::PhantomData }
        } else {
            ParticipantGuard { slot: None, _not_send: std::marker::PhantomData }
        }
    }
}

impl Drop for ParticipantTicket {
    fn drop(&mut self) {
        if let Some((shared, _)) = self.slot.take() {
            shared.leave();
        }
    }
}

/// Keeps the current thread counted as a participant of a [`ManualClock`]; see [`Clock::reserve_participant`].
pub struct ParticipantGuard {
    slot: Option<(Arc<ManualShared>, u64)>,
    _not_send: std::marker::PhantomData<*const ()>,
}

impl fmt::Debug for ParticipantGuard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ParticipantGuard").field("counted", &self.slot.is_some()).finish()
    }
}

impl Drop for ParticipantGuard {
    fn drop(&mut self) {
        if let Some((shared, clock_id)) = self.slot.take() {
            PARTICIPANT_OF.with(|p| {
                let mut p = p.borrow_mut();
                if let Some(i) = p.iter().rposition(|(c, _)| *c == clock_id) {
                    p.remove(i);
                }
            });
            shared.leave();
        }
    }
}

thread_local! {
    /// The clocks the current thread takes part in.
    static PARTICIPANT_OF: RefCell<Vec<(u64, Weak<ManualShared>)>> = const { RefCell::new(Vec::new()) };
}

/// Installs, once per process, a panic hook (run before the one there was) that frees every auto-advancing
/// clock the panicking thread takes part in ([`ManualShared::abandon`]). A participant that panics may block
/// while it unwinds (a drop that joins a thread or closes a session whose I/O runs on this clock): the
/// clock, waiting for it to wait, would never move, and the test would hang instead of failing.
fn free_clocks_on_panic() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let _ = PARTICIPANT_OF.try_with(|p| {
                if let Ok(p) = p.try_borrow() {
                    p.iter().filter_map(|(_, clock)| clock.upgrade()).for_each(|clock| clock.abandon());
                }
            });
            previous(info);
        }));
    });
}

// ---------------------------------------------------------------------------------------------------------
// Real clock

/// Wall time, measured from the moment the clock was made.
#[derive(Debug, Clone)]
pub struct RealClock {
    origin: Instant,
}

impl RealClock {
    /// A clock whose origin is now.
    pub fn new() -> Self {
        RealClock { origin: Instant::now() }
    }

    /// A shared handle to a new real clock.
    pub fn shared() -> SharedClock {
        Arc::new(RealClock::new())
    }
}

impl Default for RealClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for RealClock {
    fn now(&self) -> Timestamp {
        Timestamp(self.origin.elapsed())
    }

    fn signal(&self) -> Signal {
        Signal(Arc::new(RealSignal {
            origin: self.origin,
            raised: AtomicBool::new(false),
            sleeping: AtomicBool::new(false),
            lock: Mutex::new(()),
            cv: Condvar::new(),
        }))
    }
}

/// The last stretch before a deadline that a real wait spends spinning on the CPU instead of sleeping: the
/// operating system's timer slack (50 µs on Linux) would otherwise make every timed wait late by about that
/// much. The spin keeps the CPU: it does not yield, because on a busy machine a yielding thread can get the
/// CPU back only milliseconds later, and a keepalive would drift by that much.
const REAL_SPIN: Duration = Duration::from_micros(100);

/// A timed real wait with more than twice this left first sleeps to this much before its deadline, then
/// waits the rest. One long sleep ends late by the timer slack plus the time an idle core (on a virtual
/// machine, an idle virtual CPU) takes to resume, often more than [`REAL_SPIN`]; a short second sleep ends
/// much closer to its time, from a core that has just run. Measured on a 2-core virtual machine: a 1.5 ms
/// wait's median lateness from 2 µs to 0.2 µs, a 20 ms wait's from 46 µs to 1.3 µs, for one more wake-up
/// per wait and no more spinning.
const REAL_APPROACH: Duration = Duration::from_micros(300);

struct RealSignal {
    origin: Instant,
    raised: AtomicBool,
    /// True while the waiter sleeps on `cv` (or is about to): only then does a raise need the lock and a
    /// wake-up call into the operating system.
    sleeping: AtomicBool,
    lock: Mutex<()>,
    cv: Condvar,
}

impl RawSignal for RealSignal {
    fn raise(&self) {
        self.raised.store(true, Ordering::SeqCst);
        // The waiter marks itself sleeping before it looks at `raised` a last time (both sequentially
        // consistent): either it sees this raise and does not sleep, or this load sees it sleeping.
        if self.sleeping.load(Ordering::SeqCst) {
            let _g = lock(&self.lock);
            self.cv.notify_all();
        }
    }

    fn wait_until(&self, deadline: Option<Timestamp>) -> Wake {
        self.wait(deadline, REAL_SPIN)
    }

    fn wait_until_sleeping(&self, deadline: Option<Timestamp>) -> Wake {
        self.wait(deadline, Duration::ZERO)
    }
}

impl RealSignal {
    /// Waits for the signal or `deadline`, spinning through the last `spin` before the deadline.
    fn wait(&self, deadline: Option<Timestamp>, spin: Duration) -> Wake {
        loop {
            if self.raised.swap(false, Ordering::SeqCst) {
                return Wake::Raised;
            }
            let remaining = match deadline {
                None => None,
                Some(deadline) => {
                    let now = Timestamp(self.origin.elapsed());
                    if now >= deadline {
                        return Wake::Deadline;
                    }
                    Some(deadline - now)
                }
            };
            match remaining {
                Some(r) if r <= spin => std::hint::spin_loop(),
                _ => {
                    let g = lock(&self.lock);
                    self.sleeping.store(true, Ordering::SeqCst);
                    // Raised between the check above and now: do not sleep.
                    if self.raised.load(Ordering::SeqCst) {
                        self.sleeping.store(false, Ordering::SeqCst);
                        continue;
                    }
                    let g = match remaining {
                        None => self.cv.wait(g).unwrap_or_else(|e| e.into_inner()),
                        // Far from the deadline: first to REAL_APPROACH before it (see there).
                        Some(r) if !spin.is_zero() && r > REAL_APPROACH * 2 => {
                            self.cv.wait_timeout(g, r - REAL_APPROACH).unwrap_or_else(|e| e.into_inner()).0
                        }
                        Some(r) => self.cv.wait_timeout(g, r - spin).unwrap_or_else(|e| e.into_inner()).0,
                    };
                    self.sleeping.store(false, Ordering::SeqCst);
                    drop(g);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Manual clock

/// A clock that only moves when told to, for tests and for the demo.
///
/// In plain mode ([`ManualClock::new`]) time moves with [`ManualClock::advance`] and
/// [`ManualClock::set`]. In auto-advance mode ([`ManualClock::new_auto`]) it also moves by itself whenever
/// every participant thread is blocked on one of its signals: it jumps to the earliest deadline that any
/// waiter has. Participants are the threads that drive a scenario (the test thread, a client's I/O thread);
/// register one with [`Clock::reserve_participant`] and [`ParticipantTicket::enter`].
///
/// ```
/// use motionlink_link::clock::{Clock, ManualClock, Timestamp};
/// use std::time::Duration;
///
/// let clock = ManualClock::new_auto();
/// let _me = clock.reserve_participant().enter();
/// // The only participant sleeps: the clock jumps ahead instead of waiting ten real minutes.
/// clock.sleep(Duration::from_secs(600));
/// assert_eq!(clock.now(), Timestamp::from_millis(600_000));
/// ```
#[derive(Debug, Clone)]
pub struct ManualClock {
    shared: Arc<ManualShared>,
}

static NEXT_CLOCK_ID: AtomicU64 = AtomicU64::new(1);

#[derive(Debug)]
struct ManualShared {
    id: u64,
    auto: bool,
    /// A participant panicked: the clock jumps whenever anyone waits ([`ManualShared::abandon`]).
    abandoned: AtomicBool,
    state: Mutex<ManualState>,
    cv: Condvar,
}

#[derive(Debug, Default)]
struct ManualState {
    now: Timestamp,
    next_signal_id: u64,
    /// Participants counted by the clock.
    participants: usize,
    /// Signals raised and not yet consumed by a wait.
    raised: BTreeSet<u64>,
    /// Blocked waiters: signal id -> (deadline, waiter is a participant).
    waiting: BTreeMap<u64, (Option<Timestamp>, bool)>,
}

impl ManualState {
    fn idle_participants(&self) -> usize {
        self.waiting.values().filter(|(_, participant)| *participant).count()
    }

    /// Removes from `waiting` every waiter whose deadline has passed: they are runnable again.
    fn release_expired(&mut self) {
        let now = self.now;
        self.waiting.retain(|_, (deadline, _)| deadline.is_none_or(|d| d > now));
    }
}

impl ManualClock {
    /// A clock at [`Timestamp::ZERO`] that moves only when told to.
    pub fn new() -> Self {
        Self::with_mode(false)
    }

    /// A clock at [`Timestamp::ZERO`] that also jumps to the next deadline whenever all participants wait.
    /// Once a participant panics, it jumps whenever anyone waits: a failing test that unwinds through a
    /// drop waiting on this clock's threads fails instead of hanging.
    pub fn new_auto() -> Self {
        Self::with_mode(true)
    }

    fn with_mode(auto: bool) -> Self {
        ManualClock {
            shared: Arc::new(ManualShared {
                id: NEXT_CLOCK_ID.fetch_add(1, Ordering::Relaxed),
                auto,
                abandoned: AtomicBool::new(false),
                state: Mutex::new(ManualState::default()),
                cv: Condvar::new(),
            }),
        }
    }

    /// A shared handle to this clock.
    pub fn shared(&self) -> SharedClock {
        Arc::new(self.clone())
    }

    /// Moves time forward by `by` and wakes every waiter whose deadline has passed.
    pub fn advance(&self, by: Duration) {
        let mut st = lock(&self.shared.state);
        st.now += by;
        st.release_expired();
        self.shared.cv.notify_all();
    }

    /// Moves time forward to `to` (never backwards) and wakes every waiter whose deadline has passed.
    pub fn set(&self, to: Timestamp) {
        let mut st = lock(&self.shared.state);
        if to > st.now {
            st.now = to;
        }
        st.release_expired();
        self.shared.cv.notify_all();
    }
}

impl Default for ManualClock {
    fn default() -> Self {
        Self::new()
    }
}

impl ManualShared {
    fn leave(&self) {
        let mut st = lock(&self.state);
        st.participants = st.participants.saturating_sub(1);
        self.maybe_auto_advance(&mut st);
    }

    /// A participant panicked: from now on the clock no longer waits for the participants, but jumps to the
    /// earliest deadline whenever anyone waits, so that what still runs on it ends (and the test fails)
    /// instead of waiting for a thread that is unwinding. Takes no lock: it runs in a panic hook.
    fn abandon(&self) {
        self.abandoned.store(true, Ordering::SeqCst);
        self.cv.notify_all();
    }

    /// If every participant is blocked (or one panicked), jump to the earliest deadline of any waiter.
    fn maybe_auto_advance(&self, st: &mut ManualState) {
        let free = self.abandoned.load(Ordering::SeqCst);
        if !self.auto || (!free && (st.participants == 0 || st.idle_participants() < st.participants)) {
            return;
        }
        if !st.raised.is_empty() && st.waiting.keys().any(|id| st.raised.contains(id)) {
            return;
        }
        if let Some(earliest) = st.waiting.values().filter_map(|(d, _)| *d).min() {
            if earliest > st.now {
                st.now = earliest;
            }
            st.release_expired();
            self.cv.notify_all();
        }
    }
}

impl Clock for ManualClock {
    fn now(&self) -> Timestamp {
        lock(&self.shared.state).now
    }

    fn signal(&self) -> Signal {
        let id = {
            let mut st = lock(&self.shared.state);
            st.next_signal_id += 1;
            st.next_signal_id
        };
        Signal(Arc::new(ManualSignal { shared: Arc::clone(&self.shared), id }))
    }

    fn reserve_participant(&self) -> ParticipantTicket {
        lock(&self.shared.state).participants += 1;
        ParticipantTicket { slot: Some((Arc::clone(&self.shared), self.shared.id)) }
    }
}

struct ManualSignal {
    shared: Arc<ManualShared>,
    id: u64,
}

impl RawSignal for ManualSignal {
    fn raise(&self) {
        let mut st = lock(&self.shared.state);
        st.raised.insert(self.id);
        // The waiter is runnable from this instant: it no longer counts as idle.
        st.waiting.remove(&self.id);
        self.shared.cv.notify_all();
    }

    fn wait_until(&self, deadline: Option<Timestamp>) -> Wake {
        let participant = PARTICIPANT_OF.with(|p| p.borrow().iter().any(|(c, _)| *c == self.shared.id));
        let mut st = lock(&self.shared.state);
        let mut registered = false;
        loop {
            if st.raised.remove(&self.id) {
                st.waiting.remove(&self.id);
                return Wake::Raised;
            }
            if deadline.is_some_and(|d| st.now >= d) {
                st.waiting.remove(&self.id);
                return Wake::Deadline;
            }
            if !registered || !st.waiting.contains_key(&self.id) {
                st.waiting.insert(self.id, (deadline, participant));
                registered = true;
                self.shared.maybe_auto_advance(&mut st);
                continue;
            }
            st = self.shared.cv.wait(st).unwrap_or_else(|e| e.into_inner());
            if self.shared.abandoned.load(Ordering::SeqCst) {
                self.shared.maybe_auto_advance(&mut st);
            }
        }
    }
}

/// Locks a mutex, recovering the data if another thread panicked while holding it.
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests;

/// Makes the calling thread's timed waits end close to their deadlines: on Linux its timer slack (by default
/// 50 µs, by which the kernel may delay a sleeping thread's wake-up to batch it with others) is set to 1 µs;
/// elsewhere it does nothing. For a control loop that polls a device at 100 Hz to 1 kHz, and for a thread that
/// waits on the in-memory CAN bus, whose frames arrive on a timer. Returns whether the setting took.
///
/// ```
/// motionlink_link::clock::precise_timers();
/// ```
pub fn precise_timers() -> bool {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: PR_SET_TIMERSLACK takes one integer argument and changes only the calling thread's slack.
        unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1_000 as libc::c_ulong) == 0 }
    }
    #[cfg(not(target_os = "linux"))]
    {
        false
    }
}
