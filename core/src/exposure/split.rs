//! The exposure level `E = t_us · 10^(gain_dB/20)` and its split into shutter
//! and gain.
//!
//! Shutter first, up to `min(max_shutter_us, the camera's maximum)`, then
//! gain; going down, gain first back to its minimum, then shutter. Around the
//! knee a hysteresis band keeps the two from chattering: once gain is in use
//! it is at least `hysteresis_db` above its minimum (the shutter then sits a
//! little below its cap), and gain is released only when `E` has fallen
//! `hysteresis_db` below the knee. Small oscillations of `E` around the knee
//! therefore move the shutter alone.

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Error, Result};

/// The linear gain factor of `gain_db`.
pub fn gain_factor(gain_db: f64) -> f64 {
    10f64.powf(gain_db / 20.0)
}

/// A shutter time and a gain, as sent to and reported by a camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExposureSetting {
    /// Exposure time in µs (GenICam `ExposureTime`).
    pub shutter_us: f64,
    /// Gain in dB (GenICam `Gain`).
    pub gain_db: f64,
}

impl ExposureSetting {
    /// The exposure level `E = t_us · 10^(gain_dB/20)`.
    pub fn exposure(&self) -> f64 {
        self.shutter_us * gain_factor(self.gain_db)
    }
}

/// The ranges a camera reports.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExposureRange {
    /// Shortest exposure time in µs (> 0).
    pub shutter_min_us: f64,
    /// Longest exposure time in µs.
    pub shutter_max_us: f64,
    /// Lowest gain in dB.
    pub gain_min_db: f64,
    /// Highest gain in dB.
    pub gain_max_db: f64,
}

impl Default for ExposureRange {
    /// The reference rig's cameras: 10 µs – 10 s, 0 – 24 dB.
    fn default() -> Self {
        Self {
            shutter_min_us: 10.0,
            shutter_max_us: 10_000_000.0,
            gain_min_db: 0.0,
            gain_max_db: 24.0,
        }
    }
}

impl ExposureRange {
    /// Checks the range: finite, a positive shortest shutter, maxima not
    /// below minima, and something to control (a zero range is an error).
    pub fn validate(&self) -> Result<()> {
        check_range(
            "shutter_min_us",
            self.shutter_min_us,
            1e-6,
            1e9,
            "a positive exposure time in µs",
        )?;
        check_range(
            "shutter_max_us",
            self.shutter_max_us,
            self.shutter_min_us,
            1e9,
            "an exposure time in µs not below shutter_min_us",
        )?;
        check_range(
            "gain_min_db",
            self.gain_min_db,
            -100.0,
            100.0,
            "a gain in dB",
        )?;
        check_range(
            "gain_max_db",
            self.gain_max_db,
            self.gain_min_db,
            100.0,
            "a gain in dB not below gain_min_db",
        )?;
        if self.shutter_max_us <= self.shutter_min_us && self.gain_max_db <= self.gain_min_db {
            return Err(Error::invalid(
                "exposure range",
                "shutter and gain",
                "a range to control",
                format_args!(
                    "both fixed, shutter {} µs and gain {} dB",
                    self.shutter_min_us, self.gain_min_db
                ),
            ));
        }
        Ok(())
    }
}

/// Parameters of the split.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SplitParams {
    /// Longest shutter before gain is used, in µs (49 ms on the reference rig).
    pub max_shutter_us: f64,
    /// Width of the hysteresis band around the knee, in dB.
    pub hysteresis_db: f64,
}

impl Default for SplitParams {
    fn default() -> Self {
        Self {
            max_shutter_us: 49_000.0,
            hysteresis_db: 1.0,
        }
    }
}

impl SplitParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "max_shutter_us",
            self.max_shutter_us,
            1e-6,
            1e9,
            "a positive exposure time in µs",
        )?;
        check_range(
            "hysteresis_db",
            self.hysteresis_db,
            0.0,
            20.0,
            "a band in [0, 20] dB",
        )?;
        Ok(())
    }
}

/// Where a requested exposure fell outside what the camera can do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Clamped {
    /// Below the shortest shutter at the lowest gain.
    Low,
    /// Above the capped shutter at the highest gain.
    High,
}

/// Splits exposure levels into settings for one camera (stateful, for the
/// hysteresis).
#[derive(Clone, Debug)]
pub struct Splitter {
    range: ExposureRange,
    params: SplitParams,
    gain_mode: bool,
}

impl Splitter {
    /// A splitter for a camera with `range`.
    pub fn new(range: ExposureRange, params: SplitParams) -> Result<Self> {
        range.validate()?;
        params.validate()?;
        Ok(Self {
            range,
            params,
            gain_mode: false,
        })
    }

    /// The camera's range.
    pub fn range(&self) -> &ExposureRange {
        &self.range
    }

    /// The parameters.
    pub fn params(&self) -> &SplitParams {
        &self.params
    }

    fn shutter_cap(&self) -> f64 {
        self.params
            .max_shutter_us
            .min(self.range.shutter_max_us)
            .max(self.range.shutter_min_us)
    }

    /// The smallest exposure level the camera can take.
    pub fn min_exposure(&self) -> f64 {
        self.range.shutter_min_us * gain_factor(self.range.gain_min_db)
    }

    /// The largest exposure level the split allows.
    pub fn max_exposure(&self) -> f64 {
        self.shutter_cap() * gain_factor(self.range.gain_max_db)
    }

    /// Tells the splitter which setting the camera has now (e.g. after the
    /// camera's own auto-exposure ran), so the hysteresis starts in the
    /// right state.
    pub fn sync(&mut self, current: ExposureSetting) {
        self.gain_mode = current.gain_db > self.range.gain_min_db + 1e-6;
    }

    /// Splits `exposure` into a setting within the camera's ranges.
    pub fn split(&mut self, exposure: f64) -> (ExposureSetting, Option<Clamped>) {
        let (lo, hi) = (self.min_exposure(), self.max_exposure());
        let (e, clamped) = if exposure.is_nan() || exposure < lo {
            (lo, Some(Clamped::Low))
        } else if exposure > hi {
            (hi, Some(Clamped::High))
        } else {
            (exposure, None)
        };
        let r = &self.range;
        let cap = self.shutter_cap();
        let knee = cap * gain_factor(r.gain_min_db);
        let band = self.params.hysteresis_db.min(r.gain_max_db - r.gain_min_db);
        if !self.gain_mode && e > knee * (1.0 + 1e-9) && r.gain_max_db > r.gain_min_db {
            self.gain_mode = true;
        } else if self.gain_mode && e < knee / gain_factor(band) {
            self.gain_mode = false;
        }
        let setting = if self.gain_mode {
            let needed = 20.0 * (e / cap).log10();
            let gain_db = needed.max(r.gain_min_db + band).min(r.gain_max_db);
            let shutter_us = (e / gain_factor(gain_db)).clamp(r.shutter_min_us, cap);
            let gain_db = (20.0 * (e / shutter_us).log10()).clamp(r.gain_min_db, r.gain_max_db);
            ExposureSetting {
                shutter_us,
                gain_db,
            }
        } else {
            ExposureSetting {
                shutter_us: (e / gain_factor(r.gain_min_db)).clamp(r.shutter_min_us, cap),
                gain_db: r.gain_min_db,
            }
        };
        (setting, clamped)
    }
}
