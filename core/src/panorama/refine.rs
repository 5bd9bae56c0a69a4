//! Refinement of the cameras' rotations from the panorama's matches.
//!
//! Every camera gets a small rotation about its centre, `f → exp(ω_k) f`
//! for its rays in the vehicle frame; translations stay the calibration's.
//! Levenberg–Marquardt (`rigview_calib::lm::minimise`) minimises the
//! inliers' errors under the Cauchy loss `s²·ln(1 + (e/s)²)` (scale `s`,
//! one pixel by default), with a prior of σ = `bound_deg` on each rotation,
//! which keeps the rotations the matches hardly see near none. A step that
//! would turn a camera by more than `bound_deg` (3° by default) is refused,
//! so that one bad frame set cannot throw the calibration away. Two stages:
//!
//! 1. **Epipolar errors.** Every camera but the fixed one turns, and each
//!    inlier's error is its epipolar error (see [`super::matching`]: the
//!    angle of camera `j`'s ray from the plane through both centres and
//!    camera `i`'s ray, in canvas pixels). A point's depth is unknown, so a
//!    turn that moves a match along its epipolar curve costs nothing; in a
//!    narrow overlap whose curves run nearly level, a camera's turn about
//!    the vertical is hardly seen. This stage's prior is σ = 1° (the bound
//!    if smaller): a camera with inliers in one of its pairs only would
//!    otherwise turn about the vertical as far as the bound, and the
//!    ground stage would find no matches on the ground (what it did on the
//!    simulated rig: `docs/panorama.md`, In rounds).
//! 2. **Points on the ground.** A match whose two rays meet the ground
//!    (z = 0) within [`RefineOptions::ground_px`] of each other is taken for
//!    a point on it: where one camera's ray meets the ground, seen from
//!    the other camera, must lie on the other's ray, an error of two
//!    dimensions (both ways) that sees every rotation. Every camera turns,
//!    the fixed one too: with the cameras' positions known, the ground
//!    fixes the rig's tilt and heading (relative to the vehicle frame).
//!    The other inliers keep their epipolar errors. The matches on the
//!    ground are chosen again after each solution, with a limit of 8, 4, 2
//!    and 1 times `ground_px`, so that the first stage's error about the
//!    vertical does not hide them. With fewer than 12 such matches the
//!    first stage's rotations stand.
//!
//! Matches on the ground are many where the canvas shows the ground as
//! such: on a cylinder with a floor ([`super::CylinderSpec::floor`]), both
//! cameras of an overlap warp the ground's features to the same place.

use nalgebra::{Rotation3, Vector3};
use rigview_calib::rig::Rig;
use rigview_calib::Pose;

use super::matching::{PairGeometry, RayPair};
use super::{PairMatches, Panorama};
use crate::error::{check_range, Error, Result};
use crate::stats::median;

/// The prior (σ, degrees; the bound if smaller) on each rotation in the
/// first stage, of the epipolar errors alone: see the module
/// documentation.
const FIRST_PRIOR_DEG: f64 = 1.0;

/// The share of a frame set's inliers that must be aligned by their
/// patches ([`super::FeatureMatch::aligned`]) for the refinement to take
/// those alone: see [`Panorama::inlier_rays`].
const ALIGNED_SHARE: f64 = 0.75;

/// Options of [`Panorama::refine`].
#[derive(Clone, Debug, PartialEq)]
pub struct RefineOptions {
    /// The camera that keeps its rotation in the first stage (epipolar
    /// errors), and whenever too few matches lie on the ground for the
    /// second.
    pub fixed: usize,
    /// The largest rotation of a camera, degrees.
    pub bound_deg: f64,
    /// The Cauchy loss's scale, canvas pixels.
    pub loss_px: f64,
    /// Levenberg–Marquardt iterations at most.
    pub iterations: usize,
    /// The largest two-dimensional error (canvas pixels), after the
    /// epipolar refinement, of a match taken for a point on the ground.
    pub ground_px: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            fixed: 0,
            bound_deg: 3.0,
            loss_px: 1.0,
            iterations: 50,
            ground_px: 3.0,
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
    /// How many of them it took for points on the ground.
    pub on_ground: usize,
    /// Their median epipolar error with the calibration, canvas pixels.
    pub error_before_px: Option<f64>,
    /// The same with the refined rotations.
    pub error_after_px: Option<f64>,
}

