//! Image features for the panorama's matching: BRIEF binary descriptors
//! ([`brief`]), compared by popcount Hamming distance and matched mutually
//! with a ratio test, and the sub-pixel alignment of a match's two corners
//! ([`align`]). Pure Rust: Debian's OpenCV has no `xfeatures2d`, and
//! `core` calls no OpenCV.

pub mod align;
pub mod brief;

pub use align::{AlignOptions, Aligner, Gray};
pub use brief::{match_mutual, match_mutual_where, Descriptor, Match, Smoothed, PATCH_RADIUS};
