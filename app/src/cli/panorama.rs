//! `rigview panorama`: compose still images of a calibrated rig into a
//! cylindrical panorama, and match features in its overlaps.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use rigview_core::panorama::CylinderSpec;

use super::surround::RigImages;

/// Options of `rigview panorama`.
#[derive(Debug, Args)]
pub struct PanoramaArgs {
    /// The rig, its images and the blending.
    #[command(flatten)]
    pub input: RigImages,
    /// Where to write the panorama (PNG).
    #[arg(long)]
    pub out: PathBuf,
    /// The cylinder's radius, metres: what stands this far from the rig's
    /// centre lines up across the seams.
    #[arg(long, default_value_t = 10.0)]
    pub radius_m: f64,
    /// Canvas width, pixels (360°).
    #[arg(long, default_value_t = 4096)]
    pub width: usize,
    /// Canvas height, pixels.
    #[arg(long, default_value_t = 760)]
    pub height: usize,
    /// Degrees shown below the horizon.
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true)]
    pub below_deg: f64,
    /// Degrees shown above the horizon.
    #[arg(long, default_value_t = 35.0, allow_negative_numbers = true)]
    pub above_deg: f64,
    /// Also write the panorama with each pair's matches drawn on it (inliers
    /// green, outliers red) to this PNG.
    #[arg(long)]
    pub matches_out: Option<PathBuf>,
    /// Refine the cameras' rotations from the matches (in rounds, on a
    /// cylinder with a floor) and compose the panorama with them; each
    /// pair's median reprojection error is reported before and after.
    #[arg(long)]
    pub refine: bool,
    /// The largest rotation the refinement may give a camera, degrees.
    #[arg(long, default_value_t = 3.0, requires = "refine")]
    pub refine_bound_deg: f64,
    /// Rounds of matching and refinement, each on the rig the last one
    /// refined (on a cylinder with a floor).
    #[arg(long, default_value_t = 4, requires = "refine")]
    pub rounds: usize,
    /// Save the refined rig to this file (any format `rigview calib
    /// convert` writes; the rig file for `.yaml`).
    #[arg(long, requires = "refine")]
    pub save_rig: Option<PathBuf>,
}

impl PanoramaArgs {
    /// The cylinder asked for.
    pub fn spec(&self) -> CylinderSpec {
        CylinderSpec {
            width: self.width,
            height: self.height,
            radius_m: self.radius_m,
            below_deg: self.below_deg,
            above_deg: self.above_deg,
            ..CylinderSpec::default()
        }
    }
}

/// Runs `rigview panorama`, reporting to `out`.
pub fn run(args: &PanoramaArgs, out: &mut dyn Write) -> Result<()> {
    crate::panorama::run_stills(args, out)
}
