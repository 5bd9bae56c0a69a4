//! The canvas maps of a [`super::Mosaic`], computed exactly on a coarse grid
//! and interpolated between.
//!
//! Projecting every canvas pixel into every camera through the fisheye
//! model (an `atan2`, a `hypot` and the distortion polynomial per pixel and
//! camera) was most of a view's build. The maps are smooth over a few
//! pixels, so the view's `locate` runs only on the nodes of a grid of
//! [`MAP_GRID`]-pixel cells (and the last row and column), and each cell is
//! filled by bilinear interpolation of its four corners, camera by camera,
//! when
//!
//! - the same cameras show all four corners, and
//! - `locate` at three probes (the middle of the cell's top edge, of its
//!   left edge, and its centre) finds those cameras and no other, and for
//!   each camera the interpolation's errors at the two edge probes sum to
//!   at most [`MAP_TOLERANCE_PX`] source pixels, and its error at the
//!   centre is at most that too.
//!
//! Any other cell (a camera's edge of view, the vehicle's outline, a side's
//! border, strong distortion) is mapped pixel by pixel, exactly. To second
//! order, bilinear interpolation errs by `½·(u(1−u)·a + v(1−v)·b)` inside
//! a cell (`a`, `b` the map's second differences along the cell's sides;
//! the cross term is interpolated exactly), which peaks at `(|a| + |b|)/8`:
//! the edge probes measure `a/8` and `b/8` apart, where the centre alone
//! would see them cancel on a saddle. `core`'s tests measure the largest
//! difference from the exact maps on the real surround-nz rig for both
//! views (0.030 and 0.028 source pixels: within 0.05).

use nalgebra::Point2;

/// The side of a grid cell, canvas pixels.
pub(crate) const MAP_GRID: usize = 8;

/// The largest error (source pixels) of a cell's interpolation, as its
/// probes estimate it, for the cell to be interpolated.
pub(crate) const MAP_TOLERANCE_PX: f64 = 0.03;

/// The same for the canvas positions of the source masks' samples, canvas
/// pixels: a mask only asks which canvas pixel a sample lands on.
pub(crate) const MASK_TOLERANCE_PX: f64 = 0.25;

/// The side of a grid cell of the source masks' samples. A sample stands
/// for `mask_step` source pixels, which span several canvas pixels, so
/// the cells are smaller than the canvas's: on the real rig, 8 left three
/// in four cells to be mapped exactly, 4 one in three.
pub(crate) const MASK_GRID: usize = 4;

/// Per camera, per canvas pixel, its source position or (−1, −1); per
/// canvas pixel, how many cameras show it.
pub(crate) type CanvasMaps = (Vec<Vec<[f32; 2]>>, Vec<u8>);

