//! Cameras with coarse exposure levels: a bracket sequence answered with
//! its nearest image (levels often 1 EV apart), or a camera whose exposure
//! steps are coarse. The controller's laws ask for any exposure; the
//! [`LevelWalker`] turns their requests into levels so that every law ends
//! on the level nearest its fixed point.
//!
//! Rounding each frame's request to the nearest level fails both ways:
//!
//! - **Small steps are lost.** A law whose step from a level is smaller
//!   than half the spacing (Eq. 3 and 4 near their fixed point, a damped
//!   prediction) asks for the level it has on every frame, and the camera
//!   stops one level or more short of its fixed point.
//! - **Carried steps circle.** Adding the requests up instead always
//!   crosses a boundary at last, and between two levels that bracket the
//!   fixed point the camera then goes back and forth.
//!
//! The walker does both halves right:
//!
//! - An incremental law's requests (Eq. 3, Eq. 4, PID, mean-intensity AE,
//!   balancing) add up across the frames at one level until they pass the
//!   midpoint to the next; a predicting law's request (the fast law, a
//!   fixed exposure) is the distance itself and is taken as it is, without
//!   its damping, which on coarse levels only rounds it back. Where the
//!   estimate itself says how far the law's fixed point lies
//!   (scale-and-clip's `ŝ` within the anchors' span: the exposure ratio to
//!   where `ŝ = 1`), an incremental law is placed there at once.
//! - It remembers, per level, the latest request a frame at that level
//!   made (in the same light). When the camera would move to a level whose
//!   frame asked to come back, the fixed point lies between the two, and
//!   the two requests place it: linearly in log exposure,
//!   `x = |s_here| / (|s_here| + |s_there|)` of the way. Where the darker
//!   of the two frames gave the distance in EV ([`Request::Placed`]), that
//!   distance alone places it: a linear sensor's frame predicts brightening
//!   exactly, and the brighter frame's distance overshoots where darkening
//!   would bring back what its saturated pixels hide. The camera moves
//!   only when `x` passes the midpoint by [`SWITCH_MARGIN`], and rests at
//!   the nearer level otherwise.
//! - Before it has seen the level ahead, an incremental law's signals at
//!   the frame's level and the one behind it place the fixed point by a
//!   secant (they shrink towards it); where that lies short of the
//!   midpoint to the level ahead by the same margin, the camera does not
//!   go there (also while a command is in flight: the frame's level is
//!   then behind the one the camera goes to). Nearer the midpoint it goes
//!   and looks.
//!
//! What a level's frame said is forgotten when the frame at the current
//! level contradicts it as a linear sensor would (the light changed): the
//! mean intensities of two frames of one scene at exposures `2^d` apart
//! differ by `2^d` when neither clips, and otherwise by at most `2^d` in
//! the same direction. It is not forgotten with age: a camera resting at
//! the nearer level would otherwise visit the farther one again whenever
//! its memory lapsed, a visible flicker; a drift of light within the
//! check's tolerance moves the request at the current level, which alone
//! can then carry the camera over.

/// Requests smaller than this (EV) leave the camera where it is and clear
/// what it carried.
pub const DEAD_BAND_EV: f64 = 0.03;
/// How far past the midpoint between two levels (a share of their spacing)
/// the placed fixed point must lie for the camera to leave its level.
pub const SWITCH_MARGIN: f64 = 0.1;
/// Two frames whose means differ by their exposure ratio within this (EV)
/// show the same light (neither clipping).
pub const LIGHT_TOLERANCE_EV: f64 = 0.3;
/// Above this saturated fraction (or below this mean) a frame's mean no
/// longer follows its exposure in proportion.
const LINEAR_SATURATED: f64 = 0.02;
const LINEAR_MIN_MEAN: f64 = 0.01;

/// What a frame at a level showed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelFrame {
    /// log2 of the exposure it was taken with.
    pub log2_e: f64,
    /// Its metered mean intensity, [0, 1].
    pub mean: f64,
    /// Its saturated fraction.
    pub saturated: f64,
}

