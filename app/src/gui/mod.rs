//! The desktop app (eframe/egui): the surround view, the cameras with
//! their metering ROI, overlap patches, histograms and readouts, the
//! controls, the live plots and the status bar.
//!
//! The window only shows what the pipeline's threads produce
//! ([`rigview_core::pipeline`]): it takes the newest output when it paints,
//! uploads it as textures, and sends every change the operator makes to the
//! processing thread. A slow window skips outputs; it never slows capture or
//! processing.

//!
//! `RigviewApp` holds the session and what the window shows of it; the
//! parts with a life of their own are types of their own: the messages
//! ([`messages`]), the Record button and the recordings it closes
//! ([`recording`]), the file dialogs and the views built in the background
//! ([`background`]), and closing on time or after a screenshot
//! ([`closing`]). What is drawn is in [`panels`], [`controls`] and
//! [`plots`].

pub mod background;
mod bowl;
pub mod bowl_gl;
mod bowl_gpu;
pub mod closing;
pub mod controls;
pub mod messages;
pub mod panels;
pub mod plots;
pub mod recording;
pub mod view_texture;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use egui::{Color32, TextureHandle, TextureOptions};
use rigview_core::pipeline::{
    Control, Notify, Output, PipelineOptions, PipelineStatus, ProcessingSettings,
};
use rigview_record::Recorder;

use self::background::{Background, Loaded, Loading, Pick};
use self::closing::Closing;
pub use self::messages::Message;
use self::messages::Messages;
pub use self::recording::recording_text;
use self::recording::RecordButton;
use self::view_texture::{GlTexture, ViewTexture};
use crate::logging::{self, LogBuffer};
use crate::report::CpuMeter;
use crate::session::{self, Session, SourceSpec};
use crate::session::{RecordSpec, ReplayControl, ReplaySpec};
use crate::settings::{BowlRenderer, Settings, SettingsStore};

/// The start's share of a run that the steady CPU figure leaves out.
const WARM_UP: Duration = Duration::from_secs(5);

/// What the pipeline calls for each new output: one window frame.
///
/// egui paints twice for every immediate request (`request_repaint`: "to
/// give some things time to settle"), and once for a request after a
/// delay. A new output every 50 ms made 28 frames a second, of which 8
/// showed nothing new; a request 1 ms ahead makes one frame per output.
/// What the second frame settles is settled by the next output's.
fn repaint_on_output(ctx: &egui::Context) -> Notify {
    let ctx = ctx.clone();
    Arc::new(move || ctx.request_repaint_after(Duration::from_millis(1)))
}

/// Panels without a fill: the window is cleared to the panels' colour
/// instead ([`panel_colour`]). With Mesa's software GL each pixel painted
/// costs the rasteriser its time, and every pixel of the window was
/// painted twice, by the clear and by a panel's fill, and the views' pixels
/// a third time.
fn unfilled_panels(ctx: &egui::Context) {
    ctx.all_styles_mut(|s| s.visuals.panel_fill = egui::Color32::TRANSPARENT);
}

/// The panels' colour of the theme of `visuals`.
fn panel_colour(visuals: &egui::Visuals) -> egui::Color32 {
    if visuals.dark_mode {
        egui::Visuals::dark().panel_fill
    } else {
        egui::Visuals::light().panel_fill
    }
}

/// The app's state.
pub struct RigviewApp {
    session: Option<Session>,
    settings: Settings,
    store: SettingsStore,
    dirty: Option<Instant>,
    latest: Option<Arc<Output>>,
    /// The pipeline's status, taken once per window frame.
    status: Option<PipelineStatus>,
    canvas_tex: ViewTexture,
    /// The bird's-eye view beside the bowl.
    beside_tex: ViewTexture,
    thumb_tex: Vec<Option<TextureHandle>>,
    messages: Messages,
    background: Background,
    open_path: String,
    recording_path: String,
    record: RecordButton,
    pipeline_options: PipelineOptions,
    notify: Notify,
    manual: Vec<(bool, f64)>,
    calibration: String,
    shown: u64,
    /// Window frames laid out (and painted) since the start.
    painted: u64,
    /// Of them, frames no repaint request asked for (input or the
    /// window system's own).
    causeless: u64,
    displayed_trigger: Option<u64>,
    closing: Closing,
    cpu: CpuMeter,
    /// CPU use from [`WARM_UP`] after the start on: without the start's
    /// one-off work (the simulated scene's tracing, the first views).
    steady_cpu: Option<CpuMeter>,
    bowl: bowl::BowlState,
    gpu_bowl: bowl_gpu::GpuBowl,
    /// The remote view's options, for each session (a replay opened in
    /// the window serves too).
    serve: Option<crate::serve::ServeOptions>,
}