/// The maps of a `w × h` canvas into `sources` (each camera's image size)
/// through `locate` (see [`super::Mosaic::build`]), on a grid of `grid`
/// pixels (1: every pixel exactly) where a cell's interpolation errs by at
/// most `tolerance` (source pixels; see the module documentation). Bands of rows, one thread per core.
pub(crate) fn map_canvas<L>(
    (w, h): (usize, usize),
    sources: &[(usize, usize)],
    locate: &L,
    (grid, tolerance): (usize, f64),
) -> CanvasMaps
where
    L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>) + Sync,
{
    let n = sources.len();
    let mut source: Vec<Vec<[f32; 2]>> = vec![vec![[-1.0, -1.0]; w * h]; n];
    let mut count = vec![0u8; w * h];
    let exact = grid < 2 || w < 2 || h < 2;
    let (xs, ys) = if exact {
        ((0..w).collect(), (0..h).collect())
    } else {
        (nodes(w, grid), nodes(h, grid))
    };
    // Cell rows: row t covers pixel rows ys[t] .. ys[t + 1] (the last one
    // down to h); in the exact case, row t is pixel row t.
    let cell_rows = if exact { h } else { ys.len() - 1 };
    let end_row = |t: usize| {
        if exact {
            t
        } else if t == cell_rows {
            h
        } else {
            ys[t]
        }
    };
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let per = cell_rows.div_ceil(threads.min(cell_rows).max(1)).max(1);
    // Split the maps into the bands' rows.
    let mut bands = Vec::new();
    let mut rest: Vec<&mut [[f32; 2]]> = source.iter_mut().map(|m| m.as_mut_slice()).collect();
    let mut rest_count = count.as_mut_slice();
    let mut t = 0;
    while t < cell_rows {
        let tb = (t + per).min(cell_rows);
        let rows = end_row(tb) - end_row(t);
        let mut maps = Vec::with_capacity(n);
        let mut next = Vec::with_capacity(n);
        for m in rest {
            let (a, b) = m.split_at_mut(rows * w);
            maps.push(a);
            next.push(b);
        }
        rest = next;
        let (a, b) = rest_count.split_at_mut(rows * w);
        rest_count = b;
        bands.push((t, tb, maps, a));
        t = tb;
    }
    let (xs, ys) = (&xs, &ys);
    std::thread::scope(|scope| {
        for (ta, tb, maps, counts) in bands {
            let mut band = Band {
                w,
                row0: end_row(ta),
                sources,
                tolerance,
                maps,
                counts,
                found: Vec::with_capacity(n),
            };
            scope.spawn(move || {
                if exact {
                    for r in band.row0..end_row(tb) {
                        for c in 0..w {
                            band.exact(locate, c, r);
                        }
                    }
                } else {
                    band.interpolate(locate, xs, ys, (ta, tb), cell_rows);
                }
            });
        }
    });
    (source, count)
}

/// The grid's node positions along a side of `len` pixels: every `grid`-th
/// pixel and the last one.
fn nodes(len: usize, grid: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..len).step_by(grid).collect();
    if v.last() != Some(&(len - 1)) {
        v.push(len - 1);
    }
    v
}

/// One thread's rows of the maps.
struct Band<'a> {
    w: usize,
    /// The band's first canvas row.
    row0: usize,
    sources: &'a [(usize, usize)],
    /// The largest interpolation error of a cell (see [`MAP_TOLERANCE_PX`]).
    tolerance: f64,
    maps: Vec<&'a mut [[f32; 2]]>,
    counts: &'a mut [u8],
    found: Vec<(usize, Point2<f64>)>,
}

