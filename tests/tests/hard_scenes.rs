#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The scenes where mean-intensity auto-exposure should lose to the
//! gradient laws (issue 30, section 5): the presets `sky`, `tunnel-exit`,
//! `snow` and `lawn`, simulated reproductions of what the paper and the
//! real lawn sequence describe.
//!
//! For each scene: the dense sweep of M over exposure on the noise-free
//! renders (metered as the controller meters: the surround view's ground,
//! or whole frames for `sky`, whose sky no ground mask contains), and the
//! closed loops of `rigview eval` (`rigview::eval::closed_loop`, 120 sets
//! from the preset's start, the median of the last 20) of mean-intensity
//! AE and of the gradient laws under both exposure simulations, probes on
//! as the app runs them, each as M where it settles over the sweep's best.
//! Rendered at a quarter of the rig's resolution (322×241); the tunnel
//! exit's front camera also at the rig's resolution.
//!
//! Downstream, over the same tails without their probe sets
//! ([`rigview::eval::downstream`]): the
//! corners each strategy keeps tracked from frame to frame, and those
//! matched across the overlaps.
//!
//! Run with `--nocapture` for the table of figures.

use std::sync::Arc;

use rigview::eval::closed_loop;
use rigview::eval::downstream::{self, Downstream, FeatureMeter};
use rigview::eval::strategy::EvalStrategy;
use rigview_core::pipeline::MeterRoi;
use rigview_core::sim::config::LAWN_START_US;
use rigview_core::sim::truth::{self, Sweep, SweepOptions};
use rigview_core::sim::{SimConfig, SimRender};

const SCALE: f64 = 0.25;
const FRAMES: usize = 120;
const TAIL: usize = 20;

/// The strategies measured: mean AE, then each gradient law under the
/// γ-mapping and under scale-and-clip.
const STRATEGIES: [EvalStrategy; 7] = [
    EvalStrategy::Mean,
    EvalStrategy::Nonlinear,
    EvalStrategy::Fast,
    EvalStrategy::Multi,
    EvalStrategy::NonlinearSc,
    EvalStrategy::FastSc,
    EvalStrategy::MultiSc,
];

/// A preset, or a simulation file of `assets/sim` (`courtyard.sim.yaml`).
fn config(scene: &str) -> SimConfig {
    if scene.ends_with(".sim.yaml") {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/sim");
        SimConfig::load(&dir.join(scene)).unwrap()
    } else {
        SimConfig::preset(scene).unwrap()
    }
}

fn render(preset: &str) -> Arc<SimRender> {
    let config = SimConfig {
        scale: SCALE,
        ..config(preset)
    };
    Arc::new(SimRender::new(&config).unwrap())
}

/// Which pixels a scene is metered by.
fn roi(preset: &str) -> MeterRoi {
    if preset == "sky" {
        MeterRoi::Full
    } else {
        MeterRoi::Ground
    }
}

/// Each camera's sweep of M (0.1 EV steps over 2⁴–2²⁰ µs).
fn sweeps(render: &SimRender, roi: MeterRoi) -> Vec<Sweep> {
    let view = rigview_tests::test_view(render).unwrap();
    (0..render.cameras().len())
        .map(|cam| {
            let mask = match roi {
                MeterRoi::Ground => view.ground_masks().get(cam),
                MeterRoi::Full => None,
            };
            truth::sweep(render, cam, 0.0, &SweepOptions::default(), mask).unwrap()
        })
        .collect()
}

/// Per strategy, per camera: M where the strategy settles over the best M;
/// and the downstream measures over the tail.
struct Measured {
    sweeps: Vec<Sweep>,
    fractions: Vec<(EvalStrategy, Vec<f64>)>,
    /// Per strategy, per camera: the first set from which every later
    /// set (probe sets left out) keeps 90 % or more of the best M (`None`:
    /// the tail falls below).
    reach: Vec<(EvalStrategy, Vec<Option<usize>>)>,
    /// Per strategy: corners tracked frame to frame, summed over the
    /// cameras (mean per set), and inliers across the overlaps, summed
    /// over the overlaps (mean per set).
    features: Vec<(EvalStrategy, f64, f64)>,
}

impl Measured {
    fn of(&self, s: EvalStrategy) -> &[f64] {
        &self.fractions.iter().find(|f| f.0 == s).unwrap().1
    }
}

