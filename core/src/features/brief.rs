//! BRIEF descriptors (Calonder et al., ECCV 2010): 256 binary intensity
//! tests on a smoothed patch around a keypoint.
//!
//! # Smoothing
//!
//! Single pixels are too noisy for binary tests, so the image is smoothed
//! first ([`Smoothed::new`]) by a separable 9-tap approximation of a
//! Gaussian with σ = 2 px (the paper's choice), in integers so that a
//! uniform region stays exactly uniform:
//!
//! ```text
//! weights (offset −4 … 4): 7, 17, 32, 46, 52, 46, 32, 17, 7   (sum 256)
//! ```
//!
//! (round(256·e^(−x²/8) / Σ), adjusted to sum to 256). Rows are filtered
//! first into 16-bit sums, then columns, and the result is rounded:
//! `s = (Σ_y w_y Σ_x w_x I + 2¹⁵) >> 16`. The image border is replicated.
//!
//! # The sampling pattern
//!
//! The paper's pattern G II: 256 pairs of points (p, q) drawn independently
//! from an isotropic Gaussian of σ = S/5 around the keypoint, on a patch of
//! S × S = 48 × 48 pixels, so σ = 9.6 px. Each coordinate is rounded to the
//! nearest pixel and clamped to ±[`PATCH_RADIUS`] = ±24. The pattern is
//! generated once, deterministically: ChaCha8 seeded with [`PATTERN_SEED`],
//! two uniforms per Gaussian by Box–Muller (`√(−2 ln(1−u₁))·cos(2π u₂)`
//! and the same with sin), in the order p.x, p.y, q.x, q.y; a pair whose two
//! points coincide (a test that is always 0) is drawn again. Its first pairs
//! are pinned by a unit test: ((−2, −9), (−4, 1)), ((−3, 12), (7, −21)),
//! ((1, 10), (−3, 3)).
//!
//! # The descriptor and its distance
//!
//! Bit i (bit i mod 64 of word i / 64) is 1 when s(k + pᵢ) < s(k + qᵢ), k
//! being the keypoint rounded to the nearest pixel. Keypoints closer than
//! [`PATCH_RADIUS`] to the border get no descriptor. Two descriptors differ
//! by their Hamming distance, the popcount of their XOR.
//!
//! # Matching
//!
//! [`match_mutual`] keeps a pair (i, j) when j is i's nearest neighbour, i
//! is j's, and i's nearest distance is below `ratio` × its second nearest
//! (Lowe's ratio test, here on Hamming distances).

use std::sync::OnceLock;

use rand::{Rng, SeedableRng};

use crate::error::{Error, Result};

/// Half the side of the sampling patch: pattern coordinates lie in
/// −24 … 24 (S = 48).
pub const PATCH_RADIUS: usize = 24;

/// The seed of the sampling pattern's generator.
pub const PATTERN_SEED: u64 = 0x4252_4945_4632_3536;

/// The smoothing kernel, offsets −4 … 4; sums to 256.
pub const SMOOTHING_KERNEL: [u32; 9] = [7, 17, 32, 46, 52, 46, 32, 17, 7];

/// The number of binary tests.
pub const BITS: usize = 256;

/// A BRIEF descriptor: 256 bits, bit i in bit i mod 64 of word i / 64.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Descriptor(pub [u64; 4]);

impl Descriptor {
    /// Bit `i` (0 … 255).
    pub fn bit(&self, i: usize) -> bool {
        self.0[i / 64] >> (i % 64) & 1 == 1
    }

    /// The Hamming distance: the number of bits that differ.
    pub fn distance(&self, other: &Descriptor) -> u32 {
        self.0
            .iter()
            .zip(&other.0)
            .map(|(a, b)| (a ^ b).count_ones())
            .sum()
    }
}