impl Band<'_> {
    /// Sets camera `k`'s position of canvas pixel (`c`, `r`) when it lies
    /// in the image with its right and lower neighbours (for the bilinear
    /// sample) and the pixel has none yet.
    fn put(&mut self, c: usize, r: usize, k: usize, x: f64, y: f64) {
        let Some(&(iw, ih)) = self.sources.get(k) else {
            return;
        };
        let i = (r - self.row0) * self.w + c;
        if x >= 0.0
            && y >= 0.0
            && x <= iw as f64 - 1.0
            && y <= ih as f64 - 1.0
            && self.maps[k][i][0] < 0.0
        {
            self.maps[k][i] = [x as f32, y as f32];
            self.counts[i] += 1;
        }
    }

    /// Maps canvas pixel (`c`, `r`) exactly.
    fn exact<L>(&mut self, locate: &L, c: usize, r: usize)
    where
        L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>),
    {
        let mut found = std::mem::take(&mut self.found);
        found.clear();
        locate(c, r, &mut found);
        for &(k, px) in &found {
            self.put(c, r, k, px.x, px.y);
        }
        self.found = found;
    }

    /// Maps the cell rows `ta .. tb` of the grid (`xs`, `ys`; `cell_rows`
    /// in all): see the module documentation.
    fn interpolate<L>(
        &mut self,
        locate: &L,
        xs: &[usize],
        ys: &[usize],
        (ta, tb): (usize, usize),
        cell_rows: usize,
    ) where
        L: Fn(usize, usize, &mut Vec<(usize, Point2<f64>)>),
    {
        let n = self.sources.len();
        let nx = xs.len();
        // Per node of rows ta ..= tb, per camera, its position (NaN where
        // the camera does not show it).
        let mut node = vec![[f64::NAN; 2]; (tb - ta + 1) * nx * n];
        for (dt, &r) in ys[ta..=tb].iter().enumerate() {
            for (s, &c) in xs.iter().enumerate() {
                self.found.clear();
                locate(c, r, &mut self.found);
                let at = (dt * nx + s) * n;
                for &(k, px) in &self.found {
                    if k < n && node[at + k][0].is_nan() {
                        node[at + k] = [px.x, px.y];
                    }
                }
            }
        }
        let mut corners = Vec::with_capacity(n);
        let mut errors: Vec<[f64; 2]> = Vec::with_capacity(n);
        for t in ta..tb {
            let (y0, y1) = (ys[t], ys[t + 1]);
            let y_end = if t + 1 == cell_rows { y1 + 1 } else { y1 };
            for s in 0..nx - 1 {
                let (x0, x1) = (xs[s], xs[s + 1]);
                let x_end = if s + 2 == nx { x1 + 1 } else { x1 };
                let at =
                    |dt: usize, ds: usize, k: usize| node[((t + dt - ta) * nx + s + ds) * n + k];
                // The cameras at all four corners; none at only some.
                corners.clear();
                let mut smooth = true;
                for k in 0..n {
                    let shown = [at(0, 0, k), at(0, 1, k), at(1, 0, k), at(1, 1, k)]
                        .map(|p| !p[0].is_nan());
                    if shown.iter().all(|&v| v) {
                        corners.push((k, [at(0, 0, k), at(0, 1, k), at(1, 0, k), at(1, 1, k)]));
                    } else if shown.iter().any(|&v| v) {
                        smooth = false;
                    }
                }
                let lerp = |p: &[[f64; 2]; 4], u: f64, v: f64| {
                    let [a, b, c, d] = p;
                    std::array::from_fn::<f64, 2, _>(|e| {
                        (1.0 - v) * ((1.0 - u) * a[e] + u * b[e])
                            + v * ((1.0 - u) * c[e] + u * d[e])
                    })
                };
                let (dx, dy) = ((x1 - x0) as f64, (y1 - y0) as f64);
                if smooth {
                    // The error of the interpolation at the middle of the
                    // top and the left edge and at the centre, exactly.
                    let (cx, cy) = ((x0 + x1) / 2, (y0 + y1) / 2);
                    errors.clear();
                    errors.resize(corners.len(), [0.0; 2]);
                    for (probe, (c, r)) in [(cx, y0), (x0, cy), (cx, cy)].into_iter().enumerate() {
                        self.found.clear();
                        locate(c, r, &mut self.found);
                        let (u, v) = ((c - x0) as f64 / dx, (r - y0) as f64 / dy);
                        smooth &= self.found.len() == corners.len()
                            && self.found.iter().all(|(k, px)| {
                                corners.iter().zip(errors.iter_mut()).any(|((m, p), e)| {
                                    if m != k {
                                        return false;
                                    }
                                    let q = lerp(p, u, v);
                                    e[usize::from(probe == 2)] += (q[0] - px.x).hypot(q[1] - px.y);
                                    true
                                })
                            });
                        if !smooth {
                            break;
                        }
                    }
                    smooth &= errors
                        .iter()
                        .all(|e| e[0] <= self.tolerance && e[1] <= self.tolerance);
                }
                for r in y0..y_end {
                    for c in x0..x_end {
                        if smooth {
                            let (u, v) = ((c - x0) as f64 / dx, (r - y0) as f64 / dy);
                            for (k, p) in &corners {
                                let [x, y] = lerp(p, u, v);
                                self.put(c, r, *k, x, y);
                            }
                        } else {
                            self.exact(locate, c, r);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::MAP_GRID;
    use crate::panorama::{CylinderSpec, Panorama, PanoramaOptions};
    use crate::surround::{CanvasSpec, Mosaic, SurroundOptions, SurroundView};

    /// Camera `k`'s source position at canvas pixel (`c`, `r`), if any.
    fn at(m: &Mosaic, k: usize, c: usize, r: usize) -> Option<[f32; 2]> {
        let layer = &m.layers()[k];
        let [c0, r0, rw, rh] = layer.roi;
        if c < c0 || r < r0 || c >= c0 + rw || r >= r0 + rh {
            return None;
        }
        let p = layer.map[(r - r0) * rw + (c - c0)];
        (p[0] >= 0.0).then_some(p)
    }

    /// The largest distance (source pixels) between the two mosaics' maps
    /// where both show a pixel, and the pixels only one shows, each with
    /// how far the exact position lies inside the image's usable part.
    fn compare(approx: &Mosaic, exact: &Mosaic) -> (f64, usize, f64) {
        let (w, h) = exact.size();
        assert_eq!(approx.size(), (w, h));
        let (mut worst, mut differ, mut inside) = (0.0f64, 0, 0.0f64);
        for (k, layer) in exact.layers().iter().enumerate() {
            let (sw, sh) = layer.source;
            for r in 0..h {
                for c in 0..w {
                    match (at(approx, k, c, r), at(exact, k, c, r)) {
                        (Some(a), Some(e)) => {
                            let d = f64::from(a[0] - e[0]).hypot(f64::from(a[1] - e[1]));
                            worst = worst.max(d);
                        }
                        (None, None) => {}
                        (a, e) => {
                            differ += 1;
                            // Only at the image's edge: the exact position
                            // (or the interpolated one) within a hair of it.
                            let p = e.or(a).unwrap_or([0.0, 0.0]);
                            let margin = f64::from(p[0])
                                .min(f64::from(p[1]))
                                .min(sw as f64 - 1.0 - f64::from(p[0]))
                                .min(sh as f64 - 1.0 - f64::from(p[1]))
                                .abs();
                            inside = inside.max(margin);
                        }
                    }
                }
            }
        }
        (worst, differ, inside)
    }

    fn rig() -> rigview_calib::Rig {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz");
        rigview_calib::formats::load(&data, None, None).unwrap().rig
    }

    /// Checks the default build against the exact one (grid 1): the maps
    /// within 0.05 source pixels, and the source masks.
    fn check(what: &str, approx: &Mosaic, exact: &Mosaic) {
        let (worst, differ, margin) = compare(approx, exact);
        eprintln!("{what}: worst {worst:.4} px, {differ} pixels differ in coverage, within {margin:.4} px of the image's edge");
        assert!(worst <= 0.05, "{what}: {worst} px");
        assert!(
            differ == 0 || margin <= 0.05,
            "{what}: {differ} pixels, {margin} px"
        );
        // The source masks (whose samples land on canvas pixels through
        // interpolated positions) differ only where a sample lands within
        // a hair of a pixel's edge: on at most 0.1 % of each camera's
        // masked pixels.
        for (k, (a, e)) in approx.masks().iter().zip(exact.masks()).enumerate() {
            let (mut differ, mut set) = (0, 0);
            for y in 0..e.height() {
                for (x, y) in a.row(y).iter().zip(e.row(y)) {
                    differ += usize::from(x != y);
                    set += usize::from(*y > 0);
                }
            }
            eprintln!("{what}: camera {k}: the masks differ on {differ} of {set} pixels");
            assert!(
                set > 0 && differ * 1000 <= set,
                "{what}: camera {k}: {differ} of {set}"
            );
        }
    }

    #[test]
    fn interpolated_maps_stay_within_a_twentieth_of_a_pixel_of_the_exact_ones() {
        let rig = rig();
        let spec = CanvasSpec::around_car_16x12(100.0);
        let options = SurroundOptions::default();
        let build = |grid| SurroundView::build_on_grid(&rig, &spec, &options, grid).unwrap();
        check("surround view", &build(MAP_GRID), &build(1));
        let cylinder = CylinderSpec {
            width: 4096,
            height: 1024,
            ..CylinderSpec::default()
        };
        let options = PanoramaOptions::default();
        let build = |grid| Panorama::build_on_grid(&rig, &cylinder, &options, grid).unwrap();
        check("panorama", &build(MAP_GRID), &build(1));
    }
}
