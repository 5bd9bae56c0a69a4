//! The per-set work: metering, the controller, the measured ratios and the
//! composed view. The pipeline's processing thread and [`super::LockStep`]
//! both drive a [`Processor`].

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::{
    CameraOutput, DisplayGains, DisplayInput, Output, Overlay, PairOutput, ProcessingSettings,
    StageTimes, Strategy, View, BRIGHT_QUANTILE,
};
use crate::error::{Error, Result};
use crate::exposure::metering::histogram_quantile;
use crate::exposure::{
    CameraMasks, Estimate, Estimator, ExposureSetting, FrameView, Meter, Metered, NeighbourGraph,
    PixelFormat, ProbeEvent, RigController,
};
use crate::image::scale_8bit;
use crate::source::{CameraInfo, ExposureCommand, FrameSet};
use crate::surround::{Canvas, Composer, Mosaic, SeamBands, SurroundView};

/// How far (canvas pixels) from a seam the seam gains compare the cameras.
const SEAM_BAND_PX: usize = 3;
/// At most this many pixels of each seam's band are compared per set.
const SEAM_SAMPLES: usize = 512;

/// Checks that a view (its mosaic) fits the source's cameras (count and
/// image sizes).
pub fn check_view(view: &Mosaic, cameras: &[CameraInfo]) -> Result<()> {
    if view.layers().len() != cameras.len() {
        return Err(Error::invalid(
            "the calibration",
            "cameras",
            format!("the source's {}", cameras.len()),
            view.layers().len(),
        ));
    }
    for (layer, cam) in view.layers().iter().zip(cameras) {
        if layer.source != (cam.width, cam.height) {
            return Err(Error::invalid(
                format!("camera {} (\"{}\")", layer.camera, cam.name),
                "image size",
                format!("the camera's {}×{}", cam.width, cam.height),
                format_args!(
                    "the calibration is for {}×{} images",
                    layer.source.0, layer.source.1
                ),
            ));
        }
    }
    Ok(())
}

/// The rig controller for `cameras`: their ranges, and the fixed exposure
/// levels of those that have them.
fn rig_controller(
    settings: &ProcessingSettings,
    cameras: &[CameraInfo],
    graph: NeighbourGraph,
) -> Result<RigController> {
    let ranges: Vec<_> = cameras.iter().map(|c| c.range).collect();
    let mut controller = RigController::new(settings.controller_config(), &ranges, graph)?;
    for (k, cam) in cameras.iter().enumerate() {
        let camera = controller.camera_mut(k)?;
        camera.set_levels(cam.levels.clone());
        camera.set_tone_curve(cam.tone_curve.clone())?;
    }
    Ok(controller)
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
    view: Option<View>,
    masks: CameraMasks,
    overlay: Arc<Overlay>,
    composer: Composer,
    last_taken: Vec<Option<ExposureSetting>>,
    compose: bool,
    display: DisplayGains,
    /// Per camera, the samples of a frame shown at another exposure.
    scaled: Vec<Vec<u8>>,
    /// The view's seam bands, for the seam gains (built when first needed).
    seams: Option<SeamBands>,
    /// The canvases handed out last ([`CANVASES`]), taken again for a new
    /// set once nothing else holds them.
    canvases: Vec<Arc<Canvas>>,
}

/// How many canvases handed out a [`Processor`] keeps for reuse.
const CANVASES: usize = 4;

/// A `w×h` canvas of `channels` for a new set's picture (whose every pixel
/// the composition writes): one of `canvases` (handed out before) that
/// nothing else holds any more, or a new one. Reusing them spares a fresh
/// allocation of a few megabytes, and its page faults, per set.
fn take_canvas(canvases: &mut Vec<Arc<Canvas>>, w: usize, h: usize, channels: usize) -> Canvas {
    let free = canvases
        .iter()
        .position(|c| Arc::strong_count(c) == 1 && Arc::weak_count(c) == 0);
    let Some(mut canvas) = free.and_then(|i| Arc::into_inner(canvases.remove(i))) else {
        return Canvas::new(w, h, channels);
    };
    canvas.data.resize(w * h * channels, 0);
    (canvas.width, canvas.height, canvas.channels) = (w, h, channels);
    canvas
}

