//! The least-squares polynomial through the anchors' scores, and its
//! maximum.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::AnchorScore;
use crate::error::{Error, Result};

/// The variable a [`Polynomial`] is fitted in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FitVariable {
    /// The anchor value `x` itself (the paper's fit in γ).
    #[default]
    Linear,
    /// `ln x` (for positive anchors).
    Log,
}

impl FitVariable {
    fn forward(self, x: f64) -> f64 {
        match self {
            Self::Linear => x,
            Self::Log => x.ln(),
        }
    }

    fn inverse(self, u: f64) -> f64 {
        match self {
            Self::Linear => u,
            Self::Log => u.exp(),
        }
    }
}

/// A polynomial in the normalised variable `t = (u − centre) / half_width`,
/// where `u` is the anchor value `x` or `ln x` ([`Polynomial::variable`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Polynomial {
    /// Coefficients of `t^0, t^1, …`.
    pub coefficients: Vec<f64>,
    /// Centre of the fitted range, in `u`.
    pub centre: f64,
    /// Half the width of the fitted range, in `u`.
    pub half_width: f64,
    /// What `u` is.
    #[serde(default)]
    pub variable: FitVariable,
}

impl Polynomial {
    fn eval_t(&self, t: f64) -> f64 {
        self.coefficients
            .iter()
            .rev()
            .fold(0.0, |acc, &c| acc * t + c)
    }

    fn derivative_t(&self, t: f64) -> f64 {
        self.coefficients
            .iter()
            .enumerate()
            .skip(1)
            .rev()
            .fold(0.0, |acc, (i, &c)| acc * t + i as f64 * c)
    }

    /// The polynomial at the anchor value `x`.
    pub fn eval(&self, x: f64) -> f64 {
        self.eval_t((self.variable.forward(x) - self.centre) / self.half_width)
    }

    /// The lower and upper end of the fitted range, as anchor values.
    pub fn range(&self) -> (f64, f64) {
        (
            self.variable.inverse(self.centre - self.half_width),
            self.variable.inverse(self.centre + self.half_width),
        )
    }

    /// Where the polynomial is largest on its range (as an anchor value):
    /// the ends and every interior critical point are compared.
    pub fn argmax(&self) -> f64 {
        self.argmax_within(0.0)
    }

    /// The polynomial's local maxima on its range, `[t, p(t)]` in the
    /// normalised variable: every interior maximum, and each end the
    /// polynomial rises towards.
    fn maxima(&self) -> Vec<[f64; 2]> {
        const SAMPLES: usize = 256;
        let mut out = Vec::new();
        if self.derivative_t(-1.0) <= 0.0 {
            out.push([-1.0, self.eval_t(-1.0)]);
        }
        let mut prev_t = -1.0;
        let mut prev_d = self.derivative_t(prev_t);
        for i in 1..=SAMPLES {
            let t = -1.0 + 2.0 * i as f64 / SAMPLES as f64;
            let d = self.derivative_t(t);
            // A sign change from + to − brackets a maximum.
            if prev_d > 0.0 && d <= 0.0 {
                let (mut lo, mut hi) = (prev_t, t);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if self.derivative_t(mid) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let m = 0.5 * (lo + hi);
                out.push([m, self.eval_t(m)]);
            }
            prev_t = t;
            prev_d = d;
        }
        if self.derivative_t(1.0) >= 0.0 {
            out.push([1.0, self.eval_t(1.0)]);
        }
        if out.is_empty() {
            // A constant: every point is a maximum; the middle stands for
            // them.
            out.push([0.0, self.eval_t(0.0)]);
        }
        out
    }

    /// The maximiser where the fit cannot tell its highest maxima apart (as
    /// an anchor value, which must be positive when `tolerance > 0`). Each
    /// local maximum within `tolerance` of the highest in value is weighted
    /// by how close it comes (1 at the top, 0 at `tolerance` below), and the
    /// maximiser is their weighted mean in `ln x`. `tolerance = 0` gives the
    /// plain maximiser.
    ///
    /// As the heights of two humps cross, the plain maximiser jumps from
    /// one to the other; here the maximiser moves between them continuously
    /// while their heights are within `tolerance`. Both kinds of hump need
    /// it:
    /// - two humps closer than the anchors' spacing are one plateau the fit
    ///   wiggles over, and the jump made a balanced camera circle;
    /// - two humps far apart are distinct optima with a valley between them
    ///   (one near the current exposure, one at the end of the anchors),
    ///   and where balancing holds a camera past the exposure at which the
    ///   far one overtakes the near one, a jump of the estimate is a jump
    ///   of its own law's request that no damping of the loop settles: the
    ///   camera climbed to the jump and fell back, a saw-tooth
    ///   (`docs/exposure-results.md`). Outside the band the highest is
    ///   taken alone, so a camera settles on one of them, not in the
    ///   valley.
    pub fn argmax_within(&self, tolerance: f64) -> f64 {
        self.blend(&self.maxima(), tolerance)
    }

