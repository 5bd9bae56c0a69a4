//! The bird's-eye surround view: the ground around the vehicle, composed from
//! every camera of a calibrated rig, with ground-only metering masks and the
//! overlap patches the exposure balancing measures.
//!
//! # The canvas
//!
//! A [`CanvasSpec`] is a rectangle of the ground plane (z = 0) in the vehicle
//! frame (x forward, y left, metres) at a resolution in pixels per metre. The
//! canvas shows it with the vehicle's front up and its left side on the left:
//! column `c` and row `r` see the ground point at the pixel's centre,
//!
//! ```text
//! x = x_max − (r + ½)/ppm,   y = y_max − (c + ½)/ppm.
//! ```
//!
//! # Who shows what
//!
//! Each camera looks past one side of the vehicle's rectangle: the side its
//! optical axis points to most (by yaw: front, left, back or right). Its
//! *region* is the ground beyond that side, where it actually sees (the
//! ground point projects into its image). Where two regions meet (the corners
//! of a four-camera rig) both cameras see the ground: that is an overlap.
//! A camera's *exclusive* region is where it is the only one.
//!
//! In an overlap, camera `c`'s blend weight falls off with the distance `d_c`
//! (canvas pixels, exact Euclidean: [`crate::image::distance_to_zero`]) from
//! its exclusive region: `w_c ∝ 1/d_c²`, so for two cameras
//! `w_A = d_B² / (d_A² + d_B²)`. [`BlendMode::Alpha`] weighs both halves
//! alike and [`BlendMode::Seams`] gives each overlap pixel to the camera with
//! the larger linear weight, so that a bad calibration shows as a break in
//! the mat's lines.
//!
//! # Built once, used every frame
//!
//! [`SurroundView::build`] maps every canvas pixel directly to sub-pixel
//! positions in the fisheye images (no intermediate undistorted image). On
//! first use of a blend mode it turns the maps and weights into a plan of
//! fixed-point bilinear taps with the blend weights folded in (`remap/`):
//! per frame, [`Composer::compose`] then writes each canvas pixel once,
//! from one gathered bilinear sample where one camera shows it and from the
//! sum of the cameras' samples in the overlaps. Bayer frames are
//! demosaiced inside that pass (bilinearly, at each sample), and
//! [`Composer::compose_with_gains`] scales each camera's samples by a
//! display gain before they are summed.
//!
//! It also derives the **ground masks** (the source pixels that reach the
//! canvas: only these are metered) and the **overlap patches** (a grid of
//! small ground squares in each overlap, each with its source pixels in both
//! cameras), from which [`Mosaic::pair_observations`] gives the
//! balancing its patch means.

mod compose;
pub(crate) mod grid;
pub(crate) mod mosaic;
mod remap;
mod seams;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use rigview_calib::rig::Rig;

pub use compose::{Canvas, Composer};
pub use mosaic::{CameraLayer, Mosaic};
pub(crate) use remap::Plan;
pub use seams::{SeamBands, SeamStep};

use crate::error::{Error, Result};
use crate::image::RoiMask;

/// The ground rectangle a canvas shows, and at what resolution.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CanvasSpec {
    /// Rearmost ground x shown, metres (vehicle frame).
    pub x_min_m: f64,
    /// Foremost ground x shown, metres.
    pub x_max_m: f64,
    /// Rightmost ground y shown, metres (y points left).
    pub y_min_m: f64,
    /// Leftmost ground y shown, metres.
    pub y_max_m: f64,
    /// Canvas pixels per metre of ground.
    pub px_per_m: f64,
    /// The vehicle's rectangle on the ground: `[x_min, x_max, y_min, y_max]`,
    /// metres. Nothing is composed inside it.
    pub vehicle_m: [f64; 4],
}

impl Default for CanvasSpec {
    /// 10 m × 10 m around a 4.6 m × 1.9 m car, at 100 px/m (1000 × 1000 px).
    fn default() -> Self {
        Self {
            x_min_m: -5.0,
            x_max_m: 5.0,
            y_min_m: -5.0,
            y_max_m: 5.0,
            px_per_m: 100.0,
            vehicle_m: [-2.3, 2.3, -0.95, 0.95],
        }
    }
}

