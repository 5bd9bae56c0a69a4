//! The exact Euclidean distance transform of a binary image: for every
//! pixel, the distance to the nearest zero pixel.
//!
//! Felzenszwalb and Huttenlocher, "Distance Transforms of Sampled
//! Functions" (Theory of Computing 8, 2012), in two passes of 1-D
//! transforms:
//!
//! 1. per column, the distance `g(x, y)` from each pixel to the nearest zero
//!    of its column (counted in two sweeps, down and up);
//! 2. per row, the lower envelope of the parabolas `g(p, y)² + (x − p)²`:
//!
//! ```text
//! D(x, y)² = min_p ( g(p, y)² + (x − p)² )
//! ```
//!
//! The envelope is built left to right, keeping the parabolas that are the
//! lowest somewhere and the abscissas where each takes over from the one
//! before: the parabolas of `p` and `q > p` cross at
//! `s = ((f_q + q²) − (f_p + p²)) / (2(q − p))`, with `f = g²`. Both passes
//! are linear in the pixels. Every `D²` is an integer and is computed
//! exactly (in `f64`); the distance is its square root in `f32`, as OpenCV's
//! `distanceTransform` with `DIST_L2` and `DIST_MASK_PRECISE` gives it
//! (which implements the same algorithm).
//!
//! A column without a zero contributes `g² = 10¹⁵` (OpenCV's stand-in for
//! infinity): the other columns' parabolas win wherever the row has any,
//! and an image without any zero gets distances of about 3.2·10⁷.

use crate::error::{Error, Result};

/// `g²` of a column without a zero.
const FAR: f64 = 1e15;

/// The distance (pixels, L2) of every pixel of the `width × height` image
/// `mask` (one byte per pixel, row-major) to the nearest pixel whose byte is
/// 0; 0 on the zero pixels themselves.
pub fn distance_to_zero(mask: &[u8], width: usize, height: usize) -> Result<Vec<f32>> {
    if width == 0 || height == 0 {
        return Err(Error::EmptyImage {
            what: "distance transform mask",
            width,
            height,
        });
    }
    let pixels = width.saturating_mul(height);
    if mask.len() != pixels {
        return Err(Error::BufferSize {
            what: "distance transform mask",
            expected: pixels,
            actual: mask.len(),
            detail: format!("one byte per pixel, {width}×{height}"),
        });
    }
    let column = column_distances(mask, width);
    let mut out = vec![0.0f32; pixels];
    let mut f = vec![0.0f64; width];
    let mut envelope = Envelope::new(width);
    for (g, out) in column.chunks_exact(width).zip(out.chunks_exact_mut(width)) {
        for (f, &g) in f.iter_mut().zip(g) {
            *f = if g == u32::MAX {
                FAR
            } else {
                f64::from(g) * f64::from(g)
            };
        }
        envelope.transform(&f, out);
    }
    Ok(out)
}

/// Per pixel, the distance to the nearest zero of its column (`u32::MAX`
/// when the column has none), in two sweeps over the rows: down, counting
/// the rows since the last zero above, then up.
fn column_distances(mask: &[u8], width: usize) -> Vec<u32> {
    let mut column = vec![0u32; mask.len()];
    let mut run = vec![u32::MAX; width];
    for (m, c) in mask.chunks_exact(width).zip(column.chunks_exact_mut(width)) {
        for ((&m, c), r) in m.iter().zip(c.iter_mut()).zip(run.iter_mut()) {
            *r = if m == 0 { 0 } else { r.saturating_add(1) };
            *c = *r;
        }
    }
    run.fill(u32::MAX);
    for (m, c) in mask
        .chunks_exact(width)
        .zip(column.chunks_exact_mut(width))
        .rev()
    {
        for ((&m, c), r) in m.iter().zip(c.iter_mut()).zip(run.iter_mut()) {
            *r = if m == 0 { 0 } else { r.saturating_add(1) };
            *c = (*c).min(*r);
        }
    }
    column
}

