//! Recordings of rigview's frame sets as MCAP files in the ROS 2 profile,
//! which Foxglove and `ros2 bag` open: writing ([`SetWriter`], and
//! [`Recorder`] on a thread of its own behind a bounded queue), reading
//! ([`SetStream`] without the index, [`IndexedRecording`] by it), replay as
//! a frame source ([`ReplaySource`]), [`repair`] and [`info`].
//!
//! The layout is in [`writer`]; the messages and their schemas in [`msgs`];
//! CDR in [`cdr`].

pub mod cdr;
mod error;
pub mod msgs;
pub mod reader;
pub mod recorder;
pub mod replay;
pub mod writer;

pub use error::{RecordError, Result};
pub use reader::{
    info, repair, IndexedRecording, RecordedSet, RecordingEnd, RecordingInfo, RecordingMeta,
    RepairReport, SetStream,
};
pub use recorder::{FreeSpace, Recorder, RecorderOptions, RecorderStats};
pub use replay::ReplaySource;
pub use writer::{Compression, RecordingSetup, SetWriter};
