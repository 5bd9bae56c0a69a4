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

use std::fmt;

use crate::error::{Error, Result};

/// Bits of the fixed-point weights.
const SHIFT: u32 = 12;
/// The weights of one canvas pixel sum to this.
pub(crate) const ONE: u32 = 1 << SHIFT;

/// Height of the tiles the canvas is walked in: the pixels of a tile come
/// from a compact patch of each source image, which stays in the caches
/// (walking whole canvas rows, a side camera's row runs down a source
/// column, a new cache line per pixel).
const TILE: usize = 32;
/// Width of the tiles: runs end at tile edges, so wide tiles mean few
/// runs.
const TILE_WIDTH: usize = 128;

/// A run of canvas pixels with the same contributing cameras, within one
/// row of a tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Run {
    /// First canvas pixel (row-major index).
    start: u32,
    /// Number of pixels.
    len: u32,
    /// First tap. The taps are camera by camera: pixel `p` of the run takes
    /// from its `j`-th camera the tap `taps + j·len + p`.
    taps: u32,
    /// The cameras: `cameras[cameras .. cameras + n]`.
    cameras: u32,
    /// Number of cameras (0: a black run).
    n: u32,
}

/// One camera's contribution to a canvas pixel, as [`Plan::build`] asks for
/// it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Contribution {
    /// The camera (index into the plan's sources).
    pub(crate) camera: u32,
    /// The source position (x, y), pixels, in `[0, w − 1] × [0, h − 1]`.
    pub(crate) at: [f32; 2],
    /// The blend weight (any positive scale: a pixel's weights are
    /// normalised).
    pub(crate) weight: f64,
}

/// An 8-bit image a plan reads: `width · height · channels` bytes, packed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Image<'a> {
    pub(crate) bytes: &'a [u8],
    pub(crate) width: usize,
    pub(crate) height: usize,
}

/// The per-frame work of one view and blend mode: see the module docs.
///
/// Invariant (checked at the end of [`Plan::build`], relied on by the
/// gathering kernels when `gather_ok`): every tap index of a camera with
/// source size `w×h` is at most `(h − 1)·w − 2`, and each source holds
/// fewer than 2³¹ bytes in RGB.
#[derive(Clone, Default, PartialEq)]
pub(crate) struct Plan {
    /// Canvas pixels.
    pixels: usize,
    /// Per camera, the source size (width, height).
    sources: Vec<(usize, usize)>,
    /// Runs covering the canvas, tile by tile.
    runs: Vec<Run>,
    /// Per tap, the row-major index of the top-left source pixel
    /// (`y0 · width + x0`, with `x0 ≤ width − 2`, `y0 ≤ height − 2`).
    index: Vec<u32>,
    /// Per tap, the weights of the top-left, top-right, bottom-left and
    /// bottom-right pixels in 1/4096 (blend weight included), as four
    /// little-endian `u16`: the low 32 bits are the top pair, the high 32
    /// bits the bottom pair.
    weights: Vec<u64>,
    cameras: Vec<u32>,
    /// Whether the invariant holds (always, unless a bug broke it): the
    /// gathering kernels run only then.
    gather_ok: bool,
}

impl fmt::Debug for Plan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Plan")
            .field("pixels", &self.pixels)
            .field("sources", &self.sources)
            .field("runs", &self.runs.len())
            .field("taps", &self.index.len())
            .finish()
    }
}

/// The four bilinear weights (top-left, top-right, bottom-left,
/// bottom-right) of position (`x`, `y`) in a `w×h` image (w, h ≥ 2), and the
/// index of the top-left pixel. The neighbourhood is kept inside the image:
/// on the last column or row it is the one to the left or above, with the
/// weight on its right or lower pixels.
pub(crate) fn bilinear(x: f32, y: f32, w: usize, h: usize) -> (u32, [f64; 4]) {
    let x = f64::from(x).clamp(0.0, (w - 1) as f64);
    let y = f64::from(y).clamp(0.0, (h - 1) as f64);
    let x0 = (x.floor() as usize).min(w - 2);
    let y0 = (y.floor() as usize).min(h - 2);
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    (
        (y0 * w + x0) as u32,
        [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ],
    )
}

