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

use std::sync::OnceLock;

use super::fastmath::{self, madd};

/// The vector instruction set a kernel was compiled for; narrower sets
/// order first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// Baseline x86-64 (SSE2) or a non-x86 target, without fused
    /// multiply-adds.
    Baseline,
    /// AVX2 and FMA.
    Avx2,
    /// AVX-512 (F) and FMA.
    Avx512,
}

impl Isa {
    /// The widest instruction set this CPU supports (detected once).
    pub fn detect() -> Self {
        static DETECTED: OnceLock<Isa> = OnceLock::new();
        *DETECTED.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            {
                let avx2 = std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma");
                if avx2 && std::arch::is_x86_feature_detected!("avx512f") {
                    return Isa::Avx512;
                }
                if avx2 {
                    return Isa::Avx2;
                }
            }
            Isa::Baseline
        })
    }

    /// Every instruction set this CPU can run, narrowest first.
    pub fn available() -> Vec<Self> {
        let best = Self::detect();
        [Isa::Baseline, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .filter(|&isa| isa <= best)
            .collect()
    }

    /// `self`, or the widest this CPU has if it lacks `self`.
    pub fn supported(self) -> Self {
        self.min(Self::detect())
    }

    /// The name used in telemetry and benchmarks.
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }
}

/// Where the rows of the image to score come from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Source<'a> {
    /// The image as it is.
    Plain(&'a [f32]),
    /// The γ-mapping `I^γ = 2^(γ·log₂ I)`, from `log₂ I` (each value in
    /// `[−126/γ, 0]`, as [`log2_map`] makes them).
    Gamma { log2: &'a [f32], gamma: f32 },
    /// Scale-and-clip `min(1, s·I)`.
    Scale { luma: &'a [f32], s: f32 },
    /// Scale-and-hold: `s·I` below `level`, `I` (held) at or above it: a
    /// darkening `s < 1` that leaves saturated pixels saturated.
    Hold { luma: &'a [f32], s: f32, level: f32 },
    /// Scale-and-clip of a block average whose fraction `f` of samples is
    /// saturated: those are held at 1 and the rest, `I − f`, scaled and
    /// clipped as a block, `f + min(1 − f, s·(I − f))`.
    Blocks {
        luma: &'a [f32],
        saturated: &'a [f32],
        s: f32,
    },
    /// Scale-and-clip of a pixel whose saturated part is known from a
    /// darker frame: the part below saturation `u` scales, the saturated
    /// part `f` (the fraction of samples at full well) comes back below it
    /// once its true level `t` (what those samples sum to without the
    /// clip) scaled falls under it: `s·u + min(f, s·t)`.
    Declipped {
        unsaturated: &'a [f32],
        saturated: &'a [f32],
        hidden: &'a [f32],
        s: f32,
    },
}

/// The per-pixel constants of Eq. 1: `q = max(|∇'| + offset, 1)`, where the
/// rows are mapped already multiplied by `scale`, so that `∇' = scale·∇`,
/// is `1 + λ·max(m − δ, 0)` with `m = |∇| / (4√2)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params {
    scale: f32,
    offset: f32,
    /// How many rows' factors `q` each column's product takes before its
    /// exponent is moved out: `2·(1.01·q_max)^group < 2^127` (intensities
    /// are at most 1, so `q ≤ q_max` up to rounding).
    group: usize,
}

impl Params {
    /// For `λ > 0` and `0 ≤ δ < 1`.
    pub(crate) fn new(lambda: f32, delta: f32, sobel_norm: f32) -> Self {
        let q_max = 1.0 + lambda * (1.0 - delta);
        Self {
            scale: lambda / sobel_norm,
            offset: 1.0 - lambda * delta,
            group: ((125.0 / (1.01 * q_max).log2().max(1.0)) as usize).max(1),
        }
    }
}

/// The most lanes any kernel uses: rows are padded by this much.
const MAX_LANES: usize = 16;

/// Row buffers, reused from call to call.
#[derive(Clone, Debug, Default)]
pub(crate) struct Rows {
    ring: [Aligned<f32>; 3],
    sv: Aligned<f32>,
    dv: Aligned<f32>,
    product: Aligned<f32>,
    exponent: Aligned<i32>,
    info: Aligned<f32>,
    column: Aligned<f32>,
}

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

/// `Σ w·ln q` over the interior pixels of the `w×h` image `src` (0 when it
/// is smaller than 3×3 or a buffer is short).
pub(crate) fn sum_ln_q(
    isa: Isa,
    src: Source<'_>,
    w: usize,
    h: usize,
    weight: Option<&[f32]>,
    p: Params,
    rows: &mut Rows,
) -> f64 {
    if w < 3 || h < 3 || !src.covers(w * h) || weight.is_some_and(|wt| wt.len() < w * h) {
        return 0.0;
    }
    rows.resize(w);
    dispatch(
        isa,
        SumLnQ {
            src,
            log2: None,
            pass: Pass {
                w,
                h,
                weight,
                p,
                rows,
            },
            avx512: isa.supported() == Isa::Avx512,
        },
    )
    .0
}

/// `Σ ln q` over the interior pixels of the unweighted image `luma` (as
/// [`sum_ln_q`]), and `Σ ln q·log₂ I` with `ln q` to about 1.5e-4 absolute
/// ([`fastmath::log2_approx`]); for an information-weighted mean that needs
/// no more.
pub(crate) fn sum_ln_q_and_dot(
    isa: Isa,
    luma: &[f32],
    log2: &[f32],
    w: usize,
    h: usize,
    p: Params,
    rows: &mut Rows,
) -> (f64, f64) {
    if w < 3 || h < 3 || luma.len() < w * h || log2.len() < w * h {
        return (0.0, 0.0);
    }
    rows.resize(w);
    dispatch(
        isa,
        SumLnQ {
            src: Source::Plain(luma),
            log2: Some(log2),
            pass: Pass {
                w,
                h,
                weight: None,
                p,
                rows,
            },
            avx512: false,
        },
    )
}

/// The information of the image `luma` as it is: returns `Σ w·ln q` and,
/// when `log2` (`log₂ I` per pixel) is given, `Σ w·ln q·log₂ I`. When `map`
/// is given, each interior pixel's `w·ln q` goes there (the border is 0).
#[allow(clippy::too_many_arguments)]
pub(crate) fn information(
    isa: Isa,
    luma: &[f32],
    log2: Option<&[f32]>,
    w: usize,
    h: usize,
    weight: Option<&[f32]>,
    p: Params,
    rows: &mut Rows,
    mut map: Option<&mut Vec<f32>>,
) -> (f64, f64) {
    if let Some(map) = map.as_deref_mut() {
        map.clear();
        map.resize(w * h, 0.0);
    }
    let short = |v: &[f32]| v.len() < w * h;
    if w < 3 || h < 3 || short(luma) || log2.is_some_and(short) || weight.is_some_and(short) {
        return (0.0, 0.0);
    }
    rows.resize(w);
    dispatch(
        isa,
        Information {
            luma,
            log2,
            pass: Pass {
                w,
                h,
                weight,
                p,
                rows,
            },
            map: map.map(Vec::as_mut_slice),
        },
    )
}

/// `log₂ I` of every pixel into `out`, clamped to `[floor, 0]` (`floor` is
/// at least −126; [`Source::Gamma`] needs `γ·floor ≥ −126`). `out` starts
/// on a cache line, so that the γ passes' whole-vector loads of a row whose
/// width is a multiple of 16 never straddle two lines (a `Vec` of this size
/// may start anywhere on a 16-byte boundary, depending on what the
/// allocator did before: the γ estimate took 213 µs or 239 µs from run to
/// run).
pub(crate) fn log2_map(isa: Isa, luma: &[f32], floor: f32, out: &mut Aligned<f32>) {
    out.reset(luma.len(), 0.0);
    let floor = floor.clamp(-126.0, 0.0);
    dispatch(isa, Log2Map { luma, floor, out });
}

/// What scale-and-clip's assumed recovery needs to know about the
/// saturated pixels of a `w×h` image (interior pixels only, each counted
/// with its weight): the weight of the saturated ones (at or above
/// `level`), of those in each band `[s, level)` for the `levels` below 1
/// (0 for the others), and the weight and summed `info` of the pixels whose
/// whole 3×3 neighbourhood lies in `[widest, level)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct SaturationSums {
    pub(crate) saturated: f64,
    pub(crate) bands: Vec<f64>,
    pub(crate) texture_weight: f64,
    pub(crate) texture_info: f64,
}

/// [`SaturationSums`] of `luma` (`w×h`, with `info` per pixel and optional
/// weights; empty sums if a buffer is short).
#[allow(clippy::too_many_arguments)]
pub(crate) fn saturation_sums(
    isa: Isa,
    luma: &[f32],
    weight: Option<&[f32]>,
    info: &[f32],
    w: usize,
    h: usize,
    levels: &[f32],
    widest: f32,
    level: f32,
) -> SaturationSums {
    let short = |v: &[f32]| v.len() < w * h;
    if w < 3 || h < 3 || short(luma) || short(info) || weight.is_some_and(short) {
        return SaturationSums {
            bands: vec![0.0; levels.len()],
            ..Default::default()
        };
    }
    dispatch(
        isa,
        Saturation {
            luma,
            weight,
            info,
            w,
            h,
            levels,
            widest,
            level,
        },
    )
}

struct Saturation<'a> {
    luma: &'a [f32],
    weight: Option<&'a [f32]>,
    info: &'a [f32],
    w: usize,
    h: usize,
    levels: &'a [f32],
    widest: f32,
    level: f32,
}

