//! Metering: luminance from a camera frame, an optional region of interest,
//! and area downsampling to the metering size.
//!
//! The metered image is what the estimator sees. Luminance is read as
//! [`crate::image`] defines it (BT.601 weights, normalised to [0, 1] by the
//! format's full scale; Bayer frames as 2×2 quads, so no demosaicing is
//! needed). Downsampling averages `k×k` blocks with one integer factor `k`,
//! the largest that keeps the result at least as large as the target: a
//! 1288×964 frame with the default 320×240 target gives 322×241.
//!
//! A block average mixes saturated samples with unsaturated ones: a
//! metered pixel on the edge of a saturated area is below saturation,
//! but only its unsaturated samples would follow an exposure change. The
//! metered image therefore also carries, per pixel, the part of its
//! luminance that saturated samples carry ([`Metered::saturated_samples`]),
//! so that scale-and-clip can scale only the rest.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::image::luma::{self, bayer_luma_row, bayer_row, bayer_weights, luma_row};
use crate::image::{FrameView, PixelFormat, RoiMask};

/// Luminance at or above this counts as saturated in [`ImageStats`].
pub const SATURATED_LEVEL: f32 = 0.98;
/// Luminance at or below this counts as dark in [`ImageStats`].
pub const DARK_LEVEL: f32 = 0.02;
/// Bins of [`ImageStats::histogram`] over [0, 1].
pub const HISTOGRAM_BINS: usize = 256;

/// How large the metered image is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeteringConfig {
    /// Target width of the metered image in pixels (default 320).
    pub target_width: usize,
    /// Target height of the metered image in pixels (default 240).
    pub target_height: usize,
}

impl Default for MeteringConfig {
    fn default() -> Self {
        Self {
            target_width: 320,
            target_height: 240,
        }
    }
}

impl MeteringConfig {
    /// Checks the configuration.
    pub fn validate(&self) -> Result<()> {
        if self.target_width < 3 || self.target_height < 3 {
            return Err(Error::invalid(
                "metering",
                "size",
                "at least 3×3 pixels (the Sobel operator needs a neighbourhood)",
                format_args!("{}×{}", self.target_width, self.target_height),
            ));
        }
        Ok(())
    }

    /// The block factor for a source grid of `w×h` (pixels, or Bayer quads).
    fn factor(&self, w: usize, h: usize) -> usize {
        (w / self.target_width).min(h / self.target_height).max(1)
    }
}

/// Summary statistics of the metered pixels that count.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageStats {
    /// Mean luminance in [0, 1].
    pub mean: f32,
    /// Median luminance in [0, 1] (from the histogram, interpolated in its bin).
    pub median: f32,
    /// Fraction of pixels at or above [`SATURATED_LEVEL`].
    pub saturated_fraction: f32,
    /// Fraction of pixels at or below [`DARK_LEVEL`].
    pub dark_fraction: f32,
    /// Histogram over [0, 1] with [`HISTOGRAM_BINS`] bins.
    pub histogram: Vec<u32>,
    /// How many pixels the statistics cover.
    pub count: usize,
}

impl ImageStats {
    /// The statistics of `pixels`, taken 4096 at a time (see
    /// [`StatsSums::add`]).
    fn from_pixels<'a>(pixels: impl Iterator<Item = &'a f32>) -> Self {
        let mut sums = StatsSums::default();
        let mut block = [0.0f32; STATS_BLOCK];
        let mut n = 0;
        for &v in pixels {
            block[n] = v;
            n += 1;
            if n == STATS_BLOCK {
                sums.add(&block);
                n = 0;
            }
        }
        sums.add(&block[..n]);
        sums.finish()
    }

    /// The statistics of the pixels of `pixels` in `runs` (start, end),
    /// in order: the same values as [`ImageStats::from_pixels`] over them
    /// (the same blocks of [`STATS_BLOCK`]), copied a run at a time.
    fn from_runs(pixels: &[f32], runs: &[(usize, usize)]) -> Self {
        let mut sums = StatsSums::default();
        let mut block = [0.0f32; STATS_BLOCK];
        let mut n = 0;
        for &(start, end) in runs {
            let Some(mut run) = pixels.get(start..end) else {
                continue;
            };
            while !run.is_empty() {
                let take = run.len().min(STATS_BLOCK - n);
                block[n..n + take].copy_from_slice(&run[..take]);
                n += take;
                run = &run[take..];
                if n == STATS_BLOCK {
                    sums.add(&block);
                    n = 0;
                }
            }
        }
        sums.add(&block[..n]);
        sums.finish()
    }

    /// The statistics of every pixel of `pixels`.
    fn from_slice(pixels: &[f32]) -> Self {
        let mut sums = StatsSums::default();
        for block in pixels.chunks(STATS_BLOCK) {
            sums.add(block);
        }
        sums.finish()
    }
}

/// Pixels summed in `f32` before the sum is carried in `f64`.
const STATS_BLOCK: usize = 4096;

/// The running sums of [`ImageStats`].
struct StatsSums {
    sum: f64,
    count: usize,
    saturated: usize,
    dark: usize,
    /// Four histograms, pixel `i` counted in `i % 4`'s: consecutive
    /// pixels in the same bin then do not wait on each other's count.
    histograms: [[u32; HISTOGRAM_BINS]; 4],
}

impl Default for StatsSums {
    fn default() -> Self {
        Self {
            sum: 0.0,
            count: 0,
            saturated: 0,
            dark: 0,
            histograms: [[0; HISTOGRAM_BINS]; 4],
        }
    }
}

