#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The exposure core in closed loop on the simulated rig under constant
//! light: every camera under its own gradient auto-exposure (nonlinear law,
//! latency 1 frame, surround-view ground masks), for both exposure
//! simulations, against the ground truth of the noise-free renders: the
//! estimator's fixed points (reading, as the loop's does, the frame of the
//! probe it rests after, if any) and the dense-sweep optimum of `M`.
//!
//! Two constant-light presets: `reference` (sun and a building's shadow:
//! sunlit and shadowed ground in the same view) and `overcast` (soft light).
//! Two resolutions: the product's (1288×964, which the metering averages
//! in 4×4 blocks to 322×241) and a quarter of it (322×241, metered 1:1,
//! so that a metered pixel is a sensor pixel and scale-and-clip is exact
//! below saturation). They differ where a block straddles the edge of a
//! saturated area.
//!
//! Run with `--nocapture` for the table of figures.

use std::sync::Arc;

use rigview_core::exposure::{
    ControllerConfig, EstimatorConfig, LawKind, LawParams, ProbeEvent, Simulation,
};
use rigview_core::pipeline::{LockStep, ProcessingSettings, Strategy};
use rigview_core::sim::truth::{self, FixedPoint, FixedPointSearch, Sweep, SweepOptions};
use rigview_core::sim::{Event, Script, SimConfig, SimRender, SimRig};
use rigview_core::surround::SurroundView;

const FRAMES: usize = 100;
/// The frames over which a loop is judged settled.
const TAIL: usize = 20;

/// The product's resolution (1288×964, metered as 322×241 blocks of 4×4)
/// and a quarter of it (322×241, metered 1:1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Res {
    Full,
    Quarter,
}

impl Res {
    fn scale(self) -> f64 {
        match self {
            Res::Full => 1.0,
            Res::Quarter => 0.25,
        }
    }
}

impl std::fmt::Display for Res {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(match self {
            Res::Full => "full",
            Res::Quarter => "1/4",
        })
    }
}

fn render(preset: &str, res: Res) -> Arc<SimRender> {
    let config = SimConfig {
        scale: res.scale(),
        ..SimConfig::preset(preset).unwrap()
    };
    Arc::new(SimRender::new(&config).unwrap())
}

fn view(render: &SimRender) -> SurroundView {
    rigview_tests::test_view(render).unwrap()
}

/// Each camera under its own gradient law (Eq. 4) with `simulation`.
fn config_for(simulation: Simulation) -> ProcessingSettings {
    ProcessingSettings {
        strategy: Strategy::Single,
        controller: ControllerConfig {
            estimator: EstimatorConfig {
                simulation,
                ..Default::default()
            },
            law: LawParams {
                kind: LawKind::Nonlinear,
                ..Default::default()
            },
            ..Default::default()
        },
        ..Default::default()
    }
}

/// What each camera did alone under `simulation`.
fn run(render: &Arc<SimRender>, view: SurroundView, simulation: Simulation) -> Trace {
    run_with(render, view, config_for(simulation), &[])
}

/// What a closed loop did, per camera.
struct Trace {
    /// log2 of the exposure each frame was taken with.
    log2_e: Vec<Vec<f64>>,
    /// The probe events, with the frame they came with.
    probes: Vec<Vec<(usize, ProbeEvent)>>,
    /// The exposure of the probe frame each camera's estimator reads
    /// saturated pixels from at the end, if any.
    probe_frame: Vec<Option<f64>>,
}

impl Trace {
    /// Camera `cam`'s log2 E without the frames of probes it came back
    /// from (a probe is a deliberate one-set excursion; it is counted
    /// apart).
    fn steady(&self, cam: usize) -> Vec<f64> {
        let mut back_from = Vec::new();
        let mut sent = None;
        for (_, e) in &self.probes[cam] {
            match e {
                ProbeEvent::Sent { to, .. } => sent = Some(to.log2()),
                ProbeEvent::Rejected { .. } | ProbeEvent::Abandoned => {
                    back_from.extend(sent.take());
                }
                _ => sent = None,
            }
        }
        self.log2_e[cam]
            .iter()
            .copied()
            .filter(|l| back_from.iter().all(|p| (l - p).abs() > 0.02))
            .collect()
    }

    /// The probe frames camera `cam` sent.
    fn sent(&self, cam: usize) -> Vec<usize> {
        self.probes[cam]
            .iter()
            .filter(|(_, e)| matches!(e, ProbeEvent::Sent { .. }))
            .map(|(f, _)| *f)
            .collect()
    }
}

