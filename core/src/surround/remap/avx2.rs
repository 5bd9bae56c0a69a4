//! The AVX2 kernels: loads or gathers and `vpmaddwd`, 4 RGB, 8 mono or 8 Bayer
//! pixels of one camera a step (see the module documentation of
//! [`super`]).

use super::bayer::BORDER;
use super::plan::Job;
use super::scalar::pixels_bmi2;
use super::{prefetch_run, AHEAD, UNIT_GAIN};

/// The steps of one run of `$n`-pixel vectors through the AVX2 chunk
/// functions `$sample` (a step's sums for one camera), `$scale` (sums
/// scaled by a broadcast gain, camera `j`'s being `$gain(j)`), `$add` and
/// `$store` (`$bytes` canvas bytes a step): one camera, two, or the
/// general loop over any number. Stops before the run's last `len % $n`
/// pixels.
///
/// Expanded inside [`run_avx2`], whose contract makes each `$sample`
/// call sound: the taps of camera `j` are `cams[j]`'s and `image(j)`
/// is its image.
macro_rules! steps {
    ($k:ident, $dst:ident, $index:ident, $weights:ident, $len:ident, $cams:ident, $image:ident, $gain:ident;
     $n:expr, $bytes:expr, $sample:path, $scale:path, $add:path, $store:path) => {
        match ($cams.len(), $image(0), $image(1)) {
            (1, Some(a), _) => {
                let ga = ops::broadcast($gain(0));
                // Fixed-size chunks: no division by a chunk length at
                // run time, once per run.
                let chunks = $dst
                    .as_chunks_mut::<{ $bytes }>()
                    .0
                    .iter_mut()
                    .zip($index.as_chunks::<{ $n }>().0)
                    .zip($weights.as_chunks::<{ $n }>().0);
                for ((d, i), w) in chunks {
                    // SAFETY: see the macro's docs.
                    let s = unsafe { $sample(a.bytes, a.width, i, w, &$k) };
                    $store(d, $scale(s, ga), &$k);
                }
            }
            // Two cameras: an overlap.
            (2, Some(a), Some(b)) => {
                let (ga, gb) = (ops::broadcast($gain(0)), ops::broadcast($gain(1)));
                let (ia, ib) = $index.split_at($len);
                let (wa, wb) = $weights.split_at($len);
                let chunks = $dst
                    .as_chunks_mut::<{ $bytes }>()
                    .0
                    .iter_mut()
                    .zip(
                        ia.as_chunks::<{ $n }>()
                            .0
                            .iter()
                            .zip(wa.as_chunks::<{ $n }>().0),
                    )
                    .zip(
                        ib.as_chunks::<{ $n }>()
                            .0
                            .iter()
                            .zip(wb.as_chunks::<{ $n }>().0),
                    );
                for ((d, (ia, wa)), (ib, wb)) in chunks {
                    // SAFETY: see the macro's docs.
                    let (sa, sb) = unsafe {
                        (
                            $sample(a.bytes, a.width, ia, wa, &$k),
                            $sample(b.bytes, b.width, ib, wb, &$k),
                        )
                    };
                    $store(d, $add($scale(sa, ga), $scale(sb, gb)), &$k);
                }
            }
            // Three or more cameras.
            _ => {
                for (p, d) in $dst.chunks_exact_mut($bytes).enumerate() {
                    let mut acc = None;
                    for j in 0..$cams.len() {
                        let t = j * $len + p * $n;
                        let (Some(img), Some(i), Some(w)) = (
                            $image(j),
                            $index[t..].first_chunk(),
                            $weights[t..].first_chunk(),
                        ) else {
                            continue;
                        };
                        // SAFETY: see the macro's docs.
                        let s = unsafe { $sample(img.bytes, img.width, i, w, &$k) };
                        let s = $scale(s, ops::broadcast($gain(j)));
                        acc = Some(acc.map_or(s, |a| $add(a, s)));
                    }
                    if let Some(acc) = acc {
                        $store(d, acc, &$k);
                    }
                }
            }
        }
    };
}

