//! Recording on a thread of its own behind a bounded queue: whoever offers
//! sets (the capture loop, the processing thread) never waits for the
//! disk. When the queue is full the set is dropped whole and counted; the
//! next set written carries the count (`dropped_since_last`) and the end
//! record the total.
//!
//! The writer thread checks the free space about once a second and stops
//! cleanly below a reserve; a write error stops the recording too, leaving
//! the file readable up to the last complete set. Either way the reason is
//! kept in [`RecorderStats::stopped`] and whoever offers sets goes on.

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rigview_core::pipeline::{Processed, SetSink};
use rigview_core::source::FrameSet;

use crate::error::{RecordError, Result};
use crate::msgs::{self, SetTelemetryMsg};
use crate::writer::{unix_now_ns, Compression, RecordingSetup, SetWriter};

/// How a [`Recorder`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecorderOptions {
    /// How chunks are compressed.
    pub compression: Compression,
    /// Sets waiting for the writer before sets are dropped.
    pub queue: usize,
    /// Free space the recording leaves on its disk, bytes.
    pub reserve_bytes: u64,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            compression: Compression::None,
            queue: 16,
            reserve_bytes: 2 << 30,
        }
    }
}

/// The free space where the recording goes, bytes (the writer thread asks
/// about once a second).
pub type FreeSpace = Box<dyn FnMut() -> std::io::Result<u64> + Send>;

/// What a recording has done so far.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecorderStats {
    /// Sets written (each closed in its chunk).
    pub sets: u64,
    /// Sets dropped because the writer fell behind.
    pub dropped: u64,
    /// Bytes of frames written.
    pub bytes: u64,
    /// The last set written (its trigger number).
    pub last_trigger: Option<u64>,
    /// Why the recording stopped before it was finished (a write error,
    /// the disk's reserve).
    pub stopped: Option<String>,
    /// Whether the file was closed with its summary and indexes.
    pub finished: bool,
}

#[derive(Debug)]
struct Job {
    set: FrameSet,
    telemetry: SetTelemetryMsg,
    host_ns: u64,
    /// Sets dropped before this one was queued.
    drops_before: u64,
}

#[derive(Debug, Default)]
struct Shared {
    stats: Mutex<RecorderStats>,
    dropped: AtomicU64,
}

impl Shared {
    fn stats(&self) -> std::sync::MutexGuard<'_, RecorderStats> {
        // Every update leaves the stats consistent.
        self.stats.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A recording in progress (see the module documentation).
pub struct Recorder {
    file: PathBuf,
    names: Vec<String>,
    queue: Mutex<Option<SyncSender<Job>>>,
    shared: Arc<Shared>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("file", &self.file)
            .field("stats", &self.stats())
            .finish_non_exhaustive()
    }
}

fn free_space_of(file: &Path) -> FreeSpace {
    let dir = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    Box::new(move || fs4::available_space(&dir))
}

impl Recorder {
    /// Creates `file` (which must not exist: a recording is never
    /// overwritten) and starts recording into it. The start (header,
    /// schemas, rig, metadata) is written before this returns, so a file
    /// that cannot be written is an error here.
    pub fn create(file: &Path, setup: &RecordingSetup, options: RecorderOptions) -> Result<Self> {
        let f = File::options()
            .write(true)
            .create_new(true)
            .open(file)
            .map_err(|e| RecordError::io(file, e))?;
        let out = BufWriter::with_capacity(1 << 22, f);
        Self::start(file, out, setup, options, free_space_of(file))
    }

