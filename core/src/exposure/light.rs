//! Following a change of light seen against a reference frame.
//!
//! Under a change of light that scales the whole scene (the sun out of a
//! cloud, a tunnel's mouth, a street light), every pixel's radiance moves by
//! one factor `ρ`, and the best exposure moves by `1/ρ`. The gradient
//! estimators cannot see that from a single frame when the change is large:
//! after +4 stops most of the image is saturated and the texture the
//! estimate needs is gone; after −4 stops it sits in the lowest few grey
//! levels. Each frame then gives a short step in the right direction, and
//! every step costs the loop's latency.
//!
//! The pixels that are well exposed in both the new frame and a frame of the
//! same scene before the change measure `ρ` directly, however few they are:
//!
//! ```text
//! ρ = median over pixels p of  (I(p) / E) / (I_ref(p) / E_ref)
//! ```
//!
//! with `E` the exposure each frame was taken with. The best exposure the
//! law predicted on the reference frame, over `ρ`, is the best exposure now.
//!
//! When the scene itself changed (the vehicle moved on, something passed
//! close to the lens) the ratios of co-located pixels disagree. Their spread
//! (the interquartile range of `log2` ratios) tells the two apart: a change
//! of light leaves it at the noise's few hundredths of an EV. A change that
//! is not uniform over the image (a cloud over the sun leaves the shadows
//! as they were) spreads the ratios too, and is left to the law.
//!
//! The reference is a copy of the metered frame's intensities over its
//! exposure (every `stride`-th pixel along each axis: every second by
//! default, about 19 000 at the default metering size). The controller
//! renews it on every frame that shows the camera at rest, in light it
//! could measure, so under motion it compares frames a frame or two apart.

use serde::{Deserialize, Serialize};

use super::metering::Metered;
use super::tone::{self, ToneCurve};
use crate::error::{check_range, Result};
use crate::stats::{quantile, quantiles};

/// Parameters of the light tracking.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LightParams {
    /// A uniform change of light of at least this (EV) is followed.
    pub min_change_ev: f64,
    /// Ratios spread wider than this (interquartile range, EV) mean the
    /// scene changed, not only its light...
    pub max_spread_ev: f64,
    /// ...or wider than this fraction of the change itself, where that is
    /// more. A large change leaves few pixels in range in both frames,
    /// the darker of them noisier (a tunnel's frames carry the gain's
    /// noise): 0.5 EV of spread says nothing against a change of 6 EV,
    /// while a changed scene spreads its ratios about no change at all.
    pub spread_per_ev: f64,
    /// Pixels well exposed in both frames needed for a measurement.
    pub min_pixels: usize,
    /// A pixel counts when its intensity lies in `[low, high]` in both
    /// frames and none of its samples saturated.
    pub low: f32,
    /// See `low`.
    pub high: f32,
    /// The reference keeps every `stride`-th metered pixel along each axis.
    pub stride: usize,
}

impl Default for LightParams {
    fn default() -> Self {
        Self {
            min_change_ev: 0.25,
            max_spread_ev: 0.25,
            spread_per_ev: 0.15,
            min_pixels: 100,
            low: 0.012,
            high: 0.9,
            stride: 2,
        }
    }
}

impl LightParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "light.min_change_ev",
            self.min_change_ev,
            0.01,
            10.0,
            "an EV in [0.01, 10]",
        )?;
        check_range(
            "light.max_spread_ev",
            self.max_spread_ev,
            0.001,
            5.0,
            "an EV in [0.001, 5]",
        )?;
        check_range(
            "light.spread_per_ev",
            self.spread_per_ev,
            0.0,
            0.5,
            "a fraction in [0, 0.5]",
        )?;
        check_range(
            "light.min_pixels",
            self.min_pixels as f64,
            10.0,
            1e7,
            "a pixel count of at least 10",
        )?;
        check_range(
            "light.low",
            f64::from(self.low),
            0.0,
            0.5,
            "an intensity in [0, 0.5]",
        )?;
        check_range(
            "light.high",
            f64::from(self.high),
            f64::from(self.low) + 0.05,
            1.0,
            "an intensity in (low + 0.05, 1]",
        )?;
        check_range(
            "light.stride",
            self.stride as f64,
            1.0,
            64.0,
            "a stride in [1, 64]",
        )?;
        Ok(())
    }
}

