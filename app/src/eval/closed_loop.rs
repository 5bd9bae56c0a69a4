//! One closed loop of the evaluation: the app's processor in lock step on
//! the simulated rig (one frame of actuation latency, a command every
//! frame, the surround view's ground metered and its overlaps measured, no
//! view composed).

use std::sync::Arc;

use anyhow::{Context, Result};
use rigview_calib::rig::{Frame, Rig};
use rigview_core::exposure::FrameView;
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{LockStep, ProcessingSettings, Processor, View};
use rigview_core::sim::{SimRender, SimRig, SimRigOptions};
use rigview_core::source::{FrameSet, FrameSource};
use rigview_core::surround::{Canvas, CanvasSpec, SeamBands, SurroundView};

use crate::session::view::{build_view, ViewSpec};

/// The surround view the evaluation meters and measures: the rig's ground
/// at 25 px/m.
pub fn eval_view(render: &SimRender) -> Result<SurroundView> {
    rig_view(render.rig()).context("building the surround view of the simulated rig")
}

/// The view the evaluation's processor composes: the surround view on
/// [`eval_view`]'s canvas.
fn eval_spec() -> ViewSpec {
    ViewSpec::surround(CanvasSpec {
        px_per_m: 25.0,
        ..Default::default()
    })
}

/// [`eval_view`] of any rig calibrated in the vehicle frame.
pub fn rig_view(rig: &Rig) -> Result<SurroundView> {
    surround_of(build_view(rig, &eval_spec())?)
}

/// The surround view the evaluation's view is.
fn surround_of(view: View) -> Result<SurroundView> {
    view.into_surround()
        .context("the evaluation's view is the surround view")
}

/// [`rig_view`] of a rig posed in the vehicle frame; `None` for a rig posed
/// relative to one of its cameras (a Kalibr camchain), whose ground is not
/// known: its cameras are metered over their whole frames and no view is
/// composed.
pub fn ground_view(rig: &Rig) -> Result<Option<SurroundView>> {
    grounded_view(rig)?.map(surround_of).transpose()
}

/// The view the evaluation's processor composes of `rig`, as
/// [`ground_view`] decides it: `None` without a ground.
fn grounded_view(rig: &Rig) -> Result<Option<View>> {
    match rig.frame {
        Frame::Vehicle => build_view(rig, &eval_spec()).map(Some),
        Frame::Camera(_) => Ok(None),
    }
}

/// How far (canvas pixels) from a seam its step is measured.
pub const SEAM_BAND_PX: usize = 3;

/// What a closed loop records besides the exposures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoopOptions {
    /// Compose the view (with the settings' display gains), measure the
    /// ratios it shows and the step across each seam, and keep the last
    /// canvas.
    pub view: bool,
}

/// What a closed loop did, frame by frame.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Per camera, log2 of the exposure each frame was taken with.
    pub log2_e: Vec<Vec<f64>>,
    /// Per camera, whether each frame was a probe frame.
    pub probe: Vec<Vec<bool>>,
    /// The overlaps, camera index pairs.
    pub pairs: Vec<(usize, usize)>,
    /// Per set, per overlap, `log2 r_ij` of the overlap patches in the
    /// cameras' images.
    pub log2_r: Vec<Vec<Option<f64>>>,
    /// Per set, per overlap, `log2 r_ij` as the view shows it (the display
    /// gains applied; with [`LoopOptions::view`] only).
    pub shown_log2_r: Vec<Vec<Option<f64>>>,
    /// Per set, per seam, the step the view shows across it, EV (with
    /// [`LoopOptions::view`] only).
    pub seam_steps: Vec<Vec<Option<f64>>>,
    /// The last composed view.
    pub canvas: Option<Arc<Canvas>>,
}

impl Trace {
    /// Camera `k`'s settled log2 E: the median over the last `tail` frames
    /// (probe frames left out); NaN for an empty trace.
    pub fn settled(&self, k: usize, tail: usize) -> f64 {
        let (Some(e), Some(p)) = (self.log2_e.get(k), self.probe.get(k)) else {
            return f64::NAN;
        };
        let from = e.len().saturating_sub(tail);
        let mut v: Vec<f64> = (from..e.len()).filter(|&i| !p[i]).map(|i| e[i]).collect();
        crate::report::quantile(&mut v, 0.5)
    }