    /// Starts recording into `out` (named `file` in messages), asking
    /// `free_space` about once a second.
    pub fn start<W: Write + Seek + Send + 'static>(
        file: &Path,
        out: W,
        setup: &RecordingSetup,
        options: RecorderOptions,
        free_space: FreeSpace,
    ) -> Result<Self> {
        let writer = SetWriter::new(file, out, setup, options.compression)?;
        let names = writer.camera_names().to_vec();
        let (tx, rx) = mpsc::sync_channel(options.queue.max(1));
        let shared = Arc::new(Shared::default());
        let thread = {
            let shared = shared.clone();
            let reserve = options.reserve_bytes;
            std::thread::Builder::new()
                .name("rigview-recorder".into())
                .spawn(move || write_loop(writer, &rx, &shared, free_space, reserve))
                .map_err(|e| RecordError::Thread {
                    file: file.to_owned(),
                    reason: e.to_string(),
                })?
        };
        Ok(Self {
            file: file.to_owned(),
            names,
            queue: Mutex::new(Some(tx)),
            shared,
            thread: Mutex::new(Some(thread)),
        })
    }

    /// The recording's file.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// Hands a set to the writer without waiting; `processed` is what
    /// processing made of it (`None`: recorded without processing). Returns
    /// whether the set was queued: `false` when the queue was full (the set
    /// is dropped and counted) or the recording has stopped.
    pub fn offer(&self, set: &FrameSet, processed: Option<Processed<'_>>) -> bool {
        if self.is_stopped() {
            return false;
        }
        let telemetry = msgs::telemetry_of(set, processed.as_ref(), &self.names);
        let queue = self.queue.lock().unwrap_or_else(PoisonError::into_inner);
        // Under the queue's lock, so that the count is the drops before
        // this set.
        let job = Job {
            set: set.clone(),
            telemetry,
            host_ns: unix_now_ns(),
            drops_before: self.shared.dropped.load(Ordering::SeqCst),
        };
        let Some(tx) = queue.as_ref() else {
            return false;
        };
        match tx.try_send(job) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                self.shared.dropped.fetch_add(1, Ordering::SeqCst);
                self.shared.stats().dropped += 1;
                false
            }
            Err(TrySendError::Disconnected(_)) => false,
        }
    }

    /// What the recording has done so far.
    pub fn stats(&self) -> RecorderStats {
        self.shared.stats().clone()
    }

    /// Whether the recording stopped on its own (see
    /// [`RecorderStats::stopped`]).
    pub fn is_stopped(&self) -> bool {
        self.shared.stats().stopped.is_some()
    }

    /// Writes what is queued, ends the file (summary and indexes, unless a
    /// write error stopped it) and returns the totals. Later offers are
    /// refused.
    pub fn finish(&self) -> RecorderStats {
        drop(
            self.queue
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .take(),
        );
        let thread = self
            .thread
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some(t) = thread {
            if t.join().is_err() {
                self.shared.stats().stopped = Some("the recorder's thread panicked".into());
            }
        }
        self.stats()
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.finish();
    }
}

impl SetSink for Recorder {
    fn offer(&self, set: &FrameSet, processed: Option<Processed<'_>>) {
        Recorder::offer(self, set, processed);
    }
}

fn write_loop<W: Write + Seek>(
    mut writer: SetWriter<W>,
    rx: &Receiver<Job>,
    shared: &Shared,
    mut free_space: FreeSpace,
    reserve: u64,
) {
    let mut last_check: Option<Instant> = None;
    let mut counted_drops = 0u64;
    let stop = |why: String| {
        shared.stats().stopped = Some(why);
    };
    let reason = loop {
        let Ok(job) = rx.recv() else {
            break "finished".to_owned();
        };
        if last_check.is_none_or(|t| t.elapsed() >= Duration::from_secs(1)) {
            last_check = Some(Instant::now());
            match free_space() {
                Ok(free) if free < reserve => {
                    let why = format!(
                        "stopped: {} MiB free on the disk, below the reserve of {} MiB",
                        free >> 20,
                        reserve >> 20
                    );
                    stop(why.clone());
                    break why;
                }
                Ok(_) => {}
                Err(e) => {
                    let why = format!("stopped: cannot tell the free space on the disk: {e}");
                    stop(why.clone());
                    break why;
                }
            }
        }
        let before = job.drops_before.saturating_sub(counted_drops);
        counted_drops = counted_drops.max(job.drops_before);
        let bytes: u64 = job
            .set
            .frames
            .iter()
            .flatten()
            .map(|f| f.data.len() as u64)
            .sum();
        match writer.write_set(&job.set, job.telemetry, before, job.host_ns) {
            Ok(()) => {
                let mut s = shared.stats();
                s.sets += 1;
                s.bytes += bytes;
                s.last_trigger = Some(job.set.trigger);
            }
            Err(e) => {
                // The file stays readable up to the last set written; the
                // MCAP writer refuses everything after an I/O error.
                stop(format!("write error: {e}"));
                return;
            }
        }
    };
    // Sets dropped after the last one written, and any that were still
    // queued when the recording stopped early.
    let queued = rx.try_iter().count() as u64;
    let drops = shared.dropped.load(Ordering::SeqCst) + queued;
    if queued > 0 {
        shared.stats().dropped += queued;
    }
    writer.note_dropped(drops - counted_drops);
    match writer.finish(&reason) {
        Ok(_) => shared.stats().finished = true,
        Err(e) => stop(format!("write error at the end: {e}")),
    }
}