/// The light of a frame against the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightChange {
    /// `log2 ρ`: how much brighter the scene is (EV).
    pub ev: f64,
    /// Interquartile range of the pixels' `log2` ratios (EV).
    pub spread_ev: f64,
    /// Pixels compared.
    pub pixels: usize,
    /// The best exposure now: the reference's over `ρ`.
    pub best: f64,
    /// Whether too few pixels stayed in range and `ev` is a bound from
    /// those that left it: the light changed at least this much.
    pub bound: bool,
}

impl LightChange {
    /// Whether this is a uniform change of light large enough to follow.
    pub fn follow(&self, params: &LightParams) -> bool {
        self.uniform(params) && self.ev.abs() >= params.min_change_ev
    }

    /// Whether the pixels agree on one ratio (the scene is the reference's).
    pub fn uniform(&self, params: &LightParams) -> bool {
        let allowed = params
            .max_spread_ev
            .max(params.spread_per_ev * self.ev.abs());
        self.pixels >= params.min_pixels && self.spread_ev <= allowed
    }
}

#[derive(Clone, Debug)]
struct Reference {
    width: usize,
    height: usize,
    stride: usize,
    /// `I / E` per kept pixel; NaN where the pixel does not count.
    radiance: Vec<f32>,
    /// The best exposure the law predicted on the reference frame.
    best: f64,
}

/// The reference frame and what it measures.
#[derive(Clone, Debug, Default)]
pub struct LightTracker {
    reference: Option<Reference>,
    /// The light of each recorded value, when the frames went through a
    /// tone curve ([`LightTracker::set_tone_curve`]).
    linear: Option<Vec<f32>>,
}

/// A metered pixel as the tracking sees it.
enum Pixel {
    /// Outside the metered region.
    Out,
    /// Within `[low, high]` with no saturated sample: its intensity.
    Usable(f32),
    /// Below `low`: its intensity is at most this.
    Dark(f32),
    /// Above `high` or with a saturated sample: at least this.
    Bright(f32),
}

/// A pixel of a metered frame, classified when asked ([`At::pixel`]).
struct At<'a> {
    params: &'a LightParams,
    /// The frame's planes from the pixel's row on (the weights and
    /// saturated samples where it has them).
    luma: &'a [f32],
    weight: Option<&'a [f32]>,
    saturated: Option<&'a [f32]>,
    /// The light of recorded values evenly spaced over `[0, 1]`, for
    /// frames that went through a tone curve.
    linear: Option<&'a [f32]>,
    /// The pixel's column.
    x: usize,
}

impl At<'_> {
    /// The pixel as the tracking sees it, its value as light.
    #[inline(always)]
    fn pixel(&self) -> Pixel {
        let light = |v: f32| match self.linear {
            Some(table) => tone::interpolate(table, v),
            None => v,
        };
        match classify(self.params, self.luma, self.weight, self.saturated, self.x) {
            Pixel::Out => Pixel::Out,
            Pixel::Usable(v) => Pixel::Usable(light(v)),
            Pixel::Dark(v) => Pixel::Dark(light(v)),
            Pixel::Bright(v) => Pixel::Bright(light(v)),
        }
    }
}

