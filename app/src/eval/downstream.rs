//! What a consumer of the frames gets from where a strategy holds the
//! cameras: features, the currency of visual odometry, SLAM and the
//! panorama's own stitching. Exposure that clips a textured surface or
//! buries it in noise costs features that no later stage gets back, so the
//! bracket-benchmark literature scores auto-exposure by them as well as by
//! a gradient metric.
//!
//! Two measures per set, both with the panorama's detector (Harris corners
//! through OpenCV) and descriptor (BRIEF, mutual matches with a ratio
//! test):
//! - **tracked**: per camera, the corners of its frame matched to those of
//!   its previous frame. The simulated rig stands still, so a true match
//!   stays where it was: candidates are limited to [`MAX_MOTION_PX`]. What
//!   the count loses is what noise and clipping take between two frames.
//! - **across overlaps**: per overlap, the inliers of the panorama's
//!   matching ([`Panorama::match_pairs`]): corners both cameras see well
//!   enough to match each other.
//! - **stereo**: per stereo pair of the rig (two cameras side by side,
//!   [`stereo_pairs`]), the share of the rectified view with a valid
//!   disparity from OpenCV's `StereoSGBM` ([`StereoRectifier`]): what a
//!   depth consumer gets. The reference surround rig has no pair.

use anyhow::{Context, Result};
use rigview_calib::rig::{Frame, Rig};
use rigview_calib::tools::corners::{harris_corners, HarrisParams};
use rigview_calib::tools::stereo::{stereo_pairs, Disparities, StereoRectifier};
use rigview_core::features::{match_mutual_where, Descriptor, Smoothed};
use rigview_core::image::FrameView;
use rigview_core::panorama::{MatchOptions, Panorama, PanoramaOptions};
use rigview_core::pipeline::PanoramaSettings;

use super::strategy::EvalStrategy;
use crate::report::mean;

/// How far (pixels) a corner may move between two frames of the standing
/// rig and still count as tracked: noise moves a Harris maximum by a pixel
/// or so.
pub const MAX_MOTION_PX: f32 = 2.0;

/// Lowe's ratio test of the frame-to-frame matches.
pub const RATIO: f32 = 0.8;

/// One camera's corners and their descriptors.
#[derive(Debug)]
struct Described {
    points: Vec<[f32; 2]>,
    descriptors: Vec<Descriptor>,
}

/// What one set gave.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SetFeatures {
    /// Per camera, corners matched to its previous frame (`None` for the
    /// first set measured).
    pub tracked: Vec<Option<usize>>,
    /// Per overlap (the panorama's bands, in order): cameras `i`, `j` and
    /// RANSAC's inliers.
    pub overlaps: Vec<(usize, usize, usize)>,
    /// Per stereo pair: left and right camera and the share of valid
    /// disparities.
    pub stereo: Vec<(usize, usize, f64)>,
}

/// The sets of `measured`, the first of them set `from` of `trace`, that
/// show the strategy at rest: a set with a probe frame (darker or brighter
/// on purpose; counted as flicker, `super::start`) is left out, and the
/// frames after one are not counted as tracked from it.
pub fn at_rest(
    measured: Vec<SetFeatures>,
    trace: &super::closed_loop::Trace,
    from: usize,
) -> Vec<SetFeatures> {
    measured
        .into_iter()
        .enumerate()
        .filter(|(k, _)| !trace.probe_set(from + k))
        .map(|(k, mut set)| {
            if from + k > 0 && trace.probe_set(from + k - 1) {
                set.tracked.iter_mut().for_each(|t| *t = None);
            }
            set
        })
        .collect()
}

/// Measures [`SetFeatures`] set after set (module documentation).
#[derive(Debug)]
pub struct FeatureMeter {
    panorama: Option<Panorama>,
    params: HarrisParams,
    previous: Vec<Option<Described>>,
    stereo: Vec<StereoRectifier>,
    /// The last set's disparities, per pair.
    last_stereo: Vec<Disparities>,
    /// The disparities of the latest [`RECENT_SETS`] sets measured by
    /// [`Self::from_set`], with their set's index: the report draws the
    /// last at rest.
    recent: std::collections::VecDeque<(usize, Vec<Disparities>)>,
}

