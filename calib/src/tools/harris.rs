//! OpenCV's `goodFeaturesToTrack` with the Harris score (3×3 Sobel, 3×3
//! block, k = 0.04, `BORDER_REFLECT_101`), computed in one pass over the
//! image's rows in exact arithmetic.
//!
//! OpenCV computes the whole image's response in `f32` (`cornerHarris`:
//! the Sobel images, their products, a box filter, the response), takes
//! its masked maximum, thresholds the image, dilates it, collects every
//! pixel equal to its dilation, sorts them and keeps the strongest that
//! lie at least `min_distance` from a stronger one. Here:
//!
//! - The Sobel derivatives are integers (at most 4·255 in magnitude), and
//!   so are their products and the 3×3 sums of the products (`A`, `B`,
//!   `C`, below 2²⁴). OpenCV's response is `s⁴·(AC − B² − k(A + C)²)`
//!   with `s = 1/(4·3·255)`; with `k = 1/25` the integer
//!   `R = 25(AC − B²) − (A + C)²` (below 2⁵²) has the same order and is
//!   exact in `f64`, so neither the order of the corners nor the local
//!   maxima depend on rounding.
//! - The rows are computed in turn, each from the five source rows about
//!   it, and only three rows of the response are kept: the image's
//!   response is never stored.
//! - The local maxima (a pixel at least as strong as its eight
//!   neighbours, positive, off the image's outermost ring, in the mask)
//!   are collected with their response while the masked maximum is
//!   found; the quality threshold (a fraction of that maximum) is applied
//!   after. This is OpenCV's selection: a pixel above the threshold equals
//!   the dilation of the thresholded response exactly when no neighbour
//!   is stronger.
//! - The order is OpenCV's: strongest first, ties broken by the later
//!   pixel (OpenCV compares the pixels' addresses); the spacing is its
//!   grid of `round(min_distance)` cells.
//!
//! So the corners are OpenCV's, except where OpenCV's `f32` response
//! rounds two different responses to the same value or orders them the
//! other way (tested against OpenCV on real frames:
//! `the_corners_are_opencvs`). An image whose masked maximum is not
//! positive has no corners (OpenCV would return points of negative
//! response: there is no corner there).

use super::corners::{reflect101, HarrisParams};

/// Corners of a `w × h` grey image (`w`, `h` ≥ 3; `gray` and `mask` of
/// `w·h` bytes, checked by the caller), as OpenCV's `goodFeaturesToTrack`
/// with the Harris score returns them (see the module documentation) for
/// `params`' corner count (≥ 1), quality and least distance: whole-pixel
/// positions, strongest first.
pub(super) fn good_features(
    gray: &[u8],
    (w, h): (usize, usize),
    mask: Option<&[u8]>,
    params: &HarrisParams,
) -> Vec<[f32; 2]> {
    let (max_corners, min_distance) = (params.max_corners, params.min_distance);
    let Some(mut found) = maxima(gray, (w, h), mask) else {
        return Vec::new();
    };
    let threshold = found.max * params.quality;
    found.list.retain(|&(r, _)| r > threshold);
    // Strongest first; of equal responses, the later pixel first.
    found
        .list
        .sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(b.1.cmp(&a.1)));
    let at = |i: usize| ((i % w) as f32, (i / w) as f32);
    if min_distance < 1.0 {
        return found
            .list
            .iter()
            .take(max_corners)
            .map(|&(_, i)| {
                let (x, y) = at(i);
                [x, y]
            })
            .collect();
    }
    let cell = (min_distance.round_ties_even() as usize).max(1);
    let (gw, gh) = (w.div_ceil(cell), h.div_ceil(cell));
    let mut grid: Vec<Vec<(f32, f32)>> = vec![Vec::new(); gw * gh];
    let limit = min_distance * min_distance;
    let mut out = Vec::new();
    for &(_, i) in &found.list {
        let (x, y) = at(i);
        let (cx, cy) = (i % w / cell, i / w / cell);
        let near = (cy.saturating_sub(1)..=(cy + 1).min(gh - 1)).any(|gy| {
            (cx.saturating_sub(1)..=(cx + 1).min(gw - 1)).any(|gx| {
                grid[gy * gw + gx].iter().any(|&(px, py)| {
                    let (dx, dy) = (x - px, y - py);
                    f64::from(dx * dx + dy * dy) < limit
                })
            })
        });
        if !near {
            grid[cy * gw + cx].push((x, y));
            out.push([x, y]);
            if out.len() == max_corners {
                break;
            }
        }
    }
    out
}