fn measure(preset: &str) -> Measured {
    let render = render(preset);
    let roi = roi(preset);
    let sweeps = sweeps(&render, roi);
    let mut meter = FeatureMeter::new(render.rig(), (2048, 270)).unwrap();
    let mut features = Vec::new();
    let mut reach = Vec::new();
    let fractions = STRATEGIES
        .iter()
        .map(|&s| {
            let mut settings = s.settings_as_run();
            settings.roi = roi;
            let mut measured = Vec::new();
            let trace = closed_loop::run_observed(
                closed_loop::sim_source(&render, FRAMES).unwrap(),
                render.rig(),
                settings,
                Default::default(),
                &mut meter.from_set(FRAMES - TAIL, &mut measured),
                &mut || {},
            )
            .unwrap();
            let measured = downstream::at_rest(measured, &trace, FRAMES - TAIL);
            let d = Downstream::of(&measured);
            let tracked = (0..sweeps.len()).map(|c| d.tracked(c)).sum();
            let inliers = d.overlaps("", s, &[]).iter().map(|o| o.inliers).sum();
            features.push((s, tracked, inliers));
            let f = sweeps
                .iter()
                .enumerate()
                .map(|(cam, sw)| sw.score_at(trace.settled(cam, TAIL).exp2()) / sw.best_score)
                .collect();
            let r = sweeps
                .iter()
                .enumerate()
                .map(|(cam, sw)| {
                    let good = |i: usize| {
                        trace.probe[cam][i]
                            || sw.score_at(trace.log2_e[cam][i].exp2()) >= 0.9 * sw.best_score
                    };
                    let n = trace.log2_e[cam].len();
                    let from = (0..n).rev().take_while(|&i| good(i)).last()?;
                    Some(from)
                })
                .collect();
            reach.push((s, r));
            (s, f)
        })
        .collect();
    let m = Measured {
        sweeps,
        fractions,
        reach,
        features,
    };
    println!("{preset}: settled M / best M per camera (best at log2 E µs)");
    let best: Vec<String> = m
        .sweeps
        .iter()
        .map(|s| format!("{:.1}", s.best.log2()))
        .collect();
    println!("  {:<42} {}", "best log2 E", best.join("  "));
    for ((s, f), (_, r)) in m.fractions.iter().zip(&m.reach) {
        let f: Vec<String> = f.iter().map(|v| format!("{:5.1}%", 100.0 * v)).collect();
        let r: Vec<String> = r
            .iter()
            .map(|v| v.map_or("-".into(), |v| v.to_string()))
            .collect();
        println!(
            "  {:<42} {}   at 90 % from set {}",
            s.label(),
            f.join(" "),
            r.join(" ")
        );
    }
    println!("  downstream: corners tracked frame to frame (all cameras), matched across the overlaps (all overlaps)");
    for (s, t, i) in &m.features {
        println!("  {:<42} {t:6.0} {i:6.0}", s.label());
    }
    m
}

/// The camera where mean AE keeps the least of the best M, and its
/// fraction.
fn worst_of_mean(m: &Measured) -> (usize, f64) {
    m.of(EvalStrategy::Mean)
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap()
}

/// Mean AE settles measurably away from the best M on at least one camera
/// (below 90 %), and the gradient laws under scale-and-clip keep more of
/// it there. Returns what was measured.
fn baseline_fails(preset: &str) -> Measured {
    let m = measure(preset);
    let (cam, mean) = worst_of_mean(&m);
    assert!(
        mean < 0.9,
        "{preset}: mean AE keeps {:.1} % of the best M on its worst camera",
        100.0 * mean
    );
    for s in [EvalStrategy::NonlinearSc, EvalStrategy::FastSc] {
        let f = m.of(s)[cam];
        assert!(
            f > mean + 0.05,
            "{preset}, camera {cam}: {} keeps {:.1} %, mean AE {:.1} %",
            s.label(),
            100.0 * f,
            100.0 * mean
        );
    }
    m
}

/// The downstream measure: every gradient law under scale-and-clip keeps
/// at least `factor` times the corners mean AE keeps tracked from frame to
/// frame (all cameras).
fn tracks_more(m: &Measured, preset: &str, factor: f64) {
    let tracked = |s: EvalStrategy| m.features.iter().find(|f| f.0 == s).unwrap().1;
    let mean = tracked(EvalStrategy::Mean);
    for s in [
        EvalStrategy::NonlinearSc,
        EvalStrategy::FastSc,
        EvalStrategy::MultiSc,
    ] {
        assert!(
            tracked(s) >= factor * mean,
            "{preset}: {} tracks {:.0} corners, mean AE {mean:.0}",
            s.label(),
            tracked(s)
        );
    }
}