/// The app's processor on `render` under `settings`, balancing over
/// `edges`, metering the surround view's ground, in lock step.
fn closed_loop(
    render: &Arc<SimRender>,
    view: SurroundView,
    settings: ProcessingSettings,
    edges: &[(usize, usize)],
) -> LockStep<SimRig> {
    rigview_tests::sim_loop(render, view, settings, edges).unwrap()
}

/// Camera `cam`'s controller in `lp`.
fn camera(lp: &mut LockStep<SimRig>, cam: usize) -> &mut rigview_core::exposure::CameraController {
    lp.processor_mut().controller_mut().camera_mut(cam).unwrap()
}

/// [`run`] with any processing settings and neighbour edges.
fn run_with(
    render: &Arc<SimRender>,
    view: SurroundView,
    settings: ProcessingSettings,
    edges: &[(usize, usize)],
) -> Trace {
    let n = render.cameras().len();
    let mut lp = closed_loop(render, view, settings, edges);
    let mut out = Trace {
        log2_e: vec![Vec::new(); n],
        probes: vec![Vec::new(); n],
        probe_frame: vec![None; n],
    };
    for frame in 0..FRAMES {
        let step = lp.step().unwrap().unwrap();
        let output = step.output.expect("the simulated rig gives complete sets");
        for (cam, c) in output.cameras.iter().enumerate() {
            out.log2_e[cam].push(c.taken.exposure().log2());
        }
        for c in &output.step.cameras {
            if let Some(e) = c.probe {
                out.probes[c.camera].push((frame, e));
            }
        }
    }
    for (cam, p) in out.probe_frame.iter_mut().enumerate() {
        *p = camera(&mut lp, cam).probe_frame();
    }
    out
}

/// What one camera did and what the truth says.
#[derive(Debug)]
struct Outcome {
    preset: &'static str,
    scale: Res,
    simulation: Simulation,
    camera: String,
    /// The range of log2 E over the last [`TAIL`] frames.
    lo: f64,
    hi: f64,
    /// The fixed point the loop is at (log2 E) and the jump of γ̂ across it.
    fixed: Option<(f64, f64)>,
    /// The dense-sweep optimum (log2 E).
    best: f64,
    /// M at the fixed point over M at the optimum.
    m_ratio: f64,
    /// The first frame from which the exposure stays in its final band.
    settled_after: usize,
    /// Probe frames sent.
    probes: usize,
}

impl Outcome {
    /// Its last exposures lie within 0.25 EV (the noise moves γ̂ a little
    /// from frame to frame).
    fn converged(&self) -> bool {
        self.hi - self.lo <= 0.25
    }
    fn gap(&self) -> Option<f64> {
        self.fixed.map(|(f, _)| f - self.best)
    }
}

/// The dense sweep of `M` of every camera on the noise-free render at `t`
/// seconds (141 exposures from 16 µs to 2^18 µs, 0.1 EV apart), over its
/// ground mask.
fn sweeps(render: &SimRender, surround: &SurroundView, t: f64) -> Vec<Sweep> {
    let options = SweepOptions {
        lo: 16.0,
        hi: 262_144.0,
        steps: 141,
        ..Default::default()
    };
    (0..render.cameras().len())
        .map(|cam| {
            truth::sweep(render, cam, t, &options, surround.ground_masks().get(cam)).unwrap()
        })
        .collect()
}

