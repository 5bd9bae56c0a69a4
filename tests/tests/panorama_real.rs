#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The panorama of the real four-fisheye rig in `tests/data/surround-nz`:
//! composed on a 2048×380 cylinder of 8 m, with Harris + BRIEF matches in
//! its overlaps, their epipolar errors and brightness ratios, the
//! refinement of the rotations (which must lower every matched overlap's
//! median error), and the matches with the front camera turned by 2° of
//! yaw; the product's refinement in rounds, which must lower every pair's
//! median error, with each overlap's gradient agreement before and after.
//! Run with `--nocapture` for the figures.

mod surround_common;

use rigview_calib::formats;
use rigview_calib::pose::Pose;
use rigview_calib::rig::Rig;
use rigview_core::exposure::balance::pair_ratio;
use rigview_core::exposure::{BalanceParams, FrameView};
use rigview_core::panorama::{
    refine_in_rounds, CylinderSpec, MatchOptions, PairMatches, Panorama, PanoramaOptions,
    RefineOptions, RoundsOptions,
};
use rigview_core::surround::{Canvas, Composer};
use surround_common::{aligned, data, images, views};

fn spec() -> CylinderSpec {
    CylinderSpec {
        width: 2048,
        height: 380,
        radius_m: 8.0,
        ..CylinderSpec::default()
    }
}

fn matches(rig: &Rig, images: &[(usize, usize, Vec<u8>)]) -> Vec<PairMatches> {
    let pano = Panorama::build(rig, &spec(), &PanoramaOptions::default()).unwrap();
    let frames = views(images);
    let (pairs, _) = pano
        .match_pairs(&frames, &rigview_tests::harris, &MatchOptions::default())
        .unwrap();
    let params = BalanceParams::default();
    for p in &pairs {
        let (a, b) = (&rig.cameras[p.i].name, &rig.cameras[p.j].name);
        println!(
            "{a}–{b}: corners {:?}, {} matches ({} aligned), {} inliers ({} aligned), error {:.2} -> {:.2} px, r = {:.3}{}",
            p.corners,
            p.matches.len(),
            aligned(p).0,
            p.inliers,
            aligned(p).1,
            p.error_before_px.unwrap_or(f64::NAN),
            p.error_after_px.unwrap_or(f64::NAN),
            pair_ratio(&p.patches, &params).unwrap_or(f64::NAN),
            p.problem
                .as_deref()
                .map(|s| format!(" ({s})"))
                .unwrap_or_default()
        );
    }
    pairs
}

#[test]
fn the_real_rig_matches_its_overlaps_and_a_turned_camera_shows() {
    let rig = formats::load(&data(), None, None).unwrap().rig;
    let imgs = images(&rig);
    let pairs = matches(&rig, &imgs);
    assert_eq!(pairs.len(), 4);
    let params = BalanceParams::default();
    let with_ratio: Vec<&PairMatches> = pairs
        .iter()
        .filter(|p| pair_ratio(&p.patches, &params).is_some())
        .collect();
    assert!(
        with_ratio.len() >= 3,
        "{} pairs with a ratio",
        with_ratio.len()
    );
    for p in &with_ratio {
        let r = pair_ratio(&p.patches, &params).unwrap();
        // The four auto-exposed stills differ by well under 2 EV.
        assert!(r.log2().abs() < 2.0, "{}–{}: {r}", p.i, p.j);
        // The pair's rotation does not make its inliers worse.
        assert!(p.error_after_px.unwrap() <= p.error_before_px.unwrap() + 0.1);
    }
    for p in pairs.iter().filter(|p| p.problem.is_some()) {
        assert!(p.problem.as_deref().unwrap().contains("fewer than"));
    }
    // The refinement of the rotations lowers the median reprojection error
    // of every overlap that has inliers.
    let pano = Panorama::build(&rig, &spec(), &PanoramaOptions::default()).unwrap();
    let refined = pano.refine(&pairs, &RefineOptions::default()).unwrap();
    assert_eq!(refined.pairs.len(), with_ratio.len());
    for p in &refined.pairs {
        let (e0, e1) = (p.error_before_px.unwrap(), p.error_after_px.unwrap());
        println!(
            "refined {}–{}: {} inliers, {e0:.2} -> {e1:.2} px",
            p.i, p.j, p.inliers
        );
        assert!(e1 < e0, "{}–{}: {e0} -> {e1}", p.i, p.j);
    }
    for (k, q) in refined.rotations.iter().enumerate() {
        println!("camera {k} turned by {:.3}°", q.angle().to_degrees());
    }
    // The front camera turned by 2° of yaw: its pairs' figures move (for
    // the report; the calibration's own front yaw may be off, so which way
    // is not asserted).
    let front = rig.index_of("front").unwrap();
    let mut turned = rig.clone();
    let pose = turned.cameras[front].pose.unwrap();
    let [yaw, pitch, roll] = pose.ypr_deg();
    turned.cameras[front].pose =
        Some(Pose::from_ypr_deg([yaw + 2.0, pitch, roll], *pose.translation()).unwrap());
    println!("front camera turned by 2° of yaw:");
    let bad = matches(&turned, &imgs);
    assert_eq!(bad.len(), 4);
}