impl Kernel for Saturation<'_> {
    type Output = SaturationSums;

    #[inline(always)]
    fn run<const L: usize, const FMA: bool>(self) -> SaturationSums {
        let (luma, weight, info, levels) = (self.luma, self.weight, self.info, self.levels);
        let (w, h, widest, level) = (self.w, self.h, self.widest, self.level);
        let n = w - 2;
        let mut out = SaturationSums {
            bands: vec![0.0; levels.len()],
            ..Default::default()
        };
        // Each row's extremes over three columns, for the last three rows.
        let mut lo = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        let mut hi = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        let extremes = |y: usize, lo: &mut [f32], hi: &mut [f32]| {
            let row = &luma[y * w..(y + 1) * w];
            let (a, b, c) = (&row[..n], &row[1..n + 1], &row[2..n + 2]);
            for ((((lo, hi), &a), &b), &c) in lo.iter_mut().zip(hi.iter_mut()).zip(a).zip(b).zip(c)
            {
                *lo = a.min(b).min(c);
                *hi = a.max(b).max(c);
            }
        };
        let ones = vec![1.0f32; n];
        let mut nmin = vec![0.0f32; n];
        let mut nmax = vec![0.0f32; n];
        let mut bands = vec![[0.0f32; L]; levels.len()];
        for y in 0..h {
            extremes(y, &mut lo[y % 3], &mut hi[y % 3]);
            if y < 2 {
                continue;
            }
            // Row `y − 1` now has all three rows of its neighbourhoods.
            for (((mn, mx), (&l0, &h0)), ((&l1, &h1), (&l2, &h2))) in nmin
                .iter_mut()
                .zip(nmax.iter_mut())
                .zip(lo[0].iter().zip(&hi[0]))
                .zip(lo[1].iter().zip(&hi[1]).zip(lo[2].iter().zip(&hi[2])))
            {
                *mn = l0.min(l1).min(l2);
                *mx = h0.max(h1).max(h2);
            }
            let span = (y - 1) * w + 1..(y - 1) * w + 1 + n;
            let v = &luma[span.clone()];
            let wt = weight.map_or(&ones[..], |wt| &wt[span.clone()]);
            let inf = &info[span];
            let mut sat = [0.0f32; L];
            let (mut tw, mut ti) = ([0.0f32; L], [0.0f32; L]);
            let (vc, _) = v.as_chunks::<L>();
            let (wc, _) = wt.as_chunks::<L>();
            let (ic, _) = inf.as_chunks::<L>();
            let (nc, _) = nmin.as_chunks::<L>();
            let (xc, _) = nmax.as_chunks::<L>();
            for ((((v, wt), inf), mn), mx) in vc.iter().zip(wc).zip(ic).zip(nc).zip(xc) {
                for l in 0..L {
                    sat[l] += if v[l] >= level { wt[l] } else { 0.0 };
                    let texture = mn[l] >= widest && mx[l] < level;
                    tw[l] += if texture { wt[l] } else { 0.0 };
                    ti[l] += if texture { inf[l] } else { 0.0 };
                }
            }
            for (acc, &s) in bands.iter_mut().zip(levels) {
                *acc = [0.0; L];
                if s < 1.0 {
                    for (v, wt) in vc.iter().zip(wc) {
                        for l in 0..L {
                            acc[l] += if v[l] >= s && v[l] < level {
                                wt[l]
                            } else {
                                0.0
                            };
                        }
                    }
                }
            }
            // The row's last, partial vector.
            let tail = vc.len() * L..n;
            for x in tail {
                sat[0] += if v[x] >= level { wt[x] } else { 0.0 };
                let texture = nmin[x] >= widest && nmax[x] < level;
                tw[0] += if texture { wt[x] } else { 0.0 };
                ti[0] += if texture { inf[x] } else { 0.0 };
                for (acc, &s) in bands.iter_mut().zip(levels) {
                    acc[0] += if s < 1.0 && v[x] >= s && v[x] < level {
                        wt[x]
                    } else {
                        0.0
                    };
                }
            }
            out.saturated += total(&sat);
            out.texture_weight += total(&tw);
            out.texture_info += total(&ti);
            for (b, acc) in out.bands.iter_mut().zip(&bands) {
                *b += total(acc);
            }
        }
        out
    }
}