impl CanvasSpec {
    /// 16 m × 12 m around a 5 m × 2 m car (the canvas of the real
    /// surround-nz rig's source project) at `px_per_m`.
    pub fn around_car_16x12(px_per_m: f64) -> Self {
        Self {
            x_min_m: -8.0,
            x_max_m: 8.0,
            y_min_m: -6.0,
            y_max_m: 6.0,
            px_per_m,
            vehicle_m: [-2.5, 2.5, -1.0, 1.0],
        }
    }
}

/// The largest canvas side, pixels.
const MAX_CANVAS_SIDE: f64 = 8192.0;

impl CanvasSpec {
    /// Checks the spec: finite numbers, a non-empty extent, a resolution
    /// giving at most 8192 pixels a side, a vehicle rectangle with min < max.
    pub fn validate(&self) -> Result<()> {
        let fields = [
            ("canvas.x_min_m", self.x_min_m),
            ("canvas.x_max_m", self.x_max_m),
            ("canvas.y_min_m", self.y_min_m),
            ("canvas.y_max_m", self.y_max_m),
            ("canvas.px_per_m", self.px_per_m),
            ("canvas.vehicle_m", self.vehicle_m.iter().sum::<f64>()),
        ];
        for (name, v) in fields {
            if !v.is_finite() {
                return Err(Error::InvalidParameter {
                    name,
                    value: v,
                    expected: "a finite number",
                });
            }
        }
        if self.x_max_m <= self.x_min_m || self.y_max_m <= self.y_min_m {
            return Err(Error::invalid(
                "canvas",
                "ground extent",
                "min < max",
                format_args!(
                    "x ∈ [{}, {}], y ∈ [{}, {}] m",
                    self.x_min_m, self.x_max_m, self.y_min_m, self.y_max_m
                ),
            ));
        }
        let [vx0, vx1, vy0, vy1] = self.vehicle_m;
        if vx1 < vx0 || vy1 < vy0 {
            return Err(Error::invalid(
                "canvas",
                "vehicle_m",
                "[x_min, x_max, y_min, y_max] with min ≤ max",
                format_args!("[{vx0}, {vx1}, {vy0}, {vy1}]"),
            ));
        }
        let (w, h) = self.size_f64();
        if self.px_per_m <= 0.0 || w < 1.0 || h < 1.0 || w > MAX_CANVAS_SIDE || h > MAX_CANVAS_SIDE
        {
            return Err(Error::InvalidParameter {
                name: "canvas.px_per_m",
                value: self.px_per_m,
                expected: "a resolution that gives a canvas of 1 to 8192 pixels a side",
            });
        }
        Ok(())
    }

    fn size_f64(&self) -> (f64, f64) {
        (
            ((self.y_max_m - self.y_min_m) * self.px_per_m).round(),
            ((self.x_max_m - self.x_min_m) * self.px_per_m).round(),
        )
    }

    /// Canvas width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        let (w, h) = self.size_f64();
        (w.max(0.0) as usize, h.max(0.0) as usize)
    }

    /// The ground point (x, y) a canvas position (column, row; pixel centres
    /// at +½) shows.
    pub fn ground(&self, col: f64, row: f64) -> (f64, f64) {
        (
            self.x_max_m - row / self.px_per_m,
            self.y_max_m - col / self.px_per_m,
        )
    }

    /// The canvas position (column, row) of a ground point.
    pub fn canvas(&self, x: f64, y: f64) -> (f64, f64) {
        (
            (self.y_max_m - y) * self.px_per_m,
            (self.x_max_m - x) * self.px_per_m,
        )
    }

    /// Whether a ground point lies on the vehicle.
    pub fn on_vehicle(&self, x: f64, y: f64) -> bool {
        let [x0, x1, y0, y1] = self.vehicle_m;
        x >= x0 && x <= x1 && y >= y0 && y <= y1
    }

    /// The vehicle's rectangle on the canvas: column, row, width, height.
    pub fn vehicle_rect_px(&self) -> [usize; 4] {
        let [x0, x1, y0, y1] = self.vehicle_m;
        let (c0, r0) = self.canvas(x1, y1);
        let (c1, r1) = self.canvas(x0, y0);
        let (w, h) = self.size();
        let clamp = |v: f64, hi: usize| (v.round().max(0.0) as usize).min(hi);
        let (c0, c1) = (clamp(c0, w), clamp(c1, w));
        let (r0, r1) = (clamp(r0, h), clamp(r1, h));
        [c0, r0, c1 - c0, r1 - r0]
    }
}

