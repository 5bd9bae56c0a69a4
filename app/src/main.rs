//! The `rigview` command line. With no arguments, the desktop app on the
//! simulated rig.

mod calib_cmd;
mod demo;
mod surround_cmd;

use anyhow::Result;
use clap::{Parser, Subcommand};
use rigview::gui::{self, AppOptions};
use rigview::live;
use rigview::run_cmd::{self, RunArgs, ViewArgs};
use rigview::session::{SimSpec, SourceSpec};
use rigview_core::pipeline::PipelineOptions;

/// rigview: capture, exposure control and surround view for rigs of
/// synchronised cameras.
#[derive(Debug, Parser)]
#[command(name = "rigview", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Window options (with no subcommand).
    #[command(flatten)]
    view: ViewArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The pipeline on a chosen source: in the window, or headless with
    /// views, telemetry and a plot written to a folder.
    Run(RunArgs),
    /// Closed-loop exposure control on the simulated four-camera fisheye rig,
    /// printed frame by frame.
    Demo(demo::DemoArgs),
    /// Calibration: show, convert, and make intrinsics and ground extrinsics.
    Calib(calib_cmd::CalibArgs),
    /// Compose still images of a calibrated rig into a bird's-eye view.
    Surround(surround_cmd::SurroundArgs),
    /// The desktop app on the rig's GenICam cameras (`--headless`: a status
    /// block per second on the terminal instead).
    Live(live::cmd::LiveArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Calib(args)) => calib_cmd::run(&args, &mut std::io::stdout().lock()),
        Some(Command::Live(args)) if args.headless => {
            let settings = run_cmd::load_settings(&cli.view, &args.processing);
            live::cmd::run(&args, &settings.processing, &mut std::io::stdout().lock())
        }
        Some(Command::Live(args)) => {
            let processing = args.processing.clone();
            run_cmd::window(&cli.view, &processing, SourceSpec::Live(Box::new(args)))
        }
        Some(Command::Run(args)) => run_cmd::run(&args, &cli.view),
        Some(Command::Surround(args)) => surround_cmd::run(&args, &mut std::io::stdout().lock()),
        None => gui::run(AppOptions {
            source: SourceSpec::Sim(SimSpec::default()),
            settings: cli.view.settings.clone(),
            quit_after: run_cmd::quit_after(&cli.view)?,
            screenshot: run_cmd::screenshot(&cli.view)?,
            pipeline: PipelineOptions::default(),
        }),
    }
}