/// Calls `f` with every `stride`-th pixel of every `stride`-th row of
/// `metered`, in row-major order, read through `linear` when given. The
/// rows of the metered frame's planes are looked up once a row, and a
/// pixel is classified only when `f` asks.
fn for_each_pixel(
    params: &LightParams,
    metered: &Metered,
    stride: usize,
    linear: Option<&[f32]>,
    mut f: impl FnMut(At<'_>),
) {
    let (w, h) = (metered.width(), metered.height());
    let (luma, weight, saturated) = (
        metered.luma(),
        metered.weight(),
        metered.saturated_samples(),
    );
    // The part of a plane from pixel `start` on.
    fn from(plane: &[f32], start: usize) -> &[f32] {
        plane.get(start..).unwrap_or(&[])
    }
    for y in (0..h).step_by(stride) {
        let (luma, weight, saturated) = (
            from(luma, y * w),
            weight.map(|p| from(p, y * w)),
            saturated.map(|p| from(p, y * w)),
        );
        for x in (0..w).step_by(stride) {
            f(At {
                params,
                luma,
                weight,
                saturated,
                linear,
                x,
            });
        }
    }
}

/// Pixel `k` of the planes `luma`, `weight` and `saturated` (the metered
/// frame's; the weights and saturated samples where it has them).
#[inline(always)]
fn classify(
    params: &LightParams,
    luma: &[f32],
    weight: Option<&[f32]>,
    saturated: Option<&[f32]>,
    k: usize,
) -> Pixel {
    let Some(&v) = luma.get(k) else {
        return Pixel::Out;
    };
    if weight.is_some_and(|w| w.get(k).is_none_or(|&w| w <= 0.0)) {
        return Pixel::Out;
    }
    let clipped = saturated.is_some_and(|s| s.get(k).is_some_and(|&s| s > 0.0));
    if clipped || v > params.high {
        Pixel::Bright(v.max(params.high))
    } else if v < params.low {
        Pixel::Dark(params.low)
    } else {
        Pixel::Usable(v)
    }
}

impl LightTracker {
    /// Forgets the reference.
    pub fn reset(&mut self) {
        self.reference = None;
    }

    /// Reads the frames' values as light through `curve` (frames that went
    /// through a camera's tone curve: a change of light `ρ` moves a
    /// recorded value by `ρ^(1/p)` on a power curve `p`, not by `ρ`), or as
    /// they are (`None`). Forgets the reference when the curve changes.
    pub fn set_tone_curve(&mut self, curve: Option<&ToneCurve>) {
        let linear = curve.map(ToneCurve::linear_lookup);
        if linear != self.linear {
            self.linear = linear;
            self.reference = None;
        }
    }

    /// Whether there is a reference.
    pub fn has_reference(&self) -> bool {
        self.reference.is_some()
    }

    /// Makes `metered`, taken at exposure `taken`, the reference, with
    /// `best` the best exposure the law predicts on it; with fewer than
    /// `min_pixels` pixels in range it leaves no reference.
    pub fn set_reference(
        &mut self,
        params: &LightParams,
        metered: &Metered,
        taken: f64,
        best: f64,
    ) {
        let stride = params.stride.max(1);
        let (w, h) = (metered.width(), metered.height());
        let (width, height) = (w.div_ceil(stride), h.div_ceil(stride));
        let mut radiance = match self.reference.take() {
            Some(r) => r.radiance,
            None => Vec::new(),
        };
        radiance.clear();
        let inv = (1.0 / taken) as f32;
        for_each_pixel(params, metered, stride, self.linear.as_deref(), |at| {
            radiance.push(match at.pixel() {
                Pixel::Usable(v) => v * inv,
                _ => f32::NAN,
            });
        });
        // A frame with too few pixels in range (all but saturated, or all
        // but black) can measure no change: it is no reference, and the
        // next frame at rest is taken instead.
        let usable = radiance.iter().filter(|v| !v.is_nan()).count();
        self.reference = (taken.is_finite()
            && taken > 0.0
            && best.is_finite()
            && best > 0.0
            && usable >= params.min_pixels.max(4))
        .then_some(Reference {
            width,
            height,
            stride,
            radiance,
            best,
        });
    }

    /// Replaces the best exposure of the reference (the exposure finally
    /// commanded on it, when that differs from what the law asked).
    pub fn set_best(&mut self, best: f64) {
        if let Some(r) = self
            .reference
            .as_mut()
            .filter(|_| best.is_finite() && best > 0.0)
        {
            r.best = best;
        }
    }

    /// The light of `metered`, taken at `taken`, against the reference;
    /// `None` without a reference, or when the frame's size differs from
    /// the reference's or too few pixels count in both.
    pub fn change(
        &self,
        params: &LightParams,
        metered: &Metered,
        taken: f64,
    ) -> Option<LightChange> {
        let r = self.reference.as_ref()?;
        let (w, h) = (metered.width(), metered.height());
        if w.div_ceil(r.stride) != r.width
            || h.div_ceil(r.stride) != r.height
            || taken.is_nan()
            || taken <= 0.0
        {
            return None;
        }
        let inv = 1.0 / taken;
        let mut ratios = Vec::with_capacity(r.radiance.len());
        // Ratios known only to be at least (pixels now too bright) or at
        // most (now too dark) this.
        let (mut above, mut below) = (Vec::new(), Vec::new());
        let mut reference = r.radiance.iter();
        for_each_pixel(params, metered, r.stride, self.linear.as_deref(), |at| {
            let Some(&before) = reference.next().filter(|v| !v.is_nan()) else {
                return;
            };
            match at.pixel() {
                Pixel::Usable(v) => ratios.push(v / before),
                Pixel::Bright(v) => above.push(v / before),
                Pixel::Dark(v) => below.push(v / before),
                Pixel::Out => {}
            }
        });
        let ev = |r: f32| (f64::from(r) * inv).log2();
        let change = |ev: f64, spread_ev: f64, pixels: usize, bound: bool| LightChange {
            ev,
            spread_ev,
            pixels,
            best: r.best / ev.exp2(),
            bound,
        };
        let min = params.min_pixels.max(4);
        if ratios.len() >= min {
            // Quantiles of the ratios are the ratios of the quantiles of
            // their logarithms: one log2 per quantile, not per pixel.
            let pixels = ratios.len();
            if let Some([q1, median, q3]) = quantiles(&mut ratios, [0.25, 0.5, 0.75]) {
                return Some(change(ev(median), ev(q3) - ev(q1), pixels, false));
            }
        }
        // Too few pixels left in range: when most of the reference's went
        // out of it the same way, those nearest the edge of the range
        // bound the change (a pixel of the reference just below the level
        // that clips now says the light grew by nearly the whole ratio).
        let all = ratios.len() + above.len() + below.len();
        let (out, q) = if above.len() >= below.len() {
            (&mut above, 1.0 - BOUND_QUANTILE)
        } else {
            (&mut below, BOUND_QUANTILE)
        };
        let pixels = out.len();
        if pixels < min || 2 * pixels <= all {
            return None;
        }
        quantile(out, q).map(|r| change(ev(r), 0.0, pixels, true))
    }
}

/// Of the pixels that left the range, the quantile of their ratios that
/// bounds the change (from the near end): robust to a few that moved.
const BOUND_QUANTILE: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured scene of radiance in (0.01, 1.6), seen at exposure `e`
    /// under light `l`, with a sensor that clips at 1.
    fn frame(w: usize, h: usize, e: f64, l: f64, shift: usize) -> Metered {
        let luma = (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w + shift) as f64, (k / w) as f64);
                let r = 0.01 + 0.8 * (1.0 + (x * 0.37).sin() * (y * 0.23).cos()) + 0.002 * x;
                ((r * e * l) as f32).min(1.0)
            })
            .collect();
        Metered::from_luma(w, h, luma, None).expect("metered")
    }

    #[test]
    fn through_a_tone_curve_the_change_is_measured_as_light() {
        // The frames through a display gamma of 2.2: +2 stops of light move
        // the recorded values by 2/2.2 of a stop.
        let toned = |e: f64, l: f64| {
            let m = frame(160, 120, e, l, 0);
            let luma = m.luma().iter().map(|&v| v.powf(1.0 / 2.2)).collect();
            Metered::from_luma(160, 120, luma, None).expect("metered")
        };
        let p = LightParams::default();
        let (before, after) = (toned(0.25, 1.0), toned(0.25, 4.0));
        let mut plain = LightTracker::default();
        plain.set_reference(&p, &before, 0.25, 0.3);
        let c = plain.change(&p, &after, 0.25).expect("plain");
        assert!((c.ev - 2.0 / 2.2).abs() < 0.02, "{c:?}");
        let mut t = LightTracker::default();
        t.set_tone_curve(Some(&ToneCurve::Power(2.2)));
        t.set_reference(&p, &before, 0.25, 0.3);
        let c = t.change(&p, &after, 0.25).expect("through the curve");
        assert!((c.ev - 2.0).abs() < 0.02 && c.follow(&p), "{c:?}");
        assert!((c.best / (0.3 / 4.0) - 1.0).abs() < 0.02, "{c:?}");
        // A new curve forgets the reference (it was read under the old).
        t.set_tone_curve(None);
        assert!(!t.has_reference());
        t.set_reference(&p, &before, 0.25, 0.3);
        t.set_tone_curve(None);
        assert!(t.has_reference(), "the same curve keeps it");
    }

    /// A camera that comes to rest in a frame all but saturated (a start
    /// far too bright) keeps no reference from it: such a reference
    /// measures nothing, and the next frame at rest must be able to take
    /// its place.
    #[test]
    fn a_frame_with_too_few_pixels_in_range_is_no_reference() {
        let p = LightParams::default();
        let mut t = LightTracker::default();
        let white = frame(160, 120, 0.5, 64.0, 0);
        assert!(white.stats().saturated_fraction > 0.97);
        t.set_reference(&p, &white, 0.5, 0.55);
        assert!(!t.has_reference());
        let black = frame(160, 120, 0.5, 0.001, 0);
        t.set_reference(&p, &black, 0.5, 0.55);
        assert!(!t.has_reference());
        t.set_reference(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5, 0.55);
        assert!(t.has_reference());
    }

    #[test]
    fn a_uniform_change_of_light_is_measured_from_the_pixels_left() {
        let p = LightParams::default();
        let mut t = LightTracker::default();
        let before = frame(160, 120, 0.5, 1.0, 0);
        t.set_reference(&p, &before, 0.5, 0.55);
        // Unchanged: no change to follow.
        let same = t
            .change(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5)
            .expect("same");
        assert!(same.ev.abs() < 1e-4 && !same.follow(&p), "{same:?}");
        // +3 stops at the same exposure: most of the image clips, and the
        // darker pixels still measure the light.
        let bright = frame(160, 120, 0.5, 8.0, 0);
        assert!(bright.stats().saturated_fraction > 0.5);
        let c = t.change(&p, &bright, 0.5).expect("bright");
        assert!(
            (c.ev - 3.0).abs() < 0.01 && !c.bound && c.follow(&p),
            "{c:?}"
        );
        assert!((c.best / (0.55 / 8.0) - 1.0).abs() < 0.01, "{c:?}");
        // +5 stops: too few pixels stay in range; those that clipped say
        // the light grew by at least this much.
        let c = t
            .change(&p, &frame(160, 120, 0.5, 32.0, 0), 0.5)
            .expect("bound");
        assert!(
            c.bound && c.ev > 1.5 && c.ev <= 5.0 && c.follow(&p),
            "{c:?}"
        );
        // −2 stops, measured on a frame taken at twice the exposure.
        let c = t
            .change(&p, &frame(160, 120, 1.0, 0.25, 0), 1.0)
            .expect("dark");
        assert!((c.ev + 2.0).abs() < 0.01 && c.follow(&p), "{c:?}");
    }

    /// [`frame`] with each pixel scaled by `2^n`, `n` uniform in
    /// `[-a/2, a/2]` (a fixed sequence): the ratios' interquartile range
    /// against a noiseless frame is about `a/2`.
    fn noisy(w: usize, h: usize, e: f64, l: f64, a: f64) -> Metered {
        // Rendered 1000× darker so that nothing clips before the noise,
        // then scaled back and clipped.
        let clean = frame(w, h, e * 1e-3, l, 0);
        let mut state = 0x9e37_79b9_u32;
        let luma = clean
            .luma()
            .iter()
            .map(|&v| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                let n = (f64::from(state) / f64::from(u32::MAX) - 0.5) * a;
                ((f64::from(v) * 1e3 * n.exp2()) as f32).min(1.0)
            })
            .collect();
        Metered::from_luma(w, h, luma, None).expect("metered")
    }

    #[test]
    fn a_large_change_is_followed_through_noise_that_a_small_one_is_not() {
        let p = LightParams::default();
        let mut t = LightTracker::default();
        t.set_reference(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5, 0.5);
        // +5 stops seen at 1/64 of the exposure, through noise of about
        // 0.5 EV (interquartile range): the change dwarfs the spread.
        let far = t
            .change(&p, &noisy(160, 120, 0.5 / 64.0, 32.0, 1.0), 0.5 / 64.0)
            .expect("far");
        assert!(
            (far.ev - 5.0).abs() < 0.1 && far.spread_ev > p.max_spread_ev && far.follow(&p),
            "{far:?}"
        );
        // The same noise with a change of 1 stop: as likely a changed
        // scene, not followed.
        let near = t
            .change(&p, &noisy(160, 120, 0.25, 2.0, 1.0), 0.25)
            .expect("near");
        assert!(
            (near.ev - 1.0).abs() < 0.1 && !near.uniform(&p) && !near.follow(&p),
            "{near:?}"
        );
        // With the fraction at 0 only the absolute spread counts.
        let absolute = LightParams {
            spread_per_ev: 0.0,
            ..p
        };
        assert!(!far.follow(&absolute), "{far:?}");
        assert!(LightParams {
            spread_per_ev: 0.6,
            ..p
        }
        .validate()
        .is_err());
    }

    #[test]
    fn a_changed_scene_is_not_taken_for_a_change_of_light() {
        let p = LightParams::default();
        let mut t = LightTracker::default();
        t.set_reference(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5, 0.5);
        let moved = t
            .change(&p, &frame(160, 120, 0.5, 2.0, 7), 0.5)
            .expect("moved");
        assert!(!moved.uniform(&p) && !moved.follow(&p), "{moved:?}");
        // A frame of another size has nothing to compare with.
        assert!(t.change(&p, &frame(80, 60, 0.5, 1.0, 0), 0.5).is_none());
        t.reset();
        assert!(t.change(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5).is_none());
    }

    #[test]
    fn a_frame_that_left_the_range_gives_a_bound_only_when_most_of_it_did() {
        let p = LightParams::default();
        let mut t = LightTracker::default();
        t.set_reference(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5, 0.5);
        // +10 stops: every pixel clips; −12 stops: every pixel is black.
        let up = t
            .change(&p, &frame(160, 120, 0.5, 1024.0, 0), 0.5)
            .expect("up");
        assert!(up.bound && up.ev > 1.0 && up.ev < 10.0, "{up:?}");
        let down = t
            .change(&p, &frame(160, 120, 0.5, 1.0 / 4096.0, 0), 0.5)
            .expect("down");
        assert!(down.bound && down.ev < -1.0 && down.ev > -12.0, "{down:?}");
        // A reference with too few pixels in range measures nothing.
        t.set_reference(&p, &frame(160, 120, 0.5, 1024.0, 0), 0.5, 0.5);
        assert!(t.change(&p, &frame(160, 120, 0.5, 1.0, 0), 0.5).is_none());
    }
}
