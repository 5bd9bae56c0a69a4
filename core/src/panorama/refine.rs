//! Refinement of the cameras' rotations from the panorama's matches.
//!
//! Every camera but one (the fixed one) gets a small rotation about its
//! centre, `f → exp(ω_k) f` for its rays in the vehicle frame; translations
//! stay the calibration's. Levenberg–Marquardt
//! (`rigview_calib::lm::minimise`) minimises the inlier matches' epipolar
//! errors (see [`super::matching`]: the angle of camera `j`'s ray from the
//! plane through both centres and camera `i`'s ray, in canvas pixels) with
//! the Cauchy loss `s²·ln(1 + (e/s)²)` (scale `s`, one pixel by default),
//! and a prior of σ = `bound_deg` on each rotation, which keeps the
//! rotations the matches hardly see near none. A step that would turn a
//! camera by more than `bound_deg` (3° by default) is refused, so that one
//! bad frame set cannot throw the calibration away.

use nalgebra::{Rotation3, Vector3};
use rigview_calib::rig::Rig;
use rigview_calib::Pose;

use super::matching::{median, PairGeometry, RayPair};
use super::{PairMatches, Panorama};
use crate::error::{check_range, Error, Result};

/// Options of [`Panorama::refine`].
#[derive(Clone, Debug, PartialEq)]
pub struct RefineOptions {
    /// The camera that keeps its rotation.
    pub fixed: usize,
    /// The largest rotation of a camera, degrees.
    pub bound_deg: f64,
    /// The Cauchy loss's scale, canvas pixels.
    pub loss_px: f64,
    /// Levenberg–Marquardt iterations at most.
    pub iterations: usize,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            fixed: 0,
            bound_deg: 3.0,
            loss_px: 1.0,
            iterations: 50,
        }
    }
}

/// One pair's inliers before and after the refinement.
#[derive(Clone, Debug, PartialEq)]
pub struct PairRefinement {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// The inliers the refinement used.
    pub inliers: usize,
    /// Their median epipolar error with the calibration, canvas pixels.
    pub error_before_px: Option<f64>,
    /// The same with the refined rotations.
    pub error_after_px: Option<f64>,
}

/// What [`Panorama::refine`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    /// Per camera, its rotation about its centre (vehicle frame): the new
    /// orientation is `rotation · R`.
    pub rotations: Vec<Rotation3<f64>>,
    /// Per pair with inliers.
    pub pairs: Vec<PairRefinement>,
}

impl Refinement {
    /// `rig` with each camera's rotation applied (translations kept).
    pub fn apply(&self, rig: &Rig) -> Result<Rig> {
        let mut out = rig.clone();
        for (cam, q) in out.cameras.iter_mut().zip(&self.rotations) {
            if let Some(pose) = cam.pose {
                let r = q.matrix() * pose.rotation_matrix();
                cam.pose = Some(Pose::new(r, *pose.translation()).map_err(|e| {
                    Error::InvalidConfig(format!("refined camera `{}`: {e}", cam.name))
                })?);
            }
        }
        Ok(out)
    }
}

impl Panorama {
    /// Refines the cameras' rotations from the inliers of `pairs` (from
    /// [`Panorama::match_pairs`] on this panorama): see the module
    /// documentation. A rig without any inliers is an error.
    pub fn refine(&self, pairs: &[PairMatches], options: &RefineOptions) -> Result<Refinement> {
        let n = self.origins.len();
        if options.fixed >= n {
            return Err(Error::CameraIndex {
                index: options.fixed,
                count: n,
            });
        }
        let bound = check_range(
            "refine.bound_deg",
            options.bound_deg,
            0.01,
            20.0,
            "0.01° to 20°",
        )?
        .to_radians();
        let scale = check_range(
            "refine.loss_px",
            options.loss_px,
            0.01,
            100.0,
            "0.01 to 100 canvas pixels",
        )?;
        // Per pair: its geometry and its inliers' rays.
        let data: Vec<(&PairMatches, PairGeometry, Vec<RayPair>)> = pairs
            .iter()
            .filter(|p| p.i < n && p.j < n)
            .map(|p| {
                let rays = p
                    .matches
                    .iter()
                    .filter(|m| m.inlier)
                    .map(|m| (self.ray(p.i, m.at_i), self.ray(p.j, m.at_j)))
                    .collect();
                (p, self.pair_geometry(p.i, p.j), rays)
            })
            .collect();
        if data.iter().all(|(_, _, rays)| rays.is_empty()) {
            return Err(Error::InvalidConfig(
                "panorama refinement: no pair has inliers to refine the rotations with".into(),
            ));
        }
        // The parameters: ω of every camera but the fixed one.
        let free: Vec<usize> = (0..n).filter(|&k| k != options.fixed).collect();
        let rotations = |x: &[f64]| -> Option<Vec<Rotation3<f64>>> {
            let mut out = vec![Rotation3::identity(); n];
            for (slot, &k) in free.iter().enumerate() {
                let w = Vector3::new(x[3 * slot], x[3 * slot + 1], x[3 * slot + 2]);
                if w.norm() > bound {
                    return None;
                }
                out[k] = Rotation3::new(w);
            }
            Some(out)
        };
        let prior = 1.0 / bound;
        let residuals = |x: &[f64]| -> Option<Vec<f64>> {
            let q = rotations(x)?;
            let mut out = Vec::new();
            for (p, g, rays) in &data {
                for (f_i, f_j) in rays {
                    let e = g.signed_error_px(&(q[p.i] * f_i), &(q[p.j] * f_j))?;
                    out.push(e.signum() * scale * (1.0 + (e / scale).powi(2)).ln().sqrt());
                }
            }
            out.extend(x.iter().map(|v| v * prior));
            Some(out)
        };
        let (x, _) =
            rigview_calib::lm::minimise(&vec![0.0; 3 * free.len()], residuals, options.iterations);
        let q = rotations(&x).ok_or_else(|| {
            Error::InvalidConfig("panorama refinement: the solution left its bound".into())
        })?;
        let pairs = data
            .iter()
            .filter(|(_, _, rays)| !rays.is_empty())
            .map(|(p, g, rays)| {
                let errors = |qi: &Rotation3<f64>, qj: &Rotation3<f64>| {
                    median(
                        rays.iter()
                            .filter_map(|(a, b)| g.error_px(&(qi * a), &(qj * b)))
                            .collect(),
                    )
                };
                PairRefinement {
                    i: p.i,
                    j: p.j,
                    inliers: rays.len(),
                    error_before_px: errors(&Rotation3::identity(), &Rotation3::identity()),
                    error_after_px: errors(&q[p.i], &q[p.j]),
                }
            })
            .collect();
        Ok(Refinement {
            rotations: q,
            pairs,
        })
    }
}
