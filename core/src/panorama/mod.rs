//! The cylindrical panorama: the surroundings of the vehicle on a cylinder
//! around its vertical axis, composed from every camera of a calibrated rig
//! with the same machinery as the surround view (a [`Mosaic`]: maps, blend
//! weights, the fixed-point remap plans and kernels).
//!
//! # The cylinder
//!
//! The cylinder's axis is the vertical (z) line through the centroid `o` of
//! the cameras' positions; its radius is `R` ([`CylinderSpec::radius_m`],
//! 10 m by default). The canvas unrolls it over 360° of azimuth `φ`
//! (from the x axis, towards y: 0 straight ahead, 90° to the left) and over
//! a band of elevations seen from the axis at the centroid's height, from
//! `below_deg` under the horizon to `above_deg` over it. Column `c` and row
//! `r` (pixel centres at +½) show the point
//!
//! ```text
//! φ = π − 2π·c/W,    t = tan(above) − (r/H)·(tan(above) + tan(below)),
//! p = o + (R cos φ, R sin φ, R t)
//! ```
//!
//! so that the front is in the middle, the left side left of it, and the
//! back at both ends; rows are linear in `tan`, as on a cylinder. With a
//! floor ([`CylinderSpec::floor`]) a row below the horizon whose ray from
//! `o` meets the ground (z = 0) nearer than `R` shows that point of the
//! ground instead: the surface is a bowl, and what lies on the ground
//! lines up across the seams at any distance. Each
//! canvas pixel is that 3-D point projected into the cameras with their
//! full pose (translation included). The cameras stand metres apart, so a
//! single cylinder cannot show the whole scene without parallax: what
//! stands at distance `R` from the axis lines up across a seam, what is
//! nearer or farther is doubled or cut in the overlaps, the more the nearer
//! it is and the farther apart the two cameras are.
//!
//! # Who shows what
//!
//! Fisheye cameras see far more than their share of the cylinder, and the
//! blend weights need each camera's exclusive region. A camera shows the
//! azimuths around its optical axis's heading: at azimuth `φ`, camera `k`
//! with heading `ψ_k` is used where `|φ − ψ_k| − min_m |φ − ψ_m| ≤ overlap`
//! ([`PanoramaOptions::overlap_deg`]; angles wrapped to ±180°): for four
//! cameras 90° apart, each shows ±(45° + overlap/2) around its heading, and
//! neighbours overlap by `overlap` degrees. The blend weights, the three
//! blend modes, the masks and the overlap patches are the surround view's
//! (see [`crate::surround`]). The source masks hold the pixels whose ray
//! meets the cylinder on a canvas pixel the camera contributes to: the
//! whole image that reaches the panorama is metered.

mod matching;
mod refine;
mod rounds;

use std::sync::OnceLock;

use nalgebra::{Point2, Vector3};
use serde::{Deserialize, Serialize};

use rigview_calib::rig::{CameraProjector, Rig};

use crate::error::{check_range, Error, Result};
use crate::image::RoiMask;
use crate::surround::{grid, mosaic};
use crate::surround::{Mosaic, Overlap, Plan};

pub use matching::{Detector, FeatureMatch, MatchOptions, MatchTimes, OverlapBand, PairMatches};
pub use refine::{InlierRays, PairRefinement, RefineOptions, Refinement};
pub use rounds::{
    matching_spec, refine_in_rounds, Rounds, RoundsOptions, MATCH_WIDTH, MAX_ROUNDS,
    POOL_WITHIN_DEG, WORSE_PX,
};

/// The cylinder a panorama shows, and its canvas.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CylinderSpec {
    /// Canvas width, pixels (360° of azimuth).
    pub width: usize,
    /// Canvas height, pixels (the elevation band).
    pub height: usize,
    /// The cylinder's radius, metres: what stands this far from the axis
    /// lines up across the seams.
    pub radius_m: f64,
    /// The lowest elevation shown, degrees below the horizon.
    pub below_deg: f64,
    /// The highest elevation shown, degrees above the horizon.
    pub above_deg: f64,
    /// Whether the surface has a floor: the ground (z = 0) inside the
    /// cylinder, where a row below the horizon meets it nearer than the
    /// radius (a bowl); otherwise the cylinder alone.
    #[serde(default)]
    pub floor: bool,
}

impl Default for CylinderSpec {
    /// 4096 × 760 pixels (square pixels: 0.088° of azimuth each), radius
    /// 10 m, from 25° below the horizon to 35° above it.
    fn default() -> Self {
        Self {
            width: 4096,
            height: 760,
            radius_m: 10.0,
            below_deg: 25.0,
            above_deg: 35.0,
            floor: false,
        }
    }
}

/// The largest canvas side, pixels.
const MAX_SIDE: usize = 16384;

