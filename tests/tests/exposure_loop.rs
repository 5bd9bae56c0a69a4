//! The exposure core in closed loop on synthetic linear-camera scenes:
//! direction, fixed points and settling of every update law, for both
//! exposure simulations. Run with `--nocapture` to see the figures.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use rigview_core::exposure::{
    ControlMode, ControllerConfig, EstimatorConfig, LawKind, LawParams, Simulation,
};
use rigview_core::synth::{HdrScene, Illumination, LinearCamera};
use rigview_tests::{fixed_point, m_at, run_single, sweep_argmax};

fn scene() -> HdrScene {
    HdrScene::generate(640, 480, 7, &Illumination::Uniform(1.0)).unwrap()
}

fn estimator(simulation: Simulation) -> EstimatorConfig {
    EstimatorConfig {
        simulation,
        ..Default::default()
    }
}

/// The estimator's fixed point against the dense-sweep optimum of M.
#[test]
fn fixed_points_against_the_dense_sweep() {
    let (scene, cam) = (scene(), LinearCamera::default());
    // 161 log-spaced levels, 0.05 EV apart.
    let (best, m_best) = sweep_argmax(&scene, &cam, 10.0, 18.0, 161).unwrap();
    for sim in [Simulation::Gamma, Simulation::ScaleClip] {
        let fp = fixed_point(&scene, &cam, &estimator(sim), 10.5, 17.5).unwrap();
        let ratio = m_at(&scene, &cam, fp).unwrap() / m_best;
        println!(
            "{:>10}: fixed point log2 E = {fp:.3}, sweep optimum {best:.3}, gap {:+.3} EV, M(fixed)/M(max) = {ratio:.3}",
            sim.name(),
            fp - best
        );
        match sim {
            Simulation::ScaleClip => {
                assert!((fp - best).abs() <= 0.15, "scale-clip gap {} EV", fp - best);
                assert!(ratio > 0.97);
            }
            Simulation::Gamma => {
                // The γ-mapping's fixed point sits darker than the optimum on
                // a linear camera (about 1 EV), but well inside the useful range.
                assert!(fp < best, "γ fixed point {fp} not darker than {best}");
                assert!(best - fp < 1.5);
                assert!(ratio > 0.5);
            }
        }
    }
}

fn config(kind: LawKind, sim: Simulation) -> ControllerConfig {
    ControllerConfig {
        mode: ControlMode::Gradient,
        estimator: estimator(sim),
        law: LawParams {
            kind,
            ..Default::default()
        },
        balancing: None,
        ..Default::default()
    }
}

fn check_settles(name: &str, config: ControllerConfig, fp: f64, scene: &HdrScene) -> usize {
    let cam = LinearCamera::default();
    let mut worst_frames = 0;
    for start in [fp - 2.0, fp + 2.0] {
        let traj = run_single(scene, &cam, config.clone(), start, 1, 60).unwrap();
        // The first change moves toward the fixed point.
        let first_move = traj
            .iter()
            .find(|&&l| (l - start).abs() > 1e-6)
            .copied()
            .unwrap_or(start);
        assert!(
            (first_move - fp).abs() < (start - fp).abs(),
            "{name}: from {start:.2} the first move went to {first_move:.2}, away from {fp:.2}"
        );
        let last = *traj.last().unwrap();
        let tail = &traj[traj.len() - 10..];
        let spread = tail.iter().cloned().fold(f64::MIN, f64::max)
            - tail.iter().cloned().fold(f64::MAX, f64::min);
        assert!(
            (last - fp).abs() < 0.12 && spread < 0.05,
            "{name}: from {start:.2} ended at {last:.3} (spread {spread:.3}), fixed point {fp:.3}: {traj:.2?}"
        );
        let settled = traj
            .iter()
            .position(|&l| (l - fp).abs() < 0.15)
            .unwrap_or(traj.len());
        let overshoot = traj
            .iter()
            .map(|&l| if start < fp { l - fp } else { fp - l })
            .fold(0.0, f64::max);
        println!(
            "{name:>28}: from {:+.0} EV within 0.15 EV after {settled:2} frames, overshoot {overshoot:.3} EV",
            start - fp
        );
        worst_frames = worst_frames.max(settled);
    }
    worst_frames
}

#[test]
fn every_law_moves_toward_the_fixed_point_and_settles() {
    let scene = scene();
    let cam = LinearCamera::default();
    for sim in [Simulation::Gamma, Simulation::ScaleClip] {
        let fp = fixed_point(&scene, &cam, &estimator(sim), 10.5, 17.5).unwrap();
        let mut frames = Vec::new();
        for kind in [LawKind::Linear, LawKind::Nonlinear, LawKind::Fast] {
            let name = format!("{} / {}", sim.name(), kind.name());
            frames.push(check_settles(&name, config(kind, sim), fp, &scene));
        }
        let pid = ControllerConfig {
            mode: ControlMode::Pid,
            ..config(LawKind::Nonlinear, sim)
        };
        check_settles(&format!("{} / pid", sim.name()), pid, fp, &scene);
        // The fast law needs no more frames than the paper's laws.
        assert!(
            frames[2] <= frames[0].min(frames[1]),
            "{}: fast law took {} frames, linear {}, nonlinear {}",
            sim.name(),
            frames[2],
            frames[0],
            frames[1]
        );
    }
}

/// Two illumination levels 100× apart (sunlit ground beside a shadow): γ̂
/// crosses 1 upwards once per level, so there are two stable fixed points.
/// The controller settles on the one whose basin holds its start; the
/// figures say which.
#[test]
fn two_illumination_levels_have_two_fixed_points() {
    let scene = HdrScene::generate(
        640,
        480,
        7,
        &Illumination::Split {
            left: 1.0,
            right: 100.0,
            boundary: 0.5,
        },
    )
    .unwrap();
    let cam = LinearCamera::default();
    // The γ-mapping's fixed points, as the loop below runs it.
    let mut est = rigview_core::exposure::Estimator::new(EstimatorConfig {
        simulation: Simulation::Gamma,
        ..EstimatorConfig::default()
    })
    .unwrap();
    let grid: Vec<f64> = (0..=130).map(|k| 4.0 + 0.1 * f64::from(k)).collect();
    let g: Vec<f64> = grid
        .iter()
        .map(|&l| {
            est.estimate(&rigview_tests::meter_at(&scene, &cam, l.exp2()).unwrap())
                .unwrap()
                .gamma_hat
        })
        .collect();
    let crossings: Vec<f64> = (1..grid.len())
        .filter(|&k| g[k - 1] < 1.0 && g[k] >= 1.0)
        .map(|k| grid[k - 1] + 0.1 * (1.0 - g[k - 1]) / (g[k] - g[k - 1]))
        .collect();
    for c in &crossings {
        println!(
            "two levels: stable fixed point at log2 E = {c:.2}, M = {:.0}",
            m_at(&scene, &cam, *c).unwrap()
        );
    }
    assert_eq!(crossings.len(), 2, "{crossings:?}");
    for start in [5.0, 9.5, 16.0] {
        let traj = run_single(
            &scene,
            &cam,
            config(LawKind::Nonlinear, Simulation::Gamma),
            start,
            1,
            80,
        )
        .unwrap();
        let last = *traj.last().unwrap();
        let nearest = crossings
            .iter()
            .cloned()
            .min_by(|a, b| (a - last).abs().total_cmp(&(b - last).abs()))
            .unwrap();
        println!("two levels: from log2 E = {start:.1} the controller settles at {last:.2}");
        assert!(
            (last - nearest).abs() < 0.25,
            "settled at {last}, fixed points {crossings:?}"
        );
    }
}
