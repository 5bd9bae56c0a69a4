//! Exposure balancing between cameras that overlap (Eq. 5 and 6).
//!
//! For camera `i` with neighbours `G(i)`:
//!
//! ```text
//! E*_{t+1,i} = argmin_X α_i·(X − E_{t+1,i})² + (1 − α_i)/N · Σ_j (X − r_ij·E*_{t,i})²
//!            = α_i·E_{t+1,i} + (1 − α_i)·mean_j(r_ij)·E*_{t,i}
//! r_ij       = median over overlap patches p of mean(p_j) / (mean(p_i) + ε)
//! α_i        = (1 − R_i) + 0.5 if R_i < 1,   R_i / 2 otherwise,
//! R_i        = E_{t+1,i} / E_{t,i} clamped to [0.5, 2]
//! ```
//!
//! Patches in which either camera is saturated or nearly black say nothing
//! about the brightness ratio and are left out.
//!
//! ## Damping a circling camera
//!
//! Eq. 6's α is smallest (½) where the unary ratio `R` is 1 and grows on
//! either side, so near a camera's own fixed point a small change of `R`
//! moves the balanced step a lot: `d(E*/E)/dR = 1.5 − 2R + mean_j r_ij` for
//! `R < 1`, about 4 for a camera whose neighbours want it 2 EV brighter.
//! Fed back through a unary law that answers a change of exposure with a
//! change of `R` of the same order, the loop gain exceeds 1 and the camera
//! circles the balanced fixed point every two steps instead of settling on
//! it.
//!
//! [`Damping`] takes only a fraction `κ` of each balanced step, in log
//! exposure: `E_{t+1} = E_t·(E*_{t+1}/E_t)^κ`. `κ` halves each time the
//! step changes direction (both steps larger than a dead band, so noise at
//! rest does not count) down to a floor, and doubles back towards 1 on
//! each step that keeps the direction once the camera has moved
//! `recover_ev` that way since the last reversal. A camera that follows its scene (a
//! tunnel, a step of light) keeps `κ = 1` and Eq. 5 as written; one that
//! circles is slowed until the loop gain is below 1. The fixed points are
//! Eq. 5's: `E*_{t+1} = E_t` is a fixed point for every `κ`. A change of
//! light (a frame whose mean intensity its exposure cannot explain) ends
//! the damping: `κ` is 1 again, so that a camera damped while it rested
//! follows the new light at the full step.
//!
//! Eq. 6's `α` can be a running mean over the camera's frames (weight
//! `alpha_weight` below 1; 1 is each frame's own `α`, as Eq. 6 is
//! written; unset, the weight follows the exposure simulation: 1 under the
//! γ-mapping, 1/8 under scale-and-clip). The loop gain above comes mostly
//! from `α` moving with `R` (`dα/dR·(R − mean_j r_ij)`: 3.4 of the 4.3 at
//! the balanced rest of a camera whose neighbours want it 2 EV brighter);
//! with `α` averaged, a
//! swing of `R` from frame to frame moves the balanced step by about `α`
//! times as much. The fixed points are Eq. 5's (`α` settles where `R`
//! does); a change of light starts the mean again from the frame's own
//! `α`, with `κ`. Under scale-and-clip a weight of 1/8 holds the simulated
//! front camera still in real time where each frame's `α` lets it
//! saw-tooth; under the γ-mapping it does not help, and 1 is what holds it
//! (docs/exposure-results.md). Taking the mean only while a camera is
//! damped was tried: switching between the two made slow cycles of more
//! than 1 EV on a model of a steep own law.
//!
//! The distance before `κ` grows again catches a saw-tooth as well as a
//! two-step cycle: where the balanced target jumps (γ̂ of the γ-mapping
//! jumping to the end of the anchors as the exposure crosses a point),
//! the camera climbs a little in a few steps and drops once; regaining `κ`
//! on steps alone would give it back its whole step before each drop
//! (`docs/exposure-results.md` has the measurements).

use serde::{Deserialize, Serialize};

use super::bracket::same_scene;
use super::estimator::{AnchorScore, Estimate, Simulation};
use super::tone::ToneCurve;
use crate::error::{check_range, Error, Result};
use crate::stats::median;

