//! `rigview live`: the rig's cameras in closed-loop exposure control,
//! headless, with a status block per second.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use rigview_core::exposure::PixelFormat;
use rigview_core::pipeline::{Output, PipelineStatus, ProcessingSettings};
use rigview_core::source::StreamState;

use super::config::{CaptureConfig, Region, TriggerMode};

/// How the cameras are triggered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Trigger {
    /// rigview sends a software trigger to every camera at `--rate`.
    Software,
    /// A trigger box on `--line` (rising edge).
    Hardware,
    /// No trigger; each camera runs at `--rate`.
    FreeRun,
}

/// Options of `rigview live`.
#[derive(Clone, Debug, Args)]
pub struct LiveArgs {
    /// The rig file (rigview rig YAML); each camera needs a `device` (GenICam
    /// id or IP address). Needed unless `--fake`.
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "fake",
        conflicts_with = "fake"
    )]
    pub rig: Option<PathBuf>,
    /// Stop after this many frame sets.
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long, value_name = "S")]
    pub seconds: Option<f64>,
    /// How the cameras are triggered.
    #[arg(long, value_enum, default_value_t = Trigger::Software)]
    pub trigger: Trigger,
    /// Software-trigger rate, or free-run frame rate, in Hz.
    #[arg(long, default_value_t = 20.0, value_name = "HZ")]
    pub rate: f64,
    /// Trigger input line of `--trigger hardware`.
    #[arg(long, default_value = "Line0")]
    pub line: String,
    /// Pixel format (GenICam name: Mono8, Mono12, Mono16, RGB8, BayerRG8, …).
    #[arg(long, default_value = "Mono8", value_parser = parse_pixel_format)]
    pub pixel_format: PixelFormat,
    /// Region of interest, WIDTHxHEIGHT[+X+Y] (default: as the camera has it).
    #[arg(long, conflicts_with = "fake")]
    pub region: Option<Region>,
    /// GigE Vision packet size in bytes (default: the largest that gets
    /// through).
    #[arg(long, value_name = "BYTES")]
    pub packet_size: Option<u32>,
    /// GigE Vision inter-packet delay in ns.
    #[arg(long, default_value_t = 0, value_name = "NS")]
    pub packet_delay: u64,
    /// Socket buffer per GigE Vision stream in bytes (capped by
    /// net.core.rmem_max).
    #[arg(long, default_value_t = 4 << 20, value_name = "BYTES")]
    pub socket_buffer: u32,
    /// Seconds of each camera's own auto-exposure before rigview takes over
    /// (0: none).
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub settle: f64,
    /// Frames of one trigger arrive within this many ms of each other.
    #[arg(long, default_value_t = 20.0, value_name = "MS")]
    pub sync_tolerance: f64,
    /// Frames between writing a command and the first frame that shows it,
    /// beyond those already in flight (cameras without chunk data).
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub latency_frames: u32,
    /// dB per step of GainRaw, for cameras without Gain in dB.
    #[arg(long, default_value_t = 1.0, value_name = "DB")]
    pub gain_raw_db: f64,
    /// Instead of a rig's cameras, Aravis's in-process fake cameras showing
    /// the simulated rig (to try rigview without hardware): one fake camera
    /// per simulated camera, at its size, on a trigger clock of `--rate`.
    #[arg(long)]
    pub fake: bool,
    /// The simulation the fake cameras show: a preset (reference, steps,
    /// ramp, tunnel, backlight, overcast) or a simulation file (see
    /// assets/sim/) [default: reference].
    #[arg(long, value_name = "NAME|FILE", requires = "fake")]
    pub scenario: Option<String>,
    /// Render the fake cameras at this fraction of the simulated rig's
    /// resolution (0.25: 322×241) [default: 1].
    #[arg(long, requires = "fake")]
    pub scale: Option<f64>,
    /// Without the window: a status block per second on the terminal.
    #[arg(long)]
    pub headless: bool,
    /// Processing overrides.
    #[command(flatten)]
    pub processing: crate::run_cmd::ProcessingArgs,
}

impl LiveArgs {
    /// The options `args` give, as on the command line of `rigview live`.
    pub fn parse_from<I: IntoIterator<Item = String>>(args: I) -> Result<Self> {
        use clap::Parser;
        #[derive(Parser)]
        struct Wrap {
            #[command(flatten)]
            live: LiveArgs,
        }
        let argv = std::iter::once("live".to_owned()).chain(args);
        Ok(Wrap::try_parse_from(argv)?.live)
    }
}

