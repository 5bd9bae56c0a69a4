//! The error type of `rigview-core`.

/// Everything that can go wrong in `rigview-core`.
///
/// Each variant names the offending input and what was expected, so that an
/// application can show it to the user as it is.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An image has no pixels.
    #[error("{what}: the image is empty ({width}×{height})")]
    EmptyImage {
        /// Which image.
        what: &'static str,
        /// Its width in pixels.
        width: usize,
        /// Its height in pixels.
        height: usize,
    },
    /// A buffer does not hold what its declared size needs.
    #[error("{what}: expected {expected} bytes for {detail}, got {actual}")]
    BufferSize {
        /// Which buffer.
        what: &'static str,
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        actual: usize,
        /// The declared layout, e.g. "Mono8 1288×964, stride 1288".
        detail: String,
    },
    /// Two inputs that must agree in size do not.
    #[error("{what}: expected {expected_width}×{expected_height}, got {width}×{height}")]
    SizeMismatch {
        /// Which input.
        what: &'static str,
        /// The size it must have.
        expected_width: usize,
        /// The size it must have.
        expected_height: usize,
        /// The size it has.
        width: usize,
        /// The size it has.
        height: usize,
    },
    /// A parameter is out of its valid range (this includes NaN).
    #[error("parameter `{name}` = {value}: expected {expected}")]
    InvalidParameter {
        /// The parameter's name as it appears in settings.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What was expected, in words.
        expected: &'static str,
    },
    /// A value of a configuration or of an input is not what it must be.
    #[error("{what}: {field}: expected {expected}, found {found}")]
    Invalid {
        /// What holds the value: the configuration, view or step.
        what: String,
        /// The value's name (a field, a size, a count).
        field: String,
        /// What a valid value looks like.
        expected: String,
        /// What was found instead.
        found: String,
    },
    /// Something about one camera of a view is wrong.
    #[error("{view}: camera {camera} (\"{name}\"): {source}")]
    Camera {
        /// The view (surround view, panorama).
        view: &'static str,
        /// The camera's index in the rig.
        camera: usize,
        /// Its name.
        name: String,
        /// What is wrong.
        #[source]
        source: Box<Error>,
    },
    /// A rig, pose or lens could not be made or read.
    #[error("{what}: {source}")]
    Calibration {
        /// What was being made or read.
        what: String,
        /// What the calibration library said.
        #[source]
        source: Box<rigview_calib::CalibError>,
    },
    /// A description could not be written as YAML.
    #[error("{what}: {source}")]
    Yaml {
        /// What was being written.
        what: String,
        /// What the YAML writer said.
        #[source]
        source: serde_norway::Error,
    },
    /// A numerical solution has none, or left its bounds.
    #[error("{what}: {reason}")]
    Solver {
        /// What was being solved.
        what: &'static str,
        /// Why there is no solution.
        reason: String,
    },
    /// A camera index is not part of the rig.
    #[error("camera index {index} is out of range: the rig has {count} cameras")]
    CameraIndex {
        /// The index given.
        index: usize,
        /// How many cameras there are.
        count: usize,
    },
    /// A file (a simulation, scene or rig description) cannot be read or
    /// parsed; `detail` says where and why.
    #[error("{file}: {detail}")]
    File {
        /// The file (or the name of a built-in description).
        file: String,
        /// What is wrong, with the field and line where the parser knows them.
        detail: String,
    },
    /// A field of a description holds a value out of its range.
    #[error("{file}: field \"{field}\": expected {expected}, found {found}")]
    Field {
        /// The file (or the name of a built-in description).
        file: String,
        /// The field, with its path (`scene.obstacles[2].size_m[0]`).
        field: String,
        /// What a valid value looks like.
        expected: String,
        /// What was found instead.
        found: String,
    },
    /// A frame set that is not complete was given to processing, which
    /// takes complete sets only.
    #[error("frame set {trigger}: {complete} of {cameras} frames complete")]
    IncompleteSet {
        /// The set's trigger number.
        trigger: u64,
        /// Its complete frames.
        complete: usize,
        /// The cameras of the rig.
        cameras: usize,
    },
    /// One of the pipeline's threads could not be started.
    #[error("cannot start the pipeline's {thread} thread: {source}")]
    ThreadStart {
        /// Which thread.
        thread: &'static str,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// The pipeline's processing thread has stopped and takes no more
    /// changes.
    #[error("the pipeline's processing thread has stopped")]
    PipelineStopped,
}

impl Error {
    /// An [`Error::Invalid`].
    pub fn invalid(
        what: impl Into<String>,
        field: impl Into<String>,
        expected: impl Into<String>,
        found: impl std::fmt::Display,
    ) -> Self {
        Self::Invalid {
            what: what.into(),
            field: field.into(),
            expected: expected.into(),
            found: found.to_string(),
        }
    }

    /// An [`Error::Calibration`].
    pub fn calibration(what: impl Into<String>, source: rigview_calib::CalibError) -> Self {
        Self::Calibration {
            what: what.into(),
            source: Box::new(source),
        }
    }
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Checks that `value` is finite and inside `[lo, hi]`.
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    expected: &'static str,
) -> Result<f64> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(Error::InvalidParameter {
            name,
            value,
            expected,
        })
    }
}
