//! Update laws: how far to move the exposure, given an estimate.
//!
//! - [`LawKind::Linear`], Eq. 3: `E' = (1 + α·Kp·(1 − γ̂))·E`.
//! - [`LawKind::Nonlinear`], Eq. 4: `E' = (1 + α·Kp·(R − 1))·E` with
//!   `R = d·tan((2 − γ̂)·atan(1/d) − atan(1/d)) + 1`.
//! - [`LawKind::Fast`], rigview's own: it predicts the exposure ratio that
//!   reaches the estimator's fixed point and jumps (most of) the way there in
//!   one frame:
//!   - scale-and-clip: `ŝ` *is* the ratio of a linear sensor;
//!   - γ-mapping: a Newton step on `γ̂` as a function of log exposure,
//!     `Δ ln E = −(γ̂ − 1) / k`. The slope `k` is a secant from the frame
//!     to the root of `γ̂ = 1` searched on the image itself, scaled by
//!     simulated exposure ratios (`min(1, s·I)`, what a linear sensor
//!     would deliver; up to two more estimates, starting where a typical
//!     slope puts the root), so that the step lands on that root
//!     ([`Estimate::slope`]). Without a usable slope (an estimate at a
//!     bound, or a slope that is not positive) the image statistics predict
//!     the ratio instead: a pixel of intensity `μ` mapped by `γ̂` becomes
//!     `μ^γ̂`, which a linear sensor reaches with the ratio `μ^(γ̂−1)`; `μ`
//!     is the intensity where the image's gradient information lies
//!     ([`Estimate::info_intensity`], clamped to [0.02, 0.95]; the mean
//!     intensity for an estimate made without it);
//!   - when the maximiser sits at an end of the anchors' span the best
//!     exposure lies beyond it: scale-and-clip's `ŝ` at its upper end is
//!     squared (extrapolated one span further); the γ prediction is replaced, if that is larger, by
//!     the step of one anchor span (`1/γ̂`) or the step that brings the mean
//!     intensity to 0.45, whichever is larger in the same direction (this
//!     gets a strongly over-exposed image back quickly);
//!   - the ratio is damped in the log domain, `E' = E·ratio^β` (β = 0.8 by
//!     default), which absorbs estimation noise without a visible overshoot.
//!
//! In all laws `α = 1/2` when `γ̂ ≥ 1` and `α = 1` when `γ̂ < 1`, and every
//! law bounds the change per frame to `[1/max_step, max_step]`. Under
//! scale-and-clip, while `ŝ` puts the fixed point [`AHEAD_MIN_EV`] or more
//! away, the linear and nonlinear laws go on from where the commands in
//! flight will leave the camera ([`LawStep::Ahead`]), as the fast law does;
//! nearer, their step is the frame's own, but commands in flight that
//! already go further that way stand ([`LawStep::Standing`]). Under a
//! camera's own law, where two frames of one scene do not ask towards each
//! other (each stays on its side of their midpoint), the controller
//! follows the one with more gradient information
//! ([`super::bracket::Repeller`]): with a frame of latency, even and odd
//! frames would otherwise keep two chains of commands apart.

use serde::{Deserialize, Serialize};

use super::estimator::{Bound, Estimate, Simulation};
use super::metering::ImageStats;
use crate::error::{check_range, Result};

/// Which update law.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum LawKind {
    /// Eq. 3.
    Linear,
    /// Eq. 4 (the paper's best), the default.
    #[default]
    Nonlinear,
    /// rigview's ratio-predicting law (see the module documentation): the
    /// fastest under changing light in lock step, but it rings at start-up
    /// in the app's threads (`docs/exposure-results.md`).
    Fast,
}

impl LawKind {
    /// The name used in settings and telemetry.
    pub fn name(self) -> &'static str {
        match self {
            Self::Linear => "linear",
            Self::Nonlinear => "nonlinear",
            Self::Fast => "fast",
        }
    }
}

