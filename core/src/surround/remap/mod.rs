//! The per-frame work of the composition: a gather-based fixed-point
//! bilinear remap, with the blend weights folded into the bilinear ones.
//!
//! # The plan
//!
//! A [`Plan`] is built once per view and blend mode. It walks the canvas in
//! tiles and cuts each tile's rows into runs of pixels that the same cameras
//! contribute to: a run of one camera is a plain remap written straight
//! into the canvas, a run of several cameras sums their samples before it
//! writes; the pixels no camera shows are runs of black. Every canvas pixel
//! lies in exactly one run, so a composition writes each pixel once and
//! needs no cleared canvas and no accumulator.
//!
//! Per pixel and contributing camera the plan holds one tap: the index of
//! the top-left source pixel of the bilinear neighbourhood and the four
//! weights (top-left, top-right, bottom-left, bottom-right) in 1/4096, the
//! taps of a run stored camera by camera so that each camera's are
//! contiguous. The blend weight is folded in: a camera with blend weight
//! `b` (of 256) contributes `b/256` of the bilinear weights, and all of a
//! pixel's weights are rounded together so that they sum to exactly 4096
//! (largest remainder). A pixel is then `(Σ w·p + 2048) >> 12`: against the
//! exact value (double precision, at the map's position) the weights are
//! off by less than 1/4096 each, which moves a pixel by less than
//! `127.5·n/4096` for `n` weights (0.125 for one camera, 0.25 for two), and
//! the last rounding adds at most ½: the remap is within 0.75 of the exact
//! bilinear value for up to two cameras.
//!
//! # The kernels
//!
//! With AVX2 (x86-64, detected at run time) a step is 4 RGB or 8 mono pixels
//! of one camera (8 Bayer pixels: see below): each pixel's top and bottom
//! bytes are loaded one by one into two vectors (plain loads: on the
//! machine measured they beat `vpgather` by a quarter to a third, see
//! BENCHMARKS.md; the Bayer kernel, which reads four rows, keeps its
//! gathers, which measured faster there), a
//! byte shuffle pairs each left neighbour with its right one, and one
//! `vpmaddwd` per row applies the weight pairs; the cameras' sums are
//! added, rounded and packed. The source lines a run will read are
//! prefetched a few runs ahead: the lines a run needs are too far apart in
//! the instruction stream for the out-of-order window to overlap their
//! misses.
//!
//! Without AVX2 (and for the last pixels of a run) an RGB sample is computed
//! in one `u64` with three 21-bit lanes: each of the four neighbours is
//! spread from its three bytes to the lanes, multiplied by its weight (at
//! most 255 · 4096 + 2048 < 2²¹ per lane, so no lane carries into the next)
//! and summed; the three bytes are then picked out of the lanes. The two
//! top neighbours are one unaligned 8-byte load, and so are the bottom two
//! (read 2 bytes early and shifted, so that the last pixel of the image
//! never reads past its end). With BMI2 the spreading and picking are one
//! `pdep`/`pext` each. All kernels give the same bytes.
//!
//! # Bayer mosaics
//!
//! A Bayer frame (any of the four orders) is read as it is, one byte a
//! pixel, and demosaiced at each tap: the tap's four pixels get the
//! bilinear demosaic (a pixel's own colour is its sample; a colour it
//! lacks is the mean of its two or four nearest samples of that colour,
//! the demosaic of OpenCV's `cvtColor` `COLOR_Bayer*2RGB`), which are then
//! weighed with the tap's weights as an RGB pixel's would be. With `S` 4×
//! a pixel's demosaic (an integer), a channel is `(Σ w·S + 2¹³) >> 14`:
//! nothing is rounded before the end, so a mosaic composes to the
//! bilinear remap of its bilinear demosaic within the same bound as RGB
//! (0.75 for two cameras), and within one level of demosaicing the whole
//! frame with OpenCV and composing the RGB frame, which rounds each
//! demosaiced value first (`tests/tests/surround_bayer.rs`). The measured
//! differences are in `BENCHMARKS.md`, Surround view composition.
//!
//! The tap reads the 4×4 neighbourhood `n[r][c]` from (x0 − 1, y0 − 1).
//! So that one formula serves the four orders and the four places of a
//! tap in the 2×2 pattern, the neighbourhood is mirrored left–right when
//! the top-left pixel is on an odd column of the pattern (red's being
//! even), top–bottom when it is on an odd row, and the weights with it;
//! the top-left pixel is then red, and the `S` of the top-left, top-right,
//! bottom-left and bottom-right pixels are
//!
//! ```text
//! R: 4·n11                  2·(n11 + n13)   2·(n11 + n31)   n11 + n13 + n31 + n33
//! G: n01 + n10 + n12 + n21  4·n12           4·n21           n12 + n21 + n23 + n32
//! B: n00 + n02 + n20 + n22  2·(n02 + n22)   2·(n20 + n22)   4·n22
//! ```
//!
//! Where the neighbourhood leaves the image the mosaic is reflected
//! without repeating its edge (…, 1, 0, 1, …), which keeps every pixel's
//! colour. OpenCV copies the image's outermost ring from the next
//! instead, so the two differ there; the tests compare the rest.
//!
//! The plan keeps a site table, one byte a tap (built when a mosaic is
//! first composed): the parities of x0 and y0 and whether the
//! neighbourhood leaves the image. The AVX2 kernel takes 8 taps of one
//! camera a step: four 32-bit gathers (one a neighbourhood row; a lane
//! mirrored top–bottom gathers its rows bottom-up), one byte shuffle
//! mirrors the lanes mirrored left–right, `vpmaddubsw` makes the `S` pairs
//! from the bytes, and `vpmaddwd` weighs them with the (mirrored) weight
//! pairs. Steps with a tap at the edge and runs that mix a mosaic with
//! other images go through the scalar kernels, which give the same bytes.
//! A mosaic composes into an RGB canvas; the composer makes a mono one the
//! grey of that.
//!
//! # Gains
//!
//! With a gain `G` per camera (in 1/256, 16 to 4096: 1/16 to 16), each
//! camera's unrounded sum is multiplied by its gain before the cameras'
//! sums are added (a Bayer sum brought to 1/4096 first, rounded down): the
//! sum, in 1/2²⁰, is at most 255·4096·4096 < 2³², and the end rounds it
//! and saturates it at 255. A pixel shown by one camera is then
//! `min(255, round(g·v))` of its unrounded ungained value `v`, to the
//! exact rounding; against the ungained byte, whose rounding the gain
//! multiplies, it is within `1 + g/2`. Without gains the ungained kernels
//! run, as before; a gain of 1 for every camera gives the same bytes
//! through the gained ones.
//!
//! # Files
//!
//! - `plan.rs`: the plan, built once per view and blend mode.
//! - `bayer.rs`: Bayer orders, the site table, the scalar Bayer tap.
//! - `scalar.rs`: the portable and BMI2 kernels.
//! - `avx2.rs`: the AVX2 kernels.
//!
//! The kernel runs with the widest instruction set the CPU has
//! ([`crate::cpu::Isa`]), or a narrower one that a caller forces.

