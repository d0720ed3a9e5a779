//! What a family command's port comes from and what watches it: `--device` (with `--port` and
//! `MOTIONLINK_PORT`, resolved by [`crate::devices`]), `-v`'s live wire trace ([`crate::term::WireTrace`]) and
//! `--capture`'s file ([`CaptureWriter`]), both fed by a tap on the link ([`TapLink`], [`TapCanLink`]).

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use motionlink_link::can::CanLink;
use motionlink_link::capture::{CaptureWriter, Fanout, TapCanLink, TapLink, TapSink};
use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::clock::lock;
use motionlink_link::describe::{Annotation, Describe, DescribingTap, OnTelegrams};
use motionlink_link::error::{ErrorClass, TransportKind};
use motionlink_link::link::Link;
use motionlink_link::LinkError;
use motionlink_link::{SharedClock, Timestamp};

use crate::common::CliError;

/// The options every family command shares besides `--port`: where the port comes from and where its
/// traffic goes.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct LinkArgs {
    /// A device named in the configuration file (devices.toml in the platform's configuration directory, or
    /// the file MOTIONLINK_CONFIG names), instead of --port: its port, and its options where the command line
    /// gives none. Without either, MOTIONLINK_PORT is the port.
    #[arg(long, value_name = "NAME", global = true)]
    pub device: Option<String>,
    /// Write every telegram of the session to FILE, time-stamped: the capture format of docs/cli.md for
    /// serial lines, candump log lines for CAN. `motionlink decode` reads it back.
    #[arg(long, value_name = "FILE", global = true)]
    pub capture: Option<PathBuf>,
}

impl LinkArgs {
    /// The port of a `family` command: `--port`, else `--device`, else `MOTIONLINK_PORT`.
    pub fn resolve_port(&self, family: &str, port: Option<&str>) -> Result<String, CliError> {
        motionlink_link::devices::resolve(family, port, self.device.as_deref())
            .map_err(|e| crate::common::classified(&e))
    }
}

/// The port (as the user gave it) whose first connection a busy `motionlink sim` server refused, if one did.
static REFUSED_AS_BUSY: OnceLock<String> = OnceLock::new();

/// Told when [`REFUSED_AS_BUSY`] is set (for the console, which serves on while its scans fail).
static REFUSED_NOTICE: tokio::sync::Notify = tokio::sync::Notify::const_new();

/// Completes once a busy server has refused the command's first connection.
pub async fn refused_as_busy_notice() {
    if REFUSED_AS_BUSY.get().is_none() {
        REFUSED_NOTICE.notified().await;
    }
}

/// Watches the links of one port for a busy server's refusal ([`LinkError::Busy`]) on the command's first
/// connection: nothing can have been started then, and the command's error is told as the one plain line
/// [`refused_as_busy`] makes of it. (A refusal of a reconnection keeps the family's own message, which says
/// what became of what was started.)
#[derive(Clone)]
pub struct BusyWatch {
    port: Arc<str>,
    opened: Arc<AtomicUsize>,
}

impl BusyWatch {
    /// A watch of `port`, as the user gave it.
    pub fn new(port: &str) -> Self {
        BusyWatch { port: port.into(), opened: Arc::new(AtomicUsize::new(0)) }
    }

    /// `link`, watched.
    pub fn link(&self, link: Box<dyn Link>) -> Box<dyn Link> {
        let first = self.opened.fetch_add(1, Ordering::SeqCst) == 0;
        Box::new(BusyLink { inner: link, port: first.then(|| Arc::clone(&self.port)) })
    }
}

/// A link whose refusal by a busy server is recorded when it is the command's first connection.
struct BusyLink {
    inner: Box<dyn Link>,
    /// The port, on the first connection only.
    port: Option<Arc<str>>,
}

impl BusyLink {
    fn seen<T>(&self, result: Result<T, LinkError>) -> Result<T, LinkError> {
        if let (Err(LinkError::Busy { .. }), Some(port)) = (&result, &self.port) {
            if REFUSED_AS_BUSY.set(port.to_string()).is_ok() {
                REFUSED_NOTICE.notify_one();
            }
        }
        result
    }
}

impl Link for BusyLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let r = self.inner.send(bytes);
        self.seen(r)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: std::time::Duration) -> Result<usize, LinkError> {
        let r = self.inner.recv(buf, timeout);
        self.seen(r)
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        let r = self.inner.discard_input();
        self.seen(r)
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
    fn send_break(&mut self, duration: std::time::Duration) -> Result<(), LinkError> {
        let r = self.inner.send_break(duration);
        self.seen(r)
    }
}

