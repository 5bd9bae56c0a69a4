//! `rigview run`: the pipeline on a chosen source, in the window or
//! headless. Headless, it writes the composed views as PNG, the telemetry
//! as CSV, a PNG plot of the exposure state and a summary, with a progress
//! bar on the terminal.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use rigview_core::exposure::{LawKind, Simulation};
use rigview_core::pipeline::{MeterRoi, Output, PipelineOptions, ProcessingSettings, Strategy};
use rigview_core::surround::{BlendMode, Canvas};

use crate::gui::AppOptions;
use crate::live::cmd::LiveArgs;
use crate::report::{self, CpuMeter};
use crate::session::{self, SimSpec, SourceSpec};
use crate::settings::{Settings, SettingsStore};

/// Where frame sets come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SourceKind {
    /// The simulated four-camera rig.
    Sim,
    /// Live cameras (`--rig FILE`, or `--fake` for Aravis's fake cameras).
    Live,
}

/// Processing options that override the saved settings, for every command
/// that runs the processor.
#[derive(Clone, Debug, Default, Args)]
pub struct ProcessingArgs {
    /// How exposure is decided (overrides the saved strategy).
    #[arg(long, value_enum)]
    pub strategy: Option<Strategy>,
    /// The update law (overrides the saved one).
    #[arg(long, value_enum)]
    pub law: Option<LawKind>,
    /// The estimator's exposure simulation (overrides the saved one).
    #[arg(long, value_enum)]
    pub simulation: Option<Simulation>,
    /// Which pixels are metered (overrides the saved choice).
    #[arg(long, value_enum, value_name = "ROI")]
    pub meter: Option<MeterRoi>,
    /// How the overlaps of the view are blended (overrides the saved
    /// choice).
    #[arg(long, value_enum)]
    pub blend: Option<BlendMode>,
}

impl ProcessingArgs {
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
        if let Some(b) = self.blend {
            p.blend = b;
        }
    }
}