/// The local maxima of a response and the response's masked maximum.
#[derive(Debug, Default)]
struct Maxima {
    /// Positive local maxima in the mask: (response, pixel index).
    list: Vec<(f64, usize)>,
    /// The largest response in the mask.
    max: f64,
}

/// [`Maxima`] of the Harris response `R` of `gray` (see the module
/// documentation); `None` where the masked maximum is not positive.
fn maxima(gray: &[u8], (w, h): (usize, usize), mask: Option<&[u8]>) -> Option<Maxima> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, the one feature `maxima_avx2` is
        // compiled for.
        #[allow(unsafe_code)]
        return unsafe { maxima_avx2(gray, (w, h), mask) };
    }
    maxima_in(gray, (w, h), mask)
}

/// [`maxima_in`] compiled for AVX2.
///
/// # Safety
///
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn maxima_avx2(gray: &[u8], size: (usize, usize), mask: Option<&[u8]>) -> Option<Maxima> {
    maxima_in(gray, size, mask)
}

/// Row `y`'s products of the Sobel derivatives (`xx`, `xy`, `yy`),
/// summed over each pixel's three columns, into `out`; `s` and `d` are
/// scratch rows of `w`.
#[inline(always)]
fn box_row(
    gray: &[u8],
    (w, h): (usize, usize),
    y: usize,
    (s, d): (&mut [i32], &mut [i32]),
    out: &mut [Vec<i32>; 3],
) {
    let row = |r: usize| &gray[r * w..(r + 1) * w];
    let (up, mid, down) = (
        row(reflect101(y as i64 - 1, h)),
        row(y),
        row(reflect101(y as i64 + 1, h)),
    );
    // Down each column: the smoothing [1 2 1] and the difference [−1 0 1].
    for ((((s, d), &u), &m), &b) in s.iter_mut().zip(d.iter_mut()).zip(up).zip(mid).zip(down) {
        let (u, m, b) = (i32::from(u), i32::from(m), i32::from(b));
        *s = u + 2 * m + b;
        *d = b - u;
    }
    let [xx, xy, yy] = out;
    // Along the row: gx = s[x+1] − s[x−1], gy = d[x−1] + 2d[x] + d[x+1],
    // the columns reflected at the ends.
    let product = |gx: i32, gy: i32| (gx * gx, gx * gy, gy * gy);
    let (first, last) = (
        product(0, 2 * (d[0] + d[1])),
        product(0, 2 * (d[w - 1] + d[w - 2])),
    );
    xx[0] = first.0;
    xy[0] = first.1;
    yy[0] = first.2;
    let inner = s
        .windows(3)
        .zip(d.windows(3))
        .zip(xx[1..w - 1].iter_mut())
        .zip(xy[1..w - 1].iter_mut())
        .zip(yy[1..w - 1].iter_mut());
    for ((((s, d), xx), xy), yy) in inner {
        let gx = s[2] - s[0];
        let gy = d[0] + 2 * d[1] + d[2];
        *xx = gx * gx;
        *xy = gx * gy;
        *yy = gy * gy;
    }
    xx[w - 1] = last.0;
    xy[w - 1] = last.1;
    yy[w - 1] = last.2;
    // The three columns about each pixel, reflected at the ends: in place
    // through `s` (the products' row copied there first).
    for c in [xx, xy, yy] {
        s.copy_from_slice(c);
        c[0] = s[0] + 2 * s[1];
        c[w - 1] = s[w - 1] + 2 * s[w - 2];
        for (c, s) in c[1..w - 1].iter_mut().zip(s.windows(3)) {
            *c = s[0] + s[1] + s[2];
        }
    }
}