/// What [`Panorama::refine`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    /// Per camera, its rotation about its centre (vehicle frame): the new
    /// orientation is `rotation · R`. The fixed camera's is none unless the
    /// ground's matches turned it (the second stage).
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
                    Error::invalid(
                        format!("refined camera `{}`", cam.name),
                        e.field,
                        e.expected,
                        e.found,
                    )
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
        self.refine_rays(&self.inlier_rays(pairs), options)
    }

    /// The inliers of `pairs` (matched on this panorama) as rays of its
    /// rig, which [`Panorama::refine_rays`] refines from, and which can be
    /// pooled with other frame sets' ([`InlierRays::extend`]).
    ///
    /// Where most inliers (at least `ALIGNED_SHARE`) were aligned by
    /// their patches, the cameras see the overlaps alike enough for patches
    /// to tell, and only the aligned ones are taken: an inlier whose
    /// patches do not align is then likely no single scene point (an edge
    /// one camera sees in front of another object), and such inliers turn
    /// the cameras. Where fewer align (as where the overlaps lie at the
    /// fisheyes' edges and see near objects from metres apart), every inlier
    /// is taken. The measurements on the simulated rig and the real stills
    /// are in `docs/panorama.md`, In rounds.
    pub fn inlier_rays(&self, pairs: &[PairMatches]) -> InlierRays {
        let n = self.origins.len();
        let inliers = || {
            pairs
                .iter()
                .flat_map(|p| p.matches.iter().filter(|m| m.inlier))
        };
        let aligned = inliers().filter(|m| m.aligned).count();
        let only_aligned =
            aligned > 0 && aligned as f64 >= ALIGNED_SHARE * inliers().count() as f64;
        InlierRays {
            pairs: pairs
                .iter()
                .filter(|p| p.i < n && p.j < n)
                .map(|p| {
                    let rays = p
                        .matches
                        .iter()
                        .filter(|m| m.inlier && (m.aligned || !only_aligned))
                        .map(|m| (self.ray(p.i, m.at_i), self.ray(p.j, m.at_j)))
                        .collect();
                    (p.i, p.j, rays)
                })
                .collect(),
        }
    }

    /// [`Panorama::refine`] from rays (of this panorama's rig, or turned to
    /// it with [`InlierRays::turned`]).
    pub fn refine_rays(&self, rays: &InlierRays, options: &RefineOptions) -> Result<Refinement> {
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
        check_range(
            "refine.ground_px",
            options.ground_px,
            0.1,
            100.0,
            "0.1 to 100 canvas pixels",
        )?;
        // Per pair: its cameras, its geometry and its inliers' rays.
        let data: Vec<Pair<'_>> = rays
            .pairs
            .iter()
            .filter(|(i, j, _)| *i < n && *j < n)
            .map(|(i, j, rays)| ((*i, *j), self.pair_geometry(*i, *j), rays.as_slice()))
            .collect();
        if data.iter().all(|(_, _, rays)| rays.is_empty()) {
            return Err(Error::Solver {
                what: "panorama refinement",
                reason: "no pair has inliers to refine the rotations with".into(),
            });
        }
        // First the epipolar errors alone, every camera but the fixed one
        // turning (about its three axes; the fixed one about none).
        let fixed: Vec<usize> = (0..n)
            .map(|k| if k == options.fixed { 0 } else { 3 })
            .collect();
        let epipolar_only: Vec<Vec<bool>> = data
            .iter()
            .map(|(_, _, rays)| vec![false; rays.len()])
            .collect();
        let sigma = FIRST_PRIOR_DEG.to_radians().min(bound);
        let first = self
            .solve_with_prior(
                &data,
                &epipolar_only,
                &fixed,
                (bound, sigma, scale, options.iterations, ROUGH),
                &vec![Rotation3::identity(); n],
            )
            .ok_or_else(|| Error::Solver {
                what: "panorama refinement",
                reason: "the solution left its bound".into(),
            })?;
        // Then the matches on the ground, whose depth the ground gives, with
        // their full two-dimensional errors, and every camera turning: with
        // the cameras' positions known, the ground sees every rotation.
        let classify = |q: &[Rotation3<f64>], limit: f64| -> Vec<Vec<bool>> {
            data.iter()
                .map(|((i, j), g, rays)| {
                    rays.iter()
                        .map(|(f_i, f_j)| {
                            g.ground_error_px(&(q[*i] * f_i), &(q[*j] * f_j))
                                .is_some_and(|e| e <= limit)
                        })
                        .collect()
                })
                .collect()
        };
        // The matches within a loose limit first, then tighter ones, each
        // solution telling the next which matches lie on the ground.
        let every = vec![3; n];
        let mut current = first;
        let mut ground = epipolar_only.clone();
        for factor in GROUND_SCHEDULE {
            let taken = classify(&current, factor * options.ground_px);
            if taken.iter().flatten().filter(|&&b| b).count() < MIN_GROUND {
                break;
            }
            let limits = (bound, scale, options.iterations, ROUGH);
            match self.solve(&data, &taken, &every, limits, &current) {
                Some(all) => {
                    current = all;
                    ground = taken;
                }
                None => break,
            }
        }
        // The last solution again, to convergence: the ones before only
        // told which matches lie on the ground.
        let on_ground = ground.iter().flatten().any(|&b| b);
        let axes = if on_ground { &every } else { &fixed };
        let limits = (bound, scale, options.iterations, 1e-15);
        let q = self
            .solve(&data, &ground, axes, limits, &current)
            .unwrap_or(current);
        let pairs = data
            .iter()
            .zip(&ground)
            .filter(|((_, _, rays), _)| !rays.is_empty())
            .map(|(((i, j), g, rays), on_ground)| PairRefinement {
                i: *i,
                j: *j,
                inliers: rays.len(),
                on_ground: on_ground.iter().filter(|&&b| b).count(),
                error_before_px: median_error(
                    g,
                    rays,
                    &Rotation3::identity(),
                    &Rotation3::identity(),
                ),
                error_after_px: median_error(g, rays, &q[*i], &q[*j]),
            })
            .collect();
        Ok(Refinement {
            rotations: q,
            pairs,
        })
    }
}

