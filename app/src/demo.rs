//! The headless closed-loop demo on the simulated rig: four 185° fisheye
//! cameras on a car in a sunny car park (or any simulation preset or file),
//! each controlled by the gradient-based exposure core, balanced with its
//! neighbours through the surround view's overlaps, with commands that take
//! effect after the cameras' actuation latency. Every frame set prints each
//! camera's exposure, γ̂ and M, and each overlap's brightness ratio as
//! measured and as the simulation's ground truth predicts it.

use std::io::Write;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use rigview::run_cmd::ProcessingArgs;
use rigview_core::exposure::{LawKind, NeighbourGraph, Simulation};
use rigview_core::pipeline::{LockStep, MeterRoi, ProcessingSettings, Processor, Strategy};
use rigview_core::sim::{truth, Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::surround::{CanvasSpec, SurroundOptions, SurroundView};

/// Options of `rigview demo`.
#[derive(Clone, Debug, Args)]
pub struct DemoArgs {
    /// The simulation: a preset (reference, steps, ramp, tunnel, backlight,
    /// overcast) or a simulation file (see assets/sim/).
    #[arg(long, default_value = "reference")]
    pub scenario: String,
    /// Frame sets to run [default: the scenario's length at its trigger
    /// rate].
    #[arg(long)]
    pub frames: Option<u64>,
    /// Print every K-th frame set.
    #[arg(long, default_value_t = 1)]
    pub every: u64,
    /// How exposure is decided [default: multi, balanced gradient AE].
    #[arg(long, value_enum)]
    pub strategy: Option<Strategy>,
    /// Update law [default: nonlinear].
    #[arg(long, value_enum)]
    pub law: Option<LawKind>,
    /// Exposure simulation of the estimator [default: gamma].
    #[arg(long, value_enum)]
    pub simulation: Option<Simulation>,
    /// Which pixels are metered [default: ground].
    #[arg(long, value_enum, value_name = "ROI")]
    pub meter: Option<MeterRoi>,
    /// Frames between a command and the first frame that shows it, 0 to 2
    /// [default: the scenario's].
    #[arg(long)]
    pub latency: Option<u32>,
    /// Starting shutter time of every camera, µs [default: the scenario's].
    #[arg(long)]
    pub start_us: Option<f64>,
    /// Render at this fraction of the rig's resolution (0.25: 322×241).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Output bits of the cameras, 8 or 12 [default: the scenario's].
    #[arg(long)]
    pub bits: Option<u32>,
    /// Seed of the sensor noise [default: the scenario's].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Produce frame sets at the trigger rate instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
}

impl Default for DemoArgs {
    fn default() -> Self {
        Self {
            scenario: "reference".into(),
            frames: None,
            every: 1,
            strategy: None,
            law: None,
            simulation: None,
            meter: None,
            latency: None,
            start_us: None,
            scale: 1.0,
            bits: None,
            seed: None,
            realtime: false,
        }
    }
}

impl DemoArgs {
    /// The processing settings: the defaults, with the options given.
    pub fn settings(&self) -> ProcessingSettings {
        let mut s = ProcessingSettings::default();
        ProcessingArgs {
            strategy: self.strategy,
            law: self.law,
            simulation: self.simulation,
            meter: self.meter,
            blend: None,
        }
        .apply(&mut s);
        s
    }
}

/// The simulation the options ask for.
fn sim_config(args: &DemoArgs) -> Result<SimConfig> {
    let mut c = SimConfig::named(&args.scenario)
        .with_context(|| format!("loading the simulation \"{}\"", args.scenario))?;
    c.scale = args.scale;
    if let Some(l) = args.latency {
        c.latency_frames = l;
    }
    if let Some(s) = args.start_us {
        c.start.shutter_us = s;
    }
    if let Some(b) = args.bits {
        c.sensor.bits = b;
    }
    if let Some(s) = args.seed {
        c.seed = s;
    }
    c.validate().context("the demo's options")?;
    Ok(c)
}

/// Runs the demo and prints what it does.
pub fn run(args: &DemoArgs) -> Result<()> {
    let out = std::io::stdout();
    run_to(args, &mut out.lock())
}

/// Runs the demo, printing to `out`.
pub fn run_to(args: &DemoArgs, out: &mut impl Write) -> Result<()> {
    let config = sim_config(args)?;
    let started = Instant::now();
    let render = Arc::new(SimRender::new(&config).context("building the simulated rig")?);
    let traced = started.elapsed().as_secs_f64();
    let cams = render.cameras();
    let n = cams.len();
    let view = SurroundView::build(
        render.rig(),
        &CanvasSpec::default(),
        &SurroundOptions::default(),
    )
    .context("building the surround view of the simulated rig")?;
    let dr = truth::dynamic_range(&render, 0.0)?;
    let frames = args
        .frames
        .unwrap_or_else(|| (config.duration_s * config.trigger_hz).round().max(1.0) as u64);

    let settings = args.settings();
    let graph = NeighbourGraph::new(n, &render.rig().neighbours)?;
    let source = SimRig::new(
        render.clone(),
        SimRigOptions {
            pacing: if args.realtime {
                Pacing::Realtime
            } else {
                Pacing::AsFastAsAsked
            },
            frames: Some(frames),
            latency: None,
        },
    )?;
    let mut processor = Processor::new(cams.to_vec(), Some(view), graph, settings.clone())?;
    processor.set_compose(false);
    let mut lp = LockStep::new(source, processor)?;

    let info = &cams[0];
    writeln!(
        out,
        "rigview demo: simulated rig, scenario \"{}\": {n} cameras {}×{} {} ({}° fisheye), trigger {} Hz{}, latency {} frame(s)",
        args.scenario,
        info.width,
        info.height,
        info.format.genicam_name(),
        config.lens_fov_deg,
        config.trigger_hz,
        if args.realtime { "" } else { " (run as fast as possible)" },
        lp.source().latency()
    )?;
    writeln!(
        out,
        "scene traced in {traced:.2} s; scene dynamic range {:.1e} (0.01–99.99 % of pixels); sensor {:.1} dB, {} bits",
        dr.ratio(),
        render.sensor().dynamic_range_db(),
        render.sensor().bits
    )?;
    writeln!(
        out,
        "control: {}, {} law, {} simulation, metering {}; E = shutter_us · 10^(gain_dB/20)",
        settings.strategy.label(),
        settings.controller.law.kind.name(),
        settings.controller.estimator.simulation.name(),
        match settings.roi {
            MeterRoi::Ground => "the surround view's ground",
            MeterRoi::Full => "whole frames",
        }
    )?;
    writeln!(
        out,
        "overlaps: log2 r_ij measured (and as the ground truth predicts it from E_j/E_i)\n"
    )?;
    let pairs: Vec<(usize, usize)> = render.rig().neighbours.clone();
    write!(out, "{:>5} {:>6} {:>6}", "set", "t/s", "light")?;
    for c in cams {
        write!(out, " | {:>6}: {:>7} {:>5} {:>6}", c.name, "E", "γ̂", "M")?;
    }
    write!(out, " |")?;
    for &(i, j) in &pairs {
        let label = format!("{}-{}", short(&cams[i].name), short(&cams[j].name));
        write!(out, " {label:>12}")?;
    }
    writeln!(out)?;

    let mut last_spread = f64::NAN;
    for f in 0..frames {
        let Some(step) = lp.step()? else {
            break;
        };
        let t = step.set.timestamp_ns as f64 * 1e-9;
        let Some(rig_step) = step.output.map(|o| o.step) else {
            writeln!(out, "{f:>5} {t:>6.2}  incomplete set, skipped")?;
            continue;
        };
        let mut logs: Vec<f64> = rig_step
            .ratios
            .iter()
            .filter_map(|r| r.r_ij)
            .map(|r| r.log2().abs())
            .collect();
        logs.sort_by(f64::total_cmp);
        last_spread = logs.get(logs.len() / 2).copied().unwrap_or(f64::NAN);
        if f % args.every.max(1) != 0 && f + 1 != frames {
            continue;
        }
        let light = render.levels(t).sun.log2();
        write!(out, "{f:>5} {t:>6.2} {light:>+6.2}")?;
        for c in &rig_step.cameras {
            let (g, m) = c
                .estimate
                .as_ref()
                .map_or((f64::NAN, f64::NAN), |e| (e.gamma_hat, e.m_current));
            write!(out, " | {:>15.0} {g:>5.2} {m:>6.0}", c.taken.exposure())?;
        }
        write!(out, " |")?;
        let view = lp.processor().view().context("no surround view")?;
        let truths = truth::overlap_ratios(&render, view, t)?;
        for &(i, j) in &pairs {
            let measured = rig_step
                .ratios
                .iter()
                .find(|r| r.i == i && r.j == j)
                .and_then(|r| r.r_ij)
                .map_or(f64::NAN, f64::log2);
            let predicted = truths
                .iter()
                .find(|o| o.i == i && o.j == j)
                .and_then(|o| o.ratio)
                .map_or(f64::NAN, |r| {
                    (r * rig_step.cameras[j].taken.exposure()
                        / rig_step.cameras[i].taken.exposure())
                    .log2()
                });
            write!(out, " {measured:>+5.2}({predicted:>+5.2})")?;
        }
        writeln!(out)?;
    }
    writeln!(
        out,
        "\nafter {frames} frame sets: median |log2 r_ij| over the overlaps = {last_spread:.3}"
    )?;
    Ok(())
}

/// The first letter of a camera's name, for column labels.
fn short(name: &str) -> String {
    name.chars().next().map_or("?".into(), |c| c.to_string())
}