    /// As [`Self::argmax_within`], with a local maximum in either end
    /// interval (between the two lowest or the two highest anchors) no
    /// higher than `tolerance` above the larger score of those two anchors.
    /// Where it lies, the fit says; whether it beats the other humps, its
    /// anchors do.
    ///
    /// A least-squares polynomial overshoots at the ends of its range,
    /// where one side holds no anchor: on a real frame a quarter saturated
    /// it put a hump between the two darkest anchors 300 above both of
    /// them (2 % of M) and above the hump the anchors showed at the bright
    /// side, and the estimate jumped by 0.9 EV while the exposure moved by
    /// 0.01 EV (`docs/exposure-results.md`). Interior maxima are not
    /// capped: a true peak between two anchors lies above both, and
    /// capping it made the γ-mapping's linear law rest 0.45 EV off after a
    /// step of light. `anchors` are those the polynomial was fitted to.
    pub fn argmax_supported(&self, anchors: &[AnchorScore], tolerance: f64) -> f64 {
        let t_of = |a: &AnchorScore| (self.variable.forward(a.x) - self.centre) / self.half_width;
        let mut points: Vec<[f64; 2]> = anchors
            .iter()
            .filter(|a| a.m.is_finite())
            .map(|a| [t_of(a), a.m])
            .filter(|p| p[0].is_finite())
            .collect();
        points.sort_by(|a, b| a[0].total_cmp(&b[0]));
        // Only the two end intervals: a least-squares polynomial overshoots
        // at the ends of its range, where one side holds no anchor.
        let n = points.len();
        let capped: Vec<[f64; 2]> = self
            .maxima()
            .into_iter()
            .map(|[t, v]| {
                let Some(above) = points.iter().position(|p| p[0] >= t - 1e-12) else {
                    return [t, v];
                };
                let below = points
                    .iter()
                    .rposition(|p| p[0] <= t + 1e-12)
                    .unwrap_or(above);
                if n < 3 || (below > 0 && above + 1 < n) {
                    return [t, v];
                }
                [
                    t,
                    v.min(points[below][1].max(points[above][1]) + tolerance.max(0.0)),
                ]
            })
            .collect();
        self.blend(&capped, tolerance)
    }

    /// The maximiser among `maxima` (`[t, height]`), those within
    /// `tolerance` of the highest blended ([`Self::argmax_within`]).
    fn blend(&self, maxima: &[[f64; 2]], tolerance: f64) -> f64 {
        let at = |t: f64| self.variable.inverse(self.centre + t * self.half_width);
        let top =
            maxima.iter().copied().fold(
                [0.0, f64::MIN],
                |best, m| if m[1] > best[1] { m } else { best },
            );
        let top_x = at(top[0]);
        if !(tolerance > 0.0 && top_x > 0.0) {
            return top_x;
        }
        let (sum, weight) =
            maxima
                .iter()
                .map(|m| (at(m[0]).ln(), m[1]))
                .fold((0.0, 0.0), |(s, w), (l, v)| {
                    let k = (1.0 - (top[1] - v) / tolerance).max(0.0);
                    (s + k * l, w + k)
                });
        (sum / weight).exp()
    }

    /// `n ≥ 2` samples `[x, p(x)]` over the range, evenly spaced in `x`, for
    /// plots.
    pub fn sample(&self, n: usize) -> Vec<[f64; 2]> {
        let n = n.max(2);
        let (lo, hi) = self.range();
        (0..n)
            .map(|i| {
                let x = lo + (hi - lo) * i as f64 / (n - 1) as f64;
                [x, self.eval(x)]
            })
            .collect()
    }
}

/// Least-squares polynomial of order `degree` through the anchor scores, in
/// the anchor value itself ([`FitVariable::Linear`]).
pub fn fit(anchors: &[AnchorScore], degree: usize) -> Result<Polynomial> {
    fit_in(anchors, degree, FitVariable::Linear)
}

/// Least-squares polynomial of order `degree` through the anchor scores, in
/// `variable` (for [`FitVariable::Log`] every anchor must be positive).
pub fn fit_in(anchors: &[AnchorScore], degree: usize, variable: FitVariable) -> Result<Polynomial> {
    if let Some(bad) = anchors
        .iter()
        .find(|a| variable == FitVariable::Log && (a.x <= 0.0 || a.x.is_nan()))
    {
        return Err(Error::InvalidParameter {
            name: "anchor",
            value: bad.x,
            expected: "a positive anchor value for a fit in ln x",
        });
    }
    let u = |a: &AnchorScore| variable.forward(a.x);
    let lo = anchors.iter().map(u).fold(f64::MAX, f64::min);
    let hi = anchors.iter().map(u).fold(f64::MIN, f64::max);
    if anchors.len() < degree + 1 || hi - lo <= 0.0 {
        return Err(Error::invalid(
            "polynomial fit",
            "anchors",
            format!("at least {} spanning a range", degree + 1),
            format_args!("{} spanning [{lo}, {hi}]", anchors.len()),
        ));
    }
    if let Some(bad) = anchors.iter().find(|a| !a.m.is_finite()) {
        return Err(Error::InvalidParameter {
            name: "anchor score",
            value: bad.m,
            expected: "a finite metric value",
        });
    }
    let centre = 0.5 * (lo + hi);
    let half_width = 0.5 * (hi - lo);
    let scale = anchors
        .iter()
        .map(|a| a.m.abs())
        .fold(0.0, f64::max)
        .max(1e-300);
    let v = DMatrix::from_fn(anchors.len(), degree + 1, |r, c| {
        ((u(&anchors[r]) - centre) / half_width).powi(c as i32)
    });
    let y = DVector::from_iterator(anchors.len(), anchors.iter().map(|a| a.m / scale));
    // The normal equations (a Cholesky factorisation of VᵀV, a few times
    // cheaper than an SVD of V): with `t` in [−1, 1] and at most order 9
    // they are well conditioned; an SVD takes over if they are not positive
    // definite (anchors that cannot determine the order).
    let vt = v.transpose();
    let coefficients = match (&vt * &v).cholesky() {
        Some(normal) => normal.solve(&(&vt * &y)),
        None => v
            .svd(true, true)
            .solve(&y, 1e-12)
            .map_err(|e| Error::Solver {
                what: "polynomial fit",
                reason: e.into(),
            })?,
    };
    Ok(Polynomial {
        coefficients: coefficients.iter().map(|c| c * scale).collect(),
        centre,
        half_width,
        variable,
    })
}
