//! Gradient-based exposure control after Shim et al., "Gradient-based Camera
//! Exposure Control for Outdoor Mobile Platforms", IEEE TCSVT 2018.
//!
//! The data flow of one frame set:
//!
//! ```text
//! frame ─► metering ─► estimator (γ̂, M(γ)) ─► update law ─► balancing ─► split ─► command
//! ```
//!
//! Conventions: intensities are in [0, 1]; the γ-mapping is `I^γ` (γ > 1
//! darkens, so γ̂ > 1 lowers exposure); the exposure level is one linear
//! number per camera, `E = t_us · 10^(gain_dB/20)`.

pub mod balance;
pub mod baselines;
pub mod bracket;
pub mod controller;
pub mod estimator;
mod fastmath;
mod kernel;
pub mod laws;
pub mod levels;
pub mod light;
pub mod metering;
pub mod metric;
pub mod probe;
pub mod split;
pub mod tone;

// The frame types, where the data flow starts.
pub use crate::image::{FrameView, PixelFormat, RoiMask};

pub use balance::{BalanceParams, NeighbourGraph, PatchPair};
pub use baselines::{MeanIntensityParams, PidParams};
pub use bracket::{Bracket, BracketParams, Repeller};
pub use controller::{
    CameraController, CameraInput, CameraStep, ControlMode, ControllerConfig, FrameInfo, Hold,
    PairObservation, PairRatio, RigController, RigStep,
};
pub use estimator::{
    Darker, Estimate, EstimateOptions, Estimator, EstimatorConfig, Simulation, DARKER_MIN_EV,
    DEFAULT_ANCHORS,
};
pub use laws::{LawKind, LawParams, LawStep};
pub use light::{LightChange, LightParams, LightTracker};
pub use metering::{CameraMasks, ImageStats, Meter, Metered, MeteringConfig, PreparedMask};
pub use metric::{GradientMetric, MetricParams};
pub use probe::{ProbeEvent, ProbeParams};
pub use split::{ExposureRange, ExposureSetting, SplitParams, Splitter};
pub use tone::ToneCurve;
