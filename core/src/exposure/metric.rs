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

use super::kernel;
use crate::cpu::Isa;
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
    kernel: kernel::Params,
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
            kernel: kernel::Params::new(params.lambda as f32, params.delta as f32, SOBEL_NORM),
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
        self.score_source(kernel::Source::Plain(image), w, h, weight, scratch)
    }

    /// `M` of a simulated image, computed on the fly from its source.
    pub(crate) fn score_source(
        &self,
        source: kernel::Source<'_>,
        w: usize,
        h: usize,
        weight: Option<&[f32]>,
        scratch: &mut Scratch,
    ) -> f64 {
        kernel::sum_ln_q(
            scratch.isa,
            source,
            w,
            h,
            weight,
            self.kernel,
            &mut scratch.rows,
        ) * self.inv_n
    }

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
        let (sum, _) = kernel::information(
            scratch.isa,
            image,
            None,
            w,
            h,
            weight,
            self.kernel,
            &mut scratch.rows,
            Some(&mut *out),
        );
        let inv_n = self.inv_n as f32;
        for v in out.iter_mut() {
            *v *= inv_n;
        }
        sum * self.inv_n
    }

    /// `M` of the image as it is, and `Σ m̄·log₂ I` from `log2` (`log₂ I`
    /// per pixel; 0 without it); each pixel's `m̄` goes to `map` when given.
    /// Without a map or weights, the second sum takes `m̄` to about 2e-5
    /// absolute.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn information_with_log2(
        &self,
        image: &[f32],
        log2: Option<&[f32]>,
        w: usize,
        h: usize,
        weight: Option<&[f32]>,
        scratch: &mut Scratch,
        map: Option<&mut Vec<f32>>,
    ) -> (f64, f64) {
        if let (None, None, Some(log2)) = (&map, weight, log2) {
            let (sum, dot) = kernel::sum_ln_q_and_dot(
                scratch.isa,
                image,
                log2,
                w,
                h,
                self.kernel,
                &mut scratch.rows,
            );
            return (sum * self.inv_n, dot * self.inv_n);
        }
        let mut map = map;
        let (sum, sum_log2) = kernel::information(
            scratch.isa,
            image,
            log2,
            w,
            h,
            weight,
            self.kernel,
            &mut scratch.rows,
            map.as_deref_mut(),
        );
        if let Some(map) = map {
            let inv_n = self.inv_n as f32;
            for v in map.iter_mut() {
                *v *= inv_n;
            }
        }
        (sum * self.inv_n, sum_log2 * self.inv_n)
    }
}

/// Reusable row buffers for [`GradientMetric::score`], and the vector
/// instruction set its kernels run with.
#[derive(Clone, Debug)]
pub struct Scratch {
    rows: kernel::Rows,
    isa: Isa,
}

impl Default for Scratch {
    fn default() -> Self {
        Self::with_isa(Isa::detect())
    }
}

impl Scratch {
    /// Buffers for kernels compiled for `isa`, or for the widest set at or
    /// below it that the CPU has and the kernels have code for (they have
    /// none for BMI2 alone: that runs the baseline code).
    pub fn with_isa(isa: Isa) -> Self {
        Self {
            rows: kernel::Rows::default(),
            isa: kernel::kernel_isa(isa),
        }
    }

    /// The instruction set the kernels run with.
    pub fn isa(&self) -> Isa {
        self.isa
    }
}
