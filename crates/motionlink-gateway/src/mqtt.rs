//! The broker's side: the connection's options (the last will, credentials, TLS with rustls on ring) and
//! the event loop, run in its own task: it reconnects with backoff and tells the gateway what happens.

use std::sync::Arc;
use std::time::Duration;

use rumqttc::v5::mqttbytes::v5::{LastWill, Packet, Publish, SubAck, SubscribeReasonCode};
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{Event, EventLoop, MqttOptions};
use rumqttc::{Outgoing, TlsConfiguration, Transport};
use tokio::sync::mpsc;

use crate::config::GatewayConfig;
use crate::error::GatewayError;
use crate::topics::Topics;

/// What `status` holds while the gateway is connected.
pub const ONLINE: &str = "online";
/// What `status` holds once the gateway is gone (its last will, and its clean exit).
pub const OFFLINE: &str = "offline";

/// The largest MQTT packet the gateway takes (a request is a few hundred bytes).
pub const MAX_PACKET_BYTES: u32 = 64 * 1024;

/// How many requests to the broker (publishes, the subscription) may wait for the connection at once, unless
/// [`QUEUE_ENV`] says otherwise.
pub const QUEUE: usize = 1024;

/// The environment variable that sets the queue's length instead of [`QUEUE`] (a whole number from 1 to
/// 65535): the tests fill a short one.
pub const QUEUE_ENV: &str = "MOTIONLINK_GATEWAY_MQTT_QUEUE";

/// The queue's length: [`QUEUE_ENV`] read by `env`, else [`QUEUE`]; a value that is not a whole number from 1
/// to 65535 is a usage error naming it.
pub fn queue_length(env: impl Fn(&str) -> Option<String>) -> Result<usize, GatewayError> {
    match env(QUEUE_ENV) {
        None => Ok(QUEUE),
        Some(text) => match text.trim().parse::<u16>() {
            Ok(n) if n > 0 => Ok(usize::from(n)),
            _ => Err(GatewayError::Usage(format!("{QUEUE_ENV}={text:?}: give a whole number from 1 to 65535"))),
        },
    }
}

/// The first wait before a reconnection; it doubles up to [`MAX_BACKOFF`].
pub const FIRST_BACKOFF: Duration = Duration::from_millis(250);
/// The longest wait between two reconnections.
pub const MAX_BACKOFF: Duration = Duration::from_secs(10);

/// The CA bundles tried, in order, when the file names no `ca_file` (Debian, Fedora, Alpine / macOS).
const SYSTEM_ROOTS: [&str; 3] =
    ["/etc/ssl/certs/ca-certificates.crt", "/etc/pki/tls/certs/ca-bundle.crt", "/etc/ssl/cert.pem"];

/// What the event loop tells the gateway.
#[derive(Debug)]
pub enum Net {
    /// The broker accepted the connection (the first, or again after a loss).
    Connected,
    /// A message on a subscribed topic.
    Message(Box<Publish>),
    /// The broker's answer to the subscription (SUBACK): `Err` names why it refused it.
    Subscribed(Result<(), String>),
    /// The connection is lost (or could not be made); the loop tries again after a backoff.
    Lost(String),
    /// The gateway's own DISCONNECT went out: the loop has ended.
    Closed,
}

/// The connection's options: the gateway's client id, keepalive, the last will `offline` (retained) on
/// its `status`, the credentials and, for `mqtts://`, TLS.
pub fn options(config: &GatewayConfig, topics: &Topics) -> Result<MqttOptions, GatewayError> {
    let mut o = MqttOptions::new(format!("motionlink-{}", config.name), config.broker.host.clone(), config.broker.port);
    o.set_keep_alive(Duration::from_secs(5));
    o.set_clean_start(true);
    o.set_connection_timeout(5);
    // The largest packet the gateway takes, told the broker in CONNECT (MQTT 5 Maximum Packet Size): a
    // larger message is the broker's to drop, and never reaches the connection, which would fail on it and
    // stop every motion the gateway serves.
    o.set_max_packet_size(Some(MAX_PACKET_BYTES));
    // Requests and replies are small messages: sent at once, not held back for more (Nagle's algorithm).
    let mut network = rumqttc::NetworkOptions::new();
    network.set_tcp_nodelay(true);
    o.set_network_options(network);
    o.set_last_will(LastWill::new(topics.status(), OFFLINE, QoS::AtLeastOnce, true, None));
    if let Some((user, password)) = &config.credentials {
        o.set_credentials(user.clone(), password.clone());
    }
    if config.broker.tls {
        o.set_transport(Transport::Tls(TlsConfiguration::Rustls(Arc::new(tls(config)?))));
    }
    Ok(o)
}