impl Processor {
    /// A processor for `cameras`, with an optional view (checked with
    /// [`check_view`]) and the cameras' neighbour graph.
    pub fn new(
        cameras: Vec<CameraInfo>,
        view: Option<View>,
        graph: NeighbourGraph,
        settings: ProcessingSettings,
    ) -> Result<Self> {
        settings.validate()?;
        if let Some(v) = &view {
            check_view(v.mosaic(), &cameras)?;
        }
        let controller = rig_controller(&settings, &cameras, graph)?;
        let display_estimators = cameras
            .iter()
            .map(|_| Estimator::new(settings.controller.estimator.clone()))
            .collect::<Result<_>>()?;
        let n = cameras.len();
        let mut p = Self {
            meter: Meter::new(settings.metering)?,
            controller,
            display_estimators,
            overlay: Arc::new(Overlay::of(view.as_ref().map(View::mosaic), n)),
            view,
            masks: CameraMasks::none(n),
            composer: Composer::new(),
            last_taken: vec![None; n],
            compose: true,
            display: DisplayGains::default(),
            scaled: Vec::new(),
            canvases: Vec::new(),
            seams: None,
            cameras,
            shared_settings: Arc::new(settings.clone()),
            settings,
        };
        p.update_masks();
        Ok(p)
    }

    fn update_masks(&mut self) {
        self.masks = match self
            .view
            .as_ref()
            .and_then(|v| v.meter_masks(self.settings.roi))
        {
            Some(masks) => {
                let formats: Vec<_> = self.cameras.iter().map(|c| c.format).collect();
                CameraMasks::new(&self.meter, masks, &formats)
            }
            None => CameraMasks::none(self.cameras.len()),
        };
    }

    /// The settings in force.
    pub fn settings(&self) -> &ProcessingSettings {
        &self.settings
    }

    /// The surround view, if that is the view.
    pub fn view(&self) -> Option<&SurroundView> {
        self.view.as_ref().and_then(View::surround)
    }

    /// The view, whichever it is.
    pub fn live_view(&self) -> Option<&View> {
        self.view.as_ref()
    }

    /// Asks the panorama (if that is the view) for a refinement of its
    /// rotations in the background; an error without a panorama.
    pub fn refine(&mut self) -> Result<()> {
        match self.view.as_mut().and_then(View::panorama_mut) {
            Some(p) => {
                p.request_refine();
                Ok(())
            }
            None => Err(Error::invalid(
                "refinement",
                "view",
                "the panorama (switch the view to the panorama first)",
                "another view",
            )),
        }
    }

    /// The controller.
    pub fn controller(&self) -> &RigController {
        &self.controller
    }

    /// The controller, to change (a camera's manual override or its sync
    /// goes through [`Processor::set_manual`] in the app; tests and offline
    /// tools reach a camera's controller here).
    pub fn controller_mut(&mut self) -> &mut RigController {
        &mut self.controller
    }

