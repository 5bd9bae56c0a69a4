//! The processing pipeline: the threads that take frame sets from a source,
//! control exposure and compose the view, for the app's window and its
//! headless mode.
//!
//! ```text
//!  capture thread            processing thread                        display (the app)
//!  source.next_set() ──► [DropOldest, 4] ──► meter ─► controller ─► compose ──► [DropOldest, 1] ──► texture
//!        ▲  (per-camera threads and                     │                 │
//!        │   frame-set sync live inside                 │ commands        └──► telemetry (history)
//!        └── the source: LiveSource, SimRig) ◄──────────┘
//! ```
//!
//! - The capture thread only waits on the source and pushes; a full queue
//!   drops its oldest set (counted), so capture never blocks. Exposure
//!   commands come back to it over a channel and are applied before the
//!   next set is asked for.
//! - The processing thread meters each camera (the surround view's ground
//!   only, or whole frames), steps the rig controller, composes the
//!   bird's-eye canvas and records telemetry with the time of every stage.
//! - The display takes the newest output when it paints
//!   ([`Pipeline::latest`]); a slow display skips outputs but never slows
//!   processing. It reports when it showed an output
//!   ([`Pipeline::displayed`]), which gives the end-to-end latency.
//! - Everything the operator changes (strategy, law, parameters, manual
//!   overrides, a new calibration) reaches the processing thread as a
//!   [`Control`] message and applies from the next set on.
//! - Offline sources may run in lock step ([`PipelineOptions::lockstep`]):
//!   capture then waits for room instead of dropping.

mod queue;
mod telemetry;

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender, TryRecvError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

pub use queue::{DropOldest, QueueStats};
pub use telemetry::{CameraRow, StageTimes, Telemetry, TelemetryRow};

use crate::error::{Error, Result};
use crate::exposure::{
    BalanceParams, CameraMasks, ControlMode, ControllerConfig, Estimate, Estimator,
    ExposureSetting, FrameView, Meter, Metered, MeteringConfig, NeighbourGraph, PixelFormat,
    ProbeEvent, RigController,
};
use crate::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
};
use crate::surround::{BlendMode, Canvas, Composer, SurroundView};

/// How exposure is decided: the choices the app offers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Strategy {
    /// Every camera at a fixed manual exposure level.
    Manual,
    /// The cameras' own auto-exposure (live cameras only); rigview only
    /// watches.
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

/// Checks that a surround view fits the source's cameras (count and image
/// sizes).
pub fn check_view(view: &SurroundView, cameras: &[CameraInfo]) -> Result<()> {
    if view.layers().len() != cameras.len() {
        return Err(Error::InvalidConfig(format!(
            "the calibration has {} cameras, the source {}",
            view.layers().len(),
            cameras.len()
        )));
    }
    for (layer, cam) in view.layers().iter().zip(cameras) {
        if layer.source != (cam.width, cam.height) {
            return Err(Error::InvalidConfig(format!(
                "camera {} (\"{}\"): the calibration is for {}×{} images, the camera gives {}×{}",
                layer.camera, cam.name, layer.source.0, layer.source.1, cam.width, cam.height
            )));
        }
    }
    Ok(())
}

/// An overlap patch drawn over a camera's thumbnail: its bounding box in
/// the source image, as fractions of the width and height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchBox {
    /// The overlap (index into [`Overlay::pairs`]).
    pub pair: usize,
    /// Left, top, right, bottom in [0, 1].
    pub rect: [f32; 4],
}

/// What the display draws over each camera: the overlap patches.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlay {
    /// The overlaps as camera index pairs.
    pub pairs: Vec<(usize, usize)>,
    /// Per camera, its patches.
    pub patches: Vec<Vec<PatchBox>>,
}

impl Overlay {
    fn of(view: Option<&SurroundView>, cameras: usize) -> Self {
        let mut o = Overlay {
            pairs: Vec::new(),
            patches: vec![Vec::new(); cameras],
        };
        let Some(view) = view else {
            return o;
        };
        for (k, ov) in view.overlaps().iter().enumerate() {
            o.pairs.push((ov.i, ov.j));
            for patch in &ov.patches {
                for (cam, pixels) in [(ov.i, &patch.pixels_i), (ov.j, &patch.pixels_j)] {
                    let Some(layer) = view.layers().get(cam) else {
                        continue;
                    };
                    let (w, h) = layer.source;
                    if let Some(rect) = bounding_box(pixels, w, h) {
                        if let Some(list) = o.patches.get_mut(cam) {
                            list.push(PatchBox { pair: k, rect });
                        }
                    }
                }
            }
        }
        o
    }
}

