//! What the composition benchmarks share: the benchmark rig (four 185°
//! equidistant fisheyes at 1288×964 around a 4.6 m × 1.9 m car), random
//! RGB frames, and the OpenCV-remap peer that composes a view's maps.
#![allow(dead_code)]

use nalgebra::Vector3;
use opencv::core::{self, Mat, MatTraitConst, MatTraitConstManual, Scalar};
use opencv::imgproc;
use rand::{Rng, SeedableRng};
use rigview_calib::model::{Distortion, Intrinsics};
use rigview_calib::pose::Pose;
use rigview_calib::rig::{Camera, Frame, Rig};
use rigview_core::exposure::{FrameView, PixelFormat};
use rigview_core::surround::Mosaic;

pub const W: usize = 1288;
pub const H: usize = 964;

pub fn rig() -> Rig {
    // Equidistant: r = f·θ; 185° across the width.
    let f = (W as f64 / 2.0) / (92.5f64).to_radians();
    let intrinsics = Intrinsics {
        width: W as u32,
        height: H as u32,
        fx: f,
        fy: f,
        cx: W as f64 / 2.0 - 0.5,
        cy: H as f64 / 2.0 - 0.5,
        distortion: Distortion::Fisheye([0.0; 4]),
    };
    let cams = [
        ("front", [0.0, 30.0, 0.0], [2.3, 0.0, 1.0]),
        ("left", [90.0, 45.0, 0.0], [0.0, 0.95, 1.0]),
        ("back", [180.0, 30.0, 0.0], [-2.3, 0.0, 1.0]),
        ("right", [-90.0, 45.0, 0.0], [0.0, -0.95, 1.0]),
    ];
    let cameras = cams
        .iter()
        .map(|(name, ypr, t)| {
            let mut c = Camera::new(*name, intrinsics);
            c.pose = Some(Pose::from_ypr_deg(*ypr, Vector3::from(*t)).unwrap());
            c
        })
        .collect();
    Rig::new(
        Frame::Vehicle,
        cameras,
        vec![(0, 1), (1, 2), (2, 3), (0, 3)],
    )
    .unwrap()
}

/// The OpenCV-remap peer composes the same view within a few levels (it
/// rounds positions to 1/32 px): fewer than 1 % of the values differ by
/// more than 10.
pub fn assert_like_opencv_remap(ours: &[u8], opencv: &[u8]) {
    let differ = ours
        .iter()
        .zip(opencv)
        .filter(|(a, b)| a.abs_diff(**b) > 10)
        .count();
    assert!(
        differ < ours.len() / 100,
        "the OpenCV-remap composition differs: {differ} values"
    );
}

pub fn frames() -> Vec<Vec<u8>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    (0..4)
        .map(|_| (0..W * H * 3).map(|_| rng.gen::<u8>()).collect())
        .collect()
}

/// [`frames`] as RGB8 views.
pub fn rgb_views(data: &[Vec<u8>]) -> Vec<FrameView<'_>> {
    data.iter()
        .map(|d| FrameView::new(PixelFormat::Rgb8, W, H, d).unwrap())
        .collect()
}

/// One camera's part of [`OpencvRemap`]: the fixed-point maps of its ROI,
/// and its runs of ROI pixels (row, first column, length, blended with
/// other cameras).
struct CameraRemap {
    map1: Mat,
    map2: Mat,
    runs: Vec<(usize, usize, usize, bool)>,
}

/// The composition through OpenCV's `remap` (rigview's before its own
/// remap), with its tables built once from the view's maps and linear
/// weights.
pub struct OpencvRemap {
    cameras: Vec<CameraRemap>,
    /// The runs of canvas pixels blended from several cameras (first pixel,
    /// length).
    blended: Vec<(usize, usize)>,
    warped: Mat,
    acc: Vec<u16>,
}

