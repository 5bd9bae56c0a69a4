//! What the estimator simulates and how: the anchors, the simulation of an
//! exposure change and the estimator's settings.

use serde::{Deserialize, Serialize};

use super::FitVariable;
use crate::error::{check_range, Error, Result};
use crate::exposure::metric::{GradientMetric, MetricParams};
use crate::exposure::tone::ToneCurve;

/// The paper's seven anchors.
pub const DEFAULT_ANCHORS: [f64; 7] = [1.0 / 1.9, 1.0 / 1.5, 1.0 / 1.2, 1.0, 1.2, 1.5, 1.9];

/// How an exposure change is simulated on the current image.
///
/// Scale-and-clip is the default: GenICam cameras deliver linear frames,
/// on which the paper's γ-mapping puts the optimum 1.7 EV or more below
/// where `M` is highest (real 12-bit brackets), and the simulator's sensor
/// is linear too (docs/exposure-results.md, *The default simulation*).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Simulation {
    /// The paper's `I_out = I_in^γ`; γ > 1 darkens.
    Gamma,
    /// `I_out = min(1, s·I_in)`, exact for a linear sensor below saturation;
    /// s > 1 brightens.
    #[default]
    ScaleClip,
}

impl Simulation {
    /// The name used in settings and telemetry.
    pub fn name(self) -> &'static str {
        match self {
            Self::Gamma => "gamma",
            Self::ScaleClip => "scale-clip",
        }
    }

    /// The γ-equivalent of an estimate `x` of this simulation.
    pub fn gamma_equivalent(self, x: f64) -> f64 {
        match self {
            Self::Gamma => x,
            Self::ScaleClip => 1.0 / x,
        }
    }

    /// The variable its polynomial is fitted in (module documentation).
    pub fn fit_variable(self) -> FitVariable {
        match self {
            Self::Gamma => FitVariable::Linear,
            Self::ScaleClip => FitVariable::Log,
        }
    }
}

/// Configuration of the estimator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatorConfig {
    /// The exposure simulation.
    pub simulation: Simulation,
    /// Anchor values (γ for the γ-mapping, s for scale-and-clip).
    pub anchors: Vec<f64>,
    /// Order of the fitted polynomial (default 5).
    pub degree: usize,
    /// Parameters of the metric.
    pub metric: MetricParams,
    /// Maxima of the fit within this fraction of the anchors' spread of
    /// `M` of the highest are blended, near or far, and γ̂ is their
    /// weighted mean, so that it moves continuously as their heights
    /// cross; 0: the highest alone. No maximum counts higher than this band
    /// above the anchors around it ([`super::Polynomial::argmax_supported`]).
    #[serde(default = "default_plateau")]
    pub plateau: f64,
    /// The cameras' tone curve, when their frames are not linear:
    /// scale-and-clip then simulates an exposure change through it
    /// ([`ToneCurve`]); the γ-mapping ignores it. A source that knows a
    /// camera's curve (a bracket sequence's recovered response) sets that
    /// camera's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tone_curve: Option<ToneCurve>,
}

/// [`EstimatorConfig::plateau`] when a settings file leaves it out.
fn default_plateau() -> f64 {
    DEFAULT_PLATEAU
}

/// The default [`EstimatorConfig::plateau`]: 2 % of the anchors' spread,
/// above the wiggle a 5th-order fit leaves between anchors of equal `M`.
pub const DEFAULT_PLATEAU: f64 = 0.02;

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            simulation: Simulation::default(),
            anchors: DEFAULT_ANCHORS.to_vec(),
            degree: 5,
            metric: MetricParams::default(),
            plateau: DEFAULT_PLATEAU,
            tone_curve: None,
        }
    }
}

impl EstimatorConfig {
    /// Checks the configuration.
    pub fn validate(&self) -> Result<()> {
        for &a in &self.anchors {
            if !(a.is_finite() && a > 0.0 && a <= 100.0) {
                return Err(Error::InvalidParameter {
                    name: "anchors",
                    value: a,
                    expected: "positive finite anchor values (at most 100)",
                });
            }
        }
        if self.degree == 0 || self.degree > 9 {
            return Err(Error::InvalidParameter {
                name: "degree",
                value: self.degree as f64,
                expected: "a polynomial order from 1 to 9",
            });
        }
        let mut sorted = self.anchors.clone();
        sorted.sort_by(f64::total_cmp);
        sorted.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        if sorted.len() < self.degree + 1 {
            return Err(Error::invalid(
                "estimator",
                "distinct anchors",
                format!(
                    "at least {} for a polynomial of order {}",
                    self.degree + 1,
                    self.degree
                ),
                sorted.len(),
            ));
        }
        GradientMetric::new(self.metric)?;
        if let Some(curve) = &self.tone_curve {
            curve.validate()?;
        }
        check_range(
            "plateau",
            self.plateau,
            0.0,
            0.5,
            "a fraction of the anchors' spread of M in [0, 0.5]",
        )?;
        Ok(())
    }
}
