//! Experiment 3, M against exposure (the paper's Fig. 11): for each camera
//! of each preset, the dense sweep of M over exposure (noise-free renders,
//! the ground the surround view shows metered as the controller meters it),
//! and where each strategy settles: the median log2 E of the last `tail`
//! frames of a closed loop of `frames` sets in the preset's constant light,
//! with M there as a fraction of the sweep's best.

use std::sync::Arc;

use anyhow::{Context, Result};
use rigview_core::pipeline::MeterRoi;
use rigview_core::sim::truth::{self, Sweep, SweepOptions};
use rigview_core::sim::{SimConfig, SimRender};

use super::closed_loop;
use super::downstream::{
    self, Downstream, FeatureMeter, OverlapFeatures, StereoDensity, StereoView,
};
use super::strategy::EvalStrategy;
use crate::report::mean;

/// What experiment 3 measures.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepPlan {
    /// The presets (constant light).
    pub presets: Vec<String>,
    /// The presets metered over whole frames (the sweeps and every
    /// strategy's loop) rather than over the surround view's ground: `sky`,
    /// whose bright sky no ground mask contains.
    pub whole_frames: Vec<String>,
    /// The sweep: lowest and highest level, and levels.
    pub lo: f64,
    /// Highest level.
    pub hi: f64,
    /// Levels of the sweep.
    pub steps: usize,
    /// Sets of each closed loop.
    pub frames: usize,
    /// Frames at the end whose median is the settled exposure; the
    /// downstream measures ([`super::downstream`]) are taken over them.
    pub tail: usize,
    /// The panorama whose overlaps the downstream measures match.
    pub canvas: (usize, usize),
}

/// One camera's sweep in one preset.
#[derive(Clone, Debug)]
pub struct CameraSweep {
    /// The preset.
    pub preset: String,
    /// The camera's name.
    pub camera: String,
    /// The sweep.
    pub sweep: Sweep,
}

/// Where a strategy settled.
#[derive(Clone, Debug, PartialEq)]
pub struct Settled {
    /// The preset.
    pub preset: String,
    /// The camera's name.
    pub camera: String,
    /// The strategy.
    pub strategy: EvalStrategy,
    /// The settled log2 E.
    pub log2_e: f64,
    /// M there.
    pub m: f64,
    /// M there over the sweep's best.
    pub fraction: f64,
    /// The sweep's best log2 E.
    pub best_log2_e: f64,
    /// Corners tracked from frame to frame over the tail, mean per frame
    /// ([`super::downstream`]).
    pub tracked: f64,
}

impl Settled {
    /// The CSV header.
    pub const HEADER: &'static str =
        "preset,camera,strategy,settled_log2_e,m,m_fraction_of_best,best_log2_e,gap_ev,tracked";

    /// A CSV line.
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{:.4},{:.3},{:.5},{:.4},{:.4},{:.1}",
            self.preset,
            self.camera,
            self.strategy.key(),
            self.log2_e,
            self.m,
            self.fraction,
            self.best_log2_e,
            self.log2_e - self.best_log2_e,
            self.tracked
        )
    }
}

/// What experiment 3 measured.
#[derive(Clone, Debug, Default)]
pub struct SweepResult {
    /// The sweeps.
    pub sweeps: Vec<CameraSweep>,
    /// The settled exposures.
    pub settled: Vec<Settled>,
    /// Features matched across each overlap over the tail.
    pub overlaps: Vec<OverlapFeatures>,
    /// Valid disparities of each stereo pair over the tail (none on a rig
    /// without a pair).
    pub stereo: Vec<StereoDensity>,
    /// The last views and disparities of each stereo pair under the
    /// strategies of the report's figure.
    pub stereo_views: Vec<StereoView>,
}

/// Work units of one preset (sweep levels and closed-loop sets).
pub fn units(plan: &SweepPlan, cameras: usize) -> u64 {
    (cameras * plan.steps + EvalStrategy::SETTLED.len() * plan.frames) as u64
}

