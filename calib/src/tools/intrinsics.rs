//! Intrinsic calibration from chessboard images, through OpenCV
//! (`calibrateCamera` for the pinhole models, with `CALIB_RATIONAL_MODEL`
//! for the rational one; `fisheye::calibrate` for the fisheye model).
//!
//! Every image is either used or rejected with a reason: it cannot be read,
//! its size differs from the first image's, the board is not found whole,
//! or (after a first calibration) its reprojection error is an outlier
//! (above 3× the median and above 1 px), in which case the calibration is
//! run again without it. The RMS error is computed with this crate's own
//! model from OpenCV's result, over every corner of the images used.

use std::path::PathBuf;

use nalgebra::Vector3;
use opencv::core::{
    Mat, Point2f, Point3f, Size, TermCriteria, TermCriteria_COUNT, TermCriteria_EPS, Vector,
};

use crate::cvutil::mat_to_f64;
use crate::error::{cv, CalibError, Result};
use crate::model::{Distortion, Intrinsics, ModelKind};
use crate::pose::Pose;
use crate::tools::{find_chessboard, GrayImage};

/// A calibration chessboard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Board {
    /// Inner corners along a row.
    pub cols: u32,
    /// Inner corners along a column.
    pub rows: u32,
    /// Side of a square, metres.
    pub square_m: f64,
}

impl Board {
    /// The inner corners in the board's frame (z = 0), row by row.
    pub fn object_points(&self) -> Vec<Vector3<f64>> {
        (0..self.rows)
            .flat_map(|r| {
                (0..self.cols).map(move |c| {
                    Vector3::new(
                        f64::from(c) * self.square_m,
                        f64::from(r) * self.square_m,
                        0.0,
                    )
                })
            })
            .collect()
    }
}

/// What happened to one image.
#[derive(Clone, Debug, PartialEq)]
pub enum ImageStatus {
    /// Used, with its RMS reprojection error in pixels.
    Used {
        /// RMS reprojection error of its corners, pixels.
        rms_px: f64,
    },
    /// Not used, and why.
    Rejected {
        /// Why.
        reason: String,
    },
}

/// One image of a calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageReport {
    /// The file.
    pub file: PathBuf,
    /// Used or rejected.
    pub status: ImageStatus,
}

/// The result of an intrinsic calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct IntrinsicsResult {
    /// The intrinsics.
    pub intrinsics: Intrinsics,
    /// RMS reprojection error over every corner of the images used, pixels.
    pub rms_px: f64,
    /// The RMS error OpenCV reported.
    pub opencv_rms_px: f64,
    /// Every image, used or rejected, in the order given.
    pub images: Vec<ImageReport>,
}

impl IntrinsicsResult {
    /// The number of images used.
    pub fn used(&self) -> usize {
        self.images
            .iter()
            .filter(|i| matches!(i.status, ImageStatus::Used { .. }))
            .count()
    }
}

struct View {
    index: usize,
    corners: Vec<[f64; 2]>,
}

/// Calibrates one camera from chessboard images.
pub fn calibrate(files: &[PathBuf], board: Board, model: ModelKind) -> Result<IntrinsicsResult> {
    if !matches!(
        model,
        ModelKind::Fisheye | ModelKind::Pinhole | ModelKind::Rational
    ) {
        return Err(CalibError::Argument(format!(
            "--model {model:?}: OpenCV calibrates the fisheye, pinhole and rational models; \
             calibrate a {model:?} camera with Kalibr or Basalt and load its file"
        )));
    }
    if board.cols < 2 || board.rows < 2 || !(board.square_m > 0.0 && board.square_m.is_finite()) {
        return Err(CalibError::Argument(format!(
            "a board needs at least 2×2 inner corners and a positive square size; got {}×{} of {} m",
            board.cols, board.rows, board.square_m
        )));
    }
    let mut images: Vec<ImageReport> = files
        .iter()
        .map(|f| ImageReport {
            file: f.clone(),
            status: ImageStatus::Rejected {
                reason: "not processed".into(),
            },
        })
        .collect();
    let mut size: Option<(u32, u32)> = None;
    let mut views = Vec::new();
    for (i, f) in files.iter().enumerate() {
        let reject = |reason: String| ImageStatus::Rejected { reason };
        let img = match GrayImage::load(f) {
            Ok(img) => img,
            Err(e) => {
                images[i].status = reject(format!("cannot be read: {e}"));
                continue;
            }
        };
        let (w, h) = *size.get_or_insert((img.width, img.height));
        if (img.width, img.height) != (w, h) {
            images[i].status = reject(format!(
                "its size {}×{} differs from the first image's {w}×{h}",
                img.width, img.height
            ));
            continue;
        }
        match find_chessboard(&img, board.cols, board.rows)? {
            Some(corners) => views.push(View { index: i, corners }),
            None => {
                images[i].status =
                    reject(format!("no {}×{} chessboard found", board.cols, board.rows));
            }
        }
    }
    let (w, h) = size.ok_or_else(|| CalibError::Calibration("no image could be read".into()))?;
    let mut result = run(&views, board, model, w, h)?;
    // Reject outliers once and calibrate again.
    let mut sorted: Vec<f64> = result.1.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let keep: Vec<bool> = result
        .1
        .iter()
        .map(|&e| e <= 1.0 || e <= 3.0 * median)
        .collect();
    if keep.iter().any(|k| !k) && keep.iter().filter(|k| **k).count() >= 3 {
        for (v, (&k, &e)) in views.iter().zip(keep.iter().zip(&result.1)) {
            if !k {
                images[v.index].status = ImageStatus::Rejected {
                    reason: format!(
                        "reprojection error {e:.2} px, above 3× the median ({median:.2} px)"
                    ),
                };
            }
        }
        let mut kept = keep.iter();
        views.retain(|_| kept.next().copied().unwrap_or(false));
        result = run(&views, board, model, w, h)?;
    }
    let (intrinsics, per_view, rms_px, opencv_rms_px) = result;
    for (v, e) in views.iter().zip(per_view) {
        images[v.index].status = ImageStatus::Used { rms_px: e };
    }
    Ok(IntrinsicsResult {
        intrinsics,
        rms_px,
        opencv_rms_px,
        images,
    })
}

