//! `rigview-core`: the algorithms of rigview that need neither a camera nor a
//! display.
//!
//! - [`cpu`]: the vector instruction sets the kernels are compiled for, and
//!   which of them this CPU runs.
//! - [`exposure`]: gradient-based auto-exposure after Shim et al. (IEEE TCSVT
//!   2018): metering, the gradient-information metric, the γ̂ estimator, the
//!   update laws, multi-camera balancing, the shutter/gain split, baselines and
//!   the per-camera and per-rig controllers.
//! - [`features`]: BRIEF binary descriptors and their mutual matching, for
//!   the panorama's feature matches.
//! - [`image`]: camera frames as the crate reads them: pixel formats,
//!   borrowed frames, region-of-interest masks and luminance; 8-bit colour
//!   conversion and the Euclidean distance transform.
//! - [`panorama`]: the cylindrical panorama: a cylinder around the vehicle
//!   mapped into every camera with the surround view's remap machinery.
//! - [`pipeline`]: the capture and processing threads of the app and its
//!   headless mode: bounded drop-oldest queues, live control, telemetry and
//!   stage times.
//! - [`sim`]: the simulated HDR rig (scene, scripted light, EMVA 1288
//!   sensor, reference rig, ground truth): the default source of the app,
//!   the tests and the benchmarks.
//! - [`source`]: the frame-source interface that the simulated rig, live
//!   cameras and replay implement: frame sets, frame metadata, exposure
//!   commands, stream health.
//! - [`stats`]: order statistics of samples (median, nearest-rank
//!   quantiles), one definition for every part that summarises a sample.
//! - [`surround`]: the bird's-eye surround view: remap tables from the rig
//!   calibration, blending, ground masks and overlap patches.
//! - [`synth`]: small synthetic high-dynamic-range scenes seen by linear
//!   cameras, for the exposure core's own tests and benchmarks.

pub mod bowl;
pub mod cpu;
pub mod error;
pub mod eval;
pub mod exposure;
pub mod features;
pub mod hdr;
pub mod image;
pub mod panorama;
pub mod pipeline;
pub mod sim;
pub mod source;
pub mod stats;
pub mod surround;
pub mod synth;

pub use error::{Error, Result};