    /// The source's cameras.
    pub fn cameras(&self) -> &[CameraInfo] {
        &self.cameras
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
        if let Some(p) = self.view.as_mut().and_then(View::panorama_mut) {
            p.set_settings(&settings.panorama);
        }
        if let Some(b) = self.view.as_mut().and_then(View::bowl_mut) {
            b.set_wanted(&settings.bowl, settings.blend);
        }
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

    /// Tells each camera's controller where its camera is (for example
    /// after the cameras' own start-up auto-exposure), in rig order.
    pub fn sync(&mut self, settings: &[ExposureSetting]) -> Result<()> {
        if settings.len() != self.cameras.len() {
            return Err(Error::invalid(
                "starting settings",
                "count",
                format!("one for each of {} cameras", self.cameras.len()),
                settings.len(),
            ));
        }
        for (i, s) in settings.iter().enumerate() {
            self.controller.camera_mut(i)?.sync(*s);
            self.last_taken[i] = Some(*s);
        }
        Ok(())
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

    /// Uses a new calibration (see [`super::settings::Control::Calibration`]).
    pub fn set_calibration(&mut self, view: Option<View>, graph: NeighbourGraph) -> Result<()> {
        if let Some(v) = &view {
            check_view(v.mosaic(), &self.cameras)?;
        }
        let mut controller = rig_controller(&self.settings, &self.cameras, graph)?;
        for i in 0..self.cameras.len() {
            let manual = self.controller.camera_mut(i)?.manual();
            let c = controller.camera_mut(i)?;
            c.set_manual(manual);
            if let Some(Some(t)) = self.last_taken.get(i) {
                c.sync(*t);
            }
        }
        self.controller = controller;
        self.display.reset();
        self.overlay = Arc::new(Overlay::of(
            view.as_ref().map(View::mosaic),
            self.cameras.len(),
        ));
        self.view = view;
        self.seams = None;
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
            return Err(Error::IncompleteSet {
                trigger: set.trigger,
                complete: frames.iter().filter(|f| f.is_complete()).count(),
                cameras: n,
            });
        }
        let t0 = Instant::now();
        // The panorama takes in what its worker finished (a refined view
        // changes the maps and masks) and hands it its next job.
        let mut panorama = None;
        if let Some(p) = self.view.as_mut().and_then(View::panorama_mut) {
            let rebuilt = p.poll();
            p.schedule(set);
            let taken: Vec<f64> = frames.iter().map(|f| f.meta.taken.exposure()).collect();
            panorama = Some((p.observations(&taken), p.report().clone()));
            if rebuilt {
                self.overlay = Arc::new(Overlay::of(
                    self.view.as_ref().map(View::mosaic),
                    self.cameras.len(),
                ));
                self.update_masks();
            }
        }
        // The bowl takes in a viewpoint its builder finished.
        if let Some(b) = self.view.as_mut().and_then(View::bowl_mut) {
            b.poll();
        }
        let views = frames
            .iter()
            .map(|f| f.view())
            .collect::<Result<Vec<FrameView<'_>>>>()?;
        let metered = self.masks.meter(&self.meter, &views)?;
        let (observations, report) = match (&self.view, panorama) {
            (_, Some((observations, report))) => (observations, Some(report)),
            (Some(v), None) => (v.mosaic().pair_observations(&views)?, None),
            (None, None) => (Vec::new(), None),
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
            let (manual, last_probe) = (
                camera.manual(),
                (camera.last_probe(), camera.last_probe_brighter()),
            );
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
                cs.is_some_and(|c| c.probe_frame),
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
        let mut compose_error = None;
        let mut display_gains = Vec::new();
        let mut gain_parts = Vec::new();
        let mut shown_frames = Vec::new();
        let mut beside = None;
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
                // The bowl shows its own picture (with the vehicle painted
                // over it) at the gains of the bird's-eye view's seams.
                let bowl = view.bowl().map(|b| b.shown().clone());
                let shown_view = view.display_mosaic();
                let view = view.mosaic();
                let (w, h) = shown_view.size();
                let mut canvas = take_canvas(&mut self.canvases, w, h, channels);
                // Each camera's tone curve as its nearest power (1: linear).
                let powers: Vec<f64> = (0..cameras.len())
                    .map(|k| {
                        self.controller
                            .camera_mut(k)
                            .map_or(1.0, |c| c.tone_power())
                    })
                    .collect();
                let inputs: Vec<DisplayInput> = cameras
                    .iter()
                    .zip(&powers)
                    .map(|(c, &power)| DisplayInput {
                        taken: c.taken.exposure(),
                        mean: f64::from(c.mean),
                        probe_frame: c.probe_frame,
                        // A seam gain may not wash out a camera's bright
                        // part: the panorama's cameras see sky and shade
                        // side by side, the surround view's sunlit ground
                        // beside a shaded neighbour (the simulated rig's
                        // front camera, brightened 0.6 EV to its shaded
                        // neighbours at the seams, showed its sunlit
                        // ground white).
                        bright: f64::from(histogram_quantile(&c.histogram, BRIGHT_QUANTILE)),
                        power,
                    })
                    .collect();
                // The seam gains even out the ratios the view shows at its
                // seams; a seam with no pixel both cameras show unclipped
                // falls back to its overlap's patches.
                let patch = |i: usize, j: usize| {
                    pairs
                        .iter()
                        .find(|p| (p.i, p.j) == (i, j))
                        .and_then(|p| p.log2_r)
                };
                // In the panorama the pixels either side of a seam show the
                // same point only at the cylinder's radius (parallax
                // elsewhere): its seam gains use the matched patches,
                // which are correspondences.
                let matched = report.is_some();
                let ratios: Vec<_> = if self.settings.display.compensate && matched {
                    pairs.iter().map(|p| (p.i, p.j, p.log2_r)).collect()
                } else if self.settings.display.compensate {
                    self.seams
                        .get_or_insert_with(|| SeamBands::new(view, SEAM_BAND_PX))
                        .ratios(&views, SEAM_SAMPLES)?
                        .into_iter()
                        .map(|(i, j, r)| (i, j, r.or_else(|| patch(i, j))))
                        .collect()
                } else {
                    Vec::new()
                };
                let gains = self
                    .display
                    .update(&self.settings.display, &inputs, &ratios);
                display_gains = gains.iter().map(|g| g.total()).collect();
                if bowl.is_some() {
                    // What a GPU needs to show the frames as the composer
                    // does: the exposure gain (clipped at white) and the
                    // seam gain, or the whole gain where the frame is shown
                    // at the exposure it was taken with.
                    gain_parts = gains
                        .iter()
                        .map(|g| {
                            if (g.exposure - 1.0).abs() > 1e-6 {
                                [g.exposure, g.seam]
                            } else {
                                [1.0, g.total()]
                            }
                        })
                        .collect();
                }
                // The window draws the bowl itself (on the GPU): no picture
                // here, but the bird's-eye view beside it if asked for.
                let skip_picture = bowl.is_some() && self.settings.bowl.gpu_draws;
                // A frame shown at another exposure than it was taken with
                // is scaled sample by sample (clipped where its sensor
                // clips); the composer applies the seam gains.
                self.scaled.resize_with(n, Vec::new);
                let mut shown = Vec::with_capacity(n);
                let mut composer_gains = Vec::with_capacity(n);
                for ((v, g), buf) in views.iter().zip(&gains).zip(&mut self.scaled) {
                    let scaled = if (g.exposure - 1.0).abs() > 1e-6 {
                        scale_8bit(v, g.exposure, buf)?
                    } else {
                        None
                    };
                    match scaled {
                        Some(s) => {
                            shown.push(s);
                            composer_gains.push(g.seam);
                        }
                        None => {
                            shown.push(*v);
                            composer_gains.push(g.total());
                        }
                    }
                }
                let composed = if skip_picture {
                    Ok(())
                } else {
                    self.composer
                        .compose_with_gains(
                            shown_view,
                            &shown,
                            self.settings.blend,
                            Some(&composer_gains),
                            &mut canvas,
                        )
                        .and_then(|()| match &bowl {
                            Some(b) => b.paint_vehicle(&mut canvas),
                            None => Ok(()),
                        })
                };
                // The bird's-eye view beside the bowl, at the same gains.
                if bowl.is_some() && self.settings.bowl.beside && composed.is_ok() {
                    let (bw, bh) = view.size();
                    let mut birds_eye = Canvas::new(bw, bh, channels);
                    match self.composer.compose_with_gains(
                        view,
                        &shown,
                        self.settings.blend,
                        Some(&composer_gains),
                        &mut birds_eye,
                    ) {
                        Ok(()) => beside = Some(Arc::new(birds_eye)),
                        Err(e) => compose_error = Some(e.to_string()),
                    }
                }
                match composed {
                    Ok(()) if skip_picture => None,
                    Ok(()) => {
                        let canvas = Arc::new(canvas);
                        if self.canvases.len() == CANVASES {
                            self.canvases.remove(0);
                        }
                        self.canvases.push(Arc::clone(&canvas));
                        Some(canvas)
                    }
                    Err(e) => {
                        compose_error = Some(e.to_string());
                        None
                    }
                }
            }
            _ => None,
        };
        // The frames go along (shared, not copied), for a renderer or a
        // remote view of their own.
        shown_frames.extend(frames.iter().map(|f| (*f).clone()));
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
            beside,
            display_gains,
            compose_error,
            overlay: self.overlay.clone(),
            times,
            settings: self.shared_settings.clone(),
            step,
            panorama: report,
            view: self.view.as_ref().map(View::kind),
            bowl: self
                .view
                .as_ref()
                .and_then(View::bowl)
                .map(|b| (*b.shown().viewpoint(), b.building())),
            bowl_view: self
                .view
                .as_ref()
                .and_then(View::bowl)
                .map(|b| b.shown().clone()),
            frames: shown_frames,
            gain_parts,
        };
        Ok((output, commands))
    }
}

/// The thumbnail's byte of an intensity: `v` (clamped to [0, 1], NaN as 0)
/// times 255, rounded to the nearest (ties to even). Adding 1.5·2²³ leaves
/// the rounded integer in the low bits of the mantissa: that vectorises,
/// where the saturating `as u8` ran one value at a time (3 % of the
/// processing thread).
#[allow(clippy::manual_clamp)] // `max` first: NaN becomes 0 (`clamp` keeps it)
pub(super) fn thumb_byte(v: f32) -> u8 {
    let rounded = v.max(0.0).min(1.0) * 255.0 + 12_582_912.0;
    rounded.to_bits().to_le_bytes()[0]
}

fn camera_output(
    taken: ExposureSetting,
    m: &Metered,
    estimate: Option<Estimate>,
    command: Option<ExposureSetting>,
    manual: Option<f64>,
    (last_probe, last_probe_brighter): (Option<ProbeEvent>, bool),
    probe_frame: bool,
) -> CameraOutput {
    let thumb = m.luma().iter().map(|&v| thumb_byte(v)).collect();
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
        last_probe_brighter,
        probe_frame,
    }
}

pub(super) fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}
