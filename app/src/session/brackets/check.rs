//! The emulation checked on a bracket folder, leaving one bracket out:
//! every image that has a shorter and a longer one in its bracket is
//! emulated from the others and compared with itself (`rigview eval
//! check-emulation DIR`).

use std::path::Path;

use anyhow::{Context, Result};
use rigview_core::exposure::ToneCurve;
use rigview_core::hdr::{EmulateOptions, Response};

use super::emulate::{merge_decoded, noise_of};
use super::{read_image, read_manifest, BracketImage, Decoded, Emulator, MANIFEST};

/// Histogram bins of |error| (EV) for the medians.
const BIN_EV: f64 = 0.0005;
/// Bins: errors up to 8 EV (larger ones count in the last).
const BINS: usize = 16_000;

/// What to check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CheckOptions {
    /// At most this many moments, from the first (`None`: all).
    pub moments: Option<usize>,
    /// The seed of the noisy emulation.
    pub seed: u64,
}

/// The figures of one bracket level (or of all).
#[derive(Clone, Debug, PartialEq)]
pub struct LevelFigures {
    /// Its exposure level (µs at 0 dB); `None` for all levels.
    pub level: Option<f64>,
    /// Images emulated.
    pub images: usize,
    /// Samples compared (the image's, neither clipped nor in the noise
    /// floor).
    pub samples: u64,
    /// Median |log2(emulated / image)| of the noise-free emulation, EV (in
    /// light: an 8-bit curve's values linearised first).
    pub median_ev: f64,
    /// The same with the sensor's noise added.
    pub median_ev_noisy: f64,
    /// PSNR of the noise-free emulation against the image over all its
    /// samples, dB (peak: the largest value of the bit depth).
    pub psnr_db: f64,
    /// PSNR with the noise added.
    pub psnr_db_noisy: f64,
}

/// The leave-one-out figures of a folder.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckReport {
    /// Moments checked.
    pub moments: usize,
    /// Per bracket level, ascending.
    pub levels: Vec<LevelFigures>,
    /// Over every image.
    pub all: LevelFigures,
    /// Per camera (its name), the linear value (0–255) of each 8-bit code
    /// of a response recovered from its brackets; `None` for linear data.
    pub responses: Vec<(String, Option<Vec<f32>>)>,
}

impl CheckReport {
    /// The levels (µs at 0 dB) whose median |error|, noise-free or with
    /// noise, exceeds `limit_ev`. The median over every image can meet a
    /// limit that the levels with the scene's light miss: on a real 8-bit
    /// bracket whose short images sit on the black pedestal, those images
    /// are emulated to the code and outnumber the rest.
    pub fn levels_over(&self, limit_ev: f64) -> Vec<f64> {
        self.levels
            .iter()
            .filter(|f| !(f.median_ev <= limit_ev && f.median_ev_noisy <= limit_ev))
            .filter_map(|f| f.level)
            .collect()
    }

    /// The exponent `g` of the power curve `v = 255 (z/255)^g` nearest a
    /// recovered response (`inverse`: the linear value of each code), by
    /// least squares in logarithms over codes 32 to 224 (2.2 for a display
    /// gamma, 1 for linear data); `None` without such codes above zero.
    pub fn power_of(inverse: &[f32]) -> Option<f64> {
        if inverse.len() != 256 {
            return None;
        }
        ToneCurve::from_code_values(inverse).ok()?.nearest_power()
    }

    /// Whether the goal holds: the median |error| at most `limit_ev` over
    /// every image and at every level, noise-free and with noise.
    pub fn meets(&self, limit_ev: f64) -> bool {
        self.all.median_ev <= limit_ev
            && self.all.median_ev_noisy <= limit_ev
            && self.levels_over(limit_ev).is_empty()
    }
}

/// Sums for one level's figures.
#[derive(Clone, Debug)]
struct Tally {
    images: usize,
    hist: Vec<u64>,
    hist_noisy: Vec<u64>,
    se: f64,
    se_noisy: f64,
    all_samples: f64,
    peak: f64,
}

impl Tally {
    fn new() -> Self {
        Self {
            images: 0,
            hist: vec![0; BINS],
            hist_noisy: vec![0; BINS],
            se: 0.0,
            se_noisy: 0.0,
            all_samples: 0.0,
            peak: 0.0,
        }
    }

    fn add(&mut self, other: &Tally) {
        self.images += other.images;
        for (a, b) in self.hist.iter_mut().zip(&other.hist) {
            *a += b;
        }
        for (a, b) in self.hist_noisy.iter_mut().zip(&other.hist_noisy) {
            *a += b;
        }
        self.se += other.se;
        self.se_noisy += other.se_noisy;
        self.all_samples += other.all_samples;
        self.peak = self.peak.max(other.peak);
    }

    fn figures(&self, level: Option<f64>) -> LevelFigures {
        let median = |h: &[u64]| {
            let n: u64 = h.iter().sum();
            let mut seen = 0;
            for (k, c) in h.iter().enumerate() {
                seen += c;
                if n > 0 && 2 * seen >= n {
                    return (k as f64 + 0.5) * BIN_EV;
                }
            }
            f64::NAN
        };
        let psnr =
            |se: f64| 10.0 * (self.peak.powi(2) / (se / self.all_samples).max(1e-12)).log10();
        LevelFigures {
            level,
            images: self.images,
            samples: self.hist.iter().sum(),
            median_ev: median(&self.hist),
            median_ev_noisy: median(&self.hist_noisy),
            psnr_db: psnr(self.se),
            psnr_db_noisy: psnr(self.se_noisy),
        }
    }
}