impl StatsSums {
    /// Adds a block of at most [`STATS_BLOCK`] pixels (every block but
    /// the last of a sequence exactly that many). The block is summed in
    /// eight `f32` partial sums, pixel `i` into `i % 8`'s, so that the
    /// additions do not wait on each other, and the partial sums are
    /// added to the `f64` total in order.
    fn add(&mut self, block: &[f32]) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::Isa::detect() >= crate::cpu::Isa::Avx2 {
            // SAFETY: `detect` reports AVX2 only when the CPU has it.
            #[allow(unsafe_code)]
            unsafe {
                self.add_avx2(block);
            }
            return;
        }
        self.add_in(block);
    }

    /// [`StatsSums::add_in`] compiled for AVX2 (the same operations in
    /// the same order: the same values).
    ///
    /// # Safety
    ///
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn add_avx2(&mut self, block: &[f32]) {
        self.add_in(block);
    }

    /// The work of [`StatsSums::add`].
    #[inline(always)]
    fn add_in(&mut self, block: &[f32]) {
        let mut partial = [0.0f32; 8];
        let (eights, rest) = block.as_chunks::<8>();
        for e in eights {
            for (p, &v) in partial.iter_mut().zip(e) {
                *p += v;
            }
        }
        for (p, &v) in partial.iter_mut().zip(rest) {
            *p += v;
        }
        self.sum += f64::from(partial.iter().sum::<f32>());
        self.count += block.len();
        self.saturated += block.iter().filter(|&&v| v >= SATURATED_LEVEL).count();
        self.dark += block.iter().filter(|&&v| v <= DARK_LEVEL).count();
        // The bins first, in a loop that vectorises (clamped in `f32`:
        // NaN and negative values to bin 0, 1 and above to the last, as
        // the saturating conversion of the scaled value would; a
        // conversion to an integer type ran one value at a time), then
        // counted.
        const _: () = assert!(HISTOGRAM_BINS <= 256, "a bin is a byte");
        const LAST_BIN: f32 = (HISTOGRAM_BINS - 1) as f32;
        let mut bins = [0u8; STATS_BLOCK];
        for part in block.chunks(STATS_BLOCK) {
            let bins = &mut bins[..part.len()];
            for (b, &v) in bins.iter_mut().zip(part) {
                let x = v * HISTOGRAM_BINS as f32;
                let x = if x > 0.0 { x } else { 0.0 };
                let x = if x < LAST_BIN { x } else { LAST_BIN };
                // A whole number below 2²³ plus 2²³ is exact, and its
                // mantissa's low byte is that number.
                *b = (x.floor() + 8_388_608.0).to_bits() as u8;
            }
            let (quads, rest) = bins.as_chunks::<4>();
            let [h0, h1, h2, h3] = &mut self.histograms;
            for q in quads {
                h0[usize::from(q[0])] += 1;
                h1[usize::from(q[1])] += 1;
                h2[usize::from(q[2])] += 1;
                h3[usize::from(q[3])] += 1;
            }
            for &b in rest {
                h0[usize::from(b)] += 1;
            }
        }
    }

    fn finish(self) -> ImageStats {
        let mut histogram = vec![0u32; HISTOGRAM_BINS];
        for h in &self.histograms {
            for (t, &c) in histogram.iter_mut().zip(h) {
                *t += c;
            }
        }
        let n = self.count.max(1) as f32;
        ImageStats {
            mean: (self.sum / self.count.max(1) as f64) as f32,
            median: histogram_quantile(&histogram, 0.5),
            saturated_fraction: self.saturated as f32 / n,
            dark_fraction: self.dark as f32 / n,
            histogram,
            count: self.count,
        }
    }
}

/// The `q`-quantile of a histogram over [0, 1], interpolated inside its bin.
pub fn histogram_quantile(histogram: &[u32], q: f32) -> f32 {
    let total: u64 = histogram.iter().map(|&c| u64::from(c)).sum();
    if total == 0 {
        return 0.0;
    }
    let target = f64::from(q.clamp(0.0, 1.0)) * total as f64;
    let bins = histogram.len() as f32;
    let mut seen = 0.0f64;
    for (i, &c) in histogram.iter().enumerate() {
        let next = seen + f64::from(c);
        if next >= target && c > 0 {
            let frac = ((target - seen) / f64::from(c)) as f32;
            return (i as f32 + frac) / bins;
        }
        seen = next;
    }
    1.0
}

/// The metered image: downsampled luminance, the weights of the pixels that
/// count, and their statistics.
#[derive(Clone, Debug)]
pub struct Metered {
    width: usize,
    height: usize,
    luma: Vec<f32>,
    /// Shared with the prepared mask it came from (not copied per frame).
    weight: Option<Arc<[f32]>>,
    saturated: Option<Vec<f32>>,
    scale: usize,
    stats: ImageStats,
}

