//! Live capture from GenICam cameras through Aravis.
//!
//! | part | what it does |
//! | --- | --- |
//! | [`config`] | what is configured on each camera (pixel format, region, trigger, GigE packet size, inter-packet delay, socket buffer) and how capture runs (start-up settling, sync tolerance, loss and reconnection times) |
//! | `device` | opening a camera behind one global lock and configuring its features (pixel format, region, GigE Vision packets, chunk data, the stream's buffers); exposure time and gain within the camera's ranges, their auto modes, stream counters |
//! | `trigger` | how a camera is triggered (hardware line, software, free run), when the software triggers fire, and which tick an arriving frame answers |
//! | `worker` | one acquisition thread per camera: the start-up auto-exposure (Algorithm 1), the stream's buffers turned into frames with the setting they were taken with, exposure commands, loss and reconnection with back-off |
//! | [`tracker`] | which setting each frame was taken with when the camera has no chunk data: monotonic frame ids and a command history keyed by the first frame that shows each command |
//! | [`assemble`] | frame sets: one frame per camera and trigger, matched by arrival time within a tolerance; incomplete sets are counted |
//! | [`health`] | per-camera stream health (state, fps, completed/failed/underrun buffers, missing/resent packets) |
//! | `LiveSource` | all of it as a [`rigview_core::source::FrameSource`] |
//! | [`fake`] | what Aravis's in-process fake cameras show: the simulated rig ([`rigview_core::sim`]), each frame rendered at the fake camera's exposure time and gain, with the noise of its frame id and the light of its timestamp; and the fake cameras' wiring (their fill callback and region) |
//! | `error` | [`LiveError`] when capture starts, [`CameraError`] naming the camera and the feature |
//! | `open` | which cameras a live source opens ([`LiveSpec`]: a rig file's, or fake cameras showing a simulated rig) and opening them |
//! | `clock` | the host's wall clock that frames are stamped with |
//!
//! Everything that needs Aravis is behind the `aravis` feature (on by
//! default).

pub mod assemble;
mod clock;
pub mod config;
#[cfg(feature = "aravis")]
mod device;
mod error;
pub mod fake;
#[cfg(feature = "aravis")]
pub mod ffi;
pub mod health;
mod open;
#[cfg(feature = "aravis")]
mod source;
pub mod tracker;
#[cfg(feature = "aravis")]
mod trigger;
#[cfg(feature = "aravis")]
mod worker;

pub use config::{CaptureConfig, Region, TriggerMode};
#[cfg(feature = "aravis")]
pub use device::DeviceSpec;
#[cfg(feature = "aravis")]
pub use error::CameraError;
pub use error::LiveError;
pub use fake::FakeRig;
pub use health::CameraStatus;
#[cfg(feature = "aravis")]
pub use open::{open, Opened};
pub use open::{LiveCameras, LiveSpec};
#[cfg(feature = "aravis")]
pub use source::{CameraSpec, LiveSource, LiveStatus};
