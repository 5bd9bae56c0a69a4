//! What the view shows of each camera: display gains that leave the
//! cameras' exposures alone.
//!
//! Two things would make the view flicker or step although the control is
//! right:
//!
//! - **Deliberate exposure jumps.** A probe frame is taken darker on
//!   purpose; shown as it is, its camera's part of the view darkens for a
//!   set or two. The view shows such a frame at its camera's *display
//!   exposure* `D`: its samples scaled by `D / E_taken` (a linear sensor's
//!   brightness follows its exposure; through a camera's tone curve, the
//!   nearest power's `(D / E_taken)^(1/p)`, and the scene read from the
//!   mean's light) and clipped where the sensor clips,
//!   before the view interpolates them. `D` is the exposure of the camera's
//!   latest frame that was not a probe. The same holds for any frame whose
//!   exposure dropped by more than `ease_ev` while the scene stayed the
//!   same (its mean intensity moved with the exposure): `D` then moves
//!   towards the new exposure by `ease_ev` per set, so the view darkens
//!   gradually. A brighter jump is shown as it is (easing it would take a
//!   gain below 1, which shows what the camera clipped as grey), and when
//!   the scene changed (the light), `D` follows at once.
//! - **Residual seams.** Balancing keeps each camera's information but
//!   leaves brightness steps where the cameras meet. With `compensate` on,
//!   each camera also gets a gain `2^c_k` that minimises the brightness
//!   ratios across the overlaps as the view shows them, in the least-squares
//!   sense with a prior that keeps gains near 1 (as OpenCV's stitcher's
//!   gain compensation does): `Σ_(i,j) (log2 r_ij + c_j − c_i)² + λ Σ c_k²`,
//!   over the pairs whose ratio was measured, shifted so that the smallest
//!   is 1. The ratios are the ones the view shows: the median log ratio of
//!   the two cameras' pixels near each seam (`surround::SeamBands`), where
//!   the overlap patches' `r_ij` (the balancing's) is a median over the
//!   whole overlap (gains that evened the patches out to 0.02 EV left
//!   0.11 EV at a seam); a seam with no usable pixel falls back to its
//!   patches. The panorama uses its matched patches' ratios instead: its
//!   seams join the same point only at the cylinder's radius, and the
//!   pixels either side of a seam show different things elsewhere
//!   (parallax). Pixels either camera
//!   clips are left out (Eq. 5's rule), so clipped areas do not pull the
//!   gains. The gains brighten only (what a camera clipped stays white),
//!   unless that would push a camera's 90th percentile past 0.95: then all
//!   of them move down together by what that camera lacks, so that the
//!   seams stay even and the cameras with room are shown darker instead
//!   of the brighter camera washed out (the panorama's cameras see sky
//!   and shade side by side, the surround view's front camera sunlit
//!   ground beside shaded sides). The
//!   gains move `smoothing` of the way to the
//!   solution each set, and hold on a set with a probe frame (it sees
//!   patches that its camera's normal frames saturate).
//!
//! Neither touches the telemetry: `r_ij`, M and the exposures are the
//! cameras'.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::{check_range, Result};

/// How the view shows the cameras.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DisplaySettings {
    /// Display gains that even out the brightness across the seams.
    pub compensate: bool,
    /// λ, the prior that keeps the seam gains near 1 (per pair's weight 1).
    pub prior: f64,
    /// The fraction of the way to the new seam gains taken per set.
    pub smoothing: f64,
    /// Exposure jumps (EV) above which the view eases to a camera's new
    /// exposure while its scene stays the same.
    pub ease_ev: f64,
}

impl Default for DisplaySettings {
    fn default() -> Self {
        Self {
            compensate: true,
            prior: 0.01,
            smoothing: 0.3,
            ease_ev: 0.25,
        }
    }
}

impl DisplaySettings {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "display.prior",
            self.prior,
            1e-6,
            1e3,
            "a positive weight up to 1000",
        )?;
        check_range(
            "display.smoothing",
            self.smoothing,
            1e-3,
            1.0,
            "a fraction in (0, 1]",
        )?;
        check_range(
            "display.ease_ev",
            self.ease_ev,
            0.01,
            4.0,
            "an exposure step in EV in [0.01, 4]",
        )?;
        Ok(())
    }
}