/// Parameters of the update laws.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LawParams {
    /// The law.
    pub kind: LawKind,
    /// Speed `Kp` of Eq. 3 and 4.
    pub kp: f64,
    /// Curvature `d` of Eq. 4.
    pub d: f64,
    /// Damping β of the fast law, in (0, 1].
    pub damping: f64,
    /// Largest change per frame, as a ratio (> 1).
    pub max_step: f64,
}

impl Default for LawParams {
    fn default() -> Self {
        Self {
            kind: LawKind::default(),
            kp: 1.0,
            d: 0.8,
            damping: 0.8,
            max_step: 4.0,
        }
    }
}

impl LawParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range("kp", self.kp, 1e-6, 20.0, "a positive number up to 20")?;
        check_range("d", self.d, 1e-3, 1e3, "a number in [0.001, 1000]")?;
        check_range("damping", self.damping, 1e-3, 1.0, "a number in (0, 1]")?;
        check_range(
            "max_step",
            self.max_step,
            1.01,
            1e3,
            "a ratio in [1.01, 1000]",
        )?;
        Ok(())
    }

    /// Clamps a ratio to `[1/max_step, max_step]`.
    pub fn bound(&self, ratio: f64) -> f64 {
        if ratio.is_nan() {
            return 1.0;
        }
        ratio.clamp(1.0 / self.max_step, self.max_step)
    }

    /// The exposure ratio `E_{t+1} / E_t` this law asks for, from the
    /// frame alone (no commands in flight).
    pub fn ratio(&self, estimate: &Estimate, stats: &ImageStats) -> f64 {
        let g = estimate.gamma_hat;
        let raw = match self.kind {
            LawKind::Linear => linear_ratio(self.kp, g),
            LawKind::Nonlinear => nonlinear_ratio(self.kp, self.d, g),
            LawKind::Fast => fast_ratio(self.damping, estimate, stats),
        };
        self.bound(raw)
    }

    /// What this law asks for, as a [`LawStep`]: the fast law's estimate
    /// inside the anchors' span predicts the best exposure; everything else
    /// is a step from the frame.
    pub fn step(&self, estimate: &Estimate, stats: &ImageStats) -> LawStep {
        match self.kind {
            LawKind::Fast if estimate.at_bound.is_none() => LawStep::Predicted {
                ratio: fast_prediction(estimate, stats),
            },
            // At an end of the span the best exposure lies beyond what the
            // estimate sees: the whole step, undamped.
            LawKind::Fast => LawStep::AtLeast(self.bound(fast_ratio(1.0, estimate, stats))),
            // Scale-and-clip's ŝ is the ratio to the estimator's fixed
            // point, which lets the law be applied again from where the
            // commands in flight will leave the camera, while that is far.
            LawKind::Linear | LawKind::Nonlinear
                if estimate.simulation == Simulation::ScaleClip
                    && !estimate.flat
                    && estimate.x_hat > 0.0
                    && estimate.x_hat.log2().abs() >= AHEAD_MIN_EV =>
            {
                LawStep::Ahead {
                    ratio: self.ratio(estimate, stats),
                    best: estimate.x_hat,
                    beyond: false,
                }
            }
            // Nearer, scale-and-clip's step is the frame's own, but the
            // commands in flight that already go further that way stand: a
            // frame that predates them would undo them (with two frames of
            // latency, the nonlinear law rang between two exposures).
            LawKind::Linear | LawKind::Nonlinear
                if estimate.simulation == Simulation::ScaleClip && !estimate.flat =>
            {
                LawStep::Standing(self.ratio(estimate, stats))
            }
            LawKind::Linear | LawKind::Nonlinear => LawStep::Relative(self.ratio(estimate, stats)),
        }
    }

    /// Eq. 3 or Eq. 4 at `gamma_hat`, bounded (the fast law: 1).
    fn paper_ratio(&self, gamma_hat: f64) -> f64 {
        self.bound(match self.kind {
            LawKind::Linear => linear_ratio(self.kp, gamma_hat),
            LawKind::Nonlinear => nonlinear_ratio(self.kp, self.d, gamma_hat),
            LawKind::Fast => 1.0,
        })
    }

    /// The exposure to command next, for a frame taken at `taken` and
    /// commands in flight that will leave the camera at `base` (`taken`
    /// when there are none). This is the controller's predictor: the frame
    /// is evaluated where it was taken, and the commands in flight are
    /// accounted for instead of waited for.
    ///
    /// - [`LawStep::Relative`]: `taken · ratio`. A step computed on the
    ///   frame is anchored to the frame, so a frame taken before the
    ///   previous command showed asks for the same exposure again, never
    ///   for the step on top of it.
    /// - [`LawStep::AtLeast`] and [`LawStep::Standing`]: as `Relative`,
    ///   except that commands in flight that already go further that way
    ///   stand.
    /// - [`LawStep::Ahead`]: as `Relative` with nothing in flight. With
    ///   commands in flight, the law is applied where they leave the
    ///   camera, to the estimate as seen from there: the fixed point at
    ///   `best · taken / base` of `base`, so `base` times the law's ratio
    ///   at `γ̂ = base / (best · taken)`; when the commands in flight reach
    ///   the fixed point already (or go past it), they stand. Without
    ///   this, a camera whose commands take two frames to show steps only
    ///   every other frame: the frame before a command shows asks for the
    ///   same exposure again.
    /// - [`LawStep::Predicted`]: the best exposure is `taken · ratio`; the
    ///   command moves `damping` of the way there from `base`, in log
    ///   exposure (times [`FAST_SMALL_DAMPING`] between [`FAST_SMALL_MIN_EV`]
    ///   and [`FAST_SMALL_EV`]
    ///   when `damp_small`: a camera under its own law; balancing damps
    ///   its own moves), bounded to `max_step` per command, and stays at
    ///   `base` when that is within [`FAST_REST_EV`].
    pub fn next_exposure(&self, step: LawStep, taken: f64, base: f64, damp_small: bool) -> f64 {
        match step {
            LawStep::Relative(r) => taken * r,
            LawStep::Ahead { ratio, .. } if (base / taken).ln().abs() < 1e-12 => taken * ratio,
            // The best lies beyond what the frame shows: the commands in
            // flight have not reached it yet either.
            LawStep::Ahead {
                ratio,
                beyond: true,
                ..
            } => base * ratio,
            LawStep::Ahead { ratio, best, .. } => {
                let ahead = best * taken / base;
                if ahead.ln() * ratio.ln() <= 0.0 {
                    // (A step that the commands in flight already went
                    // past: the frame's own step, as with `Relative`.)
                    if (base / (taken * ratio)).ln() * ratio.ln() >= 0.0 {
                        return base;
                    }
                    return taken * ratio;
                }
                base * self.paper_ratio(1.0 / ahead)
            }
            LawStep::AtLeast(r) | LawStep::Standing(r) => {
                let target = taken * r;
                if (base / target).ln() * r.ln() > 0.0 {
                    base
                } else {
                    target
                }
            }
            LawStep::Predicted { ratio } => {
                let best = taken * ratio;
                if (best / base).log2().abs() < FAST_REST_EV {
                    // Close enough: the estimate's own noise and plateaus
                    // would only make the camera creep.
                    return base;
                }
                // A small correction is the size of the estimate's own
                // frame-to-frame noise: go half of it.
                let damping = if damp_small
                    && (FAST_SMALL_MIN_EV..FAST_SMALL_EV).contains(&(best / base).log2().abs())
                {
                    self.damping * FAST_SMALL_DAMPING
                } else {
                    self.damping
                };
                base * self.bound((best / base).powf(damping))
            }
        }
    }
}