impl Metered {
    /// A metered image from luminance in [0, 1] that is already at metering
    /// size (used by tests and by sources that meter themselves). `weight`,
    /// when given, has one 0/1 entry per pixel.
    pub fn from_luma(
        width: usize,
        height: usize,
        luma: Vec<f32>,
        weight: Option<Vec<f32>>,
    ) -> Result<Self> {
        if width < 3 || height < 3 {
            return Err(Error::EmptyImage {
                what: "metered image (needs at least 3×3 pixels)",
                width,
                height,
            });
        }
        if luma.len() != width * height {
            return Err(Error::BufferSize {
                what: "metered luminance",
                expected: width * height,
                actual: luma.len(),
                detail: format!("one f32 per pixel, {width}×{height}"),
            });
        }
        if let Some(w) = &weight {
            if w.len() != luma.len() {
                return Err(Error::BufferSize {
                    what: "metering weights",
                    expected: luma.len(),
                    actual: w.len(),
                    detail: format!("one f32 per pixel, {width}×{height}"),
                });
            }
        }
        if let Some(bad) = luma.iter().find(|v| !(0.0..=1.0).contains(*v)) {
            return Err(Error::InvalidParameter {
                name: "metered luminance",
                value: f64::from(*bad),
                expected: "values in [0, 1]",
            });
        }
        let stats = match &weight {
            Some(w) => ImageStats::from_pixels(
                luma.iter().zip(w).filter(|(_, &w)| w > 0.0).map(|(v, _)| v),
            ),
            None => ImageStats::from_slice(&luma),
        };
        Ok(Self {
            width,
            height,
            luma,
            weight: weight.map(Arc::from),
            saturated: None,
            scale: 1,
            stats,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Luminance in [0, 1], row-major.
    pub fn luma(&self) -> &[f32] {
        &self.luma
    }
    /// Per-pixel weights of the metric (1 = counts), or `None` when every
    /// interior pixel counts.
    pub fn weight(&self) -> Option<&[f32]> {
        self.weight.as_deref()
    }
    /// Per metered pixel, the part of its luminance (in [0, 1], like the
    /// luminance) that saturated samples carry: for a grey frame the
    /// fraction of the samples averaged into it that were at or above
    /// [`SATURATED_LEVEL`]; a saturated colour channel counts with its
    /// luminance weight. `None` when every metered pixel is one sample, or
    /// when no sample was saturated.
    pub fn saturated_samples(&self) -> Option<&[f32]> {
        self.saturated.as_deref()
    }
    /// Full-frame pixels per metered pixel along each axis.
    pub fn scale(&self) -> usize {
        self.scale
    }
    /// Statistics of the pixels that count.
    pub fn stats(&self) -> &ImageStats {
        &self.stats
    }

    /// Mean luminance inside a rectangle given in full-frame pixels
    /// (`x, y, width, height`), clipped to the image, with the fraction of
    /// its pixels that are saturated. `None` if the rectangle is outside.
    pub fn region_mean(&self, x: usize, y: usize, w: usize, h: usize) -> Option<(f32, f32)> {
        let s = self.scale;
        let (x0, y0) = (x / s, y / s);
        let x1 = ((x + w).div_ceil(s)).min(self.width);
        let y1 = ((y + h).div_ceil(s)).min(self.height);
        if x0 >= x1 || y0 >= y1 {
            return None;
        }
        let (mut sum, mut sat, mut n) = (0.0f64, 0usize, 0usize);
        for row in self.luma.chunks_exact(self.width).take(y1).skip(y0) {
            for &v in &row[x0..x1] {
                sum += f64::from(v);
                sat += usize::from(v >= SATURATED_LEVEL);
                n += 1;
            }
        }
        Some(((sum / n as f64) as f32, sat as f32 / n as f32))
    }
}

/// Meters camera frames (see the module documentation).
#[derive(Clone, Debug, Default)]
pub struct Meter {
    config: MeteringConfig,
}

impl Meter {
    /// A meter for `config`.
    pub fn new(config: MeteringConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self { config })
    }

    /// The configuration.
    pub fn config(&self) -> &MeteringConfig {
        &self.config
    }

    /// Meters `frame`. With a `mask` (same size as the frame), a metered
    /// pixel counts if at least half of its block is inside the mask, and the
    /// gradient metric uses only pixels whose 3×3 neighbourhood counts.
    pub fn meter(&self, frame: &FrameView<'_>, mask: Option<&RoiMask>) -> Result<Metered> {
        let grid = self.grid(frame)?;
        let prepared = match mask {
            Some(m) => Some(self.prepare_for(m, &grid, frame.width(), frame.height())?),
            None => None,
        };
        Ok(self.finish(frame, &grid, prepared.as_ref()))
    }

    /// Prepares `mask` for frames of `format` at its size: which metered
    /// pixels it covers. A mask is fixed per calibration, so a caller that
    /// meters many frames prepares it once ([`Meter::meter_prepared`]).
    pub fn prepare(&self, mask: &RoiMask, format: PixelFormat) -> Result<PreparedMask> {
        let grid = Grid::of(&self.config, format, mask.width(), mask.height())?;
        self.prepare_for(mask, &grid, mask.width(), mask.height())
    }

    /// [`Meter::meter`] with a prepared mask; the same result.
    pub fn meter_prepared(&self, frame: &FrameView<'_>, mask: &PreparedMask) -> Result<Metered> {
        let grid = self.grid(frame)?;
        if (mask.frame_width, mask.frame_height, mask.bayer, mask.k)
            != (frame.width(), frame.height(), grid.bayer, grid.k)
        {
            return Err(Error::SizeMismatch {
                what: "prepared ROI mask against its frame (size, Bayer layout or metering size)",
                expected_width: frame.width(),
                expected_height: frame.height(),
                width: mask.frame_width,
                height: mask.frame_height,
            });
        }
        Ok(self.finish(frame, &grid, Some(mask)))
    }

    fn grid(&self, frame: &FrameView<'_>) -> Result<Grid> {
        Grid::of(&self.config, frame.format(), frame.width(), frame.height())
    }

    fn prepare_for(
        &self,
        m: &RoiMask,
        grid: &Grid,
        width: usize,
        height: usize,
    ) -> Result<PreparedMask> {
        if m.width() != width || m.height() != height {
            return Err(Error::SizeMismatch {
                what: "ROI mask against its frame",
                expected_width: width,
                expected_height: height,
                width: m.width(),
                height: m.height(),
            });
        }
        let Grid { k, ow, oh, bayer } = *grid;
        let mut cov = vec![0u32; ow * oh];
        for oy in 0..oh {
            let cov = &mut cov[oy * ow..(oy + 1) * ow];
            for gy in oy * k..(oy + 1) * k {
                // For Bayer quads the top-left pixel of the quad decides.
                let (mrow, step) = if bayer {
                    (m.row(2 * gy), 2)
                } else {
                    (m.row(gy), 1)
                };
                for (ox, c) in cov.iter_mut().enumerate() {
                    let start = ox * k * step;
                    *c += (0..k).filter(|i| mrow[start + i * step] != 0).count() as u32;
                }
            }
        }
        let half = (k * k).div_ceil(2) as u32;
        let valid: Vec<bool> = cov.iter().map(|&c| c >= half).collect();
        let mut weight = vec![0.0f32; ow * oh];
        for y in 1..oh - 1 {
            for x in 1..ow - 1 {
                let all = (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| valid[yy * ow + xx]));
                if all {
                    weight[y * ow + x] = 1.0;
                }
            }
        }
        // Statistics use the valid pixels, the metric the eroded ones.
        let valid_runs = runs_of(&valid);
        Ok(PreparedMask {
            frame_width: width,
            frame_height: height,
            bayer,
            k,
            weight: Arc::from(weight),
            valid_runs,
        })
    }

    /// The metered image of `frame` on `grid`, with the mask's weights.
    fn finish(&self, frame: &FrameView<'_>, grid: &Grid, mask: Option<&PreparedMask>) -> Metered {
        let Grid { k, ow, oh, bayer } = *grid;
        let gw = if bayer {
            frame.width() / 2
        } else {
            frame.width()
        };
        let mut luma = vec![0.0f32; ow * oh];
        let mut row = vec![0.0f32; gw];
        let inv_block = 1.0 / (k * k) as f32;
        // 8-bit mono and RGB: the block sums are taken on the bytes, in
        // integers, and weighted once per metered pixel.
        let channels = match frame.format() {
            PixelFormat::Mono8 => Some(1),
            PixelFormat::Rgb8 => Some(3),
            _ => None,
        };
        let mut bytes = vec![0u32; if channels.is_some() { gw * 3 } else { 0 }];
        // The luminance of saturated samples, summed per metered pixel (only
        // when a block averages several samples), and the saturated bytes
        // per sample column of the current block row.
        let blocks = k > 1;
        let mut sat_sums = vec![0.0f32; if blocks { ow * oh } else { 0 }];
        let mut sat_scratch = SaturationScratch::default();
        let mut fused = FusedScratch::default();
        let mut sat_row = vec![0.0f32; if blocks { gw } else { 0 }];
        for oy in 0..oh {
            let out = &mut luma[oy * ow..(oy + 1) * ow];
            if let Some(c) = channels {
                let rows = oy * k..(oy + 1) * k;
                let sums = blocks.then(|| &mut sat_sums[oy * ow..(oy + 1) * ow]);
                if k <= usize::from(u8::MAX) {
                    // One pass over the rows: sums and saturated counts
                    // per column in 16 and 8 bits.
                    fused.block_row(BlockRows { frame, rows, c, k }, out, sums);
                } else {
                    block_sums_8bit(frame, rows.clone(), c, k, &mut bytes, out);
                    if let Some(sums) = sums {
                        saturated_sums_8bit(frame, rows, c, k, &mut sat_scratch, sums);
                    }
                }
            } else {
                let rows = oy * k..(oy + 1) * k;
                let sat = blocks.then(|| &mut sat_sums[oy * ow..(oy + 1) * ow]);
                let scratch = (&mut row[..], &mut sat_row[..]);
                let at = FloatRows {
                    frame,
                    rows,
                    bayer,
                    k,
                };
                float_block_row(at, scratch, out, sat);
            }
            for o in out.iter_mut() {
                *o = (*o * inv_block).clamp(0.0, 1.0);
            }
        }
        let (weight, stats) = match mask {
            Some(m) => (
                Some(Arc::clone(&m.weight)),
                ImageStats::from_runs(&luma, &m.valid_runs),
            ),
            None => (None, ImageStats::from_slice(&luma)),
        };
        let saturated = sat_sums.iter().any(|&c| c > 0.0).then(|| {
            sat_sums
                .iter()
                .map(|&c| (c * inv_block).clamp(0.0, 1.0))
                .collect()
        });
        Metered {
            width: ow,
            height: oh,
            luma,
            weight,
            saturated,
            scale: if bayer { 2 * k } else { k },
            stats,
        }
    }
}

/// The metering grid of a frame: the block side `k`, the metered size and
/// whether the source grid is Bayer quads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Grid {
    k: usize,
    ow: usize,
    oh: usize,
    bayer: bool,
}