/// A change of `log2(mean / exposure)` below this (EV) counts as the same
/// scene.
const SAME_SCENE_EV: f64 = 0.15;

/// The largest display gain either way (the composer takes 1/16 to 16).
const MAX_GAIN_EV: f64 = 4.0;

/// The largest seam gain (EV), either way: compensation evens out the
/// residual steps that balancing leaves (tenths of an EV to about one), not
/// the stops between cameras each under its own law, which it would blow
/// out (or, moved down, black out).
const MAX_SEAM_EV: f64 = 2.0;

/// One camera's frame as the display sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayInput {
    /// The exposure the frame was taken with.
    pub taken: f64,
    /// Its mean intensity in [0, 1].
    pub mean: f64,
    /// Whether it was taken at a probe's exposure (darker, or brighter).
    pub probe_frame: bool,
    /// The [`BRIGHT_QUANTILE`]-quantile of its metered intensities in
    /// [0, 1] (the pixels the view shows, about): a seam gain brightens
    /// this no further than [`CLIP_LEVEL`]. 0: no such limit.
    pub bright: f64,
    /// The camera's tone curve as the nearest power `p` (`L = I^p`;
    /// [`crate::exposure::ToneCurve::nearest_power`]), 1 for a linear
    /// camera: a ratio of light `r` records as `r^(1/p)`, so the frame
    /// shown at the display exposure takes the gain `(D / E_taken)^(1/p)`
    /// on its recorded values.
    pub power: f64,
}

/// The quantile of a camera's metered intensities that a seam gain may not
/// push past [`CLIP_LEVEL`]: at most a tenth of its pixels are clipped by
/// the gain.
pub const BRIGHT_QUANTILE: f32 = 0.9;

/// The brightest a seam gain may make a camera's [`BRIGHT_QUANTILE`].
pub const CLIP_LEVEL: f64 = 0.95;

/// One camera's display gain, in two parts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayGain {
    /// `D / E_taken`: the frame shown at its camera's display exposure (a
    /// probe frame or an eased jump; 1 otherwise). The view applies it to
    /// the camera's samples before interpolating them, so that what the
    /// sensor clipped stays clipped.
    pub exposure: f32,
    /// The seam gain `2^c_k`.
    pub seam: f32,
}

impl DisplayGain {
    /// Both parts together, within the composer's 1/16 to 16.
    pub fn total(self) -> f32 {
        let ev = f64::from(self.exposure * self.seam).log2();
        ev.clamp(-MAX_GAIN_EV, MAX_GAIN_EV).exp2() as f32
    }
}

/// The display gains of a rig, set by set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DisplayGains {
    /// Per camera, the display exposure and the scene's
    /// `log2(mean / exposure)` of its latest frame that was not a probe.
    held: Vec<Option<(f64, f64)>>,
    /// Per camera, the seam gain `c_k` (log2).
    seam: Vec<f64>,
}

