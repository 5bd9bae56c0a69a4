//! The estimator of Shim et al. (Eq. 2): which simulated exposure change
//! would give the most gradient information.
//!
//! The metered image is mapped through a simulated exposure change at each
//! anchor, each mapped image is scored with Eq. 1, a least-squares polynomial
//! (5th order by default) is fitted to the scores, and its maximum over the
//! anchors' span is the estimate.
//!
//! Two simulations are offered; they point in opposite directions:
//!
//! | simulation | mapping | estimate > 1 means |
//! | --- | --- | --- |
//! | [`Simulation::Gamma`] (the paper's) | `I^γ` | darker is better |
//! | [`Simulation::ScaleClip`] (default) | `min(1, s·I)` | brighter is better |
//!
//! Scale-and-clip is exact for brightening (`s ≥ 1`) on a linear sensor,
//! and for darkening the pixels that are not saturated. How far above
//! saturation a saturated pixel lies cannot be known from the frame, so for
//! `s < 1` rigview keeps what is known apart from what is assumed:
//!
//! - **Known:** saturated pixels (at or above [`SATURATED_LEVEL`]) are held
//!   saturated, as under the γ-mapping (`1^γ = 1`): an edge into a
//!   saturated area keeps its bright side while its dark side darkens. Only
//!   pixels that carry information now (`m ≥ δ`) are counted: where a
//!   saturation contour is smooth, holding the saturated side would invent
//!   an edge that darkening does not make.
//! - **Assumed:** darkening by `s` brings back about as many saturated
//!   pixels as now lie in `[s, 1)` (the histogram continues past saturation;
//!   at most all saturated ones), and they carry the *texture* of the
//!   surfaces now just below saturation: the mean information of the pixels
//!   whose whole 3×3 neighbourhood lies in `[s_min, 1)` (`s_min` the
//!   smallest anchor, so the texture is the same for every anchor). Edges (a
//!   neighbourhood that reaches below `s_min` or into saturation) do not
//!   count as texture, so a textureless bright surface (a white marking, a
//!   wall in the sun) that saturates is not credited with information it
//!   does not have.
//!
//! ```text
//! M_sim(s) = Σ_{m̄ > 0 now} m̄ of (I ≥ 0.98 ? I : s·I)
//!            + min(N_sat, N_[s,1)) · mean{ m̄ : 3×3 ⊂ [s_min, 0.98) }  (s < 1)
//! M_sim(s) = M(min(1, s·I))                                             (s ≥ 1)
//! ```
//!
//! Without saturated pixels both lines equal `M(min(1, s·I))`.
//!
//! A metered pixel that averages several sensor pixels (a full frame
//! metered in 4×4 blocks) can be partly saturated: a fraction `f` of its
//! samples is at full well ([`Metered::saturated_samples`]) and the rest
//! sum to `I − f`. Only the rest follows an exposure change, so
//! scale-and-clip maps such a block to `f + min(1 − f, s·(I − f))`, for
//! brightening and darkening alike (its saturated samples held, as
//! above): its saturated samples cannot get brighter, and a scaled block
//! would clip early. The assumed texture recovery leaves the partly
//! saturated blocks out: they are the edges of saturated areas, neither
//! saturated surface nor texture.
//!
//! **A darker frame of the same scene** ([`Darker`], [`EstimateOptions`])
//! takes the guesswork out: every saturated sample the darker frame shows
//! below saturation has a known level, so darkening is exact down to the
//! darker frame's exposure, and a sample saturated there too stays
//! saturated at every anchor above it. Per metered pixel, with `u` the part
//! below saturation now, `f` the saturated part and `t` the level the
//! saturated samples have without the clip (the darker frame's value over
//! the exposure ratio, minus `u`; at least `f`):
//!
//! ```text
//! M_sim(s) = M(min(1, s·u + min(f, s·t)))        (every anchor)
//! ```
//!
//! with the image's own weights and no assumed recovery. A sample
//! saturated in the darker frame too counts at saturation there, a lower
//! bound, which only matters for anchors darker than the darker frame. The
//! darker frame is read only where it is the same scene: its pixels below
//! saturation in both frames, scaled by the exposure ratio, match the
//! current ones in sum (the light is the same) and pixel by pixel (the view
//! is the same) within [`DARKER_LEVEL_TOLERANCE`] and
//! [`DARKER_MISMATCH_TOLERANCE`]; otherwise the estimate is the plain one
//! and says so ([`Estimate::declipped`]). The controller keeps the frame of
//! a probe that measured no better for this ([`super::probe`]), and the
//! frame after which the camera's own law sent it brighter. How much the
//! darker frame corrects is measured in `docs/exposure-results.md`.
//!
//! **Through a tone curve** ([`ToneCurve`], set in the configuration or
//! per camera with [`Estimator::set_tone_curve`]): for a frame whose
//! camera applies a curve `I = f(L)`, scale-and-clip maps each pixel
//! through `f(min(1, s·f⁻¹(I)))` (a lookup per anchor), saturated pixels
//! held and the assumed recovery counted at the recorded level of `s`, as
//! above; partly saturated blocks are mapped as a whole, and a darker
//! frame is not read (its split assumes a linear frame).
//!
//! The
//! scale-and-clip polynomial is fitted in `ln s` ([`FitVariable::Log`]): the
//! anchors are geometric and exposure acts multiplicatively, and in `s` the
//! wide gap between the upper anchors lets a 5th-order fit overshoot there
//! and its maximum jump between two bumps. The γ-mapping keeps the paper's
//! fit in γ.
//!
//! Every estimate is also expressed as the γ-equivalent `γ̂`
//! ([`Estimate::gamma_hat`]): `γ̂ = γ` for the γ-mapping and `γ̂ = 1/ŝ` for
//! scale-and-clip, so the update laws (written for γ̂) move the right way for
//! both.

