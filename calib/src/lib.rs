//! `rigview-calib`: camera models (OpenCV fisheye / Kannala–Brandt, pinhole
//! with radial-tangential or rational distortion), the rig (intrinsics, extrinsics in the
//! vehicle frame, neighbour graph), calibration file formats and the
//! calibration tools.
//!
//! This crate opens no camera and draws no UI.

mod cvutil;
pub mod error;
pub mod formats;
mod lm;
pub mod model;
pub mod pose;
pub mod report;
pub mod rig;
pub mod tools;

pub use error::{CalibError, FieldError, Result};
pub use model::{Distortion, FieldOfView, Intrinsics, ModelKind};
pub use pose::Pose;
pub use rig::{Camera, DeviceId, Frame, Rig};
