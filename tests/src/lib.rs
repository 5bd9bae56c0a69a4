//! Shared helpers of rigview's cross-crate integration tests: the app's
//! processor in lock step on the simulated rig, a single linear camera in
//! a closed loop with actuation latency, and the ground truths the tests
//! compare against (the estimator's fixed point, the dense-sweep optimum of
//! `M`).

use std::sync::Arc;

pub mod rigs;
pub mod strip;

use rigview_core::exposure::{
    ControllerConfig, Estimator, EstimatorConfig, ExposureRange, ExposureSetting, FrameInfo,
    FrameView, Meter, Metered, MeteringConfig, NeighbourGraph, PixelFormat, RigController,
};
use rigview_core::pipeline::{LockStep, ProcessingSettings, Processor};
use rigview_core::sim::{Actuation, SimRender, SimRig, SimRigOptions};
use rigview_core::source::{ExposureCommand, SourceError};
use rigview_core::surround::SurroundView;
use rigview_core::synth::{HdrScene, LinearCamera};
use rigview_core::Result;

/// The app's processor under `settings` in lock step on the simulated rig
/// `render` (commands one set late, as the rig's latency says), metering
/// `view`'s ground and measuring its overlaps, balancing over `edges` when
/// the strategy balances. No view is composed.
pub fn sim_loop(
    render: &Arc<SimRender>,
    view: SurroundView,
    settings: ProcessingSettings,
    edges: &[(usize, usize)],
) -> std::result::Result<LockStep<SimRig>, SourceError> {
    sim_loop_with(render, view, settings, edges, SimRigOptions::default())
}

/// [`sim_loop`] with the simulated rig's `options` (its cameras' latency,
/// say).
pub fn sim_loop_with(
    render: &Arc<SimRender>,
    view: SurroundView,
    settings: ProcessingSettings,
    edges: &[(usize, usize)],
    options: SimRigOptions,
) -> std::result::Result<LockStep<SimRig>, SourceError> {
    let cameras = render.cameras().to_vec();
    let graph = NeighbourGraph::new(cameras.len(), edges)?;
    let mut processor = Processor::new(cameras, Some(view.into()), graph, settings)?;
    processor.set_compose(false);
    let source = SimRig::new(render.clone(), options)?;
    LockStep::new(source, processor)
}

/// The surround view of `render`'s rig at 25 px/m, as the closed-loop tests
/// meter and compose it.
pub fn test_view(render: &SimRender) -> std::result::Result<SurroundView, rigview_core::Error> {
    let spec = rigview_core::surround::CanvasSpec {
        px_per_m: 25.0,
        ..Default::default()
    };
    SurroundView::build(render.rig(), &spec, &Default::default())
}

/// Renders and meters `scene` at exposure level `e` (noise-free).
pub fn meter_at(scene: &HdrScene, camera: &LinearCamera, e: f64) -> Result<Metered> {
    let frame = camera.render_mono8(scene.radiance(), e, 0);
    let view = FrameView::new(PixelFormat::Mono8, scene.width(), scene.height(), &frame)?;
    Meter::new(MeteringConfig::default())?.meter(&view, None)
}

/// The exposure level (log2) where the estimator's γ̂ crosses 1, searched by
/// bisection in `[lo, hi]` (log2 units); γ̂ must be < 1 at `lo` and > 1 at `hi`.
pub fn fixed_point(
    scene: &HdrScene,
    camera: &LinearCamera,
    config: &EstimatorConfig,
    lo: f64,
    hi: f64,
) -> Result<f64> {
    let mut est = Estimator::new(config.clone())?;
    let mut g = |l: f64| -> Result<f64> {
        Ok(est.estimate(&meter_at(scene, camera, l.exp2())?)?.gamma_hat)
    };
    assert!(g(lo)? < 1.0 && g(hi)? > 1.0, "no crossing in [{lo}, {hi}]");
    let (mut a, mut b) = (lo, hi);
    for _ in 0..30 {
        let m = 0.5 * (a + b);
        if g(m)? < 1.0 {
            a = m;
        } else {
            b = m;
        }
    }
    Ok(0.5 * (a + b))
}

/// The log2 exposure level in a dense sweep of `n` log-spaced levels over
/// `[lo, hi]` where `M` of the metered image is largest, and that `M`.
pub fn sweep_argmax(
    scene: &HdrScene,
    camera: &LinearCamera,
    lo: f64,
    hi: f64,
    n: usize,
) -> Result<(f64, f64)> {
    let mut est = Estimator::new(EstimatorConfig::default())?;
    let mut best = (lo, f64::MIN);
    for k in 0..n {
        let l = lo + (hi - lo) * k as f64 / (n - 1) as f64;
        let m = est.score(&meter_at(scene, camera, l.exp2())?);
        if m > best.1 {
            best = (l, m);
        }
    }
    Ok(best)
}

/// `M` of the image at log2 exposure `l`.
pub fn m_at(scene: &HdrScene, camera: &LinearCamera, l: f64) -> Result<f64> {
    let mut est = Estimator::new(EstimatorConfig::default())?;
    Ok(est.score(&meter_at(scene, camera, l.exp2())?))
}

/// Runs one camera in closed loop for `frames` frames, with commands taking
/// effect `latency` frames late; returns log2 of the exposure each frame was
/// taken with.
pub fn run_single(
    scene: &HdrScene,
    camera: &LinearCamera,
    config: ControllerConfig,
    start_log2: f64,
    latency: usize,
    frames: usize,
) -> Result<Vec<f64>> {
    let range = ExposureRange::default();
    let mut rig = RigController::new(config, &[range], NeighbourGraph::new(1, &[])?)?;
    let mut current = ExposureSetting {
        shutter_us: start_log2.exp2(),
        gain_db: 0.0,
    };
    let mut actuation = Actuation::new(latency as u64);
    let mut out = Vec::with_capacity(frames);
    for f in 0..frames {
        actuation.apply_due(f as u64, std::slice::from_mut(&mut current));
        let metered = meter_at(scene, camera, current.exposure())?;
        out.push(current.exposure().log2());
        let step = rig.step(
            &[rigview_core::exposure::CameraInput {
                info: FrameInfo {
                    frame_id: f as u64,
                    taken: current,
                },
                metered: &metered,
            }],
            &[],
        )?;
        if let Some(setting) = step.cameras[0].command {
            actuation.send(f as u64 + 1, ExposureCommand { camera: 0, setting });
        }
    }
    Ok(out)
}

/// Harris corners through OpenCV with the default spread, as the
/// panorama's matching asks for them (the app's detector).
pub fn harris(gray: &[u8], w: usize, h: usize, mask: &[u8]) -> Result<Vec<[f32; 2]>> {
    use rigview_calib::tools::corners::{harris_corners, HarrisParams};
    harris_corners(gray, w, h, Some(mask), &HarrisParams::default())
        .map_err(|e| rigview_core::Error::calibration("Harris corners", e))
}

/// [`harris`] with positions refined to a fraction of a pixel (the Harris
/// response's parabola at each corner).
pub fn harris_subpixel(gray: &[u8], w: usize, h: usize, mask: &[u8]) -> Result<Vec<[f32; 2]>> {
    use rigview_calib::tools::corners::{harris_corners, HarrisParams};
    let params = HarrisParams {
        subpixel: true,
        ..HarrisParams::default()
    };
    harris_corners(gray, w, h, Some(mask), &params)
        .map_err(|e| rigview_core::Error::calibration("Harris corners", e))
}
