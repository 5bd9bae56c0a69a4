//! The view a session composes and meters: the surround view or the
//! panorama of a calibration, checked against the source's cameras, with
//! the rig's neighbour graph; and the Harris corners (OpenCV) the live
//! panorama's matching is given.

use std::path::Path;

use anyhow::{Context, Result};
use rigview_calib::rig::Rig;
use rigview_calib::tools::corners::{harris_corners, HarrisParams};
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{
    check_view, BowlSettings, PanoramaSettings, ProcessingSettings, SharedDetector, View, ViewKind,
};
use rigview_core::source::CameraInfo;
use rigview_core::surround::{BlendMode, CanvasSpec};

/// The canvas every session composes on: 10 m × 10 m at 100 px/m.
pub fn canvas_spec() -> CanvasSpec {
    CanvasSpec::default()
}

/// A view built for a session: the view, the neighbour graph and the rig
/// it was built from.
pub type BuiltView = (View, NeighbourGraph, Rig);

/// Everything besides the rig that decides a view.
#[derive(Clone)]
pub struct ViewSpec {
    /// Which view.
    pub kind: ViewKind,
    /// The surround view's canvas.
    pub canvas: CanvasSpec,
    /// The panorama's settings.
    pub panorama: PanoramaSettings,
    /// The bowl and its viewpoint.
    pub bowl: BowlSettings,
    /// How the view's overlaps are blended (the bowl's plan is built for
    /// it with the view).
    pub blend: BlendMode,
    /// The live panorama's corner detector.
    pub detector: SharedDetector,
}

impl std::fmt::Debug for ViewSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewSpec")
            .field("kind", &self.kind)
            .field("canvas", &self.canvas)
            .field("panorama", &self.panorama)
            .field("bowl", &self.bowl)
            .finish_non_exhaustive()
    }
}

impl ViewSpec {
    /// The view `kind` of a session: on [`canvas_spec`], the panorama as
    /// `panorama` says, with [`shared_detector`].
    pub fn session(kind: ViewKind, panorama: &PanoramaSettings) -> Self {
        Self {
            kind,
            canvas: canvas_spec(),
            panorama: panorama.clone(),
            bowl: BowlSettings::default(),
            blend: BlendMode::default(),
            detector: shared_detector(),
        }
    }

    /// The view `processing` asks for, in a session.
    pub fn processing(processing: &ProcessingSettings) -> Self {
        Self {
            bowl: processing.bowl.clone(),
            blend: processing.blend,
            ..Self::session(processing.view, &processing.panorama)
        }
    }

    /// The surround view on `canvas`.
    pub fn surround(canvas: CanvasSpec) -> Self {
        Self {
            canvas,
            ..Self::session(ViewKind::Surround, &PanoramaSettings::default())
        }
    }
}

/// Builds the view `spec` asks for of `rig`: the one way every command,
/// the window and the evaluation build the view the processor composes.
pub fn build_view(rig: &Rig, spec: &ViewSpec) -> Result<View> {
    View::build(
        spec.kind,
        rig,
        &spec.canvas,
        &spec.panorama,
        (&spec.bowl, spec.blend),
        spec.detector.clone(),
    )
    .with_context(|| format!("building the {} view", spec.kind.name()))
}

/// The view `spec` asks for of `rig`, checked against `cameras`, with the
/// rig's neighbour graph.
pub fn view_with(
    rig: &Rig,
    cameras: &[CameraInfo],
    spec: &ViewSpec,
) -> Result<(View, NeighbourGraph)> {
    let view = build_view(rig, spec)?;
    check_view(view.mosaic(), cameras)?;
    let graph = NeighbourGraph::new(cameras.len(), &rig.neighbours)?;
    Ok((view, graph))
}

/// The view `kind` (the panorama as `panorama` says) and neighbour graph
/// of `rig` for `cameras`.
pub fn view_of(
    rig: &Rig,
    cameras: &[CameraInfo],
    kind: ViewKind,
    panorama: &PanoramaSettings,
) -> Result<(View, NeighbourGraph)> {
    view_with(rig, cameras, &ViewSpec::session(kind, panorama))
}

/// The view `processing` asks for, of `rig` for `cameras`.
pub fn view_for(
    rig: &Rig,
    cameras: &[CameraInfo],
    processing: &ProcessingSettings,
) -> Result<(View, NeighbourGraph)> {
    view_with(rig, cameras, &ViewSpec::processing(processing))
}

/// Loads a calibration file (any supported format) and builds the view
/// `processing` asks for, for `cameras`; errors name the file.
pub fn load_calibration(
    path: &Path,
    cameras: &[CameraInfo],
    processing: &ProcessingSettings,
) -> Result<BuiltView> {
    let loaded = rigview_calib::formats::load(path, None, None)
        .with_context(|| format!("cannot load the calibration {}", path.display()))?;
    let (view, graph) = view_for(&loaded.rig, cameras, processing)
        .with_context(|| format!("cannot use the calibration {}", path.display()))?;
    Ok((view, graph, loaded.rig))
}

/// Harris corners through OpenCV with the default spread, as the
/// panorama's matching asks for them, at positions refined to a fraction
/// of a pixel (the refinement of the rotations needs them).
pub fn detect(gray: &[u8], w: usize, h: usize, mask: &[u8]) -> rigview_core::Result<Vec<[f32; 2]>> {
    let params = HarrisParams {
        subpixel: true,
        ..HarrisParams::default()
    };
    harris_corners(gray, w, h, Some(mask), &params)
        .map_err(|e| rigview_core::Error::calibration("Harris corners", e))
}

/// [`detect`] as the live panorama's detector.
pub fn shared_detector() -> rigview_core::pipeline::SharedDetector {
    std::sync::Arc::new(detect)
}