/// Rounds non-negative `values` (summing to `total` up to rounding) to
/// integers in `out` that sum to exactly `total`: each is rounded down, then
/// the ones with the largest remainders get one more (the earliest on a
/// tie). Rounding each value on its own can miss the total by one either
/// way (two halves both rounded up, or three thirds all rounded down).
pub(crate) fn round_to_total(values: &[f64], total: u32, out: &mut [u32]) {
    let n = values.len().min(out.len());
    if n == 0 {
        return;
    }
    let (values, out) = (&values[..n], &mut out[..n]);
    for (o, &v) in out.iter_mut().zip(values) {
        *o = if v > 0.0 { v.floor() as u32 } else { 0 };
    }
    let mut sum: u64 = out.iter().map(|&o| u64::from(o)).sum();
    let total = u64::from(total);
    while sum < total {
        // The largest remainder; one that was raised has a negative one.
        let mut best = 0;
        for i in 1..n {
            if values[i] - f64::from(out[i]) > values[best] - f64::from(out[best]) {
                best = i;
            }
        }
        out[best] += 1;
        sum += 1;
    }
    while sum > total {
        // The smallest remainder among the non-zero ones.
        let mut best = None;
        for i in 0..n {
            if out[i] == 0 {
                continue;
            }
            let r = values[i] - f64::from(out[i]);
            if best.is_none_or(|b: usize| r < values[b] - f64::from(out[b])) {
                best = Some(i);
            }
        }
        let Some(b) = best else { break };
        out[b] -= 1;
        sum -= 1;
    }
}

/// The taps of the run being built, pixel by pixel (`n` per pixel).
#[derive(Debug, Default)]
struct Pending {
    index: Vec<u32>,
    weights: Vec<u64>,
}

impl Plan {
    /// The plan of a canvas `width` pixels wide and `pixels` pixels in all,
    /// over cameras of the given source sizes (each at least 2×2):
    /// `at(i, list)` fills `list` (handed over empty) with the cameras
    /// contributing to canvas pixel `i`, in camera order; contributions of
    /// weight 0 are left out.
    pub(crate) fn build(
        width: usize,
        pixels: usize,
        sources: Vec<(usize, usize)>,
        mut at: impl FnMut(usize, &mut Vec<Contribution>),
    ) -> Self {
        let mut plan = Plan {
            pixels,
            sources,
            ..Plan::default()
        };
        let width = width.max(1);
        let height = pixels.div_ceil(width);
        let mut pending = Pending::default();
        let mut list = Vec::new();
        let mut exact: Vec<f64> = Vec::new();
        let mut rounded: Vec<u32> = Vec::new();
        for tr in (0..height).step_by(TILE) {
            for tc in (0..width).step_by(TILE_WIDTH) {
                for r in tr..(tr + TILE).min(height) {
                    for c in tc..(tc + TILE_WIDTH).min(width) {
                        let i = r * width + c;
                        if i >= pixels {
                            continue;
                        }
                        list.clear();
                        at(i, &mut list);
                        // Contributions of weight 0, of unknown cameras or
                        // of sources too small for a 2×2 neighbourhood are
                        // left out.
                        list.retain(|c| {
                            c.weight > 0.0
                                && plan
                                    .sources
                                    .get(c.camera as usize)
                                    .is_some_and(|&(w, h)| w >= 2 && h >= 2)
                        });
                        plan.push_pixel(i, &list, &mut pending);
                        plan.push_taps(&list, &mut pending, &mut exact, &mut rounded);
                    }
                }
            }
        }
        plan.flush(&mut pending);
        plan.gather_ok = plan.check();
        plan
    }

    /// Appends canvas pixel `i` with contributions `list` to the runs.
    fn push_pixel(&mut self, i: usize, list: &[Contribution], pending: &mut Pending) {
        let n = list.len() as u32;
        if let Some(run) = self.runs.last_mut() {
            let cams = &self.cameras[run.cameras as usize..][..run.n as usize];
            let same = run.n == n && cams.iter().zip(list).all(|(&a, c)| a == c.camera);
            if same && (run.start + run.len) as usize == i {
                run.len += 1;
                return;
            }
        }
        self.flush(pending);
        let cameras = self.cameras.len() as u32;
        self.cameras.extend(list.iter().map(|c| c.camera));
        self.runs.push(Run {
            start: i as u32,
            len: 1,
            taps: self.index.len() as u32,
            cameras,
            n,
        });
    }

