//! The Record button: the file it records into, the recording in progress
//! (its rate, and a stop of its own told once), and the recordings it
//! stopped being closed in the background.

use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigview_record::Recorder;

use super::messages::Messages;
use crate::session::{describe, RecordSpec, Session};

/// The recording in progress, as the window shows it.
#[derive(Debug)]
pub struct Recording {
    /// The recorder.
    pub recorder: Arc<Recorder>,
    /// When it started.
    pub started: Instant,
    /// A moment and the bytes written by then, for the rate.
    mark: (Instant, u64),
    /// MB/s over the last second or so.
    pub rate_mb_s: f64,
    /// Whether its stop has been told to the operator.
    stop_told: bool,
}

impl Recording {
    fn new(recorder: Arc<Recorder>) -> Self {
        let now = Instant::now();
        Self {
            recorder,
            started: now,
            mark: (now, 0),
            rate_mb_s: 0.0,
            stop_told: false,
        }
    }
}

/// The Record button's line: elapsed time, size, rate and drops.
pub fn recording_text(elapsed: Duration, bytes: u64, rate_mb_s: f64, dropped: u64) -> String {
    let s = elapsed.as_secs();
    format!(
        "REC {:02}:{:02} · {:.1} MB · {rate_mb_s:.1} MB/s · dropped {dropped}",
        s / 60,
        s % 60,
        bytes as f64 / 1e6
    )
}

/// Where the Record button records unless the operator says: a new file
/// in the working folder, named by the time.
fn default_record_path() -> String {
    let secs = rigview_record::writer::unix_now_ns() / 1_000_000_000;
    format!("rigview-{secs}.mcap")
}

/// The Record button's state.
#[derive(Debug)]
pub struct RecordButton {
    /// The file the button records into.
    pub path: String,
    /// The recording in progress.
    pub current: Option<Recording>,
    /// Recordings being finished in the background, with their summaries.
    finishing: Vec<Receiver<(String, bool)>>,
}

impl RecordButton {
    /// The button, with `recorder` in progress (`--record`) if given.
    pub fn new(recorder: Option<Arc<Recorder>>) -> Self {
        let current = recorder.map(Recording::new);
        Self {
            path: current.as_ref().map_or_else(default_record_path, |r| {
                r.recorder.file().display().to_string()
            }),
            current,
            finishing: Vec::new(),
        }
    }

    /// The recording in progress.
    pub fn recorder(&self) -> Option<&Arc<Recorder>> {
        self.current.as_ref().map(|r| &r.recorder)
    }

    /// Whether recordings stopped by the operator are still being closed.
    pub fn is_finishing(&self) -> bool {
        !self.finishing.is_empty()
    }

    /// Whether a recording is in progress or being closed (the window then
    /// repaints to follow it).
    pub fn is_busy(&self) -> bool {
        self.current.is_some() || !self.finishing.is_empty()
    }

    /// Starts recording `session`'s sets into `spec`'s file; a failure is
    /// shown and the view goes on.
    pub fn start(&mut self, session: Option<&Session>, spec: &RecordSpec, messages: &mut Messages) {
        let Some(s) = session else {
            messages.note("no source is running: nothing to record".into(), true);
            return;
        };
        if s.replay.is_some() {
            messages.note(
                "a replay is not recorded again: its recording is the file".into(),
                true,
            );
            return;
        }
        match s.start_recording(spec) {
            Ok(r) => {
                messages.note(format!("recording into {}", spec.file.display()), false);
                self.current = Some(Recording::new(r));
            }
            Err(e) => messages.note(format!("{e:#}"), true),
        }
    }

    /// Stops the recording in progress: no set is offered to it after
    /// this, and its file is closed in the background (its summary then
    /// goes to the messages).
    pub fn stop(&mut self, session: Option<&Session>, messages: &mut Messages) {
        let Some(rec) = self.current.take() else {
            return;
        };
        if let Some(s) = session {
            s.stop_recording();
        }
        let (tx, rx) = mpsc::channel();
        let r = rec.recorder;
        let spawned = std::thread::Builder::new()
            .name("rigview-recording-end".into())
            .spawn(move || {
                let stats = r.finish();
                let _ = tx.send((
                    describe(r.file(), &stats),
                    stats.stopped.is_some() || !stats.finished,
                ));
            });
        match spawned {
            Ok(_) => self.finishing.push(rx),
            Err(e) => messages.note(format!("cannot close the recording: {e}"), true),
        }
    }

    /// Stops the recording in progress and closes it now (the window is
    /// closing); its summary.
    pub fn finish(&mut self, session: &Session) -> Option<String> {
        self.current.take().map(|rec| {
            session.stop_recording();
            describe(rec.recorder.file(), &rec.recorder.finish())
        })
    }

    /// Follows the recording in progress: its rate, and a stop of its own
    /// (disk full, reserve reached, write error) told to the operator once.
    pub fn poll(&mut self, messages: &mut Messages) {
        let mut told = None;
        if let Some(rec) = &mut self.current {
            let stats = rec.recorder.stats();
            let (t0, b0) = rec.mark;
            let dt = t0.elapsed().as_secs_f64();
            if dt >= 1.0 {
                rec.rate_mb_s = stats.bytes.saturating_sub(b0) as f64 / 1e6 / dt;
                rec.mark = (Instant::now(), stats.bytes);
            }
            if let (Some(why), false) = (&stats.stopped, rec.stop_told) {
                rec.stop_told = true;
                rec.rate_mb_s = 0.0;
                told = Some(format!(
                    "the recording {} stopped ({why}); it is readable up to its last set, and the view goes on",
                    rec.recorder.file().display()
                ));
            }
        }
        if let Some(t) = told {
            messages.note(t, true);
        }
        let mut done = Vec::new();
        self.finishing.retain(|rx| match rx.try_recv() {
            Ok(d) => {
                done.push(d);
                false
            }
            Err(mpsc::TryRecvError::Empty) => true,
            Err(mpsc::TryRecvError::Disconnected) => false,
        });
        for (text, problem) in done {
            messages.note(text, problem);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_recording_line_says_time_size_rate_and_drops() {
        assert_eq!(
            recording_text(Duration::from_millis(125_900), 2_345_600_000, 98.74, 3),
            "REC 02:05 · 2345.6 MB · 98.7 MB/s · dropped 3"
        );
    }
}
