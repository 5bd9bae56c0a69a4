#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! BRIEF on real images: Harris corners detected through OpenCV
//! (`goodFeaturesToTrack` with the Harris score), described and matched by
//! `rigview_core::features`.
//!
//! - A 10 % gain change keeps at least 90 % of the true matches.
//! - OpenCV's sample pair graf1/graf3 (a planar graffiti wall seen from two
//!   viewpoints about 40° apart) with its ground-truth homography
//!   `H1to3p.xml`: the matches' precision at 3 px and the inlier ratio of a
//!   RANSAC homography, checked against thresholds that descriptors of random
//!   bits fail.

use std::path::PathBuf;

use nalgebra::Matrix3;
use opencv::core::{
    FileNodeTraitConst, FileStorage, FileStorageTraitConst, Mat, MatTraitConst, Point2f, Vector,
};
use opencv::{calib3d, imgproc};
use rand::{Rng, SeedableRng};
use rigview_core::features::{match_mutual, Descriptor, Match, Smoothed};

fn samples() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/opencv-samples")
}

/// A sample image as Mono8 (BT.601 luminance): width, height, pixels.
fn gray(name: &str) -> (usize, usize, Vec<u8>) {
    let img = image::open(samples().join(name)).unwrap().to_luma8();
    (img.width() as usize, img.height() as usize, img.into_raw())
}

/// Harris corners through OpenCV: at most 2000, score at least 0.1 % of the
/// best, 6 px apart (non-maximum suppression), 3×3 blocks, k = 0.04.
fn harris((w, h, data): &(usize, usize, Vec<u8>)) -> Vec<[f32; 2]> {
    let m = Mat::new_rows_cols_with_data(*h as i32, *w as i32, data).unwrap();
    let mut corners = Vector::<Point2f>::new();
    imgproc::good_features_to_track(
        &m,
        &mut corners,
        2000,
        0.001,
        6.0,
        &Mat::default(),
        3,
        true,
        0.04,
    )
    .unwrap();
    corners.iter().map(|p| [p.x, p.y]).collect()
}

/// The keypoints that get a descriptor, and their descriptors.
fn describe(
    img: &(usize, usize, Vec<u8>),
    points: &[[f32; 2]],
) -> (Vec<[f32; 2]>, Vec<Descriptor>) {
    let s = Smoothed::new(&img.2, img.0, img.1).unwrap();
    points
        .iter()
        .filter_map(|p| s.describe(p[0], p[1]).map(|d| (*p, d)))
        .unzip()
}

const RATIO: f32 = 0.8;

#[test]
fn a_ten_percent_gain_change_keeps_the_true_matches() {
    for name in ["graf1.png", "graf3.png"] {
        let img = gray(name);
        let points = harris(&img);
        let (_, base) = describe(&img, &points);
        let brighter = (
            img.0,
            img.1,
            img.2
                .iter()
                .map(|&v| (f32::from(v) * 1.1).round().min(255.0) as u8)
                .collect(),
        );
        let (_, bright) = describe(&brighter, &points);
        assert_eq!(base.len(), bright.len());
        // The true matches: each keypoint with itself, where the image
        // matches itself so (the ratio test drops look-alike corners).
        let is_true = |m: &Match| m.query == m.train;
        let truth: Vec<Match> = match_mutual(&base, &base, RATIO)
            .unwrap()
            .into_iter()
            .filter(is_true)
            .collect();
        let kept = match_mutual(&base, &bright, RATIO).unwrap();
        let kept_true = kept.iter().filter(|m| is_true(m)).count();
        let wrong = kept.len() - kept_true;
        let share = kept_true as f64 / truth.len() as f64;
        println!(
            "{name}: {} keypoints, {} true matches, {kept_true} kept ({:.1} %), {wrong} wrong",
            base.len(),
            truth.len(),
            100.0 * share
        );
        assert!(
            truth.len() > 300,
            "{name}: only {} true matches",
            truth.len()
        );
        assert!(
            share >= 0.9,
            "{name}: kept {:.1} % of the true matches",
            100.0 * share
        );
        assert!(
            wrong * 100 <= kept.len(),
            "{name}: {wrong} wrong matches of {}",
            kept.len()
        );
    }
}