/// How many of the latest sets' disparities [`FeatureMeter`] keeps, for
/// the last set at rest (a probe's runs over at most four).
const RECENT_SETS: usize = 8;

impl FeatureMeter {
    /// A meter of the cameras of `rig` (poses in the vehicle frame), whose
    /// overlaps are matched on a panorama of `canvas` (width, height)
    /// pixels, the rest of its settings rigview's defaults.
    pub fn new(rig: &Rig, canvas: (usize, usize)) -> Result<Self> {
        let settings = PanoramaSettings {
            width: canvas.0,
            height: canvas.1,
            ..PanoramaSettings::default()
        };
        // A rig posed relative to one of its cameras has no panorama around
        // the vehicle: its overlaps are not matched.
        let panorama = match rig.frame {
            Frame::Vehicle => Some(
                Panorama::build(rig, &settings.spec(), &PanoramaOptions::default())
                    .context("building the panorama whose overlaps are matched")?,
            ),
            Frame::Camera(_) => None,
        };
        let stereo = stereo_pairs(rig)
            .into_iter()
            .map(|(l, r)| {
                StereoRectifier::new(rig, l, r).with_context(|| {
                    format!(
                        "rectifying the stereo pair {} and {}",
                        rig.cameras[l].name, rig.cameras[r].name
                    )
                })
            })
            .collect::<Result<_>>()?;
        Ok(Self {
            panorama,
            params: HarrisParams::default(),
            previous: Vec::new(),
            stereo,
            last_stereo: Vec::new(),
            recent: Default::default(),
        })
    }

    /// Forgets the previous frames (a new run).
    pub fn reset(&mut self) {
        self.previous.clear();
        self.recent.clear();
    }

    /// An observer for [`super::closed_loop::run_observed`] that measures
    /// every set from index `from` on into `out` (after a
    /// [`Self::reset`]).
    pub fn from_set<'a>(
        &'a mut self,
        from: usize,
        out: &'a mut Vec<SetFeatures>,
    ) -> impl FnMut(usize, &[FrameView<'_>]) -> Result<()> + 'a {
        self.reset();
        move |set, frames| {
            if set >= from {
                out.push(self.observe(frames)?);
                if !self.last_stereo.is_empty() {
                    if self.recent.len() == RECENT_SETS {
                        self.recent.pop_front();
                    }
                    self.recent.push_back((set, self.last_stereo.clone()));
                }
            }
            Ok(())
        }
    }

    /// The rectified views and disparities of each stereo pair (in the
    /// order of `stereo_pairs`) in the last set observed; empty
    /// before the first, or on a rig without a pair.
    pub fn last_stereo(&self) -> &[Disparities] {
        &self.last_stereo
    }

    /// Measures one complete set (one frame per camera, rig order).
    pub fn observe(&mut self, frames: &[FrameView<'_>]) -> Result<SetFeatures> {
        self.previous.resize_with(frames.len(), || None);
        let greys: Vec<Vec<u8>> = frames.iter().map(grey).collect();
        let mut tracked = Vec::with_capacity(frames.len());
        for (k, frame) in frames.iter().enumerate() {
            let now = describe(frame, &greys[k], &self.params)
                .with_context(|| format!("the corners of camera {k}'s frame"))?;
            tracked.push(
                self.previous[k]
                    .as_ref()
                    .map(|before| matched(before, &now).map(|m| m.len()).unwrap_or_default()),
            );
            self.previous[k] = Some(now);
        }
        let pairs = match &self.panorama {
            Some(panorama) => {
                panorama
                    .match_pairs(
                        frames,
                        &crate::session::view::detect,
                        &MatchOptions::default(),
                    )
                    .context("matching the overlaps")?
                    .0
            }
            None => Vec::new(),
        };
        let mut stereo = Vec::with_capacity(self.stereo.len());
        self.last_stereo.clear();
        for s in &self.stereo {
            let (Some(l), Some(r)) = (greys.get(s.left), greys.get(s.right)) else {
                anyhow::bail!(
                    "a set of {} frames for a stereo pair of cameras {} and {}",
                    frames.len(),
                    s.left,
                    s.right
                );
            };
            let d = s.disparities(l, r).with_context(|| {
                format!("the disparities of cameras {} and {}", s.left, s.right)
            })?;
            stereo.push((s.left, s.right, d.density()));
            self.last_stereo.push(d);
        }
        Ok(SetFeatures {
            tracked,
            overlaps: pairs.iter().map(|p| (p.i, p.j, p.inliers)).collect(),
            stereo,
        })
    }
}

/// The corners of `frame` (`gray`, as [`grey`] gives it) and their
/// descriptors.
fn describe(frame: &FrameView<'_>, gray: &[u8], params: &HarrisParams) -> Result<Described> {
    let (w, h) = (frame.width(), frame.height());
    let corners = harris_corners(gray, w, h, None, params)?;
    let smoothed = Smoothed::new(gray, w, h)?;
    let (points, descriptors) = corners
        .iter()
        .zip(smoothed.describe_all(&corners))
        .filter_map(|(p, d)| Some((*p, d?)))
        .unzip();
    Ok(Described {
        points,
        descriptors,
    })
}

/// Features matched across one overlap where a strategy settled.
#[derive(Clone, Debug, PartialEq)]
pub struct OverlapFeatures {
    /// The preset.
    pub preset: String,
    /// The strategy.
    pub strategy: EvalStrategy,
    /// The overlap's cameras' names.
    pub cameras: (String, String),
    /// RANSAC's inliers of the panorama's matching, mean per set.
    pub inliers: f64,
}

impl OverlapFeatures {
    /// The CSV header.
    pub const HEADER: &'static str = "preset,strategy,camera_i,camera_j,inliers";

    /// A CSV line.
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{},{:.1}",
            self.preset,
            self.strategy.key(),
            self.cameras.0,
            self.cameras.1,
            self.inliers
        )
    }
}