impl Source<'_> {
    fn covers(&self, len: usize) -> bool {
        match self {
            Source::Plain(v) => v.len() >= len,
            Source::Gamma { log2, .. } => log2.len() >= len,
            Source::Scale { luma, .. } | Source::Hold { luma, .. } => luma.len() >= len,
            Source::Blocks {
                luma, saturated, ..
            } => luma.len() >= len && saturated.len() >= len,
            Source::Declipped {
                unsaturated,
                saturated,
                hidden,
                ..
            } => unsaturated.len() >= len && saturated.len() >= len && hidden.len() >= len,
        }
    }

    /// Row `r` (of width `w`) of the simulated image, clamped to [0, 1]
    /// and multiplied by `scale`, into `out`.
    #[inline(always)]
    fn map_row<const FMA: bool>(&self, r: usize, w: usize, scale: f32, out: &mut [f32]) {
        let span = r * w..(r + 1) * w;
        match *self {
            Source::Plain(v) => {
                for (o, &v) in out.iter_mut().zip(&v[span]) {
                    *o = (scale * v).clamp(0.0, scale);
                }
            }
            Source::Gamma { log2, gamma } => {
                let exp2 = fastmath::Exp2::scaled(scale);
                for (o, &l) in out.iter_mut().zip(&log2[span]) {
                    *o = exp2.product::<FMA>(gamma, l);
                }
            }
            Source::Scale { luma, s } => {
                let s = s * scale;
                for (o, &v) in out.iter_mut().zip(&luma[span]) {
                    *o = (s * v).clamp(0.0, scale);
                }
            }
            Source::Hold { luma, s, level } => {
                let s = s * scale;
                for (o, &v) in out.iter_mut().zip(&luma[span]) {
                    let k = if v >= level { scale } else { s };
                    *o = (k * v).clamp(0.0, scale);
                }
            }
            Source::Blocks { luma, saturated, s } => {
                for ((o, &v), &f) in out
                    .iter_mut()
                    .zip(&luma[span.clone()])
                    .zip(&saturated[span])
                {
                    let rest = (s * (v - f).max(0.0)).min(1.0 - f);
                    *o = (scale * (f + rest)).clamp(0.0, scale);
                }
            }
            Source::Declipped {
                unsaturated,
                saturated,
                hidden,
                s,
            } => {
                for (((o, &u), &f), &t) in out
                    .iter_mut()
                    .zip(&unsaturated[span.clone()])
                    .zip(&saturated[span.clone()])
                    .zip(&hidden[span])
                {
                    *o = (scale * (s * u + f.min(s * t))).clamp(0.0, scale);
                }
            }
        }
    }
}

/// The rows `y − 1`, `y` and `y + 1` of the ring.
#[inline(always)]
fn ring_rows(ring: &[Aligned<f32>; 3], y: usize) -> [&[f32]; 3] {
    let [r0, r1, r2] = ring;
    match (y + 1) % 3 {
        0 => [r1, r2, r0],
        1 => [r2, r0, r1],
        _ => [r0, r1, r2],
    }
}

impl Rows {
    /// Ring rows of `w`; pass rows of `w` plus zero padding, so that a row's
    /// last vector can be loaded whole.
    fn resize(&mut self, w: usize) {
        for r in &mut self.ring {
            r.reset(w + 2 * MAX_LANES, 0.0);
        }
        self.sv.reset(w + 2 * MAX_LANES, 0.0);
        self.dv.reset(w + 2 * MAX_LANES, 0.0);
    }