/// The body of [`maxima`]: the rows in turn (see the module
/// documentation), three rows of column sums and of response kept.
#[inline(always)]
fn maxima_in(gray: &[u8], (w, h): (usize, usize), mask: Option<&[u8]>) -> Option<Maxima> {
    let mut s = vec![0i32; w];
    let mut d = vec![0i32; w];
    // Rows `y` of the column sums and of the response are kept in slot
    // `y % 3`.
    let mut sums: [[Vec<i32>; 3]; 3] = std::array::from_fn(|_| std::array::from_fn(|_| vec![0; w]));
    let mut response: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; w]);
    let mut peaks = vec![0u8; w];
    let mut found = Maxima {
        list: Vec::new(),
        max: f64::NEG_INFINITY,
    };
    box_row(gray, (w, h), 0, (&mut s, &mut d), &mut sums[0]);
    for y in 0..h {
        if y + 1 < h {
            box_row(
                gray,
                (w, h),
                y + 1,
                (&mut s, &mut d),
                &mut sums[(y + 1) % 3],
            );
        }
        // Rows y − 1 and y + 1, reflected at the ends.
        let (above, below) = (
            reflect101(y as i64 - 1, h) % 3,
            reflect101(y as i64 + 1, h) % 3,
        );
        let r = &mut response[y % 3];
        {
            let [a0, b0, c0] = &sums[above];
            let [a1, b1, c1] = &sums[y % 3];
            let [a2, b2, c2] = &sums[below];
            let terms = r
                .iter_mut()
                .zip(a0.iter().zip(a1).zip(a2))
                .zip(b0.iter().zip(b1).zip(b2))
                .zip(c0.iter().zip(c1).zip(c2));
            for (((r, ((&a0, &a1), &a2)), ((&b0, &b1), &b2)), ((&c0, &c1), &c2)) in terms {
                let a = f64::from(a0 + a1 + a2);
                let b = f64::from(b0 + b1 + b2);
                let c = f64::from(c0 + c1 + c2);
                *r = 25.0 * (a * c - b * b) - (a + c) * (a + c);
            }
        }
        let row_mask = mask.map(|m| &m[y * w..(y + 1) * w]);
        found.max = found.max.max(row_max(r, row_mask));
        // Row y − 1's maxima, now that its neighbours below are known.
        if y >= 2 {
            let c = y - 1;
            let (up, mid, down) = (&response[(c - 1) % 3], &response[c % 3], &response[y % 3]);
            let m = mask.map(|m| &m[c * w..(c + 1) * w]);
            push_maxima((up, mid, down), m, c * w, &mut peaks, &mut found.list);
        }
    }
    (found.max > 0.0).then_some(found)
}

/// The largest of `r` where `mask` (if any) is not zero; −∞ for none.
#[inline(always)]
fn row_max(r: &[f64], mask: Option<&[u8]>) -> f64 {
    // Eight running maxima, element by element (vectorised), then theirs.
    let mut lanes = [f64::NEG_INFINITY; 8];
    let mut fold = |chunk: &[f64; 8], m: [u8; 8]| {
        for i in 0..8 {
            let v = if m[i] == 0 {
                f64::NEG_INFINITY
            } else {
                chunk[i]
            };
            lanes[i] = if v > lanes[i] { v } else { lanes[i] };
        }
    };
    let all = [1u8; 8];
    let whole = r.len() - r.len() % 8;
    match mask {
        Some(mask) => {
            for (c, m) in r.chunks_exact(8).zip(mask.chunks_exact(8)) {
                if let (Some(c), Some(m)) = (c.first_chunk(), m.first_chunk()) {
                    fold(c, *m);
                }
            }
        }
        None => {
            for c in r.chunks_exact(8) {
                if let Some(c) = c.first_chunk() {
                    fold(c, all);
                }
            }
        }
    }
    let tail = r[whole..]
        .iter()
        .enumerate()
        .filter(|&(i, _)| mask.is_none_or(|m| m.get(whole + i).is_some_and(|&m| m != 0)))
        .fold(f64::NEG_INFINITY, |a, (_, &v)| if v > a { v } else { a });
    lanes.iter().fold(tail, |a, &l| if l > a { l } else { a })
}

