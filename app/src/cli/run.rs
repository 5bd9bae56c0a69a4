//! `rigview run`: the pipeline on a chosen source, in the window or
//! headless.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use super::options::{ProcessingArgs, ViewArgs};
use crate::commands::run::{self as headless, HeadlessRun};
use crate::live::{CaptureConfig, FakeRig, LiveCameras, LiveSpec};
use crate::logging::LogBuffer;
use crate::session::{SimSpec, SourceSpec};

/// Where frame sets come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SourceKind {
    /// The simulated four-camera rig.
    Sim,
    /// Live cameras (`--rig FILE`, or `--fake` for Aravis's fake cameras).
    Live,
    /// A recording (`replay:FILE`).
    Replay(PathBuf),
    /// A bracket sequence (`brackets:DIR`).
    Brackets(PathBuf),
}

impl std::str::FromStr for SourceKind {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        match s {
            "sim" => Ok(Self::Sim),
            "live" => Ok(Self::Live),
            _ => match (s.strip_prefix("replay:"), s.strip_prefix("brackets:")) {
                (Some(f), _) if !f.is_empty() => Ok(Self::Replay(PathBuf::from(f))),
                (_, Some(d)) if !d.is_empty() => Ok(Self::Brackets(PathBuf::from(d))),
                _ => Err(format!(
                    "unknown source \"{s}\" (known: sim, live, replay:FILE, brackets:DIR)"
                )),
            },
        }
    }
}

/// Options of `rigview run`.
#[derive(Clone, Debug, Args)]
pub struct RunArgs {
    /// Without the window: write views, telemetry and a plot to `--out`.
    #[arg(long)]
    pub headless: bool,
    /// Where frame sets come from: sim, live, replay:FILE (a recording;
    /// its calibration unless --rig gives another) or brackets:DIR (a
    /// bracket sequence, docs/brackets.md; its rig.yaml unless --rig).
    #[arg(
        long,
        value_name = "sim|live|replay:FILE|brackets:DIR",
        default_value = "sim"
    )]
    pub source: SourceKind,
    /// How `--source brackets:DIR` answers a command: `emulate` a frame at
    /// the exposure asked from the moment's brackets, or give the
    /// `nearest` bracket (docs/brackets.md).
    #[arg(long, value_enum, default_value_t = crate::session::brackets::BracketMode::Emulate)]
    pub bracket_mode: crate::session::brackets::BracketMode,
    /// Record every processed set into this MCAP file.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// How the recording is written.
    #[command(flatten)]
    pub recording: super::options::RecordingArgs,
    /// The live remote view.
    #[command(flatten)]
    pub serve: super::options::ServeArgs,
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
    /// tunnel, backlight, overcast, sky, tunnel-exit, snow, lawn) or a
    /// simulation file.
    #[arg(long, default_value = "reference")]
    pub scenario: String,
    /// Render scale of the simulated rig (0.25: 322×241).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Run the simulated rig at its trigger rate (headless runs go as fast
    /// as processing takes the sets, in lock step, unless this is given).
    #[arg(long)]
    pub realtime: bool,
    /// The rig file of `--source live`, or the calibration of a replay.
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

/// Frame sets of a headless run unless `--frames` says.
const FRAMES: u64 = 100;

impl RunArgs {
    /// The source these options name, for a headless run or the window.
    pub fn source(&self, headless: bool) -> Result<SourceSpec> {
        match &self.source {
            SourceKind::Replay(file) => {
                if self.fake {
                    anyhow::bail!("--fake is an option of --source live");
                }
                Ok(SourceSpec::Replay(crate::session::ReplaySpec {
                    file: file.clone(),
                    rig: self.rig.clone(),
                    interactive: !headless,
                }))
            }
            SourceKind::Brackets(dir) => {
                if self.fake {
                    anyhow::bail!("--fake is an option of --source live");
                }
                Ok(SourceSpec::Brackets(crate::session::BracketSpec {
                    dir: dir.clone(),
                    rig: self.rig.clone(),
                    mode: self.bracket_mode,
                    realtime: self.realtime || !headless,
                }))
            }
            SourceKind::Sim => {
                if self.rig.is_some() || self.fake {
                    anyhow::bail!("--rig and --fake are options of --source live");
                }
                Ok(SourceSpec::Sim(SimSpec {
                    scenario: self.scenario.clone(),
                    scale: self.scale,
                    realtime: self.realtime || !headless,
                    frames: headless.then(|| self.frames.unwrap_or(FRAMES)),
                }))
            }
            SourceKind::Live => {
                let cameras = match (&self.rig, self.fake) {
                    (Some(r), false) => LiveCameras::Rig(r.clone()),
                    (None, true) => LiveCameras::Fake(FakeRig {
                        scenario: self.scenario.clone(),
                        scale: self.scale,
                        ..FakeRig::default()
                    }),
                    _ => anyhow::bail!("--source live needs either --rig FILE or --fake"),
                };
                Ok(SourceSpec::Live(LiveSpec {
                    cameras,
                    capture: CaptureConfig::default(),
                    frames: None,
                }))
            }
        }
    }
}