    /// Maps the rows the first output row needs.
    #[inline(always)]
    fn start<const FMA: bool>(&mut self, src: &Source<'_>, w: usize, scale: f32) {
        src.map_row::<FMA>(0, w, scale, &mut self.ring[0]);
        src.map_row::<FMA>(1, w, scale, &mut self.ring[1]);
    }

    /// Maps row `y + 1` into the ring.
    #[inline(always)]
    fn map_next<const FMA: bool>(&mut self, src: &Source<'_>, w: usize, scale: f32, y: usize) {
        let [r0, r1, r2] = &mut self.ring;
        let c = match (y + 1) % 3 {
            0 => r0,
            1 => r1,
            _ => r2,
        };
        src.map_row::<FMA>(y + 1, w, scale, c);
    }

    /// Maps row `y + 1` and runs the vertical Sobel passes centred on row
    /// `y`: smoothing for ∂x into `sv`, difference for ∂y into `dv`.
    #[inline(always)]
    fn advance<const FMA: bool>(&mut self, src: &Source<'_>, w: usize, scale: f32, y: usize) {
        self.map_next::<FMA>(src, w, scale, y);
        self.vertical::<FMA>(w, y);
    }

    /// The vertical Sobel passes centred on row `y` (rows `y ± 1` mapped).
    #[inline(always)]
    fn vertical<const FMA: bool>(&mut self, w: usize, y: usize) {
        let [a, b, c] = ring_rows(&self.ring, y);
        for (((sv, dv), (&a, &b)), &c) in self
            .sv
            .iter_mut()
            .zip(self.dv.iter_mut())
            .zip(a[..w].iter().zip(&b[..w]))
            .zip(&c[..w])
        {
            *sv = madd::<FMA>(2.0, b, a + c);
            *dv = c - a;
        }
    }
}

/// `q` of one pixel from its vertical passes.
#[inline(always)]
fn q_of<const FMA: bool>(svl: f32, svr: f32, dvl: f32, dvc: f32, dvr: f32, p: &Params) -> f32 {
    let gx = svr - svl;
    let gy = madd::<FMA>(2.0, dvc, dvl + dvr);
    let mag2 = madd::<FMA>(gx, gx, gy * gy);
    (mag2.sqrt() + p.offset).max(1.0)
}

/// One row's `q`s multiplied into `product` (`q^w` with 0/1 weights
/// `mask`), with the vertical and horizontal Sobel passes fused in
/// registers: each vector's vertical passes come from the three mapped rows
/// `a`, `b`, `c` and the next vector's are shifted in across the boundary
/// (`valignd`), so the only memory traffic is the three rows and the
/// product. AVX-512 only: the portable lanes cannot express the shift (LLVM
/// makes gathers of it). Returns `false`, having done nothing, when a buffer
/// is shorter than the pass needs (the rows are padded by one vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
#[allow(unsafe_code)]
fn product_row_avx512(
    rows: [&[f32]; 3],
    product: &mut [f32],
    mask: Option<&[f32]>,
    n: usize,
    p: &Params,
) -> bool {
    use std::arch::x86_64::{
        __m512, _mm512_add_ps, _mm512_alignr_epi32, _mm512_castps_si512, _mm512_castsi512_ps,
        _mm512_cmp_ps_mask, _mm512_fmadd_ps, _mm512_loadu_ps, _mm512_mask_blend_ps, _mm512_max_ps,
        _mm512_mul_ps, _mm512_set1_ps, _mm512_setzero_ps, _mm512_sqrt_ps, _mm512_storeu_ps,
        _mm512_sub_ps, _CMP_GT_OQ,
    };
    const L: usize = 16;
    let chunks = n.div_ceil(L);
    let [a, b, c] = rows;
    if [a, b, c].iter().any(|r| r.len() < (chunks + 1) * L)
        || product.len() < chunks * L
        || mask.is_some_and(|m| m.len() < n)
    {
        return false;
    }
    // SAFETY (every load and store below): the lengths were checked above,
    // so vector `k ≤ chunks` of a row and vector `k < chunks` of the product
    // lie inside their slices; mask loads go through `lanes`.
    let load =
        |row: &[f32], k: usize| -> __m512 { unsafe { _mm512_loadu_ps(row.as_ptr().add(k * L)) } };
    let two = _mm512_set1_ps(2.0);
    let offset = _mm512_set1_ps(p.offset);
    let one = _mm512_set1_ps(1.0);
    let vertical = |k: usize| {
        let (av, bv, cv) = (load(a, k), load(b, k), load(c, k));
        (
            _mm512_fmadd_ps(two, bv, _mm512_add_ps(av, cv)),
            _mm512_sub_ps(cv, av),
        )
    };
    let shift = |next: __m512, cur: __m512, k: u8| -> __m512 {
        let (next, cur) = (_mm512_castps_si512(next), _mm512_castps_si512(cur));
        _mm512_castsi512_ps(if k == 1 {
            _mm512_alignr_epi32::<1>(next, cur)
        } else {
            _mm512_alignr_epi32::<2>(next, cur)
        })
    };
    let (mut sv, mut dv) = vertical(0);
    for k in 0..chunks {
        let (sv_next, dv_next) = vertical(k + 1);
        let gx = _mm512_sub_ps(shift(sv_next, sv, 2), sv);
        let gy = _mm512_fmadd_ps(
            two,
            shift(dv_next, dv, 1),
            _mm512_add_ps(dv, shift(dv_next, dv, 2)),
        );
        let mag2 = _mm512_fmadd_ps(gx, gx, _mm512_mul_ps(gy, gy));
        let q = _mm512_max_ps(_mm512_add_ps(_mm512_sqrt_ps(mag2), offset), one);
        // Lanes past the row, and with weight 0, take 1.
        let rest = n - k * L;
        let mut keep: u16 = if rest < L {
            (1u16 << rest) - 1
        } else {
            u16::MAX
        };
        if let Some(mask) = mask {
            let m = lanes::<L>(mask, k * L);
            let mv = unsafe { _mm512_loadu_ps(m.as_ptr()) };
            keep &= _mm512_cmp_ps_mask::<_CMP_GT_OQ>(mv, _mm512_setzero_ps());
        }
        let q = _mm512_mask_blend_ps(keep, one, q);
        let at = unsafe { product.as_mut_ptr().add(k * L) };
        unsafe { _mm512_storeu_ps(at, _mm512_mul_ps(_mm512_loadu_ps(at), q)) };
        sv = sv_next;
        dv = dv_next;
    }
    true
}

