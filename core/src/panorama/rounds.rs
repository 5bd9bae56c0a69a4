//! Refinement in rounds: what the product runs (`rigview panorama
//! --refine`, the window's Refine button, `--refine-every`).
//!
//! One refinement ([`Panorama::refine`]) starts from the matches of a
//! panorama built on the calibration it corrects. When that calibration is
//! a degree or two off, the floor of the cylinder lines the ground up
//! poorly, few matches are taken for points on the ground, and the result
//! is a few tenths of a degree off. So the refinement runs in rounds: each
//! builds the panorama of the rig the last one refined, matches on it, and
//! refines. The inliers of the rounds are pooled (turned to the current
//! rig: [`InlierRays::turned`]) and refined together, so that the result
//! does not follow the corners one matching happens to give. A round that
//! turned a camera by more than [`POOL_WITHIN_DEG`] (the first, when the
//! calibration was off) empties the pool: its inliers were matched on a
//! rig that far from the refined one.
//!
//! A round after the first is not taken, and the rounds stop, if it leaves
//! some pair's inliers further from their epipolar planes than the
//! calibration given did (by [`WORSE_PX`]): the ground stage trusts the
//! calibration's camera heights, and a scene whose ground is not where they
//! put it would otherwise walk the rotations away round after round.
//!
//! The matching cylinder is the view's cylinder with a floor
//! ([`CylinderSpec::floor`]) at [`MATCH_WIDTH`] columns, whatever the view's
//! own width: the matching's gates ([`MatchOptions::search_px`], 30 pixels
//! by default, 5.3° there) then hold a calibration a few degrees off.

use nalgebra::Rotation3;
use rigview_calib::rig::Rig;

use super::{
    CylinderSpec, Detector, InlierRays, MatchOptions, PairMatches, Panorama, PanoramaOptions,
    RefineOptions, Refinement,
};
use crate::error::{Error, Result};
use crate::image::FrameView;

/// The width of the matching cylinder, pixels (360°).
pub const MATCH_WIDTH: usize = 2048;

/// The largest turn of a camera in a round (degrees) after which that
/// round's inliers, and the pool's, are kept for the next rounds.
pub const POOL_WITHIN_DEG: f64 = 0.25;

/// How much a pair's median epipolar error (pixels) may exceed the
/// calibration's after a round for the round to be taken.
pub const WORSE_PX: f64 = 0.05;

/// The most rounds [`refine_in_rounds`] runs.
pub const MAX_ROUNDS: usize = 20;

/// Options of [`refine_in_rounds`].
#[derive(Clone, Debug, PartialEq)]
pub struct RoundsOptions {
    /// Rounds of matching and refinement (at least 1).
    pub rounds: usize,
    /// Each refinement's options.
    pub refine: RefineOptions,
    /// The matching's options.
    pub matching: MatchOptions,
}

impl Default for RoundsOptions {
    fn default() -> Self {
        Self {
            rounds: 4,
            refine: RefineOptions::default(),
            matching: MatchOptions::default(),
        }
    }
}

/// What [`refine_in_rounds`] found.
#[derive(Clone, Debug)]
pub struct Rounds {
    /// The refined rig.
    pub rig: Rig,
    /// Per camera, its rotation from the calibration given to the refined
    /// one (about its centre, vehicle frame).
    pub rotations: Vec<Rotation3<f64>>,
    /// Per round, its matches (on the matching cylinder) and its
    /// refinement; the pairs' errors of a round from the second on are
    /// those of the pooled inliers.
    pub rounds: Vec<(Vec<PairMatches>, Refinement)>,
    /// Per pair with inliers in the last pool (or the last round's, if
    /// none was kept): cameras `i` and `j`, and the median epipolar error
    /// of those inliers with the calibration given and with the refined
    /// rig, pixels of the matching cylinder.
    pub errors: Vec<(usize, usize, Option<f64>, Option<f64>)>,
    /// Why the rounds stopped before the last, if they did.
    pub stopped: Option<String>,
}