/// Parameters of the balancing.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BalanceParams {
    /// ε of Eq. 5, in intensity units.
    pub epsilon: f64,
    /// A patch whose saturated fraction exceeds this in either camera is left out.
    pub max_saturated: f64,
    /// A patch whose mean is below this in either camera is left out.
    pub min_mean: f64,
    /// A pair needs at least this many usable patches to give `r_ij`.
    pub min_patches: usize,
    /// How a circling camera's balanced step is damped ([`Damping`]).
    #[serde(default)]
    pub damping: DampingParams,
    /// For how many sets a pair's last measured scene ratio stands in
    /// while its patches are unusable, not counting sets in which they are
    /// clipped ([`HeldRatios`]; 0: never).
    #[serde(default = "default_hold_sets")]
    pub hold_sets: u32,
    /// The largest share of its own best `M` that balancing may cost a
    /// camera by pulling it darker, as its estimate predicts it under
    /// scale-and-clip ([`guard_m`]; 1: no limit, Eq. 5 as written).
    #[serde(default = "default_max_m_loss")]
    pub max_m_loss: f64,
}

fn default_hold_sets() -> u32 {
    DEFAULT_HOLD_SETS
}

fn default_max_m_loss() -> f64 {
    DEFAULT_MAX_M_LOSS
}

/// [`BalanceParams::max_m_loss`] by default: 8 %. The `snow` preset's
/// back camera keeps 91.5 % of its best `M` at a quarter of the resolution
/// (88 % at 10 %). At 5 % it kept 94.5 %, but at full resolution it came
/// to rest where its estimate is bistable (γ̂ 0.85 or 1.82 at the same
/// exposure) and cycled 1.2 EV every second or so; at 8 % it rests at
/// 2^11.17 µs with one darker probe in 10 s.
pub const DEFAULT_MAX_M_LOSS: f64 = 0.08;

/// Sets a scene ratio is held by default: 5 s at 20 Hz.
pub const DEFAULT_HOLD_SETS: u32 = 100;

impl Default for BalanceParams {
    fn default() -> Self {
        Self {
            epsilon: 1e-3,
            max_saturated: 0.05,
            min_mean: 0.01,
            min_patches: 1,
            damping: DampingParams::default(),
            hold_sets: DEFAULT_HOLD_SETS,
            max_m_loss: DEFAULT_MAX_M_LOSS,
        }
    }
}

impl BalanceParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "balance.epsilon",
            self.epsilon,
            0.0,
            0.5,
            "a number in [0, 0.5]",
        )?;
        check_range(
            "balance.max_saturated",
            self.max_saturated,
            0.0,
            1.0,
            "a fraction in [0, 1]",
        )?;
        check_range(
            "balance.min_mean",
            self.min_mean,
            0.0,
            0.5,
            "a mean in [0, 0.5]",
        )?;
        check_range(
            "balance.max_m_loss",
            self.max_m_loss,
            0.0,
            1.0,
            "a fraction in [0, 1]",
        )?;
        if self.min_patches == 0 {
            return Err(Error::InvalidParameter {
                name: "balance.min_patches",
                value: 0.0,
                expected: "at least 1",
            });
        }
        self.damping.validate()
    }
}

/// One overlap patch as both cameras see it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PatchPair {
    /// Mean intensity in camera `i`.
    pub mean_i: f32,
    /// Saturated fraction in camera `i`.
    pub saturated_i: f32,
    /// Mean intensity in camera `j`.
    pub mean_j: f32,
    /// Saturated fraction in camera `j`.
    pub saturated_j: f32,
}

/// `r_ij` (Eq. 5) from the patches of one pair, or `None` when fewer than
/// `min_patches` are usable.
pub fn pair_ratio(patches: &[PatchPair], params: &BalanceParams) -> Option<f64> {
    pair_ratio_through(patches, params, [None, None])
}

