#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Surround-view composition: four 1288×964 RGB fisheye frames into a
//! 1000×1000 canvas (10 m × 10 m at 100 px/m) with linear blending, on one
//! core (OpenCV limited to one thread for both).
//!
//! - `rigview`: `Composer::compose` — one pass over the canvas with a plan
//!   built once: per pixel one gathered fixed-point bilinear sample per
//!   contributing camera, the blend weights folded into the bilinear ones
//!   (AVX-512/AVX2 where the CPU has them). From RGB8 frames, from Mono8
//!   frames (the green bytes of the RGB ones), from BayerRG8 mosaics of the
//!   RGB frames (demosaiced inside the remap), and each of these with a
//!   display gain per camera (`Composer::compose_with_gains`, gains 1.5,
//!   0.75, 2 and 1.25).
//! - `opencv_demosaic_then_rigview_rgb`: the mosaics demosaiced whole by
//!   OpenCV's `cvtColor` (`COLOR_BayerRGGB2RGB`), then composed from RGB8:
//!   the separate pass that demosaicing inside the remap saves.
//! - `opencv_remap`: the composition rigview had before its own remap —
//!   per camera one OpenCV fixed-point `remap` (maps from `convertMaps`,
//!   built once) straight from the fisheye image over its part of the
//!   canvas, copies where one camera shows the ground, 8-bit-weighted sums
//!   in the overlaps.
//! - `reference`: the straightforward pipeline — per camera, undistort the
//!   fisheye image to a pinhole view (`fisheye::initUndistortRectifyMap` once,
//!   `remap` per frame), `warpPerspective` it onto the whole canvas through
//!   the ground homography, and blend in floating point with the same
//!   weights.
//!
//! The rig: four 185° equidistant fisheyes at 1288×964, 1 m high, looking
//! past the four sides of a 4.6 m × 1.9 m car, tilted down (front and back
//! 30°, sides 45°). Results: `BENCHMARKS.md`.
//!
//! Two image operations of the view, each against the OpenCV call it
//! replaces (one OpenCV thread):
//!
//! - `rgb_to_mono_4x1288x964`: `image::rgb8_to_mono8` of the four frames
//!   (what "mono from RGB" composes from) against `cvtColor RGB2GRAY`.
//! - `patch_means_4x1288x964`: the balancing's patch means of the view's
//!   overlaps (`SurroundView::pair_observations`, each camera's samples
//!   read in one sweep in memory order) against reading them patch by
//!   patch (what it did before), from Mono8 and RGB8 frames. The frames of
//!   eight sets are cycled (40 MB of Mono8, more than the last-level
//!   cache), as each set's frames arrive fresh in the pipeline.
//! - `distance_transform_1000x1000`: `image::distance_to_zero` of the
//!   complement of the front camera's exclusive region (once per camera
//!   when a view is built) against `distanceTransform` `DIST_L2` with
//!   `DIST_MASK_PRECISE` (the same exact distances) and with `DIST_MASK_5`
//!   (the chamfer approximation rigview called before).

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};
use nalgebra::{Matrix3, Vector3};
use opencv::core::{self, Mat, MatTraitConst, MatTraitConstManual, Scalar, Size, CV_32F, CV_32FC3};
use opencv::{calib3d, imgproc};
use rigview_calib::pose::Pose;
use rigview_calib::rig::Rig;
use rigview_core::exposure::{FrameView, PixelFormat};
use rigview_core::image::{distance_to_zero, rgb8_to_mono8};
use rigview_core::panorama::{
    CylinderSpec, MatchOptions, MatchTimes, Panorama, PanoramaOptions, RefineOptions,
};
use rigview_core::sim::{SimConfig, SimRender};
use rigview_core::surround::{
    BlendMode, Canvas, CanvasSpec, Composer, SurroundOptions, SurroundView,
};

mod common;

use common::{assert_like_opencv_remap, frames, rgb_views, rig, OpencvRemap, H, W};

/// The straightforward pipeline, with its per-camera tables built once.
struct Reference {
    undistort: Vec<(Mat, Mat)>,
    homography: Vec<Mat>,
    weights: Vec<Mat>,
    undistorted: Mat,
    warped: Mat,
    warped_f: Mat,
    weighted: Mat,
    acc: Mat,
    out: Mat,
}

