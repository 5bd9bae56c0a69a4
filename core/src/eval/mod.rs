//! Measures of the closed loop, for the tests and the evaluation.
//!
//! - [`dynamics`]: frames to settle, overshoot and jitter of a camera's
//!   exposure after a change of light.

pub mod dynamics;