/// Both simulations on `preset` at `scale`: each camera alone, probes
/// on (the default). The band a loop ends in leaves out the frames of
/// probes it came back from.
fn evaluate(preset: &'static str, scale: Res) -> Vec<Outcome> {
    let render = render(preset, scale);
    let surround = view(&render);
    let sweeps = sweeps(&render, &surround, 0.0);
    let mut out = Vec::new();
    for simulation in [Simulation::ScaleClip, Simulation::Gamma] {
        let trace = run(&render, view(&render), simulation);
        for (cam, sweep) in sweeps.iter().enumerate() {
            let t = trace.steady(cam);
            let tail = &t[t.len().saturating_sub(TAIL)..];
            let lo = tail.iter().copied().fold(f64::MAX, f64::min);
            let hi = tail.iter().copied().fold(f64::MIN, f64::max);
            let mean = tail.iter().sum::<f64>() / TAIL as f64;
            let search = FixedPointSearch {
                estimator: config_for(simulation).controller.estimator,
                lo: (lo - 1.0).exp2(),
                hi: (hi + 1.0).exp2(),
                step_ev: 0.05,
                darker: trace.probe_frame[cam],
                ..Default::default()
            };
            let found: Vec<FixedPoint> =
                truth::fixed_points(&render, cam, 0.0, surround.ground_masks().get(cam), &search)
                    .unwrap();
            // A converged loop is at the fixed point nearest its exposure; a
            // circling loop at one inside the band it circles.
            let fixed = found
                .iter()
                .map(|f| (f.exposure.log2(), f.jump))
                .filter(|(f, _)| *f >= lo - 0.15 && *f <= hi + 0.15)
                .min_by(|a, b| (a.0 - mean).abs().total_cmp(&(b.0 - mean).abs()));
            let settled_after = t
                .iter()
                .rposition(|l| *l < lo - 0.05 || *l > hi + 0.05)
                .map_or(0, |k| k + 1);
            out.push(Outcome {
                preset,
                scale,
                simulation,
                camera: render.cameras()[cam].name.clone(),
                lo,
                hi,
                fixed,
                best: sweep.best.log2(),
                m_ratio: fixed.map_or(0.0, |(f, _)| sweep.score_at(f.exp2()) / sweep.best_score),
                settled_after,
                probes: trace.sent(cam).len(),
            });
        }
    }
    out
}

fn print(outcomes: &[Outcome]) {
    println!(
        "{:>5} {:>9} {:>10} {:>6} | {:>13} | {:>15} | {:>6} {:>7} | {:>7} | {:>7} | {:>6}",
        "scale",
        "preset",
        "simulation",
        "camera",
        "loop log2 E",
        "fixed (jump γ̂)",
        "sweep",
        "gap EV",
        "M/M_max",
        "settled",
        "probes"
    );
    for o in outcomes {
        let (f, j) = o.fixed.unwrap_or((f64::NAN, f64::NAN));
        println!(
            "{:>5} {:>9} {:>10} {:>6} | {:>6.2}–{:<6.2} | {f:>7.3} ({j:>5.2}) | {:>6.2} {:>+7.2} | {:>7.3} | {:>7} | {:>6}",
            o.scale,
            o.preset,
            o.simulation.name(),
            o.camera,
            o.lo,
            o.hi,
            o.best,
            o.gap().unwrap_or(f64::NAN),
            o.m_ratio,
            if o.converged() {
                format!("{} fr", o.settled_after)
            } else {
                "cycle".into()
            },
            o.probes
        );
    }
}

/// Every camera ends at a fixed point of its estimator: converged onto it
/// (its last 20 exposures, probe frames left out, within 0.25 EV, their
/// middle within 0.15 EV of the fixed point) or, where γ̂ jumps across 1
/// there, circling it in a band of at most 1 EV. No scale-and-clip camera
/// circles (one that did probes, and reads the probe's frame) and every
/// scale-and-clip fixed point keeps at least 99 % of the best `M` of the
/// dense sweep. The γ-mapping's keep at least 90 % at a quarter and 85 % at
/// full resolution, where its fixed points lie up to 2.1 EV below the
/// optimum. Both resolutions, both constant-light presets.
#[test]
fn constant_light_settles_every_camera_at_its_fixed_point() {
    let outcomes: Vec<Outcome> = [Res::Full, Res::Quarter]
        .into_iter()
        .flat_map(|scale| {
            ["reference", "overcast"]
                .into_iter()
                .flat_map(move |p| evaluate(p, scale))
        })
        .collect();
    print(&outcomes);
    for scale in [Res::Full, Res::Quarter] {
        for s in [Simulation::ScaleClip, Simulation::Gamma] {
            let gaps: Vec<f64> = outcomes
                .iter()
                .filter(|o| o.simulation == s && o.scale == scale)
                .filter_map(Outcome::gap)
                .collect();
            let worst = gaps.iter().copied().fold(0.0, |a: f64, g| a.max(g.abs()));
            let mean = gaps.iter().sum::<f64>() / gaps.len() as f64;
            println!(
                "scale {scale}, {}: fixed point − sweep optimum: mean {mean:+.2} EV, largest |gap| {worst:.2} EV",
                s.name()
            );
        }
    }
    for o in &outcomes {
        let what = format!(
            "scale {} {} {} {}",
            o.scale,
            o.preset,
            o.simulation.name(),
            o.camera
        );
        let (f, jump) = o.fixed.unwrap_or_else(|| {
            panic!(
                "{what}: no fixed point of the estimator near {:.2}–{:.2}",
                o.lo, o.hi
            )
        });
        if o.converged() {
            let mean = 0.5 * (o.lo + o.hi);
            assert!(
                (mean - f).abs() <= 0.15,
                "{what}: settled at {mean:.3}, fixed point {f:.3}"
            );
        } else {
            assert!(
                jump > 0.2,
                "{what}: circles {:.2}–{:.2} around a fixed point {f:.3} that γ̂ crosses smoothly",
                o.lo,
                o.hi
            );
            assert!(
                o.hi - o.lo <= 1.0,
                "{what}: circles {:.2}–{:.2}",
                o.lo,
                o.hi
            );
        }
        let floor = match (o.simulation, o.scale == Res::Full) {
            (Simulation::ScaleClip, _) => 0.99,
            (Simulation::Gamma, false) => 0.9,
            (Simulation::Gamma, true) => 0.85,
        };
        assert!(
            o.m_ratio >= floor,
            "{what}: M at the fixed point is {:.3} of the best",
            o.m_ratio
        );
        if o.simulation == Simulation::ScaleClip {
            assert!(
                o.converged(),
                "{what}: circles {:.2}–{:.2} instead of settling",
                o.lo,
                o.hi
            );
        }
    }
}

