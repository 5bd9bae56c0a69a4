#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The darker probe of a settled camera under saturation
//! (`exposure::probe`), frame by frame on hand-made inputs.

use rigview_core::exposure::probe::{ProbeInput, Prober};
use rigview_core::exposure::{ProbeEvent, ProbeParams};

/// A frame taken at `taken` with `M = m`, 30 % saturated, whose law wants
/// `desired`.
fn frame(taken: f64, m: f64, desired: f64) -> ProbeInput {
    ProbeInput {
        taken,
        m,
        saturated: 0.3,
        desired,
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
    let cases: [(ProbeParams, &str); 3] = [
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
    ];
    for (params, name) in cases {
        let err = params.validate().unwrap_err().to_string();
        assert!(err.contains(name), "{err}");
    }
    ProbeParams::default().validate().unwrap();
}
