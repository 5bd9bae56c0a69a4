//! `rigview eval`: the evaluation suite on the simulated rig,
//! `rigview eval export-brackets` and `rigview eval check-emulation`.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use indicatif::ProgressBar;
use rigview_core::sim::{SimConfig, SimRender};

use crate::eval::{self, Plan, Preset};
use crate::session::brackets::{self, ExportSpec};

/// Options of `rigview eval`.
#[derive(Clone, Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct EvalArgs {
    /// Something else than the evaluation.
    #[command(subcommand)]
    pub command: Option<EvalCommand>,
    /// How much to measure: `quick` (reduced, about a minute and a half) or
    /// `full`.
    #[arg(long, value_enum, default_value_t = Preset::Full)]
    pub preset: Preset,
    /// A simulation preset or file (repeatable): the first gives the scene
    /// of the γ̂ accuracy and the steps of light, all of them the M(E)
    /// sweeps and the seams [default: reference; sweeps: reference,
    /// backlight, overcast, and with `--preset full` also sky (metered over
    /// whole frames), tunnel-exit, snow, lawn; seams: backlight, tunnel,
    /// reference].
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
    /// With `--brackets`: how the sequence answers the cameras' commands,
    /// by a frame emulated at the exposure asked (M(E) then swept densely)
    /// or by the nearest bracket.
    #[arg(long, value_enum, default_value_t = crate::session::brackets::BracketMode::Emulate, requires = "brackets")]
    pub bracket_mode: crate::session::brackets::BracketMode,
}

/// What `rigview eval` can do besides the evaluation.
#[derive(Clone, Debug, Subcommand)]
pub enum EvalCommand {
    /// Write a bracket sequence of the simulated rig (several exposures per
    /// moment and camera, docs/brackets.md) for `--source brackets:DIR`.
    ExportBrackets(ExportArgs),
    /// Check the exposure emulation on a bracket folder: every bracket
    /// that has a shorter and a longer one is emulated from the others and
    /// compared with itself (median |error| in stops over its unclipped
    /// samples, PSNR), noise-free and with the sensor's noise.
    CheckEmulation(CheckArgs),
    /// Write the manifest of a dataset laid out as SRC/<camera>/<exposure>/
    /// <image>.png (exposure folders such as 1ms, 2000us, 0.004s), making
    /// SRC a bracket folder (docs/brackets.md).
    ImportBrackets(ImportArgs),
}

/// Options of `rigview eval import-brackets`.
#[derive(Clone, Debug, Args)]
pub struct ImportArgs {
    /// The dataset's folder; the manifest is written into it.
    #[arg(value_name = "SRC")]
    pub src: PathBuf,
    /// The rig's calibration (any format `rigview calib` reads), copied to
    /// SRC/rig.yaml [default: SRC/rig.yaml as it is].
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// The unit of exposure folders named by a bare number.
    #[arg(long, value_parser = ["us", "ms", "s"])]
    pub unit: Option<String>,
    /// Moments per second (the k-th image of each folder is at k / rate).
    #[arg(long, default_value_t = 10.0)]
    pub rate: f64,
    /// At most this many moments, from the first [default: all].
    #[arg(long, value_name = "N")]
    pub moments: Option<usize>,
    /// The Bayer mosaic's colour order (RGGB, GRBG, GBRG, BGGR) or mono.
    #[arg(long)]
    pub pattern: Option<String>,
    /// Bits of the images' values: 8, 12 or 16 [default: the PNGs' depth].
    #[arg(long)]
    pub bits: Option<u32>,
    /// The sensor's response: linear (raw data) or recover (Debevec–Malik
    /// from the brackets) [default: linear above 8 bits].
    #[arg(long, value_parser = ["linear", "recover"])]
    pub response: Option<String>,
}