/// A Mono8 image smoothed for BRIEF's tests (see the module's
/// documentation for the kernel).
#[derive(Clone, Debug, PartialEq)]
pub struct Smoothed {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

/// The BRIEF smoothing of a packed `width × height` Mono8 image (its size
/// checked by the caller), with the kernels of the widest instruction set
/// the CPU has: AVX2 where it has it (the same integer sums, so the same
/// bytes), baseline x86-64 otherwise.
fn smooth(gray: &[u8], width: usize, height: usize) -> Vec<u8> {
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::Isa::detect() >= crate::cpu::Isa::Avx2 {
        // SAFETY: `detect` names AVX2 or wider only when the CPU has AVX2,
        // the one feature `smooth_avx2` is compiled for.
        #[allow(unsafe_code)]
        return unsafe { smooth_avx2(gray, width, height) };
    }
    smooth_in(gray, width, height)
}

/// [`smooth_in`] compiled for AVX2.
///
/// # Safety
///
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn smooth_avx2(gray: &[u8], width: usize, height: usize) -> Vec<u8> {
    smooth_in(gray, width, height)
}

/// The body of [`smooth`]: rows, then columns, in integers.
#[inline(always)]
fn smooth_in(gray: &[u8], width: usize, height: usize) -> Vec<u8> {
    let expected = width * height;
    let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    // Rows: 16-bit sums of up to 255 × 256 (exact in u16). The interior
    // tap by tap over whole rows (the compiler vectorises it), the
    // four pixels at each end with the border replicated.
    let mut rows = vec![0u16; expected];
    for (src, out) in gray.chunks_exact(width).zip(rows.chunks_exact_mut(width)) {
        if width > 8 {
            let inner = width - 8;
            for (t, &w) in SMOOTHING_KERNEL.iter().enumerate() {
                let w = w as u16;
                for (o, &v) in out[4..4 + inner].iter_mut().zip(&src[t..t + inner]) {
                    *o += w * u16::from(v);
                }
            }
        }
        for x in (0..width.min(4)).chain(width.saturating_sub(4).max(4)..width) {
            let mut sum = 0u32;
            for (t, &w) in SMOOTHING_KERNEL.iter().enumerate() {
                sum += w * u32::from(src[clamp(x as isize + t as isize - 4, width)]);
            }
            out[x] = sum as u16;
        }
    }
    // Columns: each output row sums nine rows (replicated at the top
    // and bottom), tap by tap over the whole row.
    let mut data = vec![0u8; expected];
    let mut acc = vec![0u32; width];
    for (y, out) in data.chunks_exact_mut(width).enumerate() {
        acc.fill(0);
        for (t, &w) in SMOOTHING_KERNEL.iter().enumerate() {
            let yy = clamp(y as isize + t as isize - 4, height);
            for (a, &v) in acc.iter_mut().zip(&rows[yy * width..(yy + 1) * width]) {
                *a += w * u32::from(v);
            }
        }
        for (o, &a) in out.iter_mut().zip(&acc) {
            *o = ((a + (1 << 15)) >> 16) as u8;
        }
    }
    data
}

impl Smoothed {
    /// Smooths a packed Mono8 image of `width` × `height`.
    pub fn new(gray: &[u8], width: usize, height: usize) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::EmptyImage {
                what: "BRIEF image",
                width,
                height,
            });
        }
        let expected = width.checked_mul(height).ok_or_else(|| {
            Error::invalid(
                "BRIEF image",
                "size",
                "a pixel count that fits in memory",
                format_args!("{width}×{height}"),
            )
        })?;
        if gray.len() != expected {
            return Err(Error::BufferSize {
                what: "BRIEF image",
                expected,
                actual: gray.len(),
                detail: format!("Mono8 {width}×{height}, packed"),
            });
        }
        let data = smooth(gray, width, height);
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Width, height.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The smoothed value at a pixel.
    pub fn at(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.width + x]
    }

    /// The descriptor of a keypoint at `(x, y)` (pixel coordinates, the
    /// centre of the top-left pixel at (0, 0)); `None` if its patch leaves
    /// the image.
    pub fn describe(&self, x: f32, y: f32) -> Option<Descriptor> {
        let r = PATCH_RADIUS as f32;
        let (kx, ky) = (x.round(), y.round());
        if !(kx >= r && ky >= r && kx + r < self.width as f32 && ky + r < self.height as f32) {
            return None;
        }
        let (kx, ky) = (kx as isize, ky as isize);
        let value = |[dx, dy]: [i8; 2]| {
            self.at(
                (kx + isize::from(dx)) as usize,
                (ky + isize::from(dy)) as usize,
            )
        };
        let mut d = [0u64; 4];
        for (i, [p, q]) in pattern().iter().enumerate() {
            if value(*p) < value(*q) {
                d[i / 64] |= 1 << (i % 64);
            }
        }
        Some(Descriptor(d))
    }

    /// The descriptors of many keypoints, `None` where a patch leaves the
    /// image.
    pub fn describe_all(&self, points: &[[f32; 2]]) -> Vec<Option<Descriptor>> {
        points.iter().map(|p| self.describe(p[0], p[1])).collect()
    }
}

