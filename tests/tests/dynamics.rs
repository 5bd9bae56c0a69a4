#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Exposure control under changing light, in closed loop through the app's
//! processor on the simulated rig (one frame of latency, a command every
//! frame): no limit cycle where the light is constant, every law settled
//! at the estimator's fixed point, and the fast law's step responses on the
//! `steps` preset (+2, −2, −4, +4 stops at 1, 3, 5 and 7 s).
//!
//! "No limit cycle": over the last [`TAIL`] frames of every run of
//! constant light at least [`MIN_RUN`] frames long, the standard deviation
//! of log2 E stays within [`CYCLE_SD_EV`] (probe frames left out), for
//! every law, simulation and strategy on every preset, with the light held
//! long enough for the slow laws to settle ([`held`]).
//!
//! Run with `--nocapture` for the tables.

use std::sync::Arc;

use rigview_core::eval::dynamics::{constant_runs, std_dev, step_response, ResponseSpec};
use rigview_core::exposure::{ControllerConfig, EstimatorConfig, LawKind, LawParams, Simulation};
use rigview_core::pipeline::{ProcessingSettings, Strategy};
use rigview_core::sim::truth::{self, FixedPointSearch, Sweep, SweepOptions};
use rigview_core::sim::{Event, Script, SimConfig, SimRender, SimRigOptions};

/// Frames of the constant-light tail judged.
const TAIL: usize = 20;
/// Runs of constant light shorter than this are not judged.
const MIN_RUN: usize = 40;
/// The largest standard deviation of log2 E in a settled tail, EV.
const CYCLE_SD_EV: f64 = 0.05;
/// How far (EV) a settled loop may lie from the estimator's fixed point.
const FIXED_POINT_EV: f64 = 0.03;
/// How much longer (s) [`held`] holds the light after each change.
const HOLD_S: f64 = 3.0;
/// Frames of the presets whose light is constant.
const CONSTANT_FRAMES: usize = 120;

/// What a closed loop did.
struct Run {
    cameras: Vec<String>,
    /// log2 of the exposure each frame was taken with, per camera.
    log2_e: Vec<Vec<f64>>,
    /// Whether each frame was a probe frame, per camera.
    probe: Vec<Vec<bool>>,
    /// The light's level per frame (any number that changes with it).
    level: Vec<f64>,
    /// Per camera at the end, the exposure of the darker frame its
    /// estimate read saturated pixels from (scale-and-clip), if it did.
    darker: Vec<Option<f64>>,
    /// Per set, `|log2 r_ij|` of every overlap measured.
    log2_r: Vec<Vec<f64>>,
}

fn settings(
    strategy: Strategy,
    law: LawKind,
    simulation: Simulation,
    probe: bool,
) -> ProcessingSettings {
    let mut controller = ControllerConfig {
        law: LawParams {
            kind: law,
            ..Default::default()
        },
        estimator: EstimatorConfig {
            simulation,
            ..Default::default()
        },
        ..Default::default()
    };
    if !probe {
        controller.probe = None;
    }
    ProcessingSettings {
        strategy,
        controller,
        ..Default::default()
    }
}

fn run(preset: &str, scale: f64, settings: ProcessingSettings) -> Run {
    let config = SimConfig {
        scale,
        ..SimConfig::preset(preset).unwrap()
    };
    run_config(&config, settings)
}

fn run_config(config: &SimConfig, settings: ProcessingSettings) -> Run {
    run_with_latency(config, settings, None)
}