/// The saved settings (`--settings FILE` or the default file), with the
/// command line's overrides applied; a settings file that cannot be read is
/// reported on stderr and the defaults are used.
pub fn load_settings(view: &ViewArgs, overrides: &ProcessingArgs) -> Settings {
    let mut store = SettingsStore::new(view.settings.clone());
    let (mut settings, err) = store.load();
    if let Some(e) = err {
        eprintln!("{e:#}");
    }
    overrides.apply(&mut settings.processing);
    settings
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

/// Options of `rigview run`.
#[derive(Clone, Debug, Args)]
pub struct RunArgs {
    /// Without the window: write views, telemetry and a plot to `--out`.
    #[arg(long)]
    pub headless: bool,
    /// Where frame sets come from.
    #[arg(long, value_enum, default_value_t = SourceKind::Sim)]
    pub source: SourceKind,
    /// Frame sets to run (headless) [default: 100].
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,
    /// Output folder of the headless run (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Write the composed view of every K-th set (and of the last).
    #[arg(long, value_name = "K", default_value_t = 10)]
    pub every: u64,
    /// The simulation (`--source sim`): a preset (reference, steps, ramp,
    /// tunnel, backlight, overcast) or a simulation file.
    #[arg(long, default_value = "reference")]
    pub scenario: String,
    /// Render scale of the simulated rig (0.25: 322×241).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Run the simulated rig at its trigger rate (headless runs go as fast
    /// as processing takes the sets, in lock step, unless this is given).
    #[arg(long)]
    pub realtime: bool,
    /// The rig file of `--source live`.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// `--source live` on Aravis's in-process fake cameras showing the
    /// simulation.
    #[arg(long)]
    pub fake: bool,
    /// Processing overrides.
    #[command(flatten)]
    pub processing: ProcessingArgs,
}

impl RunArgs {
    fn source_spec(&self, headless: bool) -> Result<SourceSpec> {
        match self.source {
            SourceKind::Sim => {
                if self.rig.is_some() || self.fake {
                    anyhow::bail!("--rig and --fake are options of --source live");
                }
                Ok(SourceSpec::Sim(SimSpec {
                    scenario: self.scenario.clone(),
                    scale: self.scale,
                    realtime: self.realtime || !headless,
                    frames: headless.then(|| self.frames.unwrap_or(100)),
                }))
            }
            SourceKind::Live => {
                let mut argv = Vec::new();
                match (&self.rig, self.fake) {
                    (Some(r), false) => {
                        argv.push("--rig".to_owned());
                        argv.push(r.display().to_string());
                    }
                    (None, true) => {
                        argv.extend(["--fake".to_owned(), "--scenario".to_owned()]);
                        argv.push(self.scenario.clone());
                        argv.push("--scale".to_owned());
                        argv.push(self.scale.to_string());
                    }
                    _ => anyhow::bail!("--source live needs either --rig FILE or --fake"),
                }
                Ok(SourceSpec::Live(Box::new(LiveArgs::parse_from(argv)?)))
            }
        }
    }
}

/// Runs `rigview run`.
pub fn run(args: &RunArgs, view: &ViewArgs) -> Result<()> {
    if args.headless {
        let out = args.out.clone().context("--headless needs --out DIR")?;
        let summary = run_headless(args, view, &out, true)?;
        println!("{summary}");
        Ok(())
    } else {
        if args.out.is_some() {
            anyhow::bail!("--out is for --headless runs");
        }
        window(view, &args.processing, args.source_spec(false)?)
    }
}

/// The window on `source`, with the command line's processing overrides
/// saved into the settings it opens with.
pub fn window(view: &ViewArgs, overrides: &ProcessingArgs, source: SourceSpec) -> Result<()> {
    let mut store = SettingsStore::new(view.settings.clone());
    let (mut settings, err) = store.load();
    if let Some(e) = err {
        eprintln!("{e:#}");
    } else {
        overrides.apply(&mut settings.processing);
        store.save(&settings)?;
    }
    crate::gui::run(AppOptions {
        source,
        settings: view.settings.clone(),
        quit_after: quit_after(view)?,
        screenshot: screenshot(view)?,
        pipeline: PipelineOptions::default(),
    })
}

/// The screenshot options.
pub fn screenshot(v: &ViewArgs) -> Result<Option<(PathBuf, Duration)>> {
    let Some(p) = &v.screenshot else {
        return Ok(None);
    };
    let after = Duration::try_from_secs_f64(v.screenshot_after)
        .context("--screenshot-after: expected a number of seconds ≥ 0")?;
    Ok(Some((p.clone(), after)))
}

/// `--quit-after` as a duration.
pub fn quit_after(v: &ViewArgs) -> Result<Option<Duration>> {
    v.quit_after
        .map(Duration::try_from_secs_f64)
        .transpose()
        .context("--quit-after: expected a number of seconds ≥ 0")
}

fn write_canvas(c: &Canvas, path: &Path) -> Result<()> {
    let (w, h) = (
        u32::try_from(c.width).context("canvas width")?,
        u32::try_from(c.height).context("canvas height")?,
    );
    let r = if c.channels == 3 {
        image::RgbImage::from_raw(w, h, c.data.clone()).map(|i| i.save(path))
    } else {
        image::GrayImage::from_raw(w, h, c.data.clone()).map(|i| i.save(path))
    };
    r.context("the canvas has the wrong size")?
        .with_context(|| format!("writing the view {}", path.display()))
}

/// The headless run; returns its summary. `progress` shows a progress bar.
pub fn run_headless(args: &RunArgs, view: &ViewArgs, out: &Path, progress: bool) -> Result<String> {
    std::fs::create_dir_all(out.join("views"))
        .with_context(|| format!("creating the output folder {}", out.display()))?;
    let settings = load_settings(view, &args.processing);
    let frames = args.frames.unwrap_or(100);
    let spec = args.source_spec(true)?;
    let lockstep = matches!(&spec, SourceSpec::Sim(s) if !s.realtime);
    let cpu = CpuMeter::start();
    let mut session = session::start(
        &spec,
        &settings.processing,
        PipelineOptions {
            lockstep,
            output_queue: 8,
            history: usize::try_from(frames)
                .unwrap_or(usize::MAX)
                .saturating_add(16),
            ..Default::default()
        },
        Arc::new(|| {}),
    )?;
    let bar = if progress {
        indicatif::ProgressBar::new(frames)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} sets ({per_sec}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut done = 0u64;
    let mut last: Option<Arc<Output>> = None;
    let mut written = 0usize;
    let every = args.every.max(1);
    while done < frames {
        let Some(o) = session.pipeline.next_output(Duration::from_millis(200)) else {
            if session.pipeline.is_stopped() {
                break;
            }
            continue;
        };
        done = session.pipeline.telemetry().total();
        bar.set_position(done);
        if o.trigger % every == 0 {
            if let Some(c) = &o.canvas {
                write_canvas(
                    c,
                    &out.join("views").join(format!("view_{:06}.png", o.trigger)),
                )?;
                written += 1;
            }
        }
        last = Some(o);
    }
    session.pipeline.stop();
    bar.finish_and_clear();
    if let Some(o) = &last {
        if o.trigger % every != 0 {
            if let Some(c) = &o.canvas {
                write_canvas(
                    c,
                    &out.join("views").join(format!("view_{:06}.png", o.trigger)),
                )?;
                written += 1;
            }
        }
    }
    let status = session.pipeline.status();
    let telemetry = session.pipeline.telemetry().clone();
    let csv = out.join("telemetry.csv");
    {
        let f =
            std::fs::File::create(&csv).with_context(|| format!("creating {}", csv.display()))?;
        let mut w = std::io::BufWriter::new(f);
        telemetry.write_csv_header(&mut w)?;
        for r in telemetry.rows() {
            telemetry.write_csv_row(&mut w, r)?;
        }
        w.flush()
            .with_context(|| format!("writing {}", csv.display()))?;
    }
    crate::plot_png::write(&telemetry, &out.join("exposure.png"), 1400, 1500)?;
    let mut summary = format!(
        "rigview run: {} on {}; {} of {frames} sets processed; {written} views in {}, telemetry {}, plot {}\n{}",
        settings.processing.strategy.label(),
        session.source_name,
        telemetry.total(),
        out.join("views").display(),
        csv.display(),
        out.join("exposure.png").display(),
        report::summary(&status, &telemetry)
    );
    if let Some(c) = cpu.cores() {
        summary += &format!("\nCPU use: {c:.2} cores");
    }
    std::fs::write(out.join("summary.txt"), &summary)
        .with_context(|| format!("writing {}", out.join("summary.txt").display()))?;
    Ok(summary)
}