/// The range of the last [`TAIL`] values (of all, when fewer).
fn tail_band(t: &[f64]) -> f64 {
    let tail = &t[t.len().saturating_sub(TAIL)..];
    tail.iter().copied().fold(f64::MIN, f64::max) - tail.iter().copied().fold(f64::MAX, f64::min)
}

/// The app's default mode (nonlinear law, balancing over the rig's
/// overlaps) under `simulation` on the reference preset at `scale`:
/// balancing adds no cycle of its own. Every camera's last exposures lie in
/// a band at most 0.15 EV wider than the same camera's alone. Under the
/// γ-mapping balanced cameras never probe; under scale-and-clip (the
/// default) they probe darker too, and the frames of probes they came back
/// from are left out, alone and balanced.
fn check_balancing_adds_no_cycle(scale: Res, simulation: Simulation) {
    let render = render("reference", scale);
    let alone = run(&render, view(&render), simulation);
    let mut settings = ProcessingSettings::default();
    settings.controller.estimator.simulation = simulation;
    let balanced = run_with(&render, view(&render), settings, &render.rig().neighbours);
    if simulation == Simulation::Gamma {
        assert!(
            balanced.probes.iter().all(Vec::is_empty),
            "a balanced camera probed: {:?}",
            balanced.probes
        );
    }
    let n = render.cameras().len();
    let alone: Vec<Vec<f64>> = (0..n).map(|c| alone.steady(c)).collect();
    let balanced: Vec<Vec<f64>> = (0..n).map(|c| balanced.steady(c)).collect();
    for (cam, (a, b)) in alone.iter().zip(&balanced).enumerate() {
        let name = &render.cameras()[cam].name;
        let (ba, bb) = (tail_band(a), tail_band(b));
        let sim = simulation.name();
        println!(
            "{sim}, {name}: last {TAIL} exposures within {ba:.2} EV alone, {bb:.2} EV balanced"
        );
        assert!(
            bb <= ba + 0.15,
            "{name}: balanced band {bb:.2} EV against {ba:.2} EV alone: {:.2?}",
            &b[b.len() - TAIL..]
        );
    }
}

/// [`check_balancing_adds_no_cycle`] at a quarter of the resolution, under
/// both exposure simulations. Without the damping of the balanced step
/// (`balance::Damping`) the front camera, on the sunlit mat about 2 EV
/// darker than its neighbours want, circles 0.6 EV every two steps around
/// the balanced fixed point.
#[test]
fn balancing_adds_no_cycle_in_the_default_mode() {
    for simulation in [Simulation::Gamma, Simulation::ScaleClip] {
        check_balancing_adds_no_cycle(Res::Quarter, simulation);
    }
}

