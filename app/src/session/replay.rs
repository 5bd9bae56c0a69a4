//! A recording as a session's source (`--source replay:FILE`, *File →
//! Open recording…*): its calibration, or `--rig`'s checked against it, and
//! the window's hold on it (`ReplayControl`: pause, steps, seeks, speed,
//! held at its end).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use rigview_calib::Rig;
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{Notify, PipelineOptions, ProcessingSettings, Processor};
use rigview_core::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
};
use rigview_record::ReplaySource;

use super::control::{ReplayControl, GIVEN_KEPT};
use super::record::RecordSpec;
use super::start::{start_session, Origin, Session};
use super::view::view_for;

/// A recording to replay.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplaySpec {
    /// The recording.
    pub file: PathBuf,
    /// A calibration to use instead of the recording's own.
    pub rig: Option<PathBuf>,
    /// Replayed under the window's controls ([`ReplayControl`]): held at
    /// its end (paused) instead of finishing, so that it can be sought
    /// back.
    pub interactive: bool,
}

/// The calibration a replay uses: `--rig` if given (it must fit the
/// recording), else the recording's attachment.
fn replay_rig(spec: &ReplaySpec, source: &ReplaySource) -> Result<Option<(Rig, String)>> {
    let file = &spec.file;
    if let Some(path) = &spec.rig {
        let rig = rigview_calib::formats::load(path, None, None)
            .with_context(|| format!("cannot load the calibration {}", path.display()))?
            .rig;
        let cameras = source.cameras();
        if rig.cameras.len() != cameras.len() {
            anyhow::bail!(
                "the calibration {} has {} cameras, the recording {} has {}",
                path.display(),
                rig.cameras.len(),
                file.display(),
                cameras.len()
            );
        }
        for (r, c) in rig.cameras.iter().zip(cameras) {
            let size = (r.intrinsics.width as usize, r.intrinsics.height as usize);
            if size != (c.width, c.height) {
                anyhow::bail!(
                    "the calibration {} has camera \"{}\" at {}×{}, the recording {} has \"{}\" at {}×{}",
                    path.display(),
                    r.name,
                    size.0,
                    size.1,
                    file.display(),
                    c.name,
                    c.width,
                    c.height
                );
            }
        }
        return Ok(Some((rig, path.display().to_string())));
    }
    match &source.meta().rig_yaml {
        Some(text) => {
            let name = format!("{} (attachment rig.yaml)", file.display());
            let rig = rigview_calib::formats::rig_yaml::parse(text, &name)
                .with_context(|| format!("the rig recorded in {}", file.display()))?;
            Ok(Some((rig, name)))
        }
        None => Ok(None),
    }
}

/// Starts a session on a recording: open loop, the recorded frames through
/// the processing of `processing` (and into `record`, if given).
pub fn start_replay(
    spec: &ReplaySpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
) -> Result<Session> {
    let source = ReplaySource::open(&spec.file)
        .with_context(|| format!("cannot replay {}", spec.file.display()))?;
    let cameras = source.cameras().to_vec();
    let rig = replay_rig(spec, &source)?;
    let (view, graph, calibration) = match &rig {
        Some((rig, name)) => {
            let (v, g) = view_for(rig, &cameras, processing)
                .with_context(|| format!("the view of {name}"))?;
            (Some(v), g, name.clone())
        }
        None => (
            None,
            NeighbourGraph::new(cameras.len(), &[])?,
            "none".into(),
        ),
    };
    let processor = Processor::new(cameras.clone(), view, graph, processing.clone())?;
    let origin = Origin {
        source_name: format!(
            "replay of {} ({} cameras)",
            spec.file.display(),
            cameras.len()
        ),
        calibration,
        rig: rig.as_ref().map(|(r, _)| r),
        time_offset_ns: source.meta().time_offset_ns,
    };
    // In the window: at the recorded rate; in lock step as fast as asked.
    let speed = (!options.lockstep).then_some(1.0);
    let (source, control) = Controlled::new(source, speed, spec.interactive);
    let mut session = start_session(source, processor, options, notify, record, origin)?;
    session.replay = Some(control);
    Ok(session)
}

