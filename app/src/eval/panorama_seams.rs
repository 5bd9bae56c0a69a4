//! Experiment 5, the seams of the cylindrical panorama: experiment 4's
//! measurement with `r_ij` from matched patches.
//!
//! Each scenario of experiment 4 runs under each strategy of
//! [`EvalStrategy::PANORAMA`] in closed loop with the panorama as the view
//! (`View::Panorama`): every pixel that reaches the cylinder is metered,
//! and the balancing takes its ratios from the live panorama's matching
//! worker (Harris corners, BRIEF, RANSAC on the pair's rotation, patches
//! around the inliers) every [`PanoramaPlan::match_every`] sets, as
//! `rigview run --view panorama` does.
//!
//! Measured, after the warm-up, on every `match_every`-th set: a matching
//! of that set of its own, on the panorama in use, with the same detector
//! and options as the worker's. Each overlap gives either `log2 r_ij`
//! (Eq. 5's median ratio over its usable patches, in the cameras' images)
//! or none, counted by why: too few matches (fewer inliers than RANSAC
//! needs, [`PairMatches::problem`]) or no usable patch (every patch
//! saturated or near black). A pair without a ratio is counted, never
//! given one.
//!
//! The measuring matching is separate from the worker's so that it sees
//! each measured set at the exposures it was taken with (the worker's
//! held ratios are rescaled to later exposures) and is the same for every
//! strategy. The worker runs on a thread of its own, so when its matches
//! reach the balancing depends on the machine: unlike experiment 4, a run
//! under balancing does not repeat to the bit (the strategies that use no
//! ratio do).
//!
//! The display-gain strategies of experiment 4 are left out: their
//! exposures, and so their images and matched patches, are those of the
//! strategies without display gains.
//!
//! [`PairMatches::problem`]: rigview_core::panorama::PairMatches::problem

use std::sync::Arc;

use anyhow::{Context, Result};
use rigview_core::exposure::balance::{clipped, pair_ratio};
use rigview_core::exposure::{BalanceParams, NeighbourGraph};
use rigview_core::panorama::MatchOptions;
use rigview_core::pipeline::{
    LockStep, PanoramaSettings, Processor, SharedDetector, View, ViewKind,
};
use rigview_core::sim::{SimConfig, SimRender};

use super::closed_loop;
use super::seams::{frames_of, histogram, mean_sd_abs};
use super::strategy::EvalStrategy;
use crate::session::view::{build_view, ViewSpec};

/// What experiment 5 measures.
#[derive(Clone, Debug, PartialEq)]
pub struct PanoramaPlan {
    /// The scenarios (those of experiment 4).
    pub scenarios: Vec<String>,
    /// Sets of a scenario of constant light (others run their length).
    pub frames: usize,
    /// Sets left out at the start.
    pub warmup: usize,
    /// The panorama's canvas, pixels (360° of azimuth × the elevation
    /// band).
    pub canvas: (usize, usize),
    /// The worker matches every `match_every` sets; the measurement
    /// matches every `match_every`-th set after the warm-up.
    pub match_every: usize,
}

impl PanoramaPlan {
    /// The live panorama's settings: the plan's canvas and schedule, the
    /// rest at rigview's defaults (no refinement).
    pub fn settings(&self) -> PanoramaSettings {
        PanoramaSettings {
            width: self.canvas.0,
            height: self.canvas.1,
            match_every: self.match_every as u64,
            ..PanoramaSettings::default()
        }
    }
}

/// One overlap of one measured set.
#[derive(Clone, Debug, PartialEq)]
pub struct PairSample {
    /// The set (0 is the first of the run).
    pub set: usize,
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// Mutual matches.
    pub matches: usize,
    /// RANSAC's inliers (0 with too few).
    pub inliers: usize,
    /// Brightness patches around the inliers.
    pub patches: usize,
    /// `log2 r_ij` from the patches, if the pair gives a ratio.
    pub log2_r: Option<f64>,
    /// Whether the pair had too few matches for a rotation and patches
    /// (otherwise a pair without a ratio had no usable patch).
    pub too_few: bool,
    /// Whether most of its patches are saturated in either camera.
    pub saturated: bool,
}

/// One scenario under one strategy.
#[derive(Clone, Debug)]
pub struct PanoramaRun {
    /// The scenario.
    pub scenario: String,
    /// The strategy.
    pub strategy: EvalStrategy,
    /// Every overlap of every measured set.
    pub samples: Vec<PairSample>,
}

/// Summary figures of one run (or of several: [`PanoramaStats::of`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PanoramaStats {
    /// Mean of `|log2 r_ij|`, EV (NaN without a ratio).
    pub mean: f64,
    /// Its standard deviation.
    pub sd: f64,
    /// Pairs × sets with a ratio.
    pub with_ratio: usize,
    /// Pairs × sets with too few matches.
    pub too_few: usize,
    /// Pairs × sets with matches but no usable patch.
    pub unusable: usize,
}

impl PanoramaStats {
    /// The figures over every sample of `runs`.
    pub fn of<'a>(runs: impl IntoIterator<Item = &'a PanoramaRun>) -> Self {
        let samples: Vec<&PairSample> = runs.into_iter().flat_map(|r| &r.samples).collect();
        let ratios: Vec<f64> = samples.iter().filter_map(|s| s.log2_r).collect();
        let (mean, sd) = mean_sd_abs(&ratios);
        let too_few = samples.iter().filter(|s| s.too_few).count();
        Self {
            mean,
            sd,
            with_ratio: ratios.len(),
            too_few,
            unusable: samples.len() - ratios.len() - too_few,
        }
    }
}

