//! Leases: a motion lives as long as its commanding client renews it. Each motion id has a deadline, the
//! time of its last renewal plus its lease; the gateway stops a motion whose deadline passed.

use std::collections::HashMap;
use std::time::Duration;

use tokio::time::Instant;

/// The leases of the motions under way, by motion id.
#[derive(Debug, Default)]
pub struct Leases {
    held: HashMap<String, Held>,
}

#[derive(Debug, Clone, Copy)]
struct Held {
    lease: Duration,
    deadline: Instant,
}

impl Leases {
    /// No lease.
    pub fn new() -> Leases {
        Leases::default()
    }

    /// A motion `id` starts at `now` with `lease`.
    pub fn start(&mut self, id: &str, lease: Duration, now: Instant) {
        self.held.insert(id.to_string(), Held { lease, deadline: now + lease });
    }

    /// A keepalive of motion `id` at `now`: its deadline moves to `now` plus its lease. `None` if no motion
    /// `id` holds a lease (it ended, or never started); else the lease.
    pub fn renew(&mut self, id: &str, now: Instant) -> Option<Duration> {
        let held = self.held.get_mut(id)?;
        if now >= held.deadline {
            // Lapsed already: the stop is due, a late keepalive does not undo it.
            return None;
        }
        held.deadline = now + held.lease;
        Some(held.lease)
    }

    /// Motion `id` ended: its lease goes.
    pub fn end(&mut self, id: &str) {
        self.held.remove(id);
    }

    /// The motions whose lease lapsed by `now` (their leases go), with their leases.
    pub fn expired(&mut self, now: Instant) -> Vec<(String, Duration)> {
        let lapsed: Vec<(String, Duration)> =
            self.held.iter().filter(|(_, h)| h.deadline <= now).map(|(id, h)| (id.clone(), h.lease)).collect();
        for (id, _) in &lapsed {
            self.held.remove(id);
        }
        lapsed
    }

    /// The earliest deadline, if any lease is held.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.held.values().map(|h| h.deadline).min()
    }

    /// True while motion `id` holds a lease.
    pub fn holds(&self, id: &str) -> bool {
        self.held.contains_key(id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lease_lapses_one_lease_after_its_last_renewal() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut leases = Leases::new();
        leases.start("m1", ms(1000), t0);
        assert_eq!(leases.next_deadline(), Some(t0 + ms(1000)));
        assert_eq!(leases.renew("m1", t0 + ms(900)), Some(ms(1000)));
        assert!(leases.expired(t0 + ms(1899)).is_empty());
        assert_eq!(leases.next_deadline(), Some(t0 + ms(1900)));
        assert_eq!(leases.expired(t0 + ms(1900)), vec![("m1".to_string(), ms(1000))]);
        assert!(!leases.holds("m1") && leases.next_deadline().is_none());
    }

    #[test]
    fn a_late_or_unknown_keepalive_renews_nothing() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut leases = Leases::new();
        leases.start("m1", ms(100), t0);
        assert_eq!(leases.renew("m2", t0), None);
        assert_eq!(leases.renew("m1", t0 + ms(100)), None, "lapsed: the stop is due");
        leases.start("m2", ms(500), t0);
        leases.end("m2");
        assert_eq!(leases.renew("m2", t0 + ms(1)), None);
    }

    #[test]
    fn several_motions_keep_their_own_deadlines() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut leases = Leases::new();
        leases.start("a", ms(300), t0);
        leases.start("b", ms(100), t0);
        assert_eq!(leases.next_deadline(), Some(t0 + ms(100)));
        assert_eq!(leases.expired(t0 + ms(150)), vec![("b".to_string(), ms(100))]);
        assert!(leases.holds("a"));
    }
}