/// Sample values of a decoded image.
fn values(d: &Decoded) -> Vec<f64> {
    if d.format.bytes_per_pixel() == 2 {
        d.data
            .chunks_exact(2)
            .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
            .collect()
    } else {
        d.data.iter().map(|&v| f64::from(v)).collect()
    }
}

/// The camera names of `dir`'s manifest, in their order of appearance.
fn manifest_cameras(dir: &Path) -> Result<Vec<String>> {
    let path = dir.join(MANIFEST);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let mut names: Vec<String> = Vec::new();
    for line in text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .skip(1)
    {
        let name = line.split(',').next().unwrap_or_default().trim();
        if !names.iter().any(|n| n == name) {
            names.push(name.to_owned());
        }
    }
    Ok(names)
}

/// Leave-one-out on the bracket folder `dir` (see the module
/// documentation). Samples compared: those of the image left out that are
/// neither clipped (97 % of the top) nor in the noise floor (the merge's).
pub fn check_emulation(dir: &Path, options: &CheckOptions) -> Result<CheckReport> {
    let names = manifest_cameras(dir)?;
    let manifest = read_manifest(dir, &names)?;
    let emulator = Emulator::new(&manifest, options.seed)?;
    let moments = options
        .moments
        .unwrap_or(usize::MAX)
        .min(manifest.moments.len());
    let mut levels: Vec<(f64, Tally)> = Vec::new();
    for (n, moment) in manifest.moments.iter().take(moments).enumerate() {
        for (cam, images) in moment.cameras.iter().enumerate() {
            if images.len() < 3 {
                continue;
            }
            let decoded: Vec<Decoded> = images
                .iter()
                .map(|i| read_image(&manifest, i))
                .collect::<Result<_>>()?;
            let noise = noise_of(emulator.sensor(), decoded[0].format)?;
            for j in 1..images.len() - 1 {
                let (rest, rest_decoded): (Vec<&BracketImage>, Vec<Decoded>) = images
                    .iter()
                    .zip(&decoded)
                    .enumerate()
                    .filter(|(k, _)| *k != j)
                    .map(|(_, (i, d))| (i, d.clone()))
                    .unzip();
                let radiance = merge_decoded(
                    &manifest,
                    &rest,
                    &rest_decoded,
                    emulator.response(cam),
                    emulator.sensor(),
                )?;
                let setting = images[j].setting;
                let truth = values(&decoded[j]);
                let mut out = vec![0u8; decoded[j].data.len()];
                let mut tally = Tally::new();
                tally.images = 1;
                tally.peak = noise.max_dn;
                tally.all_samples = truth.len() as f64;
                let (_, _, _, top) = noise.at_gain(setting.gain_db);
                let clip = 0.97
                    * if emulator.response(cam).is_linear() {
                        top
                    } else {
                        255.0
                    };
                let floor = (2.0 * noise.k * noise.read_noise_e).max(2.0);
                for noisy in [false, true] {
                    let o = EmulateOptions {
                        noise: noisy,
                        seed: options.seed,
                        camera: cam,
                        frame: n as u64,
                    };
                    radiance.emulate(&setting, &o, &mut out)?;
                    let emulated = values(&Decoded {
                        data: std::mem::take(&mut out),
                        ..decoded[j].clone()
                    });
                    let (hist, se) = if noisy {
                        (&mut tally.hist_noisy, &mut tally.se_noisy)
                    } else {
                        (&mut tally.hist, &mut tally.se)
                    };
                    let response = emulator.response(cam);
                    // In stops of light: through the response's linear
                    // values (the identity for linear data).
                    let light = |v: f64| f64::from(response.linear(v as u16)).max(0.5);
                    for (&e, &t) in emulated.iter().zip(&truth) {
                        *se += (e - t).powi(2);
                        if t >= floor && t < clip {
                            let err = (light(e) / light(t)).log2().abs();
                            hist[((err / BIN_EV) as usize).min(BINS - 1)] += 1;
                        }
                    }
                    out = vec![0u8; decoded[j].data.len()];
                }
                let level = setting.exposure();
                match levels
                    .iter_mut()
                    .find(|(l, _)| (l / level).log2().abs() < 0.01)
                {
                    Some((_, t)) => t.add(&tally),
                    None => levels.push((level, tally)),
                }
            }
        }
    }
    if levels.is_empty() {
        anyhow::bail!(
            "{}: no bracket of three images or more to leave one out of",
            manifest.path.display()
        );
    }
    levels.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut all = Tally::new();
    for (_, t) in &levels {
        all.add(t);
    }
    let responses = names
        .iter()
        .enumerate()
        .map(|(cam, name)| {
            let curve = match emulator.response(cam) {
                Response::Curve { inverse, .. } => Some(inverse.clone()),
                Response::Linear => None,
            };
            (name.clone(), curve)
        })
        .collect();
    Ok(CheckReport {
        moments,
        levels: levels.iter().map(|(l, t)| t.figures(Some(*l))).collect(),
        all: all.figures(None),
        responses,
    })
}