/// How overlapping cameras are mixed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum BlendMode {
    /// Weights falling off with the distance from each camera's exclusive
    /// region (the default).
    #[default]
    Linear,
    /// Half and half.
    Alpha,
    /// Each overlap pixel from one camera: a hard seam, for checking the
    /// calibration.
    Seams,
}

impl BlendMode {
    /// Every mode, in the order of [`CameraLayer`]'s weight tables.
    pub const ALL: [BlendMode; 3] = [BlendMode::Linear, BlendMode::Alpha, BlendMode::Seams];

    /// The name used in settings and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Linear => "linear",
            Self::Alpha => "alpha",
            Self::Seams => "seams",
        }
    }

    fn index(self) -> usize {
        match self {
            Self::Linear => 0,
            Self::Alpha => 1,
            Self::Seams => 2,
        }
    }
}

/// Options of [`SurroundView::build`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurroundOptions {
    /// Side of an overlap patch on the ground, metres.
    pub patch_m: f64,
    /// The fraction of a patch's canvas pixels that both cameras must show.
    pub patch_coverage: f64,
    /// The ground masks are computed on every `mask_step`-th source pixel
    /// (each result covers a `mask_step × mask_step` block).
    pub mask_step: usize,
}

impl Default for SurroundOptions {
    fn default() -> Self {
        Self {
            patch_m: 0.25,
            patch_coverage: 0.9,
            mask_step: 2,
        }
    }
}

/// One overlap patch: the source pixels (row-major indices) of one small
/// square of ground in both cameras.
#[derive(Clone, Debug, PartialEq)]
pub struct OverlapPatch {
    /// The patch's centre on the ground (x, y), metres.
    pub centre_m: (f64, f64),
    /// Source pixel indices in camera `i`.
    pub pixels_i: Vec<u32>,
    /// Source pixel indices in camera `j`.
    pub pixels_j: Vec<u32>,
}

/// The overlap of two neighbouring cameras.
#[derive(Clone, Debug, PartialEq)]
pub struct Overlap {
    /// Camera `i` (the smaller index).
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// Canvas pixels both cameras show.
    pub pixels: usize,
    /// Its patches.
    pub patches: Vec<OverlapPatch>,
}

/// The surround view of one rig and canvas, built once per calibration: a
/// [`Mosaic`] on the ground plane (it derefs to it: sizes, layers, frame
/// checks), the ground masks and the overlap patches.
#[derive(Debug)]
pub struct SurroundView {
    spec: CanvasSpec,
    mosaic: Mosaic,
}

impl std::ops::Deref for SurroundView {
    type Target = Mosaic;

    fn deref(&self) -> &Mosaic {
        &self.mosaic
    }
}

/// Which side of the vehicle a camera looks past.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Side {
    Front,
    Left,
    Back,
    Right,
}

impl Side {
    /// The side each camera looks past, by the yaw of its optical axis.
    pub(crate) fn of_cameras(projectors: &[rigview_calib::rig::CameraProjector]) -> Vec<Self> {
        projectors
            .iter()
            .map(|p| {
                let axis = p.pose().optical_axis();
                Self::of_yaw(axis.y.atan2(axis.x))
            })
            .collect()
    }

    fn of_yaw(yaw: f64) -> Self {
        let d = yaw.to_degrees();
        if d.abs() <= 45.0 {
            Side::Front
        } else if (45.0..=135.0).contains(&d) {
            Side::Left
        } else if (-135.0..=-45.0).contains(&d) {
            Side::Right
        } else {
            Side::Back
        }
    }

    /// Whether a ground point lies beyond this side of the vehicle.
    pub(crate) fn beyond(self, vehicle: &[f64; 4], x: f64, y: f64) -> bool {
        self.margin(vehicle, x, y) > 0.0
    }

    /// How far a ground point lies beyond this side of the vehicle
    /// (metres; negative short of it): linear in the point.
    pub(crate) fn margin(self, vehicle: &[f64; 4], x: f64, y: f64) -> f64 {
        let [x0, x1, y0, y1] = *vehicle;
        match self {
            Side::Front => x - x1,
            Side::Back => x0 - x,
            Side::Left => y - y1,
            Side::Right => y0 - y,
        }
    }
}

