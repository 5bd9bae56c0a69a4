//! [`LiveSource`]: the rig's cameras through Aravis, as a [`FrameSource`].

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rigview_calib::{DeviceId, Rig};
use rigview_core::exposure::ExposureSetting;
use rigview_core::source::{
    check_command, CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
    StreamState,
};

use super::assemble::{Assembler, SetCounters};
use super::clock::host_now_ns;
use super::config::{CaptureConfig, TriggerMode};
use super::device::DeviceSpec;
use super::error::{CameraError, LiveError};
use super::health::{CameraStatus, HealthCell};
use super::trigger::Schedule;
use super::worker::{CameraCommand, Event, Worker};

/// One camera to open.
#[derive(Clone, Debug)]
pub struct CameraSpec {
    /// Its name in the rig.
    pub name: String,
    /// How to reach it.
    pub device: DeviceSpec,
}

impl CameraSpec {
    /// The cameras of a rig file, by their device ids (GenICam id or IP
    /// address); a camera without one is an error that names it.
    pub fn from_rig(rig: &Rig) -> Result<Vec<CameraSpec>, LiveError> {
        rig.cameras
            .iter()
            .map(|c| {
                let device = match &c.device {
                    Some(DeviceId::GenICam(id)) => DeviceSpec::Id(id.clone()),
                    Some(DeviceId::Ip(ip)) => DeviceSpec::Id(ip.to_string()),
                    None => {
                        return Err(LiveError::NoDevice {
                            camera: c.name.clone(),
                        })
                    }
                };
                Ok(CameraSpec {
                    name: c.name.clone(),
                    device,
                })
            })
            .collect()
    }
}

/// Everything the source knows about the rig right now.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveStatus {
    /// Per camera, in rig order.
    pub cameras: Vec<CameraStatus>,
    /// The assembled sets.
    pub sets: SetCounters,
}

struct Handle {
    thread: Option<JoinHandle<()>>,
    commands: Sender<CameraCommand>,
    health: HealthCell,
}

/// Live frame sets from the rig's cameras.
///
/// Each camera runs in its own thread (opened one after another behind one
/// global lock); frames are matched into sets by arrival time; a camera that
/// stops answering is marked lost while the others go on, and rejoins when
/// it comes back. What happens (cameras opened, lost, rejoined, their own
/// auto-exposure switched) is reported as [`tracing`] events.
pub struct LiveSource {
    names: Vec<String>,
    infos: Vec<CameraInfo>,
    start: Vec<ExposureSetting>,
    handles: Vec<Handle>,
    events: Receiver<Event>,
    assembler: Assembler,
    states: Vec<StreamState>,
    stop: Arc<AtomicBool>,
    config: CaptureConfig,
    started_ns: u64,
}

impl std::fmt::Debug for LiveSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveSource")
            .field("cameras", &self.infos)
            .field("states", &self.states)
            .finish_non_exhaustive()
    }
}

impl LiveSource {
    /// Opens and configures every camera, runs their start-up
    /// auto-exposure, and starts streaming. Fails, naming the camera, if one
    /// cannot be opened within `config.open_timeout`.
    pub fn open(cameras: Vec<CameraSpec>, config: CaptureConfig) -> Result<Self, LiveError> {
        config.validate()?;
        if cameras.is_empty() {
            return Err(LiveError::NoCameras);
        }
        let schedule = match config.trigger {
            TriggerMode::Software { .. } => config.trigger.period().map(Schedule::starting_now),
            _ => None,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, events) = mpsc::channel();
        let mut handles = Vec::with_capacity(cameras.len());
        for (index, spec) in cameras.iter().enumerate() {
            let (ctx, crx) = mpsc::channel();
            let health = HealthCell::new(&spec.name, &spec.device.describe());
            let worker = Worker {
                index,
                name: spec.name.clone(),
                spec: spec.device.clone(),
                config: config.clone(),
                schedule,
                events: tx.clone(),
                commands: crx,
                health: health.clone(),
                stop: stop.clone(),
            };
            let (events, cell, name) = (tx.clone(), health.clone(), spec.name.clone());
            let thread = std::thread::Builder::new()
                .name(format!("camera {}", spec.name))
                .spawn(move || {
                    // A panic in Aravis's bindings ends this camera only.
                    if catch_unwind(AssertUnwindSafe(|| worker.run())).is_err() {
                        let failed = || CameraError::Panicked {
                            camera: name.clone(),
                        };
                        cell.set_state(StreamState::Lost);
                        cell.error(failed().to_string());
                        // (While starting, the first ends the start; later,
                        // the second marks the camera lost.)
                        let _ = events.send(Event::OpenFailed(failed()));
                        let _ = events.send(Event::Lost {
                            camera: index,
                            error: failed(),
                        });
                    }
                })
                .map_err(LiveError::Thread)?;
            handles.push(Handle {
                thread: Some(thread),
                commands: ctx,
                health,
            });
        }
        drop(tx);
        let n = cameras.len();
        let mut source = LiveSource {
            names: cameras.iter().map(|c| c.name.clone()).collect(),
            infos: Vec::new(),
            start: Vec::new(),
            handles,
            events,
            assembler: Assembler::new(n, nanos(config.sync_tolerance), nanos(config.set_timeout)),
            states: vec![StreamState::Reconnecting; n],
            stop,
            config: config.clone(),
            started_ns: u64::MAX,
        };
        let mut infos: Vec<Option<(CameraInfo, ExposureSetting)>> = vec![None; n];
        // Opening is one at a time; each camera may take the whole open
        // timeout, then its start-up settling.
        let deadline = Instant::now()
            + config.open_timeout * u32::try_from(n).unwrap_or(u32::MAX)
            + config.auto_settle
            + Duration::from_secs(10);
        while infos.iter().any(Option::is_none) {
            let left = deadline.saturating_duration_since(Instant::now());
            match source.events.recv_timeout(left) {
                Ok(Event::Ready {
                    camera,
                    info,
                    setting,
                }) => {
                    tracing::info!(
                        "{}: open, {}×{} {}, exposure {:.0}–{:.0} µs, gain {:.1}–{:.1} dB; starting at {:.0} µs, {:.2} dB",
                        info.name,
                        info.width,
                        info.height,
                        info.format.genicam_name(),
                        info.range.shutter_min_us,
                        info.range.shutter_max_us,
                        info.range.gain_min_db,
                        info.range.gain_max_db,
                        setting.shutter_us,
                        setting.gain_db
                    );
                    if let Some(p) = info.tone_curve.as_ref().and_then(|c| c.nearest_power()) {
                        tracing::info!(
                            "{}: gamma correction or lookup table on: frames read through a tone curve of {p:.2}",
                            info.name
                        );
                    }
                    if let Some(slot) = infos.get_mut(camera) {
                        *slot = Some((info, setting));
                    }
                    if let Some(s) = source.states.get_mut(camera) {
                        *s = StreamState::Streaming;
                    }
                }
                Ok(Event::OpenFailed(error)) => return Err(LiveError::Camera(error)),
                Ok(Event::Frame(_)) => {}
                Ok(e) => source.handle(e),
                Err(RecvTimeoutError::Timeout) => {
                    let cameras = infos
                        .iter()
                        .zip(&cameras)
                        .filter(|(i, _)| i.is_none())
                        .map(|(_, c)| c.name.clone())
                        .collect();
                    return Err(LiveError::OpenTimeout { cameras });
                }
                Err(RecvTimeoutError::Disconnected) => return Err(LiveError::ThreadsEnded),
            }
        }
        for (info, setting) in infos.into_iter().flatten() {
            source.infos.push(info);
            source.start.push(setting);
        }
        // Frames of earlier triggers may have been dropped for some cameras
        // while others were still starting: sets begin after this point.
        source.started_ns = host_now_ns();
        Ok(source)
    }

