//! The 3-D surround view: the cameras' pictures on a bowl around the
//! vehicle, seen from a viewpoint an operator chooses or moves, with a
//! model of the vehicle in the middle.
//!
//! # The bowl
//!
//! A [`BowlSpec`] is a height field over the ground (vehicle frame: x
//! forward, y left, z up, metres): flat within `flat_m` of the vehicle
//! (its rectangle for the rounded-rectangle footprint, its centre for the
//! round one), then a wall rising as `wall_height_m · u^steepness`, with
//! `u` going from 0 at `flat_m` to 1 at `radius_m`, where the bowl ends.
//! Near the vehicle the ground is where it is, as in the bird's-eye view;
//! further out, what stands up (cars, posts, walls) lands on the wall
//! instead of being smeared across the ground.
//!
//! # A fixed viewpoint is a remap
//!
//! [`BowlView::build`] casts the ray of every pixel of the viewpoint's
//! pinhole image ([`Viewpoint::camera`]) onto the bowl and projects the
//! point it meets into every camera through its calibration (any lens
//! model, full pose). Which cameras may show a point is the bird's-eye
//! view's rule (the side of the vehicle's rectangle the point lies beyond:
//! [`crate::surround`]), so the seams fall where they fall there and the
//! blend weights come from the same distance to each camera's exclusive
//! region. The result is a [`Mosaic`]: the same maps, weights, plans and
//! kernels as the other views compose it, with the same display gains.
//! The vehicle model ([`VehicleModel`]) is ray cast once per viewpoint
//! into an overlay with smooth edges (2 × 2 samples a pixel), painted over
//! the composed picture by [`BowlView::paint_vehicle`]; its shadow covers
//! the ground under the vehicle, which no camera sees.
//!
//! The bowl shows; it does not meter or balance. The exposure control of a
//! bowl session keeps the bird's-eye view's ground masks and overlap
//! patches (see [`crate::pipeline::View`]), so moving the viewpoint never
//! changes what the cameras are balanced on.

mod gpu;
mod mesh;
mod plan;
mod surface;
mod vehicle;
mod viewpoint;

#[cfg(test)]
mod tests;

use std::sync::Arc;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use rigview_calib::rig::Rig;

pub use gpu::{SurfaceMesh, SurfaceVertex, VehicleTriangles, MAX_GPU_CAMERAS};
pub use mesh::Mesh;
pub use plan::GroundPlan;
pub use vehicle::{VehicleHit, VehicleModel};
pub use viewpoint::{Viewpoint, VirtualCamera, PRESETS};

use crate::error::{check_range, Error, Result};
use crate::surround::mosaic::{self, Mosaic};
use crate::surround::{grid, Canvas, CanvasSpec, Side};

/// The bowl's footprint: how the distance from the vehicle is measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Footprint {
    /// From the vehicle's rectangle: a rounded rectangle that follows the
    /// vehicle's shape.
    #[default]
    RoundedRectangle,
    /// From the vehicle's centre: a circle.
    Round,
}

/// The bowl, the vehicle in it, and the size of the picture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BowlSpec {
    /// Extent of the flat ground beyond the vehicle (its rectangle, or its
    /// centre for a round footprint), metres.
    pub flat_m: f64,
    /// Where the wall ends, measured the same way, metres.
    pub radius_m: f64,
    /// The wall's height at `radius_m`, metres.
    pub wall_height_m: f64,
    /// The exponent of the wall's curve (1: a cone; larger: flatter near
    /// the ground, steeper at the rim).
    pub steepness: f64,
    /// How distance from the vehicle is measured.
    pub footprint: Footprint,
    /// The vehicle's rectangle on the ground: `[x_min, x_max, y_min,
    /// y_max]`, metres.
    pub vehicle_m: [f64; 4],
    /// The vehicle model's height, metres.
    pub vehicle_height_m: f64,
    /// A vehicle model to show instead of the built-in one: glTF 2.0
    /// (`.gltf`, `.glb`; front along +z) or Wavefront OBJ (front along
    /// −z); y up, scaled onto the vehicle's box ([`Mesh::load`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle_model: Option<std::path::PathBuf>,
    /// The picture's width and height, pixels.
    pub size_px: [usize; 2],
}

