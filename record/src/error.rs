//! The crate's one error type.

use std::path::{Path, PathBuf};

/// What can go wrong with a recording. Every error names the file.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file could not be opened, read or written.
    #[error("{}: {source}", file.display())]
    Io {
        /// The recording.
        file: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The MCAP layer refused the file or a write.
    #[error("{}: {detail}", file.display())]
    Mcap {
        /// The recording.
        file: PathBuf,
        /// What the mcap crate said, with its causes.
        detail: String,
        /// The mcap crate's error.
        source: mcap::McapError,
    },
    /// The file is MCAP but not what rigview records: a field, message or
    /// record is missing or wrong.
    #[error("{}: {what}", file.display())]
    Format {
        /// The recording.
        file: PathBuf,
        /// What was expected and what was found.
        what: String,
    },
    /// A frame set or option the recorder cannot record.
    #[error("{}: {what}", file.display())]
    Unsupported {
        /// The recording.
        file: PathBuf,
        /// What is not supported.
        what: String,
    },
    /// The recording stopped earlier (disk full, write error, reserve
    /// reached) and takes nothing more.
    #[error("{}: the recording has stopped: {reason}", file.display())]
    Stopped {
        /// The recording.
        file: PathBuf,
        /// Why it stopped.
        reason: String,
    },
    /// The recorder's thread could not be started.
    #[error("{}: cannot start the recorder's thread: {reason}", file.display())]
    Thread {
        /// The recording.
        file: PathBuf,
        /// What the system said.
        reason: String,
    },
}

impl RecordError {
    pub(crate) fn io(file: &Path, source: std::io::Error) -> Self {
        Self::Io {
            file: file.to_owned(),
            source,
        }
    }

    pub(crate) fn mcap(file: &Path, source: mcap::McapError) -> Self {
        let mut detail = source.to_string();
        let mut cause = std::error::Error::source(&source);
        while let Some(c) = cause {
            detail = format!("{detail}: {c}");
            cause = c.source();
        }
        Self::Mcap {
            file: file.to_owned(),
            detail,
            source,
        }
    }

    pub(crate) fn format(file: &Path, what: impl Into<String>) -> Self {
        Self::Format {
            file: file.to_owned(),
            what: what.into(),
        }
    }
}

/// The crate's result.
pub type Result<T, E = RecordError> = std::result::Result<T, E>;
