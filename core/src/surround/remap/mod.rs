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
//! of one camera: two gathers fetch each pixel's top and bottom bytes, a
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
//! # Files
//!
//! - `plan.rs`: the plan, built once per view and blend mode.
//! - `scalar.rs`: the portable and BMI2 kernels.
//! - `avx2.rs`: the AVX2 kernels.
//!
//! The kernel runs with the widest instruction set the CPU has
//! ([`crate::cpu::Isa`]), or a narrower one that a caller forces.

#[cfg(target_arch = "x86_64")]
mod avx2;
mod plan;
mod scalar;
#[cfg(test)]
mod tests;

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

/// Runs every run of `plan` (checked by [`Plan::execute_with`]) with the
/// kernels of `isa` (AVX-512 runs the AVX2 kernels), or of the widest set
/// below it the CPU has.
fn run(isa: Isa, plan: &Plan, images: &[Image<'_>], ch: usize, out: &mut [u8]) {
    match isa.supported() {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 if plan.gather_ok => {
            // SAFETY: `supported` returns AVX2 or AVX-512 only when the CPU
            // has AVX2 and BMI2 (`crate::cpu`), the features `run_avx2` is
            // compiled for; the plan's invariant holds
            // (`gather_ok`) and `execute_with` checked that each image
            // has its camera's size and at least w·h·ch bytes: the
            // contract of `run_avx2`.
            #[allow(unsafe_code)]
            unsafe {
                run_avx2(plan, images, ch, out);
            }
        }
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 | Isa::Bmi2 => {
            // SAFETY: `supported` returns these only when the CPU has BMI2,
            // the feature `run_bmi2` is compiled for.
            #[allow(unsafe_code)]
            unsafe {
                run_bmi2(plan, images, ch, out);
            }
        }
        _ => run_portable(plan, images, ch, out),
    }
}

/// How many runs ahead the source pixels are prefetched.
const AHEAD: usize = 8;
/// Every how many taps of a run a source pixel is prefetched.
const STRIDE: usize = 4;

/// Asks for the cache lines of the source pixels of `run` (its top-left
/// and bottom-left neighbours, every few taps), which will be read a few
/// runs later: the lines a run needs are a few hundred instructions
/// apart, too far for the out-of-order window to overlap their misses.
#[inline(always)]
fn prefetch_run(plan: &Plan, run: Option<&Run>, images: &[Image<'_>], ch: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let Some(run) = run else { return };
        let (len, first) = (run.len as usize, run.taps as usize);
        let Some(cams) = plan
            .cameras
            .get(run.cameras as usize..run.cameras as usize + run.n as usize)
        else {
            return;
        };
        for (j, &c) in cams.iter().enumerate() {
            let Some(img) = images.get(c as usize) else {
                continue;
            };
            let Some(taps) = plan.index.get(first + j * len..first + (j + 1) * len) else {
                continue;
            };
            let row = ch * img.width;
            for &i in taps.iter().step_by(STRIDE) {
                let top = img.bytes.as_ptr().wrapping_add(ch * i as usize);
                // SAFETY: a prefetch reads nothing into the program and
                // never faults, whatever the address.
                #[allow(unsafe_code)]
                unsafe {
                    use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
                    _mm_prefetch::<_MM_HINT_T0>(top.cast::<i8>());
                    _mm_prefetch::<_MM_HINT_T0>(top.wrapping_add(row).cast::<i8>());
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (plan, run, images, ch);
}