/// The AVX2 kernel: per camera, the taps of 4 RGB pixels (each pixel's
/// top and bottom 8 bytes, loaded one by one), 8 mono pixels (4 bytes
/// each, loaded one by one) or 8 Bayer pixels (four gathers of 4 bytes,
/// one per row of the neighbourhood) at a time; each neighbour pair (left, right)
/// meets its weight pair in one `vpmaddwd`; the cameras' sums are
/// scaled by their gains (`GAIN`), added, rounded and packed. The ends
/// of runs, Bayer steps with a tap at the image's edge and runs mixing
/// mosaics with other images go through the BMI2 kernel.
///
/// # Safety
///
/// The CPU has AVX2 and BMI2; `job.plan.gather_ok`; every image has
/// the size of its camera's source and at least `w·h` bytes a channel
/// (one for a mosaic); `job.sites` is empty or `job.plan.sites()`.
#[target_feature(enable = "avx2,bmi2")]
#[allow(unsafe_code)]
pub(super) unsafe fn run_avx2<const GAIN: bool>(job: Job<'_>, out: &mut [u8]) {
    use ops::{Consts, MONO, RGB};
    let (plan, images, gains, ch) = (job.plan, job.images, job.gains, job.ch);
    let k = Consts::new();
    for (r, run) in plan.runs.iter().enumerate() {
        prefetch_run(&job, plan.runs.get(r + AHEAD));
        let Some((dst, taps)) = plan.parts(run, &job, out) else {
            continue;
        };
        let (index, weights, cams, len) = (taps.index, taps.weights, taps.cams, taps.len);
        if cams.is_empty() {
            dst.fill(0);
            continue;
        }
        let image = |j: usize| cams.get(j).and_then(|&c| images.get(c as usize));
        // Camera `j`'s gain.
        let gain = |j: usize| {
            cams.get(j)
                .and_then(|&c| gains.get(c as usize))
                .copied()
                .unwrap_or(UNIT_GAIN)
        };
        let main = if ch == 1 {
            let main = len - len % MONO;
            let dst = &mut dst[..main];
            steps!(k, dst, index, weights, len, cams, image, gain;
                MONO, MONO, ops::mono, ops::mono_gain::<GAIN>, ops::mono_add, ops::store_mono::<GAIN>);
            main
        } else if taps.mosaics == 0 {
            let main = len - len % RGB;
            let dst = &mut dst[..3 * main];
            steps!(k, dst, index, weights, len, cams, image, gain;
                RGB, 3 * RGB, ops::rgb, ops::rgb_gain::<GAIN>, ops::rgb_add, ops::store_rgb::<GAIN>);
            main
        } else if taps.mosaics == cams.len() {
            let main = len - len % MONO;
            for p in (0..main).step_by(MONO) {
                // A step with a tap whose neighbourhood leaves its image
                // goes through the scalar kernel, which reflects the edge.
                let edge = (0..cams.len()).any(|j| {
                    taps.sites
                        .get(j * len + p..)
                        .and_then(|s| s.first_chunk::<MONO>())
                        .is_none_or(|s| {
                            u64::from_le_bytes(*s) & u64::from_le_bytes([BORDER; 8]) != 0
                        })
                });
                if edge {
                    pixels_bmi2::<GAIN>(&job, &taps, (p, p + MONO), dst);
                    continue;
                }
                let mut acc = None;
                for j in 0..cams.len() {
                    let t = j * len + p;
                    let (Some(img), Some(i), Some(w), Some(s)) = (
                        image(j),
                        index[t..].first_chunk(),
                        weights[t..].first_chunk(),
                        taps.sites[t..].first_chunk(),
                    ) else {
                        continue;
                    };
                    let Some(cfa) = img.cfa else { continue };
                    // SAFETY: `img` is a mosaic of its camera's size with
                    // at least w·h bytes (fewer than 2³¹: `gather_ok`),
                    // and its taps `i` have the sites `s` of the plan's
                    // table, none at the edge (checked above): the
                    // contract of `ops::bayer`.
                    let s = unsafe { ops::bayer(img.bytes, img.width, i, w, s, cfa.code(), &k) };
                    let s = ops::bayer_gain::<GAIN>(s, ops::broadcast(gain(j)));
                    acc = Some(match acc {
                        Some(a) => ops::bayer_add(a, s),
                        None => s,
                    });
                }
                if let (Some(acc), Some(d)) = (acc, dst.get_mut(3 * p..3 * (p + MONO))) {
                    ops::store_bayer::<GAIN>(d, acc, &k);
                }
            }
            main
        } else {
            // Mosaics and other images in one run.
            0
        };
        pixels_bmi2::<GAIN>(&job, &taps, (main, len), dst);
    }
}

