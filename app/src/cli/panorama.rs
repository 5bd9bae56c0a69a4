//! `rigview panorama`: compose still images of a calibrated rig into a
//! cylindrical panorama, and match features in its overlaps.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use rigview_core::panorama::CylinderSpec;

use super::surround::RigImages;
use crate::commands::panorama::{self, PanoramaJob};

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

    /// The job these options ask for.
    pub fn job(&self) -> PanoramaJob {
        PanoramaJob {
            rig: self.input.rig.clone(),
            images: self.input.images.clone(),
            blend: self.input.blend,
            out: self.out.clone(),
            cylinder: self.spec(),
            matches_out: self.matches_out.clone(),
            refine: self.refine,
            refine_bound_deg: self.refine_bound_deg,
            rounds: self.rounds,
            save_rig: self.save_rig.clone(),
        }
    }
}

/// Runs `rigview panorama`, reporting to `out`.
pub fn run(args: &PanoramaArgs, out: &mut dyn Write) -> Result<()> {
    panorama::run(&args.job(), out)
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use clap::Parser;
    use rigview_calib::formats;

    use super::*;

    /// `rigview panorama`'s options alone on a command line.
    #[derive(Parser)]
    struct Line {
        #[command(flatten)]
        args: PanoramaArgs,
    }

    fn data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz")
    }

    fn args(extra: &[&str]) -> PanoramaArgs {
        let d = data();
        let mut argv: Vec<String> = vec!["rigview".into(), "--rig".into()];
        argv.push(d.display().to_string());
        argv.push("--images".into());
        for n in ["front", "left", "back", "right"] {
            argv.push(format!("{n}={}", d.join(format!("{n}.png")).display()));
        }
        argv.extend(extra.iter().map(|s| s.to_string()));
        Line::try_parse_from(argv).unwrap().args
    }

    #[test]
    fn composes_the_real_rig_and_reports_every_pair() {
        let dir = std::env::temp_dir().join(format!("rigview-panorama-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (png, overlay) = (dir.join("pano.png"), dir.join("matches.png"));
        let rig_out = dir.join("refined.rig.yaml");
        let a = args(&[
            "--out",
            png.to_str().unwrap(),
            "--matches-out",
            overlay.to_str().unwrap(),
            "--width",
            "2048",
            "--height",
            "380",
            "--blend",
            "seams",
            "--radius-m",
            "8",
            "--refine",
            "--save-rig",
            rig_out.to_str().unwrap(),
        ]);
        let mut report = Vec::new();
        run(&a, &mut report).unwrap();
        let report = String::from_utf8(report).unwrap();
        println!("{report}");
        for pair in ["front–left", "front–right", "back–left", "back–right"] {
            // The rig file's neighbour order, either way round.
            let (x, y) = pair.split_once('–').unwrap();
            assert!(
                report.contains(&format!("pair {x}–{y}"))
                    || report.contains(&format!("pair {y}–{x}")),
                "{pair}: {report}"
            );
        }
        assert!(report.contains("radius 8 m"), "{report}");
        assert!(report.contains("refined pair front–left"), "{report}");
        // The refined rig reads back, every camera within the bound.
        let refined = formats::load(&rig_out, None, None).unwrap().rig;
        let original = formats::load(&data(), None, None).unwrap().rig;
        let turn = |k: usize| {
            original.cameras[k]
                .pose
                .unwrap()
                .rotation_angle_to(&refined.cameras[k].pose.unwrap())
                .to_degrees()
        };
        assert!((0..4).all(|k| turn(k) <= 3.0 + 1e-6));
        assert!((0..4).any(|k| turn(k) > 0.0));
        for p in [&png, &overlay] {
            let img = image::open(p).unwrap();
            assert_eq!((img.width(), img.height()), (2048, 380));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_wrong_image_size_names_the_file_and_the_camera() {
        let d = data();
        let mut a = args(&["--out", "/nonexistent/never.png"]);
        a.input.images[1] = format!("left={}", d.join("car.png").display());
        let e = run(&a, &mut Vec::new()).unwrap_err();
        let e = format!("{e:#}");
        assert!(e.contains("car.png") && e.contains("camera `left`"), "{e}");
    }
}
