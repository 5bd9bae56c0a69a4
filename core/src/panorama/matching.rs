//! Feature matches in the panorama's overlaps, and the brightness ratios
//! their patches give.
//!
//! # Where features are found
//!
//! Each overlap of two neighbours `i` and `j` is a band of the canvas: the
//! smallest rectangle holding every pixel both cameras show
//! ([`OverlapBand`]). Each camera's frame is warped alone into that band,
//! in the cylinder's coordinates, through the mosaic's remap: there the
//! two cameras see the scene nearly alike given the calibration (in the
//! raw fisheye images the same corner is rotated and scaled). Corners are
//! searched where both cameras see, at least a descriptor's reach
//! ([`PATCH_RADIUS`] + 1 pixels) inside; the detector is the caller's
//! (Harris corners through OpenCV in the app: `core` calls no OpenCV).
//!
//! # Matching
//!
//! Each corner gets a BRIEF descriptor ([`crate::features`]) on its warped
//! band. A corner at canvas position `a` in camera `i`'s warp is camera
//! `i`'s ray `f_i` from its centre `o_i` through the cylinder's point at
//! `a`; likewise `f_j` from `o_j` for a corner at `b` in camera `j`'s. The
//! current poses predict where a corner's match lies, up to its unknown
//! depth: on the epipolar curve, where `f_j` lies in the plane through the
//! baseline `o_j − o_i` and `f_i`. Its angle from that plane, in canvas
//! pixels (`W/2π` a radian), is the match's *reprojection error*; a point
//! at the cylinder's radius lands at `b = a`, a nearer or farther one moves
//! along the curve (parallax), which costs nothing. A pair of corners is a
//! candidate when its error is at most [`MatchOptions::search_px`] and `b`
//! lies within [`MatchOptions::max_shift_px`] of `a`; among candidates,
//! mutual nearest neighbours that pass the ratio test are matches.
//!
//! # Alignment
//!
//! The detector's two corners of a match are not quite the same scene
//! point (each detection errs on its own). With
//! [`MatchOptions::align_radius_px`] (7 by default), camera `i`'s corner is
//! taken at its nearest pixel and camera `j`'s position is where the patch
//! around it lies in `j`'s warp, to a fraction of a pixel
//! ([`crate::features::align`], which allows for the two cameras'
//! brightness). A match whose patches do not align (too little texture,
//! the scene seen too differently) keeps the detector's positions and says
//! so ([`FeatureMatch::aligned`]); where most of a frame set's inliers
//! aligned, the refinement takes those alone ([`Panorama::inlier_rays`]),
//! since overlaps at the edges of the fisheyes that see near objects from
//! viewpoints metres apart align far fewer than overlaps seen alike (how
//! many align on the simulated rig and the real stills:
//! `docs/panorama.md`, In rounds).
//!
//! # Outliers: RANSAC on the pair's relative rotation
//!
//! A small rotation `Q` of camera `j` about its centre (`f_j → Q f_j`)
//! that puts every match on its epipolar plane aligns the pair: with the
//! plane's normal `n = (t × f_i)/|t × f_i|`, each match gives the linear
//! equation `n·f_j + ω·(f_j × n) = 0` in the rotation vector `ω`. Three
//! matches fix `ω` (three Gauss–Newton steps from `Q = I`); a match whose
//! two rays then meet in front of both cameras within
//! [`MatchOptions::ransac_px`] is an inlier. The best of
//! [`MatchOptions::iterations`] seeded samples (so a run repeats) is
//! refitted on its inliers by least squares, twice. The translation stays
//! the calibration's: only the rotation is in question.
//!
//! # Brightness ratios
//!
//! Around each inlier, a [`MatchOptions::patch_px`]-square patch of each
//! warped band gives its mean and saturated fraction (a patch must lie
//! where both cameras see); the balancing's `pair_ratio` takes their median
//! ratio, leaving out saturated and near-black patches. A pair with fewer
//! than [`MatchOptions::min_inliers`] inliers gives no patches, hence no
//! ratio, and says so ([`PairMatches::problem`]).