/// [`check_balancing_adds_no_cycle`] at full resolution. There the front
/// camera's M curve has two humps of nearly equal height (γ ≈ 1.53 and the
/// anchors' end, 1.90); γ̂ used to jump between them as its exposure
/// crossed 2^10.04, and the balanced target with it, so that the camera
/// crept up and dropped 0.1 EV about once a second. The estimator now
/// takes such a plateau's weighted middle (`EstimatorConfig::plateau`),
/// which moves continuously (`tests/realtime_loop.rs` checks the same in
/// the app's threaded pipeline).
#[test]
fn balancing_adds_no_cycle_in_the_default_mode_at_full_resolution() {
    check_balancing_adds_no_cycle(Res::Full, Simulation::default());
}

/// Probing darker (`exposure::probe`, on by default for a camera under its
/// own law) takes a camera past the fixed points that saturation hides a
/// better one behind. On the reference preset, without probes, the loop
/// coming down from 2000 µs stops at the first fixed point it meets: at a
/// quarter of the resolution the front camera's (2^9.83, +1.44 EV from
/// the dense-sweep optimum, 96 % of its `M`), at full resolution the left
/// camera's (2^11.33, +0.73 EV, 95 %). With probes every camera more than
/// 0.5 EV from the optimum without them ends within 0.2 EV of it. No
/// camera ends with less `M` than without probes, every camera stops
/// probing (at most three probe frames, none in the last 20 frames), and
/// every probe frame is at most one anchor step (`1/1.9`) darker than the
/// exposure it left (a ladder's rung: than the rung before).
#[test]
fn probing_darker_takes_a_camera_to_the_best_fixed_point() {
    for scale in [Res::Quarter, Res::Full] {
        let render = render("reference", scale);
        let sweeps = sweeps(&render, &view(&render), 0.0);
        let with = run_with(
            &render,
            view(&render),
            config_for(Simulation::ScaleClip),
            &[],
        );
        let without = run_with(
            &render,
            view(&render),
            {
                let mut s = config_for(Simulation::ScaleClip);
                s.controller.probe = None;
                s
            },
            &[],
        );
        assert!(without.probes.iter().all(Vec::is_empty));
        let mut helped = 0;
        for (cam, name) in render.cameras().iter().map(|c| &c.name).enumerate() {
            let sweep = &sweeps[cam];
            let mid = |t: &[f64]| t[t.len() - TAIL..].iter().sum::<f64>() / TAIL as f64;
            let steady = with.steady(cam);
            let (a, b) = (mid(&steady), mid(&without.log2_e[cam]));
            let (ma, mb) = (
                sweep.score_at(a.exp2()) / sweep.best_score,
                sweep.score_at(b.exp2()) / sweep.best_score,
            );
            let best = sweep.best.log2();
            let sent = with.sent(cam);
            println!(
                "scale {scale} {name:>6}: with probes {a:.2} (gap {:+.2} EV, M {ma:.3} of the best), without {b:.2} (gap {:+.2} EV, M {mb:.3}); probes sent at frames {sent:?}; events {:?}",
                a - best,
                b - best,
                with.probes[cam].iter().map(|(_, e)| e).collect::<Vec<_>>()
            );
            assert!(
                tail_band(&steady) <= 0.25,
                "{name}: not settled with probes"
            );
            assert!(
                ma >= mb - 0.001,
                "{name}: probing lost M ({ma:.4} < {mb:.4})"
            );
            assert!(sent.len() <= 3, "{name}: {} probes", sent.len());
            assert!(
                sent.iter().all(|&f| f < FRAMES - TAIL),
                "{name}: probed in the last {TAIL} frames: {sent:?}"
            );
            // A ladder's rungs (a reacquisition: here the start, with half
            // the front camera's pixels saturated) each go one step darker
            // than the rung before, from the same exposure.
            let mut last: Option<(f64, f64)> = None;
            for (_, e) in &with.probes[cam] {
                if let ProbeEvent::Sent { from, to } = *e {
                    let above = match last {
                        Some((home, rung)) if (home / from - 1.0).abs() < 1e-12 => rung,
                        _ => from,
                    };
                    assert!(
                        (above / to).log2() <= 1.9f64.log2() + 1e-9,
                        "{name}: probe {from} → {to}, one step below {above}"
                    );
                    last = Some((from, to));
                }
            }
            if b - best > 0.5 {
                helped += 1;
                assert!(
                    (a - best).abs() <= 0.2,
                    "scale {scale} {name}: with probes at {a:.2}, the optimum at {best:.2}"
                );
            }
        }
        assert!(
            helped > 0,
            "scale {scale}: no camera was more than 0.5 EV above the optimum without probes"
        );
    }
}

