#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The surround view of the simulated rig, whose calibration is exactly
//! known: the mat's checkerboard corners land where they are on the ground,
//! and under backlight the closed loop with ground-only metering and
//! balancing leaves the overlaps closer in brightness than each camera
//! controlled alone. Run with `--nocapture` for the figures.

mod surround_common;

use std::sync::Arc;

use opencv::core::{self, Mat, Point2f, TermCriteria, Vector};
use opencv::imgproc;
use rigview_core::pipeline::{ProcessingSettings, Strategy};
use rigview_core::sim::{SimConfig, SimRender};
use rigview_core::surround::{
    BlendMode, Canvas, CanvasSpec, Composer, SurroundOptions, SurroundView,
};

fn render(preset: &str, scale: f64) -> SimRender {
    let config = SimConfig {
        scale,
        ..SimConfig::preset(preset).unwrap()
    };
    SimRender::new(&config).unwrap()
}

/// The inner corners of the mat's four checkerboard fields (the default
/// mat: 10 m × 6 m around a 5 m × 2 m hole, 40 cm squares counted from the
/// outer corner), vehicle frame, metres. Corners next to a partial square
/// or the band of circles are left out.
fn checker_corners() -> Vec<(f64, f64)> {
    let xs: Vec<f64> = (1..=5).map(|k| 5.0 - 0.4 * f64::from(k)).collect(); // 4.6 … 3.0
    let ys: Vec<f64> = (1..=4).map(|k| 3.0 - 0.4 * f64::from(k)).collect(); // 2.6 … 1.4
    let mut out = Vec::new();
    for &x in &xs {
        for &y in &ys {
            for (sx, sy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                out.push((sx * x, sy * y));
            }
        }
    }
    out
}

/// The rig's full resolution: at half resolution a square 4–5 m away spans
/// only a few source pixels and the corners wander by up to 1 canvas px.
const SCALE: f64 = 1.0;

/// How far OpenCV's sub-pixel saddle search (a 7×7 px = 14 cm window),
/// seeded at each true corner, moves in the canvas: where it settles is
/// where the composed image has the corner.
fn corner_offsets(canvas: &Canvas, truth: &[(f32, f32)]) -> Vec<f64> {
    let img = Mat::new_rows_cols_with_data(canvas.height as i32, canvas.width as i32, &canvas.data)
        .unwrap();
    let mut found: Vector<Point2f> = truth.iter().map(|&(x, y)| Point2f::new(x, y)).collect();
    imgproc::corner_sub_pix(
        &img,
        &mut found,
        core::Size::new(7, 7),
        core::Size::new(-1, -1),
        TermCriteria::new(core::TermCriteria_COUNT + core::TermCriteria_EPS, 50, 1e-3).unwrap(),
    )
    .unwrap();
    truth
        .iter()
        .zip(found.iter())
        .map(|(&(tx, ty), p)| f64::from((p.x - tx).hypot(p.y - ty)))
        .collect()
}

