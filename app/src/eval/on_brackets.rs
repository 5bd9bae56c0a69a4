//! `rigview eval --brackets DIR`: the experiments that apply to a bracket
//! sequence (`docs/brackets.md`), on its images instead of the simulator.
//!
//! - **Experiment 3**: M(E) per camera from the sequence's own images of
//!   its last moment (the ground the view shows metered as the controller
//!   meters it), at the brackets' levels, with where each strategy settles
//!   on the sequence (the median log2 E of its last frames) marked.
//! - **Experiments 4 and 6**: the closed loop on the sequence with the view
//!   composed: `log2 r_ij`, the seam step, M as a fraction of the best,
//!   the profile across the seams and the last view.
//!
//! Experiments 1 and 2 need the simulator (a noise-free render at any
//! exposure; known steps of light) and are left out, as is the cameras'
//! own AE, which needs the simulated camera. Experiment 5, the panorama's
//! closed loop, runs on the simulated rig only.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use rigview_core::exposure::{Estimator, EstimatorConfig, Meter};
use rigview_core::sim::truth::Sweep;

use super::closed_loop::{self, LoopOptions};
use super::seams::{self, SeamRun, SeamsResult};
use super::strategy::EvalStrategy;
use super::sweep::{CameraSweep, Settled, SweepResult};
use super::{write_all, Plan, Results};
use crate::session::brackets::{self, read_image, BracketMode, BracketOptions};
use crate::session::BRACKETS_START;

/// The name experiments 3 and 4 give the sequence.
const NAME: &str = "brackets";

/// The strategies run on brackets: every strategy but the cameras' own AE.
pub const STRATEGIES: [EvalStrategy; 8] = [
    EvalStrategy::Linear,
    EvalStrategy::Nonlinear,
    EvalStrategy::Fast,
    EvalStrategy::Multi,
    EvalStrategy::Pid,
    EvalStrategy::Mean,
    EvalStrategy::Fixed,
    EvalStrategy::MultiComp,
];

/// Runs what applies of `plan` on the bracket sequence in `dir`, writing
/// into `out`.
pub fn run(plan: &Plan, dir: &Path, out: &Path) -> Result<Results> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    // The brackets as they are (section 6 of issue 30 moves this to the
    // emulation).
    let options = BracketOptions::new(BRACKETS_START, BracketMode::Nearest);
    let (probe, rig) = brackets::open_with_rig(dir, None, &options)?;
    let moments = probe.manifest().moments.len();
    let view = closed_loop::rig_view(&rig)?;
    let names: Vec<String> = rig.cameras.iter().map(|c| c.name.clone()).collect();
    let mut plan = plan.clone();
    plan.scenario = dir.display().to_string();
    plan.sweep.presets = vec![NAME.into()];
    plan.seams.scenarios = vec![NAME.into()];
    plan.seams.warmup = plan.seams.warmup.min(moments / 4);
    plan.seams.tail = plan.seams.tail.min(moments / 4).max(1);

    // M(E) of the last moment, from its brackets.
    let last = probe
        .manifest()
        .moments
        .last()
        .context("a bracket sequence without moments")?;
    let meter = Meter::new(plan.sweep_metering())?;
    let mut est = Estimator::new(EstimatorConfig::default())?;
    let mut sweeps = Vec::new();
    for (cam, images) in last.cameras.iter().enumerate() {
        let mut exposures = Vec::with_capacity(images.len());
        let mut scores = Vec::with_capacity(images.len());
        for image in images {
            let d = read_image(probe.manifest(), image)?;
            let frame =
                rigview_core::exposure::FrameView::new(d.format, d.width, d.height, &d.data)?;
            let m = meter.meter(&frame, view.ground_masks().get(cam))?;
            exposures.push(image.setting.exposure());
            scores.push(est.score(&m));
        }
        let (k, best_score) = scores
            .iter()
            .copied()
            .enumerate()
            .fold((0, f64::MIN), |a, (k, m)| if m > a.1 { (k, m) } else { a });
        sweeps.push(CameraSweep {
            preset: NAME.into(),
            camera: names[cam].clone(),
            sweep: Sweep {
                best: exposures[k],
                best_score,
                exposures,
                scores,
            },
        });
    }
    let t_sweep = started.elapsed().as_secs_f64();

    let t = Instant::now();
    let bar = super::progress_bar((STRATEGIES.len() * moments) as u64)?;
    bar.set_message("closed loops on the brackets");
    let mut settled = Vec::new();
    let mut runs = Vec::new();
    for strategy in STRATEGIES {
        let (source, _) = brackets::open_with_rig(dir, None, &options)?;
        let trace = closed_loop::run_source(
            source,
            &rig,
            strategy.settings(),
            LoopOptions { view: true },
            &mut || bar.inc(1),
        )?;
        let mut m_fraction = Vec::new();
        for (cam, s) in sweeps.iter().enumerate() {
            let log2_e = trace.settled(cam, plan.seams.tail);
            let m = s.sweep.score_at(log2_e.exp2());
            let fraction = m / s.sweep.best_score.max(f64::MIN_POSITIVE);
            m_fraction.push(fraction);
            if strategy != EvalStrategy::MultiComp {
                settled.push(Settled {
                    preset: NAME.into(),
                    camera: s.camera.clone(),
                    strategy,
                    log2_e,
                    m,
                    fraction,
                    best_log2_e: s.sweep.best.log2(),
                });
            }
        }
        let canvas = trace
            .canvas
            .clone()
            .context("the closed loop composed no view")?;
        runs.push(SeamRun {
            scenario: NAME.into(),
            strategy,
            profile: seams::profile(&view, &canvas),
            trace,
            m_fraction,
        });
    }
    bar.finish_and_clear();
    let results = Results {
        gamma: Vec::new(),
        steps: Default::default(),
        sweep: SweepResult { sweeps, settled },
        seams: SeamsResult {
            runs,
            seam_angles: vec![(NAME.into(), seams::seam_angles(&view))],
        },
        panorama: Default::default(),
        seconds: vec![
            ("3. M against exposure (the brackets)", t_sweep),
            (
                "3, 4, 6. closed loops on the brackets",
                t.elapsed().as_secs_f64(),
            ),
        ],
        source: format!(
            "the bracket sequence {} ({moments} moments, {} cameras)",
            dir.display(),
            names.len()
        ),
        plan,
    };
    write_all(&results, out)?;
    Ok(results)
}