use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use super::Panorama;
use crate::error::{Error, Result};
use crate::exposure::controller::PairObservation;
use crate::exposure::PatchPair;
use crate::features::{
    match_mutual_where, AlignOptions, Aligner, Descriptor, Gray, Match, Smoothed, PATCH_RADIUS,
};
use crate::image::FrameView;
use crate::stats::median;
use crate::surround::{Canvas, Composer};

mod ransac;

use ransac::ransac;
pub(super) use ransac::{PairGeometry, RayPair};

/// The part of the canvas where two neighbours overlap.
#[derive(Clone, Debug, PartialEq)]
pub struct OverlapBand {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// The smallest canvas rectangle holding every pixel both show:
    /// column, row, width, height.
    pub rect: [usize; 4],
    /// Per band pixel, 255 where both cameras show it.
    pub both: Vec<u8>,
    /// Per band pixel, 255 where a corner is searched: both cameras show
    /// every pixel within a descriptor's reach.
    pub search: Vec<u8>,
}

/// Options of [`Panorama::match_pairs`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MatchOptions {
    /// How far from the epipolar curve the current poses predict (canvas
    /// pixels) a match may lie.
    pub search_px: f64,
    /// How far from a corner (canvas pixels) its match may lie along the
    /// curve.
    pub max_shift_px: f64,
    /// Lowe's ratio test on Hamming distances.
    pub ratio: f32,
    /// A RANSAC inlier's largest error, canvas pixels.
    pub ransac_px: f64,
    /// RANSAC samples.
    pub iterations: usize,
    /// The seed of RANSAC's samples.
    pub seed: u64,
    /// The fewest inliers that give a pair a rotation and a ratio.
    pub min_inliers: usize,
    /// Side of the brightness patch around an inlier, canvas pixels (odd).
    pub patch_px: usize,
    /// Half the side of the patches that align a match's two corners to a
    /// fraction of a pixel ([`crate::features::align`]), canvas pixels; 0
    /// keeps the detector's positions.
    #[serde(default = "default_align_radius")]
    pub align_radius_px: usize,
}

fn default_align_radius() -> usize {
    AlignOptions::default().radius
}

impl Default for MatchOptions {
    fn default() -> Self {
        Self {
            search_px: 30.0,
            max_shift_px: 300.0,
            ratio: 0.9,
            ransac_px: 2.0,
            iterations: 300,
            seed: 18,
            min_inliers: 6,
            patch_px: 15,
            align_radius_px: default_align_radius(),
        }
    }
}

impl MatchOptions {
    fn validate(&self) -> Result<()> {
        crate::error::check_range(
            "matching.search_px",
            self.search_px,
            1.0,
            1000.0,
            "1 to 1000 canvas pixels",
        )?;
        crate::error::check_range(
            "matching.max_shift_px",
            self.max_shift_px,
            1.0,
            10000.0,
            "1 to 10000 canvas pixels",
        )?;
        crate::error::check_range(
            "matching.ransac_px",
            self.ransac_px,
            0.1,
            100.0,
            "0.1 to 100 canvas pixels",
        )?;
        if self.patch_px.is_multiple_of(2) || self.patch_px > 2 * PATCH_RADIUS + 1 {
            return Err(Error::InvalidParameter {
                name: "matching.patch_px",
                value: self.patch_px as f64,
                expected: "an odd patch side of at most 49 pixels",
            });
        }
        if self.align_radius_px > MAX_ALIGN_RADIUS {
            return Err(Error::InvalidParameter {
                name: "matching.align_radius_px",
                value: self.align_radius_px as f64,
                expected: "0 (no alignment) to 16 canvas pixels",
            });
        }
        if self.iterations == 0 || self.min_inliers < 2 {
            return Err(Error::invalid(
                "matching",
                "RANSAC samples and inliers",
                "at least 1 sample and 2 inliers",
                format_args!("{} samples, {} inliers", self.iterations, self.min_inliers),
            ));
        }
        Ok(())
    }
}