/// The valid stereo disparities of one pair where a strategy settled.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoDensity {
    /// The preset.
    pub preset: String,
    /// The strategy.
    pub strategy: EvalStrategy,
    /// The pair's cameras' names, left and right.
    pub cameras: (String, String),
    /// The share of the rectified view with a valid disparity, mean per
    /// set.
    pub density: f64,
}

impl StereoDensity {
    /// The CSV header.
    pub const HEADER: &'static str = "preset,strategy,camera_left,camera_right,density";

    /// A CSV line.
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{},{:.4}",
            self.preset,
            self.strategy.key(),
            self.cameras.0,
            self.cameras.1,
            self.density
        )
    }
}

/// One pair's rectified views and disparities in the last set a strategy
/// was measured on, for the report's figure.
#[derive(Clone, Debug)]
pub struct StereoView {
    /// The preset.
    pub preset: String,
    /// The strategy.
    pub strategy: EvalStrategy,
    /// The pair's cameras' names, left and right.
    pub cameras: (String, String),
    /// The views and the disparities.
    pub disparities: Disparities,
}

/// The strategies whose stereo views the report shows: the fixed exposure,
/// mean AE, the paper's nonlinear law under both simulations and
/// rigview's default (balanced, scale-and-clip).
pub const STEREO_FIGURE: [EvalStrategy; 5] = [
    EvalStrategy::Fixed,
    EvalStrategy::Mean,
    EvalStrategy::Nonlinear,
    EvalStrategy::NonlinearSc,
    EvalStrategy::MultiSc,
];

