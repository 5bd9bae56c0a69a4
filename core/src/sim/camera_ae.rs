//! The simulated cameras' own auto-exposure: what a machine-vision camera
//! runs in its firmware when its `ExposureAuto` and `GainAuto` are on, the
//! baseline the paper compares against ("AE"). [`super::SimRig`] runs it
//! for every camera while the cameras' own auto-exposure is switched on
//! ([`crate::pipeline::Strategy::CameraAuto`]); rigview then sends no
//! commands and only watches.
//!
//! The model, per camera and frame:
//!
//! - **Measure**: the mean luminance `m` of the whole image, in [0, 1]
//!   (every pixel counts the same; no region, no weighting).
//! - **Target**: a mean grey `T` (default 0.5, 50 % grey). The error is
//!   `e = log2(T / m)` EV (`m` floored at 1/1024, a black frame).
//! - **Dead band**: within `|e| ≤ dead_band_ev` nothing changes, so the
//!   camera does not flicker on noise.
//! - **Damping**: the camera moves a fraction `d` of the error,
//!   `Δ = d·e`, from the exposure the measured frame was *taken* with (so
//!   a frame taken before the previous change showed asks for the same
//!   exposure again, not for a second step).
//! - **Rate limit**: the new exposure lies within `max_step_ev` of the
//!   exposure the camera has now: a large change of light takes several
//!   frames, as on real cameras whose auto functions are slowed to avoid
//!   visible pumping.
//! - **Shutter before gain**: the exposure level `E` is reached with the
//!   shutter alone, up to `min(max_shutter_us, the camera's maximum)`, then
//!   with gain; going down, gain goes back to its minimum first. Both are
//!   clamped to the camera's ranges.
//!
//! The command takes effect after the rig's actuation latency, as rigview's
//! commands do. A saturated image reads a mean of at most 1, so after a
//! large brightening the error is underestimated and the camera comes down
//! in several steps: that is the behaviour of a mean-based AE, not a
//! defect of the model.

use crate::error::{check_range, Result};
use crate::exposure::split::gain_factor;
use crate::exposure::{ExposureRange, ExposureSetting};

/// The parameters of the simulated built-in auto-exposure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraAeParams {
    /// Target mean intensity in (0, 1).
    pub target: f64,
    /// Fraction of the error corrected per frame, in (0, 1].
    pub damping: f64,
    /// Largest change of exposure per frame, EV.
    pub max_step_ev: f64,
    /// Errors within this are ignored, EV.
    pub dead_band_ev: f64,
    /// Longest shutter before gain is used, µs.
    pub max_shutter_us: f64,
}

impl Default for CameraAeParams {
    /// 50 % grey, 0.7 of the error per frame (about the damping machine-
    /// vision cameras ship with), at most 0.5 EV per frame, a dead band of
    /// 0.05 EV, shutter up to 49 ms.
    fn default() -> Self {
        Self {
            target: 0.5,
            damping: 0.7,
            max_step_ev: 0.5,
            dead_band_ev: 0.05,
            max_shutter_us: 49_000.0,
        }
    }
}