fn parse_pixel_format(s: &str) -> std::result::Result<PixelFormat, String> {
    const ALL: [PixelFormat; 8] = [
        PixelFormat::Mono8,
        PixelFormat::Mono12,
        PixelFormat::Mono16,
        PixelFormat::Rgb8,
        PixelFormat::BayerRg8,
        PixelFormat::BayerGr8,
        PixelFormat::BayerGb8,
        PixelFormat::BayerBg8,
    ];
    ALL.into_iter()
        .find(|f| f.genicam_name().eq_ignore_ascii_case(s))
        .ok_or_else(|| {
            let names: Vec<_> = ALL.iter().map(|f| f.genicam_name()).collect();
            format!("unknown pixel format \"{s}\" (known: {})", names.join(", "))
        })
}

fn seconds(what: &str, s: f64) -> Result<Duration> {
    Duration::try_from_secs_f64(s)
        .with_context(|| format!("--{what} {s}: expected a number of seconds ≥ 0"))
}

impl LiveArgs {
    /// The capture configuration these options ask for.
    pub fn capture_config(&self) -> Result<CaptureConfig> {
        let trigger = match self.trigger {
            Trigger::Software => TriggerMode::Software { rate_hz: self.rate },
            Trigger::Hardware => TriggerMode::Hardware {
                line: self.line.clone(),
            },
            Trigger::FreeRun => TriggerMode::FreeRun {
                rate_hz: Some(self.rate),
            },
        };
        let config = CaptureConfig {
            pixel_format: self.pixel_format,
            region: self.region,
            trigger,
            packet_size: self.packet_size,
            packet_delay_ns: self.packet_delay,
            socket_buffer_bytes: self.socket_buffer,
            auto_settle: seconds("settle", self.settle)?,
            sync_tolerance: seconds("sync-tolerance", self.sync_tolerance / 1000.0)?,
            command_latency_frames: self.latency_frames,
            gain_raw_db_per_step: self.gain_raw_db,
            ..Default::default()
        };
        config.validate()?;
        Ok(config)
    }
}

fn state_word(s: StreamState) -> &'static str {
    match s {
        StreamState::Streaming => "streaming",
        StreamState::Lost => "LOST",
        StreamState::Reconnecting => "reconnecting",
    }
}

/// The status block printed once a second: one line for the sets, one per
/// camera (its stream, the exposure its last frame was taken with, γ̂, the
/// command sent and, when balanced, α of Eq. 6), and one for the overlaps'
/// brightness ratios.
pub fn format_status(
    elapsed: Duration,
    names: &[String],
    status: &PipelineStatus,
    last: Option<&Output>,
) -> String {
    let mut s = format!(
        "[{:7.1} s] sets: {} from the cameras, {} processed, {} incomplete, {} dropped (processing behind)",
        elapsed.as_secs_f64(),
        status.sets,
        status.processed,
        status.incomplete,
        status.capture_queue.dropped,
    );
    if let Some(a) = &status.assembly {
        s += &format!(
            "; {} frames broken, {} missing; skew last {:.2} ms, max {:.2} ms",
            a.broken_frames,
            a.missing_frames,
            a.last_skew_ns as f64 / 1e6,
            a.max_skew_ns as f64 / 1e6,
        );
    }
    s.push('\n');
    for (i, name) in names.iter().enumerate() {
        let h = status.health.get(i).cloned().unwrap_or_default();
        let cam = last.and_then(|o| o.cameras.get(i));
        let step = last.and_then(|o| o.step.cameras.get(i));
        let (e, gain) = cam.map_or((f64::NAN, f64::NAN), |c| {
            (c.taken.exposure(), c.taken.gain_db)
        });
        let gamma = cam
            .and_then(|c| c.estimate.as_ref())
            .map_or(f64::NAN, |e| e.gamma_hat);
        let command = match cam.and_then(|c| c.command) {
            Some(c) => format!("→ {:>9.0}", c.exposure()),
            None => format!("{:>11}", "no command"),
        };
        let alpha = step
            .and_then(|c| c.alpha)
            .map_or_else(String::new, |a| format!("  balanced α {a:.2}"));
        s += &format!(
            "  {name:<10} {:<12} {:5.1} fps  E {e:>9.0}  gain {gain:5.2} dB  γ̂ {gamma:5.2}  {command}{alpha}  completed {:>6} failed {:>4} underruns {:>3} packets missing {:>5} resent {:>5}\n",
            state_word(h.state),
            h.fps,
            h.completed,
            h.failed,
            h.underruns,
            h.missing_packets,
            h.resent_packets,
        );
    }
    if let Some(o) = last.filter(|o| !o.pairs.is_empty()) {
        let pairs: Vec<String> = o
            .pairs
            .iter()
            .map(|p| {
                let label = format!(
                    "{}-{}",
                    names.get(p.i).map_or("?", String::as_str),
                    names.get(p.j).map_or("?", String::as_str)
                );
                match p.log2_r {
                    Some(r) => format!("{label} {r:+.2}"),
                    None => format!("{label} n/a"),
                }
            })
            .collect();
        s += &format!("  overlaps, log2 r_ij: {}\n", pairs.join(", "));
    }
    s
}