/// A [`ReplaySource`] under a [`ReplayControl`].
struct Controlled {
    inner: ReplaySource,
    control: ReplayControl,
    /// Held at the end instead of finishing.
    hold: bool,
    speed: Option<f64>,
    was_paused: bool,
    messages: Vec<String>,
}

impl Controlled {
    fn new(mut inner: ReplaySource, speed: Option<f64>, hold: bool) -> (Self, ReplayControl) {
        inner.set_speed(speed);
        let control =
            ReplayControl::new(inner.file().to_owned(), inner.times().map(Arc::from), speed);
        let source = Self {
            inner,
            control: control.clone(),
            hold,
            speed,
            was_paused: false,
            messages: Vec::new(),
        };
        (source, control)
    }

    /// Carries out the window's requests; whether a set is to be given now
    /// even though the replay is paused.
    fn apply_requests(&mut self) -> (bool, bool) {
        let (seek, steps, speed, paused, shown) = {
            let mut s = self.control.lock();
            (
                s.seek.take(),
                std::mem::take(&mut s.steps),
                s.speed.take(),
                s.paused,
                s.shown,
            )
        };
        if let Some(speed) = speed {
            self.speed = speed;
            self.inner.set_speed(speed);
        }
        if !paused && self.was_paused {
            // The pause is not replayed: the clock starts again now.
            self.inner.set_speed(self.speed);
        }
        self.was_paused = paused;
        let mut one = false;
        if let Some(k) = seek {
            match self.inner.seek(k) {
                Ok(()) => one = true,
                Err(e) => self.messages.push(e.to_string()),
            }
        }
        if steps != 0 {
            let from = shown.map_or(-1, |k| i64::try_from(k).unwrap_or(i64::MAX));
            let target = usize::try_from(from.saturating_add(steps).max(0)).unwrap_or(0);
            if self.inner.position().is_some() {
                match self.inner.seek(target) {
                    Ok(()) => one = true,
                    Err(e) => self.messages.push(e.to_string()),
                }
            } else if steps == 1 {
                // Without the index the next set is the only one to step to.
                one = true;
            } else {
                self.messages.push(format!(
                    "{}: the file has no index, so it steps forward one set at a time only; \
                     `rigview recording repair` rewrites it with one",
                    self.inner.file().display()
                ));
            }
        }
        if one {
            // Given at once, whatever the pacing.
            self.inner.set_speed(self.speed);
        }
        (paused, one)
    }
}

impl FrameSource for Controlled {
    fn cameras(&self) -> &[CameraInfo] {
        self.inner.cameras()
    }

    fn next_set(&mut self, timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        let (paused, one) = self.apply_requests();
        if paused && !one {
            std::thread::sleep(timeout.min(Duration::from_millis(20)));
            return Ok(None);
        }
        let k = self.inner.position();
        // A paced wait is cut short, so that a pause takes effect within
        // 20 ms.
        let got = self.inner.next_set(timeout.min(Duration::from_millis(20)));
        let mut s = self.control.lock();
        match &got {
            Ok(Some(set)) => {
                let n = k.unwrap_or_else(|| s.shown.map_or(0, |n| n + 1));
                s.shown = Some(n);
                s.given.push_back((set.trigger, n));
                if s.given.len() > GIVEN_KEPT {
                    s.given.pop_front();
                }
                s.at_end = false;
            }
            Ok(None) if self.inner.is_finished() => {
                s.at_end = true;
                if self.hold {
                    s.paused = true;
                }
            }
            Ok(None) | Err(_) => {}
        }
        got
    }

    fn apply(&mut self, _commands: &[ExposureCommand]) -> Result<(), SourceError> {
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.inner.health()
    }

    fn is_finished(&self) -> bool {
        !self.hold && self.inner.is_finished()
    }

    fn take_messages(&mut self) -> Vec<String> {
        let mut m = std::mem::take(&mut self.messages);
        m.extend(self.inner.take_messages());
        m
    }
}
