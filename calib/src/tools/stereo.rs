//! Stereo pairs of a rig and the density of their disparities: two
//! calibrated cameras side by side are rectified to a common pinhole view
//! (rows aligned, disparity along the rows) through their own lens models,
//! and OpenCV's semi-global block matcher (`StereoSGBM`) finds a disparity
//! where the pair's images hold enough texture to match. The share of
//! pixels with a valid disparity is what a depth consumer gets from where
//! the exposure holds the two cameras: a clipped or noise-buried surface
//! gives none.
//!
//! Any lens model the rig's calibration uses rectifies: each rectified
//! pixel's ray is projected into each camera by its own intrinsics (as
//! OpenCV's `initUndistortRectifyMap` does for its pinhole and fisheye
//! models).

use nalgebra::{Matrix3, Vector3};
use opencv::calib3d::{StereoSGBM, StereoSGBM_MODE_SGBM};
use opencv::core::{Mat, MatTraitConst, Scalar, BORDER_CONSTANT, CV_16S};
use opencv::prelude::{MatTraitConstManual, StereoMatcherTrait};

use crate::error::{cv, CalibError, Result};
use crate::pose::Pose;
use crate::rig::Rig;

/// The largest angle between two cameras' optical axes, and between
/// their baseline and the rectified rows, for them to form a pair
/// (degrees).
pub const MAX_PAIR_ANGLE_DEG: f64 = 30.0;

/// The shortest baseline of a pair (metres).
pub const MIN_BASELINE_M: f64 = 0.01;

/// The widest rectified view, pixels: wider cameras are rectified at a
/// smaller scale (the matcher's time and memory grow with the width times
/// the disparity range; a 1288-pixel pair took half a second a set).
pub const MAX_WIDTH: usize = 640;

/// The matcher's block side (pixels).
pub const BLOCK: i32 = 5;

/// The least texture a block needs for its disparity to count: the mean
/// |I(x+1) − I(x−1)| over the block, grey levels of 255. `StereoSGBM`
/// matches a blank block (a clipped surface, all 255) at any disparity
/// with cost 0 and its uniqueness check cannot refuse a tie at 0; and it
/// matches the noise of a smooth sky into blobs its speckle filter keeps.
/// At 2 grey levels 16 % of the simulated forward pair's disparities fell
/// in the sky at its best exposure, at 4 under 2 % (`tests/tests/stereo.rs`).
pub const MIN_TEXTURE: f64 = 4.0;

/// The pairs of `rig` (left camera, right camera): cameras with poses whose
/// optical axes are within [`MAX_PAIR_ANGLE_DEG`] of each other and whose
/// baseline (at least [`MIN_BASELINE_M`]) runs within that angle of the
/// left camera's image rows. The reference surround rig's cameras, 90°
/// apart, form none.
pub fn stereo_pairs(rig: &Rig) -> Vec<(usize, usize)> {
    let max = MAX_PAIR_ANGLE_DEG.to_radians().cos();
    let mut out = Vec::new();
    for (i, a) in rig.cameras.iter().enumerate() {
        for (j, b) in rig.cameras.iter().enumerate().skip(i + 1) {
            let (Some(pa), Some(pb)) = (&a.pose, &b.pose) else {
                continue;
            };
            if pa.optical_axis().dot(&pb.optical_axis()) < max {
                continue;
            }
            let base = pb.translation() - pa.translation();
            let Some(dir) = base.try_normalize(MIN_BASELINE_M) else {
                continue;
            };
            let along = dir.dot(&pa.rotation_matrix().column(0).into_owned());
            if along >= max {
                out.push((i, j));
            } else if -along >= max {
                out.push((j, i));
            }
        }
    }
    out
}

/// The disparities of one rectified pair.
#[derive(Clone, Debug)]
pub struct Disparities {
    /// Width and height of the rectified view, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Per rectified pixel (row-major) of the left view, its disparity in
    /// pixels, or NaN where the matcher found none.
    pub values: Vec<f32>,
    /// The matcher's disparity range, pixels.
    pub max_disparity: usize,
    /// How many pixels could have a disparity: both cameras see them and
    /// the search range fits left of them.
    pub considered: usize,
    /// How many of those have one.
    pub valid: usize,
    /// The rectified left and right views (grey, `width × height`, 0 where
    /// a camera does not see).
    pub rectified: [Vec<u8>; 2],
}

