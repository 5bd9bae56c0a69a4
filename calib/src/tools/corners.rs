//! Harris corners, spread over the image: the keypoints of the panorama's
//! feature matches.
//!
//! OpenCV's `goodFeaturesToTrack` with the Harris score (3×3 blocks,
//! k = 0.04; computed in Rust by [`super::harris`], which gives OpenCV's
//! corners faster) keeps local maxima above a fraction of the best score
//! and suppresses any corner closer than `min_distance` to a stronger one
//! (non-maximum suppression). A textured building would then hold most
//! of the corners; so the image is cut into a grid of cells and each cell
//! keeps at most its `per_cell` strongest corners (a spatial spread).

use super::harris;
use crate::error::{cv, CalibError, Result};

/// Parameters of [`harris_corners`].
#[derive(Clone, Debug, PartialEq)]
pub struct HarrisParams {
    /// Corners OpenCV is asked for before the spread.
    pub max_corners: usize,
    /// The weakest Harris score kept, as a fraction of the strongest.
    pub quality: f64,
    /// The least distance between two corners, pixels.
    pub min_distance: f64,
    /// The grid's cell side, pixels.
    pub cell: usize,
    /// The most corners a cell keeps.
    pub per_cell: usize,
    /// Whether positions are refined to a fraction of a pixel: the peak of
    /// a parabola through the Harris response at the corner's pixel and its
    /// two neighbours, along each axis (by at most half a pixel). Off by
    /// default.
    pub subpixel: bool,
}

impl Default for HarrisParams {
    fn default() -> Self {
        Self {
            max_corners: 3000,
            quality: 0.0002,
            min_distance: 5.0,
            cell: 64,
            per_cell: 12,
            subpixel: false,
        }
    }
}

/// The Harris corners of a `width × height` grey image where `mask` (one
/// byte a pixel, non-zero to search; `None`: everywhere) allows, strongest
/// first within each cell of the spread, as (x, y) pixel positions.
pub fn harris_corners(
    gray: &[u8],
    width: usize,
    height: usize,
    mask: Option<&[u8]>,
    params: &HarrisParams,
) -> Result<Vec<[f32; 2]>> {
    let pixels = width
        .checked_mul(height)
        .ok_or_else(|| CalibError::Argument(format!("a {width}×{height} image is too large")))?;
    if gray.len() != pixels || mask.is_some_and(|m| m.len() != pixels) {
        return Err(CalibError::Argument(format!(
            "Harris corners: expected {pixels} bytes for a {width}×{height} image and its mask, got {} and {}",
            gray.len(),
            mask.map_or(pixels, <[u8]>::len)
        )));
    }
    if params.cell == 0 || params.max_corners == 0 {
        return Err(CalibError::Argument(
            "Harris corners: the cell side and the corner count must be positive".into(),
        ));
    }
    if height < 3 || width < 3 {
        return Ok(Vec::new());
    }
    let found = harris::good_features(gray, (width, height), mask, params);
    // Strongest first.
    let cells_x = width.div_ceil(params.cell);
    let mut taken = vec![0usize; cells_x * height.div_ceil(params.cell)];
    let mut out = Vec::new();
    for [x, y] in found {
        let (cx, cy) = (x as usize / params.cell, y as usize / params.cell);
        let Some(n) = taken.get_mut(cy * cells_x + cx.min(cells_x - 1)) else {
            continue;
        };
        if *n < params.per_cell {
            *n += 1;
            out.push(if params.subpixel {
                subpixel_near(gray, width, height, x, y)
            } else {
                [x, y]
            });
        }
    }
    Ok(out)
}

/// OpenCV's `goodFeaturesToTrack` with the Harris score (3×3 blocks,
/// k = 0.04) for `params`' corner count, quality and least distance, on
/// the same input as [`harris_corners`]: whole-pixel positions, strongest
/// first, before the spread. The reference that [`super::harris`] is
/// tested and measured against.
pub fn opencv_good_features(
    gray: &[u8],
    (width, height): (usize, usize),
    mask: Option<&[u8]>,
    params: &HarrisParams,
) -> Result<Vec<[f32; 2]>> {
    use opencv::core::{Mat, MatTraitConst, Point2f, Vector};
    let size = |v: usize| {
        i32::try_from(v).map_err(|_| CalibError::Argument(format!("a side of {v} pixels")))
    };
    let (rows, cols) = (size(height)?, size(width)?);
    let image = cv(
        "wrapping an image",
        Mat::new_rows_cols_with_data(rows, cols, gray),
    )?;
    let mask = match mask {
        Some(m) => cv(
            "copying a mask",
            cv(
                "wrapping a mask",
                Mat::new_rows_cols_with_data(rows, cols, m),
            )?
            .try_clone(),
        )?,
        None => Mat::default(),
    };
    let mut found = Vector::<Point2f>::new();
    cv(
        "detecting Harris corners",
        opencv::imgproc::good_features_to_track(
            &image,
            &mut found,
            i32::try_from(params.max_corners).unwrap_or(i32::MAX),
            params.quality,
            params.min_distance,
            &mask,
            3,
            true,
            0.04,
        ),
    )?;
    Ok(found.iter().map(|p| [p.x, p.y]).collect())
}