impl Default for BowlSpec {
    /// The bowl around the default bird's-eye canvas: flat as far as that
    /// canvas reaches ahead of and behind the vehicle, a 4 m wall at 12 m,
    /// a 1280 × 800 picture.
    fn default() -> Self {
        Self::around(&CanvasSpec::default())
    }
}

/// The largest picture side, pixels.
const MAX_SIDE: usize = 8192;

/// How far (source pixels) the interpolated maps of the bowl may stray
/// from the exact ones: the bowl is shown, not measured on, and a tenth
/// of a pixel is not seen; the views that are measured on keep
/// [`grid::MAP_TOLERANCE_PX`]. It lets four of five cells of the picture
/// be interpolated rather than cast pixel by pixel.
const MAP_TOLERANCE_PX: f64 = 0.1;

impl BowlSpec {
    /// The bowl around `canvas`'s vehicle, flat as far as the canvas
    /// reaches from it (the nearer of its ends and sides).
    pub fn around(canvas: &CanvasSpec) -> Self {
        let [x0, x1, y0, y1] = canvas.vehicle_m;
        let reach = (x0 - canvas.x_min_m)
            .min(canvas.x_max_m - x1)
            .min(y0 - canvas.y_min_m)
            .min(canvas.y_max_m - y1)
            .max(0.5);
        Self {
            flat_m: reach,
            radius_m: 12.0,
            wall_height_m: 4.0,
            steepness: 2.0,
            footprint: Footprint::RoundedRectangle,
            vehicle_m: canvas.vehicle_m,
            vehicle_height_m: 1.5,
            vehicle_model: None,
            size_px: [1280, 800],
        }
    }

    /// Checks the spec; errors name the field.
    pub fn validate(&self) -> Result<()> {
        check_range("bowl.flat_m", self.flat_m, 0.0, 1e3, "0 to 1000 m")?;
        check_range(
            "bowl.radius_m",
            self.radius_m,
            self.flat_m + 0.1,
            1e3,
            "at least 0.1 m beyond bowl.flat_m, and at most 1000 m",
        )?;
        check_range(
            "bowl.wall_height_m",
            self.wall_height_m,
            0.0,
            1e3,
            "0 to 1000 m",
        )?;
        check_range("bowl.steepness", self.steepness, 0.5, 8.0, "0.5 to 8")?;
        check_range(
            "bowl.vehicle_height_m",
            self.vehicle_height_m,
            0.2,
            10.0,
            "0.2 to 10 m",
        )?;
        let [x0, x1, y0, y1] = self.vehicle_m;
        for v in self.vehicle_m {
            check_range("bowl.vehicle_m", v, -1e3, 1e3, "within 1 km")?;
        }
        if x0 >= x1 || y0 >= y1 {
            return Err(Error::invalid(
                "bowl view",
                "bowl.vehicle_m",
                "[x_min, x_max, y_min, y_max] with min < max",
                format_args!("{:?}", self.vehicle_m),
            ));
        }
        let [w, h] = self.size_px;
        if !(16..=MAX_SIDE).contains(&w) || !(16..=MAX_SIDE).contains(&h) {
            return Err(Error::invalid(
                "bowl view",
                "bowl.size_px",
                format!("16 to {MAX_SIDE} pixels a side"),
                format_args!("{w}×{h}"),
            ));
        }
        Ok(())
    }
}

