//! `rigview calib`: show, convert, and make intrinsics and ground
//! extrinsics.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};
use rigview_calib::formats::Format;
use rigview_calib::tools::intrinsics::Board;
use rigview_calib::ModelKind;

use crate::commands::calib::{self as calibration, GroundJob, IntrinsicsJob, Reading, Writing};

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
    pub from: Option<Format>,
    /// Camera model for OpenCV files that do not say which (4 coefficients
    /// fit fisheye and pinhole; rational keeps 8 as the rational model even
    /// when k4..k6 are 0).
    #[arg(long, value_enum)]
    pub model: Option<ModelKind>,
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
    pub to: Option<Format>,
    /// Fit every camera to this lens model first (for tools that read one
    /// model only), reporting the reprojection error over the image.
    #[arg(long, value_enum)]
    pub to_model: Option<ModelKind>,
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
    #[arg(long, value_enum, default_value_t = ModelKind::Pinhole)]
    pub model: ModelKind,
    /// Camera name in the output.
    #[arg(long, default_value = "camera")]
    pub name: String,
    /// Write the result here (format as for convert).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum)]
    pub to: Option<Format>,
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
    pub to: Option<Format>,
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

impl InputArgs {
    /// How these options read a calibration.
    pub fn reading(&self) -> Reading {
        Reading {
            format: self.from,
            model: self.model,
        }
    }
}

/// Where `--output`/`-o` and `--to` write.
fn writing(output: Option<&PathBuf>, to: Option<Format>) -> Option<Writing> {
    output.map(|path| Writing {
        path: path.clone(),
        format: to,
    })
}

