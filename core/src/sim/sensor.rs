//! The camera model: a linear sensor after EMVA 1288.
//!
//! For a pixel whose sensor irradiance is `L` (scene radiance × vignetting,
//! in the scene's units) exposed for `t` µs at gain `g = 10^(gain_dB/20)`:
//!
//! ```text
//! μ_e  = L · t · responsivity                       mean electrons
//! K    = (2^bits − 1) / full_well                    DN per electron at 0 dB
//! μ    = K · g · μ_e                                  mean digital value
//! σ²   = (K g)² · (min(μ_e, full_well) + σ_read²)
//! DN   = round(clamp(μ + σ · n, 0, min(2^bits − 1, K g · full_well)))
//! ```
//!
//! so the mean grows in proportion to the exposure level
//! `E = t · 10^(gain_dB/20)` until the pixel saturates, at full well (0 dB)
//! or at the top of the converter (with gain, earlier). Shot noise (the
//! `μ_e` term) and read noise are amplified by the gain; rounding adds the
//! quantisation noise (1/12 DN²).
//!
//! # The noise and its accuracy
//!
//! `n` comes from a table of 2^20 standard normal samples (Box–Muller on a
//! ChaCha8 stream, then shifted and scaled to mean 0 and variance 1
//! exactly), read from a random offset for every row of every frame. The
//! offsets come from a ChaCha8 stream seeded by (seed, camera, frame), so a
//! frame is a pure function of its inputs. What that costs:
//!
//! - the marginal distribution is the table's: a normal to within the
//!   sampling error of 2^20 draws (tail quantiles out to about ±4.9σ);
//! - the shot noise is Gaussian rather than Poisson: exact in mean and
//!   variance, slightly off in skew below about 10 electrons, where the
//!   read noise (12 e⁻) dominates anyway;
//! - two rows whose offsets fall within a row's width of each other share
//!   shifted samples (probability about 2·width/2^20 per pair of rows,
//!   0.25 % at 1288 px); the noise of pixels more than a row apart is
//!   independent otherwise.

use std::sync::OnceLock;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::texture::mix;
use super::{check_field, FieldError};
use crate::exposure::split::gain_factor;
use crate::exposure::{ExposureRange, ExposureSetting};
use crate::image::PixelFormat;

/// Samples in the noise table.
pub const NOISE_TABLE_LEN: usize = 1 << 20;

/// The sensor and its output.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sensor {
    /// Full-well capacity, electrons.
    pub full_well_e: f64,
    /// Read noise, electrons (rms).
    pub read_noise_e: f64,
    /// Electrons per µs for a sensor irradiance of 1 (quantum efficiency
    /// and pixel area folded in).
    pub responsivity: f64,
    /// Bits of the output: 8 (Mono8) or 12 (Mono12).
    pub bits: u32,
    /// Shortest exposure time, µs.
    pub shutter_min_us: f64,
    /// Longest exposure time, µs.
    pub shutter_max_us: f64,
    /// Lowest gain, dB.
    pub gain_min_db: f64,
    /// Highest gain, dB.
    pub gain_max_db: f64,
    /// Vignetting: the irradiance falls by this fraction from the optical
    /// axis to the edge of the lens's field, as `1 − v·(θ/θ_max)²` (0: none).
    pub vignetting: f64,
    /// Whether to add noise (off: the noise-free render, quantised).
    pub noise: bool,
}

impl Default for Sensor {
    /// The reference camera (a Sony ICX445-class CCD): 10 000 e⁻ full well,
    /// 12 e⁻ read noise (58.4 dB dynamic range), 8-bit output, 10 µs – 10 s,
    /// 0 – 24 dB, no vignetting.
    fn default() -> Self {
        Self {
            full_well_e: 10_000.0,
            read_noise_e: 12.0,
            responsivity: 60.0,
            bits: 8,
            shutter_min_us: 10.0,
            shutter_max_us: 10_000_000.0,
            gain_min_db: 0.0,
            gain_max_db: 24.0,
            vignetting: 0.0,
            noise: true,
        }
    }
}