    /// Each camera's setting when rigview took over (after its own
    /// auto-exposure settled).
    pub fn start_settings(&self) -> &[ExposureSetting] {
        &self.start
    }

    /// The capture configuration.
    pub fn config(&self) -> &CaptureConfig {
        &self.config
    }

    /// Health, settings and set counters.
    pub fn status(&self) -> LiveStatus {
        LiveStatus {
            cameras: self.handles.iter().map(|h| h.health.snapshot()).collect(),
            sets: self.assembler.counters().clone(),
        }
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Frame(a) => {
                let c = a.frame.meta.camera;
                if self.states.get(c) == Some(&StreamState::Streaming)
                    && a.host_ns >= self.started_ns
                {
                    self.assembler.push(a);
                }
            }
            Event::Lost { camera, error } => {
                if let Some(s) = self.states.get_mut(camera) {
                    *s = StreamState::Lost;
                }
                self.assembler.drop_camera(camera);
                tracing::warn!("{error} (stream lost)");
            }
            Event::Rejoined { camera, device } => {
                if let Some(s) = self.states.get_mut(camera) {
                    *s = StreamState::Streaming;
                }
                self.assembler.restart_ids(camera);
                let name = self.name(camera);
                tracing::info!("{name}: streaming: rejoined ({device})");
            }
            Event::Note { camera, message } => {
                let name = self.name(camera);
                tracing::info!("{name}: {message}");
            }
            Event::Ready { .. } | Event::OpenFailed(_) => {}
        }
    }

    /// Camera `camera`'s name in messages.
    fn name(&self, camera: usize) -> String {
        self.names
            .get(camera)
            .map_or_else(|| format!("camera {camera}"), Clone::clone)
    }

    fn active(&self) -> Vec<bool> {
        self.states
            .iter()
            .map(|s| *s == StreamState::Streaming)
            .collect()
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

impl FrameSource for LiveSource {
    fn cameras(&self) -> &[CameraInfo] {
        &self.infos
    }

    fn next_set(&mut self, timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        let deadline = Instant::now() + timeout;
        loop {
            while let Ok(e) = self.events.try_recv() {
                self.handle(e);
            }
            let active = self.active();
            if let Some(set) = self.assembler.pop(host_now_ns(), &active) {
                return Ok(Some(set));
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            match self.events.recv_timeout(left.min(Duration::from_millis(5))) {
                Ok(e) => self.handle(e),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(SourceError::Failed("every camera thread has ended".into()))
                }
            }
        }
    }

    fn apply(&mut self, commands: &[ExposureCommand]) -> Result<(), SourceError> {
        for c in commands {
            check_command(c, self.handles.len())?;
            if let Some(h) = self.handles.get(c.camera) {
                // A camera whose thread ended is reported by its health.
                let _ = h.commands.send(CameraCommand::Set(c.setting));
            }
        }
        Ok(())
    }

    fn set_counters(&self) -> Option<SetCounters> {
        Some(self.assembler.counters().clone())
    }

    fn has_camera_auto(&self) -> bool {
        true
    }

    fn set_camera_auto(&mut self, on: bool) -> Result<(), SourceError> {
        // Each camera reports (in the messages) whether it could.
        for h in &self.handles {
            let _ = h.commands.send(CameraCommand::Auto(on));
        }
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.handles
            .iter()
            .map(|h| h.health.snapshot().health)
            .collect()
    }
}

impl Drop for LiveSource {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for h in &mut self.handles {
            if let Some(t) = h.thread.take() {
                let _ = t.join();
            }
        }
    }
}
