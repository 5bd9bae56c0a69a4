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
//! 4.2 M canvas pixels. Then the same surround view with every camera's
//! lens replaced by each of the other models (double sphere, extended
//! unified, unified, WoodScape's polynomial, Scaramuzza's), each scaled so
//! that a ray at 90° from the axis lands where the real lens puts it (the
//! same canvas coverage), against the real lens's Kannala–Brandt build in
//! the same run. Results: `BENCHMARKS.md`.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use rigview_calib::model::ocam::Ocam;
use rigview_calib::{formats, Distortion, Rig};
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
    // The other models, each at the focal length that puts a ray at 90°
    // where the real lens does: radius(90°) = f·m(90°).
    let k = rig.cameras[0].intrinsics;
    let at_90 = |d: Distortion| {
        let probe = rigview_calib::Intrinsics {
            fx: 1.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
            distortion: d,
            ..k
        };
        probe
            .project(&nalgebra::Vector3::new(1.0, 0.0, 0.0))
            .unwrap()
            .x
    };
    let real = at_90(k.distortion) * k.fx;
    let models = [
        Distortion::DoubleSphere([-0.2, 0.6]),
        Distortion::Eucm([0.6, 1.1]),
        Distortion::Omni([0.9, -0.05, 0.004, 0.0005, -0.0005, 0.0]),
        Distortion::RadialPoly([1.0, -0.05, 0.06, -0.015]),
        // z = −s + a·ρ² reaches 0 (90°) at the real lens's radius.
        Distortion::Scaramuzza(
            Ocam::new(&[-k.fx, 0.0, k.fx / (real * real)], &[], [1.0, 0.0, 0.0]).unwrap(),
        ),
    ];
    for d in models {
        let f = if matches!(d, Distortion::Scaramuzza(_)) {
            1.0
        } else {
            real / at_90(d)
        };
        let mut other: Rig = rig.clone();
        for c in &mut other.cameras {
            c.intrinsics.distortion = d;
            c.intrinsics.fx = f;
            c.intrinsics.fy = f;
        }
        g.bench_function(format!("surround_nz_1200x1600_{}", d.model_name()), |b| {
            b.iter(|| black_box(SurroundView::build(&other, &spec, &options).unwrap()));
        });
    }
    g.finish();
}

criterion_group!(benches, build);
criterion_main!(benches);