fn bounding_box(pixels: &[u32], w: usize, h: usize) -> Option<[f32; 4]> {
    if pixels.is_empty() || w == 0 || h == 0 {
        return None;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for &p in pixels {
        let (x, y) = (p as usize % w, p as usize / w);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    Some([
        x0 as f32 / w as f32,
        y0 as f32 / h as f32,
        (x1 + 1) as f32 / w as f32,
        (y1 + 1) as f32 / h as f32,
    ])
}

/// One camera in one processed set, for the display.
#[derive(Clone, Debug)]
pub struct CameraOutput {
    /// What the frame was taken with.
    pub taken: ExposureSetting,
    /// The metered image as 8-bit grey (the thumbnail), row-major.
    pub thumb: Vec<u8>,
    /// Its width.
    pub thumb_width: usize,
    /// Its height.
    pub thumb_height: usize,
    /// Per thumbnail pixel, whether it is metered (`None`: all are).
    pub metered_mask: Option<Vec<bool>>,
    /// Histogram of the metered pixels over [0, 1].
    pub histogram: Vec<u32>,
    /// Mean metered luminance in [0, 1].
    pub mean: f32,
    /// Fraction of metered pixels that are saturated.
    pub saturated: f32,
    /// The estimate (also computed for display when the strategy needs
    /// none).
    pub estimate: Option<Estimate>,
    /// The command sent after this frame.
    pub command: Option<ExposureSetting>,
    /// The manual override in force.
    pub manual: Option<f64>,
    /// The outcome of the camera's latest probe darker
    /// ([`crate::exposure::probe`]).
    pub last_probe: Option<ProbeEvent>,
}

/// One overlap in one processed set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairOutput {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// `log2 r_ij` (`None`: too few usable patches).
    pub log2_r: Option<f64>,
}

/// One processed frame set.
#[derive(Clone, Debug)]
pub struct Output {
    /// The set's trigger number.
    pub trigger: u64,
    /// When the set was ready (the source gave it).
    pub ready: Instant,
    /// When its processing was done.
    pub processed: Instant,
    /// Per camera.
    pub cameras: Vec<CameraOutput>,
    /// Per overlap.
    pub pairs: Vec<PairOutput>,
    /// The composed view (`None`: no calibration, or composition is off).
    pub canvas: Option<Arc<Canvas>>,
    /// The overlap patches to draw over the cameras.
    pub overlay: Arc<Overlay>,
    /// Stage times.
    pub times: StageTimes,
    /// The settings in force when it was processed.
    pub settings: Arc<ProcessingSettings>,
}

/// A set as the capture thread hands it on.
#[derive(Debug)]
struct Captured {
    set: FrameSet,
    ready: Instant,
    capture_ms: f64,
}

/// Does the per-set work; the processing thread owns one. Usable on its own
/// (tests, offline tools).
#[derive(Debug)]
pub struct Processor {
    cameras: Vec<CameraInfo>,
    settings: ProcessingSettings,
    shared_settings: Arc<ProcessingSettings>,
    meter: Meter,
    controller: RigController,
    display_estimators: Vec<Estimator>,
    view: Option<SurroundView>,
    masks: CameraMasks,
    overlay: Arc<Overlay>,
    composer: Composer,
    last_taken: Vec<Option<ExposureSetting>>,
    compose: bool,
    compose_error: Option<String>,
}

impl Processor {
    /// A processor for `cameras`, with an optional surround view (checked
    /// with [`check_view`]) and the cameras' neighbour graph.
    pub fn new(
        cameras: Vec<CameraInfo>,
        view: Option<SurroundView>,
        graph: NeighbourGraph,
        settings: ProcessingSettings,
    ) -> Result<Self> {
        settings.validate()?;
        if let Some(v) = &view {
            check_view(v, &cameras)?;
        }
        let ranges: Vec<_> = cameras.iter().map(|c| c.range).collect();
        let controller = RigController::new(settings.controller_config(), &ranges, graph)?;
        let display_estimators = cameras
            .iter()
            .map(|_| Estimator::new(settings.controller.estimator.clone()))
            .collect::<Result<_>>()?;
        let n = cameras.len();
        let mut p = Self {
            meter: Meter::new(settings.metering)?,
            controller,
            display_estimators,
            overlay: Arc::new(Overlay::of(view.as_ref(), n)),
            view,
            masks: CameraMasks::none(n),
            composer: Composer::new(),
            last_taken: vec![None; n],
            compose: true,
            compose_error: None,
            cameras,
            shared_settings: Arc::new(settings.clone()),
            settings,
        };
        p.update_masks();
        Ok(p)
    }

    fn update_masks(&mut self) {
        self.masks = match (&self.view, self.settings.roi) {
            (Some(v), MeterRoi::Ground) => {
                let formats: Vec<_> = self.cameras.iter().map(|c| c.format).collect();
                CameraMasks::new(&self.meter, v.ground_masks(), &formats)
            }
            _ => CameraMasks::none(self.cameras.len()),
        };
    }

    /// The settings in force.
    pub fn settings(&self) -> &ProcessingSettings {
        &self.settings
    }

    /// The surround view, if any.
    pub fn view(&self) -> Option<&SurroundView> {
        self.view.as_ref()
    }

    /// The controller.
    pub fn controller(&self) -> &RigController {
        &self.controller
    }

    /// Whether views are composed.
    pub fn set_compose(&mut self, on: bool) {
        self.compose = on;
    }

    /// Applies new settings. Returns whether the cameras' own auto-exposure
    /// must be switched (`Some(on)`).
    pub fn set_settings(&mut self, settings: ProcessingSettings) -> Result<Option<bool>> {
        settings.validate()?;
        let was_auto = self.settings.strategy == Strategy::CameraAuto;
        let is_auto = settings.strategy == Strategy::CameraAuto;
        self.controller.set_config(settings.controller_config())?;
        let metering_changed = settings.metering != self.settings.metering;
        if metering_changed {
            self.meter = Meter::new(settings.metering)?;
        }
        if settings.controller.estimator != self.settings.controller.estimator {
            self.display_estimators = self
                .cameras
                .iter()
                .map(|_| Estimator::new(settings.controller.estimator.clone()))
                .collect::<Result<_>>()?;
        }
        let roi_changed = settings.roi != self.settings.roi;
        self.shared_settings = Arc::new(settings.clone());
        self.settings = settings;
        if roi_changed || metering_changed {
            self.update_masks();
        }
        if was_auto && !is_auto {
            // The cameras' own AE moved them: start from where they are.
            self.sync_to_last();
        }
        Ok((was_auto != is_auto).then_some(is_auto))
    }

    fn sync_to_last(&mut self) {
        for (i, t) in self.last_taken.iter().enumerate() {
            if let (Some(t), Ok(c)) = (t, self.controller.camera_mut(i)) {
                c.sync(*t);
            }
        }
    }

    /// Holds camera `camera` at `exposure`, or releases it.
    pub fn set_manual(&mut self, camera: usize, exposure: Option<f64>) -> Result<()> {
        if let Some(e) = exposure {
            if !(e.is_finite() && e > 0.0) {
                return Err(Error::InvalidParameter {
                    name: "manual exposure",
                    value: e,
                    expected: "a positive exposure level (µs at 0 dB)",
                });
            }
        }
        self.controller.camera_mut(camera)?.set_manual(exposure);
        Ok(())
    }

    /// Uses a new calibration (see [`Control::Calibration`]).
    pub fn set_calibration(
        &mut self,
        view: Option<SurroundView>,
        graph: NeighbourGraph,
    ) -> Result<()> {
        if let Some(v) = &view {
            check_view(v, &self.cameras)?;
        }
        let ranges: Vec<_> = self.cameras.iter().map(|c| c.range).collect();
        let mut controller = RigController::new(self.settings.controller_config(), &ranges, graph)?;
        for i in 0..self.cameras.len() {
            let manual = self.controller.camera_mut(i)?.manual();
            let c = controller.camera_mut(i)?;
            c.set_manual(manual);
            if let Some(Some(t)) = self.last_taken.get(i) {
                c.sync(*t);
            }
        }
        self.controller = controller;
        self.overlay = Arc::new(Overlay::of(view.as_ref(), self.cameras.len()));
        self.view = view;
        self.compose_error = None;
        self.update_masks();
        Ok(())
    }

    /// The overlaps as camera index pairs (in telemetry order).
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        self.overlay.pairs.clone()
    }

    /// Processes one complete set: returns what to display and the commands
    /// to send. The set's frames must match the cameras.
    pub fn process(
        &mut self,
        set: &FrameSet,
        ready: Instant,
        mut times: StageTimes,
    ) -> Result<(Output, Vec<ExposureCommand>)> {
        let n = self.cameras.len();
        let frames: Vec<_> = set.frames.iter().flatten().collect();
        if frames.len() != n || !set.is_complete() {
            return Err(Error::InvalidConfig(format!(
                "frame set {}: {} of {n} frames complete",
                set.trigger,
                frames.iter().filter(|f| f.is_complete()).count()
            )));
        }
        let t0 = Instant::now();
        let views = frames
            .iter()
            .map(|f| f.view())
            .collect::<Result<Vec<FrameView<'_>>>>()?;
        let metered = self.masks.meter(&self.meter, &views)?;
        let observations = match &self.view {
            Some(v) => v.pair_observations(&views)?,
            None => Vec::new(),
        };
        let t1 = Instant::now();
        let step = self
            .controller
            .step_frames(&frames, &metered, &observations)?;
        let camera_auto = self.settings.strategy == Strategy::CameraAuto;
        let commands = if camera_auto {
            Vec::new()
        } else {
            step.commands()
        };
        let mut cameras = Vec::with_capacity(n);
        for (k, (f, m)) in frames.iter().zip(&metered).enumerate() {
            self.last_taken[k] = Some(f.meta.taken);
            let cs = step.cameras.get(k);
            let estimate = match cs.and_then(|c| c.estimate.clone()) {
                Some(e) => Some(e),
                None => match self.display_estimators.get_mut(k) {
                    Some(est) => Some(est.estimate(m)?),
                    None => None,
                },
            };
            let camera = self.controller.camera_mut(k)?;
            let (manual, last_probe) = (camera.manual(), camera.last_probe());
            cameras.push(camera_output(
                f.meta.taken,
                m,
                estimate,
                if camera_auto {
                    None
                } else {
                    cs.and_then(|c| c.command)
                },
                manual,
                last_probe,
            ));
        }
        let pairs: Vec<PairOutput> = self
            .overlay
            .pairs
            .iter()
            .map(|&(i, j)| PairOutput {
                i,
                j,
                log2_r: step
                    .ratios
                    .iter()
                    .find(|r| r.i == i && r.j == j)
                    .and_then(|r| r.r_ij)
                    .filter(|r| *r > 0.0)
                    .map(f64::log2),
            })
            .collect();
        let t2 = Instant::now();
        let canvas = match (&self.view, self.compose) {
            (Some(view), true) => {
                let channels = if views
                    .iter()
                    .any(|v| v.format() == PixelFormat::Rgb8 || v.format().is_bayer())
                {
                    3
                } else {
                    1
                };
                let (w, h) = view.size();
                let mut canvas = Canvas::new(w, h, channels);
                match self
                    .composer
                    .compose(view, &views, self.settings.blend, &mut canvas)
                {
                    Ok(()) => {
                        self.compose_error = None;
                        Some(Arc::new(canvas))
                    }
                    Err(e) => {
                        self.compose_error = Some(e.to_string());
                        None
                    }
                }
            }
            _ => None,
        };
        let t3 = Instant::now();
        times.meter_ms = ms(t1 - t0);
        times.control_ms = ms(t2 - t1);
        times.compose_ms = ms(t3 - t2);
        times.total_ms = ms(t3.saturating_duration_since(ready));
        let output = Output {
            trigger: set.trigger,
            ready,
            processed: t3,
            cameras,
            pairs,
            canvas,
            overlay: self.overlay.clone(),
            times,
            settings: self.shared_settings.clone(),
        };
        Ok((output, commands))
    }

    /// Why the last composition failed, if it did.
    pub fn compose_error(&self) -> Option<&str> {
        self.compose_error.as_deref()
    }
}

