//! The one error type of `rigview-calib`.
//!
//! Every error about a file names the file; every error about a value names
//! the field and says what was expected and what was found, for example
//! `front.yaml: field "camera_matrix": expected a 3×3 matrix, found 2×3`.

use std::fmt;

/// What is wrong with one field of a calibration: which field, what was
/// expected and what was found. Carried by [`CalibError::Field`], which adds
/// the file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    /// The field, with its path for nested fields (`cameras[1].focal_px`).
    pub field: String,
    /// What a valid value looks like.
    pub expected: String,
    /// What the file holds instead.
    pub found: String,
}

impl FieldError {
    /// A field error.
    pub fn new(
        field: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> Self {
        Self {
            field: field.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }

    /// The same error with `prefix.` before the field name.
    #[must_use]
    pub fn within(mut self, prefix: &str) -> Self {
        if !prefix.is_empty() {
            self.field = format!("{prefix}.{}", self.field);
        }
        self
    }

    /// The same error reported under the name a file format gives the
    /// field (`camera_matrix` for `fx`), keeping the model's name in the
    /// expectation.
    #[must_use]
    pub fn renamed(self, field: impl Into<String>) -> Self {
        Self {
            expected: format!("{} ({})", self.expected, self.field),
            field: field.into(),
            found: self.found,
        }
    }

    /// Attaches the file the field was read from.
    pub fn in_file(self, file: impl Into<String>) -> CalibError {
        CalibError::Field {
            file: file.into(),
            error: self,
        }
    }
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "field \"{}\": expected {}, found {}",
            self.field, self.expected, self.found
        )
    }
}

/// Errors of `rigview-calib`.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    /// A file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A file cannot be parsed: a YAML or XML syntax error, a truncated file,
    /// bytes that are not text, or a value of the wrong type or shape where
    /// the parser itself checks it (the message then names the field).
    #[error("{file}: {detail}")]
    Parse {
        /// The file.
        file: String,
        /// What the parser said.
        detail: String,
    },
    /// A field that must be there is missing.
    #[error("{file}: missing field \"{field}\" (expected {expected})")]
    Missing {
        /// The file.
        file: String,
        /// The missing field.
        field: String,
        /// What it should hold.
        expected: String,
    },
    /// A field holds a value of the wrong shape, type or range.
    #[error("{file}: {error}")]
    Field {
        /// The file.
        file: String,
        /// The field and what is wrong with it.
        error: FieldError,
    },
    /// A camera or distortion model this crate does not implement.
    #[error(
        "{file}: field \"{field}\": unknown camera model \"{model}\" (supported: {supported})"
    )]
    UnknownModel {
        /// The file.
        file: String,
        /// The field that names the model.
        field: String,
        /// The model the file names.
        model: String,
        /// The models that are supported there.
        supported: String,
    },
    /// A rig file of a format version this build cannot read.
    #[error("{file}: field \"version\": expected rig format version {supported}, found {found}")]
    UnsupportedVersion {
        /// The file.
        file: String,
        /// The version the file declares.
        found: String,
        /// The versions this build reads.
        supported: String,
    },
    /// The calibration format of a file cannot be told from its name or
    /// contents, or is not one this crate reads or writes there.
    #[error("{file}: {detail}")]
    Format {
        /// The file.
        file: String,
        /// Why, and what would help.
        detail: String,
    },
    /// An image file could not be read or written.
    #[error("{file}: {source}")]
    Image {
        /// The file.
        file: String,
        /// What the image decoder said.
        source: image::ImageError,
    },
    /// A file of a format this build cannot read or write: its reader or
    /// writer needs a feature of `rigview-calib` that the build was made
    /// without.
    #[error(
        "{file}: {format} files need rigview-calib's `{feature}` feature, and this build has it off"
    )]
    NeedsFeature {
        /// The file.
        file: String,
        /// The format, in words.
        format: String,
        /// The feature.
        feature: &'static str,
    },
    /// OpenCV failed.
    #[cfg(feature = "opencv")]
    #[error("{context}: OpenCV: {source}")]
    OpenCv {
        /// What was being done.
        context: String,
        /// OpenCV's error.
        source: opencv::Error,
    },
    /// A calibration could not be computed from the data given (too few
    /// usable images, a pattern that is not seen, a pose that does not
    /// converge).
    #[error("{0}")]
    Calibration(String),
    /// An argument of a library call is out of range (an empty rig, a
    /// camera name that is not in the rig).
    #[error("{0}")]
    Argument(String),
}

/// Result with [`CalibError`].
pub type Result<T, E = CalibError> = std::result::Result<T, E>;

/// Wraps an OpenCV error with what was being done.
#[cfg(feature = "opencv")]
pub(crate) fn cv<T>(context: &str, r: opencv::Result<T>) -> Result<T> {
    r.map_err(|source| CalibError::OpenCv {
        context: context.to_owned(),
        source,
    })
}
