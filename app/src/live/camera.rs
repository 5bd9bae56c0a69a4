//! One camera's thread: open (behind the global lock), configure, the
//! start-up auto-exposure, the acquisition loop with software triggers and
//! exposure commands, and reconnection with back-off.

use std::collections::VecDeque;
use std::net::IpAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use aravis::glib::prelude::Cast;
use aravis::prelude::*;
use aravis::{
    AcquisitionMode, Auto, Buffer, BufferStatus, Camera, ChunkParser, FakeDevice, GvStream,
    GvStreamOption, GvStreamPacketResend, GvStreamSocketBuffer, Stream,
};
use rigview_core::exposure::{ExposureRange, ExposureSetting};
use rigview_core::source::{CameraInfo, Frame, FrameMeta, FrameStatus, StreamState};

use super::assemble::Arrived;
use super::config::{CaptureConfig, TriggerMode};
use super::fake::{render_into, FakeView};
use super::ffi::{install_fill, FillFn, FillGuard};
use super::health::{HealthCell, StreamCounts};
use super::tracker::{IdUnwrapper, SettingTracker};

/// Aravis corrupts its GenICam state when cameras are opened or enumerated
/// from several threads at once: every open goes through this lock.
static OPEN_LOCK: Mutex<()> = Mutex::new(());

/// How to reach a camera.
#[derive(Clone, Debug)]
pub enum DeviceSpec {
    /// A GenICam device id (`Vendor-Serial`) or an IP address, as Aravis
    /// opens it.
    Id(String),
    /// An Aravis in-process fake camera with this serial number, showing
    /// `view` (a camera of the simulated rig) in `view`'s pixel format and
    /// size.
    Fake {
        /// Serial number (unique per fake camera).
        serial: String,
        /// What it shows.
        view: FakeView,
    },
}

impl DeviceSpec {
    /// How it is named in messages.
    pub fn describe(&self) -> String {
        match self {
            DeviceSpec::Id(id) => id.clone(),
            DeviceSpec::Fake { serial, .. } => format!("in-process fake camera {serial}"),
        }
    }
}

/// What a camera thread tells the source.
#[derive(Debug)]
pub(crate) enum Event {
    /// The camera is open and configured, its start-up is over.
    Ready {
        camera: usize,
        info: CameraInfo,
        setting: ExposureSetting,
    },
    /// It could not be opened in time.
    OpenFailed { error: String },
    /// A frame.
    Frame(Arrived),
    /// Its state changed (with what happened).
    State {
        camera: usize,
        state: StreamState,
        message: String,
    },
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

/// When software triggers fire: every camera fires at the same ticks, so a
/// tick's index names the frame set its frames belong to.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Schedule {
    pub epoch: Instant,
    /// The epoch on the host's wall clock, ns since the Unix epoch.
    pub epoch_wall_ns: u64,
    pub period: Duration,
}

impl Schedule {
    fn period_ns(&self) -> u64 {
        u64::try_from(self.period.as_nanos())
            .unwrap_or(u64::MAX)
            .max(1)
    }

    /// The index and instant of the first tick after `now`.
    fn next_after(&self, now: Instant) -> (u64, Instant) {
        let p = self.period_ns();
        let since =
            u64::try_from(now.saturating_duration_since(self.epoch).as_nanos()).unwrap_or(u64::MAX);
        let k = since / p + 1;
        (k, self.epoch + Duration::from_nanos(k.saturating_mul(p)))
    }

    /// Tick `k` on the host's wall clock: the key its frames are matched by.
    fn wall_ns(&self, k: u64) -> u64 {
        self.epoch_wall_ns + k.saturating_mul(self.period_ns())
    }
}

fn host_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

fn msg(what: &str, e: impl std::fmt::Display) -> String {
    format!("{what}: {e}")
}

/// How a camera's gain is expressed.
#[derive(Clone, Copy, Debug, PartialEq)]
enum GainUnit {
    Db,
    Raw { db_per_step: f64 },
    None,
}

impl GainUnit {
    fn to_db(self, native: f64) -> f64 {
        match self {
            GainUnit::Db => native,
            GainUnit::Raw { db_per_step } => native * db_per_step,
            GainUnit::None => 0.0,
        }
    }
    fn to_native(self, db: f64) -> f64 {
        match self {
            GainUnit::Db => db,
            GainUnit::Raw { db_per_step } => (db / db_per_step).round(),
            GainUnit::None => 0.0,
        }
    }
}

