//! Recording a session: where and how to record (`RecordSpec`, from
//! `--record FILE` or the window's Record button), and the slot through
//! which the pipeline hands every set it takes to the recorder in progress
//! (`RecordSlot`, a `pipeline::SetSink`), with the recorder's drops per set
//! for `telemetry.csv`. The format and its guarantees are
//! `rigview-record`'s.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use anyhow::{Context, Result};
use rigview_calib::Rig;
use rigview_core::pipeline::{Processed, SetSink, Telemetry};
use rigview_core::source::{CameraInfo, FrameSet};
use rigview_record::{Compression, Recorder, RecorderOptions, RecorderStats, RecordingSetup};

/// Where and how to record.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordSpec {
    /// The MCAP file to write.
    pub file: PathBuf,
    /// How chunks are compressed.
    pub compression: Compression,
    /// Free space to leave on the disk, bytes.
    pub reserve_bytes: u64,
}

impl RecordSpec {
    /// A recording into `file` with the defaults (no compression, a 2 GiB
    /// reserve).
    pub fn new(file: PathBuf) -> Self {
        Self {
            file,
            compression: Compression::None,
            reserve_bytes: RecorderOptions::default().reserve_bytes,
        }
    }

    /// Starts the recorder for `cameras` with the calibration `rig`.
    pub fn create(
        &self,
        cameras: &[CameraInfo],
        rig: Option<&Rig>,
        source: &str,
        time_offset_ns: u64,
    ) -> Result<Recorder> {
        self.create_for(&RecordingSetup {
            cameras: cameras.to_vec(),
            rig: rig.cloned(),
            source: source.to_owned(),
            time_offset_ns,
        })
    }

    /// Starts the recorder for the source `setup` describes.
    pub fn create_for(&self, setup: &RecordingSetup) -> Result<Recorder> {
        let options = RecorderOptions {
            compression: self.compression,
            reserve_bytes: self.reserve_bytes,
            ..Default::default()
        };
        Recorder::create(&self.file, setup, options)
            .with_context(|| format!("cannot record into {}", self.file.display()))
    }
}

/// What a recording did, in one line.
pub fn describe(file: &Path, stats: &RecorderStats) -> String {
    let mut s = format!(
        "recording {}: {} sets ({:.1} MB of frames), {} dropped",
        file.display(),
        stats.sets,
        stats.bytes as f64 / 1e6,
        stats.dropped
    );
    match &stats.stopped {
        Some(why) => {
            let _ = write!(s, "; STOPPED EARLY: {why}");
        }
        None if !stats.finished => s += "; not closed properly",
        None => {}
    }
    s
}

/// The recording a session's pipeline hands its sets to: none, or one
/// started at start-up (`--record`) or by the window's Record button and
/// stopped by it. The pipeline always has this sink; it offers a set only
/// while a recorder is in it.
#[derive(Debug, Default)]
pub struct RecordSlot {
    current: Mutex<Option<Arc<Recorder>>>,
    /// Per processed set while recording: its trigger and the sets the
    /// recorder had dropped by then (the last [`DROPS_KEPT`]).
    drops: Mutex<std::collections::VecDeque<(u64, u64)>>,
}

/// Sets whose recorder drops a [`RecordSlot`] keeps for `telemetry.csv`
/// (an hour and a half at 20 Hz).
const DROPS_KEPT: usize = 100_000;

impl RecordSlot {
    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Arc<Recorder>>> {
        // The slot holds an `Option`; no update leaves it half done.
        self.current.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The recording in progress.
    pub fn recorder(&self) -> Option<Arc<Recorder>> {
        self.lock().clone()
    }

    /// Puts `recorder` in the slot; returns the one it replaces.
    pub fn replace(&self, recorder: Option<Arc<Recorder>>) -> Option<Arc<Recorder>> {
        std::mem::replace(&mut *self.lock(), recorder)
    }

    /// The sets the recorder had dropped when the set `trigger` was
    /// processed (`None`: no recording was in progress then).
    pub fn dropped_at(&self, trigger: u64) -> Option<u64> {
        let drops = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
        drops.iter().rev().find(|(t, _)| *t == trigger).map(|d| d.1)
    }

    /// Writes `telemetry` as `telemetry.csv` does, with a last column
    /// `recorder_dropped`: the sets the recorder had dropped by each set
    /// (empty while nothing was recorded).
    pub fn write_csv(&self, telemetry: &Telemetry, out: &mut dyn std::io::Write) -> Result<()> {
        let mut line = Vec::new();
        telemetry.write_csv_header(&mut line)?;
        with_column(&mut line, "recorder_dropped");
        out.write_all(&line)?;
        let drops = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
        let by_trigger: std::collections::HashMap<u64, u64> = drops.iter().copied().collect();
        for row in telemetry.rows() {
            line.clear();
            telemetry.write_csv_row(&mut line, row)?;
            let d = by_trigger
                .get(&row.trigger)
                .map_or_else(String::new, u64::to_string);
            with_column(&mut line, &d);
            out.write_all(&line)?;
        }
        Ok(())
    }
}

/// Adds `field` at the end of the CSV `line`.
fn with_column(line: &mut Vec<u8>, field: &str) {
    if line.last() == Some(&b'\n') {
        line.pop();
    }
    line.push(b',');
    line.extend_from_slice(field.as_bytes());
    line.push(b'\n');
}

impl SetSink for RecordSlot {
    fn offer(&self, set: &FrameSet, processed: Option<Processed<'_>>) {
        let Some(r) = self.recorder() else {
            return;
        };
        r.offer(set, processed);
        if let Some(p) = processed {
            let mut drops = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
            drops.push_back((p.row.trigger, r.stats().dropped));
            while drops.len() > DROPS_KEPT {
                drops.pop_front();
            }
        }
    }
}
