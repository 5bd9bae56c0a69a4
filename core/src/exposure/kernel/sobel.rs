//! The Sobel/log kernel: simulated exposure change → 3×3 Sobel → magnitude
//! → `ln q` → sum, over a ring of three rows (see the module documentation
//! of [`super`]).

use super::super::fastmath::{self, madd};
#[cfg(target_arch = "x86_64")]
use super::avx512::product_row_avx512;
use super::{dispatch, lanes, total, Aligned, Isa, Kernel, Source, MAX_LANES};

/// The per-pixel constants of Eq. 1: `q = max(|∇'| + offset, 1)`, where the
/// rows are mapped already multiplied by `scale`, so that `∇' = scale·∇`,
/// is `1 + λ·max(m − δ, 0)` with `m = |∇| / (4√2)`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params {
    scale: f32,
    pub(super) offset: f32,
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
    /// The image row each ring slot holds (slot `r % 3` for row `r`),
    /// `usize::MAX` for none.
    tags: [usize; 3],
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
/// allocator did before, which made the γ estimate's time vary from run to
/// run: `BENCHMARKS.md`, Exposure estimator, Results).
pub(crate) fn log2_map(isa: Isa, luma: &[f32], floor: f32, out: &mut Aligned<f32>) {
    out.reset(luma.len(), 0.0);
    let floor = floor.clamp(-126.0, 0.0);
    dispatch(isa, Log2Map { luma, floor, out });
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
        self.tags = [usize::MAX; 3];
    }

    /// Maps whichever of rows `y − 1`, `y` and `y + 1` the ring does not
    /// hold yet (going down the image row by row, only `y + 1`; after rows
    /// left out, up to all three).
    #[inline(always)]
    fn ensure<const FMA: bool>(&mut self, src: &Source<'_>, w: usize, scale: f32, y: usize) {
        for r in y - 1..=y + 1 {
            let slot = r % 3;
            if self.tags[slot] != r {
                src.map_row::<FMA>(r, w, scale, &mut self.ring[slot]);
                self.tags[slot] = r;
            }
        }
    }

    /// The vertical Sobel passes centred on row `y` (rows `y ± 1` mapped)
    /// over the columns `cols`: smoothing for ∂x into `sv`, difference for
    /// ∂y into `dv`.
    #[inline(always)]
    fn vertical<const FMA: bool>(&mut self, cols: std::ops::Range<usize>, y: usize) {
        let [a, b, c] = ring_rows(&self.ring, y);
        let (a, b, c) = (&a[cols.clone()], &b[cols.clone()], &c[cols.clone()]);
        for (((sv, dv), (&a, &b)), &c) in self.sv[cols.clone()]
            .iter_mut()
            .zip(self.dv[cols].iter_mut())
            .zip(a.iter().zip(b))
            .zip(c)
        {
            *sv = madd::<FMA>(2.0, b, a + c);
            *dv = c - a;
        }
    }
}

/// The interior pixels of a row that count, given their weights (`n` of
/// them): `from..to`, `from` rounded down to a multiple of
/// [`MAX_LANES`], `to` one past the last weight above 0; `0..0` when none
/// is. Whole vectors are tested at a time.
#[inline(always)]
pub(super) fn counted_span(weight: &[f32]) -> (usize, usize) {
    let (chunks, rest) = weight.as_chunks::<MAX_LANES>();
    let any = |c: &[f32]| c.iter().fold(false, |any, &v| any | (v > 0.0));
    let tail = chunks.len() * MAX_LANES;
    let first = match chunks.iter().position(|c| any(c)) {
        Some(k) => k * MAX_LANES,
        None if any(rest) => tail,
        None => return (0, 0),
    };
    let last = match rest.iter().rposition(|&v| v > 0.0) {
        Some(i) => tail + i,
        None => {
            // Some chunk counts (`first` found one, and `rest` none).
            let k = chunks.iter().rposition(|c| any(c)).unwrap_or(0);
            k * MAX_LANES + chunks[k].iter().rposition(|&v| v > 0.0).unwrap_or(0)
        }
    };
    (first, last + 1)
}

/// `q` of one pixel from its vertical passes.
#[inline(always)]
fn q_of<const FMA: bool>(svl: f32, svr: f32, dvl: f32, dvc: f32, dvr: f32, p: &Params) -> f32 {
    let gx = svr - svl;
    let gy = madd::<FMA>(2.0, dvc, dvl + dvr);
    let mag2 = madd::<FMA>(gx, gx, gy * gy);
    (mag2.sqrt() + p.offset).max(1.0)
}