/// The bowl seen from one viewpoint: the cameras' mosaic on the picture
/// and the vehicle's overlay.
#[derive(Debug)]
pub struct BowlView {
    spec: BowlSpec,
    viewpoint: Viewpoint,
    camera: VirtualCamera,
    mosaic: Mosaic,
    /// The pixels the vehicle model covers: index and RGBA.
    vehicle: Vec<(u32, [u8; 4])>,
    /// A user's vehicle model, as loaded (for the next viewpoint).
    mesh: Option<Arc<Mesh>>,
    /// The ground plan the blend distances are measured on (for the next
    /// viewpoint, and the GPU's mesh).
    plan: Arc<GroundPlan>,
}

impl BowlView {
    /// Builds the bowl view of `rig` (poses in the vehicle frame) from
    /// `viewpoint`.
    pub fn build(rig: &Rig, spec: &BowlSpec, viewpoint: &Viewpoint) -> Result<Self> {
        Self::build_after(rig, spec, viewpoint, false, None)
    }

    /// [`BowlView::build`] for a picture shown while the viewpoint moves:
    /// the maps interpolated where they err by up to half a source pixel
    /// (about twice as fast).
    pub fn build_preview(rig: &Rig, spec: &BowlSpec, viewpoint: &Viewpoint) -> Result<Self> {
        Self::build_after(rig, spec, viewpoint, true, None)
    }

    /// [`BowlView::build`] (or [`BowlView::build_preview`]) of the next
    /// viewpoint after `previous` (of the same rig): a user's vehicle
    /// model it loaded for the same file and box is used again rather than
    /// read again, and its ground plan for the same surface.
    pub fn build_after(
        rig: &Rig,
        spec: &BowlSpec,
        viewpoint: &Viewpoint,
        preview: bool,
        previous: Option<&BowlView>,
    ) -> Result<Self> {
        let tolerance = if preview { 0.5 } else { MAP_TOLERANCE_PX };
        let same_vehicle = |p: &&BowlView| {
            (
                &p.spec.vehicle_model,
                p.spec.vehicle_m,
                p.spec.vehicle_height_m,
            ) == (&spec.vehicle_model, spec.vehicle_m, spec.vehicle_height_m)
        };
        let mesh = match previous.filter(same_vehicle).and_then(|p| p.mesh.clone()) {
            Some(m) => Some(m),
            None => spec
                .vehicle_model
                .as_deref()
                .map(|p| Mesh::load(p, spec.vehicle_m, spec.vehicle_height_m).map(Arc::new))
                .transpose()?,
        };
        let plan = match previous.filter(|p| p.plan.serves(spec)) {
            Some(p) => p.plan.clone(),
            None => Arc::new(GroundPlan::build(rig, spec)?),
        };
        Self::build_on_grid(
            rig,
            spec,
            viewpoint,
            (grid::MAP_GRID, tolerance),
            mesh,
            plan,
        )
    }

    /// [`BowlView::build`] with the maps interpolated on a grid of `grid`
    /// pixels where that errs by at most `tolerance` source pixels (a grid
    /// of 1: every pixel cast exactly).
    pub(crate) fn build_on_grid(
        rig: &Rig,
        spec: &BowlSpec,
        viewpoint: &Viewpoint,
        (grid, tolerance): (usize, f64),
        mesh: Option<Arc<Mesh>>,
        plan: Arc<GroundPlan>,
    ) -> Result<Self> {
        spec.validate()?;
        viewpoint.validate()?;
        let what = "bowl view";
        let cameras = mosaic::vehicle_cameras(rig, what)?;
        let [w, h] = spec.size_px;
        let camera = viewpoint.camera(w, h);
        let sides = Side::of_cameras(&cameras.projectors);
        let projectors = &cameras.projectors;
        let on_plan = projectors.len();
        let (mut mosaic, _) = Mosaic::build_on_surface(
            what,
            (w, h),
            &cameras.sources,
            (grid, tolerance),
            |c, r, found| {
                let ray = camera.ray(c as f64 + 0.5, r as f64 + 0.5);
                let Some(p) = spec.intersect(&camera.eye, &ray) else {
                    return;
                };
                for (k, projector) in projectors.iter().enumerate() {
                    if sides[k].beyond(&spec.vehicle_m, p.x, p.y) {
                        if let Some(px) = projector.project_rig(&p) {
                            found.push((k, px));
                        }
                    }
                }
                found.push((on_plan, plan.position(p.x, p.y)));
            },
            plan.distances(),
        )?;
        mosaic.set_regions(Vec::new(), Vec::new());
        let vehicle = vehicle_overlay(spec, &camera, mesh.as_deref());
        Ok(Self {
            spec: spec.clone(),
            viewpoint: *viewpoint,
            camera,
            mosaic,
            vehicle,
            mesh,
            plan,
        })
    }