/// What is done with each vector of `q`s (a trait rather than a closure, so
/// that it is inlined into the vector code of each instruction set).
trait Sink<const L: usize> {
    /// Takes the `q`s of interior pixels `x..x + L` (those beyond the row
    /// are 1).
    fn take(&mut self, x: usize, q: &[f32; L]);
}

/// Runs `sink.take(x, q)` over the `n` interior pixels of one row, `L` at a
/// time, from its vertical passes (padded by at least `L + 2`).
#[inline(always)]
fn for_each_q<const L: usize, const FMA: bool>(
    sv: &[f32],
    dv: &[f32],
    n: usize,
    p: &Params,
    sink: &mut impl Sink<L>,
) {
    let chunks = n.div_ceil(L);
    let span = chunks * L;
    let (a, _) = sv[..span].as_chunks::<L>();
    let (b, _) = sv[2..span + 2].as_chunks::<L>();
    let (c, _) = dv[..span].as_chunks::<L>();
    let (d, _) = dv[1..span + 1].as_chunks::<L>();
    let (e, _) = dv[2..span + 2].as_chunks::<L>();
    let full = n / L;
    let mut x = 0;
    for ((((a, b), c), d), e) in a.iter().zip(b).zip(c).zip(d).zip(e).take(full) {
        let mut q = [0.0f32; L];
        for l in 0..L {
            q[l] = q_of::<FMA>(a[l], b[l], c[l], d[l], e[l], p);
        }
        sink.take(x, &q);
        x += L;
    }
    if full < chunks {
        let rest = n - x;
        let mut q = [0.0f32; L];
        for l in 0..L {
            let v = q_of::<FMA>(
                a[full][l], b[full][l], c[full][l], d[full][l], e[full][l], p,
            );
            q[l] = if l < rest { v } else { 1.0 };
        }
        sink.take(x, &q);
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

/// Multiplies one row's `q`s into a running product per column, kept as
/// mantissa × 2^exponent (see [`Params::group`]).
struct ProductSink<'a> {
    product: &'a mut [f32],
}

impl<const L: usize> Sink<L> for ProductSink<'_> {
    #[inline(always)]
    fn take(&mut self, x: usize, q: &[f32; L]) {
        for (p, &q) in self.product[x..x + L].iter_mut().zip(q) {
            *p *= q;
        }
    }
}

/// [`ProductSink`], and adds `log₂ q·log₂ I` (approximate) per column.
struct ProductDotSink<'a, const L: usize, const FMA: bool> {
    product: &'a mut [f32],
    dot: [f32; L],
    log2: &'a [f32],
}

impl<const L: usize, const FMA: bool> Sink<L> for ProductDotSink<'_, L, FMA> {
    #[inline(always)]
    fn take(&mut self, x: usize, q: &[f32; L]) {
        let li = lanes::<L>(self.log2, x);
        for (((p, d), &q), &li) in self.product[x..x + L]
            .iter_mut()
            .zip(&mut self.dot)
            .zip(q)
            .zip(&li)
        {
            *p *= q;
            *d = madd::<FMA>(fastmath::log2_approx::<FMA>(q), li, *d);
        }
    }
}

/// Moves the binary exponent of each column's product into its counter,
/// leaving the mantissa in [1, 2).
#[inline(always)]
fn normalise(product: &mut [f32], exponent: &mut [i32]) {
    for (p, e) in product.iter_mut().zip(exponent.iter_mut()) {
        let bits = p.to_bits();
        *e += (bits >> 23) as i32 - 127;
        *p = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    }
}

/// [`ProductSink`] for 0/1 weights: `q^w` is `q` or 1, so the weighted sum
/// of logarithms stays a product.
struct MaskedProductSink<'a> {
    product: &'a mut [f32],
    weight: &'a [f32],
}

impl<const L: usize> Sink<L> for MaskedProductSink<'_> {
    #[inline(always)]
    fn take(&mut self, x: usize, q: &[f32; L]) {
        let wt = lanes::<L>(self.weight, x);
        for ((p, &q), &wt) in self.product[x..x + L].iter_mut().zip(q).zip(&wt) {
            *p *= if wt > 0.0 { q } else { 1.0 };
        }
    }
}

/// Stores `w·ln q` of one row (whole vectors: the row is padded).
struct InfoSink<'a, const L: usize, const FMA: bool> {
    out: &'a mut [f32],
    weight: Option<&'a [f32]>,
}

impl<const L: usize, const FMA: bool> Sink<L> for InfoSink<'_, L, FMA> {
    #[inline(always)]
    fn take(&mut self, x: usize, q: &[f32; L]) {
        let f = self.weight.map_or([1.0; L], |wt| lanes::<L>(wt, x));
        for ((o, &q), &f) in self.out[x..x + L].iter_mut().zip(q).zip(&f) {
            *o = f * fastmath::ln_with::<FMA>(q);
        }
    }
}