impl Reference {
    fn new(rig: &Rig, spec: &CanvasSpec, view: &SurroundView) -> Self {
        let (cw, ch) = view.size();
        let mut undistort = Vec::new();
        let mut homography = Vec::new();
        for cam in &rig.cameras {
            let k = &cam.intrinsics;
            let km = Mat::from_slice_2d(&k.camera_matrix()).unwrap();
            let d = Mat::from_slice(&[0.0f64; 4]).unwrap();
            // A pinhole view of 120° across the width.
            let fp = (W as f64 / 2.0) / (60f64).to_radians().tan();
            let p = [[fp, 0.0, k.cx], [0.0, fp, k.cy], [0.0, 0.0, 1.0]];
            let pm = Mat::from_slice_2d(&p).unwrap();
            let (mut m1, mut m2) = (Mat::default(), Mat::default());
            calib3d::fisheye_init_undistort_rectify_map(
                &km,
                &d,
                &Mat::eye(3, 3, core::CV_64F).unwrap(),
                &pm,
                Size::new(W as i32, H as i32),
                core::CV_16SC2,
                &mut m1,
                &mut m2,
            )
            .unwrap();
            undistort.push((m1, m2));
            // Canvas (c, r, 1) → ground (x, y, 1) → pinhole pixel.
            let pose = cam.pose.unwrap();
            let r_cw = pose.rotation_matrix().transpose();
            let t_cw = -r_cw * pose.translation();
            let ground_to_cam = Matrix3::from_columns(&[
                r_cw.column(0).into_owned(),
                r_cw.column(1).into_owned(),
                t_cw,
            ]);
            let ppm = spec.px_per_m;
            let canvas_to_ground = Matrix3::new(
                0.0,
                -1.0 / ppm,
                spec.x_max_m - 0.5 / ppm,
                -1.0 / ppm,
                0.0,
                spec.y_max_m - 0.5 / ppm,
                0.0,
                0.0,
                1.0,
            );
            let kp = Matrix3::new(fp, 0.0, k.cx, 0.0, fp, k.cy, 0.0, 0.0, 1.0);
            let h = kp * ground_to_cam * canvas_to_ground;
            let rows: Vec<[f64; 3]> = (0..3).map(|r| [h[(r, 0)], h[(r, 1)], h[(r, 2)]]).collect();
            homography.push(Mat::from_slice_2d(&rows).unwrap());
        }
        // The same linear weights as rigview's, as full-canvas floats.
        let weights = view
            .layers()
            .iter()
            .map(|layer| {
                let mut full = vec![0.0f32; cw * ch];
                let [c0, r0, rw, rh] = layer.roi;
                for rr in 0..rh {
                    for cc in 0..rw {
                        full[(r0 + rr) * cw + c0 + cc] =
                            f32::from(layer.weights[0][rr * rw + cc]) / 256.0;
                    }
                }
                let m = Mat::new_rows_cols_with_data(ch as i32, cw as i32, &full)
                    .unwrap()
                    .try_clone()
                    .unwrap();
                let mut m3 = Mat::default();
                imgproc::cvt_color(&m, &mut m3, imgproc::COLOR_GRAY2RGB, 0).unwrap();
                m3
            })
            .collect();
        Self {
            undistort,
            homography,
            weights,
            undistorted: Mat::default(),
            warped: Mat::default(),
            warped_f: Mat::default(),
            weighted: Mat::default(),
            acc: Mat::default(),
            out: Mat::default(),
        }
    }

    fn compose(&mut self, frames: &[Vec<u8>], size: (usize, usize)) {
        let dsize = Size::new(size.0 as i32, size.1 as i32);
        self.acc = Mat::new_size_with_default(dsize, CV_32FC3, Scalar::all(0.0)).unwrap();
        for (k, f) in frames.iter().enumerate() {
            undistort(f, &self.undistort[k], &mut self.undistorted);
            imgproc::warp_perspective(
                &self.undistorted,
                &mut self.warped,
                &self.homography[k],
                dsize,
                imgproc::INTER_LINEAR | imgproc::WARP_INVERSE_MAP,
                core::BORDER_CONSTANT,
                Scalar::all(0.0),
            )
            .unwrap();
            self.warped
                .convert_to(&mut self.warped_f, CV_32F, 1.0, 0.0)
                .unwrap();
            core::multiply(
                &self.warped_f,
                &self.weights[k],
                &mut self.weighted,
                1.0,
                -1,
            )
            .unwrap();
            let mut sum = Mat::default();
            core::add(&self.acc, &self.weighted, &mut sum, &core::no_array(), -1).unwrap();
            self.acc = sum;
        }
        self.acc
            .convert_to(&mut self.out, core::CV_8U, 1.0, 0.0)
            .unwrap();
    }
}

