#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Building a view: `SurroundView::build` of the real four-fisheye rig in
//! `tests/data/surround-nz` (960×640 fisheyes, OpenCV fisheye model) on the
//! source project's canvas at 1 cm/px: 16 m × 12 m around a 5 m × 2 m car,
//! 1200×1600 pixels. A build maps every canvas pixel into every camera whose
//! side it lies beyond, computes the distance transforms and blend weights,
//! the ground masks and the overlap patches; the panorama's refinement
//! rebuilds its view, so this has to be fast. Beside it, in the same run,
//! `Panorama::build` of the same rig on a 4096×1024 cylinder (radius
//! 10 m, 25° below to 35° above the horizon): the same machinery on
//! 4.2 M canvas pixels. Results: `BENCHMARKS.md`.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use rigview_calib::formats;
use rigview_core::panorama::{CylinderSpec, Panorama, PanoramaOptions};
use rigview_core::surround::{CanvasSpec, SurroundOptions, SurroundView};

fn build(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz");
    let rig = formats::load(&data, None, None).unwrap().rig;
    let spec = CanvasSpec::around_car_16x12(100.0);
    assert_eq!(spec.size(), (1200, 1600));
    let options = SurroundOptions::default();
    let mut g = c.benchmark_group("view_build");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(10));
    g.bench_function("surround_nz_1200x1600", |b| {
        b.iter(|| black_box(SurroundView::build(&rig, &spec, &options).unwrap()));
    });
    let cylinder = CylinderSpec {
        width: 4096,
        height: 1024,
        ..CylinderSpec::default()
    };
    let pano_options = PanoramaOptions::default();
    g.bench_function("panorama_nz_4096x1024", |b| {
        b.iter(|| black_box(Panorama::build(&rig, &cylinder, &pano_options).unwrap()));
    });
    g.finish();
}

criterion_group!(benches, build);
criterion_main!(benches);
