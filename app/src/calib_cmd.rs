//! `rigview calib`: show, convert and make calibrations.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use rigview_calib::formats::{self, Format};
use rigview_calib::rig::{Camera, Frame, Rig};
use rigview_calib::tools::ground::{self, GroundLayout};
use rigview_calib::tools::intrinsics::{self, Board, ImageStatus};
use rigview_calib::{report, ModelKind};

/// A camera model on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Model {
    /// OpenCV fisheye (Kannala–Brandt, k1..k4).
    Fisheye,
    /// Pinhole with radial-tangential distortion (k1, k2, p1, p2, k3).
    Pinhole,
}

impl From<Model> for ModelKind {
    fn from(m: Model) -> Self {
        match m {
            Model::Fisheye => ModelKind::Fisheye,
            Model::Pinhole => ModelKind::Pinhole,
        }
    }
}

/// A calibration format on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// rigview's rig YAML.
    Rig,
    /// OpenCV FileStorage YAML (one file a camera).
    OpencvYaml,
    /// OpenCV FileStorage XML (one file a camera).
    OpencvXml,
    /// Kalibr camchain YAML.
    Kalibr,
    /// ROS camera_info YAML (one file a camera).
    Ros,
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Rig => Format::Rig,
            FormatArg::OpencvYaml => Format::OpenCvYaml,
            FormatArg::OpencvXml => Format::OpenCvXml,
            FormatArg::Kalibr => Format::Kalibr,
            FormatArg::Ros => Format::Ros,
        }
    }
}

/// Options of `rigview calib`.
#[derive(Debug, Args)]
pub struct CalibArgs {
    #[command(subcommand)]
    pub command: CalibCommand,
}

/// The calibration tools.
#[derive(Debug, Subcommand)]
pub enum CalibCommand {
    /// Summarise a calibration and check it: field of view, principal point
    /// offset, and where each camera sees the ground.
    Show(ShowArgs),
    /// Convert a calibration between formats (rig YAML, OpenCV YAML/XML,
    /// Kalibr, ROS camera_info).
    Convert(ConvertArgs),
    /// Calibrate one camera's intrinsics from chessboard images (OpenCV).
    Intrinsics(IntrinsicsArgs),
    /// Calibrate camera poses from a checkerboard mat of known layout lying
    /// on the ground.
    Ground(GroundArgs),
}

/// How to read an input calibration.
#[derive(Debug, Args)]
pub struct InputArgs {
    /// Input format (default: told from the file).
    #[arg(long, value_enum)]
    pub from: Option<FormatArg>,
    /// Camera model for OpenCV files that do not say which (4 coefficients
    /// fit both).
    #[arg(long, value_enum)]
    pub model: Option<Model>,
}

/// Options of `rigview calib show`.
#[derive(Debug, Args)]
pub struct ShowArgs {
    /// A calibration file, or a folder of per-camera files (for example the
    /// four OpenCV files of a surround-view rig).
    pub file: PathBuf,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Options of `rigview calib convert`.
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Input file or folder.
    pub input: PathBuf,
    /// Output file. For per-camera formats and a rig of several cameras, a
    /// folder (ending in /) or a path containing {camera}.
    pub output: PathBuf,
    #[command(flatten)]
    pub read: InputArgs,
    /// Output format (default: .xml → opencv-xml, otherwise rig).
    #[arg(long, value_enum)]
    pub to: Option<FormatArg>,
}

/// Options of `rigview calib intrinsics`.
#[derive(Debug, Args)]
pub struct IntrinsicsArgs {
    /// Chessboard images (PNG or JPEG), all of one camera.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Inner corners of the board, COLSxROWS (for example 9x6).
    #[arg(long, value_parser = parse_board)]
    pub board: (u32, u32),
    /// Side of a board square, metres.
    #[arg(long, default_value_t = 0.025)]
    pub square: f64,
    /// Lens model to fit.
    #[arg(long, value_enum, default_value_t = Model::Pinhole)]
    pub model: Model,
    /// Camera name in the output.
    #[arg(long, default_value = "camera")]
    pub name: String,
    /// Write the result here (format as for convert).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum)]
    pub to: Option<FormatArg>,
}

/// Options of `rigview calib ground`.
#[derive(Debug, Args)]
pub struct GroundArgs {
    /// The rig whose intrinsics to use (any readable format).
    #[arg(long)]
    pub rig: PathBuf,
    /// The ground layout file: which camera sees which mat in which image
    /// (format: rigview-ground, see the README).
    #[arg(long)]
    pub layout: PathBuf,
    /// Write the rig with the solved poses here (rig YAML unless --to).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum)]
    pub to: Option<FormatArg>,
    #[command(flatten)]
    pub input: InputArgs,
}

fn parse_board(s: &str) -> std::result::Result<(u32, u32), String> {
    let (a, b) = s
        .split_once(['x', 'X', '×'])
        .ok_or_else(|| format!("expected COLSxROWS, for example 9x6; got \"{s}\""))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| *n >= 2)
            .ok_or_else(|| format!("expected a whole number ≥ 2, got \"{v}\""))
    };
    Ok((p(a)?, p(b)?))
}

fn load(path: &std::path::Path, input: &InputArgs) -> Result<formats::Loaded> {
    Ok(formats::load(
        path,
        input.from.map(Into::into),
        input.model.map(Into::into),
    )?)
}

/// Runs `rigview calib …`, printing to `out`.
pub fn run(args: &CalibArgs, out: &mut dyn Write) -> Result<()> {
    match &args.command {
        CalibCommand::Show(a) => {
            let loaded = load(&a.file, &a.input)?;
            write!(out, "{}", report::summary(&loaded))?;
        }
        CalibCommand::Convert(a) => {
            let loaded = load(&a.input, &a.read)?;
            let written = formats::save(&loaded.rig, &a.output, a.to.map(Into::into))?;
            for w in written {
                writeln!(out, "wrote {}", w.display())?;
            }
        }
        CalibCommand::Intrinsics(a) => intrinsics_cmd(a, out)?,
        CalibCommand::Ground(a) => ground_cmd(a, out)?,
    }
    Ok(())
}

fn intrinsics_cmd(a: &IntrinsicsArgs, out: &mut dyn Write) -> Result<()> {
    let board = Board {
        cols: a.board.0,
        rows: a.board.1,
        square_m: a.square,
    };
    let r =
        intrinsics::calibrate(&a.images, board, a.model.into()).context("intrinsic calibration")?;
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
    if let Some(o) = &a.output {
        let rig = Rig::new(
            Frame::Vehicle,
            vec![Camera::new(a.name.clone(), *k)],
            vec![],
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?;
        for w in formats::save(&rig, o, a.to.map(Into::into))? {
            writeln!(out, "wrote {}", w.display())?;
        }
    }
    Ok(())
}

fn ground_cmd(a: &GroundArgs, out: &mut dyn Write) -> Result<()> {
    let loaded = load(&a.rig, &a.input)?;
    let layout = GroundLayout::load(&a.layout)?;
    if layout.views.is_empty() {
        bail!("{}: the layout has no views", a.layout.display());
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
    if let Some(o) = &a.output {
        for w in formats::save(&rig, o, a.to.map(Into::into))? {
            writeln!(out, "wrote {}", w.display())?;
        }
    }
    Ok(())
}
