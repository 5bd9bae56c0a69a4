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
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{LockStep, MeterRoi, ProcessingSettings, Processor};
use rigview_core::sim::{truth, Pacing, SimConfig, SimRender, SimRig, SimRigOptions};

use crate::session::view::{build_view, canvas_spec, ViewSpec};

/// A demo run.
#[derive(Clone, Debug)]
pub struct Demo {
    /// What the simulation is called (a preset's name or a file).
    pub scenario: String,
    /// The simulated rig.
    pub sim: SimConfig,
    /// Frame sets to run (`None`: the scenario's length at its trigger
    /// rate).
    pub frames: Option<u64>,
    /// Print every `every`-th frame set (and the last).
    pub every: u64,
    /// Produce frame sets at the trigger rate instead of as fast as
    /// possible.
    pub realtime: bool,
}

/// Runs the demo with the processing `settings`, printing to `out`.
pub fn run(demo: &Demo, settings: &ProcessingSettings, out: &mut dyn Write) -> Result<()> {
    let config = &demo.sim;
    let started = Instant::now();
    let render = Arc::new(SimRender::new(config).context("building the simulated rig")?);
    let traced = started.elapsed().as_secs_f64();
    let cams = render.cameras();
    let n = cams.len();
    let view = build_view(render.rig(), &ViewSpec::surround(canvas_spec()))
        .context("building the surround view of the simulated rig")?;
    let dr = truth::dynamic_range(&render, 0.0)?;
    let frames = demo
        .frames
        .unwrap_or_else(|| (config.duration_s * config.trigger_hz).round().max(1.0) as u64);

    let graph = NeighbourGraph::new(n, &render.rig().neighbours)?;
    let source = SimRig::new(
        render.clone(),
        SimRigOptions {
            pacing: if demo.realtime {
                Pacing::Realtime
            } else {
                Pacing::AsFastAsAsked
            },
            frames: Some(frames),
            ..Default::default()
        },
    )?;
    let mut processor = Processor::new(cams.to_vec(), Some(view), graph, settings.clone())?;
    processor.set_compose(false);
    let mut lp = LockStep::new(source, processor)?;

    let info = &cams[0];
    writeln!(
        out,
        "rigview demo: simulated rig, scenario \"{}\": {n} cameras {}×{} {} ({}° fisheye), trigger {} Hz{}, latency {} frame(s)",
        demo.scenario,
        info.width,
        info.height,
        info.format.genicam_name(),
        config.lens_fov_deg,
        config.trigger_hz,
        if demo.realtime { "" } else { " (run as fast as possible)" },
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
        "control: {}, metering {}; E = shutter_us · 10^(gain_dB/20)",
        crate::report::control(settings),
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
        if f % demo.every.max(1) != 0 && f + 1 != frames {
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