/// The cylinder the refinement matches on: `spec` with a floor, at
/// [`MATCH_WIDTH`] columns and as many rows as keep the view's aspect.
pub fn matching_spec(spec: &CylinderSpec) -> CylinderSpec {
    let rows = (spec.height as f64 * MATCH_WIDTH as f64 / spec.width as f64).round() as usize;
    CylinderSpec {
        width: MATCH_WIDTH,
        height: rows.max(8),
        floor: true,
        ..spec.clone()
    }
}

/// Refines the rotations of `rig`'s cameras from one frame set (`frames`,
/// in rig order) in rounds: see the module documentation. `spec` is the
/// view's cylinder (its band and radius are kept).
pub fn refine_in_rounds(
    rig: &Rig,
    spec: &CylinderSpec,
    panorama: &PanoramaOptions,
    frames: &[FrameView<'_>],
    detector: &Detector<'_>,
    options: &RoundsOptions,
) -> Result<Rounds> {
    if !(1..=MAX_ROUNDS).contains(&options.rounds) {
        return Err(Error::InvalidParameter {
            name: "refine.rounds",
            value: options.rounds as f64,
            expected: "1 to 20 rounds",
        });
    }
    let spec = matching_spec(spec);
    let mut current = rig.clone();
    let mut total = vec![Rotation3::identity(); rig.cameras.len()];
    let mut pool = InlierRays::default();
    let mut rounds = Vec::with_capacity(options.rounds);
    let mut errors = Vec::new();
    let mut stopped = None;
    for round in 1..=options.rounds {
        let pano = Panorama::build(&current, &spec, panorama)?;
        let (matches, _) = pano.match_pairs(frames, detector, &options.matching)?;
        let mut tried = pool.clone();
        tried.extend(pano.inlier_rays(&matches));
        let refinement = pano.refine_rays(&tried, &options.refine)?;
        let turned = refinement
            .rotations
            .iter()
            .map(|q| q.angle())
            .fold(0.0, f64::max);
        let tried = tried.turned(&refinement.rotations);
        let whole: Vec<Rotation3<f64>> = total
            .iter()
            .zip(&refinement.rotations)
            .map(|(t, q)| q * t)
            .collect();
        // The bound holds for the rounds together, too.
        let bound = options.refine.bound_deg;
        if let Some((k, t)) = whole
            .iter()
            .enumerate()
            .find(|(_, t)| t.angle().to_degrees() > bound + 1e-9)
        {
            return Err(Error::invalid(
                "panorama refinement (the calibration is kept)",
                format!("camera `{}`'s turn in {round} rounds", rig.cameras[k].name),
                format!("at most the bound of {bound}°"),
                format_args!("{:.2}°", t.angle().to_degrees()),
            ));
        }
        // The errors of these inliers with the calibration given (the
        // whole turn undone) and with this round's rig.
        let back: Vec<Rotation3<f64>> = whole.iter().map(|t| t.inverse()).collect();
        let round_errors: Vec<_> = pano
            .ray_errors(&tried, &back)
            .into_iter()
            .zip(pano.ray_errors(&tried, &[]))
            .map(|((i, j, before), (_, _, after))| (i, j, before, after))
            .collect();
        // A round that leaves a pair's inliers further from their
        // epipolar planes than the calibration given did is not taken (a
        // scene whose ground is not where the calibration puts it).
        if round > 1 {
            let worse = round_errors
                .iter()
                .find(|(_, _, b, a)| matches!((b, a), (Some(b), Some(a)) if *a > b + WORSE_PX));
            if let Some((i, j, b, a)) = worse {
                stopped = Some(format!(
                    "round {round} would raise the median error of pair {}–{} from {:.2} to {:.2} px; the rig of round {} is kept",
                    rig.cameras[*i].name,
                    rig.cameras[*j].name,
                    b.unwrap_or(f64::NAN),
                    a.unwrap_or(f64::NAN),
                    round - 1
                ));
                break;
            }
        }
        current = refinement.apply(&current)?;
        total = whole;
        errors = round_errors;
        // Inliers matched on a rig this far from the refined one are not
        // kept for the next rounds.
        pool = if turned > POOL_WITHIN_DEG.to_radians() {
            InlierRays::default()
        } else {
            tried
        };
        rounds.push((matches, refinement));
    }
    Ok(Rounds {
        rig: current,
        rotations: total,
        rounds,
        errors,
        stopped,
    })
}