/// Appends to `list` the pixels of row `mid` (its first pixel being
/// canvas index `base`), off its first and last column, that are positive,
/// at least as strong as their eight neighbours in rows `up`, `mid` and
/// `down`, and in `mask` (if any); `peaks` is a scratch row.
#[inline(always)]
fn push_maxima(
    (up, mid, down): (&[f64], &[f64], &[f64]),
    mask: Option<&[u8]>,
    base: usize,
    peaks: &mut [u8],
    list: &mut Vec<(f64, usize)>,
) {
    let n = mid.len().saturating_sub(2);
    let (peaks, u, m, d) = (&mut peaks[..n], &up[..n + 2], &mid[..n + 2], &down[..n + 2]);
    for (x, p) in peaks.iter_mut().enumerate() {
        let v = m[x + 1];
        // Non-short-circuiting: one mask of comparisons.
        let peak = (v > 0.0)
            & (v >= m[x])
            & (v >= m[x + 2])
            & (v >= u[x])
            & (v >= u[x + 1])
            & (v >= u[x + 2])
            & (v >= d[x])
            & (v >= d[x + 1])
            & (v >= d[x + 2]);
        *p = u8::from(peak);
    }
    if let Some(k) = mask.and_then(|k| k.get(1..n + 1)) {
        for (p, &k) in peaks.iter_mut().zip(k) {
            *p &= u8::from(k != 0);
        }
    }
    // Eight flags at a time: most are zero.
    for (c, word) in peaks.chunks(8).enumerate() {
        let mut bytes = [0u8; 8];
        bytes[..word.len()].copy_from_slice(word);
        let mut bits = u64::from_le_bytes(bytes);
        while bits != 0 {
            let x = 8 * c + bits.trailing_zeros() as usize / 8;
            bits &= !(0xff << (bits.trailing_zeros() / 8 * 8));
            list.push((m[x + 1], base + x + 1));
        }
    }
}

#[cfg(test)]
mod tests {
    // Whole-pixel positions are compared exactly.
    #![allow(clippy::unwrap_used, clippy::float_cmp)]
    use std::path::PathBuf;

    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::tools::corners::opencv_good_features;

    /// A real frame of the repository's data, as grey (Rec. 601 luma).
    fn frame(name: &str) -> (Vec<u8>, (usize, usize)) {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../tests/data")
            .join(name);
        let img = image::open(&path).unwrap().to_luma8();
        let size = (img.width() as usize, img.height() as usize);
        (img.into_raw(), size)
    }

    /// How many of `a`'s corners `b` has too, and how many of the first
    /// `n` are in the same place of both lists.
    fn agreement(a: &[[f32; 2]], b: &[[f32; 2]]) -> (usize, usize) {
        let shared = a.iter().filter(|p| b.contains(p)).count();
        let same_place = a.iter().zip(b).filter(|(p, q)| p == q).count();
        (shared, same_place)
    }

