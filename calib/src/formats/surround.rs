//! The four-fisheye surround-view layout of the public
//! `surround-view-system-introduction` project (its data is in
//! `tests/data/surround-nz`): one OpenCV FileStorage file per camera
//! (`front`, `left`, `back`, `right`) with the fisheye intrinsics and
//!
//! - `scale_xy`, `shift_xy`: the undistorted image uses the camera matrix
//!   K' = K with fx·sx, fy·sy, cx + shx, cy + shy (R = identity);
//! - `project_matrix` H: a homography from that undistorted image to the
//!   camera's strip of a bird's-eye canvas.
//!
//! The canvas: 1 px = 1 cm on the ground, 1200 × 1600 px; the car occupies
//! x ∈ [500, 700], y ∈ [550, 1050], with its front at the top. Strips map
//! onto the canvas unrotated (front), rotated 180° (back), 90°
//! counter-clockwise (left) and 90° clockwise (right). Each H was fitted to
//! four ground points ([`fitted_points`]).
//!
//! Here the rig's vehicle frame has its origin on the ground below the
//! centre of the car's rectangle, x forward (canvas up), y left (canvas
//! left), z up, in metres.
//!
//! Each camera's pose comes from its four fitted points: the strip points
//! are taken through H⁻¹ and K'⁻¹ to rays in the camera frame, the canvas
//! points to ground points in the vehicle frame, and OpenCV's planar PnP
//! (IPPE, then Levenberg–Marquardt on the rays) gives a first pose. It is
//! then refined (Levenberg–Marquardt) on the quantity the layout is judged
//! by: the distance on the ground between each fitted point and where it
//! lands when projected through the pose and the fisheye model and taken
//! back through K' and H. A pose has six degrees of freedom and the four
//! points give eight equations, so some residual remains: it measures how
//! far H is from a homography that a real camera at some pose induces (H
//! was fitted to hand-picked points). [`SurroundFit`] reports
//! that residual per point.

use nalgebra::{Matrix3, Point2, Vector3};

use crate::cvutil::planar_pnp;
use crate::error::{CalibError, Result};
use crate::formats::opencv::{OpenCvCamera, SurroundKeys};
use crate::model::Intrinsics;
use crate::pose::Pose;
use crate::rig::{Camera, Frame, Rig};

/// The camera names of the layout, in rig order.
pub const CAMERAS: [&str; 4] = ["front", "left", "back", "right"];

/// Canvas size (width, height), pixels = centimetres.
pub const CANVAS_SIZE: (f64, f64) = (1200.0, 1600.0);

/// The car's rectangle on the canvas: x range, y range.
pub const CAR_RECT: ([f64; 2], [f64; 2]) = ([500.0, 700.0], [550.0, 1050.0]);

/// The four ground points each homography was fitted to, in the strip's own
/// pixel coordinates.
pub fn fitted_points(camera: &str) -> Option<[[f64; 2]; 4]> {
    match camera {
        "front" | "back" => Some([
            [420.0, 300.0],
            [780.0, 300.0],
            [420.0, 460.0],
            [780.0, 460.0],
        ]),
        "left" => Some([
            [580.0, 300.0],
            [1140.0, 300.0],
            [580.0, 460.0],
            [1140.0, 460.0],
        ]),
        "right" => Some([
            [460.0, 300.0],
            [1020.0, 300.0],
            [460.0, 460.0],
            [1020.0, 460.0],
        ]),
        _ => None,
    }
}

/// A strip pixel on the canvas (pixel centres: a W-wide image flipped maps
/// x to W − 1 − x).
pub fn strip_to_canvas(camera: &str, x: f64, y: f64) -> Option<[f64; 2]> {
    let (w, h) = CANVAS_SIZE;
    match camera {
        "front" => Some([x, y]),
        "back" => Some([w - 1.0 - x, h - 1.0 - y]),
        "left" => Some([y, h - 1.0 - x]),
        "right" => Some([w - 1.0 - y, x]),
        _ => None,
    }
}