/// Reflects position `v` into `0..n` as OpenCV's `BORDER_REFLECT_101`.
pub(super) fn reflect101(v: i64, n: usize) -> usize {
    let n = n as i64;
    let mut v = v;
    if n == 1 {
        return 0;
    }
    while v < 0 || v >= n {
        v = if v < 0 { -v } else { 2 * (n - 1) - v };
    }
    v as usize
}

/// OpenCV's `cornerHarris` response (3×3 Sobel, 3×3 window, k = 0.04,
/// `BORDER_REFLECT_101`), up to a positive factor, at pixel (`x`, `y`) of a
/// `w`×`h` grey image and at its four neighbours (left, right, above,
/// below): computed at those five pixels instead of the whole image, from
/// the 5×5 gradients about the pixel (integers, so the sums are exact).
fn harris_near(gray: &[u8], w: usize, h: usize, x: i64, y: i64) -> [f64; 5] {
    let px = |u: i64, v: i64| f64::from(gray[reflect101(v, h) * w + reflect101(u, w)]);
    // The gradients at the window's positions, which reflect the gradient
    // images at the border.
    let mut g = [[(0.0f64, 0.0f64); 5]; 5];
    for (j, row) in g.iter_mut().enumerate() {
        for (i, g) in row.iter_mut().enumerate() {
            let (u, v) = (
                reflect101(x + i as i64 - 2, w) as i64,
                reflect101(y + j as i64 - 2, h) as i64,
            );
            let gx = px(u + 1, v - 1) + 2.0 * px(u + 1, v) + px(u + 1, v + 1)
                - px(u - 1, v - 1)
                - 2.0 * px(u - 1, v)
                - px(u - 1, v + 1);
            let gy = px(u - 1, v + 1) + 2.0 * px(u, v + 1) + px(u + 1, v + 1)
                - px(u - 1, v - 1)
                - 2.0 * px(u, v - 1)
                - px(u + 1, v - 1);
            *g = (gx, gy);
        }
    }
    let at = |cx: usize, cy: usize| {
        let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
        for row in &g[cy - 1..=cy + 1] {
            for &(gx, gy) in &row[cx - 1..=cx + 1] {
                xx += gx * gx;
                xy += gx * gy;
                yy += gy * gy;
            }
        }
        xx * yy - xy * xy - 0.04 * (xx + yy) * (xx + yy)
    };
    [at(2, 2), at(1, 2), at(3, 2), at(2, 1), at(2, 3)]
}

/// The peak of the Harris response near pixel (`x`, `y`): along each axis,
/// the vertex of the parabola through the pixel and its two neighbours
/// ([`vertex`]; the pixel itself at the border), with the response
/// computed at those five pixels only ([`harris_near`]; the vertex does
/// not depend on the response's scale).
fn subpixel_near(gray: &[u8], w: usize, h: usize, x: f32, y: f32) -> [f32; 2] {
    let (xi, yi) = (x.round() as i64, y.round() as i64);
    if xi < 1 || yi < 1 || xi + 1 >= w as i64 || yi + 1 >= h as i64 {
        return [x, y];
    }
    let [c, left, right, up, down] = harris_near(gray, w, h, xi, yi);
    [
        xi as f32 + vertex(left, c, right),
        yi as f32 + vertex(up, c, down),
    ]
}

