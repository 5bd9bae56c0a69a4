#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The probe of a settled camera (`exposure::probe`): darker under
//! saturation, brighter where most of the frame is dark; frame by frame
//! on hand-made inputs.

use rigview_core::exposure::probe::{ProbeInput, Prober};
use rigview_core::exposure::{ProbeEvent, ProbeParams};

/// A frame taken at `taken` with `M = m`, 30 % saturated, whose law wants
/// `desired`.
fn frame(taken: f64, m: f64, desired: f64) -> ProbeInput {
    ProbeInput {
        taken,
        m,
        saturated: 0.3,
        dark: 0.0,
        desired,
        wants_frame: false,
        read_probe_frame: false,
        rungs: 1,
        balanced: false,
        relight: false,
        brighter_only: false,
    }
}

/// A settled frame at `e`.
fn settled(e: f64, m: f64) -> ProbeInput {
    frame(e, m, e * 1.01)
}

fn params() -> ProbeParams {
    ProbeParams {
        settle_frames: 2,
        cooldown_frames: 3,
        ..ProbeParams::default()
    }
}

/// Settles at 1000 for the two frames [`params`] asks and returns the
/// probe's exposure.
fn settle_and_probe(p: &mut Prober, params: &ProbeParams, m: f64) -> f64 {
    let (d, e) = p.step(params, settled(1000.0, m));
    assert_eq!(e, None, "probed after one settled frame");
    assert!(
        (d - 1010.0).abs() < 1e-9,
        "the law's step is passed through"
    );
    let (d, e) = p.step(params, settled(1000.0, m));
    match e {
        Some(ProbeEvent::Sent { from, to }) => {
            assert!((from - 1000.0).abs() < 1e-9);
            assert!((to - 1000.0 / 1.9).abs() < 1e-6, "probe at {to}");
            assert!((d - to).abs() < 1e-9);
            to
        }
        other => panic!("expected a probe, got {other:?}"),
    }
}

/// Feeds a probe ladder sent from 1000 (first rung at `first`) frames that
/// each measure `m`, until it goes home (asserted at 1000); the rungs sent
/// and the last rung's exposure.
fn every_rung_measures(p: &mut Prober, params: &ProbeParams, first: f64, m: f64) -> (u32, f64) {
    let (mut d, mut sent) = (first, 1);
    loop {
        let (next, e) = p.step(params, frame(d, m, d));
        match e {
            Some(ProbeEvent::Sent { .. }) => {
                sent += 1;
                d = next;
            }
            Some(ProbeEvent::Rejected { .. }) => {
                assert!((next - 1000.0).abs() < 1e-9, "back to {next}, not home");
                return (sent, d);
            }
            other => panic!("unexpected {other:?}"),
        }
    }
}

#[test]
fn a_probe_that_measures_better_is_taken_and_the_law_goes_on_from_it() {
    let params = params();
    let mut p = Prober::default();
    let probe = settle_and_probe(&mut p, &params, 100.0);
    // 1 % better than the settled M: taken; the law's wish passes through.
    let (d, e) = p.step(&params, frame(probe, 101.0, probe * 1.1));
    assert!(matches!(e, Some(ProbeEvent::Taken { gain }) if (gain - 0.01).abs() < 1e-9));
    assert!((d - probe * 1.1).abs() < 1e-9);
    // From there it watches again: a new settled place probes again.
    let (_, e) = p.step(&params, settled(600.0, 102.0));
    assert_eq!(e, None);
    let (_, e) = p.step(&params, settled(600.0, 102.0));
    assert!(matches!(e, Some(ProbeEvent::Sent { from, .. }) if (from - 600.0).abs() < 1e-9));
}