impl Grid {
    fn of(
        config: &MeteringConfig,
        format: PixelFormat,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        let bayer = format.is_bayer();
        // The source grid: pixels, or Bayer quads.
        let (gw, gh) = if bayer {
            (width / 2, height / 2)
        } else {
            (width, height)
        };
        let k = config.factor(gw, gh);
        let (ow, oh) = (gw / k, gh / k);
        if ow < 3 || oh < 3 {
            return Err(Error::EmptyImage {
                what: "metered image (the frame is too small to meter: needs at least 3×3 metered pixels)",
                width: ow,
                height: oh,
            });
        }
        Ok(Self { k, ow, oh, bayer })
    }
}

/// Each camera's metering mask (or none), prepared for its camera's frames
/// once, so that metering a frame set costs no mask work.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraMasks {
    raw: Vec<Option<RoiMask>>,
    prepared: Vec<Option<PreparedMask>>,
}

impl CameraMasks {
    /// No masks for `cameras` cameras: whole frames are metered.
    pub fn none(cameras: usize) -> Self {
        Self {
            raw: vec![None; cameras],
            prepared: vec![None; cameras],
        }
    }

    /// `masks[i]` for camera `i`, whose frames come in `formats[i]`. A mask
    /// that does not fit its camera is kept unprepared (and metering a
    /// frame with it reports why).
    pub fn new(meter: &Meter, masks: &[RoiMask], formats: &[PixelFormat]) -> Self {
        Self {
            raw: masks.iter().cloned().map(Some).collect(),
            prepared: masks
                .iter()
                .zip(formats)
                .map(|(m, &f)| meter.prepare(m, f).ok())
                .collect(),
        }
    }

    /// The masks as given.
    pub fn raw(&self) -> &[Option<RoiMask>] {
        &self.raw
    }

    /// Meters `frames[i]` with camera `i`'s mask: through the prepared mask
    /// when the frame fits it, else with the mask itself.
    pub fn meter(&self, meter: &Meter, frames: &[FrameView<'_>]) -> Result<Vec<Metered>> {
        frames
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let raw = self.raw.get(i).and_then(Option::as_ref);
                match self.prepared.get(i).and_then(Option::as_ref) {
                    Some(p) => meter.meter_prepared(f, p).or_else(|_| meter.meter(f, raw)),
                    None => meter.meter(f, raw),
                }
            })
            .collect()
    }
}

/// The source rows `rows` (pixels, or Bayer quad rows with `bayer`) of one
/// block row of a frame that is not Mono8 or RGB8, blocks of `k×k`.
struct FloatRows<'f, 'a> {
    frame: &'f FrameView<'a>,
    rows: std::ops::Range<usize>,
    bayer: bool,
    k: usize,
}

/// The luminance sums of the `k×k` blocks over the source rows `rows`
/// (pixels, or Bayer quad rows) of a frame that is not Mono8 or RGB8, in
/// `f32` row by row, into `out`; with `saturated`, the luminance of their
/// saturated samples. `scratch` holds a row of each. Compiled for AVX2
/// where the CPU has it: the same operations in the same order, so the
/// same values.
fn float_block_row(
    at: FloatRows<'_, '_>,
    scratch: (&mut [f32], &mut [f32]),
    out: &mut [f32],
    saturated: Option<&mut [f32]>,
) {
    /// The work, inlined into each build.
    #[inline(always)]
    fn work(
        at: FloatRows<'_, '_>,
        (row, sat_row): (&mut [f32], &mut [f32]),
        out: &mut [f32],
        mut saturated: Option<&mut [f32]>,
    ) {
        let FloatRows {
            frame,
            rows,
            bayer,
            k,
        } = at;
        for gy in rows {
            if bayer {
                let (top, bottom) = (frame.row(2 * gy), frame.row(2 * gy + 1));
                bayer_luma_row(frame.format(), top, bottom, row);
                if saturated.is_some() {
                    bayer_saturated_row(frame.format(), top, bottom, sat_row);
                }
            } else {
                luma_row(frame.format(), frame.row(gy), row);
                if saturated.is_some() {
                    for (s, &v) in sat_row.iter_mut().zip(row.iter()) {
                        *s = if v >= SATURATED_LEVEL { 1.0 } else { 0.0 };
                    }
                }
            }
            add_block_sums(out, row, k);
            if let Some(sat) = saturated.as_deref_mut() {
                add_block_sums(sat, sat_row, k);
            }
        }
    }
    /// [`work`] compiled for AVX2.
    ///
    /// # Safety
    ///
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn avx2(
        at: FloatRows<'_, '_>,
        scratch: (&mut [f32], &mut [f32]),
        out: &mut [f32],
        saturated: Option<&mut [f32]>,
    ) {
        work(at, scratch, out, saturated);
    }
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::Isa::detect() >= crate::cpu::Isa::Avx2 {
        // SAFETY: `detect` reports AVX2 only when the CPU has it.
        #[allow(unsafe_code)]
        unsafe {
            avx2(at, scratch, out, saturated);
        }
        return;
    }
    work(at, scratch, out, saturated);
}