    /// The ground plan its blend distances are measured on.
    pub fn plan(&self) -> &Arc<GroundPlan> {
        &self.plan
    }

    /// The user's vehicle model it draws, if any.
    pub fn vehicle_mesh(&self) -> Option<&Arc<Mesh>> {
        self.mesh.as_ref()
    }

    /// The spec.
    pub fn spec(&self) -> &BowlSpec {
        &self.spec
    }

    /// The viewpoint.
    pub fn viewpoint(&self) -> &Viewpoint {
        &self.viewpoint
    }

    /// The viewpoint's pinhole camera.
    pub fn camera(&self) -> &VirtualCamera {
        &self.camera
    }

    /// The cameras' maps, weights and plans on the picture.
    pub fn mosaic(&self) -> &Mosaic {
        &self.mosaic
    }

    /// The share of the picture the vehicle model covers (0 to 1).
    pub fn vehicle_coverage(&self) -> f64 {
        let [w, h] = self.spec.size_px;
        self.vehicle
            .iter()
            .map(|(_, c)| f64::from(c[3]) / 255.0)
            .sum::<f64>()
            / (w * h) as f64
    }

    /// The vehicle model's colour and opacity (RGBA) at picture pixel
    /// (column, row), if it covers it.
    pub fn vehicle_at(&self, col: usize, row: usize) -> Option<[u8; 4]> {
        let i = (row * self.spec.size_px[0] + col) as u32;
        self.vehicle
            .binary_search_by_key(&i, |(j, _)| *j)
            .ok()
            .map(|k| self.vehicle[k].1)
    }

    /// Paints the vehicle model over a picture composed from
    /// [`BowlView::mosaic`] (grey pictures get its luma).
    pub fn paint_vehicle(&self, canvas: &mut Canvas) -> Result<()> {
        let [w, h] = self.spec.size_px;
        if (canvas.width, canvas.height) != (w, h) || !matches!(canvas.channels, 1 | 3) {
            return Err(Error::invalid(
                "bowl view",
                "the picture",
                format!("{w}×{h}, grey or RGB"),
                format_args!(
                    "{}×{} with {} channels",
                    canvas.width, canvas.height, canvas.channels
                ),
            ));
        }
        let ch = canvas.channels;
        for &(i, [r, g, b, a]) in &self.vehicle {
            let (a, keep) = (u32::from(a), 255 - u32::from(a));
            let at = i as usize * ch;
            let blend = |under: u8, over: u8| {
                ((u32::from(over) * a + u32::from(under) * keep + 127) / 255) as u8
            };
            if ch == 1 {
                let luma =
                    ((77 * u32::from(r) + 150 * u32::from(g) + 29 * u32::from(b) + 128) >> 8) as u8;
                canvas.data[at] = blend(canvas.data[at], luma);
            } else {
                for (k, over) in [r, g, b].into_iter().enumerate() {
                    canvas.data[at + k] = blend(canvas.data[at + k], over);
                }
            }
        }
        Ok(())
    }
}

