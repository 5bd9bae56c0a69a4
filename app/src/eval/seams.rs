//! Experiment 4, the seams of the surround view (the paper's Figs. 18 and
//! 19), and experiment 6, the views side by side.
//!
//! Each scenario runs under each strategy of [`EvalStrategy::SEAMS`], with
//! the view composed every set (display gains only for the strategies that
//! have them). Measured, after a warm-up:
//!
//! - `log2 r_ij` of every overlap and set, in the cameras' images (the
//!   overlap patches' median ratio, as balancing measures it) and as the
//!   view shows it (the display gains applied): histograms, and the mean
//!   and spread of `|log2 r_ij|`;
//! - the seam step: the median `|log2|` intensity step the view shows
//!   within 3 canvas pixels of each seam ([`SeamBands`]), the median over
//!   seams and sets;
//! - each camera's M where it settled (the median log2 E of the last
//!   frames) as a fraction of its best, from a dense sweep at the last
//!   moment;
//! - an intensity profile of the last view along a circle around the
//!   vehicle, which crosses every seam.
//!
//! [`SeamBands`]: rigview_core::surround::SeamBands

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};
use plotters::prelude::*;
use rigview_core::sim::truth::{self, SweepOptions};
use rigview_core::sim::SimRender;
use rigview_core::surround::{Canvas, SurroundView};

use super::closed_loop::{self, LoopOptions, Trace};
use super::strategy::EvalStrategy;
use crate::report::glyphs::{register_font, FONT};

/// Histogram bins of `log2 r_ij`: from −HIST_EV to +HIST_EV.
pub const HIST_EV: f64 = 3.0;
/// Width of a histogram bin, EV.
pub const BIN_EV: f64 = 0.1;
/// Radius of the profile's circle around the canvas centre, metres.
pub const PROFILE_RADIUS_M: f64 = 3.5;

/// What experiment 4 measures.
#[derive(Clone, Debug, PartialEq)]
pub struct SeamsPlan {
    /// The scenarios.
    pub scenarios: Vec<String>,
    /// Sets of a scenario of constant light (others run their length).
    pub frames: usize,
    /// Sets left out at the start.
    pub warmup: usize,
    /// Frames at the end whose median is the settled exposure.
    pub tail: usize,
    /// The sweeps of M: lowest and highest level, and levels.
    pub sweep: (f64, f64, usize),
}

/// One scenario under one strategy.
#[derive(Clone, Debug)]
pub struct SeamRun {
    /// The scenario.
    pub scenario: String,
    /// The strategy.
    pub strategy: EvalStrategy,
    /// What the loop did.
    pub trace: Trace,
    /// Per camera, M where it settled over its best.
    pub m_fraction: Vec<f64>,
    /// The last view's intensity along the circle: (angle in degrees
    /// clockwise from ahead, mean intensity 0–255).
    pub profile: Vec<(f64, f64)>,
}

/// Summary figures of one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamStats {
    /// Mean of `|log2 r_ij|` in the images, EV.
    pub mean_images: f64,
    /// Its standard deviation.
    pub sd_images: f64,
    /// Mean of `|log2 r_ij|` in the view.
    pub mean_view: f64,
    /// Its standard deviation.
    pub sd_view: f64,
    /// Median seam step in the view, EV.
    pub seam_step: f64,
    /// Mean over cameras of M / best.
    pub m_mean: f64,
    /// Lowest over cameras of M / best.
    pub m_min: f64,
}

impl SeamRun {
    /// The samples of `log2 r_ij` after the warm-up (`view`: as shown).
    pub fn samples(&self, warmup: usize, view: bool) -> Vec<f64> {
        let sets = if view {
            &self.trace.shown_log2_r
        } else {
            &self.trace.log2_r
        };
        sets.iter()
            .skip(warmup)
            .flatten()
            .flatten()
            .copied()
            .collect()
    }

