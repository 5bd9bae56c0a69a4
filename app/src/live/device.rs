//! Device set-up: opening a camera (behind the global lock), configuring its
//! features (pixel format, region, trigger, GigE Vision packets, chunk data,
//! the stream's buffers), and the features the acquisition reads and writes
//! afterwards (exposure time, gain, their auto modes, stream counters).

use std::net::IpAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use aravis::glib::prelude::Cast;
use aravis::prelude::*;
use aravis::{
    AcquisitionMode, Auto, Buffer, Camera, ChunkParser, GvStream, GvStreamOption,
    GvStreamPacketResend, GvStreamSocketBuffer, Stream,
};
use rigview_core::exposure::{ExposureRange, ExposureSetting, ToneCurve};
use rigview_core::source::CameraInfo;

use super::config::CaptureConfig;
use super::error::{CameraError, Named};
use super::fake::{self, FakeView};
use super::health::StreamCounts;
use super::trigger;

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
pub(crate) struct Device {
    // Field order is drop order: the stream goes before the camera, the
    // fake camera (and its fill callback) last.
    stream: Stream,
    camera: Camera,
    _fake: Option<fake::FakeDevice>,
    control_lost: Arc<AtomicBool>,
    name: String,
    info: CameraInfo,
    gain: GainUnit,
    chunks: Option<ChunkParser>,
    is_gv: bool,
    payload: usize,
    auto_exposure: bool,
    auto_gain: bool,
}

impl std::fmt::Debug for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Device").field("info", &self.info).finish()
    }
}

