//! Small bridges between OpenCV matrices and plain Rust data.

use opencv::core::{Mat, MatTraitConst, CV_64F};
use opencv::prelude::MatTraitConstManual;

use crate::error::{cv, Result};

/// A new owned `rows × cols` CV_64F matrix from row-major data.
pub(crate) fn mat_f64(rows: i32, cols: i32, data: &[f64]) -> Result<Mat> {
    let m = cv(
        "building a matrix",
        Mat::new_rows_cols_with_data(rows, cols, data),
    )?;
    cv("copying a matrix", m.try_clone())
}

/// A new owned `rows × cols` CV_32S matrix from row-major data.
pub(crate) fn mat_i32(rows: i32, cols: i32, data: &[i32]) -> Result<Mat> {
    let m = cv(
        "building a matrix",
        Mat::new_rows_cols_with_data(rows, cols, data),
    )?;
    cv("copying a matrix", m.try_clone())
}

/// All elements of a matrix of any depth, as f64, row-major.
pub(crate) fn mat_to_f64(m: &Mat) -> Result<Vec<f64>> {
    let mut d = Mat::default();
    cv(
        "converting a matrix",
        m.convert_to(&mut d, CV_64F, 1.0, 0.0),
    )?;
    let d = if d.is_continuous() {
        d
    } else {
        cv("copying a matrix", d.try_clone())?
    };
    Ok(cv("reading a matrix", d.data_typed::<f64>())?.to_vec())
}

/// OpenCV's planar PnP (IPPE) on normalised image points (K = I, no
/// distortion): the rig-to-camera `rvec`, `tvec`, or `None` if OpenCV finds
/// no pose. With `refine`, Levenberg–Marquardt polishes it.
pub(crate) fn planar_pnp(
    object: &[[f64; 3]],
    normalised: &[[f64; 2]],
    refine: bool,
) -> Result<Option<([f64; 3], [f64; 3])>> {
    use opencv::core::{Point2d, Point3d, Vector};
    let obj: Vector<Point3d> = object
        .iter()
        .map(|p| Point3d::new(p[0], p[1], p[2]))
        .collect();
    let img: Vector<Point2d> = normalised
        .iter()
        .map(|p| Point2d::new(p[0], p[1]))
        .collect();
    let eye = mat_f64(3, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])?;
    let no_dist = Mat::default();
    let mut rvec = Mat::default();
    let mut tvec = Mat::default();
    let ok = cv(
        "solvePnP",
        opencv::calib3d::solve_pnp(
            &obj,
            &img,
            &eye,
            &no_dist,
            &mut rvec,
            &mut tvec,
            false,
            opencv::calib3d::SOLVEPNP_IPPE,
        ),
    )?;
    if !ok {
        return Ok(None);
    }
    if refine {
        cv(
            "solvePnPRefineLM",
            opencv::calib3d::solve_pnp_refine_lm_def(
                &obj, &img, &eye, &no_dist, &mut rvec, &mut tvec,
            ),
        )?;
    }
    let (r, t) = (mat_to_f64(&rvec)?, mat_to_f64(&tvec)?);
    match (r.as_slice(), t.as_slice()) {
        (&[r0, r1, r2], &[t0, t1, t2]) => Ok(Some(([r0, r1, r2], [t0, t1, t2]))),
        _ => Ok(None),
    }
}