/// A camera that leaves its own law (here: balancing is switched on) forgets
/// its probes: the operator's camera card no longer shows one, and the
/// estimator no longer reads the frame of one.
#[test]
fn a_camera_that_leaves_its_own_law_forgets_its_probe() {
    let render = render("reference", Res::Quarter);
    let n = render.cameras().len();
    let mut lp = closed_loop(
        &render,
        view(&render),
        config_for(Simulation::ScaleClip),
        &render.rig().neighbours,
    );
    for _ in 0..30 {
        lp.step().unwrap();
    }
    let front = camera(&mut lp, 0).last_probe();
    assert!(
        matches!(
            front,
            Some(ProbeEvent::Taken { .. } | ProbeEvent::Rejected { .. })
        ),
        "{front:?}"
    );
    let kept = (0..n)
        .filter(|&cam| camera(&mut lp, cam).probe_frame().is_some())
        .count();
    assert!(kept > 0, "no camera kept the frame of a probe it rejected");
    let balanced = ProcessingSettings {
        strategy: Strategy::Multi,
        ..config_for(Simulation::ScaleClip)
    };
    lp.set_settings(balanced).unwrap();
    for _ in 0..3 {
        lp.step().unwrap();
    }
    for cam in 0..n {
        let c = camera(&mut lp, cam);
        assert_eq!(c.last_probe(), None);
        assert_eq!(c.probe_frame(), None);
    }
}

/// The acceptance figure: the scale-and-clip fixed point every camera
/// settles on lies within 0.2 EV of the dense-sweep optimum, on both
/// constant-light presets, at full resolution and at a quarter of it.
///
/// Holding saturated pixels cannot get there where `M` is flat near its
/// maximum: a few per cent of error in the predicted darkening moves the
/// fixed point across the plateau. At full resolution the back camera's
/// `M` is flat to 0.1 % from 2^12.25 to 2^12.6; holding the saturated
/// sunlit ground over-predicted darkening by 9 % at the smallest anchor
/// (the ground lies only a little above saturation, and its edges soften
/// as it comes back), and the camera settled 0.25 EV below the optimum.
/// At a quarter, the right camera's saturated surfaces are textured, the
/// assumed recovery under-credited them by 5.6 %, and it settled 0.22 EV
/// above. Two overcast cameras at full resolution circled a jump of ŝ
/// 0.34 EV below the optimum, never settled, and so never probed.
///
/// A camera now probes when it circles as well as when it settles, and its
/// estimator reads the frame of a probe that measured no better
/// (`exposure::Darker`): every saturated pixel that frame shows below
/// saturation is known, and the predictions at the darkening anchors match
/// the renders to a few tenths of a per cent.
///
/// Run with `--nocapture` to see the gaps.
#[test]
fn scale_clip_fixed_points_lie_within_0_2_ev_of_the_sweep_optimum() {
    let outcomes: Vec<Outcome> = [Res::Full, Res::Quarter]
        .into_iter()
        .flat_map(|scale| {
            ["reference", "overcast"]
                .into_iter()
                .flat_map(move |p| evaluate(p, scale))
        })
        .filter(|o| o.simulation == Simulation::ScaleClip)
        .collect();
    print(&outcomes);
    let missed: Vec<String> = outcomes
        .iter()
        .filter_map(|o| {
            let gap = o.gap().unwrap_or(f64::INFINITY);
            (gap.abs() > 0.2 || !o.converged()).then(|| {
                format!(
                    "scale {} {} {}: gap {gap:+.2} EV, band {:.2}–{:.2}",
                    o.scale, o.preset, o.camera, o.lo, o.hi
                )
            })
        })
        .collect();
    assert!(missed.is_empty(), "{missed:?}");
}