/// [`pair_ratio`] as a ratio of light: each camera's patch means read
/// through its tone curve (`curves[0]` camera `i`'s, `curves[1]` camera
/// `j`'s; `None`: a linear camera). Eq. 6 moves exposures by the ratio,
/// which is the ratio of recorded values only for a linear camera: through
/// a power curve of 2.2 a ratio of light of 2 records as 1.37. Which
/// patches are usable is decided on the recorded values. (A patch's mean
/// is read through the curve, not each pixel: the patches are small and
/// nearly even.)
pub fn pair_ratio_through(
    patches: &[PatchPair],
    params: &BalanceParams,
    curves: [Option<&ToneCurve>; 2],
) -> Option<f64> {
    // (ε of Eq. 5 is in recorded units: it is added before the curve.)
    let light = |v: f64, curve: Option<&ToneCurve>| curve.map_or(v, |c| c.linear(v));
    let mut ratios: Vec<f64> = patches
        .iter()
        .filter(|p| {
            !clips(p, params)
                && f64::from(p.mean_i) >= params.min_mean
                && f64::from(p.mean_j) >= params.min_mean
        })
        .map(|p| {
            light(f64::from(p.mean_j), curves[1])
                / light(f64::from(p.mean_i) + params.epsilon, curves[0])
        })
        .filter(|r| r.is_finite())
        .collect();
    if ratios.len() < params.min_patches {
        return None;
    }
    median(&mut ratios)
}

/// Whether most of a pair's patches are left out because either camera
/// saturates them (rather than because they are dark).
pub fn clipped(patches: &[PatchPair], params: &BalanceParams) -> bool {
    2 * patches.iter().filter(|p| clips(p, params)).count() > patches.len()
}

/// Whether either camera saturates patch `p` beyond what Eq. 5 uses (a
/// saturated fraction that is not a number counts as saturated).
fn clips(p: &PatchPair, params: &BalanceParams) -> bool {
    !(f64::from(p.saturated_i) <= params.max_saturated
        && f64::from(p.saturated_j) <= params.max_saturated)
}

/// The last usable ratio of each ordered pair, as a ratio of the scene
/// (exposure removed), standing in while the pair's patches are unusable.
///
/// `r_ij` is measured only where neither camera saturates its overlap
/// patches. After a step of light one camera often does for a few sets;
/// dropping the pair then lets that camera follow its own law alone and
/// pulls it back with the whole pairwise term when the patches return, a
/// jump of up to the full balancing step (2 EV on the reference preset's
/// front camera). A linear sensor's patch brightness is `E·L`, so
/// `ρ_ij = r_ij·E_i/E_j = L_j/L_i` does not change with the exposures, and
/// a step of light over the whole scene leaves it as it was: the held `ρ`
/// gives `r_ij = ρ_ij·E_j/E_i` at the exposures the frames were taken with.
///
/// The held ratio stands for `hold_sets` sets, the scene in the overlap
/// may have changed after that, but for as long as the patches stay
/// clipped it does not age: a balanced camera whose neighbours see the
/// overlap much brighter may clip the shared patches at its balanced
/// exposure, and dropping the pair there would make it jump to its own
/// law's exposure (2 EV on the tunnel's front camera 5 s after the exit,
/// under scale-and-clip), and back once the patches show again.
#[derive(Clone, Debug, Default)]
pub struct HeldRatios {
    /// `((i, j), log2 ρ_ij, sets since it was measured)`.
    held: Vec<((usize, usize), f64, u32)>,
}

impl HeldRatios {
    /// `r_ij` for frames taken at `e_i` and `e_j`: the measured one (which
    /// is kept), or the held scene ratio for at most `hold_sets` sets in
    /// which the patches were not `clipped`. Call once per ordered pair and
    /// set.
    pub fn update(
        &mut self,
        (i, j): (usize, usize),
        measured: Option<f64>,
        e_i: f64,
        e_j: f64,
        hold_sets: u32,
        clipped: bool,
    ) -> Option<f64> {
        let exposure = (e_j / e_i).log2();
        let slot = self.held.iter().position(|h| h.0 == (i, j));
        match (measured.filter(|r| r.is_finite() && *r > 0.0), slot) {
            (Some(r), Some(k)) => {
                self.held[k] = ((i, j), r.log2() - exposure, 0);
                Some(r)
            }
            (Some(r), None) => {
                self.held.push(((i, j), r.log2() - exposure, 0));
                Some(r)
            }
            (None, Some(k)) => {
                let h = &mut self.held[k];
                if !clipped {
                    h.2 = h.2.saturating_add(1);
                }
                (h.2 <= hold_sets && exposure.is_finite()).then(|| (h.1 + exposure).exp2())
            }
            (None, None) => None,
        }
    }