#[test]
fn a_probe_that_measures_no_better_goes_back_and_rests_until_the_scene_changes() {
    let params = params();
    let mut p = Prober::default();
    let probe = settle_and_probe(&mut p, &params, 100.0);
    // 0.4 % better is inside the acceptance margin (0.5 %): back home.
    let (d, e) = p.step(&params, frame(probe, 100.4, probe * 1.5));
    assert!(matches!(e, Some(ProbeEvent::Rejected { gain }) if (gain - 0.004).abs() < 1e-9));
    assert!((d - 1000.0).abs() < 1e-9, "went to {d}, not back home");
    // At home, the same scene: no more probes, cooldown or not.
    for k in 0..10 {
        let (d, e) = p.step(&params, settled(1000.0, 100.1));
        assert_eq!(e, None, "frame {k}: probed again in an unchanged scene");
        assert!((d - 1010.0).abs() < 1e-9);
    }
    // The scene changes (M at home 5 % higher, beyond `rearm_change`): the
    // camera settles again and probes again.
    let (_, e) = p.step(&params, settled(1000.0, 105.0));
    assert_eq!(e, None);
    let (_, e) = p.step(&params, settled(1000.0, 105.0));
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })), "{e:?}");
}

#[test]
fn the_cooldown_holds_off_a_new_probe_however_the_scene_changes() {
    let params = ProbeParams {
        cooldown_frames: 5,
        ..params()
    };
    let mut p = Prober::default();
    let probe = settle_and_probe(&mut p, &params, 100.0);
    p.step(&params, frame(probe, 90.0, probe));
    let mut first = None;
    for k in 0..12 {
        // A new scene on every frame.
        let (_, e) = p.step(&params, settled(1000.0, 100.0 + 10.0 * f64::from(k)));
        if matches!(e, Some(ProbeEvent::Sent { .. })) {
            first = Some(k);
            break;
        }
    }
    // 5 frames of cooldown, then two settled frames in the new scene; the
    // M of the scene keeps changing, but the settled count only looks at
    // the law's step and the exposure.
    assert_eq!(first, Some(6));
}

#[test]
fn a_camera_without_saturation_or_still_moving_does_not_probe() {
    let params = params();
    let mut p = Prober::default();
    for _ in 0..10 {
        let (_, e) = p.step(
            &params,
            ProbeInput {
                saturated: 0.0,
                dark: 0.0,
                ..settled(1000.0, 100.0)
            },
        );
        assert_eq!(e, None, "probed with nothing saturated");
    }
    let mut p = Prober::default();
    for k in 0..10 {
        // Steps of 0.1 EV: not settled (settle_ev 0.05).
        let e0 = 1000.0 * (0.1 * f64::from(k)).exp2();
        let (d, e) = p.step(&params, frame(e0, 100.0, e0 * 0.1f64.exp2()));
        assert_eq!(e, None, "probed while moving");
        assert!((d / e0 - 0.1f64.exp2()).abs() < 1e-9);
    }
}

#[test]
fn a_law_creeping_in_small_steps_has_not_settled() {
    let params = ProbeParams::default();
    assert_eq!((params.settle_frames, params.settle_ev), (3, 0.03));
    let mut p = Prober::default();
    // Steps of 0.02 EV, each within `settle_ev`, drift 0.04 EV in three
    // frames: no probe.
    for k in 0..20 {
        let e0 = 1000.0 * (0.02 * f64::from(k)).exp2();
        let (_, e) = p.step(&params, frame(e0, 100.0, e0 * 0.02f64.exp2()));
        assert_eq!(e, None, "frame {k}: probed while creeping");
    }
    // Steps of 0.005 EV: settled after three frames.
    let mut p = Prober::default();
    let events: Vec<_> = (0..3)
        .map(|k| {
            let e0 = 1000.0 * (0.005 * f64::from(k)).exp2();
            p.step(&params, frame(e0, 100.0, e0 * 0.005f64.exp2())).1
        })
        .collect();
    assert_eq!(&events[..2], &[None, None]);
    assert!(
        matches!(events[2], Some(ProbeEvent::Sent { .. })),
        "{events:?}"
    );
}