    /// The taps of one pixel with contributions `list`, into `pending`.
    fn push_taps(
        &self,
        list: &[Contribution],
        pending: &mut Pending,
        exact: &mut Vec<f64>,
        rounded: &mut Vec<u32>,
    ) {
        if list.is_empty() {
            return;
        }
        let total: f64 = list.iter().map(|c| c.weight).sum();
        exact.clear();
        for c in list {
            let (w, h) = self.sources[c.camera as usize];
            let (index, b) = bilinear(c.at[0], c.at[1], w, h);
            pending.index.push(index);
            let scale = f64::from(ONE) * c.weight / total;
            exact.extend(b.iter().map(|&v| v * scale));
        }
        rounded.resize(exact.len(), 0);
        round_to_total(exact, ONE, rounded);
        for w in rounded.chunks_exact(4) {
            pending.weights.push(
                u64::from(w[0])
                    | u64::from(w[1]) << 16
                    | u64::from(w[2]) << 32
                    | u64::from(w[3]) << 48,
            );
        }
    }

    /// Moves the pending taps of the last run to the plan, camera by camera.
    fn flush(&mut self, pending: &mut Pending) {
        if let Some(run) = self.runs.last() {
            let n = run.n as usize;
            for j in 0..n {
                self.index
                    .extend(pending.index.iter().skip(j).step_by(n).copied());
                self.weights
                    .extend(pending.weights.iter().skip(j).step_by(n).copied());
            }
        }
        pending.index.clear();
        pending.weights.clear();
    }

    /// Whether the plan's invariant holds (see [`Plan`]).
    fn check(&self) -> bool {
        let sizes_ok = self.sources.iter().all(|&(w, h)| {
            w >= 2 && h >= 2 && w.checked_mul(h).is_some_and(|p| p < i32::MAX as usize / 3)
        });
        if !sizes_ok || self.index.len() != self.weights.len() {
            return false;
        }
        self.runs.iter().all(|run| {
            let (len, n) = (run.len as usize, run.n as usize);
            let first = run.taps as usize;
            let Some(cams) = self
                .cameras
                .get(run.cameras as usize..run.cameras as usize + n)
            else {
                return false;
            };
            (run.start as usize + len) <= self.pixels
                && first + n * len <= self.index.len()
                && cams.iter().enumerate().all(|(j, &k)| {
                    let Some(&(w, h)) = self.sources.get(k as usize) else {
                        return false;
                    };
                    let limit = ((h - 1) * w - 2) as u32;
                    self.index[first + j * len..first + (j + 1) * len]
                        .iter()
                        .all(|&i| i <= limit)
                })
        })
    }

    /// Canvas pixels seen by one camera, by several, and taps in all.
    #[cfg(test)]
    pub(crate) fn counts(&self) -> (usize, usize, usize) {
        let count = |f: fn(u32) -> bool| -> usize {
            self.runs
                .iter()
                .filter(|r| f(r.n))
                .map(|r| r.len as usize)
                .sum()
        };
        (count(|n| n == 1), count(|n| n > 1), self.index.len())
    }

