//! What every view of the rig shares, whatever surface its canvas shows
//! (the ground plane of the surround view, the cylinder of the panorama):
//! each camera's map from canvas pixels to sub-pixel source positions, the
//! blend weights of the three [`BlendMode`]s, and the per-frame remap plans
//! built from them.
//!
//! A view describes its surface by one function: for a canvas pixel, the
//! cameras that may show it and where in their images
//! ([`Mosaic::build`]'s `locate`). The mosaic keeps the positions that
//! fall inside the image (with its right and lower neighbour, for the
//! bilinear sample), computes each camera's exclusive region and the
//! distance of every pixel from it, and the weights: in an overlap, camera
//! `c`'s weight falls off with its distance `d_c` from its exclusive region,
//! `w_c ∝ 1/d_c²`; [`BlendMode::Alpha`] weighs all alike, and
//! [`BlendMode::Seams`] gives each pixel to the camera of the largest
//! linear weight. The canvas is mapped in bands of rows, one thread per
//! core; each pixel is computed alone, so the maps do not depend on the
//! number of threads.

use std::sync::OnceLock;

use nalgebra::Point2;
use rigview_calib::rig::{CameraProjector, Frame, Rig};

use super::grid;
use super::remap;
use super::{BlendMode, Overlap, OverlapPatch};
use crate::error::{Error, Result};
use crate::exposure::controller::PairObservation;
use crate::exposure::PatchPair;
use crate::image::{distance_to_zero, FrameView, RoiMask};

/// One camera's part of the canvas.
#[derive(Debug)]
pub struct CameraLayer {
    /// The camera's index in the rig.
    pub camera: usize,
    /// The camera's name in the rig.
    pub name: String,
    /// The part of the canvas it contributes to: column, row, width, height.
    pub roi: [usize; 4],
    /// Source image size (width, height).
    pub source: (usize, usize),
    /// Per ROI pixel, the source position (x, y), or (−1, −1) where the
    /// camera contributes nothing.
    pub map: Vec<[f32; 2]>,
    /// Per blend mode ([`BlendMode::ALL`] order), per ROI pixel, the weight
    /// in 1/256 (the weights of all cameras sum to exactly 256 on a covered
    /// pixel).
    pub weights: [Vec<u16>; 3],
}

impl CameraLayer {
    /// Checks that `frame` has the camera's calibrated size.
    pub fn check_frame(&self, frame: &FrameView<'_>) -> Result<()> {
        if (frame.width(), frame.height()) != self.source {
            return Err(Error::SizeMismatch {
                what: "frame against its camera's calibration",
                expected_width: self.source.0,
                expected_height: self.source.1,
                width: frame.width(),
                height: frame.height(),
            });
        }
        Ok(())
    }
}

/// The cameras' maps and blend weights on one canvas, and the per-frame
/// plans: the part of a view that [`super::Composer`] composes.
#[derive(Debug)]
pub struct Mosaic {
    /// What the view is called in errors ("surround view", "panorama").
    what: &'static str,
    width: usize,
    height: usize,
    layers: Vec<CameraLayer>,
    /// Per blend mode, the per-frame plan, built on first use.
    plans: [OnceLock<remap::Plan>; 3],
    /// Per camera, the source pixels that reach the canvas (set by the
    /// view from the maps).
    masks: Vec<RoiMask>,
    /// The overlaps of the rig's neighbour pairs (set by the view).
    overlaps: Vec<Overlap>,
    /// The overlap patches' sampled pixels, camera by camera in memory
    /// order (set with the overlaps).
    samples: PatchSamples,
}

/// What [`Mosaic::build`] returns besides the mosaic: the whole-canvas maps
/// of every camera (a view derives its masks and overlaps from them).
pub(crate) struct Maps {
    /// Per camera, per canvas pixel, the source position or (−1, −1).
    pub(crate) source: Vec<Vec<[f32; 2]>>,
}

impl Maps {
    /// Whether camera `k` shows canvas pixel `p`.
    pub(crate) fn sees(&self, k: usize, p: usize) -> bool {
        self.source[k][p][0] >= 0.0
    }

    /// The row-major index of camera `k`'s source pixel nearest to where
    /// canvas pixel `p` samples it (`sees(k, p)` must hold).
    pub(crate) fn nearest(&self, k: usize, p: usize, (sw, sh): (usize, usize)) -> u32 {
        let [x, y] = self.source[k][p];
        let (x, y) = (
            (x.round() as usize).min(sw - 1),
            (y.round() as usize).min(sh - 1),
        );
        (y * sw + x) as u32
    }
}