#[test]
fn a_law_creeping_darker_with_saturation_in_view_probes_from_where_it_came() {
    let params = ProbeParams::default();
    // Steps of 0.03 EV down (a law whose held pixels put its fixed point
    // too high): the creep goes where the probe would look, and counts as
    // settling; the probe goes from the third frame's exposure.
    let mut p = Prober::default();
    let creep = |k: u32, step: f64| 1000.0 * (-step * f64::from(k)).exp2();
    let events: Vec<_> = (0..3)
        .map(|k| {
            let e0 = creep(k, 0.03);
            p.step(&params, frame(e0, 100.0, e0 * (-0.03f64).exp2())).1
        })
        .collect();
    assert_eq!(&events[..2], &[None, None]);
    match events[2] {
        Some(ProbeEvent::Sent { from, to }) => {
            assert!((from - creep(2, 0.03)).abs() < 1e-9, "from {from}");
            assert!((to - from / 1.9).abs() < 1e-6, "to {to}");
        }
        ref other => panic!("expected a probe, got {other:?}"),
    }
    // Steps of 0.1 EV down are a move, not a creep; creeping down with
    // nothing saturated has nothing to probe for.
    for (step, saturated) in [(0.1, 0.3), (0.03, 0.0)] {
        let mut p = Prober::default();
        for k in 0..20 {
            let e0 = creep(k, step);
            let input = ProbeInput {
                saturated,
                ..frame(e0, 100.0, e0 * (-step).exp2())
            };
            let (_, e) = p.step(&params, input);
            assert_eq!(
                e, None,
                "step {step}, saturated {saturated}: probed at frame {k}"
            );
        }
    }
}

#[test]
fn a_recent_frame_in_the_probes_range_answers_without_a_probe() {
    let params = params();
    let mut p = Prober::default();
    // Climbing from dark: 0.7 EV below where it settles, M lower there.
    p.step(&params, frame(1000.0 / 0.7f64.exp2(), 90.0, 1000.0));
    p.step(&params, settled(1000.0, 100.0));
    let (d, e) = p.step(&params, settled(1000.0, 100.0));
    assert!(
        matches!(e, Some(ProbeEvent::Known { gain }) if (gain + 0.1).abs() < 1e-9),
        "{e:?}"
    );
    assert!((d - 1010.0).abs() < 1e-9, "a known answer sends no probe");
    // And it rests.
    for _ in 0..5 {
        assert_eq!(p.step(&params, settled(1000.0, 100.0)).1, None);
    }
}

/// A camera whose estimator reads probe frames (scale-and-clip) probes
/// even where a recent frame measured worse: the probe is for its frame.
/// A recent frame that measured better still answers, as before.
#[test]
fn a_camera_that_reads_probe_frames_probes_past_a_frame_that_measured_worse() {
    let params = params();
    // Climbed from a frame 0.7 EV darker that measured `m_dark`, settled at
    // 1000 with M 100: what the second settled frame does.
    let settle_after = |m_dark: f64| {
        let reading = |i: ProbeInput| ProbeInput {
            wants_frame: true,
            ..i
        };
        let mut p = Prober::default();
        p.step(
            &params,
            reading(frame(1000.0 / 0.7f64.exp2(), m_dark, 1000.0)),
        );
        p.step(&params, reading(settled(1000.0, 100.0)));
        p.step(&params, reading(settled(1000.0, 100.0))).1
    };
    let e = settle_after(90.0);
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })), "{e:?}");
    let e = settle_after(110.0);
    assert!(
        matches!(e, Some(ProbeEvent::Known { gain }) if (gain - 0.1).abs() < 1e-9),
        "{e:?}"
    );
}

