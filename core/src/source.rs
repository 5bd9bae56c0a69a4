//! The frame-source interface: what every source of frame sets offers the
//! pipeline, whether it is the simulated rig, live cameras through Aravis, or
//! a replayed recording.
//!
//! A source produces one [`FrameSet`] per trigger, with one slot per camera,
//! and takes [`ExposureCommand`]s. Each [`Frame`] carries the metadata a
//! GenICam camera gives (see [`FrameMeta`]); in particular the setting the
//! frame was *taken* with, which the controller must use rather than the
//! last one commanded.
//!
//! A set is fed to the controller only when [`FrameSet::is_complete`]: every
//! camera delivered a frame and every frame arrived whole.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::exposure::{ExposureRange, ExposureSetting, ToneCurve};
use crate::image::{FrameView, PixelFormat};
use crate::{Error, Result};

/// How a frame arrived.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum FrameStatus {
    /// Every packet arrived.
    Complete,
    /// Packets were lost; the pixels are not to be trusted.
    MissingPackets {
        /// How many packets were missing.
        missing: u32,
    },
    /// The camera or the transport reported an error.
    Failed(String),
}

/// What a camera says about one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameMeta {
    /// The camera's index in the rig.
    pub camera: usize,
    /// Pixel layout.
    pub format: PixelFormat,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The setting the frame was exposed with (exposure time in µs, gain in
    /// dB), from chunk data or from tracking the command latency.
    pub taken: ExposureSetting,
    /// The camera's timestamp in ns.
    pub timestamp_ns: u64,
    /// The camera's frame id (block id).
    pub frame_id: u64,
    /// How it arrived.
    pub status: FrameStatus,
}

/// One camera's frame: metadata and tightly packed pixels (row stride =
/// width × bytes per pixel).
#[derive(Clone, Debug)]
pub struct Frame {
    /// What the camera says about it.
    pub meta: FrameMeta,
    /// The pixels, shared so that a frame can go to several consumers
    /// (controller, view, recorder) without copies.
    pub data: Arc<[u8]>,
}

impl FrameMeta {
    /// A complete frame's metadata with no time, id or exposure of note
    /// (for stills, tests and benchmarks; an exposure of 1 ms at 0 dB).
    pub fn still(camera: usize, format: PixelFormat, width: usize, height: usize) -> Self {
        Self {
            camera,
            format,
            width,
            height,
            taken: ExposureSetting {
                shutter_us: 1000.0,
                gain_db: 0.0,
            },
            timestamp_ns: 0,
            frame_id: 0,
            status: FrameStatus::Complete,
        }
    }
}

impl Frame {
    /// A frame whose `data` is checked against the size and format in
    /// `meta`.
    pub fn new(meta: FrameMeta, data: Arc<[u8]>) -> Result<Self> {
        FrameView::new(meta.format, meta.width, meta.height, &data)?;
        Ok(Self { meta, data })
    }

    /// A view of the pixels for metering.
    pub fn view(&self) -> Result<FrameView<'_>> {
        FrameView::new(
            self.meta.format,
            self.meta.width,
            self.meta.height,
            &self.data,
        )
    }

    /// Whether every packet of the frame arrived.
    pub fn is_complete(&self) -> bool {
        self.meta.status == FrameStatus::Complete
    }
}

/// The frames of one trigger, one slot per camera (`None`: the camera sent
/// nothing for this trigger).
#[derive(Clone, Debug)]
pub struct FrameSet {
    /// The source's running count of triggers.
    pub trigger: u64,
    /// When the trigger fired, in ns (the source's clock).
    pub timestamp_ns: u64,
    /// One slot per camera, in rig order.
    pub frames: Vec<Option<Frame>>,
}

impl FrameSet {
    /// Every camera delivered a whole frame: only such sets reach the
    /// controller.
    pub fn is_complete(&self) -> bool {
        self.frames
            .iter()
            .all(|f| f.as_ref().is_some_and(Frame::is_complete))
    }

    /// The largest difference between the cameras' timestamps, in ns (0 for
    /// fewer than two frames).
    pub fn timestamp_skew_ns(&self) -> u64 {
        let stamps = self.frames.iter().flatten().map(|f| f.meta.timestamp_ns);
        let (lo, hi) = stamps.fold((u64::MAX, 0), |(lo, hi), t| (lo.min(t), hi.max(t)));
        hi.saturating_sub(lo.min(hi))
    }
}