/// A band's warp as a grey image.
fn band_gray<'a>(band: &OverlapBand, warp: &'a Canvas) -> Result<Gray<'a>> {
    Gray::new(&warp.data, band.rect[2], band.rect[3]).ok_or_else(|| {
        Error::invalid(
            format!("panorama band {}–{}", band.i, band.j),
            "warp size",
            format!("the band's {}×{}", band.rect[2], band.rect[3]),
            format_args!("{} pixels", warp.data.len()),
        )
    })
}

/// The largest [`MatchOptions::align_radius_px`]: its patch, shifted by up
/// to [`AlignOptions::max_shift`], stays inside a corner's descriptor reach.
const MAX_ALIGN_RADIUS: usize = 16;

/// One match between the warped bands of a pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureMatch {
    /// The corner in camera `i`'s warp, canvas position (column, row).
    pub at_i: [f64; 2],
    /// The corner in camera `j`'s warp, canvas position.
    pub at_j: [f64; 2],
    /// Their descriptors' Hamming distance.
    pub distance: u32,
    /// Whether the two positions were aligned by their patches (rather
    /// than the detector's own).
    pub aligned: bool,
    /// Whether RANSAC kept it.
    pub inlier: bool,
}

/// What one overlap's matches gave.
#[derive(Clone, Debug, PartialEq)]
pub struct PairMatches {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// Corners found in camera `i`'s and camera `j`'s warp.
    pub corners: (usize, usize),
    /// The matches, inliers marked.
    pub matches: Vec<FeatureMatch>,
    /// How many matches RANSAC kept.
    pub inliers: usize,
    /// The rotation of camera `j` about its centre that aligns the inliers
    /// best (`None` with too few).
    pub rotation: Option<Rotation3<f64>>,
    /// Median canvas distance between the inliers' two positions with the
    /// current poses, pixels.
    pub error_before_px: Option<f64>,
    /// The same after `rotation`.
    pub error_after_px: Option<f64>,
    /// The brightness patches around the inliers (none with too few).
    pub patches: Vec<PatchPair>,
    /// Why the pair gives no rotation and no ratio, if it does not.
    pub problem: Option<String>,
}

impl PairMatches {
    /// The pair's patches for the balancing (Eq. 5).
    pub fn observation(&self) -> PairObservation {
        PairObservation {
            i: self.i,
            j: self.j,
            patches: self.patches.clone(),
        }
    }
}

/// Where the time of [`Panorama::match_pairs`] went, summed over pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MatchTimes {
    /// Warping the bands.
    pub warp: Duration,
    /// The caller's corner detector.
    pub detect: Duration,
    /// Smoothing and BRIEF descriptors.
    pub describe: Duration,
    /// Gated mutual matching.
    pub matching: Duration,
    /// Aligning each match's two corners.
    pub align: Duration,
    /// RANSAC and the patches.
    pub ransac: Duration,
}

/// A corner detector: a `width × height` grey image and a search mask (one
/// byte a pixel, non-zero to search) to corner positions (x, y), pixels.
pub type Detector<'a> = dyn Fn(&[u8], usize, usize, &[u8]) -> Result<Vec<[f32; 2]>> + 'a;