impl std::fmt::Debug for RigviewApp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RigviewApp")
            .field("calibration", &self.calibration)
            .field("shown", &self.shown)
            .finish_non_exhaustive()
    }
}

/// How the app starts.
#[derive(Debug)]
pub struct AppOptions {
    /// The source.
    pub source: SourceSpec,
    /// The settings file (`None`: the user's configuration folder).
    pub settings: Option<PathBuf>,
    /// Close the window after this long (for scripted runs).
    pub quit_after: Option<Duration>,
    /// Save a screenshot to this PNG after this long, then close.
    pub screenshot: Option<(PathBuf, Duration)>,
    /// The window's size, points (`None`: 1600 × 1000).
    pub window_size: Option<[f32; 2]>,
    /// Serve the live remote view (`--serve`).
    pub serve: Option<crate::serve::ServeOptions>,
    /// Pipeline options (lock step for repeatable tests).
    pub pipeline: PipelineOptions,
    /// The events the Messages panel shows (those from the app's start on):
    /// [`LogBuffer::global`] when [`logging::init`] has set up the process.
    pub log: LogBuffer,
    /// Record from the start, as the Record button does (`--record`).
    pub record: Option<RecordSpec>,
}

impl RigviewApp {
    /// Starts the session; a failure is shown in the window, which stays
    /// open so that the operator can read it.
    pub fn new(ctx: &egui::Context, options: AppOptions) -> Self {
        let messages = Messages::new(options.log);
        let mut store = SettingsStore::new(options.settings);
        let (mut settings, settings_error) = store.load();
        if let Some(e) = settings_error {
            tracing::warn!("{e:#}");
        }
        // The window's view choice is the view the pipeline composes.
        settings.processing.view = settings.window.view.kind();
        let notify = repaint_on_output(ctx);
        unfilled_panels(ctx);
        let start = |record| {
            session::start_recording(
                &options.source,
                &settings.processing,
                options.pipeline,
                notify.clone(),
                record,
            )
        };
        let started = match start(options.record.as_ref()) {
            Err(e) if options.record.is_some() => {
                // The view goes on without the recording if that is what failed.
                tracing::error!("{e:#}");
                start(None)
            }
            other => other,
        };
        let mut session = match started {
            Ok(s) => Some(s),
            Err(e) => {
                tracing::error!("cannot start the source: {e:#}");
                None
            }
        };
        if let (Some(s), Some(serve)) = (session.as_mut(), &options.serve) {
            match s.serve(serve) {
                Ok(()) => {
                    tracing::info!(target: logging::NOTE, "remote view on ws://{}", serve.addr);
                }
                Err(e) => tracing::error!("{e:#}"),
            }
        }
        let record = RecordButton::new(session.as_ref().and_then(Session::recorder));
        let n = session.as_ref().map_or(0, |s| s.pipeline.cameras().len());
        let start_level = settings.processing.controller.fixed_exposure;
        let calibration = session
            .as_ref()
            .map_or_else(|| "none".into(), |s| s.calibration.clone());
        let mut app = Self {
            session,
            settings,
            store,
            dirty: None,
            latest: None,
            status: None,
            canvas_tex: ViewTexture::default(),
            beside_tex: ViewTexture::default(),
            thumb_tex: vec![None; n],
            messages,
            background: Background::default(),
            open_path: String::new(),
            recording_path: String::new(),
            record,
            pipeline_options: options.pipeline,
            notify,
            manual: vec![(false, start_level); n],
            calibration,
            shown: 0,
            painted: 0,
            causeless: 0,
            displayed_trigger: None,
            closing: Closing::new(options.quit_after, options.screenshot),
            cpu: CpuMeter::start(),
            steady_cpu: None,
            bowl: bowl::BowlState::default(),
            gpu_bowl: bowl_gpu::GpuBowl::default(),
            serve: options.serve.clone(),
        };
        if let Some(r) = app.record.recorder() {
            let text = format!("recording into {}", r.file().display());
            app.note(text, false);
        }
        app.messages.read();
        app
    }