impl Panorama {
    /// Per pair of `rays` with inliers: its cameras and the median
    /// epipolar error of its inliers (canvas pixels) with each camera
    /// turned by `rotations` (none for a camera beyond them).
    pub fn ray_errors(
        &self,
        rays: &InlierRays,
        rotations: &[Rotation3<f64>],
    ) -> Vec<(usize, usize, Option<f64>)> {
        let n = self.origins.len();
        rays.pairs
            .iter()
            .filter(|(i, j, r)| *i < n && *j < n && !r.is_empty())
            .map(|(i, j, r)| {
                let g = self.pair_geometry(*i, *j);
                let (qi, qj) = (rotation_of(rotations, *i), rotation_of(rotations, *j));
                (*i, *j, median_error(&g, r, &qi, &qj))
            })
            .collect()
    }
}

/// Camera `k`'s rotation of `rotations` (none for a camera beyond them).
fn rotation_of(rotations: &[Rotation3<f64>], k: usize) -> Rotation3<f64> {
    rotations
        .get(k)
        .copied()
        .unwrap_or_else(Rotation3::identity)
}

/// The median epipolar error (canvas pixels) of a pair's inliers `rays`
/// with its cameras turned by `qi` and `qj`.
fn median_error(
    g: &PairGeometry,
    rays: &[RayPair],
    qi: &Rotation3<f64>,
    qj: &Rotation3<f64>,
) -> Option<f64> {
    median(
        &mut rays
            .iter()
            .filter_map(|(a, b)| g.error_px(&(qi * a), &(qj * b)))
            .collect::<Vec<_>>(),
    )
}

/// One pair in a refinement: its cameras, its geometry and its inliers'
/// rays.
type Pair<'a> = ((usize, usize), PairGeometry, &'a [RayPair]);

/// The inliers of a panorama's pairs as rays (vehicle frame) of a rig,
/// from one frame set or pooled from several: see
/// [`Panorama::inlier_rays`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InlierRays {
    /// Per pair, cameras `i` and `j` and each inlier's two rays.
    pairs: Vec<(usize, usize, Vec<RayPair>)>,
}

impl InlierRays {
    /// The same inliers seen by the rig turned by `rotations` (per camera,
    /// about its centre: what [`Refinement::apply`] does).
    pub fn turned(&self, rotations: &[Rotation3<f64>]) -> Self {
        Self {
            pairs: self
                .pairs
                .iter()
                .map(|(i, j, rays)| {
                    let (qi, qj) = (rotation_of(rotations, *i), rotation_of(rotations, *j));
                    (*i, *j, rays.iter().map(|(a, b)| (qi * a, qj * b)).collect())
                })
                .collect(),
        }
    }

