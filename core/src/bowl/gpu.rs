//! What a GPU draws of the bowl: the surface as a dense mesh whose
//! vertices carry, per camera, where the calibration projects them (any
//! camera model, with its full pose), their distance from the camera's
//! exclusive region on the ground plan, and how far they lie beyond the
//! camera's side; and the vehicle model as lit triangles. A fragment
//! weighs the cameras as the picture's maps do (`w ∝ 1/d²`, the side rule,
//! the image's bounds), so that the GPU's picture agrees with
//! [`super::BowlView`]'s on the CPU.
//!
//! The mesh follows the footprint: rings at a growing distance from the
//! vehicle's rectangle (or centre), closer where the wall rises, each ring
//! the same number of points round (more at the corners' arcs), so that
//! the projection's curvature within a triangle stays well under a source
//! pixel.

use nalgebra::Vector3;
use rigview_calib::rig::Rig;

use super::vehicle::{Part, TYRE};
use super::{BowlSpec, Footprint, GroundPlan, Mesh, VehicleModel};
use crate::error::{Error, Result};
use crate::surround::{mosaic, Side};

/// The most cameras the GPU's bowl shows (one texture unit and a few
/// vertex attributes each).
pub const MAX_GPU_CAMERAS: usize = 4;

/// A point along the footprint's edges between rings, metres.
const EDGE_STEP_M: f64 = 0.06;
/// Points on each corner's quarter arc.
const ARC_POINTS: usize = 48;
/// The step between rings along the surface near the vehicle, metres, and
/// its growth per metre of distance.
const RING_STEP_M: (f64, f64) = (0.06, 0.03);
/// Segments round a wheel.
const WHEEL_SEGMENTS: usize = 24;

/// One vertex of the surface.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceVertex {
    /// The surface point, vehicle frame, metres.
    pub position: [f32; 3],
    /// Per camera, where it projects (source pixels, centres at whole
    /// numbers), or far off the image where the model cannot project it.
    pub source: [[f32; 2]; MAX_GPU_CAMERAS],
    /// Per camera, its distance from the camera's exclusive region (plan
    /// cells).
    pub distance: [f32; MAX_GPU_CAMERAS],
    /// Per camera, how far the point lies beyond the camera's side of the
    /// vehicle (metres; a camera shows only points beyond it); negative
    /// where the camera's model cannot project it.
    pub beyond: [f32; MAX_GPU_CAMERAS],
}

/// The bowl's surface as triangles.
#[derive(Clone, Debug)]
pub struct SurfaceMesh {
    /// The vertices.
    pub vertices: Vec<SurfaceVertex>,
    /// Triangles, three indices each, facing up (counter-clockwise seen
    /// from above the bowl's inside).
    pub indices: Vec<u32>,
    /// Each camera's image size (width, height), rig order.
    pub sources: Vec<(usize, usize)>,
}

