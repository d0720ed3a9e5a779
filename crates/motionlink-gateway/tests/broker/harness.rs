//! A real mosquitto on a free loopback port, the gateway binary, and an MQTT 5 client for the tests and
//! the benchmark (each uses part of it).

#![allow(dead_code)]

use std::io::Write;
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rumqttc::v5::mqttbytes::v5::Packet;
use rumqttc::v5::mqttbytes::QoS;
use rumqttc::v5::{AsyncClient, Event, MqttOptions};
use serde_json::Value;
use tokio::sync::mpsc;

/// One emulated device of each family: `lift` (SCU), `arm` (PowerCube), `axis` (COMPAX).
pub const ALL: &str = r#"
[device.lift]
family = "scu"
port = "sim"

[device.arm]
family = "powercube"
port = "sim"

[device.axis]
family = "compax"
port = "sim"
"#;

/// Where mosquitto may be.
const MOSQUITTO: [&str; 3] = ["/usr/sbin/mosquitto", "/usr/bin/mosquitto", "/usr/local/sbin/mosquitto"];

/// The broker (MOTIONLINK_MOSQUITTO, else the usual places, else on PATH), or `None` with the test
/// reported skipped by name (a failure with MOTIONLINK_REQUIRE_BROKER=1).
pub fn broker(test: &str) -> Option<Broker> {
    let on_path = || {
        std::env::var_os("PATH")
            .and_then(|paths| std::env::split_paths(&paths).map(|d| d.join("mosquitto")).find(|p| p.is_file()))
    };
    let found = match std::env::var_os("MOTIONLINK_MOSQUITTO") {
        Some(named) => Some(PathBuf::from(named)).filter(|p| p.is_file()),
        None => MOSQUITTO.iter().map(PathBuf::from).find(|p| p.exists()).or_else(on_path),
    };
    match found {
        Some(path) => Some(Broker::start(path, test, "allow_anonymous true")),
        None if std::env::var("MOTIONLINK_REQUIRE_BROKER").is_ok_and(|v| v == "1") => {
            panic!("{test}: mosquitto is not installed and MOTIONLINK_REQUIRE_BROKER=1")
        }
        None => {
            eprintln!("SKIPPED broker::{test}: mosquitto is not installed (apt-get install mosquitto)");
            None
        }
    }
}

/// A mosquitto of a test.
pub struct Broker {
    path: PathBuf,
    conf: PathBuf,
    /// Its TCP port on 127.0.0.1.
    pub port: u16,
    child: Option<Child>,
}

impl Broker {
    fn start(path: PathBuf, test: &str, settings: &str) -> Broker {
        let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let conf = dir(test).join("mosquitto.conf");
        let mut f = std::fs::File::create(&conf).unwrap();
        writeln!(f, "listener {port} 127.0.0.1\npersistence false\nset_tcp_nodelay true\n{settings}").unwrap();
        let mut b = Broker { path, conf, port, child: None };
        b.restart();
        b
    }

    /// Another mosquitto of the same installation on another port, configured with `settings` (lines of
    /// mosquitto.conf after its `listener`).
    pub fn another(&self, test: &str, settings: &str) -> Broker {
        Broker::start(self.path.clone(), test, settings)
    }

