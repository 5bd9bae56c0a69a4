//! One camera's acquisition thread: it opens its [`Device`] (retrying until
//! the open time-out), runs the start-up auto-exposure, then the stream:
//! software triggers at the schedule's ticks, exposure commands, buffers
//! turned into frames with the setting they were taken with, stream
//! counters, and loss and reconnection with back-off.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use aravis::{Buffer, BufferStatus};
use rigview_core::exposure::ExposureSetting;
use rigview_core::source::{CameraInfo, Frame, FrameMeta, FrameStatus, StreamState};

use super::assemble::Arrived;
use super::config::{CaptureConfig, TriggerMode};
use super::device::{Device, DeviceSpec};
use super::error::CameraError;
use super::health::HealthCell;
use super::tracker::{IdUnwrapper, SettingTracker};
use super::trigger::{Outstanding, Schedule};

/// What a camera thread tells the source.
#[derive(Debug)]
pub(crate) enum Event {
    /// The camera is open and configured, its start-up is over.
    Ready {
        camera: usize,
        info: CameraInfo,
        setting: ExposureSetting,
    },
    /// It could not be opened in time (or its thread failed).
    OpenFailed(CameraError),
    /// A frame.
    Frame(Arrived),
    /// Its stream was lost.
    Lost { camera: usize, error: CameraError },
    /// It is streaming again after a loss (the device it was found as).
    Rejoined { camera: usize, device: String },
    /// Something worth telling the operator that changes no state.
    Note { camera: usize, message: String },
}

/// What the source asks of a camera's thread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum CameraCommand {
    /// Take this exposure setting.
    Set(ExposureSetting),
    /// Switch the camera's own auto-exposure (and auto-gain) on or off.
    Auto(bool),
}

/// Why an acquisition loop ended.
enum Ended {
    Stop,
    Lost(CameraError),
}

/// How an acquisition starts.
#[derive(Clone, Copy)]
enum Start {
    /// The first time: the camera's own auto-exposure settles first.
    First,
    /// After a reconnect: back to the setting it had.
    Rejoin(ExposureSetting),
}

/// A camera's thread.
pub(crate) struct Worker {
    pub index: usize,
    pub name: String,
    pub spec: DeviceSpec,
    pub config: CaptureConfig,
    pub schedule: Option<Schedule>,
    pub events: Sender<Event>,
    pub commands: Receiver<CameraCommand>,
    pub health: HealthCell,
    pub stop: Arc<AtomicBool>,
}

impl Worker {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Sleeps up to `d`, waking early on stop; false when stopped.
    fn nap(&self, d: Duration) -> bool {
        let end = Instant::now() + d;
        while Instant::now() < end {
            if self.stopped() {
                return false;
            }
            std::thread::sleep((end - Instant::now()).min(Duration::from_millis(10)));
        }
        !self.stopped()
    }

    fn send(&self, event: Event) {
        // The source has gone: the thread is about to be stopped.
        let _ = self.events.send(event);
    }

    fn note(&self, message: String) {
        self.send(Event::Note {
            camera: self.index,
            message,
        });
    }

    /// The thread's body: runs until stopped.
    pub fn run(self) {
        let deadline = Instant::now() + self.config.open_timeout;
        let mut device = loop {
            if self.stopped() {
                return;
            }
            match Device::open(&self.name, &self.spec, &self.config) {
                Ok(d) => break d,
                Err(e) if Instant::now() >= deadline => {
                    self.send(Event::OpenFailed(e));
                    return;
                }
                Err(_) => {
                    if !self.nap(Duration::from_millis(200)) {
                        return;
                    }
                }
            }
        };
        let mut start = Start::First;
        loop {
            let (ended, last) = self.acquire(&device, start);
            self.health.close_stream();
            let error = match ended {
                Ended::Stop => {
                    device.close();
                    return;
                }
                Ended::Lost(e) => e,
            };
            if matches!(start, Start::First) && last.is_none() {
                device.close();
                self.send(Event::OpenFailed(error));
                return;
            }
            self.health.set_state(StreamState::Lost);
            self.health.error(error.to_string());
            self.send(Event::Lost {
                camera: self.index,
                error,
            });
            device.abandon();
            let Some(d) = self.reconnect() else { return };
            device = d;
            start = Start::Rejoin(last.unwrap_or(ExposureSetting {
                shutter_us: device.info().range.shutter_min_us,
                gain_db: device.info().range.gain_min_db,
            }));
        }
    }

    fn reconnect(&self) -> Option<Device> {
        let mut wait = self.config.reconnect_initial;
        loop {
            if !self.nap(wait) {
                return None;
            }
            self.health.set_state(StreamState::Reconnecting);
            match Device::open(&self.name, &self.spec, &self.config) {
                Ok(d) => return Some(d),
                Err(e) => {
                    self.health.set_state(StreamState::Lost);
                    self.health.error(e.to_string());
                    wait = (wait * 2).min(self.config.reconnect_max);
                }
            }
        }
    }