/// Runs `rigview calib …`, printing to `out`.
pub fn run(args: &CalibArgs, out: &mut dyn Write) -> Result<()> {
    match &args.command {
        CalibCommand::Show(a) => calibration::show(&a.file, a.input.reading(), out),
        CalibCommand::Convert(a) => calibration::convert(
            &a.input,
            a.read.reading(),
            a.to_model,
            &Writing {
                path: a.output.clone(),
                format: a.to,
            },
            out,
        ),
        CalibCommand::Intrinsics(a) => calibration::intrinsics(
            &IntrinsicsJob {
                images: a.images.clone(),
                board: Board {
                    cols: a.board.0,
                    rows: a.board.1,
                    square_m: a.square,
                },
                model: a.model,
                name: a.name.clone(),
                output: writing(a.output.as_ref(), a.to),
            },
            out,
        ),
        CalibCommand::Ground(a) => calibration::ground(
            &GroundJob {
                rig: a.rig.clone(),
                reading: a.input.reading(),
                layout: a.layout.clone(),
                output: writing(a.output.as_ref(), a.to),
            },
            out,
        ),
    }
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use clap::{CommandFactory, Parser};
    use rigview_calib::formats;
    use rigview_calib::tools::ground::{GroundLayout, GroundMat, GroundView};
    use rigview_calib::tools::render::{render_mat, Palette};

    use super::*;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(subcommand)]
        calib: CalibCommand,
    }

    fn data() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/data")
    }

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rigview-cli-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn run_args(args: &[&str]) -> Result<String> {
        let cli = Cli::try_parse_from(std::iter::once("calib").chain(args.iter().copied()))?;
        let mut out = Vec::new();
        run(&CalibArgs { command: cli.calib }, &mut out)?;
        Ok(String::from_utf8(out)?)
    }

    fn s(p: &Path) -> String {
        p.display().to_string()
    }

    #[test]
    fn every_subcommand_has_help() {
        Cli::command().debug_assert();
        for sub in ["show", "convert", "intrinsics", "ground"] {
            let e = Cli::try_parse_from(["calib", sub, "--help"]).unwrap_err();
            assert_eq!(e.kind(), clap::error::ErrorKind::DisplayHelp);
            assert!(e.to_string().contains("Usage"), "{sub}");
        }
    }

    #[test]
    fn show_and_convert_the_surround_rig() {
        let nz = data().join("surround-nz");
        let shown = run_args(&["show", &s(&nz)]).unwrap();
        for want in [
            "[0] front",
            "[3] right",
            "yaw",
            "field of view",
            "sees ground",
            "residual",
        ] {
            assert!(shown.contains(want), "no \"{want}\" in:\n{shown}");
        }
        let d = tmp("convert");
        let rig = d.join("rig.yaml");
        run_args(&["convert", &s(&nz), &s(&rig)]).unwrap();
        let xml = d.join("xml/");
        let out = run_args(&["convert", &s(&rig), &s(&xml), "--to", "opencv-xml"]).unwrap();
        assert_eq!(out.lines().count(), 4, "{out}");
        let a = formats::load(&rig, None, None).unwrap().rig;
        let b = formats::load(&xml, None, None).unwrap().rig;
        for c in &a.cameras {
            let other = b.camera(&c.name).unwrap();
            assert_eq!((other.intrinsics, other.pose), (c.intrinsics, c.pose));
        }
        let shown = run_args(&["show", &s(&rig)]).unwrap();
        assert!(shown.contains("format: rig"), "{shown}");
    }

    #[test]
    fn convert_fits_the_real_fisheyes_to_another_model_and_reports_the_error() {
        let nz = data().join("surround-nz");
        let d = tmp("to-model");
        let out_path = d.join("ds.yaml");
        let out = run_args(&[
            "convert",
            &s(&nz),
            &s(&out_path),
            "--to-model",
            "double-sphere",
        ])
        .unwrap();
        assert!(out.contains("front: fisheye → double-sphere"), "{out}");
        // Each camera's largest reprojection error, as reported.
        let reported = |name: &str| -> f64 {
            let line = out
                .lines()
                .find(|l| l.starts_with(&format!("{name}: ")))
                .unwrap();
            let before = line.split(" px at most").next().unwrap();
            before.rsplit(' ').next().unwrap().parse().unwrap()
        };
        let fisheye = formats::load(&nz, None, None).unwrap().rig;
        let ds = formats::load(&out_path, None, None).unwrap().rig;
        for c in &ds.cameras {
            assert_eq!(c.intrinsics.distortion.kind(), ModelKind::DoubleSphere);
            let real = fisheye.camera(&c.name).unwrap();
            assert_eq!(c.pose, real.pose);
            // The report holds: rays of the real lens land within the
            // reported largest error of where the double sphere puts them.
            let most = reported(&c.name);
            for px in [
                [480.0, 320.0],
                [100.0, 320.0],
                [480.0, 40.0],
                [700.0, 500.0],
            ] {
                let px = nalgebra::Point2::new(px[0], px[1]);
                let ray = real.intrinsics.unproject(&px).unwrap();
                let q = c.intrinsics.project(&ray).unwrap();
                assert!(
                    (q - px).norm() <= most + 1e-9,
                    "{}: {q} for {px}, {most}",
                    c.name
                );
            }
        }
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let e = run_args(&["show", "/nonexistent/rig.yaml"]).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/rig.yaml"), "{e}");
        assert!(run_args(&["intrinsics", "--board", "9by6", "x.png"]).is_err());
        assert!(run_args(&["convert", "/nonexistent", "/tmp/x.yaml"]).is_err());
    }

    #[test]
    fn intrinsics_from_the_sample_chessboards() {
        let d = tmp("intrinsics");
        let out_file = d.join("left.yaml");
        let imgs: Vec<String> = ["01", "02", "03", "04", "05", "06"]
            .iter()
            .map(|n| s(&data().join(format!("opencv-samples/left{n}.jpg"))))
            .collect();
        let mut args = vec!["intrinsics", "--board", "9x6", "--name", "left", "-o"];
        let o = s(&out_file);
        args.push(&o);
        args.extend(imgs.iter().map(String::as_str));
        let out = run_args(&args).unwrap();
        assert!(out.contains("from 6 of 6 images"), "{out}");
        let rig = formats::load(&out_file, None, None).unwrap().rig;
        assert!((rig.cameras[0].intrinsics.fx - 533.0).abs() < 15.0);
    }

    #[test]
    fn show_and_convert_files_as_users_bring_them() {
        let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../calib/tests/data");
        // Each file both ways: told from its contents, and named.
        let show = |file: &str, from: &str, wants: &[&str]| {
            for from in [None, Some(from)] {
                let path = s(&d.join(file));
                let mut args = vec!["show", path.as_str()];
                args.extend(from.iter().flat_map(|f| ["--from", *f]));
                let out = run_args(&args).unwrap();
                for want in wants {
                    assert!(out.contains(want), "{args:?}: no \"{want}\" in:\n{out}");
                }
            }
        };
        show(
            "kalibr-opencv-header.yaml",
            "kalibr",
            &[
                "format: kalibr",
                "[0] cam0",
                "[1] cam1",
                "pinhole-radtan 752×480",
            ],
        );
        show(
            "ros2-camera-info.yaml",
            "ros",
            &[
                "format: ros",
                "[0] camera_optical",
                "pinhole-radtan 640×480",
            ],
        );
        let rational = s(&d.join("ros-rational.yaml"));
        let out = run_args(&["show", &rational]).unwrap();
        for want in [
            "model: pinhole-rational 1280×720",
            "distortion: [k1 0.520000, k2 -2.600000, p1 0.000620, p2 -0.000210, k3 1.500000, k4 0.400000, k5 -2.450000, k6 1.420000]",
            "field of view: horizontal",
        ] {
            assert!(out.contains(want), "no \"{want}\" in:\n{out}");
        }
        let t = tmp("rational");
        let xml = t.join("rgb.xml");
        run_args(&["convert", &rational, &s(&xml)]).unwrap();
        let back = formats::load(&xml, None, None).unwrap().rig;
        let orig = formats::load(Path::new(&rational), None, None).unwrap().rig;
        assert_eq!(back.cameras[0].intrinsics, orig.cameras[0].intrinsics);
        let e = run_args(&[
            "convert",
            &rational,
            &s(&t.join("chain.yaml")),
            "--to",
            "kalibr",
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("rgb_camera") && e.contains("Kalibr has no rational"),
            "{e}"
        );
    }

    #[test]
    fn rational_intrinsics_from_the_sample_chessboards() {
        let d = tmp("intrinsics-rational");
        let out_file = d.join("left.yaml");
        let imgs: Vec<String> = ["01", "02", "03", "04", "05", "06"]
            .iter()
            .map(|n| s(&data().join(format!("opencv-samples/left{n}.jpg"))))
            .collect();
        let o = s(&out_file);
        let mut args = vec![
            "intrinsics",
            "--board",
            "9x6",
            "--model",
            "rational",
            "-o",
            &o,
        ];
        args.extend(imgs.iter().map(String::as_str));
        let out = run_args(&args).unwrap();
        assert!(
            out.contains("pinhole-rational model from 6 of 6 images"),
            "{out}"
        );
        let k = formats::load(&out_file, None, None).unwrap().rig.cameras[0].intrinsics;
        assert_eq!(k.distortion.kind(), ModelKind::Rational);
        assert!((k.fx - 533.0).abs() < 15.0, "{k:?}");
    }

    #[test]
    fn ground_from_a_rendered_mat() {
        let loaded = formats::load(&data().join("surround-nz"), None, None).unwrap();
        let truth = loaded.rig.camera("front").unwrap().clone();
        let d = tmp("ground");
        let mat = GroundMat {
            squares: [9, 6],
            square_m: 0.2,
            origin_m: [3.2, 0.9],
            yaw_deg: -90.0,
            margin_m: 0.2,
        };
        render_mat(&truth, &mat, &Palette::default(), 2)
            .save_png(&d.join("front.png"))
            .unwrap();
        let layout = GroundLayout {
            format: "rigview-ground".into(),
            version: 1,
            views: vec![GroundView {
                camera: "front".into(),
                image: "front.png".into(),
                mat,
            }],
        };
        std::fs::write(d.join("layout.yaml"), layout.to_string().unwrap()).unwrap();
        let out_rig = d.join("solved.yaml");
        let out = run_args(&[
            "ground",
            "--rig",
            &s(&data().join("surround-nz")),
            "--layout",
            &s(&d.join("layout.yaml")),
            "-o",
            &s(&out_rig),
        ])
        .unwrap();
        assert!(out.contains("front: 40 corners"), "{out}");
        let solved = formats::load(&out_rig, None, None).unwrap().rig;
        let p = solved.camera("front").unwrap().pose.unwrap();
        let t = truth.pose.unwrap();
        assert!((p.translation() - t.translation()).norm() < 0.005);
        assert!(p.rotation_angle_to(&t).to_degrees() < 0.1);
    }
}