fn camera_output(
    taken: ExposureSetting,
    m: &Metered,
    estimate: Option<Estimate>,
    command: Option<ExposureSetting>,
    manual: Option<f64>,
    last_probe: Option<ProbeEvent>,
) -> CameraOutput {
    let thumb = m
        .luma()
        .iter()
        .map(|&v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
        .collect();
    let metered_mask = m.weight().map(|w| w.iter().map(|&v| v > 0.0).collect());
    let stats = m.stats();
    CameraOutput {
        taken,
        thumb,
        thumb_width: m.width(),
        thumb_height: m.height(),
        metered_mask,
        histogram: stats.histogram.clone(),
        mean: stats.mean,
        saturated: stats.saturated_fraction,
        estimate,
        command,
        manual,
        last_probe,
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// How the pipeline runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineOptions {
    /// Sets waiting between capture and processing (default 4: 200 ms at
    /// 20 Hz, enough for the first sets, which take longer).
    pub queue: usize,
    /// Outputs waiting for the display (1 for a window, which only wants the
    /// newest; more for a consumer that wants every output).
    pub output_queue: usize,
    /// Lock step (offline sources only): capture asks for the next set only
    /// when processing is done with the last one and its commands are
    /// applied, so nothing is dropped and a run is repeatable.
    pub lockstep: bool,
    /// Telemetry rows kept.
    pub history: usize,
    /// Whether views are composed.
    pub compose: bool,
}

impl Default for PipelineOptions {
    fn default() -> Self {
        Self {
            queue: 4,
            output_queue: 1,
            lockstep: false,
            history: 2400,
            compose: true,
        }
    }
}

/// The state of the pipeline as a whole.
#[derive(Clone, Debug, Default)]
pub struct PipelineStatus {
    /// Per camera, its stream health.
    pub health: Vec<StreamHealth>,
    /// The queue between capture and processing (its drops are sets that
    /// processing lost).
    pub capture_queue: QueueStats,
    /// The queue between processing and the display.
    pub output_queue: QueueStats,
    /// Sets the source gave.
    pub sets: u64,
    /// Sets that were incomplete (not processed).
    pub incomplete: u64,
    /// Sets processed.
    pub processed: u64,
    /// Sets reaching processing per second, over the last second.
    pub set_rate_hz: f64,
    /// The most recent problems, newest last.
    pub errors: VecDeque<String>,
    /// The source's messages for the operator, newest last (the last 50).
    pub notes: VecDeque<String>,
    /// Messages so far, including those forgotten.
    pub notes_total: u64,
    /// Whether the source has ended (a replay or a bounded simulation).
    pub finished: bool,
    /// Whether both threads have stopped.
    pub stopped: bool,
    /// The last end-to-end latencies (set ready → displayed), ms, with the
    /// time of the set, s.
    pub display_latency: VecDeque<[f64; 2]>,
}

impl PipelineStatus {
    fn error(&mut self, e: String) {
        if self.errors.back() != Some(&e) {
            self.errors.push_back(e);
        }
        while self.errors.len() > 8 {
            self.errors.pop_front();
        }
    }
}

enum CaptureMsg {
    Commands(Vec<ExposureCommand>),
    CameraAuto(bool),
    /// Processing is done with a set (lock step: capture may go on).
    Done,
}

#[derive(Debug)]
struct Shared {
    stop: AtomicBool,
    telemetry: Mutex<Telemetry>,
    status: Mutex<PipelineStatus>,
    t0_ns: Mutex<Option<u64>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // Every update under these locks leaves the data consistent, so a
    // poisoned lock still holds good data.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The running pipeline (see the module documentation). Dropping it stops
/// its threads.
#[derive(Debug)]
pub struct Pipeline {
    cameras: Vec<CameraInfo>,
    control: Sender<Control>,
    shared: Arc<Shared>,
    captured: Arc<DropOldest<Captured>>,
    output: Arc<DropOldest<Arc<Output>>>,
    threads: Vec<JoinHandle<()>>,
    started: Instant,
}

/// Called after each output is queued (a window asks for a repaint).
pub type Notify = Arc<dyn Fn() + Send + Sync>;

impl Pipeline {
    /// Starts the threads on `source`.
    pub fn start<S: FrameSource + 'static>(
        source: S,
        processor: Processor,
        options: PipelineOptions,
        notify: Notify,
    ) -> Result<Self> {
        let cameras = source.cameras().to_vec();
        if cameras.len() != processor.cameras.len() {
            return Err(Error::InvalidConfig(format!(
                "pipeline: the source has {} cameras, the processor {}",
                cameras.len(),
                processor.cameras.len()
            )));
        }
        let names = cameras.iter().map(|c| c.name.clone()).collect();
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            telemetry: Mutex::new(Telemetry::new(names, &processor.pairs(), options.history)),
            status: Mutex::new(PipelineStatus {
                health: source.health(),
                ..Default::default()
            }),
            t0_ns: Mutex::new(None),
        });
        let captured = Arc::new(DropOldest::new(options.queue));
        let output = Arc::new(DropOldest::new(options.output_queue));
        let (control_tx, control_rx) = mpsc::channel();
        let (capture_tx, capture_rx) = mpsc::channel();
        let mut processor = processor;
        processor.set_compose(options.compose);
        if processor.settings.strategy == Strategy::CameraAuto {
            let _ = capture_tx.send(CaptureMsg::CameraAuto(true));
        }
        let capture = {
            let (shared, captured) = (shared.clone(), captured.clone());
            let lockstep = options.lockstep;
            std::thread::Builder::new()
                .name("rigview-capture".into())
                .spawn(move || capture_loop(source, &shared, &captured, &capture_rx, lockstep))
                .map_err(|e| {
                    Error::InvalidConfig(format!("cannot start the capture thread: {e}"))
                })?
        };
        let processing = {
            let (shared, captured, output) = (shared.clone(), captured.clone(), output.clone());
            std::thread::Builder::new()
                .name("rigview-processing".into())
                .spawn(move || {
                    let mut ctx = ProcessingLoop {
                        processor,
                        shared: &shared,
                        captured: &captured,
                        output: &output,
                        control: &control_rx,
                        capture: &capture_tx,
                        notify: &notify,
                        recent: VecDeque::new(),
                    };
                    ctx.run();
                    output.close();
                    lock(&shared.status).stopped = true;
                    notify();
                })
                .map_err(|e| {
                    Error::InvalidConfig(format!("cannot start the processing thread: {e}"))
                })?
        };
        Ok(Self {
            cameras,
            control: control_tx,
            shared,
            captured,
            output,
            threads: vec![capture, processing],
            started: Instant::now(),
        })
    }

    /// The source's cameras.
    pub fn cameras(&self) -> &[CameraInfo] {
        &self.cameras
    }

    /// Sends a change to the processing thread.
    pub fn send(&self, control: Control) -> Result<()> {
        self.control
            .send(control)
            .map_err(|_| Error::InvalidConfig("the processing thread has stopped".into()))
    }

    /// The newest output not yet taken (older ones are skipped).
    pub fn latest(&self) -> Option<Arc<Output>> {
        self.output.take_latest()
    }

    /// The next output in order, waiting up to `timeout` (for consumers
    /// that want every output; start with a long output queue).
    pub fn next_output(&self, timeout: Duration) -> Option<Arc<Output>> {
        self.output.pop(timeout)
    }

    /// Records that `output` was shown now: the end-to-end latency.
    pub fn displayed(&self, output: &Output) {
        let latency = ms(Instant::now().saturating_duration_since(output.ready));
        let t = self.started.elapsed().as_secs_f64();
        let mut s = lock(&self.shared.status);
        s.display_latency.push_back([t, latency]);
        while s.display_latency.len() > 2400 {
            s.display_latency.pop_front();
        }
    }

    /// The telemetry history (hold the guard briefly: processing waits for
    /// it to record the next set).
    pub fn telemetry(&self) -> MutexGuard<'_, Telemetry> {
        lock(&self.shared.telemetry)
    }

    /// The pipeline's state.
    pub fn status(&self) -> PipelineStatus {
        let mut s = lock(&self.shared.status).clone();
        s.capture_queue = self.captured.stats();
        s.output_queue = self.output.stats();
        s
    }

    /// Whether the threads have stopped (the source ended or failed).
    pub fn is_stopped(&self) -> bool {
        lock(&self.shared.status).stopped
    }

    /// Stops the threads and waits for them.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.captured.close();
        self.output.close();
        for t in self.threads.drain(..) {
            // A thread that panicked has nothing more to give; its panic
            // message went to stderr.
            let _ = t.join();
        }
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        self.stop();
    }
}

