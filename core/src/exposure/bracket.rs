//! Safeguards of a camera's own law: the bracket of its best exposure and
//! the choice between frames that point apart.
//!
//! # The bracket
//!
//! A camera's own law looks for the exposure where its estimate says
//! "neither brighter nor darker". Where the estimate is smooth and
//! monotonic in exposure, any of the laws gets there. Where it is not, a
//! law circles: scale-and-clip's estimate can jump from one end of the
//! anchors' span to the other as the exposure crosses a point (a surface
//! saturates: below the point, brightening is better by at least a span;
//! above it, the held saturated pixels make darkening look better by a
//! span), and the γ-mapping's can fall again past a saturation event. Each
//! frame then says "far too dark" or "far too bright", and every finite
//! step overshoots.
//!
//! A [`Bracket`] keeps what the frames have said: the brightest exposure
//! whose frame asked for more (`lo`) and the darkest whose frame asked for
//! less (`hi`). Once both are known, the best exposure lies between them
//! (for a monotonic estimate; where the estimate jumps, at the jump), and a
//! command outside is replaced by the midpoint in log exposure: a safeguarded
//! search, which converges wherever the law's own step would circle and
//! leaves the law's step alone wherever it stays inside.
//!
//! The bracket must not outlive its scene:
//! - a frame whose mean intensity contradicts an end's shows that the
//!   light changed, and both ends go. A linear sensor's mean intensity
//!   grows at most in proportion to the exposure (clipping only slows it)
//!   and never falls with it: a frame taken at `k` times an end's
//!   exposure whose mean lies below `min(1, k)` or above `max(1, k)` times
//!   that end's, by more than `light_tolerance`, contradicts it;
//! - a frame beyond an end by more than `narrow_ev` that still asks to go
//!   past it removes that end (at the end itself, an estimate that jumps
//!   there asks either way from frame to frame, and the ends close in);
//! - when the ends are closer than `narrow_ev` and `narrow_frames`
//!   frames in a row ask for the same direction, the end in that direction
//!   opens by `narrow_ev`, twice as far with every second further frame
//!   (the light drifts past it: the camera follows at once, while a run of
//!   noise at a jump costs one small step);
//! - an end that no frame has confirmed for `max_age_frames` frames goes.
//!   A frame confirms both ends when its mean intensity agrees with each
//!   end's within half of `light_tolerance` (the same light on the same
//!   scene, as far as the mean can tell). A balanced camera's frames sit
//!   on one side of its bracket, away from the end it set long ago; if
//!   that end went by age alone, the law would step past it once in every
//!   `max_age_frames`, and the camera would circle around its jump that
//!   often (snow under the fast law, balanced).
//!
//! # Frames that point apart
//!
//! [`Repeller`]: where two frames of one scene predict best exposures on
//! opposite sides of themselves, the fast law follows the frame with more
//! gradient information instead of each frame in turn.

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Result};

/// When the bracket's ends hold (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BracketParams {
    /// Law steps smaller than this (|log2|, EV) say nothing about the
    /// direction.
    pub dead_band_ev: f64,
    /// Ends closer than this (EV) open after `narrow_frames` frames asking
    /// the same way; a frame past an end by more than this removes it.
    pub narrow_ev: f64,
    /// See `narrow_ev`.
    pub narrow_frames: u32,
    /// Frames an end is kept without a frame that confirms it (module
    /// documentation).
    pub max_age_frames: u32,
    /// The relative change of mean intensity that counts as a change of
    /// light.
    pub light_tolerance: f64,
}

impl Default for BracketParams {
    fn default() -> Self {
        Self {
            dead_band_ev: 0.02,
            narrow_ev: 0.03,
            narrow_frames: 3,
            max_age_frames: 40,
            light_tolerance: 0.1,
        }
    }
}

impl BracketParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "controller.bracket.dead_band_ev",
            self.dead_band_ev,
            0.0,
            1.0,
            "an exposure step in EV in [0, 1]",
        )?;
        check_range(
            "controller.bracket.narrow_ev",
            self.narrow_ev,
            0.0,
            1.0,
            "an exposure span in EV in [0, 1]",
        )?;
        check_range(
            "controller.bracket.narrow_frames",
            f64::from(self.narrow_frames),
            1.0,
            1000.0,
            "a number of frames in [1, 1000]",
        )?;
        check_range(
            "controller.bracket.max_age_frames",
            f64::from(self.max_age_frames),
            1.0,
            1e6,
            "a number of frames in [1, 1000000]",
        )?;
        check_range(
            "controller.bracket.light_tolerance",
            self.light_tolerance,
            1e-3,
            1.0,
            "a relative change of mean intensity in [0.001, 1]",
        )?;
        Ok(())
    }
}