impl CylinderSpec {
    /// Checks the spec: a canvas of 8 to 16384 pixels a side, a finite
    /// radius of 0.5 to 10⁴ m, and a band within ±80° that is not empty.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("panorama.width", self.width),
            ("panorama.height", self.height),
        ] {
            if !(8..=MAX_SIDE).contains(&v) {
                return Err(Error::InvalidParameter {
                    name,
                    value: v as f64,
                    expected: "8 to 16384 pixels",
                });
            }
        }
        check_range(
            "panorama.radius_m",
            self.radius_m,
            0.5,
            1e4,
            "a radius of 0.5 to 10000 m",
        )?;
        check_range(
            "panorama.below_deg",
            self.below_deg,
            -80.0,
            80.0,
            "an angle of −80° to 80° below the horizon",
        )?;
        check_range(
            "panorama.above_deg",
            self.above_deg,
            -80.0,
            80.0,
            "an angle of −80° to 80° above the horizon",
        )?;
        if self.above_deg + self.below_deg < 1.0 {
            return Err(Error::invalid(
                "panorama",
                "band",
                "at least 1° of elevation",
                format_args!(
                    "{}° below to {}° above the horizon, which is empty",
                    self.below_deg, self.above_deg
                ),
            ));
        }
        Ok(())
    }

    /// `tan` of the top and of the bottom of the band.
    fn tan_band(&self) -> (f64, f64) {
        (
            self.above_deg.to_radians().tan(),
            -self.below_deg.to_radians().tan(),
        )
    }

    /// The azimuth (radians, in (−π, π]) of canvas column position `col`.
    pub fn azimuth(&self, col: f64) -> f64 {
        std::f64::consts::PI - std::f64::consts::TAU * col / self.width as f64
    }

    /// The height over the horizon per metre from the axis (`tan` of the
    /// elevation) of canvas row position `row`.
    pub fn slope(&self, row: f64) -> f64 {
        let (top, bottom) = self.tan_band();
        top - row / self.height as f64 * (top - bottom)
    }

    /// The canvas position (column in `[0, width)`, row) of a direction
    /// seen from the axis: azimuth `phi` (radians) and slope `t`.
    pub fn canvas(&self, phi: f64, t: f64) -> (f64, f64) {
        let (top, bottom) = self.tan_band();
        let w = self.width as f64;
        let col = ((std::f64::consts::PI - phi) / std::f64::consts::TAU * w).rem_euclid(w);
        (col, (top - t) / (top - bottom) * self.height as f64)
    }
}

/// Options of [`Panorama::build`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PanoramaOptions {
    /// How far (degrees of azimuth) a camera reaches past the half-way
    /// heading to its neighbour's: the width of each overlap for cameras
    /// spread evenly.
    pub overlap_deg: f64,
    /// Side of an overlap patch, canvas pixels.
    pub patch_px: usize,
    /// The fraction of a patch's canvas pixels that both cameras must show.
    pub patch_coverage: f64,
    /// The source masks are computed on every `mask_step`-th source pixel
    /// (4 by default: the metering's own resolution at its default size,
    /// 320 of 1288 columns, where a metered pixel counts if half its block
    /// is in the mask).
    pub mask_step: usize,
}

impl Default for PanoramaOptions {
    fn default() -> Self {
        Self {
            overlap_deg: 30.0,
            patch_px: 16,
            patch_coverage: 0.9,
            mask_step: 4,
        }
    }
}

impl PanoramaOptions {
    fn validate(&self) -> Result<()> {
        check_range(
            "panorama.overlap_deg",
            self.overlap_deg,
            0.0,
            180.0,
            "0° to 180°",
        )?;
        if !(2..=256).contains(&self.patch_px) {
            return Err(Error::InvalidParameter {
                name: "panorama.patch_px",
                value: self.patch_px as f64,
                expected: "a patch side of 2 to 256 canvas pixels",
            });
        }
        mosaic::check_sampling(
            ("panorama.patch_coverage", self.patch_coverage),
            ("panorama.mask_step", self.mask_step),
        )
    }
}

/// The panorama of one rig and cylinder, built once per calibration: a
/// [`Mosaic`] on the cylinder (it derefs to it), the source masks and the
/// overlaps of the rig's neighbour pairs.
#[derive(Debug)]
pub struct Panorama {
    spec: CylinderSpec,
    centre: Vector3<f64>,
    /// Per camera, its centre (vehicle frame).
    origins: Vec<Vector3<f64>>,
    headings: Vec<f64>,
    mosaic: Mosaic,
    /// Per overlap, its band of the canvas.
    bands: Vec<OverlapBand>,
    /// Per band, the plans warping each of its cameras into it, built on
    /// first use.
    band_plans: Vec<OnceLock<[Option<Plan>; 2]>>,
}

impl std::ops::Deref for Panorama {
    type Target = Mosaic;