impl SurfaceMesh {
    /// The mesh of `spec`'s bowl around `rig`, weighed on `plan` (built
    /// for the same spec and rig).
    pub fn build(rig: &Rig, spec: &BowlSpec, plan: &GroundPlan) -> Result<Self> {
        spec.validate()?;
        let what = "bowl view";
        let cameras = mosaic::vehicle_cameras(rig, what)?;
        if cameras.projectors.len() > MAX_GPU_CAMERAS {
            return Err(Error::invalid(
                what,
                "the rig's cameras",
                format!("at most {MAX_GPU_CAMERAS} for the GPU's bowl"),
                cameras.projectors.len(),
            ));
        }
        if !plan.serves(spec) {
            return Err(Error::invalid(
                what,
                "the ground plan",
                "one built for the same bowl",
                "one of another bowl",
            ));
        }
        let sides = Side::of_cameras(&cameras.projectors);
        let rings = ring_distances(spec);
        let outline = Outline::of(spec);
        let n = outline.len();
        let mut vertices = Vec::with_capacity(rings.len() * n + 4);
        for &d in &rings {
            for j in 0..n {
                let (x, y) = outline.at(j, d);
                let z = spec.height(x, y).unwrap_or(spec.wall_height_m);
                let p = Vector3::new(x, y, z);
                let mut v = SurfaceVertex {
                    position: [x as f32, y as f32, z as f32],
                    ..SurfaceVertex::default()
                };
                for (k, projector) in cameras.projectors.iter().enumerate() {
                    let margin = sides[k].margin(&spec.vehicle_m, x, y);
                    match projector.project_rig(&p) {
                        Some(px) => {
                            v.source[k] = [px.x as f32, px.y as f32];
                            v.beyond[k] = margin as f32;
                        }
                        None => {
                            v.source[k] = [-1e4, -1e4];
                            v.beyond[k] = -1.0;
                        }
                    }
                    v.distance[k] = plan.distance(k, x, y).unwrap_or(1e6);
                }
                for k in cameras.projectors.len()..MAX_GPU_CAMERAS {
                    v.beyond[k] = -1.0;
                }
                vertices.push(v);
            }
        }
        let mut indices = Vec::with_capacity(6 * (rings.len() - 1) * n + 6);
        for i in 0..rings.len() - 1 {
            for j in 0..n {
                let (a, b) = ((i * n + j) as u32, (i * n + (j + 1) % n) as u32);
                let (c, d) = (a + n as u32, b + n as u32);
                // The outline runs counter-clockwise seen from above and
                // the rings outwards: (a, d, b) and (a, c, d) face up.
                indices.extend_from_slice(&[a, d, b, a, c, d]);
            }
        }
        // Under the vehicle (which no camera sees): its rectangle.
        if spec.footprint == Footprint::RoundedRectangle {
            let [x0, x1, y0, y1] = spec.vehicle_m;
            let base = vertices.len() as u32;
            for (x, y) in [(x1, y0), (x1, y1), (x0, y1), (x0, y0)] {
                let mut v = SurfaceVertex {
                    position: [x as f32, y as f32, 0.0],
                    ..SurfaceVertex::default()
                };
                v.beyond = [-1.0; MAX_GPU_CAMERAS];
                vertices.push(v);
            }
            indices.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        Ok(Self {
            vertices,
            indices,
            sources: cameras.sources.iter().map(|(_, s)| *s).collect(),
        })
    }
}

/// The distances of the mesh's rings from the footprint: from 0 to the
/// rim, a step of [`RING_STEP_M`] along the surface, with a ring where
/// the wall begins.
fn ring_distances(spec: &BowlSpec) -> Vec<f64> {
    let rise = |d: f64| {
        if d <= spec.flat_m {
            0.0
        } else {
            let u = ((d - spec.flat_m) / (spec.radius_m - spec.flat_m)).min(1.0);
            spec.wall_height_m * u.powf(spec.steepness)
        }
    };
    let mut out = vec![0.0];
    let mut d = 0.0f64;
    while d < spec.radius_m {
        let step = RING_STEP_M.0 + RING_STEP_M.1 * d;
        // The slope here, to step the same length along the wall.
        let slope = (rise(d + 1e-3) - rise(d)) / 1e-3;
        let mut next = d + step / (1.0 + slope * slope).sqrt();
        if d < spec.flat_m && next > spec.flat_m {
            next = spec.flat_m;
        }
        d = next.min(spec.radius_m);
        out.push(d);
    }
    out
}

/// The footprint's outline at a distance: the vehicle's rectangle grown
/// by it (rounded corners), or a circle about its centre, as points in
/// the same order at every distance.
struct Outline {
    rect: [f64; 4],
    /// Per segment: 0–3 an edge (front, left, back, right), 4–7 a corner's
    /// arc; and its points.
    segments: Vec<(usize, usize)>,
}

impl Outline {
    fn of(spec: &BowlSpec) -> Self {
        let [x0, x1, y0, y1] = spec.vehicle_m;
        let rect = match spec.footprint {
            Footprint::RoundedRectangle => spec.vehicle_m,
            Footprint::Round => {
                let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
                [cx, cx, cy, cy]
            }
        };
        let [x0, x1, y0, y1] = rect;
        let edge = |len: f64| (len / EDGE_STEP_M).ceil() as usize;
        // Counter-clockwise from above: the front edge (right to left),
        // the front-left corner, the left edge (front to back), …
        let segments = vec![
            (0, edge(y1 - y0)),
            (4, ARC_POINTS),
            (1, edge(x1 - x0)),
            (5, ARC_POINTS),
            (2, edge(y1 - y0)),
            (6, ARC_POINTS),
            (3, edge(x1 - x0)),
            (7, ARC_POINTS),
        ];
        Self { rect, segments }
    }

    fn len(&self) -> usize {
        self.segments.iter().map(|s| s.1).sum()
    }