    /// The newest output shown.
    pub fn latest(&self) -> Option<&Arc<Output>> {
        self.latest.as_ref()
    }

    /// Outputs shown so far.
    pub fn shown(&self) -> u64 {
        self.shown
    }

    /// The messages in the window.
    pub fn messages(&self) -> &[Message] {
        self.messages.list()
    }

    /// The settings as the operator set them.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The session, if it started.
    pub fn session(&self) -> Option<&Session> {
        self.session.as_ref()
    }

    /// The cameras' names, in rig order (none without a session).
    pub fn camera_names(&self) -> Vec<String> {
        self.session
            .as_ref()
            .map(Session::camera_names)
            .unwrap_or_default()
    }

    /// Where the calibration came from.
    pub fn calibration(&self) -> &str {
        &self.calibration
    }

    /// Whether a calibration is being loaded.
    pub fn is_loading(&self) -> bool {
        self.background.is_loading()
    }

    /// Whether the app asked to close (its time is up).
    pub fn wants_close(&self) -> bool {
        self.closing.wants_close()
    }

    /// Closes the window at its next frame (*File → Quit*).
    pub fn close(&mut self) {
        self.closing.close();
    }

    /// The replay's controls, when the source is a recording.
    pub fn replay(&self) -> Option<&ReplayControl> {
        self.session.as_ref().and_then(|s| s.replay.as_ref())
    }

    /// The recording in progress.
    pub fn recorder(&self) -> Option<&Arc<Recorder>> {
        self.record.recorder()
    }

    /// Whether recordings stopped by the operator are still being closed.
    pub fn is_finishing_recording(&self) -> bool {
        self.record.is_finishing()
    }

    /// The file the Record button records into.
    pub fn set_record_path(&mut self, path: &Path) {
        self.record.path = path.display().to_string();
    }

    /// Starts recording the session's sets into `spec`'s file (the Record
    /// button, `--record`); a failure is shown and the view goes on.
    pub fn start_recording(&mut self, spec: &RecordSpec) {
        self.record
            .start(self.session.as_ref(), spec, &mut self.messages);
    }

    /// Stops the recording in progress: no set is offered to it after
    /// this, and its file is closed in the background (its summary then
    /// goes to the Messages panel).
    pub fn stop_recording(&mut self) {
        self.record.stop(self.session.as_ref(), &mut self.messages);
    }

    /// Switches the window's source to a replay of `path`, with the
    /// recording's own calibration. The running source stops (and its
    /// recording, if any); a recording that cannot be opened is reported
    /// and nothing else changes.
    pub fn open_recording(&mut self, path: &Path) {
        let spec = session::SourceSpec::Replay(ReplaySpec {
            file: path.to_path_buf(),
            rig: None,
            interactive: true,
        });
        // The file is checked before the running source is stopped.
        if let Err(e) = rigview_record::ReplaySource::open(path) {
            self.note(format!("cannot open the recording: {e}"), true);
            return;
        }
        self.stop_recording();
        if let Some(mut old) = self.session.take() {
            old.pipeline.stop();
        }
        let started = session::start(
            &spec,
            &self.settings.processing,
            self.pipeline_options,
            self.notify.clone(),
        );
        let n = match started {
            Ok(mut s) => {
                if let Some(serve) = &self.serve {
                    if let Err(e) = s.serve(serve) {
                        self.note(format!("{e:#}"), true);
                    }
                }
                let n = s.pipeline.cameras().len();
                self.calibration = s.calibration.clone();
                self.note(format!("replaying {}", path.display()), false);
                self.session = Some(s);
                n
            }
            Err(e) => {
                self.calibration = "none".into();
                self.note(format!("cannot replay {}: {e:#}", path.display()), true);
                0
            }
        };
        self.latest = None;
        self.status = None;
        self.canvas_tex.clear();
        self.beside_tex.clear();
        self.thumb_tex = vec![None; n];
        let level = self.settings.processing.controller.fixed_exposure;
        self.manual = vec![(false, level); n];
        self.displayed_trigger = None;
    }

