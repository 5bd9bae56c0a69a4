#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! rigview's image operations against OpenCV's, which the core used
//! before: the Euclidean distance transform against `distanceTransform`
//! (`DIST_L2`, `DIST_MASK_PRECISE`), and the 8-bit colour conversions
//! against `cvtColor` (`RGB2GRAY`, `GRAY2RGB`).

use opencv::core::{self, Mat, MatTraitConst, MatTraitConstManual};
use opencv::imgproc;
use rand::{Rng, SeedableRng};
use rigview_core::image::{distance_to_zero, mono8_to_rgb8, rgb8_to_mono8};

type TestResult = Result<(), Box<dyn std::error::Error>>;

/// OpenCV's exact distance transform of `mask` (`w×h`, one byte a pixel).
fn opencv_distance(mask: &[u8], w: usize, h: usize) -> opencv::Result<Vec<f32>> {
    let src = Mat::new_rows_cols_with_data(h as i32, w as i32, mask)?;
    let mut dst = Mat::default();
    imgproc::distance_transform(
        &src,
        &mut dst,
        imgproc::DIST_L2,
        imgproc::DIST_MASK_PRECISE,
        core::CV_32F,
    )?;
    Ok(dst.data_typed::<f32>()?.to_vec())
}

/// Masks like the surround view's: the complement of a camera's exclusive
/// region (a wedge beyond one side of a vehicle rectangle), random
/// speckle, a single zero, and zeros on one edge only.
fn masks() -> Vec<(String, usize, usize, Vec<u8>)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut out = Vec::new();
    let (w, h) = (400, 300);
    let wedge: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64 - 200.0, (i / w) as f64 - 150.0);
            let exclusive = y < -40.0 && x.abs() < -y * 1.3;
            if exclusive {
                0
            } else {
                255
            }
        })
        .collect();
    out.push(("wedge".into(), w, h, wedge));
    for share in [0.001, 0.05, 0.5] {
        let speckle = (0..w * h)
            .map(|_| if rng.gen_bool(share) { 0 } else { 255 })
            .collect();
        out.push((format!("speckle {share}"), w, h, speckle));
    }
    let mut single = vec![255u8; 257 * 131];
    single[57 * 257 + 200] = 0;
    out.push(("one zero".into(), 257, 131, single));
    let mut edge = vec![1u8; 90 * 250];
    edge[..90].fill(0);
    out.push(("top row".into(), 90, 250, edge));
    out
}

#[test]
fn the_distance_transform_matches_opencvs_precise_one() -> TestResult {
    for (name, w, h, mask) in masks() {
        let ours = distance_to_zero(&mask, w, h)?;
        let theirs = opencv_distance(&mask, w, h)?;
        assert_eq!(ours.len(), theirs.len());
        let mut worst = 0.0f32;
        for (i, (&a, &b)) in ours.iter().zip(&theirs).enumerate() {
            let err = (a - b).abs();
            assert!(
                err <= 1e-4 * b.max(1.0),
                "{name}: pixel ({}, {}): rigview {a}, OpenCV {b}",
                i % w,
                i / w
            );
            worst = worst.max(err);
        }
        let far = theirs.iter().copied().fold(0.0f32, f32::max);
        eprintln!("{name} ({w}×{h}): largest distance {far:.2}, largest difference {worst:e}");
        assert!(far >= 2.0, "{name}: the mask should have distant pixels");
    }
    Ok(())
}

#[test]
fn colour_conversions_match_cvt_color() -> TestResult {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    // Odd sizes, so that no loop ends on a whole vector.
    let (w, h) = (333, 77);
    let rgb: Vec<u8> = (0..w * h * 3).map(|_| rng.gen()).collect();
    let flat = Mat::new_rows_cols_with_data(h as i32, (w * 3) as i32, &rgb)?;
    let shaped = flat.reshape(3, h as i32)?;
    let mut grey = Mat::default();
    imgproc::cvt_color(&shaped, &mut grey, imgproc::COLOR_RGB2GRAY, 0)?;
    let mut ours = vec![0u8; w * h];
    rgb8_to_mono8(&rgb, &mut ours)?;
    assert_eq!(ours.as_slice(), grey.data_bytes()?);
    let mut colour = Mat::default();
    imgproc::cvt_color(&grey, &mut colour, imgproc::COLOR_GRAY2RGB, 0)?;
    let mut back = vec![0u8; w * h * 3];
    mono8_to_rgb8(&ours, &mut back)?;
    assert_eq!(back.as_slice(), colour.data_bytes()?);
    // Not a trivial image: many grey levels.
    let mut levels = ours.clone();
    levels.sort_unstable();
    levels.dedup();
    assert!(levels.len() > 150, "{}", levels.len());
    Ok(())
}