/// Runs `rigview live` headless with the processing `settings`: the
/// same processor as the window, a status block per second.
pub fn run(args: &LiveArgs, settings: &ProcessingSettings, out: &mut dyn Write) -> Result<()> {
    // (clap lets these through next to --rig, which rules out --fake.)
    if !args.fake && (args.scenario.is_some() || args.scale.is_some()) {
        anyhow::bail!("--scenario and --scale choose what the fake cameras show: they need --fake");
    }
    let config = args.capture_config()?;
    run_cameras(args, config, settings, out)
}

#[cfg(not(feature = "aravis"))]
fn run_cameras(
    _args: &LiveArgs,
    _config: CaptureConfig,
    _settings: &ProcessingSettings,
    _out: &mut dyn Write,
) -> Result<()> {
    Err(super::LiveError::NoAravis.into())
}

/// The rig file's cameras, and the rig.
#[cfg(feature = "aravis")]
fn rig_cameras(args: &LiveArgs) -> Result<(Vec<super::CameraSpec>, rigview_calib::rig::Rig)> {
    let path = args
        .rig
        .as_ref()
        .context("--rig FILE names the cameras (or --fake runs fake cameras)")?;
    let rig = rigview_calib::formats::load(path, None, None)
        .with_context(|| format!("reading the rig file {}", path.display()))?
        .rig;
    Ok((super::CameraSpec::from_rig(&rig)?, rig))
}

/// Opens the cameras these options name (a rig file's, or the fake cameras
/// of `--fake`): the source, the rig and where it came from, in words.
/// What it reports on the way is added to `notes`.
#[cfg(feature = "aravis")]
pub fn open_source(
    args: &LiveArgs,
    notes: &mut Vec<String>,
) -> Result<(super::LiveSource, Option<rigview_calib::rig::Rig>, String)> {
    if !args.fake && (args.scenario.is_some() || args.scale.is_some()) {
        anyhow::bail!("--scenario and --scale choose what the fake cameras show: they need --fake");
    }
    let config = args.capture_config()?;
    let mut said = Vec::new();
    let (specs, config, rig, what) = if args.fake {
        let (specs, config, rig) = fake_cameras(args, config, &mut said)?;
        let what = format!(
            "Aravis fake cameras showing \"{}\"",
            args.scenario.as_deref().unwrap_or("reference")
        );
        (specs, config, rig, what)
    } else {
        let (specs, rig) = rig_cameras(args)?;
        let what = args
            .rig
            .as_ref()
            .map_or_else(String::new, |p| p.display().to_string());
        (specs, config, rig, what)
    };
    notes.extend(String::from_utf8_lossy(&said).lines().map(str::to_owned));
    let source = super::LiveSource::open(specs, config)?;
    Ok((source, Some(rig), what))
}

/// The in-process fake cameras of `--fake`, showing the simulated rig of
/// `--scenario`, and the capture configuration they run with.
#[cfg(feature = "aravis")]
fn fake_cameras(
    args: &LiveArgs,
    mut config: CaptureConfig,
    out: &mut dyn Write,
) -> Result<(
    Vec<super::CameraSpec>,
    CaptureConfig,
    rigview_calib::rig::Rig,
)> {
    use std::sync::Arc;
    use std::time::Instant;

    use rigview_core::sim::{SimConfig, SimRender, PRESETS};

    use super::fake::FakeView;
    use super::{CameraSpec, DeviceSpec};

    // The in-process fake cameras ignore software triggers: in trigger
    // mode they fire on their own clock, like a trigger box.
    if !matches!(config.trigger, TriggerMode::FreeRun { .. }) {
        config.trigger = TriggerMode::Hardware {
            line: "Line0".into(),
        };
    }
    super::fake::check_format(config.pixel_format)?;
    let scenario = args.scenario.as_deref().unwrap_or("reference");
    if !PRESETS.iter().any(|p| p.0 == scenario) && !std::path::Path::new(scenario).exists() {
        anyhow::bail!(
            "--scenario {scenario}: neither a simulation preset ({}) nor a simulation file",
            PRESETS.map(|p| p.0).join(", ")
        );
    }
    let mut sim = SimConfig::named(scenario)
        .with_context(|| format!("loading the simulation \"{scenario}\""))?;
    sim.scale = args.scale.unwrap_or(1.0);
    // The fake cameras fire at the simulation's trigger rate.
    sim.trigger_hz = args.rate;
    let started = Instant::now();
    let render = Arc::new(SimRender::new(&sim).with_context(|| {
        format!(
            "building the simulation \"{scenario}\" (--scale {}, --rate {})",
            sim.scale, args.rate
        )
    })?);
    // The script starts when the controller takes over from the cameras'
    // own start-up auto-exposure (give or take the time to open them).
    let epoch_ns = super::fake::clock_ns()
        .saturating_add(u64::try_from(config.auto_settle.as_nanos()).unwrap_or(u64::MAX));
    let views = FakeView::rig(&render, config.pixel_format, epoch_ns)?;
    let mut sizes: Vec<String> = views
        .iter()
        .map(|v| format!("{}×{}", v.width, v.height))
        .collect();
    sizes.dedup();
    writeln!(
        out,
        "simulation \"{}\": {} cameras of {} {}, traced in {:.1} s",
        sim.name,
        views.len(),
        sizes.join(", "),
        config.pixel_format.genicam_name(),
        started.elapsed().as_secs_f64()
    )?;
    super::ffi::enable_interface("Fake");
    let specs = views
        .into_iter()
        .zip(render.cameras())
        .enumerate()
        .map(|(i, (view, info))| {
            let name = info.name.clone();
            // Aravis takes serial numbers of at most 15 bytes.
            let mut serial = format!("RV{i}-{name}");
            while serial.len() > 15 {
                serial.pop();
            }
            CameraSpec {
                name,
                device: DeviceSpec::Fake { serial, view },
            }
        })
        .collect();
    Ok((specs, config, render.rig().clone()))
}