type RunResult = (Intrinsics, Vec<f64>, f64, f64);

fn run(views: &[View], board: Board, model: ModelKind, w: u32, h: u32) -> Result<RunResult> {
    if views.len() < 3 {
        return Err(CalibError::Calibration(format!(
            "only {} image(s) with the whole board; a calibration needs at least 3",
            views.len()
        )));
    }
    let obj_one: Vector<Point3f> = board
        .object_points()
        .iter()
        .map(|p| Point3f::new(p.x as f32, p.y as f32, 0.0))
        .collect();
    let mut obj = Vector::<Vector<Point3f>>::new();
    let mut img = Vector::<Vector<Point2f>>::new();
    for v in views {
        obj.push(obj_one.clone());
        img.push(
            v.corners
                .iter()
                .map(|c| Point2f::new(c[0] as f32, c[1] as f32))
                .collect(),
        );
    }
    let size = Size::new(w as i32, h as i32);
    let mut k = Mat::default();
    let mut d = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let criteria = cv(
        "calibration criteria",
        TermCriteria::new(TermCriteria_COUNT + TermCriteria_EPS, 100, f64::EPSILON),
    )?;
    let flags = if model == ModelKind::Rational {
        opencv::calib3d::CALIB_RATIONAL_MODEL
    } else {
        0
    };
    let opencv_rms = match model {
        ModelKind::Pinhole | ModelKind::Rational => cv(
            "calibrateCamera",
            opencv::calib3d::calibrate_camera(
                &obj, &img, size, &mut k, &mut d, &mut rvecs, &mut tvecs, flags, criteria,
            ),
        )?,
        ModelKind::DoubleSphere
        | ModelKind::Eucm
        | ModelKind::Omni
        | ModelKind::RadialPoly
        | ModelKind::Scaramuzza
        | ModelKind::Fov => {
            return Err(CalibError::Argument(format!(
                "OpenCV cannot calibrate the {model:?} model"
            )))
        }
        ModelKind::Fisheye => cv(
            "fisheye::calibrate",
            opencv::calib3d::calibrate(
                &obj,
                &img,
                size,
                &mut k,
                &mut d,
                &mut rvecs,
                &mut tvecs,
                opencv::calib3d::Fisheye_CALIB_RECOMPUTE_EXTRINSIC
                    | opencv::calib3d::Fisheye_CALIB_FIX_SKEW,
                criteria,
            ),
        )?,
    };
    let kv = mat_to_f64(&k)?;
    let dv = mat_to_f64(&d)?;
    if kv.len() != 9 {
        return Err(CalibError::Calibration(
            "OpenCV returned no camera matrix".into(),
        ));
    }
    let distortion = match model {
        ModelKind::Fisheye if dv.len() >= 4 => Distortion::Fisheye([dv[0], dv[1], dv[2], dv[3]]),
        ModelKind::Pinhole if dv.len() >= 5 => {
            Distortion::RadTan([dv[0], dv[1], dv[2], dv[3], dv[4]])
        }
        ModelKind::Rational if dv.len() >= 8 => {
            Distortion::Rational([dv[0], dv[1], dv[2], dv[3], dv[4], dv[5], dv[6], dv[7]])
        }
        _ => {
            return Err(CalibError::Calibration(
                "OpenCV returned too few distortion coefficients".into(),
            ))
        }
    };
    let intrinsics = Intrinsics {
        width: w,
        height: h,
        fx: kv[0],
        fy: kv[4],
        cx: kv[2],
        cy: kv[5],
        distortion,
    };
    intrinsics
        .validate()
        .map_err(|e| CalibError::Calibration(format!("the calibration diverged: {e}")))?;
    let object = board.object_points();
    let mut per_view = Vec::with_capacity(views.len());
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, v) in views.iter().enumerate() {
        let r = mat_to_f64(&cv("reading rvec", rvecs.get(i))?)?;
        let t = mat_to_f64(&cv("reading tvec", tvecs.get(i))?)?;
        if r.len() != 3 || t.len() != 3 {
            return Err(CalibError::Calibration(
                "OpenCV returned a malformed pose".into(),
            ));
        }
        let pose = Pose::from_opencv_rvec_tvec(
            &Vector3::new(r[0], r[1], r[2]),
            &Vector3::new(t[0], t[1], t[2]),
        );
        let mut s = 0.0;
        for (p, c) in object.iter().zip(&v.corners) {
            let e = match intrinsics.project(&pose.to_camera(p)) {
                Some(q) => (q.x - c[0]).powi(2) + (q.y - c[1]).powi(2),
                None => f64::INFINITY,
            };
            s += e;
        }
        per_view.push((s / object.len() as f64).sqrt());
        sum += s;
        count += object.len();
    }
    Ok((
        intrinsics,
        per_view,
        (sum / count as f64).sqrt(),
        opencv_rms,
    ))
}