/// OpenCV's own route to a cylindrical panorama: per camera, the fisheye
/// image undistorted to a pinhole view (`fisheye::initUndistortRectifyMap`
/// once, `remap` per frame), warped onto the cylinder by
/// `detail::CylindricalWarper` (its maps built in each call, as the
/// stitching pipeline does), converted to 16 bits and fed to a
/// `detail::FeatherBlender` with its warped mask (warped once). Its
/// cylinder is at infinity (OpenCV's warper has no radius) and its scale
/// gives 4096 pixels for 360°.
struct OpencvStitching {
    undistort: Vec<(Mat, Mat)>,
    k: Mat,
    rotations: Vec<Mat>,
    masks: Vec<Mat>,
    warper: opencv::stitching::Detail_CylindricalWarper,
    roi: core::Rect,
    undistorted: Mat,
    warped: Mat,
    warped16: Mat,
    out: Mat,
    out_mask: Mat,
}

impl OpencvStitching {
    fn new(rig: &Rig) -> Self {
        use opencv::stitching::{Detail_CylindricalWarper, Detail_CylindricalWarperTrait};
        let cam = &rig.cameras[0].intrinsics;
        let k_fish = Mat::from_slice_2d(&[
            [cam.fx, 0.0, cam.cx],
            [0.0, cam.fy, cam.cy],
            [0.0, 0.0, 1.0],
        ])
        .unwrap();
        let d = Mat::from_slice(&[0.0f64; 4]).unwrap();
        // A level pinhole of 120° across and ±30° up and down, turned to
        // each camera's heading (the rectification undoes its tilt): about
        // the panorama's band.
        let f = (W as f64 / 2.0) / 60f64.to_radians().tan();
        let hp = (2.0 * f * 30f64.to_radians().tan()).round();
        let pinhole = Size::new(W as i32, hp as i32);
        let (cx, cy) = (W as f64 / 2.0 - 0.5, hp / 2.0 - 0.5);
        let k_pin = Mat::from_slice_2d(&[[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]]).unwrap();
        let k = Mat::from_slice_2d(&[
            [f as f32, 0.0, cx as f32],
            [0.0, f as f32, cy as f32],
            [0.0, 0.0, 1.0],
        ])
        .unwrap();
        // The warper's world: x right (−y of the vehicle), y down (−z), z
        // forward (x); its cylinder's axis is its y.
        let w = Matrix3::new(0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0);
        let mat3 = |r: &Matrix3<f64>| {
            let rows: Vec<[f64; 3]> = (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect();
            Mat::from_slice_2d(&rows).unwrap()
        };
        let mut undistort = Vec::new();
        let mut rotations = Vec::new();
        for c in &rig.cameras {
            let pose = c.pose.unwrap();
            let level =
                Pose::from_ypr_deg([pose.ypr_deg()[0], 0.0, 0.0], Vector3::zeros()).unwrap();
            let rect = level.rotation_matrix().transpose() * pose.rotation_matrix();
            let (mut m1, mut m2) = (Mat::default(), Mat::default());
            calib3d::fisheye_init_undistort_rectify_map(
                &k_fish,
                &d,
                &mat3(&rect),
                &k_pin,
                pinhole,
                core::CV_16SC2,
                &mut m1,
                &mut m2,
            )
            .unwrap();
            undistort.push((m1, m2));
            let mut r32 = Mat::default();
            mat3(&(w * level.rotation_matrix()))
                .convert_to(&mut r32, CV_32F, 1.0, 0.0)
                .unwrap();
            rotations.push(r32);
        }
        let mut warper =
            Detail_CylindricalWarper::new((4096.0 / std::f64::consts::TAU) as f32).unwrap();
        let full =
            Mat::new_rows_cols_with_default(H as i32, W as i32, core::CV_8U, Scalar::all(255.0))
                .unwrap();
        let mut masks = Vec::new();
        let mut roi: Option<core::Rect> = None;
        for r in &rotations {
            let mut m = Mat::default();
            let tl = Detail_CylindricalWarperTrait::warp(
                &mut warper,
                &full,
                &k,
                r,
                imgproc::INTER_NEAREST,
                core::BORDER_CONSTANT,
                &mut m,
            )
            .unwrap();
            let rect = core::Rect::new(tl.x, tl.y, m.cols(), m.rows());
            roi = Some(roi.map_or(rect, |a| a | rect));
            masks.push(m);
        }
        Self {
            undistort,
            k,
            rotations,
            masks,
            warper,
            roi: roi.unwrap(),
            undistorted: Mat::default(),
            warped: Mat::default(),
            warped16: Mat::default(),
            out: Mat::default(),
            out_mask: Mat::default(),
        }
    }

    /// Composes RGB `frames`; the blended panorama's size.
    fn compose(&mut self, frames: &[Vec<u8>]) -> (i32, i32) {
        use opencv::stitching::{
            Detail_CylindricalWarperTrait, Detail_FeatherBlender, Detail_FeatherBlenderTrait,
        };
        let mut blender = Detail_FeatherBlender::new(0.02).unwrap();
        Detail_FeatherBlenderTrait::prepare(&mut blender, self.roi).unwrap();
        for (k, f) in frames.iter().enumerate() {
            undistort(f, &self.undistort[k], &mut self.undistorted);
            let tl = Detail_CylindricalWarperTrait::warp(
                &mut self.warper,
                &self.undistorted,
                &self.k,
                &self.rotations[k],
                imgproc::INTER_LINEAR,
                core::BORDER_CONSTANT,
                &mut self.warped,
            )
            .unwrap();
            self.warped
                .convert_to(&mut self.warped16, core::CV_16SC3, 1.0, 0.0)
                .unwrap();
            Detail_FeatherBlenderTrait::feed(&mut blender, &self.warped16, &self.masks[k], tl)
                .unwrap();
        }
        Detail_FeatherBlenderTrait::blend(&mut blender, &mut self.out, &mut self.out_mask).unwrap();
        (self.out.cols(), self.out.rows())
    }
}

/// An RGB fisheye frame remapped through fixed-point maps `(m1, m2)` (the
/// undistortion of both OpenCV pipelines) into `out`.
fn undistort(frame: &[u8], (m1, m2): &(Mat, Mat), out: &mut Mat) {
    let src = Mat::new_rows_cols_with_data(H as i32, (W * 3) as i32, frame).unwrap();
    let src = src.reshape(3, H as i32).unwrap();
    imgproc::remap(
        &src,
        out,
        m1,
        m2,
        imgproc::INTER_LINEAR,
        core::BORDER_CONSTANT,
        Scalar::all(0.0),
    )
    .unwrap();
}

/// A benchmarked composition: its name, frames, canvas channels and gains.
type Composition<'a, 'f> = (&'a str, &'a [FrameView<'f>], usize, Option<&'a [f32]>);

fn compose(c: &mut Criterion) {
    let threads = core::get_num_threads().unwrap();
    core::set_num_threads(1).unwrap();
    let rig = rig();
    let spec = CanvasSpec::default();
    let view = SurroundView::build(&rig, &spec, &SurroundOptions::default()).unwrap();
    let data = frames();
    let views = rgb_views(&data);
    let mut composer = Composer::new();
    let mut canvas = Canvas::new(0, 0, 3);
    let mut reference = Reference::new(&rig, &spec, &view);
    let mut opencv_remap = OpencvRemap::new(&view);
    let mut opencv_canvas = vec![0u8; view.size().0 * view.size().1 * 3];
    composer
        .compose(&view, &views, BlendMode::Linear, &mut canvas)
        .unwrap();
    reference.compose(&data, view.size());
    opencv_remap.compose(&view, &data, &mut opencv_canvas);
    // The peers compose the same view: the OpenCV-remap one within a few
    // levels (it rounds positions to 1/32 px), and the reference at the
    // same place (its own remap chain, so only roughly alike).
    assert_like_opencv_remap(&canvas.data, &opencv_canvas);
    let covered: usize = view
        .layers()
        .iter()
        .map(|l| l.weights[0].iter().filter(|&&w| w > 0).count())
        .sum();
    eprintln!(
        "surround: canvas {:?}, {} camera-pixel contributions ({:.2} per canvas pixel), OpenCV threads 1 (was {threads})",
        view.size(),
        covered,
        covered as f64 / (view.size().0 * view.size().1) as f64
    );

    let gray: Vec<Vec<u8>> = data
        .iter()
        .map(|d| d.chunks_exact(3).map(|p| p[1]).collect())
        .collect();
    let gray_views: Vec<FrameView<'_>> = gray
        .iter()
        .map(|d| FrameView::new(PixelFormat::Mono8, W, H, d).unwrap())
        .collect();
    // BayerRG8 mosaics of the RGB frames.
    let bayer: Vec<Vec<u8>> = data
        .iter()
        .map(|d| {
            d.chunks_exact(3)
                .enumerate()
                .map(|(i, p)| p[[[0, 1], [1, 2]][i / W % 2][i % W % 2]])
                .collect()
        })
        .collect();
    let bayer_views: Vec<FrameView<'_>> = bayer
        .iter()
        .map(|d| FrameView::new(PixelFormat::BayerRg8, W, H, d).unwrap())
        .collect();
    let gains = [1.5f32, 0.75, 2.0, 1.25];
    let mut group = group(c, "surround_4x1288x964_to_1000x1000", 4);
    // Each composition: its frames, the canvas's channels and the gains.
    let compositions: [Composition<'_, '_>; 7] = [
        ("rigview_linear_rgb", &views, 3, None),
        ("rigview_linear_mono_from_rgb", &views, 1, None),
        ("rigview_linear_mono8", &gray_views, 1, None),
        ("rigview_linear_bayer_rg8", &bayer_views, 3, None),
        ("rigview_linear_rgb_gains", &views, 3, Some(&gains)),
        ("rigview_linear_mono8_gains", &gray_views, 1, Some(&gains)),
        (
            "rigview_linear_bayer_rg8_gains",
            &bayer_views,
            3,
            Some(&gains),
        ),
    ];
    for (name, frames, channels, gains) in compositions {
        let mut out = Canvas::new(0, 0, channels);
        group.bench_function(name, |b| {
            b.iter(|| {
                composer
                    .compose_with_gains(
                        &view,
                        black_box(frames),
                        BlendMode::Linear,
                        gains,
                        &mut out,
                    )
                    .unwrap();
            });
        });
    }
    let mut demosaiced: Vec<Mat> = vec![Mat::default(); 4];
    group.bench_function("opencv_demosaic_then_rigview_rgb", |b| {
        b.iter(|| {
            for (f, o) in black_box(&bayer).iter().zip(demosaiced.iter_mut()) {
                let src = Mat::new_rows_cols_with_data(H as i32, W as i32, f).unwrap();
                imgproc::cvt_color(&src, o, imgproc::COLOR_BayerRGGB2RGB, 0).unwrap();
            }
            let frames: Vec<FrameView<'_>> = demosaiced
                .iter()
                .map(|m| FrameView::new(PixelFormat::Rgb8, W, H, m.data_bytes().unwrap()).unwrap())
                .collect();
            composer
                .compose(&view, &frames, BlendMode::Linear, &mut canvas)
                .unwrap();
        });
    });
    group.bench_function("opencv_remap_linear_rgb", |b| {
        b.iter(|| opencv_remap.compose(&view, black_box(&data), &mut opencv_canvas));
    });
    group.bench_function("reference_undistort_warp_float_blend", |b| {
        b.iter(|| reference.compose(black_box(&data), view.size()));
    });
    group.finish();
    core::set_num_threads(threads).unwrap();
}

/// A benchmark group of 20 samples after a 1 s warm-up, over `seconds`.
fn group<'c>(c: &'c mut Criterion, name: &str, seconds: u64) -> BenchmarkGroup<'c, WallTime> {
    let mut group = c.benchmark_group(name);
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(seconds));
    group
}

