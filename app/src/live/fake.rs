//! What Aravis's in-process fake cameras show: the simulated rig
//! ([`rigview_core::sim`]), each fake camera one of its cameras, exposed at
//! the exposure time and gain the fake camera's registers hold, so that
//! exposure commands sent through the real Aravis API change the pixels.
//!
//! [`render_into`] is the one place that decides what a fake camera shows.
//! A frame is a pure function of the camera, its frame id (which picks the
//! sensor noise), its timestamp (the moment of the illumination script) and
//! the setting it was taken with ([`SimRender::fill`]): whoever knows those,
//! as a frame's metadata does, can render the same bytes again.

use std::sync::Arc;

use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::sim::{FillRequest, SimRender};
use rigview_core::source::FrameMeta;

use super::LiveError;

/// The environment variable naming a GenICam XML that Aravis's fake
/// cameras describe themselves with instead of Aravis's own (as
/// `app/tests/live_gamma.rs` gives them gamma correction).
pub const FAKE_GENICAM_ENV: &str = "RIGVIEW_FAKE_GENICAM";

/// The largest region of Aravis's fake camera (its sensor), pixels.
pub const FAKE_SENSOR_SIZE: usize = 2048;

/// What one fake camera shows: one camera of a simulated rig, into frames
/// of the format and size the fake camera is configured with.
#[derive(Clone, Debug)]
pub struct FakeView {
    /// The simulated rig (shared by every fake camera; its trigger rate is
    /// the rate the fake camera fires at).
    pub render: Arc<SimRender>,
    /// Which of its cameras.
    pub camera: usize,
    /// The fake camera's pixel format (one it offers: [`check_format`]).
    pub format: PixelFormat,
    /// The fake camera's region width, pixels (another size than the
    /// simulated camera's resamples its image, nearest pixel).
    pub width: usize,
    /// The fake camera's region height, pixels.
    pub height: usize,
    /// The start of the simulation's illumination script on the fake
    /// camera's timestamp clock ([`clock_ns`]): a frame stamped `t` shows
    /// the light at `t − epoch_ns` (frames before it, that at 0).
    pub epoch_ns: u64,
}

/// The fake camera's timestamp clock now: Aravis's in-process fake camera
/// stamps each frame with the host's wall clock, ns since the Unix epoch.
pub fn clock_ns() -> u64 {
    super::clock::host_now_ns()
}

impl FakeView {
    /// Camera `camera` of `render` at its own size, in `format`, its script
    /// starting at `epoch_ns`.
    pub fn new(
        render: Arc<SimRender>,
        camera: usize,
        format: PixelFormat,
        epoch_ns: u64,
    ) -> Result<Self, LiveError> {
        let info = render
            .cameras()
            .get(camera)
            .ok_or_else(|| no_camera(&render, camera))?;
        let (width, height) = (info.width, info.height);
        Self::sized(render, camera, format, (width, height), epoch_ns)
    }

    /// Camera `camera` of `render` resampled to `size` (width, height), in
    /// `format`, its script starting at `epoch_ns`.
    pub fn sized(
        render: Arc<SimRender>,
        camera: usize,
        format: PixelFormat,
        size: (usize, usize),
        epoch_ns: u64,
    ) -> Result<Self, LiveError> {
        let (width, height) = size;
        if camera >= render.cameras().len() {
            return Err(no_camera(&render, camera));
        }
        check_format(format)?;
        let fits = |n: usize| (1..=FAKE_SENSOR_SIZE).contains(&n);
        if !(fits(width) && fits(height)) {
            return Err(LiveError::Config {
                field: "fake camera size",
                expected: "1 to 2048 pixels each way (the fake camera's sensor)",
                value: format!("{width}×{height}"),
            });
        }
        Ok(Self {
            render,
            camera,
            format,
            width,
            height,
            epoch_ns,
        })
    }

