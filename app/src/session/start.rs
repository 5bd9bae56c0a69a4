//! A running session and how one starts: the pipeline on a source, with
//! the record slot every session's pipeline has (and a recorder in it when
//! `--record` asks), and what the source is in words.

use std::sync::Arc;

use anyhow::Result;
use rigview_calib::Rig;
use rigview_core::pipeline::{Notify, Pipeline, PipelineOptions, Processor, SetSink};
use rigview_core::source::FrameSource;
use rigview_record::{Recorder, RecordingSetup};

use super::control::ReplayControl;
use super::record::{RecordSlot, RecordSpec};

/// A running session.
#[derive(Debug)]
pub struct Session {
    /// The pipeline.
    pub pipeline: Pipeline,
    /// What the source is, in words.
    pub source_name: String,
    /// Where the calibration came from, in words.
    pub calibration: String,
    /// Whether the cameras have their own auto-exposure.
    pub camera_auto: bool,
    /// The recording the pipeline hands its sets to (`--record`, the
    /// window's Record button).
    pub record: Arc<RecordSlot>,
    /// What a recording of this session says about its source.
    pub record_setup: rigview_record::RecordingSetup,
    /// The window's hold on a replay (a replay session only).
    pub replay: Option<ReplayControl>,
    /// The calibration in use (`None`: none), from which another view is
    /// built.
    pub rig: Option<Rig>,
    /// The live remote view, while it serves (`--serve`).
    pub serving: Option<crate::serve::Serving>,
}

impl Session {
    /// Starts serving the live remote view of this session.
    pub fn serve(&mut self, options: &crate::serve::ServeOptions) -> Result<()> {
        let serving = crate::serve::Serving::start(
            options,
            self.pipeline.watch(),
            &self.record_setup.cameras,
            self.rig.as_ref(),
        )
        .map_err(|e| anyhow::anyhow!("the remote view (--serve): {e}"))?;
        self.serving = Some(serving);
        Ok(())
    }

    /// The cameras' names, in rig order.
    pub fn camera_names(&self) -> Vec<String> {
        self.pipeline
            .cameras()
            .iter()
            .map(|c| c.name.clone())
            .collect()
    }

    /// The recording in progress.
    pub fn recorder(&self) -> Option<Arc<Recorder>> {
        self.record.recorder()
    }

    /// Starts recording the sets from now on into `spec`'s file; an error
    /// if a recording is in progress or the file cannot be created.
    pub fn start_recording(&self, spec: &RecordSpec) -> Result<Arc<Recorder>> {
        if let Some(r) = self.record.recorder() {
            anyhow::bail!(
                "already recording into {}: stop that recording first",
                r.file().display()
            );
        }
        let recorder = Arc::new(spec.create_for(&self.record_setup)?);
        self.record.replace(Some(recorder.clone()));
        Ok(recorder)
    }

    /// Takes the recording in progress out of the pipeline's way (no set
    /// is offered to it after this); the caller finishes it.
    pub fn stop_recording(&self) -> Option<Arc<Recorder>> {
        self.record.replace(None)
    }
}

/// What a session's source is, for its summary and its recording.
#[derive(Debug)]
pub struct Origin<'a> {
    /// The source, in words.
    pub source_name: String,
    /// Where the calibration came from, in words.
    pub calibration: String,
    /// The calibration (a recording's `rig.yaml` attachment and
    /// `camera_info`).
    pub rig: Option<&'a Rig>,
    /// Added to the source's timestamps to make Unix time.
    pub time_offset_ns: u64,
}

/// Starts the pipeline on `source` and, if `record` says, a recorder on it.
pub fn start_session<S: FrameSource + 'static>(
    source: S,
    processor: Processor,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
    origin: Origin<'_>,
) -> Result<Session> {
    let record_setup = RecordingSetup {
        cameras: source.cameras().to_vec(),
        rig: origin.rig.cloned(),
        source: origin.source_name.clone(),
        time_offset_ns: origin.time_offset_ns,
    };
    let slot = Arc::new(RecordSlot::default());
    if let Some(r) = record {
        slot.replace(Some(Arc::new(r.create_for(&record_setup)?)));
    }
    let camera_auto = source.has_camera_auto();
    let sink = slot.clone() as Arc<dyn SetSink>;
    let pipeline = Pipeline::start_with_sink(source, processor, options, notify, Some(sink))?;
    Ok(Session {
        pipeline,
        record: slot,
        record_setup,
        replay: None,
        source_name: origin.source_name,
        calibration: origin.calibration,
        camera_auto,
        rig: origin.rig.cloned(),
        serving: None,
    })
}