impl PanoramaRun {
    /// Every `log2 r_ij` measured.
    pub fn ratios(&self) -> Vec<f64> {
        self.samples.iter().filter_map(|s| s.log2_r).collect()
    }

    /// The summary figures.
    pub fn stats(&self) -> PanoramaStats {
        PanoramaStats::of([self])
    }

    /// The histogram of `log2 r_ij` (see [`histogram`]).
    pub fn histogram(&self) -> Vec<(f64, f64)> {
        histogram(&self.ratios())
    }
}

/// What experiment 5 measured.
#[derive(Clone, Debug, Default)]
pub struct PanoramaResult {
    /// The cameras' names.
    pub cameras: Vec<String>,
    /// Every run.
    pub runs: Vec<PanoramaRun>,
}

/// Work units of [`run`] for `frames` sets per scenario (the progress
/// bar).
pub fn units(frames: &[usize]) -> u64 {
    frames
        .iter()
        .map(|f| (EvalStrategy::PANORAMA.len() * f) as u64)
        .sum()
}

/// Runs experiment 5; `config` makes a scenario's simulation, `detector`
/// finds the corners both matchings use.
pub fn run(
    plan: &PanoramaPlan,
    config: &dyn Fn(&str) -> Result<SimConfig>,
    detector: &SharedDetector,
    tick: &mut dyn FnMut(u64),
) -> Result<PanoramaResult> {
    let mut out = PanoramaResult::default();
    for scenario in &plan.scenarios {
        let render = Arc::new(SimRender::new(&config(scenario)?)?);
        let frames = frames_of(render.config(), plan.frames);
        out.cameras = render.cameras().iter().map(|c| c.name.clone()).collect();
        for strategy in EvalStrategy::PANORAMA {
            let samples = run_loop(&render, plan, strategy, frames, detector, &mut || tick(1))
                .with_context(|| {
                    format!(
                        "the panorama's closed loop on {scenario} under {}",
                        strategy.key()
                    )
                })?;
            out.runs.push(PanoramaRun {
                scenario: scenario.clone(),
                strategy,
                samples,
            });
        }
    }
    Ok(out)
}

/// One closed loop of `strategy` with the panorama as the view, for
/// `frames` sets; returns the measured overlaps.
fn run_loop(
    render: &Arc<SimRender>,
    plan: &PanoramaPlan,
    strategy: EvalStrategy,
    frames: usize,
    detector: &SharedDetector,
    tick: &mut dyn FnMut(),
) -> Result<Vec<PairSample>> {
    let mut settings = strategy.settings();
    settings.view = ViewKind::Panorama;
    settings.panorama = plan.settings();
    let cameras = render.cameras().to_vec();
    let rig = render.rig().clone();
    let graph = NeighbourGraph::new(cameras.len(), &rig.neighbours)?;
    let view = build_view(
        &rig,
        &ViewSpec {
            detector: detector.clone(),
            ..ViewSpec::session(ViewKind::Panorama, &settings.panorama)
        },
    )
    .context("building the panorama of the simulated rig")?;
    let mut processor = Processor::new(cameras, Some(view), graph, settings)?;
    processor.set_compose(false);
    let mut lp = LockStep::new(closed_loop::sim_source(render, frames)?, processor)?;
    let options = MatchOptions::default();
    let params = BalanceParams::default();
    let mut samples = Vec::new();
    let mut set = 0;
    while let Some(step) = lp.step()? {
        step.output
            .as_ref()
            .context("the simulated rig gave an incomplete frame set")?;
        if set >= plan.warmup && (set - plan.warmup).is_multiple_of(plan.match_every.max(1)) {
            let views = closed_loop::frame_views(&step.set)?;
            let panorama = lp
                .processor()
                .live_view()
                .and_then(View::panorama)
                .context("the processor has no panorama")?
                .panorama();
            let (pairs, _) = panorama.match_pairs(&views, &**detector, &options)?;
            samples.extend(pairs.iter().map(|p| PairSample {
                set,
                i: p.i,
                j: p.j,
                matches: p.matches.len(),
                inliers: p.inliers,
                patches: p.patches.len(),
                log2_r: if p.problem.is_none() {
                    pair_ratio(&p.patches, &params).map(f64::log2)
                } else {
                    None
                },
                too_few: p.problem.is_some(),
                saturated: clipped(&p.patches, &params),
            }));
        }
        set += 1;
        tick();
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(log2_r: Option<f64>, too_few: bool) -> PairSample {
        PairSample {
            set: 0,
            i: 0,
            j: 1,
            matches: 10,
            inliers: 8,
            patches: 8,
            log2_r,
            too_few,
            saturated: false,
        }
    }

    #[test]
    fn pairs_without_a_ratio_are_counted_by_why_and_left_out_of_the_figures() {
        let run = PanoramaRun {
            scenario: "backlight".into(),
            strategy: EvalStrategy::Multi,
            samples: vec![
                sample(Some(0.5), false),
                sample(Some(-1.5), false),
                sample(None, true),
                sample(None, true),
                sample(None, false),
            ],
        };
        let s = run.stats();
        assert_eq!((s.with_ratio, s.too_few, s.unusable), (2, 2, 1));
        assert!((s.mean - 1.0).abs() < 1e-12, "{}", s.mean);
        assert!((s.sd - 0.5).abs() < 1e-12, "{}", s.sd);
        let h = run.histogram();
        let total: f64 = h.iter().map(|b| b.1).sum();
        assert!((total - 1.0).abs() < 1e-12);
        let empty = PanoramaRun {
            samples: vec![sample(None, true)],
            ..run
        };
        assert!(empty.stats().mean.is_nan());
        assert!(empty.histogram().iter().all(|b| b.1 == 0.0));
    }
}