    fn deref(&self) -> &Mosaic {
        &self.mosaic
    }
}

/// `a − b` wrapped to (−π, π].
fn wrap(a: f64) -> f64 {
    let t = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU);
    t - std::f64::consts::PI
}

impl Panorama {
    /// Builds the panorama of `rig` (poses in the vehicle frame) on `spec`.
    pub fn build(rig: &Rig, spec: &CylinderSpec, options: &PanoramaOptions) -> Result<Self> {
        Self::build_on_grid(rig, spec, options, grid::MAP_GRID)
    }

    /// [`Panorama::build`] with the maps interpolated on a grid of `grid`
    /// pixels (1: every pixel projected exactly).
    pub(crate) fn build_on_grid(
        rig: &Rig,
        spec: &CylinderSpec,
        options: &PanoramaOptions,
        grid: usize,
    ) -> Result<Self> {
        spec.validate()?;
        options.validate()?;
        let what = "panorama";
        let cameras = mosaic::vehicle_cameras(rig, what)?;
        let projectors = &cameras.projectors;
        let n = projectors.len();
        let centre = projectors
            .iter()
            .map(|p| *p.pose().translation())
            .sum::<Vector3<f64>>()
            / n as f64;
        let headings: Vec<f64> = projectors
            .iter()
            .map(|p| {
                let axis = p.pose().optical_axis();
                axis.y.atan2(axis.x)
            })
            .collect();
        let (w, h) = (spec.width, spec.height);
        // Per column, the direction and the cameras that show it; per row,
        // the slope.
        let reach = options.overlap_deg.to_radians();
        let columns: Vec<(f64, f64, Vec<usize>)> = (0..w)
            .map(|c| {
                let phi = spec.azimuth(c as f64 + 0.5);
                let off: Vec<f64> = headings.iter().map(|&psi| wrap(phi - psi).abs()).collect();
                let nearest = off.iter().copied().fold(f64::INFINITY, f64::min);
                let shows = (0..n).filter(|&k| off[k] - nearest <= reach + 1e-12);
                let (s, co) = phi.sin_cos();
                (co, s, shows.collect())
            })
            .collect();
        let slopes: Vec<f64> = (0..h).map(|r| spec.slope(r as f64 + 0.5)).collect();
        let radius = spec.radius_m;
        let surface = Surface {
            centre,
            radius,
            floor: spec.floor,
        };
        let (mut mosaic, maps) = Mosaic::build(
            what,
            (w, h),
            &cameras.sources,
            (grid, grid::MAP_TOLERANCE_PX),
            |c, r, found| {
                let (co, s, shows) = &columns[c];
                let p = surface.point(*co, *s, slopes[r]);
                for &k in shows {
                    if let Some(px) = projectors[k].project_rig(&p) {
                        found.push((k, px));
                    }
                }
            },
            |k| {
                Some(Error::invalid(
                    "panorama",
                    format!("camera `{}`'s view of the cylinder", cameras.sources[k].0),
                    "a camera looking outwards",
                    format_args!(
                        "none of it (radius {} m, {}° below to {}° above the horizon, azimuths within {:.0}° of its heading {:.1}°)",
                        spec.radius_m,
                        spec.below_deg,
                        spec.above_deg,
                        options.overlap_deg,
                        headings[k].to_degrees()
                    ),
                ))
            },
        )?;
        let masks =
            mosaic::source_masks(&mosaic, projectors, (options.mask_step, grid), |p, px| {
                let (o, d) = p.ray_rig(px)?;
                let q = surface.hit(&o, &d)?;
                Some(spec.canvas(q.y.atan2(q.x), q.z / q.x.hypot(q.y)))
            })?;
        let overlaps = mosaic::overlaps(
            &maps,
            mosaic.layers(),
            (w, h),
            &rig.neighbours,
            options.patch_px,
            options.patch_coverage,
            |c, _| {
                let phi = spec.azimuth(c);
                (centre.x + radius * phi.cos(), centre.y + radius * phi.sin())
            },
        );
        check_overlaps(&mosaic, &overlaps)?;
        let bands: Vec<OverlapBand> = matching::bands(
            (w, h),
            |k, p| maps.sees(k, p),
            |i, j| mosaic::shared_rect(mosaic.layers(), i, j),
            &rig.neighbours,
        )
        .into_iter()
        .flatten()
        .collect();
        mosaic.set_regions(masks, overlaps);
        Ok(Self {
            spec: spec.clone(),
            centre,
            origins: projectors.iter().map(|p| *p.pose().translation()).collect(),
            headings,
            mosaic,
            band_plans: bands.iter().map(|_| OnceLock::new()).collect(),
            bands,
        })
    }

    /// The cylinder and canvas.
    pub fn spec(&self) -> &CylinderSpec {
        &self.spec
    }