/// How a law's request is read ([`LevelWalker::step`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Request {
    /// A step towards the fixed point, repeated on every frame while the
    /// camera stays: added up across frames.
    Incremental,
    /// The distance to the fixed point itself: taken as it is.
    Predicted,
    /// An incremental law whose estimate also says where its fixed point
    /// lies: this far from the frame, EV. Placed there without waiting for
    /// the steps to add up.
    Placed(f64),
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Seen {
    /// Where the frame places the fixed point: a signed measure that is
    /// zero there and grows with the distance (only ratios are used).
    signal: f64,
    /// The distance to the fixed point in EV, where the estimate gave it
    /// ([`Request::Placed`]).
    placed: Option<f64>,
    frame: LevelFrame,
}

/// Where a camera with fixed levels goes (module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct LevelWalker {
    /// log2 of the levels, ascending.
    levels: Vec<f64>,
    /// The levels themselves (sent exactly as the camera gave them).
    exact: Vec<f64>,
    seen: Vec<Option<Seen>>,
    /// The request added up at `carried_at`.
    carried_ev: f64,
    carried_at: Option<usize>,
}

impl LevelWalker {
    /// A walker over `levels` (exposure levels, any order; levels that are
    /// not positive and finite are left out); `None` without any.
    pub fn new(levels: &[f64]) -> Option<Self> {
        let mut exact: Vec<f64> = levels
            .iter()
            .copied()
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        exact.sort_by(f64::total_cmp);
        exact.dedup_by(|a, b| (a.log2() - b.log2()).abs() < 1e-9);
        (!exact.is_empty()).then(|| Self {
            seen: vec![None; exact.len()],
            levels: exact.iter().map(|v| v.log2()).collect(),
            exact,
            carried_ev: 0.0,
            carried_at: None,
        })
    }

