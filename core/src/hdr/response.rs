//! The camera's response: how a recorded value relates to the light.
//!
//! Raw sensor data (12- and 16-bit, and the simulator's frames at any
//! depth) is linear: the value is proportional to the exposure until it
//! clips. 8-bit images from a camera's image processor are often not
//! (gamma, tone curves); their response is recovered from the brackets
//! themselves by Debevec and Malik's method (SIGGRAPH 1997): with `g(z) =
//! ln f⁻¹(z)`, every sample `i` seen in image `j` at value `z_ij` gives
//! `g(z_ij) − ln X_i = ln E_j`, weighted by the hat `w(z) = min(z, 255 − z) +
//! 1` (values 0, 1, 254 and 255, black or clipped, give no equation), with
//! `g(128) = 0` and `λ·w(z)·g''(z) = 0` to keep the curve smooth; the
//! least-squares solution (an SVD) gives `g` on 0..=255.

use nalgebra::{DMatrix, DVector};

use super::Shot;
use crate::{Error, Result};

/// Values of an 8-bit response curve.
const CODES: usize = 256;
/// Bins of the forward lookup (linear value → code) over `[0, 255]`.
const FORWARD_BINS: usize = 4096;

/// How recorded values map to linear values (in DN of the same scale).
#[derive(Clone, Debug, PartialEq)]
pub enum Response {
    /// The value is proportional to the light (raw sensor data).
    Linear,
    /// An 8-bit response: the linear value of each code, ascending, with
    /// `inverse[255] = 255`, and the nearest code of each linear value.
    Curve {
        /// The linear value of each code 0..=255.
        inverse: Vec<f32>,
        /// The code nearest each of `FORWARD_BINS` linear values evenly
        /// spaced over `[0, 255]`.
        forward: Vec<u8>,
    },
}

impl Response {
    /// A curve from the linear value of each of the 256 codes (made
    /// non-decreasing and scaled to end at 255).
    pub fn from_inverse(inverse: &[f32]) -> Result<Self> {
        if inverse.len() != CODES || inverse.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(Error::invalid(
                "an 8-bit response",
                "inverse",
                "256 finite values ≥ 0",
                format_args!("{} values", inverse.len()),
            ));
        }
        let mut inv: Vec<f32> = Vec::with_capacity(CODES);
        let mut top = 0.0f32;
        for &v in inverse {
            top = top.max(v);
            inv.push(top);
        }
        if top <= 0.0 {
            return Err(Error::invalid(
                "an 8-bit response",
                "inverse",
                "a value above zero",
                "zero everywhere",
            ));
        }
        for v in &mut inv {
            *v *= 255.0 / top;
        }
        let forward = (0..FORWARD_BINS)
            .map(|b| {
                let v = b as f32 * 255.0 / (FORWARD_BINS - 1) as f32;
                // The first code at or above v, or the one before if nearer.
                let above = inv.partition_point(|&c| c < v).min(CODES - 1);
                let below = above.saturating_sub(1);
                if (v - inv[below]).abs() <= (inv[above] - v).abs() {
                    below as u8
                } else {
                    above as u8
                }
            })
            .collect();
        Ok(Self::Curve {
            inverse: inv,
            forward,
        })
    }

    /// Debevec and Malik's recovery from 8-bit images of the same scene
    /// (`shots`, each `samples` values of one byte), on about `points`
    /// samples spread over the image, with smoothness `lambda` (OpenCV's
    /// default is 10). Needs at least two exposures.
    pub fn recover(shots: &[Shot<'_>], samples: usize, points: usize, lambda: f64) -> Result<Self> {
        if shots.len() < 2 {
            return Err(Error::invalid(
                "recovering a response",
                "images",
                "two exposures or more",
                shots.len(),
            ));
        }
        if let Some(s) = shots.iter().find(|s| s.data.len() < samples) {
            return Err(Error::BufferSize {
                what: "8-bit image of a response recovery",
                expected: samples,
                actual: s.data.len(),
                detail: format!("{samples} samples of one byte"),
            });
        }
        let hat = |z: u8| f64::from(z.min(255 - z)) + 1.0;
        // Samples spread evenly, skipping those clipped or black in every
        // image (they say nothing about the curve).
        let step = (samples / points.max(1)).max(1);
        let picked: Vec<usize> = (0..samples)
            .step_by(step)
            .filter(|&i| shots.iter().any(|s| (6..250).contains(&s.data[i])))
            .collect();
        let (p, n) = (picked.len(), shots.len());
        if p < 2 {
            return Err(Error::invalid(
                "recovering a response",
                "samples",
                "at least two between black and clipped",
                p,
            ));
        }
        let rows = p * n + 1 + (CODES - 2);
        let mut a = DMatrix::<f64>::zeros(rows, CODES + p);
        let mut b = DVector::<f64>::zeros(rows);
        let mut r = 0;
        for (i, &px) in picked.iter().enumerate() {
            for s in shots {
                // A black or clipped value says only that the light is
                // below or above the range: no equation (the ends of the
                // curve follow from its smoothness).
                let z = s.data[px];
                let w = if (2..=253).contains(&z) { hat(z) } else { 0.0 };
                a[(r, usize::from(z))] = w;
                a[(r, CODES + i)] = -w;
                b[r] = w * s.setting.exposure().ln();
                r += 1;
            }
        }
        a[(r, CODES / 2)] = 1.0;
        r += 1;
        for z in 1..CODES - 1 {
            let w = lambda * hat(z as u8);
            a[(r, z - 1)] = w;
            a[(r, z)] = -2.0 * w;
            a[(r, z + 1)] = w;
            r += 1;
        }
        let x = a
            .svd(true, true)
            .solve(&b, 1e-10)
            .map_err(|e| Error::Solver {
                what: "recovering a response",
                reason: e.into(),
            })?;
        let g: Vec<f32> = (0..CODES).map(|z| x[z].exp() as f32).collect();
        Self::from_inverse(&g)
    }

    /// Whether the response is linear.
    pub fn is_linear(&self) -> bool {
        matches!(self, Self::Linear)
    }

    /// The linear value of a recorded value.
    #[inline]
    pub fn linear(&self, v: u16) -> f32 {
        match self {
            Self::Linear => f32::from(v),
            Self::Curve { inverse, .. } => inverse[usize::from(v.min(255))],
        }
    }

    /// The recorded value of a linear value in `[0, 255]` (curves only; a
    /// linear response rounds).
    #[inline]
    pub(crate) fn code(&self, v: f32) -> u16 {
        match self {
            Self::Linear => (v + 0.5) as u16,
            Self::Curve { forward, .. } => {
                let b = (v * ((FORWARD_BINS - 1) as f32 / 255.0) + 0.5) as usize;
                u16::from(forward[b.min(FORWARD_BINS - 1)])
            }
        }
    }
}