/// A ground mask prepared for one frame size, pixel layout and metering
/// size ([`Meter::prepare`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PreparedMask {
    frame_width: usize,
    frame_height: usize,
    bayer: bool,
    k: usize,
    /// Per metered pixel, 1 where the metric counts it (the mask eroded by
    /// one metered pixel).
    weight: Arc<[f32]>,
    /// The metered pixels at least half of whose block is masked in (the
    /// statistics count these), as runs of consecutive indices (start,
    /// end), in order: the statistics copy them run by run.
    valid_runs: Vec<(usize, usize)>,
}

/// The runs of consecutive `true` entries of `flags`, as (start, end).
fn runs_of(flags: &[bool]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, &f) in flags.iter().enumerate() {
        match (f, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                runs.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push((s, flags.len()));
    }
    runs
}

/// The luminance sums (in [0, 1] units) of `k×k` blocks of an 8-bit frame
/// with `c` channels (1: mono, 3: RGB) over the frame rows `rows`, into
/// `out`; `bytes` is scratch.
fn block_sums_8bit(
    frame: &FrameView<'_>,
    rows: std::ops::Range<usize>,
    c: usize,
    k: usize,
    bytes: &mut [u32],
    out: &mut [f32],
) {
    let n = frame.width() * c;
    let bytes = &mut bytes[..n];
    bytes.fill(0);
    for y in rows {
        for (a, &b) in bytes.iter_mut().zip(&frame.row(y)[..n]) {
            *a += u32::from(b);
        }
    }
    let to_unit = 1.0 / 255.0;
    if c == 1 {
        for (o, block) in out.iter_mut().zip(bytes.chunks_exact(k)) {
            *o = block.iter().sum::<u32>() as f32 * to_unit;
        }
    } else {
        for (o, block) in out.iter_mut().zip(bytes.chunks_exact(3 * k)) {
            *o = rgb_sum(block) * to_unit;
        }
    }
}

/// The byte at or above which an 8-bit sample is saturated
/// ([`SATURATED_LEVEL`] of 255, rounded up).
const SATURATED_BYTE: u8 = 250;

/// The luminance of the saturated samples of `k×k` blocks of an 8-bit
/// frame with `c` channels (1: mono, 3: RGB) over the frame rows `rows`,
/// into `out` (in samples: a saturated grey sample counts 1, a saturated
/// red channel its luminance weight, 0.299). The counts per sample column
/// are kept in bytes while a block is at most 255 rows tall (16 columns per
/// SSE2 operation), in 16-bit words beyond.
fn saturated_sums_8bit(
    frame: &FrameView<'_>,
    rows: std::ops::Range<usize>,
    c: usize,
    k: usize,
    scratch: &mut SaturationScratch,
    out: &mut [f32],
) {
    if rows.len() <= usize::from(u8::MAX) {
        saturated_sums_in(frame, rows, c, k, &mut scratch.bytes, out);
    } else {
        saturated_sums_in(frame, rows, c, k, &mut scratch.words, out);
    }
}

/// The per-column sums (16 bits) and saturated counts (8 bits) of one
/// block row of an 8-bit frame, taken in one pass over its rows: the
/// metering of Mono8 and RGB8 frames for blocks of at most 255 rows.
#[derive(Default)]
struct FusedScratch {
    sums: Vec<u16>,
    saturated: Vec<u8>,
    /// The saturated counts widened, for [`rgb_totals`].
    wide: Vec<u16>,
    /// [`rgb_totals`]'s scratch.
    a: Vec<u16>,
    b: Vec<u16>,
}

/// The rows of one block row of an 8-bit frame with `c` channels (1 or
/// 3), blocks of `k×k` pixels.
struct BlockRows<'f, 'a> {
    frame: &'f FrameView<'a>,
    rows: std::ops::Range<usize>,
    c: usize,
    k: usize,
}

impl FusedScratch {
    /// The luminance sums (in [0, 1] units) of the `k×k` blocks of an
    /// 8-bit frame with `c` channels over the frame rows `rows` (`k ≤ 255`
    /// of them) into `out`, and, with `saturated`, the luminance of their
    /// saturated samples: the same values as [`block_sums_8bit`] and
    /// [`saturated_sums_8bit`].
    fn block_row(
        &mut self,
        rows: BlockRows<'_, '_>,
        out: &mut [f32],
        saturated: Option<&mut [f32]>,
    ) {
        // 4×4 blocks of Mono8 and RGB8 frames: their AVX2 kernels.
        #[cfg(target_arch = "x86_64")]
        if matches!(rows.c, 1 | 3)
            && rows.k == 4
            && crate::cpu::Isa::detect() >= crate::cpu::Isa::Avx2
        {
            let width = 4 * rows.c * out.len();
            let row = |i: usize| rows.frame.row(rows.rows.start + i).get(..width);
            if let (4, Some(r0), Some(r1), Some(r2), Some(r3)) =
                (rows.rows.len(), row(0), row(1), row(2), row(3))
            {
                if rows.c == 1 {
                    prefetch_rows(
                        rows.frame,
                        rows.rows.end + 4 * PREFETCH_BLOCK_ROWS,
                        4,
                        width,
                    );
                }
                let four = [r0, r1, r2, r3];
                // SAFETY: `detect` reports AVX2 only when the CPU has it.
                #[allow(unsafe_code)]
                unsafe {
                    if rows.c == 1 {
                        mono4_block_row_avx2(four, out, saturated);
                    } else {
                        rgb4_block_row_avx2(four, out, saturated);
                    }
                }
                return;
            }
        }
        let n = out.len() * rows.k * rows.c;
        self.sums.clear();
        self.sums.resize(n, 0);
        self.saturated.clear();
        self.saturated.resize(n, 0);
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::Isa::detect() >= crate::cpu::Isa::Avx2 {
            // SAFETY: `detect` reports AVX2 only when the CPU has it.
            #[allow(unsafe_code)]
            unsafe {
                self.block_row_avx2(rows, out, saturated);
            }
            return;
        }
        self.block_row_in(rows, out, saturated);
    }

    /// [`FusedScratch::block_row_in`] compiled for AVX2.
    ///
    /// # Safety
    ///
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn block_row_avx2(
        &mut self,
        rows: BlockRows<'_, '_>,
        out: &mut [f32],
        saturated: Option<&mut [f32]>,
    ) {
        self.block_row_in(rows, out, saturated);
    }