    /// Reports a problem (`error`) or a note as an event, and shows it.
    fn note(&mut self, text: String, error: bool) {
        self.messages.note(text, error);
    }

    /// Sends the processing settings to the pipeline and marks them for
    /// saving.
    fn settings_changed(&mut self) {
        // The view is the window's choice (Reset to defaults keeps it).
        self.settings.processing.view = self.settings.window.view.kind();
        let processing: ProcessingSettings = self.settings.processing.clone();
        if let Err(e) = processing.validate() {
            self.note(format!("setting refused: {e}"), true);
            return;
        }
        if let Some(s) = &self.session {
            if let Err(e) = s.pipeline.send(Control::Settings(Box::new(processing))) {
                self.note(format!("{e}"), true);
            }
        }
        self.dirty = Some(Instant::now());
    }

    fn window_changed(&mut self) {
        self.dirty = Some(Instant::now());
    }

    fn set_manual(&mut self, camera: usize, exposure: Option<f64>) {
        if let Some(s) = &self.session {
            if let Err(e) = s.pipeline.send(Control::Manual { camera, exposure }) {
                self.note(format!("{e}"), true);
            }
        }
    }

    /// Starts loading a calibration file in the background.
    pub fn open_calibration(&mut self, path: &Path) {
        let Some(s) = &self.session else {
            self.note(
                "no source is running: a calibration has nothing to apply to".into(),
                true,
            );
            return;
        };
        let cameras = s.pipeline.cameras().to_vec();
        let processing = self.settings.processing.clone();
        let p = path.to_path_buf();
        self.background.build(
            Loading::Calibration(path.to_path_buf()),
            move || session::load_calibration(&p, &cameras, &processing),
            &mut self.messages,
        );
    }

    /// Switches the big view to `mode`: the pipeline goes on with the view
    /// it has while the new one is built in the background.
    pub fn switch_view(&mut self, mode: crate::settings::ViewMode) {
        self.settings.window.view = mode;
        self.settings.processing.view = mode.kind();
        self.settings_changed();
        let Some(s) = &self.session else {
            return;
        };
        let Some(rig) = s.rig.clone() else {
            self.note(
                format!(
                    "no calibration in use: the {} view needs one (File, Open calibration)",
                    mode.kind().name()
                ),
                true,
            );
            return;
        };
        let cameras = s.pipeline.cameras().to_vec();
        let processing = self.settings.processing.clone();
        self.background.build(
            Loading::View(mode.kind()),
            move || {
                let (view, graph) = session::view_for(&rig, &cameras, &processing)?;
                Ok((view, graph, rig))
            },
            &mut self.messages,
        );
    }

    /// Asks the panorama for a refinement of its rotations (in the
    /// background; the view changes when it is done).
    pub fn refine(&mut self) {
        if let Some(s) = &self.session {
            match s.pipeline.send(Control::Refine) {
                Ok(()) => self.note("refining the panorama's rotations…".into(), false),
                Err(e) => self.note(format!("{e}"), true),
            }
        }
    }

    /// Saves the rig the panorama is built from (refined rotations
    /// included) to `path`, in the format its extension says.
    pub fn save_rig(&mut self, path: &Path) {
        let rig = self
            .latest
            .as_ref()
            .and_then(|o| o.panorama.as_ref())
            .and_then(|r| r.rig.clone());
        let Some(rig) = rig else {
            self.note("no panorama: there is no refined rig to save".into(), true);
            return;
        };
        match rigview_calib::formats::save(&rig, path, None) {
            Ok(written) => {
                for p in written {
                    self.note(format!("wrote the rig to {}", p.display()), false);
                }
            }
            Err(e) => self.note(
                format!("cannot save the rig to {}: {e}", path.display()),
                true,
            ),
        }
    }

    /// Opens the native file dialog in the background.
    pub(super) fn open_dialog(&mut self, pick: Pick) {
        self.background.open_dialog(pick, &mut self.messages);
    }