/// Gradient agreement of two cameras' warps of a band over the pixels
/// both show, 2 px in from either's edge: `Σ ∇a·∇b / √(Σ|∇a|² Σ|∇b|²)` of
/// central differences after a 3×3 box blur. 1 means the same edges in
/// the same places; misplaced edges pull it towards 0.
fn band_agreement(a: &Canvas, b: &Canvas) -> f64 {
    let (w, h) = (a.width, a.height);
    let blur = |c: &Canvas| -> Vec<f64> {
        let mut out = vec![0.0; w * h];
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let mut s = 0.0;
                for dy in 0..3 {
                    for dx in 0..3 {
                        s += f64::from(c.data[(y + dy - 1) * w + x + dx - 1]);
                    }
                }
                out[y * w + x] = s / 9.0;
            }
        }
        out
    };
    let (fa, fb) = (blur(a), blur(b));
    let shown = |x: usize, y: usize| {
        (y.saturating_sub(2)..(y + 3).min(h)).all(|v| {
            (x.saturating_sub(2)..(x + 3).min(w))
                .all(|u| a.data[v * w + u] > 0 && b.data[v * w + u] > 0)
        })
    };
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for y in 3..h.saturating_sub(3) {
        for x in 3..w.saturating_sub(3) {
            if !shown(x, y) {
                continue;
            }
            let g = |f: &[f64]| {
                (
                    f[y * w + x + 1] - f[y * w + x - 1],
                    f[(y + 1) * w + x] - f[(y - 1) * w + x],
                )
            };
            let ((ax, ay), (bx, by)) = (g(&fa), g(&fb));
            ab += ax * bx + ay * by;
            aa += ax * ax + ay * ay;
            bb += bx * bx + by * by;
        }
    }
    ab / (aa * bb).sqrt().max(1e-12)
}

/// Each band's gradient agreement between its two cameras (band order), on
/// the refinement's matching cylinder (with a floor: the ground lines up
/// across the seams at any distance).
fn agreements(rig: &Rig, frames: &[FrameView<'_>]) -> Vec<(usize, usize, f64)> {
    let spec = rigview_core::panorama::matching_spec(&spec());
    let pano = Panorama::build(rig, &spec, &PanoramaOptions::default()).unwrap();
    let mut composer = Composer::new();
    pano.bands()
        .iter()
        .enumerate()
        .map(|(b, band)| {
            let mut warp = |k: usize| pano.warp_band(&mut composer, b, k, &frames[k]).unwrap();
            let (wi, wj) = (warp(band.i), warp(band.j));
            (band.i, band.j, band_agreement(&wi, &wj))
        })
        .collect()
}

/// The product's refinement (rounds on a cylinder with a floor, corners to
/// a fraction of a pixel) on the real stills: every pair's median error
/// falls, and the overlaps' gradient agreement, reported before and after,
/// does not fall on average.
#[test]
fn the_refinement_in_rounds_lowers_the_real_rigs_errors() {
    let rig = formats::load(&data(), None, None).unwrap().rig;
    let imgs = images(&rig);
    let frames = views(&imgs);
    let out = refine_in_rounds(
        &rig,
        &spec(),
        &PanoramaOptions::default(),
        &frames,
        &rigview_tests::harris_subpixel,
        &RoundsOptions::default(),
    )
    .unwrap();
    println!(
        "{} rounds{}",
        out.rounds.len(),
        out.stopped
            .as_deref()
            .map(|s| format!(" (stopped: {s})"))
            .unwrap_or_default()
    );
    for (k, (pairs, refinement)) in out.rounds.iter().enumerate() {
        for (p, r) in pairs.iter().zip(&refinement.pairs) {
            println!(
                "round {}: {}–{}: {} matches ({} aligned), {} inliers ({} aligned), refined on {}",
                k + 1,
                p.i,
                p.j,
                p.matches.len(),
                aligned(p).0,
                p.inliers,
                aligned(p).1,
                r.inliers
            );
        }
    }
    assert!(out.errors.len() >= 3, "{:?}", out.errors);
    for &(i, j, before, after) in &out.errors {
        let (b, a) = (before.unwrap(), after.unwrap());
        let (x, y) = (&rig.cameras[i].name, &rig.cameras[j].name);
        println!("{x}–{y}: median reprojection error {b:.2} -> {a:.2} px");
    }
    let before = agreements(&rig, &frames);
    let after = agreements(&out.rig, &frames);
    for ((i, j, g0), (_, _, g1)) in before.iter().zip(&after) {
        let (x, y) = (&rig.cameras[*i].name, &rig.cameras[*j].name);
        println!("{x}–{y}: gradient agreement {g0:.3} -> {g1:.3}");
    }
    let mean = |v: &[(usize, usize, f64)]| v.iter().map(|t| t.2).sum::<f64>() / v.len() as f64;
    println!(
        "mean gradient agreement {:.3} -> {:.3}",
        mean(&before),
        mean(&after)
    );
    // (Asserted after every figure is printed.)
    assert!(
        out.errors
            .iter()
            .all(|&(_, _, b, a)| a.unwrap() < b.unwrap()),
        "{:?}",
        out.errors
    );
    assert!(
        mean(&after) >= mean(&before) - 0.01,
        "{before:?} -> {after:?}"
    );
}

#[test]
fn a_frame_of_the_wrong_size_names_its_camera() {
    let rig = formats::load(&data(), None, None).unwrap().rig;
    let pano = Panorama::build(&rig, &spec(), &PanoramaOptions::default()).unwrap();
    let mut imgs = images(&rig);
    imgs[2] = (100, 80, vec![0; 100 * 80 * 3]);
    let frames = views(&imgs);
    let e = pano
        .match_pairs(&frames, &rigview_tests::harris, &MatchOptions::default())
        .unwrap_err()
        .to_string();
    let name = &rig.cameras[2].name;
    assert!(
        e.contains(&format!("camera 2 (\"{name}\")")) && e.contains("100×80"),
        "{e}"
    );
}
