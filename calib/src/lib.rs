//! `rigview-calib`: camera models (OpenCV fisheye / Kannala–Brandt, pinhole
//! with radial-tangential distortion), the rig (intrinsics, extrinsics in the
//! vehicle frame, neighbour graph) and calibration file formats.
//!
//! This crate opens no camera and draws no UI.
