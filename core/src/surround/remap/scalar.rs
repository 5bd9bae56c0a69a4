//! The scalar kernels: portable 64-bit integer code, and the same with
//! BMI2's `pdep`/`pext` for the RGB lanes (see the module documentation of
//! [`super`]).

use super::plan::{Job, Taps};
use super::{bayer, prefetch_run, Image, AHEAD, GAIN_SHIFT, ONE, SHIFT, UNIT_GAIN};

/// Per-lane rounding of an RGB sum (three 21-bit lanes).
const ROUND_RGB: u64 = (ONE as u64 / 2) * (1 | 1 << 21 | 1 << 42);
/// The bytes of a pixel placed in the three 21-bit lanes.
#[cfg(target_arch = "x86_64")]
const SPREAD_MASK: u64 = 0xff | 0xff << 21 | 0xff << 42;
/// Rounding of a mono sum.
const HALF: u32 = ONE / 2;
/// A lane of [`ROUND_RGB`] (21 bits).
const LANE: u64 = (1 << 21) - 1;
/// Rounding of a Bayer sum (scale 4·4096).
const HALF_BAYER: u64 = 2 * ONE as u64;

/// The byte of a gained sum `Σ G·s` (scale 256·4096): rounded, and
/// saturated at white.
#[inline(always)]
fn gained(acc: u64) -> u8 {
    ((acc + (1 << (GAIN_SHIFT - 1))) >> GAIN_SHIFT).min(255) as u8
}

/// Camera `k`'s gain in 1/256 (1 when there are none).
#[inline(always)]
fn gain(gains: &[u16], k: u32) -> u64 {
    u64::from(gains.get(k as usize).copied().unwrap_or(UNIT_GAIN))
}

/// The three bytes of a pixel spread to the 21-bit lanes.
#[inline(always)]
fn spread_portable(x: u64) -> u64 {
    (x & 0xff) | (x & 0xff00) << 13 | (x & 0xff_0000) << 26
}

/// The rounded bytes of a sum in the lanes, as R | G << 8 | B << 16.
#[inline(always)]
fn pick_portable(acc: u64) -> u32 {
    let acc = acc + ROUND_RGB;
    ((acc >> SHIFT & 0xff)
        | (acc >> (21 + SHIFT - 8) & 0xff00)
        | (acc >> (42 + SHIFT - 16) & 0xff_0000)) as u32
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "bmi2")]
#[inline]
fn spread_bmi2(x: u64) -> u64 {
    std::arch::x86_64::_pdep_u64(x, SPREAD_MASK)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "bmi2")]
#[inline]
fn pick_bmi2(acc: u64) -> u32 {
    std::arch::x86_64::_pext_u64(acc + ROUND_RGB, SPREAD_MASK << SHIFT) as u32
}

/// 8 bytes from `src` at `o` (little-endian), or 0 past the end (which
/// the plan's indices never reach).
#[inline(always)]
fn load8(src: &[u8], o: usize) -> u64 {
    src.get(o..)
        .and_then(|s| s.first_chunk::<8>())
        .map_or(0, |b| u64::from_le_bytes(*b))
}

/// 2 bytes from `src` at `o`, or 0 past the end.
#[inline(always)]
fn load2(src: &[u8], o: usize) -> u32 {
    src.get(o..)
        .and_then(|s| s.first_chunk::<2>())
        .map_or(0, |b| u32::from(u16::from_le_bytes(*b)))
}

/// One mono sample: `Σ w·p` (not yet rounded).
#[inline(always)]
fn mono(img: &Image<'_>, index: u32, w: u64) -> u32 {
    let o = index as usize;
    let top = load2(img.bytes, o);
    let bottom = load2(img.bytes, o + img.width);
    let w = |k: u32| (w >> (16 * k)) as u32 & 0xffff;
    (top & 0xff) * w(0) + (top >> 8) * w(1) + (bottom & 0xff) * w(2) + (bottom >> 8) * w(3)
}

#[inline(always)]
fn store3(d: &mut [u8], v: u32) {
    d.copy_from_slice(&v.to_le_bytes()[..3]);
}