/// A new exposure setting for one camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExposureCommand {
    /// The camera's index in the rig.
    pub camera: usize,
    /// Exposure time (µs) and gain (dB), within the camera's ranges.
    pub setting: ExposureSetting,
}

/// What a source knows about one of its cameras.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// The camera's name in the rig (e.g. "front").
    pub name: String,
    /// Pixel layout of its frames.
    pub format: PixelFormat,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The exposure and gain ranges it reports.
    pub range: ExposureRange,
    /// The only exposure levels (`shutter · gain`) it takes, ascending, when
    /// it has a fixed set: a bracket sequence answers every command with
    /// its nearest level. `None`: any level within `range`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels: Option<Vec<f64>>,
    /// Its tone curve, when its frames are not linear and the source knows
    /// it (a bracket sequence's recovered 8-bit response): scale-and-clip
    /// simulates exposure changes through it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tone_curve: Option<ToneCurve>,
}

/// Waits until `due` if it comes within `timeout`: `true` once it has
/// come, `false` (after waiting `timeout`) while it is further away. For
/// sources that serve each set at its time on the wall clock.
pub fn wait_until(due: Instant, timeout: Duration) -> bool {
    let now = Instant::now();
    if due > now {
        let wait = due - now;
        if wait > timeout {
            std::thread::sleep(timeout);
            return false;
        }
        std::thread::sleep(wait);
    }
    true
}

/// The state of one camera's stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum StreamState {
    /// Frames are arriving.
    Streaming,
    /// The camera stopped answering.
    Lost,
    /// The source is trying to bring it back.
    Reconnecting,
}

/// Counters of a source that assembles frame sets from cameras that
/// deliver on their own (live cameras): how whole its sets were and how
/// far apart their frames.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SetCounters {
    /// Sets with a whole frame from every camera.
    pub complete: u64,
    /// Sets with a frame missing or not whole (never fed to the controller).
    pub incomplete: u64,
    /// Frames that were not whole (missing packets or failed), over all sets.
    pub broken_frames: u64,
    /// Slots left empty (a camera sent nothing for that trigger).
    pub missing_frames: u64,
    /// A frame arrived too late for its set and was dropped.
    pub late_frames: u64,
    /// Frame ids skipped between consecutive frames of a camera in sets
    /// (frames that were lost whole or dropped).
    pub id_gaps: u64,
    /// Timestamp skew of the last set with two or more frames, ns (camera
    /// clocks).
    pub last_skew_ns: u64,
    /// Largest skew of a complete set so far, ns.
    pub max_skew_ns: u64,
    /// Arrival spread (host clock) of the last set, ns.
    pub last_arrival_spread_ns: u64,
}

/// Counters of one camera's stream, since the source started.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StreamHealth {
    /// The stream's state.
    pub state: StreamState,
    /// Frames per second over the last second or so.
    pub fps: f64,
    /// Buffers that arrived whole.
    pub completed: u64,
    /// Buffers that arrived with an error or missing packets.
    pub failed: u64,
    /// Frames dropped for want of a free buffer.
    pub underruns: u64,
    /// Packets that never arrived.
    pub missing_packets: u64,
    /// Packets that were asked for again.
    pub resent_packets: u64,
}

/// A stream's frame rate over the last second or so, from the times its
/// frames were delivered ([`StreamHealth::fps`] of the sources that keep no
/// count of their own).
#[derive(Clone, Debug, Default)]
pub struct RateMeter {
    recent: VecDeque<Instant>,
}

impl RateMeter {
    /// Counts a frame delivered now; returns the rate (0 until a second
    /// frame).
    pub fn tick(&mut self) -> f64 {
        self.tick_at(Instant::now())
    }

    /// [`Self::tick`] at `now`.
    pub fn tick_at(&mut self, now: Instant) -> f64 {
        self.recent.push_back(now);
        while self
            .recent
            .front()
            .is_some_and(|t| now.saturating_duration_since(*t) > Duration::from_secs(1))
        {
            self.recent.pop_front();
        }
        match (self.recent.front(), self.recent.len()) {
            (Some(first), k) if k > 1 => {
                (k - 1) as f64
                    / now
                        .saturating_duration_since(*first)
                        .as_secs_f64()
                        .max(1e-9)
            }
            _ => 0.0,
        }
    }
}

impl Default for StreamHealth {
    fn default() -> Self {
        Self {
            state: StreamState::Streaming,
            fps: 0.0,
            completed: 0,
            failed: 0,
            underruns: 0,
            missing_packets: 0,
            resent_packets: 0,
        }
    }
}

