//! The calibration tools of `rigview calib`: show, convert, and make
//! intrinsics and ground extrinsics, each reporting to a writer.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use rigview_calib::formats::{self, Format, Loaded};
use rigview_calib::rig::{Camera, Frame, Rig};
use rigview_calib::tools::ground::{self, GroundLayout};
use rigview_calib::tools::intrinsics::{self, Board, ImageStatus};
use rigview_calib::{report, ModelKind};

/// How to read a calibration: its format and camera model where the file
/// does not say (`None`: told from the file).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reading {
    /// The format.
    pub format: Option<Format>,
    /// The camera model for OpenCV files that do not name one.
    pub model: Option<ModelKind>,
}

impl Reading {
    /// Loads `path` (a file, or a folder of per-camera files).
    pub fn load(self, path: &Path) -> Result<Loaded> {
        Ok(formats::load(path, self.format, self.model)?)
    }
}

/// Where to write a calibration, and in which format (`None`: `.xml` is
/// OpenCV XML, anything else rig YAML).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Writing {
    /// A file; for per-camera formats and a rig of several cameras, a
    /// folder (ending in `/`) or a path containing `{camera}`.
    pub path: PathBuf,
    /// The format.
    pub format: Option<Format>,
}

impl Writing {
    /// Writes `rig` and says which files it wrote.
    fn save(&self, rig: &Rig, out: &mut dyn Write) -> Result<()> {
        for w in formats::save(rig, &self.path, self.format)? {
            writeln!(out, "wrote {}", w.display())?;
        }
        Ok(())
    }
}

/// Prints a summary of the calibration at `path` and its checks: field of
/// view, principal point offset, and where each camera sees the ground.
pub fn show(path: &Path, reading: Reading, out: &mut dyn Write) -> Result<()> {
    let loaded = reading.load(path)?;
    write!(out, "{}", report::summary(&loaded))?;
    Ok(())
}

/// Converts the calibration at `input` to `output`.
pub fn convert(
    input: &Path,
    reading: Reading,
    model: Option<ModelKind>,
    output: &Writing,
    out: &mut dyn Write,
) -> Result<()> {
    let mut rig = reading.load(input)?.rig;
    if let Some(model) = model {
        for c in &mut rig.cameras {
            let fit = rigview_calib::convert::fit_model(&c.intrinsics, model)
                .with_context(|| format!("fitting camera \"{}\" to {model:?}", c.name))?;
            writeln!(
                out,
                "{}: {} → {}: reprojection error {:.3} px RMS, {:.3} px at most, over {} of {} rays \
                 of the image; it sees {:.1}° from the axis, the fit reaches {:.1}°",
                c.name,
                c.intrinsics.distortion.model_name(),
                fit.intrinsics.distortion.model_name(),
                fit.rms_px,
                fit.max_px,
                fit.fitted,
                fit.rays,
                fit.source_fov_deg,
                fit.reach_deg
            )?;
            c.intrinsics = fit.intrinsics;
        }
    }
    output.save(&rig, out)
}

/// One camera's intrinsic calibration from chessboard images.
#[derive(Clone, Debug)]
pub struct IntrinsicsJob {
    /// Chessboard images (PNG or JPEG), all of one camera.
    pub images: Vec<PathBuf>,
    /// The board.
    pub board: Board,
    /// The lens model to fit.
    pub model: ModelKind,
    /// The camera's name in the output.
    pub name: String,
    /// Where to write the result.
    pub output: Option<Writing>,
}

/// Calibrates a camera's intrinsics and prints the fit, image by image.
pub fn intrinsics(job: &IntrinsicsJob, out: &mut dyn Write) -> Result<()> {
    let r = intrinsics::calibrate(&job.images, job.board, job.model)
        .context("intrinsic calibration")?;
    let k = &r.intrinsics;
    writeln!(
        out,
        "{} model from {} of {} images: RMS reprojection error {:.4} px (OpenCV's figure {:.4} px)",
        k.distortion.model_name(),
        r.used(),
        r.images.len(),
        r.rms_px,
        r.opencv_rms_px
    )?;
    writeln!(
        out,
        "f = ({:.3}, {:.3}) px, principal point ({:.3}, {:.3}) px, distortion {:?}",
        k.fx,
        k.fy,
        k.cx,
        k.cy,
        k.distortion.coefficients()
    )?;
    for img in &r.images {
        match &img.status {
            ImageStatus::Used { rms_px } => {
                writeln!(out, "  used     {} ({rms_px:.3} px)", img.file.display())?;
            }
            ImageStatus::Rejected { reason } => {
                writeln!(out, "  rejected {}: {reason}", img.file.display())?;
            }
        }
    }
    if let Some(o) = &job.output {
        let rig = Rig::new(
            Frame::Vehicle,
            vec![Camera::new(job.name.clone(), *k)],
            vec![],
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?;
        o.save(&rig, out)?;
    }
    Ok(())
}

/// Camera poses from a checkerboard mat of known layout on the ground.
#[derive(Clone, Debug)]
pub struct GroundJob {
    /// The rig whose intrinsics to use.
    pub rig: PathBuf,
    /// How to read it.
    pub reading: Reading,
    /// The ground layout file (which camera sees which mat in which image).
    pub layout: PathBuf,
    /// Where to write the rig with the solved poses.
    pub output: Option<Writing>,
}

/// Solves the cameras' poses on the ground and prints each fit.
pub fn ground(job: &GroundJob, out: &mut dyn Write) -> Result<()> {
    let loaded = job.reading.load(&job.rig)?;
    let layout = GroundLayout::load(&job.layout)?;
    if layout.views.is_empty() {
        bail!("{}: the layout has no views", job.layout.display());
    }
    let (rig, results) = ground::calibrate(&loaded.rig, &layout)?;
    for g in &results {
        let t = g.pose.translation();
        let [yaw, pitch, roll] = g.pose.ypr_deg();
        writeln!(
            out,
            "{}: {} corners, reprojection RMS {:.3} px (max {:.3} px); at ({:.3}, {:.3}, {:.3}) m, yaw {yaw:.2}°, pitch {pitch:.2}°, roll {roll:.2}°",
            g.camera, g.corners, g.rms_px, g.max_px, t.x, t.y, t.z
        )?;
    }
    if let Some(o) = &job.output {
        o.save(&rig, out)?;
    }
    Ok(())
}
