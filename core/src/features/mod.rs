//! Image features for the panorama's matching: BRIEF binary descriptors
//! ([`brief`]), compared by popcount Hamming distance and matched mutually
//! with a ratio test. Pure Rust: Debian's OpenCV has no `xfeatures2d`, and
//! `core` calls no OpenCV.

pub mod brief;

pub use brief::{match_mutual, match_mutual_where, Descriptor, Match, Smoothed, PATCH_RADIUS};
