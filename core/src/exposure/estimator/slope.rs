//! The slope `dγ̂/d ln E`: a second estimate on the image scaled towards
//! the fixed point.

use super::*;

/// `image` with every intensity mapped by `f` (same size and weights).
pub(super) fn map_luma(image: &Metered, f: impl Fn(f32) -> f32) -> Result<Metered> {
    Metered::from_luma(
        image.width(),
        image.height(),
        image.luma().iter().map(|&v| f(v)).collect(),
        image.weight().map(<[f32]>::to_vec),
    )
}

/// The smallest exposure step [`Estimator::estimate_with_slope`] simulates.
pub const SLOPE_STEP: f64 = 1.3;

/// The largest exposure ratio the slope's root search simulates.
pub const SLOPE_REACH: f64 = 4.0;

/// A typical `dγ̂/d ln E` across a step of light: where the root search
/// starts.
pub const PRIOR_SLOPE: f64 = 0.6;

/// Estimates the root search takes at most.
pub const SLOPE_EVALUATIONS: usize = 2;

/// `|γ̂ − 1|` below which a scaled image counts as the root.
pub const SLOPE_ROOT_TOLERANCE: f64 = 0.01;

impl Estimator {
    /// [`Estimator::estimate_with_info`], plus the slope `dγ̂/d ln E` measured by
    /// estimating again on the image scaled by [`SLOPE_STEP`] towards the
    /// fixed point (`min(1, s·I)`: what a linear sensor delivers). The
    /// slope is left out when either estimate sits at a bound or is flat.
    pub fn estimate_with_slope(&mut self, image: &Metered) -> Result<Estimate> {
        self.estimate_with(
            image,
            EstimateOptions {
                slope: true,
                ..Default::default()
            },
        )
    }

    /// The slope of [`Estimator::estimate_with_slope`], into `estimate`:
    /// the secant from the frame to the root of `γ̂ = 1` found on the image
    /// scaled by `s` (`min(1, s·I)`, what a linear sensor delivers), so that
    /// the fast law's Newton step lands on that root. The search starts
    /// [`PRIOR_SLOPE`] away (at least [`SLOPE_STEP`], at most
    /// [`SLOPE_REACH`]) and takes up to [`SLOPE_EVALUATIONS`] estimates:
    /// interpolation where `γ̂ − 1` changes sign, extrapolation otherwise.
    /// It is measured without a darker frame (the scaled image is not the
    /// darker frame's scene at the scaled exposure), which only sets the
    /// step of the fast law, not where it stops. A simulated darkening
    /// leaves saturated regions flat, so the root of a saturated frame lies
    /// short of the true one: the law undershoots and takes another step
    /// rather than overshooting.
    pub(super) fn add_slope(&mut self, image: &Metered, estimate: &mut Estimate) -> Result<()> {
        if estimate.flat || estimate.at_bound.is_some() {
            return Ok(());
        }
        let f0 = estimate.gamma_hat - 1.0;
        if f0 == 0.0 {
            return Ok(());
        }
        let (min_ln, max_ln) = (SLOPE_STEP.ln(), SLOPE_REACH.ln());
        let dir = -f0.signum();
        let clamp = |u: f64| dir * (u * dir).clamp(min_ln, max_ln);
        // (ln s, γ̂(s) − 1) of the frame and of the scaled images.
        let mut near = (0.0, f0);
        let mut far: Option<(f64, f64)> = None;
        let mut at = clamp(dir * f0.abs() / PRIOR_SLOPE);
        let mut root = None;
        for _ in 0..SLOPE_EVALUATIONS {
            let sf = at.exp() as f32;
            let scaled = map_luma(image, |v| (v * sf).min(1.0))?;
            let other = self.estimate(&scaled)?;
            if other.flat || other.at_bound.is_some() {
                break;
            }
            let point = (at, other.gamma_hat - 1.0);
            // Keep the two points that bracket the root, or the two
            // nearest it.
            if point.1.signum() != near.1.signum() {
                far = Some(point);
            } else {
                near = point;
            }
            let (a, b) = match far {
                Some(f) => (near, f),
                None => ((0.0, f0), near),
            };
            if (b.0 - a.0).abs() < 1e-9 || (b.1 - a.1).abs() < 1e-12 {
                root = Some(point.0);
                break;
            }
            let r = a.0 - a.1 * (b.0 - a.0) / (b.1 - a.1);
            let r = if far.is_some() {
                r.clamp(a.0.min(b.0), a.0.max(b.0))
            } else if r * dir > 0.0 {
                clamp(r)
            } else {
                // γ̂ moved away from 1: no usable slope.
                break;
            };
            root = Some(r);
            if point.1.abs() < SLOPE_ROOT_TOLERANCE {
                root = Some(point.0);
                break;
            }
            at = r;
        }
        if let Some(r) = root.filter(|r| r * dir > 0.0) {
            estimate.slope = Some(-f0 / r);
        }
        Ok(())
    }
}