/// A canvas pixel in the camera's strip (the inverse of
/// [`strip_to_canvas`]).
pub fn canvas_to_strip(camera: &str, u: f64, v: f64) -> Option<[f64; 2]> {
    let (w, h) = CANVAS_SIZE;
    match camera {
        "front" => Some([u, v]),
        "back" => Some([w - 1.0 - u, h - 1.0 - v]),
        "left" => Some([h - 1.0 - v, u]),
        "right" => Some([v, w - 1.0 - u]),
        _ => None,
    }
}

fn car_centre() -> (f64, f64) {
    let (x, y) = CAR_RECT;
    (0.5 * (x[0] + x[1]), 0.5 * (y[0] + y[1]))
}

/// A canvas pixel as a vehicle-frame ground point (x, y), metres.
pub fn canvas_to_vehicle(u: f64, v: f64) -> [f64; 2] {
    let (cu, cv) = car_centre();
    [(cv - v) / 100.0, (cu - u) / 100.0]
}

/// A vehicle-frame ground point (x, y in metres) as a canvas pixel.
pub fn vehicle_to_canvas(x: f64, y: f64) -> [f64; 2] {
    let (cu, cv) = car_centre();
    [cu - 100.0 * y, cv - 100.0 * x]
}

/// The undistorted image's camera matrix K'.
pub fn undistorted_camera_matrix(k: &Intrinsics, s: &SurroundKeys) -> Matrix3<f64> {
    Matrix3::new(
        k.fx * s.scale_xy[0],
        0.0,
        k.cx + s.shift_xy[0],
        0.0,
        k.fy * s.scale_xy[1],
        k.cy + s.shift_xy[1],
        0.0,
        0.0,
        1.0,
    )
}

fn apply_h(h: &Matrix3<f64>, x: f64, y: f64) -> Option<[f64; 2]> {
    let p = h * Vector3::new(x, y, 1.0);
    (p.z.abs() > 1e-12).then(|| [p.x / p.z, p.y / p.z])
}

/// Maps a fisheye image pixel of a surround camera to the canvas the way
/// the source project does: unproject with the fisheye model, project with
/// K', apply H, place the strip on the canvas.
pub fn pixel_to_canvas(
    camera: &str,
    k: &Intrinsics,
    s: &SurroundKeys,
    px: &Point2<f64>,
) -> Option<[f64; 2]> {
    let ray = k.unproject(px)?;
    if ray.z <= 0.0 {
        return None;
    }
    let q = undistorted_camera_matrix(k, s) * (ray.into_inner() / ray.z);
    let [x, y] = apply_h(&s.project_matrix, q.x, q.y)?;
    strip_to_canvas(camera, x, y)
}

/// How well one recovered pose reproduces the layout's fitted ground points.
#[derive(Clone, Debug, PartialEq)]
pub struct SurroundFit {
    /// The camera.
    pub camera: String,
    /// The fitted ground points in the vehicle frame (x, y), metres.
    pub ground_m: [[f64; 2]; 4],
    /// For each point: the distance on the ground, centimetres, between it
    /// and where it lands after projection through the recovered pose and
    /// the fisheye model and back through K' and H to the canvas.
    pub residual_cm: [f64; 4],
}

/// The rig recovered from the layout, and how well each pose fits.
#[derive(Clone, Debug, PartialEq)]
pub struct SurroundImport {
    /// The rig: four cameras in the vehicle frame, neighbours in a ring.
    pub rig: Rig,
    /// One fit report per camera, in rig order.
    pub fits: Vec<SurroundFit>,
    /// The layout's keys per camera, in rig order.
    pub keys: Vec<SurroundKeys>,
}

