//! The `rigview` command line.
//!
//! Until the desktop app lands, `rigview` with no arguments runs the
//! headless closed-loop demo on the simulated rig (`rigview demo`).

mod calib_cmd;
mod demo;
mod surround_cmd;

use anyhow::Result;
use clap::{Parser, Subcommand};
use rigview::live;

/// rigview: capture, exposure control and surround view for rigs of
/// synchronised cameras.
#[derive(Debug, Parser)]
#[command(name = "rigview", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Closed-loop exposure control on the simulated four-camera fisheye rig,
    /// printed frame by frame (the default).
    Demo(demo::DemoArgs),
    /// Calibration: show, convert, and make intrinsics and ground extrinsics.
    Calib(calib_cmd::CalibArgs),
    /// Compose still images of a calibrated rig into a bird's-eye view.
    Surround(surround_cmd::SurroundArgs),
    /// Capture from the rig's GenICam cameras and control their exposure
    /// (headless until the desktop app lands).
    Live(live::cmd::LiveArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Calib(args)) => calib_cmd::run(&args, &mut std::io::stdout().lock()),
        Some(Command::Live(args)) => live::cmd::run(&args, &mut std::io::stdout().lock()),
        Some(Command::Surround(args)) => surround_cmd::run(&args, &mut std::io::stdout().lock()),
        None => demo::run(&demo::DemoArgs::default()),
    }
}