/// The bands of every overlap: see [`OverlapBand`]. `shared(i, j)` is a
/// canvas rectangle (column, row, width, height) holding every pixel both
/// cameras may show.
pub(super) fn bands(
    (pano_width, _height): (usize, usize),
    sees: impl Fn(usize, usize) -> bool,
    shared: impl Fn(usize, usize) -> Option<[usize; 4]>,
    pairs: &[(usize, usize)],
) -> Vec<Option<OverlapBand>> {
    let reach = (PATCH_RADIUS + 1) as f32;
    pairs
        .iter()
        .map(|&(i, j)| {
            let [x0, y0, sw, sh] = shared(i, j)?;
            let (mut c0, mut r0, mut c1, mut r1) = (usize::MAX, usize::MAX, 0, 0);
            for r in y0..y0 + sh {
                for c in x0..x0 + sw {
                    let p = r * pano_width + c;
                    if sees(i, p) && sees(j, p) {
                        c0 = c0.min(c);
                        c1 = c1.max(c);
                        r0 = r0.min(r);
                        r1 = r1.max(r);
                    }
                }
            }
            if c0 == usize::MAX {
                return None;
            }
            let (w, h) = (c1 - c0 + 1, r1 - r0 + 1);
            let both: Vec<u8> = (0..w * h)
                .map(|q| {
                    let p = (r0 + q / w) * pano_width + c0 + q % w;
                    u8::from(sees(i, p) && sees(j, p)) * 255
                })
                .collect();
            let distance = crate::image::distance_to_zero(&both, w, h).ok()?;
            let search = (0..w * h)
                .map(|q| {
                    let (x, y) = ((q % w) as f32, (q / w) as f32);
                    let edge = x.min(y).min((w - 1) as f32 - x).min((h - 1) as f32 - y);
                    u8::from(distance[q] >= reach && edge >= reach) * 255
                })
                .collect();
            Some(OverlapBand {
                i,
                j,
                rect: [c0, r0, w, h],
                both,
                search,
            })
        })
        .collect()
}

impl Panorama {
    /// The bands of the overlaps of the rig's neighbour pairs (rig order).
    pub fn bands(&self) -> &[OverlapBand] {
        &self.bands
    }

    /// Camera `k`'s frame warped alone into band `b` (mono).
    pub fn warp_band(
        &self,
        composer: &mut Composer,
        b: usize,
        k: usize,
        frame: &FrameView<'_>,
    ) -> Result<Canvas> {
        let band = self.bands.get(b).ok_or(Error::CameraIndex {
            index: b,
            count: self.bands.len(),
        })?;
        let side = usize::from(k == band.j);
        if k != band.i && k != band.j {
            return Err(self.camera_error(
                k,
                Error::invalid("band", "camera", "one of the band's two cameras", k),
            ));
        }
        let plans = self.band_plans[b]
            .get_or_init(|| [band.i, band.j].map(|c| self.mosaic.region_plan(c, band.rect)));
        let plan = plans[side].as_ref().ok_or_else(|| {
            self.camera_error(
                k,
                Error::invalid("band", "plan", "a plan over the band", "none"),
            )
        })?;
        composer.warp_with_plan(&self.mosaic, plan, k, frame, (band.rect[2], band.rect[3]))
    }

