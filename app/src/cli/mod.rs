//! The command line of `rigview`: the arguments of each subcommand (one
//! file each) and how they map to the library's options. With no
//! subcommand, the desktop app on the simulated rig.

pub mod calib;
pub mod demo;
pub mod eval;
pub mod live;
pub mod panorama;
pub mod record;
pub mod run;
pub mod surround;

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use rigview_core::exposure::{LawKind, ProbeParams, Simulation};
use rigview_core::pipeline::{MeterRoi, PipelineOptions, ProcessingSettings, Strategy, ViewKind};
use rigview_core::surround::BlendMode;

use crate::gui::AppOptions;
use crate::logging::LogBuffer;
use crate::session::SourceSpec;
use crate::settings::{Settings, SettingsStore};

/// rigview: capture, exposure control and surround view for rigs of
/// synchronised cameras.
#[derive(Debug, Parser)]
#[command(name = "rigview", version, about, long_about = None)]
pub struct Cli {
    /// The subcommand (none: the window on the simulated rig).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Window options (with no subcommand).
    #[command(flatten)]
    pub view: ViewArgs,
    /// More messages on stderr: -v what rigview reports, -vv its details
    /// (RUST_LOG, if set, chooses instead).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// The pipeline on a chosen source: in the window, or headless with
    /// views, telemetry and a plot written to a folder.
    Run(run::RunArgs),
    /// Closed-loop exposure control on the simulated four-camera fisheye rig,
    /// printed frame by frame.
    Demo(demo::DemoArgs),
    /// Calibration: show, convert, and make intrinsics and ground extrinsics.
    Calib(calib::CalibArgs),
    /// Compose still images of a calibrated rig into a bird's-eye view.
    Surround(surround::SurroundArgs),
    /// Compose still images of a calibrated rig into a cylindrical
    /// panorama, with feature matches and brightness ratios per overlap.
    Panorama(panorama::PanoramaArgs),
    /// The desktop app on the rig's GenICam cameras (`--headless`: a status
    /// block per second on the terminal instead).
    Live(live::LiveArgs),
    /// Capture into a recording (MCAP) without processing.
    Record(record::RecordArgs),
    /// Look at or repair a recording.
    Recording(record::RecordingCmd),
    /// The paper's experiments on the simulated rig: figures, their data
    /// and a report, written to a folder.
    Eval(eval::EvalArgs),
}

/// Options of the window and of `rigview run`.
#[derive(Clone, Debug, Default, Args)]
pub struct ViewArgs {
    /// The settings file [default: ~/.config/rigview/settings.yaml].
    #[arg(long, value_name = "FILE", global = true)]
    pub settings: Option<PathBuf>,
    /// Close the window after this many seconds (for scripted runs).
    #[arg(long, value_name = "S", global = true)]
    pub quit_after: Option<f64>,
    /// Save a screenshot of the window to FILE (PNG) after
    /// `--screenshot-after` seconds, then close it.
    #[arg(long, value_name = "FILE", global = true)]
    pub screenshot: Option<PathBuf>,
    /// Seconds before the screenshot.
    #[arg(long, value_name = "S", default_value_t = 8.0, global = true)]
    pub screenshot_after: f64,
}

impl ViewArgs {
    /// The saved settings (`--settings FILE` or the default file), with
    /// `overrides` applied; a settings file that cannot be read is reported
    /// on stderr and the defaults are used.
    pub fn settings(&self, overrides: &ProcessingArgs) -> Settings {
        let mut store = SettingsStore::new(self.settings.clone());
        let (mut settings, err) = store.load();
        if let Some(e) = err {
            tracing::warn!("{e:#}");
        }
        overrides.apply(&mut settings.processing);
        settings
    }

    /// `--screenshot` and `--screenshot-after`.
    pub fn screenshot(&self) -> Result<Option<(PathBuf, Duration)>> {
        let Some(p) = &self.screenshot else {
            return Ok(None);
        };
        let after = Duration::try_from_secs_f64(self.screenshot_after)
            .context("--screenshot-after: expected a number of seconds ≥ 0")?;
        Ok(Some((p.clone(), after)))
    }

    /// `--quit-after` as a duration.
    pub fn quit_after(&self) -> Result<Option<Duration>> {
        self.quit_after
            .map(Duration::try_from_secs_f64)
            .transpose()
            .context("--quit-after: expected a number of seconds ≥ 0")
    }

