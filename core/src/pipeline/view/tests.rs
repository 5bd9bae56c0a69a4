use super::*;

fn pair(i: usize, j: usize, patches: usize) -> PairMatches {
    let patch = PatchPair {
        mean_i: 0.2,
        saturated_i: 0.0,
        mean_j: 0.4,
        saturated_j: 0.0,
    };
    PairMatches {
        i,
        j,
        corners: (40, 40),
        matches: Vec::new(),
        inliers: patches,
        rotation: None,
        error_before_px: None,
        error_after_px: None,
        patches: vec![patch; patches],
        problem: (patches < 6).then(|| "fewer than the 6 needed".to_string()),
    }
}

#[test]
fn a_pairs_ratio_is_held_through_matchings_without_it_until_it_ages_out() {
    let mut held = Held::default();
    held.take(vec![pair(0, 1, 8), pair(1, 2, 3)], &[1.0, 2.0, 4.0], 10);
    let at = |held: &Held, now: u64| -> Vec<(usize, usize, u64)> {
        held.current(now, 100)
            .map(|h| (h.pair.i, h.pair.j, h.at))
            .collect()
    };
    // The pair with too few inliers gives nothing to hold.
    assert_eq!(at(&held, 10), vec![(0, 1, 10)]);
    assert_eq!(held.pairs[0].taken, (1.0, 2.0));
    // A later matching without patches for 0–1 keeps the one held; one
    // with them replaces it.
    held.take(vec![pair(0, 1, 2), pair(1, 2, 7)], &[1.0, 2.0, 4.0], 50);
    assert_eq!(at(&held, 50), vec![(0, 1, 10), (1, 2, 50)]);
    assert_eq!(at(&held, 110), vec![(0, 1, 10), (1, 2, 50)]);
    assert_eq!(at(&held, 111), vec![(1, 2, 50)]);
    held.take(vec![pair(0, 1, 9)], &[3.0, 5.0, 4.0], 120);
    assert_eq!(at(&held, 151), vec![(0, 1, 120)]);
    assert_eq!(held.pairs[0].taken, (3.0, 5.0));
}

#[test]
fn held_patches_follow_the_exposures_and_saturate() {
    let p = PatchPair {
        mean_i: 0.2,
        saturated_i: 0.0,
        mean_j: 0.4,
        saturated_j: 0.0,
    };
    let q = rescaled(&p, 2.0, 0.5);
    assert!((q.mean_i - 0.4).abs() < 1e-6 && (q.mean_j - 0.2).abs() < 1e-6);
    assert!(q.saturated_i.abs() < 1e-6 && q.saturated_j.abs() < 1e-6);
    let q = rescaled(&p, 1.0, 3.0);
    assert!((q.saturated_j - 1.0).abs() < 1e-6);
    assert!(q.mean_j <= 1.0);
    let sat = PatchPair {
        saturated_i: 0.5,
        ..p
    };
    assert!((rescaled(&sat, 0.5, 1.0).saturated_i - 0.5).abs() < 1e-6);
}

#[test]
fn a_moving_viewpoint_is_previewed_at_half_size_then_built_whole() {
    use crate::bowl::{BowlSpec, Viewpoint};
    use crate::surround::{BlendMode, CanvasSpec};
    let rig = crate::sim::reference_rig().unwrap();
    let settings = BowlSettings {
        spec: BowlSpec {
            size_px: [320, 200],
            ..BowlSpec::default()
        },
        viewpoint: Viewpoint::preset("top").unwrap(),
        beside: false,
        gpu_draws: false,
    };
    let mut bowl =
        LiveBowl::new(&rig, &CanvasSpec::default(), &settings, BlendMode::Linear).unwrap();
    assert_eq!(bowl.shown().mosaic().size(), (320, 200));
    assert!(!bowl.is_preview());
    // A new viewpoint, asked for just now: in motion, built at half size.
    let turned = BowlSettings {
        viewpoint: settings.viewpoint.orbited(20.0, -30.0, 1.0),
        ..settings.clone()
    };
    bowl.set_wanted(&turned, BlendMode::Linear);
    assert!(bowl.building());
    bowl.settle();
    assert_eq!(bowl.built(), &turned);
    assert!(bowl.is_preview());
    assert_eq!(bowl.shown().mosaic().size(), (160, 100));
    // At rest: the whole size follows.
    std::thread::sleep(MOTION_FOR_TESTS);
    assert!(!bowl.poll(), "nothing was built yet");
    assert!(bowl.building());
    bowl.settle();
    assert!(!bowl.is_preview());
    assert_eq!(bowl.shown().mosaic().size(), (320, 200));
    assert_eq!(bowl.built(), &turned);
    // The same again asks for nothing, nor does the bird's-eye view
    // beside it.
    bowl.set_wanted(&turned, BlendMode::Linear);
    assert!(!bowl.building());
    let beside = BowlSettings {
        beside: true,
        ..turned.clone()
    };
    bowl.set_wanted(&beside, BlendMode::Linear);
    assert!(!bowl.building());
    // A bowl that cannot be built leaves the one shown and says why.
    let bad = BowlSettings {
        spec: BowlSpec {
            steepness: 100.0,
            ..turned.spec.clone()
        },
        ..turned.clone()
    };
    bowl.set_wanted(&bad, BlendMode::Linear);
    bowl.settle();
    assert_eq!(bowl.built(), &turned);
    let problem = bowl.problem().unwrap_or_default();
    assert!(problem.contains("bowl.steepness"), "{problem}");
    // While the window draws the bowl on the GPU, a new viewpoint builds
    // nothing (the GPU takes it as a matrix), a new bowl does (the GPU
    // needs its ground plan); once the GPU stops, the viewpoint it showed
    // is built.
    let on_gpu = BowlSettings {
        gpu_draws: true,
        viewpoint: turned.viewpoint.orbited(40.0, 0.0, 1.0),
        ..turned.clone()
    };
    bowl.set_wanted(&on_gpu, BlendMode::Linear);
    assert!(!bowl.building());
    let wider = BowlSettings {
        spec: BowlSpec {
            flat_m: turned.spec.flat_m + 0.5,
            ..turned.spec.clone()
        },
        ..on_gpu.clone()
    };
    bowl.set_wanted(&wider, BlendMode::Linear);
    assert!(bowl.building());
    bowl.settle();
    assert_eq!(bowl.built().spec, wider.spec);
    assert_eq!(bowl.built().viewpoint, turned.viewpoint);
    let off = BowlSettings {
        gpu_draws: false,
        ..wider.clone()
    };
    bowl.set_wanted(&off, BlendMode::Linear);
    assert!(bowl.building());
    bowl.settle();
    assert_eq!(bowl.built().viewpoint, off.viewpoint);
}