impl Sensor {
    /// The exposure ranges the camera reports.
    pub fn range(&self) -> ExposureRange {
        ExposureRange {
            shutter_min_us: self.shutter_min_us,
            shutter_max_us: self.shutter_max_us,
            gain_min_db: self.gain_min_db,
            gain_max_db: self.gain_max_db,
        }
    }

    /// The pixel format of its frames.
    pub fn format(&self) -> PixelFormat {
        if self.bits == 12 {
            PixelFormat::Mono12
        } else {
            PixelFormat::Mono8
        }
    }

    /// The dynamic range, dB: `20·log10(full_well / read_noise)`.
    pub fn dynamic_range_db(&self) -> f64 {
        20.0 * (self.full_well_e / self.read_noise_e.max(1e-9)).log10()
    }

    /// Checks every value; the error names the field (`sensor.bits`).
    pub fn validate(&self) -> Result<(), FieldError> {
        let pos = |f: &str, v: f64, lo: f64, hi: f64, e: &str| {
            check_field(format!("sensor.{f}"), v, lo, hi, e)
        };
        pos(
            "full_well_e",
            self.full_well_e,
            1.0,
            1e9,
            "a capacity in electrons from 1 to 10⁹",
        )?;
        pos(
            "read_noise_e",
            self.read_noise_e,
            0.0,
            1e6,
            "a noise in electrons ≥ 0",
        )?;
        pos(
            "responsivity",
            self.responsivity,
            1e-12,
            1e12,
            "a positive responsivity",
        )?;
        if self.bits != 8 && self.bits != 12 {
            return Err(FieldError::new(
                "sensor.bits",
                "8 (Mono8) or 12 (Mono12)",
                format!("{}", self.bits),
            ));
        }
        pos(
            "vignetting",
            self.vignetting,
            0.0,
            1.0,
            "a fraction in [0, 1]",
        )?;
        self.range().validate().map_err(|e| match e {
            crate::Error::InvalidParameter {
                name,
                value,
                expected,
            } => FieldError::new(format!("sensor.{name}"), expected, format!("{value}")),
            other => FieldError::new(
                "sensor",
                "a shutter or gain range to control",
                other.to_string(),
            ),
        })
    }

    /// The gains of one frame: `a` and `b` turn the sun's and the sky's
    /// irradiance into mean DN.
    pub(crate) fn gains(
        &self,
        setting: &ExposureSetting,
        sun: f64,
        sky: f64,
        bits: u32,
        noise: bool,
    ) -> Gains {
        let max_dn = f64::from((1u32 << bits) - 1);
        let kg = max_dn / self.full_well_e * gain_factor(setting.gain_db);
        let per_unit = setting.shutter_us * self.responsivity * kg;
        let full = kg * self.full_well_e;
        Gains {
            a: (per_unit * sun) as f32,
            b: (per_unit * sky) as f32,
            kg: if noise { kg as f32 } else { 0.0 },
            read_var: if noise {
                ((kg * self.read_noise_e).powi(2)) as f32
            } else {
                0.0
            },
            full: full as f32,
            top: full.min(max_dn) as f32,
            noise,
        }
    }
}

/// What turns irradiance into digital values in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Gains {
    pub a: f32,
    pub b: f32,
    pub kg: f32,
    pub read_var: f32,
    pub full: f32,
    pub top: f32,
    pub noise: bool,
}

/// The shared table of standard normal samples.
pub(crate) fn noise_table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut rng = ChaCha8Rng::seed_from_u64(0x005e_ed0f_1288);
        let mut v: Vec<f64> = Vec::with_capacity(NOISE_TABLE_LEN);
        while v.len() < NOISE_TABLE_LEN {
            // Box–Muller: two independent normals from two uniforms.
            let u1: f64 = 1.0 - rng.gen::<f64>();
            let u2: f64 = rng.gen::<f64>();
            let r = (-2.0 * u1.ln()).sqrt();
            let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
            v.push(r * c);
            v.push(r * s);
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        for x in &mut v {
            *x = (*x - mean) / sd;
        }
        v.into_iter().map(|x| x as f32).collect()
    })
}