    /// The exposure levels, ascending.
    pub fn levels(&self) -> impl Iterator<Item = f64> + '_ {
        self.exact.iter().copied()
    }

    /// Forgets what the frames said.
    pub fn reset(&mut self) {
        self.seen.iter_mut().for_each(|s| *s = None);
        self.carried_ev = 0.0;
        self.carried_at = None;
    }

    /// The index of the level nearest `log2_e`.
    fn nearest(&self, log2_e: f64) -> usize {
        let mut best = (0, f64::INFINITY);
        for (k, l) in self.levels.iter().enumerate() {
            let d = (l - log2_e).abs();
            if d < best.1 {
                best = (k, d);
            }
        }
        best.0
    }

    /// The level nearest `exposure` (for a command that is not a law's
    /// request, such as a probe).
    pub fn round(&self, exposure: f64) -> f64 {
        self.exact[self.nearest(exposure.max(f64::MIN_POSITIVE).log2())]
    }

    /// Whether `seen` (a frame at another level) shows the light of
    /// `frame`.
    fn same_light(seen: &LevelFrame, frame: &LevelFrame) -> bool {
        let d = seen.log2_e - frame.log2_e;
        let ratio = (seen.mean.max(1e-6) / frame.mean.max(1e-6)).log2();
        let linear = |f: &LevelFrame| f.saturated <= LINEAR_SATURATED && f.mean >= LINEAR_MIN_MEAN;
        if linear(seen) && linear(frame) {
            (ratio - d).abs() <= LIGHT_TOLERANCE_EV
        } else {
            // Clipping only slows the growth of the mean with exposure.
            ratio >= d.min(0.0) - LIGHT_TOLERANCE_EV && ratio <= d.max(0.0) + LIGHT_TOLERANCE_EV
        }
    }

    /// Whether the signals at `here` and at the level behind it (opposite
    /// `dir`; the same sign, larger) place the fixed point, extrapolated
    /// linearly in log exposure, short of the midpoint between `from` and
    /// the level after it in `dir` by more than [`SWITCH_MARGIN`] of their
    /// spacing.
    fn crossing_short_of_midpoint(
        &self,
        here: usize,
        dir: isize,
        signal: f64,
        from: usize,
    ) -> bool {
        let (behind, next) = (here as isize - dir, from as isize + dir);
        let n = self.levels.len() as isize;
        if behind < 0 || behind >= n || next < 0 || next >= n {
            return false;
        }
        let (behind, next) = (behind as usize, next as usize);
        let Some(s) = self.seen[behind] else {
            return false;
        };
        let (near, far) = (signal.abs(), s.signal.abs());
        if s.signal * signal <= 0.0 || far <= near * 1.05 {
            return false;
        }
        let d = dir as f64;
        let crossing = self.levels[here]
            + d * near * (self.levels[here] - self.levels[behind]).abs() / (far - near);
        let spacing = (self.levels[next] - self.levels[from]).abs();
        let midpoint = 0.5 * (self.levels[next] + self.levels[from]);
        d * (crossing - midpoint) < -SWITCH_MARGIN * spacing
    }

    /// The level to send after a frame taken at `frame.log2_e` whose law
    /// asks for `step_ev` from the frame's own exposure (log2 of desired
    /// over taken), read as `request` says; `base` is the exposure the
    /// camera will have once the commands in flight show (the frame's own
    /// when none is). As in continuous control, a frame taken before the
    /// last command showed adds its step to where that command leaves the
    /// camera.
    pub fn step(
        &mut self,
        frame: LevelFrame,
        base: f64,
        step_ev: f64,
        signal: f64,
        request: Request,
    ) -> f64 {
        let here = self.nearest(frame.log2_e);
        let at = self.nearest(base.max(f64::MIN_POSITIVE).log2());
        for (k, s) in self.seen.iter_mut().enumerate() {
            if k != here && s.is_some_and(|s| !Self::same_light(&s.frame, &frame)) {
                *s = None;
            }
        }
        let step_ev = if step_ev.is_finite() { step_ev } else { 0.0 };
        let signal = if signal.is_finite() { signal } else { 0.0 };
        let placed = match request {
            Request::Placed(d) if d.is_finite() => Some(d),
            _ => None,
        };
        self.seen[here] = Some(Seen {
            signal,
            placed,
            frame,
        });
        if self.carried_at != Some(at) {
            self.carried_ev = 0.0;
            self.carried_at = Some(at);
        }
        // From `at`: an incremental law's steps add up while they point
        // the same way (small ones too: noise cancels, a slow drift does
        // not); a prediction is of the fixed point, seen from the frame.
        let wanted = match request {
            Request::Incremental if self.carried_ev * step_ev >= 0.0 => self.carried_ev + step_ev,
            Request::Incremental => step_ev,
            Request::Predicted => step_ev - (self.levels[at] - self.levels[here]),
            Request::Placed(d) if d.is_finite() => d - (self.levels[at] - self.levels[here]),
            Request::Placed(_) => 0.0,
        };
        self.carried_ev = match request {
            Request::Incremental => wanted,
            Request::Predicted | Request::Placed(_) => 0.0,
        };
        if wanted.abs() < DEAD_BAND_EV {
            return self.exact[at];
        }
        let goal = self.levels[at] + wanted;
        let dir: isize = if wanted > 0.0 { 1 } else { -1 };
        // Placed by the signals: the latest at `at` (this frame's, unless a
        // command is in flight), or this frame's where `at` has none.
        let (mut from, mut from_signal) = (at, self.seen[at].map_or(signal, |s| s.signal));
        let mut from_placed = self.seen[at].map_or(placed, |s| s.placed);
        let mut rest = false;
        loop {
            let next = from as isize + dir;
            if next < 0 || next as usize >= self.levels.len() {
                break;
            }
            let next = next as usize;
            let (a, b) = (self.levels[from], self.levels[next]);
            match self.seen[next].filter(|s| s.signal * wanted < 0.0) {
                // The fixed point lies between the two: place it.
                Some(s) => {
                    // Where the darker of the two frames gives the
                    // distance in EV, it places the fixed point: a linear
                    // sensor's frame predicts brightening exactly, while
                    // the brighter frame cannot see what darkening brings
                    // back under its saturated pixels (its distance
                    // overshoots). Otherwise the signals place it,
                    // linearly.
                    let (darker, placed) = if b > a {
                        (a, from_placed)
                    } else {
                        (b, s.placed)
                    };
                    let x = match placed {
                        Some(d) => ((darker + d - a) / (b - a)).clamp(0.0, 1.0),
                        None => from_signal.abs() / (from_signal.abs() + s.signal.abs()),
                    };
                    let margin = if from == at { SWITCH_MARGIN } else { 0.0 };
                    if x > 0.5 + margin {
                        from = next;
                    } else {
                        rest = true;
                    }
                    break;
                }
                // An incremental law's steps shrink towards its fixed
                // point: where the step behind and the step here place it
                // (a secant) well short of the midpoint, the camera stays.
                None if request == Request::Incremental
                    && self.crossing_short_of_midpoint(here, dir, signal, from) =>
                {
                    rest = true;
                    break;
                }
                None if (goal - b).abs() < (goal - a).abs() => {
                    from = next;
                    from_signal = self.seen[next].map_or(signal, |s| s.signal);
                    from_placed = self.seen[next].and_then(|s| s.placed);
                }
                None => break,
            }
        }
        if from != at {
            self.carried_ev = 0.0;
            self.carried_at = None;
        } else if rest {
            // The camera rests here by what the levels said: nothing to
            // carry.
            self.carried_ev = 0.0;
        }
        self.exact[from]
    }
}

