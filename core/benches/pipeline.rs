#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The processing thread's cost per frame set: one set of four 1288×964
//! Mono8 frames of the simulated reference rig through
//! `Processor::process` (ground-masked metering, overlap patches, the rig
//! controller with balancing, the bird's-eye composition into 1000×1000,
//! thumbnails and histograms). At 20 Hz the budget is 50 ms a set, and the
//! window's end-to-end target is two frame periods (100 ms).
//!
//! - `processor`: rigview's processing thread as it runs (masks prepared
//!   once per calibration).
//! - `processor_fast_law`: the same under rigview's fast law (its root
//!   search, and every frame's light measured against a reference frame).
//! - `closed_loop_and_compose`: the peer in the same run: the same steps
//!   with metering that derives each ground mask's coverage on every frame
//!   (`Meter::meter` with the raw mask), plus the composition.
//!
//! Results: `BENCHMARKS.md` at the workspace root.

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use rigview_core::exposure::{LawKind, Meter, MeteringConfig, NeighbourGraph, RigController};
use rigview_core::pipeline::{ProcessingSettings, Processor, StageTimes};
use rigview_core::sim::{SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::FrameSource;
use rigview_core::surround::{
    BlendMode, Canvas, CanvasSpec, Composer, SurroundOptions, SurroundView,
};

fn bench(c: &mut Criterion) {
    let render = Arc::new(SimRender::new(&SimConfig::default()).unwrap());
    let cams = render.cameras().to_vec();
    let build = || {
        SurroundView::build(
            render.rig(),
            &CanvasSpec::default(),
            &SurroundOptions::default(),
        )
        .unwrap()
    };
    let graph = || NeighbourGraph::new(cams.len(), &render.rig().neighbours).unwrap();
    let mut rig = SimRig::new(render.clone(), SimRigOptions::default()).unwrap();
    let set = rig.next_set(Duration::from_secs(1)).unwrap().unwrap();

    let mut g = c.benchmark_group("pipeline");
    g.sample_size(20).measurement_time(Duration::from_secs(6));

    let mut p = Processor::new(
        cams.clone(),
        Some(build().into()),
        graph(),
        ProcessingSettings::default(),
    )
    .unwrap();
    g.bench_function("processor", |b| {
        b.iter(|| {
            black_box(
                p.process(&set, Instant::now(), StageTimes::default())
                    .unwrap(),
            )
        });
    });

    // The same with rigview's fast law, which also measures every frame's
    // light against a reference frame.
    let mut fast = ProcessingSettings::default();
    fast.controller.law.kind = LawKind::Fast;
    let mut p = Processor::new(cams.clone(), Some(build().into()), graph(), fast).unwrap();
    g.bench_function("processor_fast_law", |b| {
        b.iter(|| {
            black_box(
                p.process(&set, Instant::now(), StageTimes::default())
                    .unwrap(),
            )
        });
    });

    let view = build();
    let settings = ProcessingSettings::default();
    let ranges: Vec<_> = cams.iter().map(|c| c.range).collect();
    let mut controller =
        RigController::new(settings.controller_config(), &ranges, graph()).unwrap();
    let meter = Meter::new(MeteringConfig::default()).unwrap();
    let mut composer = Composer::new();
    let (w, h) = view.size();
    g.bench_function("closed_loop_and_compose", |b| {
        b.iter(|| {
            let frames: Vec<_> = set.frames.iter().flatten().collect();
            let views: Vec<_> = frames.iter().map(|f| f.view().unwrap()).collect();
            let metered: Vec<_> = views
                .iter()
                .zip(view.ground_masks())
                .map(|(v, m)| meter.meter(v, Some(m)).unwrap())
                .collect();
            let pairs = view.pair_observations(&views).unwrap();
            let step = controller.step_frames(&frames, &metered, &pairs).unwrap();
            let mut canvas = Canvas::new(w, h, 1);
            composer
                .compose(&view, &views, BlendMode::Linear, &mut canvas)
                .unwrap();
            black_box((step, canvas))
        });
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