/// Adds `a` and `a·b` column by column into `sum` and `dot` (all of one
/// length): element-wise, so it vectorises without reassociating a sum.
#[inline(always)]
fn accumulate<const FMA: bool>(sum: &mut [f32], dot: &mut [f32], a: &[f32], b: &[f32]) {
    for (((s, d), &a), &b) in sum.iter_mut().zip(dot.iter_mut()).zip(a).zip(b) {
        *s += a;
        *d = madd::<FMA>(a, b, *d);
    }
}

/// `ln Π m·2^e` over the columns (each mantissa `m` in [1, 2)): the
/// mantissas are multiplied in double precision, eight at a time (a product
/// below 2^8), so one logarithm per eight columns replaces one per column.
fn ln_of_products(mantissa: &[f32], exponent: &[i32]) -> f64 {
    let exponents: f64 = exponent.iter().map(|&e| f64::from(e)).sum();
    let logs: f64 = mantissa
        .chunks(8)
        .map(|c| c.iter().map(|&m| f64::from(m)).product::<f64>().ln())
        .sum();
    exponents * std::f64::consts::LN_2 + logs
}

/// `Σ v` in double precision.
fn total(v: &[f32]) -> f64 {
    v.iter().map(|&v| f64::from(v)).sum()
}

/// What every pass over an image needs: its size, its weights, Eq. 1's
/// constants and the row buffers.
struct Pass<'a> {
    w: usize,
    h: usize,
    weight: Option<&'a [f32]>,
    p: Params,
    rows: &'a mut Rows,
}

struct SumLnQ<'a> {
    src: Source<'a>,
    log2: Option<&'a [f32]>,
    pass: Pass<'a>,
    /// The pass runs on AVX-512 ([`product_row_avx512`] may be called).
    avx512: bool,
}

impl Kernel for SumLnQ<'_> {
    type Output = (f64, f64);

    #[inline(always)]
    fn run<const L: usize, const FMA: bool>(self) -> (f64, f64) {
        let Self {
            src,
            log2,
            pass,
            avx512,
        } = self;
        let Pass {
            w,
            h,
            weight,
            p,
            rows,
        } = pass;
        let n = w - 2;
        let span = n.div_ceil(L) * L;
        rows.product.reset(span, 1.0);
        rows.exponent.reset(span, 0);
        rows.info.reset(span, 0.0);
        rows.column.reset(span, 0.0);
        let mut taken = 0;
        let mut dot_total = 0.0f64;
        // Weights of only 0 and 1 keep the product (no logarithm per pixel).
        #[allow(clippy::float_cmp)] // exactly 0 or exactly 1
        let binary = weight.is_some_and(|wt| {
            wt.iter()
                .fold(true, |all, &v| all & ((v == 0.0) | (v == 1.0)))
        });
        // The product passes fused on AVX-512 (no vertical pass rows).
        let fused = avx512 && log2.is_none() && (weight.is_none() || binary);
        rows.start::<FMA>(&src, w, p.scale);
        for y in 1..h - 1 {
            if fused {
                rows.map_next::<FMA>(&src, w, p.scale, y);
                #[cfg(target_arch = "x86_64")]
                {
                    let [a, b, c] = ring_rows(&rows.ring, y);
                    let mask = weight.map(|wt| &wt[y * w + 1..y * w + 1 + n]);
                    // SAFETY: `avx512` is set only when the CPU has AVX-512F,
                    // AVX2 and FMA (`Isa::supported`).
                    #[allow(unsafe_code)]
                    let done =
                        unsafe { product_row_avx512([a, b, c], &mut rows.product, mask, n, &p) };
                    if done {
                        taken += 1;
                        if taken == p.group {
                            normalise(&mut rows.product, &mut rows.exponent);
                            taken = 0;
                        }
                        continue;
                    }
                }
                rows.vertical::<FMA>(w, y);
            } else {
                rows.advance::<FMA>(&src, w, p.scale, y);
            }
            match (weight, log2) {
                (None, Some(log2)) => {
                    let mut sink = ProductDotSink::<L, FMA> {
                        product: &mut rows.product,
                        dot: [0.0; L],
                        log2: &log2[y * w + 1..y * w + 1 + n],
                    };
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, n, &p, &mut sink);
                    dot_total += total(&sink.dot);
                    taken += 1;
                    if taken == p.group {
                        normalise(&mut rows.product, &mut rows.exponent);
                        taken = 0;
                    }
                }
                (None, None) => {
                    let mut sink = ProductSink {
                        product: &mut rows.product,
                    };
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, n, &p, &mut sink);
                    taken += 1;
                    if taken == p.group {
                        normalise(&mut rows.product, &mut rows.exponent);
                        taken = 0;
                    }
                }
                (Some(wt), _) if binary => {
                    let mut sink = MaskedProductSink {
                        product: &mut rows.product,
                        weight: &wt[y * w + 1..y * w + 1 + n],
                    };
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, n, &p, &mut sink);
                    taken += 1;
                    if taken == p.group {
                        normalise(&mut rows.product, &mut rows.exponent);
                        taken = 0;
                    }
                }
                (Some(wt), _) => {
                    let span = y * w + 1..y * w + 1 + n;
                    let mut sink = InfoSink::<L, FMA> {
                        out: &mut rows.info,
                        weight: Some(&wt[span]),
                    };
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, n, &p, &mut sink);
                    for (s, &v) in rows.column.iter_mut().zip(rows.info.iter()) {
                        *s += v;
                    }
                }
            }
        }
        normalise(&mut rows.product, &mut rows.exponent);
        let ln_product = ln_of_products(&rows.product, &rows.exponent);
        let dot = dot_total * std::f64::consts::LN_2;
        (total(&rows.column) + ln_product, dot)
    }
}

