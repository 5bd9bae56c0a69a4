//! Extrinsic calibration from a checkerboard mat of known layout lying on
//! the ground: detect its inner corners in a camera's image, undistort them
//! with OpenCV (`fisheye::undistortPoints` or `undistortPoints`), solve the
//! pose with OpenCV's planar PnP (IPPE) on the normalised points, and refine
//! it by Levenberg–Marquardt on the pixel reprojection error through the
//! camera model. The reprojection error is reported per camera.
//!
//! A checkerboard's corners can be listed from any of its corners, so the
//! detector's order is ambiguous. Every ordering is solved; orderings that
//! put the camera under the ground or do not fit are dropped, and of the
//! rest the one whose predicted square colours best match the image wins
//! (square (0, 0) of the mat is dark).
//!
//! The layout file (YAML):
//!
//! ```yaml
//! format: rigview-ground
//! version: 1
//! views:
//! - camera: front                # a camera of the rig
//!   image: front.png             # relative to this file
//!   mat:
//!     squares: [9, 6]            # squares along the mat's x and y axes
//!     square_m: 0.25
//!     origin_m: [2.0, 1.0]       # vehicle x, y of the outer corner of square (0, 0)
//!     yaw_deg: -90               # direction of the mat's x axis (0 = forward, 90 = left)
//! ```

use std::path::{Path, PathBuf};

use nalgebra::{Point2, Vector3};
use opencv::core::{Mat, Point2d, TermCriteria, TermCriteria_COUNT, TermCriteria_EPS, Vector};
use serde::{Deserialize, Serialize};

use crate::cvutil::{mat_f64, planar_pnp};
use crate::error::{cv, CalibError, FieldError, Result};
use crate::model::{Distortion, Intrinsics};
use crate::pose::Pose;
use crate::rig::{Frame, Rig};
use crate::tools::{find_chessboard, GrayImage};

/// A checkerboard mat on the ground.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundMat {
    /// Squares along the mat's x and y axes (inner corners: one fewer
    /// each).
    pub squares: [u32; 2],
    /// Side of a square, metres.
    pub square_m: f64,
    /// Vehicle-frame x, y of the outer corner of square (0, 0), metres.
    pub origin_m: [f64; 2],
    /// Direction of the mat's x axis in the vehicle frame, degrees (0 =
    /// forward, 90 = left). The mat's y axis is 90° further.
    pub yaw_deg: f64,
    /// Width of the light border around the squares, metres (for
    /// rendering; the detector needs a light border).
    #[serde(default = "default_margin")]
    pub margin_m: f64,
}

fn default_margin() -> f64 {
    0.0
}

impl GroundMat {
    /// Checks the numbers.
    pub fn validate(&self) -> Result<(), FieldError> {
        if self.squares[0] < 3
            || self.squares[1] < 3
            || self.squares[0] > 100
            || self.squares[1] > 100
        {
            return Err(FieldError::new(
                "mat.squares",
                "3 to 100 squares each way",
                format!("{:?}", self.squares),
            ));
        }
        if !(self.square_m > 0.0 && self.square_m.is_finite()) {
            return Err(FieldError::new(
                "mat.square_m",
                "a positive size in metres",
                format!("{}", self.square_m),
            ));
        }
        if !(self.origin_m.iter().all(|v| v.is_finite())
            && self.yaw_deg.is_finite()
            && self.margin_m.is_finite()
            && self.margin_m >= 0.0)
        {
            return Err(FieldError::new(
                "mat",
                "finite origin_m, yaw_deg and a margin_m ≥ 0",
                "a non-finite or negative value",
            ));
        }
        Ok(())
    }

    /// Inner corners along x and y.
    pub fn inner_corners(&self) -> (u32, u32) {
        (
            self.squares[0].saturating_sub(1),
            self.squares[1].saturating_sub(1),
        )
    }

    fn axes(&self) -> ([f64; 2], [f64; 2]) {
        let (s, c) = self.yaw_deg.to_radians().sin_cos();
        ([c, s], [-s, c])
    }

    /// A point of the mat (metres along its x and y axes) in the vehicle
    /// frame.
    pub fn to_vehicle(&self, mx: f64, my: f64) -> Vector3<f64> {
        let (ax, ay) = self.axes();
        Vector3::new(
            self.origin_m[0] + mx * ax[0] + my * ay[0],
            self.origin_m[1] + mx * ax[1] + my * ay[1],
            0.0,
        )
    }