/// The ground-truth homography from graf1 to graf3.
fn h13() -> Matrix3<f64> {
    let path = samples().join("H1to3p.xml");
    let fs = FileStorage::new(path.to_str().unwrap(), opencv::core::FileStorage_READ, "").unwrap();
    let m = fs.get_node("H13").unwrap().mat().unwrap();
    assert_eq!((m.rows(), m.cols()), (3, 3));
    Matrix3::from_fn(|r, c| *m.at_2d::<f64>(r as i32, c as i32).unwrap())
}

/// What matching graf1 to graf3 gives: matches, the share within 3 px of
/// where the ground truth puts them, and the inlier share of a RANSAC
/// homography (3 px).
struct Score {
    matches: usize,
    precision: f64,
    inlier_ratio: f64,
}

fn score(
    p1: &[[f32; 2]],
    d1: &[Descriptor],
    p3: &[[f32; 2]],
    d3: &[Descriptor],
    h: &Matrix3<f64>,
) -> Score {
    let matches = match_mutual(d1, d3, RATIO).unwrap();
    let correct = matches
        .iter()
        .filter(|m| {
            let [x, y] = p1[m.query];
            let q = h * nalgebra::Vector3::new(f64::from(x), f64::from(y), 1.0);
            let [u, v] = p3[m.train];
            (q.x / q.z - f64::from(u)).hypot(q.y / q.z - f64::from(v)) <= 3.0
        })
        .count();
    let inliers = if matches.len() >= 4 {
        let src: Vector<Point2f> = matches
            .iter()
            .map(|m| Point2f::new(p1[m.query][0], p1[m.query][1]))
            .collect();
        let dst: Vector<Point2f> = matches
            .iter()
            .map(|m| Point2f::new(p3[m.train][0], p3[m.train][1]))
            .collect();
        let mut mask = Mat::default();
        let hm = calib3d::find_homography(&src, &dst, &mut mask, calib3d::RANSAC, 3.0).unwrap();
        if hm.empty() {
            0
        } else {
            (0..mask.rows())
                .filter(|&i| *mask.at::<u8>(i).unwrap() != 0)
                .count()
        }
    } else {
        0
    };
    let n = matches.len().max(1) as f64;
    Score {
        matches: matches.len(),
        precision: correct as f64 / n,
        inlier_ratio: inliers as f64 / n,
    }
}

#[test]
fn graf1_to_graf3_matches_agree_with_the_ground_truth() {
    let (img1, img3) = (gray("graf1.png"), gray("graf3.png"));
    let (p1, d1) = describe(&img1, &harris(&img1));
    let (p3, d3) = describe(&img3, &harris(&img3));
    let h = h13();
    let brief = score(&p1, &d1, &p3, &d3, &h);
    // A broken descriptor: random bits.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut random =
        |n: usize| -> Vec<Descriptor> { (0..n).map(|_| Descriptor(rng.gen())).collect() };
    let (r1, r3) = (random(d1.len()), random(d3.len()));
    let broken = score(&p1, &r1, &p3, &r3, &h);
    println!(
        "graf1 → graf3: {} and {} keypoints; BRIEF: {} matches, precision at 3 px {:.1} %, RANSAC inlier ratio {:.1} %; random bits: {} matches, precision {:.1} %, inlier ratio {:.1} %",
        d1.len(),
        d3.len(),
        brief.matches,
        100.0 * brief.precision,
        100.0 * brief.inlier_ratio,
        broken.matches,
        100.0 * broken.precision,
        100.0 * broken.inlier_ratio
    );
    assert!(brief.matches >= MIN_MATCHES, "{} matches", brief.matches);
    assert!(
        brief.precision >= MIN_PRECISION,
        "precision {}",
        brief.precision
    );
    assert!(
        brief.inlier_ratio >= MIN_INLIER_RATIO,
        "inlier ratio {}",
        brief.inlier_ratio
    );
    // The thresholds tell a working descriptor from a broken one.
    assert!(
        broken.matches < MIN_MATCHES
            || broken.precision < MIN_PRECISION
            || broken.inlier_ratio < MIN_INLIER_RATIO
    );
}

// Measured: 37 matches, 40.5 % within 3 px, 40.5 % RANSAC inliers; random
// bits give no match that passes the ratio test.
const MIN_MATCHES: usize = 25;
const MIN_PRECISION: f64 = 0.3;
const MIN_INLIER_RATIO: f64 = 0.3;
