//! `rigview eval`: the evaluation suite on the simulated rig, and
//! `rigview eval export-brackets`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use indicatif::ProgressBar;
use rigview_core::sim::{SimConfig, SimRender};

use crate::brackets::{self, ExportSpec};
use crate::eval::{self, Plan, Preset};

/// Options of `rigview eval`.
#[derive(Clone, Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct EvalArgs {
    /// Something else than the evaluation.
    #[command(subcommand)]
    pub command: Option<EvalCommand>,
    /// How much to measure: `quick` (reduced, about half a minute) or
    /// `full`.
    #[arg(long, value_enum, default_value_t = Preset::Full)]
    pub preset: Preset,
    /// A simulation preset or file (repeatable): the first gives the scene
    /// of the γ̂ accuracy and the steps of light, all of them the M(E)
    /// sweeps and the seams [default: reference; sweeps: reference,
    /// backlight, overcast; seams: backlight, tunnel, reference].
    #[arg(long, value_name = "NAME|FILE")]
    pub scenario: Vec<String>,
    /// The folder to write the figures, their data and report.html into.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Run the experiments that apply (M against exposure, the seams, the
    /// views) on this bracket sequence instead of the simulator
    /// (docs/brackets.md).
    #[arg(long, value_name = "DIR")]
    pub brackets: Option<PathBuf>,
}

/// What `rigview eval` can do besides the evaluation.
#[derive(Clone, Debug, Subcommand)]
pub enum EvalCommand {
    /// Write a bracket sequence of the simulated rig (several exposures per
    /// moment and camera, docs/brackets.md) for `--source brackets:DIR`.
    ExportBrackets(ExportArgs),
}

/// Options of `rigview eval export-brackets`.
#[derive(Clone, Debug, Args)]
pub struct ExportArgs {
    /// The simulation: a preset or a simulation file.
    #[arg(long, default_value = "reference")]
    pub scenario: String,
    /// Render scale (0.25: 322×241).
    #[arg(long, default_value_t = 0.25)]
    pub scale: f64,
    /// Moments (sets at the trigger rate, from the start).
    #[arg(long, default_value_t = 40)]
    pub frames: usize,
    /// Exposures per moment and camera.
    #[arg(long, default_value_t = 15)]
    pub exposures: usize,
    /// The exposures' range, log2 µs at 0 dB: `LO:HI`.
    #[arg(long, value_name = "LO:HI", default_value = "8:13")]
    pub range_ev: String,
    /// The folder to write into.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

impl ExportArgs {
    /// `--range-ev` as two numbers.
    pub fn range(&self) -> Result<(f64, f64)> {
        brackets::parse_range_ev(&self.range_ev)
    }
}

/// Runs `rigview eval`.
pub fn run(args: &EvalArgs, out: &mut dyn Write) -> Result<()> {
    if let Some(EvalCommand::ExportBrackets(e)) = &args.command {
        return export(e, out);
    }
    let dir = args
        .out
        .as_ref()
        .context("rigview eval: --out DIR is needed (the folder of the report)")?;
    let plan = Plan::of(args.preset, &args.scenario);
    let started = Instant::now();
    match &args.brackets {
        Some(b) => {
            eval::on_brackets::run(&plan, b, dir)?;
        }
        None => {
            eval::run(&plan, dir)?;
        }
    }
    writeln!(
        out,
        "rigview eval ({}): {} in {:.1} s; open {}",
        plan.preset,
        dir.display(),
        started.elapsed().as_secs_f64(),
        dir.join(eval::files::REPORT).display()
    )?;
    Ok(())
}

fn export(args: &ExportArgs, out: &mut dyn Write) -> Result<()> {
    let (lo, hi) = args.range()?;
    if !(2..=64).contains(&args.exposures) || args.frames == 0 {
        anyhow::bail!(
            "--exposures {} --frames {}: expected 2 to 64 exposures and at least one moment",
            args.exposures,
            args.frames
        );
    }
    let config = SimConfig {
        scale: args.scale,
        ..SimConfig::named(&args.scenario)
            .with_context(|| format!("the simulation \"{}\"", args.scenario))?
    };
    let render = SimRender::new(&config).context("building the simulated rig")?;
    let spec = ExportSpec {
        frames: args.frames,
        levels: brackets::levels(lo, hi, args.exposures),
    };
    let bar = ProgressBar::new((args.frames * args.exposures * render.cameras().len()) as u64);
    brackets::export(&render, &spec, &args.out, &mut || bar.inc(1))?;
    bar.finish_and_clear();
    writeln!(
        out,
        "rigview eval export-brackets: {} moments × {} cameras × {} exposures (2^{lo} to 2^{hi} µs, {:.3} EV apart) in {}",
        args.frames,
        render.cameras().len(),
        args.exposures,
        (hi - lo) / (args.exposures - 1) as f64,
        args.out.display()
    )?;
    Ok(())
}