/// The command's transport error `e` as the one plain line `<port> is busy: another client is connected`
/// (exit code 3) when a busy server refused the command's first connection; any other error as it is.
pub fn refused_as_busy(e: CliError) -> CliError {
    match REFUSED_AS_BUSY.get() {
        Some(port) if e.class().is_transport() => {
            CliError::Transport(TransportKind::Io, LinkError::Busy { port: port.clone() }.to_string())
        }
        _ => e,
    }
}

/// A describer of a family's traffic, made anew for each watcher (each keeps its own state).
pub type MakeDescriber<'a> = &'a dyn Fn() -> Box<dyn Describe + Send>;

/// The telegrams of a session, explained as they pass (for `send`, which prints the request and its reply):
/// the library's [`DescribingTap`] keeping what it explains.
pub struct Telegrams {
    seen: Arc<Mutex<Vec<Annotation>>>,
    tap: DescribingTap,
}

impl Telegrams {
    fn new(describer: Box<dyn Describe + Send>) -> Self {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let keep = Arc::clone(&seen);
        let tap = DescribingTap::new(
            describer,
            Box::new(move |_: Timestamp, found: &mut Vec<Annotation>| lock(&keep).append(found)) as OnTelegrams,
        );
        Telegrams { seen, tap }
    }

    /// Forgets what was seen so far.
    pub fn clear(&self) {
        lock(&self.seen).clear();
    }

    /// Every telegram seen since the last `clear` or `take`.
    pub fn take(&self) -> Vec<Annotation> {
        std::mem::take(&mut *lock(&self.seen))
    }
}

impl TapSink for Telegrams {
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        self.tap.record(at, direction, data);
    }
}

/// Counts what came from the device (bytes of a serial line, CAN frames): whether anything answered at all.
#[derive(Default)]
struct Heard(AtomicU64);