    /// Forgets every pair.
    pub fn clear(&mut self) {
        self.held.clear();
    }
}

/// α of Eq. 6 for the unary ratio `R = E_{t+1}/E_t` (clamped to [0.5, 2]).
pub fn alpha(unary_ratio: f64) -> f64 {
    let r = if unary_ratio.is_nan() {
        1.0
    } else {
        unary_ratio.clamp(0.5, 2.0)
    };
    if r < 1.0 {
        (1.0 - r) + 0.5
    } else {
        r / 2.0
    }
}

/// The closed-form minimiser of Eq. 5.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Balanced {
    /// The balanced exposure `E*_{t+1}`.
    pub exposure: f64,
    /// α used.
    pub alpha: f64,
    /// Mean of the neighbours' `r_ij`.
    pub mean_ratio: f64,
}

/// Solves Eq. 5 for one camera: `unary` is `E_{t+1,i}`, `current` is
/// `E*_{t,i}` (the exposure its frame was taken with), `ratios` the `r_ij`
/// of its neighbours that have one. With no ratios the unary stands.
pub fn balance(unary: f64, current: f64, ratios: &[f64]) -> Balanced {
    balance_with(unary, current, ratios, |a| a)
}

/// [`balance`] with Eq. 6's `α` passed through `alpha_of` (the damping's
/// smoothing of `α` over frames, [`Damping::smooth_alpha`]).
pub fn balance_with(
    unary: f64,
    current: f64,
    ratios: &[f64],
    alpha_of: impl FnOnce(f64) -> f64,
) -> Balanced {
    if ratios.is_empty() || current <= 0.0 {
        return Balanced {
            exposure: unary,
            alpha: 1.0,
            mean_ratio: 1.0,
        };
    }
    let a = alpha_of(alpha(unary / current)).clamp(0.5, 1.0);
    let mean_ratio = ratios.iter().sum::<f64>() / ratios.len() as f64;
    Balanced {
        exposure: a * unary + (1.0 - a) * mean_ratio * current,
        alpha: a,
        mean_ratio,
    }
}

/// Where balancing may take a camera: a balanced `target` darker (or
/// brighter) than the camera's own `unary` exposure, moved back towards it
/// until the camera's estimate predicts at least `1 − max_loss` of the best
/// `M` its anchors show.
///
/// Eq. 5 weighs the neighbours as much as the camera's own law at rest
/// (`α = ½`), whatever that costs the camera. Where neighbours see their
/// overlap very differently (snow lit on one side of the vehicle, shade on
/// the other), a chain of cameras pulls one of them far from its own best:
/// the simulated `snow` preset's back camera rested 0.9 EV under its best
/// with 81 % of its `M`. Under scale-and-clip the anchors' scores are the
/// `M` of the frame as the sensor would give it at `s` times the exposure
/// (exact below saturation), so they say what a balanced exposure costs:
/// `M̂(s)` interpolates them in `ln s`. When `M̂` at the target falls under
/// the floor, the target moves from there towards the best anchor to the
/// first exposure that reaches the floor, but not past the unary (the law
/// keeps its own pace). A target beyond the anchors' span is judged by
/// the nearest end.
///
/// A pull brighter is guarded the same way, from the target down towards
/// the best anchor and the unary. On the real courtyard
/// (`assets/sim/courtyard.sim.yaml`) the front camera faces a sunlit yard
/// and its neighbours the shade under a roof: pulled brighter unguarded it
/// clipped the yard and kept 50 % of its best `M`, guarded 88 %. A pull
/// brighter once led the `tunnel-exit` preset's front camera over a hump of
/// `M(E)` its anchors cannot see past (its own law rests at 2^10.4 µs, its
/// best is 2^15.8); balanced cameras now probe brighter themselves where
/// most of a frame is dark ([`super::probe`]), which finds it. The
/// γ-mapping's scores are not an exposure's and the target stands; so it
/// does for a flat estimate and for `max_loss ≥ 1`.
pub fn guard_m(target: f64, unary: f64, taken: f64, estimate: &Estimate, max_loss: f64) -> f64 {
    if estimate.simulation != Simulation::ScaleClip || estimate.flat {
        return target;
    }
    guard_m_by(target, unary, taken, &estimate.anchors, max_loss)
}