impl DisplayGains {
    /// Forgets every camera's history (a new rig or calibration).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Takes a set: each camera's frame, and per overlap `(i, j, log2 r_ij)`
    /// as measured on the frames. Returns each camera's display gain.
    pub fn update(
        &mut self,
        settings: &DisplaySettings,
        frames: &[DisplayInput],
        log2_r: &[(usize, usize, Option<f64>)],
    ) -> Vec<DisplayGain> {
        let n = frames.len();
        if self.held.len() != n {
            self.held = vec![None; n];
            self.seam = vec![0.0; n];
        }
        // Per camera, log2(D / taken), in light.
        let mut ease = vec![0.0; n];
        let power = |f: &DisplayInput| {
            if f.power.is_finite() && f.power > 0.0 {
                f.power
            } else {
                1.0
            }
        };
        for (k, f) in frames.iter().enumerate() {
            if !(f.taken.is_finite() && f.taken > 0.0) {
                self.held[k] = None;
                continue;
            }
            let e = f.taken.log2();
            // The scene's light: the mean's, through the camera's curve.
            let light = f.mean.max(1e-4).powf(power(f));
            let scene = (light.max(1e-12) / f.taken).log2();
            match (self.held[k], f.probe_frame) {
                // A darker probe frame is shown at the display exposure; a
                // brighter one (a mostly black camera probing up) as taken,
                // like any brighter jump: darkened, what it clipped would
                // show grey, and black at its last rung 4.5 EV up.
                (Some((d, _)), true) => ease[k] = (d - e).max(0.0),
                (None, true) => {}
                (Some((d, last_scene)), false) => {
                    let jump = e - d;
                    let same = (scene - last_scene).abs() < SAME_SCENE_EV;
                    // Only a darker jump is eased: easing a brighter one
                    // would show the frame darker than taken, and what it
                    // clipped as grey.
                    let shown = if jump < -settings.ease_ev && same {
                        d - settings.ease_ev
                    } else {
                        e
                    };
                    ease[k] = shown - e;
                    self.held[k] = Some((shown, scene));
                }
                (None, false) => self.held[k] = Some((e, scene)),
            }
        }
        // The same on the recorded values the view scales.
        for (a, f) in ease.iter_mut().zip(frames) {
            *a /= power(f);
        }
        if !settings.compensate {
            self.seam.iter_mut().for_each(|c| *c = 0.0);
        } else if !frames.iter().any(|f| f.probe_frame) {
            // A probe frame sees patches its normal frames saturate: its
            // ratios are of other patches, and the seam gains hold.
            let mut target = seam_gains(n, log2_r, &ease, settings.prior);
            // Brighten only: a gain below 1 would show the pixels a camera
            // clipped as grey (a probe frame, which clips fewer, would then
            // show them brighter than its neighbours in time)...
            let lowest = target.iter().copied().fold(f64::INFINITY, f64::min);
            if lowest.is_finite() {
                target.iter_mut().for_each(|c| *c -= lowest);
            }
            // ...unless that washes a camera out: no gain may push a
            // camera's bright pixels past `CLIP_LEVEL` (a camera of the
            // panorama seeing the sky beside a dark wall; the surround
            // view's front camera on sunlit ground beside shaded sides).
            // Then every gain moves down by what the tightest camera
            // lacks: the seams stay even, and the cameras with room are
            // shown darker (what they clipped as light grey) rather than
            // that camera white.
            let excess = target
                .iter()
                .zip(frames)
                .zip(&ease)
                .filter(|((_, f), _)| f.bright > 0.0)
                .map(|((c, f), a)| c - ((CLIP_LEVEL / f.bright).log2() - a).max(0.0))
                .fold(0.0, f64::max);
            target
                .iter_mut()
                .for_each(|c| *c = (*c - excess).clamp(-MAX_SEAM_EV, MAX_SEAM_EV));
            for (c, t) in self.seam.iter_mut().zip(target) {
                *c += settings.smoothing * (t - *c);
            }
        }
        ease.iter()
            .zip(&self.seam)
            .map(|(a, c)| DisplayGain {
                exposure: a.clamp(-MAX_GAIN_EV, MAX_GAIN_EV).exp2() as f32,
                seam: c.exp2() as f32,
            })
            .collect()
    }
}