    /// The summary figures.
    pub fn stats(&self, warmup: usize) -> SeamStats {
        let (mean_images, sd_images) = mean_sd_abs(&self.samples(warmup, false));
        let (mean_view, sd_view) = mean_sd_abs(&self.samples(warmup, true));
        let mut steps: Vec<f64> = self
            .trace
            .seam_steps
            .iter()
            .skip(warmup)
            .flatten()
            .flatten()
            .copied()
            .collect();
        let n = self.m_fraction.len().max(1) as f64;
        SeamStats {
            mean_images,
            sd_images,
            mean_view,
            sd_view,
            seam_step: crate::report::quantile(&mut steps, 0.5),
            m_mean: self.m_fraction.iter().sum::<f64>() / n,
            m_min: self
                .m_fraction
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// The histogram of `log2 r_ij` in the view (see [`histogram`]).
    pub fn histogram(&self, warmup: usize) -> Vec<(f64, f64)> {
        histogram(&self.samples(warmup, true))
    }
}

/// The mean and standard deviation of `|v|`; NaN for no values.
pub fn mean_sd_abs(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    let m = a.iter().sum::<f64>() / a.len() as f64;
    (m, rigview_core::eval::dynamics::std_dev(&a))
}

/// The histogram of `samples` of `log2 r_ij` from −[`HIST_EV`] to
/// +[`HIST_EV`] in bins of [`BIN_EV`]: per bin, its lower edge and the
/// fraction of samples (outliers in the end bins; all zero without
/// samples).
pub fn histogram(samples: &[f64]) -> Vec<(f64, f64)> {
    let bins = (2.0 * HIST_EV / BIN_EV).round() as usize;
    let mut counts = vec![0usize; bins];
    for v in samples {
        let k = ((v + HIST_EV) / BIN_EV)
            .floor()
            .clamp(0.0, (bins - 1) as f64) as usize;
        counts[k] += 1;
    }
    let total = samples.len().max(1) as f64;
    counts
        .iter()
        .enumerate()
        .map(|(k, &c)| (-HIST_EV + BIN_EV * k as f64, c as f64 / total))
        .collect()
}

/// What experiment 4 measured.
#[derive(Clone, Debug, Default)]
pub struct SeamsResult {
    /// Every run.
    pub runs: Vec<SeamRun>,
    /// Per scenario, the angles (degrees) where the profile's circle
    /// crosses a seam.
    pub seam_angles: Vec<(String, Vec<f64>)>,
}

/// Work units of [`run`] for `frames` sets per run (the progress bar).
pub fn units(plan: &SeamsPlan, frames: &[usize], cameras: usize) -> u64 {
    frames
        .iter()
        .map(|f| (cameras * plan.sweep.2 + EvalStrategy::SEAMS.len() * f) as u64)
        .sum()
}

/// The sets of a run of `config`'s scenario: `constant` in constant
/// light, otherwise the script's length.
pub fn frames_of(config: &rigview_core::sim::SimConfig, constant: usize) -> usize {
    if config.script.is_constant() {
        constant
    } else {
        (config.duration_s * config.trigger_hz).round() as usize
    }
}

/// The camera the hard seams show at canvas pixel `(x, y)`.
fn owner(view: &SurroundView, x: usize, y: usize) -> Option<usize> {
    view.layers().iter().position(|l| {
        let [x0, y0, w, h] = l.roi;
        (x0..x0 + w).contains(&x)
            && (y0..y0 + h).contains(&y)
            && l.weights[2]
                .get((y - y0) * w + x - x0)
                .is_some_and(|&v| v > 0)
    })
}

/// The profile's circle: canvas pixel at `deg` clockwise from ahead (up).
fn on_circle(view: &SurroundView, deg: f64) -> (usize, usize) {
    let (w, h) = view.size();
    let r = PROFILE_RADIUS_M * view.spec().px_per_m;
    let a = deg.to_radians();
    let x = (w as f64 / 2.0 + r * a.sin())
        .round()
        .clamp(0.0, (w - 1) as f64);
    let y = (h as f64 / 2.0 - r * a.cos())
        .round()
        .clamp(0.0, (h - 1) as f64);
    (x as usize, y as usize)
}

/// Mean intensity (0–255) of the 3×3 pixels around `(x, y)`.
fn intensity(c: &Canvas, x: usize, y: usize) -> f64 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for yy in y.saturating_sub(1)..=(y + 1).min(c.height - 1) {
        for xx in x.saturating_sub(1)..=(x + 1).min(c.width - 1) {
            let p = (yy * c.width + xx) * c.channels;
            sum += c.data[p..p + c.channels]
                .iter()
                .map(|&v| f64::from(v))
                .sum::<f64>()
                / c.channels as f64;
            n += 1.0;
        }
    }
    sum / n
}

/// The angles (degrees clockwise from ahead) where the profile's circle
/// crosses a seam of `view`.
pub fn seam_angles(view: &SurroundView) -> Vec<f64> {
    let mut angles = Vec::new();
    let mut last = None;
    for d in 0..=360 {
        let (x, y) = on_circle(view, f64::from(d));
        let o = owner(view, x, y);
        if let (Some(a), Some(b)) = (last, o) {
            if a != b {
                angles.push(f64::from(d) - 0.5);
            }
        }
        if o.is_some() {
            last = o;
        }
    }
    angles
}

/// The intensity of `canvas` (a view of `view`) along the profile's
/// circle, a value per degree.
pub fn profile(view: &SurroundView, canvas: &Canvas) -> Vec<(f64, f64)> {
    (0..360)
        .map(|d| {
            let (x, y) = on_circle(view, f64::from(d));
            (f64::from(d), intensity(canvas, x, y))
        })
        .collect()
}

/// Runs experiment 4; `config` makes a scenario's simulation.
pub fn run(
    plan: &SeamsPlan,
    config: &dyn Fn(&str) -> Result<rigview_core::sim::SimConfig>,
    tick: &mut dyn FnMut(u64),
) -> Result<SeamsResult> {
    let mut out = SeamsResult::default();
    for scenario in &plan.scenarios {
        let render = Arc::new(SimRender::new(&config(scenario)?)?);
        let view = closed_loop::eval_view(&render)?;
        let frames = frames_of(render.config(), plan.frames);
        let t_last = (frames.saturating_sub(1)) as f64 / render.config().trigger_hz;
        let options = SweepOptions {
            lo: plan.sweep.0,
            hi: plan.sweep.1,
            steps: plan.sweep.2,
            ..Default::default()
        };
        let sweeps = (0..render.cameras().len())
            .map(|cam| {
                let s = truth::sweep(&render, cam, t_last, &options, view.ground_masks().get(cam));
                tick(plan.sweep.2 as u64);
                s
            })
            .collect::<rigview_core::Result<Vec<_>>>()?;
        let angles = seam_angles(&view);
        out.seam_angles.push((scenario.clone(), angles));
        for strategy in EvalStrategy::SEAMS {
            let trace = closed_loop::run_with(
                &render,
                strategy.settings(),
                frames,
                LoopOptions { view: true },
                &mut || tick(1),
            )?;
            let m_fraction = sweeps
                .iter()
                .enumerate()
                .map(|(cam, s)| {
                    s.score_at(trace.settled(cam, plan.tail).exp2())
                        / s.best_score.max(f64::MIN_POSITIVE)
                })
                .collect();
            let canvas = trace
                .canvas
                .clone()
                .context("the closed loop composed no view")?;
            let profile = profile(&view, &canvas);
            out.runs.push(SeamRun {
                scenario: scenario.clone(),
                strategy,
                trace,
                m_fraction,
                profile,
            });
        }
    }
    Ok(out)
}

/// Experiment 6: the last view of each scenario (rows) under each
/// strategy (columns), labelled, written as one PNG.
pub fn write_views(result: &SeamsResult, scenarios: &[String], path: &Path) -> Result<()> {
    register_font()?;
    let tile = result
        .runs
        .iter()
        .find_map(|r| r.trace.canvas.as_ref().map(|c| (c.width, c.height)))
        .context("no view was composed")?;
    let (left, top, gap) = (110usize, 40usize, 6usize);
    let mut strategies: Vec<EvalStrategy> = Vec::new();
    for r in &result.runs {
        if !strategies.contains(&r.strategy) {
            strategies.push(r.strategy);
        }
    }
    let cols = strategies.len();
    let w = left + cols * (tile.0 + gap);
    let h = top + scenarios.len() * (tile.1 + gap);
    let mut buf = vec![255u8; w * h * 3];
    for (row, scenario) in scenarios.iter().enumerate() {
        for (col, strategy) in strategies.iter().enumerate() {
            let Some(c) = result
                .runs
                .iter()
                .find(|r| &r.scenario == scenario && r.strategy == *strategy)
                .and_then(|r| r.trace.canvas.as_ref())
            else {
                continue;
            };
            let (x0, y0) = (left + col * (tile.0 + gap), top + row * (tile.1 + gap));
            for y in 0..c.height.min(tile.1) {
                for x in 0..c.width.min(tile.0) {
                    let p = (y * c.width + x) * c.channels;
                    let q = ((y0 + y) * w + x0 + x) * 3;
                    for k in 0..3 {
                        buf[q + k] = c.data[p + k.min(c.channels - 1)];
                    }
                }
            }
        }
    }
    {
        let root = crate::report::glyphs::Glyphs::new(BitMapBackend::with_buffer(
            &mut buf,
            (w as u32, h as u32),
        ))
        .into_drawing_area();
        let style = TextStyle::from((FONT, 14)).color(&BLACK);
        for (col, strategy) in strategies.iter().enumerate() {
            let x = (left + col * (tile.0 + gap)) as i32;
            root.draw_text(strategy.label(), &style, (x, 12))
                .map_err(|e| anyhow::anyhow!("views: {e}"))?;
        }
        for (row, scenario) in scenarios.iter().enumerate() {
            let y = (top + row * (tile.1 + gap) + tile.1 / 2) as i32;
            root.draw_text(scenario, &style, (6, y))
                .map_err(|e| anyhow::anyhow!("views: {e}"))?;
        }
        root.present().map_err(|e| anyhow::anyhow!("views: {e}"))?;
    }
    let img = image::RgbImage::from_raw(w as u32, h as u32, buf).context("views: buffer size")?;
    crate::report::plot::save_png(&img, path)
        .with_context(|| format!("writing the views {}", path.display()))
}
