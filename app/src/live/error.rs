//! The errors of live capture: [`LiveError`] when capture starts, and
//! [`CameraError`] for what one camera did not do.

/// What can go wrong when live capture starts.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// A capture setting is out of range.
    #[error("capture setting `{field}` = {value}: expected {expected}")]
    Config {
        /// The setting.
        field: &'static str,
        /// What is valid.
        expected: &'static str,
        /// What was given.
        value: String,
    },
    /// The rig names no cameras.
    #[error("the rig has no cameras")]
    NoCameras,
    /// A camera of the rig file has no device id.
    #[error("camera \"{camera}\" has no device in the rig file: add `device: {{genicam: VENDOR-SERIAL}}` or `device: {{ip: ADDRESS}}` to it")]
    NoDevice {
        /// The camera's name.
        camera: String,
    },
    /// A camera could not be opened or configured.
    #[cfg(feature = "aravis")]
    #[error("cannot start camera {0}")]
    Camera(#[source] CameraError),
    /// Some cameras did not get through their start-up in time.
    #[error("cannot start the cameras: timed out waiting for {}", .cameras.join(", "))]
    OpenTimeout {
        /// The cameras still starting.
        cameras: Vec<String>,
    },
    /// Every camera's thread ended before the cameras were ready.
    #[error("cannot start the cameras: their threads ended")]
    ThreadsEnded,
    /// A thread could not be started.
    #[error("cannot start a camera thread: {0}")]
    Thread(#[source] std::io::Error),
    /// This build has no Aravis.
    #[error(
        "this build of rigview has no camera support (it was built without the `aravis` feature)"
    )]
    NoAravis,
}

/// What one camera did not do: each names the camera and the GenICam
/// feature or command, or what was expected of it.
#[cfg(feature = "aravis")]
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The device could not be found or opened.
    #[error("{camera} ({device}): cannot open the device: {source}")]
    Open {
        /// The camera's name in the rig.
        camera: String,
        /// How it was to be reached.
        device: String,
        /// Aravis's error.
        source: aravis::glib::Error,
    },
    /// A feature could not be written.
    #[error("{camera}: cannot set {feature} to {value}: {source}")]
    Set {
        /// The camera's name in the rig.
        camera: String,
        /// The GenICam feature.
        feature: &'static str,
        /// The value written.
        value: String,
        /// Aravis's error.
        source: aravis::glib::Error,
    },
    /// A feature could not be read.
    #[error("{camera}: cannot read {feature}: {source}")]
    Read {
        /// The camera's name in the rig.
        camera: String,
        /// The GenICam feature.
        feature: &'static str,
        /// Aravis's error.
        source: aravis::glib::Error,
    },
    /// A command failed (starting acquisition, a software trigger, creating
    /// the stream).
    #[error("{camera}: {command} failed: {source}")]
    Command {
        /// The camera's name in the rig.
        camera: String,
        /// The GenICam command or Aravis call.
        command: &'static str,
        /// Aravis's error.
        source: aravis::glib::Error,
    },
    /// The camera reports something rigview cannot work with.
    #[error("{camera}: {feature}: expected {expected}, found {found}")]
    Unexpected {
        /// The camera's name in the rig.
        camera: String,
        /// The feature or property.
        feature: &'static str,
        /// What rigview needs.
        expected: String,
        /// What the camera has.
        found: String,
    },
    /// The camera stopped answering its control channel.
    #[error("{camera}: the camera stopped answering (control lost)")]
    ControlLost {
        /// The camera's name in the rig.
        camera: String,
    },
    /// No frame arrived for too long (software trigger or free run).
    #[error("{camera}: no frame for {seconds:.1} s")]
    Silent {
        /// The camera's name in the rig.
        camera: String,
        /// Seconds since the last frame.
        seconds: f64,
    },
    /// The camera's thread panicked.
    #[error("{camera}: its thread failed; restart rigview to bring it back")]
    Panicked {
        /// The camera's name in the rig.
        camera: String,
    },
}

#[cfg(feature = "aravis")]
/// Errors of one camera's features, naming the camera.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Named<'a>(pub &'a str);

impl Named<'_> {
    pub fn set(
        self,
        feature: &'static str,
        value: impl std::fmt::Display,
    ) -> impl FnOnce(aravis::glib::Error) -> CameraError {
        let (camera, value) = (self.0.to_owned(), value.to_string());
        move |source| CameraError::Set {
            camera,
            feature,
            value,
            source,
        }
    }

    pub fn read(self, feature: &'static str) -> impl FnOnce(aravis::glib::Error) -> CameraError {
        let camera = self.0.to_owned();
        move |source| CameraError::Read {
            camera,
            feature,
            source,
        }
    }

    pub fn command(self, command: &'static str) -> impl FnOnce(aravis::glib::Error) -> CameraError {
        let camera = self.0.to_owned();
        move |source| CameraError::Command {
            camera,
            command,
            source,
        }
    }
}
