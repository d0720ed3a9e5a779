//! The terminal: colours (`--color`, NO_COLOR), quiet and verbose output, log lines that never garble a
//! progress bar, and the live wire trace of `-v`.

use std::io::{IsTerminal, Write};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, WeakProgressBar};
use motionlink_link::capture::UnixTime;
use motionlink_link::clock::{lock, SharedClock, Timestamp};
use motionlink_link::describe::{Annotation, Describe, DescribingTap};
use motionlink_link::hex::hex;
use tracing_subscriber::filter::{LevelFilter, Targets};
use tracing_subscriber::layer::SubscriberExt as _;
use tracing_subscriber::util::SubscriberInitExt as _;
use tracing_subscriber::Layer as _;

use crate::json::{to_json, Keyed, Telegram};

/// `--color`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ColorChoice {
    /// Colours when stderr is a terminal and NO_COLOR is not set.
    #[default]
    Auto,
    /// Always colours.
    Always,
    /// Never colours.
    Never,
}

/// How the command talks on stderr.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Output {
    /// Colours on stderr.
    pub color: bool,
    /// `-q`: only errors.
    pub quiet: bool,
    /// `-v` count: 1 the wire trace, 2 debug logs, 3 trace logs.
    pub verbose: u8,
    /// `--json`: what goes on stderr is JSON too, one object per line (logs `{"log": ...}`, the wire trace
    /// one decoded telegram per line), so that stderr can be read line by line as JSON.
    pub json: bool,
}

static OUTPUT: OnceLock<Output> = OnceLock::new();

/// `--json`, the global option: results, errors and notes are JSON.
pub fn json() -> bool {
    output().json
}

/// The output settings (defaults before [`init`]).
pub fn output() -> Output {
    *OUTPUT.get().unwrap_or(&Output { color: false, quiet: false, verbose: 0, json: false })
}

/// Decides colours: `--color always` and `never` win; `auto` colours a terminal unless NO_COLOR is set and
/// not empty (<https://no-color.org>).
pub fn use_color(choice: ColorChoice, no_color: Option<&str>, terminal: bool) -> bool {
    match choice {
        ColorChoice::Always => true,
        ColorChoice::Never => false,
        ColorChoice::Auto => terminal && no_color.is_none_or(str::is_empty),
    }
}

/// Sets up the output and the logging: errors only with `-q`, warnings by default, more with each `-v`,
/// (-v: information and the wire trace), or as `RUST_LOG` says.
/// With `json`, stderr carries JSON lines only.
///
/// At the default verbosity (no `-v`, no `RUST_LOG`) an event is one plain line for the user, `motionlink:
/// warning: ...` or `motionlink: error: ...`, without time or source ([`PlainEvent`]): the libraries log at
/// WARN only what the user must know besides the error a command ends with (a fallback such as moves polled
/// with reads, a watchdog that is not armed, a halt broadcast to every module); what only retells that
/// error, or narrates a retry or a stop whose outcome the final message gives, is logged at INFO or DEBUG
/// and shows with `-v`. With `-v` (or `RUST_LOG`) every event is a log line with time, level and source.
pub fn init(verbose: u8, quiet: bool, color: ColorChoice, json: bool) {
    let no_color = std::env::var("NO_COLOR").ok();
    let out = Output {
        color: !json && use_color(color, no_color.as_deref(), std::io::stderr().is_terminal()),
        quiet,
        verbose: if quiet { 0 } else { verbose },
        json,
    };
    let _ = OUTPUT.set(out);
    start_stderr_writer();
    let default = match (quiet, verbose) {
        (true, _) => LevelFilter::ERROR,
        (_, 0) => LevelFilter::WARN,
        (_, 1) => LevelFilter::INFO,
        (_, 2) => LevelFilter::DEBUG,
        _ => LevelFilter::TRACE,
    };
    // RUST_LOG, when set and valid, chooses the levels (`warn`, `motionlink_scu=debug,info`, ...).
    let filter = std::env::var("RUST_LOG")
        .ok()
        .and_then(|spec| spec.parse::<Targets>().ok())
        .unwrap_or_else(|| Targets::new().with_default(default));
    let plain = out.verbose == 0 && std::env::var_os("RUST_LOG").is_none();
    let logs = (!plain).then(|| {
        tracing_subscriber::fmt::layer().with_writer(LogWriter).with_ansi(out.color).with_filter(filter.clone())
    });
    let lines = plain
        .then(|| tracing_subscriber::fmt::layer().event_format(PlainEvent).with_writer(LogWriter).with_filter(filter));
    let _ = tracing_subscriber::registry().with(logs).with(lines).try_init();
}

/// An event as one plain line for the user (the default verbosity): `motionlink: warning: <message>` for
/// WARN, `motionlink: error: <message>` for ERROR, without time, level column or source.
struct PlainEvent;

