//! Where a session's frame sets come from (`SourceSpec`: the simulated
//! rig, live cameras, a recording or a bracket sequence) and starting a
//! session on each: the source opened, its calibration's view built, and
//! the pipeline started on them.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use rigview_calib::rig::Frame;
use rigview_core::exposure::{ExposureSetting, NeighbourGraph};
use rigview_core::pipeline::{Notify, PipelineOptions, ProcessingSettings, Processor};
use rigview_core::sim::{Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
#[cfg(feature = "aravis")]
use rigview_core::source::Budget;
use rigview_core::source::FrameSource;

use super::brackets::{self, BracketMode, BracketOptions};
use super::record::RecordSpec;
use super::replay::{start_replay, ReplaySpec};
use super::start::{start_session, Origin, Session};
use super::view::view_for;
use crate::live::LiveSpec;

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
    Replay(ReplaySpec),
    /// A bracket sequence ([`super::brackets`]).
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
    pub mode: BracketMode,
    /// Serve each moment at its time, as cameras would (the window);
    /// otherwise as fast as the sets are taken.
    pub realtime: bool,
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
        SourceSpec::Replay(r) => start_replay(r, processing, options, notify, record),
        SourceSpec::Brackets(b) => start_brackets(b, processing, options, notify, record),
    }
}

/// Where a bracket sequence's cameras start: the simulated rig's start.
pub const BRACKETS_START: ExposureSetting = ExposureSetting {
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
    let opening = BracketOptions {
        realtime: spec.realtime,
        ..BracketOptions::new(BRACKETS_START, spec.mode)
    };
    let (source, rig) = brackets::open_with_rig(&spec.dir, spec.rig.as_deref(), &opening)?;
    let cameras = source.cameras().to_vec();
    let (view, graph) = match &rig.frame {
        // A rig posed relative to one of its cameras (a public dataset's
        // Kalibr camchain) has no ground to show: the cameras are metered
        // over their whole frames and controlled, as `rigview eval` does.
        Frame::Camera(camera) => {
            tracing::warn!(
                "{}: the rig is posed relative to its camera \"{camera}\", not on the ground: \
                 no surround view, whole frames metered (`rigview calib ground` poses it)",
                spec.dir.display()
            );
            (None, NeighbourGraph::new(cameras.len(), &rig.neighbours)?)
        }
        Frame::Vehicle => {
            let (view, graph) = view_for(&rig, &cameras, processing).with_context(|| {
                format!("the calibration of the brackets {}", spec.dir.display())
            })?;
            (Some(view), graph)
        }
    };
    let processor = Processor::new(cameras.clone(), view, graph, processing.clone())?;
    let origin = Origin {
        source_name: format!(
            "brackets {} ({} moments × {} cameras, {:?})",
            spec.dir.display(),
            source.manifest().moments.len(),
            cameras.len(),
            spec.mode
        ),
        calibration: format!("{}", spec.dir.join(brackets::RIG).display()),
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
