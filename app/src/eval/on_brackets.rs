//! `rigview eval --brackets DIR`: the experiments that apply to a bracket
//! sequence (`docs/brackets.md`), on its images instead of the simulator.
//!
//! - **Experiment 3**: M(E) per camera of the sequence's last moment (the
//!   ground the view shows metered as the controller meters it): in
//!   `emulate` mode (the default) a dense sweep of noise-free emulated
//!   frames every [`SWEEP_STEP_EV`] over the exposures the source offers,
//!   in `nearest` mode the brackets themselves; where each strategy settles
//!   (the median log2 E of its last frames) marked, with the corners it
//!   keeps tracked and matched across the overlaps there, and the valid
//!   disparities of any stereo pair of the rig ([`super::downstream`]).
//! - **From the start** ([`super::start`]): frames to settle from the
//!   common start, the overshoot on the way, and the flicker at rest.
//! - **Experiments 4 and 6**: the closed loop on the sequence with the view
//!   composed: `log2 r_ij`, the seam step, M as a fraction of the best,
//!   the profile across the seams and the last view.
//!
//! Experiments 1 and 2 need the simulator (a noise-free render at any
//! exposure; known steps of light) and are left out, as is the cameras'
//! own AE, which needs the simulated camera. Experiment 5, the panorama's
//! closed loop, runs on the simulated rig only.
//!
//! A rig posed relative to one of its cameras (a Kalibr camchain, as
//! public stereo datasets give it) has no ground: its cameras are metered
//! over their whole frames, and what needs the view (experiments 4 and 6,
//! the overlaps' matches, the compensated strategy) is left out; M, the
//! tracked corners, the stereo disparities and the start are measured.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use rigview_core::exposure::{Estimator, EstimatorConfig, ExposureSetting, Meter};
use rigview_core::sim::truth::Sweep;
use rigview_core::source::FrameSource;

use super::closed_loop::{self, LoopOptions};
use super::downstream::{self, Downstream, FeatureMeter};
use super::seams::{self, SeamRun, SeamsResult};
use super::start::StartRow;
use super::strategy::EvalStrategy;
use super::sweep::{CameraSweep, Settled, SweepResult};
use super::{write_all, Plan, Results};
use crate::session::brackets::{self, read_image, BracketMode, BracketOptions, Emulator};
use crate::session::BRACKETS_START;

/// The name experiments 3 and 4 give the sequence.
const NAME: &str = "brackets";

/// The strategies run on brackets: every strategy but the cameras' own AE,
/// the gradient ones under both exposure simulations.
pub const STRATEGIES: [EvalStrategy; 13] = [
    EvalStrategy::Linear,
    EvalStrategy::Nonlinear,
    EvalStrategy::Fast,
    EvalStrategy::Multi,
    EvalStrategy::Pid,
    EvalStrategy::LinearSc,
    EvalStrategy::NonlinearSc,
    EvalStrategy::FastSc,
    EvalStrategy::MultiSc,
    EvalStrategy::PidSc,
    EvalStrategy::Mean,
    EvalStrategy::Fixed,
    EvalStrategy::MultiComp,
];

/// The steps of the dense emulated sweep of M, EV.
pub const SWEEP_STEP_EV: f64 = 0.1;