/// Byte shuffles shared by the vector kernels (one 128-bit lane).
mod lanes {
    const Z: i8 = -1;
    /// A lane holding a pixel's top 8 bytes, then its bottom 8 bytes
    /// read 2 early: the (left, right) pairs of R, G and B of the top
    /// row as `u16` pairs.
    pub(super) const RGB_TOP: [i8; 16] = [0, Z, 3, Z, 1, Z, 4, Z, 2, Z, 5, Z, Z, Z, Z, Z];
    /// The same for the bottom row.
    pub(super) const RGB_BOTTOM: [i8; 16] = [10, Z, 13, Z, 11, Z, 14, Z, 12, Z, 15, Z, Z, Z, Z, Z];
    /// Per 32-bit lane of 4 top bytes: the (left, right) pair as `u16`.
    pub(super) const MONO_TOP: [i8; 16] = [0, Z, 1, Z, 4, Z, 5, Z, 8, Z, 9, Z, 12, Z, 13, Z];
    /// Per 32-bit lane of 4 bottom bytes read 2 early: the pair.
    pub(super) const MONO_BOTTOM: [i8; 16] = [2, Z, 3, Z, 6, Z, 7, Z, 10, Z, 11, Z, 14, Z, 15, Z];
    /// 4 pixels' RGB0 bytes to 12 bytes of RGB.
    pub(super) const RGB12: [i8; 16] = [0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, Z, Z, Z, Z];

    /// `pattern` in each 32-bit lane (indices into the lane's 4 bytes).
    const fn quad(pattern: [i8; 4]) -> [i8; 16] {
        let mut out = [Z; 16];
        let mut i = 0;
        while i < 16 {
            let b = pattern[i % 4];
            out[i] = if b < 0 { Z } else { b + (i / 4 * 4) as i8 };
            i += 1;
        }
        out
    }

    /// The 4 bytes of each 32-bit lane as they are.
    pub(super) const IDENT: [i8; 16] = quad([0, 1, 2, 3]);
    /// The 4 bytes of each 32-bit lane reversed: a neighbourhood row
    /// mirrored left–right.
    pub(super) const REVERSE: [i8; 16] = quad([3, 2, 1, 0]);
    /// The two `u16` of each 32-bit lane swapped: a weight pair mirrored.
    pub(super) const SWAP16: [i8; 16] = quad([2, 3, 0, 1]);
    /// A neighbourhood row's columns 1, 3, 1, 3.
    pub(super) const COLS_13: [i8; 16] = quad([1, 3, 1, 3]);
    /// A neighbourhood row's columns 0, 2, 0, 2.
    pub(super) const COLS_02: [i8; 16] = quad([0, 2, 0, 2]);
    /// A row's column 1 as the low `u16` of the lane.
    pub(super) const COL_1_LOW: [i8; 16] = quad([1, Z, Z, Z]);
    /// A row's column 2 as the high `u16` of the lane.
    pub(super) const COL_2_HIGH: [i8; 16] = quad([Z, Z, 2, Z]);
    /// `values` in each 32-bit lane.
    const fn every(values: [i8; 4]) -> [i8; 16] {
        let mut out = [0; 16];
        let mut i = 0;
        while i < 16 {
            out[i] = values[i % 4];
            i += 1;
        }
        out
    }

    /// 4 pixels' R, G, B (4 bytes each, then 4 spare) to 12 bytes of RGB.
    pub(super) const BAYER_RGB: [i8; 16] = [0, 4, 8, 1, 5, 9, 2, 6, 10, 3, 7, 11, Z, Z, Z, Z];

    /// `vpmaddubsw` coefficients of a lane holding columns (1, 3, 1, 3)
    /// of row 1: red's top pair (4·n11, 2·n11 + 2·n13).
    pub(super) const RED_TOP: [i8; 16] = every([4, 0, 2, 2]);
    /// Of columns (1, 3, 1, 3) of row 1 or 3: its part of red's bottom
    /// pair (2·n11 + 2·n31, n11 + n13 + n31 + n33).
    pub(super) const RED_BOTTOM: [i8; 16] = every([2, 0, 1, 1]);
    /// Of columns (0, 2, 0, 2) of row 0 or 2: its part of blue's top
    /// pair (n00 + n02 + n20 + n22, 2·n02 + 2·n22).
    pub(super) const BLUE_TOP: [i8; 16] = every([1, 1, 0, 2]);
    /// Of columns (0, 2, 0, 2) of row 2: blue's bottom pair
    /// (2·n20 + 2·n22, 4·n22).
    pub(super) const BLUE_BOTTOM: [i8; 16] = every([2, 2, 0, 4]);
    /// Of columns (0, 2, 0, 2) of row 1: (n10 + n12, 4·n12) of green's
    /// top pair (n01 + n10 + n12 + n21, 4·n12).
    pub(super) const GREEN_TOP: [i8; 16] = every([1, 1, 0, 4]);
    /// Of columns (1, 3, 1, 3) of row 2: (4·n21, n21 + n23) of green's
    /// bottom pair (4·n21, n12 + n21 + n23 + n32).
    pub(super) const GREEN_BOTTOM: [i8; 16] = every([4, 0, 1, 1]);
}

