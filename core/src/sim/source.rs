//! The simulated rig as a frame source.
//!
//! [`SimRig`] implements [`FrameSource`]: one frame set per trigger, every
//! camera exposed with the setting it has at that trigger. Commands take
//! effect `latency` triggers late: with latency `L`, a command applied
//! before set `n` is produced first shows in set `n + L` (0: in the very
//! next set). Every frame reports the setting it was taken with.
//!
//! With the cameras' own auto-exposure switched on
//! ([`FrameSource::set_camera_auto`]), each camera runs the built-in AE of
//! [`super::camera_ae`] on its own frames, with the same latency, and
//! rigview's commands are ignored (a camera locks its exposure features
//! while its own auto-exposure runs).
//!
//! Simulation time is `trigger / trigger_hz`, whatever the wall clock does;
//! [`Pacing::Realtime`] also holds each set back until its trigger's moment,
//! [`Pacing::AsFastAsAsked`] renders each set when asked.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::actuation::Actuation;
use super::camera_ae::CameraAeParams;
use super::render::{FillRequest, SimRender};
use crate::exposure::{ExposureSetting, Meter, MeteringConfig};
use crate::source::{
    check_command, wait_until, CameraInfo, ExposureCommand, Frame, FrameSet, FrameSource,
    RateMeter, SourceError, StreamHealth,
};

/// When a set is produced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Pacing {
    /// At once, whenever asked.
    #[default]
    AsFastAsAsked,
    /// At the trigger rate of the wall clock.
    Realtime,
}

/// Options of a [`SimRig`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimRigOptions {
    /// When sets are produced.
    pub pacing: Pacing,
    /// Triggers before the source finishes (`None`: never).
    pub frames: Option<u64>,
    /// Frames between a command and the first frame that shows it (0 to 2;
    /// `None`: the configuration's).
    pub latency: Option<u32>,
    /// The cameras' own auto-exposure, while it is switched on.
    pub camera_ae: CameraAeParams,
}

impl Default for SimRigOptions {
    fn default() -> Self {
        Self {
            pacing: Pacing::AsFastAsAsked,
            frames: None,
            latency: None,
            camera_ae: CameraAeParams::default(),
        }
    }
}

/// The simulated rig (see the module documentation).
#[derive(Debug)]
pub struct SimRig {
    render: Arc<SimRender>,
    options: SimRigOptions,
    settings: Vec<ExposureSetting>,
    actuation: Actuation,
    trigger: u64,
    started: Option<Instant>,
    rate: RateMeter,
    health: Vec<StreamHealth>,
    /// Whether the cameras' own auto-exposure runs.
    camera_auto: bool,
    /// Per camera, the setting its own auto-exposure last chose (queued or
    /// in force).
    ae_setting: Vec<ExposureSetting>,
    /// The whole-image metering of the cameras' own auto-exposure.
    ae_meter: Meter,
}

impl SimRig {
    /// A source on `render`; every camera starts at the configuration's
    /// start setting.
    pub fn new(render: Arc<SimRender>, options: SimRigOptions) -> Result<Self, SourceError> {
        let latency = options.latency.unwrap_or(render.config().latency_frames);
        if latency > 2 {
            return Err(SourceError::Failed(format!(
                "simulated rig: latency {latency} frames: expected 0, 1 or 2"
            )));
        }
        options.camera_ae.validate()?;
        let n = render.cameras().len();
        Ok(Self {
            camera_auto: false,
            ae_setting: vec![render.config().start; n],
            ae_meter: Meter::new(MeteringConfig::default())?,
            settings: vec![render.config().start; n],
            health: vec![StreamHealth::default(); n],
            render,
            options,
            actuation: Actuation::new(u64::from(latency)),
            trigger: 0,
            started: None,
            rate: RateMeter::default(),
        })
    }

    /// The renderer (share it with a fake camera's callback or the ground
    /// truth).
    pub fn render(&self) -> &Arc<SimRender> {
        &self.render
    }