/// A law that circles (up, up, down, over and over, as around a jump of its
/// estimate) never settles; the prober recognises the circle after three
/// turns and probes from where the camera is (for its frame: the frames of
/// the circle measured no better). Without saturation it does
/// not, nor does a law that climbs in steps or zig-zags while it drifts.
#[test]
fn a_circling_law_probes_from_where_it_is() {
    let params = params();
    let circle = [1000.0, 1300.0, 1600.0];
    let run = |saturated: f64, at: &dyn Fn(usize) -> f64| {
        let mut p = Prober::default();
        for k in 0..30 {
            let (taken, next) = (at(k), at(k + 1));
            let (d, e) = p.step(
                &params,
                ProbeInput {
                    saturated,
                    wants_frame: true,
                    ..frame(taken, 100.0, next)
                },
            );
            if let Some(ProbeEvent::Sent { from, to }) = e {
                assert!((from - taken).abs() < 1e-9 && (d - to).abs() < 1e-9);
                return Some((k, from));
            }
        }
        None
    };
    let circling = |k: usize| circle[k % 3];
    assert_eq!(run(0.3, &circling), Some((8, circle[8 % 3])));
    assert_eq!(run(0.0, &circling), None, "probed without saturation");
    let climbing = |k: usize| 1000.0 * (0.2 * k as f64).exp2();
    assert_eq!(run(0.3, &climbing), None, "probed while climbing");
    // Up 0.3 EV, down 0.2 EV: drifts 0.3 EV in nine frames.
    let drifting = |k: usize| {
        1000.0 * (0.3 * (k / 2) as f64 - 0.2 * (k / 2) as f64 + 0.3 * (k % 2) as f64).exp2()
    };
    assert_eq!(run(0.3, &drifting), None, "probed while drifting");
}

/// While the estimate reads the frame of the probe the camera rests after
/// (the scene is the probe's), the rest goes on however far the law moves
/// the camera and `M` with it; once it no longer does, the moved camera
/// re-arms after the cooldown and probes again.
#[test]
fn a_camera_reading_its_probe_frame_rests_on() {
    let params = params();
    let mut p = Prober::default();
    let probe = settle_and_probe(&mut p, &params, 100.0);
    let (_, e) = p.step(&params, frame(probe, 90.0, 1000.0));
    assert!(matches!(e, Some(ProbeEvent::Rejected { .. })), "{e:?}");
    assert!(p.resting());
    // The law moves the camera 0.6 EV up (beyond half a probe step) and M
    // 8 % with it, for longer than the cooldown.
    let moved = 1000.0 * 0.6f64.exp2();
    for k in 0..10 {
        let (_, e) = p.step(
            &params,
            ProbeInput {
                read_probe_frame: true,
                ..settled(moved, 108.0)
            },
        );
        assert_eq!(e, None, "frame {k}: probed while reading its probe frame");
        assert!(p.resting());
    }
    // The frame no longer matches: the camera settles there (two frames)
    // and probes.
    let events: Vec<_> = (0..2)
        .map(|_| {
            p.step(
                &params,
                ProbeInput {
                    wants_frame: true,
                    ..settled(moved, 108.0)
                },
            )
            .1
        })
        .collect();
    assert!(
        matches!(events[..], [None, Some(ProbeEvent::Sent { from, .. })] if (from - moved).abs() < 1e-9),
        "{events:?}"
    );
}

#[test]
fn a_probe_that_does_not_show_is_abandoned() {
    let params = params();
    let mut p = Prober::default();
    settle_and_probe(&mut p, &params, 100.0);
    // The range ends at 900: the camera only got 0.15 EV darker.
    let (d, e) = p.step(&params, frame(900.0, 120.0, 900.0));
    assert_eq!(e, Some(ProbeEvent::Abandoned));
    assert!((d - 1000.0).abs() < 1e-9);
    // A range that allows 0.6 EV (more than half the step) still counts.
    let mut p = Prober::default();
    settle_and_probe(&mut p, &params, 100.0);
    let e0 = 1000.0 / 0.6f64.exp2();
    let (_, e) = p.step(&params, frame(e0, 120.0, e0));
    assert!(matches!(e, Some(ProbeEvent::Taken { .. })), "{e:?}");
}

