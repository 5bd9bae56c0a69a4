//! A running session: a source (the simulated rig or live cameras), its
//! calibration's surround view, and the processing pipeline on them. The
//! window and the headless mode both start one.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use rigview_calib::rig::Rig;
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{
    check_view, Notify, PanoramaSettings, Pipeline, PipelineOptions, ProcessingSettings, Processor,
    View, ViewKind,
};
use rigview_core::sim::{Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::{Budget, CameraInfo, FrameSource};
use rigview_core::surround::CanvasSpec;

use crate::live::LiveSpec;
use crate::recording::{start_session, Origin, RecordSlot, RecordSpec, ReplayControl};
use rigview_record::Recorder;

/// The simulated rig to run.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSpec {
    /// A preset or a simulation file.
    pub scenario: String,
    /// Render scale (1: 1288×964).
    pub scale: f64,
    /// At the trigger rate of the wall clock (otherwise as fast as
    /// processing takes the sets).
    pub realtime: bool,
    /// Sets before the source ends (`None`: never).
    pub frames: Option<u64>,
}

impl Default for SimSpec {
    fn default() -> Self {
        Self {
            scenario: "reference".into(),
            scale: 1.0,
            realtime: true,
            frames: None,
        }
    }
}

/// Where the frame sets come from.
#[derive(Debug)]
pub enum SourceSpec {
    /// The simulated rig.
    Sim(SimSpec),
    /// Live cameras.
    Live(LiveSpec),
    /// A recording replayed.
    Replay(crate::recording::ReplaySpec),
    /// A bracket sequence ([`crate::brackets`]).
    Brackets(BracketSpec),
}

/// A bracket sequence to run on.
#[derive(Clone, Debug, PartialEq)]
pub struct BracketSpec {
    /// Its folder.
    pub dir: std::path::PathBuf,
    /// Its calibration, if not `dir/rig.yaml`.
    pub rig: Option<std::path::PathBuf>,
    /// How commands are answered: the nearest bracket or an emulated frame.
    pub mode: crate::brackets::BracketMode,
}

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
}