impl Disparities {
    /// The share of the considered pixels with a valid disparity (0 when
    /// none is considered).
    pub fn density(&self) -> f64 {
        if self.considered == 0 {
            0.0
        } else {
            self.valid as f64 / self.considered as f64
        }
    }
}

/// One stereo pair of a rig, rectified.
pub struct StereoRectifier {
    /// The left camera's index in the rig.
    pub left: usize,
    /// The right camera's index.
    pub right: usize,
    /// The distance between the two cameras' centres, metres.
    pub baseline_m: f64,
    /// The rectified views' focal length, pixels.
    pub focal_px: f64,
    /// The rectified views' width (the left camera's, at most
    /// [`MAX_WIDTH`]), pixels.
    pub width: usize,
    /// Their height, pixels.
    pub height: usize,
    /// The matcher's disparity range, pixels: a quarter of the width, a
    /// multiple of 16, at most 256 (the ground right below a forward pair
    /// can be nearer than that reaches, and finds no disparity).
    pub max_disparity: usize,
    /// Rows: the rectified frame's axes in the rig frame (rig → rectified).
    rotation: Matrix3<f64>,
    /// The left camera's centre, rig frame.
    origin: Vector3<f64>,
    /// Per camera (left, right): the source pixel of each rectified pixel,
    /// x and y (`CV_32FC1`, −1 where the camera does not see it).
    maps: [(Mat, Mat); 2],
    /// Rectified pixels both cameras see.
    seen: Vec<bool>,
    /// The sizes the cameras' images must have.
    sizes: [(usize, usize); 2],
}

impl std::fmt::Debug for StereoRectifier {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StereoRectifier")
            .field("left", &self.left)
            .field("right", &self.right)
            .field("baseline_m", &self.baseline_m)
            .field("focal_px", &self.focal_px)
            .field("width", &self.width)
            .field("height", &self.height)
            .finish_non_exhaustive()
    }
}