    /// The work of [`FusedScratch::block_row`], its buffers sized.
    #[inline(always)]
    fn block_row_in(
        &mut self,
        rows: BlockRows<'_, '_>,
        out: &mut [f32],
        saturated: Option<&mut [f32]>,
    ) {
        let BlockRows { frame, rows, c, k } = rows;
        let n = self.sums.len();
        for y in rows {
            let Some(row) = frame.row(y).get(..n) else {
                continue;
            };
            let sums = self.sums.iter_mut().zip(self.saturated.iter_mut());
            for ((s, t), &b) in sums.zip(row) {
                // At most 255 rows: neither wraps.
                *s = s.wrapping_add(u16::from(b));
                *t = t.wrapping_add(u8::from(b >= SATURATED_BYTE));
            }
        }
        let to_unit = 1.0 / 255.0;
        if c == 1 {
            block_totals(out, &self.sums, k, to_unit);
        } else if !rgb_totals(out, &self.sums, k, to_unit, (&mut self.a, &mut self.b)) {
            for (o, block) in out.iter_mut().zip(self.sums.chunks_exact(3 * k)) {
                *o = rgb_sum(block) * to_unit;
            }
        }
        let Some(sat) = saturated else { return };
        // Whether any sample saturated, 64 columns at a time (an early
        // exit per byte would not vectorise).
        let none = self
            .saturated
            .chunks(64)
            .all(|c| c.iter().fold(0u8, |a, &b| a | b) == 0);
        if none {
            sat.fill(0.0);
        } else if c == 1 {
            block_totals(sat, &self.saturated, k, 1.0);
        } else {
            self.wide.clear();
            self.wide
                .extend(self.saturated.iter().map(|&v| u16::from(v)));
            if !rgb_totals(sat, &self.wide, k, 1.0, (&mut self.a, &mut self.b)) {
                for (o, block) in sat.iter_mut().zip(self.saturated.chunks_exact(3 * k)) {
                    *o = rgb_sum(block);
                }
            }
        }
    }
}

/// How many block rows past the next one the Mono8 4×4 kernel asks for a
/// frame's rows (2: the block row three ahead of the one being summed): a
/// frame just written by another core (the capture thread) is read at the
/// latency of that core's caches, which the loads alone wait on. (For
/// RGB8, three times the bytes a row, asking ahead made the kernel slower
/// where the frame was already near: not done.)
const PREFETCH_BLOCK_ROWS: usize = 2;

/// Asks the caches for the first `width` bytes of `count` rows of `frame`
/// from row `first` (rows past the frame's end are left out).
#[inline]
fn prefetch_rows(frame: &FrameView<'_>, first: usize, count: usize, width: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        for y in first..(first + count).min(frame.height()) {
            let Some(row) = frame.row(y).get(..width) else {
                continue;
            };
            for line in row.chunks(64) {
                // SAFETY: a prefetch reads nothing into the program and
                // never faults; the address lies in the row anyway.
                #[allow(unsafe_code)]
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(line.as_ptr().cast::<i8>());
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (frame, first, count, width);
}

/// The 4×4 blocks of one block row of a Mono8 frame (the live default:
/// 1288×964 metered to 322×241): [`FusedScratch::block_row`]'s values, to
/// the bit, 32 columns (8 blocks) a step. Each row's bytes are summed in
/// pairs by `vpmaddubsw`, the four rows' pairs added in 16 bits (at most
/// 2040), and `vpmaddwd` adds the pairs of each block into 32 bits; the
/// saturated bytes (≥ [`SATURATED_BYTE`], by an unsigned maximum) are
/// counted the same way from their all-ones masks. The last blocks of a
/// row that is not a multiple of 32 columns are summed one by one.
///
/// # Safety
///
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn mono4_block_row_avx2(
    rows: [&[u8]; 4],
    out: &mut [f32],
    mut saturated: Option<&mut [f32]>,
) {
    use std::arch::x86_64::*;
    let to_unit = 1.0f32 / 255.0;
    let n = out.len();
    let scale = _mm256_set1_ps(to_unit);
    let steps = whole_steps(&rows, 32, n);
    for i in 0..steps {
        let (at, blocks) = (32 * i, 8 * i..8 * i + 8);
        // SAFETY: `at + 32 ≤ 32·steps ≤` every row's length.
        let load = |r: &[u8]| unsafe { _mm256_loadu_si256(r.as_ptr().add(at).cast()) };
        let v = rows.map(load);
        let luma = _mm256_mul_ps(_mm256_cvtepi32_ps(sums_of_fours(v)), scale);
        // SAFETY: `blocks` lies in `out` (`8·steps ≤ n`).
        unsafe { _mm256_storeu_ps(out[blocks.clone()].as_mut_ptr(), luma) };
        if let Some(sat) = saturated.as_deref_mut() {
            let counts = _mm256_cvtepi32_ps(saturated_in_fours(v));
            if let Some(dst) = sat.get_mut(blocks) {
                // SAFETY: `dst` holds 8 values.
                unsafe { _mm256_storeu_ps(dst.as_mut_ptr(), counts) };
            }
        }
    }
    for (b, o) in out.iter_mut().enumerate().skip(8 * steps) {
        let (mut sum, mut count) = (0u32, 0u32);
        for r in rows {
            for &v in r.get(4 * b..4 * b + 4).unwrap_or_default() {
                sum += u32::from(v);
                count += u32::from(v >= SATURATED_BYTE);
            }
        }
        *o = sum as f32 * to_unit;
        if let Some(x) = saturated.as_deref_mut().and_then(|s| s.get_mut(b)) {
            *x = count as f32;
        }
    }
}

/// Of four rows' 32 bytes each (`v`), the sums of each run of four bytes
/// down the four rows (16 bytes: a 4×4 block of Mono8, or of one RGB8
/// channel), as eight 32-bit integers: each row's bytes summed in pairs
/// by `vpmaddubsw`, the four rows' pairs added in 16 bits (at most 2040),
/// and `vpmaddwd` adding the pairs of each block.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn sums_of_fours(v: [std::arch::x86_64::__m256i; 4]) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let ones8 = _mm256_set1_epi8(1);
    let pairs = v.map(|v| _mm256_maddubs_epi16(v, ones8));
    _mm256_madd_epi16(
        _mm256_add_epi16(
            _mm256_add_epi16(pairs[0], pairs[1]),
            _mm256_add_epi16(pairs[2], pairs[3]),
        ),
        _mm256_set1_epi16(1),
    )
}

/// [`sums_of_fours`] of the bytes at or above [`SATURATED_BYTE`] counted
/// as 1 (by an unsigned maximum, from their all-ones masks).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn saturated_in_fours(v: [std::arch::x86_64::__m256i; 4]) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let threshold = _mm256_set1_epi8(SATURATED_BYTE as i8);
    // All ones (−1) where a byte saturates: minus the count.
    let mask = v.map(|v| _mm256_cmpeq_epi8(_mm256_max_epu8(v, threshold), v));
    let minus = _mm256_add_epi8(
        _mm256_add_epi8(mask[0], mask[1]),
        _mm256_add_epi8(mask[2], mask[3]),
    );
    let minus = _mm256_madd_epi16(
        _mm256_maddubs_epi16(_mm256_set1_epi8(1), minus),
        _mm256_set1_epi16(1),
    );
    _mm256_sub_epi32(_mm256_setzero_si256(), minus)
}

