#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The bowl view's CPU path: four 1288×964 RGB fisheye frames composed
//! into a 1280×800 picture of the bowl from a fixed viewpoint
//! (behind-left), with linear blending, and the vehicle model painted
//! over it; on one core (OpenCV limited to one thread).
//!
//! - `rigview`: `Composer::compose` of the bowl's mosaic (the same plan
//!   and kernels as the bird's-eye view) and `BowlView::paint_vehicle`.
//! - `opencv_remap`: the same maps through OpenCV's fixed-point `remap`
//!   per camera, copies where one camera shows the pixel and 8-bit
//!   weighted sums where several do (the peer of the bird's-eye bench).
//! - `build`: the bowl built for a new viewpoint (rays cast, maps,
//!   weights, vehicle overlay) and its plan: what the window's orbit waits
//!   for, off the per-set path.
//!
//! The rig: the composition benchmarks' (`benches/common`). Results:
//! `BENCHMARKS.md`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use opencv::core;
use rigview_core::bowl::{BowlSpec, BowlView, Viewpoint};
use rigview_core::surround::{BlendMode, Canvas, Composer};

mod common;

use common::{assert_like_opencv_remap, frames, rgb_views, rig, OpencvRemap};

fn bowl(c: &mut Criterion) {
    core::set_num_threads(1).unwrap();
    let rig = rig();
    let spec = BowlSpec::default();
    let viewpoint = Viewpoint::preset("behind-left").unwrap();
    let view = BowlView::build(&rig, &spec, &viewpoint).unwrap();
    let data = frames();
    let views = rgb_views(&data);
    let mut composer = Composer::new();
    let mut canvas = Canvas::new(0, 0, 3);
    composer
        .compose(view.mosaic(), &views, BlendMode::Linear, &mut canvas)
        .unwrap();
    let mut opencv_remap = OpencvRemap::new(view.mosaic());
    let mut opencv_canvas = vec![0u8; canvas.data.len()];
    opencv_remap.compose(view.mosaic(), &data, &mut opencv_canvas);
    assert_like_opencv_remap(&canvas.data, &opencv_canvas);
    let covered: usize = view
        .mosaic()
        .layers()
        .iter()
        .map(|l| l.weights[0].iter().filter(|&&w| w > 0).count())
        .sum();
    let [w, h] = spec.size_px;
    eprintln!(
        "bowl: picture {w}×{h}, {covered} camera-pixel contributions ({:.2} per pixel), vehicle over {:.1} %",
        covered as f64 / (w * h) as f64,
        100.0 * view.vehicle_coverage()
    );
    let mut group = c.benchmark_group("bowl_4x1288x964_to_1280x800");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    group.bench_function("rigview_linear_rgb_with_vehicle", |b| {
        b.iter(|| {
            composer
                .compose(
                    view.mosaic(),
                    black_box(&views),
                    BlendMode::Linear,
                    &mut canvas,
                )
                .unwrap();
            view.paint_vehicle(&mut canvas).unwrap();
        });
    });
    group.bench_function("opencv_remap_linear_rgb", |b| {
        b.iter(|| opencv_remap.compose(view.mosaic(), black_box(&data), &mut opencv_canvas));
    });
    group.finish();
    let mut group = c.benchmark_group("bowl_build_1280x800");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(8));
    group.bench_function("build_and_plan", |b| {
        b.iter(|| {
            let v = BowlView::build(&rig, &spec, black_box(&viewpoint)).unwrap();
            v.mosaic().prepare(BlendMode::Linear);
            v
        });
    });
    group.finish();
}

criterion_group!(benches, bowl);
criterion_main!(benches);