    /// One view per camera of `render`, each at its own size, in `format`,
    /// the script starting at `epoch_ns`.
    pub fn rig(
        render: &Arc<SimRender>,
        format: PixelFormat,
        epoch_ns: u64,
    ) -> Result<Vec<Self>, LiveError> {
        (0..render.cameras().len())
            .map(|i| Self::new(render.clone(), i, format, epoch_ns))
            .collect()
    }

    /// The bytes of one frame.
    pub fn buffer_len(&self) -> usize {
        self.width * self.height * self.format.bytes_per_pixel()
    }

    /// The moment of the script, seconds, that a frame stamped
    /// `timestamp_ns` shows.
    pub fn moment(&self, timestamp_ns: u64) -> f64 {
        timestamp_ns.saturating_sub(self.epoch_ns) as f64 / 1e9
    }

    /// The simulation's request for frame `frame_id` stamped `timestamp_ns`
    /// at `setting`, with noise.
    pub fn request(
        &self,
        frame_id: u64,
        timestamp_ns: u64,
        setting: ExposureSetting,
    ) -> FillRequest {
        FillRequest {
            time_s: Some(self.moment(timestamp_ns)),
            ..FillRequest::new(
                self.camera,
                frame_id,
                setting,
                self.format,
                self.width,
                self.height,
            )
        }
    }
}

/// Checks that Aravis's fake camera offers `format`: all that rigview
/// knows but Mono12 and the 12- and 16-bit mosaics.
pub fn check_format(format: PixelFormat) -> Result<(), LiveError> {
    match format {
        PixelFormat::Mono8
        | PixelFormat::Mono16
        | PixelFormat::Rgb8
        | PixelFormat::BayerRg8
        | PixelFormat::BayerGr8
        | PixelFormat::BayerGb8
        | PixelFormat::BayerBg8 => Ok(()),
        // Mono12 and the 12- and 16-bit mosaics.
        _ => Err(LiveError::Config {
            field: "pixel format",
            expected: "one that Aravis's fake camera offers: Mono8, Mono16, RGB8, BayerRG8, BayerGR8, BayerGB8, BayerBG8",
            value: format.genicam_name().to_owned(),
        }),
    }
}

fn no_camera(render: &SimRender, camera: usize) -> LiveError {
    LiveError::Config {
        field: "fake camera",
        expected: "a camera of the simulated rig",
        value: format!("camera {camera} of a rig of {}", render.cameras().len()),
    }
}

/// Renders frame `frame_id`, stamped `timestamp_ns`, of `view` as exposed
/// for `exposure_us` at `gain_db` into `out` (the view's format and size,
/// rows tightly packed): the simulated camera's image in the light of the
/// script's moment [`FakeView::moment`], with the sensor noise of that
/// frame id.
pub fn render_into(
    view: &FakeView,
    frame_id: u64,
    timestamp_ns: u64,
    exposure_us: f64,
    gain_db: f64,
    out: &mut [u8],
) -> rigview_core::Result<FrameMeta> {
    let setting = ExposureSetting {
        shutter_us: exposure_us,
        gain_db,
    };
    view.render
        .fill(&view.request(frame_id, timestamp_ns, setting), out)
}

/// An in-process fake camera of Aravis with its fill callback installed.
/// Dropping it lets the device go, then removes the callback (the guard
/// keeps the fake camera alive until then).
#[cfg(feature = "aravis")]
pub(crate) struct FakeDevice {
    // Field order is drop order: the fill callback goes last.
    _device: aravis::FakeDevice,
    _fill: super::ffi::FillGuard,
}

#[cfg(feature = "aravis")]
impl std::fmt::Debug for FakeDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeDevice").finish_non_exhaustive()
    }
}

