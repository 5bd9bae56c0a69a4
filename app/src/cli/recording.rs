//! `rigview recording info|repair`: what a recording holds, and one that
//! was not closed rewritten with its indexes.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, Subcommand};

use crate::commands::recording;

/// `rigview recording`.
#[derive(Clone, Debug, Args)]
pub struct RecordingCmd {
    /// What to do.
    #[command(subcommand)]
    pub action: RecordingAction,
}

/// What `rigview recording` does.
#[derive(Clone, Debug, Subcommand)]
pub enum RecordingAction {
    /// Duration, sets, topics and drops of a recording.
    Info {
        /// The recording.
        file: PathBuf,
    },
    /// Rewrites a recording that was not closed (killed, disk full) with
    /// its indexes, keeping every complete set.
    Repair {
        /// The recording to repair.
        input: PathBuf,
        /// The repaired copy.
        output: PathBuf,
    },
}

/// Runs `rigview recording`.
pub fn run(cmd: &RecordingCmd, out: &mut dyn std::io::Write) -> Result<()> {
    let text = match &cmd.action {
        RecordingAction::Info { file } => recording::info(file)?,
        RecordingAction::Repair { input, output } => recording::repair(input, output)?,
    };
    writeln!(out, "{}", text.trim_end())?;
    Ok(())
}