/// [`run_config`] with the simulated cameras' latency (frames between a
/// command and the first frame that shows it; `None`: the configuration's).
fn run_with_latency(config: &SimConfig, settings: ProcessingSettings, latency: Option<u32>) -> Run {
    let frames = if config.script.is_constant() {
        CONSTANT_FRAMES
    } else {
        (config.duration_s * config.trigger_hz).round() as usize
    };
    let render = Arc::new(SimRender::new(config).unwrap());
    let view = rigview_tests::test_view(&render).unwrap();
    let edges = render.rig().neighbours.clone();
    let options = SimRigOptions {
        latency,
        ..Default::default()
    };
    let mut lp = rigview_tests::sim_loop_with(&render, view, settings, &edges, options).unwrap();
    let n = render.cameras().len();
    let mut out = Run {
        cameras: render.cameras().iter().map(|c| c.name.clone()).collect(),
        log2_e: vec![Vec::new(); n],
        probe: vec![Vec::new(); n],
        level: Vec::new(),
        darker: vec![None; n],
        log2_r: Vec::new(),
    };
    for k in 0..frames {
        let step = lp.step().unwrap().unwrap();
        let output = step.output.expect("the simulated rig gives complete sets");
        for c in &output.step.cameras {
            out.log2_e[c.camera].push(c.taken.exposure().log2());
            out.probe[c.camera].push(c.probe_frame);
        }
        out.log2_r.push(
            output
                .pairs
                .iter()
                .filter_map(|p| p.log2_r.map(f64::abs))
                .collect(),
        );
        let l = config.script.levels(k as f64 / config.trigger_hz);
        out.level.push(l.sun + 1e3 * l.sky);
        if k + 1 == frames {
            for c in &output.step.cameras {
                let declipped = c.estimate.as_ref().is_some_and(|e| e.declipped);
                out.darker[c.camera] = declipped
                    .then(|| {
                        let controller = lp.processor_mut().controller_mut();
                        controller.camera_mut(c.camera).ok()?.darker_frame()
                    })
                    .flatten();
            }
        }
    }
    out
}

impl Run {
    /// Per camera, the largest standard deviation of log2 E over the last
    /// [`TAIL`] kept frames of a run of constant light.
    fn tail_sd(&self) -> Vec<f64> {
        let runs = constant_runs(self.level.len(), |k| self.level[k]);
        (0..self.cameras.len())
            .map(|cam| {
                runs.iter()
                    .filter(|(a, b)| b + 1 - a >= MIN_RUN)
                    .map(|&(_, b)| {
                        let tail: Vec<f64> = (b + 1 - TAIL..=b)
                            .filter(|&k| !self.probe[cam][k])
                            .map(|k| self.log2_e[cam][k])
                            .collect();
                        std_dev(&tail)
                    })
                    .fold(0.0, f64::max)
            })
            .collect()
    }

    /// The frames where the light changes.
    fn steps(&self) -> Vec<usize> {
        constant_runs(self.level.len(), |k| self.level[k])
            .iter()
            .skip(1)
            .map(|r| r.0)
            .collect()
    }
}

/// `config` with every change of light held [`HOLD_S`] longer before the
/// next (and at the end), so that the slow laws settle before the light
/// changes again: the presets give the light 1–2 s between changes, and
/// the paper's laws need longer after a step of 4 stops.
fn held(config: &SimConfig) -> SimConfig {
    let mut events = config.script.events.clone();
    let start = |e: &Event| match *e {
        Event::Step { at_s, .. } => at_s,
        Event::Ramp { from_s, .. } => from_s,
        Event::Tunnel { enter_s, .. } => enter_s,
    };
    events.sort_by(|a, b| start(a).total_cmp(&start(b)));
    let mut shift = 0.0;
    for e in &mut events {
        match e {
            Event::Step { at_s, .. } => *at_s += shift,
            Event::Ramp { from_s, to_s, .. } => {
                *from_s += shift;
                *to_s += shift;
            }
            Event::Tunnel {
                enter_s, exit_s, ..
            } => {
                *enter_s += shift;
                shift += HOLD_S;
                *exit_s += shift;
            }
        }
        shift += HOLD_S;
    }
    SimConfig {
        script: Script::new(events),
        duration_s: config.duration_s + shift,
        ..config.clone()
    }
}

