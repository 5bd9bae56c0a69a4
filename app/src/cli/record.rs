//! `rigview record`: capture into a recording without processing, or into
//! a bracket sequence (`--brackets N`).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::options::{parse_pixel_format, RecordingArgs};
use crate::commands::record::{self, BracketRun, CaptureRun, RecordJob};
use crate::live::{CaptureConfig, FakeRig, LiveCameras, LiveSpec};
use crate::session::brackets::parse_range_ev;
use crate::session::capture::CaptureFrom;

/// Options of `rigview record`.
#[derive(Clone, Debug, Args)]
pub struct RecordArgs {
    /// The rig file of the live cameras to record.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// Record Aravis's in-process fake cameras showing the simulation.
    #[arg(long)]
    pub fake: bool,
    /// Record the simulated rig (at its trigger rate).
    #[arg(long)]
    pub sim: bool,
    /// The cameras' pixel format with `--rig` or `--fake` (GenICam name,
    /// e.g. Mono8, BayerRG8) [default: Mono8].
    #[arg(long, value_name = "FORMAT", value_parser = parse_pixel_format)]
    pub pixel_format: Option<rigview_core::exposure::PixelFormat>,
    /// The simulation of `--sim` and `--fake`.
    #[arg(long, default_value = "reference")]
    pub scenario: String,
    /// Render scale of `--sim` and `--fake`.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// The recording (MCAP), or with `--brackets` the folder of the
    /// bracket sequence.
    #[arg(long, value_name = "FILE|DIR")]
    pub out: PathBuf,
    /// Stop after this many seconds (otherwise when the source ends).
    #[arg(long, value_name = "S")]
    pub seconds: Option<f64>,
    /// Record exposure brackets instead of a recording: the cameras cycle
    /// through N exposures per moment, and each frame that shows one is
    /// written into the folder `--out` (docs/brackets.md).
    #[arg(long, value_name = "N")]
    pub brackets: Option<usize>,
    /// With `--brackets`: the exposures' range, log2 µs at 0 dB, `LO:HI`
    /// (default: 3 EV either side of each camera's exposure at the start).
    #[arg(long, value_name = "LO:HI", requires = "brackets")]
    pub range_ev: Option<String>,
    /// With `--brackets`: stop after this many moments.
    #[arg(long, value_name = "M", requires = "brackets")]
    pub moments: Option<usize>,
    /// How the recording is written.
    #[command(flatten)]
    pub recording: RecordingArgs,
}

/// Runs `rigview record`.
pub fn run(args: &RecordArgs, out: &mut dyn std::io::Write) -> Result<()> {
    let mut capture = CaptureConfig::default();
    if let Some(f) = args.pixel_format {
        if args.sim {
            anyhow::bail!("--pixel-format is an option of --rig and --fake (the simulated rig renders its sensor's format)");
        }
        capture.pixel_format = f;
    }
    let from = match (&args.rig, args.fake, args.sim) {
        (Some(r), false, false) => CaptureFrom::Live(Box::new(LiveSpec {
            cameras: LiveCameras::Rig(r.clone()),
            capture,
            frames: None,
        })),
        (None, true, false) => CaptureFrom::Live(Box::new(LiveSpec {
            cameras: LiveCameras::Fake(FakeRig {
                scenario: args.scenario.clone(),
                scale: args.scale,
                ..FakeRig::default()
            }),
            capture,
            frames: None,
        })),
        (None, false, true) => CaptureFrom::Sim {
            scenario: args.scenario.clone(),
            scale: args.scale,
        },
        _ => anyhow::bail!("rigview record needs one of --rig FILE, --fake or --sim"),
    };
    let job = match args.brackets {
        Some(exposures) => RecordJob::Brackets(BracketRun {
            from,
            dir: args.out.clone(),
            exposures,
            range_ev: args.range_ev.as_deref().map(parse_range_ev).transpose()?,
            moments: args.moments,
            seconds: args.seconds,
        }),
        None => RecordJob::Recording(CaptureRun {
            from,
            record: args.recording.spec(args.out.clone()),
            seconds: args.seconds,
        }),
    };
    let summary = record::run(&job, out)?;
    writeln!(out, "{summary}")?;
    Ok(())
}