/// The sampling pattern: 256 pairs of offsets `[p, q]`, each `[dx, dy]`
/// (see the module's documentation for how it is drawn).
pub fn pattern() -> &'static [[[i8; 2]; 2]; BITS] {
    static PATTERN: OnceLock<[[[i8; 2]; 2]; BITS]> = OnceLock::new();
    PATTERN.get_or_init(|| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(PATTERN_SEED);
        let sigma = 2.0 * PATCH_RADIUS as f64 / 5.0;
        let limit = PATCH_RADIUS as f64;
        // Box–Muller gives Gaussians in pairs.
        let mut gaussians = move || {
            let (u1, u2): (f64, f64) = (rng.gen(), rng.gen());
            let radius = (-2.0 * (1.0 - u1).ln()).sqrt() * sigma;
            let angle = std::f64::consts::TAU * u2;
            let to_px = |v: f64| v.round().clamp(-limit, limit) as i8;
            [to_px(radius * angle.cos()), to_px(radius * angle.sin())]
        };
        let mut out = [[[0i8; 2]; 2]; BITS];
        for pair in out.iter_mut() {
            loop {
                let (p, q) = (gaussians(), gaussians());
                if p != q {
                    *pair = [p, q];
                    break;
                }
            }
        }
        out
    })
}

/// A match between descriptor `query` of the first set and `train` of the
/// second.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Match {
    /// Index in the first set.
    pub query: usize,
    /// Index in the second set.
    pub train: usize,
    /// Their Hamming distance.
    pub distance: u32,
}

/// Mutual nearest neighbours by Hamming distance that pass the ratio test:
/// (i, j) is kept when `b[j]` is `a[i]`'s nearest, `a[i]` is `b[j]`'s
/// nearest, and the nearest distance is below `ratio` × `a[i]`'s second
/// nearest (a query with a single candidate passes). Sorted by `query`.
/// `ratio` must lie in (0, 1].
pub fn match_mutual(a: &[Descriptor], b: &[Descriptor], ratio: f32) -> Result<Vec<Match>> {
    match_mutual_where(a, b, ratio, |_, _| true)
}