impl OpencvRemap {
    pub fn new(view: &Mosaic) -> Self {
        let (w, h) = view.size();
        let mut blended = vec![false; w * h];
        let cameras = view
            .layers()
            .iter()
            .map(|layer| {
                let [c0, r0, rw, rh] = layer.roi;
                // Pixels without a source read the first pixel (weight 0):
                // an in-range position keeps `remap` on its fast path.
                let flat: Vec<f32> = layer
                    .map
                    .iter()
                    .flat_map(|p| if p[0] >= 0.0 { *p } else { [0.0, 0.0] })
                    .collect();
                let xy = Mat::new_rows_cols_with_data(rh as i32, 2 * rw as i32, &flat).unwrap();
                let xy = xy.reshape(2, rh as i32).unwrap();
                let (mut m1, mut m2) = (Mat::default(), Mat::default());
                imgproc::convert_maps(
                    &xy,
                    &Mat::default(),
                    &mut m1,
                    &mut m2,
                    core::CV_16SC2,
                    false,
                )
                .unwrap();
                let mut runs = Vec::new();
                for (row, line) in layer.weights[0].chunks_exact(rw).enumerate() {
                    let mut col = 0;
                    while col < rw {
                        if line[col] == 0 {
                            col += 1;
                            continue;
                        }
                        let blend = line[col] < 256;
                        let start = col;
                        while col < rw && line[col] != 0 && (line[col] < 256) == blend {
                            col += 1;
                        }
                        runs.push((row, start, col - start, blend));
                        if blend {
                            let s = (r0 + row) * w + c0 + start;
                            blended[s..s + col - start].fill(true);
                        }
                    }
                }
                CameraRemap {
                    map1: m1,
                    map2: m2,
                    runs,
                }
            })
            .collect();
        let mut runs = Vec::new();
        let mut i = 0;
        while i < w * h {
            if !blended[i] {
                i += 1;
                continue;
            }
            let start = i;
            while i < w * h && blended[i] && i / w == start / w {
                i += 1;
            }
            runs.push((start, i - start));
        }
        Self {
            cameras,
            blended: runs,
            warped: Mat::default(),
            acc: vec![0; w * h * 3],
        }
    }

    /// Composes RGB `frames` with linear blending into `out` (RGB, the
    /// canvas size).
    pub fn compose(&mut self, view: &Mosaic, frames: &[Vec<u8>], out: &mut [u8]) {
        let w = view.size().0;
        out.fill(0);
        for &(start, len) in &self.blended {
            self.acc[3 * start..3 * (start + len)].fill(0);
        }
        for ((layer, cam), f) in view.layers().iter().zip(&self.cameras).zip(frames) {
            let src = Mat::new_rows_cols_with_data(H as i32, (W * 3) as i32, f).unwrap();
            let src = src.reshape(3, H as i32).unwrap();
            imgproc::remap(
                &src,
                &mut self.warped,
                &cam.map1,
                &cam.map2,
                imgproc::INTER_LINEAR,
                core::BORDER_CONSTANT,
                Scalar::all(0.0),
            )
            .unwrap();
            let warped = self.warped.data_bytes().unwrap();
            let [c0, r0, rw, _] = layer.roi;
            for &(row, col, len, blend) in &cam.runs {
                let s = &warped[3 * (row * rw + col)..3 * (row * rw + col + len)];
                let start = 3 * ((r0 + row) * w + c0 + col);
                if !blend {
                    out[start..start + 3 * len].copy_from_slice(s);
                    continue;
                }
                let wrow = &layer.weights[0][row * rw + col..row * rw + col + len];
                let dst = &mut self.acc[start..start + 3 * len];
                for ((d, s), &wt) in dst.chunks_exact_mut(3).zip(s.chunks_exact(3)).zip(wrow) {
                    for c in 0..3 {
                        d[c] += wt * u16::from(s[c]);
                    }
                }
            }
        }
        for &(start, len) in &self.blended {
            let span = 3 * start..3 * (start + len);
            for (o, &v) in out[span.clone()].iter_mut().zip(&self.acc[span]) {
                *o = ((u32::from(v) + 128) >> 8).min(255) as u8;
            }
        }
    }
}