use serde::{Deserialize, Serialize};

use super::kernel::{self, Source};
use super::metering::{Metered, SATURATED_LEVEL};
use super::metric::{GradientMetric, Scratch};
use super::tone::ToneCurve;
use crate::cpu::Isa;
use crate::error::Result;

mod config;
mod polynomial;
mod slope;

use slope::map_luma;

pub use config::{EstimatorConfig, Simulation, DEFAULT_ANCHORS, DEFAULT_PLATEAU};
pub use polynomial::{fit, fit_in, FitVariable, Polynomial};
pub use slope::{PRIOR_SLOPE, SLOPE_EVALUATIONS, SLOPE_REACH, SLOPE_ROOT_TOLERANCE, SLOPE_STEP};

/// `M` at one anchor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnchorScore {
    /// The anchor (γ or s).
    pub x: f64,
    /// `M` of the simulated image.
    pub m: f64,
}

/// Which end of the anchors' span the maximum sits on, if any: then the best
/// exposure probably lies beyond what the anchors simulate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Bound {
    /// The smallest anchor.
    Lower,
    /// The largest anchor.
    Upper,
}

/// The result of one estimate, with everything a plot needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// The simulation that produced it.
    pub simulation: Simulation,
    /// `M` at each anchor, in ascending anchor order.
    pub anchors: Vec<AnchorScore>,
    /// The fitted polynomial.
    pub poly: Polynomial,
    /// The maximiser in the simulation's own variable (γ̂ or ŝ).
    pub x_hat: f64,
    /// The γ-equivalent estimate: `γ̂ > 1` means darker is better.
    pub gamma_hat: f64,
    /// Set when the maximiser sits at an end of the anchors' span.
    pub at_bound: Option<Bound>,
    /// Set when no anchor shows any gradient information (a black or a fully
    /// saturated image): the estimate then says nothing and is 1.
    pub flat: bool,
    /// `M` of the image as it is.
    pub m_current: f64,
    /// The information-weighted geometric mean intensity of the image as it
    /// is, `exp(Σ m̄·ln I / Σ m̄)`: the intensity where its gradient
    /// information lies (0.5 when there is none). Computed when asked for
    /// ([`Estimator::estimate_with_info`], [`Estimator::estimate_with_slope`]);
    /// a plain estimate leaves it out (only the fast law uses it: under the
    /// γ-mapping it makes the γ = 1 pass about 2.5 times as long, under
    /// scale-and-clip it needs `log₂ I` of every pixel, which the
    /// estimate does not).
    pub info_intensity: Option<f64>,
    /// `dγ̂/d ln E` measured on the image itself, when asked for
    /// ([`Estimator::estimate_with_slope`]).
    pub slope: Option<f64>,
    /// Set when scale-and-clip read the saturated pixels from a darker
    /// frame of the same scene ([`Darker`]) instead of holding them.
    #[serde(default)]
    pub declipped: bool,
    /// Set when the maximiser sat at an end of the anchors' span and a
    /// second search beyond that end ([`EstimateOptions::extend`]) gave
    /// `x_hat`: then `anchors` and `poly` are the first search's.
    #[serde(default)]
    pub extended: bool,
}