/// The random stream of one frame of one camera.
pub(crate) fn frame_rng(seed: u64, camera: usize, frame: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix(
        seed ^ mix(camera as u64 ^ mix(frame.wrapping_add(0x51)))
    ))
}

/// Mean DN (noise-free, not yet rounded) and the noisy value of one row,
/// into `out` (DN as f32, clamped, not rounded).
#[inline]
pub(crate) fn expose_row(g: &Gains, sun: &[f32], sky: &[f32], noise: &[f32], out: &mut [f32]) {
    let n = out.len();
    let (sun, sky) = (&sun[..n], &sky[..n]);
    if g.noise {
        let noise = &noise[..n];
        for i in 0..n {
            // The charge is clipped at full well after the shot noise, so a
            // pixel far beyond it sits at the top without noise.
            let mu = g.a * sun[i] + g.b * sky[i];
            let sigma = (g.kg * mu.min(g.full) + g.read_var).sqrt();
            out[i] = (mu + sigma * noise[i]).max(0.0).min(g.top);
        }
    } else {
        for i in 0..n {
            out[i] = (g.a * sun[i] + g.b * sky[i]).max(0.0).min(g.top);
        }
    }
}

/// Writes one row of DN values in `format` (rounded to the nearest
/// integer; grey in every channel of RGB8 and every site of a Bayer
/// mosaic).
#[inline]
pub(crate) fn store_row(format: PixelFormat, dn: &[f32], out: &mut [u8]) {
    match format {
        PixelFormat::Mono12 | PixelFormat::Mono16 => {
            for (o, &v) in out.chunks_exact_mut(2).zip(dn) {
                o.copy_from_slice(&((v + 0.5) as u16).to_le_bytes());
            }
        }
        PixelFormat::Rgb8 => {
            for (o, &v) in out.chunks_exact_mut(3).zip(dn) {
                o.fill((v + 0.5) as u8);
            }
        }
        _ => {
            for (o, &v) in out.iter_mut().zip(dn) {
                *o = (v + 0.5) as u8;
            }
        }
    }
}

/// The output bits of a pixel format.
pub fn format_bits(format: PixelFormat) -> u32 {
    match format {
        PixelFormat::Mono12 => 12,
        PixelFormat::Mono16 => 16,
        _ => 8,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_table_is_standard_normal() {
        let t = noise_table();
        assert_eq!(t.len(), NOISE_TABLE_LEN);
        let n = t.len() as f64;
        let mean = t.iter().map(|&x| f64::from(x)).sum::<f64>() / n;
        let var = t.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / n;
        assert!(mean.abs() < 1e-6 && (var - 1.0).abs() < 1e-5);
        // Tails as a normal's: P(|n| > 2) = 0.0455, P(|n| > 3) = 0.0027.
        let over = |k: f32| t.iter().filter(|x| x.abs() > k).count() as f64 / n;
        assert!((over(2.0) - 0.0455).abs() < 0.001, "{}", over(2.0));
        assert!((over(3.0) - 0.0027).abs() < 0.0002, "{}", over(3.0));
    }

    #[test]
    fn gain_amplifies_the_noise_at_equal_exposure() {
        let s = Sensor::default();
        let low = ExposureSetting {
            shutter_us: 400.0,
            gain_db: 0.0,
        };
        let high = ExposureSetting {
            shutter_us: 100.0,
            gain_db: 20.0 * 4f64.log10(),
        };
        let (gl, gh) = (
            s.gains(&low, 1.0, 0.0, 12, true),
            s.gains(&high, 1.0, 0.0, 12, true),
        );
        // Same mean DN per unit irradiance …
        assert!((gl.a - gh.a).abs() < 1e-3 * gl.a);
        // … but 4× the DN per electron, so more noise at the same mean.
        let var = |g: &Gains, mu: f32| g.kg * mu + g.read_var;
        assert!(var(&gh, 1000.0) > 3.9 * var(&gl, 1000.0));
        assert!((s.dynamic_range_db() - 58.4).abs() < 0.05);
    }
}
