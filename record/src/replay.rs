//! A recording as a [`FrameSource`]: it gives exactly the recorded sets, in
//! order, as fast as asked or at a multiple of the recorded rate, and then
//! finishes. Replay is open loop: the frames are what they were, so
//! commands are taken and ignored.
//!
//! A file with its index (closed properly, or repaired) is read through
//! it, so a replay can go to any set ([`ReplaySource::seek`]); a file
//! without one (killed, cut short) is read from start to end, up to its
//! last complete set. Either way each chunk's CRC is checked before its set
//! is given.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rigview_core::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
};

use crate::error::{RecordError, Result};
use crate::reader::{IndexedRecording, RecordedSet, RecordingMeta, SetStream};

/// How the recording is read.
enum Reader {
    /// From start to end (no index).
    Stream(Box<SetStream<BufReader<File>>>),
    /// By its index; `next` is the number of the next set.
    Indexed {
        recording: Box<IndexedRecording>,
        next: usize,
    },
}

/// A recording replayed (see the module documentation).
pub struct ReplaySource {
    file: PathBuf,
    reader: Reader,
    meta: RecordingMeta,
    health: Vec<StreamHealth>,
    finished: bool,
    messages: Vec<String>,
    /// The next set, read ahead (at open, because the rig attachment
    /// precedes it; when paced, until it is due).
    ahead: Option<Result<RecordedSet>>,
    /// Replay speed (`None`: as fast as asked).
    speed: Option<f64>,
    /// When paced: a moment and the log time that plays at it.
    clock: Option<(Instant, u64)>,
    /// Sets given over the last second.
    rate: Rate,
}

/// Sets per second over the last second.
#[derive(Debug, Default)]
struct Rate(std::collections::VecDeque<Instant>);

impl Rate {
    /// Counts a set given `now`; returns the rate.
    fn tick(&mut self, now: Instant) -> f64 {
        self.0.push_back(now);
        while self
            .0
            .front()
            .is_some_and(|t| now.duration_since(*t) > Duration::from_secs(1))
        {
            self.0.pop_front();
        }
        match (self.0.front(), self.0.len()) {
            (Some(first), n) if n > 1 => {
                (n - 1) as f64 / now.duration_since(*first).as_secs_f64().max(1e-9)
            }
            _ => 0.0,
        }
    }
}

impl std::fmt::Debug for ReplaySource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReplaySource")
            .field("file", &self.file)
            .field("finished", &self.finished)
            .finish_non_exhaustive()
    }
}

impl ReplaySource {
    /// Opens `file`: through its index if it has one, else from start to
    /// end (a killed file replays up to its last complete set).
    pub fn open(file: &Path) -> Result<Self> {
        let (reader, meta, ahead) = match IndexedRecording::open(file) {
            Ok(recording) => {
                let meta = recording.meta().clone();
                let reader = Reader::Indexed {
                    recording: Box::new(recording),
                    next: 0,
                };
                (reader, meta, None)
            }
            Err(_) => {
                let mut stream = SetStream::open(file, true)?;
                // The rig attachment comes before the first set.
                let ahead = stream.next();
                let meta = stream
                    .meta()
                    .cloned()
                    .ok_or_else(|| RecordError::format(file, "no metadata record"))?;
                (Reader::Stream(Box::new(stream)), meta, ahead)
            }
        };
        Ok(Self {
            file: file.to_owned(),
            health: vec![StreamHealth::default(); meta.cameras.len()],
            meta,
            reader,
            finished: false,
            messages: Vec::new(),
            ahead,
            speed: None,
            clock: None,
            rate: Rate::default(),
        })
    }

    /// The sets' log times, if the file has its index.
    pub fn times(&self) -> Option<&[u64]> {
        match &self.reader {
            Reader::Indexed { recording, .. } => Some(recording.times()),
            Reader::Stream(_) => None,
        }
    }

    /// The number of the next set, if the file has its index.
    pub fn position(&self) -> Option<usize> {
        match &self.reader {
            // A set held back until it is due has been read already.
            Reader::Indexed { next, .. } => Some(next - usize::from(self.ahead.is_some())),
            Reader::Stream(_) => None,
        }
    }