    /// Composes `images` (one per source, `ch` channels: 1 or 3) into `out`
    /// (the canvas, `pixels · ch` bytes): every byte is written.
    pub(crate) fn execute(&self, images: &[Image<'_>], ch: usize, out: &mut [u8]) -> Result<()> {
        self.execute_with(kernels::Isa::detect(), images, ch, out)
    }

    /// [`Plan::execute`] with the kernels of `isa` (which the CPU must
    /// have: see [`kernels::Isa::available`]).
    pub(crate) fn execute_with(
        &self,
        isa: kernels::Isa,
        images: &[Image<'_>],
        ch: usize,
        out: &mut [u8],
    ) -> Result<()> {
        if ch != 1 && ch != 3 {
            return Err(Error::InvalidParameter {
                name: "canvas.channels",
                value: ch as f64,
                expected: "1 (mono) or 3 (RGB)",
            });
        }
        if images.len() != self.sources.len() {
            return Err(Error::InvalidConfig(format!(
                "surround view: {} images for a plan of {} cameras",
                images.len(),
                self.sources.len()
            )));
        }
        for (img, &(w, h)) in images.iter().zip(&self.sources) {
            if (img.width, img.height) != (w, h) || img.bytes.len() < w * h * ch {
                return Err(Error::SizeMismatch {
                    what: "image against the surround view's camera",
                    expected_width: w,
                    expected_height: h,
                    width: img.width,
                    height: img.height,
                });
            }
        }
        if out.len() != self.pixels * ch {
            return Err(Error::BufferSize {
                what: "surround canvas",
                expected: self.pixels * ch,
                actual: out.len(),
                detail: format!("{} pixels of {ch} channels", self.pixels),
            });
        }
        kernels::run(isa, self, images, ch, out);
        Ok(())
    }

    /// Run `run`'s part of the canvas `out` (`ch` channels), its tap indices
    /// and weights (camera by camera) and its cameras.
    #[allow(clippy::type_complexity)]
    #[inline]
    fn parts<'o>(
        &self,
        run: &Run,
        ch: usize,
        out: &'o mut [u8],
    ) -> Option<(&'o mut [u8], &[u32], &[u64], &[u32])> {
        let (start, len, n) = (run.start as usize, run.len as usize, run.n as usize);
        let first = run.taps as usize;
        Some((
            out.get_mut(start * ch..(start + len) * ch)?,
            self.index.get(first..first + len * n)?,
            self.weights.get(first..first + len * n)?,
            self.cameras
                .get(run.cameras as usize..run.cameras as usize + n)?,
        ))
    }
}

/// The run loops: portable, with BMI2, and with AVX2 gathers (x86-64),
/// chosen at run time.
pub(crate) mod kernels {
    use std::sync::OnceLock;

    use super::{Image, Plan, Run, ONE, SHIFT};

    /// The instruction set a composition runs with; wider sets order later.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) enum Isa {
        /// Plain 64-bit integer code.
        Portable,
        /// With BMI2's `pdep`/`pext` for the RGB lanes.
        Bmi2,
        /// AVX2 gathers and multiply-adds, 4 RGB or 8 mono pixels at a time
        /// (and BMI2 for the ends of runs).
        Avx2,
    }

    impl Isa {
        /// The widest set this CPU runs (detected once).
        pub(crate) fn detect() -> Self {
            static DETECTED: OnceLock<Isa> = OnceLock::new();
            *DETECTED.get_or_init(|| {
                #[cfg(target_arch = "x86_64")]
                {
                    use std::arch::is_x86_feature_detected as has;
                    let bmi2 = has!("bmi2");
                    let avx2 = bmi2 && has!("avx2");
                    if avx2 {
                        return Isa::Avx2;
                    }
                    if bmi2 {
                        return Isa::Bmi2;
                    }
                }
                Isa::Portable
            })
        }

        /// Every set this CPU runs, narrowest first.
        #[cfg(test)]
        pub(crate) fn available() -> Vec<Self> {
            let best = Self::detect();
            [Isa::Portable, Isa::Bmi2, Isa::Avx2]
                .into_iter()
                .filter(|&isa| isa <= best)
                .collect()
        }
    }