/// An open, configured camera with its stream.
struct Conn {
    // Field order is drop order: the stream goes before the camera, the
    // fake camera's fill callback last.
    stream: Stream,
    camera: Camera,
    _fake: Option<(FakeDevice, FillGuard)>,
    control_lost: Arc<AtomicBool>,
    info: CameraInfo,
    gain: GainUnit,
    chunks: Option<ChunkParser>,
    is_gv: bool,
    payload: usize,
    auto_exposure: bool,
    auto_gain: bool,
}

impl std::fmt::Debug for Conn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Conn").field("info", &self.info).finish()
    }
}

fn is_loopback(id: &str) -> bool {
    id.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

fn open(name: &str, spec: &DeviceSpec, config: &CaptureConfig) -> Result<Conn, String> {
    let _one_at_a_time = OPEN_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let (camera, fake) = match spec {
        DeviceSpec::Id(id) => (
            Camera::new(Some(id)).map_err(|e| msg("cannot open", e))?,
            None,
        ),
        DeviceSpec::Fake { serial, view } => {
            let device = FakeDevice::new(serial).map_err(|e| msg("cannot create", e))?;
            let fake = device
                .fake_camera()
                .ok_or_else(|| "the fake device has no fake camera".to_owned())?;
            // In trigger mode the in-process fake camera does not wait for
            // software triggers: it fires on its own, aligned to the
            // monotonic clock, like a trigger box shared by the rig; here at
            // the simulation's trigger rate.
            fake.set_trigger_frequency(view.render.config().trigger_hz);
            let guard = install_fill(
                &fake,
                view.width,
                view.height,
                view.format.bytes_per_pixel(),
                fake_fill(view.clone(), config.gain_raw_db_per_step),
            );
            let camera = Camera::with_device(&device).map_err(|e| msg("cannot open", e))?;
            (camera, Some((device, guard)))
        }
    };
    let mut config = config.clone();
    if let DeviceSpec::Fake { view, .. } = spec {
        config.region = Some(super::config::Region {
            x: 0,
            y: 0,
            width: u32::try_from(view.width).unwrap_or(u32::MAX),
            height: u32::try_from(view.height).unwrap_or(u32::MAX),
        });
        config.pixel_format = view.format;
    }
    let loopback = matches!(spec, DeviceSpec::Id(id) if is_loopback(id));
    let conn = configure(name, camera, fake, &config, loopback)?;
    if let DeviceSpec::Fake { view, .. } = spec {
        // The fill callback writes a whole frame into each buffer.
        if conn.payload < view.buffer_len() {
            return Err(format!(
                "the fake camera's payload ({} bytes) is smaller than a {}×{} {} frame",
                conn.payload,
                view.width,
                view.height,
                view.format.genicam_name()
            ));
        }
    }
    Ok(conn)
}

/// The fill callback of a fake camera showing `view`: its registers' raw
/// gain read as `db_per_step` dB a step (as the camera's thread reads it),
/// its frame ids made monotonic (as the camera's thread makes them), so a
/// frame's id, timestamp and `taken` setting are the ones it was rendered
/// with.
fn fake_fill(view: FakeView, db_per_step: f64) -> Box<FillFn> {
    let ids = Mutex::new(IdUnwrapper::default());
    Box::new(move |pixels, args| {
        let frame = ids
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .unwrap(args.frame_id);
        let shown = render_into(
            &view,
            frame,
            args.timestamp_ns,
            f64::from(args.exposure_us),
            f64::from(args.gain_raw) * db_per_step,
            pixels,
        );
        // (Only an exposure time of 0 µs, which the fake camera's range
        // excludes, makes the simulation refuse a frame.)
        if shown.is_err() {
            pixels.fill(0);
        }
    })
}

fn configure(
    name: &str,
    camera: Camera,
    fake: Option<(FakeDevice, FillGuard)>,
    config: &CaptureConfig,
    loopback: bool,
) -> Result<Conn, String> {
    camera
        .set_pixel_format_from_string(config.pixel_format.genicam_name())
        .map_err(|e| {
            msg(
                &format!("pixel format {}", config.pixel_format.genicam_name()),
                e,
            )
        })?;
    if let Some(r) = config.region {
        let int = |v: u32| i32::try_from(v).unwrap_or(i32::MAX);
        camera
            .set_region(int(r.x), int(r.y), int(r.width), int(r.height))
            .map_err(|e| msg("region", e))?;
    }
    // Some cameras refuse trigger changes during acquisition.
    let _ = camera.stop_acquisition();
    camera
        .set_acquisition_mode(AcquisitionMode::Continuous)
        .map_err(|e| msg("acquisition mode", e))?;
    match &config.trigger {
        TriggerMode::Hardware { line } => camera
            .set_trigger(line)
            .map_err(|e| msg(&format!("trigger on {line}"), e))?,
        TriggerMode::Software { .. } => camera
            .set_trigger("Software")
            .map_err(|e| msg("software trigger", e))?,
        TriggerMode::FreeRun { rate_hz } => {
            camera.clear_triggers().map_err(|e| msg("free run", e))?;
            if let Some(r) = rate_hz {
                camera
                    .set_frame_rate(*r)
                    .map_err(|e| msg(&format!("frame rate {r} Hz"), e))?;
            }
        }
    }
    let has = |f: &str| camera.is_feature_available(f).unwrap_or(false);
    let gain = if has("Gain") {
        GainUnit::Db
    } else if has("GainRaw") {
        GainUnit::Raw {
            db_per_step: config.gain_raw_db_per_step,
        }
    } else {
        GainUnit::None
    };
    let (t_lo, t_hi) = camera
        .exposure_time_bounds()
        .map_err(|e| msg("exposure time range", e))?;
    let (g_lo, g_hi) = match gain {
        GainUnit::None => (0.0, 0.0),
        _ => camera.gain_bounds().map_err(|e| msg("gain range", e))?,
    };
    let range = ExposureRange {
        shutter_min_us: t_lo.max(1e-3),
        shutter_max_us: t_hi.max(t_lo.max(1e-3)),
        gain_min_db: gain.to_db(g_lo),
        gain_max_db: gain.to_db(g_hi),
    };
    range
        .validate()
        .map_err(|e| msg("the camera reports an unusable exposure range", e))?;
    let is_gv = camera.is_gv_device();
    if is_gv {
        if loopback {
            camera.gv_set_stream_options(GvStreamOption::PACKET_SOCKET_DISABLED);
        }
        match config.packet_size {
            Some(n) => camera
                .gv_set_packet_size(i32::try_from(n).unwrap_or(i32::MAX))
                .map_err(|e| msg(&format!("packet size {n}"), e))?,
            None => camera
                .gv_auto_packet_size()
                .map_err(|e| msg("packet size negotiation", e))?,
        }
        if config.packet_delay_ns > 0 || camera.gv_get_packet_delay().unwrap_or(0) > 0 {
            camera
                .gv_set_packet_delay(i64::try_from(config.packet_delay_ns).unwrap_or(i64::MAX))
                .map_err(|e| msg("inter-packet delay", e))?;
        }
    }
    // (`are_chunks_available` of the bindings asserts on a plain "no".)
    let chunks = if config.use_chunks && has("ChunkModeActive") {
        camera
            .set_chunks("ExposureTime,Gain")
            .ok()
            .and_then(|()| camera.create_chunk_parser())
    } else {
        None
    };
    let (_, _, width, height) = camera.region().map_err(|e| msg("region", e))?;
    let payload = camera.payload().map_err(|e| msg("payload size", e))? as usize;
    let stream = camera
        .create_stream()
        .map_err(|e| msg("cannot create the stream", e))?;
    if let Some(gv) = stream.downcast_ref::<GvStream>() {
        gv.set_socket_buffer(GvStreamSocketBuffer::Fixed);
        gv.set_socket_buffer_size(i32::try_from(config.socket_buffer_bytes).unwrap_or(i32::MAX));
        gv.set_packet_resend(GvStreamPacketResend::Always);
    }
    for _ in 0..config.buffers {
        stream.push_buffer(Buffer::new_allocate(payload));
    }
    let control_lost = Arc::new(AtomicBool::new(false));
    if let Some(device) = camera.device() {
        let flag = control_lost.clone();
        device.connect_control_lost(move |_| flag.store(true, Ordering::SeqCst));
    }
    let auto_exposure = camera.is_exposure_auto_available().unwrap_or(false);
    let auto_gain = gain != GainUnit::None && camera.is_gain_auto_available().unwrap_or(false);
    let info = CameraInfo {
        name: name.to_owned(),
        format: config.pixel_format,
        width: usize::try_from(width).unwrap_or(0),
        height: usize::try_from(height).unwrap_or(0),
        range,
    };
    Ok(Conn {
        stream,
        camera,
        _fake: fake,
        control_lost,
        info,
        gain,
        chunks,
        is_gv,
        payload,
        auto_exposure,
        auto_gain,
    })
}

impl Conn {
    fn read_setting(&self) -> Result<ExposureSetting, String> {
        let shutter_us = self
            .camera
            .exposure_time()
            .map_err(|e| msg("reading the exposure time", e))?;
        let gain_db = match self.gain {
            GainUnit::None => 0.0,
            g => g.to_db(self.camera.gain().map_err(|e| msg("reading the gain", e))?),
        };
        Ok(ExposureSetting {
            shutter_us,
            gain_db,
        })
    }

    fn set_auto(&self, on: bool) -> Result<(), String> {
        let mode = if on { Auto::Continuous } else { Auto::Off };
        if self.auto_exposure {
            self.camera
                .set_exposure_time_auto(mode)
                .map_err(|e| msg("ExposureAuto", e))?;
        }
        if self.auto_gain {
            self.camera
                .set_gain_auto(mode)
                .map_err(|e| msg("GainAuto", e))?;
        }
        Ok(())
    }

    /// Writes `setting` (clamped to the camera's ranges) and reads back what
    /// the camera made of it.
    fn apply(&self, setting: ExposureSetting) -> Result<ExposureSetting, String> {
        let r = self.info.range;
        let t = setting.shutter_us.clamp(r.shutter_min_us, r.shutter_max_us);
        let g = setting.gain_db.clamp(r.gain_min_db, r.gain_max_db);
        self.camera
            .set_exposure_time(t)
            .map_err(|e| msg(&format!("setting the exposure time to {t:.1} µs"), e))?;
        if self.gain != GainUnit::None {
            self.camera
                .set_gain(self.gain.to_native(g))
                .map_err(|e| msg(&format!("setting the gain to {g:.2} dB"), e))?;
        }
        self.read_setting()
    }

    fn counts(&self) -> StreamCounts {
        let (completed, failed, underruns) = self.stream.statistics();
        let (missing_packets, resent_packets) = if self.is_gv {
            (
                self.stream.info_uint64_by_name("n_missing_packets"),
                self.stream.info_uint64_by_name("n_resent_packets"),
            )
        } else {
            (0, 0)
        };
        StreamCounts {
            completed,
            failed,
            underruns,
            missing_packets,
            resent_packets,
        }
    }

    fn chunk_setting(&self, buffer: &Buffer) -> Option<ExposureSetting> {
        let parser = self.chunks.as_ref()?;
        if !buffer.has_chunks() {
            return None;
        }
        let shutter_us = parser.float_value(buffer, "ChunkExposureTime").ok()?;
        let gain_db = match self.gain {
            GainUnit::None => 0.0,
            g => g.to_db(parser.float_value(buffer, "ChunkGain").ok()?),
        };
        Some(ExposureSetting {
            shutter_us,
            gain_db,
        })
    }

    /// Stops acquisition and lets the camera go.
    fn close(self) {
        let _ = self.camera.stop_acquisition();
    }

    /// Lets a camera that stopped answering go. Aravis's GenICam
    /// requests to it (releasing control) only end by time-out, so this
    /// happens on a thread of its own while the camera's thread goes on
    /// reconnecting.
    fn abandon(self) {
        // If no thread can be started, the closure, and the camera with it,
        // is dropped here instead.
        let _ = std::thread::Builder::new()
            .name("camera release".into())
            .spawn(move || drop(self));
    }
}

/// Why an acquisition loop ended.
enum Ended {
    Stop,
    Lost(String),
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

    fn state(&self, state: StreamState, message: String) {
        self.health.set_state(state);
        if state != StreamState::Streaming {
            self.health.error(message.clone());
        }
        let _ = self.events.send(Event::State {
            camera: self.index,
            state,
            message,
        });
    }

    fn note(&self, message: String) {
        let _ = self.events.send(Event::Note {
            camera: self.index,
            message,
        });
    }

    /// The thread's body: runs until stopped.
    pub fn run(self) {
        let deadline = Instant::now() + self.config.open_timeout;
        let mut conn = loop {
            if self.stopped() {
                return;
            }
            match open(&self.name, &self.spec, &self.config) {
                Ok(c) => break c,
                Err(e) if Instant::now() >= deadline => {
                    let _ = self.events.send(Event::OpenFailed {
                        error: format!("{} ({}): {e}", self.name, self.spec.describe()),
                    });
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
            let (ended, last) = self.acquire(&conn, start);
            self.health.close_stream();
            let message = match ended {
                Ended::Stop => {
                    conn.close();
                    return;
                }
                Ended::Lost(m) => m,
            };
            if matches!(start, Start::First) && last.is_none() {
                conn.close();
                let _ = self.events.send(Event::OpenFailed {
                    error: format!("{} ({}): {message}", self.name, self.spec.describe()),
                });
                return;
            }
            self.state(StreamState::Lost, message);
            conn.abandon();
            let Some(c) = self.reconnect() else { return };
            conn = c;
            start = Start::Rejoin(last.unwrap_or(ExposureSetting {
                shutter_us: conn.info.range.shutter_min_us,
                gain_db: conn.info.range.gain_min_db,
            }));
        }
    }

    fn reconnect(&self) -> Option<Conn> {
        let mut wait = self.config.reconnect_initial;
        loop {
            if !self.nap(wait) {
                return None;
            }
            self.health.set_state(StreamState::Reconnecting);
            match open(&self.name, &self.spec, &self.config) {
                Ok(c) => return Some(c),
                Err(e) => {
                    self.health.set_state(StreamState::Lost);
                    self.health.error(e);
                    wait = (wait * 2).min(self.config.reconnect_max);
                }
            }
        }
    }

    /// Runs one acquisition; returns why it ended and the setting the
    /// camera had last (`None` if it never got through its start-up).
    fn acquire(&self, conn: &Conn, start: Start) -> (Ended, Option<ExposureSetting>) {
        let mut current = None;
        let ended = match self.acquire_inner(conn, start, &mut current) {
            Ok(e) => e,
            Err(m) => Ended::Lost(m),
        };
        (ended, current)
    }

    fn acquire_inner(
        &self,
        conn: &Conn,
        start: Start,
        current: &mut Option<ExposureSetting>,
    ) -> Result<Ended, String> {
        let cfg = &self.config;
        let software = matches!(cfg.trigger, TriggerMode::Software { .. });
        let watch_silence = !matches!(cfg.trigger, TriggerMode::Hardware { .. });
        let period = cfg.trigger.period().unwrap_or(Duration::from_millis(100));
        let frame_timeout = period * 3 + Duration::from_millis(200);
        let mut settle_until = None;
        let mut tracker = SettingTracker::new(conn.read_setting()?);
        match start {
            Start::First
                if !cfg.auto_settle.is_zero() && (conn.auto_exposure || conn.auto_gain) =>
            {
                conn.set_auto(true)?;
                settle_until = Some(Instant::now() + cfg.auto_settle);
            }
            Start::First => {
                conn.set_auto(false)?;
                let s = conn.read_setting()?;
                self.ready(conn, s, &mut tracker, current, true);
            }
            Start::Rejoin(s) => {
                conn.set_auto(false)?;
                let s = conn.apply(s)?;
                self.ready(conn, s, &mut tracker, current, false);
            }
        }
        conn.camera
            .start_acquisition()
            .map_err(|e| msg("cannot start acquisition", e))?;
        let mut next_tick = self.schedule.map(|s| s.next_after(Instant::now()));
        // Software triggers sent whose frame has not arrived: (tick, sent).
        let mut outstanding: VecDeque<(u64, Instant)> = VecDeque::new();
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
            if conn.control_lost.load(Ordering::SeqCst) {
                return Ok(Ended::Lost(
                    "the camera stopped answering (control lost)".into(),
                ));
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
                conn.set_auto(false)?;
                let s = conn.read_setting()?;
                self.ready(conn, s, &mut tracker, current, true);
            }
            if let (Some(on), None) = (auto_request, settle_until) {
                auto_request = None;
                let first = last_id.map_or(0, |l| l + 1) + outstanding.len() as u64;
                if !(conn.auto_exposure || conn.auto_gain) {
                    self.note(
                        "it has no ExposureAuto or GainAuto: its exposure stays as set".into(),
                    );
                } else if let Err(e) = conn.set_auto(on) {
                    self.note(format!("its own auto-exposure cannot be switched: {e}"));
                } else {
                    camera_auto = on;
                    pending = None;
                    let s = conn.read_setting()?;
                    tracker.commanded(first, s);
                    *current = Some(s);
                    self.health.setting(s, self.setting_source(conn));
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
                let s = conn.read_setting()?;
                if *current != Some(s) {
                    tracker.commanded(last_id.map_or(0, |l| l + 1), s);
                    *current = Some(s);
                    self.health.setting(s, self.setting_source(conn));
                }
            }
            if settle_until.is_none() && !camera_auto {
                if let Some(s) = pending.take() {
                    let actual = conn.apply(s)?;
                    // Frames of software triggers already sent keep the old
                    // setting; so do the camera's own latency frames.
                    let in_flight = outstanding.len() as u64;
                    let first = last_id.map_or(0, |l| l + 1)
                        + in_flight
                        + u64::from(cfg.command_latency_frames);
                    tracker.commanded(first, actual);
                    *current = Some(actual);
                    self.health.setting(actual, self.setting_source(conn));
                }
            }
            if let (true, Some((k, tick))) = (software, next_tick) {
                if now >= tick {
                    conn.camera
                        .software_trigger()
                        .map_err(|e| msg("the software trigger failed", e))?;
                    outstanding.push_back((k, now));
                    next_tick = self.schedule.map(|s| s.next_after(Instant::now()));
                }
            }
            while outstanding
                .front()
                .is_some_and(|(_, t)| now.duration_since(*t) > frame_timeout)
            {
                outstanding.pop_front();
            }
            let wait = match (software, next_tick) {
                (true, Some((_, t))) => t.saturating_duration_since(Instant::now()),
                _ => Duration::from_millis(20),
            }
            .clamp(Duration::from_micros(200), Duration::from_millis(20));
            let wait_us = u64::try_from(wait.as_micros()).unwrap_or(20_000);
            if let Some(buffer) = conn.stream.timeout_pop_buffer(wait_us) {
                let counts = conn.counts();
                let missing = counts.missing_packets.saturating_sub(missing_seen);
                missing_seen = counts.missing_packets;
                let mut arrived = self.frame(conn, &buffer, &mut ids, &mut tracker, missing);
                conn.stream.push_buffer(buffer);
                // Each trigger makes one frame: the oldest trigger waiting is
                // this frame's, after those of frames lost whole (a gap in
                // the ids).
                let gap = last_id.map_or(0, |l| arrived.id.saturating_sub(l + 1));
                for _ in 0..gap.min(outstanding.len() as u64) {
                    outstanding.pop_front();
                }
                if let (Some((k, _)), Some(s)) = (outstanding.pop_front(), &self.schedule) {
                    arrived.host_ns = s.wall_ns(k);
                }
                last_frame_at = Instant::now();
                last_id = Some(arrived.id);
                self.health.frame_arrived();
                if settle_until.is_none() {
                    let _ = self.events.send(Event::Frame(arrived));
                }
            }
            if counts_at.elapsed() > Duration::from_millis(250) {
                self.health.set_counts(conn.counts());
                counts_at = Instant::now();
            }
            if watch_silence && last_frame_at.elapsed() > cfg.lost_after {
                return Ok(Ended::Lost(format!(
                    "no frame for {:.1} s",
                    last_frame_at.elapsed().as_secs_f64()
                )));
            }
        }
    }

    fn setting_source(&self, conn: &Conn) -> &'static str {
        if conn.chunks.is_some() {
            "chunk"
        } else {
            "latency"
        }
    }

    fn ready(
        &self,
        conn: &Conn,
        setting: ExposureSetting,
        tracker: &mut SettingTracker,
        current: &mut Option<ExposureSetting>,
        first: bool,
    ) {
        *tracker = SettingTracker::new(setting);
        *current = Some(setting);
        self.health.setting(setting, self.setting_source(conn));
        if first {
            self.health.set_state(StreamState::Streaming);
            let _ = self.events.send(Event::Ready {
                camera: self.index,
                info: conn.info.clone(),
                setting,
            });
        } else {
            self.health.rejoined();
            let _ = self.events.send(Event::State {
                camera: self.index,
                state: StreamState::Streaming,
                message: format!("rejoined ({})", self.spec.describe()),
            });
        }
    }

    fn frame(
        &self,
        conn: &Conn,
        buffer: &Buffer,
        ids: &mut IdUnwrapper,
        tracker: &mut SettingTracker,
        missing_packets: u64,
    ) -> Arrived {
        let id = ids.unwrap(buffer.frame_id());
        let host_ns = match buffer.system_timestamp() {
            0 => host_now_ns(),
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
        let taken = conn
            .chunk_setting(buffer)
            .unwrap_or_else(|| tracker.taken(id));
        let info = &conn.info;
        let (mut width, mut height) = (info.width, info.height);
        let mut data = if status == FrameStatus::Complete {
            let image = buffer.image_data();
            if image.is_empty() {
                let need = width * height * info.format.bytes_per_pixel();
                super::ffi::buffer_bytes(buffer, need, conn.payload)
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
