//! `rigview-calib`: camera models (OpenCV fisheye / Kannala–Brandt, pinhole
//! with radial-tangential or rational distortion), the rig (intrinsics, extrinsics in the
//! vehicle frame, neighbour graph), calibration file formats and the
//! calibration tools.
//!
//! This crate opens no camera and draws no UI.
//!
//! Its `opencv` feature (on by default) brings what needs OpenCV: the
//! OpenCV FileStorage formats and the surround layout built on them
//! ([`formats::opencv`], [`formats::surround`]) and the calibration tools
//! ([`tools`]). Without it, reading or writing an OpenCV file is a
//! [`CalibError::NeedsFeature`] naming the file.

pub mod convert;
#[cfg(feature = "opencv")]
mod cvutil;
pub mod error;
pub mod formats;
pub mod lm;
pub mod model;
pub mod pose;
pub mod report;
pub mod rig;
#[cfg(feature = "opencv")]
pub mod tools;

pub use error::{CalibError, FieldError, Result};
pub use model::{Distortion, FieldOfView, Intrinsics, ModelKind, Projector};
pub use pose::Pose;
pub use rig::{Camera, CameraProjector, DeviceId, Frame, Rig};