/// Issue 30's goal for `M`: every gradient law under scale-and-clip
/// settles at 90 % or more of the best `M` on every camera, and keeps at
/// least as much as mean AE over the rig (the mean of the cameras'
/// fractions). Balanced (multi) too: snow's back camera keeps 91.5 % with
/// balancing limited to 8 % of a camera's own `M` (88 % at 10 %, 81 %
/// unlimited; 5 % gave 94.5 % here but a limit cycle at full resolution,
/// docs/exposure-results.md).
fn gradient_laws_keep_90(m: &Measured, preset: &str) {
    keep_at_least(
        m,
        preset,
        &[
            (EvalStrategy::NonlinearSc, 0.9),
            (EvalStrategy::FastSc, 0.9),
            (EvalStrategy::MultiSc, 0.9),
        ],
    );
}

/// Each strategy keeps its `floor` of the best `M` on every camera, and
/// at least as much as mean AE over the rig.
fn keep_at_least(m: &Measured, preset: &str, floors: &[(EvalStrategy, f64)]) {
    let rig = |s: EvalStrategy| m.of(s).iter().sum::<f64>() / m.of(s).len() as f64;
    for &(s, floor) in floors {
        for (cam, f) in m.of(s).iter().enumerate() {
            assert!(
                *f >= floor,
                "{preset}, camera {cam}: {} keeps {:.1} % of the best M",
                s.label(),
                100.0 * f
            );
        }
        assert!(
            rig(s) >= rig(EvalStrategy::Mean),
            "{preset}: {} keeps {:.1} % over the rig, mean AE {:.1} %",
            s.label(),
            100.0 * rig(s),
            100.0 * rig(EvalStrategy::Mean)
        );
    }
}

#[test]
fn under_a_bright_sky_mean_ae_darkens_the_ground() {
    let m = baseline_fails("sky");
    gradient_laws_keep_90(&m, "sky");
    // 341–366 corners against 225.
    tracks_more(&m, "sky", 1.2);
}

#[test]
fn at_a_tunnel_exit_mean_ae_follows_the_bright_exit() {
    let m = baseline_fails("tunnel-exit");
    gradient_laws_keep_90(&m, "tunnel-exit");
}

#[test]
fn on_snow_mean_ae_darkens_the_textured_objects() {
    let m = baseline_fails("snow");
    // Balanced, the back camera kept 81 % before the balancing's guard of
    // its own M (`balance::guard_m`); 88 % with it.
    gradient_laws_keep_90(&m, "snow");
    // 182–186 corners against 137.
    tracks_more(&m, "snow", 1.2);
}

/// The lawn: on every camera M rises with exposure over the 5 EV up to its
/// best (as the real sequence's M rose through brackets of 1 to 32 ms),
/// the best is not bought with large saturated areas (under 15 % of the
/// metered ground clipped, the mean below 0.7), and the preset starts about
/// 4 EV (3 to 5) below each camera's best.
#[test]
fn on_the_lawn_m_rises_across_a_wide_range() {
    let render = render("lawn");
    let sweeps = sweeps(&render, MeterRoi::Ground);
    let view = rigview_tests::test_view(&render).unwrap();
    let meter =
        rigview_core::exposure::Meter::new(rigview_core::exposure::MeteringConfig::default())
            .unwrap();
    for (cam, s) in sweeps.iter().enumerate() {
        let kbest = (0..s.scores.len())
            .max_by(|&a, &b| s.scores[a].total_cmp(&s.scores[b]))
            .unwrap();
        // 5 EV at 0.1 EV a step.
        let from = kbest
            .checked_sub(50)
            .expect("the best is 5 EV above the sweep's start");
        let rises = s.scores[from..=kbest]
            .windows(2)
            .all(|w| w[1] >= w[0] * 0.995);
        let ratio = s.scores[kbest] / s.scores[from];
        let metered = truth::meter_noise_free(
            &render,
            cam,
            0.0,
            s.best,
            &meter,
            view.ground_masks().get(cam),
        )
        .unwrap();
        let stats = metered.stats();
        let start_ev = (s.best / LAWN_START_US).log2();
        println!(
            "lawn camera {cam}: best at log2 E {:.1}, M {:.0} 5 EV below, {:.0} at the best, \
             mean {:.2}, saturated {:.1} % at the best; start {start_ev:.1} EV below",
            s.best.log2(),
            s.scores[from],
            s.scores[kbest],
            stats.mean,
            100.0 * stats.saturated_fraction
        );
        assert!(
            rises,
            "lawn camera {cam}: M falls somewhere in the 5 EV below its best"
        );
        assert!(ratio > 4.0, "lawn camera {cam}: M rises only ×{ratio:.2}");
        assert!(
            stats.saturated_fraction < 0.15 && stats.mean < 0.7,
            "lawn camera {cam}: {stats:?}"
        );
        assert!(
            (3.0..=5.0).contains(&start_ev),
            "lawn camera {cam}: the start is {start_ev:.2} EV below the best"
        );
    }
}