    /// Matches features in every overlap of `frames` (one per camera, rig
    /// order): see the module documentation. Errors name the camera whose
    /// frame does not fit; a pair without matches is not an error (its
    /// [`PairMatches::problem`] says why).
    pub fn match_pairs(
        &self,
        frames: &[FrameView<'_>],
        detect: &Detector<'_>,
        options: &MatchOptions,
    ) -> Result<(Vec<PairMatches>, MatchTimes)> {
        options.validate()?;
        self.check_frames(frames)?;
        let mut times = MatchTimes::default();
        let mut composer = Composer::new();
        let mut out = Vec::with_capacity(self.bands.len());
        for (b, band) in self.bands.iter().enumerate() {
            let t = Instant::now();
            let warp_i = self.warp_band(&mut composer, b, band.i, &frames[band.i])?;
            let warp_j = self.warp_band(&mut composer, b, band.j, &frames[band.j])?;
            times.warp += t.elapsed();
            out.push(self.match_band(band, &warp_i, &warp_j, detect, options, &mut times)?);
        }
        Ok((out, times))
    }

    fn match_band(
        &self,
        band: &OverlapBand,
        warp_i: &Canvas,
        warp_j: &Canvas,
        detect: &Detector<'_>,
        options: &MatchOptions,
        times: &mut MatchTimes,
    ) -> Result<PairMatches> {
        let [x0, y0, w, h] = band.rect;
        let t = Instant::now();
        let corners_i = detect(&warp_i.data, w, h, &band.search)?;
        let corners_j = detect(&warp_j.data, w, h, &band.search)?;
        times.detect += t.elapsed();
        let t = Instant::now();
        let described =
            |warp: &Canvas, corners: &[[f32; 2]]| -> Result<(Vec<[f32; 2]>, Vec<Descriptor>)> {
                let s = Smoothed::new(&warp.data, w, h)?;
                Ok(corners
                    .iter()
                    .filter_map(|p| s.describe(p[0], p[1]).map(|d| (*p, d)))
                    .unzip())
            };
        let (pi, di) = described(warp_i, &corners_i)?;
        let (pj, dj) = described(warp_j, &corners_j)?;
        times.describe += t.elapsed();
        let t = Instant::now();
        let canvas = |p: [f32; 2]| {
            [
                f64::from(p[0]) + x0 as f64 + 0.5,
                f64::from(p[1]) + y0 as f64 + 0.5,
            ]
        };
        let geometry = self.pair_geometry(band.i, band.j);
        let fi: Vec<_> = pi.iter().map(|&p| self.ray(band.i, canvas(p))).collect();
        let fj: Vec<_> = pj.iter().map(|&p| self.ray(band.j, canvas(p))).collect();
        let found = match_mutual_where(&di, &dj, options.ratio, |a, b| {
            self.canvas_distance(canvas(pi[a]), canvas(pj[b])) <= options.max_shift_px
                && geometry
                    .error_px(&fi[a], &fj[b])
                    .is_some_and(|e| e <= options.search_px)
        })?;
        times.matching += t.elapsed();
        let t = Instant::now();
        // Each match's two positions, aligned to a fraction of a pixel
        // (camera i's corner at its nearest pixel, where camera j's patch
        // lies); a match whose patches do not align keeps the detector's.
        let detected = |m: &Match| (*m, pi[m.query], pj[m.train], false);
        let aligned: Vec<(Match, [f32; 2], [f32; 2], bool)> = if options.align_radius_px == 0 {
            found.iter().map(detected).collect()
        } else {
            let (gi, gj) = (band_gray(band, warp_i)?, band_gray(band, warp_j)?);
            let aligner = Aligner::new(AlignOptions {
                radius: options.align_radius_px,
                ..AlignOptions::default()
            });
            found
                .iter()
                .map(|m| {
                    let (a, b) = (pi[m.query], pj[m.train]);
                    let at = [a[0].round(), a[1].round()];
                    let guess = [b[0] + at[0] - a[0], b[1] + at[1] - a[1]];
                    // (Corners lie inside the band: the rounding is a pixel.)
                    let pixel = [at[0].max(0.0) as usize, at[1].max(0.0) as usize];
                    aligner
                        .align(&gi, pixel, &gj, guess)
                        .map_or_else(|| detected(m), |p| (*m, at, p, true))
                })
                .collect()
        };
        times.align += t.elapsed();
        let t = Instant::now();
        let mut matches: Vec<FeatureMatch> = aligned
            .iter()
            .map(|(m, a, b, aligned)| FeatureMatch {
                at_i: canvas(*a),
                at_j: canvas(*b),
                distance: m.distance,
                aligned: *aligned,
                inlier: false,
            })
            .collect();
        let mut result = PairMatches {
            i: band.i,
            j: band.j,
            corners: (corners_i.len(), corners_j.len()),
            matches: Vec::new(),
            inliers: 0,
            rotation: None,
            error_before_px: None,
            error_after_px: None,
            patches: Vec::new(),
            problem: None,
        };
        // (A match that kept the detector's positions has its rays already.)
        let rays: Vec<RayPair> = matches
            .iter()
            .zip(&aligned)
            .map(|(m, (found, ..))| {
                if m.aligned {
                    (self.ray(band.i, m.at_i), self.ray(band.j, m.at_j))
                } else {
                    (fi[found.query], fj[found.train])
                }
            })
            .collect();
        let rotation = ransac(&geometry, &rays, &mut matches, options);
        result.inliers = matches.iter().filter(|m| m.inlier).count();
        if result.inliers < options.min_inliers {
            result.problem = Some(format!(
                "{} matches, {} inliers of {} corners and {}: fewer than the {} needed for a rotation and a ratio",
                matches.len(),
                result.inliers,
                corners_i.len(),
                corners_j.len(),
                options.min_inliers
            ));
            for m in &mut matches {
                m.inlier = false;
            }
            result.inliers = 0;
        } else if let Some(q) = rotation {
            let errors = |q: &Rotation3<f64>| -> Vec<f64> {
                rays.iter()
                    .zip(&matches)
                    .filter(|(_, m)| m.inlier)
                    .filter_map(|((a, b), _)| geometry.error_px(a, &(q * b)))
                    .collect()
            };
            result.error_before_px = median(&mut errors(&Rotation3::identity()));
            result.error_after_px = median(&mut errors(&q));
            result.rotation = Some(q);
            result.patches = matches
                .iter()
                .filter(|m| m.inlier)
                .filter_map(|m| patch_pair(band, warp_i, warp_j, m, options.patch_px))
                .collect();
        }
        result.matches = matches;
        times.ransac += t.elapsed();
        Ok(result)
    }

    /// The distance of two canvas positions, columns wrapped around.
    pub fn canvas_distance(&self, a: [f64; 2], b: [f64; 2]) -> f64 {
        let w = self.spec.width as f64;
        let dc = (a[0] - b[0]).rem_euclid(w);
        dc.min(w - dc).hypot(a[1] - b[1])
    }

    /// Camera `k`'s ray (unit, vehicle frame) through the cylinder's point
    /// at a canvas position.
    pub(super) fn ray(&self, k: usize, at: [f64; 2]) -> Vector3<f64> {
        (self.point(at[0], at[1]) - self.origins[k]).normalize()
    }

    /// What the reprojection error of a pair's matches needs.
    pub(super) fn pair_geometry(&self, i: usize, j: usize) -> PairGeometry {
        PairGeometry {
            o_i: self.origins[i],
            o_j: self.origins[j],
            px_per_rad: self.spec.width as f64 / std::f64::consts::TAU,
        }
    }
}

/// The patch means and saturated fractions around an inlier in both warps,
/// or `None` when the patch leaves where both cameras see.
fn patch_pair(
    band: &OverlapBand,
    warp_i: &Canvas,
    warp_j: &Canvas,
    m: &FeatureMatch,
    side: usize,
) -> Option<PatchPair> {
    let [x0, y0, w, h] = band.rect;
    let half = (side / 2) as isize;
    let stats = |warp: &Canvas, at: [f64; 2]| -> Option<(f32, f32)> {
        let cx = (at[0] - x0 as f64 - 0.5).round() as isize;
        let cy = (at[1] - y0 as f64 - 0.5).round() as isize;
        let (mut sum, mut sat) = (0u32, 0u32);
        for y in cy - half..=cy + half {
            for x in cx - half..=cx + half {
                if x < 0 || y < 0 || x as usize >= w || y as usize >= h {
                    return None;
                }
                let p = y as usize * w + x as usize;
                if band.both[p] == 0 {
                    return None;
                }
                let v = warp.data[p];
                sum += u32::from(v);
                sat +=
                    u32::from(f32::from(v) / 255.0 >= crate::exposure::metering::SATURATED_LEVEL);
            }
        }
        let n = (side * side) as f32;
        Some((sum as f32 / n / 255.0, sat as f32 / n))
    };
    let (mean_i, saturated_i) = stats(warp_i, m.at_i)?;
    let (mean_j, saturated_j) = stats(warp_j, m.at_j)?;
    Some(PatchPair {
        mean_i,
        saturated_i,
        mean_j,
        saturated_j,
    })
}

#[cfg(test)]
mod tests {
    use super::ransac::fit_rotation;
    use super::*;