impl FeatureMeter {
    /// The views of the last set at rest (`at_rest(set)`, among the latest
    /// [`RECENT_SETS`] that [`Self::from_set`] measured; else of the last
    /// set observed) as [`StereoView`]s of `preset` under `strategy` (none
    /// unless `strategy` is one of [`STEREO_FIGURE`]); `names` are the
    /// cameras'. A set with a probe frame shows a camera at an exposure
    /// it does not rest at.
    pub fn stereo_views(
        &self,
        preset: &str,
        strategy: EvalStrategy,
        names: &[String],
        at_rest: impl Fn(usize) -> bool,
    ) -> Vec<StereoView> {
        if !STEREO_FIGURE.contains(&strategy) {
            return Vec::new();
        }
        let name = |k: usize| names.get(k).cloned().unwrap_or_else(|| k.to_string());
        let shown = last_at_rest(&self.recent, &self.last_stereo, at_rest);
        self.stereo
            .iter()
            .zip(shown)
            .map(|(s, d)| StereoView {
                preset: preset.to_string(),
                strategy,
                cameras: (name(s.left), name(s.right)),
                disparities: d.clone(),
            })
            .collect()
    }
}

/// The disparities of the latest of `recent` (set index, disparities)
/// whose set is `at_rest`, or `last` when none is.
fn last_at_rest<'a>(
    recent: &'a std::collections::VecDeque<(usize, Vec<Disparities>)>,
    last: &'a [Disparities],
    at_rest: impl Fn(usize) -> bool,
) -> &'a [Disparities] {
    recent
        .iter()
        .rev()
        .find(|(set, _)| at_rest(*set))
        .map_or(last, |(_, d)| d.as_slice())
}