/// The 8-bit RGB to grey conversion of the four frames, rigview's and
/// OpenCV's.
fn rgb_to_mono(c: &mut Criterion) {
    let threads = core::get_num_threads().unwrap();
    core::set_num_threads(1).unwrap();
    let data = frames();
    let mats: Vec<Mat> = data
        .iter()
        .map(|f| {
            Mat::new_rows_cols_with_data(H as i32, (W * 3) as i32, f)
                .unwrap()
                .reshape(3, H as i32)
                .unwrap()
                .try_clone()
                .unwrap()
        })
        .collect();
    let mut ours = vec![vec![0u8; W * H]; 4];
    let mut theirs = vec![Mat::default(); 4];
    for ((f, o), (m, t)) in data.iter().zip(&mut ours).zip(mats.iter().zip(&mut theirs)) {
        rgb8_to_mono8(f, o).unwrap();
        imgproc::cvt_color(m, t, imgproc::COLOR_RGB2GRAY, 0).unwrap();
        assert_eq!(o.as_slice(), t.data_bytes().unwrap(), "the same bytes");
    }
    let mut group = group(c, "rgb_to_mono_4x1288x964", 2);
    group.bench_function("rigview", |b| {
        b.iter(|| {
            for (f, o) in black_box(&data).iter().zip(&mut ours) {
                rgb8_to_mono8(f, o).unwrap();
            }
        });
    });
    group.bench_function("opencv", |b| {
        b.iter(|| {
            for (m, t) in black_box(&mats).iter().zip(&mut theirs) {
                imgproc::cvt_color(m, t, imgproc::COLOR_RGB2GRAY, 0).unwrap();
            }
        });
    });
    group.finish();
    core::set_num_threads(threads).unwrap();
}

