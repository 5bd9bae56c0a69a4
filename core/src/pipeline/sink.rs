//! A consumer of every set the processing thread takes (a recorder): it
//! gets the set and, for a processed set, its telemetry row. It must not
//! block: it runs on the processing thread.

use super::{ProcessingSettings, TelemetryRow};
use crate::source::FrameSet;

/// What processing made of a set, for a [`SetSink`].
#[derive(Clone, Copy, Debug)]
pub struct Processed<'a> {
    /// The set's telemetry row.
    pub row: &'a TelemetryRow,
    /// The settings it was processed with.
    pub settings: &'a ProcessingSettings,
    /// The overlaps' names, in the order of `row.log2_r`.
    pub pair_names: &'a [String],
}

/// Takes every set the processing thread takes, in order, with what
/// processing made of it (`None`: the set was incomplete and not
/// processed). Implementations hand the set on without waiting (the frames
/// are shared, so a clone of the set copies no pixels).
pub trait SetSink: Send + Sync {
    /// One set.
    fn offer(&self, set: &FrameSet, processed: Option<Processed<'_>>);
}
