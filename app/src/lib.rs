//! `rigview` as a library: the parts of the application that tests and
//! other front ends use.
//!
//! - [`gui`]: the desktop app (eframe/egui).
//! - [`live`]: live capture from GenICam cameras through Aravis (the
//!   `aravis` feature, on by default), frame-set assembly, stream health and
//!   the `rigview live` command.
//! - [`plot_png`]: a PNG plot of the exposure state (plotters).
//! - [`report`]: the summary of a run (drops, latency, CPU use).
//! - [`run_cmd`]: `rigview run`, in the window or headless.
//! - [`session`]: a source, its calibration and the processing pipeline.
//! - [`settings`]: the settings that persist between runs.

pub mod gui;
pub mod live;
pub mod plot_png;
pub mod report;
pub mod run_cmd;
pub mod session;
pub mod settings;
