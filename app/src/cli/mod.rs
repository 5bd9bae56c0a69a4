//! The command line of `rigview`: the arguments of each subcommand (one
//! file each, named as the command and as the service in `commands/` it
//! calls) and how they map to the library's plain options; the options
//! several commands share are in [`options`]. With no subcommand, the
//! desktop app on the simulated rig. Nothing below the command line takes
//! a clap type.

pub mod calib;
pub mod demo;
pub mod eval;
pub mod live;
pub mod options;
pub mod panorama;
pub mod record;
pub mod recording;
pub mod run;
pub mod surround;

use clap::{Parser, Subcommand};

pub use options::{ControlArgs, ProcessingArgs, RecordingArgs, Switch, ViewArgs};

/// rigview: capture, exposure control and surround view for rigs of
/// synchronised cameras.
#[derive(Debug, Parser)]
#[command(name = "rigview", version, about, long_about = None)]
pub struct Cli {
    /// The subcommand (none: the window on the simulated rig).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Window options (with no subcommand).
    #[command(flatten)]
    pub view: ViewArgs,
    /// More messages on stderr: -v what rigview reports, -vv its details
    /// (RUST_LOG, if set, chooses instead).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// The pipeline on a chosen source: in the window, or headless with
    /// views, telemetry and a plot written to a folder.
    Run(run::RunArgs),
    /// Closed-loop exposure control on the simulated four-camera fisheye rig,
    /// printed frame by frame.
    Demo(demo::DemoArgs),
    /// Calibration: show, convert, and make intrinsics and ground extrinsics.
    Calib(calib::CalibArgs),
    /// Compose still images of a calibrated rig into a bird's-eye view.
    Surround(surround::SurroundArgs),
    /// Compose still images of a calibrated rig into a cylindrical
    /// panorama, with feature matches and brightness ratios per overlap.
    Panorama(panorama::PanoramaArgs),
    /// The desktop app on the rig's GenICam cameras (`--headless`: a status
    /// block per second on the terminal instead).
    Live(live::LiveArgs),
    /// Capture into a recording (MCAP) without processing.
    Record(record::RecordArgs),
    /// Look at or repair a recording.
    Recording(recording::RecordingCmd),
    /// The paper's experiments on the simulated rig: figures, their data
    /// and a report, written to a folder.
    Eval(eval::EvalArgs),
}