impl Estimate {
    /// The largest anchor score.
    pub fn m_max_anchor(&self) -> f64 {
        self.anchors.iter().map(|a| a.m).fold(0.0, f64::max)
    }
}

/// A frame of the same scene taken darker than the one estimated on, from
/// which scale-and-clip reads what the saturated pixels hide (module
/// documentation). Metered like it: same size, same mask.
#[derive(Clone, Copy, Debug)]
pub struct Darker<'a> {
    /// The darker frame.
    pub image: &'a Metered,
    /// Its exposure over the current frame's: at most `2^−DARKER_MIN_EV`.
    pub ratio: f64,
}

/// A darker frame serves while it is at least this much darker than the
/// frame estimated on, EV: nearer, it shows little the current frame does
/// not.
pub const DARKER_MIN_EV: f64 = 0.1;

/// How far the darker frame's pixels that are below saturation in both
/// frames may disagree with the current frame, scaled by the exposure
/// ratio, for it to count as the same scene: their sums by this fraction
/// (the light changed) …
pub const DARKER_LEVEL_TOLERANCE: f64 = 0.05;
/// … and their mean absolute difference, over their mean, by this (the
/// view moved). The noise of the simulated reference camera, metered in
/// 4×4 blocks or 1:1, stays below a third of it.
pub const DARKER_MISMATCH_TOLERANCE: f64 = 0.12;

/// What an estimate computes besides the anchors and the fit.
#[derive(Clone, Copy, Debug, Default)]
pub struct EstimateOptions<'a> {
    /// [`Estimate::info_intensity`].
    pub intensity: bool,
    /// [`Estimate::slope`] (and the intensity).
    pub slope: bool,
    /// A darker frame of the same scene, for scale-and-clip; ignored by the
    /// γ-mapping, and left unused ([`Estimate::declipped`] false) when it
    /// does not match the current frame.
    pub darker: Option<Darker<'a>>,
    /// Where the maximiser sits at an end of the anchors' span, search
    /// once more beyond it: on the image mapped by the end anchor, with the
    /// same anchors, whose estimate composes with it (`(I^a)^b = I^(ab)`,
    /// `min(1, b·min(1, a·I)) = min(1, ab·I)` for `a, b ≥ 1`). The
    /// γ-mapping searches one span further (about ±1.9 EV by default),
    /// where a change of light left the camera far from its best exposure.
    /// Scale-and-clip searches beyond its upper end only, span after span
    /// while the maximiser stays at the end, up to [`EXTEND_SPANS`] (1.9⁴,
    /// 3.7 EV by default): brightening is simulated exactly, whereas
    /// below its lower end darkening rests on assumptions about the
    /// saturated pixels.
    pub extend: bool,
}

/// How many spans beyond its brightest anchor scale-and-clip searches
/// ([`EstimateOptions::extend`]): with the default anchors, up to 1.9⁴ ≈ 13
/// (3.7 EV).
pub const EXTEND_SPANS: usize = 3;