    /// Carries out what the background finished: a file picked, a view
    /// built.
    fn poll_background(&mut self) {
        if let Some((pick, path)) = self.background.poll_dialog(&mut self.messages) {
            match pick {
                Pick::Calibration => self.open_calibration(&path),
                Pick::Recording => self.open_recording(&path),
                Pick::SaveRig => self.save_rig(&path),
            }
        }
        if let Some((what, result)) = self.background.poll_loading() {
            self.view_built(what, result);
        }
    }

    /// Hands a view built in the background to the pipeline.
    fn view_built(&mut self, what: Loading, result: Option<Loaded>) {
        let (view, graph, rig) = match result {
            Some(Ok(built)) => built,
            Some(Err(e)) => return self.note(format!("{e:#}"), true),
            None => {
                return self.note(
                    format!("building the view ({what:?}) stopped without a result"),
                    true,
                )
            }
        };
        let Some(s) = self.session.as_mut() else {
            return;
        };
        let kind = view.kind();
        if let Err(e) = s.pipeline.send(Control::Calibration {
            view: Some(Box::new(view)),
            graph,
        }) {
            return self.note(format!("{e}"), true);
        }
        s.rig = Some(rig);
        match what {
            Loading::Calibration(path) => {
                self.calibration = path.display().to_string();
                self.note(format!("calibration {} in use", path.display()), false);
                let recent = &mut self.settings.window.recent;
                recent.retain(|p| p != &path);
                recent.insert(0, path);
                recent.truncate(8);
                self.window_changed();
            }
            Loading::View(_) => self.note(format!("the {} view is in use", kind.name()), false),
        }
    }

    /// Takes the newest output and uploads its images.
    fn take_output(&mut self, ctx: &egui::Context) {
        let Some(out) = self.session.as_ref().and_then(|s| s.pipeline.latest()) else {
            return;
        };
        let mut failures = Vec::new();
        if let Some(c) = &out.canvas {
            failures.extend(self.canvas_tex.upload(ctx, "surround", c));
        }
        match &out.beside {
            Some(c) => failures.extend(self.beside_tex.upload(ctx, "beside", c)),
            None => self.beside_tex.clear(),
        }
        for e in failures {
            self.note(e, true);
        }
        if self.thumb_tex.len() != out.cameras.len() {
            self.thumb_tex = vec![None; out.cameras.len()];
        }
        for (k, cam) in out.cameras.iter().enumerate() {
            let image = panels::thumbnail_image(cam, self.settings.window.show_roi);
            match &mut self.thumb_tex[k] {
                Some(t) => t.set(image, TextureOptions::LINEAR),
                slot @ None => {
                    *slot =
                        Some(ctx.load_texture(format!("camera{k}"), image, TextureOptions::LINEAR));
                }
            }
        }
        self.latest = Some(out);
    }

    /// Draws the whole window into `ui`.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        self.painted += 1;
        if self.steady_cpu.is_none() && self.cpu.seconds() >= WARM_UP.as_secs_f64() {
            self.steady_cpu = Some(CpuMeter::start());
        }
        self.causeless += u64::from(ctx.repaint_causes().is_empty());
        self.poll_background();
        self.record.poll(&mut self.messages);
        self.status = self.session.as_ref().map(|s| s.pipeline.status());
        // The pipeline's new messages and problems pass on as events, and
        // what reached the log is shown.
        self.messages.forward(self.status.as_ref());
        self.take_output(&ctx);
        bowl::step(self, &ctx);
        panels::menu_bar(self, ui);
        panels::replay_bar(self, ui);
        panels::status_bar(self, ui);
        controls::controls(self, ui);
        plots::plot_panel(self, ui);
        panels::cameras_panel(self, ui);
        panels::central(self, ui);
        // An output counts as displayed once, in the first frame laid out
        // with it (the paint follows at once).
        if let (Some(out), Some(s)) = (&self.latest, &self.session) {
            if self.displayed_trigger != Some(out.trigger) {
                s.pipeline.displayed(out);
                self.displayed_trigger = Some(out.trigger);
                self.shown += 1;
            }
        }
        if self
            .dirty
            .is_some_and(|t| t.elapsed() > Duration::from_millis(500))
        {
            self.save_settings();
        }
        self.closing.poll(&ctx);
        if self.background.is_busy() || self.record.is_busy() || self.replay().is_some() {
            ctx.request_repaint_after(Duration::from_millis(50));
        }
    }

    fn save_settings(&mut self) {
        self.dirty = None;
        if let Err(e) = self.store.save(&self.settings) {
            self.note(format!("{e:#}"), true);
        }
    }

    /// Saves the settings and stops the pipeline; returns a summary of the
    /// run (sets, drops, latency, CPU).
    pub fn finish(&mut self) -> String {
        self.save_settings();
        let Some(s) = self.session.as_mut() else {
            return "no source ran".into();
        };
        // The pipeline first, so that every set it processed is recorded.
        s.pipeline.stop();
        let recorded = self.record.finish(s);
        let status = s.pipeline.status();
        let mut summary = format!(
            "source: {}\n{}",
            s.source_name,
            crate::report::summary(&status, &s.pipeline.telemetry())
        );
        if let Some(c) = self.cpu.cores() {
            summary += &format!("\nCPU use of the whole app: {c:.2} cores");
            if let Some(steady) = self.steady_cpu.as_ref().and_then(CpuMeter::cores) {
                summary += &format!(" ({steady:.2} after the first {} s)", WARM_UP.as_secs());
            }
        }
        summary += &format!(
            "\nwindow frames painted: {} ({:.1} a second; {} not asked for by a repaint request)",
            self.painted,
            self.painted as f64 / self.cpu.seconds(),
            self.causeless
        );
        if let Some(g) = self.gpu_bowl.summary() {
            summary += &format!("\n{g}");
        }
        if let Some(r) = recorded {
            summary += &format!("\n{r}");
        }
        summary
    }
}

