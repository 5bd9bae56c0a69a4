//! `rigview` as a library: the parts of the application that tests and
//! other front ends use.
//!
//! - [`cli`]: the command line's arguments, one file per subcommand, and
//!   how they map to the options below.
//! - [`brackets`]: exposure brackets (a folder of images at several
//!   exposures per moment), their frame source and their export from the
//!   simulated rig.
//! - [`calibration`]: `rigview calib`'s tools (show, convert, intrinsics,
//!   ground).
//! - [`demo`]: the closed loop on the simulated rig, printed.
//! - [`eval`]: `rigview eval`, the paper's experiments as figures, data
//!   and a report.
//! - [`gui`]: the desktop app (eframe/egui).
//! - [`headless`]: `rigview run --headless` (views, telemetry, plot and
//!   summary to a folder).
//! - [`live`]: live capture from GenICam cameras through Aravis (the
//!   `aravis` feature, on by default), frame-set assembly, stream health and
//!   `rigview live --headless`.
//! - [`logging`]: rigview's messages as `tracing` events, on stderr and in
//!   the buffer the window and the headless modes show.
//! - [`panorama`]: the panorama's Harris corners (OpenCV), its per-pair
//!   report, and `rigview panorama`.
//! - [`plot_png`]: a PNG plot of the exposure state (plotters).
//! - [`plot_text`]: the plots' text drawn where its glyphs belong.
//! - [`report`]: the summary of a run (drops, latency, CPU use).
//! - [`session`]: a source, its calibration and the processing pipeline.
//! - [`settings`]: the settings that persist between runs.
//! - [`stills`]: still images of a calibrated rig composed into a
//!   bird's-eye view (`rigview surround`).

pub mod brackets;
pub mod calibration;
pub mod cli;
pub mod demo;
pub mod eval;
pub mod gui;
pub mod headless;
pub mod live;
pub mod logging;
pub mod panorama;
pub mod plot_png;
pub mod plot_text;
pub mod record_brackets;
pub mod recording;
pub mod report;
pub mod session;
pub mod settings;
pub mod stills;