/// No limit cycle on any preset, for any law, simulation or strategy (a
/// quarter of the resolution, probes off), with the light held long
/// enough between its changes for the slow laws to settle ([`held`]).
#[test]
fn no_limit_cycle_on_any_preset() {
    let mut failures = Vec::new();
    for (preset, ..) in rigview_core::sim::PRESETS {
        let config = held(&SimConfig {
            scale: 0.25,
            ..SimConfig::preset(preset).unwrap()
        });
        for strategy in [Strategy::Single, Strategy::Multi] {
            for law in [LawKind::Linear, LawKind::Nonlinear, LawKind::Fast] {
                for sim in [Simulation::Gamma, Simulation::ScaleClip] {
                    let r = run_config(&config, settings(strategy, law, sim, false));
                    let sd = r.tail_sd();
                    println!(
                        "{preset:>9} {:>6} {:>9} {:>10}: tail SD {}",
                        strategy.name(),
                        law.name(),
                        sim.name(),
                        sd.iter()
                            .zip(&r.cameras)
                            .map(|(s, c)| format!("{c} {s:.3}"))
                            .collect::<Vec<_>>()
                            .join("  ")
                    );
                    for (s, c) in sd.iter().zip(&r.cameras) {
                        if *s > CYCLE_SD_EV {
                            failures.push(format!(
                                "{preset} {} {} {} {c}: {s:.3} EV",
                                strategy.name(),
                                law.name(),
                                sim.name()
                            ));
                        }
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "limit cycles: {failures:?}");
}

/// The fast law's step responses on the `steps` preset at full resolution,
/// both simulations, with probes off and on (probe frames left out), meet
/// rigview's goals on every camera: settled within 0.1 EV in at most 4
/// frames after ±2 stops and 6 after ±4, overshoot at most 0.3 EV, and a
/// jitter (SD over the window's last 20 frames) of at most 0.02 EV.
///
/// One exception, asserted as such: under scale-and-clip the first step
/// comes 1 s after start-up, while a camera may still be finding its
/// fixed point (ŝ asks for a few hundredths of an EV at a time near it;
/// with probes on, the back camera's first probe is under way when the
/// light steps). The light tracking moves such a camera to where it was
/// in the old light, which is not yet its fixed point, so that step only
/// has to settle within the window, its jitter within the no-cycle bound.
#[test]
fn the_fast_law_settles_after_every_step_of_light() {
    let spec = ResponseSpec::default();
    let mut failures = Vec::new();
    for (sim, probe) in [
        (Simulation::Gamma, false),
        (Simulation::Gamma, true),
        (Simulation::ScaleClip, false),
        (Simulation::ScaleClip, true),
    ] {
        let r = run(
            "steps",
            1.0,
            settings(Strategy::Single, LawKind::Fast, sim, probe),
        );
        let steps = r.steps();
        assert_eq!(steps, vec![20, 60, 100, 140], "the preset's steps moved");
        let what = format!(
            "{}, probes {}",
            sim.name(),
            if probe { "on" } else { "off" }
        );
        println!("{what}: frames to settle / overshoot EV / jitter EV");
        for (cam, name) in r.cameras.iter().enumerate() {
            let mut row = Vec::new();
            for &s in &steps {
                let resp = step_response(&r.log2_e[cam], &r.probe[cam], s, &spec)
                    .expect("the run covers each step's window");
                row.push(format!(
                    "{:>2}/{:.2}/{:.3}",
                    resp.settle_frames, resp.overshoot_ev, resp.jitter_ev
                ));
                let stops = (resp.end - resp.start).abs();
                let frames = if stops > 3.0 { 6 } else { 4 };
                let met = resp.settle_frames <= frames
                    && resp.overshoot_ev <= 0.3
                    && resp.jitter_ev <= 0.02;
                if !met {
                    failures.push(format!(
                        "{what}: {name} step at {s}: {} frames, overshoot {:.2} EV, jitter {:.3} EV",
                        resp.settle_frames, resp.overshoot_ev, resp.jitter_ev
                    ));
                }
            }
            println!("  {name:>6}: {}", row.join("  "));
        }
        for (s, c) in r.tail_sd().iter().zip(&r.cameras) {
            println!("  {c:>6}: tail SD {s:.3} EV");
            if *s > CYCLE_SD_EV {
                failures.push(format!("{what}: {c} cycles, tail SD {s:.3} EV"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// Commanding every frame moves no fixed point: under constant light,
/// every law settles where the estimator says the exposure is right (its
/// γ̂ crosses 1 on the render metered like the loop), within
/// [`FIXED_POINT_EV`], on both constant-light presets at a quarter of the
/// resolution, each camera under its own law, both simulations, probes
/// off. Scale-and-clip's fixed point is found reading the darker frame
/// the loop's estimate read at the end, if it did. The loop's frames are
/// noisy, the fixed points are found on noise-free renders.
#[test]
fn every_law_settles_at_the_estimators_fixed_point() {
    let mut failures = Vec::new();
    for preset in ["reference", "overcast"] {
        let config = SimConfig {
            scale: 0.25,
            ..SimConfig::preset(preset).unwrap()
        };
        let render = SimRender::new(&config).unwrap();
        let view = rigview_tests::test_view(&render).unwrap();
        for (law, sim) in [LawKind::Linear, LawKind::Nonlinear, LawKind::Fast]
            .into_iter()
            .flat_map(|l| [Simulation::Gamma, Simulation::ScaleClip].map(|s| (l, s)))
        {
            let s = settings(Strategy::Single, law, sim, false);
            let estimator = s.controller.estimator.clone();
            let r = run_config(&config, s);
            for (cam, name) in r.cameras.iter().enumerate() {
                let t = &r.log2_e[cam];
                let mean = t[t.len() - TAIL..].iter().sum::<f64>() / TAIL as f64;
                let search = FixedPointSearch {
                    estimator: estimator.clone(),
                    lo: (mean - 1.0).exp2(),
                    hi: (mean + 1.0).exp2(),
                    step_ev: 0.01,
                    darker: r.darker[cam],
                    ..Default::default()
                };
                let found =
                    truth::fixed_points(&render, cam, 0.0, view.ground_masks().get(cam), &search)
                        .unwrap();
                let gap = found
                    .iter()
                    .map(|f| f.exposure.log2() - mean)
                    .min_by(|a, b| a.abs().total_cmp(&b.abs()));
                println!(
                    "{preset:>9} {:>9} {:>10} {name:>6}: settled at {mean:.3}, fixed point {}",
                    law.name(),
                    sim.name(),
                    gap.map_or("none".into(), |g| format!("{:.3} ({g:+.3} EV)", mean + g))
                );
                if !gap.is_some_and(|g| g.abs() <= FIXED_POINT_EV) {
                    failures.push(format!(
                        "{preset} {} {} {name}: {gap:?}",
                        law.name(),
                        sim.name()
                    ));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "away from the fixed point: {failures:?}"
    );
}

/// The median of `v` (0 when empty).
/// The dense sweep of `M` the best is taken from: 2^4 to 2^18 µs.
fn dense_sweep() -> SweepOptions {
    SweepOptions {
        lo: 16.0,
        hi: 262_144.0,
        steps: 141,
        ..Default::default()
    }
}

/// Each camera's dense sweep of `M` at the start, metering the test view's
/// ground.
fn start_sweeps(render: &SimRender) -> Vec<Sweep> {
    let view = rigview_tests::test_view(render).unwrap();
    let options = dense_sweep();
    (0..render.cameras().len())
        .map(|cam| truth::sweep(render, cam, 0.0, &options, view.ground_masks().get(cam)).unwrap())
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    0.5 * (v[(n - 1) / 2] + v[n / 2])
}

/// Every strategy, law and simulation measured the same way, for the
/// tables in docs/exposure-results.md: the step responses on `steps` at
/// full resolution (probes as by default, probe frames left out), and on
/// `reference` at a quarter of the resolution each camera's M at its
/// settled exposure as a fraction of the best of a dense sweep, and the
/// median `|log2 r_ij|` of the last 20 sets. Every combination settles
/// after every step within the 1.5 s window.
#[test]
fn every_strategy_measured_alike() {
    let spec = ResponseSpec::default();
    let reference = SimConfig {
        scale: 0.25,
        ..SimConfig::preset("reference").unwrap()
    };
    let render = SimRender::new(&reference).unwrap();
    let sweeps = start_sweeps(&render);
    let mut failures = Vec::new();
    println!(
        "| strategy | law | simulation | frames to settle, median (max) | overshoot, max | jitter, median (max) | M / best, min | median abs(log2 r_ij) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for strategy in [Strategy::Single, Strategy::Multi] {
        for law in [LawKind::Linear, LawKind::Nonlinear, LawKind::Fast] {
            for sim in [Simulation::Gamma, Simulation::ScaleClip] {
                let what = format!("{} {} {}", strategy.name(), law.name(), sim.name());
                let r = run("steps", 1.0, settings(strategy, law, sim, true));
                let (mut settle, mut overshoot, mut jitter) = (Vec::new(), 0.0f64, Vec::new());
                for cam in 0..r.cameras.len() {
                    for s in r.steps() {
                        let resp = step_response(&r.log2_e[cam], &r.probe[cam], s, &spec)
                            .expect("the run covers each step's window");
                        if resp.settle_frames > spec.window {
                            failures.push(format!(
                                "{what} {}: step at {s} never settled",
                                r.cameras[cam]
                            ));
                        }
                        settle.push(resp.settle_frames as f64);
                        overshoot = overshoot.max(resp.overshoot_ev);
                        jitter.push(resp.jitter_ev);
                    }
                }
                let c = run_config(&reference, settings(strategy, law, sim, true));
                let m = (0..c.cameras.len())
                    .map(|cam| {
                        let e = c.log2_e[cam].last().copied().unwrap_or(0.0).exp2();
                        sweeps[cam].score_at(e) / sweeps[cam].best_score
                    })
                    .fold(f64::INFINITY, f64::min);
                let tail = c.log2_r.len().saturating_sub(TAIL);
                let r_ij = median(c.log2_r[tail..].concat());
                println!(
                    "| {} | {} | {} | {:.0} ({:.0}) | {overshoot:.2} EV | {:.3} ({:.3}) EV | {:.1} % | {r_ij:.2} EV |",
                    strategy.name(),
                    law.name(),
                    sim.name(),
                    median(settle.clone()),
                    settle.iter().copied().fold(0.0, f64::max),
                    median(jitter.clone()),
                    jitter.iter().copied().fold(0.0, f64::max),
                    100.0 * m
                );
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// Under scale-and-clip, a balanced rig comes down after each brighter step
/// of light to where every camera measures at least 90 % of its best `M`
/// (a dense sweep in that light) before the next step ([`held`]). The estimator
/// cannot see under what the brighter light saturates, so each camera
/// meets a hump of `M(E)` coming down; without the balanced cameras'
/// probes (as before they probed: the peer, printed) the rig rested there,
/// 1 EV too bright.
#[test]
fn a_balanced_rig_under_scale_and_clip_comes_down_after_brighter_light() {
    let config = held(&SimConfig {
        scale: 0.25,
        ..SimConfig::preset("steps").unwrap()
    });
    let render = SimRender::new(&config).unwrap();
    let view = rigview_tests::test_view(&render).unwrap();
    let options = dense_sweep();
    let balanced = |probe| {
        let s = settings(
            Strategy::Multi,
            LawKind::Nonlinear,
            Simulation::ScaleClip,
            probe,
        );
        run_config(&config, s)
    };
    let (r, peer) = (balanced(true), balanced(false));
    let mut worst = f64::INFINITY;
    for (k, s) in r.steps().into_iter().enumerate() {
        // Brighter: the level rises at the step.
        if r.level[s] <= r.level[s - 1] {
            continue;
        }
        let before_next = r.steps().get(k + 1).copied().unwrap_or(r.level.len()) - 1;
        let t = before_next as f64 / config.trigger_hz;
        for cam in 0..r.cameras.len() {
            let sweep =
                truth::sweep(&render, cam, t, &options, view.ground_masks().get(cam)).unwrap();
            let at =
                |run: &Run| sweep.score_at(run.log2_e[cam][before_next].exp2()) / sweep.best_score;
            println!(
                "step at frame {s}, {}: M / best {:.1} % (without balanced probes {:.1} %)",
                r.cameras[cam],
                100.0 * at(&r),
                100.0 * at(&peer)
            );
            worst = worst.min(at(&r));
        }
    }
    assert!(
        worst >= 0.9,
        "a camera rested at {:.1} % of its best M",
        100.0 * worst
    );
}

/// The app's default mode (balanced, scale-and-clip, nonlinear law, probes
/// on) at full resolution: one second after each brighter step of `steps`
/// (+2 stops at 1 s, +4 at 7 s), every camera measures at least 85 % of
/// its best `M` (a dense sweep in that light; balancing holds the back
/// camera at about 91 %), and where the rig rested in the same light
/// before (after +4 stops the light is that of 3–5 s) every camera is back
/// within 0.1 EV of that rest. Before every law followed
/// a uniform change of light (the peer, printed: light following off), the
/// front camera stayed white after +4 stops (2^12.0, mean 0.91, `M` a
/// tenth of its rest's) and its neighbours rested on a hump 2.5 EV above
/// their best.
#[test]
fn the_default_rig_at_full_resolution_is_back_a_second_after_a_brighter_step() {
    let config = SimConfig::preset("steps").unwrap();
    let render = SimRender::new(&config).unwrap();
    let view = rigview_tests::test_view(&render).unwrap();
    let options = dense_sweep();
    let defaults = ProcessingSettings::default();
    assert_eq!(defaults.strategy, Strategy::Multi);
    assert_eq!(
        defaults.controller.estimator.simulation,
        Simulation::ScaleClip
    );
    let mut without = defaults.clone();
    without.controller.light = None;
    let (r, peer) = (run_config(&config, defaults), run_config(&config, without));
    let mut judged = 0;
    let mut worst = f64::INFINITY;
    let mut returned = 0;
    let steps = r.steps();
    for &s in &steps {
        if r.level[s] <= r.level[s - 1] {
            continue;
        }
        let k = s + config.trigger_hz.round() as usize;
        // The last frame of an earlier run of the same light.
        let rest = steps
            .iter()
            .map(|&e| e - 1)
            .rfind(|&e| e < s && (r.level[e] / r.level[s] - 1.0).abs() < 1e-9);
        if let Some(e) = rest {
            for cam in 0..r.cameras.len() {
                // The median of the run's last 10 frames, probes left out.
                let then = median(
                    (e - 9..=e)
                        .filter(|&f| !r.probe[cam][f])
                        .map(|f| r.log2_e[cam][f])
                        .collect(),
                );
                let now = r.log2_e[cam][k];
                println!(
                    "{}: 2^{now:.2} 1 s after the step at frame {s}, 2^{then:.2} at rest in the same light (to frame {e})",
                    r.cameras[cam]
                );
                assert!(
                    (now - then).abs() <= 0.1,
                    "{}: 2^{now:.2}, not back at 2^{then:.2}",
                    r.cameras[cam]
                );
            }
            returned += 1;
        }
        let t = k as f64 / config.trigger_hz;
        for cam in 0..r.cameras.len() {
            let sweep =
                truth::sweep(&render, cam, t, &options, view.ground_masks().get(cam)).unwrap();
            let at = |run: &Run| sweep.score_at(run.log2_e[cam][k].exp2()) / sweep.best_score;
            println!(
                "1 s after the step at frame {s}, {}: 2^{:.2}, M / best {:.1} % (without following the light 2^{:.2}, {:.1} %)",
                r.cameras[cam],
                r.log2_e[cam][k],
                100.0 * at(&r),
                peer.log2_e[cam][k],
                100.0 * at(&peer)
            );
            worst = worst.min(at(&r));
            judged += 1;
        }
    }
    assert_eq!(judged, 2 * r.cameras.len(), "two brighter steps");
    assert_eq!(returned, 1, "one brighter step back to an earlier light");
    assert!(
        worst >= 0.85,
        "a camera was at {:.1} % of its best M",
        100.0 * worst
    );
}

/// Under scale-and-clip, a rig that starts far above its best (the
/// reference scene at full resolution from 10 000 µs, as the Aravis fake
/// cameras start) comes
/// down to where every camera measures at least 85 % of its best `M` (a
/// dense sweep), alone and balanced. Coming down, a camera meets a plateau
/// of `M(E)` 2–3 EV above its best, where the estimator, blind under the
/// saturated pixels, sees its fixed point; the start's reacquisition
/// (half the pixels saturated or more,
/// [`ProbeParams::reacquire_start_saturated`]) probes below it with a ladder.
/// The peer without it (printed) must rest on that plateau, or the scene no
/// longer shows the trap. The rig runs with the configuration's latency
/// and with 0 and 2 frames: with no latency the balanced rig came back
/// onto the plateau after its ladder found the way down, until the frame
/// of the rung that measured better was kept for the law going on from it
/// (as on the Aravis fake cameras).
///
/// [`ProbeParams::reacquire_start_saturated`]: rigview_core::exposure::ProbeParams::reacquire_start_saturated
#[test]
fn under_scale_and_clip_a_rig_that_starts_far_too_bright_comes_down_to_its_best() {
    let mut config = SimConfig::preset("reference").unwrap();
    config.start.shutter_us = 10_000.0;
    let render = SimRender::new(&config).unwrap();
    let sweeps = start_sweeps(&render);
    // Each camera's M over its best, from the median exposure of the last
    // 10 frames (probe frames left out).
    let settled = |r: &Run| -> Vec<f64> {
        (0..r.cameras.len())
            .map(|cam| {
                let n = r.log2_e[cam].len();
                let e = median(
                    (n - 10..n)
                        .filter(|&f| !r.probe[cam][f])
                        .map(|f| r.log2_e[cam][f])
                        .collect(),
                );
                sweeps[cam].score_at(e.exp2()) / sweeps[cam].best_score
            })
            .collect()
    };
    let mut peer_worst = f64::INFINITY;
    for strategy in [Strategy::Single, Strategy::Multi] {
        let mut s = ProcessingSettings {
            strategy,
            ..Default::default()
        };
        s.controller.estimator.simulation = Simulation::ScaleClip;
        let mut without = s.clone();
        if let Some(p) = without.controller.probe.as_mut() {
            p.reacquire_start_saturated = 1.0;
        }
        let peer = settled(&run_config(&config, without));
        for latency in [None, Some(0), Some(2)] {
            let r = settled(&run_with_latency(&config, s.clone(), latency));
            for (cam, name) in render.cameras().iter().map(|c| &c.name).enumerate() {
                println!(
                    "{} latency {latency:?} {name}: M / best {:.1} % (without the start's reacquisition {:.1} %)",
                    strategy.name(),
                    100.0 * r[cam],
                    100.0 * peer[cam]
                );
                assert!(
                    r[cam] >= 0.85,
                    "{} latency {latency:?} {name}: at {:.1} % of its best M",
                    strategy.name(),
                    100.0 * r[cam]
                );
            }
        }
        peer_worst = peer.iter().copied().fold(peer_worst, f64::min);
    }
    assert!(
        peer_worst < 0.85,
        "without the start's reacquisition every camera reached 85 % of its best M: the scene no longer shows the plateau"
    );
}