/// rustls (ring) with the roots of `ca_file`, else of the system's CA bundle.
fn tls(config: &GatewayConfig) -> Result<rustls::ClientConfig, GatewayError> {
    use rustls::pki_types::pem::PemObject;
    use rustls::pki_types::CertificateDer;
    let path = match &config.ca_file {
        Some(p) => p.clone(),
        None => SYSTEM_ROOTS.iter().map(std::path::PathBuf::from).find(|p| p.exists()).ok_or_else(|| {
            GatewayError::Usage(format!(
                "{}: no CA bundle found ({}): name the CA that signs the broker's certificate with ca_file",
                config.broker,
                SYSTEM_ROOTS.join(", ")
            ))
        })?,
    };
    let shown = path.display();
    let mut roots = rustls::RootCertStore::empty();
    let certs = CertificateDer::pem_file_iter(&path)
        .map_err(|e| GatewayError::Usage(format!("ca_file {shown}: {e}")))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| GatewayError::Usage(format!("ca_file {shown}: {e}")))?;
    let (added, _ignored) = roots.add_parsable_certificates(certs);
    if added == 0 {
        return Err(GatewayError::Usage(format!("ca_file {shown}: no certificate in it")));
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    Ok(rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| GatewayError::Usage(format!("TLS: {e}")))?
        .with_root_certificates(roots)
        .with_no_client_auth())
}

/// Whether a SUBACK grants every filter: `Err` names the reason codes (and the broker's reason string).
fn granted(ack: &SubAck) -> Result<(), String> {
    let refused: Vec<String> = ack
        .return_codes
        .iter()
        .filter(|c| !matches!(c, SubscribeReasonCode::Success(_)))
        .map(|c| format!("{c:?}"))
        .collect();
    if refused.is_empty() {
        return Ok(());
    }
    let mut why = refused.join(", ");
    if let Some(reason) = ack.properties.as_ref().and_then(|p| p.reason_string.as_ref()) {
        why.push_str(&format!(": {reason}"));
    }
    Err(why)
}

/// Runs the event loop until the gateway's DISCONNECT goes out, telling `to` what happens; after a loss
/// it waits (from [`FIRST_BACKOFF`], doubling to [`MAX_BACKOFF`]) and connects again.
pub async fn drive(mut events: EventLoop, to: mpsc::UnboundedSender<Net>) {
    let mut backoff = FIRST_BACKOFF;
    loop {
        match events.poll().await {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                backoff = FIRST_BACKOFF;
                let _ = to.send(Net::Connected);
            }
            Ok(Event::Incoming(Packet::Publish(p))) => {
                let _ = to.send(Net::Message(Box::new(p)));
            }
            Ok(Event::Incoming(Packet::SubAck(ack))) => {
                let _ = to.send(Net::Subscribed(granted(&ack)));
            }
            Ok(Event::Outgoing(Outgoing::Disconnect)) => {
                let _ = to.send(Net::Closed);
                return;
            }
            Ok(_) => {}
            Err(e) => {
                if to.send(Net::Lost(e.to_string())).is_err() {
                    return;
                }
                tokio::time::sleep(backoff).await;
                backoff = (backoff * 2).min(MAX_BACKOFF);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_queue_s_length_is_1024_or_the_variable_s_named_when_bad() {
        assert_eq!(queue_length(|_| None).unwrap(), QUEUE);
        assert_eq!(queue_length(|k| (k == QUEUE_ENV).then(|| "8".to_string())).unwrap(), 8);
        for bad in ["0", "-1", "x", "70000", ""] {
            let e = queue_length(|_| Some(bad.to_string())).unwrap_err();
            assert_eq!(e.exit_code(), 2, "{bad}");
            assert_eq!(
                e.to_string(),
                format!("MOTIONLINK_GATEWAY_MQTT_QUEUE={bad:?}: give a whole number from 1 to 65535"),
                "{bad}"
            );
        }
    }
}