#[test]
fn bad_frames_reset_the_prober_and_pass_the_law_through() {
    let params = params();
    let mut p = Prober::default();
    p.step(&params, settled(1000.0, 100.0));
    for bad in [
        frame(1000.0, f64::NAN, 1010.0),
        frame(f64::INFINITY, 100.0, 1010.0),
        frame(1000.0, 100.0, -1.0),
    ] {
        let (d, e) = p.step(&params, bad);
        assert_eq!(e, None);
        assert_eq!(d.to_bits(), bad.desired.to_bits());
    }
    // The settled count starts over: one settled frame does not probe.
    assert_eq!(p.step(&params, settled(1000.0, 100.0)).1, None);
    assert!(matches!(
        p.step(&params, settled(1000.0, 100.0)).1,
        Some(ProbeEvent::Sent { .. })
    ));
}

#[test]
fn bad_parameters_are_named() {
    let cases: [(ProbeParams, &str); 6] = [
        (
            ProbeParams {
                step_ev: 0.0,
                ..ProbeParams::default()
            },
            "controller.probe.step_ev",
        ),
        (
            ProbeParams {
                accept_gain: f64::NAN,
                ..ProbeParams::default()
            },
            "controller.probe.accept_gain",
        ),
        (
            ProbeParams {
                settle_frames: 0,
                ..ProbeParams::default()
            },
            "controller.probe.settle_frames",
        ),
        (
            ProbeParams {
                ladder_gain: -0.1,
                ..ProbeParams::default()
            },
            "controller.probe.ladder_gain",
        ),
        (
            ProbeParams {
                relight_change: f64::INFINITY,
                ..ProbeParams::default()
            },
            "controller.probe.relight_change",
        ),
        (
            ProbeParams {
                reacquire_start_saturated: 1.5,
                ..ProbeParams::default()
            },
            "controller.probe.reacquire_start_saturated",
        ),
    ];
    for (params, name) in cases {
        let err = params.validate().unwrap_err().to_string();
        assert!(err.contains(name), "{err}");
    }
    ProbeParams::default().validate().unwrap();
}

/// A ladder of three rungs: a rung that measures no better is followed by
/// one a probe step darker again, from the same home; the first that
/// measures better is taken; after the last the camera goes home and
/// rests.
#[test]
fn a_ladder_probes_further_down_until_a_rung_measures_better() {
    let params = params();
    let ladder = |p: &mut Prober, e: f64, m: f64| {
        p.step(
            &params,
            ProbeInput {
                rungs: 3,
                ..settled(e, m)
            },
        )
    };
    let step = 1.9f64;
    // Settle at 1000 (M 100) and probe: rung 1 at 1000/1.9.
    let mut p = Prober::default();
    assert_eq!(ladder(&mut p, 1000.0, 100.0).1, None);
    let (d, e) = ladder(&mut p, 1000.0, 100.0);
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })));
    assert!((d - 1000.0 / step).abs() < 1e-6);
    // Rung 1 measures less (a dip): rung 2, one step darker again.
    let (d, e) = p.step(&params, frame(d, 96.0, d));
    match e {
        Some(ProbeEvent::Sent { from, to }) => {
            assert!((from - 1000.0).abs() < 1e-9);
            assert!((to - 1000.0 / (step * step)).abs() < 1e-6, "rung 2 at {to}");
            assert!((d - to).abs() < 1e-9);
        }
        other => panic!("expected rung 2, got {other:?}"),
    }
    // Rung 2 measures 20 % more: taken, the law goes on from there.
    let (d2, e) = p.step(&params, frame(d, 120.0, d * 1.05));
    assert!(matches!(e, Some(ProbeEvent::Taken { gain }) if (gain - 0.2).abs() < 1e-9));
    assert!((d2 - d * 1.05).abs() < 1e-9);

    // Every rung no better: three probe frames, then home, resting.
    let mut p = Prober::default();
    ladder(&mut p, 1000.0, 100.0);
    let (d, _) = ladder(&mut p, 1000.0, 100.0);
    let (sent, d) = every_rung_measures(&mut p, &params, d, 90.0);
    assert_eq!(sent, 3);
    assert!(p.resting());
    assert!((d - 1000.0 / step.powi(3)).abs() < 1e-6, "last rung at {d}");
    // A one-rung probe (the default) goes home after the first.
    let mut p = Prober::default();
    let probe = settle_and_probe(&mut p, &params, 100.0);
    let (_, e) = p.step(&params, frame(probe, 90.0, probe));
    assert!(matches!(e, Some(ProbeEvent::Rejected { .. })));
    // The ladder's parameters are checked.
    let bad = ProbeParams {
        ladder: 0,
        ..ProbeParams::default()
    };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("controller.probe.ladder"), "{err}");
}

