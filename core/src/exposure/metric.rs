//! The gradient-information metric of Shim et al. (Eq. 1).
//!
//! For each pixel, `m` is the 3×3 Sobel gradient magnitude of the [0, 1]
//! image divided by 4·√2 (the conventional bound of the magnitude), so
//! `m ∈ [0, 1]`. Its information is
//!
//! ```text
//! m̄ = log(λ·(m − δ) + 1) / N   if m ≥ δ,   0 otherwise,   N = log(λ·(1 − δ) + 1)
//! ```
//!
//! and the image's score is `M = Σ m̄` over the interior pixels (the one-pixel
//! border has no full neighbourhood and is left out), optionally weighted by
//! the metering weights.

use serde::{Deserialize, Serialize};

use super::fastmath;
use crate::error::{check_range, Result};

/// Divides the Sobel magnitude of a [0, 1] image into [0, 1].
pub const SOBEL_NORM: f32 = 4.0 * std::f32::consts::SQRT_2;

/// Parameters of Eq. 1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MetricParams {
    /// Activation threshold δ on the normalised magnitude (default 0.06).
    pub delta: f64,
    /// Weight λ of weak gradients (default 1000).
    pub lambda: f64,
}

impl Default for MetricParams {
    fn default() -> Self {
        Self {
            delta: 0.06,
            lambda: 1000.0,
        }
    }
}

/// Eq. 1, ready to evaluate.
#[derive(Clone, Debug)]
pub struct GradientMetric {
    params: MetricParams,
    delta: f32,
    lambda: f32,
    inv_n: f64,
}

impl GradientMetric {
    /// Checks the parameters: `0 ≤ δ < 1`, `λ > 0`, both finite.
    pub fn new(params: MetricParams) -> Result<Self> {
        check_range("delta", params.delta, 0.0, 0.999, "a number in [0, 1)")?;
        check_range(
            "lambda",
            params.lambda,
            1e-6,
            1e9,
            "a positive number (at most 1e9)",
        )?;
        let n = (params.lambda * (1.0 - params.delta)).ln_1p();
        Ok(Self {
            params,
            delta: params.delta as f32,
            lambda: params.lambda as f32,
            inv_n: 1.0 / n,
        })
    }

    /// The parameters.
    pub fn params(&self) -> MetricParams {
        self.params
    }

    /// `m̄` of one normalised gradient magnitude, in double precision (the
    /// reference the fast kernel is tested against).
    pub fn information(&self, m: f64) -> f64 {
        if m < self.params.delta {
            0.0
        } else {
            (self.params.lambda * (m - self.params.delta)).ln_1p() * self.inv_n
        }
    }

    /// `M` of a `w×h` image with values in [0, 1]; `weight`, when given,
    /// multiplies each pixel's `m̄`. `scratch` is reused between calls.
    pub fn score(
        &self,
        image: &[f32],
        w: usize,
        h: usize,
        weight: Option<&[f32]>,
        scratch: &mut Scratch,
    ) -> f64 {
        if w < 3 || h < 3 || image.len() < w * h {
            return 0.0;
        }
        scratch.sv.resize(w, 0.0);
        scratch.dv.resize(w, 0.0);
        let n = w - 2;
        let shift = self.lambda * self.delta;
        let scale = self.lambda / SOBEL_NORM;
        let mut total = 0.0f64;
        for y in 1..h - 1 {
            let a = &image[(y - 1) * w..y * w];
            let b = &image[y * w..(y + 1) * w];
            let c = &image[(y + 1) * w..(y + 2) * w];
            scratch.vertical_passes(a, b, c);
            let (sv, dv) = (&scratch.sv, &scratch.dv);
            let row_weight = weight.map(|wt| &wt[y * w + 1..y * w + 1 + n]);
            total += f64::from(row_information(
                &sv[..n],
                &sv[2..],
                &dv[..n],
                &dv[1..n + 1],
                &dv[2..],
                row_weight,
                scale,
                shift,
            ));
        }
        total * self.inv_n
    }
}

/// `log(max(λ·m − λ·δ, 0) + 1)` of one pixel from its vertical passes.
#[inline(always)]
fn info(svl: f32, svr: f32, dvl: f32, dvc: f32, dvr: f32, scale: f32, shift: f32) -> f32 {
    let gx = svr - svl;
    let gy = dvl + 2.0 * dvc + dvr;
    let t = (scale * (gx * gx + gy * gy).sqrt() - shift).max(0.0);
    fastmath::ln(1.0 + t)
}