impl<S, N> tracing_subscriber::fmt::FormatEvent<S, N> for PlainEvent
where
    S: tracing::Subscriber + for<'a> tracing_subscriber::registry::LookupSpan<'a>,
    N: for<'a> tracing_subscriber::fmt::FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        ctx: &tracing_subscriber::fmt::FmtContext<'_, S, N>,
        mut writer: tracing_subscriber::fmt::format::Writer<'_>,
        event: &tracing::Event<'_>,
    ) -> std::fmt::Result {
        let label = match *event.metadata().level() {
            tracing::Level::ERROR => "error",
            tracing::Level::WARN => "warning",
            _ => "note",
        };
        write!(writer, "motionlink: {label}: ")?;
        ctx.field_format().format_fields(writer.by_ref(), event)?;
        writeln!(writer)
    }
}

/// The progress bars on screen: a line written on stderr first hides them, then draws them again.
static BARS: Mutex<Vec<WeakProgressBar>> = Mutex::new(Vec::new());

/// Text for stderr, written by a thread of its own once [`init`] started it: a stderr that is slow or not
/// read at all (a pipe whose reader stalled) never holds up the thread that wrote the line (the session's,
/// the signals'), so a stop is never kept waiting for a log line or a `-v` trace.
struct StderrQueue {
    texts: std::collections::VecDeque<String>,
    /// Texts left out since the last one written: the queue was full.
    left_out: usize,
    /// The writer is writing a text it took.
    writing: bool,
}

static STDERR_QUEUE: Mutex<StderrQueue> =
    Mutex::new(StderrQueue { texts: std::collections::VecDeque::new(), left_out: 0, writing: false });
static STDERR_WAKE: std::sync::Condvar = std::sync::Condvar::new();
/// Set once the writer runs; until then (and where it could not be started) stderr is written at once.
static STDERR_WRITER: OnceLock<()> = OnceLock::new();
/// At most this many texts wait for a stderr that is not read; more are left out (and counted).
const STDERR_QUEUE_TEXTS: usize = 4096;

fn start_stderr_writer() {
    // One writer, however often `init` runs.
    static STARTED: std::sync::Once = std::sync::Once::new();
    STARTED.call_once(spawn_stderr_writer);
}

fn spawn_stderr_writer() {
    let spawned = std::thread::Builder::new().name("stderr".into()).spawn(|| loop {
        let (text, left_out) = {
            let mut q = lock(&STDERR_QUEUE);
            while q.texts.is_empty() {
                q = STDERR_WAKE.wait(q).unwrap_or_else(|e| e.into_inner());
            }
            q.writing = true;
            let left_out = std::mem::take(&mut q.left_out);
            (q.texts.pop_front().unwrap_or_default(), left_out)
        };
        if left_out > 0 {
            write_stderr_now(&format!("motionlink: {left_out} lines for stderr left out (it was not read)\n"));
        }
        write_stderr_now(&text);
        lock(&STDERR_QUEUE).writing = false;
        STDERR_WAKE.notify_all();
    });
    if spawned.is_ok() {
        let _ = STDERR_WRITER.set(());
    }
}

/// Waits until every text given to [`write_stderr`] was written, at most `bound` (a stderr nobody reads
/// would keep the process from ending): before the process exits.
pub fn flush_stderr(bound: Duration) {
    if STDERR_WRITER.get().is_none() {
        return;
    }
    let deadline = std::time::Instant::now() + bound;
    let mut q = lock(&STDERR_QUEUE);
    while !q.texts.is_empty() || q.writing {
        let Some(left) = deadline.checked_duration_since(std::time::Instant::now()) else { return };
        q = STDERR_WAKE.wait_timeout(q, left).unwrap_or_else(|e| e.into_inner()).0;
    }
}

/// Writes `text` (one or more whole lines) on stderr without garbling a progress bar, ignoring failures
/// (after SIGHUP the terminal may be gone), through the writer thread once [`init`] started it: never
/// waiting for a stderr that is slow or not read.
pub fn write_stderr(text: &str) {
    if STDERR_WRITER.get().is_none() {
        return write_stderr_now(text);
    }
    let mut q = lock(&STDERR_QUEUE);
    if q.texts.len() >= STDERR_QUEUE_TEXTS {
        q.left_out += 1;
        return;
    }
    q.texts.push_back(text.to_string());
    STDERR_WAKE.notify_all();
}

fn write_stderr_now(text: &str) {
    let bar = {
        let mut bars = lock(&BARS);
        bars.retain(|b| b.upgrade().is_some_and(|b| !b.is_finished()));
        bars.first().and_then(WeakProgressBar::upgrade)
    };
    let write = || {
        let mut err = std::io::stderr().lock();
        let _ = err.write_all(text.as_bytes());
        let _ = err.flush();
    };
    match bar {
        Some(bar) => bar.suspend(write),
        None => write(),
    }
}

/// Collects one log event and writes it in one piece when dropped: an ERROR event as an error line, any other
/// as a note (left out once stdout was closed).
#[derive(Default)]
struct LineWriter {
    text: Vec<u8>,
    error: bool,
}

impl Write for LineWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.text.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for LineWriter {
    fn drop(&mut self) {
        if self.text.is_empty() {
            return;
        }
        let text = String::from_utf8_lossy(&self.text);
        if self.error {
            error_note(text.trim_end());
        } else {
            note(text.trim_end());
        }
    }
}