/// Runs experiment 3; `config` makes the preset's simulation.
pub fn run(
    plan: &SweepPlan,
    config: &dyn Fn(&str) -> Result<SimConfig>,
    tick: &mut dyn FnMut(u64),
) -> Result<SweepResult> {
    let mut out = SweepResult::default();
    for preset in &plan.presets {
        let render = Arc::new(SimRender::new(&config(preset)?)?);
        let view = closed_loop::eval_view(&render)?;
        let options = SweepOptions {
            lo: plan.lo,
            hi: plan.hi,
            steps: plan.steps,
            ..Default::default()
        };
        let first = out.sweeps.len();
        let whole = plan.whole_frames.contains(preset);
        for (cam, info) in render.cameras().iter().enumerate() {
            let mask = if whole {
                None
            } else {
                view.ground_masks().get(cam)
            };
            let sweep = truth::sweep(&render, cam, 0.0, &options, mask)?;
            tick(plan.steps as u64);
            out.sweeps.push(CameraSweep {
                preset: preset.clone(),
                camera: info.name.clone(),
                sweep,
            });
        }
        let mut meter = FeatureMeter::new(render.rig(), plan.canvas)?;
        let names: Vec<String> = render.cameras().iter().map(|c| c.name.clone()).collect();
        for strategy in EvalStrategy::SETTLED {
            let mut settings = strategy.settings_as_run();
            if whole {
                settings.roi = MeterRoi::Full;
            }
            // The tail, and the set before it (the first tracked from).
            let from = plan.frames.saturating_sub(plan.tail + 1);
            let mut measured = Vec::new();
            let trace = closed_loop::run_observed(
                closed_loop::sim_source(&render, plan.frames)?,
                render.rig(),
                settings,
                Default::default(),
                &mut meter.from_set(from, &mut measured),
                &mut || tick(1),
            )
            .with_context(|| format!("the closed loop on {preset} under {}", strategy.key()))?;
            let measured = downstream::at_rest(measured, &trace, from);
            let downstream = Downstream::of(&measured);
            out.overlaps
                .extend(downstream.overlaps(preset, strategy, &names));
            out.stereo
                .extend(downstream.stereo(preset, strategy, &names));
            out.stereo_views
                .extend(meter.stereo_views(preset, strategy, &names, |set| !trace.probe_set(set)));
            for (cam, s) in out.sweeps[first..].iter().enumerate() {
                let log2_e = trace.settled(cam, plan.tail);
                let m = s.sweep.score_at(log2_e.exp2());
                out.settled.push(Settled {
                    preset: preset.clone(),
                    camera: s.camera.clone(),
                    strategy,
                    log2_e,
                    m,
                    fraction: m / s.sweep.best_score.max(f64::MIN_POSITIVE),
                    best_log2_e: s.sweep.best.log2(),
                    tracked: downstream.tracked(cam),
                });
            }
        }
    }
    Ok(out)
}

/// The mean of `of` over the `rows` of `strategy` (NaN without one).
fn mean_of<T>(
    rows: &[T],
    strategy: EvalStrategy,
    strategy_of: fn(&T) -> EvalStrategy,
    of: fn(&T) -> f64,
) -> f64 {
    let v: Vec<f64> = rows
        .iter()
        .filter(|r| strategy_of(r) == strategy)
        .map(of)
        .collect();
    mean(&v)
}

impl SweepResult {
    /// The mean of `M/M_best` of `strategy` over every camera and preset.
    pub fn mean_fraction(&self, strategy: EvalStrategy) -> f64 {
        mean_of(&self.settled, strategy, |s| s.strategy, |s| s.fraction)
    }

    /// Corners `strategy` kept tracked from frame to frame, mean per
    /// camera over every camera and preset.
    pub fn mean_tracked(&self, strategy: EvalStrategy) -> f64 {
        mean_of(&self.settled, strategy, |s| s.strategy, |s| s.tracked)
    }

    /// Inliers matched across an overlap where `strategy` settled, mean
    /// per overlap over every overlap and preset.
    pub fn mean_inliers(&self, strategy: EvalStrategy) -> f64 {
        mean_of(&self.overlaps, strategy, |o| o.strategy, |o| o.inliers)
    }

    /// The share of valid stereo disparities where `strategy` settled,
    /// mean over every pair and preset (NaN on a rig without a pair).
    pub fn mean_stereo(&self, strategy: EvalStrategy) -> f64 {
        mean_of(&self.stereo, strategy, |o| o.strategy, |o| o.density)
    }
}