    /// Starts it (again) on its port, and waits until it takes connections.
    pub fn restart(&mut self) {
        let child = Command::new(&self.path)
            .arg("-c")
            .arg(&self.conf)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("mosquitto starts");
        self.child = Some(child);
        let until = Instant::now() + Duration::from_secs(10);
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(Instant::now() < until, "mosquitto does not listen on {}", self.port);
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Kills it (SIGKILL: no goodbye to anyone).
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// `mqtt://127.0.0.1:PORT`.
    pub fn url(&self) -> String {
        format!("mqtt://127.0.0.1:{}", self.port)
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        self.kill();
        if let Some(dir) = self.conf.parent() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// A directory of the test `name`, made empty.
pub fn dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("motionlink-broker-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A gateway process.
pub struct Gateway {
    child: Child,
    /// The directory of its file (removed when it ends).
    dir: PathBuf,
}

/// The file of a gateway named `name` on `broker` serving `devices` (TOML `[device.NAME]` tables).
pub fn gateway(broker: &Broker, name: &str, devices: &str) -> Gateway {
    gateway_of(name, &format!("[gateway]\nname = \"{name}\"\nbroker = \"{}\"\n\n{devices}", broker.url()), &[])
}

/// A gateway `name` of the file `text`, with the environment variables `env`.
pub fn gateway_of(name: &str, text: &str, env: &[(&str, &str)]) -> Gateway {
    gateway_with(name, text, env, &[])
}

/// [`gateway_of`] with the command-line arguments `args` after `--config FILE`.
pub fn gateway_with(name: &str, text: &str, env: &[(&str, &str)], args: &[&str]) -> Gateway {
    let dir = dir(&format!("gw-{name}"));
    let file = dir.join("gateway.toml");
    std::fs::write(&file, text).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_motionlink-gateway"))
        .args(args)
        .arg("--config")
        .arg(&file)
        .env_remove("MOTIONLINK_MQTT_PASSWORD")
        // Device profiles beside a devices.toml of its own (none): not the user's.
        .env("MOTIONLINK_CONFIG", dir.join("devices.toml"))
        .envs(env.iter().copied())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the gateway starts");
    Gateway { child, dir }
}

impl Gateway {
    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Waits for the gateway's first line on stderr (its start, or why it could not start); the rest of stderr is
    /// read and dropped.
    pub fn first_line(&mut self) -> String {
        let mut err = self.child.stderr.take().expect("stderr");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = Vec::new();
            let mut byte = [0u8; 1];
            while std::io::Read::read(&mut err, &mut byte).unwrap_or(0) == 1 && byte[0] != b'\n' {
                line.push(byte[0]);
            }
            let _ = tx.send(String::from_utf8_lossy(&line).to_string());
            // The rest is drained: a gateway writing to a closed pipe would fail on its next message.
            let _ = std::io::copy(&mut err, &mut std::io::sink());
        });
        rx.recv_timeout(Duration::from_secs(20)).expect("a line on stderr")
    }

    /// Closes the reading end of its stderr: its next line there fails (EPIPE).
    pub fn close_stderr(&mut self) {
        drop(self.child.stderr.take());
    }

    /// Sends `signal` and waits for the end: the exit code and stderr.
    pub fn signal(mut self, signal: i32) -> (Option<i32>, String) {
        // SAFETY: kill(2) on the child's pid.
        unsafe { libc::kill(self.child.id() as i32, signal) };
        self.finish()
    }

    fn finish(&mut self) -> (Option<i32>, String) {
        let until = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let mut err = String::new();
                if let Some(mut e) = self.child.stderr.take() {
                    std::io::Read::read_to_string(&mut e, &mut err).unwrap();
                }
                return (status.code(), err);
            }
            assert!(Instant::now() < until, "the gateway did not end");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Gateway {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            // SAFETY: kill(2) on the child's pid. SIGCONT first: a gateway stopped (as by SIGTSTP) takes no
            // SIGTERM until it runs again.
            unsafe {
                libc::kill(self.child.id() as i32, libc::SIGCONT);
                libc::kill(self.child.id() as i32, libc::SIGTERM);
            }
            let (_, stderr) = self.finish();
            // A test that fails with the gateway running shows what the gateway said.
            if std::thread::panicking() {
                eprintln!("the gateway's stderr:\n{stderr}");
            }
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A message a client received.
#[derive(Debug, Clone)]
pub struct Message {
    pub topic: String,
    pub retain: bool,
    pub payload: String,
    /// The MQTT 5 correlation data, if any.
    pub correlation: Option<Vec<u8>>,
}

impl Message {
    /// The payload as JSON.
    pub fn json(&self) -> Value {
        serde_json::from_str(&self.payload).unwrap_or_else(|e| panic!("{}: {e}: {}", self.topic, self.payload))
    }
}

/// An MQTT 5 client of a test.
pub struct Client {
    pub mqtt: AsyncClient,
    rx: mpsc::UnboundedReceiver<Message>,
    /// Messages received but not yet waited for.
    backlog: Vec<Message>,
}

impl Client {
    /// Connects to `broker` as `id` and subscribes to `topics`.
    pub async fn connect(broker: &Broker, id: &str, topics: &[&str]) -> Client {
        Client::connect_as(broker, id, None, topics).await
    }

    /// Connects to `broker` as `id` with the user name and password `user` and subscribes to `topics`.
    pub async fn connect_as(broker: &Broker, id: &str, user: Option<(&str, &str)>, topics: &[&str]) -> Client {
        let mut o = MqttOptions::new(id, "127.0.0.1", broker.port);
        if let Some((name, password)) = user {
            o.set_credentials(name, password);
        }
        o.set_keep_alive(Duration::from_secs(5));
        // As the gateway: larger messages are the broker's to drop (a test sends one).
        o.set_max_packet_size(Some(64 * 1024));
        let mut network = rumqttc::NetworkOptions::new();
        network.set_tcp_nodelay(true);
        o.set_network_options(network);
        let (mqtt, mut events) = AsyncClient::new(o, 100);
        let (tx, rx) = mpsc::unbounded_channel();
        let (ready_tx, mut ready) = mpsc::unbounded_channel();
        tokio::spawn(async move {
            loop {
                match events.poll().await {
                    Ok(Event::Incoming(Packet::Publish(p))) => {
                        let m = Message {
                            topic: String::from_utf8_lossy(&p.topic).to_string(),
                            retain: p.retain,
                            payload: String::from_utf8_lossy(&p.payload).to_string(),
                            correlation: p.properties.and_then(|pp| pp.correlation_data).map(|c| c.to_vec()),
                        };
                        if tx.send(m).is_err() {
                            return;
                        }
                    }
                    Ok(Event::Incoming(Packet::SubAck(_))) => {
                        let _ = ready_tx.send(());
                    }
                    Ok(_) => {}
                    Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
                }
            }
        });
        for t in topics {
            mqtt.subscribe(*t, QoS::AtLeastOnce).await.unwrap();
            tokio::time::timeout(Duration::from_secs(5), ready.recv()).await.expect("subscribed");
        }
        Client { mqtt, rx, backlog: Vec::new() }
    }

    /// Publishes `payload` to `topic`.
    pub async fn send(&self, topic: &str, payload: impl Into<String>) {
        self.mqtt.publish(topic, QoS::AtLeastOnce, false, payload.into()).await.unwrap();
    }

    /// The next message for which `want` holds, within `within`, else a panic naming `what`.
    /// Messages received earlier and not waited for count, in order.
    pub async fn wait(&mut self, what: &str, within: Duration, mut want: impl FnMut(&Message) -> bool) -> Message {
        if let Some(i) = self.backlog.iter().position(&mut want) {
            return self.backlog.remove(i);
        }
        let until = tokio::time::Instant::now() + within;
        loop {
            match tokio::time::timeout_at(until, self.rx.recv()).await {
                Ok(Some(m)) if want(&m) => return m,
                Ok(Some(m)) => self.backlog.push(m),
                Ok(None) => panic!("{what}: the client's loop ended"),
                Err(_) => panic!("{what}: nothing within {within:?}"),
            }
        }
    }

    /// The reply to request `id` on `topic`.
    pub async fn reply(&mut self, topic: &str, id: &str, within: Duration) -> Value {
        let m = self.wait(&format!("the reply to {id}"), within, |m| m.topic == topic && m.json()["id"] == id).await;
        m.json()
    }

    /// Messages already received, without waiting.
    pub fn drain(&mut self) -> Vec<Message> {
        let mut all = std::mem::take(&mut self.backlog);
        while let Ok(m) = self.rx.try_recv() {
            all.push(m);
        }
        all
    }
}