impl eframe::App for RigviewApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        if let Some(gl) = frame.gl().cloned() {
            // The views go into textures of the window's own, their bytes
            // as they are.
            for t in [&mut self.canvas_tex, &mut self.beside_tex] {
                if t.wants_gl() {
                    match GlTexture::new(gl.clone()) {
                        Ok(g) => {
                            let id = frame.register_native_glow_texture(g.native());
                            t.set_gl(g, id);
                        }
                        Err(e) => {
                            let e =
                                format!("a texture for the view: {e}; egui's textures take over");
                            tracing::warn!("{e}");
                            t.refuse_gl(e);
                        }
                    }
                }
            }
            self.gpu_bowl.available = true;
            if self.gpu_bowl.gl_renderer.is_none() {
                use eframe::glow::HasContext;
                // SAFETY: a query of the window's current context.
                #[allow(unsafe_code)]
                let name = unsafe { gl.get_parameter_string(eframe::glow::RENDERER) };
                self.gpu_bowl.gl_renderer = Some(name);
            }
        }
        self.show(ui);
        if self.closing.wants_close() {
            ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    /// The panels' colour of the theme: the panels paint no fill of
    /// their own ([`unfilled_panels`]).
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        panel_colour(visuals).to_normalized_gamma_f32()
    }

    fn on_exit(&mut self, _gl: Option<&eframe::glow::Context>) {
        let summary = self.finish();
        tracing::info!(target: logging::NOTE, "{summary}");
    }
}

/// Whether the window draws the bowl on the GPU now: it has a GL context,
/// the operator wants it, it has not failed, and the latest set suits it.
fn bowl_gpu_usable(app: &RigviewApp) -> bool {
    app.gpu_bowl.available
        && bowl_gpu_chosen(app)
        && app.gpu_bowl.failure().is_none()
        && app.latest.as_ref().is_some_and(|out| {
            out.view == Some(rigview_core::pipeline::ViewKind::Bowl)
                && out.bowl_view.is_some()
                && bowl_gpu::unsuited(out).is_none()
        })
}

/// Whether the operator's choice of renderer puts the bowl on the GPU
/// (auto: where the GL is not a software renderer).
fn bowl_gpu_chosen(app: &RigviewApp) -> bool {
    match app.settings.window.bowl_renderer {
        BowlRenderer::Gpu => true,
        BowlRenderer::Cpu => false,
        BowlRenderer::Auto => app
            .gpu_bowl
            .gl_renderer
            .as_deref()
            .is_some_and(|r| !bowl_gpu::is_software(r)),
    }
}