    /// The inner corner `(i, j)` (0-based along x and y) in the vehicle
    /// frame.
    pub fn inner_corner(&self, i: u32, j: u32) -> Vector3<f64> {
        self.to_vehicle(
            f64::from(i + 1) * self.square_m,
            f64::from(j + 1) * self.square_m,
        )
    }

    /// What the mat shows at a vehicle-frame ground point: `Some(true)` on a
    /// dark square, `Some(false)` on a light square or the border, `None`
    /// off the mat. Square (0, 0) is dark.
    pub fn shade_at(&self, x: f64, y: f64) -> Option<bool> {
        let (ax, ay) = self.axes();
        let (dx, dy) = (x - self.origin_m[0], y - self.origin_m[1]);
        let mx = dx * ax[0] + dy * ax[1];
        let my = dx * ay[0] + dy * ay[1];
        let (w, h) = (
            f64::from(self.squares[0]) * self.square_m,
            f64::from(self.squares[1]) * self.square_m,
        );
        let m = self.margin_m;
        if mx < -m || my < -m || mx >= w + m || my >= h + m {
            return None;
        }
        if mx < 0.0 || my < 0.0 || mx >= w || my >= h {
            return Some(false);
        }
        let (i, j) = ((mx / self.square_m) as u64, (my / self.square_m) as u64);
        Some((i + j) % 2 == 0)
    }
}

/// The pose of one camera from the mat.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundPose {
    /// The camera.
    pub camera: String,
    /// Its pose in the vehicle frame.
    pub pose: Pose,
    /// RMS reprojection error of the mat's corners, pixels.
    pub rms_px: f64,
    /// Largest reprojection error of a corner, pixels.
    pub max_px: f64,
    /// Corners used.
    pub corners: usize,
    /// Mean grey level of the light squares minus the dark ones, at the
    /// square centres predicted by the pose (how sure the ordering is).
    pub contrast: f64,
}

type Ordering = Box<dyn Fn(u32, u32) -> (u32, u32)>;

/// The corner orderings a detector may report for a `c × r` grid: index
/// `k = row·c + col` of the detection maps to inner corner `(i, j)`.
fn orderings(c: u32, r: u32) -> Vec<Ordering> {
    let mut v: Vec<Ordering> = vec![
        Box::new(|col, row| (col, row)),
        Box::new(move |col, row| (c - 1 - col, r - 1 - row)),
        Box::new(move |col, row| (c - 1 - col, row)),
        Box::new(move |col, row| (col, r - 1 - row)),
    ];
    if c == r {
        v.push(Box::new(|col, row| (row, col)));
        v.push(Box::new(move |col, row| (r - 1 - row, c - 1 - col)));
        v.push(Box::new(move |col, row| (r - 1 - row, col)));
        v.push(Box::new(move |col, row| (row, c - 1 - col)));
    }
    v
}

/// Undistorts pixels to normalised image coordinates with OpenCV.
fn undistort(k: &Intrinsics, corners: &[[f64; 2]]) -> Result<Vec<[f64; 2]>> {
    if matches!(
        k.distortion,
        Distortion::DoubleSphere(_)
            | Distortion::Eucm(_)
            | Distortion::Omni(_)
            | Distortion::RadialPoly(_)
            | Distortion::Scaramuzza(_)
            | Distortion::Fov(_)
    ) {
        // Models OpenCV does not know: the model's own unprojection, onto
        // the plane z = 1 (a corner the mats give lies in front).
        return corners
            .iter()
            .map(|c| {
                k.unproject(&nalgebra::Point2::new(c[0], c[1]))
                    .filter(|r| r.z > 1e-9)
                    .map(|r| [r.x / r.z, r.y / r.z])
                    .ok_or_else(|| {
                        CalibError::Calibration(format!(
                            "corner ({:.1}, {:.1}) lies outside the camera model's field of view \
                             or behind the camera",
                            c[0], c[1]
                        ))
                    })
            })
            .collect();
    }
    let src: Vector<Point2d> = corners.iter().map(|c| Point2d::new(c[0], c[1])).collect();
    let km = mat_f64(3, 3, &k.camera_matrix().concat())?;
    let d = k.distortion.coefficients();
    let dm = mat_f64(d.len() as i32, 1, d)?;
    let mut dst = Vector::<Point2d>::new();
    let none = Mat::default();
    match k.distortion {
        Distortion::Fisheye(_) => {
            let criteria = cv(
                "undistortion criteria",
                TermCriteria::new(TermCriteria_COUNT + TermCriteria_EPS, 50, 1e-12),
            )?;
            cv(
                "fisheye::undistortPoints",
                opencv::calib3d::fisheye_undistort_points(
                    &src, &mut dst, &km, &dm, &none, &none, criteria,
                ),
            )?;
        }
        _ => {
            let criteria = cv(
                "undistortion criteria",
                TermCriteria::new(TermCriteria_COUNT + TermCriteria_EPS, 200, 1e-12),
            )?;
            cv(
                "undistortPoints",
                opencv::calib3d::undistort_points_iter(
                    &src, &mut dst, &km, &dm, &none, &none, criteria,
                ),
            )?;
        }
    }
    Ok(dst.iter().map(|p| [p.x, p.y]).collect())
}