/// The balancing's patch means of the surround view's overlaps: rigview's
/// sweep per camera against the patch-by-patch reading, over eight sets'
/// frames in turn.
fn patch_means(c: &mut Criterion) {
    const SETS: usize = 8;
    let view =
        SurroundView::build(&rig(), &CanvasSpec::default(), &SurroundOptions::default()).unwrap();
    let data = frames();
    // Each set's frames: the base frames with every byte offset by the set.
    let sets = |bytes: &dyn Fn(&[u8]) -> Vec<u8>| -> Vec<Vec<Vec<u8>>> {
        (0..SETS as u8)
            .map(|k| {
                data.iter()
                    .map(|d| bytes(d).iter().map(|&v| v.wrapping_add(k)).collect())
                    .collect()
            })
            .collect()
    };
    let rgb = sets(&|d| d.to_vec());
    let mono = sets(&|d| d.chunks_exact(3).map(|p| p[1]).collect());
    let patches: usize = view.overlaps().iter().map(|o| o.patches.len()).sum();
    eprintln!("patch means: {patches} patches");
    // The reading before: patch by patch, at most 64 samples each.
    let per_patch = |frames: &[FrameView<'_>]| -> Vec<(f32, f32)> {
        let side = |f: &FrameView<'_>, idx: &[u32]| {
            let (mut sum, mut sat, mut n) = (0.0f64, 0usize, 0usize);
            f.for_each_luma(idx.iter().step_by(idx.len().div_ceil(64).max(1)), |v| {
                sum += f64::from(v);
                sat += usize::from(v >= rigview_core::exposure::metering::SATURATED_LEVEL);
                n += 1;
            });
            ((sum / n.max(1) as f64) as f32, sat as f32 / n.max(1) as f32)
        };
        view.overlaps()
            .iter()
            .flat_map(|o| {
                o.patches.iter().flat_map(move |p| {
                    [
                        side(&frames[o.i], &p.pixels_i),
                        side(&frames[o.j], &p.pixels_j),
                    ]
                })
            })
            .collect()
    };
    let mut group = group(c, "patch_means_4x1288x964", 2);
    for (name, format, sets) in [
        ("mono8", PixelFormat::Mono8, &mono),
        ("rgb8", PixelFormat::Rgb8, &rgb),
    ] {
        let views: Vec<Vec<FrameView<'_>>> = sets
            .iter()
            .map(|set| {
                set.iter()
                    .map(|d| FrameView::new(format, W, H, d).unwrap())
                    .collect()
            })
            .collect();
        // The same means both ways.
        let swept: Vec<(f32, f32)> = view
            .pair_observations(&views[0])
            .unwrap()
            .iter()
            .flat_map(|o| {
                o.patches
                    .iter()
                    .flat_map(|p| [(p.mean_i, p.saturated_i), (p.mean_j, p.saturated_j)])
            })
            .collect();
        let read = per_patch(&views[0]);
        assert_eq!(swept, read, "{name}");
        let mut k = 0;
        group.bench_function(format!("rigview_{name}"), |b| {
            b.iter(|| {
                k = (k + 1) % SETS;
                black_box(view.pair_observations(&views[k]).unwrap())
            });
        });
        group.bench_function(format!("per_patch_{name}"), |b| {
            b.iter(|| {
                k = (k + 1) % SETS;
                black_box(per_patch(&views[k]))
            });
        });
    }
    group.finish();
}