/// A balanced camera's probe (or a ladder's rung) must measure
/// `ladder_gain` more to be taken: balancing's rest is not the camera's
/// own maximum, and where `M` is flat a darker frame measures a little
/// more without being worth leaving the neighbours for.
#[test]
fn a_balanced_cameras_probe_needs_the_ladder_gain() {
    let params = ProbeParams {
        ladder_gain: 0.1,
        ..params()
    };
    let outcome = |balanced: bool, m_probe: f64| {
        let mut p = Prober::default();
        let at = |e: f64, m: f64, d: f64| ProbeInput {
            balanced,
            ..frame(e, m, d)
        };
        p.step(&params, at(1000.0, 100.0, 1000.0));
        let (probe, sent) = p.step(&params, at(1000.0, 100.0, 1000.0));
        assert!(matches!(sent, Some(ProbeEvent::Sent { .. })), "{sent:?}");
        p.step(&params, at(probe, m_probe, probe)).1
    };
    // 5 % more: taken alone, not balanced.
    assert!(matches!(
        outcome(false, 105.0),
        Some(ProbeEvent::Taken { .. })
    ));
    assert!(matches!(
        outcome(true, 105.0),
        Some(ProbeEvent::Rejected { .. })
    ));
    // 15 % more: taken either way.
    assert!(matches!(
        outcome(true, 115.0),
        Some(ProbeEvent::Taken { .. })
    ));
}

/// After a probe that found nothing, a change of `M` at the rest by more
/// than `relight_change` (a new light) lets the camera probe again before
/// the cooldown, where the caller asks for it (scale-and-clip); a smaller
/// change, or without it, the camera waits out the cooldown.
#[test]
fn a_new_light_rearms_the_probe_before_the_cooldown() {
    let params = ProbeParams {
        cooldown_frames: 50,
        relight_change: 0.2,
        ..params()
    };
    // Frames after a rejected probe, resting at 1000 (M 100), then at
    // `m_after`: whether a probe is sent within ten frames.
    let probes_again = |relight: bool, m_after: f64| {
        let mut p = Prober::default();
        let at = |e: f64, m: f64| ProbeInput {
            relight,
            ..settled(e, m)
        };
        let probe = settle_and_probe(&mut p, &params, 100.0);
        let (_, e) = p.step(&params, frame(probe, 90.0, probe));
        assert!(matches!(e, Some(ProbeEvent::Rejected { .. })));
        assert!(p.resting());
        (0..10).any(|_| {
            matches!(
                p.step(&params, at(1000.0, m_after)).1,
                Some(ProbeEvent::Sent { .. })
            )
        })
    };
    assert!(probes_again(true, 70.0), "a 30 % drop of M is a new light");
    assert!(
        !probes_again(false, 70.0),
        "without relight the cooldown holds"
    );
    assert!(
        !probes_again(true, 90.0),
        "a 10 % change waits for the cooldown"
    );
}