/// The light steps up one stop while the cameras rest on the frames of
/// their probes: those frames no longer match (their pixels below
/// saturation are half as bright as the current ones, scaled), so once the
/// step shows a camera keeps a probe frame only from after the step, or
/// one from before it moved with the light it followed (its exposure
/// halved: the frame shows the scene as a frame at half the exposure
/// would now), and every camera settles again
/// with at least 99 % of the best `M` of the dense sweep under the new
/// light. (Where `M` is flat, where it settles may differ from before by
/// more than the step: the right camera's `M` varies by 0.5 % from 2^10.5
/// to 2^11.2 at the old light, and it comes down from above.)
#[test]
fn a_change_of_light_retires_the_probe_frame() {
    const STEP_AT: u64 = 60;
    let mut config = SimConfig {
        scale: Res::Quarter.scale(),
        ..SimConfig::preset("reference").unwrap()
    };
    config.script = Script::new(vec![Event::Step {
        at_s: STEP_AT as f64 / config.trigger_hz,
        stops: 1.0,
        light: Default::default(),
    }]);
    config.duration_s = 10.0;
    let render = Arc::new(SimRender::new(&config).unwrap());
    let n = render.cameras().len();
    let mut lp = closed_loop(
        &render,
        view(&render),
        config_for(Simulation::ScaleClip),
        &[],
    );
    let mut log2_e = vec![Vec::new(); n];
    // Whether each frame was a probe's (left out of the bands: a probe is
    // darker on purpose).
    let mut probe = vec![Vec::new(); n];
    // The exposures each camera took frames with after the step.
    let mut after: Vec<Vec<f64>> = vec![Vec::new(); n];
    let mut before: Vec<Vec<f64>> = vec![Vec::new(); n];
    let mut kept_before = 0;
    for frame in 0..3 * STEP_AT {
        let step = lp.step().unwrap().unwrap();
        let output = step.output.expect("the simulated rig gives complete sets");
        for (cam, c) in output.cameras.iter().enumerate() {
            let e = c.taken.exposure();
            log2_e[cam].push(e.log2());
            probe[cam].push(c.probe_frame);
            if frame >= STEP_AT {
                after[cam].push(e);
            } else {
                before[cam].push(e);
            }
        }
        for (cam, taken_after) in after.iter().enumerate() {
            let kept = camera(&mut lp, cam).probe_frame();
            if frame == STEP_AT - 1 {
                kept_before += usize::from(kept.is_some());
            }
            // Once the step has shown on one frame the camera reacted to,
            // a kept probe frame must come from after it.
            if frame >= STEP_AT + 3 {
                if let Some(e) = kept {
                    // The followed change is measured, so a moved frame
                    // lies within a few hundredths of an EV of half its
                    // exposure.
                    let moved = before[cam]
                        .iter()
                        .any(|b| (2.0 * e / b).log2().abs() < 0.05);
                    assert!(
                        taken_after.iter().any(|a| (a / e - 1.0).abs() < 1e-9) || moved,
                        "camera {cam}, frame {frame}: still keeps the probe frame at {e:.1} from before the step, not moved with the light"
                    );
                }
            }
        }
    }
    assert!(
        kept_before > 0,
        "no camera rested on a probe frame before the step"
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let surround = view(&render);
    let (old_light, new_light) = (
        sweeps(&render, &surround, 0.0),
        sweeps(&render, &surround, 8.0),
    );
    let k = STEP_AT as usize;
    for (cam, (l, p)) in log2_e.iter().zip(&probe).enumerate() {
        let unprobed = |r: std::ops::Range<usize>| -> Vec<f64> {
            r.filter(|&f| !p[f]).map(|f| l[f]).collect()
        };
        let (before, end) = (unprobed(k - TAIL..k), unprobed(l.len() - TAIL..l.len()));
        for (what, tail, sweep) in [
            ("before", &before[..], &old_light[cam]),
            ("after", &end[..], &new_light[cam]),
        ] {
            let ratio = sweep.score_at(mean(tail).exp2()) / sweep.best_score;
            println!(
                "camera {cam} {what} the step: log2 E {:.3} (sweep optimum {:.2}), M {ratio:.4} of the best, band {:.3} EV",
                mean(tail),
                sweep.best.log2(),
                tail_band(tail)
            );
            assert!(
                ratio >= 0.99 && tail_band(tail) <= 0.25,
                "camera {cam} {what} the step: M {ratio:.4} of the best, band {:.3} EV",
                tail_band(tail)
            );
        }
    }
}

/// The reference front camera's index.
const FRONT: usize = 0;

/// The reference preset at full resolution and the surround view the
/// window builds by default (its ground masks are what the window meters).
fn reference_as_the_window_meters_it() -> (Arc<SimRender>, SurroundView) {
    use rigview_core::surround::{CanvasSpec, SurroundOptions};
    let render = render("reference", Res::Full);
    assert_eq!(render.cameras()[FRONT].name, "front");
    let view = SurroundView::build(
        render.rig(),
        &CanvasSpec::default(),
        &SurroundOptions::default(),
    )
    .unwrap();
    (render, view)
}

/// Scale-and-clip on the reference front camera at full resolution, metered
/// over the view's ground as the window meters it: its `M` curve has one
/// hump near the current exposure and one at the darkest anchor (more
/// than a third of the ground saturated; the darkest anchor gains as more
/// of it saturates), and their heights cross at about 2^9.99 µs. The
/// highest hump alone jumped there from ŝ ≈ 1.0 to the darkest anchor
/// (0.93 EV within 0.01 EV of exposure), and in the default mode with
/// balancing the camera climbed to the jump and fell back, a saw-tooth of
/// 0.09–0.16 EV. The estimate now moves continuously from one hump to the
/// other (`Polynomial::argmax_within`): over the scan it still goes from
/// about "stay" to more than 0.5 EV darker, over about 0.1 EV of exposure
/// instead of at once, with no step of 0.01 EV moving it by more than
/// 0.5 EV (0.34 EV measured; 0.95 EV with the highest hump alone).
#[test]
fn scale_clip_moves_continuously_where_two_humps_cross() {
    use rigview_core::exposure::{Estimator, Meter, MeteringConfig};
    let (render, view) = reference_as_the_window_meters_it();
    let meter = Meter::new(MeteringConfig::default()).unwrap();
    let mut est = Estimator::new(EstimatorConfig {
        simulation: Simulation::ScaleClip,
        ..Default::default()
    })
    .unwrap();
    let log2_s: Vec<f64> = (0..=40)
        .map(|k| {
            let l = 9.8 + 0.01 * f64::from(k);
            let m = truth::meter_noise_free(
                &render,
                FRONT,
                0.0,
                l.exp2(),
                &meter,
                view.ground_masks().get(FRONT),
            )
            .unwrap();
            est.estimate(&m).unwrap().x_hat.log2()
        })
        .collect();
    let largest = log2_s
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    let (first, last) = (log2_s[0], log2_s[log2_s.len() - 1]);
    println!(
        "front, 2^9.80 to 2^10.20 µs: log2 ŝ from {first:+.3} to {last:+.3}, largest step {largest:.3} EV"
    );
    assert!(first > -0.2 && last < -0.5, "{log2_s:.3?}");
    assert!(largest <= 0.5, "{log2_s:.3?}");
}

/// The default mode (balanced over the rig's overlaps, nonlinear law)
/// under scale-and-clip on the reference preset at full resolution, in
/// lock step, metering the ground as the window does: the front camera,
/// which its neighbours hold brighter than its own law wants, rests where
/// its estimate moves from the hump near its exposure to the darkest
/// anchor ([`scale_clip_moves_continuously_where_two_humps_cross`]). With
/// the highest hump alone it climbed to the jump and fell back, 0.09 EV
/// from end to end; now its last 100 of 220 exposures lie within 0.06 EV
/// (0.04 EV measured). It is not yet still: the estimate falls by 0.8 EV
/// within about 0.1 EV of exposure there, steeper than the balancing's
/// damping (κ down to 1/16) settles (`docs/exposure-results.md`). (The
/// left camera is not judged: it moves from one balanced rest to another
/// late in the run.)
#[test]
fn balanced_scale_clip_no_longer_saw_tooths_the_front_camera_at_full_resolution() {
    let (render, view) = reference_as_the_window_meters_it();
    let mut settings = ProcessingSettings::default();
    settings.controller.estimator.simulation = Simulation::ScaleClip;
    assert!(settings.controller.balancing.is_some());
    let mut lp = closed_loop(&render, view, settings, &render.rig().neighbours);
    let mut log2_e = Vec::new();
    for _ in 0..220 {
        let step = lp.step().unwrap().unwrap();
        let output = step.output.expect("the simulated rig gives complete sets");
        log2_e.push(output.cameras[FRONT].taken.exposure().log2());
    }
    let tail = &log2_e[log2_e.len() - 100..];
    let band = tail.iter().copied().fold(f64::MIN, f64::max)
        - tail.iter().copied().fold(f64::MAX, f64::min);
    println!(
        "front: last 100 exposures within {band:.3} EV, at 2^{:.3}",
        tail[tail.len() - 1]
    );
    assert!(band <= 0.06, "{tail:.3?}");
}
