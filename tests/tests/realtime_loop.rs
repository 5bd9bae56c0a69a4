#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The app's threaded pipeline on the simulated rig at its trigger rate, as
//! the window runs it by default: capture and processing on their own
//! threads, commands reaching the rig whenever processing sends them (so
//! the latency in frames varies from set to set), views composed.

use std::sync::Arc;
use std::time::Duration;

use rigview_core::exposure::{NeighbourGraph, Simulation};
use rigview_core::pipeline::{Pipeline, PipelineOptions, ProcessingSettings, Processor};
use rigview_core::sim::{Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::surround::{CanvasSpec, SurroundOptions, SurroundView};

/// Sets run: the test needs `2 · TAIL` of them processed, and a loaded
/// machine's pipeline drops a few (the queue keeps the newest).
const SETS: u64 = 220;
/// The sets judged at the end (5 s).
const TAIL: usize = 100;

/// The default mode (balanced, scale-and-clip, nonlinear law) on the
/// reference preset at full resolution holds every camera still once
/// settled: over the last 5 s each camera's exposure stays within a band
/// of 0.03 EV. Under scale-and-clip Eq. 6's `α` is averaged over frames by
/// default (weight 1/8): with each frame's own `α` the front camera swung
/// 0.12 EV, and after every law came to follow the light still 0.036 EV.
#[test]
fn the_default_mode_holds_every_camera_still_in_real_time() {
    let settings = ProcessingSettings::default();
    assert_eq!(
        settings.controller.estimator.simulation,
        Simulation::ScaleClip
    );
    holds_every_camera_still(settings);
}

/// The same under the paper's γ-mapping, whose default is Eq. 6 as written
/// (each frame's own `α`; averaged with weight 1/8 the front camera moved
/// 0.036 EV).
///
/// The front camera's M curve has two humps of nearly equal height
/// (γ ≈ 1.55 and the anchors' end, 1.9). When the estimate took the higher
/// hump alone, γ̂ jumped between them as the exposure crossed 2^10.04; the
/// balancing, which holds that camera brighter than its own law wants,
/// pulled it up to the jump again and again, and the camera's part of the
/// view pulsed by 0.1 EV about once a second.
#[test]
fn the_gamma_mapping_holds_every_camera_still_in_real_time() {
    let mut settings = ProcessingSettings::default();
    settings.controller.estimator.simulation = Simulation::Gamma;
    holds_every_camera_still(settings);
}

fn holds_every_camera_still(settings: ProcessingSettings) {
    let config = SimConfig::preset("reference").unwrap();
    let render = Arc::new(SimRender::new(&config).unwrap());
    let view = SurroundView::build(
        render.rig(),
        &CanvasSpec::default(),
        &SurroundOptions::default(),
    )
    .unwrap();
    let graph = NeighbourGraph::new(render.cameras().len(), &render.rig().neighbours).unwrap();
    let rig = SimRig::new(
        render.clone(),
        SimRigOptions {
            pacing: Pacing::Realtime,
            frames: Some(SETS),
            ..Default::default()
        },
    )
    .unwrap();
    let processor = Processor::new(
        render.cameras().to_vec(),
        Some(view.into()),
        graph,
        settings,
    )
    .unwrap();
    let mut pipeline = Pipeline::start(
        rig,
        processor,
        PipelineOptions {
            output_queue: SETS as usize,
            ..Default::default()
        },
        Arc::new(|| {}),
    )
    .unwrap();
    let mut log2_e = vec![Vec::new(); render.cameras().len()];
    while let Some(out) = pipeline.next_output(Duration::from_secs(30)) {
        assert!(out.canvas.is_some(), "set {}: no view", out.trigger);
        for (cam, c) in out.cameras.iter().enumerate() {
            log2_e[cam].push(c.taken.exposure().log2());
        }
    }
    pipeline.stop();
    for (cam, e) in log2_e.iter().enumerate() {
        let name = &render.cameras()[cam].name;
        assert!(
            e.len() >= 2 * TAIL,
            "{name}: only {} sets processed",
            e.len()
        );
        let tail = &e[e.len() - TAIL..];
        let band = tail.iter().copied().fold(f64::MIN, f64::max)
            - tail.iter().copied().fold(f64::MAX, f64::min);
        println!("{name}: last {TAIL} exposures within {band:.3} EV");
        assert!(
            band <= 0.03,
            "{name}: exposure moved {band:.3} EV over the last {TAIL} sets: {:.3?}",
            tail
        );
    }
}