fn is_loopback(id: &str) -> bool {
    id.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

impl Device {
    /// Opens camera `name` as `spec` says (one open at a time) and
    /// configures it.
    pub fn open(
        name: &str,
        spec: &DeviceSpec,
        config: &CaptureConfig,
    ) -> Result<Self, CameraError> {
        let _one_at_a_time = OPEN_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        match spec {
            DeviceSpec::Id(id) => {
                let camera = Camera::new(Some(id)).map_err(|source| CameraError::Open {
                    camera: name.to_owned(),
                    device: spec.describe(),
                    source,
                })?;
                configure(name, camera, None, config, is_loopback(id))
            }
            DeviceSpec::Fake { serial, view } => {
                let (camera, device, config) = fake::open(name, serial, view, config)?;
                let dev = configure(name, camera, Some(device), &config, false)?;
                fake::check_payload(name, view, dev.payload)?;
                Ok(dev)
            }
        }
    }

    /// What the camera delivers.
    pub fn info(&self) -> &CameraInfo {
        &self.info
    }

    /// Bytes of a frame's buffer.
    pub fn payload(&self) -> usize {
        self.payload
    }

    /// Whether the camera has its own auto-exposure or auto-gain.
    pub fn has_auto(&self) -> bool {
        self.auto_exposure || self.auto_gain
    }

    /// Whether the camera stopped answering its control channel.
    pub fn control_lost(&self) -> bool {
        self.control_lost.load(Ordering::SeqCst)
    }

    /// Where a frame's `taken` setting comes from, for the health readout.
    pub fn setting_source(&self) -> &'static str {
        if self.chunks.is_some() {
            "chunk"
        } else {
            "latency"
        }
    }

    /// The exposure time and gain the camera has now.
    pub fn read_setting(&self) -> Result<ExposureSetting, CameraError> {
        let named = Named(&self.name);
        let shutter_us = self
            .camera
            .exposure_time()
            .map_err(named.read("ExposureTime"))?;
        let gain_db = match self.gain {
            GainUnit::None => 0.0,
            g => g.to_db(self.camera.gain().map_err(named.read("Gain"))?),
        };
        Ok(ExposureSetting {
            shutter_us,
            gain_db,
        })
    }

    /// Switches the camera's own auto-exposure and auto-gain, where it has
    /// them.
    pub fn set_auto(&self, on: bool) -> Result<(), CameraError> {
        let named = Named(&self.name);
        let mode = if on { Auto::Continuous } else { Auto::Off };
        if self.auto_exposure {
            self.camera
                .set_exposure_time_auto(mode)
                .map_err(named.set("ExposureAuto", format!("{mode:?}")))?;
        }
        if self.auto_gain {
            self.camera
                .set_gain_auto(mode)
                .map_err(named.set("GainAuto", format!("{mode:?}")))?;
        }
        Ok(())
    }

    /// Writes `setting` (clamped to the camera's ranges) and reads back what
    /// the camera made of it.
    pub fn apply(&self, setting: ExposureSetting) -> Result<ExposureSetting, CameraError> {
        let named = Named(&self.name);
        let r = self.info.range;
        let t = setting.shutter_us.clamp(r.shutter_min_us, r.shutter_max_us);
        let g = setting.gain_db.clamp(r.gain_min_db, r.gain_max_db);
        self.camera
            .set_exposure_time(t)
            .map_err(named.set("ExposureTime", format!("{t:.1} µs")))?;
        if self.gain != GainUnit::None {
            self.camera
                .set_gain(self.gain.to_native(g))
                .map_err(named.set("Gain", format!("{g:.2} dB")))?;
        }
        self.read_setting()
    }

    /// Starts acquisition.
    pub fn start(&self) -> Result<(), CameraError> {
        self.camera
            .start_acquisition()
            .map_err(Named(&self.name).command("AcquisitionStart"))
    }

    /// Sends a software trigger.
    pub fn trigger(&self) -> Result<(), CameraError> {
        self.camera
            .software_trigger()
            .map_err(Named(&self.name).command("TriggerSoftware"))
    }

    /// The next filled buffer, waiting up to `wait_us`.
    pub fn pop(&self, wait_us: u64) -> Option<Buffer> {
        self.stream.timeout_pop_buffer(wait_us)
    }

    /// Gives a buffer back to the stream.
    pub fn push(&self, buffer: Buffer) {
        self.stream.push_buffer(buffer);
    }

    /// The stream's counters.
    pub fn counts(&self) -> StreamCounts {
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

    /// The exposure time and gain a buffer's chunk data says it was taken
    /// with, where the camera sends them.
    pub fn chunk_setting(&self, buffer: &Buffer) -> Option<ExposureSetting> {
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
    pub fn close(self) {
        let _ = self.camera.stop_acquisition();
    }

    /// Lets a camera that stopped answering go. Aravis's GenICam
    /// requests to it (releasing control) only end by time-out, so this
    /// happens on a thread of its own while the camera's thread goes on
    /// reconnecting.
    pub fn abandon(self) {
        // If no thread can be started, the closure, and the camera with it,
        // is dropped here instead.
        let _ = std::thread::Builder::new()
            .name("camera release".into())
            .spawn(move || drop(self));
    }
}

/// The tone curve the camera's frames went through, where it has one:
/// its gamma correction, where it is on (GenICam's `GammaEnable` where
/// there is one, then `GammaSelector` `sRGB`, about 1/2.2, or else
/// `Gamma`: each pixel `P` output as `P^Gamma`,
/// [`ToneCurve::from_genicam_gamma`]; an sRGB colour space on top,
/// [`gamma_of`]), then its pixel lookup table, where
/// `LUTEnable` is on (the one `LUTSelector` selects, read through
/// `LUTIndex` and `LUTValue` at up to [`LUT_SAMPLES`] inputs,
/// [`ToneCurve::from_genicam_lut`]). Scale-and-clip and the balancing read
/// the frames through it.
fn tone_curve(
    camera: &Camera,
    has: &dyn Fn(&str) -> bool,
    named: Named<'_>,
) -> Result<Option<ToneCurve>, CameraError> {
    let unexpected =
        |feature: &'static str, expected: &str, e: rigview_core::Error| CameraError::Unexpected {
            camera: named.0.to_owned(),
            feature,
            expected: expected.into(),
            found: e.to_string(),
        };
    let gamma = match gamma_of(camera, has, named)? {
        Some(g) => ToneCurve::from_genicam_gamma(g).map_err(|e| {
            unexpected(
                "Gamma",
                "a positive gamma (each pixel P output as P^Gamma)",
                e,
            )
        })?,
        None => None,
    };
    match lut_of(camera, has, named)? {
        Some(lut) => ToneCurve::from_genicam_lut(&lut, gamma.as_ref()).map_err(|e| {
            unexpected(
                "LUTValue",
                "a lookup table whose outputs do not fall as its inputs rise",
                e,
            )
        }),
        None => Ok(gamma),
    }
}

/// The camera's gamma where its gamma correction is on (see
/// [`tone_curve`]), times that of an sRGB colour space where the camera
/// has one selected (`BslColorSpace`, `BslColorSpaceMode` or `ColorSpace`
/// `sRGB`, Basler's, applied on top of `Gamma`: about 1/2.2).
fn gamma_of(
    camera: &Camera,
    has: &dyn Fn(&str) -> bool,
    named: Named<'_>,
) -> Result<Option<f64>, CameraError> {
    let gamma = own_gamma(camera, has, named)?;
    let space = COLOUR_SPACES.into_iter().find(|f| has(f));
    let srgb = match space {
        Some(f) => camera
            .string(f)
            .map_err(named.read(f))?
            .eq_ignore_ascii_case("sRGB"),
        None => false,
    };
    Ok(match (gamma, srgb) {
        (g, false) => g,
        (Some(g), true) => Some(g / 2.2),
        (None, true) => Some(1.0 / 2.2),
    })
}

/// The features that select a camera's colour space (Basler's).
const COLOUR_SPACES: [&str; 3] = ["BslColorSpace", "BslColorSpaceMode", "ColorSpace"];

/// The camera's own gamma correction, where it is on.
fn own_gamma(
    camera: &Camera,
    has: &dyn Fn(&str) -> bool,
    named: Named<'_>,
) -> Result<Option<f64>, CameraError> {
    if !has("Gamma") && !has("GammaSelector") {
        return Ok(None);
    }
    if has("GammaEnable")
        && !camera
            .boolean("GammaEnable")
            .map_err(named.read("GammaEnable"))?
    {
        return Ok(None);
    }
    let srgb = has("GammaSelector")
        && camera
            .string("GammaSelector")
            .map_err(named.read("GammaSelector"))?
            .eq_ignore_ascii_case("sRGB");
    Ok(if srgb {
        Some(1.0 / 2.2)
    } else if has("Gamma") {
        Some(camera.float("Gamma").map_err(named.read("Gamma"))?)
    } else {
        None
    })
}

/// The most inputs of a pixel lookup table that are read (evenly spread
/// over `LUTIndex`'s range, its ends included): two requests each.
const LUT_SAMPLES: i64 = 256;

/// The camera's pixel lookup table where `LUTEnable` is on, as (input,
/// output) pairs normalised to `[0, 1]` (`LUTIndex` and `LUTValue` over
/// their ranges); `LUTIndex` is set back to where it was.
fn lut_of(
    camera: &Camera,
    has: &dyn Fn(&str) -> bool,
    named: Named<'_>,
) -> Result<Option<Vec<(f64, f64)>>, CameraError> {
    if !(has("LUTEnable") && has("LUTIndex") && has("LUTValue")) {
        return Ok(None);
    }
    if !camera
        .boolean("LUTEnable")
        .map_err(named.read("LUTEnable"))?
    {
        return Ok(None);
    }
    let (lo, hi) = camera
        .integer_bounds("LUTIndex")
        .map_err(named.read("LUTIndex"))?;
    let (_, top) = camera
        .integer_bounds("LUTValue")
        .map_err(named.read("LUTValue"))?;
    if hi <= lo || top <= 0 {
        return Err(CameraError::Unexpected {
            camera: named.0.to_owned(),
            feature: "LUTIndex",
            expected: "a lookup table of at least two entries and a positive largest value".into(),
            found: format!("indices {lo} to {hi}, values up to {top}"),
        });
    }
    let inc = camera.integer_increment("LUTIndex").unwrap_or(1).max(1);
    let stride = ((hi - lo) / inc / LUT_SAMPLES).max(1) * inc;
    // The last index the increment reaches (the range's end, on a camera
    // whose range is whole increments).
    let last = lo + (hi - lo) / inc * inc;
    let was = camera.integer("LUTIndex").ok();
    let mut table = Vec::new();
    let mut index = lo;
    loop {
        camera
            .set_integer("LUTIndex", index)
            .map_err(named.set("LUTIndex", index))?;
        let value = camera.integer("LUTValue").map_err(named.read("LUTValue"))?;
        table.push((
            (index - lo) as f64 / (hi - lo) as f64,
            (value as f64 / top as f64).clamp(0.0, 1.0),
        ));
        if index >= last {
            break;
        }
        index = (index + stride).min(last);
    }
    if let Some(was) = was {
        camera
            .set_integer("LUTIndex", was)
            .map_err(named.set("LUTIndex", was))?;
    }
    Ok(Some(table))
}

fn int(v: u32) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

fn configure(
    name: &str,
    camera: Camera,
    fake: Option<fake::FakeDevice>,
    config: &CaptureConfig,
    loopback: bool,
) -> Result<Device, CameraError> {
    let named = Named(name);
    let format = config.pixel_format.genicam_name();
    camera
        .set_pixel_format_from_string(format)
        .map_err(named.set("PixelFormat", format))?;
    if let Some(r) = config.region {
        camera
            .set_region(int(r.x), int(r.y), int(r.width), int(r.height))
            .map_err(named.set(
                "the region",
                format!("{}×{}+{}+{}", r.width, r.height, r.x, r.y),
            ))?;
    }
    // Some cameras refuse trigger changes during acquisition.
    let _ = camera.stop_acquisition();
    camera
        .set_acquisition_mode(AcquisitionMode::Continuous)
        .map_err(named.set("AcquisitionMode", "Continuous"))?;
    trigger::configure(&camera, named, &config.trigger)?;
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
        .map_err(named.read("the ExposureTime range"))?;
    let (g_lo, g_hi) = match gain {
        GainUnit::None => (0.0, 0.0),
        _ => camera.gain_bounds().map_err(named.read("the Gain range"))?,
    };
    let range = ExposureRange {
        shutter_min_us: t_lo.max(1e-3),
        shutter_max_us: t_hi.max(t_lo.max(1e-3)),
        gain_min_db: gain.to_db(g_lo),
        gain_max_db: gain.to_db(g_hi),
    };
    range.validate().map_err(|e| CameraError::Unexpected {
        camera: name.to_owned(),
        feature: "the exposure range",
        expected: "a usable range of exposure time and gain".into(),
        found: e.to_string(),
    })?;
    let is_gv = camera.is_gv_device();
    if is_gv {
        if loopback {
            camera.gv_set_stream_options(GvStreamOption::PACKET_SOCKET_DISABLED);
        }
        match config.packet_size {
            Some(n) => camera
                .gv_set_packet_size(i32::try_from(n).unwrap_or(i32::MAX))
                .map_err(named.set("GevSCPSPacketSize", n))?,
            None => camera
                .gv_auto_packet_size()
                .map_err(named.command("packet size negotiation"))?,
        }
        if config.packet_delay_ns > 0 || camera.gv_get_packet_delay().unwrap_or(0) > 0 {
            camera
                .gv_set_packet_delay(i64::try_from(config.packet_delay_ns).unwrap_or(i64::MAX))
                .map_err(named.set(
                    "GevSCPD (inter-packet delay)",
                    format!("{} ns", config.packet_delay_ns),
                ))?;
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
    let (_, _, width, height) = camera.region().map_err(named.read("the region"))?;
    let payload = camera.payload().map_err(named.read("PayloadSize"))? as usize;
    let stream = camera
        .create_stream()
        .map_err(named.command("creating the stream"))?;
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
    let tone_curve = tone_curve(&camera, &has, named)?;
    let info = CameraInfo {
        name: name.to_owned(),
        format: config.pixel_format,
        width: usize::try_from(width).unwrap_or(0),
        height: usize::try_from(height).unwrap_or(0),
        range,
        levels: None,
        tone_curve,
    };
    Ok(Device {
        stream,
        camera,
        _fake: fake,
        control_lost,
        name: name.to_owned(),
        info,
        gain,
        chunks,
        is_gv,
        payload,
        auto_exposure,
        auto_gain,
    })
}
