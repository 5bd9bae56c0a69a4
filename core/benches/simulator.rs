#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The simulated rig's per-trigger cost: four 1288×964 frames of the
//! reference rig (preset `reference`), exposed from the precomputed
//! irradiance with gain, shot and read noise and quantisation.
//!
//! - `rigview_mono8`, `rigview_mono12`: `SimRender::fill` for the four
//!   cameras (noise from the shared normal table, one random offset per row).
//! - `rigview_noise_free_mono8`: the same without noise (the ground-truth
//!   renders).
//! - `straightforward_mono8`: the textbook per-pixel version of the same
//!   model: a ChaCha8 stream and Box–Muller in f64 for every pixel.
//! - `opencv_mono8` (OpenCV's thread pool) and `opencv_mono8_1thread`:
//!   OpenCV's composition of the same steps per camera: `addWeighted` of the
//!   two irradiance parts → `min` with the full well → `convertTo` (variance
//!   `K g·μ + (K g σ_read)²`) → `sqrt` → `randn` → `multiply` → `add` →
//!   `convertTo(CV_8U)` (saturating, rounded).
//!
//! The time of the one-off precomputation (ray tracing) is printed, not
//! benchmarked. Results: `BENCHMARKS.md` at the workspace root.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use opencv::core::{self, Mat, MatTraitConst, MatTraitConstManual, Scalar, CV_32F, CV_8U};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::sim::{FillRequest, SimConfig, SimRender};

/// A setting that puts the sunlit mat near the top and the shadow well
/// inside the range.
const SETTING: ExposureSetting = ExposureSetting {
    shutter_us: 250.0,
    gain_db: 6.0,
};

/// The per-frame constants of the model (see `rigview_core::sim::sensor`).
struct Model {
    a: f64,
    b: f64,
    kg: f64,
    read_var: f64,
    full: f64,
    top: f64,
}

fn model(render: &SimRender, bits: u32) -> Model {
    let s = render.sensor();
    let l = render.levels(0.0);
    let max_dn = f64::from((1u32 << bits) - 1);
    let kg = max_dn / s.full_well_e * 10f64.powf(SETTING.gain_db / 20.0);
    let per_unit = SETTING.shutter_us * s.responsivity * kg;
    Model {
        a: per_unit * l.sun,
        b: per_unit * l.sky,
        kg,
        read_var: (kg * s.read_noise_e).powi(2),
        full: kg * s.full_well_e,
        top: (kg * s.full_well_e).min(max_dn),
    }
}

/// The textbook version: one normal per pixel from ChaCha8 and Box–Muller.
fn straightforward(sun: &[f32], sky: &[f32], m: &Model, rng: &mut ChaCha8Rng, out: &mut [u8]) {
    for ((o, &s), &k) in out.iter_mut().zip(sun).zip(sky) {
        let mu = m.a * f64::from(s) + m.b * f64::from(k);
        let u1: f64 = 1.0 - rng.gen::<f64>();
        let u2: f64 = rng.gen();
        let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        let v = mu + (m.kg * mu.min(m.full) + m.read_var).sqrt() * n;
        *o = v.clamp(0.0, m.top).round() as u8;
    }
}

/// OpenCV's composition, its buffers reused.
struct OpenCvPeer {
    sun: Vec<Mat>,
    sky: Vec<Mat>,
    mu: Mat,
    sigma: Mat,
    noise: Mat,
    out: Mat,
}

impl OpenCvPeer {
    fn new(render: &SimRender) -> Self {
        let mat = |v: &[f32], h: i32| {
            Mat::new_rows_cols_with_data(h, v.len() as i32 / h, v)
                .unwrap()
                .try_clone()
                .unwrap()
        };
        let (mut sun, mut sky) = (Vec::new(), Vec::new());
        for (i, info) in render.cameras().iter().enumerate() {
            let (s, k) = render.light_parts(i).unwrap();
            sun.push(mat(s, info.height as i32));
            sky.push(mat(k, info.height as i32));
        }
        Self {
            sun,
            sky,
            mu: Mat::default(),
            sigma: Mat::default(),
            noise: Mat::default(),
            out: Mat::default(),
        }
    }