impl LawStep {
    /// Where the step puts the best exposure, seen from the frame: log2 of
    /// the ratio to the frame's exposure.
    pub fn frame_ev(self) -> f64 {
        match self {
            Self::Relative(r)
            | Self::AtLeast(r)
            | Self::Standing(r)
            | Self::Predicted { ratio: r }
            | Self::Ahead { ratio: r, .. } => r.log2(),
        }
    }

    /// The step anchored to the frame: [`LawStep::Ahead`] and
    /// [`LawStep::Standing`] as [`LawStep::Relative`], every other step as
    /// it is.
    pub fn anchored(self) -> Self {
        match self {
            Self::Ahead { ratio, .. } | Self::Standing(ratio) => Self::Relative(ratio),
            other => other,
        }
    }

    /// The same kind of step to `ev` (log2 of the ratio to the frame's
    /// exposure).
    pub fn with_frame_ev(self, ev: f64) -> Self {
        let r = ev.exp2();
        match self {
            // (A step the repeller moved is its own, from the frame.)
            Self::Ahead { ratio, .. } if (ratio.log2() - ev).abs() < 1e-12 => self,
            Self::Relative(_) | Self::Ahead { .. } => Self::Relative(r),
            Self::AtLeast(_) => Self::AtLeast(r),
            Self::Standing(_) => Self::Standing(r),
            Self::Predicted { .. } => Self::Predicted { ratio: r },
        }
    }
}