/// One end of a [`Bracket`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct End {
    /// log2 of the exposure.
    at: f64,
    /// The frame's mean intensity.
    mean: f64,
    /// When (the bracket's frame count).
    frame: u64,
}

/// The bracket of one camera's best exposure (module documentation). All
/// exposures in log2.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bracket {
    lo: Option<End>,
    hi: Option<End>,
    frame: u64,
    /// The direction of the latest frames that had one, and how many in a
    /// row.
    run: (i8, u32),
}

impl Bracket {
    /// The ends, `(lo, hi)`, in log2 exposure.
    pub fn ends(&self) -> (Option<f64>, Option<f64>) {
        (self.lo.map(|e| e.at), self.hi.map(|e| e.at))
    }

    /// Forgets both ends.
    pub fn reset(&mut self) {
        self.lo = None;
        self.hi = None;
        self.run = (0, 0);
    }

    /// Takes a frame taken at `at` (log2 exposure) with mean intensity
    /// `mean`, whose law puts the best exposure `step_ev` away (log2 of the
    /// best over the frame's exposure).
    pub fn observe(&mut self, params: &BracketParams, at: f64, mean: f64, step_ev: f64) {
        self.frame += 1;
        if !(at.is_finite() && mean.is_finite() && step_ev.is_finite()) {
            self.reset();
            return;
        }
        let age = u64::from(params.max_age_frames);
        let frame = self.frame;
        self.lo = self.lo.filter(|e| frame - e.frame <= age);
        self.hi = self.hi.filter(|e| frame - e.frame <= age);
        let tol = params.light_tolerance;
        // A linear sensor's mean intensity grows at most in proportion to
        // the exposure (clipping only slows it) and never falls with it.
        let changed = |e: &End| !same_scene((e.at, e.mean), (at, mean), tol);
        if self.lo.iter().chain(self.hi.iter()).any(changed) {
            self.reset();
        }
        for e in [&mut self.lo, &mut self.hi].into_iter().flatten() {
            if same_scene((e.at, e.mean), (at, mean), tol / 2.0) {
                e.frame = frame;
            }
        }
        if step_ev.abs() < params.dead_band_ev {
            return;
        }
        let dir: i8 = if step_ev > 0.0 { 1 } else { -1 };
        self.run = if self.run.0 == dir {
            (dir, self.run.1.saturating_add(1))
        } else {
            (dir, 1)
        };
        let end = End { at, mean, frame };
        // Only a frame clearly past an end (by more than `narrow_ev`)
        // shows that end stale; at the end itself an estimate that jumps
        // there may ask either way from frame to frame (noise), and the
        // ends close in on the jump.
        let past = params.narrow_ev;
        if dir > 0 {
            if self.hi.is_some_and(|h| at >= h.at + past) {
                self.hi = None;
            }
            if self.lo.is_none_or(|l| at >= l.at) {
                self.lo = Some(end);
            }
        } else {
            if self.lo.is_some_and(|l| at <= l.at - past) {
                self.lo = None;
            }
            if self.hi.is_none_or(|h| at <= h.at) {
                self.hi = Some(end);
            }
        }
        if let (Some(l), Some(h)) = (self.lo, self.hi) {
            if h.at - l.at < params.narrow_ev && self.run.1 >= params.narrow_frames {
                // The light drifts past a narrow bracket: the end in the
                // run's direction opens by `narrow_ev`, doubling with every
                // second further frame of the run (a camera with a frame of
                // latency shows each exposure twice), so that the camera
                // follows a drift at once and a noisy jump costs one small
                // step.
                let extra = self.run.1 - params.narrow_frames;
                let open = params.narrow_ev * f64::from(1u32 << (extra / 2).min(6));
                if dir > 0 {
                    self.hi = Some(End {
                        at: l.at.max(h.at) + open,
                        ..end
                    });
                } else {
                    self.lo = Some(End {
                        at: h.at.min(l.at) - open,
                        ..end
                    });
                }
            }
        }
    }

