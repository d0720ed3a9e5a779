//! The gateway's presence on the broker, asked for on every connection and confirmed: the subscription to
//! every device's `cmd` (until the broker's SUBACK grants it, it is asked for again), then `online`
//! (retained) once it is granted, so that `online` says that requests reach the gateway. A request that
//! cannot be queued (the queue to the broker is full) is tried again every second and said on stderr, never
//! dropped without a word.

use std::time::Duration;

use rumqttc::v5::mqttbytes::v5::{Filter, RetainForwardRule};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::AsyncClient as Mqtt;
use tokio::time::Instant;

use crate::mqtt::ONLINE;
use crate::topics::Topics;

/// How long the gateway waits for the broker's SUBACK before it asks for the subscription again.
pub(super) const SUBACK_WAIT: Duration = Duration::from_secs(5);

/// How long the gateway waits before it asks again for a subscription the broker refused.
pub(super) const REFUSED_WAIT: Duration = Duration::from_secs(10);

/// The gateway's subscription: every device's `cmd` at QoS 1, with MQTT 5's retain handling 2 (the broker
/// sends no retained message when it subscribes: a retained request would otherwise run again at each
/// start and each reconnection) and retain as published (a request published with the retain flag comes
/// with it, and is refused).
pub fn cmd_filter(topics: &Topics) -> Filter {
    Filter {
        path: topics.all_cmd(),
        qos: QoS::AtLeastOnce,
        nolocal: false,
        preserve_retain: true,
        retain_forward_rule: RetainForwardRule::Never,
    }
}

/// Where the subscription and `online` stand on the current connection.
#[derive(Debug, Default)]
pub(super) struct Presence {
    /// Connected to the broker.
    up: bool,
    /// Not the first connection (what is said differs).
    again: bool,
    /// When the subscription is to be asked for next (`None`: at once).
    next_ask: Option<Instant>,
    /// Asked for, and no SUBACK yet.
    awaiting: bool,
    /// The broker granted it.
    subscribed: bool,
    /// `online` is queued.
    online: bool,
    /// A request that could not be queued was said on stderr (once per connection).
    said_full: bool,
}

impl Presence {
    /// A connection (the first, or again after a loss): nothing is asked for yet on it.
    pub(super) fn connected(&mut self) {
        let again = self.again || self.up;
        *self = Presence { up: true, again, ..Presence::default() };
    }

    /// The connection is lost: everything is asked for again on the next.
    pub(super) fn lost(&mut self) {
        *self = Presence { again: true, ..Presence::default() };
    }

    /// Whether `online` is queued on this connection (the subscription was granted).
    #[cfg(test)]
    pub(super) fn is_online(&self) -> bool {
        self.online
    }

    /// The broker's SUBACK: granted, or refused (said, and asked for again after [`REFUSED_WAIT`]).
    pub(super) fn suback(&mut self, granted: Result<(), String>, mqtt: &Mqtt, topics: &Topics, now: Instant) {
        if !self.up {
            return;
        }
        self.awaiting = false;
        match granted {
            Ok(()) => self.subscribed = true,
            Err(why) => {
                self.subscribed = false;
                self.next_ask = Some(now + REFUSED_WAIT);
                crate::notice::say!(
                    "motionlink gateway: the broker refused the subscription to {} ({why}): no request reaches the \
                     gateway, and `online` is not published; it asks again in {} s",
                    topics.all_cmd(),
                    REFUSED_WAIT.as_secs()
                );
            }
        }
        self.step(mqtt, topics, now);
    }

    /// What is due on this connection: the subscription (again, once [`SUBACK_WAIT`] passed without its
    /// SUBACK), then `online` once it is granted. Called on a connection, on a SUBACK and every second.
    pub(super) fn step(&mut self, mqtt: &Mqtt, topics: &Topics, now: Instant) {
        if !self.up {
            return;
        }
        if !self.subscribed {
            if self.next_ask.is_some_and(|t| now < t) {
                return;
            }
            match mqtt.try_subscribe_many([cmd_filter(topics)]) {
                Ok(()) => {
                    if self.awaiting {
                        crate::notice::say!(
                            "motionlink gateway: no answer from the broker to the subscription to {} within {} s: \
                             asked again",
                            topics.all_cmd(),
                            SUBACK_WAIT.as_secs()
                        );
                    }
                    self.awaiting = true;
                    self.next_ask = Some(now + SUBACK_WAIT);
                }
                Err(e) => self.full("the subscription to every device's cmd", "no request reaches the gateway", &e),
            }
            return;
        }
        if !self.online {
            match mqtt.try_publish(topics.status(), QoS::AtLeastOnce, true, ONLINE) {
                Ok(()) => {
                    self.online = true;
                    if self.again {
                        crate::notice::say!(
                            "motionlink gateway: subscribed to {} again; `online` published",
                            topics.all_cmd()
                        );
                    }
                }
                Err(e) => self.full("`online`", "the status does not say `online`", &e),
            }
        }
    }