/// The lower envelope of one row's parabolas, with its buffers.
struct Envelope {
    /// The parabolas (their abscissas `p`) of the envelope, left to right.
    v: Vec<usize>,
    /// Where each of them takes over: parabola `v[k]` is the lowest on
    /// `[z[k], z[k + 1]]`.
    z: Vec<f64>,
}

impl Envelope {
    fn new(width: usize) -> Self {
        Self {
            v: vec![0; width],
            z: vec![0.0; width + 1],
        }
    }

    /// `out[x] = √ min_p (f[p] + (x − p)²)` (`f` and `out` of one length, at
    /// most the width the envelope was made for).
    fn transform(&mut self, f: &[f64], out: &mut [f32]) {
        let n = f.len().min(out.len()).min(self.v.len());
        if n == 0 {
            return;
        }
        let (v, z) = (&mut self.v, &mut self.z);
        let sq = |p: usize| (p * p) as f64;
        let mut k = 0;
        v[0] = 0;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        for q in 1..n {
            let fq = f[q] + sq(q);
            // `z[0]` is −∞ and `s` finite, so the loop stops at `k = 0` at
            // the latest.
            loop {
                let p = v[k];
                let s = (fq - (f[p] + sq(p))) / (2 * (q - p)) as f64;
                if s > z[k] {
                    k += 1;
                    v[k] = q;
                    z[k] = s;
                    z[k + 1] = f64::INFINITY;
                    break;
                }
                k -= 1;
            }
        }
        k = 0;
        for (q, o) in out[..n].iter_mut().enumerate() {
            while z[k + 1] < q as f64 {
                k += 1;
            }
            let p = v[k];
            let d2 = sq(q.abs_diff(p)) + f[p];
            *o = (d2 as f32).sqrt();
        }
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;

    /// The distances by brute force, in double precision.
    fn brute_force(mask: &[u8], w: usize, h: usize) -> Vec<f64> {
        let zeros: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| mask[i] == 0)
            .map(|i| (i % w, i / w))
            .collect();
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                zeros
                    .iter()
                    .map(|&(zx, zy)| {
                        let (dx, dy) = (x.abs_diff(zx) as f64, y.abs_diff(zy) as f64);
                        (dx * dx + dy * dy).sqrt()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    #[test]
    fn distances_are_exact_against_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        // Sparse and dense zeros, thin and wide images, rows and columns
        // without a zero.
        for (w, h, zero_share) in [
            (1, 1, 1.0),
            (1, 9, 0.2),
            (13, 1, 0.2),
            (37, 23, 0.01),
            (37, 23, 0.3),
            (64, 41, 0.002),
        ] {
            let mut mask: Vec<u8> = (0..w * h)
                .map(|_| if rng.gen_bool(zero_share) { 0 } else { 255 })
                .collect();
            // At least one zero.
            mask[rng.gen_range(0..w * h)] = 0;
            let got = distance_to_zero(&mask, w, h).unwrap();
            let want = brute_force(&mask, w, h);
            for (i, (&g, &e)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (f64::from(g) - e).abs() <= 1e-6 * e.max(1.0),
                    "{w}×{h}, pixel ({}, {}): {g} vs {e}",
                    i % w,
                    i / w
                );
            }
            assert!(got.iter().zip(&mask).all(|(&d, &m)| (d <= 0.0) == (m == 0)));
        }
    }

    #[test]
    fn an_image_without_a_zero_is_far_from_one_everywhere() {
        let d = distance_to_zero(&[7u8; 12], 4, 3).unwrap();
        assert!(d.iter().all(|&v| v.is_finite() && v > 3.0e7), "{d:?}");
    }

    #[test]
    fn masks_of_the_wrong_size_are_refused() {
        assert!(matches!(
            distance_to_zero(&[0u8; 11], 4, 3),
            Err(Error::BufferSize { .. })
        ));
        assert!(matches!(
            distance_to_zero(&[], 0, 3),
            Err(Error::EmptyImage { .. })
        ));
    }
}