/// Computes [`Estimate`]s; holds buffers reused from frame to frame.
#[derive(Clone, Debug)]
pub struct Estimator {
    config: EstimatorConfig,
    anchors: Vec<f64>,
    metric: GradientMetric,
    scratch: Scratch,
    logs: kernel::Aligned<f32>,
    info: Vec<f32>,
    mapped: Vec<f32>,
    declip: Declip,
    /// The tone curve scale-and-clip simulates through, if any.
    tone: Option<ToneCurve>,
    /// The lookup of the anchor being scored through `tone`.
    lut: Vec<f32>,
    /// The weights of [`Self::texture_recovery`]'s whole blocks.
    whole: Vec<f32>,
}

/// The per-pixel parts of [`Source::Declipped`], reused from frame to frame.
#[derive(Clone, Debug, Default)]
struct Declip {
    unsaturated: Vec<f32>,
    saturated: Vec<f32>,
    hidden: Vec<f32>,
}

impl Estimator {
    /// An estimator for `config` (checked).
    pub fn new(config: EstimatorConfig) -> Result<Self> {
        config.validate()?;
        let mut anchors = config.anchors.clone();
        anchors.sort_by(f64::total_cmp);
        anchors.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        Ok(Self {
            metric: GradientMetric::new(config.metric)?,
            anchors,
            scratch: Scratch::default(),
            logs: kernel::Aligned::default(),
            info: Vec::new(),
            mapped: Vec::new(),
            declip: Declip::default(),
            lut: Vec::new(),
            whole: Vec::new(),
            tone: config.tone_curve.clone(),
            config,
        })
    }

    /// Sets the tone curve scale-and-clip simulates through (checked);
    /// `None` goes back to the configuration's.
    pub fn set_tone_curve(&mut self, curve: Option<ToneCurve>) -> Result<()> {
        if let Some(c) = &curve {
            c.validate()?;
        }
        self.tone = curve.or_else(|| self.config.tone_curve.clone());
        Ok(())
    }

    /// The tone curve scale-and-clip simulates through, if any.
    pub fn tone_curve(&self) -> Option<&ToneCurve> {
        self.tone.as_ref()
    }

    /// The tone curve, when scale-and-clip simulates through one.
    fn toned(&self) -> Option<&ToneCurve> {
        self.tone
            .as_ref()
            .filter(|_| self.config.simulation == Simulation::ScaleClip)
    }

    /// Runs the kernels with the vector instruction set `isa` (or the
    /// widest below it that the CPU has and the kernels have code for; see
    /// [`Scratch::with_isa`]) instead of the widest; for comparisons and
    /// benchmarks. Returns the one chosen.
    pub fn set_isa(&mut self, isa: Isa) -> Isa {
        self.scratch = Scratch::with_isa(isa);
        self.scratch.isa()
    }

