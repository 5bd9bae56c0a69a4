//! The `rigview` command line (see [`rigview::cli`]). With no arguments,
//! the desktop app on the simulated rig.

use anyhow::Result;
use clap::Parser;
use rigview::cli::{self, Cli, Command, ProcessingArgs};
use rigview::session::{SimSpec, SourceSpec};

fn main() -> Result<()> {
    // Before any thread starts: buffers freed at the frame rate are reused
    // rather than faulted in again.
    rigview::memory::keep_freed_memory();
    match run() {
        // The reader of the output went away (`rigview … | head`): what it
        // wanted was written, and there is nothing to report.
        Err(e) if is_broken_pipe(&e) => Ok(()),
        r => r,
    }
}

/// Whether `e` comes from writing to a pipe whose reader has closed it.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn run() -> Result<()> {
    let cli = Cli::parse();
    rigview::logging::init(cli.verbose)?;
    let out = &mut std::io::stdout().lock();
    match &cli.command {
        None => cli.view.window(
            &ProcessingArgs::default(),
            SourceSpec::Sim(SimSpec::default()),
            None,
            None,
        ),
        Some(Command::Run(args)) => cli::run::run(args, &cli.view),
        Some(Command::Demo(args)) => cli::demo::run(args, out),
        Some(Command::Calib(args)) => cli::calib::run(args, out),
        Some(Command::Surround(args)) => cli::surround::run(args, out),
        Some(Command::Panorama(args)) => cli::panorama::run(args, out),
        Some(Command::Live(args)) => cli::live::run(args, &cli.view, out),
        Some(Command::Record(args)) => cli::record::run(args, out),
        Some(Command::Recording(args)) => cli::recording::run(args, out),
        Some(Command::Eval(args)) => cli::eval::run(args, out),
    }
}
