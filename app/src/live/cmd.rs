//! `rigview live`: the rig's cameras in closed-loop exposure control,
//! headless, with a status block per second.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use rigview_core::exposure::{CameraInput, Metered};
use rigview_core::exposure::{
    ControllerConfig, ExposureSetting, FrameInfo, Meter, MeteringConfig, NeighbourGraph,
    PixelFormat, RigController, RigStep,
};
use rigview_core::source::{FrameSet, FrameSource, StreamState};

use super::config::{CaptureConfig, Region, TriggerMode};
use super::health::CameraStatus;

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

/// The exposure control loop over a frame source: meters every complete
/// set, steps the controller and sends its commands. Incomplete sets are
/// counted and never reach the controller.
#[derive(Debug)]
pub struct LiveLoop {
    controller: RigController,
    meter: Meter,
    fed: u64,
    skipped: u64,
    last: Option<RigStep>,
}

impl LiveLoop {
    /// A loop for `source`'s cameras with `config` (balancing needs overlap
    /// patches, which come with the surround view; until then each camera
    /// runs alone), starting each camera's controller from `start`.
    pub fn new(
        source: &dyn FrameSource,
        config: ControllerConfig,
        start: &[ExposureSetting],
    ) -> Result<Self> {
        let ranges: Vec<_> = source.cameras().iter().map(|c| c.range).collect();
        let graph = NeighbourGraph::new(ranges.len(), &[])?;
        let mut controller = RigController::new(
            ControllerConfig {
                balancing: None,
                ..config
            },
            &ranges,
            graph,
        )?;
        for (i, s) in start.iter().enumerate() {
            controller.camera_mut(i)?.sync(*s);
        }
        Ok(Self {
            controller,
            meter: Meter::new(MeteringConfig::default())?,
            fed: 0,
            skipped: 0,
            last: None,
        })
    }

    /// One set: a complete one is metered, stepped and its commands applied
    /// to `source`; an incomplete one is counted and returns `None`.
    pub fn step(
        &mut self,
        source: &mut dyn FrameSource,
        set: &FrameSet,
    ) -> Result<Option<&RigStep>> {
        if !set.is_complete() {
            self.skipped += 1;
            return Ok(None);
        }
        let mut metered: Vec<Metered> = Vec::with_capacity(set.frames.len());
        let mut infos = Vec::with_capacity(set.frames.len());
        for f in set.frames.iter().flatten() {
            metered.push(self.meter.meter(&f.view()?, None)?);
            infos.push(FrameInfo {
                frame_id: f.meta.frame_id,
                taken: f.meta.taken,
            });
        }
        let inputs: Vec<CameraInput<'_>> = metered
            .iter()
            .zip(&infos)
            .map(|(m, info)| CameraInput {
                info: *info,
                metered: m,
            })
            .collect();
        let step = self.controller.step(&inputs, &[])?;
        let commands: Vec<_> = step
            .cameras
            .iter()
            .filter_map(|c| {
                c.command
                    .map(|setting| rigview_core::source::ExposureCommand {
                        camera: c.camera,
                        setting,
                    })
            })
            .collect();
        source.apply(&commands)?;
        self.fed += 1;
        self.last = Some(step);
        Ok(self.last.as_ref())
    }

    /// Complete sets fed to the controller.
    pub fn fed(&self) -> u64 {
        self.fed
    }