/// Writes the report's figure of `views` to `path` (PNG): a row per view,
/// its rectified left and right frames and its disparities (near red, far
/// blue, none black; the search range is the scale), labelled with the strategy, the pair and the share
/// of valid disparities.
pub fn write_stereo_views(views: &[StereoView], path: &std::path::Path) -> Result<()> {
    use crate::report::glyphs::{register_font, FONT};
    use plotters::prelude::*;
    register_font()?;
    let (tw, th) = views
        .iter()
        .map(|v| (v.disparities.width, v.disparities.height))
        .fold((0, 0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
    anyhow::ensure!(tw > 0 && th > 0, "stereo views: nothing to draw");
    let (left, top, gap) = (230usize, 30usize, 6usize);
    let w = left + 3 * (tw + gap);
    let h = top + views.len() * (th + gap);
    let mut buf = vec![255u8; w * h * 3];
    for (row, v) in views.iter().enumerate() {
        let d = &v.disparities;
        let y0 = top + row * (th + gap);
        // (One scale for every row: the search range.)
        let max = d.max_disparity.max(1) as f32;
        for y in 0..d.height {
            for x in 0..d.width {
                let k = y * d.width + x;
                let grey = |img: &[u8]| img.get(k).copied().unwrap_or(0);
                let disparity = d.values.get(k).copied().unwrap_or(f32::NAN);
                let cells = [
                    [grey(&d.rectified[0]); 3],
                    [grey(&d.rectified[1]); 3],
                    ramp(disparity / max),
                ];
                for (col, rgb) in cells.iter().enumerate() {
                    let q = ((y0 + y) * w + left + col * (tw + gap) + x) * 3;
                    buf[q..q + 3].copy_from_slice(rgb);
                }
            }
        }
    }
    {
        let root = crate::report::glyphs::Glyphs::new(BitMapBackend::with_buffer(
            &mut buf,
            (w as u32, h as u32),
        ))
        .into_drawing_area();
        let style = TextStyle::from((FONT, 14)).color(&BLACK);
        let draw = |text: &str, at: (usize, usize)| {
            root.draw_text(text, &style, (at.0 as i32, at.1 as i32))
                .map_err(|e| anyhow::anyhow!("stereo views: {e}"))
        };
        for (col, title) in [
            "left, rectified",
            "right, rectified",
            "disparity (near red, far blue, none black)",
        ]
        .iter()
        .enumerate()
        {
            draw(title, (left + col * (tw + gap), 8))?;
        }
        for (row, v) in views.iter().enumerate() {
            let y = top + row * (th + gap) + th / 2 - 20;
            draw(v.strategy.label(), (6, y))?;
            draw(&format!("{} – {}", v.cameras.0, v.cameras.1), (6, y + 18))?;
            draw(
                &format!("{:.1} % valid", 100.0 * v.disparities.density()),
                (6, y + 36),
            )?;
        }
        root.present()
            .map_err(|e| anyhow::anyhow!("stereo views: {e}"))?;
    }
    let img =
        image::RgbImage::from_raw(w as u32, h as u32, buf).context("stereo views: buffer size")?;
    crate::report::plot::save_png(&img, path)
        .with_context(|| format!("writing the stereo views {}", path.display()))
}

/// A disparity's colour: `t` in [0, 1] from blue (far) through green to
/// red (near); black where it is not a number.
fn ramp(t: f32) -> [u8; 3] {
    if !t.is_finite() {
        return [0, 0, 0];
    }
    let t = t.clamp(0.0, 1.0);
    let up = |x: f32| (255.0 * x.clamp(0.0, 1.0)).round() as u8;
    [
        up(2.0 * t - 1.0),
        up(1.0 - (2.0 * t - 1.0).abs()),
        up(1.0 - 2.0 * t),
    ]
}

/// The downstream measures of a run's measured sets.
#[derive(Debug)]
pub struct Downstream<'a>(&'a [SetFeatures]);

impl<'a> Downstream<'a> {
    /// Of the sets `measured`.
    pub fn of(measured: &'a [SetFeatures]) -> Self {
        Self(measured)
    }

    /// Camera `cam`'s corners tracked from frame to frame, mean per frame
    /// (NaN without a tracked frame).
    pub fn tracked(&self, cam: usize) -> f64 {
        let v: Vec<f64> = self
            .0
            .iter()
            .filter_map(|m| m.tracked.get(cam).copied().flatten())
            .map(|n| n as f64)
            .collect();
        mean(&v)
    }

    /// Per pair of cameras that `of` lists for a set (in the same order
    /// every set), the cameras' names and the mean of its figure over the
    /// sets.
    fn per_pair(
        &self,
        names: &[String],
        of: impl Fn(&SetFeatures) -> Vec<(usize, usize, f64)>,
    ) -> Vec<((String, String), f64)> {
        let Some(first) = self.0.first() else {
            return Vec::new();
        };
        let name = |k: usize| names.get(k).cloned().unwrap_or_else(|| k.to_string());
        let sets: Vec<_> = self.0.iter().map(&of).collect();
        of(first)
            .iter()
            .enumerate()
            .map(|(p, &(i, j, _))| {
                let v: Vec<f64> = sets.iter().filter_map(|s| s.get(p)).map(|x| x.2).collect();
                ((name(i), name(j)), mean(&v))
            })
            .collect()
    }

    /// Inliers across each overlap, mean per set, for the rows of
    /// `preset` under `strategy`; `names` are the cameras'.
    pub fn overlaps(
        &self,
        preset: &str,
        strategy: EvalStrategy,
        names: &[String],
    ) -> Vec<OverlapFeatures> {
        self.per_pair(names, |m| {
            m.overlaps
                .iter()
                .map(|&(i, j, n)| (i, j, n as f64))
                .collect()
        })
        .into_iter()
        .map(|(cameras, inliers)| OverlapFeatures {
            preset: preset.to_string(),
            strategy,
            cameras,
            inliers,
        })
        .collect()
    }

    /// The valid stereo disparities of each pair, mean per set, for the
    /// rows of `preset` under `strategy`; `names` are the cameras'.
    pub fn stereo(
        &self,
        preset: &str,
        strategy: EvalStrategy,
        names: &[String],
    ) -> Vec<StereoDensity> {
        self.per_pair(names, |m| m.stereo.clone())
            .into_iter()
            .map(|(cameras, density)| StereoDensity {
                preset: preset.to_string(),
                strategy,
                cameras,
                density,
            })
            .collect()
    }
}

/// Mutual matches of `a`'s and `b`'s descriptors whose corners lie within
/// [`MAX_MOTION_PX`] of each other.
fn matched(a: &Described, b: &Described) -> Result<Vec<rigview_core::features::Match>> {
    let near = |i: usize, j: usize| {
        let (p, q) = (a.points[i], b.points[j]);
        (p[0] - q[0]).hypot(p[1] - q[1]) <= MAX_MOTION_PX
    };
    Ok(match_mutual_where(
        &a.descriptors,
        &b.descriptors,
        RATIO,
        near,
    )?)
}

/// A frame as an 8-bit grey image, its luminance as the metering reads it.
fn grey(frame: &FrameView<'_>) -> Vec<u8> {
    let (w, h) = (frame.width(), frame.height());
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            out.push((frame.luma_at(x, y) * 255.0).round().clamp(0.0, 255.0) as u8);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigview_core::image::PixelFormat;

    /// Probe sets are left out, and the set after one is not tracked from
    /// it; the others pass as they were.
    #[test]
    fn the_stereo_figure_shows_the_last_set_at_rest() {
        let d = |valid: usize| Disparities {
            width: 1,
            height: 1,
            values: vec![0.0],
            max_disparity: 16,
            considered: 10,
            valid,
            rectified: [vec![0], vec![0]],
        };
        // Sets 10..14 measured; 13 and 14 hold a probe frame.
        let recent: std::collections::VecDeque<_> =
            (10..15).map(|set| (set, vec![d(set)])).collect();
        let last = vec![d(14)];
        let shown = last_at_rest(&recent, &last, |set| set < 13);
        assert_eq!(shown[0].valid, 12);
        // None at rest: the last set observed.
        let shown = last_at_rest(&recent, &last, |_| false);
        assert_eq!(shown[0].valid, 14);
    }

    #[test]
    fn at_rest_leaves_out_probe_sets() {
        let set = |k: usize| SetFeatures {
            tracked: vec![Some(k), Some(10 + k)],
            overlaps: vec![(0, 1, k)],
            stereo: Vec::new(),
        };
        // Sets 0..6; camera 1's frame of set 3 is a probe.
        let trace = super::super::closed_loop::Trace {
            probe: vec![
                vec![false; 6],
                vec![false, false, false, true, false, false],
            ],
            ..Default::default()
        };
        // Measured from set 2 on.
        let kept = at_rest((2..6).map(set).collect(), &trace, 2);
        let inliers: Vec<usize> = kept.iter().map(|s| s.overlaps[0].2).collect();
        assert_eq!(inliers, [2, 4, 5]);
        assert_eq!(kept[0].tracked, [Some(2), Some(12)]);
        assert_eq!(kept[1].tracked, [None, None], "set 4 follows the probe");
        assert_eq!(kept[2].tracked, [Some(5), Some(15)]);
    }

    /// A textured grey image: a checkerboard of 8-pixel squares.
    fn board(w: usize, h: usize, dark: u8, light: u8) -> Vec<u8> {
        (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    if (x / 8 + y / 8) % 2 == 0 {
                        dark
                    } else {
                        light
                    }
                })
            })
            .collect()
    }

    fn described(data: &[u8], w: usize, h: usize) -> Described {
        let frame = FrameView::new(PixelFormat::Mono8, w, h, data).unwrap();
        describe(&frame, &grey(&frame), &HarrisParams::default()).unwrap()
    }

    #[test]
    fn the_same_texture_tracks_and_a_clipped_one_does_not() {
        let (w, h) = (160, 120);
        let a = described(&board(w, h, 60, 180), w, h);
        let b = described(&board(w, h, 62, 178), w, h);
        let n = matched(&a, &b).unwrap().len();
        // (The spread keeps at most 12 corners in a 64-pixel cell.)
        assert!(a.points.len() >= 20, "{} corners", a.points.len());
        assert!(
            n * 10 >= a.points.len() * 9,
            "{n} of {} corners tracked",
            a.points.len()
        );
        // Shifted by 4 pixels: no corner within reach of its own.
        let shifted: Vec<u8> = (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    if ((x + 4) / 8 + y / 8) % 2 == 0 {
                        60
                    } else {
                        180
                    }
                })
            })
            .collect();
        let c = described(&shifted, w, h);
        let moved = matched(&a, &c).unwrap().len();
        assert!(moved < n / 4, "{moved} matched after a shift, {n} before");
        // Clipped white: nothing to track.
        let white = described(&vec![255; w * h], w, h);
        assert_eq!(matched(&a, &white).unwrap().len(), 0);
    }
}