impl StereoRectifier {
    /// Rectifies cameras `left` and `right` of `rig` (as [`stereo_pairs`]
    /// orders them). The rectified views share the left camera's image size
    /// and the mean of the two cameras' focal lengths (both scaled down to
    /// [`MAX_WIDTH`] where the camera is wider), their principal point at
    /// the image centre; their z axis is the mean of the optical axes,
    /// their x axis the baseline.
    pub fn new(rig: &Rig, left: usize, right: usize) -> Result<Self> {
        let camera = |k: usize| {
            rig.cameras.get(k).ok_or_else(|| {
                CalibError::Argument(format!(
                    "stereo pair: camera index {k}, the rig has {} cameras",
                    rig.cameras.len()
                ))
            })
        };
        let (a, b) = (camera(left)?, camera(right)?);
        let pose = |c: &crate::rig::Camera| {
            c.pose.ok_or_else(|| {
                CalibError::Argument(format!(
                    "stereo pair: camera \"{}\" has no pose in the rig",
                    c.name
                ))
            })
        };
        let (pa, pb) = (pose(a)?, pose(b)?);
        let base = pb.translation() - pa.translation();
        let baseline_m = base.norm();
        let x = base.try_normalize(MIN_BASELINE_M).ok_or_else(|| {
            CalibError::Argument(format!(
                "stereo pair \"{}\"–\"{}\": the cameras are {baseline_m:.4} m apart, expected at least {MIN_BASELINE_M} m",
                a.name, b.name
            ))
        })?;
        if x.dot(&pa.rotation_matrix().column(0).into_owned()) <= 0.0 {
            return Err(CalibError::Argument(format!(
                "stereo pair: camera \"{}\" is not left of \"{}\" in its own image",
                a.name, b.name
            )));
        }
        let mean_axis = pa.optical_axis() + pb.optical_axis();
        let z = (mean_axis - x * x.dot(&mean_axis))
            .try_normalize(1e-9)
            .ok_or_else(|| {
                CalibError::Argument(format!(
                    "stereo pair \"{}\"–\"{}\": the cameras look along their baseline",
                    a.name, b.name
                ))
            })?;
        let y = z.cross(&x);
        let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        // The left camera's size and the mean focal length, scaled down to
        // at most MAX_WIDTH.
        let scale = (MAX_WIDTH as f64 / f64::from(a.intrinsics.width)).min(1.0);
        let (width, height) = (
            (f64::from(a.intrinsics.width) * scale).round() as usize,
            (f64::from(a.intrinsics.height) * scale).round() as usize,
        );
        let focal_px =
            0.25 * scale * (a.intrinsics.fx + a.intrinsics.fy + b.intrinsics.fx + b.intrinsics.fy);
        if width < 2 || height < 2 || !(focal_px.is_finite() && focal_px > 0.0) {
            return Err(CalibError::Argument(format!(
                "stereo pair \"{}\"–\"{}\": a {width}×{height} image with focal length {focal_px} px cannot be rectified",
                a.name, b.name
            )));
        }
        let max_disparity = (width / 4).div_ceil(16).clamp(1, 16) * 16;
        let (cx, cy) = centre(width, height);
        let rows = i32::try_from(height)
            .map_err(|_| CalibError::Argument("stereo pair: image too tall".into()))?;
        let wrap = |m: &[f32]| -> Result<Mat> {
            cv(
                "wrapping a rectification map",
                Mat::new_rows_cols_with_data(rows, width as i32, m),
            )?
            .try_clone()
            .map_err(|source| CalibError::OpenCv {
                context: "copying a rectification map".into(),
                source,
            })
        };
        let mut seen = vec![true; width * height];
        let mut map_of = |c: &crate::rig::Camera, pose: &Pose| -> Result<(Mat, Mat)> {
            let projector = c.intrinsics.projector();
            let to_camera = pose.rotation_matrix().transpose() * rotation.transpose();
            let (cw, ch) = (
                f64::from(c.intrinsics.width),
                f64::from(c.intrinsics.height),
            );
            let mut mx = vec![-1f32; width * height];
            let mut my = vec![-1f32; width * height];
            for v in 0..height {
                for u in 0..width {
                    let ray =
                        Vector3::new((u as f64 - cx) / focal_px, (v as f64 - cy) / focal_px, 1.0);
                    let k = v * width + u;
                    match projector.project(&(to_camera * ray)) {
                        Some(q)
                            if q.x >= 0.0 && q.y >= 0.0 && q.x <= cw - 1.0 && q.y <= ch - 1.0 =>
                        {
                            mx[k] = q.x as f32;
                            my[k] = q.y as f32;
                        }
                        _ => seen[k] = false,
                    }
                }
            }
            Ok((wrap(&mx)?, wrap(&my)?))
        };
        let (l, r) = (map_of(a, &pa)?, map_of(b, &pb)?);
        Ok(Self {
            left,
            right,
            baseline_m,
            focal_px,
            width,
            height,
            max_disparity,
            rotation,
            origin: *pa.translation(),
            maps: [l, r],
            seen,
            sizes: [
                (a.intrinsics.width as usize, a.intrinsics.height as usize),
                (b.intrinsics.width as usize, b.intrinsics.height as usize),
            ],
        })
    }

    /// Where a rig-frame point shows in the rectified views: its left
    /// view's pixel (x, y) and its disparity (pixels; the right view shows
    /// it at x − disparity, the same row). `None` behind the views.
    pub fn rectified(&self, p: &Vector3<f64>) -> Option<(f64, f64, f64)> {
        let q = self.rotation * (p - self.origin);
        if q.z <= 1e-9 {
            return None;
        }
        let (cx, cy) = centre(self.width, self.height);
        Some((
            self.focal_px * q.x / q.z + cx,
            self.focal_px * q.y / q.z + cy,
            self.focal_px * self.baseline_m / q.z,
        ))
    }