/// [`guard_m`] on scale-and-clip's anchor scores, ascending in `s`.
pub fn guard_m_by(
    target: f64,
    unary: f64,
    taken: f64,
    anchors: &[AnchorScore],
    max_loss: f64,
) -> f64 {
    let usable = max_loss < 1.0
        && anchors.len() >= 2
        && anchors.windows(2).all(|w| w[0].x < w[1].x)
        && taken > 0.0
        && target > 0.0
        && unary > 0.0
        && target.is_finite()
        && unary.is_finite()
        && anchors
            .iter()
            .all(|a| a.x > 0.0 && a.x.is_finite() && a.m.is_finite());
    if !usable {
        return target;
    }
    let Some(best) = anchors.iter().max_by(|a, b| a.m.total_cmp(&b.m)) else {
        return target;
    };
    if best.m <= 0.0 {
        return target;
    }
    let floor = (1.0 - max_loss.max(0.0)) * best.m;
    let lo = anchors[0].x.ln();
    let hi = anchors[anchors.len() - 1].x.ln();
    let m_at = |u: f64| -> f64 {
        let u = u.clamp(lo, hi);
        let k = anchors
            .windows(2)
            .position(|w| u <= w[1].x.ln())
            .unwrap_or(anchors.len() - 2);
        let (a, b) = (&anchors[k], &anchors[k + 1]);
        let (ua, ub) = (a.x.ln(), b.x.ln());
        if ub - ua <= 0.0 {
            return a.m.max(b.m);
        }
        let f = ((u - ua) / (ub - ua)).clamp(0.0, 1.0);
        a.m + f * (b.m - a.m)
    };
    let u_target = (target / taken).ln();
    if m_at(u_target) >= floor {
        return target;
    }
    let u_best = best.x.ln();
    let u_unary = (unary / taken).ln();
    // The best anchor and the unary must lie on the same side of the
    // target: the guard only gives back what the neighbours' pull took.
    let from = u_target.clamp(lo, hi);
    let stop = if u_unary > u_target && u_best >= from {
        // A pull darker.
        u_unary.min(u_best)
    } else if u_unary < u_target && u_best <= from {
        // A pull brighter.
        u_unary.max(u_best)
    } else {
        return target;
    };
    const STEPS: usize = 64;
    let mut u = stop;
    for k in 1..=STEPS {
        let v = from + (stop - from) * k as f64 / STEPS as f64;
        if m_at(v) >= floor {
            u = v;
            break;
        }
    }
    taken * u.exp()
}

/// How [`Damping`] adapts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DampingParams {
    /// Steps smaller than this (|log2 of the step|, EV) neither shrink nor
    /// grow `κ`.
    pub dead_band_ev: f64,
    /// The smallest `κ`.
    pub floor: f64,
    /// How far (EV) the camera must have moved in one direction since the
    /// last reversal before `κ` grows again (0: at once).
    #[serde(default = "default_recover_ev")]
    pub recover_ev: f64,
    /// The weight of each frame's Eq. 6 `α` in its running mean over the
    /// camera's frames (1: every frame's own `α`, as Eq. 6 is written).
    /// Unset, it follows the exposure simulation
    /// ([`DampingParams::alpha_weight_under`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_weight: Option<f64>,
}

/// [`DampingParams::alpha_weight`] unset, under scale-and-clip.
pub const SCALE_CLIP_ALPHA_WEIGHT: f64 = 0.125;