impl Session {
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

/// The canvas every session composes on: 10 m × 10 m at 100 px/m.
pub fn canvas_spec() -> CanvasSpec {
    CanvasSpec::default()
}

/// A view built for a session: the view, the neighbour graph and the rig
/// it was built from.
pub type BuiltView = (View, NeighbourGraph, Rig);

/// The view `kind` (the panorama as `panorama` says) and neighbour graph
/// of `rig` for `cameras`.
pub fn view_of(
    rig: &Rig,
    cameras: &[CameraInfo],
    kind: ViewKind,
    panorama: &PanoramaSettings,
) -> Result<(View, NeighbourGraph)> {
    let view = View::build(
        kind,
        rig,
        &canvas_spec(),
        panorama,
        crate::panorama::shared_detector(),
    )
    .with_context(|| format!("building the {} view", kind.name()))?;
    check_view(view.mosaic(), cameras)?;
    let graph = NeighbourGraph::new(cameras.len(), &rig.neighbours)?;
    Ok((view, graph))
}

/// The view `processing` asks for, of `rig` for `cameras`.
pub fn view_for(
    rig: &Rig,
    cameras: &[CameraInfo],
    processing: &ProcessingSettings,
) -> Result<(View, NeighbourGraph)> {
    view_of(rig, cameras, processing.view, &processing.panorama)
}

/// Loads a calibration file (any supported format) and builds the view
/// `processing` asks for, for `cameras`; errors name the file.
pub fn load_calibration(
    path: &Path,
    cameras: &[CameraInfo],
    processing: &ProcessingSettings,
) -> Result<BuiltView> {
    let loaded = rigview_calib::formats::load(path, None, None)
        .with_context(|| format!("cannot load the calibration {}", path.display()))?;
    let (view, graph) = view_for(&loaded.rig, cameras, processing)
        .with_context(|| format!("cannot use the calibration {}", path.display()))?;
    Ok((view, graph, loaded.rig))
}

/// Starts a session.
pub fn start(
    spec: &SourceSpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
) -> Result<Session> {
    start_recording(spec, processing, options, notify, None)
}

/// Starts a session that also records every set it processes into
/// `record` (if given).
pub fn start_recording(
    spec: &SourceSpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
) -> Result<Session> {
    match spec {
        SourceSpec::Sim(s) => start_sim(s, processing, options, notify, record),
        SourceSpec::Live(live) => start_live(live, processing, options, notify, record),
        SourceSpec::Replay(r) => {
            crate::recording::start_replay(r, processing, options, notify, record)
        }
        SourceSpec::Brackets(b) => start_brackets(b, processing, options, notify, record),
    }
}

/// Where a bracket sequence's cameras start: the simulated rig's start.
pub const BRACKETS_START: rigview_core::exposure::ExposureSetting =
    rigview_core::exposure::ExposureSetting {
        shutter_us: 2000.0,
        gain_db: 0.0,
    };

fn start_brackets(
    spec: &BracketSpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
) -> Result<Session> {
    let opening = crate::brackets::BracketOptions::new(BRACKETS_START, spec.mode);
    let (source, rig) = crate::brackets::open_with_rig(&spec.dir, spec.rig.as_deref(), &opening)?;
    let cameras = source.cameras().to_vec();
    let (view, graph) = view_for(&rig, &cameras, processing)
        .with_context(|| format!("the calibration of the brackets {}", spec.dir.display()))?;
    let processor = Processor::new(cameras.clone(), Some(view), graph, processing.clone())?;
    let origin = Origin {
        source_name: format!(
            "brackets {} ({} moments × {} cameras, {:?})",
            spec.dir.display(),
            source.manifest().moments.len(),
            cameras.len(),
            spec.mode
        ),
        calibration: format!("{}", spec.dir.join(crate::brackets::RIG).display()),
        rig: Some(&rig),
        time_offset_ns: rigview_record::writer::unix_now_ns(),
    };
    start_session(source, processor, options, notify, record, origin)
}

fn start_sim(
    spec: &SimSpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
) -> Result<Session> {
    let mut config = SimConfig::named(&spec.scenario)
        .with_context(|| format!("loading the simulation \"{}\"", spec.scenario))?;
    config.scale = spec.scale;
    config
        .validate()
        .with_context(|| format!("the simulation \"{}\"", spec.scenario))?;
    let t = Instant::now();
    let render = Arc::new(SimRender::new(&config).context("building the simulated rig")?);
    tracing::info!("scene traced in {:.1} s", t.elapsed().as_secs_f64());
    let cameras = render.cameras().to_vec();
    let (view, graph) =
        view_for(render.rig(), &cameras, processing).context("the view of the simulated rig")?;
    let source = SimRig::new(
        render.clone(),
        SimRigOptions {
            pacing: if spec.realtime {
                Pacing::Realtime
            } else {
                Pacing::AsFastAsAsked
            },
            frames: spec.frames,
            ..Default::default()
        },
    )?;
    let processor = Processor::new(cameras.clone(), Some(view), graph, processing.clone())?;
    let first = cameras.first();
    let origin = Origin {
        source_name: format!(
            "simulated rig \"{}\" ({} × {}×{} at {} Hz)",
            spec.scenario,
            cameras.len(),
            first.map_or(0, |c| c.width),
            first.map_or(0, |c| c.height),
            config.trigger_hz
        ),
        calibration: "the simulated rig's exact calibration".into(),
        rig: Some(render.rig()),
        // The simulation's clock starts at 0: a recording's times start now.
        time_offset_ns: rigview_record::writer::unix_now_ns(),
    };
    start_session(source, processor, options, notify, record, origin)
}

#[cfg(not(feature = "aravis"))]
fn start_live(
    _spec: &LiveSpec,
    _processing: &ProcessingSettings,
    _options: PipelineOptions,
    _notify: Notify,
    _record: Option<&RecordSpec>,
) -> Result<Session> {
    Err(crate::live::LiveError::NoAravis.into())
}

#[cfg(feature = "aravis")]
fn start_live(
    spec: &LiveSpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
) -> Result<Session> {
    let crate::live::Opened { source, rig } = crate::live::open(spec)?;
    let what = spec.describe();
    let cameras = source.cameras().to_vec();
    let (view, graph, calibration) = match view_for(&rig, &cameras, processing) {
        Ok((v, g)) => (Some(v), g, what.clone()),
        Err(e) => {
            tracing::warn!("no view: {e:#}; whole frames are metered (File, Open calibration)");
            (
                None,
                NeighbourGraph::new(cameras.len(), &[])?,
                "none".into(),
            )
        }
    };
    let calibrated = view.is_some().then_some(&rig);
    let mut processor = Processor::new(cameras.clone(), view, graph, processing.clone())?;
    // The controller starts from where the cameras' own start-up
    // auto-exposure left them.
    processor.sync(source.start_settings())?;
    let origin = Origin {
        source_name: format!("live: {} cameras ({what})", cameras.len()),
        calibration,
        rig: calibrated,
        // Live cameras' sets are stamped with the host's Unix time.
        time_offset_ns: 0,
    };
    match spec.frames {
        Some(n) => start_session(
            Budget::new(source, n),
            processor,
            options,
            notify,
            record,
            origin,
        ),
        None => start_session(source, processor, options, notify, record, origin),
    }
}
