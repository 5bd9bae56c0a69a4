//! The strategies the evaluation compares, each with its name, its label
//! and the one colour it has in every figure.

use plotters::style::RGBColor;
use rigview_core::exposure::{LawKind, Simulation};
use rigview_core::pipeline::{ProcessingSettings, Strategy};

/// A strategy of the evaluation: a processing strategy with its law.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EvalStrategy {
    /// Fixed manual exposure.
    Fixed,
    /// The simulated cameras' own auto-exposure.
    CameraAe,
    /// rigview's mean-intensity auto-exposure.
    Mean,
    /// The PID reference on `γ̂ − 1`.
    Pid,
    /// Each camera alone, the paper's linear law (Eq. 3).
    Linear,
    /// Each camera alone, the paper's nonlinear law (Eq. 4): "single".
    Nonlinear,
    /// Each camera alone, rigview's fast law.
    Fast,
    /// Balanced with the neighbours (Eq. 5/6), nonlinear law.
    Multi,
    /// The cameras' own auto-exposure, and display gains that even out the
    /// seams of the view (what surround-view systems and OpenCV's stitcher
    /// do).
    CameraAeComp,
    /// Balanced, and display gains that even out what balancing leaves.
    MultiComp,
    /// [`Self::Linear`] under scale-and-clip, rigview's default (every
    /// other gradient strategy runs under the paper's γ-mapping, which the
    /// experiments of the paper's figures measure).
    LinearSc,
    /// [`Self::Nonlinear`] under scale-and-clip.
    NonlinearSc,
    /// [`Self::Fast`] under scale-and-clip.
    FastSc,
    /// [`Self::Multi`] under scale-and-clip.
    MultiSc,
    /// [`Self::Pid`] under scale-and-clip.
    PidSc,
}

impl EvalStrategy {
    /// Every strategy, in the order of the report's summary: rigview's
    /// gradient laws, the baselines, fixed exposure.
    pub const ALL: [EvalStrategy; 15] = [
        Self::Fast,
        Self::Linear,
        Self::Nonlinear,
        Self::Multi,
        Self::MultiComp,
        Self::Pid,
        Self::FastSc,
        Self::LinearSc,
        Self::NonlinearSc,
        Self::MultiSc,
        Self::PidSc,
        Self::Mean,
        Self::CameraAe,
        Self::CameraAeComp,
        Self::Fixed,
    ];

    /// The strategies of the step responses (experiment 2): each camera
    /// alone under both exposure simulations.
    pub const STEPS: [EvalStrategy; 10] = [
        Self::Linear,
        Self::Nonlinear,
        Self::Fast,
        Self::Pid,
        Self::LinearSc,
        Self::NonlinearSc,
        Self::FastSc,
        Self::PidSc,
        Self::Mean,
        Self::CameraAe,
    ];

    /// The strategies whose settled exposure is marked on M(E)
    /// (experiment 3): every gradient strategy under both exposure
    /// simulations.
    pub const SETTLED: [EvalStrategy; 12] = [
        Self::Linear,
        Self::Nonlinear,
        Self::Fast,
        Self::Multi,
        Self::Pid,
        Self::LinearSc,
        Self::NonlinearSc,
        Self::FastSc,
        Self::MultiSc,
        Self::PidSc,
        Self::Mean,
        Self::CameraAe,
    ];

    /// The strategies of the surround seams (experiment 4) and of the
    /// visual comparison (experiment 6).
    pub const SEAMS: [EvalStrategy; 6] = [
        Self::Fixed,
        Self::CameraAe,
        Self::Nonlinear,
        Self::Multi,
        Self::CameraAeComp,
        Self::MultiComp,
    ];

    /// The strategies of the panorama's seams (experiment 5): those of
    /// experiment 4 that set different exposures. The display gains leave
    /// the images, and so the ratios of their matched patches, as they are.
    pub const PANORAMA: [EvalStrategy; 4] =
        [Self::Fixed, Self::CameraAe, Self::Nonlinear, Self::Multi];

