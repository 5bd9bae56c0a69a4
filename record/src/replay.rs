//! A recording as a [`FrameSource`]: it gives exactly the recorded sets, in
//! order, as fast as asked, and then finishes. Replay is open loop: the
//! frames are what they were, so commands are taken and ignored.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::time::Duration;

use rigview_core::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
};

use crate::error::Result;
use crate::msgs::SetTelemetryMsg;
use crate::reader::{RecordingMeta, SetStream};

/// A recording replayed (see the module documentation).
pub struct ReplaySource {
    file: PathBuf,
    stream: SetStream<BufReader<File>>,
    meta: RecordingMeta,
    health: Vec<StreamHealth>,
    finished: bool,
    messages: Vec<String>,
    recorded: Vec<SetTelemetryMsg>,
    keep_telemetry: bool,
    /// The first set, read at open (the rig attachment precedes it).
    first: Option<Result<crate::RecordedSet>>,
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
    pub fn open(file: &Path) -> Result<Self> {
        let mut stream = SetStream::open(file, false)?;
        let first = stream.next();
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
            recorded: Vec::new(),
            keep_telemetry: false,
            first,
        })
    }

    /// Keeps each replayed set's recorded telemetry ([`Self::take_recorded`]).
    pub fn keep_telemetry(mut self, keep: bool) -> Self {
        self.keep_telemetry = keep;
        self
    }

    /// The recorded telemetry of the sets replayed since the last call.
    pub fn take_recorded(&mut self) -> Vec<SetTelemetryMsg> {
        std::mem::take(&mut self.recorded)
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

    fn next_set(&mut self, _timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        if self.finished {
            return Ok(None);
        }
        let next = match self.first.take() {
            Some(first) => Some(first),
            None => self.stream.next(),
        };
        match next {
            Some(Ok(r)) => {
                for (h, f) in self.health.iter_mut().zip(&r.set.frames) {
                    match f {
                        Some(f) if f.is_complete() => h.completed += 1,
                        _ => h.failed += 1,
                    }
                }
                if self.keep_telemetry {
                    self.recorded.push(r.telemetry);
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