    /// Adds `other`'s inliers (of the same rig) to these.
    pub fn extend(&mut self, other: Self) {
        for (i, j, rays) in other.pairs {
            match self.pairs.iter_mut().find(|(a, b, _)| (*a, *b) == (i, j)) {
                Some((_, _, held)) => held.extend(rays),
                None => self.pairs.push((i, j, rays)),
            }
        }
    }
}

/// The relative decrease of the cost below which the solutions before the
/// last stop (the last one runs to convergence).
const ROUGH: f64 = 1e-6;

/// The fewest matches on the ground that the second stage needs.
const MIN_GROUND: usize = 12;

/// The limits on a match on the ground, in turn, as multiples of
/// [`RefineOptions::ground_px`].
const GROUND_SCHEDULE: [f64; 4] = [8.0, 4.0, 2.0, 1.0];

impl Panorama {
    /// Levenberg–Marquardt (at most `iterations`) from `start` over the
    /// rotations of the cameras, each about its first `axes[k]` axes (0 to
    /// 3): the inliers of `data` with their epipolar errors, or where
    /// `ground` says so their two-dimensional errors as points on the
    /// ground, under the Cauchy loss of scale `scale`, with a prior of
    /// σ = `bound` on each rotation, which may not exceed `bound`; until a
    /// step lowers the cost by less than `rel_tol` of it. `None` if the
    /// start is not defined.
    fn solve(
        &self,
        data: &[Pair<'_>],
        ground: &[Vec<bool>],
        axes: &[usize],
        (bound, scale, iterations, rel_tol): (f64, f64, usize, f64),
        start: &[Rotation3<f64>],
    ) -> Option<Vec<Rotation3<f64>>> {
        self.solve_with_prior(
            data,
            ground,
            axes,
            (bound, bound, scale, iterations, rel_tol),
            start,
        )
    }

    /// [`Panorama::solve`] with a prior of σ = `sigma` (radians) on each
    /// rotation instead of `bound`.
    fn solve_with_prior(
        &self,
        data: &[Pair<'_>],
        ground: &[Vec<bool>],
        axes: &[usize],
        (bound, sigma, scale, iterations, rel_tol): (f64, f64, f64, usize, f64),
        start: &[Rotation3<f64>],
    ) -> Option<Vec<Rotation3<f64>>> {
        let n = self.origins.len();
        let rotations = |x: &[f64]| -> Option<Vec<Rotation3<f64>>> {
            let mut out = vec![Rotation3::identity(); n];
            let mut at = 0;
            for (k, &m) in axes.iter().enumerate().take(n) {
                let mut w = Vector3::zeros();
                for c in 0..m {
                    w[c] = x[at + c];
                }
                at += m;
                if w.norm() > bound {
                    return None;
                }
                out[k] = Rotation3::new(w);
            }
            Some(out)
        };
        let robust = |e: f64| scale * (1.0 + (e / scale).powi(2)).ln().sqrt();
        let prior = 1.0 / sigma;
        let residuals = |x: &[f64]| -> Option<Vec<f64>> {
            let q = rotations(x)?;
            let mut out = Vec::new();
            for (((i, j), g, rays), on_ground) in data.iter().zip(ground) {
                for ((f_i, f_j), &flat) in rays.iter().zip(on_ground) {
                    let (a, b) = (q[*i] * f_i, q[*j] * f_j);
                    if flat {
                        for e in g.ground_errors_px(&a, &b)? {
                            let norm = e.norm();
                            let w = if norm > 1e-12 {
                                robust(norm) / norm
                            } else {
                                1.0
                            };
                            out.extend((e * w).iter());
                        }
                    } else {
                        let e = g.signed_error_px(&a, &b)?;
                        out.push(e.signum() * robust(e.abs()));
                    }
                }
            }
            out.extend(x.iter().map(|v| v * prior));
            Some(out)
        };
        let x0: Vec<f64> = axes
            .iter()
            .zip(start)
            .flat_map(|(&m, q)| q.scaled_axis().iter().take(m).copied().collect::<Vec<_>>())
            .collect();
        let (x, _) = rigview_calib::lm::minimise_to(&x0, residuals, iterations, rel_tol);
        rotations(&x)
    }
}