/// Runs `rigview run`: headless, printing its summary, or in the window.
pub fn run(args: &RunArgs, view: &ViewArgs) -> Result<()> {
    if args.headless {
        let out = args.out.clone().context("--headless needs --out DIR")?;
        let source = args.source(true)?;
        // A replay runs to the recording's end unless --frames says.
        let frames = match source {
            SourceSpec::Replay(_) | SourceSpec::Brackets(_) => args.frames.unwrap_or(u64::MAX),
            _ => args.frames.unwrap_or(FRAMES),
        };
        let run = HeadlessRun {
            source,
            frames,
            out,
            every: args.every,
            record: args.record.clone().map(|f| args.recording.spec(f)),
            serve: args.serve.options()?,
        };
        let settings = view.settings(&args.processing);
        let summary = headless::run(&run, &settings.processing, LogBuffer::global(), true)?;
        writeln!(std::io::stdout().lock(), "{summary}")?;
        Ok(())
    } else {
        if args.out.is_some() {
            anyhow::bail!("--out is for --headless runs");
        }
        let record = args.record.clone().map(|f| args.recording.spec(f));
        let source = args.source(false)?;
        if record.is_some() && matches!(source, SourceSpec::Replay(_)) {
            anyhow::bail!(
                "--record with --source replay:FILE is for --headless runs: \
                 a replay in the window can be paused, stepped and sought"
            );
        }
        let serve = args.serve.options()?;
        view.window(&args.processing, source, record, serve)
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::{Cli, Command};

    fn parse(args: &[&str]) -> Command {
        let cli = Cli::try_parse_from(["rigview"].iter().chain(args)).unwrap();
        cli.command.unwrap()
    }

    fn run_args(args: &[&str]) -> RunArgs {
        let mut all = vec!["run"];
        all.extend(args);
        match parse(&all) {
            Command::Run(a) => a,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_bracket_sequence_is_a_source() {
        let run = run_args(&["--source", "brackets:seq", "--headless"]);
        assert_eq!(run.source, SourceKind::Brackets(PathBuf::from("seq")));
        let Ok(SourceSpec::Brackets(b)) = run.source(true) else {
            panic!("not a bracket source");
        };
        assert_eq!(
            (b.dir, b.rig, b.mode),
            (
                PathBuf::from("seq"),
                None,
                crate::session::brackets::BracketMode::Emulate
            )
        );
        let run = run_args(&["--source", "brackets:seq", "--bracket-mode", "nearest"]);
        let Ok(SourceSpec::Brackets(b)) = run.source(true) else {
            panic!("not a bracket source");
        };
        assert_eq!(b.mode, crate::session::brackets::BracketMode::Nearest);
        let e = "brackets:".parse::<SourceKind>().unwrap_err();
        assert!(e.contains("brackets:DIR"), "{e}");
    }

    #[test]
    fn live_sources_of_run_are_those_of_live() {
        let run = run_args(&[
            "--source",
            "live",
            "--fake",
            "--scenario",
            "tunnel",
            "--scale",
            "0.25",
        ]);
        let Ok(SourceSpec::Live(from_run)) = run.source(true) else {
            panic!("not a live source");
        };
        let Command::Live(live) =
            parse(&["live", "--fake", "--scenario", "tunnel", "--scale", "0.25"])
        else {
            panic!("not rigview live");
        };
        assert_eq!(from_run, live.spec().unwrap());
        assert_eq!(
            from_run.cameras,
            LiveCameras::Fake(FakeRig {
                scenario: "tunnel".into(),
                scale: 0.25,
                rate_hz: 20.0,
            })
        );
        let rig = run_args(&["--source", "live", "--rig", "rig.yaml"]);
        let Ok(SourceSpec::Live(spec)) = rig.source(false) else {
            panic!("not a live source");
        };
        assert_eq!(spec.cameras, LiveCameras::Rig("rig.yaml".into()));
    }

    #[test]
    fn the_simulated_rig_runs_in_lock_step_headless_and_live_options_are_refused() {
        let Ok(SourceSpec::Sim(sim)) = run_args(&["--frames", "7"]).source(true) else {
            panic!("not the simulated rig");
        };
        assert_eq!((sim.realtime, sim.frames), (false, Some(7)));
        let Ok(SourceSpec::Sim(sim)) = run_args(&[]).source(false) else {
            panic!("not the simulated rig");
        };
        assert_eq!((sim.realtime, sim.frames), (true, None));
        let e = run_args(&["--fake"]).source(true).unwrap_err();
        assert!(e.to_string().contains("options of --source live"), "{e}");
        let e = run_args(&["--source", "live"]).source(true).unwrap_err();
        assert!(e.to_string().contains("--rig FILE or --fake"), "{e}");
    }

    #[test]
    fn probes_are_switched_on_the_command_line() {
        use rigview_core::exposure::ProbeParams;
        use rigview_core::pipeline::ProcessingSettings;
        let mut p = ProcessingSettings::default();
        assert!(p.controller.probe.is_some());
        run_args(&["--probe", "off"]).processing.apply(&mut p);
        assert_eq!(p.controller.probe, None);
        run_args(&[]).processing.apply(&mut p);
        assert_eq!(p.controller.probe, None, "no option keeps the saved choice");
        run_args(&["--probe", "on"]).processing.apply(&mut p);
        assert_eq!(p.controller.probe, Some(ProbeParams::default()));
        let bad = ["rigview", "run", "--probe", "maybe"];
        assert!(Cli::try_parse_from(bad).is_err());
    }
}
