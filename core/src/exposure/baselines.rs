//! Baseline controllers, for comparison in the app and in the evaluation:
//! mean-intensity auto-exposure and a PID controller on `γ̂ − 1` (the paper's
//! reference). Fixed manual exposure needs no code of its own: the
//! controller simply holds the configured exposure.

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Result};

/// Mean-intensity auto-exposure: a proportional controller on log exposure
/// towards a target mean, `log E' = log E + k·(log target − log mean)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeanIntensityParams {
    /// Target mean intensity in (0, 1).
    pub target: f64,
    /// Proportional gain `k` on log exposure, in (0, 2).
    pub gain: f64,
}

impl Default for MeanIntensityParams {
    fn default() -> Self {
        Self {
            target: 0.45,
            gain: 0.7,
        }
    }
}

impl MeanIntensityParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "mean.target",
            self.target,
            0.01,
            0.99,
            "a mean in [0.01, 0.99]",
        )?;
        check_range("mean.gain", self.gain, 1e-3, 2.0, "a gain in (0, 2]")?;
        Ok(())
    }

    /// The exposure ratio for an image of mean intensity `mean`.
    pub fn ratio(&self, mean: f64) -> f64 {
        (self.target / mean.max(1e-4)).powf(self.gain)
    }
}

/// A PID controller on the error `e = 1 − γ̂` (positive: brighter is
/// better), acting on the exposure ratio `E'/E = 1 + u`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PidParams {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain (per frame).
    pub ki: f64,
    /// Derivative gain (per frame).
    pub kd: f64,
    /// Bound on the integral term's contribution to `u`.
    pub integral_limit: f64,
}

impl Default for PidParams {
    fn default() -> Self {
        Self {
            kp: 0.6,
            ki: 0.3,
            kd: 0.1,
            integral_limit: 1.0,
        }
    }
}

impl PidParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range("pid.kp", self.kp, 0.0, 20.0, "a gain in [0, 20]")?;
        check_range("pid.ki", self.ki, 0.0, 20.0, "a gain in [0, 20]")?;
        check_range("pid.kd", self.kd, 0.0, 20.0, "a gain in [0, 20]")?;
        check_range(
            "pid.integral_limit",
            self.integral_limit,
            0.0,
            100.0,
            "a bound in [0, 100]",
        )?;
        Ok(())
    }
}

/// The state of a PID controller.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PidState {
    integral: f64,
    previous: Option<f64>,
}

impl PidState {
    /// One update with error `e = 1 − γ̂`; returns the ratio `1 + u`.
    pub fn update(&mut self, params: &PidParams, error: f64) -> f64 {
        let limit = if params.ki > 0.0 {
            params.integral_limit / params.ki
        } else {
            0.0
        };
        self.integral = (self.integral + error).clamp(-limit, limit);
        let derivative = self.previous.map_or(0.0, |p| error - p);
        self.previous = Some(error);
        1.0 + params.kp * error + params.ki * self.integral + params.kd * derivative
    }

    /// Forgets the history.
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}
