//! The brightness step a viewer sees across the seams of a surround view.
//!
//! A seam is where the canvas passes from one camera to its neighbour (the
//! hard seams of [`BlendMode::Seams`]; the other modes blend across the
//! same line). Near it both cameras see the same ground, so the difference
//! of their log intensities there is the brightness step the view shows,
//! whatever the texture: [`SeamBands::steps`] gives, per seam, the median
//! of `|log2(g_i·I_i) − log2(g_j·I_j)|` over the overlap pixels within a
//! band of the seam, each camera sampled at its nearest source pixel and
//! scaled by its display gain `g`. Pixels that either camera shows clipped
//! (black or white after the gain) say nothing and are left out.

use super::{BlendMode, Mosaic};
use crate::error::{Error, Result};
use crate::exposure::metering::SATURATED_LEVEL;
use crate::exposure::FrameView;

/// Intensities below this (of 1) are too dark to compare.
const DARK_LEVEL: f32 = 0.02;

/// The pixels near one seam, as both cameras see them.
#[derive(Clone, Debug, PartialEq)]
struct SeamBand {
    i: usize,
    j: usize,
    /// Source pixel indices (row-major) in camera `i` and in camera `j`.
    pixels: Vec<(u32, u32)>,
}

/// The brightness step across one seam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamStep {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// The median `|log2|` step, EV (`None`: no pixel both cameras show
    /// unclipped).
    pub step_ev: Option<f64>,
    /// The pixels compared.
    pub samples: usize,
}

/// The bands of every seam of a view, built once per view.
#[derive(Clone, Debug, PartialEq)]
pub struct SeamBands {
    bands: Vec<SeamBand>,
    cameras: usize,
}

impl SeamBands {
    /// The bands within `band` canvas pixels of each seam of `view`
    /// (overlap pixels only: both cameras must see them).
    pub fn new(view: &Mosaic, band: usize) -> Self {
        let (w, h) = view.size();
        let layers = view.layers();
        // Per canvas pixel, the camera the hard seams show, and each
        // camera's nearest source pixel.
        let mut owner = vec![u8::MAX; w * h];
        let mut source: Vec<Vec<u32>> = vec![vec![u32::MAX; w * h]; layers.len()];
        let seams = BlendMode::Seams.index();
        for (k, layer) in layers.iter().enumerate() {
            let [x0, y0, lw, lh] = layer.roi;
            let (sw, sh) = layer.source;
            for ry in 0..lh {
                for rx in 0..lw {
                    let r = ry * lw + rx;
                    let [sx, sy] = layer.map[r];
                    if sx < 0.0 || sy < 0.0 {
                        continue;
                    }
                    let (px, py) = (sx.round() as usize, sy.round() as usize);
                    if px >= sw || py >= sh {
                        continue;
                    }
                    let c = (y0 + ry) * w + x0 + rx;
                    source[k][c] = (py * sw + px) as u32;
                    if layer.weights[seams][r] > 0 {
                        owner[c] = k as u8;
                    }
                }
            }
        }
        let mut bands = Vec::new();
        for o in view.overlaps() {
            let (a, b) = (o.i as u8, o.j as u8);
            let mut near = vec![false; w * h];
            for y in 0..h {
                for x in 0..w {
                    let p = owner[y * w + x];
                    if p != a && p != b {
                        continue;
                    }
                    let other = if p == a { b } else { a };
                    let on_seam = (x + 1 < w && owner[y * w + x + 1] == other)
                        || (y + 1 < h && owner[(y + 1) * w + x] == other);
                    if !on_seam {
                        continue;
                    }
                    for ny in y.saturating_sub(band)..(y + band + 1).min(h) {
                        for nx in x.saturating_sub(band)..(x + band + 1).min(w) {
                            near[ny * w + nx] = true;
                        }
                    }
                }
            }
            let pixels = near
                .iter()
                .enumerate()
                .filter(|(_, n)| **n)
                .map(|(c, _)| (source[o.i][c], source[o.j][c]))
                .filter(|(si, sj)| *si != u32::MAX && *sj != u32::MAX)
                .collect();
            bands.push(SeamBand {
                i: o.i,
                j: o.j,
                pixels,
            });
        }
        Self {
            bands,
            cameras: layers.len(),
        }
    }