/// The distance transform a view build runs per camera, rigview's and
/// OpenCV's.
fn distance_transform(c: &mut Criterion) {
    let threads = core::get_num_threads().unwrap();
    core::set_num_threads(1).unwrap();
    let view =
        SurroundView::build(&rig(), &CanvasSpec::default(), &SurroundOptions::default()).unwrap();
    let (w, h) = view.size();
    // 0 where the front camera alone shows the ground (all its weight).
    let layer = &view.layers()[0];
    let [c0, r0, rw, rh] = layer.roi;
    let mut mask = vec![255u8; w * h];
    for r in 0..rh {
        for col in 0..rw {
            if layer.weights[0][r * rw + col] == 256 {
                mask[(r0 + r) * w + c0 + col] = 0;
            }
        }
    }
    let src = Mat::new_rows_cols_with_data(h as i32, w as i32, &mask)
        .unwrap()
        .try_clone()
        .unwrap();
    let opencv = |precise: bool| {
        let mut dst = Mat::default();
        let size = if precise {
            imgproc::DIST_MASK_PRECISE
        } else {
            imgproc::DIST_MASK_5
        };
        imgproc::distance_transform(&src, &mut dst, imgproc::DIST_L2, size, CV_32F).unwrap();
        dst
    };
    let ours = distance_to_zero(&mask, w, h).unwrap();
    let precise = opencv(true);
    assert_eq!(
        ours.as_slice(),
        precise.data_typed::<f32>().unwrap(),
        "the same distances"
    );
    // How far the chamfer approximation is from the exact distances.
    let chamfer = opencv(false);
    let worst = ours
        .iter()
        .zip(chamfer.data_typed::<f32>().unwrap())
        .filter(|(&d, _)| d >= 1.0)
        .map(|(&d, &a)| ((a - d) / d).abs())
        .fold(0.0f32, f32::max);
    eprintln!(
        "distance_transform_1000x1000: largest distance {:.1} px, DIST_MASK_5 off by up to {:.2} %",
        ours.iter().copied().fold(0.0f32, f32::max),
        100.0 * worst
    );
    let mut group = group(c, "distance_transform_1000x1000", 2);
    group.bench_function("rigview", |b| {
        b.iter(|| distance_to_zero(black_box(&mask), w, h).unwrap());
    });
    group.bench_function("opencv_precise", |b| b.iter(|| opencv(true)));
    group.bench_function("opencv_mask5", |b| b.iter(|| opencv(false)));
    group.finish();
    core::set_num_threads(threads).unwrap();
}