impl Frame {
    /// What the controller needs to know of the frame: its id and the
    /// setting it was taken with.
    pub fn info(&self) -> crate::exposure::FrameInfo {
        crate::exposure::FrameInfo {
            frame_id: self.meta.frame_id,
            taken: self.meta.taken,
        }
    }
}

impl crate::exposure::RigController {
    /// One step on a complete set's `frames` (rig order), metered as
    /// `metered`, with the overlap patches `pairs`.
    pub fn step_frames(
        &mut self,
        frames: &[&Frame],
        metered: &[crate::exposure::Metered],
        pairs: &[crate::exposure::PairObservation],
    ) -> Result<crate::exposure::RigStep> {
        let inputs: Vec<_> = frames
            .iter()
            .zip(metered)
            .map(|(f, m)| crate::exposure::CameraInput {
                info: f.info(),
                metered: m,
            })
            .collect();
        self.step(&inputs, pairs)
    }
}

impl crate::exposure::RigStep {
    /// The step's commands, for [`FrameSource::apply`].
    pub fn commands(&self) -> Vec<ExposureCommand> {
        self.cameras
            .iter()
            .filter_map(|c| {
                c.command.map(|setting| ExposureCommand {
                    camera: c.camera,
                    setting,
                })
            })
            .collect()
    }
}

/// A source of frame sets: the simulated rig, live cameras or a replay.
///
/// Sources are driven from one thread; [`FrameSource::next_set`] blocks for
/// at most `timeout`.
pub trait FrameSource: Send {
    /// The cameras, in rig order.
    fn cameras(&self) -> &[CameraInfo];

    /// The next frame set, or `None` when none arrived within `timeout` or
    /// the source has ended (see [`FrameSource::is_finished`]).
    fn next_set(&mut self, timeout: Duration)
        -> std::result::Result<Option<FrameSet>, SourceError>;

    /// Applies exposure commands; they take effect after the source's
    /// actuation latency, and later frames report them in
    /// [`FrameMeta::taken`].
    fn apply(&mut self, commands: &[ExposureCommand]) -> std::result::Result<(), SourceError>;

    /// Each camera's stream health, in rig order.
    fn health(&self) -> Vec<StreamHealth>;

    /// How the source's sets were assembled, for a source that matches
    /// frames into sets (`None`: sets come whole, as from a simulator).
    fn set_counters(&self) -> Option<SetCounters> {
        None
    }

    /// Whether the source has no more sets to give (a replay at its end; a
    /// simulated rig with a frame budget). Live sources never finish.
    fn is_finished(&self) -> bool {
        false
    }

    /// Messages for the operator since the last call (cameras lost and
    /// back, what a camera could not do).
    fn take_messages(&mut self) -> Vec<String> {
        Vec::new()
    }

    /// Whether the cameras have their own auto-exposure that rigview can
    /// switch on ([`FrameSource::set_camera_auto`]).
    fn has_camera_auto(&self) -> bool {
        false
    }

    /// Switches the cameras' own auto-exposure on or off. Sources without
    /// one refuse.
    fn set_camera_auto(&mut self, on: bool) -> std::result::Result<(), SourceError> {
        let _ = on;
        Err(SourceError::Failed(
            "this source's cameras have no built-in auto-exposure".into(),
        ))
    }
}

impl<S: FrameSource + ?Sized> FrameSource for Box<S> {
    fn cameras(&self) -> &[CameraInfo] {
        (**self).cameras()
    }

    fn next_set(
        &mut self,
        timeout: Duration,
    ) -> std::result::Result<Option<FrameSet>, SourceError> {
        (**self).next_set(timeout)
    }

    fn apply(&mut self, commands: &[ExposureCommand]) -> std::result::Result<(), SourceError> {
        (**self).apply(commands)
    }

    fn health(&self) -> Vec<StreamHealth> {
        (**self).health()
    }

    fn set_counters(&self) -> Option<SetCounters> {
        (**self).set_counters()
    }

    fn is_finished(&self) -> bool {
        (**self).is_finished()
    }

    fn take_messages(&mut self) -> Vec<String> {
        (**self).take_messages()
    }

    fn has_camera_auto(&self) -> bool {
        (**self).has_camera_auto()
    }

    fn set_camera_auto(&mut self, on: bool) -> std::result::Result<(), SourceError> {
        (**self).set_camera_auto(on)
    }
}

/// A source that ends after a number of sets (complete or not): a bounded
/// run of a live or endless source.
#[derive(Debug)]
pub struct Budget<S> {
    inner: S,
    remaining: u64,
}

