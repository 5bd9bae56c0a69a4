//! The AVX2 kernels: gathers and `vpmaddwd`, 4 RGB or 8 mono pixels of one
//! camera a step (see the module documentation of [`super`]).

use super::scalar::pixels_bmi2;
use super::{prefetch_run, Image, Plan, AHEAD};

/// The steps of one run of `$n`-pixel vectors through the AVX2 chunk
/// functions `$sample` (a step's sums for one camera), `$add` and
/// `$store` (`$bytes` canvas bytes a step): one camera, two, or the
/// general loop over any number. Stops before the run's last
/// `len % $n` pixels.
///
/// Expanded inside [`run_avx2`], whose contract makes each `$sample`
/// call sound: the taps of camera `j` are `cams[j]`'s and `image(j)`
/// is its image.
macro_rules! steps {
    ($k:ident, $dst:ident, $index:ident, $weights:ident, $len:ident, $cams:ident, $image:ident;
     $n:expr, $bytes:expr, $sample:path, $add:path, $store:path) => {
        match ($cams.len(), $image(0), $image(1)) {
            (1, Some(a), _) => {
                let chunks = $dst
                    .chunks_exact_mut($bytes)
                    .zip($index.chunks_exact($n))
                    .zip($weights.chunks_exact($n));
                for ((d, i), w) in chunks {
                    let (Some(i), Some(w)) = (i.first_chunk(), w.first_chunk()) else {
                        break;
                    };
                    // SAFETY: see the macro's docs.
                    let s = unsafe { $sample(a.bytes, a.width, i, w, &$k) };
                    $store(d, s, &$k);
                }
            }
            // Two cameras: an overlap.
            (2, Some(a), Some(b)) => {
                let (ia, ib) = $index.split_at($len);
                let (wa, wb) = $weights.split_at($len);
                let chunks = $dst
                    .chunks_exact_mut($bytes)
                    .zip(ia.chunks_exact($n).zip(wa.chunks_exact($n)))
                    .zip(ib.chunks_exact($n).zip(wb.chunks_exact($n)));
                for ((d, (ia, wa)), (ib, wb)) in chunks {
                    let (Some(ia), Some(wa), Some(ib), Some(wb)) = (
                        ia.first_chunk(),
                        wa.first_chunk(),
                        ib.first_chunk(),
                        wb.first_chunk(),
                    ) else {
                        break;
                    };
                    // SAFETY: see the macro's docs.
                    let s = unsafe {
                        $add(
                            $sample(a.bytes, a.width, ia, wa, &$k),
                            $sample(b.bytes, b.width, ib, wb, &$k),
                        )
                    };
                    $store(d, s, &$k);
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

/// The AVX2 kernel: per camera, the taps of 4 RGB pixels (two gathers
/// of each pixel's top and bottom 8 bytes) or 8 mono pixels (two
/// gathers of 4 bytes) at a time; each neighbour pair (left, right)
/// meets its weight pair in one `vpmaddwd`; the cameras' sums are
/// added, rounded and packed. The ends of runs go through the BMI2
/// kernel.
///
/// # Safety
///
/// The CPU has AVX2 and BMI2; `plan.gather_ok`; every image has the
/// size of its camera's source and at least `w·h·ch` bytes.
#[target_feature(enable = "avx2,bmi2")]
#[allow(unsafe_code)]
pub(super) unsafe fn run_avx2(plan: &Plan, images: &[Image<'_>], ch: usize, out: &mut [u8]) {
    use ops::{Consts, MONO, RGB};
    let k = Consts::new();
    for (r, run) in plan.runs.iter().enumerate() {
        prefetch_run(plan, plan.runs.get(r + AHEAD), images, ch);
        let Some((dst, index, weights, cams)) = plan.parts(run, ch, out) else {
            continue;
        };
        if cams.is_empty() {
            dst.fill(0);
            continue;
        }
        let len = run.len as usize;
        let image = |j: usize| cams.get(j).and_then(|&c| images.get(c as usize));
        let main = if ch == 1 {
            let main = len - len % MONO;
            let dst = &mut dst[..main];
            steps!(k, dst, index, weights, len, cams, image;
                MONO, MONO, ops::mono, ops::mono_add, ops::store_mono);
            main
        } else {
            let main = len - len % RGB;
            let dst = &mut dst[..3 * main];
            steps!(k, dst, index, weights, len, cams, image;
                RGB, 3 * RGB, ops::rgb, ops::rgb_add, ops::store_rgb);
            main
        };
        pixels_bmi2(images, cams, index, weights, len, ch, (main, len), dst);
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
}

/// The AVX2 operations of a step.
mod ops {
    use std::arch::x86_64::*;

    use super::super::SHIFT;
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
    }

    impl Consts {
        #[target_feature(enable = "avx2")]
        pub(super) fn new() -> Self {
            Self {
                zero: _mm256_setzero_si256(),
                round: _mm256_set1_epi32(1 << (SHIFT - 1)),
                rgb_top: _mm256_broadcastsi128_si256(lane(lanes::RGB_TOP)),
                rgb_bottom: _mm256_broadcastsi128_si256(lane(lanes::RGB_BOTTOM)),
                mono_top: _mm256_broadcastsi128_si256(lane(lanes::MONO_TOP)),
                mono_bottom: _mm256_broadcastsi128_si256(lane(lanes::MONO_BOTTOM)),
                lanes: _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7),
                rgb12: lane(lanes::RGB12),
            }
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
        let i = _mm_setr_epi32(
            index[0] as i32,
            index[1] as i32,
            index[2] as i32,
            index[3] as i32,
        );
        let o = _mm_add_epi32(i, _mm_slli_epi32::<1>(i));
        let rows = _mm_set1_epi64x(i64::from(3 * width as i32 - 2) << 32);
        // Pixels 0 and 2 in one gather, 1 and 3 in the other: then
        // each 128-bit lane's weight pairs are one in-lane shuffle of
        // the weights (pixel 0's and 1's in lane 0, 2's and 3's in
        // lane 1).
        let o02 = _mm_add_epi32(_mm_shuffle_epi32::<0b10_10_00_00>(o), rows);
        let o13 = _mm_add_epi32(_mm_shuffle_epi32::<0b11_11_01_01>(o), rows);
        let base = bytes.as_ptr().cast::<i64>();
        // SAFETY: each offset is `3·index` or `3·(index + width) − 2`,
        // whose 8 bytes lie in `bytes` (the contract).
        let (g02, g13) = unsafe {
            (
                _mm256_i32gather_epi64::<1>(base, o02),
                _mm256_i32gather_epi64::<1>(base, o13),
            )
        };
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

    /// Rounds and stores 4 RGB pixels' sums (from [`rgb`]) in 12 bytes.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn store_rgb(dst: &mut [u8], (a, b): (__m256i, __m256i), k: &Consts) {
        let a = _mm256_srli_epi32::<{ SHIFT as i32 }>(_mm256_add_epi32(a, k.round));
        let b = _mm256_srli_epi32::<{ SHIFT as i32 }>(_mm256_add_epi32(b, k.round));
        // Lane 0: pixels 0, 1; lane 1: pixels 2, 3 (RGB0 each), in
        // their low 8 bytes.
        let bytes = _mm256_packus_epi16(_mm256_packus_epi32(a, b), k.zero);
        let ordered = _mm256_castsi256_si128(_mm256_permute4x64_epi64::<0b11_01_10_00>(bytes));
        let rgb = _mm_shuffle_epi8(ordered, k.rgb12);
        dst[..8].copy_from_slice(&(_mm_cvtsi128_si64(rgb) as u64).to_le_bytes());
        dst[8..12].copy_from_slice(&(_mm_extract_epi32::<2>(rgb) as u32).to_le_bytes());
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
        let i = _mm256_setr_epi32(
            index[0] as i32,
            index[1] as i32,
            index[2] as i32,
            index[3] as i32,
            index[4] as i32,
            index[5] as i32,
            index[6] as i32,
            index[7] as i32,
        );
        let below = _mm256_add_epi32(i, _mm256_set1_epi32(width as i32 - 2));
        let base = bytes.as_ptr().cast::<i32>();
        // SAFETY: each offset is `index` or `index + width − 2`, whose
        // 4 bytes lie in `bytes` (the contract).
        let (top, bottom) = unsafe {
            (
                _mm256_i32gather_epi32::<1>(base, i),
                _mm256_i32gather_epi32::<1>(base, below),
            )
        };
        let w = |o: usize| {
            _mm256_castsi256_ps(_mm256_setr_epi64x(
                weights[o] as i64,
                weights[o + 1] as i64,
                weights[o + 2] as i64,
                weights[o + 3] as i64,
            ))
        };
        let (w0, w1) = (w(0), w(4));
        // The top pairs are the even 32-bit lanes, the bottom pairs the
        // odd ones; the shuffle leaves 64-bit blocks 0, 2, 1, 3.
        let even =
            _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_castps_si256(_mm256_shuffle_ps::<
                0b10_00_10_00,
            >(w0, w1)));
        let odd =
            _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_castps_si256(_mm256_shuffle_ps::<
                0b11_01_11_01,
            >(w0, w1)));
        _mm256_add_epi32(
            _mm256_madd_epi16(_mm256_shuffle_epi8(top, k.mono_top), even),
            _mm256_madd_epi16(_mm256_shuffle_epi8(bottom, k.mono_bottom), odd),
        )
    }

    /// Rounds and stores 8 mono pixels' sums (from [`mono`]).
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn store_mono(dst: &mut [u8], a: __m256i, k: &Consts) {
        let a = _mm256_srli_epi32::<{ SHIFT as i32 }>(_mm256_add_epi32(a, k.round));
        let bytes = _mm256_packus_epi16(_mm256_packus_epi32(a, a), k.zero);
        // Lane 0 holds pixels 0–3 in its first 4 bytes, lane 1 pixels
        // 4–7.
        let ordered = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(bytes, k.lanes));
        dst[..8].copy_from_slice(&(_mm_cvtsi128_si64(ordered) as u64).to_le_bytes());
    }
}