/// Recovers one camera's pose from its four fitted points.
pub fn recover_pose(
    camera: &str,
    k: &Intrinsics,
    s: &SurroundKeys,
    file: &str,
) -> Result<(Pose, SurroundFit)> {
    let fail = |what: &str| CalibError::Calibration(format!("{file}: {what}"));
    let strip = fitted_points(camera).ok_or_else(|| fail("not a camera of the surround layout"))?;
    let h_inv = s
        .project_matrix
        .try_inverse()
        .ok_or_else(|| fail("project_matrix is singular"))?;
    let kp = undistorted_camera_matrix(k, s);
    let kp_inv = kp
        .try_inverse()
        .ok_or_else(|| fail("the undistorted camera matrix is singular"))?;
    let mut object = Vec::with_capacity(4);
    let mut image = Vec::with_capacity(4);
    let mut ground_m = [[0.0; 2]; 4];
    for (i, &[x, y]) in strip.iter().enumerate() {
        let [u, v] = strip_to_canvas(camera, x, y).ok_or_else(|| fail("unknown camera"))?;
        let g = canvas_to_vehicle(u, v);
        ground_m[i] = g;
        object.push([g[0], g[1], 0.0]);
        let q = h_inv * Vector3::new(x, y, 1.0);
        let n = kp_inv * (q / q.z);
        if !(n.x.is_finite() && n.y.is_finite()) {
            return Err(fail(
                "a fitted point does not map into the undistorted image",
            ));
        }
        image.push([n.x, n.y]);
    }
    let ([r0, r1, r2], [t0, t1, t2]) = planar_pnp(&object, &image, true)?
        .ok_or_else(|| fail("OpenCV found no pose for the fitted points"))?;
    let (r, t) = ([r0, r1, r2], [t0, t1, t2]);
    // Refine on what the layout is judged by: the distance on the ground
    // between each fitted point and where it lands after projection
    // through the fisheye model and back through K' and H.
    let residuals = |x: &[f64]| -> Option<Vec<f64>> {
        let pose = Pose::from_opencv_rvec_tvec(
            &Vector3::new(x[0], x[1], x[2]),
            &Vector3::new(x[3], x[4], x[5]),
        );
        let mut out = Vec::with_capacity(8);
        for g in &ground_m {
            let p = pose.to_camera(&Vector3::new(g[0], g[1], 0.0));
            let px = k.project(&p)?;
            let [u, v] = pixel_to_canvas(camera, k, s, &px)?;
            let [gu, gv] = vehicle_to_canvas(g[0], g[1]);
            out.push(u - gu);
            out.push(v - gv);
        }
        Some(out)
    };
    let (x, _) = crate::lm::minimise(&[r[0], r[1], r[2], t[0], t[1], t[2]], residuals, 100);
    let pose = Pose::from_opencv_rvec_tvec(
        &Vector3::new(x[0], x[1], x[2]),
        &Vector3::new(x[3], x[4], x[5]),
    );
    let cam = Camera {
        name: camera.into(),
        device: None,
        intrinsics: *k,
        pose: Some(pose),
    };
    let mut residual_cm = [f64::INFINITY; 4];
    for (i, g) in ground_m.iter().enumerate() {
        let landed = cam
            .project_rig(&Vector3::new(g[0], g[1], 0.0))
            .and_then(|px| pixel_to_canvas(camera, k, s, &px));
        if let Some([u, v]) = landed {
            let [gu, gv] = vehicle_to_canvas(g[0], g[1]);
            residual_cm[i] = (u - gu).hypot(v - gv);
        }
    }
    Ok((
        pose,
        SurroundFit {
            camera: camera.into(),
            ground_m,
            residual_cm,
        },
    ))
}

/// Builds the rig from the four cameras' files, given as (name, file name
/// for errors, contents).
pub fn import(cameras: &[(String, String, OpenCvCamera)]) -> Result<SurroundImport> {
    let mut rig_cameras = Vec::new();
    let mut fits = Vec::new();
    let mut keys = Vec::new();
    for name in CAMERAS {
        let Some((_, file, c)) = cameras.iter().find(|(n, _, _)| n == name) else {
            return Err(CalibError::Argument(format!(
                "the surround layout needs a file for each of {CAMERAS:?}; \"{name}\" is missing"
            )));
        };
        let s = c.surround.ok_or_else(|| CalibError::Missing {
            file: file.clone(),
            field: "project_matrix".into(),
            expected: "the bird's-eye homography of the surround layout".into(),
        })?;
        let (pose, fit) = recover_pose(name, &c.intrinsics, &s, file)?;
        rig_cameras.push(Camera {
            name: name.into(),
            device: None,
            intrinsics: c.intrinsics,
            pose: Some(pose),
        });
        fits.push(fit);
        keys.push(s);
    }
    let rig = Rig::new(
        Frame::Vehicle,
        rig_cameras,
        vec![(0, 1), (1, 2), (2, 3), (3, 0)],
    )
    .map_err(|e| CalibError::Argument(e.to_string()))?;
    Ok(SurroundImport { rig, fits, keys })
}