    /// Whether any camera's frame of set `k` was a probe frame.
    pub fn probe_set(&self, k: usize) -> bool {
        self.probe
            .iter()
            .any(|p| p.get(k).copied().unwrap_or(false))
    }
}

/// Runs `settings` on `render` for `frames` sets; `tick` is called after
/// each.
pub fn run(
    render: &Arc<SimRender>,
    settings: ProcessingSettings,
    frames: usize,
    tick: &mut dyn FnMut(),
) -> Result<Trace> {
    run_with(render, settings, frames, LoopOptions::default(), tick)
}

/// [`run`], recording what `options` asks for.
pub fn run_with(
    render: &Arc<SimRender>,
    settings: ProcessingSettings,
    frames: usize,
    options: LoopOptions,
    tick: &mut dyn FnMut(),
) -> Result<Trace> {
    run_source(
        sim_source(render, frames)?,
        render.rig(),
        settings,
        options,
        tick,
    )
}

/// The views of a set's frames (the set is complete).
pub fn frame_views(set: &FrameSet) -> Result<Vec<FrameView<'_>>> {
    Ok(set
        .frames
        .iter()
        .flatten()
        .map(|f| f.view())
        .collect::<std::result::Result<Vec<_>, _>>()?)
}

/// The simulated rig of `render` as a source that ends after `frames`
/// sets.
pub fn sim_source(render: &Arc<SimRender>, frames: usize) -> Result<SimRig> {
    Ok(SimRig::new(
        render.clone(),
        SimRigOptions {
            frames: Some(frames as u64),
            ..Default::default()
        },
    )?)
}

/// The loop on any `source` of the cameras of `rig` (calibrated in the
/// vehicle frame), until the source ends.
pub fn run_source<S: FrameSource>(
    source: S,
    rig: &Rig,
    settings: ProcessingSettings,
    options: LoopOptions,
    tick: &mut dyn FnMut(),
) -> Result<Trace> {
    run_observed(source, rig, settings, options, &mut |_, _| Ok(()), tick)
}

/// [`run_source`], showing `observe` each set (its index from 0 and its
/// frames, one per camera in rig order) as it was taken.
pub fn run_observed<S: FrameSource>(
    source: S,
    rig: &Rig,
    settings: ProcessingSettings,
    options: LoopOptions,
    observe: &mut dyn FnMut(usize, &[FrameView<'_>]) -> Result<()>,
    tick: &mut dyn FnMut(),
) -> Result<Trace> {
    let cameras = source.cameras().to_vec();
    let n = cameras.len();
    let graph = NeighbourGraph::new(n, &rig.neighbours)?;
    // Without a ground (a camera-frame rig) the processor meters whole
    // frames and composes nothing.
    let mut processor = Processor::new(cameras, grounded_view(rig)?, graph, settings)?;
    processor.set_compose(options.view);
    let seams = match (options.view, processor.view()) {
        (true, Some(v)) => Some(SeamBands::new(v, SEAM_BAND_PX)),
        _ => None,
    };
    let mut lp = LockStep::new(source, processor)?;
    let mut trace = Trace {
        log2_e: vec![Vec::new(); n],
        probe: vec![Vec::new(); n],
        pairs: lp.processor().pairs(),
        ..Default::default()
    };
    while let Some(step) = lp.step()? {
        let output = step
            .output
            .context("the simulated rig gave an incomplete frame set")?;
        for c in &output.step.cameras {
            trace.log2_e[c.camera].push(c.taken.exposure().log2());
            trace.probe[c.camera].push(c.probe_frame);
        }
        trace
            .log2_r
            .push(output.pairs.iter().map(|p| p.log2_r).collect());
        observe(trace.log2_r.len() - 1, &frame_views(&step.set)?)?;
        if let Some(seams) = &seams {
            let gains = (output.display_gains.len() == n).then_some(&output.display_gains[..]);
            let gain = |k: usize| gains.map_or(0.0, |g| f64::from(g[k]).log2());
            trace.shown_log2_r.push(
                output
                    .pairs
                    .iter()
                    .map(|p| p.log2_r.map(|r| r + gain(p.j) - gain(p.i)))
                    .collect(),
            );
            let views = frame_views(&step.set)?;
            trace.seam_steps.push(
                seams
                    .steps(&views, gains)?
                    .iter()
                    .map(|s| s.step_ev)
                    .collect(),
            );
            trace.canvas = output.canvas.clone();
        }
        tick();
    }
    Ok(trace)
}