    #[test]
    fn the_corners_are_opencvs() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for name in [
            "surround-nz/front.png",
            "surround-nz/left.png",
            "opencv-samples/graf1.png",
        ] {
            let (gray, (w, h)) = frame(name);
            // No mask, a random mask of blobs, and the panorama's settings
            // and some others.
            let blobs: Vec<u8> = {
                let centres: Vec<(f64, f64)> = (0..12)
                    .map(|_| (rng.gen_range(0.0..w as f64), rng.gen_range(0.0..h as f64)))
                    .collect();
                (0..w * h)
                    .map(|i| {
                        let (x, y) = ((i % w) as f64, (i / w) as f64);
                        let inside = centres
                            .iter()
                            .any(|&(cx, cy)| (x - cx).hypot(y - cy) < 0.15 * w as f64);
                        u8::from(inside) * 255
                    })
                    .collect()
            };
            for (mask, max, quality, distance) in [
                (None, 3000, 0.0002, 5.0),
                (Some(&blobs[..]), 3000, 0.0002, 5.0),
                (None, 500, 0.01, 10.0),
                (Some(&blobs[..]), 100000, 0.001, 0.5),
            ] {
                let params = HarrisParams {
                    max_corners: max,
                    quality,
                    min_distance: distance,
                    ..HarrisParams::default()
                };
                let ours = good_features(&gray, (w, h), mask, &params);
                let theirs = opencv_good_features(&gray, (w, h), mask, &params).unwrap();
                let (shared, same_place) = agreement(&ours, &theirs);
                eprintln!(
                    "{name}, mask {}, {max}, {quality}, {distance}: {} corners, OpenCV {}; {shared} shared, {same_place} in the same place",
                    mask.is_some(),
                    ours.len(),
                    theirs.len()
                );
                assert!(ours.len() > 50, "{name}: {} corners", ours.len());
                // The baseline kernels find the same maxima as the
                // dispatched ones (AVX2 where the CPU has it).
                let (a, b) = (
                    maxima(&gray, (w, h), mask).unwrap(),
                    maxima_in(&gray, (w, h), mask).unwrap(),
                );
                assert_eq!(a.list, b.list, "{name}");
                assert_eq!(a.max.to_bits(), b.max.to_bits(), "{name}");
                assert_eq!(ours.len(), theirs.len(), "{name}");
                // OpenCV's f32 response rounds and orders nearly equal
                // responses its own way: at most one corner in 200 differs.
                assert!(
                    200 * shared >= 199 * ours.len(),
                    "{name}: {shared} of {}",
                    ours.len()
                );
                assert!(
                    100 * same_place >= 95 * ours.len(),
                    "{name}: {same_place} of {}",
                    ours.len()
                );
                if let Some(m) = mask {
                    assert!(ours
                        .iter()
                        .all(|p| m[p[1] as usize * w + p[0] as usize] != 0));
                }
            }
        }
    }

    #[test]
    fn small_flat_and_masked_out_images_have_the_corners_opencv_finds() {
        let params = HarrisParams::default();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        // Random images down to 3×3, whole and masked: OpenCV's corners.
        for (w, h) in [(3, 3), (3, 7), (7, 3), (4, 4), (9, 5), (31, 17)] {
            let gray: Vec<u8> = (0..w * h).map(|_| rng.gen()).collect();
            let mask: Vec<u8> = (0..w * h)
                .map(|_| u8::from(rng.gen_bool(0.6)) * 255)
                .collect();
            for mask in [None, Some(&mask[..])] {
                let ours = good_features(&gray, (w, h), mask, &params);
                let theirs = opencv_good_features(&gray, (w, h), mask, &params).unwrap();
                assert_eq!(ours, theirs, "{w}×{h}, mask {}", mask.is_some());
            }
        }
        // A flat image, and a mask that allows nothing: no corners.
        let (w, h) = (40, 30);
        let gray: Vec<u8> = (0..w * h).map(|_| rng.gen()).collect();
        assert!(good_features(&vec![90; w * h], (w, h), None, &params).is_empty());
        assert!(good_features(&gray, (w, h), Some(&vec![0; w * h]), &params).is_empty());
        // The corner count caps the list, strongest first.
        let few = HarrisParams {
            max_corners: 5,
            ..params.clone()
        };
        let all = good_features(&gray, (w, h), None, &params);
        assert!(all.len() > 5);
        assert_eq!(good_features(&gray, (w, h), None, &few), all[..5]);
    }
}
