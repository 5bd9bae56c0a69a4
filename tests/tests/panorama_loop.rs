#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The closed loop in panorama mode on the simulated rig under backlight:
//! every pixel that reaches the panorama is metered, and the overlap
//! ratios r_ij come from the patches around matched features (matched on
//! the panorama's worker thread every few sets, held in between).
//!
//! - Balancing with the neighbours ("multi") ends with a lower median
//!   |log2 r_ij| over the overlaps than each camera under its own law
//!   ("single"), measured on a fresh matching of the last set.
//! - Every overlap of the panorama reports its matches and inliers, and a
//!   pair without a ratio says why.
//!
//! Run with `--nocapture` for both figures and each pair's counts.

use std::sync::Arc;

use rigview_core::exposure::balance::pair_ratio;
use rigview_core::exposure::{BalanceParams, FrameView, NeighbourGraph};
use rigview_core::panorama::MatchOptions;
use rigview_core::pipeline::{
    LivePanorama, LockStep, PanoramaSettings, ProcessingSettings, Processor, Strategy, View,
    ViewKind,
};
use rigview_core::sim::{SimConfig, SimRender, SimRig, SimRigOptions};

const SETS: usize = 80;

fn render() -> Arc<SimRender> {
    let config = SimConfig {
        scale: 0.5,
        ..SimConfig::preset("backlight").unwrap()
    };
    Arc::new(SimRender::new(&config).unwrap())
}

/// Runs the loop; returns the median |log2 r_ij| of a fresh matching of
/// the last set, and the mean over the last 10 sets of the median of the
/// ratios the balancing saw.
fn run(render: &Arc<SimRender>, strategy: Strategy) -> (f64, f64) {
    let settings = ProcessingSettings {
        strategy,
        view: ViewKind::Panorama,
        panorama: PanoramaSettings {
            match_every: 5,
            ..PanoramaSettings::default()
        },
        ..ProcessingSettings::default()
    };
    let cameras = render.cameras().to_vec();
    let rig = render.rig().clone();
    let graph = NeighbourGraph::new(cameras.len(), &rig.neighbours).unwrap();
    let live = LivePanorama::new(rig, &settings.panorama, Arc::new(rigview_tests::harris)).unwrap();
    let mut processor = Processor::new(cameras, Some(View::from(live)), graph, settings).unwrap();
    processor.set_compose(false);
    let source = SimRig::new(render.clone(), SimRigOptions::default()).unwrap();
    let mut lp = LockStep::new(source, processor).unwrap();
    let mut held = Vec::new();
    let mut last = None;
    for k in 0..SETS {
        let step = lp.step().unwrap().unwrap();
        let output = step.output.as_ref().unwrap();
        let report = output.panorama.as_ref().expect("a panorama report");
        assert_eq!(report.pairs.len(), output.pairs.len());
        let mut logs: Vec<f64> = output
            .pairs
            .iter()
            .filter_map(|p| p.log2_r.map(f64::abs))
            .collect();
        if k + 10 >= SETS && !logs.is_empty() {
            logs.sort_by(f64::total_cmp);
            held.push(logs[logs.len() / 2]);
        }
        if k + 1 == SETS {
            for p in &report.pairs {
                println!(
                    "{strategy:?} {}–{}: {} matches, {} inliers, error {:?} px{}",
                    p.i,
                    p.j,
                    p.matches,
                    p.inliers,
                    p.error_px,
                    p.problem
                        .as_deref()
                        .map(|s| format!(" ({s})"))
                        .unwrap_or_default()
                );
                assert!(report.matched_trigger.is_some(), "never matched");
                assert!(
                    p.inliers > 0 || p.problem.is_some(),
                    "{}–{} has no inliers and no reason",
                    p.i,
                    p.j
                );
            }
        }
        last = Some(step.set);
    }
    // A fresh matching of the last set, on the panorama in use.
    let set = last.unwrap();
    let frames: Vec<FrameView<'_>> = set
        .frames
        .iter()
        .map(|f| f.as_ref().unwrap().view().unwrap())
        .collect();
    let pano = lp.processor().live_view().unwrap().panorama().unwrap();
    let (pairs, _) = pano
        .panorama()
        .match_pairs(&frames, &rigview_tests::harris, &MatchOptions::default())
        .unwrap();
    let mut logs: Vec<f64> = pairs
        .iter()
        .filter_map(|p| pair_ratio(&p.patches, &BalanceParams::default()))
        .map(|r| r.log2().abs())
        .collect();
    assert!(
        logs.len() >= 2,
        "{strategy:?}: only {} pairs gave a ratio",
        logs.len()
    );
    logs.sort_by(f64::total_cmp);
    let fresh = logs[logs.len() / 2];
    assert!(!held.is_empty(), "{strategy:?}: no held ratio at the end");
    (fresh, held.iter().sum::<f64>() / held.len() as f64)
}

#[test]
fn balancing_from_matched_patches_lowers_the_panoramas_ratios_under_backlight() {
    let render = render();
    let (single, single_held) = run(&render, Strategy::Single);
    let (multi, multi_held) = run(&render, Strategy::Multi);
    println!(
        "backlight, panorama: median |log2 r_ij| from matched patches {single:.3} with each camera alone, {multi:.3} with balancing (the held ratios of the last 10 sets: {single_held:.3} and {multi_held:.3})"
    );
    assert!(
        multi < single,
        "balancing did not lower the ratios: {multi:.3} vs {single:.3}"
    );
}

#[test]
fn a_rig_whose_cameras_do_not_overlap_names_them() {
    // The left camera turned to look forward right, between the front and
    // right cameras: those two, neighbours in the rig, no longer meet on
    // the cylinder.
    let render = render();
    let mut rig = render.rig().clone();
    let left = rig.cameras[1].pose.unwrap();
    let turn =
        nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), -135f64.to_radians());
    rig.cameras[1].pose = Some(
        rigview_calib::Pose::new(turn.matrix() * left.rotation_matrix(), *left.translation())
            .unwrap(),
    );
    let e = LivePanorama::new(
        rig,
        &PanoramaSettings::default(),
        Arc::new(rigview_tests::harris),
    )
    .map(|_| ())
    .unwrap_err()
    .to_string();
    println!("{e}");
    assert!(e.contains("share no pixel"), "{e}");
    assert!(e.contains("`front` and `right`"), "{e}");
}