struct Information<'a> {
    luma: &'a [f32],
    log2: Option<&'a [f32]>,
    pass: Pass<'a>,
    map: Option<&'a mut [f32]>,
}

impl Kernel for Information<'_> {
    type Output = (f64, f64);

    #[inline(always)]
    fn run<const L: usize, const FMA: bool>(self) -> (f64, f64) {
        let Self {
            luma,
            log2,
            pass,
            mut map,
        } = self;
        let Pass {
            w,
            h,
            weight,
            p,
            rows,
        } = pass;
        let n = w - 2;
        let src = Source::Plain(luma);
        let mut row = std::mem::take(&mut rows.product);
        row.reset(n.div_ceil(L) * L, 0.0);
        let mut sum = vec![0.0f32; n];
        let mut dot = vec![0.0f32; n];
        rows.start::<FMA>(&src, w, p.scale);
        for y in 1..h - 1 {
            rows.advance::<FMA>(&src, w, p.scale, y);
            let span = y * w + 1..y * w + 1 + n;
            let mut sink = InfoSink::<L, FMA> {
                out: &mut row,
                weight: weight.map(|wt| &wt[span.clone()]),
            };
            for_each_q::<L, FMA>(&rows.sv, &rows.dv, n, &p, &mut sink);
            let v = &row[..n];
            accumulate::<FMA>(&mut sum, &mut dot, v, log2.map_or(v, |l| &l[span.clone()]));
            if let Some(map) = map.as_deref_mut() {
                map[span].copy_from_slice(v);
            }
        }
        rows.product = row;
        (total(&sum), if log2.is_some() { total(&dot) } else { 0.0 })
    }
}

struct Log2Map<'a> {
    luma: &'a [f32],
    floor: f32,
    out: &'a mut [f32],
}

