//! What the processing does, and what the operator changes while it runs.

use serde::{Deserialize, Serialize};

use super::DisplaySettings;
use crate::error::check_range;
use crate::error::Result;
use crate::exposure::{
    BalanceParams, ControlMode, ControllerConfig, MeteringConfig, NeighbourGraph,
};
use crate::surround::BlendMode;

use super::View;

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

/// Which view the pipeline composes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ViewKind {
    /// The bird's-eye surround view (the ground around the vehicle).
    #[default]
    Surround,
    /// The cylindrical panorama (the surroundings at a chosen radius).
    Panorama,
    /// The bowl around the vehicle, seen from a viewpoint.
    Bowl,
}

impl ViewKind {
    /// The name used in settings and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Surround => "surround",
            Self::Panorama => "panorama",
            Self::Bowl => "bowl",
        }
    }
}

/// The live panorama: its cylinder, and how often its features are
/// matched and its rotations refined (see [`super::LivePanorama`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PanoramaSettings {
    /// Canvas width, pixels (360° of azimuth).
    pub width: usize,
    /// Canvas height, pixels.
    pub height: usize,
    /// The cylinder's radius, metres: what stands this far from the rig's
    /// centre lines up across the seams, nearer and farther things show
    /// parallax.
    pub radius_m: f64,
    /// Degrees shown below the horizon.
    pub below_deg: f64,
    /// Degrees shown above the horizon.
    pub above_deg: f64,
    /// Features are matched on every `match_every`-th set (on a worker
    /// thread; the ratios of the last matching are held in between).
    pub match_every: u64,
    /// A pair's ratio is held for up to `hold_sets` sets after the last
    /// matching that gave it patches (one with too few inliers does not
    /// take it away before).
    pub hold_sets: u64,
    /// The rotations are refined in the background every `refine_every`
    /// sets (0: only when asked).
    pub refine_every: u64,
    /// The largest rotation a refinement may give a camera, degrees.
    pub refine_bound_deg: f64,
    /// Rounds of matching and refinement per refinement
    /// ([`crate::panorama::refine_in_rounds`]).
    pub refine_rounds: usize,
}

impl Default for PanoramaSettings {
    /// 2048 × 270 pixels (square at the horizon: 0.18° each), radius 10 m,
    /// from 25° below the horizon to 20° above it: a rig of cameras
    /// tilted down sees no higher all round (the offline `rigview
    /// panorama` shows up to 35° by default).
    fn default() -> Self {
        Self {
            width: 2048,
            height: 270,
            radius_m: 10.0,
            below_deg: 25.0,
            above_deg: 20.0,
            match_every: 10,
            hold_sets: 100,
            refine_every: 0,
            refine_bound_deg: 3.0,
            refine_rounds: 4,
        }
    }
}

impl PanoramaSettings {
    /// The cylinder these settings ask for.
    pub fn spec(&self) -> crate::panorama::CylinderSpec {
        crate::panorama::CylinderSpec {
            width: self.width,
            height: self.height,
            radius_m: self.radius_m,
            below_deg: self.below_deg,
            above_deg: self.above_deg,
            floor: false,
        }
    }

    /// Checks the cylinder and the schedule.
    pub fn validate(&self) -> Result<()> {
        self.spec().validate()?;
        if !(1..=10_000).contains(&self.match_every) {
            return Err(crate::error::Error::InvalidParameter {
                name: "panorama.match_every",
                value: self.match_every as f64,
                expected: "1 to 10000 sets",
            });
        }
        if self.hold_sets > 100_000 {
            return Err(crate::error::Error::InvalidParameter {
                name: "panorama.hold_sets",
                value: self.hold_sets as f64,
                expected: "0 to 100000 sets",
            });
        }
        check_range(
            "panorama.refine_bound_deg",
            self.refine_bound_deg,
            0.01,
            20.0,
            "0.01° to 20°",
        )?;
        if !(1..=crate::panorama::MAX_ROUNDS).contains(&self.refine_rounds) {
            return Err(crate::error::Error::InvalidParameter {
                name: "panorama.refine_rounds",
                value: self.refine_rounds as f64,
                expected: "1 to 20 rounds",
            });
        }
        Ok(())
    }
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
    /// Which view is composed (a change applies when the view is next
    /// built: [`Control::Calibration`]).
    pub view: ViewKind,
    /// The live panorama.
    pub panorama: PanoramaSettings,
    /// The bowl and its viewpoint (a change applies live, built in the
    /// background).
    pub bowl: super::BowlSettings,
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
            view: ViewKind::Surround,
            panorama: PanoramaSettings::default(),
            bowl: super::BowlSettings::default(),
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
        self.panorama.validate()?;
        self.bowl.validate()?;
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
    /// A new calibration or view: the view (`None`: none; whole frames
    /// are metered and no view is composed) and its neighbour graph. Check
    /// it with [`super::check_view`] first.
    Calibration {
        /// The view.
        view: Option<Box<View>>,
        /// Which cameras overlap.
        graph: NeighbourGraph,
    },
    /// Refine the panorama's rotations from the next set, in rounds in the
    /// background (nothing without a panorama).
    Refine,
}