    /// Runs every run of `plan` (checked by [`Plan::execute_with`]) with
    /// `isa`, or the widest set below it the CPU has.
    pub(super) fn run(isa: Isa, plan: &Plan, images: &[Image<'_>], ch: usize, out: &mut [u8]) {
        match isa.min(Isa::detect()) {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 if plan.gather_ok => {
                // SAFETY: `detect` found AVX2 and BMI2, the features
                // `run_avx2` is compiled for; the plan's invariant holds
                // (`gather_ok`) and `execute_with` checked that each image
                // has its camera's size and at least w·h·ch bytes: the
                // contract of `run_avx2`.
                #[allow(unsafe_code)]
                unsafe {
                    run_avx2(plan, images, ch, out);
                }
            }
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 | Isa::Bmi2 => {
                // SAFETY: `detect` found BMI2, the feature `run_bmi2` is
                // compiled for.
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

    /// Per-lane rounding of an RGB sum (three 21-bit lanes).
    const ROUND_RGB: u64 = (ONE as u64 / 2) * (1 | 1 << 21 | 1 << 42);
    /// The bytes of a pixel placed in the three 21-bit lanes.
    #[cfg(target_arch = "x86_64")]
    const SPREAD_MASK: u64 = 0xff | 0xff << 21 | 0xff << 42;
    /// Rounding of a mono sum.
    const HALF: u32 = ONE / 2;

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

            /// Pixels `p0..p1` of a run of `len` pixels (taps camera by
            /// camera) into `dst`, the run's part of the canvas.
            $(#[$attr])*
            #[allow(clippy::too_many_arguments)]
            fn $pixels(
                images: &[Image<'_>],
                cams: &[u32],
                index: &[u32],
                weights: &[u64],
                len: usize,
                ch: usize,
                (p0, p1): (usize, usize),
                dst: &mut [u8],
            ) {
                let tap = |j: usize, p: usize| (index[j * len + p], weights[j * len + p]);
                if ch == 1 {
                    for p in p0..p1 {
                        let mut sum = HALF;
                        for (j, &k) in cams.iter().enumerate() {
                            if let Some(img) = images.get(k as usize) {
                                let (i, w) = tap(j, p);
                                sum += mono(img, i, w);
                            }
                        }
                        dst[p] = (sum >> SHIFT) as u8;
                    }
                } else {
                    for p in p0..p1 {
                        let mut sum = 0;
                        for (j, &k) in cams.iter().enumerate() {
                            if let Some(img) = images.get(k as usize) {
                                let (i, w) = tap(j, p);
                                sum += $rgb(img, i, w);
                            }
                        }
                        store3(&mut dst[3 * p..3 * p + 3], $pick(sum));
                    }
                }
            }

            $(#[$attr])*
            fn $name(plan: &Plan, images: &[Image<'_>], ch: usize, out: &mut [u8]) {
                let ahead = AHEAD;
                for (r, run) in plan.runs.iter().enumerate() {
                    prefetch_run(plan, plan.runs.get(r + ahead), images, ch);
                    let Some((dst, index, weights, cams)) = plan.parts(run, ch, out) else {
                        continue;
                    };
                    if run.n == 0 {
                        dst.fill(0);
                        continue;
                    }
                    let len = run.len as usize;
                    match (ch, cams) {
                        // One camera: the common case, without the loop
                        // over cameras.
                        (1, &[k]) => {
                            let Some(img) = images.get(k as usize) else { continue };
                            for ((d, &i), &w) in dst.iter_mut().zip(index).zip(weights) {
                                *d = ((mono(img, i, w) + HALF) >> SHIFT) as u8;
                            }
                        }
                        (3, &[k]) => {
                            let Some(img) = images.get(k as usize) else { continue };
                            for ((d, &i), &w) in dst.chunks_exact_mut(3).zip(index).zip(weights) {
                                store3(d, $pick($rgb(img, i, w)));
                            }
                        }
                        _ => $pixels(images, cams, index, weights, len, ch, (0, len), dst),
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

    /// The steps of one run of `$n`-pixel vectors through the AVX2 chunk
    /// functions `$sample` (a step's sums for one camera), `$add` and
    /// `$store` (`$bytes` canvas bytes a step): one camera, two, or the
    /// general loop over any number. Stops before the run's last
    /// `len % $n` pixels.
    ///
    /// Expanded inside [`run_avx2`], whose contract makes each `$sample`
    /// call sound: the taps of camera `j` are `cams[j]`'s and `image(j)`
    /// is its image.
    #[cfg(target_arch = "x86_64")]
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
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi2")]
    #[allow(unsafe_code)]
    unsafe fn run_avx2(plan: &Plan, images: &[Image<'_>], ch: usize, out: &mut [u8]) {
        use avx2::{Consts, MONO, RGB};
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
                    MONO, MONO, avx2::mono, avx2::mono_add, avx2::store_mono);
                main
            } else {
                let main = len - len % RGB;
                let dst = &mut dst[..3 * main];
                steps!(k, dst, index, weights, len, cams, image;
                    RGB, 3 * RGB, avx2::rgb, avx2::rgb_add, avx2::store_rgb);
                main
            };
            pixels_bmi2(images, cams, index, weights, len, ch, (main, len), dst);
        }
    }

    /// Byte shuffles shared by the vector kernels (one 128-bit lane).
    #[cfg(target_arch = "x86_64")]
    mod lanes {
        const Z: i8 = -1;
        /// A lane holding a pixel's top 8 bytes, then its bottom 8 bytes
        /// read 2 early: the (left, right) pairs of R, G and B of the top
        /// row as `u16` pairs.
        pub(super) const RGB_TOP: [i8; 16] = [0, Z, 3, Z, 1, Z, 4, Z, 2, Z, 5, Z, Z, Z, Z, Z];
        /// The same for the bottom row.
        pub(super) const RGB_BOTTOM: [i8; 16] =
            [10, Z, 13, Z, 11, Z, 14, Z, 12, Z, 15, Z, Z, Z, Z, Z];
        /// Per 32-bit lane of 4 top bytes: the (left, right) pair as `u16`.
        pub(super) const MONO_TOP: [i8; 16] = [0, Z, 1, Z, 4, Z, 5, Z, 8, Z, 9, Z, 12, Z, 13, Z];
        /// Per 32-bit lane of 4 bottom bytes read 2 early: the pair.
        pub(super) const MONO_BOTTOM: [i8; 16] =
            [2, Z, 3, Z, 6, Z, 7, Z, 10, Z, 11, Z, 14, Z, 15, Z];
        /// 4 pixels' RGB0 bytes to 12 bytes of RGB.
        pub(super) const RGB12: [i8; 16] = [0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, Z, Z, Z, Z];
    }

    #[cfg(target_arch = "x86_64")]
    mod avx2 {
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
                b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], b[10], b[11], b[12],
                b[13], b[14], b[15],
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
            let even = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_castps_si256(
                _mm256_shuffle_ps::<0b10_00_10_00>(w0, w1),
            ));
            let odd = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_castps_si256(
                _mm256_shuffle_ps::<0b11_01_11_01>(w0, w1),
            ));
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
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::kernels::Isa;
    use super::*;

    #[test]
    fn rounding_to_a_total_keeps_the_total_where_rounding_each_misses_it() {
        // Two halves: each rounded on its own gives 129 + 128 = 257.
        let halves = [128.5f64, 127.5];
        let each: u32 = halves.iter().map(|v| v.round() as u32).sum();
        assert_eq!(each, 257);
        let mut out = [0u32; 2];
        round_to_total(&halves, 256, &mut out);
        assert_eq!(out.iter().sum::<u32>(), 256);
        assert!(out
            .iter()
            .zip(halves)
            .all(|(&o, v)| (f64::from(o) - v).abs() < 1.0));
        // Three thirds: each rounded gives 255.
        let thirds = [256.0f64 / 3.0; 3];
        let each: u32 = thirds.iter().map(|v| v.round() as u32).sum();
        assert_eq!(each, 255);
        let mut out = [0u32; 3];
        round_to_total(&thirds, 256, &mut out);
        assert_eq!(out, [86, 85, 85]);
        // Random splits of 4096 into up to 12 parts: the total, and each
        // within 1 of its value.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..2000 {
            let n = rng.gen_range(1..=12);
            let raw: Vec<f64> = (0..n).map(|_| rng.gen::<f64>()).collect();
            let sum: f64 = raw.iter().sum();
            let values: Vec<f64> = raw.iter().map(|v| v / sum * 4096.0).collect();
            let mut out = vec![0u32; n];
            round_to_total(&values, 4096, &mut out);
            assert_eq!(out.iter().sum::<u32>(), 4096, "{values:?} → {out:?}");
            for (&o, &v) in out.iter().zip(&values) {
                assert!((f64::from(o) - v).abs() < 1.0, "{v} → {o}");
            }
        }
    }

    #[test]
    fn the_bilinear_neighbourhood_stays_inside_the_image() {
        let same = |a: [f64; 4], b: [f64; 4]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
        let (w, h) = (7, 5);
        // The last pixel: the neighbourhood to its upper left, all weight on
        // its bottom-right pixel.
        let (i, b) = bilinear(6.0, 4.0, w, h);
        assert_eq!(i as usize, 3 * w + 5);
        assert!(same(b, [0.0, 0.0, 0.0, 1.0]), "{b:?}");
        let (i, b) = bilinear(0.0, 0.0, w, h);
        assert_eq!(i, 0);
        assert!(same(b, [1.0, 0.0, 0.0, 0.0]), "{b:?}");
        let (i, b) = bilinear(2.25, 1.5, w, h);
        assert_eq!(i as usize, w + 2);
        assert!(same(b, [0.375, 0.125, 0.375, 0.125]), "{b:?}");
    }

    /// Random images and a random plan over them: per canvas pixel, 0 to 3
    /// cameras at random positions (a fifth of them on the last column or
    /// row) with random blend weights.
    struct Case {
        sources: Vec<(usize, usize)>,
        frames: Vec<Vec<u8>>,
        pixels: Vec<Vec<Contribution>>,
    }

    impl Case {
        fn new(seed: u64, ch: usize) -> Self {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let sources = vec![(37, 23), (2, 2), (64, 9)];
            let frames = sources
                .iter()
                .map(|&(w, h)| (0..w * h * ch).map(|_| rng.gen::<u8>()).collect())
                .collect();
            // The same cameras for stretches of 1 to 40 pixels, so that
            // the vector kernels see whole steps and ends of runs.
            let mut cams: Vec<u32> = Vec::new();
            let mut left = 0;
            let pixels = (0..61 * 17)
                .map(|_| {
                    if left == 0 {
                        left = rng.gen_range(1..=40);
                        let n = rng.gen_range(0..=3usize);
                        let mut all: Vec<u32> = (0..3).collect();
                        all.sort_by_key(|_| rng.gen::<u32>());
                        cams = all.into_iter().take(n).collect();
                        cams.sort_unstable();
                    }
                    left -= 1;
                    cams.iter()
                        .copied()
                        .map(|camera| {
                            let (w, h) = sources[camera as usize];
                            let mut pos = |len: usize| {
                                if rng.gen_bool(0.2) {
                                    (len - 1) as f32
                                } else {
                                    rng.gen_range(0.0..(len - 1) as f32)
                                }
                            };
                            Contribution {
                                camera,
                                at: [pos(w), pos(h)],
                                weight: f64::from(rng.gen_range(1..=256u16)),
                            }
                        })
                        .collect()
                })
                .collect();
            Self {
                sources,
                frames,
                pixels,
            }
        }

        fn plan(&self) -> Plan {
            Plan::build(61, self.pixels.len(), self.sources.clone(), |i, list| {
                list.extend_from_slice(&self.pixels[i]);
            })
        }

        fn images(&self) -> Vec<Image<'_>> {
            self.frames
                .iter()
                .zip(&self.sources)
                .map(|(bytes, &(width, height))| Image {
                    bytes,
                    width,
                    height,
                })
                .collect()
        }

        /// The exact value of channel `c` of canvas pixel `i`.
        fn exact(&self, i: usize, c: usize, ch: usize) -> f64 {
            let list = &self.pixels[i];
            let total: f64 = list.iter().map(|p| p.weight).sum();
            list.iter()
                .map(|p| {
                    let (w, h) = self.sources[p.camera as usize];
                    let f = &self.frames[p.camera as usize];
                    let (x, y) = (f64::from(p.at[0]), f64::from(p.at[1]));
                    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
                    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
                    let px = |xx: usize, yy: usize| {
                        f64::from(f[(yy.min(h - 1) * w + xx.min(w - 1)) * ch + c])
                    };
                    let v = (1.0 - fy) * ((1.0 - fx) * px(x0, y0) + fx * px(x0 + 1, y0))
                        + fy * ((1.0 - fx) * px(x0, y0 + 1) + fx * px(x0 + 1, y0 + 1));
                    v * p.weight / total
                })
                .sum()
        }
    }

    #[test]
    fn the_remap_is_within_a_level_of_the_exact_bilinear_blend_with_every_kernel() {
        for ch in [1, 3] {
            let case = Case::new(7 + ch as u64, ch);
            let plan = case.plan();
            assert!(plan.gather_ok, "the plan's invariant");
            let (one, several, taps) = plan.counts();
            assert!(one > 100 && several > 300, "{one} {several}");
            // Runs of 1, 2 and 3 cameras long enough for whole vector
            // steps and their ends.
            for n in 1..=3 {
                assert!(
                    plan.runs.iter().any(|r| r.n == n && r.len >= 19),
                    "no long run of {n} cameras"
                );
            }
            assert_eq!(taps, case.pixels.iter().map(Vec::len).sum::<usize>());
            let images = case.images();
            let mut first: Option<Vec<u8>> = None;
            for isa in Isa::available() {
                // A canvas full of garbage: every byte must be written.
                let mut out = vec![0xa5; plan.pixels * ch];
                plan.execute_with(isa, &images, ch, &mut out).unwrap();
                let mut worst = 0.0f64;
                for i in 0..case.pixels.len() {
                    for c in 0..ch {
                        let n = case.pixels[i].len() as f64;
                        let err = (f64::from(out[i * ch + c]) - case.exact(i, c, ch)).abs();
                        // Each weight is off by less than 1/4096, which
                        // moves the value by less than 127.5/4096 per
                        // weight, and the last rounding adds ½.
                        let bound = 0.5 + 127.5 * 4.0 * n / 4096.0;
                        assert!(
                            err < bound,
                            "{isa:?}, {ch} channels, pixel {i} ({:?}), channel {c}: off by {err}",
                            case.pixels[i]
                        );
                        worst = worst.max(err);
                    }
                }
                eprintln!("{isa:?}, {ch} channels: worst error {worst:.3}");
                match &first {
                    None => first = Some(out),
                    Some(f) => assert!(f == &out, "{isa:?} differs from the portable kernel"),
                }
            }
        }
    }

    #[test]
    fn a_source_too_small_for_a_neighbourhood_contributes_nothing() {
        let one = Contribution {
            camera: 0,
            at: [0.0, 1.0],
            weight: 1.0,
        };
        let other = Contribution { camera: 1, ..one };
        let plan = Plan::build(2, 2, vec![(1, 5), (2, 2)], |i, list| {
            list.push(one);
            if i == 1 {
                list.push(other);
            }
        });
        // Such a plan runs the scalar kernels only.
        assert!(!plan.gather_ok);
        let (a, b) = (vec![200u8; 5], vec![10u8, 20, 30, 40]);
        let images = [
            Image {
                bytes: &a,
                width: 1,
                height: 5,
            },
            Image {
                bytes: &b,
                width: 2,
                height: 2,
            },
        ];
        let mut out = vec![0xff; 2];
        plan.execute(&images, 1, &mut out).unwrap();
        // Pixel 0: only the 1-pixel-wide camera, so black; pixel 1: the
        // other camera alone, at (0, 1).
        assert_eq!(out, [0, 30]);
    }

    #[test]
    fn images_that_do_not_fit_the_plan_are_refused() {
        let case = Case::new(3, 3);
        let plan = case.plan();
        let mut images = case.images();
        let mut out = vec![0; plan.pixels * 3];
        assert!(plan.execute(&images[..2], 3, &mut out).is_err());
        assert!(plan.execute(&images, 2, &mut out).is_err());
        assert!(plan.execute(&images, 3, &mut out[1..]).is_err());
        images[0].bytes = &images[0].bytes[1..];
        let e = plan.execute(&images, 3, &mut out).unwrap_err();
        assert!(e.to_string().contains("37×23"), "{e}");
        images[0].width = 36;
        assert!(plan.execute(&images, 3, &mut out).is_err());
    }
}