/// Σ log(max(λ·m − λ·δ, 0) + 1) over one row, with `λ·m = scale·|∇|`.
#[allow(clippy::too_many_arguments)]
#[inline]
fn row_information(
    sv_l: &[f32],
    sv_r: &[f32],
    dv_l: &[f32],
    dv_c: &[f32],
    dv_r: &[f32],
    weight: Option<&[f32]>,
    scale: f32,
    shift: f32,
) -> f32 {
    const L: usize = 8;
    let n = sv_l.len();
    let full = n / L * L;
    let (a, _) = sv_l[..full].as_chunks::<L>();
    let (b, _) = sv_r[..full].as_chunks::<L>();
    let (c, _) = dv_l[..full].as_chunks::<L>();
    let (d, _) = dv_c[..full].as_chunks::<L>();
    let (e, _) = dv_r[..full].as_chunks::<L>();
    let mut acc = [0.0f32; L];
    let mut tail = 0.0f32;
    match weight {
        None => {
            for ((((a, b), c), d), e) in a.iter().zip(b).zip(c).zip(d).zip(e) {
                for l in 0..L {
                    acc[l] += info(a[l], b[l], c[l], d[l], e[l], scale, shift);
                }
            }
            for i in full..n {
                tail += info(sv_l[i], sv_r[i], dv_l[i], dv_c[i], dv_r[i], scale, shift);
            }
        }
        Some(wt) => {
            let (w, _) = wt[..full].as_chunks::<L>();
            for (((((a, b), c), d), e), w) in a.iter().zip(b).zip(c).zip(d).zip(e).zip(w) {
                for l in 0..L {
                    acc[l] += w[l] * info(a[l], b[l], c[l], d[l], e[l], scale, shift);
                }
            }
            for i in full..n {
                tail += wt[i] * info(sv_l[i], sv_r[i], dv_l[i], dv_c[i], dv_r[i], scale, shift);
            }
        }
    }
    acc.iter().sum::<f32>() + tail
}

impl GradientMetric {
    /// Each pixel's `m̄` (times its weight) into `out` (`w×h`, border 0);
    /// returns their sum, `M`.
    pub fn information_map(
        &self,
        image: &[f32],
        w: usize,
        h: usize,
        weight: Option<&[f32]>,
        scratch: &mut Scratch,
        out: &mut Vec<f32>,
    ) -> f64 {
        out.clear();
        out.resize(w * h, 0.0);
        if w < 3 || h < 3 || image.len() < w * h {
            return 0.0;
        }
        scratch.sv.resize(w, 0.0);
        scratch.dv.resize(w, 0.0);
        let shift = self.lambda * self.delta;
        let scale = self.lambda / SOBEL_NORM;
        let inv_n = self.inv_n as f32;
        let mut total = 0.0f64;
        for y in 1..h - 1 {
            let a = &image[(y - 1) * w..y * w];
            let b = &image[y * w..(y + 1) * w];
            let c = &image[(y + 1) * w..(y + 2) * w];
            scratch.vertical_passes(a, b, c);
            let (sv, dv) = (&scratch.sv, &scratch.dv);
            let row = &mut out[y * w + 1..y * w + w - 1];
            let mut row_sum = 0.0f32;
            for (x, o) in row.iter_mut().enumerate() {
                let wt = weight.map_or(1.0, |wt| wt[y * w + 1 + x]);
                let v =
                    wt * info(sv[x], sv[x + 2], dv[x], dv[x + 1], dv[x + 2], scale, shift) * inv_n;
                *o = v;
                row_sum += v;
            }
            total += f64::from(row_sum);
        }
        total
    }
}

/// Reusable row buffers for [`GradientMetric::score`].
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    sv: Vec<f32>,
    dv: Vec<f32>,
}

impl Scratch {
    /// The vertical Sobel passes over rows `a`, `b`, `c`: smoothing for ∂x,
    /// difference for ∂y.
    #[inline]
    fn vertical_passes(&mut self, a: &[f32], b: &[f32], c: &[f32]) {
        for (((sv, dv), (&a, &b)), &c) in self
            .sv
            .iter_mut()
            .zip(self.dv.iter_mut())
            .zip(a.iter().zip(b))
            .zip(c)
        {
            *sv = a + 2.0 * b + c;
            *dv = c - a;
        }
    }
}