    /// The configuration.
    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }

    /// The metric.
    pub fn metric(&self) -> &GradientMetric {
        &self.metric
    }

    /// `M` of the image as it is.
    pub fn score(&mut self, image: &Metered) -> f64 {
        self.metric.score(
            image.luma(),
            image.width(),
            image.height(),
            image.weight(),
            &mut self.scratch,
        )
    }

    /// `M` of the image after the simulated exposure change `x` (for
    /// scale-and-clip below 1, `M_sim` of the module documentation).
    pub fn score_at(&mut self, image: &Metered, x: f64) -> f64 {
        self.prepare(image, false);
        self.current_information(image, false);
        let held = self.held_weights(image);
        let recovered = if held {
            self.texture_recovery(image, &[x])
        } else {
            Vec::new()
        };
        self.score_mapped(image, x, held) + recovered.first().copied().unwrap_or(0.0)
    }

    /// `M` of the image as it is and, when `with_intensity`, the
    /// information-weighted geometric mean intensity (needs the `log₂ I` of
    /// [`Self::prepare`]); fills the information map when scale-and-clip
    /// needs it.
    fn current_information(&mut self, image: &Metered, with_intensity: bool) -> (f64, Option<f64>) {
        let scale_clip = self.config.simulation == Simulation::ScaleClip;
        if !with_intensity && !scale_clip {
            return (self.score(image), None);
        }
        let map = scale_clip.then_some(&mut self.info);
        let (m, m_log2_i) = self.metric.information_with_log2(
            image.luma(),
            with_intensity.then_some(&self.logs[..]),
            image.width(),
            image.height(),
            image.weight(),
            &mut self.scratch,
            map,
        );
        let intensity = if m > 0.0 { (m_log2_i / m).exp2() } else { 0.5 };
        (m, with_intensity.then_some(intensity))
    }

    /// For scale-and-clip on an image with a saturated pixel: the weights of
    /// the darkening anchors (the image's weights where a pixel carries
    /// information now, 0 elsewhere) into `self.mapped`. `false` when there
    /// is nothing saturated (then `min(1, s·I)` is exact) or for the
    /// γ-mapping. Needs the information map of [`Self::current_information`].
    fn held_weights(&mut self, image: &Metered) -> bool {
        if self.config.simulation != Simulation::ScaleClip {
            return false;
        }
        let saturated = image.saturated_samples().is_some()
            || image
                .luma()
                .iter()
                .fold(false, |any, &v| any | (v >= SATURATED_LEVEL));
        if !saturated {
            return false;
        }
        self.mapped.clear();
        self.mapped
            .extend(self.info.iter().map(|&i| f32::from(i > 0.0)));
        if let Some(weight) = image.weight() {
            for (m, &w) in self.mapped.iter_mut().zip(weight) {
                *m *= w;
            }
        }
        true
    }

    /// `log₂ I` of every pixel, floored where the largest γ anchor maps
    /// it to the smallest normal number (`I^γ ≈ 0` below), where the
    /// γ-mapping or the information-weighted intensity needs it
    /// (scale-and-clip's passes scale `I` itself).
    fn prepare(&mut self, image: &Metered, with_intensity: bool) {
        if self.config.simulation == Simulation::ScaleClip && !with_intensity {
            return;
        }
        let gamma_max = self.anchors.iter().copied().fold(1.0, f64::max) as f32;
        kernel::log2_map(
            self.scratch.isa(),
            image.luma(),
            -126.0 / gamma_max,
            &mut self.logs,
        );
    }

    /// The assumed part of `M_sim` (module documentation) at each of `xs`
    /// (0 for `x ≥ 1`), for an image with a saturated pixel. The texture is
    /// measured once, on the widest band (down to the smallest anchor), so
    /// that it does not depend on `x`. Needs the information map of
    /// [`Self::current_information`].
    fn texture_recovery(&mut self, image: &Metered, xs: &[f64]) -> Vec<f64> {
        // Through a tone curve, the recorded value of the light `x`.
        let at = |x: f64| self.toned().map_or(x, |c| c.recorded(x)) as f32;
        let widest = at(self.anchors.iter().chain(xs).copied().fold(1.0, f64::min));
        let levels: Vec<f32> = xs
            .iter()
            .map(|&x| if x < 1.0 { at(x) } else { x as f32 })
            .collect();
        // Blocks that are partly saturated are edges of saturated areas,
        // neither saturated surface nor texture: they are left out (in a
        // loop over slices, which vectorises).
        let whole = &mut self.whole;
        whole.clear();
        let part = |f: f32| f > 0.0 && f < 1.0;
        let whole = match (image.saturated_samples(), image.weight()) {
            (Some(sat), Some(weight)) => {
                whole.extend(
                    sat.iter()
                        .zip(weight)
                        .map(|(&f, &w)| if part(f) { 0.0 } else { w }),
                );
                Some(&whole[..])
            }
            (Some(sat), None) => {
                whole.extend(sat.iter().map(|&f| if part(f) { 0.0 } else { 1.0 }));
                Some(&whole[..])
            }
            (None, _) => None,
        };
        let sums = kernel::saturation_sums(
            self.scratch.isa(),
            image.luma(),
            whole.or(image.weight()),
            &self.info,
            image.width(),
            image.height(),
            &levels,
            widest,
            SATURATED_LEVEL,
        );
        let texture = if sums.texture_weight > 0.0 {
            sums.texture_info / sums.texture_weight
        } else {
            0.0
        };
        sums.bands
            .iter()
            .map(|&n| sums.saturated.min(n) * texture)
            .collect()
    }

    /// Splits every metered pixel of `image` into its part below saturation
    /// and its saturated part, and reads the saturated part's true level
    /// from `darker` (see [`Source::Declipped`]). `false` when `darker` is
    /// not the same scene: its size differs, it is less than
    /// [`DARKER_MIN_EV`] darker, or its pixels below saturation in both
    /// frames disagree with the current ones beyond
    /// [`DARKER_LEVEL_TOLERANCE`] or [`DARKER_MISMATCH_TOLERANCE`]. A sample
    /// saturated in the darker frame too counts at saturation there: a
    /// lower bound.
    fn declip(&mut self, image: &Metered, darker: Darker<'_>) -> bool {
        let (d, r) = (darker.image, darker.ratio);
        let n = image.luma().len();
        if !(r > 0.0 && r.log2() <= -DARKER_MIN_EV)
            || d.width() != image.width()
            || d.height() != image.height()
            || d.luma().len() != n
        {
            return false;
        }
        let inv_r = (1.0 / r) as f32;
        let (luma, dark) = (image.luma(), &d.luma()[..n]);
        let Declip {
            unsaturated,
            saturated,
            hidden,
        } = &mut self.declip;
        unsaturated.resize(n, 0.0);
        saturated.resize(n, 0.0);
        hidden.resize(n, 0.0);
        let (u, f, h) = (&mut unsaturated[..n], &mut saturated[..n], &mut hidden[..n]);
        // Pixel by pixel without a branch or a push, so that the loops
        // vectorise; then the sums over the pixels unsaturated in both.
        match image.saturated_samples().filter(|b| b.len() == n) {
            Some(blocks) => {
                for i in 0..n {
                    f[i] = blocks[i];
                    u[i] = (luma[i] - f[i]).max(0.0);
                    h[i] = (dark[i] * inv_r - u[i]).max(f[i]);
                }
            }
            None => {
                for i in 0..n {
                    f[i] = f32::from(luma[i] >= SATURATED_LEVEL);
                    u[i] = luma[i] * (1.0 - f[i]);
                    h[i] = (dark[i] * inv_r - u[i]).max(f[i]);
                }
            }
        }
        let dark_saturated = |i: usize| match d.saturated_samples() {
            Some(b) => b.get(i).copied().unwrap_or(1.0),
            None => f32::from(dark[i] >= SATURATED_LEVEL),
        };
        let (mut now, mut then, mut apart) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let counts = image.weight().map_or(1.0, |w| w[i]) > 0.0;
            if counts && f[i] == 0.0 && dark_saturated(i) == 0.0 {
                let (v, dv) = (luma[i], dark[i] * inv_r);
                now += f64::from(v);
                then += f64::from(dv);
                apart += f64::from((dv - v).abs());
            }
        }
        now > 0.0
            && (then / now - 1.0).abs() <= DARKER_LEVEL_TOLERANCE
            && apart / now <= DARKER_MISMATCH_TOLERANCE
    }

    /// `M` of the image at `x` with its saturated pixels read from the
    /// darker frame ([`Self::declip`] filled the parts).
    fn score_declipped(&mut self, image: &Metered, x: f64) -> f64 {
        let Declip {
            unsaturated,
            saturated,
            hidden,
        } = &self.declip;
        self.metric.score_source(
            Source::Declipped {
                unsaturated,
                saturated,
                hidden,
                s: x as f32,
            },
            image.width(),
            image.height(),
            image.weight(),
            &mut self.scratch,
        )
    }

    /// `M` of the simulated image at `x`; `held`: the weights of
    /// [`Self::held_weights`] are in `self.mapped`.
    fn score_mapped(&mut self, image: &Metered, x: f64, held: bool) -> f64 {
        if (x - 1.0).abs() < 1e-12 {
            return self.score(image);
        }
        if let (Simulation::ScaleClip, Some(curve)) = (self.config.simulation, &self.tone) {
            // Held: saturated pixels stay (and the held weights leave them
            // out) under a darkening, as without a curve.
            let hold = (held && x < 1.0).then_some(SATURATED_LEVEL);
            curve.lookup(x, hold, &mut self.lut);
            return self.metric.score_source(
                Source::Table {
                    luma: image.luma(),
                    table: &self.lut,
                },
                image.width(),
                image.height(),
                if held && x < 1.0 {
                    Some(self.mapped.as_slice())
                } else {
                    image.weight()
                },
                &mut self.scratch,
            );
        }
        let (source, weight) = match (self.config.simulation, image.saturated_samples()) {
            (Simulation::Gamma, _) => (
                Source::Gamma {
                    log2: &self.logs,
                    gamma: x as f32,
                },
                image.weight(),
            ),
            (Simulation::ScaleClip, Some(saturated)) => (
                Source::Blocks {
                    luma: image.luma(),
                    saturated,
                    s: x as f32,
                },
                if held && x < 1.0 {
                    Some(self.mapped.as_slice())
                } else {
                    image.weight()
                },
            ),
            (Simulation::ScaleClip, _) if held && x < 1.0 => (
                Source::Hold {
                    luma: image.luma(),
                    s: x as f32,
                    level: SATURATED_LEVEL,
                },
                Some(self.mapped.as_slice()),
            ),
            (Simulation::ScaleClip, _) => (
                Source::Scale {
                    luma: image.luma(),
                    s: x as f32,
                },
                image.weight(),
            ),
        };
        self.metric.score_source(
            source,
            image.width(),
            image.height(),
            weight,
            &mut self.scratch,
        )
    }

    /// Scores every anchor, fits the polynomial and finds its maximum.
    pub fn estimate(&mut self, image: &Metered) -> Result<Estimate> {
        self.estimate_with(image, EstimateOptions::default())
    }

    /// [`Estimator::estimate`] with [`Estimate::info_intensity`].
    pub fn estimate_with_info(&mut self, image: &Metered) -> Result<Estimate> {
        self.estimate_with(
            image,
            EstimateOptions {
                intensity: true,
                ..Default::default()
            },
        )
    }

    /// An estimate with what `options` asks for.
    pub fn estimate_with(
        &mut self,
        image: &Metered,
        options: EstimateOptions<'_>,
    ) -> Result<Estimate> {
        let mut estimate =
            self.estimate_inner(image, options.intensity || options.slope, options.darker)?;
        if options.extend {
            self.extend(image, &mut estimate)?;
        }
        // Scale-and-clip's estimate is itself the ratio: only the
        // γ-mapping's fast law needs a slope.
        if options.slope && self.config.simulation == Simulation::Gamma {
            self.add_slope(image, &mut estimate)?;
        }
        Ok(estimate)
    }

    fn estimate_inner(
        &mut self,
        image: &Metered,
        with_intensity: bool,
        darker: Option<Darker<'_>>,
    ) -> Result<Estimate> {
        self.prepare(image, with_intensity);
        let (m_current, info_intensity) = self.current_information(image, with_intensity);
        // (The darker frame's split assumes a linear frame.)
        let declipped = self.config.simulation == Simulation::ScaleClip
            && self.tone.is_none()
            && darker.is_some_and(|d| self.declip(image, d));
        let held = !declipped && self.held_weights(image);
        let xs = self.anchors.clone();
        let recovered = if held {
            self.texture_recovery(image, &xs)
        } else {
            vec![0.0; xs.len()]
        };
        let anchors: Vec<AnchorScore> = xs
            .into_iter()
            .zip(recovered)
            .map(|(x, r)| {
                let m = if (x - 1.0).abs() < 1e-12 {
                    m_current
                } else if declipped {
                    self.score_declipped(image, x)
                } else {
                    self.score_mapped(image, x, held) + r
                };
                AnchorScore { x, m }
            })
            .collect();
        let simulation = self.config.simulation;
        let poly = fit_in(&anchors, self.config.degree, simulation.fit_variable())?;
        let m_max = anchors.iter().map(|a| a.m).fold(f64::MIN, f64::max);
        let m_min = anchors.iter().map(|a| a.m).fold(f64::MAX, f64::min);
        let flat = m_max <= 0.0 || m_max - m_min <= 1e-9 * m_max.max(1.0);
        let (x_hat, at_bound) = if flat {
            (1.0, None)
        } else {
            // Maxima of nearly equal height are blended, near or far; no
            // maximum is higher than the anchors around it show.
            let (lo, hi) = poly.range();
            let x = poly.argmax_supported(&anchors, self.config.plateau * (m_max - m_min));
            let tol = 1e-9 * (hi - lo);
            let bound = if x <= lo + tol {
                Some(Bound::Lower)
            } else if x >= hi - tol {
                Some(Bound::Upper)
            } else {
                None
            };
            (x, bound)
        };
        Ok(Estimate {
            simulation,
            anchors,
            poly,
            x_hat,
            gamma_hat: simulation.gamma_equivalent(x_hat),
            at_bound,
            flat,
            m_current,
            info_intensity,
            slope: None,
            declipped,
            extended: false,
        })
    }
}