    fn frame(&mut self, i: usize, m: &Model) -> opencv::Result<()> {
        core::add_weighted(
            &self.sun[i],
            m.a,
            &self.sky[i],
            m.b,
            0.0,
            &mut self.mu,
            CV_32F,
        )?;
        let mut clipped = Mat::default();
        core::min(&self.mu, &Scalar::all(m.full), &mut clipped)?;
        clipped.convert_to(&mut self.sigma, CV_32F, m.kg, m.read_var)?;
        let mut sd = Mat::default();
        core::sqrt(&self.sigma, &mut sd)?;
        if self.noise.size()? != sd.size()? {
            self.noise = Mat::new_size_with_default(sd.size()?, CV_32F, Scalar::all(0.0))?;
        }
        core::randn(&mut self.noise, &Scalar::all(0.0), &Scalar::all(1.0))?;
        let mut scaled = Mat::default();
        core::multiply(&self.noise, &sd, &mut scaled, 1.0, -1)?;
        let mut v = Mat::default();
        core::add(&self.mu, &scaled, &mut v, &core::no_array(), -1)?;
        // The 8-bit converter's top is 255 at ≥ 0 dB: saturate_cast does it.
        v.convert_to(&mut self.out, CV_8U, 1.0, 0.0)?;
        black_box(self.out.data_bytes()?);
        Ok(())
    }
}

fn trigger(c: &mut Criterion) {
    let start = Instant::now();
    let render = SimRender::new(&SimConfig::preset("reference").unwrap()).unwrap();
    eprintln!(
        "precomputation (ray tracing the reference rig, 4 × 1288×964, supersample 2, {} threads): {:.2} s",
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        start.elapsed().as_secs_f64()
    );
    let cams = render.cameras().len();
    let request = |i: usize, format: PixelFormat, noise: bool| {
        let info = &render.cameras()[i];
        FillRequest {
            noise,
            ..FillRequest::new(i, 7, SETTING, format, info.width, info.height)
        }
    };
    let mut bufs: Vec<Vec<u8>> = (0..cams)
        .map(|i| vec![0u8; request(i, PixelFormat::Mono12, true).buffer_len()])
        .collect();

    let mut group = c.benchmark_group("trigger_4x1288x964");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    for (name, format, noise) in [
        ("rigview_mono8", PixelFormat::Mono8, true),
        ("rigview_mono12", PixelFormat::Mono12, true),
        ("rigview_noise_free_mono8", PixelFormat::Mono8, false),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                for (i, buf) in bufs.iter_mut().enumerate() {
                    render.fill(&request(i, format, noise), buf).unwrap();
                }
                black_box(&bufs);
            });
        });
    }

    let m8 = model(&render, 8);
    // Same model, same DN on average: check one camera before timing.
    let (sun0, sky0) = render.light_parts(0).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut naive = vec![0u8; sun0.len()];
    straightforward(sun0, sky0, &m8, &mut rng, &mut naive);
    render
        .fill(&request(0, PixelFormat::Mono8, true), &mut bufs[0])
        .unwrap();
    let mean = |v: &[u8]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
    eprintln!(
        "mean DN of camera 0: rigview {:.3}, straightforward {:.3}",
        mean(&bufs[0][..sun0.len()]),
        mean(&naive)
    );
    group.bench_function("straightforward_mono8", |b| {
        b.iter(|| {
            for i in 0..cams {
                let (s, k) = render.light_parts(i).unwrap();
                straightforward(s, k, &m8, &mut rng, &mut naive);
            }
            black_box(&naive);
        });
    });

    let mut peer = OpenCvPeer::new(&render);
    let threads = core::get_num_threads().unwrap();
    group.bench_function("opencv_mono8", |b| {
        b.iter(|| {
            for i in 0..cams {
                peer.frame(i, &m8).unwrap();
            }
        });
    });
    core::set_num_threads(1).unwrap();
    group.bench_function("opencv_mono8_1thread", |b| {
        b.iter(|| {
            for i in 0..cams {
                peer.frame(i, &m8).unwrap();
            }
        });
    });
    core::set_num_threads(threads).unwrap();
    group.finish();
}

criterion_group!(benches, trigger);
criterion_main!(benches);