    /// Where a command the law proposes at `proposed` (log2 exposure) goes:
    /// itself when it lies strictly between the ends (or an end is
    /// unknown), the midpoint of the ends otherwise.
    pub fn clamp(&self, proposed: f64) -> f64 {
        match (self.lo, self.hi) {
            (Some(l), Some(h)) if proposed <= l.at || proposed >= h.at => 0.5 * (l.at + h.at),
            _ => proposed,
        }
    }
}

/// Two frames of one scene that do not ask towards each other: the darker
/// asks for less and the brighter for more, or each asks to stay (to move
/// less than a quarter of the distance between them). With a frame of
/// latency the commands of even and odd frames follow different frames (a
/// command rests on the frame it was computed from), and such frames keep
/// two chains apart:
/// between them lies a point the estimate is repelled from (a surface
/// saturating, two humps of `M`: 0.23 EV every frame on the steps preset's
/// back camera under scale-and-clip), or each sits at a fixed point of its
/// own (γ̂ crossing 1 twice: 1 EV every frame on the tunnel's right camera
/// under the nonlinear law). [`Repeller`] keeps the last frame and, when
/// the new one does not ask towards it, follows the frame with the more
/// gradient information: the camera settles on that side.
///
/// Frames closer than [`REPEL_MIN_EV`] are left alone: there the frames'
/// noise decides which asks which way, and following the one with more M
/// would hold a camera against a gentle slope of its estimate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Repeller {
    last: Option<Seen>,
}

/// How far apart (EV) two frames must lie for [`Repeller`] to choose
/// between them.
pub const REPEL_MIN_EV: f64 = 0.06;

/// A frame asks to stay when it asks to move less than this fraction of
/// the distance to the other frame.
const TOWARDS: f64 = 0.25;

/// A frame as [`Repeller`] keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Seen {
    at: f64,
    best: f64,
    m: f64,
    mean: f64,
}

impl Repeller {
    /// Forgets the last frame.
    pub fn reset(&mut self) {
        self.last = None;
    }

    /// The exposure (log2) to follow for a frame at `at` whose law asks
    /// for `best`, with gradient information `m` and mean intensity
    /// `mean`: `best` itself, or the last frame's when the two do not ask
    /// towards each other and the last frame had more information. Frames
    /// whose means disagree with their exposures by more than
    /// `light_tolerance` are taken for another scene.
    pub fn follow(&mut self, at: f64, best: f64, m: f64, mean: f64, light_tolerance: f64) -> f64 {
        let now = Seen { at, best, m, mean };
        let followed = match self.last {
            Some(l) if same_scene((l.at, l.mean), (at, mean), light_tolerance) => {
                let (lo, hi) = if l.at < at { (l, now) } else { (now, l) };
                let reach = TOWARDS * (hi.at - lo.at);
                let opposite = lo.best < lo.at && hi.best > hi.at;
                let staying = (lo.best - lo.at).abs() <= reach && (hi.best - hi.at).abs() <= reach;
                let apart = hi.at - lo.at > REPEL_MIN_EV && (opposite || staying);
                if apart && l.m > m {
                    l.best
                } else {
                    best
                }
            }
            _ => best,
        };
        self.last = Some(now);
        followed
    }
}