impl Estimator {
    /// The search beyond the anchors' span of [`EstimateOptions::extend`],
    /// into `estimate`.
    fn extend(&mut self, image: &Metered, estimate: &mut Estimate) -> Result<()> {
        let Some(bound) = estimate.at_bound.filter(|_| !estimate.flat) else {
            return Ok(());
        };
        if self.config.simulation == Simulation::ScaleClip && bound == Bound::Lower {
            return Ok(());
        }
        let (Some(&lo), Some(&hi)) = (self.anchors.first(), self.anchors.last()) else {
            return Ok(());
        };
        let end = match bound {
            Bound::Lower => lo,
            Bound::Upper => hi,
        };
        // Scale-and-clip brightens exactly, so it searches span after
        // span while the maximiser stays at the upper end.
        let spans = match self.config.simulation {
            Simulation::Gamma => 1,
            Simulation::ScaleClip => EXTEND_SPANS,
        };
        let back = match bound {
            Bound::Lower => Bound::Upper,
            Bound::Upper => Bound::Lower,
        };
        let e = end as f32;
        // (Cloned once: the searches below borrow the estimator.)
        let tone = self.tone.clone();
        let mut base = 1.0;
        let mut current: Option<Metered> = None;
        for _ in 0..spans {
            let from = current.as_ref().unwrap_or(image);
            let mapped = match (self.config.simulation, &tone) {
                (Simulation::Gamma, _) => map_luma(from, |v| v.powf(e))?,
                (Simulation::ScaleClip, Some(c)) => {
                    let e = f64::from(e);
                    map_luma(from, |v| {
                        c.recorded((e * c.linear(f64::from(v))).min(1.0)) as f32
                    })?
                }
                (Simulation::ScaleClip, None) => map_luma(from, |v| (v * e).min(1.0))?,
            };
            base *= end;
            let beyond = self.estimate_inner(&mapped, false, None)?;
            // The next search answers only if it looks further out: at its
            // end towards the last search it would say that end itself.
            if beyond.flat || beyond.at_bound == Some(back) {
                break;
            }
            let x = base * beyond.x_hat;
            estimate.x_hat = x;
            estimate.gamma_hat = self.config.simulation.gamma_equivalent(x);
            estimate.at_bound = beyond.at_bound;
            estimate.extended = true;
            if beyond.at_bound.is_none() {
                break;
            }
            current = Some(mapped);
        }
        Ok(())
    }
}