    /// `what` could not be queued (`until`: what that means meanwhile): said once per connection; it is tried
    /// again every second.
    fn full(&mut self, what: &str, until: &str, error: &dyn std::fmt::Display) {
        if !std::mem::replace(&mut self.said_full, true) {
            crate::notice::say!(
                "motionlink gateway: {what} could not be queued for the broker (its queue is full: {error}); until \
                 it is, {until}: tried again every second"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rumqttc::v5::{EventLoop, MqttOptions, Request};

    fn client(queue: usize) -> (Mqtt, EventLoop) {
        Mqtt::new(MqttOptions::new("presence-test", "127.0.0.1", 1), queue)
    }

    /// What the event loop was asked for: the queue, taken as a lost connection takes it.
    fn queued(events: &mut EventLoop) -> Vec<Request> {
        events.clean();
        events.pending.drain(..).collect()
    }

    fn is_subscription(r: &Request, topics: &Topics) -> bool {
        matches!(r, Request::Subscribe(s) if s.filters == vec![cmd_filter(topics)])
    }

    fn is_online(r: &Request, topics: &Topics) -> bool {
        matches!(r, Request::Publish(p) if p.topic == topics.status().as_bytes() && p.retain && p.payload == ONLINE)
    }

    #[test]
    fn the_subscription_never_sends_retained_requests_and_keeps_their_flag() {
        let f = cmd_filter(&Topics::new("wing-a"));
        assert_eq!((f.path.as_str(), f.qos), ("motionlink/wing-a/+/cmd", QoS::AtLeastOnce));
        assert_eq!(f.retain_forward_rule, RetainForwardRule::Never);
        assert!(f.preserve_retain && !f.nolocal);
    }

    #[test]
    fn a_full_queue_delays_the_subscription_and_online_but_never_loses_them() {
        let topics = Topics::new("g");
        let (mqtt, mut events) = client(1);
        let t0 = Instant::now();
        let mut p = Presence::default();
        p.connected();
        // The queue is full (a state waits in it): the subscription cannot be queued now...
        mqtt.try_publish("motionlink/g/a/state", QoS::AtMostOnce, true, "{}").unwrap();
        p.step(&mqtt, &topics, t0);
        let q = queued(&mut events);
        assert_eq!(q.len(), 1, "{q:?}");
        assert!(!is_subscription(&q[0], &topics), "{q:?}");
        // ...and is the next second, once there is room.
        p.step(&mqtt, &topics, t0 + Duration::from_secs(1));
        let q = queued(&mut events);
        assert!(q.len() == 1 && is_subscription(&q[0], &topics), "{q:?}");
        // No `online` before the broker grants it.
        p.step(&mqtt, &topics, t0 + Duration::from_secs(2));
        assert!(queued(&mut events).is_empty());
        assert!(!p.is_online());
        // Granted while the queue is full: `online` waits for room, and goes once there is.
        mqtt.try_publish("motionlink/g/a/state", QoS::AtMostOnce, true, "{}").unwrap();
        p.suback(Ok(()), &mqtt, &topics, t0 + Duration::from_secs(2));
        assert!(!p.is_online());
        let q = queued(&mut events);
        assert!(q.len() == 1 && !is_online(&q[0], &topics), "{q:?}");
        p.step(&mqtt, &topics, t0 + Duration::from_secs(3));
        assert!(p.is_online());
        let q = queued(&mut events);
        assert!(q.len() == 1 && is_online(&q[0], &topics), "{q:?}");
        // Once online, nothing more is asked for on this connection.
        p.step(&mqtt, &topics, t0 + Duration::from_secs(60));
        assert!(queued(&mut events).is_empty());
    }

    #[test]
    fn a_subscription_without_suback_is_asked_again_and_a_reconnection_asks_everything_again() {
        let topics = Topics::new("g");
        let (mqtt, mut events) = client(8);
        let t0 = Instant::now();
        let mut p = Presence::default();
        p.connected();
        p.step(&mqtt, &topics, t0);
        assert_eq!(queued(&mut events).len(), 1);
        p.step(&mqtt, &topics, t0 + SUBACK_WAIT - Duration::from_millis(1));
        assert!(queued(&mut events).is_empty(), "asked again before its SUBACK was due");
        p.step(&mqtt, &topics, t0 + SUBACK_WAIT);
        let q = queued(&mut events);
        assert!(q.len() == 1 && is_subscription(&q[0], &topics), "{q:?}");
        // Refused: asked again after REFUSED_WAIT, and `online` not published meanwhile.
        p.suback(Err("NotAuthorized".into()), &mqtt, &topics, t0 + SUBACK_WAIT);
        p.step(&mqtt, &topics, t0 + SUBACK_WAIT + Duration::from_secs(1));
        assert!(queued(&mut events).is_empty() && !p.is_online());
        p.step(&mqtt, &topics, t0 + SUBACK_WAIT + REFUSED_WAIT);
        let q = queued(&mut events);
        assert!(q.len() == 1 && is_subscription(&q[0], &topics), "{q:?}");
        p.suback(Ok(()), &mqtt, &topics, t0 + Duration::from_secs(20));
        assert!(p.is_online() && is_online(&queued(&mut events)[0], &topics));
        // Lost, and connected again: the subscription and `online` again.
        p.lost();
        p.step(&mqtt, &topics, t0 + Duration::from_secs(21));
        assert!(queued(&mut events).is_empty(), "nothing is asked for while disconnected");
        p.connected();
        p.step(&mqtt, &topics, t0 + Duration::from_secs(22));
        let q = queued(&mut events);
        assert!(q.len() == 1 && is_subscription(&q[0], &topics), "{q:?}");
        p.suback(Ok(()), &mqtt, &topics, t0 + Duration::from_secs(22));
        assert!(is_online(&queued(&mut events)[0], &topics));
    }
}
