//! What the processing does, and what the operator changes while it runs.

use serde::{Deserialize, Serialize};

use super::DisplaySettings;
use crate::error::Result;
use crate::exposure::{
    BalanceParams, ControlMode, ControllerConfig, MeteringConfig, NeighbourGraph,
};
use crate::surround::{BlendMode, SurroundView};

/// How exposure is decided: the choices the app offers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Strategy {
    /// Every camera at a fixed manual exposure level.
    Manual,
    /// The cameras' own auto-exposure (live cameras, and the simulated
    /// rig's model of it: `sim::camera_ae`); rigview only watches.
    CameraAuto,
    /// Mean-intensity auto-exposure (baseline).
    Mean,
    /// Gradient-based auto-exposure, each camera alone.
    Single,
    /// Gradient-based auto-exposure balanced with the neighbours (Eq. 5/6).
    #[default]
    Multi,
    /// A PID controller on γ̂ − 1 (the paper's reference).
    Pid,
}

impl Strategy {
    /// Every strategy, in the order the app lists them.
    pub const ALL: [Strategy; 6] = [
        Self::Manual,
        Self::CameraAuto,
        Self::Mean,
        Self::Single,
        Self::Multi,
        Self::Pid,
    ];

    /// A short label.
    pub fn label(self) -> &'static str {
        match self {
            Self::Manual => "fixed manual",
            Self::CameraAuto => "camera built-in AE",
            Self::Mean => "mean-intensity AE",
            Self::Single => "gradient AE (single)",
            Self::Multi => "gradient AE (multi)",
            Self::Pid => "gradient PID (reference)",
        }
    }

    /// The name used in settings and telemetry.
    pub fn name(self) -> &'static str {
        match self {
            Self::Manual => "manual",
            Self::CameraAuto => "camera-auto",
            Self::Mean => "mean",
            Self::Single => "single",
            Self::Multi => "multi",
            Self::Pid => "pid",
        }
    }
}

/// Which pixels are metered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum MeterRoi {
    /// The ground that reaches the bird's-eye view (as the paper meters).
    #[default]
    Ground,
    /// Whole frames.
    Full,
}

/// What the processing does; every part can change live.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProcessingSettings {
    /// How exposure is decided.
    pub strategy: Strategy,
    /// The controller's parameters (its mode and balancing follow
    /// `strategy`).
    pub controller: ControllerConfig,
    /// Balancing parameters, used by [`Strategy::Multi`].
    pub balance: BalanceParams,
    /// The metering size.
    pub metering: MeteringConfig,
    /// Which pixels are metered.
    pub roi: MeterRoi,
    /// How the overlaps of the view are blended.
    pub blend: BlendMode,
    /// How the view shows the cameras (display gains; the cameras'
    /// exposures are not touched).
    pub display: DisplaySettings,
}

impl Default for ProcessingSettings {
    fn default() -> Self {
        Self {
            strategy: Strategy::Multi,
            controller: ControllerConfig::default(),
            balance: BalanceParams::default(),
            metering: MeteringConfig::default(),
            roi: MeterRoi::Ground,
            blend: BlendMode::Linear,
            display: DisplaySettings::default(),
        }
    }
}

impl ProcessingSettings {
    /// The controller configuration the strategy asks for.
    pub fn controller_config(&self) -> ControllerConfig {
        let mut c = self.controller.clone();
        let (mode, balancing) = match self.strategy {
            // The camera's own AE: the controller holds and rigview sends no
            // commands.
            Strategy::Manual | Strategy::CameraAuto => (ControlMode::Fixed, None),
            Strategy::Mean => (ControlMode::MeanIntensity, None),
            Strategy::Single => (ControlMode::Gradient, None),
            Strategy::Multi => (ControlMode::Gradient, Some(self.balance)),
            Strategy::Pid => (ControlMode::Pid, None),
        };
        c.mode = mode;
        c.balancing = balancing;
        c
    }

    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        self.controller_config().validate()?;
        self.balance.validate()?;
        self.display.validate()?;
        self.metering.validate()
    }
}

/// What the operator changes while the pipeline runs.
#[derive(Debug)]
pub enum Control {
    /// New processing settings.
    Settings(Box<ProcessingSettings>),
    /// Holds one camera at a manual exposure level, or releases it.
    Manual {
        /// The camera.
        camera: usize,
        /// The level, `None` to release.
        exposure: Option<f64>,
    },
    /// A new calibration: its surround view (`None`: none; whole frames
    /// are metered and no view is composed) and its neighbour graph. Check
    /// it with [`check_view`] first.
    Calibration {
        /// The view.
        view: Option<Box<SurroundView>>,
        /// Which cameras overlap.
        graph: NeighbourGraph,
    },
}