/// The panorama of the same rig and frames on a 4096×1024 cylinder
/// (radius 10 m, 25° below to 35° above the horizon) with linear blending:
/// `Composer::compose` against the OpenCV-remap composition of the same
/// mosaic and against OpenCV's stitching route ([`OpencvStitching`]), one
/// core each. Then the feature matching of its four overlaps
/// on a noise-free frame set of the simulated rig (Harris corners through
/// OpenCV, BRIEF, gated mutual matching, RANSAC, patches), whose split is
/// printed.
fn panorama(c: &mut Criterion) {
    let threads = core::get_num_threads().unwrap();
    core::set_num_threads(1).unwrap();
    let rig = rig();
    let spec = CylinderSpec {
        width: 4096,
        height: 1024,
        ..CylinderSpec::default()
    };
    let pano = Panorama::build(&rig, &spec, &PanoramaOptions::default()).unwrap();
    let data = frames();
    let views = rgb_views(&data);
    let mut composer = Composer::new();
    let mut canvas = Canvas::new(0, 0, 3);
    composer
        .compose(&pano, &views, BlendMode::Linear, &mut canvas)
        .unwrap();
    let mut opencv_remap = OpencvRemap::new(&pano);
    let mut opencv_canvas = vec![0u8; canvas.data.len()];
    opencv_remap.compose(&pano, &data, &mut opencv_canvas);
    assert_like_opencv_remap(&canvas.data, &opencv_canvas);
    let contributions: usize = pano
        .mosaic()
        .layers()
        .iter()
        .map(|l| l.weights[0].iter().filter(|&&w| w > 0).count())
        .sum();
    eprintln!(
        "panorama: {} camera-pixel contributions ({:.2} per canvas pixel)",
        contributions,
        contributions as f64 / (4096.0 * 1024.0)
    );
    let mut compose_group = group(c, "panorama_4x1288x964_to_4096x1024", 6);
    compose_group.bench_function("rigview_linear_rgb", |b| {
        b.iter(|| {
            composer
                .compose(&pano, black_box(&views), BlendMode::Linear, &mut canvas)
                .unwrap();
        });
    });
    compose_group.bench_function("opencv_remap_linear_rgb", |b| {
        b.iter(|| opencv_remap.compose(&pano, black_box(&data), &mut opencv_canvas));
    });
    let mut stitching = OpencvStitching::new(&rig);
    eprintln!(
        "OpenCV stitching route: panorama {:?} px",
        stitching.compose(&data)
    );
    compose_group.bench_function("opencv_undistort_cylindrical_warper_feather", |b| {
        b.iter(|| stitching.compose(black_box(&data)));
    });
    compose_group.finish();

    let render = SimRender::new(&SimConfig::preset("overcast").unwrap()).unwrap();
    let sim = Panorama::build(render.rig(), &spec, &PanoramaOptions::default()).unwrap();
    let stills: Vec<Vec<u8>> = (0..4)
        .map(|k| {
            let setting = rigview_core::exposure::ExposureSetting {
                shutter_us: 4000.0,
                gain_db: 0.0,
            };
            let frame = render.render(k, 0, setting, false).unwrap();
            frame.view().unwrap().packed().unwrap().to_vec()
        })
        .collect();
    let sim_views: Vec<FrameView<'_>> = stills
        .iter()
        .zip(render.cameras())
        .map(|(d, c)| FrameView::new(c.format, c.width, c.height, d).unwrap())
        .collect();
    // The app's detector: corners refined to a fraction of a pixel.
    let detect = |gray: &[u8], w: usize, h: usize, mask: &[u8]| {
        use rigview_calib::tools::corners::{harris_corners, HarrisParams};
        let params = HarrisParams {
            subpixel: true,
            ..HarrisParams::default()
        };
        harris_corners(gray, w, h, Some(mask), &params)
            .map_err(|e| rigview_core::Error::calibration("Harris corners", e))
    };
    let options = MatchOptions::default();
    let refine_options = RefineOptions::default();
    // The first call builds the bands' plans; the next ten give the split
    // (mean per call, one core).
    sim.match_pairs(&sim_views, &detect, &options).unwrap();
    let calls = 10u32;
    let mut sum = MatchTimes::default();
    let mut refine_time = Duration::ZERO;
    let mut inliers = Vec::new();
    for _ in 0..calls {
        let (pairs, times) = sim.match_pairs(&sim_views, &detect, &options).unwrap();
        let t = std::time::Instant::now();
        black_box(sim.refine(&pairs, &refine_options).unwrap());
        refine_time += t.elapsed();
        sum.warp += times.warp;
        sum.detect += times.detect;
        sum.describe += times.describe;
        sum.matching += times.matching;
        sum.align += times.align;
        sum.ransac += times.ransac;
        inliers = pairs.iter().map(|p| p.inliers).collect();
    }
    eprintln!(
        "matching and refinement, simulated rig at 4096x1024, mean of {calls} calls on one core: warp {:?}, detect {:?}, describe {:?}, match {:?}, align {:?}, RANSAC and patches {:?}, refine {:?}; inliers per pair {inliers:?}",
        sum.warp / calls,
        sum.detect / calls,
        sum.describe / calls,
        sum.matching / calls,
        sum.align / calls,
        sum.ransac / calls,
        refine_time / calls,
    );
    // The detector alone on the first band's first camera, against OpenCV's
    // `goodFeaturesToTrack` with the same parameters (the corners the
    // spread and the refinement start from).
    let band = &sim.bands()[0];
    let [_, _, bw, bh] = band.rect;
    let warp = sim
        .warp_band(&mut Composer::new(), 0, band.i, &sim_views[band.i])
        .unwrap();
    let params = rigview_calib::tools::corners::HarrisParams::default();
    let opencv_corners = || {
        rigview_calib::tools::corners::opencv_good_features(
            &warp.data,
            (bw, bh),
            Some(&band.search),
            &params,
        )
        .unwrap()
    };
    let mut detect_group = group(c, &format!("harris_corners_{bw}x{bh}"), 10);
    detect_group.bench_function("rigview", |b| {
        b.iter(|| detect(black_box(&warp.data), bw, bh, &band.search).unwrap());
    });
    detect_group.bench_function("opencv_good_features_to_track", |b| {
        b.iter(|| black_box(opencv_corners()));
    });
    detect_group.finish();

    let (pairs, _) = sim.match_pairs(&sim_views, &detect, &options).unwrap();
    let mut group = group(c, "panorama_matching_sim_4096x1024", 10);
    group.bench_function("four_pairs", |b| {
        b.iter(|| {
            sim.match_pairs(black_box(&sim_views), &detect, &options)
                .unwrap()
        });
    });
    group.bench_function("refine", |b| {
        b.iter(|| sim.refine(black_box(&pairs), &refine_options).unwrap());
    });
    group.bench_function("four_pairs_and_refine", |b| {
        b.iter(|| {
            let (pairs, _) = sim
                .match_pairs(black_box(&sim_views), &detect, &options)
                .unwrap();
            sim.refine(&pairs, &refine_options).unwrap()
        });
    });
    group.finish();
    core::set_num_threads(threads).unwrap();
}

criterion_group!(
    benches,
    compose,
    rgb_to_mono,
    patch_means,
    distance_transform,
    panorama
);
criterion_main!(benches);
