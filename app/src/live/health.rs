//! Per-camera stream health, shared between a camera's thread (which
//! updates it) and the source (which reads it).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use rigview_core::exposure::ExposureSetting;
use rigview_core::source::{StreamHealth, StreamState};

/// Counters that Aravis keeps per stream (they restart with each stream).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamCounts {
    /// Buffers that arrived whole.
    pub completed: u64,
    /// Buffers that arrived with an error.
    pub failed: u64,
    /// Frames dropped for want of a free buffer.
    pub underruns: u64,
    /// Packets that never arrived.
    pub missing_packets: u64,
    /// Packets that were sent again on request.
    pub resent_packets: u64,
}

impl std::ops::Add for StreamCounts {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            completed: self.completed + o.completed,
            failed: self.failed + o.failed,
            underruns: self.underruns + o.underruns,
            missing_packets: self.missing_packets + o.missing_packets,
            resent_packets: self.resent_packets + o.resent_packets,
        }
    }
}

/// What the source knows about one camera right now.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraStatus {
    /// The camera's name in the rig.
    pub name: String,
    /// The device it was opened as (GenICam id or address).
    pub device: String,
    /// Counters and state.
    pub health: StreamHealth,
    /// The setting last written to the camera.
    pub setting: Option<ExposureSetting>,
    /// Where the taken setting comes from: `chunk` data or command `latency`
    /// tracking.
    pub setting_source: &'static str,
    /// Times it came back after being lost.
    pub rejoins: u64,
    /// The last fault, if any.
    pub last_error: Option<String>,
}

#[derive(Debug)]
struct Inner {
    status: CameraStatus,
    base: StreamCounts,
    current: StreamCounts,
    arrivals: VecDeque<Instant>,
}

/// One camera's health, shared.
#[derive(Clone, Debug)]
pub struct HealthCell(Arc<Mutex<Inner>>);

const FPS_WINDOW: Duration = Duration::from_secs(2);

impl HealthCell {
    /// A cell for a camera that is being connected.
    pub fn new(name: &str, device: &str) -> Self {
        Self(Arc::new(Mutex::new(Inner {
            status: CameraStatus {
                name: name.to_owned(),
                device: device.to_owned(),
                health: StreamHealth {
                    state: StreamState::Reconnecting,
                    ..Default::default()
                },
                setting: None,
                setting_source: "latency",
                rejoins: 0,
                last_error: None,
            },
            base: StreamCounts::default(),
            current: StreamCounts::default(),
            arrivals: VecDeque::new(),
        })))
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A poisoned lock only means a thread died mid-update: the counters
        // are still worth showing.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A snapshot, with the frame rate over the last two seconds.
    pub fn snapshot(&self) -> CameraStatus {
        let mut g = self.lock();
        let now = Instant::now();
        while g
            .arrivals
            .front()
            .is_some_and(|t| now.duration_since(*t) > FPS_WINDOW)
        {
            g.arrivals.pop_front();
        }
        let fps = match (g.arrivals.front(), g.arrivals.len()) {
            (Some(first), n) if n >= 2 => {
                let span = now.duration_since(*first).as_secs_f64().max(1e-3);
                (n - 1) as f64 / span
            }
            _ => 0.0,
        };
        let counts = g.base + g.current;
        let mut s = g.status.clone();
        s.health.fps = fps;
        s.health.completed = counts.completed;
        s.health.failed = counts.failed;
        s.health.underruns = counts.underruns;
        s.health.missing_packets = counts.missing_packets;
        s.health.resent_packets = counts.resent_packets;
        s
    }

    /// A frame arrived.
    pub fn frame_arrived(&self) {
        let mut g = self.lock();
        g.arrivals.push_back(Instant::now());
        if g.arrivals.len() > 4096 {
            g.arrivals.pop_front();
        }
    }

    /// The current stream's counters.
    pub fn set_counts(&self, counts: StreamCounts) {
        self.lock().current = counts;
    }

    /// The stream ended: its counters become part of the totals.
    pub fn close_stream(&self) {
        let mut g = self.lock();
        g.base = g.base + g.current;
        g.current = StreamCounts::default();
        g.arrivals.clear();
    }

    /// The stream's state changed.
    pub fn set_state(&self, state: StreamState) {
        self.lock().status.health.state = state;
    }

    /// The camera rejoined.
    pub fn rejoined(&self) {
        let mut g = self.lock();
        g.status.rejoins += 1;
        g.status.health.state = StreamState::Streaming;
    }

    /// A fault to show.
    pub fn error(&self, message: String) {
        self.lock().status.last_error = Some(message);
    }

    /// The setting last written, and where taken settings come from.
    pub fn setting(&self, setting: ExposureSetting, source: &'static str) {
        let mut g = self.lock();
        g.status.setting = Some(setting);
        g.status.setting_source = source;
    }
}