    /// Runs one acquisition; returns why it ended and the setting the
    /// camera had last (`None` if it never got through its start-up).
    fn acquire(&self, device: &Device, start: Start) -> (Ended, Option<ExposureSetting>) {
        let mut current = None;
        let ended = match self.acquire_inner(device, start, &mut current) {
            Ok(e) => e,
            Err(e) => Ended::Lost(e),
        };
        (ended, current)
    }

    fn acquire_inner(
        &self,
        device: &Device,
        start: Start,
        current: &mut Option<ExposureSetting>,
    ) -> Result<Ended, CameraError> {
        let cfg = &self.config;
        let software = matches!(cfg.trigger, TriggerMode::Software { .. });
        let watch_silence = !matches!(cfg.trigger, TriggerMode::Hardware { .. });
        let period = cfg.trigger.period().unwrap_or(Duration::from_millis(100));
        let frame_timeout = period * 3 + Duration::from_millis(200);
        let mut settle_until = None;
        let mut tracker = SettingTracker::new(device.read_setting()?);
        match start {
            Start::First if !cfg.auto_settle.is_zero() && device.has_auto() => {
                device.set_auto(true)?;
                settle_until = Some(Instant::now() + cfg.auto_settle);
            }
            Start::First => {
                device.set_auto(false)?;
                let s = device.read_setting()?;
                self.ready(device, s, &mut tracker, current, true);
            }
            Start::Rejoin(s) => {
                device.set_auto(false)?;
                let s = device.apply(s)?;
                self.ready(device, s, &mut tracker, current, false);
            }
        }
        device.start()?;
        let mut next_tick = self.schedule.map(|s| s.next_after(Instant::now()));
        let mut outstanding = Outstanding::default();
        let mut last_frame_at = Instant::now();
        let mut last_id: Option<u64> = None;
        let mut ids = IdUnwrapper::default();
        let mut pending: Option<ExposureSetting> = None;
        let mut auto_request: Option<bool> = None;
        // The camera's own auto-exposure runs (asked for by the operator):
        // commands are ignored and the setting is read back instead.
        let mut camera_auto = false;
        let mut read_back_at = Instant::now();
        let mut counts_at = Instant::now();
        let mut missing_seen = 0u64;
        loop {
            if self.stopped() {
                return Ok(Ended::Stop);
            }
            if device.control_lost() {
                return Ok(Ended::Lost(CameraError::ControlLost {
                    camera: self.name.clone(),
                }));
            }
            loop {
                match self.commands.try_recv() {
                    Ok(CameraCommand::Set(s)) => pending = Some(s),
                    Ok(CameraCommand::Auto(on)) => auto_request = Some(on),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return Ok(Ended::Stop),
                }
            }
            let now = Instant::now();
            if settle_until.is_some_and(|t| now >= t) {
                settle_until = None;
                device.set_auto(false)?;
                let s = device.read_setting()?;
                self.ready(device, s, &mut tracker, current, true);
            }
            if let (Some(on), None) = (auto_request, settle_until) {
                auto_request = None;
                let first = last_id.map_or(0, |l| l + 1) + outstanding.len();
                if !device.has_auto() {
                    self.note(
                        "it has no ExposureAuto or GainAuto: its exposure stays as set".into(),
                    );
                } else if let Err(e) = device.set_auto(on) {
                    self.note(format!("its own auto-exposure cannot be switched: {e}"));
                } else {
                    camera_auto = on;
                    pending = None;
                    let s = device.read_setting()?;
                    tracker.commanded(first, s);
                    *current = Some(s);
                    self.health.setting(s, device.setting_source());
                    self.note(format!(
                        "its own auto-exposure is {}",
                        if on { "on" } else { "off" }
                    ));
                }
            }
            if camera_auto && read_back_at.elapsed() >= Duration::from_millis(100) {
                // Without chunk data the frames carry the setting read back
                // here, up to one frame late.
                read_back_at = Instant::now();
                let s = device.read_setting()?;
                if *current != Some(s) {
                    tracker.commanded(last_id.map_or(0, |l| l + 1), s);
                    *current = Some(s);
                    self.health.setting(s, device.setting_source());
                }
            }
            if settle_until.is_none() && !camera_auto {
                if let Some(s) = pending.take() {
                    let actual = device.apply(s)?;
                    // Frames of software triggers already sent keep the old
                    // setting; so do the camera's own latency frames.
                    let first = last_id.map_or(0, |l| l + 1)
                        + outstanding.len()
                        + u64::from(cfg.command_latency_frames);
                    tracker.commanded(first, actual);
                    *current = Some(actual);
                    self.health.setting(actual, device.setting_source());
                }
            }
            if let (true, Some((k, tick))) = (software, next_tick) {
                if now >= tick {
                    device.trigger()?;
                    outstanding.sent(k, now);
                    next_tick = self.schedule.map(|s| s.next_after(Instant::now()));
                }
            }
            outstanding.expire(now, frame_timeout);
            let wait = match (software, next_tick) {
                (true, Some((_, t))) => t.saturating_duration_since(Instant::now()),
                _ => Duration::from_millis(20),
            }
            .clamp(Duration::from_micros(200), Duration::from_millis(20));
            let wait_us = u64::try_from(wait.as_micros()).unwrap_or(20_000);
            if let Some(buffer) = device.pop(wait_us) {
                let counts = device.counts();
                let missing = counts.missing_packets.saturating_sub(missing_seen);
                missing_seen = counts.missing_packets;
                let mut arrived = self.frame(device, &buffer, &mut ids, &mut tracker, missing);
                device.push(buffer);
                let lost = last_id.map_or(0, |l| arrived.id.saturating_sub(l + 1));
                if let (Some(k), Some(s)) = (outstanding.arrived(lost), &self.schedule) {
                    arrived.host_ns = s.wall_ns(k);
                }
                last_frame_at = Instant::now();
                last_id = Some(arrived.id);
                self.health.frame_arrived();
                if settle_until.is_none() {
                    self.send(Event::Frame(arrived));
                }
            }
            if counts_at.elapsed() > Duration::from_millis(250) {
                self.health.set_counts(device.counts());
                counts_at = Instant::now();
            }
            if watch_silence && last_frame_at.elapsed() > cfg.lost_after {
                return Ok(Ended::Lost(CameraError::Silent {
                    camera: self.name.clone(),
                    seconds: last_frame_at.elapsed().as_secs_f64(),
                }));
            }
        }
    }

