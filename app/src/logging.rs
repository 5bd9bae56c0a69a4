//! rigview's messages: [`tracing`] events, written to stderr at the level
//! the command line chooses (`-v`, `-vv`, or `RUST_LOG`), and kept in a
//! [`LogBuffer`] that the window's Messages panel and the headless modes'
//! status read: both show the same events.
//!
//! | target | what |
//! | --- | --- |
//! | [`NOTE`] (`rigview::cli`) | notes for the operator that stderr shows by default (the window's summary when it closes) |
//! | `rigview::…` (module paths) | what the session, the sources and the window report: on stderr with `-v`, always in the buffer |
//! | [`SOURCE`], [`PIPELINE`] | a source's messages and the pipeline's problems, as [`StatusLog`] passes them on from the pipeline's status |
//!
//! What a command is for (tables, status blocks, summaries) is printed on
//! stdout and is not a log.

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use rigview_core::pipeline::PipelineStatus;
use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::filter::{EnvFilter, LevelFilter, Targets};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};
use tracing_subscriber::registry::LookupSpan;

/// The target of notes the command line shows on stderr by default.
pub const NOTE: &str = "rigview::cli";
/// The target of a source's messages passed on from the pipeline's status.
pub const SOURCE: &str = "rigview::source";
/// The target of the pipeline's problems passed on from its status.
pub const PIPELINE: &str = "rigview::pipeline";

/// Entries a buffer keeps; older ones are forgotten.
const CAPACITY: usize = 1000;

/// One event as the buffer keeps it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Its place in the buffer's sequence (0 for the first event).
    pub seq: u64,
    /// Its level.
    pub level: Level,
    /// Its target (a module path, or one of this module's targets).
    pub target: String,
    /// The message, followed by the event's other fields as `name=value`.
    pub message: String,
}

impl Entry {
    /// A warning or an error.
    pub fn is_problem(&self) -> bool {
        self.level <= Level::WARN
    }

    /// The entry as a line for the terminal: the message, after `warning:`
    /// or `error:` for problems.
    pub fn line(&self) -> String {
        match self.level {
            Level::ERROR => format!("error: {}", self.message),
            Level::WARN => format!("warning: {}", self.message),
            _ => self.message.clone(),
        }
    }
}

#[derive(Debug, Default)]
struct Ring {
    entries: VecDeque<Entry>,
    next: u64,
}

/// The recent events, shared: cloning a buffer shares its entries.
#[derive(Clone, Debug, Default)]
pub struct LogBuffer(Arc<Mutex<Ring>>);

impl LogBuffer {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// The buffer that [`init`] feeds.
    pub fn global() -> &'static LogBuffer {
        static GLOBAL: OnceLock<LogBuffer> = OnceLock::new();
        GLOBAL.get_or_init(LogBuffer::new)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Ring> {
        // Every update leaves the ring consistent.
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn push(&self, level: Level, target: &str, message: String) {
        let mut ring = self.lock();
        let seq = ring.next;
        ring.next += 1;
        ring.entries.push_back(Entry {
            seq,
            level,
            target: target.to_owned(),
            message,
        });
        while ring.entries.len() > CAPACITY {
            ring.entries.pop_front();
        }
    }

    /// The sequence number the next event will get: [`LogBuffer::since`]
    /// with it gives what comes from now on.
    pub fn next_seq(&self) -> u64 {
        self.lock().next
    }

    /// The entries from sequence number `seq` on (those still kept),
    /// oldest first.
    pub fn since(&self, seq: u64) -> Vec<Entry> {
        self.lock()
            .entries
            .iter()
            .filter(|e| e.seq >= seq)
            .cloned()
            .collect()
    }

    /// The entries after those already read, moving `cursor` past them.
    pub fn read(&self, cursor: &mut u64) -> Vec<Entry> {
        let entries = self.since(*cursor);
        *cursor = entries.last().map_or(*cursor, |e| e.seq + 1);
        entries
    }

    /// A layer that keeps the events it is given in this buffer.
    pub fn layer(&self) -> BufferLayer {
        BufferLayer {
            buffer: self.clone(),
        }
    }
}

/// A [`Layer`] that keeps events in a [`LogBuffer`].
#[derive(Debug)]
pub struct BufferLayer {
    buffer: LogBuffer,
}

/// An event's message and other fields as text.
#[derive(Default)]
struct Text {
    message: String,
    fields: String,
}

impl Visit for Text {
    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.message.push_str(value);
        } else {
            let _ = write!(self.fields, " {}={value}", field.name());
        }
    }

    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.message, "{value:?}");
        } else {
            let _ = write!(self.fields, " {}={value:?}", field.name());
        }
    }
}