/// The seam gains (log2) that minimise `Σ (log2 r_ij + a_j − a_i + c_j −
/// c_i)² + λ Σ c_k²` over the measured pairs, where `a` is each camera's
/// gain already applied (`ease`).
fn seam_gains(
    n: usize,
    log2_r: &[(usize, usize, Option<f64>)],
    ease: &[f64],
    prior: f64,
) -> Vec<f64> {
    let mut a = DMatrix::<f64>::identity(n, n) * prior;
    let mut b = DVector::<f64>::zeros(n);
    for &(i, j, r) in log2_r {
        let Some(r) = r.filter(|r| r.is_finite()) else {
            continue;
        };
        if i >= n || j >= n || i == j {
            continue;
        }
        // Residual r' + c_j − c_i with r' the ratio as shown.
        let shown = r + ease[j] - ease[i];
        a[(i, i)] += 1.0;
        a[(j, j)] += 1.0;
        a[(i, j)] -= 1.0;
        a[(j, i)] -= 1.0;
        b[i] += shown;
        b[j] -= shown;
    }
    a.cholesky()
        .map_or_else(|| vec![0.0; n], |c| c.solve(&b).iter().copied().collect())
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // gains of exactly 1
mod tests {
    use super::*;

    fn total(gains: &[DisplayGain]) -> Vec<f32> {
        gains.iter().map(|g| g.total()).collect()
    }

    fn frame(taken: f64, mean: f64, probe_frame: bool) -> DisplayInput {
        DisplayInput {
            taken,
            mean,
            probe_frame,
            bright: 0.0,
            power: 1.0,
        }
    }

    /// Through a tone curve `L = I^2.2`, a ratio of light `r` records as
    /// `r^(1/2.2)`: a probe 1 EV darker is shown brightened by `2^(1/2.2)`
    /// on its recorded values, and a darker jump whose mean moved as the
    /// curve says is the same scene and eased (read as linear, its mean
    /// had fallen only 0.45 EV for 1 EV of exposure: a change of light,
    /// followed at once).
    #[test]
    fn through_a_tone_curve_the_gains_are_of_light() {
        let s = DisplaySettings {
            compensate: false,
            ..Default::default()
        };
        let toned = |taken: f64, mean: f64, probe: bool| DisplayInput {
            power: 2.2,
            ..frame(taken, mean, probe)
        };
        // (0.5 of light records as 0.5^(1/2.2).)
        let half = 0.5f64.powf(1.0 / 2.2);
        let mut d = DisplayGains::default();
        d.update(&s, &[toned(1000.0, 0.4, false)], &[]);
        let g = d.update(&s, &[toned(500.0, 0.4 * half, true)], &[])[0];
        let want = 2f64.powf(1.0 / 2.2);
        assert!((f64::from(g.exposure) - want).abs() < 1e-5, "{g:?}");
        // A darker jump of 1 EV in the same scene: eased, shown brighter
        // than taken by 0.75 EV of light at first.
        let mut d = DisplayGains::default();
        d.update(&s, &[toned(2000.0, 0.8, false)], &[]);
        let g = d.update(&s, &[toned(1000.0, 0.8 * half, false)], &[])[0];
        let shown = f64::from(g.exposure).log2() * 2.2;
        assert!((shown - 0.75).abs() < 1e-4, "{g:?}");
        // The same frames read as linear: a change of light, no easing.
        let mut d = DisplayGains::default();
        d.update(&s, &[frame(2000.0, 0.8, false)], &[]);
        let g = d.update(&s, &[frame(1000.0, 0.8 * half, false)], &[])[0];
        assert_eq!(g.exposure, 1.0, "{g:?}");
    }

    #[test]
    fn a_probe_frame_is_shown_at_the_exposure_before_it() {
        let s = DisplaySettings {
            compensate: false,
            ..Default::default()
        };
        let mut d = DisplayGains::default();
        assert_eq!(
            total(&d.update(&s, &[frame(1000.0, 0.4, false)], &[])),
            &[1.0]
        );
        // A probe 1 EV darker: shown twice as bright, in its samples.
        let g = d.update(&s, &[frame(500.0, 0.2, true)], &[])[0];
        assert!((g.exposure - 2.0).abs() < 1e-6 && g.seam == 1.0, "{g:?}");
        // Back at its exposure: as it is.
        assert_eq!(
            total(&d.update(&s, &[frame(1000.0, 0.4, false)], &[])),
            &[1.0]
        );
        // A probe 1.5 EV brighter: shown as taken, not darkened (what it
        // clipped would show grey).
        let g = d.update(&s, &[frame(1000.0 * 1.5f64.exp2(), 0.9, true)], &[])[0];
        assert!(g.exposure == 1.0 && g.seam == 1.0, "{g:?}");
    }

    #[test]
    fn a_darker_jump_in_one_scene_is_eased_and_a_change_of_light_is_followed() {
        let s = DisplaySettings {
            compensate: false,
            ..Default::default()
        };
        let mut d = DisplayGains::default();
        d.update(&s, &[frame(2000.0, 0.8, false)], &[]);
        // The controller jumps 1 EV darker, the scene unchanged: the view
        // eases there by 0.25 EV a set.
        let mut shown = Vec::new();
        for _ in 0..5 {
            let g = d.update(&s, &[frame(1000.0, 0.4, false)], &[])[0];
            shown.push(f64::from(g.exposure).log2() - 1.0);
        }
        let expect = [-0.25, -0.5, -0.75, -1.0, -1.0];
        for (s, e) in shown.iter().zip(expect) {
            assert!((s - e).abs() < 1e-6, "{shown:?}");
        }
        // A brighter jump is shown as it is.
        assert_eq!(
            total(&d.update(&s, &[frame(2000.0, 0.8, false)], &[])),
            &[1.0]
        );
        // Two stops less light and the camera 2 EV brighter: the frame
        // looks the same, and is shown as it is.
        d.update(&s, &[frame(1000.0, 0.4, false)], &[]);
        let g = d.update(&s, &[frame(4000.0, 0.4, false)], &[])[0].total();
        assert!((g - 1.0).abs() < 1e-6, "{g}");
    }

    #[test]
    fn seam_gains_even_out_the_measured_ratios() {
        let s = DisplaySettings {
            smoothing: 1.0,
            prior: 1e-4,
            ..Default::default()
        };
        let mut d = DisplayGains::default();
        let frames = [frame(1000.0, 0.4, false); 4];
        // A ring of four: camera 1 sees the overlaps 0.5 EV brighter than
        // its neighbours.
        let r = [
            (0, 1, Some(0.5)),
            (1, 2, Some(-0.5)),
            (2, 3, Some(0.0)),
            (3, 0, Some(0.0)),
        ];
        let g: Vec<f64> = d
            .update(&s, &frames, &r)
            .iter()
            .map(|g| f64::from(g.seam).log2())
            .collect();
        for &(i, j, r) in &r {
            let shown = r.unwrap_or(0.0) + g[j] - g[i];
            assert!(shown.abs() < 0.01, "{i}-{j}: {shown} ({g:?})");
        }
        // Gains only brighten: the darkest camera is shown as it is.
        let lowest = g.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(lowest.abs() < 1e-6, "{g:?}");
        // A pair with no ratio pulls nothing; off, the gains are 1.
        let off = DisplaySettings {
            compensate: false,
            ..s
        };
        assert!(d.update(&off, &frames, &r).iter().all(|g| g.total() == 1.0));
    }

    #[test]
    fn a_seam_gain_does_not_wash_out_a_bright_camera() {
        let s = DisplaySettings {
            smoothing: 1.0,
            prior: 1e-4,
            ..Default::default()
        };
        // Camera 1 is shown 1 EV darker than camera 0 at their seam; its
        // 90th percentile is at 0.8, camera 0's at 0.3.
        let frames = [
            DisplayInput {
                bright: 0.3,
                ..frame(1000.0, 0.2, false)
            },
            DisplayInput {
                bright: 0.8,
                ..frame(1000.0, 0.5, false)
            },
        ];
        let r = [(0, 1, Some(-1.0))];
        let mut d = DisplayGains::default();
        let g = d.update(&s, &frames, &r);
        let ev = |k: usize| f64::from(g[k].seam).log2();
        // Uncapped it would be brightened by 1 EV; its 90th percentile may
        // reach 0.95 only, and camera 0 is darkened by the rest: the seam
        // is even.
        let room = (0.95f64 / 0.8).log2();
        assert!((ev(1) - room).abs() < 1e-6, "{g:?}");
        assert!((ev(0) - (room - 1.0)).abs() < 1e-3, "{g:?}");
        // A camera already at the level (no room) is not darkened for it.
        let full = [
            frames[0],
            DisplayInput {
                bright: 0.97,
                ..frames[1]
            },
        ];
        let g = DisplayGains::default().update(&s, &full, &r);
        assert!(f64::from(g[1].seam).log2().abs() < 1e-6, "{g:?}");
        assert!((f64::from(g[0].seam).log2() + 1.0).abs() < 1e-3, "{g:?}");
        // Without a percentile, the full gain.
        let plain = [frame(1000.0, 0.2, false), frame(1000.0, 0.5, false)];
        let g = DisplayGains::default().update(&s, &plain, &r);
        assert!((f64::from(g[1].seam).log2() - 1.0).abs() < 0.01, "{g:?}");
    }
}