    /// Incomplete sets kept from it.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// The last controller step.
    pub fn last(&self) -> Option<&RigStep> {
        self.last.as_ref()
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
/// camera.
pub fn format_status(
    elapsed: Duration,
    cameras: &[CameraStatus],
    sets: &super::assemble::SetCounters,
    last: Option<&RigStep>,
) -> String {
    let mut s = format!(
        "[{:7.1} s] sets: {} complete, {} incomplete ({} frames broken, {} missing); skew last {:.2} ms, max {:.2} ms\n",
        elapsed.as_secs_f64(),
        sets.complete,
        sets.incomplete,
        sets.broken_frames,
        sets.missing_frames,
        sets.last_skew_ns as f64 / 1e6,
        sets.max_skew_ns as f64 / 1e6,
    );
    for (i, c) in cameras.iter().enumerate() {
        let step = last.and_then(|l| l.cameras.get(i));
        let gamma = step
            .and_then(|c| c.estimate.as_ref())
            .map_or(f64::NAN, |e| e.gamma_hat);
        let (e, gain) = match (step, c.setting) {
            (Some(st), _) => (st.taken.exposure(), st.taken.gain_db),
            (None, Some(st)) => (st.exposure(), st.gain_db),
            (None, None) => (f64::NAN, f64::NAN),
        };
        let h = &c.health;
        s += &format!(
            "  {:<10} {:<12} {:5.1} fps  E {:>9.0}  gain {:5.2} dB  γ̂ {:5.2}  completed {:>6} failed {:>4} underruns {:>3} packets missing {:>5} resent {:>5}{}\n",
            c.name,
            state_word(h.state),
            h.fps,
            e,
            gain,
            gamma,
            h.completed,
            h.failed,
            h.underruns,
            h.missing_packets,
            h.resent_packets,
            match (&c.last_error, h.state) {
                (Some(m), StreamState::Lost | StreamState::Reconnecting) => format!("  ({m})"),
                _ => String::new(),
            }
        );
    }
    s
}

/// Runs `rigview live`.
pub fn run(args: &LiveArgs, out: &mut dyn Write) -> Result<()> {
    // (clap lets these through next to --rig, which rules out --fake.)
    if !args.fake && (args.scenario.is_some() || args.scale.is_some()) {
        anyhow::bail!("--scenario and --scale choose what the fake cameras show: they need --fake");
    }
    let config = args.capture_config()?;
    run_cameras(args, config, out)
}

#[cfg(not(feature = "aravis"))]
fn run_cameras(_args: &LiveArgs, _config: CaptureConfig, _out: &mut dyn Write) -> Result<()> {
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

#[cfg(feature = "aravis")]
fn run_cameras(args: &LiveArgs, config: CaptureConfig, out: &mut dyn Write) -> Result<()> {
    use std::time::Instant;

    use super::LiveSource;

    let (specs, config) = if args.fake {
        let (specs, config, _) = fake_cameras(args, config, out)?;
        (specs, config)
    } else {
        (rig_cameras(args)?.0, config)
    };
    writeln!(
        out,
        "rigview live: {} cameras ({}), {}; opening them one after another…",
        specs.len(),
        specs
            .iter()
            .map(|s| format!("{} = {}", s.name, s.device.describe()))
            .collect::<Vec<_>>()
            .join(", "),
        config.trigger.describe()
    )?;
    let mut source = LiveSource::open(specs, config)?;
    for m in source.take_messages() {
        writeln!(out, "  {m}")?;
    }
    let start = source.start_settings().to_vec();
    let mut control = LiveLoop::new(&source, ControllerConfig::default(), &start)?;
    let t0 = Instant::now();
    let limit = args
        .seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .context("--seconds: expected a number of seconds ≥ 0")?;
    let mut next_print = t0 + Duration::from_secs(1);
    let print_status = |out: &mut dyn Write, source: &LiveSource, control: &LiveLoop| {
        let st = source.status();
        let block = format_status(t0.elapsed(), &st.cameras, &st.sets, control.last());
        write!(out, "{block}")
    };
    let mut sets = 0u64;
    loop {
        if args.frames.is_some_and(|n| sets >= n) || limit.is_some_and(|l| t0.elapsed() >= l) {
            break;
        }
        if let Some(set) = source.next_set(Duration::from_millis(100))? {
            sets += 1;
            control.step(&mut source, &set)?;
        }
        for m in source.take_messages() {
            writeln!(out, "  [{:7.1} s] {m}", t0.elapsed().as_secs_f64())?;
        }
        if Instant::now() >= next_print {
            print_status(out, &source, &control)?;
            next_print += Duration::from_secs(1);
        }
    }
    print_status(out, &source, &control)?;
    writeln!(
        out,
        "done: {sets} frame sets, {} fed to the controller, {} incomplete kept from it",
        control.fed(),
        control.skipped()
    )?;
    Ok(())
}