impl DampingParams {
    /// The weight of each frame's `α` under `simulation`: the one set, or
    /// by default 1 under the γ-mapping (Eq. 6 as written) and
    /// [`SCALE_CLIP_ALPHA_WEIGHT`] under scale-and-clip, each the weight
    /// that holds the simulated rig still in real time under its
    /// simulation (the other saw-tooths by 0.036 EV or more; module
    /// documentation).
    pub fn alpha_weight_under(&self, simulation: Simulation) -> f64 {
        self.alpha_weight.unwrap_or(match simulation {
            Simulation::Gamma => 1.0,
            Simulation::ScaleClip => SCALE_CLIP_ALPHA_WEIGHT,
        })
    }
}

fn default_recover_ev() -> f64 {
    0.5
}

impl Default for DampingParams {
    fn default() -> Self {
        Self {
            dead_band_ev: 0.05,
            floor: 1.0 / 16.0,
            recover_ev: default_recover_ev(),
            alpha_weight: None,
        }
    }
}

impl DampingParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "balance.damping.dead_band_ev",
            self.dead_band_ev,
            0.0,
            1.0,
            "an exposure step in EV in [0, 1]",
        )?;
        check_range(
            "balance.damping.floor",
            self.floor,
            1e-3,
            1.0,
            "a fraction in [0.001, 1]",
        )?;
        check_range(
            "balance.damping.recover_ev",
            self.recover_ev,
            0.0,
            20.0,
            "a distance in EV in [0, 20]",
        )?;
        if let Some(w) = self.alpha_weight {
            check_range(
                "balance.damping.alpha_weight",
                w,
                0.01,
                1.0,
                "a weight in [0.01, 1]",
            )?;
        }
        Ok(())
    }
}

/// The step-size adaptation of the balanced step of one camera (module
/// documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Damping {
    kappa: f64,
    /// log2 of the last balanced step outside the dead band.
    last: Option<f64>,
    /// How far (|log2|, EV) the camera has moved since the last reversal.
    travel: f64,
    /// The last frame seen: log2 of its exposure and its mean intensity.
    frame: Option<(f64, f64)>,
    /// The running mean of Eq. 6's `α`.
    alpha: Option<f64>,
}

impl Default for Damping {
    fn default() -> Self {
        Self {
            kappa: 1.0,
            last: None,
            travel: 0.0,
            frame: None,
            alpha: None,
        }
    }
}

impl Damping {
    /// The fraction of the balanced step the next call takes, before it
    /// adapts.
    pub fn kappa(&self) -> f64 {
        self.kappa
    }

    /// Forgets the history (`κ = 1`): for a step that did not balance.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Takes the camera's frame (`log2` of the exposure it was taken with,
    /// its mean intensity): where it cannot be of the last frame's scene
    /// (the light changed: the bracket's rule, within `light_tolerance`), the
    /// circling it was damped for is over, and `κ` is 1 again, so that the
    /// camera follows the new light at Eq. 5's full step.
    pub fn observe(&mut self, log2_exposure: f64, mean: f64, light_tolerance: f64) {
        let now = (log2_exposure, mean);
        if self
            .frame
            .is_some_and(|last| !same_scene(last, now, light_tolerance))
        {
            *self = Self::default();
        }
        self.frame = Some(now);
    }

    /// The running mean of Eq. 6's `α`, if a frame started it.
    pub fn alpha_mean(&self) -> Option<f64> {
        self.alpha
    }

    /// Eq. 6's `α` for this frame, whose own `α` is `raw`: `raw` folded
    /// into the running mean with weight `weight` (the first
    /// frame, and the first after a change of light, start the mean).
    pub fn smooth_alpha(&mut self, raw: f64, weight: f64) -> f64 {
        let a = match self.alpha {
            Some(a) if !raw.is_finite() => a,
            Some(a) => a + weight * (raw - a),
            None => raw,
        };
        self.alpha = Some(a);
        a
    }