/// The entries of `recent` (the newest of `total` so far) not seen yet;
/// `seen` moves on to `total`.
#[cfg(feature = "aravis")]
fn fresh<'a>(
    recent: &'a std::collections::VecDeque<String>,
    total: u64,
    seen: &mut u64,
) -> impl Iterator<Item = &'a String> {
    let new = usize::try_from(total.saturating_sub(*seen)).unwrap_or(usize::MAX);
    *seen = total;
    recent.iter().skip(recent.len().saturating_sub(new))
}

#[cfg(feature = "aravis")]
fn run_cameras(
    args: &LiveArgs,
    config: CaptureConfig,
    settings: &ProcessingSettings,
    out: &mut dyn Write,
) -> Result<()> {
    use std::sync::Arc;
    use std::time::Instant;

    use rigview_core::pipeline::PipelineOptions;

    use crate::session::{self, SourceSpec};

    let limit = args
        .seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .context("--seconds: expected a number of seconds ≥ 0")?;
    writeln!(
        out,
        "rigview live: {}, {} law, {} simulation; {}; opening the cameras one after another…",
        settings.strategy.label(),
        settings.controller.law.kind.name(),
        settings.controller.estimator.simulation.name(),
        config.trigger.describe()
    )?;
    let t0 = Instant::now();
    let mut session = session::start(
        &SourceSpec::Live(Box::new(args.clone())),
        settings,
        PipelineOptions::default(),
        Arc::new(|| {}),
    )?;
    writeln!(
        out,
        "{}; calibration: {}",
        session.source_name, session.calibration
    )?;
    for m in &session.notes {
        writeln!(out, "  {m}")?;
    }
    let names = session.camera_names();
    let pipeline = &mut session.pipeline;
    let mut next_print = Instant::now() + Duration::from_secs(1);
    let (mut last, mut notes_seen, mut errors_seen) = (None, 0u64, 0u64);
    loop {
        if let Some(o) = pipeline.latest() {
            last = Some(o);
        }
        let status = pipeline.status();
        // New messages from the cameras and new problems, as they come.
        let at = t0.elapsed().as_secs_f64();
        for line in fresh(&status.notes, status.notes_total, &mut notes_seen).chain(fresh(
            &status.errors,
            status.errors_total,
            &mut errors_seen,
        )) {
            writeln!(out, "  [{at:7.1} s] {line}")?;
        }
        if status.stopped || limit.is_some_and(|l| t0.elapsed() >= l) {
            break;
        }
        if Instant::now() >= next_print {
            let block = format_status(t0.elapsed(), &names, &status, last.as_deref());
            write!(out, "{block}")?;
            next_print += Duration::from_secs(1);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    pipeline.stop();
    if let Some(o) = pipeline.latest() {
        last = Some(o);
    }
    let status = pipeline.status();
    write!(
        out,
        "{}",
        format_status(t0.elapsed(), &names, &status, last.as_deref())
    )?;
    writeln!(
        out,
        "done: {} frame sets, {} fed to the controller, {} incomplete kept from it, {} dropped",
        status.sets, status.processed, status.incomplete, status.capture_queue.dropped
    )?;
    Ok(())
}