fn pose_from_x(x: &[f64]) -> Pose {
    Pose::from_opencv_rvec_tvec(
        &Vector3::new(x[0], x[1], x[2]),
        &Vector3::new(x[3], x[4], x[5]),
    )
}

/// Solves one camera's pose from its image of the mat.
pub fn solve_view(
    name: &str,
    k: &Intrinsics,
    img: &GrayImage,
    mat: &GroundMat,
) -> Result<GroundPose> {
    mat.validate()
        .map_err(|e| CalibError::Argument(format!("camera \"{name}\": {e}")))?;
    let (c, r) = mat.inner_corners();
    let corners = find_chessboard(img, c, r)?.ok_or_else(|| {
        CalibError::Calibration(format!(
            "camera \"{name}\": no {c}×{r} inner-corner mat found in its image"
        ))
    })?;
    let normalised = undistort(k, &corners)?;
    // Corners far off the axis cannot go on the normalised plane reliably;
    // the first PnP uses the others, the refinement uses all.
    let usable: Vec<bool> = corners
        .iter()
        .map(|p| {
            k.unproject(&Point2::new(p[0], p[1]))
                .is_some_and(|ray| ray.z > 0.2)
        })
        .collect();
    let mut best: Option<GroundPose> = None;
    for order in orderings(c, r) {
        let world: Vec<Vector3<f64>> = (0..corners.len() as u32)
            .map(|idx| {
                let (i, j) = order(idx % c, idx / c);
                mat.inner_corner(i, j)
            })
            .collect();
        let mut obj = Vec::new();
        let mut im = Vec::new();
        for ((w, n), &u) in world.iter().zip(&normalised).zip(&usable) {
            if u {
                obj.push([w.x, w.y, w.z]);
                im.push(*n);
            }
        }
        if obj.len() < 4 {
            return Err(CalibError::Calibration(format!(
                "camera \"{name}\": fewer than 4 mat corners lie within 78° of the optical axis"
            )));
        }
        let Some((rv, tv)) = planar_pnp(&obj, &im, false)? else {
            continue;
        };
        let residuals = |x: &[f64]| -> Option<Vec<f64>> {
            let pose = pose_from_x(x);
            let mut out = Vec::with_capacity(2 * world.len());
            for (w, p) in world.iter().zip(&corners) {
                let q = k.project(&pose.to_camera(w))?;
                out.push(q.x - p[0]);
                out.push(q.y - p[1]);
            }
            Some(out)
        };
        let (x, cost) =
            crate::lm::minimise(&[rv[0], rv[1], rv[2], tv[0], tv[1], tv[2]], residuals, 100);
        if !cost.is_finite() {
            continue;
        }
        let pose = pose_from_x(&x);
        if pose.translation().z <= 0.0 {
            continue;
        }
        let errs: Vec<f64> = residuals(&x)
            .unwrap_or_default()
            .chunks(2)
            .map(|e| e[0].hypot(e[1]))
            .collect();
        let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len().max(1) as f64).sqrt();
        let max = errs.iter().copied().fold(0.0, f64::max);
        // Colour check at the predicted square centres.
        let (mut dark, mut light, mut nd, mut nl) = (0.0, 0.0, 0usize, 0usize);
        for j in 0..mat.squares[1] {
            for i in 0..mat.squares[0] {
                let p = mat.to_vehicle(
                    (f64::from(i) + 0.5) * mat.square_m,
                    (f64::from(j) + 0.5) * mat.square_m,
                );
                let Some(q) = k.project(&pose.to_camera(&p)) else {
                    continue;
                };
                let Some(v) = img.sample(q.x, q.y) else {
                    continue;
                };
                if (i + j) % 2 == 0 {
                    dark += v;
                    nd += 1;
                } else {
                    light += v;
                    nl += 1;
                }
            }
        }
        if nd == 0 || nl == 0 {
            continue;
        }
        let contrast = light / nl as f64 - dark / nd as f64;
        let candidate = GroundPose {
            camera: name.into(),
            pose,
            rms_px: rms,
            max_px: max,
            corners: corners.len(),
            contrast,
        };
        let better = match &best {
            None => true,
            Some(b) => {
                let fits = |g: &GroundPose| g.rms_px < 2.0;
                (fits(&candidate), candidate.contrast) > (fits(b), b.contrast)
            }
        };
        if better {
            best = Some(candidate);
        }
    }
    match best {
        Some(b) if b.contrast > 0.0 && b.rms_px < 2.0 => Ok(b),
        Some(b) => Err(CalibError::Calibration(format!(
            "camera \"{name}\": no pose fits the mat (best: {:.2} px RMS, square contrast {:.0})",
            b.rms_px, b.contrast
        ))),
        None => Err(CalibError::Calibration(format!(
            "camera \"{name}\": OpenCV found no pose for the mat"
        ))),
    }
}