/// What an update law asks for on one frame ([`LawParams::step`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LawStep {
    /// Move to `ratio` times the frame's exposure.
    Relative(f64),
    /// Move at least to `ratio` times the frame's exposure: the best
    /// exposure lies beyond what the estimate can see.
    AtLeast(f64),
    /// The linear or nonlinear law's step `ratio` from the frame near
    /// scale-and-clip's fixed point: as [`LawStep::Relative`], except that
    /// commands in flight that already go further that way stand (a frame
    /// taken before they showed would undo them). Anchored to the frame
    /// (on fixed levels, whose walker adds up what each frame asks), it is
    /// [`LawStep::Relative`]; so it is for a balanced camera (the
    /// controller's choice).
    Standing(f64),
    /// The linear or nonlinear law's step `ratio` from the frame, whose
    /// estimate puts the fixed point at `best` times the frame's exposure
    /// (scale-and-clip's ŝ): [`LawParams::next_exposure`] applies the law
    /// again from where the commands in flight leave the camera.
    Ahead {
        /// The law's ratio at the frame.
        ratio: f64,
        /// The estimator's fixed point over the frame's exposure.
        best: f64,
        /// Set when the best lies beyond what the frame shows at all (a
        /// mostly saturated frame's step down, which the controller sets):
        /// the commands in flight are followed by the same step. (An
        /// estimate at an end of its span is not such a frame: followed by
        /// the same step, the linear law on a pair's whole frames, sky and
        /// all, ran 2 EV past its best and kept 24 % of it.)
        beyond: bool,
    },
    /// The best exposure is predicted at `ratio` times the frame's
    /// exposure.
    Predicted {
        /// Best over the frame's exposure, undamped and unbounded.
        ratio: f64,
    },
}

/// α of Eq. 3 and 4.
pub fn alpha(gamma_hat: f64) -> f64 {
    if gamma_hat >= 1.0 {
        0.5
    } else {
        1.0
    }
}

/// Eq. 3 as a ratio: `1 + α·Kp·(1 − γ̂)`.
pub fn linear_ratio(kp: f64, gamma_hat: f64) -> f64 {
    1.0 + alpha(gamma_hat) * kp * (1.0 - gamma_hat)
}

/// `R` of Eq. 4: `d·tan((2 − γ̂)·atan(1/d) − atan(1/d)) + 1`.
pub fn nonlinear_r(d: f64, gamma_hat: f64) -> f64 {
    let a = (1.0 / d).atan();
    d * ((2.0 - gamma_hat) * a - a).tan() + 1.0
}

/// Eq. 4 as a ratio: `1 + α·Kp·(R − 1)`.
pub fn nonlinear_ratio(kp: f64, d: f64, gamma_hat: f64) -> f64 {
    1.0 + alpha(gamma_hat) * kp * (nonlinear_r(d, gamma_hat) - 1.0)
}