/// The scalar kernels, written once and compiled with either pair of
/// lane helpers under the attributes given: `$rgb` is one RGB sample,
/// `$pixels` composes pixels `p0..p1` of a run, `$name` the whole plan.
macro_rules! scalar_kernels {
    ($(#[$attr:meta])* $name:ident, $pixels:ident, $rgb:ident, $spread:ident, $pick:ident) => {
        /// One RGB sample in the lanes: `Σ w·p` (not yet rounded).
        $(#[$attr])*
        #[inline]
        fn $rgb(img: &Image<'_>, index: u32, w: u64) -> u64 {
            let o = 3 * index as usize;
            let top = load8(img.bytes, o);
            // From 2 bytes early: the bottom-right pixel may be the
            // image's last.
            let bottom = load8(img.bytes, o + 3 * img.width - 2) >> 16;
            $spread(top) * (w & 0xffff)
                + $spread(top >> 24) * (w >> 16 & 0xffff)
                + $spread(bottom) * (w >> 32 & 0xffff)
                + $spread(bottom >> 24) * (w >> 48)
        }

        /// Pixels `p0..p1` of a run (`taps`) of `job` into `dst`, the run's
        /// part of the canvas, the cameras' contributions scaled by their
        /// gains when `GAIN`.
        $(#[$attr])*
        pub(super) fn $pixels<const GAIN: bool>(
            job: &Job<'_>,
            taps: &Taps<'_>,
            (p0, p1): (usize, usize),
            dst: &mut [u8],
        ) {
            let (images, gains, ch, cams) = (job.images, job.gains, job.ch, taps.cams);
            if ch == 1 {
                for p in p0..p1 {
                    let (mut sum, mut acc) = (HALF, 0u64);
                    for (j, &k) in cams.iter().enumerate() {
                        if let Some(img) = images.get(k as usize) {
                            let (i, w, _) = taps.tap(j, p);
                            if GAIN {
                                acc += u64::from(mono(img, i, w)) * gain(gains, k);
                            } else {
                                sum += mono(img, i, w);
                            }
                        }
                    }
                    dst[p] = if GAIN { gained(acc) } else { (sum >> SHIFT) as u8 };
                }
            } else if !GAIN && taps.mosaics == 0 {
                for p in p0..p1 {
                    let mut sum = 0;
                    for (j, &k) in cams.iter().enumerate() {
                        if let Some(img) = images.get(k as usize) {
                            let (i, w, _) = taps.tap(j, p);
                            sum += $rgb(img, i, w);
                        }
                    }
                    store3(&mut dst[3 * p..3 * p + 3], $pick(sum));
                }
            } else {
                // Channel by channel, at the Bayer scale (4·4096) or the
                // gained one (256·4096).
                for p in p0..p1 {
                    let mut acc = [0u64; 3];
                    for (j, &k) in cams.iter().enumerate() {
                        let Some(img) = images.get(k as usize) else {
                            continue;
                        };
                        let (i, w, site) = taps.tap(j, p);
                        let s = match img.cfa {
                            Some(cfa) => bayer::sample(
                                img.bytes, img.width, img.height, cfa, i, w, site,
                            ),
                            None => {
                                let l = $rgb(img, i, w);
                                [l & LANE, l >> 21 & LANE, l >> 42].map(|v| 4 * v as u32)
                            }
                        };
                        for (a, s) in acc.iter_mut().zip(s) {
                            *a += if GAIN {
                                u64::from(s >> 2) * gain(gains, k)
                            } else {
                                u64::from(s)
                            };
                        }
                    }
                    let px = acc.map(|a| {
                        if GAIN {
                            gained(a)
                        } else {
                            ((a + HALF_BAYER) >> (SHIFT + 2)) as u8
                        }
                    });
                    dst[3 * p..3 * p + 3].copy_from_slice(&px);
                }
            }
        }

        /// Runs the whole plan of `job` (see [`super::run`]).
        $(#[$attr])*
        pub(super) fn $name<const GAIN: bool>(job: Job<'_>, out: &mut [u8]) {
            let (plan, images, gains, ch) = (job.plan, job.images, job.gains, job.ch);
            let ahead = AHEAD;
            for (r, run) in plan.runs.iter().enumerate() {
                prefetch_run(&job, plan.runs.get(r + ahead));
                let Some((dst, taps)) = plan.parts(run, &job, out) else {
                    continue;
                };
                if run.n == 0 {
                    dst.fill(0);
                    continue;
                }
                let len = run.len as usize;
                let (index, weights) = (taps.index, taps.weights);
                match (ch, taps.cams) {
                    // One camera: the common case, without the loop
                    // over cameras.
                    (1, &[k]) => {
                        let Some(img) = images.get(k as usize) else { continue };
                        if GAIN {
                            let g = gain(gains, k);
                            for ((d, &i), &w) in dst.iter_mut().zip(index).zip(weights) {
                                *d = gained(u64::from(mono(img, i, w)) * g);
                            }
                        } else {
                            for ((d, &i), &w) in dst.iter_mut().zip(index).zip(weights) {
                                *d = ((mono(img, i, w) + HALF) >> SHIFT) as u8;
                            }
                        }
                    }
                    (3, &[k]) if !GAIN && taps.mosaics == 0 => {
                        let Some(img) = images.get(k as usize) else { continue };
                        for ((d, &i), &w) in dst.chunks_exact_mut(3).zip(index).zip(weights) {
                            store3(d, $pick($rgb(img, i, w)));
                        }
                    }
                    _ => $pixels::<GAIN>(&job, &taps, (0, len), dst),
                }
            }
        }
    };
}

scalar_kernels!(
    run_portable,
    pixels_portable,
    rgb_portable,
    spread_portable,
    pick_portable
);
#[cfg(target_arch = "x86_64")]
scalar_kernels!(
    #[target_feature(enable = "bmi2")]
    run_bmi2,
    pixels_bmi2,
    rgb_bmi2,
    spread_bmi2,
    pick_bmi2
);
