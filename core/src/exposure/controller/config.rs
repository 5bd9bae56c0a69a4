//! What decides a camera's exposure and the controller's settings.

use super::*;

/// What decides the exposure.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ControlMode {
    /// A fixed manual exposure ([`ControllerConfig::fixed_exposure`]).
    Fixed,
    /// Mean-intensity auto-exposure (baseline).
    MeanIntensity,
    /// Gradient-based auto-exposure with the configured update law.
    #[default]
    Gradient,
    /// A PID controller on `γ̂ − 1` (the paper's reference).
    Pid,
}

impl ControlMode {
    /// The name used in settings and telemetry.
    pub fn name(self) -> &'static str {
        match self {
            Self::Fixed => "fixed",
            Self::MeanIntensity => "mean",
            Self::Gradient => "gradient",
            Self::Pid => "pid",
        }
    }
}

/// Everything the controllers need to know. In a settings file every
/// field may be left out (its default stands).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControllerConfig {
    /// What decides the exposure.
    pub mode: ControlMode,
    /// The estimator (simulation, anchors, metric).
    pub estimator: EstimatorConfig,
    /// The update law of [`ControlMode::Gradient`].
    pub law: LawParams,
    /// The mean-intensity baseline.
    pub mean: MeanIntensityParams,
    /// The PID baseline.
    pub pid: PidParams,
    /// The shutter/gain split.
    pub split: SplitParams,
    /// Balancing between neighbours (`None`: each camera alone).
    pub balancing: Option<BalanceParams>,
    /// Exposure level held in [`ControlMode::Fixed`].
    pub fixed_exposure: f64,
    /// Frames to wait for a command to show before reacting anyway.
    pub latency_timeout_frames: u32,
    /// Probing darker where saturation hides what darkening would show
    /// ([`crate::exposure::probe`]), for cameras under their own gradient law
    /// (`None`: never).
    #[serde(default = "default_probe")]
    pub probe: Option<ProbeParams>,
    /// The bracket that keeps a camera's own law from circling
    /// ([`crate::exposure::bracket`]).
    pub bracket: BracketParams,
    /// Following a uniform change of light measured against a reference
    /// frame ([`crate::exposure::light`]), under every gradient law (`None`: never).
    #[serde(default = "default_light")]
    pub light: Option<LightParams>,
}

fn default_light() -> Option<LightParams> {
    Some(LightParams::default())
}

/// A configuration written before probing existed probes (`null`: never).
fn default_probe() -> Option<ProbeParams> {
    Some(ProbeParams::default())
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            mode: ControlMode::Gradient,
            estimator: EstimatorConfig::default(),
            law: LawParams::default(),
            mean: MeanIntensityParams::default(),
            pid: PidParams::default(),
            split: SplitParams::default(),
            balancing: Some(BalanceParams::default()),
            fixed_exposure: 5_000.0,
            latency_timeout_frames: 4,
            probe: default_probe(),
            bracket: BracketParams::default(),
            light: default_light(),
        }
    }
}

impl ControllerConfig {
    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        self.estimator.validate()?;
        self.law.validate()?;
        self.mean.validate()?;
        self.pid.validate()?;
        self.split.validate()?;
        if let Some(b) = &self.balancing {
            b.validate()?;
        }
        if let Some(p) = &self.probe {
            p.validate()?;
        }
        self.bracket.validate()?;
        if let Some(l) = &self.light {
            l.validate()?;
        }
        check_range(
            "fixed_exposure",
            self.fixed_exposure,
            1e-6,
            1e12,
            "a positive exposure level (µs at 0 dB)",
        )?;
        Ok(())
    }
}