fn capture_loop<S: FrameSource>(
    mut source: S,
    shared: &Shared,
    captured: &DropOldest<Captured>,
    messages: &Receiver<CaptureMsg>,
    lockstep: bool,
) {
    let mut last_health = Instant::now();
    // Lock step: sets handed on that processing has not finished.
    let mut in_flight = 0usize;
    while !shared.stop.load(Ordering::SeqCst) {
        loop {
            let msg = if lockstep && in_flight > 0 {
                match messages.recv_timeout(Duration::from_millis(100)) {
                    Ok(m) => m,
                    Err(mpsc::RecvTimeoutError::Timeout) => {
                        if shared.stop.load(Ordering::SeqCst) {
                            return;
                        }
                        continue;
                    }
                    Err(mpsc::RecvTimeoutError::Disconnected) => return,
                }
            } else {
                match messages.try_recv() {
                    Ok(m) => m,
                    Err(TryRecvError::Empty | TryRecvError::Disconnected) => break,
                }
            };
            let result = match msg {
                CaptureMsg::Commands(c) => source.apply(&c),
                CaptureMsg::CameraAuto(on) => source.set_camera_auto(on),
                CaptureMsg::Done => {
                    in_flight = in_flight.saturating_sub(1);
                    Ok(())
                }
            };
            if let Err(e) = result {
                lock(&shared.status).error(e.to_string());
            }
        }
        let t = Instant::now();
        let got = source.next_set(Duration::from_millis(100));
        let ready = Instant::now();
        if last_health.elapsed() >= Duration::from_millis(250) {
            let notes = source.take_messages();
            let mut s = lock(&shared.status);
            s.health = source.health();
            s.notes_total += notes.len() as u64;
            s.notes.extend(notes);
            while s.notes.len() > 50 {
                s.notes.pop_front();
            }
            last_health = Instant::now();
        }
        match got {
            Ok(Some(set)) => {
                lock(&shared.status).sets += 1;
                let item = Captured {
                    set,
                    ready,
                    capture_ms: ms(ready - t),
                };
                if lockstep {
                    in_flight += 1;
                    let mut item = item;
                    loop {
                        match captured.push_wait(item, Duration::from_millis(100)) {
                            Ok(()) => break,
                            Err(back) => {
                                if shared.stop.load(Ordering::SeqCst) || captured.is_closed() {
                                    return;
                                }
                                item = back;
                            }
                        }
                    }
                } else {
                    captured.push(item);
                }
            }
            Ok(None) => {
                if source.is_finished() {
                    break;
                }
            }
            Err(e) => {
                let fatal = matches!(e, SourceError::Failed(_));
                lock(&shared.status).error(e.to_string());
                if fatal {
                    std::thread::sleep(Duration::from_millis(200));
                }
            }
        }
    }
    {
        let notes = source.take_messages();
        let mut s = lock(&shared.status);
        s.health = source.health();
        s.finished = source.is_finished();
        s.notes_total += notes.len() as u64;
        s.notes.extend(notes);
    }
    captured.close();
}