    /// The setting camera `i` has now (`None`: no such camera).
    pub fn setting(&self, i: usize) -> Option<ExposureSetting> {
        self.settings.get(i).copied()
    }

    /// Sets every camera at once, with no latency (as at start-up, after the
    /// cameras' own auto-exposure), and forgets queued commands.
    pub fn force_all(&mut self, setting: ExposureSetting) {
        self.settings.fill(setting);
        self.ae_setting.fill(setting);
        self.actuation.clear();
    }

    /// Whether the cameras' own auto-exposure runs.
    pub fn camera_auto(&self) -> bool {
        self.camera_auto
    }

    /// Camera `i`'s own auto-exposure after its frame `frame`: queues the
    /// setting it chooses.
    fn camera_ae(&mut self, i: usize, frame: &Frame) -> Result<(), SourceError> {
        let mean = f64::from(self.ae_meter.meter(&frame.view()?, None)?.stats().mean);
        let range = self.render.cameras()[i].range;
        if let Some(setting) =
            self.options
                .camera_ae
                .next(mean, frame.meta.taken, self.ae_setting[i], &range)
        {
            self.ae_setting[i] = setting;
            self.actuation
                .send(self.trigger + 1, ExposureCommand { camera: i, setting });
        }
        Ok(())
    }

    /// The next trigger's number (sets produced so far).
    pub fn trigger(&self) -> u64 {
        self.trigger
    }

    /// The actuation latency, frames.
    pub fn latency(&self) -> u64 {
        self.actuation.latency()
    }

    /// Renders the set of the current trigger.
    fn produce(&mut self) -> Result<FrameSet, SourceError> {
        let n = self.trigger;
        self.actuation.apply_due(n, &mut self.settings);
        let mut frames = Vec::with_capacity(self.settings.len());
        for (i, setting) in self.settings.iter().enumerate() {
            let info = &self.render.cameras()[i];
            let req = FillRequest::new(i, n, *setting, info.format, info.width, info.height);
            let mut buf = vec![0u8; req.buffer_len()];
            let meta = self.render.fill(&req, &mut buf)?;
            frames.push(Some(Frame::new(meta, buf.into())?));
        }
        if self.camera_auto {
            for (i, f) in frames.iter().enumerate() {
                if let Some(f) = f {
                    self.camera_ae(i, f)?;
                }
            }
        }
        let fps = self.rate.tick();
        for h in &mut self.health {
            h.completed += 1;
            h.fps = fps;
        }
        self.trigger += 1;
        let t = self.render.time_of(n);
        Ok(FrameSet {
            trigger: n,
            timestamp_ns: (t * 1e9).round() as u64,
            frames,
        })
    }
}

impl FrameSource for SimRig {
    fn cameras(&self) -> &[CameraInfo] {
        self.render.cameras()
    }

    fn next_set(&mut self, timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        if self.is_finished() {
            return Ok(None);
        }
        if self.options.pacing == Pacing::Realtime {
            let start = *self.started.get_or_insert_with(Instant::now);
            let due = start + Duration::from_secs_f64(self.render.time_of(self.trigger));
            if !wait_until(due, timeout) {
                return Ok(None);
            }
        }
        self.produce().map(Some)
    }

    fn apply(&mut self, commands: &[ExposureCommand]) -> Result<(), SourceError> {
        let n = self.settings.len();
        for c in commands {
            check_command(c, n)?;
            let s = c.setting;
            if !(s.shutter_us.is_finite() && s.gain_db.is_finite() && s.shutter_us > 0.0) {
                return Err(SourceError::Camera {
                    camera: c.camera,
                    name: self.render.cameras()[c.camera].name.clone(),
                    message: format!(
                        "exposure {} µs, gain {} dB: expected a positive time and a finite gain",
                        s.shutter_us, s.gain_db
                    ),
                });
            }
        }
        if self.camera_auto {
            // The cameras' own auto-exposure holds their exposure.
            return Ok(());
        }
        for c in commands {
            // A camera clamps a setting to its ranges, as GenICam features do.
            let r = &self.render.cameras()[c.camera].range;
            let setting = ExposureSetting {
                shutter_us: c
                    .setting
                    .shutter_us
                    .clamp(r.shutter_min_us, r.shutter_max_us),
                gain_db: c.setting.gain_db.clamp(r.gain_min_db, r.gain_max_db),
            };
            self.actuation.send(
                self.trigger,
                ExposureCommand {
                    camera: c.camera,
                    setting,
                },
            );
        }
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.health.clone()
    }