    /// The window on `source`, with `overrides` saved into the settings it
    /// opens with.
    pub fn window(
        &self,
        overrides: &ProcessingArgs,
        source: SourceSpec,
        record: Option<crate::recording::RecordSpec>,
    ) -> Result<()> {
        let mut store = SettingsStore::new(self.settings.clone());
        let (mut settings, err) = store.load();
        if let Some(e) = err {
            tracing::warn!("{e:#}");
        } else {
            overrides.apply(&mut settings.processing);
            if let Some(v) = overrides.view {
                settings.window.view = match v {
                    ViewKind::Surround => crate::settings::ViewMode::Surround,
                    ViewKind::Panorama => crate::settings::ViewMode::Panorama,
                };
            }
            store.save(&settings)?;
        }
        crate::gui::run(AppOptions {
            source,
            settings: self.settings.clone(),
            quit_after: self.quit_after()?,
            screenshot: self.screenshot()?,
            pipeline: PipelineOptions::default(),
            log: LogBuffer::global().clone(),
            record,
        })
    }
}

/// Options of the control loop, for every command that runs it: they
/// override the saved settings (`rigview demo`: the built-in defaults).
#[derive(Clone, Debug, Default, Args)]
pub struct ControlArgs {
    /// How exposure is decided.
    #[arg(long, value_enum)]
    pub strategy: Option<Strategy>,
    /// The update law.
    #[arg(long, value_enum)]
    pub law: Option<LawKind>,
    /// The estimator's exposure simulation.
    #[arg(long, value_enum)]
    pub simulation: Option<Simulation>,
    /// Which pixels are metered.
    #[arg(long, value_enum, value_name = "ROI")]
    pub meter: Option<MeterRoi>,
    /// Darker probes of a camera under its own law (`off` for measuring
    /// the law alone).
    #[arg(long, value_enum, value_name = "ON|OFF")]
    pub probe: Option<Switch>,
}

/// Processing options that override the saved settings, for every command
/// that runs the processor and composes a view: the control loop's, and
/// the view's blending.
#[derive(Clone, Debug, Default, Args)]
pub struct ProcessingArgs {
    /// The control loop's options.
    #[command(flatten)]
    pub control: ControlArgs,
    /// How the overlaps of the view are blended (overrides the saved
    /// choice).
    #[arg(long, value_enum)]
    pub blend: Option<BlendMode>,
    /// The view composed (and what is metered, and where the overlap
    /// ratios come from): the bird's-eye surround view, or the
    /// cylindrical panorama with ratios from matched features.
    #[arg(long, value_enum)]
    pub view: Option<ViewKind>,
    /// The panorama's radius, metres: what stands this far from the rig's
    /// centre lines up across the seams; nearer things show parallax.
    #[arg(long, value_name = "M")]
    pub radius_m: Option<f64>,
    /// Match the panorama's features on every N-th set (in the background).
    #[arg(long, value_name = "N")]
    pub match_every: Option<u64>,
    /// Refine the panorama's rotations in the background every N sets (0:
    /// never).
    #[arg(long, value_name = "N")]
    pub refine_every: Option<u64>,
}

/// A setting switched on or off on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}

impl ControlArgs {
    /// Applies the options given to `p`.
    pub fn apply(&self, p: &mut ProcessingSettings) {
        if let Some(s) = self.strategy {
            p.strategy = s;
        }
        if let Some(l) = self.law {
            p.controller.law.kind = l;
        }
        if let Some(s) = self.simulation {
            p.controller.estimator.simulation = s;
        }
        if let Some(m) = self.meter {
            p.roi = m;
        }
        match self.probe {
            Some(Switch::Off) => p.controller.probe = None,
            Some(Switch::On) => {
                p.controller.probe.get_or_insert_with(ProbeParams::default);
            }
            None => {}
        }
    }
}

impl ProcessingArgs {
    /// Applies the options given to `p`.
    pub fn apply(&self, p: &mut ProcessingSettings) {
        self.control.apply(p);
        if let Some(b) = self.blend {
            p.blend = b;
        }
        if let Some(v) = self.view {
            p.view = v;
        }
        if let Some(r) = self.radius_m {
            p.panorama.radius_m = r;
        }
        if let Some(n) = self.match_every {
            p.panorama.match_every = n;
        }
        if let Some(n) = self.refine_every {
            p.panorama.refine_every = n;
        }
    }
}

/// A number of seconds ≥ 0 given as `--what`.
fn seconds(what: &str, s: f64) -> Result<Duration> {
    Duration::try_from_secs_f64(s)
        .with_context(|| format!("--{what} {s}: expected a number of seconds ≥ 0"))
}