    /// The point on the cylinder's axis at the horizon (the centroid of the
    /// cameras), vehicle frame.
    pub fn centre(&self) -> Vector3<f64> {
        self.centre
    }

    /// Each camera's heading (the azimuth of its optical axis), radians.
    pub fn headings(&self) -> &[f64] {
        &self.headings
    }

    /// The mosaic: the cameras' maps, weights and plans on the canvas.
    pub fn mosaic(&self) -> &Mosaic {
        &self.mosaic
    }

    /// The 3-D point (vehicle frame) that canvas position (`col`, `row`)
    /// shows.
    pub fn point(&self, col: f64, row: f64) -> Vector3<f64> {
        let phi = self.spec.azimuth(col);
        self.surface()
            .point(phi.cos(), phi.sin(), self.spec.slope(row))
    }

    fn surface(&self) -> Surface {
        Surface {
            centre: self.centre,
            radius: self.spec.radius_m,
            floor: self.spec.floor,
        }
    }

    /// The canvas position of a 3-D point (vehicle frame) as seen from the
    /// axis, or `None` on the axis.
    pub fn canvas_of(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        let q = p - self.centre;
        let rho = q.x.hypot(q.y);
        (rho > 1e-9).then(|| self.spec.canvas(q.y.atan2(q.x), q.z / rho))
    }

    /// Where camera `projector`'s pixel `px` lands on the canvas (its ray
    /// meets the cylinder), or `None`.
    pub fn canvas_of_pixel(
        &self,
        projector: &CameraProjector,
        px: &Point2<f64>,
    ) -> Option<(f64, f64)> {
        let (o, d) = projector.ray_rig(px)?;
        let q = self.surface().hit(&o, &d)?;
        Some(self.spec.canvas(q.y.atan2(q.x), q.z / q.x.hypot(q.y)))
    }

    /// Each camera's source mask (the pixels that reach the panorama), in
    /// rig order: meter these.
    pub fn source_masks(&self) -> &[RoiMask] {
        self.mosaic.masks()
    }
}

/// The surface the canvas shows: the cylinder of `radius` around the
/// vertical through `centre`, and with `floor` the ground (z = 0) inside it.
#[derive(Clone, Copy, Debug)]
struct Surface {
    centre: Vector3<f64>,
    radius: f64,
    floor: bool,
}

impl Surface {
    /// The point of the surface seen from the centre in the direction of
    /// azimuth cosine and sine (`co`, `si`) and slope `t`.
    fn point(&self, co: f64, si: f64, t: f64) -> Vector3<f64> {
        let h = self.centre.z;
        // The floor: where the centre's ray meets the ground nearer than
        // the radius.
        if self.floor && h > 0.0 && t < 0.0 && -h / t < self.radius {
            let rho = -h / t;
            return self.centre + Vector3::new(rho * co, rho * si, -h);
        }
        self.centre + self.radius * Vector3::new(co, si, t)
    }

    /// Where the ray `o + s·d` (vehicle frame, `o` inside the cylinder)
    /// meets the surface, relative to the centre.
    fn hit(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<Vector3<f64>> {
        let rel = o - self.centre;
        let h = self.centre.z;
        if self.floor && h > 0.0 && d.z < 0.0 && o.z > 0.0 {
            let q = rel + d * (-o.z / d.z);
            if q.x.hypot(q.y) < self.radius {
                return Some(q);
            }
        }
        cylinder_hit(&rel, d, self.radius)
    }
}

/// Where the ray `o + s·d` (`o` relative to a point of the axis, inside the
/// cylinder) meets the vertical cylinder of radius `r` around the axis, for
/// `s > 0`; relative to the same point.
fn cylinder_hit(o: &Vector3<f64>, d: &Vector3<f64>, r: f64) -> Option<Vector3<f64>> {
    let a = d.x * d.x + d.y * d.y;
    if a < 1e-12 {
        return None;
    }
    let b = 2.0 * (o.x * d.x + o.y * d.y);
    let c = o.x * o.x + o.y * o.y - r * r;
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let s = (-b + disc.sqrt()) / (2.0 * a);
    (s > 0.0).then(|| o + d * s)
}

/// A rig whose neighbours share no canvas pixel cannot be stitched: the
/// error names the first such pair.
fn check_overlaps(mosaic: &Mosaic, overlaps: &[Overlap]) -> Result<()> {
    if let Some(o) = overlaps.iter().find(|o| o.pixels == 0) {
        let name = |k: usize| mosaic.layers().get(k).map_or("?", |l| l.name.as_str());
        return Err(Error::invalid(
            "panorama",
            format!("neighbours `{}` and `{}`", name(o.i), name(o.j)),
            "overlapping views (check their poses and the panorama's band)",
            "views that share no pixel of the cylinder",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