    /// The exposure to command for the balanced target `target` of a frame
    /// taken at `current`, and the `κ` used.
    pub fn apply(&mut self, current: f64, target: f64, params: &DampingParams) -> (f64, f64) {
        if !(current > 0.0 && target > 0.0 && current.is_finite() && target.is_finite()) {
            return (target, self.kappa);
        }
        let step = (target / current).log2();
        if step.abs() > params.dead_band_ev {
            match self.last {
                Some(last) if last * step < 0.0 => {
                    self.kappa = (self.kappa * 0.5).max(params.floor);
                    self.travel = 0.0;
                }
                Some(_) if self.travel >= params.recover_ev => {
                    self.kappa = (self.kappa * 2.0).min(1.0);
                }
                _ => {}
            }
            self.last = Some(step);
            self.travel += (self.kappa * step).abs();
        }
        let kappa = self.kappa;
        (current * (kappa * step).exp2(), kappa)
    }
}

/// Which cameras overlap: an undirected graph over camera indices.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NeighbourGraph {
    cameras: usize,
    edges: Vec<(usize, usize)>,
}

impl NeighbourGraph {
    /// A graph over `cameras` cameras; each edge `(i, j)` with `i ≠ j`,
    /// both in range. Duplicate edges (in either order) are merged.
    pub fn new(cameras: usize, edges: &[(usize, usize)]) -> Result<Self> {
        let mut out: Vec<(usize, usize)> = Vec::with_capacity(edges.len());
        for &(i, j) in edges {
            for k in [i, j] {
                if k >= cameras {
                    return Err(Error::CameraIndex {
                        index: k,
                        count: cameras,
                    });
                }
            }
            if i == j {
                return Err(Error::invalid(
                    "neighbour graph",
                    format!("camera {i}'s neighbour"),
                    "another camera",
                    "itself",
                ));
            }
            let e = (i.min(j), i.max(j));
            if !out.contains(&e) {
                out.push(e);
            }
        }
        Ok(Self {
            cameras,
            edges: out,
        })
    }

    /// A ring `0–1–…–(n−1)–0` (the reference rig's four cameras).
    pub fn ring(cameras: usize) -> Result<Self> {
        let edges: Vec<(usize, usize)> = match cameras {
            0 | 1 => Vec::new(),
            2 => vec![(0, 1)],
            n => (0..n).map(|i| (i, (i + 1) % n)).collect(),
        };
        Self::new(cameras, &edges)
    }

    /// Number of cameras.
    pub fn cameras(&self) -> usize {
        self.cameras
    }

    /// The edges, each once with `i < j`.
    pub fn edges(&self) -> &[(usize, usize)] {
        &self.edges
    }

    /// The neighbours of camera `i`.
    pub fn neighbours(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.edges.iter().filter_map(move |&(a, b)| {
            if a == i {
                Some(b)
            } else if b == i {
                Some(a)
            } else {
                None
            }
        })
    }
}

// A target the guard leaves is returned as it came, bit for bit.
#[cfg(test)]
#[allow(clippy::float_cmp)]
mod tests {
    use super::*;

    /// Scores at the default anchors for `M(s) = m(ln s)`.
    fn scores(m: impl Fn(f64) -> f64) -> Vec<AnchorScore> {
        crate::exposure::estimator::DEFAULT_ANCHORS
            .iter()
            .map(|&x| AnchorScore { x, m: m(x.ln()) })
            .collect()
    }

    /// `M` rising linearly in `ln s` from 50 at `s = 1/1.9` to 100 at
    /// `s = 1.9`: a camera balanced darker than its best.
    fn rising() -> Vec<AnchorScore> {
        let h = 1.9f64.ln();
        scores(|u| 75.0 + 25.0 * u / h)
    }

    #[test]
    fn a_target_within_the_budget_stands() {
        let a = rising();
        // M̂(1.8) ≈ 97.9 ≥ 95.
        assert_eq!(guard_m_by(1.8, 1.9, 1.0, &a, 0.05), 1.8);
        // No limit: Eq. 5 as written.
        assert_eq!(guard_m_by(0.6, 1.5, 1.0, &a, 1.0), 0.6);
    }