#[test]
fn the_mat_corners_land_within_a_canvas_pixel_of_their_true_positions() {
    let r = render("overcast", SCALE);
    let spec = surround_common::sim_spec();
    let view = SurroundView::build(r.rig(), &spec, &SurroundOptions::default()).unwrap();
    // Noise-free frames at a mid exposure, so that the mat is neither black
    // nor saturated.
    let buffers: Vec<Vec<u8>> = (0..r.cameras().len())
        .map(|k| surround_common::still(&r, k, 4000.0))
        .collect();
    let frames = surround_common::still_views(&r, &buffers);
    let mut canvas = Canvas::new(0, 0, 1);
    Composer::new()
        .compose(&view, &frames, BlendMode::Linear, &mut canvas)
        .unwrap();
    let mean: f64 =
        canvas.data.iter().map(|&v| f64::from(v)).sum::<f64>() / canvas.data.len() as f64;
    assert!(
        mean > 20.0,
        "the canvas is too dark to find corners: mean {mean:.1}"
    );
    // Each true corner seeds the saddle search ([`corner_offsets`]).
    let truth: Vec<(f32, f32)> = checker_corners()
        .into_iter()
        .map(|(x, y)| {
            let (c, r) = spec.canvas(x, y);
            // Pixel centres are at +½ in canvas coordinates, at integers in
            // OpenCV's.
            ((c - 0.5) as f32, (r - 0.5) as f32)
        })
        .collect();
    let errors = corner_offsets(&canvas, &truth);
    for ((&(tx, ty), e), (x, y)) in truth.iter().zip(&errors).zip(checker_corners()) {
        if *e > 0.6 {
            println!("corner ({x:+.1}, {y:+.1}) m at ({tx:.1}, {ty:.1}) px: {e:.2} px off");
        }
    }
    let mut sorted = errors.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let worst = sorted[sorted.len() - 1];
    println!(
        "{} mat corners: median {median:.3} px, worst {worst:.3} px (1 px = 2 cm)",
        errors.len()
    );
    assert_eq!(errors.len(), 80);
    assert!(worst < 1.0, "a corner is {worst:.2} canvas px off");

    // The same search on a view built from a rig whose front camera is
    // turned by 2° finds the front corners displaced: the check can fail.
    let mut turned = r.rig().clone();
    let pose = turned.cameras[0].pose.unwrap();
    let [yaw, pitch, roll] = pose.ypr_deg();
    turned.cameras[0].pose = Some(
        rigview_calib::Pose::from_ypr_deg([yaw + 2.0, pitch, roll], *pose.translation()).unwrap(),
    );
    let bad_view = SurroundView::build(&turned, &spec, &SurroundOptions::default()).unwrap();
    let mut bad = Canvas::new(0, 0, 1);
    Composer::new()
        .compose(&bad_view, &frames, BlendMode::Seams, &mut bad)
        .unwrap();
    let bad_worst = corner_offsets(&bad, &truth).into_iter().fold(0.0, f64::max);
    println!("front camera turned 2°: worst corner {bad_worst:.2} px");
    assert!(
        bad_worst > 1.0,
        "a turned camera went unnoticed: {bad_worst:.2} px"
    );
}

/// The median over the overlaps of |log₂ r_ij| after `frames` steps of the
/// closed loop under backlight (mean over the last 10 steps).
fn backlight_loop(balancing: bool, frames: usize) -> f64 {
    let render = Arc::new(render("backlight", 0.25));
    let settings = ProcessingSettings {
        strategy: if balancing {
            Strategy::Multi
        } else {
            Strategy::Single
        },
        ..Default::default()
    };
    let spec = CanvasSpec {
        px_per_m: 25.0,
        ..CanvasSpec::default()
    };
    let view = SurroundView::build(render.rig(), &spec, &SurroundOptions::default()).unwrap();
    let mut lp =
        rigview_tests::sim_loop(&render, view, settings, &render.rig().neighbours).unwrap();
    let mut tail = Vec::new();
    for f in 0..frames {
        let step = lp.step().unwrap().unwrap();
        let Some(output) = step.output else { continue };
        let mut logs: Vec<f64> = output
            .step
            .ratios
            .iter()
            .filter(|p| p.i < p.j)
            .filter_map(|p| p.r_ij.map(|r| r.log2().abs()))
            .collect();
        if f + 10 >= frames && !logs.is_empty() {
            logs.sort_by(f64::total_cmp);
            tail.push(logs[logs.len() / 2]);
        }
    }
    assert!(!tail.is_empty(), "no overlap gave a ratio");
    tail.iter().sum::<f64>() / tail.len() as f64
}

#[test]
fn balancing_in_surround_mode_lowers_the_overlap_ratios_under_backlight() {
    let single = backlight_loop(false, 60);
    let multi = backlight_loop(true, 60);
    println!(
        "backlight, ground-only metering: median |log2 r_ij| {single:.3} controlling each camera alone, {multi:.3} with balancing"
    );
    assert!(
        multi < single,
        "balancing did not help: {multi:.3} vs {single:.3}"
    );
}