    /// Goes to set number `k` (the next set given; past the end: the
    /// replay has finished). Needs the file's index.
    pub fn seek(&mut self, k: usize) -> Result<()> {
        let Reader::Indexed { recording, next } = &mut self.reader else {
            return Err(RecordError::format(
                &self.file,
                "the file has no index to seek by (it was not closed); \
                 `rigview recording repair` rewrites it with one",
            ));
        };
        *next = k.min(recording.len());
        self.finished = *next >= recording.len();
        self.ahead = None;
        self.clock = None;
        Ok(())
    }

    /// The next set as recorded (`None`: the end).
    fn read(&mut self) -> Option<Result<RecordedSet>> {
        if let Some(ahead) = self.ahead.take() {
            return Some(ahead);
        }
        match &mut self.reader {
            Reader::Stream(stream) => stream.next(),
            Reader::Indexed { recording, next } => {
                let set = recording.set(*next).transpose()?;
                *next += 1;
                Some(set)
            }
        }
    }

    /// Replays at `speed` times the recorded rate from the next set on
    /// (`None`: as fast as asked, the default).
    pub fn set_speed(&mut self, speed: Option<f64>) {
        self.speed = speed.filter(|s| s.is_finite() && *s > 0.0);
        self.clock = None;
    }

    /// How long to wait until `log_time` is due (zero if it is, or when
    /// not paced).
    fn wait_for(&mut self, log_time: u64) -> Duration {
        let Some(speed) = self.speed else {
            return Duration::ZERO;
        };
        let (t0, l0) = *self.clock.get_or_insert((Instant::now(), log_time));
        let due = t0 + Duration::from_secs_f64(log_time.saturating_sub(l0) as f64 * 1e-9 / speed);
        due.saturating_duration_since(Instant::now())
    }

    /// What the recording says about itself, with its rig.
    pub fn meta(&self) -> &RecordingMeta {
        &self.meta
    }

    /// The recording's file.
    pub fn file(&self) -> &Path {
        &self.file
    }
}

impl FrameSource for ReplaySource {
    fn cameras(&self) -> &[CameraInfo] {
        &self.meta.cameras
    }

    fn next_set(&mut self, timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        if self.finished {
            return Ok(None);
        }
        match self.read() {
            Some(Ok(r)) => {
                let wait = self.wait_for(r.log_time);
                if wait > timeout {
                    std::thread::sleep(timeout);
                    self.ahead = Some(Ok(r));
                    return Ok(None);
                }
                std::thread::sleep(wait);
                let fps = self.rate.tick(Instant::now());
                for (h, f) in self.health.iter_mut().zip(&r.set.frames) {
                    match f {
                        Some(f) if f.is_complete() => h.completed += 1,
                        _ => h.failed += 1,
                    }
                    h.fps = fps;
                }
                Ok(Some(r.set))
            }
            Some(Err(e)) => {
                self.finished = true;
                Err(SourceError::Failed(e.to_string()))
            }
            None => {
                self.finished = true;
                let tail = match &self.reader {
                    Reader::Stream(stream) => stream.tail(),
                    Reader::Indexed { .. } => None,
                };
                if let Some(t) = tail {
                    self.messages.push(format!(
                        "{}: the recording ends early ({t}); replayed up to its last complete set",
                        self.file.display()
                    ));
                }
                Ok(None)
            }
        }
    }

    fn apply(&mut self, _commands: &[ExposureCommand]) -> Result<(), SourceError> {
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.health.clone()
    }

    fn is_finished(&self) -> bool {
        self.finished
    }

    fn take_messages(&mut self) -> Vec<String> {
        std::mem::take(&mut self.messages)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_counts_the_sets_of_the_last_second() {
        let mut rate = Rate::default();
        let t0 = Instant::now();
        let mut r = 0.0;
        for k in 0..60u32 {
            r = rate.tick(t0 + Duration::from_millis(50) * k);
        }
        assert!((r - 20.0).abs() < 1e-6, "{r}");
        assert_eq!(rate.0.len(), 21, "a second of sets and the first of it");
    }
}