/// Options of `rigview eval check-emulation`.
#[derive(Clone, Debug, Args)]
pub struct CheckArgs {
    /// The bracket folder (docs/brackets.md).
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,
    /// At most this many moments, from the first [default: all].
    #[arg(long, value_name = "N")]
    pub moments: Option<usize>,
    /// The seed of the emulated noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
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
    /// Bits of the images: 8 (Mono8) or 12 (Mono12, written as 16-bit
    /// PNG with `bits` 12).
    #[arg(long, default_value_t = 8)]
    pub bits: u32,
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
    match &args.command {
        Some(EvalCommand::ExportBrackets(e)) => return export(e, out),
        Some(EvalCommand::CheckEmulation(c)) => return check_emulation(c, out),
        Some(EvalCommand::ImportBrackets(i)) => return import(i, out),
        None => {}
    }
    let dir = args
        .out
        .as_ref()
        .context("rigview eval: --out DIR is needed (the folder of the report)")?;
    let plan = Plan::of(args.preset, &args.scenario);
    let started = Instant::now();
    match &args.brackets {
        Some(b) => {
            eval::on_brackets::run(&plan, b, args.bracket_mode, dir)?;
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
    if args.bits != 8 && args.bits != 12 {
        anyhow::bail!("--bits {}: expected 8 or 12", args.bits);
    }
    let mut config = SimConfig {
        scale: args.scale,
        ..SimConfig::named(&args.scenario)
            .with_context(|| format!("the simulation \"{}\"", args.scenario))?
    };
    config.sensor.bits = args.bits;
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

fn import(args: &ImportArgs, out: &mut dyn Write) -> Result<()> {
    let mut comments = Vec::new();
    if let Some(p) = &args.pattern {
        comments.push(("pattern".to_string(), p.clone()));
    }
    if let Some(b) = args.bits {
        comments.push(("bits".to_string(), b.to_string()));
    }
    if let Some(r) = &args.response {
        comments.push(("response".to_string(), r.clone()));
    }
    let done = brackets::import(&brackets::ImportSpec {
        src: args.src.clone(),
        rig: args.rig.clone(),
        unit: args.unit.clone(),
        rate_hz: args.rate,
        moments: args.moments,
        comments,
    })?;
    writeln!(
        out,
        "rigview eval import-brackets: {} moments × {} cameras ({}) × {} exposures; wrote {}",
        done.moments,
        done.cameras.len(),
        done.cameras.join(", "),
        done.exposures,
        done.manifest.display()
    )?;
    Ok(())
}

fn check_emulation(args: &CheckArgs, out: &mut dyn Write) -> Result<()> {
    let started = Instant::now();
    let options = brackets::CheckOptions {
        moments: args.moments,
        seed: args.seed,
    };
    let report = brackets::check_emulation(&args.dir, &options)?;
    writeln!(
        out,
        "rigview eval check-emulation {}: {} moments, each bracket with a shorter and a longer one emulated from the others",
        args.dir.display(),
        report.moments
    )?;
    writeln!(
        out,
        "{:>14} {:>7} {:>11} {:>13} {:>13} {:>10} {:>10}",
        "level (µs)", "images", "samples", "median |e| EV", "with noise", "PSNR dB", "with noise"
    )?;
    let row = |f: &brackets::LevelFigures| {
        format!(
            "{:>14} {:>7} {:>11} {:>13.4} {:>13.4} {:>10.2} {:>10.2}",
            f.level.map_or("all".into(), |l| format!("{l:.1}")),
            f.images,
            f.samples,
            f.median_ev,
            f.median_ev_noisy,
            f.psnr_db,
            f.psnr_db_noisy
        )
    };
    for f in &report.levels {
        writeln!(out, "{}", row(f))?;
    }
    writeln!(out, "{}", row(&report.all))?;
    for (name, curve) in &report.responses {
        let Some(inverse) = curve else {
            continue;
        };
        let at = |z: usize| inverse.get(z).copied().unwrap_or(f32::NAN);
        writeln!(
            out,
            "response of {name}, recovered from its first moment: linear value (0–255) of codes 16, 64, 128, 192: {:.2}, {:.1}, {:.1}, {:.1}; nearest power curve: exponent {}",
            at(16),
            at(64),
            at(128),
            at(192),
            brackets::CheckReport::power_of(inverse).map_or("none".into(), |g| format!("{g:.2}"))
        )?;
    }
    let over = report.levels_over(0.05);
    writeln!(
        out,
        "goal: median |error| ≤ 0.05 EV over every image and at every level: {} (noise-free {:.4}, with noise {:.4}) in {:.1} s",
        if report.meets(0.05) {
            "met".to_owned()
        } else if over.is_empty() {
            "NOT met".to_owned()
        } else {
            format!(
                "NOT met at {} of {} levels ({} µs)",
                over.len(),
                report.levels.len(),
                over.iter()
                    .map(|l| format!("{l:.0}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
        report.all.median_ev,
        report.all.median_ev_noisy,
        started.elapsed().as_secs_f64()
    )?;
    Ok(())
}