impl Mosaic {
    /// Maps a `w × h` canvas into `cameras` (name and source size each).
    /// `locate(col, row, out)` pushes `(camera, source position)` for each
    /// camera that may show the pixel `(col, row)`; positions outside the
    /// image (less one pixel right and below) are dropped. A camera that
    /// shows no pixel is the error `empty(camera)`, or, where that is
    /// `None`, a layer that covers nothing. `locate` runs on a
    /// grid of `grid` pixels and the maps are interpolated where that errs
    /// by at most `tolerance` source pixels ([`grid::map_canvas`]; a grid
    /// of 1: every pixel exactly).
    pub(crate) fn build<L>(
        what: &'static str,
        (w, h): (usize, usize),
        cameras: &[(String, (usize, usize))],
        (grid, tolerance): (usize, f64),
        locate: L,
        empty: impl Fn(usize) -> Option<Error>,
    ) -> Result<(Self, Maps)>
    where
        L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>) + Sync,
    {
        let (source, count, regions) =
            map_with_regions(what, (w, h), cameras, (grid, tolerance), &locate)?;
        Self::from_maps(what, (w, h), cameras, (source, count), regions, empty)
    }

    /// [`Mosaic::build`] for a canvas that shows a surface of its own
    /// (the bowl seen from a viewpoint): the blend distances are measured
    /// on the surface ([`SurfaceDistances`]), not on the canvas, so that
    /// the seams stay where they are on the surface whatever the canvas
    /// shows of it. `locate` pushes, besides the cameras, the pixel's
    /// position on the surface's raster as camera `cameras.len()` (none:
    /// the pixel shows no surface).
    pub(crate) fn build_on_surface<L>(
        what: &'static str,
        (w, h): (usize, usize),
        cameras: &[(String, (usize, usize))],
        (grid, tolerance): (usize, f64),
        locate: L,
        surface: &SurfaceDistances,
    ) -> Result<(Self, Maps)>
    where
        L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>) + Sync,
    {
        let mut sizes: Vec<(usize, usize)> = cameras.iter().map(|(_, size)| *size).collect();
        sizes.push(surface.size);
        let (mut source, mut count) = grid::map_canvas((w, h), &sizes, &locate, (grid, tolerance));
        let on_surface = source.pop().unwrap_or_default();
        for (n, at) in count.iter_mut().zip(&on_surface) {
            if at[0] >= 0.0 {
                *n = n.saturating_sub(1);
            }
        }
        let regions = source
            .iter()
            .enumerate()
            .map(|(k, src)| {
                let roi = bounding_box(w, h, |i| src[i][0] >= 0.0)?;
                let [c0, r0, rw, rh] = roi;
                let mut distance = Vec::with_capacity(rw * rh);
                for r in r0..r0 + rh {
                    distance.extend((c0..c0 + rw).map(|c| {
                        let [x, y] = on_surface[r * w + c];
                        surface.distance(k, x, y).unwrap_or(1e6)
                    }));
                }
                Some(Region { roi, distance })
            })
            .collect();
        Self::from_maps(what, (w, h), cameras, (source, count), regions, |_| None)
    }

    /// The mosaic from the maps, the cameras' regions and distances.
    fn from_maps(
        what: &'static str,
        (w, h): (usize, usize),
        cameras: &[(String, (usize, usize))],
        (source, count): (Vec<Vec<[f32; 2]>>, Vec<u8>),
        regions: Vec<Option<Region>>,
        empty: impl Fn(usize) -> Option<Error>,
    ) -> Result<(Self, Maps)> {
        let regions: Vec<Region> = regions
            .into_iter()
            .enumerate()
            .map(|(k, r)| match r {
                Some(r) => Ok(r),
                None => empty(k).map_or(
                    Ok(Region {
                        roi: [0, 0, 0, 0],
                        distance: Vec::new(),
                    }),
                    Err,
                ),
            })
            .collect::<Result<_>>()?;
        // The weights, one thread per camera.
        let layers = std::thread::scope(|scope| {
            let jobs: Vec<_> = cameras
                .iter()
                .enumerate()
                .map(|(k, (name, size))| {
                    let (source, regions, count) = (&source, &regions, &count);
                    scope.spawn(move || {
                        let [c0, r0, rw, rh] = regions[k].roi;
                        let mut scratch = BlendScratch::default();
                        let mut map = Vec::with_capacity(rw * rh);
                        // Zero where the camera shows nothing.
                        let mut weights: [Vec<u16>; 3] = std::array::from_fn(|_| vec![0; rw * rh]);
                        for r in r0..r0 + rh {
                            let row = r * w + c0..r * w + c0 + rw;
                            let src = &source[k][row.clone()];
                            map.extend_from_slice(src);
                            let at = (r - r0) * rw;
                            for (dc, (s, &n)) in src.iter().zip(&count[row]).enumerate() {
                                if s[0] < 0.0 {
                                    continue;
                                }
                                let [lin, alpha, seam] = if n == 1 {
                                    [256, 256, 256]
                                } else {
                                    let c = c0 + dc;
                                    blend_weights(k, (c, r), w, source, regions, &mut scratch)
                                };
                                weights[0][at + dc] = lin;
                                weights[1][at + dc] = alpha;
                                weights[2][at + dc] = seam;
                            }
                        }
                        CameraLayer {
                            camera: k,
                            name: name.clone(),
                            roi: regions[k].roi,
                            source: *size,
                            map,
                            weights,
                        }
                    })
                })
                .collect();
            jobs.into_iter()
                .map(|job| job.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect::<Vec<_>>()
        });
        let mosaic = Self {
            what,
            width: w,
            height: h,
            layers,
            plans: Default::default(),
            masks: Vec::new(),
            overlaps: Vec::new(),
            samples: PatchSamples::default(),
        };
        Ok((mosaic, Maps { source }))
    }

    /// Sets what the view derived from the maps: each camera's mask of the
    /// source pixels that reach the canvas, and the neighbour pairs'
    /// overlaps.
    pub(crate) fn set_regions(&mut self, masks: Vec<RoiMask>, overlaps: Vec<Overlap>) {
        self.samples = PatchSamples::new(&overlaps, self.layers.len());
        self.masks = masks;
        self.overlaps = overlaps;
    }

    /// Each camera's mask of the source pixels that reach the canvas, in
    /// rig order.
    pub(crate) fn masks(&self) -> &[RoiMask] {
        &self.masks
    }

    /// The overlaps of the rig's neighbour pairs.
    pub fn overlaps(&self) -> &[Overlap] {
        &self.overlaps
    }

    /// The patch means of every overlap in the current frames (rig order),
    /// for the balancing (Eq. 5). Frames of another size than the
    /// calibration are an error.
    pub fn pair_observations(&self, frames: &[FrameView<'_>]) -> Result<Vec<PairObservation>> {
        self.check_frames(frames)?;
        Ok(observations(&self.overlaps, &self.samples, frames))
    }

    /// Builds the per-frame plan of `mode` now, if it is not built yet:
    /// for a view built off the per-set path, so that its first
    /// composition does not build it there.
    pub fn prepare(&self, mode: BlendMode) {
        self.plan(mode);
    }

    /// The per-frame plan of `mode` (built on its first use).
    pub(crate) fn plan(&self, mode: BlendMode) -> &remap::Plan {
        let m = mode.index();
        self.plans[m].get_or_init(|| {
            let (w, layers) = (self.width, &self.layers);
            let sources = layers.iter().map(|l| l.source).collect();
            remap::Plan::build(w, w * self.height, sources, |i, list| {
                let (c, r) = (i % w, i / w);
                for (k, layer) in layers.iter().enumerate() {
                    let [c0, r0, rw, rh] = layer.roi;
                    if c < c0 || r < r0 || c >= c0 + rw || r >= r0 + rh {
                        continue;
                    }
                    let j = (r - r0) * rw + (c - c0);
                    let weight = layer.weights[m][j];
                    if weight > 0 {
                        list.push(remap::Contribution {
                            camera: k as u32,
                            at: layer.map[j],
                            weight: f64::from(weight),
                        });
                    }
                }
            })
        })
    }

    /// The plan of camera `k` alone over the canvas rectangle `rect`
    /// (column, row, width, height; within the canvas), unweighted: its
    /// warped image there, black where it sees nothing.
    pub(crate) fn region_plan(&self, k: usize, rect: [usize; 4]) -> Option<remap::Plan> {
        let layer = self.layers.get(k)?;
        let [x0, y0, w, h] = rect;
        if x0 + w > self.width || y0 + h > self.height || w == 0 || h == 0 {
            return None;
        }
        let [c0, r0, rw, rh] = layer.roi;
        Some(remap::Plan::build(
            w,
            w * h,
            vec![layer.source],
            |i, list| {
                let (c, r) = (x0 + i % w, y0 + i / w);
                if c < c0 || r < r0 || c >= c0 + rw || r >= r0 + rh {
                    return;
                }
                let at = layer.map[(r - r0) * rw + (c - c0)];
                if at[0] >= 0.0 {
                    list.push(remap::Contribution {
                        camera: 0,
                        at,
                        weight: 1.0,
                    });
                }
            },
        ))
    }

    /// Canvas width and height, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Each camera's part of the canvas, in rig order.
    pub fn layers(&self) -> &[CameraLayer] {
        &self.layers
    }

    /// Camera `k`'s blend weight (1/256) in `mode` at canvas pixel
    /// (`col`, `row`): 0 where it shows nothing.
    pub fn weight(&self, k: usize, mode: BlendMode, col: usize, row: usize) -> u16 {
        let Some(layer) = self.layers.get(k) else {
            return 0;
        };
        let [c0, r0, rw, rh] = layer.roi;
        if col < c0 || row < r0 || col >= c0 + rw || row >= r0 + rh {
            return 0;
        }
        layer.weights[mode.index()][(row - r0) * rw + col - c0]
    }

    /// Checks that there is one frame per camera, of its calibrated size;
    /// an error names the camera.
    pub fn check_frames(&self, frames: &[FrameView<'_>]) -> Result<()> {
        if frames.len() != self.layers.len() {
            return Err(Error::invalid(
                self.what,
                "frames",
                format!("one for each of {} cameras", self.layers.len()),
                frames.len(),
            ));
        }
        self.layers
            .iter()
            .zip(frames)
            .enumerate()
            .try_for_each(|(k, (layer, f))| {
                layer.check_frame(f).map_err(|e| self.camera_error(k, e))
            })
    }

    /// `cause`, about camera `k`, as an error that names the camera.
    pub(crate) fn camera_error(&self, k: usize, cause: Error) -> Error {
        let name = self.layers.get(k).map_or("?", |l| l.name.as_str());
        Error::Camera {
            view: self.what,
            camera: k,
            name: name.into(),
            source: Box::new(cause),
        }
    }

    /// What the view is called in errors.
    pub(crate) fn what(&self) -> &'static str {
        self.what
    }
}

/// Each camera's distance from its exclusive region, measured on a raster
/// of a surface of its own (the bowl's ground plan) rather than on a
/// canvas: what [`Mosaic::build_on_surface`] weighs with, and what a
/// renderer that draws the surface as a mesh weighs its vertices with.
#[derive(Debug)]
pub struct SurfaceDistances {
    size: (usize, usize),
    regions: Vec<Option<Region>>,
}

impl SurfaceDistances {
    /// The distances on a `w × h` raster of a surface that `cameras`
    /// show where `locate` says (as for [`Mosaic::build`]).
    pub(crate) fn build<L>(
        what: &'static str,
        (w, h): (usize, usize),
        cameras: &[(String, (usize, usize))],
        (grid, tolerance): (usize, f64),
        locate: L,
    ) -> Result<Self>
    where
        L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>) + Sync,
    {
        let (_, _, regions) = map_with_regions(what, (w, h), cameras, (grid, tolerance), &locate)?;
        Ok(Self {
            size: (w, h),
            regions,
        })
    }

    /// The raster's width and height.
    pub fn size(&self) -> (usize, usize) {
        self.size
    }

    /// Camera `k`'s distance (raster pixels) from its exclusive region at
    /// raster position (`x`, `y`) (pixel centres at whole numbers),
    /// interpolated bilinearly; positions beyond the camera's part of the
    /// raster take its edge's. `None`: the camera shows none of the
    /// surface.
    pub fn distance(&self, k: usize, x: f32, y: f32) -> Option<f32> {
        let region = self.regions.get(k)?.as_ref()?;
        let [c0, r0, rw, rh] = region.roi;
        let fx = (x - c0 as f32).clamp(0.0, (rw - 1) as f32);
        let fy = (y - r0 as f32).clamp(0.0, (rh - 1) as f32);
        let (ix, iy) = (fx as usize, fy as usize);
        let (ax, ay) = (fx - ix as f32, fy - iy as f32);
        let (jx, jy) = ((ix + 1).min(rw - 1), (iy + 1).min(rh - 1));
        let d = |c: usize, r: usize| region.distance[r * rw + c];
        let top = d(ix, iy) * (1.0 - ax) + d(jx, iy) * ax;
        let bottom = d(ix, jy) * (1.0 - ax) + d(jx, jy) * ax;
        Some(top * (1.0 - ay) + bottom * ay)
    }
}