    /// Point `j` of the outline at distance `d`.
    fn at(&self, mut j: usize, d: f64) -> (f64, f64) {
        let [x0, x1, y0, y1] = self.rect;
        for &(kind, count) in &self.segments {
            if j >= count {
                j -= count;
                continue;
            }
            let t = j as f64 / count as f64;
            let lerp = |a: f64, b: f64| a + (b - a) * t;
            let arc = |cx: f64, cy: f64, from_deg: f64| {
                let a = (from_deg + 90.0 * t).to_radians();
                (cx + d * a.cos(), cy + d * a.sin())
            };
            return match kind {
                0 => (x1 + d, lerp(y0, y1)),
                1 => (lerp(x1, x0), y1 + d),
                2 => (x0 - d, lerp(y1, y0)),
                3 => (lerp(x0, x1), y0 - d),
                4 => arc(x1, y1, 0.0),
                5 => arc(x0, y1, 90.0),
                6 => arc(x0, y0, 180.0),
                _ => arc(x1, y0, 270.0),
            };
        }
        (x1 + d, y0)
    }
}

/// The vehicle model as triangles: per vertex its position, the face's
/// normal and the colour (linear RGB, 0–1) with its opacity, lit by the
/// renderer as `bowl::vehicle` lights it.
#[derive(Clone, Debug, Default)]
pub struct VehicleTriangles {
    /// Three vertices a triangle: position, normal, colour and opacity.
    pub vertices: Vec<([f32; 3], [f32; 3], [f32; 4])>,
}

impl VehicleTriangles {
    /// The built-in model of `spec`'s vehicle, or a user's `mesh` over the
    /// built-in model's shadow.
    pub fn of(spec: &BowlSpec, mesh: Option<&Mesh>) -> Self {
        let model = VehicleModel::new(spec.vehicle_m, spec.vehicle_height_m);
        let model = match mesh {
            Some(_) => model.shadow_only(),
            None => model,
        };
        let mut out = Self::default();
        for part in model.parts() {
            out.add_box(part);
        }
        for &(c, r, half) in model.wheels() {
            out.add_wheel(c, r, half);
        }
        if let Some(mesh) = mesh {
            for ([a, b, c], colour) in mesh.triangles() {
                let n = (b - a).cross(&(c - a));
                if n.norm() == 0.0 {
                    continue;
                }
                let n = n.normalize();
                let rgba = [colour[0], colour[1], colour[2], 1.0].map(|v| v as f32);
                for p in [a, b, c] {
                    out.push(p, &n, rgba);
                }
            }
        }
        out
    }

    fn push(&mut self, p: &Vector3<f64>, n: &Vector3<f64>, rgba: [f32; 4]) {
        self.vertices.push((
            [p.x as f32, p.y as f32, p.z as f32],
            [n.x as f32, n.y as f32, n.z as f32],
            rgba,
        ));
    }

    fn add_box(&mut self, part: &Part) {
        let (lo, hi) = (part.min, part.max);
        let rgba = if part.shadow {
            // Drawn unlit: the renderer takes a normal of zero as unlit.
            [0.0, 0.0, 0.0, 200.0 / 255.0]
        } else {
            [part.colour[0], part.colour[1], part.colour[2], 1.0].map(|v| v as f32)
        };
        let corner = |i: usize| {
            Vector3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        // Each face: its corners in order round it, and its normal.
        let faces: [([usize; 4], Vector3<f64>); 6] = [
            ([0, 2, 6, 4], -Vector3::x()),
            ([1, 5, 7, 3], Vector3::x()),
            ([0, 4, 5, 1], -Vector3::y()),
            ([2, 3, 7, 6], Vector3::y()),
            ([0, 1, 3, 2], -Vector3::z()),
            ([4, 6, 7, 5], Vector3::z()),
        ];
        for (q, n) in faces {
            let n = if part.shadow { Vector3::zeros() } else { n };
            for i in [q[0], q[1], q[2], q[0], q[2], q[3]] {
                self.push(&corner(i), &n, rgba);
            }
        }
    }

    fn add_wheel(&mut self, c: Vector3<f64>, r: f64, half: f64) {
        let rgba = [TYRE[0], TYRE[1], TYRE[2], 1.0].map(|v| v as f32);
        let at = |i: usize, y: f64| {
            let a = std::f64::consts::TAU * i as f64 / WHEEL_SEGMENTS as f64;
            Vector3::new(c.x + r * a.cos(), y, c.z + r * a.sin())
        };
        // A hair inside the body's sides, which the wheels' faces share
        // (the ray caster lets the body win there; a depth buffer would
        // flicker between the two).
        let half = half - 0.003;
        let (yl, yr) = (c.y - half, c.y + half);
        for i in 0..WHEEL_SEGMENTS {
            let a = std::f64::consts::TAU * (i as f64 + 0.5) / WHEEL_SEGMENTS as f64;
            let n = Vector3::new(a.cos(), 0.0, a.sin());
            let (p0, p1, q0, q1) = (at(i, yl), at(i + 1, yl), at(i, yr), at(i + 1, yr));
            for p in [p0, p1, q1, p0, q1, q0] {
                self.push(&p, &n, rgba);
            }
            for (y, side) in [(yl, -1.0), (yr, 1.0)] {
                let n = Vector3::new(0.0, side, 0.0);
                let centre = Vector3::new(c.x, y, c.z);
                for p in [centre, at(i, y), at(i + 1, y)] {
                    self.push(&p, &n, rgba);
                }
            }
        }
    }
}