/// Whether frames `(log2 exposure, mean intensity)` `a` and `b` can be of
/// the same scene: the mean intensity of a linear sensor grows at most in
/// proportion to the exposure and never falls with it, within `tol`.
pub(crate) fn same_scene(a: (f64, f64), b: (f64, f64), tol: f64) -> bool {
    let k = (b.0 - a.0).exp2();
    let lo = a.1 * k.min(1.0) * (1.0 - tol);
    let hi = a.1 * k.max(1.0) * (1.0 + tol);
    (lo..=hi).contains(&b.1)
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // midpoints of exact values
mod tests {
    use super::*;

    #[test]
    fn frames_that_do_not_ask_towards_each_other_follow_the_one_with_more_information() {
        let mut r = Repeller::default();
        // A frame at 12.27 EV asks for 12.22; the next, at 12.52 with less
        // M, asks for 12.55: the camera follows the first.
        assert_eq!(r.follow(12.27, 12.22, 2.0, 0.40, 0.1), 12.22);
        assert_eq!(r.follow(12.52, 12.55, 1.5, 0.47, 0.1), 12.22);
        // With more M, the new frame's own prediction stands.
        r.reset();
        assert_eq!(r.follow(12.27, 12.22, 1.0, 0.40, 0.1), 12.22);
        assert_eq!(r.follow(12.52, 12.55, 1.5, 0.47, 0.1), 12.55);
        // Frames pointing towards each other leave the law alone.
        r.reset();
        assert_eq!(r.follow(12.27, 12.40, 2.0, 0.40, 0.1), 12.40);
        assert_eq!(r.follow(12.52, 12.40, 1.5, 0.47, 0.1), 12.40);
        // Two frames 1 EV apart that each ask to stay (two fixed points):
        // the one with more M is followed.
        r.reset();
        assert_eq!(r.follow(11.20, 11.20, 3.4, 0.51, 0.1), 11.20);
        assert_eq!(r.follow(12.19, 12.19, 2.2, 0.67, 0.1), 11.20);
        assert_eq!(r.follow(11.20, 11.21, 3.4, 0.51, 0.1), 11.21);
        // Frames that ask towards each other converge by themselves, even
        // where only one of them does.
        r.reset();
        assert_eq!(r.follow(11.20, 11.80, 3.4, 0.51, 0.1), 11.80);
        assert_eq!(r.follow(12.19, 11.60, 2.2, 0.67, 0.1), 11.60);
        assert_eq!(r.follow(11.20, 11.10, 3.4, 0.51, 0.1), 11.10);
        assert_eq!(r.follow(12.19, 11.80, 2.2, 0.67, 0.1), 11.80);
        // Both asking one way is no repeller, however far the darker asks.
        r.reset();
        assert_eq!(r.follow(9.81, 8.10, 3.1, 0.54, 0.1), 8.10);
        assert_eq!(r.follow(10.10, 10.05, 2.9, 0.58, 0.1), 10.05);
        // A change of light (the mean halves at a brighter exposure) is
        // another scene.
        r.reset();
        assert_eq!(r.follow(12.27, 12.22, 2.0, 0.40, 0.1), 12.22);
        assert_eq!(r.follow(12.52, 12.55, 1.5, 0.20, 0.1), 12.55);
    }

    fn step_towards(best: f64, at: f64) -> f64 {
        best - at
    }

    /// A camera from 9 EV under the bracket for `frames` frames, whose law
    /// asks for `law(at)` EV; the exposures it goes to.
    fn follow(b: &mut Bracket, frames: usize, mut law: impl FnMut(f64) -> f64) -> Vec<f64> {
        let p = BracketParams::default();
        let mut at = 9.0;
        let mut trace = Vec::new();
        for _ in 0..frames {
            let step = law(at);
            // Brighter frames have a brighter mean: the same scene.
            b.observe(&p, at, at / 20.0, step);
            at = b.clamp(at + step);
            trace.push(at);
        }
        trace
    }

    /// The smallest and largest of `v`.
    fn span(v: &[f64]) -> (f64, f64) {
        v.iter()
            .fold((f64::MAX, f64::MIN), |(a, c), &x| (a.min(x), c.max(x)))
    }

    #[test]
    fn an_end_stays_while_frames_of_its_scene_confirm_it_and_goes_when_none_does() {
        let p = BracketParams::default();
        let mean = |at: f64| (at - 10.0).exp2() * 0.5;
        let mut b = Bracket::default();
        // A frame at 9.9 asks brighter, one at 10.2 darker: the bracket.
        b.observe(&p, 9.9, mean(9.9), 0.3);
        b.observe(&p, 10.2, mean(10.2), -0.3);
        assert_eq!(b.ends(), (Some(9.9), Some(10.2)));
        // A balanced camera held at 10.25 asks darker frame after frame;
        // the light stays as it was, and the low end stays with it.
        for _ in 0..3 * p.max_age_frames {
            b.observe(&p, 10.25, mean(10.25), -0.3);
        }
        assert_eq!(b.ends(), (Some(9.9), Some(10.2)));
        assert_eq!(b.clamp(9.5), 10.05);
        // The light brightens by 7 % (within the tolerance of a change of
        // light, beyond half of it): no frame confirms the ends, and after
        // `max_age_frames` the low end goes (the high end is renewed).
        for _ in 0..=p.max_age_frames {
            b.observe(&p, 10.15, mean(10.15) * 1.07, -0.3);
        }
        assert_eq!(b.ends(), (None, Some(10.15)));
        assert_eq!(b.clamp(9.5), 9.5);
    }

    #[test]
    fn a_law_that_overshoots_both_ways_is_bisected_to_its_jump() {
        // An estimate that jumps at 10 EV: below, "1.5 EV brighter"; above,
        // "0.75 EV darker"; taken literally the camera circles.
        let mut b = Bracket::default();
        // Brighter frames have a brighter mean: the same scene.
        let trace = follow(&mut b, 30, |at| if at < 10.0 { 1.5 } else { -0.75 });
        let (lo, hi) = span(&trace[20..]);
        assert!(hi - lo < 0.05, "still circling: {trace:?}");
        assert!((lo - 10.0).abs() < 0.05, "{trace:?}");
    }

    #[test]
    fn a_change_of_light_releases_the_bracket() {
        let p = BracketParams::default();
        let mut b = Bracket::default();
        b.observe(&p, 9.0, 0.40, 0.5);
        b.observe(&p, 9.2, 0.45, -0.5);
        assert_eq!(b.ends(), (Some(9.0), Some(9.2)));
        assert_eq!(b.clamp(7.0), 9.1);
        // Two stops more light: at 9.1 the frame is much brighter than the
        // one at 9.2 was.
        b.observe(&p, 9.1, 0.9, -2.0);
        assert_eq!(b.ends(), (None, Some(9.1)));
        assert_eq!(b.clamp(7.1), 7.1);
    }

    #[test]
    fn a_drift_past_a_narrow_end_opens_it_ever_wider() {
        let p = BracketParams::default();
        let mut b = Bracket::default();
        b.observe(&p, 9.00, 0.40, 0.1);
        b.observe(&p, 9.02, 0.41, -0.1);
        let mut at = 9.01;
        let mut trace = Vec::new();
        for k in 0..10 {
            // The light fades slowly: every frame asks for 0.3 EV more.
            b.observe(&p, at, 0.40 - 0.001 * f64::from(k), 0.3);
            at = b.clamp(at + 0.3);
            trace.push(at);
        }
        // Held for the first frames of the run, then following ever faster.
        assert!(trace[0] < 9.03, "{trace:?}");
        let steps: Vec<f64> = trace.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(steps.iter().all(|&s| s >= 0.0), "{trace:?}");
        assert!(trace[9] > 9.3, "{trace:?}");
    }

    #[test]
    fn noise_at_a_jump_holds_the_camera_at_the_jump() {
        // At 10 EV the estimate says "brighter" or "darker" at random
        // (noise); away from it, it is clear.
        let mut b = Bracket::default();
        let mut state = 12345u32;
        let trace = follow(&mut b, 200, |at| {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let coin = (state >> 16) & 1 == 1;
            if at < 9.98 || (at <= 10.02 && coin) {
                0.3
            } else {
                -0.3
            }
        });
        let tail = &trace[50..];
        let (lo, hi) = span(tail);
        // The law's own steps (±0.3 EV) would circle 0.6 EV wide.
        assert!(hi - lo <= 0.15, "circling {lo:.3}–{hi:.3}: {tail:.3?}");
        assert!(
            (lo - 10.0).abs() < 0.08 && (hi - 10.0).abs() < 0.08,
            "{tail:.3?}"
        );
    }

    #[test]
    fn a_law_inside_the_bracket_is_left_alone() {
        let p = BracketParams::default();
        let mut b = Bracket::default();
        b.observe(&p, 8.0, 0.2, step_towards(9.0, 8.0));
        b.observe(&p, 10.0, 0.6, step_towards(9.0, 10.0));
        assert_eq!(b.clamp(9.3), 9.3);
        assert_eq!(b.clamp(10.5), 9.0);
        // Steps in the dead band say nothing.
        b.observe(&p, 9.3, 0.4, 0.001);
        assert_eq!(b.ends(), (Some(8.0), Some(10.0)));
    }
}