impl<S: Subscriber> Layer<S> for BufferLayer {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let mut text = Text::default();
        event.record(&mut text);
        let meta = event.metadata();
        self.buffer
            .push(*meta.level(), meta.target(), text.message + &text.fields);
    }
}

/// What the buffer keeps: rigview's own events from `info` up (its crates'
/// targets begin with `rigview`), nothing of other crates.
pub fn buffer_filter() -> Targets {
    Targets::new().with_target("rigview", LevelFilter::INFO)
}

/// The stderr filter of `-v` given `verbosity` times: warnings and the
/// command line's notes; with `-v` everything rigview reports; with `-vv`
/// its details; with `-vvv` everything it can say. Other crates' warnings
/// show at every level.
pub fn stderr_filter(verbosity: u8) -> EnvFilter {
    let rigview = match verbosity {
        0 => return EnvFilter::new(format!("warn,{NOTE}=info")),
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    EnvFilter::new(format!(
        "warn,rigview={rigview},rigview_core={rigview},rigview_calib={rigview}"
    ))
}

/// A subscriber that keeps rigview's events in `buffer` (as
/// [`buffer_filter`] says) and writes nothing.
pub fn buffer_only(buffer: &LogBuffer) -> impl Subscriber + for<'a> LookupSpan<'a> {
    tracing_subscriber::registry().with(buffer.layer().with_filter(buffer_filter()))
}

/// Keeps this thread's events in `buffer` until the guard is dropped (for
/// tests and other front ends that run rigview in-process without
/// [`init`]; events of other threads are not seen).
pub fn capture(buffer: &LogBuffer) -> tracing::subscriber::DefaultGuard {
    tracing::subscriber::set_default(buffer_only(buffer))
}

/// Installs the process's subscriber: events to stderr as `RUST_LOG` says,
/// or else as [`stderr_filter`] says for `verbosity`; rigview's events also
/// into [`LogBuffer::global`].
pub fn init(verbosity: u8) -> anyhow::Result<()> {
    use std::io::IsTerminal;
    use tracing_subscriber::util::SubscriberInitExt;

    let filter = match std::env::var("RUST_LOG") {
        Ok(spec) if !spec.trim().is_empty() => {
            EnvFilter::try_new(&spec).map_err(|e| anyhow::anyhow!("RUST_LOG={spec}: {e}"))?
        }
        _ => stderr_filter(verbosity),
    };
    let stderr = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .without_time()
        .with_target(verbosity > 0)
        .with_filter(filter);
    tracing_subscriber::registry()
        .with(stderr)
        .with(LogBuffer::global().layer().with_filter(buffer_filter()))
        .try_init()
        .map_err(|e| anyhow::anyhow!("cannot set up the messages: {e}"))
}

/// Passes the pipeline's status messages on as events: a source's messages
/// ([`SOURCE`], `info`) and the pipeline's problems ([`PIPELINE`], `warn`),
/// each once.
#[derive(Clone, Debug, Default)]
pub struct StatusLog {
    notes_seen: u64,
    errors_seen: u64,
}

impl StatusLog {
    /// Sends what is new in `status`.
    pub fn forward(&mut self, status: &PipelineStatus) {
        for n in fresh(&status.notes, status.notes_total, &mut self.notes_seen) {
            tracing::info!(target: SOURCE, "{n}");
        }
        for e in fresh(&status.errors, status.errors_total, &mut self.errors_seen) {
            tracing::warn!(target: PIPELINE, "{e}");
        }
    }
}

/// The entries of `recent` (the newest of `total` so far) not seen yet;
/// `seen` moves on to `total`.
fn fresh<'a>(
    recent: &'a VecDeque<String>,
    total: u64,
    seen: &mut u64,
) -> impl Iterator<Item = &'a String> {
    let new = usize::try_from(total.saturating_sub(*seen)).unwrap_or(usize::MAX);
    *seen = total;
    recent.iter().skip(recent.len().saturating_sub(new))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `f` with the events of this thread going through `filter` into
    /// a buffer; returns what the buffer kept.
    fn kept(filter: EnvFilter, f: impl FnOnce()) -> Vec<Entry> {
        let buffer = LogBuffer::new();
        let subscriber = tracing_subscriber::registry().with(buffer.layer().with_filter(filter));
        tracing::subscriber::with_default(subscriber, f);
        buffer.since(0)
    }

    fn messages(entries: &[Entry]) -> Vec<&str> {
        entries.iter().map(|e| e.message.as_str()).collect()
    }

    #[test]
    fn events_reach_the_buffer_with_their_level_target_and_fields() {
        let buffer = LogBuffer::new();
        {
            let _g = capture(&buffer);
            tracing::info!(camera = "front", "open, {}×{}", 322, 241);
            tracing::warn!(target: PIPELINE, "a set was dropped");
        }
        let e = buffer.since(0);
        assert_eq!(e.len(), 2, "{e:?}");
        assert_eq!(e[0].message, "open, 322×241 camera=front");
        assert_eq!(e[0].target, "rigview::logging::tests");
        assert_eq!((e[0].level, e[0].is_problem()), (Level::INFO, false));
        assert_eq!(e[1].line(), "warning: a set was dropped");
        assert!(e[1].is_problem());
        // Reading moves past what was read.
        let mut cursor = 0;
        assert_eq!(buffer.read(&mut cursor).len(), 2);
        assert!(buffer.read(&mut cursor).is_empty());
        tracing::subscriber::with_default(buffer_only(&buffer), || tracing::info!("later"));
        assert_eq!(messages(&buffer.read(&mut cursor)), ["later"]);
    }

    #[test]
    fn the_buffer_keeps_rigviews_events_from_info_up_and_forgets_the_oldest() {
        let buffer = LogBuffer::new();
        tracing::subscriber::with_default(buffer_only(&buffer), || {
            tracing::debug!("a detail");
            tracing::info!(target: "wgpu_core::device", "another crate's note");
            tracing::warn!(target: "rigview_core::sim", "core's warning");
            for k in 0..CAPACITY + 5 {
                tracing::info!("note {k}");
            }
        });
        let e = buffer.since(0);
        assert_eq!(e.len(), CAPACITY);
        assert_eq!(e[0].message, "note 5");
        assert_eq!(e[0].seq, 6);
        assert_eq!(buffer.next_seq(), CAPACITY as u64 + 6);
    }

    #[test]
    fn the_verbosity_chooses_what_stderr_shows() {
        let emit = || {
            tracing::info!(target: NOTE, "the window's summary");
            tracing::info!(target: "rigview::session", "scene traced");
            tracing::debug!(target: "rigview_core::sim", "a render");
            tracing::warn!(target: "rigview::live", "camera lost");
            tracing::warn!(target: "eframe", "no vsync");
            tracing::info!(target: "eframe", "a note of another crate");
        };
        assert_eq!(
            messages(&kept(stderr_filter(0), emit)),
            ["the window's summary", "camera lost", "no vsync"]
        );
        assert_eq!(
            messages(&kept(stderr_filter(1), emit)),
            [
                "the window's summary",
                "scene traced",
                "camera lost",
                "no vsync"
            ]
        );
        assert_eq!(
            messages(&kept(stderr_filter(2), emit)),
            [
                "the window's summary",
                "scene traced",
                "a render",
                "camera lost",
                "no vsync"
            ]
        );
    }

    #[test]
    fn status_messages_are_passed_on_once() {
        let buffer = LogBuffer::new();
        let _g = capture(&buffer);
        let mut log = StatusLog::default();
        let mut status = PipelineStatus::default();
        status
            .notes
            .push_back("front: its own auto-exposure is on".into());
        status.notes_total = 1;
        log.forward(&status);
        log.forward(&status);
        status.errors.push_back("camera 7 is not in the rig".into());
        status.errors_total = 1;
        status
            .notes
            .push_back("left: its own auto-exposure is on".into());
        status.notes_total = 2;
        log.forward(&status);
        let lines: Vec<String> = buffer.since(0).iter().map(Entry::line).collect();
        assert_eq!(
            lines,
            [
                "front: its own auto-exposure is on",
                "left: its own auto-exposure is on",
                "warning: camera 7 is not in the rig"
            ]
        );
    }
}