/// Runs what applies of `plan` on the bracket sequence in `dir`, the
/// cameras answered as `mode` says, writing into `out`.
pub fn run(plan: &Plan, dir: &Path, mode: BracketMode, out: &Path) -> Result<Results> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    let options = BracketOptions::new(BRACKETS_START, mode);
    let (probe, rig) = brackets::open_with_rig(dir, None, &options)?;
    let moments = probe.manifest().moments.len();
    // The cameras whose frames went through a tone curve, which
    // scale-and-clip simulates through.
    let toned: Vec<String> = probe
        .cameras()
        .iter()
        .filter_map(|c| {
            let curve = c.tone_curve.as_ref()?;
            Some(match curve.nearest_power() {
                Some(p) => format!("{} (nearest power {p:.1})", c.name),
                None => c.name.clone(),
            })
        })
        .collect();
    let view = closed_loop::ground_view(&rig)?;
    let names: Vec<String> = rig.cameras.iter().map(|c| c.name.clone()).collect();
    let mut plan = plan.clone();
    plan.scenario = dir.display().to_string();
    plan.sweep.presets = vec![NAME.into()];
    plan.seams.scenarios = vec![NAME.into()];
    plan.seams.warmup = plan.seams.warmup.min(moments / 4);
    plan.seams.tail = plan.seams.tail.min(moments / 4).max(1);

    // M(E) of the last moment: from its brackets, or emulated densely
    // (noise-free) over the exposures the emulating source offers.
    let manifest = probe.manifest();
    let last_moment = manifest
        .moments
        .len()
        .checked_sub(1)
        .context("a bracket sequence without moments")?;
    let last = &manifest.moments[last_moment];
    let meter = Meter::new(plan.sweep_metering())?;
    let mut est = Estimator::new(EstimatorConfig::default())?;
    let mut emulator = match mode {
        BracketMode::Emulate => Some(Emulator::new(manifest, options.seed)?),
        BracketMode::Nearest => None,
    };
    let mut sweeps = Vec::new();
    for (cam, images) in last.cameras.iter().enumerate() {
        let mut exposures = Vec::with_capacity(images.len());
        let mut scores = Vec::with_capacity(images.len());
        let mut score = |d: &brackets::Decoded, e: f64| -> Result<()> {
            let frame =
                rigview_core::exposure::FrameView::new(d.format, d.width, d.height, &d.data)?;
            let mask = view.as_ref().and_then(|v| v.ground_masks().get(cam));
            let m = meter.meter(&frame, mask)?;
            // (An exposure clamped to the moment's span repeats the last.)
            if exposures.last().is_none_or(|&l: &f64| e > l * (1.0 + 1e-9)) {
                exposures.push(e);
                scores.push(est.score(&m));
            }
            Ok(())
        };
        match emulator.as_mut() {
            Some(em) => {
                let range = em.range(cam);
                let span = (range.shutter_max_us / range.shutter_min_us).log2();
                let steps = (span / SWEEP_STEP_EV).floor() as usize;
                for k in 0..=steps {
                    let asked = ExposureSetting {
                        shutter_us: range.shutter_min_us * (k as f64 * SWEEP_STEP_EV).exp2(),
                        gain_db: 0.0,
                    };
                    let (taken, d) = em.frame_with(manifest, last_moment, cam, &asked, false)?;
                    score(&d, taken.exposure())?;
                }
            }
            None => {
                for image in images {
                    let d = read_image(manifest, image)?;
                    score(&d, image.setting.exposure())?;
                }
            }
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
    // The compensated strategy differs from multi only in the view.
    let strategies: Vec<EvalStrategy> = STRATEGIES
        .into_iter()
        .filter(|&s| view.is_some() || s != EvalStrategy::MultiComp)
        .collect();
    let bar = super::progress_bar((strategies.len() * moments) as u64)?;
    bar.set_message("closed loops on the brackets");
    let mut settled = Vec::new();
    let mut start = Vec::new();
    let mut overlaps = Vec::new();
    let mut stereo = Vec::new();
    let mut stereo_views = Vec::new();
    let mut runs = Vec::new();
    let mut meter = FeatureMeter::new(&rig, plan.sweep.canvas)?;
    for strategy in strategies {
        let (source, _) = brackets::open_with_rig(dir, None, &options)?;
        let from = moments.saturating_sub(plan.seams.tail + 1);
        let mut measured = Vec::new();
        let trace = closed_loop::run_observed(
            source,
            &rig,
            strategy.settings_as_run(),
            LoopOptions {
                view: view.is_some(),
            },
            &mut meter.from_set(from, &mut measured),
            &mut || bar.inc(1),
        )?;
        let measured = downstream::at_rest(measured, &trace, from);
        let downstream = Downstream::of(&measured);
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
                    tracked: downstream.tracked(cam),
                });
            }
        }
        if strategy != EvalStrategy::MultiComp {
            overlaps.extend(downstream.overlaps(NAME, strategy, &names));
            stereo.extend(downstream.stereo(NAME, strategy, &names));
            stereo_views
                .extend(meter.stereo_views(NAME, strategy, &names, |set| !trace.probe_set(set)));
        }
        start.extend(StartRow::of(strategy, &trace, &names, |cam, log2_e| {
            sweeps.get(cam).map(|s| {
                s.sweep.score_at(log2_e.exp2()) / s.sweep.best_score.max(f64::MIN_POSITIVE)
            })
        }));
        if let Some(view) = &view {
            let canvas = trace
                .canvas
                .clone()
                .context("the closed loop composed no view")?;
            runs.push(SeamRun {
                scenario: NAME.into(),
                strategy,
                profile: seams::profile(view, &canvas),
                trace,
                m_fraction,
            });
        }
    }
    bar.finish_and_clear();
    let results = Results {
        gamma: Vec::new(),
        steps: Default::default(),
        sweep: SweepResult {
            sweeps,
            settled,
            overlaps,
            stereo,
            stereo_views,
        },
        seams: SeamsResult {
            runs,
            seam_angles: view
                .iter()
                .map(|v| (NAME.into(), seams::seam_angles(v)))
                .collect(),
        },
        panorama: Default::default(),
        start,
        seconds: vec![
            ("3. M against exposure (the brackets)", t_sweep),
            (
                "3, 4, 6. closed loops on the brackets",
                t.elapsed().as_secs_f64(),
            ),
        ],
        source: format!(
            "the bracket sequence {} ({moments} moments, {} cameras{}; {}{})",
            dir.display(),
            names.len(),
            if view.is_some() {
                ""
            } else {
                ", posed relative to a camera: whole frames metered, no surround view"
            },
            match mode {
                BracketMode::Emulate =>
                    "frames emulated at the exposure asked, M(E) swept at 0.1 EV",
                BracketMode::Nearest =>
                    "the bracket nearest the exposure asked, M(E) at the brackets",
            },
            if toned.is_empty() {
                String::new()
            } else {
                format!(
                    "; 8-bit responses recovered, which scale-and-clip simulates \
                     exposure through: {}",
                    toned.join(", ")
                )
            }
        ),
        plan,
    };
    write_all(&results, out)?;
    Ok(results)
}
