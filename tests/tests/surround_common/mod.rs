//! What the surround-view tests share: the real rig of
//! `tests/data/surround-nz` (its folder, canvas and frames) and noise-free
//! frames of the simulated rig.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use rigview_calib::rig::Rig;
use rigview_core::exposure::{ExposureSetting, FrameView, PixelFormat};
use rigview_core::sim::{FillRequest, SimRender};
use rigview_core::surround::CanvasSpec;

/// The real rig's folder.
pub fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/surround-nz")
}

/// The source project's canvas (16 m × 12 m around the car, whose rectangle
/// is 5 m × 2 m), at 50 px/m.
pub fn spec() -> CanvasSpec {
    CanvasSpec::around_car_16x12(50.0)
}

/// The real rig's frames, packed RGB: width, height, pixels.
pub fn images(rig: &Rig) -> Vec<(usize, usize, Vec<u8>)> {
    rig.cameras
        .iter()
        .map(|c| {
            let img = image::open(data().join(format!("{}.png", c.name)))
                .unwrap()
                .to_rgb8();
            (img.width() as usize, img.height() as usize, img.into_raw())
        })
        .collect()
}

/// Frame views of packed RGB images (width, height, pixels), as
/// [`images`] gives them.
pub fn views(images: &[(usize, usize, Vec<u8>)]) -> Vec<FrameView<'_>> {
    images
        .iter()
        .map(|(w, h, d)| FrameView::new(PixelFormat::Rgb8, *w, *h, d).unwrap())
        .collect()
}

/// Frame views of the simulated rig's Mono8 frames `buffers` (one per
/// camera, rig order), as [`still`] gives them.
pub fn still_views<'a>(render: &SimRender, buffers: &'a [Vec<u8>]) -> Vec<FrameView<'a>> {
    buffers
        .iter()
        .zip(render.cameras())
        .map(|(b, c)| FrameView::new(PixelFormat::Mono8, c.width, c.height, b).unwrap())
        .collect()
}

/// The canvas of the simulated rig's mat and car (12 m × 8 m around the
/// car, whose rectangle is 5 m × 2 m), at 50 px/m.
pub fn sim_spec() -> CanvasSpec {
    CanvasSpec {
        x_min_m: -6.0,
        x_max_m: 6.0,
        y_min_m: -4.0,
        y_max_m: 4.0,
        px_per_m: 50.0,
        vehicle_m: [-2.5, 2.5, -1.0, 1.0],
    }
}

/// Camera `k`'s noise-free Mono8 frame of the simulated rig at the first
/// moment, exposed `shutter_us` at 0 dB.
pub fn still(render: &SimRender, k: usize, shutter_us: f64) -> Vec<u8> {
    let c = &render.cameras()[k];
    let mut req = FillRequest::new(
        k,
        0,
        ExposureSetting {
            shutter_us,
            gain_db: 0.0,
        },
        PixelFormat::Mono8,
        c.width,
        c.height,
    );
    req.noise = false;
    let mut buf = vec![0u8; req.buffer_len()];
    render.fill(&req, &mut buf).unwrap();
    buf
}

/// A pair's matches and inliers aligned by their patches, for the
/// panorama tests' reports.
pub fn aligned(p: &rigview_core::panorama::PairMatches) -> (usize, usize) {
    let aligned = p.matches.iter().filter(|m| m.aligned);
    (
        aligned.clone().count(),
        aligned.filter(|m| m.inlier).count(),
    )
}