/// The colour of camera `k` in plots and overlays.
pub fn camera_colour(k: usize) -> Color32 {
    const C: [Color32; 6] = [
        Color32::from_rgb(230, 85, 60),
        Color32::from_rgb(70, 160, 230),
        Color32::from_rgb(120, 200, 90),
        Color32::from_rgb(235, 180, 50),
        Color32::from_rgb(190, 110, 220),
        Color32::from_rgb(90, 210, 200),
    ];
    C[k % C.len()]
}

/// Runs the window until it is closed.
pub fn run(options: AppOptions) -> Result<()> {
    if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        anyhow::bail!(
            "no display (neither DISPLAY nor WAYLAND_DISPLAY is set): the window needs one. \
             Without a display, run `rigview run --headless …` (views, telemetry and plots to files) \
             or `rigview demo` (printed)"
        );
    }
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("rigview")
            .with_inner_size(options.window_size.unwrap_or([1600.0, 1000.0])),
        renderer: eframe::Renderer::Glow,
        ..Default::default()
    };
    eframe::run_native(
        "rigview",
        native,
        Box::new(move |cc| Ok(Box::new(RigviewApp::new(&cc.egui_ctx, options)))),
    )
    .map_err(|e| anyhow::anyhow!("the window failed: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One window frame (its textures taken as a renderer takes them).
    fn pass(ctx: &egui::Context) {
        let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
            ui.label("a view");
        });
        out.textures_delta.clear();
    }

    /// Window frames `ctx` runs after `notify`, until it asks for no more
    /// (at most 10).
    fn frames_after(ctx: &egui::Context, notify: &Notify) -> usize {
        let settle = |ctx: &egui::Context| {
            let mut n = 0;
            while n < 10 && ctx.has_requested_repaint() {
                pass(ctx);
                n += 1;
            }
            n
        };
        settle(ctx);
        notify();
        settle(ctx)
    }

    #[test]
    fn each_new_output_asks_for_one_window_frame() {
        let ctx = egui::Context::default();
        pass(&ctx);
        assert_eq!(frames_after(&ctx, &repaint_on_output(&ctx)), 1);
        assert_eq!(frames_after(&ctx, &repaint_on_output(&ctx)), 1);
        // egui's immediate request paints twice: the count tells them
        // apart.
        let c = ctx.clone();
        let immediate: Notify = Arc::new(move || c.request_repaint());
        assert_eq!(frames_after(&ctx, &immediate), 2);
    }

    /// The pixels a frame with side and central panels fills with the
    /// panels' colour, in both themes.
    fn panel_fill_area(ctx: &egui::Context) -> f32 {
        let mut area = 0.0;
        for theme in [egui::Theme::Dark, egui::Theme::Light] {
            ctx.set_theme(theme);
            let colour = panel_colour(&ctx.style_of(theme).visuals);
            let mut out = ctx.run_ui(egui::RawInput::default(), |ui| {
                egui::Panel::left("l").show(ui, |ui| ui.label("controls"));
                egui::Panel::bottom("b").show(ui, |ui| ui.label("cameras"));
                egui::CentralPanel::default_margins().show(ui, |ui| ui.label("view"));
            });
            // No renderer takes the font atlas here.
            out.textures_delta.clear();
            for clipped in &out.shapes {
                if let egui::Shape::Rect(r) = &clipped.shape {
                    if r.fill == colour {
                        area += r.rect.area();
                    }
                }
            }
        }
        area
    }

    #[test]
    fn panels_paint_no_fill_over_the_clear_colour() {
        // egui's own panels fill their rectangles (the test's check can
        // fail).
        assert!(panel_fill_area(&egui::Context::default()) > 10_000.0);
        let ctx = egui::Context::default();
        unfilled_panels(&ctx);
        let filled = panel_fill_area(&ctx);
        assert!(filled <= 0.0, "{filled} px² filled");
        // The window behind them is cleared to the theme's panel colour.
        for (theme, visuals) in [
            (egui::Theme::Dark, egui::Visuals::dark()),
            (egui::Theme::Light, egui::Visuals::light()),
        ] {
            ctx.set_theme(theme);
            let style = ctx.style_of(theme);
            assert_eq!(style.visuals.panel_fill, egui::Color32::TRANSPARENT);
            assert_eq!(panel_colour(&style.visuals), visuals.panel_fill);
        }
    }
}
