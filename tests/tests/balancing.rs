//! Multi-camera balancing in closed loop on synthetic rigs whose neighbours
//! see the same surfaces in their overlaps. Run with `--nocapture` to see the
//! figures.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use rigview_core::exposure::{
    ControllerConfig, ExposureRange, ExposureSetting, MeteringConfig, NeighbourGraph,
    RigController, RigStep,
};
use rigview_core::synth::{LinearCamera, StripRig};
use rigview_tests::strip::StripHarness;

fn median_log_ratio(step: &RigStep) -> f64 {
    let mut v: Vec<f64> = step
        .ratios
        .iter()
        .filter_map(|r| r.r_ij)
        .map(|r| r.log2().abs())
        .collect();
    assert!(!v.is_empty(), "no overlap gave a ratio");
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs `frames` sets; cameras start at `starts` (µs); returns the last
/// step's median |log2 r_ij|.
fn run(levels: &[f32], starts: &[f64], balanced: bool, frames: usize) -> f64 {
    let rig = StripRig::new(640, 480, 160, levels, 5).unwrap();
    let n = rig.cameras();
    let mut h = StripHarness::new(
        rig,
        LinearCamera::default(),
        MeteringConfig::default(),
        1,
        ExposureSetting {
            shutter_us: 1000.0,
            gain_db: 0.0,
        },
    )
    .unwrap();
    for (i, &s) in starts.iter().enumerate() {
        h.force(
            i,
            ExposureSetting {
                shutter_us: s,
                gain_db: 0.0,
            },
        );
    }
    let config = ControllerConfig {
        balancing: balanced.then(Default::default),
        ..Default::default()
    };
    let mut c = RigController::new(
        config,
        &vec![ExposureRange::default(); n],
        NeighbourGraph::ring(n).unwrap(),
    )
    .unwrap();
    let mut last = f64::NAN;
    for _ in 0..frames {
        let (_, step) = h.step(&mut c).unwrap();
        last = median_log_ratio(&step);
    }
    last
}

/// Neighbours see the same surfaces in their overlaps, not in the rest of
/// their views, so each camera's own best exposure differs. Eq. 5 keeps at
/// least half of each camera on its own law (`α ≥ 1/2`), so balanced cameras
/// rest at a compromise: under the default γ-mapping within 0.1 EV of each
/// other, and closer than each camera alone. (Under scale-and-clip the four
/// strip cameras' own optima lie 0.94 EV apart, and they rest at 0.15 EV,
/// against 0.54 alone: docs/exposure-results.md.)
#[test]
fn cameras_on_the_same_surfaces_converge_to_equal_brightness() {
    for (levels, starts) in [
        (vec![1.0f32, 1.0], vec![1500.0, 12000.0]),
        (vec![1.0f32; 4], vec![1500.0, 12000.0, 4000.0, 800.0]),
    ] {
        let initial = run(&levels, &starts, true, 1);
        let balanced = run(&levels, &starts, true, 60);
        let alone = run(&levels, &starts, false, 60);
        println!(
            "{} cameras: median |log2 r_ij| {initial:.3} at the start, {balanced:.3} after 60 sets; each camera alone {alone:.3}",
            levels.len()
        );
        assert!(initial > 1.0);
        assert!(balanced < 0.1, "balanced {balanced}, alone {alone}");
        assert!(balanced < alone, "balanced {balanced}, alone {alone}");
    }
}

#[test]
fn balancing_lowers_the_brightness_ratios_under_backlight() {
    // Camera 2 faces a region 16× brighter than the rest.
    let levels = [1.0f32, 1.0, 16.0, 1.0];
    let starts = [2000.0; 4];
    let single = run(&levels, &starts, false, 60);
    let multi = run(&levels, &starts, true, 60);
    println!("backlight: median |log2 r_ij| single {single:.3}, balanced {multi:.3}");
    assert!(multi < 0.75 * single, "single {single}, balanced {multi}");
}
