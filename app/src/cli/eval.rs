//! `rigview eval`: the evaluation suite on the simulated rig.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;

use crate::eval::{self, Plan, Preset};

/// Options of `rigview eval`.
#[derive(Clone, Debug, Args)]
pub struct EvalArgs {
    /// How much to measure: `quick` (reduced, about a minute) or `full`.
    #[arg(long, value_enum, default_value_t = Preset::Full)]
    pub preset: Preset,
    /// A simulation preset or file (repeatable): the first gives the scene
    /// of the γ̂ accuracy and the steps of light, all of them the M(E)
    /// sweeps [default: reference; sweeps: reference, backlight, overcast].
    #[arg(long, value_name = "NAME|FILE")]
    pub scenario: Vec<String>,
    /// The folder to write the figures, their data and report.html into.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// Runs `rigview eval`.
pub fn run(args: &EvalArgs, out: &mut dyn Write) -> Result<()> {
    let plan = Plan::of(args.preset, &args.scenario);
    let started = Instant::now();
    eval::run(&plan, &args.out)?;
    writeln!(
        out,
        "rigview eval ({}): {} in {:.1} s; open {}",
        plan.preset,
        args.out.display(),
        started.elapsed().as_secs_f64(),
        args.out.join(eval::files::REPORT).display()
    )?;
    Ok(())
}