/// One view of a ground layout: which camera, its image, the mat it sees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundView {
    /// The camera's name in the rig.
    pub camera: String,
    /// Its image (relative paths are relative to the layout file).
    pub image: PathBuf,
    /// The mat it sees.
    pub mat: GroundMat,
}

/// A ground calibration layout file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundLayout {
    /// `rigview-ground`.
    pub format: String,
    /// 1.
    pub version: u32,
    /// The views.
    pub views: Vec<GroundView>,
}

impl GroundLayout {
    /// Reads a layout file; image paths become relative to its folder.
    pub fn load(path: &Path) -> Result<Self> {
        let file = path.display().to_string();
        let text = crate::formats::read_text(path)?;
        let mut layout: GroundLayout =
            serde_norway::from_str(&text).map_err(|e| CalibError::Parse {
                file: file.clone(),
                detail: e.to_string(),
            })?;
        if layout.format != "rigview-ground" {
            return Err(FieldError::new(
                "format",
                "\"rigview-ground\"",
                format!("\"{}\"", layout.format),
            )
            .in_file(&file));
        }
        if layout.version != 1 {
            return Err(CalibError::UnsupportedVersion {
                file,
                found: layout.version.to_string(),
                supported: "1".into(),
            });
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        for (i, v) in layout.views.iter_mut().enumerate() {
            v.mat
                .validate()
                .map_err(|e| e.within(&format!("views[{i}]")).in_file(&file))?;
            if v.image.is_relative() {
                v.image = dir.join(&v.image);
            }
        }
        Ok(layout)
    }

    /// Writes a layout file.
    pub fn to_string(&self) -> Result<String> {
        crate::formats::yaml::to_string(self)
    }
}

/// Solves the pose of every camera of the layout; returns the rig with those
/// poses (in the vehicle frame) and the per-camera results. Cameras without
/// a view keep their pose if the rig was already in the vehicle frame, and
/// lose it otherwise.
pub fn calibrate(rig: &Rig, layout: &GroundLayout) -> Result<(Rig, Vec<GroundPose>)> {
    let mut out = rig.clone();
    if out.frame != Frame::Vehicle {
        for c in &mut out.cameras {
            c.pose = None;
        }
        out.frame = Frame::Vehicle;
    }
    let mut results = Vec::new();
    for v in &layout.views {
        let idx = rig.index_of(&v.camera).ok_or_else(|| {
            CalibError::Argument(format!("the rig has no camera \"{}\"", v.camera))
        })?;
        let img = GrayImage::load(&v.image)?;
        let k = &rig.cameras[idx].intrinsics;
        if (img.width, img.height) != (k.width, k.height) {
            return Err(CalibError::Argument(format!(
                "{}: the image is {}×{} but camera \"{}\" is {}×{}",
                v.image.display(),
                img.width,
                img.height,
                v.camera,
                k.width,
                k.height
            )));
        }
        let g = solve_view(&v.camera, k, &img, &v.mat)?;
        out.cameras[idx].pose = Some(g.pose);
        results.push(g);
    }
    Ok((out, results))
}
