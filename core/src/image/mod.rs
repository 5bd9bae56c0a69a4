//! Camera images as the rest of the crate reads them: the pixel formats,
//! borrowed frames, region-of-interest masks and luminance, and the image
//! operations the crate needs (8-bit colour conversion, the Euclidean
//! distance transform, an 8-bit frame scaled by a gain), in Rust without system libraries.
//!
//! Luminance uses the BT.601 weights (0.299 R + 0.587 G + 0.114 B, as
//! OpenCV's `RGB2GRAY`) on the camera's values, normalised to [0, 1] by the
//! format's full scale (255, 4095 or 65535). A Bayer mosaic is read as 2×2
//! quads (one R, two G sharing G's weight, one B), so no demosaicing is
//! needed: a quad's luminance is `Σ w_i·v_i / 255` over its four samples.
//! The weights and each format's row conversion are defined once
//! (`luma.rs`) and used both by the metering and by
//! [`FrameView::luma_at`].

mod convert;
mod distance;
mod format;
mod frame;
mod gain;
pub(crate) mod luma;
mod mask;

pub use convert::{mono8_to_rgb8, rgb8_to_mono8};
pub use distance::distance_to_zero;
pub use format::{PixelFormat, BAYER_PATTERNS};
pub use frame::FrameView;
pub use gain::scale_8bit;
pub use mask::RoiMask;
