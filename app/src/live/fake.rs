//! What Aravis's in-process fake cameras show: a synthetic high-dynamic-range
//! scene seen by a linear camera, rendered at the exposure time and gain the
//! fake camera's registers hold, so that exposure commands sent through the
//! real Aravis API change the pixels.
//!
//! [`render_into`] is the one place that decides what a fake camera shows.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use rigview_core::exposure::split::gain_factor;
use rigview_core::synth::{LinearCamera, StripRig};

/// The scene one fake camera sees and the sensor it is seen with.
#[derive(Clone, Debug)]
pub struct FakeView {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Radiance, row-major, `width × height`.
    pub radiance: Arc<[f32]>,
    /// The sensor.
    pub camera: LinearCamera,
    /// dB per step of the fake camera's `GainRaw`.
    pub gain_db_per_raw: f64,
}

impl FakeView {
    /// The views of `levels.len()` cameras side by side on one cyclic scene
    /// (neighbours overlap by a quarter of the width); `levels[i]` lights
    /// camera `i`'s part of it.
    pub fn strip(
        width: usize,
        height: usize,
        levels: &[f32],
        seed: u64,
        camera: LinearCamera,
    ) -> rigview_core::Result<Vec<FakeView>> {
        let rig = StripRig::new(width, height, width / 4, levels, seed)?;
        Ok((0..rig.cameras())
            .map(|i| FakeView {
                width,
                height,
                radiance: Arc::from(rig.view(i).radiance()),
                camera,
                gain_db_per_raw: 1.0,
            })
            .collect())
    }
}

static FRAME_SEED: AtomicU64 = AtomicU64::new(1);

/// Renders `view` as exposed for `exposure_us` at `gain_db` into `out`
/// (Mono8, `view.width × view.height`, tightly packed).
pub fn render_into(view: &FakeView, exposure_us: f64, gain_db: f64, out: &mut [u8]) {
    let e = exposure_us * gain_factor(gain_db);
    let seed = FRAME_SEED.fetch_add(1, Ordering::Relaxed);
    let frame = view.camera.render_mono8(&view.radiance, e, seed);
    let n = out.len().min(frame.len());
    out[..n].copy_from_slice(&frame[..n]);
}
