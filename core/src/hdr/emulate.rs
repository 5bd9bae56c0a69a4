//! A frame synthesised from a merged radiance at any exposure (see the
//! module documentation of [`crate::hdr`]).

use rand::Rng;

use super::{Response, SensorNoise};
use crate::exposure::ExposureSetting;
use crate::sim::sensor::{frame_rng, noise_table, NOISE_TABLE_LEN};
use crate::{Error, Result};

/// Samples that share one random offset into the noise table.
const CHUNK: usize = 1024;

/// Each sample's radiance per unit exposure level, from [`super::merge`].
#[derive(Clone, Debug, PartialEq)]
pub struct Radiance {
    x: Vec<f32>,
    var: Vec<f32>,
    noise: SensorNoise,
    response: Response,
    span: (f64, f64),
}

/// How to emulate one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmulateOptions {
    /// Add the sensor's noise (off: the mean, rounded).
    pub noise: bool,
    /// The seed of the noise.
    pub seed: u64,
    /// The camera (for the noise's stream).
    pub camera: usize,
    /// The frame (for the noise's stream).
    pub frame: u64,
}

impl Radiance {
    pub(crate) fn new(
        x: Vec<f32>,
        var: Vec<f32>,
        noise: SensorNoise,
        response: Response,
        span: (f64, f64),
    ) -> Self {
        Self {
            x,
            var,
            noise,
            response,
            span,
        }
    }

    /// Samples.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Each sample's radiance, DN per unit exposure level (linear DN for a
    /// response curve).
    pub fn values(&self) -> &[f32] {
        &self.x
    }

    /// Each sample's variance of the radiance (0 where the sample is
    /// clipped in every image: the value is a lower bound).
    pub fn variances(&self) -> &[f32] {
        &self.var
    }

    /// The exposure levels of the shortest and the longest image merged.
    pub fn span(&self) -> (f64, f64) {
        self.span
    }

    /// The sensor's noise and bit depth.
    pub fn noise(&self) -> &SensorNoise {
        &self.noise
    }

    /// Bytes per sample of an emulated frame: 1 up to 8 bits, else 2
    /// (little-endian).
    pub fn bytes_per_sample(&self) -> usize {
        if self.noise.bits > 8 {
            2
        } else {
            1
        }
    }

    /// Writes the frame taken at `setting` into `out` (`len()` samples of
    /// [`Self::bytes_per_sample`] bytes).
    pub fn emulate(
        &self,
        setting: &ExposureSetting,
        options: &EmulateOptions,
        out: &mut [u8],
    ) -> Result<()> {
        let e = setting.exposure();
        if !(e.is_finite() && e > 0.0) {
            return Err(Error::InvalidParameter {
                name: "exposure level",
                value: e,
                expected: "a positive exposure time and a finite gain",
            });
        }
        let bps = self.bytes_per_sample();
        if out.len() != self.len() * bps {
            return Err(Error::BufferSize {
                what: "emulated frame",
                expected: self.len() * bps,
                actual: out.len(),
                detail: format!("{} samples of {} bits", self.len(), self.noise.bits),
            });
        }
        let (kg, read_var, full, top) = self.noise.at_gain(setting.gain_db);
        let top = if self.response.is_linear() {
            top
        } else {
            top.min(255.0)
        };
        let k = Kernel {
            e: e as f32,
            e2: (e * e) as f32,
            kg: kg as f32,
            read_var: read_var as f32,
            full: full as f32,
            top: top as f32,
        };
        let table = noise_table();
        let mut rng = frame_rng(options.seed, options.camera, options.frame);
        let mut dn = [0.0f32; CHUNK];
        for ((x, var), out) in self
            .x
            .chunks(CHUNK)
            .zip(self.var.chunks(CHUNK))
            .zip(out.chunks_mut(CHUNK * bps))
        {
            let dn = &mut dn[..x.len()];
            if options.noise {
                let off = rng.gen_range(0..NOISE_TABLE_LEN - CHUNK);
                k.noisy(x, var, &table[off..off + x.len()], dn);
            } else {
                k.mean(x, dn);
            }
            store(&self.response, bps, dn, out);
        }
        Ok(())
    }
}

/// The constants of one emulated frame.
#[derive(Clone, Copy, Debug)]
struct Kernel {
    e: f32,
    e2: f32,
    kg: f32,
    read_var: f32,
    full: f32,
    top: f32,
}

impl Kernel {
    #[inline]
    fn noisy(&self, x: &[f32], var: &[f32], noise: &[f32], dn: &mut [f32]) {
        let n = dn.len();
        let (x, var, noise) = (&x[..n], &var[..n], &noise[..n]);
        for i in 0..n {
            let mu = x[i] * self.e;
            let v = (self.kg * mu.min(self.full) + self.read_var - self.e2 * var[i]).max(0.0);
            dn[i] = (mu + v.sqrt() * noise[i]).max(0.0).min(self.top);
        }
    }

    #[inline]
    fn mean(&self, x: &[f32], dn: &mut [f32]) {
        for (d, &x) in dn.iter_mut().zip(x) {
            *d = (x * self.e).max(0.0).min(self.top);
        }
    }
}

/// Quantises `dn` into `out` (`bps` bytes a sample).
#[inline]
fn store(response: &Response, bps: usize, dn: &[f32], out: &mut [u8]) {
    match (response, bps) {
        (Response::Linear, 2) => {
            for (o, &v) in out.chunks_exact_mut(2).zip(dn) {
                o.copy_from_slice(&((v + 0.5) as u16).to_le_bytes());
            }
        }
        (Response::Linear, _) => {
            for (o, &v) in out.iter_mut().zip(dn) {
                *o = (v + 0.5) as u8;
            }
        }
        (curve, _) => {
            for (o, &v) in out.iter_mut().zip(dn) {
                *o = curve.code(v) as u8;
            }
        }
    }
}