impl SurroundView {
    /// Builds the view of `rig` on `spec`. The rig's cameras need poses in
    /// the vehicle frame.
    pub fn build(rig: &Rig, spec: &CanvasSpec, options: &SurroundOptions) -> Result<Self> {
        Self::build_on_grid(rig, spec, options, grid::MAP_GRID)
    }

    /// [`SurroundView::build`] with the maps interpolated on a grid of
    /// `grid` pixels (1: every pixel projected exactly).
    pub(crate) fn build_on_grid(
        rig: &Rig,
        spec: &CanvasSpec,
        options: &SurroundOptions,
        grid: usize,
    ) -> Result<Self> {
        spec.validate()?;
        validate_options(options)?;
        let what = "surround view";
        let cameras = mosaic::vehicle_cameras(rig, what)?;
        let (w, h) = spec.size();
        // Where each camera sees: within its side.
        let sides = Side::of_cameras(&cameras.projectors);
        let projectors = &cameras.projectors;
        let (mut mosaic, maps) = Mosaic::build(
            what,
            (w, h),
            &cameras.sources,
            (grid, grid::MAP_TOLERANCE_PX),
            |c, r, found| {
                let (x, y) = spec.ground(c as f64 + 0.5, r as f64 + 0.5);
                if spec.on_vehicle(x, y) {
                    return;
                }
                let p = Vector3::new(x, y, 0.0);
                for (k, projector) in projectors.iter().enumerate() {
                    if !sides[k].beyond(&spec.vehicle_m, x, y) {
                        continue;
                    }
                    if let Some(px) = projector.project_rig(&p) {
                        found.push((k, px));
                    }
                }
            },
            |k| {
                Some(Error::invalid(
                    "surround view",
                    format!("camera `{}`'s view of the canvas", cameras.sources[k].0),
                    "a pose looking at the ground",
                    format_args!(
                        "none of x ∈ [{}, {}], y ∈ [{}, {}] m beyond the vehicle's {:?} side",
                        spec.x_min_m, spec.x_max_m, spec.y_min_m, spec.y_max_m, sides[k]
                    ),
                ))
            },
        )?;
        let masks =
            mosaic::source_masks(&mosaic, projectors, (options.mask_step, grid), |p, px| {
                let g = p.ground_point(px)?;
                Some(spec.canvas(g.x, g.y))
            })?;
        let cell = (options.patch_m * spec.px_per_m).round().max(2.0) as usize;
        let overlaps = mosaic::overlaps(
            &maps,
            mosaic.layers(),
            (w, h),
            &rig.neighbours,
            cell,
            options.patch_coverage,
            |c, r| spec.ground(c, r),
        );
        mosaic.set_regions(masks, overlaps);
        Ok(Self {
            spec: spec.clone(),
            mosaic,
        })
    }

    /// The canvas spec.
    pub fn spec(&self) -> &CanvasSpec {
        &self.spec
    }

    /// The mosaic: the cameras' maps, weights and plans on the canvas.
    pub fn mosaic(&self) -> &Mosaic {
        &self.mosaic
    }

    /// Each camera's ground mask (source pixels that reach the canvas), in
    /// rig order: meter only these.
    pub fn ground_masks(&self) -> &[RoiMask] {
        self.mosaic.masks()
    }
}