/// The AVX2 operations of a step.
mod ops {
    use std::arch::x86_64::*;

    use super::super::{GAIN_SHIFT, SHIFT};
    use super::lanes;

    /// Mono pixels per step.
    pub(super) const MONO: usize = 8;
    /// RGB pixels per step.
    pub(super) const RGB: usize = 4;

    /// Sums of two mono steps.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn mono_add(a: __m256i, b: __m256i) -> __m256i {
        _mm256_add_epi32(a, b)
    }

    /// Sums of two RGB steps.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn rgb_add(a: (__m256i, __m256i), b: (__m256i, __m256i)) -> (__m256i, __m256i) {
        (_mm256_add_epi32(a.0, b.0), _mm256_add_epi32(a.1, b.1))
    }

    /// A 128-bit lane pattern as a vector.
    #[target_feature(enable = "avx2")]
    fn lane(b: [i8; 16]) -> __m128i {
        _mm_setr_epi8(
            b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], b[10], b[11], b[12], b[13],
            b[14], b[15],
        )
    }

    /// The constant vectors of the kernels.
    pub(super) struct Consts {
        pub(super) zero: __m256i,
        round: __m256i,
        rgb_top: __m256i,
        rgb_bottom: __m256i,
        mono_top: __m256i,
        mono_bottom: __m256i,
        /// The first 32-bit lanes of each 128-bit lane, in order.
        lanes: __m256i,
        rgb12: __m128i,
        /// Rounding of a gained sum.
        round_gain: __m256i,
        /// Rounding of a Bayer sum.
        round_bayer: __m256i,
        one: __m256i,
        two: __m256i,
        ident: __m256i,
        reverse: __m256i,
        swap16: __m256i,
        cols_13: __m256i,
        cols_02: __m256i,
        col_1_low: __m256i,
        col_2_high: __m256i,
        bayer_rgb: __m256i,
        red_top: __m256i,
        red_bottom: __m256i,
        blue_top: __m256i,
        blue_bottom: __m256i,
        green_top: __m256i,
        green_bottom: __m256i,
    }

    impl Consts {
        #[target_feature(enable = "avx2")]
        pub(super) fn new() -> Self {
            let both = |b: [i8; 16]| _mm256_broadcastsi128_si256(lane(b));
            Self {
                zero: _mm256_setzero_si256(),
                round: _mm256_set1_epi32(1 << (SHIFT - 1)),
                rgb_top: both(lanes::RGB_TOP),
                rgb_bottom: both(lanes::RGB_BOTTOM),
                mono_top: both(lanes::MONO_TOP),
                mono_bottom: both(lanes::MONO_BOTTOM),
                lanes: _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7),
                rgb12: lane(lanes::RGB12),
                round_gain: _mm256_set1_epi32(1 << (GAIN_SHIFT - 1)),
                round_bayer: _mm256_set1_epi32(1 << (SHIFT + 1)),
                one: _mm256_set1_epi32(1),
                two: _mm256_set1_epi32(2),
                ident: both(lanes::IDENT),
                reverse: both(lanes::REVERSE),
                swap16: both(lanes::SWAP16),
                cols_13: both(lanes::COLS_13),
                cols_02: both(lanes::COLS_02),
                col_1_low: both(lanes::COL_1_LOW),
                col_2_high: both(lanes::COL_2_HIGH),
                bayer_rgb: both(lanes::BAYER_RGB),
                red_top: both(lanes::RED_TOP),
                red_bottom: both(lanes::RED_BOTTOM),
                blue_top: both(lanes::BLUE_TOP),
                blue_bottom: both(lanes::BLUE_BOTTOM),
                green_top: both(lanes::GREEN_TOP),
                green_bottom: both(lanes::GREEN_BOTTOM),
            }
        }
    }

    /// A gain (1/256) in every 32-bit lane.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn broadcast(gain: u16) -> __m256i {
        _mm256_set1_epi32(i32::from(gain))
    }

    /// With `GAIN`, a mono step's sums scaled by a gain (1/256): at
    /// most 255·4096·4096 < 2³², as `u32`; without, the sums.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn mono_gain<const GAIN: bool>(a: __m256i, gain: __m256i) -> __m256i {
        if GAIN {
            _mm256_mullo_epi32(a, gain)
        } else {
            a
        }
    }

    /// With `GAIN`, an RGB step's sums scaled by a gain.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn rgb_gain<const GAIN: bool>(
        a: (__m256i, __m256i),
        gain: __m256i,
    ) -> (__m256i, __m256i) {
        if GAIN {
            (_mm256_mullo_epi32(a.0, gain), _mm256_mullo_epi32(a.1, gain))
        } else {
            a
        }
    }

    /// Rounds `a` (sums of weights in 1/4096, or with `GAIN` of gains in
    /// 1/256 times those) to its integer part, as `u32`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn rounded<const GAIN: bool>(a: __m256i, k: &Consts) -> __m256i {
        if GAIN {
            _mm256_srli_epi32::<{ GAIN_SHIFT as i32 }>(_mm256_add_epi32(a, k.round_gain))
        } else {
            _mm256_srli_epi32::<{ SHIFT as i32 }>(_mm256_add_epi32(a, k.round))
        }
    }

    /// The sums `Σ w·p` of 4 RGB pixels of one image (pixels 0 and 2,
    /// then 1 and 3; per 128-bit lane R, G, B, 0 as `i32`).
    ///
    /// # Safety
    ///
    /// `bytes` is a `width`-pixel-wide RGB image of `h` rows (at
    /// least `3·width·h` bytes, fewer than 2³¹) and every `index` is
    /// at most `(h − 1)·width − 2`: the 8 bytes at `3·index` and at
    /// `3·(index + width) − 2` lie in the image.
    #[target_feature(enable = "avx2")]
    #[inline]
    #[allow(unsafe_code)]
    pub(super) unsafe fn rgb(
        bytes: &[u8],
        width: usize,
        index: &[u32; RGB],
        weights: &[u64; RGB],
        k: &Consts,
    ) -> (__m256i, __m256i) {
        // Each pixel's top 8 bytes at `3·index` and its bottom 8 bytes at
        // `3·(index + width) − 2`, loaded one by one: on the machine
        // measured (BENCHMARKS.md) eight plain loads and their inserts
        // take fewer cycles than two 4-lane gathers. Pixels 0 and 2 in one
        // vector, 1 and 3 in the other: then each 128-bit lane's weight
        // pairs are one in-lane shuffle of the weights (pixel 0's and 1's
        // in lane 0, 2's and 3's in lane 1).
        let below = 3 * width - 2;
        let base = bytes.as_ptr();
        let load = |p: usize, off: usize| {
            // SAFETY: `3·index` and `3·(index + width) − 2` are offsets
            // whose 8 bytes lie in `bytes` (the contract).
            unsafe {
                base.add(3 * index[p] as usize + off)
                    .cast::<i64>()
                    .read_unaligned()
            }
        };
        let pair = |p: usize| _mm_set_epi64x(load(p, below), load(p, 0));
        let g02 = _mm256_set_m128i(pair(2), pair(0));
        let g13 = _mm256_set_m128i(pair(3), pair(1));
        let w = _mm256_setr_epi64x(
            weights[0] as i64,
            weights[1] as i64,
            weights[2] as i64,
            weights[3] as i64,
        );
        let sum = |g: __m256i, top: __m256i, bottom: __m256i| {
            _mm256_add_epi32(
                _mm256_madd_epi16(_mm256_shuffle_epi8(g, k.rgb_top), top),
                _mm256_madd_epi16(_mm256_shuffle_epi8(g, k.rgb_bottom), bottom),
            )
        };
        (
            sum(
                g02,
                _mm256_shuffle_epi32::<0b00_00_00_00>(w),
                _mm256_shuffle_epi32::<0b01_01_01_01>(w),
            ),
            sum(
                g13,
                _mm256_shuffle_epi32::<0b10_10_10_10>(w),
                _mm256_shuffle_epi32::<0b11_11_11_11>(w),
            ),
        )
    }

    /// Rounds and stores 4 RGB pixels' sums (from [`rgb`], gained with
    /// `GAIN`; saturated at 255) in 12 bytes.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn store_rgb<const GAIN: bool>(
        dst: &mut [u8],
        (a, b): (__m256i, __m256i),
        k: &Consts,
    ) {
        let (a, b) = (rounded::<GAIN>(a, k), rounded::<GAIN>(b, k));
        // Lane 0: pixels 0, 1; lane 1: pixels 2, 3 (RGB0 each), in
        // their low 8 bytes.
        let bytes = _mm256_packus_epi16(_mm256_packus_epi32(a, b), k.zero);
        let ordered = _mm256_castsi256_si128(_mm256_permute4x64_epi64::<0b11_01_10_00>(bytes));
        store12(dst, _mm_shuffle_epi8(ordered, k.rgb12));
    }

    /// 8 taps' indices, one per 32-bit lane.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn indices(index: &[u32; MONO]) -> __m256i {
        _mm256_setr_epi32(
            index[0] as i32,
            index[1] as i32,
            index[2] as i32,
            index[3] as i32,
            index[4] as i32,
            index[5] as i32,
            index[6] as i32,
            index[7] as i32,
        )
    }

    /// 8 taps' weights as the top pairs (top-left, top-right) and the
    /// bottom pairs (bottom-left, bottom-right), one pair of `i16` per
    /// 32-bit lane.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn weight_pairs(weights: &[u64; MONO]) -> (__m256i, __m256i) {
        let w0 = _mm256_castsi256_ps(_mm256_setr_epi64x(
            weights[0] as i64,
            weights[1] as i64,
            weights[2] as i64,
            weights[3] as i64,
        ));
        let w1 = _mm256_castsi256_ps(_mm256_setr_epi64x(
            weights[4] as i64,
            weights[5] as i64,
            weights[6] as i64,
            weights[7] as i64,
        ));
        // The top pairs are the even 32-bit lanes, the bottom pairs the
        // odd ones; the shuffle leaves 64-bit blocks 0, 2, 1, 3.
        let even = _mm256_shuffle_ps::<0b10_00_10_00>(w0, w1);
        let odd = _mm256_shuffle_ps::<0b11_01_11_01>(w0, w1);
        (
            _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_castps_si256(even)),
            _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_castps_si256(odd)),
        )
    }

    /// The sums `Σ w·p` of 8 mono pixels of one image, as `i32`.
    ///
    /// # Safety
    ///
    /// `bytes` is a `width`-pixel-wide mono image of `h` rows (at least
    /// `width·h` bytes, fewer than 2³¹) and every `index` is at most
    /// `(h − 1)·width − 2`: the 4 bytes at `index` and at
    /// `index + width − 2` lie in the image.
    #[target_feature(enable = "avx2")]
    #[inline]
    #[allow(unsafe_code)]
    pub(super) unsafe fn mono(
        bytes: &[u8],
        width: usize,
        index: &[u32; MONO],
        weights: &[u64; MONO],
        k: &Consts,
    ) -> __m256i {
        // Loaded one by one rather than gathered, as in [`rgb`].
        let base = bytes.as_ptr();
        let load = |p: usize, off: usize| {
            // SAFETY: each offset is `index` or `index + width − 2`, whose
            // 4 bytes lie in `bytes` (the contract).
            unsafe {
                base.add(index[p] as usize + off)
                    .cast::<i32>()
                    .read_unaligned()
            }
        };
        let row = |off: usize| {
            _mm256_setr_epi32(
                load(0, off),
                load(1, off),
                load(2, off),
                load(3, off),
                load(4, off),
                load(5, off),
                load(6, off),
                load(7, off),
            )
        };
        let (top, bottom) = (row(0), row(width - 2));
        let (even, odd) = weight_pairs(weights);
        _mm256_add_epi32(
            _mm256_madd_epi16(_mm256_shuffle_epi8(top, k.mono_top), even),
            _mm256_madd_epi16(_mm256_shuffle_epi8(bottom, k.mono_bottom), odd),
        )
    }

    /// Rounds and stores 8 mono pixels' sums (from [`mono`], gained with
    /// `GAIN`; saturated at 255).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn store_mono<const GAIN: bool>(dst: &mut [u8], a: __m256i, k: &Consts) {
        let a = rounded::<GAIN>(a, k);
        let bytes = _mm256_packus_epi16(_mm256_packus_epi32(a, a), k.zero);
        // Lane 0 holds pixels 0–3 in its first 4 bytes, lane 1 pixels
        // 4–7.
        let ordered = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(bytes, k.lanes));
        dst[..8].copy_from_slice(&(_mm_cvtsi128_si64(ordered) as u64).to_le_bytes());
    }

    /// The sums `Σ w·S` of 8 Bayer pixels of one mosaic, per channel (R,
    /// G, B) as `i32` (scale 4·4096): the AVX2 form of
    /// `bayer::sample`. Lanes whose top-left pixel is on an odd site
    /// column (row) gather their neighbourhood mirrored left–right
    /// (top–bottom), with their weights, so that every lane's top-left
    /// pixel is red; each `S` pair is then one or two `vpmaddubsw` of the
    /// neighbourhood's bytes.
    ///
    /// # Safety
    ///
    /// `bytes` is a `width`-pixel-wide mosaic of `h` rows (at least
    /// `width·h` bytes, fewer than 2³¹), `sites` are the site codes of
    /// the taps `index` and none has [`super::BORDER`]: every tap's top-left
    /// pixel (x0, y0) has `1 ≤ x0 ≤ width − 3` and `1 ≤ y0 ≤ h − 3`, so
    /// the 4 bytes at `x0 − 1` of rows `y0 − 1 ..= y0 + 2` lie in the
    /// image.
    #[target_feature(enable = "avx2")]
    #[inline]
    #[allow(unsafe_code, clippy::too_many_arguments)]
    pub(super) unsafe fn bayer(
        bytes: &[u8],
        width: usize,
        index: &[u32; MONO],
        weights: &[u64; MONO],
        sites: &[u8; MONO],
        order: u8,
        k: &Consts,
    ) -> [__m256i; 3] {
        let i = indices(index);
        let site = _mm256_xor_si256(
            _mm256_cvtepu8_epi32(_mm_set1_epi64x(i64::from_le_bytes(*sites))),
            _mm256_set1_epi32(i32::from(order)),
        );
        let x_odd = _mm256_cmpeq_epi32(_mm256_and_si256(site, k.one), k.one);
        let y_odd = _mm256_cmpeq_epi32(_mm256_and_si256(site, k.two), k.two);
        // Rows y0 − 1 … y0 + 2 at column x0 − 1, bottom-up where mirrored
        // top–bottom.
        let w = width as i32;
        let first = _mm256_add_epi32(
            _mm256_sub_epi32(i, _mm256_set1_epi32(w + 1)),
            _mm256_and_si256(y_odd, _mm256_set1_epi32(3 * w)),
        );
        let step = _mm256_sub_epi32(
            _mm256_set1_epi32(w),
            _mm256_and_si256(y_odd, _mm256_set1_epi32(2 * w)),
        );
        let o1 = _mm256_add_epi32(first, step);
        let o2 = _mm256_add_epi32(o1, step);
        let o3 = _mm256_add_epi32(o2, step);
        let base = bytes.as_ptr().cast::<i32>();
        // SAFETY: each offset is that of 4 bytes of the neighbourhood,
        // which lie in `bytes` (the contract).
        let rows = unsafe {
            [
                _mm256_i32gather_epi32::<1>(base, first),
                _mm256_i32gather_epi32::<1>(base, o1),
                _mm256_i32gather_epi32::<1>(base, o2),
                _mm256_i32gather_epi32::<1>(base, o3),
            ]
        };
        let mirror = _mm256_blendv_epi8(k.ident, k.reverse, x_odd);
        let (r0, r1, r2, r3) = (
            _mm256_shuffle_epi8(rows[0], mirror),
            _mm256_shuffle_epi8(rows[1], mirror),
            _mm256_shuffle_epi8(rows[2], mirror),
            _mm256_shuffle_epi8(rows[3], mirror),
        );
        let (r1_13, r3_13, r2_13) = (
            _mm256_shuffle_epi8(r1, k.cols_13),
            _mm256_shuffle_epi8(r3, k.cols_13),
            _mm256_shuffle_epi8(r2, k.cols_13),
        );
        let (r0_02, r1_02, r2_02) = (
            _mm256_shuffle_epi8(r0, k.cols_02),
            _mm256_shuffle_epi8(r1, k.cols_02),
            _mm256_shuffle_epi8(r2, k.cols_02),
        );
        let add = _mm256_add_epi16;
        let red = (
            _mm256_maddubs_epi16(r1_13, k.red_top),
            add(
                _mm256_maddubs_epi16(r1_13, k.red_bottom),
                _mm256_maddubs_epi16(r3_13, k.red_bottom),
            ),
        );
        let blue = (
            add(
                _mm256_maddubs_epi16(r0_02, k.blue_top),
                _mm256_maddubs_epi16(r2_02, k.blue_top),
            ),
            _mm256_maddubs_epi16(r2_02, k.blue_bottom),
        );
        let green = (
            add(
                _mm256_maddubs_epi16(r1_02, k.green_top),
                add(
                    _mm256_shuffle_epi8(r0, k.col_1_low),
                    _mm256_shuffle_epi8(r2, k.col_1_low),
                ),
            ),
            add(
                _mm256_maddubs_epi16(r2_13, k.green_bottom),
                add(
                    _mm256_shuffle_epi8(r1, k.col_2_high),
                    _mm256_shuffle_epi8(r3, k.col_2_high),
                ),
            ),
        );
        // The weight pairs, mirrored with the neighbourhood: top and
        // bottom swapped, then left and right.
        let (top, bottom) = weight_pairs(weights);
        let (top, bottom) = (
            _mm256_blendv_epi8(top, bottom, y_odd),
            _mm256_blendv_epi8(bottom, top, y_odd),
        );
        let swap = _mm256_blendv_epi8(k.ident, k.swap16, x_odd);
        let (top, bottom) = (
            _mm256_shuffle_epi8(top, swap),
            _mm256_shuffle_epi8(bottom, swap),
        );
        [
            weigh(red, top, bottom),
            weigh(green, top, bottom),
            weigh(blue, top, bottom),
        ]
    }

    /// `Σ w·S` of a channel's `S` pairs (top, bottom) with the weight
    /// pairs `top` and `bottom`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn weigh((t, b): (__m256i, __m256i), top: __m256i, bottom: __m256i) -> __m256i {
        _mm256_add_epi32(_mm256_madd_epi16(t, top), _mm256_madd_epi16(b, bottom))
    }

    /// Sums of two Bayer steps.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn bayer_add(a: [__m256i; 3], b: [__m256i; 3]) -> [__m256i; 3] {
        [
            _mm256_add_epi32(a[0], b[0]),
            _mm256_add_epi32(a[1], b[1]),
            _mm256_add_epi32(a[2], b[2]),
        ]
    }

    /// With `GAIN`, a Bayer step's sums scaled by a gain: brought to the
    /// scale of the other images' sums (4096, rounded down) first, so
    /// that the product fits in `u32`; without, the sums.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn bayer_gain<const GAIN: bool>(a: [__m256i; 3], gain: __m256i) -> [__m256i; 3] {
        if !GAIN {
            return a;
        }
        [
            _mm256_mullo_epi32(_mm256_srli_epi32::<2>(a[0]), gain),
            _mm256_mullo_epi32(_mm256_srli_epi32::<2>(a[1]), gain),
            _mm256_mullo_epi32(_mm256_srli_epi32::<2>(a[2]), gain),
        ]
    }

    /// Rounds and stores 8 Bayer pixels' sums (from [`bayer`], gained
    /// with `GAIN`; saturated at 255) in 24 bytes of RGB.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn store_bayer<const GAIN: bool>(dst: &mut [u8], a: [__m256i; 3], k: &Consts) {
        let [r, g, b] = if GAIN {
            [
                rounded::<true>(a[0], k),
                rounded::<true>(a[1], k),
                rounded::<true>(a[2], k),
            ]
        } else {
            [
                _mm256_srli_epi32::<{ SHIFT as i32 + 2 }>(_mm256_add_epi32(a[0], k.round_bayer)),
                _mm256_srli_epi32::<{ SHIFT as i32 + 2 }>(_mm256_add_epi32(a[1], k.round_bayer)),
                _mm256_srli_epi32::<{ SHIFT as i32 + 2 }>(_mm256_add_epi32(a[2], k.round_bayer)),
            ]
        };
        // Per 128-bit lane (pixels 0–3, then 4–7): R, G, B, B as bytes.
        let bytes = _mm256_packus_epi16(_mm256_packus_epi32(r, g), _mm256_packus_epi32(b, b));
        let rgb = _mm256_shuffle_epi8(bytes, k.bayer_rgb);
        let (lo, hi) = dst.split_at_mut(12);
        store12(lo, _mm256_castsi256_si128(rgb));
        store12(hi, _mm256_extracti128_si256::<1>(rgb));
    }

    /// Stores the first 12 bytes of `v` in `dst`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn store12(dst: &mut [u8], v: __m128i) {
        dst[..8].copy_from_slice(&(_mm_cvtsi128_si64(v) as u64).to_le_bytes());
        dst[8..12].copy_from_slice(&(_mm_extract_epi32::<2>(v) as u32).to_le_bytes());
    }
}
