//! A recording as a [`FrameSource`]: it gives exactly the recorded sets, in
//! order, as fast as asked or at a multiple of the recorded rate, and then
//! finishes. Replay is open loop: the frames are what they were, so
//! commands are taken and ignored.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rigview_core::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
};

use crate::error::Result;
use crate::reader::{RecordedSet, RecordingMeta, SetStream};

/// A recording replayed (see the module documentation).
pub struct ReplaySource {
    file: PathBuf,
    stream: SetStream<BufReader<File>>,
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
    /// Opens `file` (a killed file replays up to its last complete set).
    /// Chunk CRCs are checked before a set is given: a damaged chunk ends
    /// the replay there instead of giving damaged pixels.
    pub fn open(file: &Path) -> Result<Self> {
        let mut stream = SetStream::open(file, true)?;
        let ahead = stream.next();
        let meta = stream
            .meta()
            .cloned()
            .ok_or_else(|| crate::RecordError::format(file, "no metadata"))?;
        Ok(Self {
            file: file.to_owned(),
            health: vec![StreamHealth::default(); meta.cameras.len()],
            meta,
            stream,
            finished: false,
            messages: Vec::new(),
            ahead,
            speed: None,
            clock: None,
        })
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
        let next = match self.ahead.take() {
            Some(ahead) => Some(ahead),
            None => self.stream.next(),
        };
        match next {
            Some(Ok(r)) => {
                let wait = self.wait_for(r.log_time);
                if wait > timeout {
                    std::thread::sleep(timeout);
                    self.ahead = Some(Ok(r));
                    return Ok(None);
                }
                std::thread::sleep(wait);
                for (h, f) in self.health.iter_mut().zip(&r.set.frames) {
                    match f {
                        Some(f) if f.is_complete() => h.completed += 1,
                        _ => h.failed += 1,
                    }
                }
                Ok(Some(r.set))
            }
            Some(Err(e)) => {
                self.finished = true;
                Err(SourceError::Failed(e.to_string()))
            }
            None => {
                self.finished = true;
                if let Some(t) = self.stream.tail() {
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
