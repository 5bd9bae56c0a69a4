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
