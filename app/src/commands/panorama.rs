//! `rigview panorama`: still images of a calibrated rig composed into a
//! cylindrical panorama, with each overlap's feature matches and
//! brightness ratio reported, and optionally the cameras' rotations
//! refined from the matches (and the refined rig saved).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use rigview_calib::formats;
use rigview_core::exposure::BalanceParams;
use rigview_core::panorama::{
    refine_in_rounds, CylinderSpec, MatchOptions, Panorama, PanoramaOptions, RefineOptions,
    RoundsOptions, MATCH_WIDTH,
};
use rigview_core::surround::{BlendMode, Canvas, Composer};

use super::surround;
use crate::report::panorama::{draw_matches, pair_lines, px, times_line};
use crate::session::view::detect;

/// What `rigview panorama` composes, matches and refines.
#[derive(Clone, Debug)]
pub struct PanoramaJob {
    /// The rig: a rig file or calibration in any supported format.
    pub rig: PathBuf,
    /// One image per camera, in rig order, or as `NAME=PATH`.
    pub images: Vec<String>,
    /// How overlapping cameras are mixed.
    pub blend: BlendMode,
    /// Where to write the panorama (PNG).
    pub out: PathBuf,
    /// The cylinder.
    pub cylinder: CylinderSpec,
    /// Where to write the panorama with each pair's matches drawn on it.
    pub matches_out: Option<PathBuf>,
    /// Whether to refine the cameras' rotations from the matches.
    pub refine: bool,
    /// The largest rotation the refinement may give a camera, degrees.
    pub refine_bound_deg: f64,
    /// Rounds of matching and refinement.
    pub rounds: usize,
    /// Where to save the refined rig.
    pub save_rig: Option<PathBuf>,
}

/// `rigview panorama`: composes the images, writes the panorama, and
/// reports each pair's matches and brightness ratio.
pub fn run(job: &PanoramaJob, out: &mut dyn Write) -> Result<()> {
    let (mut rig, images) = surround::load(&job.rig, &job.images)?;
    let mut pano = Panorama::build(&rig, &job.cylinder, &PanoramaOptions::default())
        .context("building the panorama")?;
    let frames = surround::frames(&images)?;
    let (mut pairs, times) = pano
        .match_pairs(&frames, &detect, &MatchOptions::default())
        .context("matching features in the overlaps")?;
    for line in pair_lines(&rig, &pairs, &BalanceParams::default()) {
        writeln!(out, "{line}")?;
    }
    writeln!(out, "{}", times_line(&times))?;
    if job.refine {
        let options = RoundsOptions {
            rounds: job.rounds,
            refine: RefineOptions {
                bound_deg: job.refine_bound_deg,
                ..RefineOptions::default()
            },
            ..RoundsOptions::default()
        };
        let refined = refine_in_rounds(
            &rig,
            &job.cylinder,
            &PanoramaOptions::default(),
            &frames,
            &detect,
            &options,
        )
        .context("refining the cameras' rotations")?;
        for (k, (matches, r)) in refined.rounds.iter().enumerate() {
            let inliers: usize = matches.iter().map(|p| p.inliers).sum();
            let on_ground: usize = r.pairs.iter().map(|p| p.on_ground).sum();
            writeln!(
                out,
                "refinement round {}: {inliers} inliers matched, {} refined from ({on_ground} on the ground)",
                k + 1,
                r.pairs.iter().map(|p| p.inliers).sum::<usize>()
            )?;
        }
        for &(i, j, before, after) in &refined.errors {
            writeln!(
                out,
                "refined pair {}–{}: median reprojection error {} before, {} after (on the {}-column matching cylinder)",
                rig.cameras[i].name,
                rig.cameras[j].name,
                px(before),
                px(after),
                MATCH_WIDTH
            )?;
        }
        if let Some(why) = &refined.stopped {
            writeln!(out, "refinement stopped: {why}")?;
        }
        for (cam, q) in rig.cameras.iter().zip(&refined.rotations) {
            writeln!(
                out,
                "refined {}: turned by {:.3}°",
                cam.name,
                q.angle().to_degrees()
            )?;
        }
        rig = refined.rig;
        pano = Panorama::build(&rig, &job.cylinder, &PanoramaOptions::default())
            .context("building the refined panorama")?;
        pairs = pano
            .match_pairs(&frames, &detect, &MatchOptions::default())
            .context("matching features with the refined rotations")?
            .0;
        if let Some(path) = &job.save_rig {
            let written = formats::save(&rig, path, None)
                .with_context(|| format!("saving the refined rig to {}", path.display()))?;
            for p in written {
                writeln!(out, "wrote the refined rig to {}", p.display())?;
            }
        }
    }
    let mut canvas = Canvas::new(0, 0, 3);
    Composer::new().compose(&pano, &frames, job.blend, &mut canvas)?;
    surround::save(&canvas, &job.out)?;
    let spec = pano.spec();
    writeln!(
        out,
        "wrote {} ({}×{} px, radius {} m, {}° below to {}° above the horizon, {} blending)",
        job.out.display(),
        canvas.width,
        canvas.height,
        spec.radius_m,
        spec.below_deg,
        spec.above_deg,
        job.blend.name()
    )?;
    for (cam, mask) in rig.cameras.iter().zip(pano.source_masks()) {
        writeln!(
            out,
            "{}: {:.1} % of the image reaches the panorama",
            cam.name,
            100.0 * mask.coverage()
        )?;
    }
    if let Some(path) = &job.matches_out {
        draw_matches(&mut canvas, &pairs);
        surround::save(&canvas, path)?;
        writeln!(
            out,
            "wrote the matches over the panorama to {}",
            path.display()
        )?;
    }
    Ok(())
}
