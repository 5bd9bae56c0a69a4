//! `rigview live`: the rig's GenICam cameras (or Aravis's fake cameras
//! showing a simulated rig) in the window, or headless with a status block
//! per second.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use rigview_core::exposure::PixelFormat;
use rigview_core::pipeline::ProcessingSettings;

use super::options::{parse_pixel_format, seconds, ProcessingArgs, RecordingArgs, ViewArgs};
use crate::live::{CaptureConfig, FakeRig, LiveCameras, LiveSpec, Region, TriggerMode};
use crate::logging::LogBuffer;
use crate::session::SourceSpec;

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
    /// ramp, tunnel, backlight, overcast, sky, tunnel-exit, snow, lawn) or a
    /// simulation file (see assets/sim/) [default: reference].
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
    pub processing: ProcessingArgs,
    /// Record every processed set into this MCAP file (in the window: as
    /// if its Record button were pressed at start-up).
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// How the recording is written.
    #[command(flatten)]
    pub recording: RecordingArgs,
    /// The live remote view.
    #[command(flatten)]
    pub serve: super::options::ServeArgs,
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

    /// The cameras and capture these options ask for.
    pub fn spec(&self) -> Result<LiveSpec> {
        // (clap lets these through next to --rig, which rules out --fake.)
        if !self.fake && (self.scenario.is_some() || self.scale.is_some()) {
            anyhow::bail!(
                "--scenario and --scale choose what the fake cameras show: they need --fake"
            );
        }
        let cameras = if self.fake {
            let default = FakeRig::default();
            LiveCameras::Fake(FakeRig {
                scenario: self.scenario.clone().unwrap_or(default.scenario),
                scale: self.scale.unwrap_or(default.scale),
                rate_hz: self.rate,
            })
        } else {
            LiveCameras::Rig(
                self.rig
                    .clone()
                    .context("--rig FILE names the cameras (or --fake runs fake cameras)")?,
            )
        };
        Ok(LiveSpec {
            cameras,
            capture: self.capture_config()?,
            frames: self.frames,
        })
    }

    /// `--seconds` as a duration.
    pub fn limit(&self) -> Result<Option<Duration>> {
        self.seconds
            .map(Duration::try_from_secs_f64)
            .transpose()
            .context("--seconds: expected a number of seconds ≥ 0")
    }
}

/// Runs `rigview live`: in the window, or headless with the saved
/// settings and the options' overrides.
pub fn run(args: &LiveArgs, view: &ViewArgs, out: &mut dyn Write) -> Result<()> {
    if args.headless {
        let settings = view.settings(&args.processing);
        headless(args, &settings.processing, LogBuffer::global(), out)
    } else {
        let record = args.record.clone().map(|f| args.recording.spec(f));
        let serve = args.serve.options()?;
        view.window(
            &args.processing,
            SourceSpec::Live(args.spec()?),
            record,
            serve,
        )
    }
}

/// Runs `rigview live --headless` with the processing `settings`,
/// printing the events that reach `log` with its status.
pub fn headless(
    args: &LiveArgs,
    settings: &ProcessingSettings,
    log: &LogBuffer,
    out: &mut dyn Write,
) -> Result<()> {
    let record = args.record.clone().map(|f| args.recording.spec(f));
    crate::commands::live::run(
        &args.spec()?,
        args.limit()?,
        settings,
        log,
        record.as_ref(),
        args.serve.options()?.as_ref(),
        out,
    )
}