    /// The name in CSV files.
    pub fn key(self) -> &'static str {
        match self {
            Self::Fixed => "fixed",
            Self::CameraAe => "camera-ae",
            Self::Mean => "mean",
            Self::Pid => "pid",
            Self::Linear => "linear",
            Self::Nonlinear => "nonlinear",
            Self::Fast => "fast",
            Self::Multi => "multi",
            Self::CameraAeComp => "camera-ae+display",
            Self::MultiComp => "multi+display",
            Self::LinearSc => "linear/scale-clip",
            Self::NonlinearSc => "nonlinear/scale-clip",
            Self::FastSc => "fast/scale-clip",
            Self::MultiSc => "multi/scale-clip",
            Self::PidSc => "pid/scale-clip",
        }
    }

    /// The label in figures and the report.
    pub fn label(self) -> &'static str {
        match self {
            Self::Fixed => "fixed manual",
            Self::CameraAe => "camera built-in AE (simulated)",
            Self::Mean => "mean-intensity AE",
            Self::Pid => "PID (the paper's reference), γ-mapping",
            Self::Linear => "gradient, linear law, γ-mapping",
            Self::Nonlinear => "gradient, nonlinear law, γ-mapping",
            Self::Fast => "gradient, fast law, γ-mapping",
            Self::Multi => "gradient balanced (multi), γ-mapping",
            Self::CameraAeComp => "built-in AE + display gains",
            Self::MultiComp => "balanced + display gains, γ-mapping",
            Self::LinearSc => "gradient, linear law, scale-and-clip",
            Self::NonlinearSc => "gradient, nonlinear law, scale-and-clip",
            Self::FastSc => "gradient, fast law, scale-and-clip",
            Self::MultiSc => "gradient balanced (multi), scale-and-clip",
            Self::PidSc => "PID, scale-and-clip",
        }
    }

    /// The colour in every figure.
    pub fn colour(self) -> RGBColor {
        match self {
            Self::Fixed => RGBColor(120, 120, 120),
            Self::CameraAe => RGBColor(230, 140, 20),
            Self::Mean => RGBColor(200, 60, 140),
            Self::Pid => RGBColor(140, 90, 40),
            Self::Linear => RGBColor(40, 120, 200),
            Self::Nonlinear => RGBColor(60, 160, 60),
            Self::Fast => RGBColor(210, 40, 40),
            Self::Multi => RGBColor(120, 60, 200),
            Self::CameraAeComp => RGBColor(240, 200, 60),
            Self::MultiComp => RGBColor(30, 170, 170),
            Self::LinearSc => RGBColor(120, 180, 240),
            Self::NonlinearSc => RGBColor(140, 210, 110),
            Self::FastSc => RGBColor(250, 120, 110),
            Self::MultiSc => RGBColor(180, 140, 240),
            Self::PidSc => RGBColor(200, 160, 110),
        }
    }

    /// The exposure simulation its estimate uses.
    pub fn simulation(self) -> Simulation {
        match self {
            Self::LinearSc | Self::NonlinearSc | Self::FastSc | Self::MultiSc | Self::PidSc => {
                Simulation::ScaleClip
            }
            _ => Simulation::Gamma,
        }
    }

    /// The processing settings: the strategy's exposure simulation, probes
    /// off (the laws measured alone), display gains only where the strategy
    /// says, the rest at rigview's defaults.
    pub fn settings(self) -> ProcessingSettings {
        let mut p = ProcessingSettings::default();
        p.controller.estimator.simulation = self.simulation();
        p.controller.probe = None;
        p.display.compensate = matches!(self, Self::CameraAeComp | Self::MultiComp);
        let (strategy, law) = match self {
            Self::Fixed => (Strategy::Manual, LawKind::Nonlinear),
            Self::CameraAe | Self::CameraAeComp => (Strategy::CameraAuto, LawKind::Nonlinear),
            Self::Mean => (Strategy::Mean, LawKind::Nonlinear),
            Self::Pid | Self::PidSc => (Strategy::Pid, LawKind::Nonlinear),
            Self::Linear | Self::LinearSc => (Strategy::Single, LawKind::Linear),
            Self::Nonlinear | Self::NonlinearSc => (Strategy::Single, LawKind::Nonlinear),
            Self::Fast | Self::FastSc => (Strategy::Single, LawKind::Fast),
            Self::Multi | Self::MultiComp | Self::MultiSc => (Strategy::Multi, LawKind::Nonlinear),
        };
        p.strategy = strategy;
        p.controller.law.kind = law;
        p
    }

    /// [`Self::settings`] with the controller's probes as the app runs
    /// them (its default): where a strategy comes to rest is what an
    /// operator gets, probes included (experiment 3). The step responses
    /// and seams measure the laws alone.
    pub fn settings_as_run(self) -> ProcessingSettings {
        let mut p = self.settings();
        p.controller.probe = ProcessingSettings::default().controller.probe;
        p
    }
}