/// The maps of a canvas ([`grid::map_canvas`]: each camera's source
/// positions, and how many cameras show each pixel) and each camera's
/// region on it ([`exclusive_regions`]).
#[allow(clippy::type_complexity)]
fn map_with_regions<L>(
    what: &'static str,
    (w, h): (usize, usize),
    cameras: &[(String, (usize, usize))],
    (grid, tolerance): (usize, f64),
    locate: &L,
) -> Result<(Vec<Vec<[f32; 2]>>, Vec<u8>, Vec<Option<Region>>)>
where
    L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>) + Sync,
{
    let sizes: Vec<(usize, usize)> = cameras.iter().map(|(_, size)| *size).collect();
    let (source, count) = grid::map_canvas((w, h), &sizes, locate, (grid, tolerance));
    let regions = exclusive_regions(what, (w, h), cameras, &source, &count)?;
    Ok((source, count, regions))
}

/// Per camera of a canvas's maps (`source`, `count`: how many cameras show
/// each pixel), its part of the canvas and the distance of each of its
/// pixels from its exclusive region (`None`: it shows nothing).
fn exclusive_regions(
    what: &'static str,
    (w, h): (usize, usize),
    cameras: &[(String, (usize, usize))],
    source: &[Vec<[f32; 2]>],
    count: &[u8],
) -> Result<Vec<Option<Region>>> {
    // Per camera, its part of the canvas and the distance of each of
    // its pixels from its exclusive region (which lies within it, so
    // the distances there are those over the whole canvas).
    std::thread::scope(|scope| {
        let jobs: Vec<_> = source
            .iter()
            .enumerate()
            .map(|(k, src)| {
                let count = &count;
                scope.spawn(move || -> Result<Option<Region>> {
                    let covered = |i: usize| src[i][0] >= 0.0;
                    let Some(roi) = bounding_box(w, h, covered) else {
                        return Ok(None);
                    };
                    let [c0, r0, rw, rh] = roi;
                    let mut exclusive = Vec::with_capacity(rw * rh);
                    for r in r0..r0 + rh {
                        exclusive.extend((c0..c0 + rw).map(|c| {
                            let i = r * w + c;
                            u8::from(!(covered(i) && count[i] == 1)) * 255
                        }));
                    }
                    let distance =
                        distance_to_zero(&exclusive, rw, rh).map_err(|e| Error::Camera {
                            view: what,
                            camera: k,
                            name: cameras[k].0.clone(),
                            source: Box::new(e),
                        })?;
                    Ok(Some(Region { roi, distance }))
                })
            })
            .collect();
        jobs.into_iter()
            .map(|job| job.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect::<Result<Vec<_>>>()
    })
}

/// Buffers of [`blend_weights`], reused from pixel to pixel.
#[derive(Debug, Default)]
struct BlendScratch {
    seeing: Vec<usize>,
    inv: Vec<f64>,
    exact: Vec<f64>,
    rounded: Vec<u32>,
    /// Per number of cameras `n` and camera, its alpha weight among `n`
    /// (computed on first use).
    alpha: Vec<Vec<u16>>,
}

/// A camera's part of the canvas (column, row, width, height) and, per
/// pixel of it, the distance from the camera's exclusive region.
#[derive(Debug)]
struct Region {
    roi: [usize; 4],
    distance: Vec<f32>,
}

impl Region {
    /// The distance at canvas pixel (`c`, `r`), which the camera shows.
    fn distance(&self, (c, r): (usize, usize)) -> f32 {
        let [c0, r0, rw, _] = self.roi;
        self.distance[(r - r0) * rw + (c - c0)]
    }
}

/// The 1/256 weights of camera `k` at canvas pixel `at` (column, row; the
/// canvas is `w` wide) for the three blend modes. The weights of all
/// cameras seeing the pixel are rounded together ([`linear_weight`],
/// [`alpha_weight`]), so
/// that they sum to exactly 256 in every mode.
fn blend_weights(
    k: usize,
    at: (usize, usize),
    w: usize,
    source: &[Vec<[f32; 2]>],
    regions: &[Region],
    scratch: &mut BlendScratch,
) -> [u16; 3] {
    let s = scratch;
    let i = at.1 * w + at.0;
    s.seeing.clear();
    s.seeing
        .extend((0..source.len()).filter(|&m| source[m][i][0] >= 0.0));
    let Some(me) = s.seeing.iter().position(|&m| m == k) else {
        return [0, 0, 0];
    };
    if s.seeing.len() == 1 {
        return [256, 256, 256];
    }
    // w ∝ 1/d², with d floored at half a pixel.
    s.inv.clear();
    s.inv.extend(
        s.seeing
            .iter()
            .map(|&m| 1.0 / f64::from(regions[m].distance(at).max(0.5)).powi(2)),
    );
    // The last camera of the largest weight takes the seam pixel.
    let best = (0..s.inv.len())
        .max_by(|&a, &b| s.inv[a].total_cmp(&s.inv[b]))
        .unwrap_or(me);
    let linear = linear_weight(&s.inv, me, &mut s.exact, &mut s.rounded);
    let n = s.inv.len();
    if s.alpha.len() <= n {
        s.alpha.resize(n + 1, Vec::new());
    }
    if s.alpha[n].is_empty() {
        s.alpha[n] = (0..n)
            .map(|m| alpha_weight(n, m, &mut s.exact, &mut s.rounded))
            .collect();
    }
    [linear, s.alpha[n][me], if best == me { 256 } else { 0 }]
}

/// The linear and alpha weights (1/256) of camera `me` among the cameras
/// seeing a pixel, from their `1/d²` (`inv`): each mode's weights of all
/// the cameras are rounded together to sum to exactly 256 (rounding each on
/// its own gives 257 when two fall on a half, 255 for three thirds).
#[cfg(test)]
pub(super) fn mode_weights(
    inv: &[f64],
    me: usize,
    exact: &mut Vec<f64>,
    rounded: &mut Vec<u32>,
) -> [u16; 2] {
    [
        linear_weight(inv, me, exact, rounded),
        alpha_weight(inv.len(), me, exact, rounded),
    ]
}

/// Camera `me`'s linear weight (1/256) among the cameras seeing a pixel,
/// from their `1/d²` (`inv`), rounded together with the others' to sum to
/// exactly 256 (rounding each on its own gives 257 when two fall on a
/// half, 255 for three thirds).
fn linear_weight(inv: &[f64], me: usize, exact: &mut Vec<f64>, rounded: &mut Vec<u32>) -> u16 {
    let total: f64 = inv.iter().sum();
    rounded.resize(inv.len(), 0);
    exact.clear();
    exact.extend(inv.iter().map(|&v| 256.0 * v / total));
    remap::round_to_total(exact, 256, rounded);
    rounded[me] as u16
}

/// Camera `me`'s alpha weight (1/256) among `n` alike, rounded the same
/// way.
fn alpha_weight(n: usize, me: usize, exact: &mut Vec<f64>, rounded: &mut Vec<u32>) -> u16 {
    rounded.resize(n, 0);
    exact.clear();
    exact.resize(n, 256.0 / n as f64);
    remap::round_to_total(exact, 256, rounded);
    rounded[me] as u16
}

/// The smallest rectangle holding every pixel where `covered` holds.
fn bounding_box(w: usize, h: usize, covered: impl Fn(usize) -> bool) -> Option<[usize; 4]> {
    let (mut c0, mut r0, mut c1, mut r1) = (usize::MAX, usize::MAX, 0, 0);
    for r in 0..h {
        for c in 0..w {
            if covered(r * w + c) {
                c0 = c0.min(c);
                c1 = c1.max(c);
                r0 = r0.min(r);
                r1 = r1.max(r);
            }
        }
    }
    (c0 != usize::MAX).then(|| [c0, r0, c1 - c0 + 1, r1 - r0 + 1])
}

/// Checks the sampling options a view shares: the fraction of a patch both
/// cameras must show, and the source masks' step (1 to 16 pixels); errors
/// name the option.
pub(crate) fn check_sampling(
    (coverage_name, coverage): (&'static str, f64),
    (step_name, step): (&'static str, usize),
) -> Result<()> {
    crate::error::check_range(coverage_name, coverage, 0.0, 1.0, "a fraction in [0, 1]")?;
    if step == 0 || step > 16 {
        return Err(Error::InvalidParameter {
            name: step_name,
            value: step as f64,
            expected: "a step of 1 to 16 source pixels",
        });
    }
    Ok(())
}

/// A rig's cameras as a view of the vehicle's surroundings needs them:
/// their names and image sizes, and their projectors.
pub(crate) struct VehicleCameras {
    /// Per camera, its name and image size.
    pub(crate) sources: Vec<(String, (usize, usize))>,
    /// Per camera, its pose and model.
    pub(crate) projectors: Vec<CameraProjector>,
}

/// Checks that `rig` is posed in the vehicle frame and that each camera has
/// a pose and a usable image size; errors name the camera and start with
/// `what` (the view).
pub(crate) fn vehicle_cameras(rig: &Rig, what: &str) -> Result<VehicleCameras> {
    if rig.frame != Frame::Vehicle {
        return Err(Error::invalid(
            what,
            "the rig's frame",
            "poses in the vehicle frame (x forward, y left, z up, ground z = 0); a camera-frame rig (e.g. a Kalibr camchain) needs its ground pose first (`rigview calib ground`)",
            "poses relative to a camera",
        ));
    }
    let mut sources = Vec::with_capacity(rig.cameras.len());
    let mut projectors = Vec::with_capacity(rig.cameras.len());
    for cam in &rig.cameras {
        let Some(projector) = cam.projector() else {
            return Err(Error::invalid(
                what,
                format!("camera `{}`'s pose", cam.name),
                "every camera's pose in the vehicle frame",
                "none",
            ));
        };
        let (iw, ih) = (
            cam.intrinsics.width as usize,
            cam.intrinsics.height as usize,
        );
        if iw < 2 || ih < 2 || iw.checked_mul(ih).is_none_or(|p| p > u32::MAX as usize) {
            return Err(Error::invalid(
                what,
                format!("camera `{}`'s image size", cam.name),
                "at least 2×2 and at most 2³² pixels",
                format_args!("{iw}×{ih}"),
            ));
        }
        sources.push((cam.name.clone(), (iw, ih)));
        projectors.push(projector);
    }
    Ok(VehicleCameras {
        sources,
        projectors,
    })
}

/// Each camera's source mask: its pixels (sampled every `step`, each result
/// covering a `step × step` block) that land, through `to_canvas` (a
/// source pixel to a canvas position, column and row), on a canvas pixel
/// the camera contributes to. The canvas positions of the samples are
/// mapped like the canvas itself ([`grid::map_canvas`] on a grid of
/// [`grid::MASK_GRID`] samples, or `grid` if smaller: within
/// [`grid::MASK_TOLERANCE_PX`] canvas pixels of `to_canvas`).
pub(crate) fn source_masks<T>(
    mosaic: &Mosaic,
    projectors: &[CameraProjector],
    (step, grid): (usize, usize),
    to_canvas: T,
) -> Result<Vec<RoiMask>>
where
    T: Fn(&CameraProjector, &Point2<f64>) -> Option<(f64, f64)> + Sync,
{
    let (w, h) = mosaic.size();
    let layers = mosaic.layers();
    projectors
        .iter()
        .zip(layers)
        .map(|(projector, layer)| {
            let (sw, sh) = layer.source;
            let (nx, ny) = (sw.div_ceil(step), sh.div_ceil(step));
            let half = 0.5 * (step as f64 - 1.0);
            let locate = |x: usize, y: usize, found: &mut Vec<(usize, Point2<f64>)>| {
                let centre = Point2::new((x * step) as f64 + half, (y * step) as f64 + half);
                if let Some((c, r)) = to_canvas(projector, &centre) {
                    found.push((0, Point2::new(c, r)));
                }
            };
            // Positions up to the canvas's far edges are kept (and then
            // left out below, as outside the camera's part).
            let (positions, _) = grid::map_canvas(
                (nx, ny),
                &[(w + 1, h + 1)],
                &locate,
                (grid.min(grid::MASK_GRID), grid::MASK_TOLERANCE_PX),
            );
            source_mask(layer, step, (nx, &positions[0]))
        })
        .collect()
}

fn source_mask(
    layer: &CameraLayer,
    step: usize,
    (nx, positions): (usize, &[[f32; 2]]),
) -> Result<RoiMask> {
    let (sw, sh) = layer.source;
    let [c0, r0, rw, rh] = layer.roi;
    let mut data = vec![0u8; sw * sh];
    for (i, &[c, r]) in positions.iter().enumerate() {
        if c < 0.0 || r < 0.0 {
            continue;
        }
        let (x, y) = ((i % nx) * step, (i / nx) * step);
        let (c, r) = (c as usize, r as usize);
        if c < c0 || r < r0 || c >= c0 + rw || r >= r0 + rh {
            continue;
        }
        if layer.weights[0][(r - r0) * rw + (c - c0)] == 0 {
            continue;
        }
        for yy in y..(y + step).min(sh) {
            data[yy * sw + x..yy * sw + (x + step).min(sw)].fill(255);
        }
    }
    RoiMask::new(sw, sh, data)
}

/// The part of the canvas where cameras `i` and `j` may both show pixels:
/// the intersection of their layers' rectangles (column, row, width,
/// height), or `None`.
pub(crate) fn shared_rect(layers: &[CameraLayer], i: usize, j: usize) -> Option<[usize; 4]> {
    let ([a0, b0, aw, bh], [c0, d0, cw, dh]) = (layers.get(i)?.roi, layers.get(j)?.roi);
    let (x0, y0) = (a0.max(c0), b0.max(d0));
    let (x1, y1) = ((a0 + aw).min(c0 + cw), (b0 + bh).min(d0 + dh));
    (x1 > x0 && y1 > y0).then(|| [x0, y0, x1 - x0, y1 - y0])
}

/// The overlaps of the neighbour pairs `pairs` on a `w × h` canvas and
/// their patches: squares of `cell` canvas pixels (on a grid from the
/// canvas's corner) of which at least the fraction `coverage` both cameras
/// show; `centre` gives a canvas position's point (x, y) in the vehicle
/// frame. One thread per pair.
pub(crate) fn overlaps(
    maps: &Maps,
    layers: &[CameraLayer],
    (w, h): (usize, usize),
    pairs: &[(usize, usize)],
    cell: usize,
    coverage: f64,
    centre: impl Fn(f64, f64) -> (f64, f64) + Sync,
) -> Vec<Overlap> {
    let centre = &centre;
    std::thread::scope(|scope| {
        let jobs: Vec<_> = pairs
            .iter()
            .map(|&pair| {
                scope.spawn(move || overlap(maps, layers, (w, h), pair, cell, coverage, centre))
            })
            .collect();
        jobs.into_iter()
            .map(|job| job.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    })
}

fn overlap(
    maps: &Maps,
    layers: &[CameraLayer],
    (w, h): (usize, usize),
    (i, j): (usize, usize),
    cell: usize,
    coverage: f64,
    centre: impl Fn(f64, f64) -> (f64, f64),
) -> Overlap {
    let none = Overlap {
        i,
        j,
        pixels: 0,
        patches: Vec::new(),
    };
    let Some([x0, y0, rw, rh]) = shared_rect(layers, i, j) else {
        return none;
    };
    let both = |p: usize| maps.sees(i, p) && maps.sees(j, p);
    let pixels = (y0..y0 + rh)
        .map(|r| (x0..x0 + rw).filter(|&c| both(r * w + c)).count())
        .sum();
    let need = (coverage * (cell * cell) as f64).ceil() as usize;
    let mut patches = Vec::new();
    // The patch grid's cells that meet the shared rectangle.
    let (first_r, first_c) = (y0 / cell * cell, x0 / cell * cell);
    let mut cells = Vec::with_capacity(cell * cell);
    for r0 in (first_r..h.saturating_sub(cell - 1).min(y0 + rh)).step_by(cell) {
        for c0 in (first_c..w.saturating_sub(cell - 1).min(x0 + rw)).step_by(cell) {
            cells.clear();
            cells.extend(
                (r0..r0 + cell)
                    .flat_map(|r| (c0..c0 + cell).map(move |c| r * w + c))
                    .filter(|&p| both(p)),
            );
            if cells.len() < need.max(1) {
                continue;
            }
            let pixels_of = |k: usize| {
                let mut px: Vec<u32> = cells
                    .iter()
                    .map(|&p| maps.nearest(k, p, layers[k].source))
                    .collect();
                px.sort_unstable();
                px.dedup();
                px
            };
            patches.push(OverlapPatch {
                centre_m: centre(c0 as f64 + 0.5 * cell as f64, r0 as f64 + 0.5 * cell as f64),
                pixels_i: pixels_of(i),
                pixels_j: pixels_of(j),
            });
        }
    }
    Overlap {
        i,
        j,
        pixels,
        patches,
    }
}

/// At most this many pixels of a patch are read for its statistics, evenly
/// spread over its (sorted) pixels. A patch holds about 250 on the default
/// canvas; every pixel's read was a tenth of the per-set processing, and
/// the mean of a quarter of them differs by the noise's hundredths of a
/// grey level.
const PATCH_SAMPLES: usize = 64;

/// The pixels of a patch side that its statistics read: every
/// `⌈n / PATCH_SAMPLES⌉`-th of its `n` (sorted) pixels, at most
/// [`PATCH_SAMPLES`].
fn patch_samples(idx: &[u32]) -> impl Iterator<Item = &u32> {
    idx.iter().step_by(idx.len().div_ceil(PATCH_SAMPLES).max(1))
}

/// The overlap patches' sampled pixels, gathered per camera and sorted by
/// their place in the frame, each with the slot of the statistics it counts
/// into: `2·g` for camera `i`'s side of the `g`-th patch (overlap by
/// overlap, patch by patch), `2·g + 1` for camera `j`'s.
///
/// Read patch by patch, the 82 000 samples of the default rig's 640 patches
/// jump about four frames; read in memory order they are a sweep the
/// caches and the prefetcher follow (the per-set processing's patch means
/// measured in BENCHMARKS.md). The order of a patch's sum does not change
/// it: the lumas are `f32` of 0 or at least 2⁻²⁴ (a 16-bit level is
/// 2⁻¹⁶), each a multiple of 2⁻⁴⁷, and at most 64 of them sum below 2⁶,
/// so every partial sum in `f64` (53 bits) is exact.
#[derive(Debug, Default)]
struct PatchSamples {
    /// Per camera, the sampled pixels in ascending order.
    pixels: Vec<Vec<u32>>,
    /// Per camera, each sampled pixel's slot.
    slots: Vec<Vec<u32>>,
    /// Slots in all: twice the patches.
    len: usize,
}

impl PatchSamples {
    /// The samples of `overlaps` on a rig of `cameras`.
    fn new(overlaps: &[Overlap], cameras: usize) -> Self {
        let mut per_camera: Vec<Vec<(u32, u32)>> = vec![Vec::new(); cameras];
        let mut slot = 0u32;
        for o in overlaps {
            for p in &o.patches {
                for (k, idx) in [(o.i, &p.pixels_i), (o.j, &p.pixels_j)] {
                    if let Some(list) = per_camera.get_mut(k) {
                        list.extend(patch_samples(idx).map(|&px| (px, slot)));
                    }
                    slot += 1;
                }
            }
        }
        let (mut pixels, mut slots) = (Vec::new(), Vec::new());
        for mut list in per_camera {
            list.sort_unstable();
            pixels.push(list.iter().map(|&(px, _)| px).collect());
            slots.push(list.iter().map(|&(_, s)| s).collect());
        }
        Self {
            pixels,
            slots,
            len: slot as usize,
        }
    }
}

/// The samples a sweep reads at a time, the next as many prefetched
/// meanwhile (BENCHMARKS.md: the prefetch took RGB8's sweep from 0.60–1.16
/// of the patch-by-patch reading's time to 0.33–0.43).
const PREFETCH: usize = 32;

/// A patch side's statistics: the sum of its sampled lumas, how many of
/// them are saturated, and how many there are.
#[derive(Clone, Copy, Default)]
struct SideSums {
    sum: f64,
    saturated: usize,
    n: usize,
}

impl SideSums {
    fn add(&mut self, v: f32) {
        self.sum += f64::from(v);
        self.saturated += usize::from(v >= crate::exposure::metering::SATURATED_LEVEL);
        self.n += 1;
    }

    /// Mean intensity in [0, 1] and saturated fraction; 0 and 0 for a side
    /// without pixels.
    fn stats(self) -> (f32, f32) {
        if self.n == 0 {
            return (0.0, 0.0);
        }
        (
            (self.sum / self.n as f64) as f32,
            self.saturated as f32 / self.n as f32,
        )
    }
}

/// The patch means of every overlap in `frames` (checked against the view
/// already), for the balancing (Eq. 5): each camera's samples read in one
/// sweep ([`PatchSamples`]).
fn observations(
    overlaps: &[Overlap],
    samples: &PatchSamples,
    frames: &[FrameView<'_>],
) -> Vec<PairObservation> {
    let mut sums = vec![SideSums::default(); samples.len];
    for ((frame, pixels), slots) in frames.iter().zip(&samples.pixels).zip(&samples.slots) {
        let mut slots = slots.iter();
        let chunks = pixels.chunks(PREFETCH);
        for (chunk, next) in chunks.clone().zip(chunks.skip(1).map(Some).chain([None])) {
            if let Some(next) = next {
                frame.prefetch(next);
            }
            frame.for_each_luma(chunk, |v| {
                if let Some(side) = slots.next().and_then(|&s| sums.get_mut(s as usize)) {
                    side.add(v);
                }
            });
        }
    }
    let mut sides = sums.into_iter().map(SideSums::stats);
    overlaps
        .iter()
        .map(|o| PairObservation {
            i: o.i,
            j: o.j,
            patches: o
                .patches
                .iter()
                .map(|_| {
                    let (mean_i, saturated_i) = sides.next().unwrap_or_default();
                    let (mean_j, saturated_j) = sides.next().unwrap_or_default();
                    PatchPair {
                        mean_i,
                        saturated_i,
                        mean_j,
                        saturated_j,
                    }
                })
                .collect(),
        })
        .collect()
}

/// Mean intensity in [0, 1] and saturated fraction of the samples of the
/// pixels `idx` of a frame, patch by patch: what [`observations`] gives.
#[cfg(test)]
pub(super) fn patch_stats(frame: &FrameView<'_>, idx: &[u32]) -> (f32, f32) {
    let mut side = SideSums::default();
    frame.for_each_luma(patch_samples(idx), |v| side.add(v));
    side.stats()
}