    /// Points spread over a 30° × 50° overlap 3 to 40 m away, seen from two
    /// centres 1.7 m apart; camera `j` turned by `turn`.
    fn rays(turn: &Rotation3<f64>) -> (PairGeometry, Vec<RayPair>) {
        let g = PairGeometry {
            o_i: Vector3::new(2.3, 0.0, 0.9),
            o_j: Vector3::new(1.0, 1.0, 1.0),
            px_per_rad: 2048.0 / std::f64::consts::TAU,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let rays = (0..60)
            .map(|_| {
                let az: f64 = rng.gen_range(30f64..60.0).to_radians();
                let el: f64 = rng.gen_range(-25f64..25.0).to_radians();
                let d: f64 = rng.gen_range(3.0..40.0);
                let p = d * Vector3::new(az.cos() * el.cos(), az.sin() * el.cos(), el.sin());
                let f_i = (p - g.o_i).normalize();
                // Camera j, turned, reports its ray turned back.
                let f_j = turn.inverse() * (p - g.o_j).normalize();
                (f_i, f_j)
            })
            .collect();
        (g, rays)
    }

    #[test]
    fn a_point_on_the_ground_has_no_ground_error_until_a_camera_turns() {
        let g = PairGeometry {
            o_i: Vector3::new(2.3, 0.0, 0.9),
            o_j: Vector3::new(1.0, 1.0, 1.0),
            px_per_rad: 2048.0 / std::f64::consts::TAU,
        };
        let p = Vector3::new(5.0, 4.0, 0.0);
        let (f_i, f_j) = ((p - g.o_i).normalize(), (p - g.o_j).normalize());
        assert!(g.ground_error_px(&f_i, &f_j).unwrap() < 1e-9);
        // A turn of camera j about the vertical, which the epipolar error
        // hardly sees, is a ground error of about its angle.
        let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.5f64.to_radians());
        let e = g.ground_error_px(&f_i, &(turn * f_j)).unwrap();
        let want = 0.5f64.to_radians() * g.px_per_rad;
        assert!(e > 0.5 * want, "{e} px for {want} px");
        // A ray that goes up, or meets the ground too far, is not on it.
        let up = Vector3::new(1.0, 0.0, 0.1).normalize();
        assert!(g.ground_error_px(&up, &f_j).is_none());
        let far = Vector3::new(1.0, 0.0, -0.01).normalize();
        assert!(g.ground_error_px(&far, &f_j).is_none());
    }

    #[test]
    fn the_fitted_rotation_puts_every_ray_on_its_epipolar_plane() {
        let none = Rotation3::identity();
        let (g, r) = rays(&none);
        assert!(r.iter().all(|(a, b)| g.error_px(a, b).unwrap() < 1e-9));
        let q = fit_rotation(&g, &r, none).unwrap();
        assert!(q.angle().to_degrees() < 1e-6, "{}", q.angle().to_degrees());
        let turn = Rotation3::from_scaled_axis(Vector3::new(0.01, -0.015, 0.02));
        let (g, r) = rays(&turn);
        let before: f64 = r.iter().map(|(a, b)| g.error_px(a, b).unwrap()).sum();
        let q = fit_rotation(&g, &r, none).unwrap();
        let after: f64 = r
            .iter()
            .map(|(a, b)| g.error_px(a, &(q * b)).unwrap())
            .sum();
        eprintln!(
            "turned {:.3}°: error {before:.1} -> {after:.3} px (sum), fitted {:.3}°, {:.3}° from the truth",
            turn.angle().to_degrees(),
            q.angle().to_degrees(),
            (q * turn.inverse()).angle().to_degrees()
        );
        assert!(after < 0.05 * before, "{before} -> {after}");
    }
}