/// Makes a [`LineWriter`] per log event, knowing the event's level.
struct LogWriter;

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for LogWriter {
    type Writer = LineWriter;

    fn make_writer(&'a self) -> LineWriter {
        LineWriter::default()
    }

    fn make_writer_for(&'a self, meta: &tracing::Metadata<'_>) -> LineWriter {
        LineWriter { text: Vec::new(), error: *meta.level() == tracing::Level::ERROR }
    }
}

/// Set once stdout was closed by its reader: notes are left out from then on.
static OUTPUT_CLOSED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Records that stdout was closed by its reader.
pub fn mark_output_closed() {
    OUTPUT_CLOSED.store(true, std::sync::atomic::Ordering::SeqCst);
}

/// True once stdout was closed by its reader.
fn output_closed() -> bool {
    OUTPUT_CLOSED.load(std::sync::atomic::Ordering::SeqCst)
}

/// A line of information on stderr (a log event, a note of the command): as it is, or with `--json` as
/// `{"log": "<text>"}`. Left out with `-q` (only errors) and once stdout was closed: the command then ends
/// quietly, after stopping what it started.
pub fn note(text: &str) {
    if output().quiet || output_closed() {
        return;
    }
    if output().json {
        write_stderr(&format!("{}\n", to_json(&Keyed("log", text))));
    } else {
        write_stderr(&format!("{text}\n"));
    }
}

/// An error besides the one the command ends with, on stderr even with `-q`: red when colours are on, with
/// `--json` as `{"log": "<text>"}`.
pub fn error_note(text: &str) {
    if output().json {
        write_stderr(&format!("{}\n", to_json(&Keyed("log", text))));
    } else {
        write_stderr(&error_line(text));
    }
}

/// An error message on stderr, in red when colours are on.
pub fn error_line(text: &str) -> String {
    if output().color {
        format!("\x1b[31m{text}\x1b[0m\n")
    } else {
        format!("{text}\n")
    }
}

/// A progress bar on stderr, drawn only when stderr is a terminal and the command is not quiet; log lines
/// and messages are written around it.
pub fn progress_bar(length: u64, message: impl Into<String>) -> ProgressBar {
    let visible = std::io::stderr().is_terminal() && !output().quiet;
    let target = if visible { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
    let bar = ProgressBar::with_draw_target(Some(length), target);
    let template = if output().color {
        "{msg} [{bar:40.cyan/blue}] {pos}/{len} {elapsed}"
    } else {
        "{msg} [{bar:40}] {pos}/{len} {elapsed}"
    };
    bar.set_style(
        ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar()).progress_chars("=> "),
    );
    bar.set_message(message.into());
    bar.enable_steady_tick(Duration::from_millis(200));
    lock(&BARS).push(bar.downgrade());
    bar
}

/// The live wire trace of `-v`: every telegram, with direction, time (UTC time of day), hex and meaning, on
/// stderr: the library's [`DescribingTap`] with a printer.
pub type WireTrace = DescribingTap;

/// A wire trace that explains telegrams with `describer`; times from `clock`.
pub fn wire_trace(describer: Box<dyn Describe + Send>, clock: &SharedClock) -> WireTrace {
    let time = UnixTime::of(clock);
    DescribingTap::new(
        describer,
        Box::new(move |fallback_at: Timestamp, found: &mut Vec<Annotation>| print_trace(&time, found, fallback_at)),
    )
}

fn print_trace(time: &UnixTime, annotations: &[Annotation], fallback_at: Timestamp) {
    for a in annotations {
        let at = time.at(a.at.unwrap_or(fallback_at));
        let local = at.as_secs() % 86_400;
        let stamp = format!("{:02}:{:02}:{:02}.{:06}", local / 3600, (local / 60) % 60, local % 60, at.subsec_micros());
        // A CAN frame as candump writes it (0C9#0A3C), serial bytes as spaced hex.
        let data = match a.can_id {
            Some(id) => format!("{id:03X}#{}", hex(&a.bytes).replace(' ', "")),
            None => hex(&a.bytes),
        };
        let mark = if a.bad { "!!" } else { a.direction.arrow() };
        if output().json {
            let telegram = Telegram { time_s: Some(at.as_secs_f64()), can_id: Some(a.can_id), ..Telegram::of(a, None) };
            write_stderr(&format!("{}\n", to_json(&Keyed("trace", telegram))));
            continue;
        }
        write_stderr(&format!("{stamp} {mark} {data:<30} {}\n", a.meaning));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_follow_the_flag_then_no_color_then_the_terminal() {
        assert!(use_color(ColorChoice::Always, Some("1"), false));
        assert!(!use_color(ColorChoice::Never, None, true));
        assert!(use_color(ColorChoice::Auto, None, true));
        assert!(use_color(ColorChoice::Auto, Some(""), true), "an empty NO_COLOR does not count");
        assert!(!use_color(ColorChoice::Auto, Some("1"), true));
        assert!(!use_color(ColorChoice::Auto, None, false));
    }
}
