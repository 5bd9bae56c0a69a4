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
use std::time::{SystemTime, UNIX_EPOCH};

use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::sim::{FillRequest, SimRender};
use rigview_core::source::FrameMeta;

use super::LiveError;

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
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
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
/// knows but Mono12.
pub fn check_format(format: PixelFormat) -> Result<(), LiveError> {
    match format {
        PixelFormat::Mono8
        | PixelFormat::Mono16
        | PixelFormat::Rgb8
        | PixelFormat::BayerRg8
        | PixelFormat::BayerGr8
        | PixelFormat::BayerGb8
        | PixelFormat::BayerBg8 => Ok(()),
        PixelFormat::Mono12 => Err(LiveError::Config {
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