#[cfg(target_arch = "x86_64")]
mod avx2;
mod bayer;
mod plan;
mod scalar;
#[cfg(test)]
mod tests;

pub(crate) use bayer::Cfa;
use plan::Job;
pub(crate) use plan::{round_to_total, Contribution, Image, Plan};

#[cfg(target_arch = "x86_64")]
use avx2::run_avx2;
use plan::Run;
#[cfg(target_arch = "x86_64")]
use scalar::run_bmi2;
use scalar::run_portable;

use crate::cpu::Isa;

/// Bits of the fixed-point weights.
const SHIFT: u32 = 12;
/// The weights of one canvas pixel sum to this.
const ONE: u32 = 1 << SHIFT;
/// Bits of a gained sum: the weights' and the gains' (1/256).
const GAIN_SHIFT: u32 = SHIFT + 8;
/// A gain of 1, in 1/256.
pub(crate) const UNIT_GAIN: u16 = 256;
/// The smallest gain, 1/16, in 1/256.
pub(crate) const MIN_GAIN: u16 = 16;
/// The largest gain, 16, in 1/256.
pub(crate) const MAX_GAIN: u16 = 4096;

/// Runs every run of `job.plan` with the kernels of `isa` (AVX-512 runs
/// the AVX2 kernels), or of the widest set below it the CPU has; with
/// `gained`, the gained kernels.
fn run(isa: Isa, job: Job<'_>, gained: bool, out: &mut [u8]) {
    if gained {
        run_with::<true>(isa, job, out);
    } else {
        run_with::<false>(isa, job, out);
    }
}