/// [`luma::rgb`] of eight blocks' red, green and blue integer sums, in its
/// operations: `(w_r·r + w_g·g) + w_b·b` (`w`: the weights broadcast).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn rgb_luma(
    w: [std::arch::x86_64::__m256; 3],
    rgb: [std::arch::x86_64::__m256i; 3],
) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    _mm256_add_ps(
        _mm256_add_ps(
            _mm256_mul_ps(w[0], _mm256_cvtepi32_ps(rgb[0])),
            _mm256_mul_ps(w[1], _mm256_cvtepi32_ps(rgb[1])),
        ),
        _mm256_mul_ps(w[2], _mm256_cvtepi32_ps(rgb[2])),
    )
}

/// The steps of 8 blocks (`bytes` of each row a step) that every one of
/// `rows` holds whole, and `n` blocks hold.
#[inline(always)]
fn whole_steps(rows: &[&[u8]; 4], bytes: usize, n: usize) -> usize {
    rows.iter()
        .map(|r| r.len() / bytes)
        .min()
        .unwrap_or(0)
        .min(n / 8)
}

/// `pshufb` masks that take channel `ch` of 16 RGB pixels (48 bytes) out of
/// each of its three 16-byte thirds (`-128`, a zero, where a pixel's byte
/// lies in another third), the same in both 128-bit lanes.
const fn rgb_channel_masks(ch: usize) -> [[i8; 32]; 3] {
    let mut masks = [[-128i8; 32]; 3];
    let mut i = 0;
    while i < 16 {
        let p = 3 * i + ch;
        masks[p / 16][i] = (p % 16) as i8;
        masks[p / 16][i + 16] = (p % 16) as i8;
        i += 1;
    }
    masks
}

/// The 4×4 blocks of one block row of an RGB8 frame (the simulated rig's
/// cameras: 1288×964 metered to 322×241): [`FusedScratch::block_row`]'s
/// values, to the bit, 32 pixels (8 blocks) a step. Each row's 96 bytes
/// are split into their channels by `pshufb` (16 pixels in each 128-bit
/// lane), each channel's bytes summed in pairs by `vpmaddubsw`, the four
/// rows' pairs added in 16 bits and the pairs of each block by `vpmaddwd`;
/// a block's luminance is [`luma::rgb`] of its three sums, in the same
/// operations. The saturated bytes are counted the same way from their
/// all-ones masks. The blocks after the last whole step are summed one by
/// one.
///
/// # Safety
///
/// The CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn rgb4_block_row_avx2(
    rows: [&[u8]; 4],
    out: &mut [f32],
    mut saturated: Option<&mut [f32]>,
) {
    use std::arch::x86_64::*;
    const MASKS: [[[i8; 32]; 3]; 3] = [
        rgb_channel_masks(0),
        rgb_channel_masks(1),
        rgb_channel_masks(2),
    ];
    let to_unit = 1.0f32 / 255.0;
    let n = out.len();
    let mut masks = [[_mm256_setzero_si256(); 3]; 3];
    for ch in 0..3 {
        for t in 0..3 {
            // SAFETY: each mask holds 32 bytes.
            masks[ch][t] = unsafe { _mm256_loadu_si256(MASKS[ch][t].as_ptr().cast()) };
        }
    }
    let weights = [
        _mm256_set1_ps(luma::W_R),
        _mm256_set1_ps(luma::W_G),
        _mm256_set1_ps(luma::W_B),
    ];
    let scale = _mm256_set1_ps(to_unit);
    let steps = whole_steps(&rows, 96, n);
    for i in 0..steps {
        let (at, blocks) = (96 * i, 8 * i..8 * i + 8);
        // Each row's channels: pixels 0–15 in the low lane, 16–31 in the
        // high one.
        let mut v = [[_mm256_setzero_si256(); 3]; 4];
        for (r, row) in rows.iter().enumerate() {
            let p = row.as_ptr();
            // SAFETY: `at + 96 ≤ 96·steps ≤` the row's length.
            let thirds = unsafe {
                [
                    _mm256_loadu2_m128i(p.add(at + 48).cast(), p.add(at).cast()),
                    _mm256_loadu2_m128i(p.add(at + 64).cast(), p.add(at + 16).cast()),
                    _mm256_loadu2_m128i(p.add(at + 80).cast(), p.add(at + 32).cast()),
                ]
            };
            for ch in 0..3 {
                v[r][ch] = _mm256_or_si256(
                    _mm256_or_si256(
                        _mm256_shuffle_epi8(thirds[0], masks[ch][0]),
                        _mm256_shuffle_epi8(thirds[1], masks[ch][1]),
                    ),
                    _mm256_shuffle_epi8(thirds[2], masks[ch][2]),
                );
            }
        }
        let mut sums = [_mm256_setzero_si256(); 3];
        for ch in 0..3 {
            sums[ch] = sums_of_fours([v[0][ch], v[1][ch], v[2][ch], v[3][ch]]);
        }
        let luminance = _mm256_mul_ps(rgb_luma(weights, sums), scale);
        // SAFETY: `blocks` lies in `out` (`8·steps ≤ n`).
        unsafe { _mm256_storeu_ps(out[blocks.clone()].as_mut_ptr(), luminance) };
        if let Some(sat) = saturated.as_deref_mut() {
            let mut counts = [_mm256_setzero_si256(); 3];
            for ch in 0..3 {
                counts[ch] = saturated_in_fours([v[0][ch], v[1][ch], v[2][ch], v[3][ch]]);
            }
            let hot = rgb_luma(weights, counts);
            if let Some(dst) = sat.get_mut(blocks) {
                // SAFETY: `dst` holds 8 values.
                unsafe { _mm256_storeu_ps(dst.as_mut_ptr(), hot) };
            }
        }
    }
    for (b, o) in out.iter_mut().enumerate().skip(8 * steps) {
        let (mut sum, mut count) = ([0u32; 3], [0u32; 3]);
        for r in rows {
            for (j, &v) in r
                .get(12 * b..12 * b + 12)
                .unwrap_or_default()
                .iter()
                .enumerate()
            {
                sum[j % 3] += u32::from(v);
                count[j % 3] += u32::from(v >= SATURATED_BYTE);
            }
        }
        let [r, g, bl] = sum.map(|v| v as f32);
        *o = luma::rgb(r, g, bl) * to_unit;
        if let Some(x) = saturated.as_deref_mut().and_then(|s| s.get_mut(b)) {
            let [r, g, bl] = count.map(|v| v as f32);
            *x = luma::rgb(r, g, bl);
        }
    }
}