/// The lawn in closed loop, for the record (`--nocapture`): where each
/// strategy settles from 4 EV below.
#[test]
fn the_lawn_in_closed_loop() {
    let m = measure("lawn");
    // Scale-and-clip's fast law reaches the best of the sweep's M nearly
    // everywhere (M flat near its best).
    for (cam, f) in m.of(EvalStrategy::FastSc).iter().enumerate() {
        assert!(*f > 0.8, "lawn camera {cam}: fast/scale-clip {f:.3}");
    }
    gradient_laws_keep_90(&m, "lawn");
}

/// At the rig's resolution the tunnel exit's front camera, each law alone,
/// comes to rest on a low hump of `M(E)` with the exit resolved and most of
/// its ground black (about two thirds of the metered pixels dark); the
/// walls' texture, four times the `M`, lies 5.4 EV up, beyond what its
/// estimate sees. Its brighter probe (a ladder of 1.5 EV rungs) finds it:
/// the camera ends at 90 % or more of the best `M`, where without probes
/// it keeps under half; under PID too, which probes only brighter, and
/// balanced (multi), whose neighbours balancing's guard no longer lets
/// pull it over the hump.
#[test]
fn at_the_rigs_resolution_the_tunnel_exits_front_camera_probes_brighter() {
    let config = SimConfig::preset("tunnel-exit").unwrap();
    let render = Arc::new(SimRender::new(&config).unwrap());
    let view = rigview_tests::test_view(&render).unwrap();
    let front = 0;
    let options = SweepOptions {
        lo: 2f64.powi(9),
        hi: 2f64.powi(17),
        steps: 81,
        ..Default::default()
    };
    let sweep = truth::sweep(
        &render,
        front,
        0.0,
        &options,
        view.ground_masks().get(front),
    )
    .unwrap();
    let frames = 50;
    let run = |settings| {
        let trace = closed_loop::run(&render, settings, frames, &mut || {}).unwrap();
        let e = trace.settled(front, 10);
        (e, sweep.score_at(e.exp2()) / sweep.best_score)
    };
    // The nonlinear law, PID (which probes only brighter) and multi.
    for s in [
        EvalStrategy::NonlinearSc,
        EvalStrategy::PidSc,
        EvalStrategy::MultiSc,
    ] {
        let (e_probed, probed) = run(s.settings_as_run());
        let (e_alone, alone) = run(s.settings());
        println!(
            "tunnel-exit, {}, front camera at 1288×964 (best at 2^{:.2} µs): probes on 2^{e_probed:.2} ({:.1} %), off 2^{e_alone:.2} ({:.1} %)",
            s.label(),
            sweep.best.log2(),
            100.0 * probed,
            100.0 * alone
        );
        assert!(
            probed >= 0.9,
            "{}: with probes {:.1} %",
            s.label(),
            100.0 * probed
        );
        assert!(
            alone < 0.5,
            "{}: without probes {:.1} %",
            s.label(),
            100.0 * alone
        );
    }
}

/// Real scenes: the radiance of four real HDR panoramas (`assets/hdri`,
/// CC0) around the simulated rig and its sensor, each started about 4 EV
/// from its best (the courtyard and the car park above, the forest and the
/// sunrise below). On every one mean AE keeps under 90 % of the best M on
/// some camera, and the laws alone under scale-and-clip keep 90 % or more
/// on every camera. Balanced, the courtyard's front camera (a sunlit yard,
/// its neighbours in the shade under a roof) keeps 88 %: its neighbours
/// pull it brighter, and balancing's guard lets it lose up to 8 % of what
/// its estimate predicts (50 % before the guard held pulls brighter).
#[test]
fn on_real_panoramas_the_gradient_laws_keep_the_best_m() {
    for (scene, from_below) in [
        ("courtyard.sim.yaml", false),
        ("forest.sim.yaml", true),
        ("sunrise.sim.yaml", true),
        ("city.sim.yaml", false),
    ] {
        let m = baseline_fails(scene);
        keep_at_least(
            &m,
            scene,
            &[
                (EvalStrategy::NonlinearSc, 0.9),
                (EvalStrategy::FastSc, 0.9),
                (EvalStrategy::MultiSc, 0.85),
            ],
        );
        // From 4 EV below, each camera's own law keeps 90 % of the best
        // from the tenth set on (the fast law 4–6; the nonlinear law 6–7,
        // 14–20 before it searched beyond its anchors and went on from the
        // commands in flight), balanced cameras from the twelfth (6–11).
        // From 4 EV above, mostly saturated frames step on from the
        // commands in flight too: the nonlinear law by set 12 (6–11; 8–23
        // before, 6–15 while a frame that predated a command in flight
        // could undo it), the fast law by set 14 (6–13; 10–62 before, 6–20
        // while a creep darker under held saturation waited to settle
        // before it probed).
        let limits: &[(EvalStrategy, usize)] = if from_below {
            &[
                (EvalStrategy::FastSc, 10),
                (EvalStrategy::NonlinearSc, 10),
                (EvalStrategy::MultiSc, 12),
            ]
        } else {
            &[(EvalStrategy::FastSc, 14), (EvalStrategy::NonlinearSc, 12)]
        };
        for &(s, sets) in limits {
            let reach = &m.reach.iter().find(|r| r.0 == s).unwrap().1;
            for (cam, r) in reach.iter().enumerate() {
                assert!(
                    r.is_some_and(|r| r <= sets),
                    "{scene}, camera {cam}: {} keeps 90 % from set {r:?}",
                    s.label()
                );
            }
        }
    }
}