impl<S: FrameSource> Budget<S> {
    /// `inner`, ending after `sets` sets.
    pub fn new(inner: S, sets: u64) -> Self {
        Self {
            inner,
            remaining: sets,
        }
    }

    /// The source inside.
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

impl<S: FrameSource> FrameSource for Budget<S> {
    fn cameras(&self) -> &[CameraInfo] {
        self.inner.cameras()
    }

    fn next_set(
        &mut self,
        timeout: Duration,
    ) -> std::result::Result<Option<FrameSet>, SourceError> {
        if self.remaining == 0 {
            return Ok(None);
        }
        let set = self.inner.next_set(timeout)?;
        if set.is_some() {
            self.remaining -= 1;
        }
        Ok(set)
    }

    fn apply(&mut self, commands: &[ExposureCommand]) -> std::result::Result<(), SourceError> {
        self.inner.apply(commands)
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.inner.health()
    }

    fn set_counters(&self) -> Option<SetCounters> {
        self.inner.set_counters()
    }

    fn is_finished(&self) -> bool {
        self.remaining == 0 || self.inner.is_finished()
    }

    fn take_messages(&mut self) -> Vec<String> {
        self.inner.take_messages()
    }

    fn has_camera_auto(&self) -> bool {
        self.inner.has_camera_auto()
    }

    fn set_camera_auto(&mut self, on: bool) -> std::result::Result<(), SourceError> {
        self.inner.set_camera_auto(on)
    }
}

/// What can go wrong in a source.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// A camera index that the source does not have.
    #[error(transparent)]
    Core(#[from] Error),
    /// A camera failed; the others may go on.
    #[error("camera {camera} ({name}): {message}")]
    Camera {
        /// The camera's index in the rig.
        camera: usize,
        /// Its name.
        name: String,
        /// What happened.
        message: String,
    },
    /// The source as a whole failed.
    #[error("{0}")]
    Failed(String),
}

/// Checks that a command names a camera of a source with `count` cameras.
pub fn check_command(command: &ExposureCommand, count: usize) -> Result<()> {
    if command.camera >= count {
        return Err(Error::CameraIndex {
            index: command.camera,
            count,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_rate_counts_the_frames_of_the_last_second() {
        let mut r = super::RateMeter::default();
        let t0 = std::time::Instant::now();
        let at = |ms: u64| t0 + std::time::Duration::from_millis(ms);
        assert!(r.tick_at(at(0)).abs() < 1e-12);
        assert!((r.tick_at(at(50)) - 20.0).abs() < 1e-6);
        for k in 2..=40 {
            r.tick_at(at(50 * k));
        }
        // Only the last second's frames count: 20 intervals of 50 ms.
        assert!((r.tick_at(at(50 * 41)) - 20.0).abs() < 1e-6);
    }

    use super::*;

    fn frame(camera: usize, t: u64, status: FrameStatus) -> Frame {
        let meta = FrameMeta {
            camera,
            format: PixelFormat::Mono8,
            width: 4,
            height: 2,
            taken: ExposureSetting {
                shutter_us: 1000.0,
                gain_db: 0.0,
            },
            timestamp_ns: t,
            frame_id: 1,
            status,
        };
        Frame::new(meta, Arc::from(vec![0u8; 8])).unwrap()
    }

    #[test]
    fn a_set_is_complete_only_with_every_frame_whole() {
        let whole = FrameSet {
            trigger: 0,
            timestamp_ns: 0,
            frames: vec![
                Some(frame(0, 100, FrameStatus::Complete)),
                Some(frame(1, 350, FrameStatus::Complete)),
            ],
        };
        assert!(whole.is_complete());
        assert_eq!(whole.timestamp_skew_ns(), 250);
        let mut missing = whole.clone();
        missing.frames[1] = None;
        assert!(!missing.is_complete());
        let mut broken = whole.clone();
        broken.frames[0] = Some(frame(0, 100, FrameStatus::MissingPackets { missing: 3 }));
        assert!(!broken.is_complete());
    }

    #[test]
    fn a_frame_with_the_wrong_size_is_refused() {
        let meta = frame(0, 0, FrameStatus::Complete).meta;
        assert!(Frame::new(meta, Arc::from(vec![0u8; 7])).is_err());
        assert!(check_command(
            &ExposureCommand {
                camera: 4,
                setting: ExposureSetting {
                    shutter_us: 1.0,
                    gain_db: 0.0
                }
            },
            4
        )
        .is_err());
    }
}