fn validate_options(o: &SurroundOptions) -> Result<()> {
    crate::error::check_range(
        "surround.patch_m",
        o.patch_m,
        0.01,
        10.0,
        "a patch side of 0.01 to 10 m",
    )?;
    mosaic::check_sampling(
        ("surround.patch_coverage", o.patch_coverage),
        ("surround.mask_step", o.mask_step),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::mosaic::mode_weights;
    use super::*;
    use crate::image::FrameView;

    #[test]
    fn bad_canvas_specs_are_refused_with_the_field() {
        let ok = CanvasSpec::default();
        assert!(ok.validate().is_ok());
        assert_eq!(ok.size(), (1000, 1000));
        let cases = [
            (
                CanvasSpec {
                    px_per_m: f64::NAN,
                    ..ok.clone()
                },
                "canvas.px_per_m",
            ),
            (
                CanvasSpec {
                    px_per_m: 1e6,
                    ..ok.clone()
                },
                "canvas.px_per_m",
            ),
            (
                CanvasSpec {
                    x_max_m: -6.0,
                    ..ok.clone()
                },
                "ground extent",
            ),
            (
                CanvasSpec {
                    vehicle_m: [2.0, -2.0, -1.0, 1.0],
                    ..ok.clone()
                },
                "canvas: vehicle_m",
            ),
        ];
        for (spec, field) in cases {
            let e = spec.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e} should name {field}");
        }
    }

    #[test]
    fn canvas_and_ground_coordinates_are_inverse() {
        let s = CanvasSpec::default();
        let (x, y) = s.ground(123.5, 456.5);
        let (c, r) = s.canvas(x, y);
        assert!((c - 123.5).abs() < 1e-9 && (r - 456.5).abs() < 1e-9);
        // Front is up, left is left.
        assert!(s.ground(500.0, 0.0).0 > 4.9);
        assert!(s.ground(0.0, 500.0).1 > 4.9);
        let [c0, r0, w, h] = s.vehicle_rect_px();
        assert_eq!((w, h), (190, 460));
        assert_eq!((c0, r0), (405, 270));
    }

    #[test]
    fn linear_weights_sum_to_256_on_an_exact_tie() {
        // 1/d² of 257 and 255: shares of exactly 128.5 and 127.5 of 256,
        // which rounded one by one make 257.
        let inv = [257.0, 255.0];
        let total: f64 = inv.iter().sum();
        let each: u32 = inv.iter().map(|v| (256.0 * v / total).round() as u32).sum();
        assert_eq!(each, 257);
        let (mut exact, mut rounded) = (Vec::new(), Vec::new());
        let w: Vec<[u16; 2]> = (0..2)
            .map(|me| mode_weights(&inv, me, &mut exact, &mut rounded))
            .collect();
        assert_eq!(w[0][0] + w[1][0], 256, "linear {w:?}");
        assert_eq!(w[0][1] + w[1][1], 256, "alpha {w:?}");
        assert_eq!((w[0][0], w[1][0]), (129, 127));
        // Three cameras alike: thirds, which rounded one by one make 255.
        let w: Vec<[u16; 2]> = (0..3)
            .map(|me| mode_weights(&[1.0; 3], me, &mut exact, &mut rounded))
            .collect();
        assert_eq!(w.iter().map(|w| w[0]).sum::<u16>(), 256);
        assert_eq!(w.iter().map(|w| w[1]).sum::<u16>(), 256);
    }

    /// A 185° equidistant fisheye filling the width of a `w×h` image.
    pub(crate) fn fisheye_185(w: u32, h: u32) -> rigview_calib::model::Intrinsics {
        let f = (f64::from(w) / 2.0) / 92.5f64.to_radians();
        rigview_calib::model::Intrinsics {
            width: w,
            height: h,
            fx: f,
            fy: f,
            cx: f64::from(w) / 2.0 - 0.5,
            cy: f64::from(h) / 2.0 - 0.5,
            distortion: rigview_calib::model::Distortion::Fisheye([0.0; 4]),
        }
    }

    /// A small four-fisheye rig like the benchmark's (185° equidistant
    /// lenses, 1 m high, past the four sides of a 4.6 m × 1.9 m car), with
    /// `w×h` images, and a 10 m × 10 m canvas at 10 px/m.
    pub(crate) fn small_view(w: u32, h: u32) -> SurroundView {
        use rigview_calib::pose::Pose;
        use rigview_calib::rig::{Camera, Frame};
        let intrinsics = fisheye_185(w, h);
        let cameras = [
            ("front", [0.0, 30.0, 0.0], [2.3, 0.0, 1.0]),
            ("left", [90.0, 45.0, 0.0], [0.0, 0.95, 1.0]),
            ("back", [180.0, 30.0, 0.0], [-2.3, 0.0, 1.0]),
            ("right", [-90.0, 45.0, 0.0], [0.0, -0.95, 1.0]),
        ]
        .iter()
        .map(|(name, ypr, t)| {
            let mut c = Camera::new(*name, intrinsics);
            c.pose = Some(Pose::from_ypr_deg(*ypr, Vector3::from(*t)).unwrap());
            c
        })
        .collect();
        let rig = Rig::new(
            Frame::Vehicle,
            cameras,
            vec![(0, 1), (1, 2), (2, 3), (0, 3)],
        )
        .unwrap();
        let spec = CanvasSpec {
            px_per_m: 10.0,
            ..CanvasSpec::default()
        };
        SurroundView::build(&rig, &spec, &SurroundOptions::default()).unwrap()
    }

    #[test]
    fn every_covered_pixel_has_weights_summing_to_256_in_every_mode() {
        let view = small_view(160, 120);
        let (w, h) = view.size();
        for m in 0..3 {
            let mut sum = vec![0u32; w * h];
            for layer in view.layers() {
                let [c0, r0, rw, rh] = layer.roi;
                for r in 0..rh {
                    for c in 0..rw {
                        sum[(r0 + r) * w + c0 + c] += u32::from(layer.weights[m][r * rw + c]);
                    }
                }
            }
            let covered = sum.iter().filter(|&&s| s > 0).count();
            assert!(covered > w * h / 2, "{covered}");
            assert!(
                sum.iter().all(|&s| s == 0 || s == 256),
                "mode {}: sums {:?}",
                BlendMode::ALL[m].name(),
                sum.iter()
                    .filter(|&&s| s != 0 && s != 256)
                    .collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn patch_means_swept_camera_by_camera_are_the_patch_by_patch_ones() {
        use super::mosaic::patch_stats;
        use crate::image::PixelFormat;
        use rand::{Rng, SeedableRng};
        let (sw, sh) = (160usize, 120usize);
        let view = small_view(sw as u32, sh as u32);
        let patches: usize = view.overlaps().iter().map(|o| o.patches.len()).sum();
        assert!(patches > 10, "{patches} patches");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for format in [
            PixelFormat::Mono8,
            PixelFormat::Rgb8,
            PixelFormat::BayerGb8,
            PixelFormat::Mono16,
            PixelFormat::BayerRg12,
        ] {
            // Samples a pixel (three for RGB), of one or two bytes.
            let (samples, top): (usize, u32) = match format {
                PixelFormat::Rgb8 => (3 * sw * sh, 255),
                PixelFormat::Mono16 => (sw * sh, 65535),
                PixelFormat::BayerRg12 => (sw * sh, 4095),
                _ => (sw * sh, 255),
            };
            // Per camera, another light: black with its smallest levels
            // (the smallest lumas), noise over the whole range, bright,
            // and saturated.
            let data: Vec<Vec<u8>> = (0..4u8)
                .map(|k| {
                    let level = |rng: &mut rand_chacha::ChaCha8Rng| match k {
                        0 => rng.gen_range(0..=1),
                        1 => rng.gen_range(0..=top),
                        2 => rng.gen_range(top * 4 / 5..=top),
                        _ => top,
                    };
                    (0..samples)
                        .flat_map(|_| {
                            let v = level(&mut rng);
                            if top > 255 {
                                (v as u16).to_le_bytes().to_vec()
                            } else {
                                vec![v as u8]
                            }
                        })
                        .collect()
                })
                .collect();
            let frames: Vec<_> = data
                .iter()
                .map(|d| FrameView::new(format, sw, sh, d).unwrap())
                .collect();
            let got = view.pair_observations(&frames).unwrap();
            assert_eq!(got.len(), view.overlaps().len());
            for (obs, o) in got.iter().zip(view.overlaps()) {
                assert_eq!((obs.i, obs.j), (o.i, o.j));
                assert_eq!(obs.patches.len(), o.patches.len());
                for (pair, patch) in obs.patches.iter().zip(&o.patches) {
                    let want_i = patch_stats(&frames[o.i], &patch.pixels_i);
                    let want_j = patch_stats(&frames[o.j], &patch.pixels_j);
                    let bits = |(m, s): (f32, f32)| (m.to_bits(), s.to_bits());
                    assert_eq!(
                        (
                            bits((pair.mean_i, pair.saturated_i)),
                            bits((pair.mean_j, pair.saturated_j))
                        ),
                        (bits(want_i), bits(want_j)),
                        "{format:?}, cameras {} and {}",
                        o.i,
                        o.j
                    );
                }
            }
            // The frames' light shows: the saturated camera's side is
            // saturated, the black one's dark.
            let side = |k: usize| {
                got.iter()
                    .flat_map(|obs| {
                        obs.patches.iter().filter_map(move |p| {
                            (obs.i == k)
                                .then_some((p.mean_i, p.saturated_i))
                                .or((obs.j == k).then_some((p.mean_j, p.saturated_j)))
                        })
                    })
                    .collect::<Vec<_>>()
            };
            assert!(
                side(3).iter().all(|&(m, s)| m >= 0.99 && s >= 1.0),
                "{format:?}"
            );
            assert!(
                side(0).iter().all(|&(m, s)| m < 0.01 && s <= 0.0),
                "{format:?}"
            );
        }
    }

    #[test]
    fn compositions_are_within_a_level_of_the_exact_blend_in_every_mode() {
        use crate::image::PixelFormat;
        use rand::{Rng, SeedableRng};
        let (sw, sh) = (160usize, 120usize);
        let view = small_view(sw as u32, sh as u32);
        let (w, h) = view.size();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let rgb: Vec<Vec<u8>> = (0..4)
            .map(|_| (0..sw * sh * 3).map(|_| rng.gen::<u8>()).collect())
            .collect();
        let gray: Vec<Vec<u8>> = (0..4)
            .map(|_| (0..sw * sh).map(|_| rng.gen::<u8>()).collect())
            .collect();
        fn frames(data: &[Vec<u8>], f: PixelFormat, (w, h): (usize, usize)) -> Vec<FrameView<'_>> {
            data.iter()
                .map(|d| FrameView::new(f, w, h, d).unwrap())
                .collect()
        }
        // The exact blend of channel `c` of canvas pixel (`col`, `row`).
        let exact = |data: &[Vec<u8>], ch: usize, m: usize, col: usize, row: usize, c: usize| {
            let mut v = 0.0;
            for (k, layer) in view.layers().iter().enumerate() {
                let [c0, r0, rw, rh] = layer.roi;
                if col < c0 || row < r0 || col >= c0 + rw || row >= r0 + rh {
                    continue;
                }
                let j = (row - r0) * rw + col - c0;
                let wt = f64::from(layer.weights[m][j]) / 256.0;
                if wt == 0.0 {
                    continue;
                }
                let [x, y] = layer.map[j].map(f64::from);
                let (x0, y0) = (x.floor() as usize, y.floor() as usize);
                let (fx, fy) = (x - x0 as f64, y - y0 as f64);
                let px = |xx: usize, yy: usize| {
                    f64::from(data[k][(yy.min(sh - 1) * sw + xx.min(sw - 1)) * ch + c])
                };
                v += wt
                    * ((1.0 - fy) * ((1.0 - fx) * px(x0, y0) + fx * px(x0 + 1, y0))
                        + fy * ((1.0 - fx) * px(x0, y0 + 1) + fx * px(x0 + 1, y0 + 1)));
            }
            v
        };
        let mut composer = Composer::new();
        for mode in BlendMode::ALL {
            for (data, format, ch) in [(&rgb, PixelFormat::Rgb8, 3), (&gray, PixelFormat::Mono8, 1)]
            {
                // A canvas of another size and full of garbage: resized,
                // and every pixel written.
                let mut canvas = Canvas {
                    width: 3,
                    height: 3,
                    channels: ch,
                    data: vec![0x5a; 7 * w * h * ch],
                };
                composer
                    .compose(&view, &frames(data, format, (sw, sh)), mode, &mut canvas)
                    .unwrap();
                assert_eq!(
                    (canvas.width, canvas.height, canvas.data.len()),
                    (w, h, w * h * ch)
                );
                let mut worst = 0.0f64;
                for row in 0..h {
                    for col in 0..w {
                        for c in 0..ch {
                            let got = f64::from(canvas.data[(row * w + col) * ch + c]);
                            let err = (got - exact(data, ch, mode.index(), col, row, c)).abs();
                            worst = worst.max(err);
                        }
                    }
                }
                eprintln!("{}, {ch} channels: worst error {worst:.3}", mode.name());
                assert!(worst < 0.75, "{} {ch}: {worst}", mode.name());
            }
            // Mono frames on an RGB canvas: the mono composition in each
            // channel.
            let gray_frames = frames(&gray, PixelFormat::Mono8, (sw, sh));
            let (mut mono, mut colour) = (Canvas::new(0, 0, 1), Canvas::new(0, 0, 3));
            for canvas in [&mut mono, &mut colour] {
                composer.compose(&view, &gray_frames, mode, canvas).unwrap();
            }
            assert!(colour
                .data
                .chunks_exact(3)
                .zip(&mono.data)
                .all(|(p, &v)| p == [v, v, v]));
        }
    }
}
