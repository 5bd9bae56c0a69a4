//! The commands that run once and end, each named as its file in `cli/`:
//! they take plain options (never clap's types) and write files and a
//! report.
//!
//! | module | command |
//! | --- | --- |
//! | [`run`] | `rigview run --headless`: a session without the window; views, telemetry, a plot and a summary written to a folder |
//! | [`live`] | `rigview live --headless`: live capture and exposure control with a status block per second |
//! | [`demo`] | `rigview demo`: the closed loop on the simulated rig, printed set by set |
//! | [`surround`] | `rigview surround`: still images composed into a bird's-eye view |
//! | [`panorama`] | `rigview panorama`: still images composed into a panorama, matched and refined |
//! | [`calib`] | `rigview calib`: show, convert, intrinsics, ground poses |
//! | [`record`] | `rigview record`: capture without processing, into a recording or a bracket sequence |
//! | [`recording`] | `rigview recording info|repair` |

pub mod calib;
pub mod demo;
pub mod live;
pub mod panorama;
pub mod record;
pub mod recording;
pub mod run;
pub mod surround;