/// What is done with each vector of `q`s (a trait rather than a closure, so
/// that it is inlined into the vector code of each instruction set).
trait Sink<const L: usize> {
    /// Takes the `q`s of interior pixels `x..x + L` (those beyond the row
    /// are 1).
    fn take(&mut self, x: usize, q: &[f32; L]);
}

/// Runs `sink.take(x, q)` over the interior pixels `from..to` of one row
/// of `n` (`from` a multiple of `L`), `L` at a time, from its vertical
/// passes (padded by at least `L + 2`). The `q`s of pixels past `to` in
/// the last vector are of whatever the passes hold there.
#[inline(always)]
fn for_each_q<const L: usize, const FMA: bool>(
    sv: &[f32],
    dv: &[f32],
    (from, to): (usize, usize),
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
    let (k0, k1) = (from / L, to.div_ceil(L).min(chunks));
    let whole = k0..k1.min(full);
    let mut x = whole.start * L;
    for ((((a, b), c), d), e) in a[whole.clone()]
        .iter()
        .zip(&b[whole.clone()])
        .zip(&c[whole.clone()])
        .zip(&d[whole.clone()])
        .zip(&e[whole.clone()])
    {
        let mut q = [0.0f32; L];
        for l in 0..L {
            q[l] = q_of::<FMA>(a[l], b[l], c[l], d[l], e[l], p);
        }
        sink.take(x, &q);
        x += L;
    }
    if full < k1 {
        let x = full * L;
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
        for y in 1..h - 1 {
            // Only the pixels that count (and their neighbours) are
            // mapped and scored: a metering mask leaves most rows out.
            let cols = match weight {
                Some(wt) => counted_span(&wt[y * w + 1..y * w + 1 + n]),
                None => (0, n),
            };
            if cols.0 >= cols.1 {
                continue;
            }
            rows.ensure::<FMA>(&src, w, p.scale, y);
            if fused {
                #[cfg(target_arch = "x86_64")]
                {
                    let (from, to) = cols;
                    let [a, b, c] = ring_rows(&rows.ring, y);
                    let mask = weight.map(|wt| &wt[y * w + 1 + from..y * w + 1 + to]);
                    // SAFETY: `avx512` is set only when the CPU has
                    // AVX-512F, AVX2 and FMA (`Isa::supported`).
                    #[allow(unsafe_code)]
                    let done = unsafe {
                        product_row_avx512(
                            [&a[from..], &b[from..], &c[from..]],
                            &mut rows.product[from..],
                            mask,
                            to - from,
                            &p,
                        )
                    };
                    if done {
                        taken += 1;
                        if taken == p.group {
                            normalise(&mut rows.product, &mut rows.exponent);
                            taken = 0;
                        }
                        continue;
                    }
                }
            }
            rows.vertical::<FMA>(cols.0..(cols.1 + 2).min(w), y);
            match (weight, log2) {
                (None, Some(log2)) => {
                    let mut sink = ProductDotSink::<L, FMA> {
                        product: &mut rows.product,
                        dot: [0.0; L],
                        log2: &log2[y * w + 1..y * w + 1 + n],
                    };
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, cols, n, &p, &mut sink);
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
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, cols, n, &p, &mut sink);
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
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, cols, n, &p, &mut sink);
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
                    for_each_q::<L, FMA>(&rows.sv, &rows.dv, cols, n, &p, &mut sink);
                    let (from, to) = cols;
                    for (s, &v) in rows.column[from..to].iter_mut().zip(&rows.info[from..to]) {
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
        for y in 1..h - 1 {
            let span = y * w + 1..y * w + 1 + n;
            let cols = match weight {
                Some(wt) => counted_span(&wt[span.clone()]),
                None => (0, n),
            };
            if cols.0 >= cols.1 {
                continue;
            }
            rows.ensure::<FMA>(&src, w, p.scale, y);
            rows.vertical::<FMA>(cols.0..(cols.1 + 2).min(w), y);
            let mut sink = InfoSink::<L, FMA> {
                out: &mut row,
                weight: weight.map(|wt| &wt[span.clone()]),
            };
            for_each_q::<L, FMA>(&rows.sv, &rows.dv, cols, n, &p, &mut sink);
            // (Past the pixels that count, every value is 0.)
            let (from, to) = cols;
            let v = &row[from..to];
            let at = span.start + from..span.start + to;
            accumulate::<FMA>(
                &mut sum[from..to],
                &mut dot[from..to],
                v,
                log2.map_or(v, |l| &l[at.clone()]),
            );
            if let Some(map) = map.as_deref_mut() {
                map[at].copy_from_slice(v);
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
