//! The fused per-pixel kernel behind Eq. 1: simulated exposure change →
//! 3×3 Sobel → magnitude → `ln(λ·max(m − δ, 0) + 1)` → sum, one image row at
//! a time so that every intermediate stays in the L1 cache.
//!
//! Three things make it fast:
//!
//! - **One pass per anchor, three rows of state.** Each source row is mapped
//!   once into a ring of three rows; the vertical Sobel passes run over the
//!   ring and the horizontal ones over the two pass rows. A row's last,
//!   partial vector is computed at full width over zero padding, with the
//!   lanes beyond the row masked out.
//! - **A sum of logarithms is the logarithm of a product.** The unweighted
//!   score needs only `Σ ln q` with `q = 1 + λ·max(m − δ, 0) ∈ [1, q_max]`.
//!   Each column multiplies its `q`s into a running product and moves the
//!   product's binary exponent into an integer counter every few rows, so
//!   it cannot overflow. At the end the columns' mantissas are multiplied
//!   eight at a time in double precision, so one logarithm per eight columns
//!   replaces one per pixel. The relative rounding error is about 6e-8 per
//!   factor, i.e. about 6e-8 absolute per pixel in `ln q`. Weights that are
//!   all 0 or 1 (a scale-and-clip mask) keep the product: `q^w` is `q` or 1.
//! - **Explicit lanes and run-time dispatch.** The loops are written over
//!   fixed-size arrays of 16 lanes that the compiler turns into vector code
//!   (16 rather than the register width: fewer, longer chunks measured
//!   faster on every instruction set), and each kernel is compiled three
//!   times: for baseline x86-64 (SSE2), for AVX2 + FMA, and for AVX-512. The
//!   widest the CPU supports is chosen at run time ([`Isa::detect`]).
//!
//! The weighted score (a metering mask) and the information map keep one
//! fast logarithm per pixel: weights are fractional at mask borders.
//!
//! On AVX-512 the unweighted (or 0/1-weighted) passes run the Sobel
//! operator in one loop per row (`product_row_avx512`): each vector's
//! vertical passes stay in registers and the next vector's are shifted in
//! across the boundary with `valignd`, which the portable lanes cannot
//! express (LLVM turns such shifts into gathers). That loop is the one place
//! with `unsafe` loads and stores; their bounds are checked before it.
//!
//! Row buffers start on a cache line (`Aligned`), so whole-vector stores
//! never straddle two lines. The γ-mapping's `log₂ I` (`log2_map`) has no
//! division (`fastmath::log2`), and `2^z` rounds and places the exponent
//! with one addition (`fastmath::Exp2`).
//!
//! # Files
//!
//! - `source.rs`: the exposure simulations a pass maps each row through.
//! - `sobel.rs`: the Sobel/log kernel (the passes of Eq. 1 and `log₂ I`).
//! - `saturation.rs`: the sums over saturated pixels that scale-and-clip
//!   needs.
//! - `avx512.rs`: the AVX-512 row loop.
//!
//! This file holds what they share: the row buffers' alignment, the lanes
//! of a row, and the run-time dispatch.

#[cfg(target_arch = "x86_64")]
mod avx512;
mod saturation;
mod sobel;
mod source;
#[cfg(test)]
#[allow(clippy::float_cmp)] // exact values: zero, one and powers of two
mod tests;

pub(crate) use saturation::saturation_sums;
pub(crate) use sobel::{information, log2_map, sum_ln_q, sum_ln_q_and_dot, Params, Rows};
pub(crate) use source::Source;

use crate::cpu::Isa;

/// The instruction set the kernels run with when `isa` is asked for: the
/// widest at or below it that the CPU has and the kernels have code for
/// (no BMI2 code: that runs the baseline code).
pub(crate) fn kernel_isa(isa: Isa) -> Isa {
    match isa.supported() {
        Isa::Bmi2 => Isa::Baseline,
        other => other,
    }
}

/// The most lanes any kernel uses: rows are padded by this much.
const MAX_LANES: usize = 16;

/// A buffer whose first element sits on a 64-byte boundary (a cache line),
/// so that whole-vector stores at multiples of 16 lanes never straddle two
/// lines (`Vec` only promises the element's alignment).
#[derive(Clone, Debug, Default)]
pub(crate) struct Aligned<T> {
    buf: Vec<T>,
    start: usize,
    len: usize,
}

impl<T: Copy + Default> Aligned<T> {
    /// `len` copies of `value`.
    fn reset(&mut self, len: usize, value: T) {
        let size = std::mem::size_of::<T>().max(1);
        let spare = 64 / size;
        self.buf.clear();
        self.buf.resize(len + spare, value);
        let misalign = (self.buf.as_ptr() as usize % 64) / size;
        self.start = (spare - misalign) % spare;
        self.len = len;
    }
}

impl<T> std::ops::Deref for Aligned<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.buf[self.start..self.start + self.len]
    }
}

impl<T> std::ops::DerefMut for Aligned<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.buf[self.start..self.start + self.len]
    }
}

/// A kernel, compiled once per instruction set by [`dispatch`].
trait Kernel {
    type Output;
    /// Runs with `L` lanes, fusing multiply-adds when `FMA`.
    fn run<const L: usize, const FMA: bool>(self) -> Self::Output;
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
fn run_avx512<K: Kernel>(kernel: K) -> K::Output {
    kernel.run::<16, true>()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run::<16, true>()
}

/// Runs `kernel` compiled for `isa`, or for the widest set the CPU has if
/// it lacks `isa`.
fn dispatch<K: Kernel>(isa: Isa, kernel: K) -> K::Output {
    match isa.supported() {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => {
            // SAFETY: `supported` only returns AVX-512 when the CPU has
            // AVX-512F, AVX2 and FMA.
            #[allow(unsafe_code)]
            unsafe {
                run_avx512(kernel)
            }
        }
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => {
            // SAFETY: `supported` only returns AVX2 when the CPU has AVX2
            // and FMA.
            #[allow(unsafe_code)]
            unsafe {
                run_avx2(kernel)
            }
        }
        _ => kernel.run::<16, false>(),
    }
}

/// `L` values of `row` from `x`, padded with zeros beyond its end.
#[inline(always)]
fn lanes<const L: usize>(row: &[f32], x: usize) -> [f32; L] {
    let mut out = [0.0f32; L];
    match row.get(x..x + L) {
        Some(v) => out.copy_from_slice(v),
        None => {
            let rest = row.len().saturating_sub(x);
            out[..rest].copy_from_slice(&row[x..x + rest]);
        }
    }
    out
}

/// `Σ v` in double precision.
fn total(v: &[f32]) -> f64 {
    v.iter().map(|&v| f64::from(v)).sum()
}