    /// The ray (rig frame, from the left camera's centre) of a rectified
    /// left-view pixel.
    pub fn ray(&self, x: f64, y: f64) -> (Vector3<f64>, Vector3<f64>) {
        let (cx, cy) = centre(self.width, self.height);
        let r = Vector3::new((x - cx) / self.focal_px, (y - cy) / self.focal_px, 1.0);
        (self.origin, self.rotation.transpose() * r)
    }

    /// The source pixel of rectified pixel (x, y) in the left (`0`) or
    /// right (`1`) camera, `None` where that camera does not see it.
    pub fn source_pixel(&self, camera: usize, x: usize, y: usize) -> Option<(f32, f32)> {
        let (mx, my) = self.maps.get(camera)?;
        if x >= self.width || y >= self.height {
            return None;
        }
        let (x, y) = (x as i32, y as i32);
        let px = *mx.at_2d::<f32>(y, x).ok()?;
        let py = *my.at_2d::<f32>(y, x).ok()?;
        (px >= 0.0).then_some((px, py))
    }

    /// Camera `camera`'s (`0` left, `1` right) 8-bit grey image, rectified
    /// (0 where the camera does not see).
    fn rectify_mat(&self, camera: usize, grey: &[u8]) -> Result<Mat> {
        let ((w, h), (mx, my)) = self
            .sizes
            .get(camera)
            .zip(self.maps.get(camera))
            .ok_or_else(|| CalibError::Argument(format!("stereo pair: no camera {camera}")))?;
        if grey.len() != w * h {
            return Err(CalibError::Argument(format!(
                "stereo pair: camera {}'s image has {} bytes, expected {w}×{h} = {}",
                if camera == 0 { self.left } else { self.right },
                grey.len(),
                w * h
            )));
        }
        let src = cv(
            "wrapping an image to rectify",
            Mat::new_rows_cols_with_data(*h as i32, *w as i32, grey),
        )?;
        let mut out = Mat::default();
        cv(
            "rectifying an image",
            opencv::imgproc::remap(
                &src,
                &mut out,
                mx,
                my,
                opencv::imgproc::INTER_LINEAR,
                BORDER_CONSTANT,
                Scalar::all(0.0),
            ),
        )?;
        Ok(out)
    }

    /// The disparities of the pair's 8-bit grey images (each at its
    /// camera's calibrated size): both rectified, then matched by
    /// `StereoSGBM` (blocks of [`BLOCK`] pixels, disparities
    /// 0..[`Self::max_disparity`], uniqueness 10 %, left–right check within
    /// a pixel, speckles of under 100 pixels removed); a disparity in a
    /// block of the left view with less than [`MIN_TEXTURE`] is refused.
    pub fn disparities(&self, left: &[u8], right: &[u8]) -> Result<Disparities> {
        let l = self.rectify_mat(0, left)?;
        let r = self.rectify_mat(1, right)?;
        let area = BLOCK * BLOCK;
        let mut sgbm = cv(
            "creating the stereo matcher",
            StereoSGBM::create(
                0,
                self.max_disparity as i32,
                BLOCK,
                8 * area,
                32 * area,
                1,
                63,
                10,
                100,
                2,
                StereoSGBM_MODE_SGBM,
            ),
        )?;
        let mut disp = Mat::default();
        cv("matching the stereo pair", sgbm.compute(&l, &r, &mut disp))?;
        if disp.typ() != CV_16S || disp.rows() as usize != self.height {
            return Err(CalibError::Argument(format!(
                "stereo pair: the matcher returned a {}×{} map of type {}",
                disp.cols(),
                disp.rows(),
                disp.typ()
            )));
        }
        let raw = cv("reading the disparities", disp.data_typed::<i16>())?;
        let left_bytes = cv("reading a rectified image", l.data_bytes())?.to_vec();
        let right_bytes = cv("reading a rectified image", r.data_bytes())?.to_vec();
        let textured = textured(&left_bytes, self.width, self.height);
        let (mut considered, mut valid) = (0, 0);
        let values = raw
            .iter()
            .enumerate()
            .map(|(k, &d)| {
                let counted = self.seen[k] && k % self.width >= self.max_disparity;
                considered += usize::from(counted);
                if d >= 0 && textured[k] {
                    valid += usize::from(counted);
                    f32::from(d) / 16.0
                } else {
                    f32::NAN
                }
            })
            .collect();
        Ok(Disparities {
            width: self.width,
            height: self.height,
            values,
            max_disparity: self.max_disparity,
            considered,
            valid,
            rectified: [left_bytes, right_bytes],
        })
    }
}