/// A rig that starts with every frame saturated (the courtyard from 4 EV
/// above) still follows a uniform change of light later: the light
/// tracking takes its reference from the first frames at rest that have
/// pixels in range, not from the saturated first frame (which measured
/// nothing and, kept, held the front and left cameras 3 EV too dark for
/// 2 s after −4 stops).
#[test]
fn after_a_saturated_start_the_light_is_still_followed() {
    let (script, duration_s) = rigview_core::sim::config::script_preset("steps").unwrap();
    let config = SimConfig {
        scale: SCALE,
        script,
        duration_s,
        ..config("courtyard.sim.yaml")
    };
    let render = Arc::new(SimRender::new(&config).unwrap());
    // −4 stops at 5 s: set 100.
    for s in [EvalStrategy::NonlinearSc, EvalStrategy::MultiSc] {
        let trace = closed_loop::run(&render, s.settings_as_run(), 110, &mut || {}).unwrap();
        for (cam, e) in trace.log2_e.iter().enumerate() {
            let moved = e[108] - e[98];
            println!(
                "{}, camera {cam}: {moved:+.2} EV from set 98 to 108",
                s.label()
            );
            assert!(
                (3.5..=4.5).contains(&moved),
                "{}, camera {cam}: {moved:+.2} EV after −4 stops",
                s.label()
            );
        }
    }
}

/// A probe is a glance its camera returns from, so a balanced camera does
/// not follow a neighbour's: on the car park and the courtyard from 4 EV
/// above (balanced, scale-and-clip), at every probe that starts after the
/// first 20 sets, each neighbour that is not probing itself stays within
/// 0.1 EV of where it was over the three frames from the probe's first
/// (its commands sent while the probe was in flight, and while it
/// showed). The car park's front and back cameras stepped 0.16 and
/// 0.18 EV down with the left camera's probe while balancing took the
/// probe in flight for where the left camera would rest.
#[test]
fn a_neighbours_probe_does_not_move_a_balanced_camera() {
    for scene in ["city.sim.yaml", "courtyard.sim.yaml"] {
        let render = render(scene);
        let mut settings = EvalStrategy::MultiSc.settings_as_run();
        settings.roi = MeterRoi::Ground;
        let trace = closed_loop::run(&render, settings, FRAMES, &mut || {}).unwrap();
        let (e, probe) = (&trace.log2_e, &trace.probe);
        let (mut seen, mut worst) = (0, 0.0f64);
        for k in 0..e.len() {
            let neighbours: Vec<usize> = trace
                .pairs
                .iter()
                .filter_map(|&(i, j)| (i == k).then_some(j).or((j == k).then_some(i)))
                .collect();
            for i in 20..FRAMES - 2 {
                if !probe[k][i] || probe[k][i - 1] {
                    continue;
                }
                for &j in &neighbours {
                    if (i - 1..=i + 2).any(|t| probe[j][t]) {
                        continue;
                    }
                    let moved = (i..=i + 2)
                        .map(|t| (e[j][t] - e[j][i - 1]).abs())
                        .fold(0.0, f64::max);
                    println!(
                        "{scene}: camera {k} probes at set {i}, camera {j} moves {moved:.3} EV"
                    );
                    seen += 1;
                    worst = worst.max(moved);
                }
            }
        }
        assert!(
            seen > 0,
            "{scene}: no probe after set 20 beside a resting neighbour"
        );
        assert!(
            worst <= 0.1,
            "{scene}: a neighbour moved {worst:.3} EV with a probe"
        );
    }
}