    fn ready(
        &self,
        device: &Device,
        setting: ExposureSetting,
        tracker: &mut SettingTracker,
        current: &mut Option<ExposureSetting>,
        first: bool,
    ) {
        *tracker = SettingTracker::new(setting);
        *current = Some(setting);
        self.health.setting(setting, device.setting_source());
        if first {
            self.health.set_state(StreamState::Streaming);
            self.send(Event::Ready {
                camera: self.index,
                info: device.info().clone(),
                setting,
            });
        } else {
            self.health.rejoined();
            self.send(Event::Rejoined {
                camera: self.index,
                device: self.spec.describe(),
            });
        }
    }

    /// The frame in `buffer`, with the setting it was taken with (from its
    /// chunk data, or from the tracker).
    fn frame(
        &self,
        device: &Device,
        buffer: &Buffer,
        ids: &mut IdUnwrapper,
        tracker: &mut SettingTracker,
        missing_packets: u64,
    ) -> Arrived {
        let id = ids.unwrap(buffer.frame_id());
        let host_ns = match buffer.system_timestamp() {
            0 => super::clock::host_now_ns(),
            t => t,
        };
        let timestamp_ns = match buffer.timestamp() {
            0 => host_ns,
            t => t,
        };
        let status = match buffer.status() {
            BufferStatus::Success => FrameStatus::Complete,
            BufferStatus::MissingPackets => FrameStatus::MissingPackets {
                missing: u32::try_from(missing_packets.max(1)).unwrap_or(u32::MAX),
            },
            other => FrameStatus::Failed(format!("{other:?}")),
        };
        let taken = device
            .chunk_setting(buffer)
            .unwrap_or_else(|| tracker.taken(id));
        let info = device.info();
        let (mut width, mut height) = (info.width, info.height);
        let mut data = if status == FrameStatus::Complete {
            let image = buffer.image_data();
            if image.is_empty() {
                let need = width * height * info.format.bytes_per_pixel();
                super::ffi::buffer_bytes(buffer, need, device.payload())
            } else {
                let (w, h) = (buffer.image_width(), buffer.image_height());
                width = usize::try_from(w).ok().filter(|w| *w > 0).unwrap_or(width);
                height = usize::try_from(h).ok().filter(|h| *h > 0).unwrap_or(height);
                image
            }
        } else {
            Vec::new()
        };
        let need = width * height * info.format.bytes_per_pixel();
        let mut status = status;
        if data.len() != need {
            if status == FrameStatus::Complete {
                status = FrameStatus::Failed(format!(
                    "{} bytes for a {width}×{height} {} frame",
                    data.len(),
                    info.format.genicam_name()
                ));
            }
            data.resize(need, 0);
        }
        let meta = FrameMeta {
            camera: self.index,
            format: info.format,
            width,
            height,
            taken,
            timestamp_ns,
            frame_id: id,
            status,
        };
        let frame = Frame {
            meta,
            data: Arc::from(data),
        };
        Arrived { host_ns, id, frame }
    }
}