/// The vehicle model's overlay on the picture: for each pixel it covers,
/// the mean of 2 × 2 samples (colour weighted by opacity, and the
/// coverage), in pixel order.
fn vehicle_overlay(
    spec: &BowlSpec,
    camera: &VirtualCamera,
    mesh: Option<&Mesh>,
) -> Vec<(u32, [u8; 4])> {
    let built_in = VehicleModel::new(spec.vehicle_m, spec.vehicle_height_m);
    // A user's model is drawn over the built-in one's shadow.
    let model = match mesh {
        Some(_) => built_in.shadow_only(),
        None => built_in,
    };
    let drawn = mesh.map(|m| m.rasterise(camera, spec.size_px[0], spec.size_px[1]));
    let [w, h] = spec.size_px;
    // Only the picture's part where the model's box projects (all of it
    // if a corner is behind the eye).
    let [x0, x1, y0, y1] = spec.vehicle_m;
    let margin = 0.2;
    let mut corners = Vec::with_capacity(8);
    for x in [x0 - margin, x1 + margin] {
        for y in [y0 - margin, y1 + margin] {
            for z in [0.0, spec.vehicle_height_m] {
                corners.push(camera.project(&Vector3::new(x, y, z)));
            }
        }
    }
    let (c0, c1, r0, r1) = if corners.iter().all(Option::is_some) {
        let cs = corners.iter().flatten();
        let (mut c0, mut c1, mut r0, mut r1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(c, r) in cs {
            (c0, c1, r0, r1) = (c0.min(c), c1.max(c), r0.min(r), r1.max(r));
        }
        let clamp = |v: f64, n: usize| v.floor().clamp(0.0, n as f64) as usize;
        (
            clamp(c0 - 1.0, w),
            clamp(c1 + 2.0, w),
            clamp(r0 - 1.0, h),
            clamp(r1 + 2.0, h),
        )
    } else {
        (0, w, 0, h)
    };
    // Only from outside the bowl (or under its surface) can the bowl
    // stand between the eye and the vehicle.
    let eye = camera.eye;
    let eye_over_bowl = spec.height(eye.x, eye.y).is_some_and(|h| eye.z > h);
    let mut out = Vec::new();
    for r in r0..r1 {
        for c in c0..c1 {
            let (mut rgb, mut alpha) = ([0.0f64; 3], 0.0f64);
            for (dc, dr) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                let ray = camera.ray(c as f64 + dc, r as f64 + dr);
                let Some(hit) = model.hit(&camera.eye, &ray) else {
                    continue;
                };
                // The bowl in front of the vehicle (a viewpoint outside
                // the bowl) hides it.
                let hidden = !eye_over_bowl
                    && spec
                        .intersect(&camera.eye, &ray)
                        .is_some_and(|p| (p - camera.eye).norm() < hit.t - 1e-6);
                if hidden {
                    continue;
                }
                let a = f64::from(hit.alpha) / 255.0;
                for (s, v) in rgb.iter_mut().zip(hit.rgb) {
                    *s += a * f64::from(v);
                }
                alpha += a;
            }
            let (mut rgb, mut alpha) = (rgb.map(|s| s / alpha.max(1e-9)), alpha / 4.0);
            // The user's model over the shadow.
            if let Some(&(mesh_rgb, share)) = drawn.as_ref().and_then(|d| d.get(r * w + c)) {
                if share > 0.0 {
                    let total = share + alpha * (1.0 - share);
                    for (v, m) in rgb.iter_mut().zip(mesh_rgb) {
                        *v = (m * share + *v * alpha * (1.0 - share)) / total;
                    }
                    alpha = total;
                }
            }
            if alpha > 0.0 {
                let px = rgb.map(|s| s.round().clamp(0.0, 255.0) as u8);
                let a = (alpha * 255.0).round().clamp(1.0, 255.0) as u8;
                out.push(((r * w + c) as u32, [px[0], px[1], px[2], a]));
            }
        }
    }
    out
}
