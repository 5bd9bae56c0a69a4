//! `rigview record` (capture into a recording without processing) and
//! `rigview recording info|repair`, and the recording options that `run`
//! shares.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};
use rigview_record::Compression;

use crate::live::{CaptureConfig, FakeRig, LiveCameras, LiveSpec};
use crate::recording::{self, CaptureFrom, CaptureRun, RecordSpec};

/// How a recording is written.
#[derive(Clone, Debug, Default, Args)]
pub struct RecordingArgs {
    /// Chunk compression of the recording (none by default: rig frames
    /// shrink by a sixth at most).
    #[arg(long, value_name = "none|lz4|zstd", default_value = "none")]
    pub compression: Compression,
    /// Free space to leave on the recording's disk, GiB.
    #[arg(long, value_name = "GIB", default_value_t = 2.0)]
    pub reserve_gib: f64,
}

impl RecordingArgs {
    /// The recording into `file`.
    pub fn spec(&self, file: PathBuf) -> RecordSpec {
        RecordSpec {
            file,
            compression: self.compression,
            reserve_bytes: (self.reserve_gib.max(0.0) * f64::from(1u32 << 30)) as u64,
        }
    }
}

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
    #[arg(long, value_name = "FORMAT", value_parser = super::live::parse_pixel_format)]
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

/// `rigview recording`.
#[derive(Clone, Debug, Args)]
pub struct RecordingCmd {
    /// What to do.
    #[command(subcommand)]
    pub action: RecordingAction,
}

/// What `rigview recording` does.
#[derive(Clone, Debug, Subcommand)]
pub enum RecordingAction {
    /// Duration, sets, topics and drops of a recording.
    Info {
        /// The recording.
        file: PathBuf,
    },
    /// Rewrites a recording that was not closed (killed, disk full) with
    /// its indexes, keeping every complete set.
    Repair {
        /// The recording to repair.
        input: PathBuf,
        /// The repaired copy.
        output: PathBuf,
    },
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
    if let Some(exposures) = args.brackets {
        let run = crate::record_brackets::BracketRun {
            from,
            dir: args.out.clone(),
            exposures,
            range_ev: args
                .range_ev
                .as_deref()
                .map(crate::brackets::parse_range_ev)
                .transpose()?,
            moments: args.moments,
            seconds: args.seconds,
        };
        let summary = crate::record_brackets::capture(&run, out)?;
        writeln!(out, "{summary}")?;
        return Ok(());
    }
    let run = CaptureRun {
        from,
        record: args.recording.spec(args.out.clone()),
        seconds: args.seconds,
    };
    let summary = recording::capture(&run, out)?;
    writeln!(out, "{summary}")?;
    Ok(())
}

/// Runs `rigview recording`.
pub fn run_recording(cmd: &RecordingCmd, out: &mut dyn std::io::Write) -> Result<()> {
    let text = match &cmd.action {
        RecordingAction::Info { file } => recording::info_text(file)?,
        RecordingAction::Repair { input, output } => recording::repair_text(input, output)?,
    };
    writeln!(out, "{}", text.trim_end())?;
    Ok(())
}
