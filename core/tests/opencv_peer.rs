#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! rigview's gradient-information metric and estimator against a
//! straightforward OpenCV composition of the same steps (the peer):
//!
//! ```text
//! mapped = pow(I, γ)            (scale-and-clip: min(s·I, 1))
//! m      = magnitude(Sobel_x, Sobel_y) / (4·√2)          (CV_32F, ksize 3)
//! m̄      = log(λ·max(m − δ, 0) + 1) / log(λ·(1 − δ) + 1)
//! M      = Σ m̄ over the interior (rows 1..h−1, cols 1..w−1)
//! ```
//!
//! Both are run on the same metered 320×240 luminance of a synthetic scene.

use opencv::core::{self, Mat, MatTraitConst, Rect};
use opencv::imgproc;
use rigview_core::exposure::estimator::{fit_in, AnchorScore};
use rigview_core::exposure::metering::SATURATED_LEVEL;
use rigview_core::exposure::{
    Estimator, EstimatorConfig, FrameView, Meter, Metered, MeteringConfig, MetricParams,
    PixelFormat, Simulation, DEFAULT_ANCHORS,
};
use rigview_core::synth::{HdrScene, Illumination, LinearCamera};

type TestResult = Result<(), Box<dyn std::error::Error>>;

const SEED: u64 = 7;
/// Bright but below saturation: the brightest radiance (0.95) gives 242/255.
const EXPOSURE: f64 = 10_000.0;
const REL_TOL: f64 = 1e-4;
const GAMMA_HAT_TOL: f64 = 1e-3;

/// The metered 320×240 luminance of a 640×480 Mono8 frame.
fn metered(exposure: f64) -> Result<Metered, Box<dyn std::error::Error>> {
    let scene = HdrScene::generate(640, 480, SEED, &Illumination::Uniform(1.0))?;
    let frame = LinearCamera::default().render_mono8(scene.radiance(), exposure, 0);
    let view = FrameView::new(PixelFormat::Mono8, 640, 480, &frame)?;
    let metered = Meter::new(MeteringConfig::default())?.meter(&view, None)?;
    assert_eq!((metered.width(), metered.height()), (320, 240));
    Ok(metered)
}

/// `M` of the simulated exposure change `x`, composed from OpenCV calls.
fn opencv_score(
    image: &Metered,
    simulation: Simulation,
    x: f64,
    params: MetricParams,
) -> opencv::Result<f64> {
    let (w, h) = (image.width() as i32, image.height() as i32);
    let luma = Mat::new_rows_cols_with_data(h, w, image.luma())?;
    assert_eq!(luma.typ(), core::CV_32F);

    let mut mapped = Mat::default();
    match simulation {
        Simulation::Gamma => core::pow(&luma, x, &mut mapped)?,
        Simulation::ScaleClip => {
            let mut scaled = Mat::default();
            luma.convert_to(&mut scaled, core::CV_32F, x, 0.0)?;
            // THRESH_TRUNC: min(value, 1).
            imgproc::threshold(&scaled, &mut mapped, 1.0, 1.0, imgproc::THRESH_TRUNC)?;
        }
    }

    let (mut gx, mut gy) = (Mat::default(), Mat::default());
    imgproc::sobel(
        &mapped,
        &mut gx,
        core::CV_32F,
        1,
        0,
        3,
        1.0,
        0.0,
        core::BORDER_DEFAULT,
    )?;
    imgproc::sobel(
        &mapped,
        &mut gy,
        core::CV_32F,
        0,
        1,
        3,
        1.0,
        0.0,
        core::BORDER_DEFAULT,
    )?;
    let mut mag = Mat::default();
    core::magnitude(&gx, &gy, &mut mag)?;

    // m = |∇| / (4·√2)
    let mut m = Mat::default();
    mag.convert_to(
        &mut m,
        core::CV_32F,
        1.0 / (4.0 * std::f64::consts::SQRT_2),
        0.0,
    )?;
    // m − δ
    let mut shifted = Mat::default();
    core::subtract(
        &m,
        &core::Scalar::all(params.delta),
        &mut shifted,
        &core::no_array(),
        -1,
    )?;
    // max(m − δ, 0)
    let mut clipped = Mat::default();
    imgproc::threshold(&shifted, &mut clipped, 0.0, 0.0, imgproc::THRESH_TOZERO)?;
    // λ·max(m − δ, 0) + 1
    let mut arg = Mat::default();
    clipped.convert_to(&mut arg, core::CV_32F, params.lambda, 1.0)?;
    let mut info = Mat::default();
    core::log(&arg, &mut info)?;

    // The interior only: rigview leaves out the one-pixel border.
    let interior = Mat::roi(&info, Rect::new(1, 1, w - 2, h - 2))?;
    let sum = core::sum_elems(&interior)?[0];
    let n = (params.lambda * (1.0 - params.delta) + 1.0).ln();
    Ok(sum / n)
}

