//! Each sample's radiance from a moment's brackets (see the module
//! documentation of [`crate::hdr`]).

use super::{Radiance, Response, SensorNoise};
use crate::exposure::ExposureSetting;
use crate::{Error, Result};

/// One image of a bracket: what it was taken with and its samples (one
/// byte each for 8 bits or fewer, else little-endian `u16`), in the same
/// layout as every other image of the bracket (a Bayer mosaic is merged
/// per photosite).
#[derive(Clone, Copy, Debug)]
pub struct Shot<'a> {
    /// Its exposure time and gain.
    pub setting: ExposureSetting,
    /// Its samples.
    pub data: &'a [u8],
}

/// How to merge.
#[derive(Clone, Debug, PartialEq)]
pub struct MergeConfig {
    /// Samples in each image (width × height).
    pub samples: usize,
    /// The sensor's noise and bit depth.
    pub noise: SensorNoise,
    /// How values relate to the light.
    pub response: Response,
    /// A value at or above this fraction of the image's top value
    /// (`min(2^bits − 1, K g·full_well)`) is clipped.
    pub clip_fraction: f64,
    /// The noise floor, DN: an image whose predicted mean falls below it
    /// is left out (unless nothing else sees the sample).
    pub floor_dn: f64,
}

impl MergeConfig {
    /// The defaults for `samples` samples of a sensor with `noise`: clipped
    /// at 97 % of the top, a floor of twice the read noise (2 DN at least),
    /// linear.
    pub fn new(samples: usize, noise: SensorNoise) -> Self {
        Self {
            samples,
            floor_dn: (2.0 * noise.k * noise.read_noise_e).max(2.0),
            noise,
            response: Response::Linear,
            clip_fraction: 0.97,
        }
    }
}

/// Per image: what the merge needs of it.
#[derive(Clone, Copy, Debug)]
struct Level {
    e: f32,
    inv_e: f32,
    e2: f32,
    kg: f32,
    var0: f32,
    clip: u16,
}

/// Merges `shots` (any order) into each sample's radiance per unit
/// exposure level (see the module documentation).
pub fn merge(shots: &[Shot<'_>], config: &MergeConfig) -> Result<Radiance> {
    if shots.is_empty() {
        return Err(Error::invalid(
            "merging a bracket",
            "images",
            "at least one",
            "no images",
        ));
    }
    if !(config.clip_fraction > 0.0 && config.clip_fraction <= 1.0 && config.floor_dn >= 0.0) {
        return Err(Error::invalid(
            "merging a bracket",
            "clip fraction and floor",
            "a fraction in (0, 1] and a floor ≥ 0 DN",
            format_args!("{} and {} DN", config.clip_fraction, config.floor_dn),
        ));
    }
    if !config.response.is_linear() && config.noise.bits != 8 {
        return Err(Error::invalid(
            "merging a bracket",
            "bits of images with a response curve",
            "8",
            config.noise.bits,
        ));
    }
    let wide = config.noise.bits > 8;
    let bytes = config.samples * if wide { 2 } else { 1 };
    let mut order: Vec<&Shot<'_>> = shots.iter().collect();
    for s in &order {
        let e = s.setting.exposure();
        if !(e.is_finite() && e > 0.0) {
            return Err(Error::InvalidParameter {
                name: "exposure level",
                value: e,
                expected: "a positive exposure time and a finite gain",
            });
        }
        if s.data.len() < bytes {
            return Err(Error::BufferSize {
                what: "bracket image",
                expected: bytes,
                actual: s.data.len(),
                detail: format!("{} samples of {} bits", config.samples, config.noise.bits),
            });
        }
    }
    order.sort_by(|a, b| a.setting.exposure().total_cmp(&b.setting.exposure()));
    let levels: Vec<Level> = order
        .iter()
        .map(|s| {
            let e = s.setting.exposure();
            let (kg, read_var, _, top) = config.noise.at_gain(s.setting.gain_db);
            let top_code = if config.response.is_linear() {
                top
            } else {
                255.0
            };
            Level {
                e: e as f32,
                inv_e: (1.0 / e) as f32,
                e2: (e * e) as f32,
                kg: kg as f32,
                var0: (read_var + 1.0 / 12.0) as f32,
                clip: (config.clip_fraction * top_code).ceil().min(65535.0) as u16,
            }
        })
        .collect();
    let data: Vec<&[u8]> = order.iter().map(|s| s.data).collect();
    let mut x = vec![0.0f32; config.samples];
    let mut var = vec![0.0f32; config.samples];
    let floor = config.floor_dn as f32;
    let response = &config.response;
    let read = |k: usize, i: usize| -> u16 {
        if wide {
            u16::from_le_bytes([data[k][2 * i], data[k][2 * i + 1]])
        } else {
            u16::from(data[k][i])
        }
    };
    let m = levels.len();
    for i in 0..config.samples {
        // The pilot: the longest image below 90 % of its clip level, else
        // the longest unclipped one.
        let margin = (0..m).rev().find(|&k| {
            let v = read(k, i);
            u32::from(v) * 10 < u32::from(levels[k].clip) * 9
        });
        let Some(p) = margin.or_else(|| (0..m).rev().find(|&k| read(k, i) < levels[k].clip)) else {
            // Clipped everywhere: the shortest image's lower bound.
            x[i] = response.linear(read(0, i)) * levels[0].inv_e;
            var[i] = 0.0;
            continue;
        };
        let x0 = response.linear(read(p, i)).max(0.0) * levels[p].inv_e;
        let (mut sw, mut sx) = (0.0f32, 0.0f32);
        for (k, l) in levels.iter().enumerate().take(p + 1) {
            let code = read(k, i);
            let mu = x0 * l.e;
            let sigma2 = l.kg * mu + l.var0;
            // Unclipped with a margin of 3σ on the prediction, and above
            // the floor (the pilot always counts).
            let room = f32::from(l.clip) - mu;
            if k != p && (mu < floor || room <= 0.0 || room * room <= 9.0 * sigma2) {
                continue;
            }
            if code >= l.clip {
                continue;
            }
            let w = l.e2 / sigma2;
            sw += w;
            sx += w * response.linear(code) * l.inv_e;
        }
        x[i] = sx / sw;
        var[i] = 1.0 / sw;
    }
    Ok(Radiance::new(
        x,
        var,
        config.noise,
        config.response.clone(),
        (order[0].setting.exposure(), order[m - 1].setting.exposure()),
    ))
}