/// The fast law leaves the camera where its commands put it while the
/// predicted best exposure is within this (EV).
pub const FAST_REST_EV: f64 = 0.01;

/// The fast law moves [`FAST_SMALL_DAMPING`] of the way to a predicted best
/// exposure this close (EV) to where its commands put the camera. So close,
/// the prediction is as much the estimate's noise as a change: under
/// scale-and-clip at full resolution, frame-to-frame `ŝ` of a camera at its
/// fixed point varies by up to ±0.15 EV, and following it in full made the
/// camera wander by as much after a change of light.
pub const FAST_SMALL_EV: f64 = 0.2;

/// Corrections smaller than this (EV) the fast law makes in full: so close
/// to its fixed point, following the estimate frame by frame averages its
/// noise out, and halving them left a camera up to 0.03 EV from the
/// estimator's fixed point.
pub const FAST_SMALL_MIN_EV: f64 = 0.03;

/// The share of a small correction ([`FAST_SMALL_EV`]) the fast law makes.
pub const FAST_SMALL_DAMPING: f64 = 0.5;

/// The linear and nonlinear laws go on from the commands in flight
/// ([`LawStep::Ahead`]) only while scale-and-clip puts the fixed point this
/// far (EV) from the frame: closer, two commands per frame of latency
/// would double the loop's gain where the estimate's own noise (up to
/// ±0.15 EV frame to frame at full resolution) is what it follows.
pub const AHEAD_MIN_EV: f64 = 0.5;

/// Mean intensity the fast law aims for when the estimate is at a bound.
pub const FAST_MEAN_TARGET: f64 = 0.45;

/// The fast law's prediction of the best exposure over the frame's, before
/// damping and bounds, for an estimate inside the anchors' span.
fn fast_prediction(estimate: &Estimate, stats: &ImageStats) -> f64 {
    match estimate.simulation {
        Simulation::ScaleClip => estimate.x_hat,
        Simulation::Gamma => {
            let g = estimate.gamma_hat;
            // A slope is local: an estimate from beyond the anchors' span
            // is too far out for its Newton step.
            let newton = estimate
                .slope
                .filter(|&k| k > 0.05 && estimate.at_bound.is_none() && !estimate.extended)
                .map(|k| (-(g - 1.0) / k).exp());
            newton.unwrap_or_else(|| {
                // Without the information-weighted intensity (an estimate
                // not made for this law), the mean intensity stands in.
                let mu = estimate
                    .info_intensity
                    .unwrap_or(f64::from(stats.mean))
                    .clamp(0.02, 0.95);
                mu.powf(g - 1.0)
            })
        }
    }
}

/// The fast law's ratio before the per-frame bound.
pub fn fast_ratio(damping: f64, estimate: &Estimate, stats: &ImageStats) -> f64 {
    let predicted = fast_prediction(estimate, stats);
    let predicted = match (estimate.at_bound.is_some(), estimate.simulation) {
        // ŝ at its upper bound: brightening is simulated exactly, so the
        // optimum lies at least one span further. (Darkening rests on what
        // is assumed about the saturated pixels, so ŝ at its lower bound
        // stands.)
        (true, Simulation::ScaleClip) if estimate.at_bound == Some(Bound::Upper) => {
            predicted * predicted
        }
        (true, Simulation::ScaleClip) => predicted,
        (true, Simulation::Gamma) => {
            // At least one span of the anchors, or the step to a mid mean.
            let span = 1.0 / estimate.x_hat;
            let to_mid = FAST_MEAN_TARGET / f64::from(stats.mean).max(1e-4);
            [span, to_mid]
                .into_iter()
                .filter(|r| r.ln() * predicted.ln() > 0.0)
                .fold(
                    predicted,
                    |a, r| if r.ln().abs() > a.ln().abs() { r } else { a },
                )
        }
        (false, _) => predicted,
    };
    predicted.powf(damping)
}