/// Per block of `k` RGB pixels (`3k` consecutive `values`), the luminance
/// of its channels' sums times `scale` into `out`, as [`rgb_sum`] gives
/// it, for `k` a power of two up to 16 (else `false`, and nothing
/// written). The channels are summed in halving steps over the whole row
/// (`v[i] + v[i + 3k/2]`, then of that `w[i] + w[i + 3k/4]`, … down to
/// `+ 3`: shifted adds of whole slices, which vectorise), after which each
/// block's first three values are its sums of R, G and B. A block's sum is
/// at most `k²·255` and fits 16 bits. `a` and `b` are scratch.
#[inline(always)]
fn rgb_totals(
    out: &mut [f32],
    values: &[u16],
    k: usize,
    scale: f32,
    (a, b): (&mut Vec<u16>, &mut Vec<u16>),
) -> bool {
    if !k.is_power_of_two() || k > 16 {
        return false;
    }
    a.clear();
    a.extend_from_slice(values);
    let mut step = 3 * k / 2;
    while step >= 3 && step < a.len() {
        b.clear();
        let (head, tail) = (&a[..a.len() - step], &a[step..]);
        b.extend(head.iter().zip(tail).map(|(&x, &y)| x.wrapping_add(y)));
        std::mem::swap(a, b);
        step /= 2;
    }
    let (triples, _) = a.as_chunks::<3>();
    for (o, t) in out.iter_mut().zip(triples.iter().step_by(k)) {
        *o = luma::rgb(f32::from(t[0]), f32::from(t[1]), f32::from(t[2])) * scale;
    }
    true
}

/// Per block of `k` consecutive `values`, their sum times `scale` into
/// `out` (summed in integers; vectorised for the usual block sizes).
#[inline(always)]
fn block_totals<T: Copy + Into<u32>>(out: &mut [f32], values: &[T], k: usize, scale: f32) {
    fn fixed<const K: usize, T: Copy + Into<u32>>(out: &mut [f32], values: &[T], scale: f32) {
        let (blocks, _) = values.as_chunks::<K>();
        for (o, b) in out.iter_mut().zip(blocks) {
            *o = b.iter().map(|&v| v.into()).sum::<u32>() as f32 * scale;
        }
    }
    match k {
        2 => fixed::<2, T>(out, values, scale),
        4 => fixed::<4, T>(out, values, scale),
        8 => fixed::<8, T>(out, values, scale),
        _ => {
            for (o, block) in out.iter_mut().zip(values.chunks_exact(k)) {
                *o = block.iter().map(|&v| v.into()).sum::<u32>() as f32 * scale;
            }
        }
    }
}

/// The per-column counters of [`saturated_sums_8bit`].
#[derive(Default)]
struct SaturationScratch {
    bytes: Vec<u8>,
    words: Vec<u16>,
}

fn saturated_sums_in<T>(
    frame: &FrameView<'_>,
    rows: std::ops::Range<usize>,
    c: usize,
    k: usize,
    counts: &mut Vec<T>,
    out: &mut [f32],
) where
    T: Copy + Default + std::ops::AddAssign + From<bool> + Into<u32>,
{
    let n = frame.width() * c;
    counts.clear();
    counts.resize(n, T::default());
    for y in rows {
        for (a, &b) in counts.iter_mut().zip(&frame.row(y)[..n]) {
            *a += T::from(b >= SATURATED_BYTE);
        }
    }
    if counts.iter().all(|&v| v.into() == 0) {
        out.fill(0.0);
        return;
    }
    if c == 1 {
        /// With the block size known at compile time, the sums vectorise
        /// (in integers: summing the counts as floats, through
        /// [`add_block_sums`], made Mono8 metering 5 % slower).
        fn fixed<const K: usize, T: Copy + Into<u32>>(out: &mut [f32], counts: &[T]) {
            let (blocks, _) = counts.as_chunks::<K>();
            for (o, b) in out.iter_mut().zip(blocks) {
                *o = b.iter().map(|&v| v.into()).sum::<u32>() as f32;
            }
        }
        match k {
            2 => fixed::<2, T>(out, counts),
            4 => fixed::<4, T>(out, counts),
            8 => fixed::<8, T>(out, counts),
            _ => {
                for (o, block) in out.iter_mut().zip(counts.chunks_exact(k)) {
                    *o = block.iter().map(|&v| v.into()).sum::<u32>() as f32;
                }
            }
        }
    } else {
        for (o, block) in out.iter_mut().zip(counts.chunks_exact(3 * k)) {
            *o = rgb_sum(block);
        }
    }
}

/// The luminance of the summed channels of the RGB triples in `block`
/// ([`luma::rgb`] of `ΣR`, `ΣG`, `ΣB`).
#[inline(always)]
fn rgb_sum<T: Copy + Into<u32>>(block: &[T]) -> f32 {
    let (pixels, _) = block.as_chunks::<3>();
    let [r, g, b] = pixels.iter().fold([0u32; 3], |[r, g, b], p| {
        [r + p[0].into(), g + p[1].into(), b + p[2].into()]
    });
    luma::rgb(r as f32, g as f32, b as f32)
}

/// The luminance of the saturated samples of a row of 2×2 Bayer quads (a
/// quad whose samples are all saturated counts 1).
#[inline(always)]
fn bayer_saturated_row(format: PixelFormat, top: &[u8], bottom: &[u8], dst: &mut [f32]) {
    if format.bytes_per_pixel() == 2 {
        let sat = |v: f32| if v >= SATURATED_LEVEL { 1.0 } else { 0.0 };
        return luma::bayer_wide_row(format, top, bottom, dst, sat);
    }
    let sat = |v: u8| if v >= SATURATED_BYTE { 1.0 } else { 0.0 };
    bayer_row(bayer_weights(format), top, bottom, dst, sat);
}

/// Adds the sums of `row`'s consecutive blocks of `k` to `out`.
#[inline(always)]
fn add_block_sums(out: &mut [f32], row: &[f32], k: usize) {
    /// With the block size known at compile time, the sums vectorise.
    fn fixed<const K: usize>(out: &mut [f32], row: &[f32]) {
        let (blocks, _) = row.as_chunks::<K>();
        for (o, b) in out.iter_mut().zip(blocks) {
            *o += b.iter().sum::<f32>();
        }
    }
    match k {
        1 => fixed::<1>(out, row),
        2 => fixed::<2>(out, row),
        3 => fixed::<3>(out, row),
        4 => fixed::<4>(out, row),
        5 => fixed::<5>(out, row),
        6 => fixed::<6>(out, row),
        8 => fixed::<8>(out, row),
        _ => {
            for (o, block) in out.iter_mut().zip(row.chunks_exact(k)) {
                *o += block.iter().sum::<f32>();
            }
        }
    }
}

#[cfg(test)]
mod tests;
