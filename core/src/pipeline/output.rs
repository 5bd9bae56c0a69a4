//! What processing a set gives the display and the telemetry.

use std::sync::Arc;
use std::time::Instant;

use super::{ProcessingSettings, StageTimes};
use crate::exposure::{Estimate, ExposureSetting, ProbeEvent, RigStep};
use crate::surround::{Canvas, Mosaic};

/// An overlap patch drawn over a camera's thumbnail: its bounding box in
/// the source image, as fractions of the width and height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchBox {
    /// The overlap (index into [`Overlay::pairs`]).
    pub pair: usize,
    /// Left, top, right, bottom in [0, 1].
    pub rect: [f32; 4],
}

/// What the display draws over each camera: the overlap patches.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlay {
    /// The overlaps as camera index pairs.
    pub pairs: Vec<(usize, usize)>,
    /// Per camera, its patches.
    pub patches: Vec<Vec<PatchBox>>,
}

impl Overlay {
    pub(super) fn of(view: Option<&Mosaic>, cameras: usize) -> Self {
        let mut o = Overlay {
            pairs: Vec::new(),
            patches: vec![Vec::new(); cameras],
        };
        let Some(view) = view else {
            return o;
        };
        for (k, ov) in view.overlaps().iter().enumerate() {
            o.pairs.push((ov.i, ov.j));
            for patch in &ov.patches {
                for (cam, pixels) in [(ov.i, &patch.pixels_i), (ov.j, &patch.pixels_j)] {
                    let Some(layer) = view.layers().get(cam) else {
                        continue;
                    };
                    let (w, h) = layer.source;
                    if let Some(rect) = bounding_box(pixels, w, h) {
                        if let Some(list) = o.patches.get_mut(cam) {
                            list.push(PatchBox { pair: k, rect });
                        }
                    }
                }
            }
        }
        o
    }
}

fn bounding_box(pixels: &[u32], w: usize, h: usize) -> Option<[f32; 4]> {
    if pixels.is_empty() || w == 0 || h == 0 {
        return None;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for &p in pixels {
        let (x, y) = (p as usize % w, p as usize / w);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    Some([
        x0 as f32 / w as f32,
        y0 as f32 / h as f32,
        (x1 + 1) as f32 / w as f32,
        (y1 + 1) as f32 / h as f32,
    ])
}

/// One camera in one processed set, for the display.
#[derive(Clone, Debug)]
pub struct CameraOutput {
    /// What the frame was taken with.
    pub taken: ExposureSetting,
    /// The metered image as 8-bit grey (the thumbnail), row-major.
    pub thumb: Vec<u8>,
    /// Its width.
    pub thumb_width: usize,
    /// Its height.
    pub thumb_height: usize,
    /// Per thumbnail pixel, whether it is metered (`None`: all are).
    pub metered_mask: Option<Vec<bool>>,
    /// Histogram of the metered pixels over [0, 1].
    pub histogram: Vec<u32>,
    /// Mean metered luminance in [0, 1].
    pub mean: f32,
    /// Fraction of metered pixels that are saturated.
    pub saturated: f32,
    /// The estimate (also computed for display when the strategy needs
    /// none).
    pub estimate: Option<Estimate>,
    /// The command sent after this frame.
    pub command: Option<ExposureSetting>,
    /// The manual override in force.
    pub manual: Option<f64>,
    /// The outcome of the camera's latest probe
    /// ([`crate::exposure::probe`]).
    pub last_probe: Option<ProbeEvent>,
    /// Whether that probe was brighter (where most of the frame was dark)
    /// rather than darker.
    pub last_probe_brighter: bool,
    /// Whether the frame was taken at a probe's darker exposure.
    pub probe_frame: bool,
}

/// One overlap in one processed set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairOutput {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// `log2 r_ij` (`None`: too few usable patches).
    pub log2_r: Option<f64>,
}

/// One processed frame set.
#[derive(Clone, Debug)]
pub struct Output {
    /// The set's trigger number.
    pub trigger: u64,
    /// When the set was ready (the source gave it).
    pub ready: Instant,
    /// When its processing was done.
    pub processed: Instant,
    /// Per camera.
    pub cameras: Vec<CameraOutput>,
    /// Per overlap.
    pub pairs: Vec<PairOutput>,
    /// The composed view (`None`: no calibration, composition is off, or
    /// it failed: see `compose_error`).
    pub canvas: Option<Arc<Canvas>>,
    /// The display gain each camera's pixels were shown with (rig order;
    /// empty when no view was composed): probe frames and eased exposure
    /// jumps, and the seam compensation ([`super::DisplaySettings`]).
    pub display_gains: Vec<f32>,
    /// Why the view could not be composed from this set, if it could not.
    pub compose_error: Option<String>,
    /// The overlap patches to draw over the cameras.
    pub overlay: Arc<Overlay>,
    /// Stage times.
    pub times: StageTimes,
    /// The settings in force when it was processed.
    pub settings: Arc<ProcessingSettings>,
    /// What the controller did with the set: per camera its estimate,
    /// target, command and probe event, and every measured ratio.
    pub step: RigStep,
    /// The panorama's latest matching and refinement (the panorama view
    /// only).
    pub panorama: Option<Arc<super::PanoramaReport>>,
    /// The bird's-eye view composed beside the bowl, when the bowl's
    /// settings ask for it ([`super::BowlSettings::beside`]).
    pub beside: Option<Arc<Canvas>>,
    /// The view the processor had for this set (`None`: none), which
    /// `canvas` shows when it is composed.
    pub view: Option<super::ViewKind>,
    /// The bowl's viewpoint `canvas` shows (the bowl view only), and
    /// whether another one is being built.
    pub bowl: Option<(crate::bowl::Viewpoint, bool)>,
    /// The bowl shown (the bowl view only): its spec, viewpoint and ground
    /// plan, for a renderer of its own.
    pub bowl_view: Option<Arc<crate::bowl::BowlView>>,
    /// The set's frames, rig order (shared, not copied): for a renderer or
    /// a remote view of their own.
    pub frames: Vec<crate::source::Frame>,
    /// Per camera of `frames`, its display gains as the composer applies
    /// them: the exposure gain (the frame scaled, clipped at white) and
    /// the seam gain.
    pub gain_parts: Vec<[f32; 2]>,
}