    /// The pixels compared across each seam, in overlap order.
    pub fn sizes(&self) -> Vec<usize> {
        self.bands.iter().map(|b| b.pixels.len()).collect()
    }

    /// The step across each seam (in the view's overlap order) of `frames`
    /// shown with display `gains` (`None`: 1 for every camera).
    pub fn steps(&self, frames: &[FrameView<'_>], gains: Option<&[f32]>) -> Result<Vec<SeamStep>> {
        Ok(self
            .differences(frames, gains, usize::MAX)?
            .into_iter()
            .zip(&self.bands)
            .map(|(d, b)| {
                let mut d: Vec<f64> = d.iter().map(|v| v.abs()).collect();
                d.sort_by(f64::total_cmp);
                SeamStep {
                    i: b.i,
                    j: b.j,
                    step_ev: (!d.is_empty()).then(|| d[d.len() / 2]),
                    samples: d.len(),
                }
            })
            .collect())
    }

    /// Per seam (in the view's overlap order) `(i, j, log2 r_ij)`: the
    /// median of `log2(I_j / I_i)` over the pixels both cameras show
    /// unclipped near the seam, how much brighter `j` shows the ground
    /// there than `i` (`None`: no such pixel). This is the ratio the view
    /// shows, where the overlap patches' `r_ij` is the ratio over the
    /// whole overlap: with lens fall-off and parallax the two differ.
    ///
    /// At most `samples` pixels of each band are read, evenly spread (a
    /// median needs far fewer than the thousands a band has).
    pub fn ratios(
        &self,
        frames: &[FrameView<'_>],
        samples: usize,
    ) -> Result<Vec<(usize, usize, Option<f64>)>> {
        Ok(self
            .differences(frames, None, samples)?
            .into_iter()
            .zip(&self.bands)
            .map(|(mut d, b)| {
                d.sort_by(f64::total_cmp);
                let n = d.len();
                (b.i, b.j, (n > 0).then(|| 0.5 * (d[(n - 1) / 2] + d[n / 2])))
            })
            .collect())
    }

    /// Per seam, `log2(g_j·I_j / g_i·I_i)` at each pixel both cameras show
    /// unclipped, of at most `samples` pixels evenly spread over the band.
    fn differences(
        &self,
        frames: &[FrameView<'_>],
        gains: Option<&[f32]>,
        samples: usize,
    ) -> Result<Vec<Vec<f64>>> {
        if frames.len() != self.cameras || gains.is_some_and(|g| g.len() != self.cameras) {
            return Err(Error::invalid(
                "seam steps",
                "frames and gains",
                format!("one each for {} cameras", self.cameras),
                format_args!(
                    "{} frames and {} gains",
                    frames.len(),
                    gains.map_or(self.cameras, <[f32]>::len)
                ),
            ));
        }
        let gain = |k: usize| gains.map_or(1.0, |g| g[k]);
        let shown = |k: usize, p: u32| -> Option<f32> {
            let f = &frames[k];
            let p = p as usize;
            let (x, y) = (p % f.width(), p / f.width());
            if y >= f.height() {
                return None;
            }
            let v = f.luma_at(x, y);
            let g = v * gain(k);
            (v < SATURATED_LEVEL && g < SATURATED_LEVEL && g > DARK_LEVEL).then_some(g)
        };
        Ok(self
            .bands
            .iter()
            .map(|b| {
                let stride = b.pixels.len().div_ceil(samples.max(1)).max(1);
                b.pixels
                    .iter()
                    .step_by(stride)
                    .filter_map(|&(pi, pj)| {
                        let (vi, vj) = (shown(b.i, pi)?, shown(b.j, pj)?);
                        Some(f64::from(vj / vi).log2())
                    })
                    .collect()
            })
            .collect())
    }
}