    fn is_finished(&self) -> bool {
        self.options.frames.is_some_and(|f| self.trigger >= f)
    }

    fn has_camera_auto(&self) -> bool {
        true
    }

    fn set_camera_auto(&mut self, on: bool) -> Result<(), SourceError> {
        if on && !self.camera_auto {
            // The AE starts from where each camera will be once rigview's
            // commands in flight have shown.
            for (i, s) in self.settings.iter().enumerate() {
                self.ae_setting[i] = self.actuation.pending(i).unwrap_or(*s);
            }
        }
        self.camera_auto = on;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_render;
    use super::*;
    use crate::source::FrameStatus;

    const WAIT: Duration = Duration::from_secs(1);

    fn setting(shutter_us: f64) -> ExposureSetting {
        ExposureSetting {
            shutter_us,
            gain_db: 0.0,
        }
    }

    fn mean(f: &Frame) -> f64 {
        f.data.iter().map(|&v| f64::from(v)).sum::<f64>() / f.data.len() as f64
    }

    #[test]
    fn commands_show_after_the_latency() {
        for latency in 0..=2u32 {
            let mut rig = SimRig::new(
                test_render(),
                SimRigOptions {
                    latency: Some(latency),
                    ..Default::default()
                },
            )
            .unwrap();
            rig.force_all(setting(100.0));
            let first = rig.next_set(WAIT).unwrap().unwrap();
            let before = mean(first.frames[1].as_ref().unwrap());
            rig.apply(&[ExposureCommand {
                camera: 1,
                setting: setting(200.0),
            }])
            .unwrap();
            for k in 0..=u64::from(latency) + 1 {
                let set = rig.next_set(WAIT).unwrap().unwrap();
                let f = set.frames[1].as_ref().unwrap();
                let shows = k >= u64::from(latency);
                let expected = if shows { 200.0 } else { 100.0 };
                assert!(
                    (f.meta.taken.shutter_us - expected).abs() < 1e-9,
                    "latency {latency}, set {k} after the command: taken {:?}",
                    f.meta.taken
                );
                // The pixels agree with the metadata.
                let ratio = mean(f) / before;
                assert!(
                    (ratio - expected / 100.0).abs() < 0.1,
                    "latency {latency}, set {k}: brightness ratio {ratio:.3}"
                );
                // The other cameras keep their setting.
                let other = set.frames[0].as_ref().unwrap();
                assert!((other.meta.taken.shutter_us - 100.0).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn frames_carry_their_metadata_and_the_health_counts_them() {
        let render = test_render();
        let mut rig = SimRig::new(
            render.clone(),
            SimRigOptions {
                frames: Some(3),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(rig.cameras().len(), 4);
        for n in 0..3u64 {
            let set = rig.next_set(WAIT).unwrap().unwrap();
            assert!(set.is_complete());
            assert_eq!(set.trigger, n);
            assert_eq!(set.timestamp_ns, n * 50_000_000, "20 Hz");
            assert_eq!(set.timestamp_skew_ns(), 0, "hardware-triggered");
            for (i, f) in set.frames.iter().enumerate() {
                let f = f.as_ref().unwrap();
                let info = &render.cameras()[i];
                assert_eq!(f.meta.camera, i);
                assert_eq!(f.meta.frame_id, n);
                assert_eq!((f.meta.width, f.meta.height), (info.width, info.height));
                assert_eq!(f.meta.format, info.format);
                assert_eq!(f.meta.status, FrameStatus::Complete);
                assert_eq!(f.meta.taken, render.config().start);
                assert!(f.view().is_ok());
            }
        }
        assert!(rig.is_finished());
        assert!(rig.next_set(WAIT).unwrap().is_none());
        assert!(rig
            .health()
            .iter()
            .all(|h| h.completed == 3 && h.failed == 0));
    }

    #[test]
    fn the_cameras_own_auto_exposure_reaches_its_target_and_ignores_commands() {
        let mut rig = SimRig::new(test_render(), SimRigOptions::default()).unwrap();
        rig.force_all(setting(20.0));
        assert!(rig.has_camera_auto());
        rig.set_camera_auto(true).unwrap();
        let meter = Meter::new(MeteringConfig::default()).unwrap();
        let params = CameraAeParams::default();
        let mut last = Vec::new();
        for _ in 0..60 {
            let set = rig.next_set(WAIT).unwrap().unwrap();
            // Commands are ignored while the cameras' own AE runs.
            rig.apply(&[ExposureCommand {
                camera: 0,
                setting: setting(10.0),
            }])
            .unwrap();
            last = set
                .frames
                .iter()
                .map(|f| {
                    let f = f.as_ref().unwrap();
                    let m = meter.meter(&f.view().unwrap(), None).unwrap();
                    (f64::from(m.stats().mean), f.meta.taken)
                })
                .collect();
        }
        for (i, (mean, taken)) in last.iter().enumerate() {
            // Within the dead band of its target, give or take the noise.
            let off = (mean / params.target).log2().abs();
            assert!(
                off <= params.dead_band_ev + 0.02,
                "camera {i}: mean {mean:.3} at {taken:?}"
            );
        }
        // Switched off, the cameras keep their setting and obey again.
        rig.set_camera_auto(false).unwrap();
        let before = rig.setting(2).unwrap();
        rig.next_set(WAIT).unwrap();
        assert_eq!(rig.setting(2).unwrap(), before);
    }

    #[test]
    fn a_realtime_rig_keeps_the_trigger_rate() {
        let mut rig = SimRig::new(
            test_render(),
            SimRigOptions {
                pacing: Pacing::Realtime,
                ..Default::default()
            },
        )
        .unwrap();
        let start = Instant::now();
        assert!(rig.next_set(WAIT).unwrap().is_some());
        // The next trigger is 50 ms away: a 1 ms wait gives nothing.
        assert!(rig.next_set(Duration::from_millis(1)).unwrap().is_none());
        assert!(rig.next_set(WAIT).unwrap().is_some());
        assert!(start.elapsed() >= Duration::from_millis(49));
    }

    #[test]
    fn bad_commands_are_refused_and_ranges_clamped() {
        let mut rig = SimRig::new(
            test_render(),
            SimRigOptions {
                latency: Some(0),
                ..Default::default()
            },
        )
        .unwrap();
        let bad = |camera, shutter_us| ExposureCommand {
            camera,
            setting: setting(shutter_us),
        };
        assert!(rig.apply(&[bad(4, 100.0)]).is_err());
        assert!(rig.apply(&[bad(0, f64::NAN)]).is_err());
        assert!(rig.apply(&[bad(0, -5.0)]).is_err());
        rig.apply(&[ExposureCommand {
            camera: 0,
            setting: ExposureSetting {
                shutter_us: 1.0,
                gain_db: 40.0,
            },
        }])
        .unwrap();
        rig.next_set(WAIT).unwrap();
        let s = rig.setting(0).unwrap();
        assert_eq!((s.shutter_us, s.gain_db), (10.0, 24.0));
        assert!(SimRig::new(
            test_render(),
            SimRigOptions {
                latency: Some(3),
                ..Default::default()
            }
        )
        .is_err());
    }
}