/// A settled frame at `e` with `dark` of its pixels dark and none
/// saturated.
fn dark(e: f64, m: f64, dark: f64) -> ProbeInput {
    ProbeInput {
        saturated: 0.0,
        dark,
        ..settled(e, m)
    }
}

/// A camera resting where most of its frame is dark (a tunnel's walls
/// behind its bright exit) probes brighter, by a ladder of
/// `bright_step_ev` steps: the first rung that measures `ladder_gain`
/// more is taken; with none, it goes home and rests.
#[test]
fn a_mostly_dark_camera_probes_brighter_by_a_ladder() {
    let params = params();
    let step = params.bright_step_ev.exp2();
    let rung = |k: i32| 1000.0 * step.powi(k);
    // Half dark (the default `min_dark`): no probe yet at 49 %.
    let mut p = Prober::default();
    for _ in 0..6 {
        assert_eq!(p.step(&params, dark(1000.0, 100.0, 0.49)).1, None);
    }
    // At 60 %: rung 1 after the settled frames.
    let mut p = Prober::default();
    assert_eq!(p.step(&params, dark(1000.0, 100.0, 0.6)).1, None);
    let (d, e) = p.step(&params, dark(1000.0, 100.0, 0.6));
    match e {
        Some(ProbeEvent::Sent { from, to }) => {
            assert!((from - 1000.0).abs() < 1e-9);
            assert!((to - rung(1)).abs() < 1e-6, "rung 1 at {to}");
            assert!((d - to).abs() < 1e-9);
        }
        other => panic!("expected a brighter probe, got {other:?}"),
    }
    // Rung 1 measures less (past the hump), rung 2 a little more (5 %,
    // short of the ladder's gain), rung 3 twice as much: taken.
    let (d, e) = p.step(&params, frame(d, 60.0, d));
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })));
    assert!((d - rung(2)).abs() < 1e-6, "rung 2 at {d}");
    let (d, e) = p.step(&params, frame(d, 105.0, d));
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })));
    assert!((d - rung(3)).abs() < 1e-6, "rung 3 at {d}");
    let (next, e) = p.step(&params, frame(d, 200.0, d * 1.3));
    assert!(matches!(e, Some(ProbeEvent::Taken { gain }) if (gain - 1.0).abs() < 1e-9));
    assert!(
        (next - d * 1.3).abs() < 1e-9,
        "the law goes on from the rung"
    );

    // No rung better: three brighter frames, then home, resting.
    let mut p = Prober::default();
    p.step(&params, dark(1000.0, 100.0, 0.6));
    let (d, _) = p.step(&params, dark(1000.0, 100.0, 0.6));
    let (sent, _) = every_rung_measures(&mut p, &params, d, 80.0);
    assert_eq!(sent, params.bright_ladder);
    assert!(p.resting());
    // Resting, it does not probe again in the same scene.
    for _ in 0..10 {
        assert_eq!(p.step(&params, dark(1000.0, 100.0, 0.6)).1, None);
    }

    // Mostly dark wins over saturation in view: the probe goes up.
    let mut p = Prober::default();
    let half = ProbeInput {
        saturated: 0.3,
        ..dark(1000.0, 100.0, 0.6)
    };
    p.step(&params, half);
    let (d, _) = p.step(&params, half);
    assert!((d - rung(1)).abs() < 1e-6, "probe at {d}");

    // A balanced camera probes brighter too (balancing's guard keeps its
    // neighbours from pulling it over a hump; docs/exposure-results.md).
    let mut p = Prober::default();
    let balanced = ProbeInput {
        balanced: true,
        ..dark(1000.0, 100.0, 0.9)
    };
    assert_eq!(p.step(&params, balanced).1, None);
    let (d, e) = p.step(&params, balanced);
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })), "{e:?}");
    assert!((d - rung(1)).abs() < 1e-6, "probe at {d}");
}

