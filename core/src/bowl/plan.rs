//! The bowl's ground plan: a raster over the ground (x, y) that holds the
//! whole bowl, each cell standing for the surface point above it (the bowl
//! is a height field). The blend distances are measured on it, as the
//! bird's-eye view measures them on its canvas, so that the bowl's seams
//! lie on the surface where the bird's-eye view's lie on the ground, and
//! stay there from every viewpoint. Both renderers weigh with it: the
//! picture's maps ([`super::BowlView`]) and the GPU's mesh
//! ([`super::SurfaceMesh`]).

use std::sync::Arc;

use nalgebra::{Point2, Vector3};
use rigview_calib::rig::Rig;

use super::{BowlSpec, SurfaceMesh};
use crate::error::Result;
use crate::surround::mosaic::{self, SurfaceDistances};
use crate::surround::{grid, Side};

/// The plan's cell, metres (finer where the bowl is small).
const CELL_M: f64 = 0.04;
/// The most cells along a side of the plan.
const MAX_SIDE: usize = 1024;
/// The plan's interpolation tolerance (cells): its distances need no
/// more.
const TOLERANCE: f64 = 0.25;

/// The bowl's ground plan and each camera's distance from its exclusive
/// region on it.
#[derive(Debug)]
pub struct GroundPlan {
    /// The ground position of the plan's corner (x, y), metres.
    origin: (f64, f64),
    /// The cell's side, metres.
    cell_m: f64,
    distances: SurfaceDistances,
    /// What it was built for: the surface's and the vehicle's part of the
    /// spec (a new viewpoint or picture size keeps it).
    key: [f64; 8],
    footprint: super::Footprint,
    /// The surface as a GPU draws it, weighed on this plan (or why there
    /// is none).
    mesh: std::result::Result<Arc<SurfaceMesh>, String>,
}

impl GroundPlan {
    /// The plan of `spec`'s bowl around `rig` (poses in the vehicle
    /// frame).
    pub fn build(rig: &Rig, spec: &BowlSpec) -> Result<Self> {
        spec.validate()?;
        let what = "bowl view";
        let cameras = mosaic::vehicle_cameras(rig, what)?;
        let [x0, x1, y0, y1] = spec.vehicle_m;
        let reach = spec.radius_m + 0.05;
        let (ox, oy, ex, ey) = match spec.footprint {
            super::Footprint::RoundedRectangle => (x0 - reach, y0 - reach, x1 + reach, y1 + reach),
            super::Footprint::Round => {
                let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
                (cx - reach, cy - reach, cx + reach, cy + reach)
            }
        };
        let cell_m = CELL_M.max((ex - ox).max(ey - oy) / MAX_SIDE as f64);
        let (w, h) = (
            ((ex - ox) / cell_m).ceil() as usize,
            ((ey - oy) / cell_m).ceil() as usize,
        );
        let sides = Side::of_cameras(&cameras.projectors);
        let projectors = &cameras.projectors;
        let distances = SurfaceDistances::build(
            what,
            (w, h),
            &cameras.sources,
            (grid::MAP_GRID, TOLERANCE),
            |c, r, found| {
                let (x, y) = (
                    ox + (c as f64 + 0.5) * cell_m,
                    oy + (r as f64 + 0.5) * cell_m,
                );
                let Some(z) = spec.height(x, y) else {
                    return;
                };
                let p = Vector3::new(x, y, z);
                for (k, projector) in projectors.iter().enumerate() {
                    if sides[k].beyond(&spec.vehicle_m, x, y) {
                        if let Some(px) = projector.project_rig(&p) {
                            found.push((k, px));
                        }
                    }
                }
            },
        )?;
        let mut plan = Self {
            origin: (ox, oy),
            cell_m,
            distances,
            key: Self::key_of(spec),
            footprint: spec.footprint,
            mesh: Err(String::new()),
        };
        plan.mesh = SurfaceMesh::build(rig, spec, &plan)
            .map(Arc::new)
            .map_err(|e| e.to_string());
        Ok(plan)
    }

    /// The bowl's surface as a GPU draws it (weighed on this plan), or why
    /// there is none (more cameras than a GPU's bowl shows).
    pub fn mesh(&self) -> std::result::Result<&Arc<SurfaceMesh>, &str> {
        self.mesh.as_ref().map_err(String::as_str)
    }

    fn key_of(spec: &BowlSpec) -> [f64; 8] {
        let [x0, x1, y0, y1] = spec.vehicle_m;
        [
            spec.flat_m,
            spec.radius_m,
            spec.wall_height_m,
            spec.steepness,
            x0,
            x1,
            y0,
            y1,
        ]
    }

    /// Whether the plan serves `spec` (of the same rig): its surface and
    /// vehicle rectangle are the same.
    pub fn serves(&self, spec: &BowlSpec) -> bool {
        // Exactly the same values (as the spec's own comparison).
        self.key.map(f64::to_bits) == Self::key_of(spec).map(f64::to_bits)
            && self.footprint == spec.footprint
    }

    /// The plan's size in cells (width along x, height along y).
    pub fn size(&self) -> (usize, usize) {
        self.distances.size()
    }

    /// The plan position (column, row; cell centres at whole numbers) of
    /// ground point (x, y).
    pub fn position(&self, x: f64, y: f64) -> Point2<f64> {
        Point2::new(
            (x - self.origin.0) / self.cell_m - 0.5,
            (y - self.origin.1) / self.cell_m - 0.5,
        )
    }

    /// Camera `k`'s distance (cells) from its exclusive region at ground
    /// point (x, y) (`None`: it shows none of the bowl).
    pub fn distance(&self, k: usize, x: f64, y: f64) -> Option<f32> {
        let p = self.position(x, y);
        self.distances.distance(k, p.x as f32, p.y as f32)
    }

    /// The distances, for [`crate::surround::mosaic::Mosaic::build_on_surface`].
    pub(crate) fn distances(&self) -> &SurfaceDistances {
        &self.distances
    }
}