struct ProcessingLoop<'a> {
    processor: Processor,
    shared: &'a Shared,
    captured: &'a DropOldest<Captured>,
    output: &'a DropOldest<Arc<Output>>,
    control: &'a Receiver<Control>,
    capture: &'a Sender<CaptureMsg>,
    notify: &'a Notify,
    recent: VecDeque<Instant>,
}

impl ProcessingLoop<'_> {
    fn run(&mut self) {
        loop {
            self.apply_controls();
            if self.shared.stop.load(Ordering::SeqCst) {
                return;
            }
            let Some(item) = self.captured.pop(Duration::from_millis(50)) else {
                if self.captured.is_closed() && self.captured.is_empty() {
                    return;
                }
                continue;
            };
            self.one(item);
            // Lock step: the commands went first, so the next set shows them.
            let _ = self.capture.send(CaptureMsg::Done);
        }
    }

    fn error(&self, e: impl ToString) {
        lock(&self.shared.status).error(e.to_string());
    }

    fn apply_controls(&mut self) {
        while let Ok(c) = self.control.try_recv() {
            let result = match c {
                Control::Settings(s) => match self.processor.set_settings(*s) {
                    Ok(Some(on)) => {
                        let _ = self.capture.send(CaptureMsg::CameraAuto(on));
                        Ok(())
                    }
                    Ok(None) => Ok(()),
                    Err(e) => Err(e),
                },
                Control::Manual { camera, exposure } => self.processor.set_manual(camera, exposure),
                Control::Calibration { view, graph } => {
                    let r = self.processor.set_calibration(view.map(|v| *v), graph);
                    if r.is_ok() {
                        lock(&self.shared.telemetry).set_pairs(&self.processor.pairs());
                    }
                    r
                }
            };
            if let Err(e) = result {
                self.error(e);
            }
        }
    }

    fn one(&mut self, item: Captured) {
        let popped = Instant::now();
        let Captured {
            set,
            ready,
            capture_ms,
        } = item;
        if !set.is_complete() {
            lock(&self.shared.status).incomplete += 1;
            return;
        }
        self.recent.push_back(ready);
        while self
            .recent
            .front()
            .is_some_and(|t| ready.saturating_duration_since(*t) > Duration::from_secs(1))
        {
            self.recent.pop_front();
        }
        let rate = match (self.recent.front(), self.recent.len()) {
            (Some(first), n) if n > 1 => {
                (n - 1) as f64
                    / ready
                        .saturating_duration_since(*first)
                        .as_secs_f64()
                        .max(1e-9)
            }
            _ => 0.0,
        };
        let times = StageTimes {
            capture_ms,
            queue_ms: ms(popped.saturating_duration_since(ready)),
            ..Default::default()
        };
        match self.processor.process(&set, ready, times) {
            Ok((output, commands)) => {
                if !commands.is_empty() {
                    let _ = self.capture.send(CaptureMsg::Commands(commands));
                }
                if let Some(e) = self.processor.compose_error() {
                    self.error(format!("the view cannot be composed: {e}"));
                }
                let dropped = self.captured.stats().dropped;
                let time_s = {
                    let mut t0 = lock(&self.shared.t0_ns);
                    let base = *t0.get_or_insert(set.timestamp_ns);
                    set.timestamp_ns.saturating_sub(base) as f64 * 1e-9
                };
                let row = TelemetryRow::of(&output, time_s, rate, dropped);
                lock(&self.shared.telemetry).push(row);
                {
                    let mut s = lock(&self.shared.status);
                    s.processed += 1;
                    s.set_rate_hz = rate;
                }
                self.output.push(Arc::new(output));
                (self.notify)();
            }
            Err(e) => self.error(format!("frame set {}: {e}", set.trigger)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{SimConfig, SimRender, SimRig, SimRigOptions};
    use crate::surround::{CanvasSpec, SurroundOptions};

    fn small_rig(frames: u64) -> (SimRig, SurroundView, NeighbourGraph) {
        let mut config = SimConfig::preset("reference").unwrap_or_default();
        config.scale = 0.25;
        let render = Arc::new(SimRender::new(&config).unwrap_or_else(|e| panic!("{e}")));
        let spec = CanvasSpec {
            px_per_m: 20.0,
            ..CanvasSpec::default()
        };
        let view = SurroundView::build(render.rig(), &spec, &SurroundOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let graph = NeighbourGraph::new(render.cameras().len(), &render.rig().neighbours)
            .unwrap_or_else(|e| panic!("{e}"));
        let rig = SimRig::new(
            render,
            SimRigOptions {
                frames: Some(frames),
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{e}"));
        (rig, view, graph)
    }

    #[test]
    fn in_lock_step_every_set_is_processed_and_composed() {
        let (rig, view, graph) = small_rig(12);
        let processor = Processor::new(
            rig.cameras().to_vec(),
            Some(view),
            graph,
            ProcessingSettings::default(),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let mut p = Pipeline::start(
            rig,
            processor,
            PipelineOptions {
                lockstep: true,
                output_queue: 64,
                ..Default::default()
            },
            Arc::new(|| {}),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let mut triggers = Vec::new();
        while let Some(out) = p.next_output(Duration::from_secs(30)) {
            assert!(out.canvas.is_some(), "set {} has no canvas", out.trigger);
            assert_eq!(out.cameras.len(), 4);
            assert_eq!(out.pairs.len(), 4);
            triggers.push(out.trigger);
        }
        p.stop();
        assert_eq!(triggers, (0..12).collect::<Vec<_>>());
        let s = p.status();
        assert_eq!(s.capture_queue.dropped, 0);
        assert_eq!(s.processed, 12);
        assert!(s.finished);
        assert_eq!(p.telemetry().total(), 12);
    }

    #[test]
    fn a_manual_override_reaches_the_camera() {
        let (rig, view, graph) = small_rig(20);
        let processor = Processor::new(
            rig.cameras().to_vec(),
            Some(view),
            graph,
            ProcessingSettings::default(),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let p = Pipeline::start(
            rig,
            processor,
            PipelineOptions {
                lockstep: true,
                output_queue: 64,
                ..Default::default()
            },
            Arc::new(|| {}),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        p.send(Control::Manual {
            camera: 2,
            exposure: Some(777.0),
        })
        .unwrap_or_else(|e| panic!("{e}"));
        let mut last = None;
        while let Some(out) = p.next_output(Duration::from_secs(30)) {
            last = Some(out);
        }
        let last = last.unwrap_or_else(|| panic!("no output"));
        let e = last.cameras[2].taken.exposure();
        assert!((e / 777.0 - 1.0).abs() < 0.01, "camera 2 at {e}, not 777");
        assert_eq!(last.cameras[2].manual, Some(777.0));
    }

    #[test]
    fn a_view_of_another_rig_is_refused() {
        let (rig, view, graph) = small_rig(1);
        let mut cams = rig.cameras().to_vec();
        cams[1].width += 2;
        let e = Processor::new(cams, Some(view), graph, ProcessingSettings::default());
        let msg = e
            .map(|_| ())
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(msg.contains("the calibration is for"), "{msg}");
    }
}
