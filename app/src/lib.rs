//! `rigview` as a library: the parts of the application that tests and
//! other front ends use, laid out by what the product does.
//!
//! - [`cli`]: the command line's arguments, one file per subcommand, and
//!   how they map to the plain options of the modules below.
//! - [`gui`]: the desktop app (eframe/egui).
//! - [`session`]: a source (simulated rig, live cameras, a recording,
//!   exposure brackets), its calibration's view and the processing
//!   pipeline on them; recording and replaying a session; brackets.
//! - [`commands`]: the commands that run once and end (the headless run,
//!   `live --headless`, the demo, stills composed into a surround view or
//!   a panorama, the calibration tools, `record`, `recording`).
//! - [`report`]: what runs report: the summary (drops, latency, CPU use),
//!   the panorama's per-pair lines, the PNG plot of the exposure state and
//!   the plots' text.
//! - [`eval`]: `rigview eval`, the paper's experiments as figures, data
//!   and a report.
//! - [`live`]: live capture from GenICam cameras through Aravis (the
//!   `aravis` feature, on by default), frame-set assembly and stream
//!   health.
//! - [`logging`]: rigview's messages as `tracing` events, on stderr and in
//!   the buffer the window and the headless modes show.
//! - [`settings`]: the settings that persist between runs.

pub mod cli;
pub mod commands;
pub mod eval;
pub mod gui;
pub mod live;
pub mod logging;
pub mod memory;
pub mod report;
pub mod serve;
pub mod session;
pub mod settings;
