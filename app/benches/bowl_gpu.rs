#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The bowl on the GPU against the bowl on the CPU, in the same run: the
//! real surround-nz frames (four RGB fisheyes) drawn as a 1280×800 picture
//! from behind-left with linear blending and the vehicle.
//!
//! - `gpu_draw`: the window's renderer (`rigview::gui::bowl_gl`) drawing a
//!   picture and waiting for it (`glFinish`): what each window frame costs
//!   on the GPU, and what a new viewpoint costs (a matrix, no rebuild).
//! - `gpu_upload_draw`: the same with a new frame set uploaded first.
//! - `cpu_compose`: the CPU's picture of a set (the composer over the
//!   bowl's maps, the vehicle painted over), the peer of both.
//! - `cpu_new_viewpoint`: the CPU's preview build for a new viewpoint
//!   (`BowlView::build_preview`), what its orbit waits for.
//!
//! The GL here is whatever EGL offers without a display: on this machine
//! Mesa's software renderer (llvmpipe, on every core), on a vehicle's
//! computer its GPU. Results: `BENCHMARKS.md`.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use rigview::commands::surround;
use rigview::gui::bowl_gl::{headless_context, BowlGl, Shot, TextureFrame};
use rigview_core::bowl::{BowlSpec, BowlView, SurfaceMesh, VehicleTriangles, Viewpoint};
use rigview_core::surround::{BlendMode, Canvas, CanvasSpec, Composer};

fn bowl_gpu(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz");
    let names: Vec<String> = ["front", "left", "back", "right"]
        .iter()
        .map(|n| data.join(format!("{n}.png")).display().to_string())
        .collect();
    let (rig, images) = surround::load(&data, &names).unwrap();
    let frames = surround::frames(&images).unwrap();
    let spec = BowlSpec {
        size_px: [1280, 800],
        ..BowlSpec::around(&CanvasSpec::around_car_16x12(25.0))
    };
    let [w, h] = spec.size_px;
    let viewpoint = Viewpoint::preset("behind-left").unwrap();
    let view = BowlView::build(&rig, &spec, &viewpoint).unwrap();
    let gl = headless_context().unwrap();
    let mut renderer = BowlGl::new(&gl).unwrap();
    let mesh: &SurfaceMesh = view.plan().mesh().unwrap();
    renderer.set_geometry(&gl, mesh, &VehicleTriangles::of(&spec, None));
    let textures: Vec<TextureFrame<'_>> = images.iter().map(TextureFrame::rgb).collect();
    renderer.upload(&gl, &textures).unwrap();
    let shot = Shot {
        camera: viewpoint.camera(w, h),
        size: (w, h),
        gains: vec![[1.0, 1.0]; 4],
        mode: BlendMode::Linear,
    };
    eprintln!(
        "bowl on the GPU: {} vertices, {} triangles; {} vehicle triangles",
        mesh.vertices.len(),
        mesh.indices.len() / 3,
        VehicleTriangles::of(&spec, None).vertices.len() / 3
    );
    let mut group = c.benchmark_group("bowl_gpu_1280x800");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(6));
    group.bench_function("gpu_draw", |b| {
        b.iter(|| {
            renderer.draw(&gl, &shot).unwrap();
            renderer.finish(&gl);
        });
    });
    group.bench_function("gpu_upload_draw", |b| {
        b.iter(|| {
            renderer.upload(&gl, &textures).unwrap();
            renderer.draw(&gl, &shot).unwrap();
            renderer.finish(&gl);
        });
    });
    let mut composer = Composer::new();
    let mut canvas = Canvas::new(w, h, 3);
    group.bench_function("cpu_compose", |b| {
        b.iter(|| {
            composer
                .compose(view.mosaic(), &frames, BlendMode::Linear, &mut canvas)
                .unwrap();
            view.paint_vehicle(&mut canvas).unwrap();
            black_box(&canvas);
        });
    });
    let turned = viewpoint.orbited(10.0, 0.0, 1.0);
    group.bench_function("cpu_new_viewpoint", |b| {
        b.iter(|| {
            black_box(BowlView::build_after(&rig, &spec, &turned, true, Some(&view)).unwrap());
        });
    });
    group.finish();
    renderer.destroy(&gl);
}

criterion_group!(benches, bowl_gpu);
criterion_main!(benches);
