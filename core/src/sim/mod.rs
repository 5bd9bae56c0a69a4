//! The simulated HDR rig: rigview's built-in source for the demo, the tests
//! and the benchmarks.
//!
//! - [`scene`]: the world: textured ground with lane markings and a
//!   calibration mat, buildings, walls, parked cars, the rig's own vehicle,
//!   a sky with a sun; sunlit and shadowed regions (10⁴ and more of dynamic
//!   range in one scene).
//! - [`environment`]: real scenes: an HDR panorama's radiance in place of
//!   the procedural world.
//! - [`script`]: illumination over time: constant, steps, ramps, tunnels.
//! - [`sensor`]: the camera: a linear EMVA 1288 sensor with full-well
//!   saturation, shot, read and quantisation noise, 8- or 12-bit output,
//!   shutter and gain ranges, optional vignetting.
//! - [`rig`]: the reference rig (four 185° Kannala–Brandt fisheyes at
//!   1288×964, about 1 m up, tilted down), or any rig file.
//! - [`config`]: simulation files and the built-in presets.
//! - [`render`]: [`SimRender`], the rig's images traced once per scene;
//!   [`SimRender::fill`] exposes one frame into any buffer (also for a
//!   GenICam fake camera's fill callback).
//! - [`source`]: [`SimRig`], the [`crate::source::FrameSource`] with
//!   actuation latency and a trigger rate.
//! - [`camera_ae`]: the cameras' own auto-exposure (a mean-intensity
//!   loop, damped and rate-limited, shutter before gain), which the rig
//!   runs when it is switched on.
//! - [`truth`]: ground truth: the dense-sweep optimum of the metric, the
//!   estimator's fixed points, the true overlap ratios, the dynamic range.
//!
//! The closed loop on the simulated rig is the app's own processor driven
//! in lock step ([`crate::pipeline::LockStep`]).
//!
//! ```no_run
//! use std::sync::Arc;
//! use rigview_core::sim::{SimConfig, SimRender, SimRig, SimRigOptions};
//! use rigview_core::source::FrameSource;
//!
//! let render = Arc::new(SimRender::new(&SimConfig::preset("tunnel")?)?);
//! let mut rig = SimRig::new(render, SimRigOptions::default())?;
//! let set = rig.next_set(std::time::Duration::from_secs(1))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod actuation;
pub mod camera_ae;
pub mod config;
pub mod environment;
pub mod render;
pub mod rig;
pub mod scene;
pub mod script;
pub mod sensor;
pub mod source;
mod texture;
pub mod truth;

pub use actuation::Actuation;
pub use camera_ae::CameraAeParams;
pub use config::{RigChoice, SimConfig, PRESETS};
pub use render::{FillRequest, SimRender};
pub use rig::reference_rig;
pub use scene::{Class, Scene};
pub use script::{Event, Levels, Script};
pub use sensor::Sensor;
pub use source::{Pacing, SimRig, SimRigOptions};

pub use rigview_calib::FieldError;

use crate::error::Error;

/// Checks that `value` is finite and in `[lo, hi]`; the error names the
/// field (with its path) and says what was expected.
pub(crate) fn check_field(
    field: impl Into<String>,
    value: f64,
    lo: f64,
    hi: f64,
    expected: &str,
) -> Result<(), FieldError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(FieldError::new(field, expected, format!("{value}")))
    }
}

/// A field error as an error of this crate, naming `file`.
pub fn field_error(error: FieldError, file: &str) -> Error {
    Error::Field {
        file: file.to_owned(),
        field: error.field,
        expected: error.expected,
        found: error.found,
    }
}

/// A small render of the reference preset shared by the unit tests.
#[cfg(test)]
pub(crate) fn test_render() -> std::sync::Arc<SimRender> {
    static RENDER: std::sync::OnceLock<std::sync::Arc<SimRender>> = std::sync::OnceLock::new();
    RENDER
        .get_or_init(|| {
            let config = SimConfig {
                scale: 0.25,
                ..SimConfig::default()
            };
            std::sync::Arc::new(SimRender::new(&config).unwrap())
        })
        .clone()
}