impl Kernel for Log2Map<'_> {
    type Output = ();

    #[inline(always)]
    fn run<const L: usize, const FMA: bool>(self) {
        let floor = self.floor;
        for (o, &v) in self.out.iter_mut().zip(self.luma) {
            *o = fastmath::log2::<FMA>(v.max(1e-30)).clamp(floor, 0.0);
        }
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact values: zero, one and powers of two
mod tests {
    use super::*;
    use crate::exposure::metric::SOBEL_NORM;
    use rand::{Rng, SeedableRng};

    fn textured(w: usize, h: usize, seed: u64) -> Vec<f32> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let base = 0.5 + 0.4 * (x * 0.3).sin() * (y * 0.17).cos();
                (base + rng.gen_range(-0.05..0.05)).clamp(0.0, 1.0)
            })
            .collect()
    }

    /// `ln q` of interior pixel `(x, y)` of a `w`-wide image, in double
    /// precision (δ = 0.06).
    fn reference_ln_q(img: &[f32], w: usize, x: usize, y: usize, lambda: f64) -> f64 {
        let at = |x: usize, y: usize| f64::from(img[y * w + x]);
        let gx = at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1)
            - at(x - 1, y - 1)
            - 2.0 * at(x - 1, y)
            - at(x - 1, y + 1);
        let gy = at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1)
            - at(x - 1, y - 1)
            - 2.0 * at(x, y - 1)
            - at(x + 1, y - 1);
        let m = (gx * gx + gy * gy).sqrt() / f64::from(SOBEL_NORM);
        (1.0 + lambda * (m - 0.06).max(0.0)).ln()
    }

    /// Straightforward double-precision Eq. 1 sum of `w·ln q`.
    fn reference(img: &[f32], w: usize, h: usize, weight: Option<&[f32]>, lambda: f64) -> f64 {
        let mut total = 0.0;
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                total += weight.map_or(1.0, |wt| f64::from(wt[y * w + x]))
                    * reference_ln_q(img, w, x, y, lambda);
            }
        }
        total
    }

    #[test]
    fn every_isa_matches_the_reference() {
        // Widths with and without a partial last chunk of 16 lanes.
        for (w, h) in [(37, 11), (64, 9), (3, 3), (130, 40)] {
            let img = textured(w, h, w as u64);
            let weight: Vec<f32> = (0..w * h).map(|i| (i % 7) as f32 / 6.0).collect();
            let binary: Vec<f32> = (0..w * h).map(|i| f32::from(i % 5 != 0)).collect();
            for lambda in [1000.0f64, 10.0, 1e9] {
                let p = Params::new(lambda as f32, 0.06, SOBEL_NORM);
                for wt in [None, Some(weight.as_slice()), Some(binary.as_slice())] {
                    let want = reference(&img, w, h, wt, lambda);
                    for isa in Isa::available() {
                        let got =
                            sum_ln_q(isa, Source::Plain(&img), w, h, wt, p, &mut Rows::default());
                        let tol = 1e-5 * want.abs().max(1.0);
                        assert!(
                            (got - want).abs() <= tol,
                            "{isa:?} {w}×{h} λ={lambda} weighted={}: {got} vs {want}",
                            wt.is_some()
                        );
                        let mut map = Vec::new();
                        let (sum, _) = information(
                            isa,
                            &img,
                            None,
                            w,
                            h,
                            wt,
                            p,
                            &mut Rows::default(),
                            Some(&mut map),
                        );
                        assert!((sum - want).abs() <= tol, "{isa:?} map sum {sum} vs {want}");
                        let map_sum: f64 = map.iter().map(|&v| f64::from(v)).sum();
                        assert!(
                            (map_sum - want).abs() <= tol,
                            "{isa:?} map {map_sum} vs {want}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn mapped_sources_match_mapping_first() {
        let (w, h) = (101, 23);
        let img = textured(w, h, 3);
        let mut log2 = Aligned::default();
        log2_map(Isa::detect(), &img, -126.0 / 1.9, &mut log2);
        let p = Params::new(1000.0, 0.06, SOBEL_NORM);
        for isa in Isa::available() {
            for gamma in [1.0f32 / 1.9, 1.5] {
                let mapped: Vec<f32> = img.iter().map(|v| v.powf(gamma)).collect();
                let want = reference(&mapped, w, h, None, 1000.0);
                let got = sum_ln_q(
                    isa,
                    Source::Gamma { log2: &log2, gamma },
                    w,
                    h,
                    None,
                    p,
                    &mut Rows::default(),
                );
                assert!(
                    (got - want).abs() <= 2e-5 * want,
                    "{isa:?} γ={gamma}: {got} vs {want}"
                );
            }
            for s in [0.6f32, 1.9] {
                let mapped: Vec<f32> = img.iter().map(|v| (v * s).min(1.0)).collect();
                let want = reference(&mapped, w, h, None, 1000.0);
                let got = sum_ln_q(
                    isa,
                    Source::Scale { luma: &img, s },
                    w,
                    h,
                    None,
                    p,
                    &mut Rows::default(),
                );
                assert!(
                    (got - want).abs() <= 1e-5 * want,
                    "{isa:?} s={s}: {got} vs {want}"
                );
            }
            // Scale-and-hold, on an image with saturated patches, weighted.
            let level = 0.9f32;
            let held: Vec<f32> = img.iter().map(|&v| (v * 1.3).min(1.0)).collect();
            let weight: Vec<f32> = (0..w * h).map(|i| (i % 5) as f32 / 4.0).collect();
            for s in [0.6f32, 0.9] {
                let mapped: Vec<f32> = held
                    .iter()
                    .map(|&v| if v >= level { v } else { v * s })
                    .collect();
                let want = reference(&mapped, w, h, Some(&weight), 1000.0);
                let got = sum_ln_q(
                    isa,
                    Source::Hold {
                        luma: &held,
                        s,
                        level,
                    },
                    w,
                    h,
                    Some(&weight),
                    p,
                    &mut Rows::default(),
                );
                assert!(
                    (got - want).abs() <= 1e-5 * want,
                    "{isa:?} hold s={s}: {got} vs {want}"
                );
            }
            // Declipped: a part below saturation and a saturated part whose
            // true level is known, some of it far above saturation.
            let unsaturated: Vec<f32> = img.iter().map(|&v| 0.5 * v).collect();
            let saturated: Vec<f32> = (0..w * h).map(|i| (i % 3) as f32 / 4.0).collect();
            let hidden: Vec<f32> = saturated
                .iter()
                .zip(&img)
                .map(|(&f, &v)| f * (1.0 + 3.0 * v))
                .collect();
            for s in [0.4f32, 0.8] {
                let mapped: Vec<f32> = (0..w * h)
                    .map(|i| (s * unsaturated[i] + saturated[i].min(s * hidden[i])).min(1.0))
                    .collect();
                let want = reference(&mapped, w, h, Some(&weight), 1000.0);
                let got = sum_ln_q(
                    isa,
                    Source::Declipped {
                        unsaturated: &unsaturated,
                        saturated: &saturated,
                        hidden: &hidden,
                        s,
                    },
                    w,
                    h,
                    Some(&weight),
                    p,
                    &mut Rows::default(),
                );
                assert!(
                    (got - want).abs() <= 1e-5 * want,
                    "{isa:?} declipped s={s}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn the_information_dot_and_the_logarithms_match_double_precision() {
        let (w, h) = (83, 29);
        let img = textured(w, h, 5);
        let p = Params::new(1000.0, 0.06, SOBEL_NORM);
        // Σ ln q·log₂ I in double precision.
        let (mut exact_sum, mut exact_dot) = (0.0, 0.0);
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let ln_q = reference_ln_q(&img, w, x, y, 1000.0);
                exact_sum += ln_q;
                exact_dot += ln_q * f64::from(img[y * w + x]).log2();
            }
        }
        let exact_mean = exact_dot / exact_sum;
        assert!(
            exact_mean < -0.1,
            "the test image should be mid-grey: {exact_mean}"
        );
        let floor = -126.0 / 1.9;
        for isa in Isa::available() {
            let mut logs = Aligned::default();
            log2_map(isa, &img, floor, &mut logs);
            for (&l, &v) in logs.iter().zip(&img) {
                let want = f64::from(v).log2().clamp(f64::from(floor), 0.0);
                assert!(
                    (f64::from(l) - want).abs() <= 3e-7 * (1.0 + want.abs()),
                    "{isa:?}: log₂ {v} = {l}, not {want}"
                );
            }
            let (sum, dot) = sum_ln_q_and_dot(isa, &img, &logs, w, h, p, &mut Rows::default());
            assert!(
                (sum - exact_sum).abs() <= 1e-5 * exact_sum,
                "{isa:?}: {sum} vs {exact_sum}"
            );
            // ln q to 1.5e-4 of ~5: the weighted mean of log₂ I moves by less
            // than 1e-4.
            let mean = dot / sum;
            assert!(
                (mean - exact_mean).abs() < 1e-4,
                "{isa:?}: {mean} vs {exact_mean}"
            );
        }
    }

    #[test]
    fn short_inputs_score_zero() {
        let p = Params::new(1000.0, 0.06, SOBEL_NORM);
        let img = vec![0.5f32; 8];
        assert_eq!(
            sum_ln_q(
                Isa::Baseline,
                Source::Plain(&img),
                4,
                4,
                None,
                p,
                &mut Rows::default()
            ),
            0.0
        );
        let short_weight = vec![1.0f32; 3];
        let img = textured(5, 5, 1);
        assert_eq!(
            sum_ln_q(
                Isa::detect(),
                Source::Plain(&img),
                5,
                5,
                Some(&short_weight),
                p,
                &mut Rows::default()
            ),
            0.0
        );
    }
}