#[cfg(test)]
// The walker sends the levels it was given, exactly.
#[allow(clippy::float_cmp)]
mod tests {
    use super::*;

    /// Levels 1 EV apart, 2^0 … 2^6.
    fn walker() -> LevelWalker {
        LevelWalker::new(&(0..7).map(|k| f64::from(k).exp2()).collect::<Vec<_>>()).unwrap()
    }

    /// A frame of a linear scene whose mean is 0.5 at 2^`fixed` (never
    /// clipping, so that the light check sees one scene).
    fn frame(log2_e: f64, fixed: f64) -> LevelFrame {
        LevelFrame {
            log2_e,
            mean: 0.5 * (log2_e - fixed).exp2(),
            saturated: 0.0,
        }
    }

    /// Runs a law that asks for `gain` of the distance to `fixed` from
    /// level 0 for `frames` frames (no latency); returns the levels.
    fn run(
        w: &mut LevelWalker,
        fixed: f64,
        gain: f64,
        request: Request,
        frames: usize,
    ) -> Vec<f64> {
        let mut at = 0.0f64;
        (0..frames)
            .map(|_| {
                let step = gain * (fixed - at);
                at = w
                    .step(frame(at, fixed), at.exp2(), step, step, request)
                    .log2();
                at
            })
            .collect()
    }

    #[test]
    fn small_incremental_steps_add_up_to_the_nearest_level_and_rest_there() {
        for fixed in [2.3, 2.7, 4.2, 5.8] {
            let mut w = walker();
            // A tenth of the distance per frame: never half a level alone
            // near the fixed point.
            let trace = run(&mut w, fixed, 0.1, Request::Incremental, 120);
            let nearest = fixed.round();
            assert!(
                trace[60..].iter().all(|&l| l == nearest),
                "fixed {fixed}: {trace:?}"
            );
        }
    }

    #[test]
    fn a_prediction_goes_to_the_nearest_level_at_once_and_is_not_added_up() {
        let mut w = walker();
        let trace = run(&mut w, 3.4, 1.0, Request::Predicted, 5);
        assert_eq!(trace, vec![3.0; 5]);
        let mut w = walker();
        let trace = run(&mut w, 0.45, 1.0, Request::Predicted, 5);
        assert_eq!(trace, vec![0.0; 5]);
    }

    #[test]
    fn a_placed_request_goes_to_the_level_nearest_the_fixed_point_at_once() {
        // A small step whose estimate puts the fixed point 2.4 EV away.
        let mut w = walker();
        let f = frame(1.0, 3.4);
        assert_eq!(w.step(f, 2.0, 0.1, 0.1, Request::Placed(2.4)), 8.0);
        // While that command is in flight, the same frame asks for the same
        // level, not for a step beyond it.
        assert_eq!(w.step(f, 8.0, 0.1, 0.1, Request::Placed(2.4)), 8.0);
        assert_eq!(
            w.step(frame(3.0, 3.4), 8.0, 0.05, 0.05, Request::Placed(0.4)),
            8.0
        );
    }

