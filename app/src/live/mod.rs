//! Live capture from GenICam cameras through Aravis.
//!
//! | part | what it does |
//! | --- | --- |
//! | [`config`] | what is configured on each camera (pixel format, region, trigger, GigE packet size, inter-packet delay, socket buffer) and how capture runs (start-up settling, sync tolerance, loss and reconnection times) |
//! | `camera` | one thread per camera: open behind one global lock, configure, the start-up auto-exposure (Algorithm 1), software triggers, exposure commands within the camera's ranges, stream counters, loss and reconnection with back-off |
//! | [`tracker`] | which setting each frame was taken with when the camera has no chunk data: monotonic frame ids and a command history keyed by the first frame that shows each command |
//! | [`assemble`] | frame sets: one frame per camera and trigger, matched by arrival time within a tolerance; incomplete sets are counted |
//! | [`health`] | per-camera stream health (state, fps, completed/failed/underrun buffers, missing/resent packets) |
//! | `LiveSource` | all of it as a [`rigview_core::source::FrameSource`] |
//! | [`fake`] | what Aravis's in-process fake cameras show: the simulated rig ([`rigview_core::sim`]), each frame rendered at the fake camera's exposure time and gain, with the noise of its frame id and the light of its timestamp |
//! | [`cmd`] | `rigview live`: capture and exposure control, headless, with a status line per second (`--fake`: on fake cameras showing a simulation) |
//!
//! Everything that needs Aravis is behind the `aravis` feature (on by
//! default).

pub mod assemble;
#[cfg(feature = "aravis")]
mod camera;
pub mod cmd;
pub mod config;
pub mod fake;
#[cfg(feature = "aravis")]
pub mod ffi;
pub mod health;
#[cfg(feature = "aravis")]
mod source;
pub mod tracker;

#[cfg(feature = "aravis")]
pub use camera::DeviceSpec;
pub use config::{CaptureConfig, Region, TriggerMode};
pub use health::CameraStatus;
#[cfg(feature = "aravis")]
pub use source::{CameraSpec, LiveSource, LiveStatus};

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
    #[error("cannot start camera {0}")]
    Open(String),
    /// A thread could not be started.
    #[error("cannot start a camera thread: {0}")]
    Thread(String),
    /// This build has no Aravis.
    #[error(
        "this build of rigview has no camera support (it was built without the `aravis` feature)"
    )]
    NoAravis,
}