/// [`match_mutual`] among the pairs (i, j) that `allowed` admits (for
/// example a search radius around the position a pose predicts): the
/// others are not candidates at all, for the nearest, the second nearest
/// and the mutual check alike.
pub fn match_mutual_where(
    a: &[Descriptor],
    b: &[Descriptor],
    ratio: f32,
    allowed: impl Fn(usize, usize) -> bool,
) -> Result<Vec<Match>> {
    if !(ratio > 0.0 && ratio <= 1.0) {
        return Err(Error::InvalidParameter {
            name: "ratio",
            value: f64::from(ratio),
            expected: "a ratio in (0, 1]",
        });
    }
    if a.is_empty() || b.is_empty() {
        return Ok(Vec::new());
    }
    // For each of b, its nearest in a.
    let mut best_of_b = vec![(u32::MAX, usize::MAX); b.len()];
    let mut out = Vec::new();
    let mut nearest = Vec::with_capacity(a.len());
    for (i, da) in a.iter().enumerate() {
        let (mut d1, mut j1, mut d2) = (u32::MAX, usize::MAX, u32::MAX);
        for (j, db) in b.iter().enumerate() {
            // The Hamming distance first: a pair that could change neither
            // i's two nearest nor j's nearest needs no admission check.
            let d = da.distance(db);
            if (d >= d2 && d >= best_of_b[j].0) || !allowed(i, j) {
                continue;
            }
            if d < d1 {
                (d2, d1, j1) = (d1, d, j);
            } else if d < d2 {
                d2 = d;
            }
            if d < best_of_b[j].0 {
                best_of_b[j] = (d, i);
            }
        }
        nearest.push((j1, d1, d2));
    }
    for (i, &(j, d1, d2)) in nearest.iter().enumerate() {
        if j == usize::MAX {
            continue;
        }
        let passes_ratio = d2 == u32::MAX || (d1 as f32) < ratio * d2 as f32;
        if best_of_b[j].1 == i && passes_ratio {
            out.push(Match {
                query: i,
                train: j,
                distance: d1,
            });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const W: usize = 64;

    /// The smoothed value of an impulse of 255 seen `(dx, dy)` away, by the
    /// kernel's definition.
    fn impulse_response(dx: isize, dy: isize) -> u8 {
        if dx.abs() > 4 || dy.abs() > 4 {
            return 0;
        }
        let w = |d: isize| SMOOTHING_KERNEL[(d + 4) as usize];
        ((255 * w(dx) * w(dy) + (1 << 15)) >> 16) as u8
    }

    /// The smoothing by its definition, pixel by pixel.
    fn smoothed_by_definition(gray: &[u8], w: usize, h: usize) -> Vec<u8> {
        let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
        let row = |x: usize, y: usize| -> u32 {
            (0..9)
                .map(|t| {
                    SMOOTHING_KERNEL[t]
                        * u32::from(gray[y * w + clamp(x as isize + t as isize - 4, w)])
                })
                .sum()
        };
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let sum: u32 = (0..9)
                    .map(|t| SMOOTHING_KERNEL[t] * row(x, clamp(y as isize + t as isize - 4, h)))
                    .sum();
                ((sum + (1 << 15)) >> 16) as u8
            })
            .collect()
    }

    #[test]
    fn smoothing_agrees_with_its_definition_on_any_size() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for (w, h) in [(1, 1), (3, 2), (8, 5), (9, 9), (10, 3), (37, 23), (64, 17)] {
            let img: Vec<u8> = (0..w * h).map(|_| rng.gen()).collect();
            let s = Smoothed::new(&img, w, h).unwrap();
            let want = smoothed_by_definition(&img, w, h);
            // The baseline kernel as well as the dispatched one.
            assert_eq!(smooth_in(&img, w, h), want, "{w}×{h}, baseline");
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(s.at(x, y), want[y * w + x], "{w}×{h} at ({x}, {y})");
                }
            }
        }
        // Saturated: the 16-bit row sums reach 255 · 256 exactly.
        let white = vec![255u8; 40 * 12];
        let s = Smoothed::new(&white, 40, 12).unwrap();
        assert!((0..12).all(|y| (0..40).all(|x| s.at(x, y) == 255)));
    }

    #[test]
    fn smoothing_an_impulse_gives_the_kernel() {
        let mut img = vec![0u8; W * W];
        img[30 * W + 35] = 255;
        let s = Smoothed::new(&img, W, W).unwrap();
        // By hand: 255·52·52 / 65536 = 10.52 → 11 after rounding
        // (689520 + 32768) >> 16; 255·46·52 / 65536 = 9.31 → 9;
        // 255·7·7 / 65536 = 0.19 → 0.
        assert_eq!(s.at(35, 30), 11);
        assert_eq!(s.at(36, 30), 9);
        assert_eq!(s.at(35, 31), 9);
        assert_eq!(s.at(39, 34), 0);
        for y in 0..W {
            for x in 0..W {
                let want = impulse_response(x as isize - 35, y as isize - 30);
                assert_eq!(s.at(x, y), want, "({x}, {y})");
            }
        }
        // A uniform image stays exactly uniform, border included.
        let s = Smoothed::new(&[77u8; 12 * 10], 12, 10).unwrap();
        assert!((0..10).all(|y| (0..12).all(|x| s.at(x, y) == 77)));
    }

    #[test]
    fn descriptor_bits_of_an_impulse_and_of_an_edge() {
        // An impulse 3 px right of and 2 px above the keypoint (32, 32).
        let mut img = vec![0u8; W * W];
        img[30 * W + 35] = 255;
        let d = Smoothed::new(&img, W, W)
            .unwrap()
            .describe(32.0, 32.0)
            .unwrap();
        let v = |[dx, dy]: [i8; 2]| impulse_response(isize::from(dx) - 3, isize::from(dy) + 2);
        let mut ones = 0;
        for (i, [p, q]) in pattern().iter().enumerate() {
            assert_eq!(d.bit(i), v(*p) < v(*q), "bit {i}: {p:?} {q:?}");
            ones += usize::from(d.bit(i));
        }
        assert!(ones > 0, "no test sees the impulse");
        // A vertical edge: 10 left of column 30, 200 from it on. Smoothed,
        // a column is exactly 10 up to 25, exactly 200 from 34 on, and
        // rises strictly in between; so a test is 1 exactly when p's column,
        // clamped to 25 … 34, is left of q's.
        let img: Vec<u8> = (0..W * W)
            .map(|i| if i % W < 30 { 10 } else { 200 })
            .collect();
        let d = Smoothed::new(&img, W, W)
            .unwrap()
            .describe(31.6, 32.2)
            .unwrap();
        let column = |dx: i8| (32 + isize::from(dx)).clamp(25, 34);
        for (i, [p, q]) in pattern().iter().enumerate() {
            assert_eq!(d.bit(i), column(p[0]) < column(q[0]), "bit {i}");
        }
    }

    #[test]
    fn the_pattern_is_the_documented_one() {
        let pat = pattern();
        // The first pairs, pinned: a change of generator or seed shows here.
        assert_eq!(pat[0], PINNED[0]);
        assert_eq!(pat[1], PINNED[1]);
        assert_eq!(pat[2], PINNED[2]);
        let r = PATCH_RADIUS as i8;
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        for [p, q] in pat {
            assert_ne!(p, q);
            for v in [p[0], p[1], q[0], q[1]] {
                assert!((-r..=r).contains(&v));
                sum += f64::from(v);
                sum2 += f64::from(v) * f64::from(v);
            }
        }
        let n = (4 * BITS) as f64;
        let (mean, sd) = (sum / n, (sum2 / n - (sum / n).powi(2)).sqrt());
        // σ = 9.6 px, a little less after clamping at ±24.
        assert!(mean.abs() < 1.0, "mean {mean}");
        assert!((8.6..10.4).contains(&sd), "σ {sd}");
    }

    const PINNED: [[[i8; 2]; 2]; 3] = [
        [[-2, -9], [-4, 1]],
        [[-3, 12], [7, -21]],
        [[1, 10], [-3, 3]],
    ];

    #[test]
    fn hamming_distance_counts_differing_bits() {
        let a = Descriptor([0b1011, 0, u64::MAX, 1 << 63]);
        let b = Descriptor([0b0110, 0, u64::MAX - 1, 0]);
        // 1011 ^ 0110 = 1101: 3; word 2: 1; word 3: 1.
        assert_eq!(a.distance(&b), 5);
        assert_eq!(b.distance(&a), 5);
        assert_eq!(a.distance(&a), 0);
        assert!(a.bit(0) && !a.bit(2) && a.bit(255) && !b.bit(255));
    }

    #[test]
    fn matching_is_mutual_and_passes_the_ratio_test() {
        let d = |bits: u64| Descriptor([bits, 0, 0, 0]);
        // a0 ↔ b0 (distance 0, next 8); a1's nearest is b0 too (not
        // mutual); a2's nearest are b2 at 2 and b3 at 3 (2 ≥ 0.6 · 3).
        let a = [d(0), d(0b1), d(0xFF00)];
        let b = [d(0), d(0xFF), d(0xFF03), d(0xF800)];
        let m = match_mutual(&a, &b, 0.6).unwrap();
        assert_eq!(
            m,
            [Match {
                query: 0,
                train: 0,
                distance: 0
            }]
        );
        // With a ratio of 1, a2 ↔ b2 is kept as well.
        let m = match_mutual(&a, &b, 1.0).unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!((m[1].query, m[1].train, m[1].distance), (2, 2, 2));
        assert!(match_mutual(&a, &b, 0.0).is_err());
        assert!(match_mutual(&a, &[], 0.8).unwrap().is_empty());
    }

    #[test]
    fn a_gate_keeps_candidates_out_of_every_test() {
        let d = |bits: u64| Descriptor([bits, 0, 0, 0]);
        let a = [d(0), d(0xFF00)];
        let b = [d(0), d(0b111), d(0xFF03)];
        // Without a gate a0 ↔ b0.
        let all = match_mutual_where(&a, &b, 0.8, |_, _| true).unwrap();
        assert_eq!((all[0].query, all[0].train), (0, 0));
        // With b0 out of a0's reach, a0's nearest is b1 (3 bits), whose
        // second nearest is b2 (far): a0 ↔ b1. a1 ↔ b2 either way.
        let gated = match_mutual_where(&a, &b, 0.8, |i, j| !(i == 0 && j == 0)).unwrap();
        let pairs: Vec<_> = gated
            .iter()
            .map(|m| (m.query, m.train, m.distance))
            .collect();
        assert_eq!(pairs, [(0, 1, 3), (1, 2, 2)]);
        // Nothing in reach: no match.
        assert!(match_mutual_where(&a, &b, 0.8, |_, _| false)
            .unwrap()
            .is_empty());
    }

    #[test]
    fn bad_images_are_refused_and_border_keypoints_get_none() {
        assert!(Smoothed::new(&[0u8; 10], 4, 4).is_err());
        assert!(Smoothed::new(&[], 0, 4).is_err());
        let s = Smoothed::new(&vec![0u8; W * W], W, W).unwrap();
        assert!(s.describe(23.0, 32.0).is_none());
        assert!(s.describe(32.0, 40.0).is_none());
        assert!(s.describe(24.0, 39.0).is_some());
        assert!(s.describe(f32::NAN, 32.0).is_none());
    }
}