    /// Between two levels that bracket the fixed point, the darker frame's
    /// distance places it: from level 2 the fixed point is 0.7 EV up (2.7,
    /// nearer 3), while level 3's frame, seeing less under its saturated
    /// pixels, puts it 0.7 EV down (2.3). Weighing the two signals alike
    /// would put it at the midpoint, where the walker stays wherever it is.
    #[test]
    fn the_darker_frames_distance_places_the_fixed_point() {
        let mut w = walker();
        let at = |l: f64| LevelFrame {
            log2_e: l,
            mean: 0.3,
            saturated: 0.1,
        };
        // Level 3 seen first (the camera came from above), then level 2.
        assert_eq!(w.step(at(3.0), 8.0, -0.7, -0.7, Request::Placed(-0.7)), 4.0);
        assert_eq!(w.step(at(2.0), 4.0, 0.7, 0.7, Request::Placed(0.7)), 8.0);
        // Back at 3 the brighter frame still says −0.7: the camera stays.
        for _ in 0..5 {
            assert_eq!(w.step(at(3.0), 8.0, -0.7, -0.7, Request::Placed(-0.7)), 8.0);
        }
        // Without distances (signals alone) the same requests leave the
        // camera where it is, at the midpoint.
        let mut w = walker();
        assert_eq!(w.step(at(3.0), 8.0, -0.7, -0.7, Request::Incremental), 4.0);
        assert_eq!(w.step(at(2.0), 4.0, 0.7, 0.7, Request::Incremental), 4.0);
    }

    #[test]
    fn a_fixed_point_between_two_levels_is_placed_by_both_requests() {
        // The law asks +0.3 from level 2 and −0.7 from level 3: the fixed
        // point lies 0.3 of the way, nearer 2. The requests at 2 add up and
        // take the camera to 3 once; from 3 it goes back to 2 and then
        // stays, however long.
        let mut w = walker();
        let f = |e: f64| frame(e, 2.3);
        assert_eq!(
            w.step(f(2.0), 2.0f64.exp2(), 0.3, 0.3, Request::Incremental),
            4.0
        );
        assert_eq!(
            w.step(f(2.0), 2.0f64.exp2(), 0.3, 0.3, Request::Incremental),
            8.0
        );
        assert_eq!(
            w.step(f(3.0), 3.0f64.exp2(), -0.7, -0.7, Request::Incremental),
            4.0
        );
        for _ in 0..200 {
            assert_eq!(
                w.step(f(2.0), 2.0f64.exp2(), 0.3, 0.3, Request::Incremental),
                4.0
            );
        }
        // Within the margin of the midpoint the camera stays where it is:
        // +0.45 from 2 and −0.55 from 3 place it at 2.45.
        let mut w = walker();
        let f = |e: f64| frame(e, 2.45);
        w.step(f(2.0), 2.0f64.exp2(), 0.45, 0.45, Request::Incremental);
        assert_eq!(
            w.step(f(2.0), 2.0f64.exp2(), 0.45, 0.45, Request::Incremental),
            8.0
        );
        for _ in 0..20 {
            assert_eq!(
                w.step(f(3.0), 3.0f64.exp2(), -0.55, -0.55, Request::Incremental),
                8.0
            );
        }
    }

    #[test]
    fn a_change_of_light_forgets_what_the_other_levels_said() {
        let mut w = walker();
        // Level 3 asked to come down in the old light.
        w.step(
            frame(3.0, 2.3),
            3.0f64.exp2(),
            -0.7,
            -0.7,
            Request::Incremental,
        );
        // Two stops less light: level 2 is now far too dark, and its mean
        // no longer matches level 3's over their exposure ratio.
        let mut at = 2.0;
        for _ in 0..10 {
            at = w
                .step(
                    frame(at, 4.3),
                    at.exp2(),
                    0.5 * (4.3 - at),
                    4.3 - at,
                    Request::Incremental,
                )
                .log2();
        }
        assert_eq!(at, 4.0);
        // Without the check, the old request at 3 would have held it at 2.
    }

    #[test]
    fn the_ends_hold_and_bad_input_is_harmless() {
        let mut w = walker();
        assert_eq!(
            w.step(frame(6.0, 9.0), 6.0f64.exp2(), 3.0, 3.0, Request::Predicted),
            64.0
        );
        assert_eq!(
            w.step(
                frame(0.0, -3.0),
                0.0f64.exp2(),
                -3.0,
                -3.0,
                Request::Predicted
            ),
            1.0
        );
        assert_eq!(
            w.step(
                frame(2.0, 2.0),
                2.0f64.exp2(),
                f64::NAN,
                f64::NAN,
                Request::Incremental
            ),
            4.0
        );
        assert!(LevelWalker::new(&[0.0, f64::NAN, -1.0]).is_none());
        assert_eq!(w.round(5.0), 4.0);
        assert_eq!(w.round(6.0), 8.0);
    }
}