#[cfg(test)]
#[allow(clippy::float_cmp)]
mod tests {
    use super::*;

    fn nonlinear() -> LawParams {
        LawParams {
            kind: LawKind::Nonlinear,
            ..Default::default()
        }
    }

    #[test]
    fn a_standing_step_keeps_commands_in_flight_that_go_further() {
        let law = nonlinear();
        // The frame at 1000 asks 10 % down; a command in flight to 800
        // already goes further down: it stands.
        let step = LawStep::Standing(0.9);
        assert_eq!(law.next_exposure(step, 1000.0, 800.0, true), 800.0);
        // One to 950 does not go as far, one to 1100 goes the other way:
        // the frame's own step.
        for base in [950.0, 1100.0, 1000.0] {
            let e = law.next_exposure(step, 1000.0, base, true);
            assert!((e - 900.0).abs() < 1e-9, "from {base}: {e}");
        }
        // Anchored to the frame (fixed levels), it is the frame's step.
        assert_eq!(step.anchored(), LawStep::Relative(0.9));
        assert_eq!(step.with_frame_ev(0.5), LawStep::Standing(0.5f64.exp2()));
    }

    #[test]
    fn ahead_with_nothing_in_flight_is_the_frames_own_step() {
        let law = nonlinear();
        let step = LawStep::Ahead {
            ratio: 1.5,
            best: 8.0,
            beyond: false,
        };
        assert_eq!(law.next_exposure(step, 1000.0, 1000.0, true), 1500.0);
    }

    #[test]
    fn ahead_goes_on_from_the_commands_in_flight_towards_the_frames_fixed_point() {
        let law = nonlinear();
        // Brighter: the fixed point at 8000, a command in flight to 1500.
        let step = LawStep::Ahead {
            ratio: 1.5,
            best: 8.0,
            beyond: false,
        };
        let next = law.next_exposure(step, 1000.0, 1500.0, true);
        let expected = 1500.0 * nonlinear_ratio(1.0, 0.8, 1500.0 / 8000.0);
        assert!((next - expected).abs() < 1e-9, "{next} against {expected}");
        assert!(next > 1500.0 && next < 8000.0);
        // Darker, the same way.
        let step = LawStep::Ahead {
            ratio: 0.8,
            best: 0.55,
            beyond: false,
        };
        let next = law.next_exposure(step, 1000.0, 800.0, true);
        let expected = 800.0 * nonlinear_ratio(1.0, 0.8, 800.0 / 550.0);
        assert!((next - expected).abs() < 1e-9, "{next} against {expected}");
        assert!(next < 800.0 && next > 550.0);
    }

    #[test]
    fn ahead_never_passes_the_fixed_point_nor_steps_back_from_a_command_past_it() {
        let law = LawParams {
            kind: LawKind::Linear,
            ..Default::default()
        };
        // In flight to 1300, the frame's fixed point at 1200: the command
        // stands (no step back from the frame's own 1150).
        let step = LawStep::Ahead {
            ratio: 1.15,
            best: 1.2,
            beyond: false,
        };
        assert_eq!(law.next_exposure(step, 1000.0, 1300.0, true), 1300.0);
        // Far ahead, with any in-flight command short of it, the step stays
        // short of the fixed point.
        for base in [1001.0, 1100.0, 1190.0, 1199.0] {
            let next = law.next_exposure(step, 1000.0, base, true);
            assert!(next > base && next <= 1200.0, "{base}: {next}");
        }
    }

    #[test]
    fn a_step_the_repeller_moves_is_the_frames_own() {
        let step = LawStep::Ahead {
            ratio: 1.5,
            best: 8.0,
            beyond: false,
        };
        assert_eq!(step.with_frame_ev(1.5f64.log2()), step);
        assert_eq!(step.with_frame_ev(0.25), LawStep::Relative(0.25f64.exp2()));
    }
}