/// [`run`] with or without gains.
fn run_with<const GAIN: bool>(isa: Isa, job: Job<'_>, out: &mut [u8]) {
    match isa.supported() {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 if job.plan.gather_ok => {
            // SAFETY: `supported` returns AVX2 or AVX-512 only when the CPU
            // has AVX2 and BMI2 (`crate::cpu`), the features `run_avx2` is
            // compiled for; the plan's invariant holds (`gather_ok`),
            // `execute_with` checked that each image has its camera's
            // size and at least w·h bytes a channel (one for a mosaic),
            // and the job's sites are empty or the plan's own table: the
            // contract of `run_avx2`.
            #[allow(unsafe_code)]
            unsafe {
                run_avx2::<GAIN>(job, out);
            }
        }
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 | Isa::Bmi2 => {
            // SAFETY: `supported` returns these only when the CPU has BMI2,
            // the feature `run_bmi2` is compiled for.
            #[allow(unsafe_code)]
            unsafe {
                run_bmi2::<GAIN>(job, out);
            }
        }
        _ => run_portable::<GAIN>(job, out),
    }
}

/// How many runs ahead the source pixels are prefetched.
const AHEAD: usize = 8;
/// Every how many taps of a run a source pixel is prefetched.
const STRIDE: usize = 4;

/// Asks for the cache lines of the source pixels of `run` (its top-left
/// and bottom-left neighbours, every few taps; for a mosaic the four rows
/// of the neighbourhood), which will be read a few runs later: the lines a
/// run needs are a few hundred instructions apart, too far for the
/// out-of-order window to overlap their misses.
#[inline(always)]
fn prefetch_run(job: &Job<'_>, run: Option<&Run>) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let Some(run) = run else { return };
        let (plan, images, ch) = (job.plan, job.images, job.ch);
        let (len, first) = (run.len as usize, run.taps as usize);
        let Some(cams) = plan.run_cameras(run) else {
            return;
        };
        for (j, &c) in cams.iter().enumerate() {
            let Some(img) = images.get(c as usize) else {
                continue;
            };
            let Some(taps) = plan.index.get(first + j * len..first + (j + 1) * len) else {
                continue;
            };
            let bpp = img.bytes_per_pixel(ch);
            let row = bpp * img.width;
            let mosaic = img.cfa.is_some();
            for &i in taps.iter().step_by(STRIDE) {
                let top = img.bytes.as_ptr().wrapping_add(bpp * i as usize);
                // SAFETY: a prefetch reads nothing into the program and
                // never faults, whatever the address.
                #[allow(unsafe_code)]
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(top.cast::<i8>());
                    _mm_prefetch::<_MM_HINT_T0>(top.wrapping_add(row).cast::<i8>());
                    if mosaic {
                        _mm_prefetch::<_MM_HINT_T0>(top.wrapping_sub(row).cast::<i8>());
                        _mm_prefetch::<_MM_HINT_T0>(top.wrapping_add(2 * row).cast::<i8>());
                    }
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (job, run);
}