/// Creates the fake camera `serial` showing `view` for camera `name`: the
/// camera to configure, the device that must outlive it, and `config` with
/// the view's region and pixel format.
#[cfg(feature = "aravis")]
pub(crate) fn open(
    name: &str,
    serial: &str,
    view: &FakeView,
    config: &super::CaptureConfig,
) -> Result<(aravis::Camera, FakeDevice, super::CaptureConfig), super::CameraError> {
    use super::CameraError;

    let opening = |source| CameraError::Open {
        camera: name.to_owned(),
        device: format!("in-process fake camera {serial}"),
        source,
    };
    let device = aravis::FakeDevice::new(serial).map_err(opening)?;
    let fake = device
        .fake_camera()
        .ok_or_else(|| CameraError::Unexpected {
            camera: name.to_owned(),
            feature: "the fake device",
            expected: "a fake camera behind it".into(),
            found: "none".into(),
        })?;
    // In trigger mode the in-process fake camera does not wait for software
    // triggers: it fires on its own, aligned to the monotonic clock, like a
    // trigger box shared by the rig; here at the simulation's trigger rate.
    fake.set_trigger_frequency(view.render.config().trigger_hz);
    let fill = super::ffi::install_fill(
        &fake,
        view.width,
        view.height,
        view.format.bytes_per_pixel(),
        fill(view.clone(), config.gain_raw_db_per_step),
    );
    let camera = aravis::Camera::with_device(&device).map_err(opening)?;
    let mut config = config.clone();
    config.region = Some(super::Region {
        x: 0,
        y: 0,
        width: u32::try_from(view.width).unwrap_or(u32::MAX),
        height: u32::try_from(view.height).unwrap_or(u32::MAX),
    });
    config.pixel_format = view.format;
    Ok((
        camera,
        FakeDevice {
            _device: device,
            _fill: fill,
        },
        config,
    ))
}

/// Checks that the fake camera's buffers of `payload` bytes hold a whole
/// frame of `view`: the fill callback writes one into each.
#[cfg(feature = "aravis")]
pub(crate) fn check_payload(
    name: &str,
    view: &FakeView,
    payload: usize,
) -> Result<(), super::CameraError> {
    if payload >= view.buffer_len() {
        return Ok(());
    }
    Err(super::CameraError::Unexpected {
        camera: name.to_owned(),
        feature: "PayloadSize",
        expected: format!(
            "at least a {}×{} {} frame ({} bytes)",
            view.width,
            view.height,
            view.format.genicam_name(),
            view.buffer_len()
        ),
        found: format!("{payload} bytes"),
    })
}