impl CameraAeParams {
    /// Checks the parameters; the error names the field.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "camera_ae.target",
            self.target,
            0.01,
            0.99,
            "a mean in [0.01, 0.99]",
        )?;
        check_range(
            "camera_ae.damping",
            self.damping,
            0.01,
            1.0,
            "a fraction in [0.01, 1]",
        )?;
        check_range(
            "camera_ae.max_step_ev",
            self.max_step_ev,
            0.01,
            16.0,
            "a step in [0.01, 16] EV",
        )?;
        check_range(
            "camera_ae.dead_band_ev",
            self.dead_band_ev,
            0.0,
            0.99,
            "a band in [0, 0.99] EV",
        )?;
        check_range(
            "camera_ae.max_shutter_us",
            self.max_shutter_us,
            1e-3,
            1e9,
            "a positive time in µs",
        )?;
        Ok(())
    }

    /// The setting the camera's AE moves to after a frame taken with
    /// `taken` whose mean intensity is `mean`, the camera having `current`
    /// now (see the module documentation); `None` within the dead band.
    pub fn next(
        &self,
        mean: f64,
        taken: ExposureSetting,
        current: ExposureSetting,
        range: &ExposureRange,
    ) -> Option<ExposureSetting> {
        let mean = if mean.is_finite() { mean } else { 0.0 };
        let error = (self.target / mean.max(1.0 / 1024.0)).log2();
        if error.abs() <= self.dead_band_ev {
            return None;
        }
        let now = current.exposure().log2();
        let wanted = taken.exposure().log2() + self.damping * error;
        let level = wanted
            .clamp(now - self.max_step_ev, now + self.max_step_ev)
            .exp2();
        let setting = self.split(level, range);
        let same = (setting.exposure() / current.exposure()).log2().abs() < 1e-6;
        (!same).then_some(setting)
    }

    /// Shutter first up to its cap, then gain; clamped to the ranges.
    pub fn split(&self, level: f64, range: &ExposureRange) -> ExposureSetting {
        let cap = self
            .max_shutter_us
            .min(range.shutter_max_us)
            .max(range.shutter_min_us);
        let base = gain_factor(range.gain_min_db);
        let shutter_us = (level / base).clamp(range.shutter_min_us, cap);
        let gain_db =
            (20.0 * (level / shutter_us).log10()).clamp(range.gain_min_db, range.gain_max_db);
        ExposureSetting {
            shutter_us,
            gain_db,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(shutter_us: f64) -> ExposureSetting {
        ExposureSetting {
            shutter_us,
            gain_db: 0.0,
        }
    }

    /// A linear camera looking at a grey scene: the mean is `k·E`, clipped
    /// at 1.
    fn mean_of(k: f64, s: ExposureSetting) -> f64 {
        (k * s.exposure()).min(1.0)
    }

    /// Closed loop with one frame of latency; returns log2 E per frame.
    fn run(params: &CameraAeParams, k: f64, start: f64, frames: usize) -> Vec<f64> {
        let range = ExposureRange::default();
        let mut current = at(start);
        let mut pending: Option<ExposureSetting> = None;
        let mut out = Vec::new();
        for _ in 0..frames {
            let taken = current;
            out.push(taken.exposure().log2());
            if let Some(p) = pending.take() {
                current = p;
            }
            if let Some(next) = params.next(mean_of(k, taken), taken, current, &range) {
                pending = Some(next);
            }
        }
        out
    }

    #[test]
    fn it_settles_at_its_target_mean() {
        let p = CameraAeParams::default();
        // The scene wants E = 0.5 / k = 4000.
        let k = 0.5 / 4000.0;
        for start in [100.0, 4000.0, 200_000.0] {
            let trace = run(&p, k, start, 80);
            let last = *trace.last().unwrap();
            let mean = mean_of(k, at(last.exp2()));
            assert!(
                (mean / p.target).log2().abs() <= p.dead_band_ev + 1e-9,
                "from {start} µs: mean {mean:.3} at 2^{last:.2}"
            );
            // And it stays there.
            let tail = &trace[60..];
            assert!(tail.iter().all(|&l| (l - last).abs() < 1e-9), "{tail:?}");
        }
    }

    #[test]
    fn it_is_rate_limited() {
        let p = CameraAeParams::default();
        let k = 0.5 / 4000.0;
        // 6 EV too dark: at most max_step_ev per frame.
        let trace = run(&p, k, 4000.0 / 64.0, 40);
        let steps: Vec<f64> = trace.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(
            steps.iter().all(|s| s.abs() <= p.max_step_ev + 1e-9),
            "{steps:?}"
        );
        // The first frames take the largest step the limit allows.
        assert!((steps[1] - p.max_step_ev).abs() < 1e-9, "{steps:?}");
        let needed = (6.0 / p.max_step_ev) as usize;
        let reached = trace.iter().position(|l| (l - 4000f64.log2()).abs() < 0.1);
        assert!(reached.is_some_and(|r| r >= needed), "{reached:?}");
    }

    #[test]
    fn shutter_before_gain() {
        let p = CameraAeParams::default();
        let r = ExposureRange::default();
        let s = p.split(10_000.0, &r);
        assert!((s.shutter_us - 10_000.0).abs() < 1e-9 && s.gain_db.abs() < 1e-12);
        let s = p.split(98_000.0, &r);
        assert!((s.shutter_us - 49_000.0).abs() < 1e-9);
        assert!((s.gain_db - 20.0 * 2f64.log10()).abs() < 1e-9, "{s:?}");
        // Beyond the ranges: clamped.
        let s = p.split(1e12, &r);
        assert!((s.gain_db - r.gain_max_db).abs() < 1e-12);
        assert!((p.split(1e-3, &r).shutter_us - r.shutter_min_us).abs() < 1e-12);
        assert!(CameraAeParams { damping: 0.0, ..p }.validate().is_err());
        assert!(p.validate().is_ok());
    }
}