/// The offset (within half a pixel) of the vertex of the parabola through
/// `a`, `b`, `c` at −1, 0, 1; 0 where `b` is not a peak.
fn vertex(a: f64, b: f64, c: f64) -> f32 {
    if a - 2.0 * b + c < 0.0 {
        (0.5 * (a - c) / (a - 2.0 * b + c)).clamp(-0.5, 0.5) as f32
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use opencv::core::{Mat, MatTraitConst};

    use super::*;

    /// A checkerboard of 8-pixel squares: a corner every 8 pixels.
    fn board(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                if ((i % w) / 8 + (i / w) / 8).is_multiple_of(2) {
                    40
                } else {
                    220
                }
            })
            .collect()
    }

    /// The peak near pixel (`x`, `y`) of the Harris response `r` (of the whole
    /// image, from OpenCV: what [`subpixel_near`] is tested against): along each
    /// axis, the vertex of the parabola through the pixel and its two
    /// neighbours, within half a pixel (the pixel itself at the border or where
    /// the response is not a peak).
    fn subpixel(r: &Mat, x: f32, y: f32) -> [f32; 2] {
        let (xi, yi) = (x.round() as i32, y.round() as i32);
        let inside = xi >= 1 && yi >= 1 && xi + 1 < r.cols() && yi + 1 < r.rows();
        if !inside {
            return [x, y];
        }
        let at = |dx: i32, dy: i32| f64::from(*r.at_2d::<f32>(yi + dy, xi + dx).unwrap());
        [
            xi as f32 + vertex(at(-1, 0), at(0, 0), at(1, 0)),
            yi as f32 + vertex(at(0, -1), at(0, 0), at(0, 1)),
        ]
    }

    /// The response at the corners' pixels gives the positions OpenCV's
    /// response of the whole image does.
    #[test]
    fn the_response_at_the_corners_is_opencvs() {
        let (w, h) = (120usize, 90usize);
        let img: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (128.0
                    + 60.0 * (x * 0.37).sin() * (y * 0.23).cos()
                    + 40.0 * ((x + 2.0 * y) * 0.11).sin()) as u8
            })
            .collect();
        let params = HarrisParams {
            subpixel: true,
            ..HarrisParams::default()
        };
        let windowed = harris_corners(&img, w, h, None, &params).unwrap();
        let plain = harris_corners(
            &img,
            w,
            h,
            None,
            &HarrisParams {
                subpixel: false,
                ..params.clone()
            },
        )
        .unwrap();
        let image = Mat::new_rows_cols_with_data(h as i32, w as i32, &img).unwrap();
        let mut whole = Mat::default();
        opencv::imgproc::corner_harris(
            &image,
            &mut whole,
            3,
            3,
            0.04,
            opencv::core::BORDER_DEFAULT,
        )
        .unwrap();
        assert!(windowed.len() > 20, "{} corners", windowed.len());
        assert_eq!(windowed.len(), plain.len());
        // Refined: most positions move off the pixel OpenCV found.
        let moved = windowed
            .iter()
            .zip(&plain)
            .filter(|(a, p)| (a[0] - p[0]).abs() + (a[1] - p[1]).abs() > 0.05)
            .count();
        assert!(2 * moved > windowed.len(), "{moved} of {}", windowed.len());
        for (a, p) in windowed.iter().zip(&plain) {
            let b = subpixel(&whole, p[0], p[1]);
            assert!(
                (a[0] - b[0]).abs() < 1e-4 && (a[1] - b[1]).abs() < 1e-4,
                "{a:?} {b:?}"
            );
        }
    }

    #[test]
    fn subpixel_positions_find_corners_between_pixels() {
        // The squares' corners lie between pixels (x + ½ a multiple of 8):
        // whole pixels are half a pixel off along each axis, the refined
        // positions within a tenth.
        let (w, h) = (128, 64);
        let img = board(w, h);
        let off = |p: &[f32; 2]| {
            let d = |v: f32| {
                let r = (v + 0.5).rem_euclid(8.0);
                r.min(8.0 - r)
            };
            d(p[0]).max(d(p[1]))
        };
        let refined = HarrisParams {
            subpixel: true,
            ..HarrisParams::default()
        };
        let refined = harris_corners(&img, w, h, None, &refined).unwrap();
        let whole = harris_corners(&img, w, h, None, &HarrisParams::default()).unwrap();
        assert!(refined.len() > 20 && refined.len() == whole.len());
        assert!(refined.iter().all(|p| off(p) < 0.1), "{refined:?}");
        assert!(whole.iter().all(|p| off(p) >= 0.4), "{whole:?}");
    }

    #[test]
    fn corners_are_spread_masked_and_on_the_squares_corners() {
        let (w, h) = (256, 128);
        let img = board(w, h);
        let params = HarrisParams {
            cell: 64,
            per_cell: 5,
            ..HarrisParams::default()
        };
        let all = harris_corners(&img, w, h, None, &params).unwrap();
        // 4 × 2 cells of at most 5 each, every cell full.
        assert_eq!(all.len(), 40, "{all:?}");
        for p in &all {
            // Each near a grid corner (sub-pixel positions are not refined:
            // within a pixel).
            let off = |v: f32| {
                let r = v.rem_euclid(8.0);
                r.min(8.0 - r)
            };
            assert!(off(p[0] + 0.5) <= 1.0 && off(p[1] + 0.5) <= 1.0, "{p:?}");
        }
        // A mask of the left half: no corner on the right.
        let mask: Vec<u8> = (0..w * h).map(|i| u8::from(i % w < w / 2) * 255).collect();
        let left = harris_corners(&img, w, h, Some(&mask), &params).unwrap();
        assert_eq!(left.len(), 20);
        assert!(left.iter().all(|p| p[0] < (w / 2) as f32));
        // A flat image has none; a wrong size is an error.
        assert!(harris_corners(&vec![9; w * h], w, h, None, &params)
            .unwrap()
            .is_empty());
        assert!(harris_corners(&img, w + 1, h, None, &params).is_err());
    }
}