/// The fill callback of a fake camera showing `view`: its registers' raw
/// gain read as `db_per_step` dB a step (as the camera's thread reads it),
/// its frame ids made monotonic (as the camera's thread makes them), so a
/// frame's id, timestamp and `taken` setting are the ones it was rendered
/// with.
#[cfg(feature = "aravis")]
fn fill(view: FakeView, db_per_step: f64) -> Box<super::ffi::FillFn> {
    let ids = std::sync::Mutex::new(super::tracker::IdUnwrapper::default());
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

/// The simulated rig that fake cameras show.
#[derive(Clone, Debug, PartialEq)]
pub struct FakeRig {
    /// A simulation preset (reference, steps, ramp, tunnel, backlight,
    /// overcast, sky, tunnel-exit, snow, lawn) or a simulation file.
    pub scenario: String,
    /// The fraction of the simulated rig's resolution rendered (0.25:
    /// 322×241).
    pub scale: f64,
    /// The rate the fake cameras fire at, Hz (they ignore software
    /// triggers and fire on their own clock, like a trigger box).
    pub rate_hz: f64,
}

impl Default for FakeRig {
    fn default() -> Self {
        Self {
            scenario: "reference".into(),
            scale: 1.0,
            rate_hz: 20.0,
        }
    }
}

/// The fake cameras of a [`FakeRig`], ready to open.
#[cfg(feature = "aravis")]
#[derive(Debug)]
pub(crate) struct FakeCameras {
    /// One per simulated camera, named as in the simulated rig.
    pub cameras: Vec<super::CameraSpec>,
    /// The capture configuration they run with.
    pub capture: super::CaptureConfig,
    /// The simulated rig (its calibration gives the view).
    pub rig: rigview_calib::Rig,
}

/// Builds the simulated rig of `fake` and one fake camera per simulated
/// camera, captured as `capture` says except for the trigger: the
/// in-process fake cameras ignore software triggers, so in trigger mode
/// they fire on their own clock, like a trigger box.
#[cfg(feature = "aravis")]
pub(crate) fn cameras(
    fake: &FakeRig,
    capture: &super::CaptureConfig,
) -> anyhow::Result<FakeCameras> {
    use anyhow::Context;
    use rigview_core::sim::{SimConfig, PRESETS};

    use super::{CameraSpec, DeviceSpec, TriggerMode};

    let mut capture = capture.clone();
    if !matches!(capture.trigger, TriggerMode::FreeRun { .. }) {
        capture.trigger = TriggerMode::Hardware {
            line: "Line0".into(),
        };
    }
    check_format(capture.pixel_format)?;
    let scenario = fake.scenario.as_str();
    if !PRESETS.iter().any(|p| p.0 == scenario) && !std::path::Path::new(scenario).exists() {
        anyhow::bail!(
            "--scenario {scenario}: neither a simulation preset ({}) nor a simulation file",
            PRESETS.map(|p| p.0).join(", ")
        );
    }
    let mut sim = SimConfig::named(scenario)
        .with_context(|| format!("loading the simulation \"{scenario}\""))?;
    sim.scale = fake.scale;
    // The fake cameras fire at the simulation's trigger rate.
    sim.trigger_hz = fake.rate_hz;
    let started = std::time::Instant::now();
    let render = Arc::new(SimRender::new(&sim).with_context(|| {
        format!(
            "building the simulation \"{scenario}\" (--scale {}, --rate {})",
            sim.scale, fake.rate_hz
        )
    })?);
    // The script starts when the controller takes over from the cameras'
    // own start-up auto-exposure (give or take the time to open them).
    let epoch_ns = clock_ns()
        .saturating_add(u64::try_from(capture.auto_settle.as_nanos()).unwrap_or(u64::MAX));
    let views = FakeView::rig(&render, capture.pixel_format, epoch_ns)?;
    let mut sizes: Vec<String> = views
        .iter()
        .map(|v| format!("{}×{}", v.width, v.height))
        .collect();
    sizes.dedup();
    tracing::info!(
        "simulation \"{}\": {} cameras of {} {}, traced in {:.1} s",
        sim.name,
        views.len(),
        sizes.join(", "),
        capture.pixel_format.genicam_name(),
        started.elapsed().as_secs_f64()
    );
    // Another GenICam description for the fake cameras (Aravis's own with
    // features added: a camera with gamma correction, say).
    if let Some(path) = std::env::var_os(FAKE_GENICAM_ENV) {
        let path = std::path::PathBuf::from(path);
        if !path.is_file() {
            anyhow::bail!(
                "{FAKE_GENICAM_ENV}={}: not a file: give a GenICam XML for the fake cameras",
                path.display()
            );
        }
        tracing::info!("fake cameras described by {}", path.display());
        super::ffi::set_fake_genicam(&path);
    }
    super::ffi::enable_interface("Fake");
    let cameras = views
        .into_iter()
        .zip(render.cameras())
        .enumerate()
        .map(|(i, (view, info))| {
            let name = info.name.clone();
            // Aravis takes serial numbers of at most 15 bytes.
            let mut serial = format!("RV{i}-{name}");
            while serial.len() > 15 {
                serial.pop();
            }
            CameraSpec {
                name,
                device: DeviceSpec::Fake { serial, view },
            }
        })
        .collect();
    Ok(FakeCameras {
        cameras,
        capture,
        rig: render.rig().clone(),
    })
}