/// The principal point of a `width × height` rectified view: its centre.
fn centre(width: usize, height: usize) -> (f64, f64) {
    (0.5 * (width as f64 - 1.0), 0.5 * (height as f64 - 1.0))
}

/// Per pixel of a `width × height` grey image: whether the
/// [`BLOCK`]-sided block around it has [`MIN_TEXTURE`].
fn textured(image: &[u8], width: usize, height: usize) -> Vec<bool> {
    // Column differences, then their sums over blocks by an integral image.
    let w1 = width + 1;
    let mut integral = vec![0u32; w1 * (height + 1)];
    for y in 0..height {
        let row = &image[y * width..(y + 1) * width];
        let mut run = 0u32;
        for x in 0..width {
            let d = if x == 0 || x + 1 == width {
                0
            } else {
                u32::from(row[x + 1].abs_diff(row[x - 1]))
            };
            run += d;
            integral[(y + 1) * w1 + x + 1] = integral[y * w1 + x + 1] + run;
        }
    }
    let r = (BLOCK / 2) as usize;
    let min = MIN_TEXTURE * f64::from(BLOCK * BLOCK);
    let mut out = vec![false; width * height];
    for y in 0..height {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(height));
        for x in 0..width {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(width));
            let sum = integral[y1 * w1 + x1] + integral[y0 * w1 + x0]
                - integral[y0 * w1 + x1]
                - integral[y1 * w1 + x0];
            // (Blocks cut by the border are scaled to a whole one.)
            let area = ((y1 - y0) * (x1 - x0)) as f64;
            out[y * width + x] = f64::from(sum) * f64::from(BLOCK * BLOCK) / area >= min;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Distortion, Intrinsics};
    use crate::pose::Pose;
    use crate::rig::{Camera, Frame};
    use nalgebra::Point2;

    fn fisheye(width: u32, height: u32) -> Intrinsics {
        Intrinsics {
            width,
            height,
            fx: 0.3 * f64::from(width),
            fy: 0.3 * f64::from(width),
            cx: 0.5 * f64::from(width) - 0.3,
            cy: 0.5 * f64::from(height) + 0.7,
            distortion: Distortion::Fisheye([0.02, -0.005, 0.0, 0.0]),
        }
    }

    /// Two forward cameras `baseline` metres apart across the vehicle
    /// (right camera on the −y side), toed in and rolled a little, and a
    /// third looking left.
    fn rig(baseline: f64) -> Rig {
        rig_of(baseline, 320, 240)
    }

    fn rig_of(baseline: f64, width: u32, height: u32) -> Rig {
        let cam = |name: &str, ypr: [f64; 3], t: [f64; 3]| Camera {
            name: name.into(),
            device: None,
            intrinsics: fisheye(width, height),
            pose: Some(Pose::from_ypr_deg(ypr, Vector3::from(t)).unwrap()),
        };
        Rig::new(
            Frame::Vehicle,
            vec![
                cam("side", [90.0, 30.0, 0.0], [1.0, 1.0, 1.0]),
                cam("right", [2.0, 15.0, -1.5], [2.3, -0.5 * baseline, 0.9]),
                cam("left", [-1.0, 16.0, 1.0], [2.3, 0.5 * baseline, 0.92]),
            ],
            Vec::new(),
        )
        .unwrap()
    }

    #[test]
    fn pairs_are_found_left_first_and_cameras_apart_are_not() {
        assert_eq!(stereo_pairs(&rig(0.3)), vec![(2, 1)]);
        assert!(stereo_pairs(&rig(0.001)).is_empty());
        assert!(StereoRectifier::new(&rig(0.3), 1, 2).is_err());
        assert!(StereoRectifier::new(&rig(0.3), 2, 7).is_err());
    }

    #[test]
    fn the_maps_send_a_scene_point_to_both_cameras_on_one_row() {
        maps_match_the_cameras(320, 240);
        // Wider cameras are rectified at a smaller scale.
        maps_match_the_cameras(1288, 964);
    }

    fn maps_match_the_cameras(width: u32, height: u32) {
        let rig = rig_of(0.3, width, height);
        let s = StereoRectifier::new(&rig, 2, 1).unwrap();
        let scale = (MAX_WIDTH as f64 / f64::from(width)).min(1.0);
        assert_eq!(s.width, (f64::from(width) * scale).round() as usize);
        assert_eq!(s.height, (f64::from(height) * scale).round() as usize);
        assert!((s.baseline_m - 0.3).abs() < 1e-3, "{}", s.baseline_m);
        let (mut checked, mut worst) = (0, 0.0f64);
        for k in 0..200 {
            // Points 2–20 m ahead, across and up and down.
            let t = f64::from(k) / 200.0;
            let p = Vector3::new(
                4.3 + 18.0 * t,
                (13.0 * t).sin() * 3.0,
                0.9 + (7.0 * t).cos() * 1.5,
            );
            let Some((x, y, d)) = s.rectified(&p) else {
                continue;
            };
            assert!(d > 0.0, "the right view shows a point left of the left's");
            let xr = x - d;
            if !(x >= 0.0 && xr >= 0.0 && y >= 0.0) {
                continue;
            }
            let (xi, yi, xri) = (x.round() as usize, y.round() as usize, xr.round() as usize);
            if xi >= s.width || yi >= s.height {
                continue;
            }
            // Each camera's own projection of the point lands where the
            // maps put the point's (rounded) rectified pixels: the same row
            // in both views, disparity d apart.
            for (cam, index, xx) in [(0usize, 2usize, xi), (1, 1, xri)] {
                let c = &rig.cameras[index];
                let Some(direct) = c.intrinsics.project(&c.pose.unwrap().to_camera(&p)) else {
                    continue;
                };
                let Some((mx, my)) = s.source_pixel(cam, xx, yi) else {
                    continue;
                };
                let err = (f64::from(mx) - direct.x).hypot(f64::from(my) - direct.y);
                worst = worst.max(err);
                checked += 1;
            }
        }
        assert!(checked > 100, "{checked} points checked");
        // (Rounding moves a rectified pixel by up to 0.71 px, which the
        // lens shrinks away from the centre, and a scaled-down view
        // stretches by 1 / scale.)
        assert!(worst < 0.75 / scale, "maps off by {worst} px");
    }

    /// Camera `index` of `rig` seeing a wall (the plane `n·p = c`, rig
    /// frame) textured with a pattern of its own coordinates, or blank.
    fn wall_image(rig: &Rig, index: usize, n: Vector3<f64>, c: f64, textured: bool) -> Vec<u8> {
        let texture = |p: &Vector3<f64>| {
            // Two coordinates across the wall.
            let e1 = if n.z.abs() < 0.9 {
                Vector3::z().cross(&n)
            } else {
                Vector3::x().cross(&n)
            }
            .normalize();
            let e2 = n.cross(&e1);
            let (a, b) = (p.dot(&e1) * 9.0, p.dot(&e2) * 11.0);
            let k = ((a.floor() as i64 * 7919 + b.floor() as i64 * 104_729) % 251 + 251) % 251;
            (40 + k * 3 / 4) as u8
        };
        let cam = &rig.cameras[index];
        let pose = cam.pose.unwrap();
        let (w, h) = (
            cam.intrinsics.width as usize,
            cam.intrinsics.height as usize,
        );
        let mut out = vec![0u8; w * h];
        for v in 0..h {
            for u in 0..w {
                let Some(r) = cam.intrinsics.unproject(&Point2::new(u as f64, v as f64)) else {
                    continue;
                };
                let d = pose.rotation_matrix() * r.into_inner();
                if n.dot(&d) <= 1e-6 {
                    continue;
                }
                let t = (c - n.dot(pose.translation())) / n.dot(&d);
                let p = pose.translation() + d * t;
                out[v * w + u] = if textured { texture(&p) } else { 128 };
            }
        }
        out
    }

    /// The disparities of pair `s` of `rig` on the wall `n·p = c`: their
    /// density and median |error| against the wall's geometry.
    fn on_the_wall(rig: &Rig, s: &StereoRectifier, n: Vector3<f64>, c: f64) -> (f64, f64) {
        let got = s
            .disparities(
                &wall_image(rig, s.left, n, c, true),
                &wall_image(rig, s.right, n, c, true),
            )
            .unwrap();
        // The true disparity of each rectified pixel: f·b over the depth
        // (along the rectified axis, which the ray has at 1) of the wall
        // point its ray meets.
        let truth = |k: usize| {
            let (o, ray) = s.ray((k % s.width) as f64, (k / s.width) as f64);
            let t = (c - n.dot(&o)) / n.dot(&ray);
            s.focal_px * s.baseline_m / t
        };
        let mut errors: Vec<f64> = got
            .values
            .iter()
            .enumerate()
            .filter(|(_, d)| d.is_finite())
            .map(|(k, &d)| (f64::from(d) - truth(k)).abs())
            .collect();
        errors.sort_by(f64::total_cmp);
        (got.density(), errors[errors.len() / 2])
    }

    #[test]
    fn a_textured_plane_gives_dense_disparities_at_its_depth_and_a_blank_one_none() {
        let rig = rig(0.3);
        let s = StereoRectifier::new(&rig, 2, 1).unwrap();
        // A vertical wall 6 m ahead.
        let (n, c) = (Vector3::x(), 8.3);
        let (density, median) = on_the_wall(&rig, &s, n, c);
        println!("wall: density {density:.3}, median |error| {median:.3} px");
        assert!(density > 0.5, "density {density}");
        assert!(median < 0.5, "median error {median} px");
        let blank = s
            .disparities(
                &wall_image(&rig, 2, n, c, false),
                &wall_image(&rig, 1, n, c, false),
            )
            .unwrap();
        assert!(blank.density() < 0.05, "blank density {}", blank.density());
        // Wrong sizes are refused.
        assert!(s
            .disparities(&[0u8; 10], &wall_image(&rig, 1, n, c, true))
            .is_err());
    }

    /// A stereo camera's Kalibr camchain (poses relative to cam0, cam1
    /// 11 cm to its right and rolled 0.8°, pinhole with radial-tangential
    /// distortion, as in public stereo datasets): the pair is found and
    /// matches a wall 4 m ahead.
    #[test]
    fn a_kalibr_stereo_camchain_is_a_pair() {
        let text = "cam0:\n  camera_model: pinhole\n  intrinsics: [458.7, 457.3, 367.2, 248.4]\n  distortion_model: radtan\n  distortion_coeffs: [-0.2834, 0.07396, 0.0001936, 1.762e-05]\n  resolution: [752, 480]\n  cam_overlaps: [1]\ncam1:\n  T_cn_cnm1:\n  - [1.0, 0.0, 0.0, -0.11007]\n  - [0.0, 0.9999020016006562, -0.013999542671148512, 0.0004]\n  - [0.0, 0.013999542671148512, 0.9999020016006562, -0.00085]\n  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  intrinsics: [457.6, 456.1, 379.9, 255.2]\n  distortion_model: radtan\n  distortion_coeffs: [-0.2837, 0.07451, -0.0001048, -3.555e-05]\n  resolution: [752, 480]\n  cam_overlaps: [0]\n";
        let rig = crate::formats::kalibr::parse(text, "camchain.yaml").unwrap();
        assert_eq!(stereo_pairs(&rig), vec![(0, 1)]);
        let s = StereoRectifier::new(&rig, 0, 1).unwrap();
        assert!((s.baseline_m - 0.110).abs() < 1e-3, "{}", s.baseline_m);
        assert_eq!((s.width, s.height), (640, 409));
        let (density, median) = on_the_wall(&rig, &s, Vector3::z(), 4.0);
        println!("camchain wall: density {density:.3}, median |error| {median:.3} px");
        assert!(density > 0.5, "density {density}");
        assert!(median < 0.5, "median error {median} px");
    }
}