/// A brighter ladder reaches far, so a recent frame answers for it only if
/// one lay as far as the last rung, or one in its range measured better.
#[test]
fn recent_frames_answer_for_a_brighter_ladder_only_as_far_as_it_reaches() {
    let params = params();
    let reach = f64::from(params.bright_ladder) * params.bright_step_ev;
    // A camera that came down from 1.5 EV above (M lower there) probes.
    let mut p = Prober::default();
    p.step(&params, frame(1000.0 * 1.5f64.exp2(), 60.0, 1000.0));
    p.step(&params, dark(1000.0, 100.0, 0.6));
    let (_, e) = p.step(&params, dark(1000.0, 100.0, 0.6));
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })), "{e:?}");
    // One that came down from the ladder's reach knows.
    let mut p = Prober::default();
    p.step(&params, frame(1000.0 * reach.exp2(), 60.0, 1000.0));
    p.step(&params, dark(1000.0, 100.0, 0.6));
    let (_, e) = p.step(&params, dark(1000.0, 100.0, 0.6));
    assert!(matches!(e, Some(ProbeEvent::Known { .. })), "{e:?}");
    // So does one whose recent frame in range measured better (the law
    // brought it back from there).
    let mut p = Prober::default();
    p.step(&params, frame(1000.0 * 2f64.exp2(), 150.0, 1000.0));
    p.step(&params, dark(1000.0, 100.0, 0.6));
    let (_, e) = p.step(&params, dark(1000.0, 100.0, 0.6));
    assert!(matches!(e, Some(ProbeEvent::Known { gain }) if (gain - 0.5).abs() < 1e-9));
    // The parameters are checked.
    for (bad, name) in [
        (
            ProbeParams {
                min_dark: 1.5,
                ..ProbeParams::default()
            },
            "controller.probe.min_dark",
        ),
        (
            ProbeParams {
                bright_step_ev: 0.0,
                ..ProbeParams::default()
            },
            "controller.probe.bright_step_ev",
        ),
        (
            ProbeParams {
                bright_ladder: 0,
                ..ProbeParams::default()
            },
            "controller.probe.bright_ladder",
        ),
    ] {
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains(name), "{err}");
    }
}

#[test]
fn a_camera_that_probes_only_brighter_makes_no_darker_probe() {
    let params = params();
    let only = |i: ProbeInput| ProbeInput {
        brighter_only: true,
        ..i
    };
    // Saturation in view (30 %) and settled: no darker probe, ever, and no
    // circle's probe either.
    let mut p = Prober::default();
    for _ in 0..12 {
        let (d, e) = p.step(&params, only(settled(1000.0, 100.0)));
        assert_eq!(e, None, "probed darker");
        assert!(!p.probing());
        assert!((d - 1010.0).abs() < 1e-9, "the law passes through: {d}");
    }
    // Mostly dark: the brighter ladder, as for any camera.
    let mut p = Prober::default();
    p.step(&params, only(dark(1000.0, 100.0, 0.6)));
    let (d, e) = p.step(&params, only(dark(1000.0, 100.0, 0.6)));
    assert!(matches!(e, Some(ProbeEvent::Sent { .. })), "{e:?}");
    assert!(d > 1000.0 && p.probing(), "probe at {d}");
    assert!(p.last_brighter(), "the probe is said to be brighter");
    // Its rung measured: no longer probing.
    let (_, e) = p.step(&params, only(frame(d, 300.0, d)));
    assert!(matches!(e, Some(ProbeEvent::Taken { .. })), "{e:?}");
    assert!(!p.probing());
    assert!(p.last_brighter());
    // Its next probe, darker (saturation in view, not only brighter now),
    // is said to be darker.
    let d = settle_and_probe(&mut p, &params, 100.0);
    assert!(d < 1000.0 && !p.last_brighter(), "probe at {d}");
}
