//! Experiment 2, convergence after steps of light (the paper's Fig. 9).
//!
//! The scene's light is held for `lead_s`, then steps by +1, −1, +2, −2,
//! +4 and −4 stops, `hold_s` apart (so the light is 1, 2, 1, 4, 1, 16, 1
//! times the scene's), with one frame of actuation latency and a command
//! every frame. Each strategy runs the whole sequence from the simulation's
//! start setting; every camera's response to every step is measured with
//! [`rigview_core::eval::dynamics::step_response`]: frames to settle within
//! 0.1 EV of the exposure 30 frames after the step, overshoot past it, and
//! the standard deviation of log2 E over the last 20 of those frames.

use std::sync::Arc;

use anyhow::{Context, Result};
use rigview_core::eval::dynamics::{constant_runs, step_response, ResponseSpec, StepResponse};
use rigview_core::sim::script::LightPart;
use rigview_core::sim::{Event, Script, SimConfig, SimRender};

use super::closed_loop::{self, Trace};
use super::strategy::EvalStrategy;

/// The steps of light, stops, in order.
pub const STEPS: [f64; 6] = [1.0, -1.0, 2.0, -2.0, 4.0, -4.0];

/// The fast law's goals (the issue on control under changing light).
pub mod goals {
    /// Frames to settle after ±2 stops.
    pub const SETTLE_2: usize = 4;
    /// Frames to settle after ±4 stops.
    pub const SETTLE_4: usize = 6;
    /// Overshoot, EV.
    pub const OVERSHOOT_EV: f64 = 0.3;
    /// Jitter, EV.
    pub const JITTER_EV: f64 = 0.02;
}

/// The timing of experiment 2.
#[derive(Clone, Debug, PartialEq)]
pub struct StepsPlan {
    /// Seconds of constant light before the first step.
    pub lead_s: f64,
    /// Seconds between steps (and after the last).
    pub hold_s: f64,
}

impl StepsPlan {
    /// The scenario: `base` with its light replaced by the steps.
    pub fn config(&self, base: &SimConfig) -> SimConfig {
        let events = STEPS
            .iter()
            .enumerate()
            .map(|(k, &stops)| Event::Step {
                at_s: self.lead_s + self.hold_s * k as f64,
                stops,
                light: LightPart::All,
            })
            .collect();
        SimConfig {
            script: Script::new(events),
            duration_s: self.lead_s + self.hold_s * STEPS.len() as f64,
            latency_frames: 1,
            ..base.clone()
        }
    }

    /// Frames of one run.
    pub fn frames(&self, config: &SimConfig) -> usize {
        (config.duration_s * config.trigger_hz).round() as usize
    }
}

/// One camera's response to one step under one strategy.
#[derive(Clone, Debug, PartialEq)]
pub struct StepRow {
    /// The strategy.
    pub strategy: EvalStrategy,
    /// The camera's name.
    pub camera: String,
    /// The step of light, stops.
    pub stops: f64,
    /// The response.
    pub response: StepResponse,
}

impl StepRow {
    /// The CSV header.
    pub const HEADER: &'static str = "strategy,camera,step_stops,step_frame,start_log2_e,end_log2_e,settle_frames,overshoot_ev,jitter_ev";

    /// A CSV line.
    pub fn csv(&self) -> String {
        let r = &self.response;
        format!(
            "{},{},{:+},{},{:.4},{:.4},{},{:.4},{:.5}",
            self.strategy.key(),
            self.camera,
            self.stops,
            r.step,
            r.start,
            r.end,
            r.settle_frames,
            r.overshoot_ev,
            r.jitter_ev
        )
    }

    /// Whether the fast law's goals hold for this response: `None` for a
    /// step they say nothing about (±1 stop).
    pub fn meets_goals(&self) -> Option<bool> {
        let settle = match self.stops.abs().round() as u32 {
            2 => goals::SETTLE_2,
            4 => goals::SETTLE_4,
            _ => return None,
        };
        let r = &self.response;
        Some(
            r.settle_frames <= settle
                && r.overshoot_ev <= goals::OVERSHOOT_EV
                && r.jitter_ev <= goals::JITTER_EV,
        )
    }
}

/// What experiment 2 measured.
#[derive(Clone, Debug, Default)]
pub struct StepsResult {
    /// Per strategy, its trace.
    pub traces: Vec<(EvalStrategy, Trace)>,
    /// Every response.
    pub rows: Vec<StepRow>,
    /// The frames of the steps.
    pub step_frames: Vec<usize>,
    /// The trigger rate.
    pub trigger_hz: f64,
    /// The cameras' names.
    pub cameras: Vec<String>,
}

/// Runs experiment 2 on `render` (built from [`StepsPlan::config`]);
/// `tick` is called after each set.
pub fn run(render: &Arc<SimRender>, tick: &mut dyn FnMut()) -> Result<StepsResult> {
    let config = render.config();
    let frames = (config.duration_s * config.trigger_hz).round() as usize;
    let level = |k: usize| {
        let l = config.script.levels(k as f64 / config.trigger_hz);
        l.sun + 1e3 * l.sky
    };
    let step_frames: Vec<usize> = constant_runs(frames, level)
        .iter()
        .skip(1)
        .map(|r| r.0)
        .collect();
    if step_frames.len() != STEPS.len() {
        anyhow::bail!(
            "the steps scenario changes its light {} times, expected {}",
            step_frames.len(),
            STEPS.len()
        );
    }
    let cameras: Vec<String> = render.cameras().iter().map(|c| c.name.clone()).collect();
    let spec = ResponseSpec::default();
    let mut out = StepsResult {
        step_frames: step_frames.clone(),
        trigger_hz: config.trigger_hz,
        cameras: cameras.clone(),
        ..Default::default()
    };
    for strategy in EvalStrategy::STEPS {
        let trace = closed_loop::run(render, strategy.settings(), frames, tick)?;
        for (k, name) in cameras.iter().enumerate() {
            for (&frame, &stops) in step_frames.iter().zip(&STEPS) {
                let response = step_response(&trace.log2_e[k], &trace.probe[k], frame, &spec)
                    .with_context(|| {
                        format!("the run ends before the response to the step at frame {frame}")
                    })?;
                out.rows.push(StepRow {
                    strategy,
                    camera: name.clone(),
                    stops,
                    response,
                });
            }
        }
        out.traces.push((strategy, trace));
    }
    Ok(out)
}

impl StepsResult {
    /// The responses of `strategy` to steps of `stops`.
    pub fn responses(&self, strategy: EvalStrategy, stops: f64) -> Vec<&StepResponse> {
        self.rows
            .iter()
            .filter(|r| r.strategy == strategy && (r.stops - stops).abs() < 1e-9)
            .map(|r| &r.response)
            .collect()
    }

    /// The fast law's responses that meet its goals, and those judged.
    pub fn goals_met(&self) -> (usize, usize) {
        let judged: Vec<bool> = self
            .rows
            .iter()
            .filter(|r| r.strategy == EvalStrategy::Fast)
            .filter_map(StepRow::meets_goals)
            .collect();
        (judged.iter().filter(|&&m| m).count(), judged.len())
    }
}
