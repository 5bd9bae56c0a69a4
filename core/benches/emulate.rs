#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Exposure emulation from brackets (`rigview_core::hdr`): one 1288×964
//! frame of the reference rig's front camera, 12-bit, emulated from the
//! radiance merged from six brackets 1 EV apart (2^8 to 2^13 µs, rendered by
//! the simulator with noise), on one thread.
//!
//! - `emulate_mono12`: `Radiance::emulate` with the sensor's noise (what
//!   `--source brackets:DIR` does per command in `emulate` mode).
//! - `emulate_noise_free_mono12`: the same without noise (scale, clamp,
//!   round).
//! - `copy_mono12` (peer): copying a 1288×964 12-bit frame, what handing
//!   over a bracket already decoded costs in `nearest` mode.
//! - `merge_6_brackets` (once per moment and camera): `hdr::merge` of the
//!   six brackets.
//!
//! The ray tracing and the rendering of the brackets are printed, not
//! benchmarked. Results: `BENCHMARKS.md` at the workspace root.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::hdr::{self, EmulateOptions, MergeConfig, SensorNoise, Shot};
use rigview_core::sim::{FillRequest, SimConfig, SimRender};

fn at(shutter_us: f64) -> ExposureSetting {
    ExposureSetting {
        shutter_us,
        gain_db: 0.0,
    }
}

fn emulate(c: &mut Criterion) {
    let t = Instant::now();
    let mut config = SimConfig::preset("reference").unwrap();
    config.sensor.bits = 12;
    let render = SimRender::new(&config).unwrap();
    let info = &render.cameras()[0];
    let (w, h) = (info.width, info.height);
    let levels: Vec<f64> = (8..14).map(|k| f64::from(k).exp2()).collect();
    let images: Vec<Vec<u8>> = levels
        .iter()
        .map(|&e| {
            let req = FillRequest::new(0, 3, at(e), PixelFormat::Mono12, w, h);
            let mut buf = vec![0u8; req.buffer_len()];
            render.fill(&req, &mut buf).unwrap();
            buf
        })
        .collect();
    eprintln!(
        "{w}×{h}: the rig traced and six brackets rendered in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    let shots: Vec<Shot<'_>> = levels
        .iter()
        .zip(&images)
        .map(|(&e, d)| Shot {
            setting: at(e),
            data: d,
        })
        .collect();
    let noise = SensorNoise::of(render.sensor(), 12).unwrap();
    let merge_config = MergeConfig::new(w * h, noise);
    let radiance = hdr::merge(&shots, &merge_config).unwrap();
    // Between two brackets, at a gain.
    let setting = ExposureSetting {
        shutter_us: 1500.0,
        gain_db: 3.0,
    };
    let mut out = vec![0u8; w * h * 2];
    let mut copy = vec![0u8; w * h * 2];
    let options = EmulateOptions {
        noise: true,
        seed: 1,
        camera: 0,
        frame: 3,
    };

    let mut group = c.benchmark_group("emulate_1288x964");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    group.bench_function("emulate_mono12", |b| {
        b.iter(|| {
            radiance.emulate(&setting, &options, &mut out).unwrap();
            black_box(&out);
        });
    });
    let quiet = EmulateOptions {
        noise: false,
        ..options
    };
    group.bench_function("emulate_noise_free_mono12", |b| {
        b.iter(|| {
            radiance.emulate(&setting, &quiet, &mut out).unwrap();
            black_box(&out);
        });
    });
    group.bench_function("copy_mono12", |b| {
        b.iter(|| {
            copy.copy_from_slice(black_box(&images[3]));
            black_box(&copy);
        });
    });
    group.bench_function("merge_6_brackets", |b| {
        b.iter(|| black_box(hdr::merge(&shots, &merge_config).unwrap()));
    });
    group.finish();
}

criterion_group!(benches, emulate);
criterion_main!(benches);