fn config(simulation: Simulation) -> EstimatorConfig {
    EstimatorConfig {
        simulation,
        ..Default::default()
    }
}

fn assert_no_saturation(image: &Metered) {
    let max = image.luma().iter().copied().fold(0.0f32, f32::max);
    assert!(
        max < SATURATED_LEVEL,
        "precondition: no metered pixel may be saturated (max {max}); \
         scale-and-clip's darkening holds saturated pixels, which the plain \
         OpenCV composition does not"
    );
    // And the image is not trivially dark either.
    assert!(
        max > 0.5,
        "precondition: a reasonably bright image (max {max})"
    );
}

fn check_anchor_scores(simulation: Simulation) -> TestResult {
    let image = metered(EXPOSURE)?;
    assert_no_saturation(&image);
    let config = config(simulation);
    let params = config.metric;
    let mut estimator = Estimator::new(config)?;
    for &x in &DEFAULT_ANCHORS {
        let ours = estimator.score_at(&image, x);
        let peer = opencv_score(&image, simulation, x, params)?;
        // The score is a sum of tens of thousands of pixels: a vanishing
        // score would make the comparison meaningless.
        assert!(
            peer > 100.0,
            "{} at {x}: the OpenCV score {peer} is too small to compare",
            simulation.name()
        );
        let rel = (ours - peer).abs() / peer.abs();
        assert!(
            rel <= REL_TOL,
            "{} at {x}: rigview M = {ours}, OpenCV M = {peer}, relative difference {rel:e} > {REL_TOL:e}",
            simulation.name()
        );
    }
    Ok(())
}

#[test]
fn gamma_anchor_scores_match_opencv() -> TestResult {
    check_anchor_scores(Simulation::Gamma)
}

#[test]
fn scale_clip_anchor_scores_match_opencv() -> TestResult {
    check_anchor_scores(Simulation::ScaleClip)
}

fn check_estimate(simulation: Simulation, exposure: f64) -> TestResult {
    let image = metered(exposure)?;
    assert_no_saturation(&image);
    let config = config(simulation);
    let (params, degree) = (config.metric, config.degree);
    let mut estimator = Estimator::new(config)?;
    let ours = estimator.estimate(&image)?;
    assert!(!ours.flat, "{}: a flat estimate", simulation.name());

    let mut anchors = DEFAULT_ANCHORS.to_vec();
    anchors.sort_by(f64::total_cmp);
    let peer_scores = anchors
        .iter()
        .map(|&x| opencv_score(&image, simulation, x, params).map(|m| AnchorScore { x, m }))
        .collect::<opencv::Result<Vec<_>>>()?;
    let x_peer = fit_in(&peer_scores, degree, simulation.fit_variable())?.argmax();
    let gamma_peer = simulation.gamma_equivalent(x_peer);
    eprintln!(
        "{} at E = {exposure}: rigview x̂ = {} (γ̂ = {}), OpenCV-fitted x̂ = {x_peer} (γ̂ = {gamma_peer})",
        simulation.name(),
        ours.x_hat,
        ours.gamma_hat
    );
    assert!(
        (ours.x_hat - x_peer).abs() <= GAMMA_HAT_TOL,
        "{}: rigview x̂ = {}, OpenCV-fitted x̂ = {x_peer}",
        simulation.name(),
        ours.x_hat
    );
    assert!(
        (ours.gamma_hat - gamma_peer).abs() <= GAMMA_HAT_TOL,
        "{}: rigview γ̂ = {}, OpenCV-fitted γ̂ = {gamma_peer}",
        simulation.name(),
        ours.gamma_hat
    );
    Ok(())
}

#[test]
fn gamma_estimate_matches_opencv_fit() -> TestResult {
    check_estimate(Simulation::Gamma, EXPOSURE)
}

#[test]
fn scale_clip_estimate_matches_opencv_fit() -> TestResult {
    check_estimate(Simulation::ScaleClip, EXPOSURE)
}
