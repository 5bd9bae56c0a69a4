//! Which cameras a live source opens ([`LiveSpec`]): a rig file's cameras,
//! or Aravis's in-process fake cameras showing a simulated rig; and opening
//! them.

use std::path::PathBuf;

use super::config::CaptureConfig;
use super::fake::FakeRig;

/// What a live source opens, and how it captures.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveSpec {
    /// Which cameras.
    pub cameras: LiveCameras,
    /// What is configured on each camera and how capture runs.
    pub capture: CaptureConfig,
    /// Frame sets before the source ends (`None`: never).
    pub frames: Option<u64>,
}

/// Which cameras a live source opens.
#[derive(Clone, Debug, PartialEq)]
pub enum LiveCameras {
    /// The cameras of a rig file (rigview rig YAML), each by its `device`
    /// (GenICam id or IP address); the rig's calibration gives the view.
    Rig(PathBuf),
    /// Aravis's in-process fake cameras showing a simulated rig, one per
    /// simulated camera; the simulated rig's calibration gives the view.
    Fake(FakeRig),
}

impl LiveSpec {
    /// What the cameras are, in words.
    pub fn describe(&self) -> String {
        match &self.cameras {
            LiveCameras::Rig(path) => path.display().to_string(),
            LiveCameras::Fake(f) => format!("Aravis fake cameras showing \"{}\"", f.scenario),
        }
    }
}

/// An open live source: the source, and the rig it comes with (its
/// calibration gives the view).
#[cfg(feature = "aravis")]
#[derive(Debug)]
pub struct Opened {
    /// The streaming cameras.
    pub source: super::LiveSource,
    /// The rig (the rig file's, or the simulated rig's).
    pub rig: rigview_calib::Rig,
}

/// Opens the cameras `spec` names, one after another, and starts
/// streaming.
#[cfg(feature = "aravis")]
pub fn open(spec: &LiveSpec) -> anyhow::Result<Opened> {
    use anyhow::Context;

    let (cameras, capture, rig) = match &spec.cameras {
        LiveCameras::Rig(path) => {
            let rig = rigview_calib::formats::load(path, None, None)
                .with_context(|| format!("reading the rig file {}", path.display()))?
                .rig;
            (
                super::CameraSpec::from_rig(&rig)?,
                spec.capture.clone(),
                rig,
            )
        }
        LiveCameras::Fake(fake) => {
            let cameras = super::fake::cameras(fake, &spec.capture)?;
            (cameras.cameras, cameras.capture, cameras.rig)
        }
    };
    let source = super::LiveSource::open(cameras, capture)?;
    Ok(Opened { source, rig })
}
