//! The plan of a composition: the canvas cut into runs of pixels with the
//! same cameras, and per pixel and camera one tap (see the module
//! documentation of [`super`]).

use std::fmt;
use std::sync::OnceLock;

use super::bayer::{self, Cfa};
use super::{Isa, MAX_GAIN, MIN_GAIN, ONE};
use crate::error::{Error, Result};

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
pub(super) struct Run {
    /// First canvas pixel (row-major index).
    pub(super) start: u32,
    /// Number of pixels.
    pub(super) len: u32,
    /// First tap. The taps are camera by camera: pixel `p` of the run takes
    /// from its `j`-th camera the tap `taps + j·len + p`.
    pub(super) taps: u32,
    /// The cameras: `cameras[cameras .. cameras + n]`.
    pub(super) cameras: u32,
    /// Number of cameras (0: a black run).
    pub(super) n: u32,
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

/// An 8-bit image a plan reads, packed: `width · height` pixels of the
/// canvas's channels, or of one byte each in a Bayer mosaic (`cfa`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Image<'a> {
    pub(crate) bytes: &'a [u8],
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// The mosaic's colour order, or `None` for pixels of the canvas's
    /// channels.
    pub(crate) cfa: Option<Cfa>,
}

impl Image<'_> {
    /// Bytes a pixel on a canvas of `ch` channels.
    #[inline(always)]
    pub(crate) fn bytes_per_pixel(&self, ch: usize) -> usize {
        if self.cfa.is_some() {
            1
        } else {
            ch
        }
    }
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
    pub(super) pixels: usize,
    /// Per camera, the source size (width, height).
    sources: Vec<(usize, usize)>,
    /// Runs covering the canvas, tile by tile.
    pub(super) runs: Vec<Run>,
    /// Per tap, the row-major index of the top-left source pixel
    /// (`y0 · width + x0`, with `x0 ≤ width − 2`, `y0 ≤ height − 2`).
    pub(super) index: Vec<u32>,
    /// Per tap, the weights of the top-left, top-right, bottom-left and
    /// bottom-right pixels in 1/4096 (blend weight included), as four
    /// little-endian `u16`: the low 32 bits are the top pair, the high 32
    /// bits the bottom pair.
    pub(super) weights: Vec<u64>,
    pub(super) cameras: Vec<u32>,
    /// Whether the invariant holds (always, unless a bug broke it): the
    /// gathering kernels run only then.
    pub(super) gather_ok: bool,
    /// Per tap, its Bayer site ([`bayer::sites`]), built when a mosaic is
    /// first composed.
    sites: OnceLock<Vec<u8>>,
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
pub(super) fn bilinear(x: f32, y: f32, w: usize, h: usize) -> (u32, [f64; 4]) {
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
            let Some(cams) = self.run_cameras(run) else {
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

    /// The cameras of `run`.
    #[inline]
    pub(super) fn run_cameras(&self, run: &Run) -> Option<&[u32]> {
        self.cameras
            .get(run.cameras as usize..run.cameras as usize + run.n as usize)
    }

    /// Per camera, the source size (width, height).
    pub(super) fn sources(&self) -> &[(usize, usize)] {
        &self.sources
    }

    /// Per tap, its Bayer site code ([`bayer::sites`]; built on first
    /// use).
    pub(super) fn sites(&self) -> &[u8] {
        self.sites.get_or_init(|| bayer::sites(self))
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

    /// Composes `images` (one per source: `ch` channels, 1 or 3, or a
    /// Bayer mosaic when `ch` is 3) into `out` (the canvas, `pixels · ch`
    /// bytes), each camera's contribution scaled by its gain in `gains`
    /// (per source, in 1/256, [`MIN_GAIN`] to [`MAX_GAIN`]) when given:
    /// every byte is written.
    pub(crate) fn execute(
        &self,
        images: &[Image<'_>],
        ch: usize,
        gains: Option<&[u16]>,
        out: &mut [u8],
    ) -> Result<()> {
        self.execute_with(Isa::detect(), images, ch, gains, out)
    }

    /// [`Plan::execute`] with the kernels of `isa`, or of the widest set
    /// below it the CPU has ([`Isa::supported`]).
    pub(crate) fn execute_with(
        &self,
        isa: Isa,
        images: &[Image<'_>],
        ch: usize,
        gains: Option<&[u16]>,
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
            return Err(Error::invalid(
                "surround view",
                "images",
                format!("one for each of {} cameras", self.sources.len()),
                images.len(),
            ));
        }
        for (img, &(w, h)) in images.iter().zip(&self.sources) {
            if (img.width, img.height) != (w, h)
                || img.bytes.len() < w * h * img.bytes_per_pixel(ch)
            {
                return Err(Error::SizeMismatch {
                    what: "image against the surround view's camera",
                    expected_width: w,
                    expected_height: h,
                    width: img.width,
                    height: img.height,
                });
            }
            if img.cfa.is_some() && ch != 3 {
                return Err(Error::invalid(
                    "surround view",
                    "canvas channels for a Bayer mosaic",
                    "3 (an RGB canvas)",
                    ch,
                ));
            }
        }
        if let Some(g) = gains {
            if g.len() != self.sources.len() {
                return Err(Error::invalid(
                    "surround view",
                    "gains",
                    format!("one for each of {} cameras", self.sources.len()),
                    g.len(),
                ));
            }
            if let Some(&bad) = g.iter().find(|&&g| !(MIN_GAIN..=MAX_GAIN).contains(&g)) {
                return Err(Error::InvalidParameter {
                    name: "surround gain (1/256)",
                    value: f64::from(bad),
                    expected: "16 to 4096 (a gain of 1/16 to 16)",
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
        let sites = if images.iter().any(|i| i.cfa.is_some()) {
            self.sites()
        } else {
            &[]
        };
        let job = Job {
            plan: self,
            images,
            ch,
            gains: gains.unwrap_or_default(),
            sites,
        };
        super::run(isa, job, gains.is_some(), out);
        Ok(())
    }

    /// Run `run`'s part of the canvas `out` (`job.ch` channels) and its
    /// taps.
    #[inline]
    pub(super) fn parts<'o, 'p>(
        &'p self,
        run: &Run,
        job: &Job<'p>,
        out: &'o mut [u8],
    ) -> Option<(&'o mut [u8], Taps<'p>)> {
        let (ch, images, sites) = (job.ch, job.images, job.sites);
        let (start, len, n) = (run.start as usize, run.len as usize, run.n as usize);
        let first = run.taps as usize;
        let cams = self.run_cameras(run)?;
        let mosaics = if sites.is_empty() {
            0
        } else {
            cams.iter()
                .filter(|&&c| images.get(c as usize).is_some_and(|i| i.cfa.is_some()))
                .count()
        };
        Some((
            out.get_mut(start * ch..(start + len) * ch)?,
            Taps {
                cams,
                index: self.index.get(first..first + len * n)?,
                weights: self.weights.get(first..first + len * n)?,
                sites: if mosaics == 0 {
                    &[]
                } else {
                    sites.get(first..first + len * n)?
                },
                len,
                mosaics,
            },
        ))
    }
}

/// What one execution of a plan reads (checked by
/// [`Plan::execute_with`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Job<'a> {
    pub(super) plan: &'a Plan,
    /// One image per camera of the plan.
    pub(super) images: &'a [Image<'a>],
    /// The canvas's channels.
    pub(super) ch: usize,
    /// Per camera, the gain in 1/256; empty without gains.
    pub(super) gains: &'a [u16],
    /// The plan's Bayer site table, or empty when no image is a mosaic.
    pub(super) sites: &'a [u8],
}

/// The taps of one run, camera by camera: pixel `p` of the run takes from
/// its `j`-th camera the tap `j·len + p`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Taps<'p> {
    /// The run's cameras.
    pub(super) cams: &'p [u32],
    /// Per tap, the top-left source pixel.
    pub(super) index: &'p [u32],
    /// Per tap, the four weights.
    pub(super) weights: &'p [u64],
    /// Per tap, its Bayer site; empty when no camera of the run is a
    /// mosaic.
    pub(super) sites: &'p [u8],
    /// Pixels in the run.
    pub(super) len: usize,
    /// How many of the run's cameras are Bayer mosaics.
    pub(super) mosaics: usize,
}

impl Taps<'_> {
    /// Camera `j`'s tap for pixel `p`: index, weights and Bayer site
    /// ([`bayer::BORDER`] where there is none, which reads safely).
    #[inline(always)]
    pub(super) fn tap(&self, j: usize, p: usize) -> (u32, u64, u8) {
        let t = j * self.len + p;
        (
            self.index[t],
            self.weights[t],
            self.sites.get(t).copied().unwrap_or(bayer::BORDER),
        )
    }
}
