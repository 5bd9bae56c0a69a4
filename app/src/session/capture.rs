//! The sources a capture without processing opens (`rigview record`, in a
//! recording or as exposure brackets): the simulated rig paced at its
//! trigger rate, or live cameras with their calibration when it fits them.

use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use rigview_calib::Rig;
#[cfg(feature = "aravis")]
use rigview_core::pipeline::ProcessingSettings;
use rigview_core::sim::{Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::FrameSource;

#[cfg(feature = "aravis")]
use super::view::view_for;
use crate::live::LiveSpec;

/// What `rigview record` captures from.
#[derive(Debug)]
pub enum CaptureFrom {
    /// The simulated rig at its trigger rate.
    Sim {
        /// A preset or simulation file.
        scenario: String,
        /// Render scale.
        scale: f64,
    },
    /// Live cameras.
    Live(Box<LiveSpec>),
}

/// A source opened for `rigview record`.
pub(crate) struct Opened {
    /// The source.
    pub source: Box<dyn FrameSource>,
    /// Its calibration, when it fits the source's cameras.
    pub rig: Option<Rig>,
    /// What it is, for the recording's metadata.
    pub what: String,
    pub time_offset_ns: u64,
}

/// Opens what `rigview record` captures from (the simulated rig paced at
/// its trigger rate).
pub(crate) fn open(from: &CaptureFrom) -> Result<Opened> {
    Ok(match from {
        CaptureFrom::Sim { scenario, scale } => {
            let mut config = SimConfig::named(scenario)
                .with_context(|| format!("loading the simulation \"{scenario}\""))?;
            config.scale = *scale;
            let render = Arc::new(SimRender::new(&config).context("building the simulated rig")?);
            let rig = render.rig().clone();
            let source = SimRig::new(
                render,
                SimRigOptions {
                    pacing: Pacing::Realtime,
                    ..Default::default()
                },
            )?;
            Opened {
                source: Box::new(source),
                rig: Some(rig),
                what: format!("simulated rig \"{scenario}\""),
                // The simulation's clock starts at 0.
                time_offset_ns: rigview_record::writer::unix_now_ns(),
            }
        }
        CaptureFrom::Live(spec) => open_live(spec)?,
    })
}

/// `--seconds S` as a duration.
pub(crate) fn time_limit(seconds: Option<f64>) -> Result<Option<Duration>> {
    seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .context("--seconds: expected a number of seconds ≥ 0")
}

#[cfg(feature = "aravis")]
fn open_live(spec: &LiveSpec) -> Result<Opened> {
    let crate::live::Opened { source, rig } = crate::live::open(spec)?;
    let fits = view_for(&rig, source.cameras(), &ProcessingSettings::default()).is_ok();
    Ok(Opened {
        source: Box::new(source),
        rig: fits.then_some(rig),
        what: spec.describe(),
        // Live sets are stamped with the host's Unix time.
        time_offset_ns: 0,
    })
}

#[cfg(not(feature = "aravis"))]
fn open_live(_spec: &LiveSpec) -> Result<Opened> {
    Err(crate::live::LiveError::NoAravis.into())
}