    #[test]
    fn a_costly_target_moves_to_where_the_estimate_reaches_the_floor() {
        let a = rising();
        let h = 1.9f64.ln();
        // The floor 95 lies at ln s = 0.8·h (M = 75 + 25·0.8).
        let want = (0.8 * h).exp();
        for taken in [1.0, 250.0] {
            let g = guard_m_by(0.8 * taken, 1.9 * taken, taken, &a, 0.05);
            assert!(
                (g / taken / want - 1.0).abs() < 0.02,
                "guarded {g} at taken {taken}, want {}",
                want * taken
            );
            // A budget of 20 %: the floor 80 at ln s = 0.2·h.
            let g = guard_m_by(0.8 * taken, 1.9 * taken, taken, &a, 0.2);
            assert!((g / taken / (0.2 * h).exp() - 1.0).abs() < 0.02, "{g}");
        }
    }

    #[test]
    fn the_guard_never_passes_the_unary() {
        let a = rising();
        // The law asks only 1.2 times the exposure: the floor (1.67) lies
        // beyond it, and the guarded target is the law's own.
        let g = guard_m_by(0.7, 1.2, 1.0, &a, 0.05);
        assert!((g - 1.2).abs() < 1e-9, "{g}");
        // A unary on the far side of the target from the best anchor:
        // the guard has nothing to give back.
        assert_eq!(guard_m_by(0.9, 0.6, 1.0, &a, 0.05), 0.9);
    }

    #[test]
    fn a_target_beyond_the_anchors_is_judged_by_the_nearest_end() {
        let a = rising();
        // s = 0.2 is judged by M̂(1/1.9) = 50 and moved up.
        let g = guard_m_by(0.2, 1.9, 1.0, &a, 0.05);
        assert!(g > 1.5 && g <= 1.9, "{g}");
        // s = 3 is judged by M̂(1.9) = 100, the best.
        assert_eq!(guard_m_by(3.0, 1.9, 1.0, &a, 0.05), 3.0);
    }

    #[test]
    fn a_pull_either_way_is_guarded() {
        // M peaks at s = 1 and falls off 30 per EV-ish on both sides.
        let a = scores(|u| 100.0 - 40.0 * u.abs());
        let up = guard_m_by(0.55, 1.1, 1.0, &a, 0.1);
        assert!(up > 0.55 && up < 1.0, "{up}");
        assert!(
            100.0 - 40.0 * up.ln().abs() >= 89.0,
            "M̂ at {up}: {}",
            100.0 - 40.0 * up.ln().abs()
        );
        // A pull brighter comes back down until M̂ keeps 90 % of the best.
        let down = guard_m_by(1.85, 0.9, 1.0, &a, 0.1);
        assert!(down > 1.0 && down < 1.85, "{down}");
        let m = 100.0 - 40.0 * down.ln();
        assert!((89.0..=91.5).contains(&m), "M̂ at {down}: {m}");
        // Not past the unary, and not when M̂ at the target holds.
        assert_eq!(guard_m_by(1.2, 0.9, 1.0, &a, 0.1), 1.2);
        let to_unary = guard_m_by(1.85, 1.3, 1.0, &a, 0.02);
        assert!((to_unary - 1.3).abs() < 1e-9, "{to_unary}");
    }

    #[test]
    fn bad_scores_leave_the_target() {
        let mut a = rising();
        a[2].m = f64::NAN;
        assert_eq!(guard_m_by(0.6, 1.5, 1.0, &a, 0.05), 0.6);
        let zero = scores(|_| 0.0);
        assert_eq!(guard_m_by(0.6, 1.5, 1.0, &zero, 0.05), 0.6);
        let mut unsorted = rising();
        unsorted.swap(0, 6);
        assert_eq!(guard_m_by(0.6, 1.5, 1.0, &unsorted, 0.05), 0.6);
        assert_eq!(guard_m_by(0.6, 1.5, 0.0, &rising(), 0.05), 0.6);
    }

    #[test]
    fn max_m_loss_is_validated() {
        let p = BalanceParams {
            max_m_loss: 1.5,
            ..Default::default()
        };
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("balance.max_m_loss"), "{e}");
        assert!(BalanceParams::default().validate().is_ok());
    }
}