impl TapSink for Heard {
    fn record(&self, _: Timestamp, direction: Direction, _: Chunk<'_>) {
        if direction == Direction::FromDevice {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// What watches a family command's link: whether anything answered, the live trace (`-v`), the capture
/// file (`--capture`) and, for `send`, the telegrams kept to be printed.
#[derive(Clone, Default)]
pub struct Tap {
    busy: Option<BusyWatch>,
    sink: Option<Arc<dyn TapSink>>,
    telegrams: Option<Arc<Telegrams>>,
    capture: Option<Arc<CaptureWriter>>,
    heard: Arc<Heard>,
}

impl Tap {
    /// The tap of a `family` command on `port`: a wire trace when `-v` was given, a capture file when
    /// `args.capture` names one (CAN frames are written with `can_interface` as their interface), the
    /// telegrams kept when `keep` is true. Times come from `clock`.
    pub fn new(
        family: &str,
        port: &str,
        clock: &SharedClock,
        args: &LinkArgs,
        can_interface: &str,
        make: MakeDescriber<'_>,
        keep: bool,
    ) -> Result<Tap, CliError> {
        let heard = Arc::new(Heard::default());
        let mut sinks: Vec<Arc<dyn TapSink>> = vec![Arc::clone(&heard) as Arc<dyn TapSink>];
        if crate::term::output().verbose >= 1 {
            sinks.push(Arc::new(crate::term::wire_trace(make(), clock)));
        }
        let mut capture = None;
        if let Some(path) = &args.capture {
            let file = std::fs::File::create(path)
                .map_err(|e| CliError::usage(format!("--capture {}: {e}", path.display())))?;
            let writer = CaptureWriter::new(Box::new(file), clock, &format!("{family} on {port}"), can_interface)
                .map_err(|e| CliError::usage(format!("--capture {}: {e}", path.display())))?;
            let writer = Arc::new(writer);
            capture = Some(Arc::clone(&writer));
            sinks.push(writer);
        }
        let telegrams = keep.then(|| Arc::new(Telegrams::new(make())));
        if let Some(t) = &telegrams {
            sinks.push(Arc::clone(t) as Arc<dyn TapSink>);
        }
        let sink: Option<Arc<dyn TapSink>> = match sinks.len() {
            0 => None,
            1 => sinks.pop(),
            _ => Some(Arc::new(Fanout(sinks))),
        };
        Ok(Tap { busy: Some(BusyWatch::new(port)), sink, telegrams, capture, heard })
    }

    /// A tap that feeds `sink` alone (the console's traffic log), watching `port` for a busy server's refusal.
    pub fn into_sink(port: &str, sink: Arc<dyn TapSink>) -> Tap {
        Tap { busy: Some(BusyWatch::new(port)), sink: Some(sink), ..Tap::default() }
    }

    /// True if anything came from the device on the tapped link (a byte, a CAN frame).
    pub fn heard_anything(&self) -> bool {
        self.heard.0.load(Ordering::Relaxed) > 0
    }

    /// `e` as the user reads it when it is a timeout and nothing at all came from the device during the
    /// session: `absent()` names the device as absent (and what to check), instead of the request that went
    /// unanswered. The error's class (and so its exit code and `--json` kind) stays. An error that says a
    /// stop was not confirmed keeps its message, and `absent()` follows it ([`Tap::name_absent_after`]).
    pub fn name_absent(&self, e: CliError, absent: impl FnOnce() -> String) -> CliError {
        if e.stop_unconfirmed() {
            return self.name_absent_after(e, absent);
        }
        if self.unheard_timeout(&e) {
            e.map_message(|_| absent())
        } else {
            e
        }
    }

    /// As [`Tap::name_absent`], for a `stop`: the message of what the stop did (whether anything was
    /// stopped) stays, and `absent()` follows it.
    pub fn name_absent_after(&self, e: CliError, absent: impl FnOnce() -> String) -> CliError {
        if self.unheard_timeout(&e) {
            e.map_message(|said| format!("{said}; {}", absent()))
        } else {
            e
        }
    }

    /// True if `e` is a timeout and nothing came from the device.
    fn unheard_timeout(&self, e: &CliError) -> bool {
        e.class() == ErrorClass::Transport(TransportKind::Timeout) && !self.heard_anything()
    }

    /// `link`, watched for a busy server's refusal ([`BusyWatch`]) and tapped if anything watches it.
    pub fn link(&self, link: Box<dyn Link>, clock: &SharedClock) -> Box<dyn Link> {
        let link = match &self.busy {
            Some(busy) => busy.link(link),
            None => link,
        };
        match &self.sink {
            Some(sink) => Box::new(TapLink::new(link, Arc::clone(clock), Arc::clone(sink))),
            None => link,
        }
    }

    /// `link`, tapped if anything watches it.
    pub fn can_link(&self, link: Box<dyn CanLink>, clock: &SharedClock) -> Box<dyn CanLink> {
        match &self.sink {
            Some(sink) => Box::new(TapCanLink::new(link, Arc::clone(clock), Arc::clone(sink))),
            None => link,
        }
    }

    /// `send`: what `run` returned, and the telegrams seen while it ran.
    pub fn seen_during<T>(&self, run: impl FnOnce() -> T) -> Result<(T, Vec<Annotation>), CliError> {
        let telegrams = self.telegrams.as_deref().ok_or_else(|| CliError::usage("send: no tap on the link"))?;
        telegrams.clear();
        let result = run();
        Ok((result, telegrams.take()))
    }

    /// Flushes the capture file, if any.
    pub fn flush(&self) {
        if let Some(c) = &self.capture {
            if let Err(e) = c.flush() {
                tracing::warn!("cannot write the capture: {e}");
            }
        }
    }
}

/// The interface name of a CAN port in a capture: the SocketCAN interface, else `can0`.
pub fn can_interface(port: &motionlink_link::url::PortUrl) -> String {
    match port {
        motionlink_link::url::PortUrl::SocketCan(name) => name.clone(),
        _ => "can0".into(),
    }
}

/// The request and its reply among the telegrams `send` saw: the last telegram to the device (the last one
/// whose bytes are `request`, if given), and the first telegram from the device after it.
pub fn exchange(telegrams: &[Annotation], request: Option<&[u8]>) -> (Option<Annotation>, Option<Annotation>) {
    let sent = telegrams
        .iter()
        .rposition(|a| a.direction == Direction::ToDevice && request.is_none_or(|r| a.bytes == r))
        .or_else(|| telegrams.iter().rposition(|a| a.direction == Direction::ToDevice));
    let Some(i) = sent else { return (None, None) };
    let reply = telegrams[i + 1..].iter().find(|a| a.direction == Direction::FromDevice).cloned();
    (Some(telegrams[i].clone()), reply)
}

/// The telegram `send` sent and the reply to it, among the telegrams a command that may wait saw: the first
/// telegram to the device whose bytes contain `request` (else the first one to the device) and the first
/// telegram from the device after it, before the next one to the device. The third part is every telegram after that reply (the status polls
/// of a wait, with their replies).
pub fn first_exchange(
    telegrams: &[Annotation],
    request: &[u8],
) -> (Option<Annotation>, Option<Annotation>, Vec<Annotation>) {
    let contains = |a: &Annotation| !request.is_empty() && a.bytes.windows(request.len()).any(|w| w == request);
    let to_device = |a: &Annotation| a.direction == Direction::ToDevice;
    let sent =
        telegrams.iter().position(|a| to_device(a) && contains(a)).or_else(|| telegrams.iter().position(to_device));
    let Some(i) = sent else { return (None, None, Vec::new()) };
    // The reply comes before the next telegram to the device (a command that asks for none has none: the
    // reply to a later poll is not its reply).
    let next_sent = telegrams[i + 1..].iter().position(to_device).map_or(telegrams.len(), |j| i + 1 + j);
    let reply =
        telegrams[i + 1..next_sent].iter().position(|a| a.direction == Direction::FromDevice).map(|j| i + 1 + j);
    let rest_from = reply.map_or(i + 1, |j| j + 1);
    (Some(telegrams[i].clone()), reply.map(|j| telegrams[j].clone()), telegrams[rest_from..].to_vec())
}

/// What `send --json` prints after the unit's identity: the command in words, the telegrams sent and received
/// (each explained, as `decode` explains them), whether the device took it, then the family's own fields
/// (`extra`, flattened into the same object).
#[derive(serde::Serialize)]
pub struct Sent<'a, X> {
    /// The command, in words.
    pub command: &'a str,
    /// The request telegram, explained (none seen: null).
    pub request: Option<serde_json::Value>,
    /// The reply telegram, explained (none seen: null).
    pub reply: Option<serde_json::Value>,
    /// Whether the device took the command.
    pub ok: bool,
    /// The family's own fields.
    #[serde(flatten)]
    pub extra: X,
}

/// Prints `send`'s exchange, `sent` and its `reply`: each telegram explained on a line of text (or `which: none`),
/// or with `--json` one [`Sent`] object through `o` (times of the session's clock are no Unix times: left
/// out; `-v` and `--capture` give them). `command` is the command in words, `ok` whether the device took it.
pub fn print_sent<X: serde::Serialize>(
    out: &mut dyn std::io::Write,
    o: &crate::common::Out<'_>,
    (sent, reply): (Option<Annotation>, Option<Annotation>),
    command: &str,
    ok: bool,
    extra: X,
) -> Result<(), CliError> {
    let untimed = |a: Option<Annotation>| a.map(|a| Annotation { at: None, ..a });
    let (sent, reply) = (untimed(sent), untimed(reply));
    if o.json {
        let j = |a: Option<Annotation>| a.map(|a| crate::common::to_json(&crate::json::Telegram::of(&a, None)));
        return o.print(out, Sent { command, request: j(sent), reply: j(reply), ok, extra });
    }
    for (which, a) in [("request", &sent), ("reply", &reply)] {
        match a {
            Some(a) => writeln!(out, "{}", crate::decode::annotation_text(a, None))?,
            None => writeln!(out, "{which}: none")?,
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn telegram(direction: Direction, text: &str) -> Annotation {
        Annotation {
            at: None,
            direction,
            can_id: None,
            bytes: text.as_bytes().to_vec(),
            meaning: text.into(),
            bad: false,
        }
    }

    #[test]
    fn the_reply_is_the_one_to_the_telegram_sent_not_a_later_polls() {
        let (to, from) = (Direction::ToDevice, Direction::FromDevice);
        let seen = [telegram(to, "1POSA 1\r"), telegram(from, "\r\n>"), telegram(to, "1S1\r"), telegram(from, "S1 1")];
        let (sent, reply, rest) = first_exchange(&seen, b"POSA 1");
        assert_eq!(
            (sent.unwrap().meaning, reply.unwrap().meaning, rest.len()),
            ("1POSA 1\r".into(), "\r\n>".into(), 2)
        );
        // A command that asks for no reply has none: the poll's reply is not taken for it.
        let seen = [telegram(to, "1POSA 1/\r"), telegram(to, "1S1\r"), telegram(from, "S1 1")];
        let (sent, reply, rest) = first_exchange(&seen, b"POSA 1/");
        assert!(sent.is_some() && reply.is_none() && rest.len() == 2, "{reply:?} {rest:?}");
    }
}
