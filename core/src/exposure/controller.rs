//! Per-camera and per-rig controllers: the feedback loop of Algorithm 1.
//!
//! A [`CameraController`] turns one metered frame and the setting it was
//! *taken* with into the camera's own desired exposure (the unary term). It
//! copes with actuation latency: after it has sent a command it waits until a
//! frame taken with that command arrives (or until `latency_timeout_frames`
//! frames have passed) before it reacts again, so it never reacts twice to the
//! same command. A [`RigController`] runs one per camera, balances neighbours
//! (Eq. 5/6) when balancing is on, and splits the result into shutter and
//! gain.

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

use super::balance::{self, BalanceParams, NeighbourGraph, PatchPair};
use super::baselines::{MeanIntensityParams, PidParams, PidState};
use super::bracket::{Bracket, BracketParams, Repeller};
use super::estimator::{
    Darker, Estimate, EstimateOptions, Estimator, EstimatorConfig, Simulation, DARKER_MIN_EV,
};
use super::laws::{LawKind, LawParams, LawStep};
use super::levels::{LevelFrame, LevelWalker, Request};
use super::light::{LightChange, LightParams, LightTracker};
use super::metering::Metered;
use super::probe::{ProbeEvent, ProbeInput, ProbeParams, Prober};
use super::split::{Clamped, ExposureRange, ExposureSetting, SplitParams, Splitter};
use super::tone::ToneCurve;
use crate::error::{check_range, Error, Result};

mod config;
mod rig;

pub use config::{ControlMode, ControllerConfig};
pub use rig::{CameraInput, CameraStep, PairObservation, PairRatio, RigController, RigStep};

/// What a frame was taken with.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameInfo {
    /// The camera's frame id.
    pub frame_id: u64,
    /// The setting the frame was exposed with.
    pub taken: ExposureSetting,
}

/// Why a camera sends no new command this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Hold {
    /// The last command has not shown in a frame yet.
    AwaitingCommand,
    /// This frame id was seen already.
    RepeatedFrame,
    /// The target equals the current setting.
    Settled,
}

/// Above this saturated fraction the metric sees too little of the image
/// (neither simulation can look into saturated regions reliably), and the
/// mean-intensity step is taken instead.
pub const SATURATED_FALLBACK: f32 = 0.8;

/// Tolerance (relative) for "this frame shows the commanded exposure".
const SETTLED_TOLERANCE: f64 = 2e-3;

/// A command sent that no frame has shown yet.
#[derive(Clone, Copy, Debug, PartialEq)]
struct InFlight {
    /// The setting in force before it: the previous command's, or the
    /// frame's when it was sent.
    from: ExposureSetting,
    /// The command.
    setting: ExposureSetting,
    /// The controller's frame count when it was sent.
    sent: u64,
    /// Whether the camera reacts to no frame until this command shows (a
    /// probe, the return from one, a PID step).
    must_show: bool,
    /// When it is a probe: its home, the exposure the camera probed from
    /// and rests at unless the probe measures better.
    home: Option<f64>,
}

/// The newest of `in_flight` that a frame taken at exposure `e` shows: the
/// command whose setting lies nearest the frame's (in log exposure), when
/// it equals it to 0.2 % or lies nearer than the setting the camera had
/// before the oldest of them. Cameras quantise exposure time (whole
/// microseconds, sensor rows), so what they apply may differ slightly
/// from what was commanded; and with more than one command in flight a
/// later one may lead back towards where the camera was, so a frame still
/// at the old setting must not be taken for it.
fn shown(in_flight: &VecDeque<InFlight>, e: f64) -> Option<usize> {
    let before = in_flight.front()?.from.exposure();
    let dist = |to: f64| (e / to).ln().abs();
    let (k, d) = in_flight
        .iter()
        .enumerate()
        .map(|(k, c)| (k, dist(c.setting.exposure())))
        .fold(None, |best: Option<(usize, f64)>, (k, d)| match best {
            Some((_, b)) if b < d => best,
            _ => Some((k, d)),
        })?;
    (d <= SETTLED_TOLERANCE || d < dist(before)).then_some(k)
}

/// A frame within this (EV) of where the commands in flight leave the
/// camera shows it at rest.
const REST_EV: f64 = 0.03;

/// At most this many commands are remembered in flight (more than any
/// camera's latency in frames).
const MAX_IN_FLIGHT: usize = 8;

/// The unary step of one camera.
#[derive(Clone, Debug, PartialEq)]
pub struct UnaryStep {
    /// The estimate (gradient and PID modes).
    pub estimate: Option<Estimate>,
    /// The exposure the frame was taken with.
    pub taken: f64,
    /// The camera's own desired exposure `E_{t+1}`.
    pub desired: f64,
    /// Set when the camera must not react to this frame.
    pub hold: Option<Hold>,
    /// Set when the metric had no information (or the image was more than
    /// [`SATURATED_FALLBACK`] saturated) and a mean-intensity step was taken
    /// instead.
    pub fallback: bool,
    /// What a darker probe did on this frame ([`super::probe`]); when set,
    /// `desired` is the probe's or the settled exposure, not the law's.
    pub probe: Option<ProbeEvent>,
    /// Whether the frame was taken at a probe's darker exposure (a view
    /// shows it at its neighbours' brightness; measures of the loop leave
    /// it out).
    pub probe_frame: bool,
    /// The uniform change of light followed on this frame
    /// ([`super::light`]): `desired` is the exposure commanded in the
    /// reference frame's light, moved by it, and balancing leaves it so.
    pub light: Option<LightChange>,
}

/// One camera's controller.
#[derive(Clone, Debug)]
pub struct CameraController {
    estimator: Estimator,
    splitter: Splitter,
    pid: PidState,
    /// Commands sent that no frame has shown yet, oldest first.
    in_flight: VecDeque<InFlight>,
    /// Frames seen: the clock of `in_flight`.
    frames: u64,
    /// Whether the next command must show before the camera reacts again.
    must_show: bool,
    /// Whether the next command is a probe: its home when it is.
    probe_next: Option<f64>,
    /// Whether the latest frame was taken at a probe's exposure (from the
    /// frame that shows a probe until the next command shows, or the probe
    /// is taken).
    probe_frame: bool,
    /// The home of the probe the latest frame shows.
    probe_home: Option<f64>,
    last_frame: Option<u64>,
    manual: Option<f64>,
    damping: balance::Damping,
    prober: Prober,
    last_probe: Option<ProbeEvent>,
    /// Reacquiring after mostly saturated frames (scale-and-clip,
    /// [`ProbeParams::reacquire_saturated`]), a camera under its own law:
    /// where it rests again, it probes with a ladder.
    reacquiring: bool,
    /// Whether the latest frame the camera reacted to was under
    /// scale-and-clip's probing: the first such frame (the camera's first,
    /// or the first after a change of mode or simulation) may start a
    /// reacquisition ([`ProbeParams::reacquire_start_saturated`]).
    was_clip_probing: bool,
    /// Whether this frame's command is a balanced camera's probe, or the
    /// return from one: balancing leaves it as it is.
    probe_alone: bool,
    /// Whether the latest frame the camera reacted to was under its own
    /// law, or PID alone (the two that probe alone): what its prober learnt
    /// does not carry over into balancing or out of it.
    was_own_law: bool,
    /// The frame of the latest probe that measured no better, kept while
    /// the camera rests after it: scale-and-clip reads from it what the
    /// saturated pixels hide. (A metered frame: about 1 MB at the
    /// default 322×241 with a mask and block saturation.)
    darker: Option<ProbeFrame>,
    /// The latest frame after which the camera's own law sent it brighter
    /// (scale-and-clip), or the frame of a probe (a ladder's rung) that
    /// measured better, from which the law goes on: the frames that follow
    /// are brighter, and read from it what their saturated pixels hide
    /// while it matches their scene. Kept only while the camera moves up,
    /// so a camera at rest copies nothing.
    passed: Option<ProbeFrame>,
    /// The bracket of the best exposure under the camera's own law.
    bracket: Bracket,
    /// The fast law's choice between frames that point apart.
    repeller: Repeller,
    /// The reference frame a change of light is measured against.
    light: LightTracker,
    /// The change of light (EV, against the reference) the kept frames'
    /// exposures have been scaled to.
    kept_light_ev: f64,
    /// Whether this frame became the light's reference: the exposure
    /// commanded on it (after balancing) is the one a change of light moves.
    fresh_reference: bool,
    /// The levels of a camera that takes only a fixed set
    /// ([`crate::source::CameraInfo::levels`]), and where it goes on them.
    walker: Option<LevelWalker>,
    /// The latest frame's request to the walker: the frame, the law's
    /// request from its exposure (EV), how to read it, and the exposure
    /// the camera's own law desired (balancing moves the request by the
    /// target's ratio to it).
    level_request: Option<LevelRequest>,
    /// The camera's own tone curve ([`Self::set_tone_curve`]).
    tone: Option<ToneCurve>,
    /// [`Self::tone_power`], computed when the curve is set.
    tone_power: f64,
}

/// A kept frame as the estimator reads it, when it is at least
/// [`DARKER_MIN_EV`] darker than a frame taken at `taken`.
fn usable_darker(kept: Option<&ProbeFrame>, taken: f64) -> Option<Darker<'_>> {
    kept.and_then(|d| {
        let ratio = d.exposure / taken;
        (ratio.log2() <= -DARKER_MIN_EV).then_some(Darker {
            image: &d.image,
            ratio,
        })
    })
}

/// A frame's request to the [`LevelWalker`] of a camera with fixed levels.
#[derive(Clone, Copy, Debug)]
struct LevelRequest {
    frame: LevelFrame,
    /// The law's request from the frame's exposure, EV.
    step_ev: f64,
    /// Where the estimate places the fixed point (`−ln γ̂`), for the
    /// incremental laws, whose steps are asymmetric (α of Eq. 3 and 4).
    signal: Option<f64>,
    /// The distance to the estimator's fixed point, EV, where the estimate
    /// gives it (scale-and-clip within the anchors' span).
    distance_ev: Option<f64>,
    kind: Request,
    /// The camera's own desired exposure: balancing moves the request by
    /// the target's ratio to it.
    desired: f64,
}

/// [`ToneCurve::nearest_power`] of `curve`, 1 without a curve or a power.
fn nearest_power(curve: Option<&ToneCurve>) -> f64 {
    curve.and_then(ToneCurve::nearest_power).unwrap_or(1.0)
}

/// A probe frame kept for the estimator.
#[derive(Clone, Debug)]
struct ProbeFrame {
    exposure: f64,
    image: Metered,
}

impl CameraController {
    /// A controller for a camera with `range`.
    pub fn new(config: &ControllerConfig, range: ExposureRange) -> Result<Self> {
        config.validate()?;
        let mut light = LightTracker::default();
        light.set_tone_curve(config.estimator.tone_curve.as_ref());
        Ok(Self {
            estimator: Estimator::new(config.estimator.clone())?,
            splitter: Splitter::new(range, config.split)?,
            pid: PidState::default(),
            in_flight: VecDeque::new(),
            frames: 0,
            must_show: false,
            probe_next: None,
            probe_frame: false,
            probe_home: None,
            last_frame: None,
            manual: None,
            damping: balance::Damping::default(),
            prober: Prober::default(),
            last_probe: None,
            reacquiring: false,
            was_clip_probing: false,
            probe_alone: false,
            was_own_law: false,
            darker: None,
            passed: None,
            bracket: Bracket::default(),
            repeller: Repeller::default(),
            light,
            kept_light_ev: 0.0,
            fresh_reference: false,
            walker: None,
            level_request: None,
            tone: None,
            tone_power: nearest_power(config.estimator.tone_curve.as_ref()),
        })
    }

    /// Tells the controller that the camera takes only these exposure
    /// levels (`None`: any within its range); see [`LevelWalker`].
    pub fn set_levels(&mut self, levels: Option<Vec<f64>>) {
        self.walker = levels.as_deref().and_then(LevelWalker::new);
        self.level_request = None;
    }

    /// Tells the controller the camera's tone curve, which its
    /// scale-and-clip estimate simulates through (`None`: the
    /// configuration's); see [`crate::exposure::ToneCurve`].
    pub fn set_tone_curve(&mut self, curve: Option<ToneCurve>) -> Result<()> {
        self.estimator.set_tone_curve(curve.clone())?;
        // The light tracking reads light under the curve whichever
        // simulation the estimate uses.
        self.light.set_tone_curve(self.estimator.tone_curve());
        self.tone_power = nearest_power(self.estimator.tone_curve());
        self.tone = curve;
        Ok(())
    }

    /// The power `p` nearest the curve the camera's frames are read through
    /// (`L = I^p`; [`ToneCurve::nearest_power`]), 1 for a linear camera or
    /// a curve without one.
    pub fn tone_power(&self) -> f64 {
        self.tone_power
    }

    /// The tone curve the camera's frames are read through: its own, or
    /// the configuration's (`None`: linear).
    pub fn tone_curve(&self) -> Option<&ToneCurve> {
        self.estimator.tone_curve()
    }

    /// The splitter (ranges and hysteresis state).
    pub fn splitter(&self) -> &Splitter {
        &self.splitter
    }

    /// The estimator.
    pub fn estimator_mut(&mut self) -> &mut Estimator {
        &mut self.estimator
    }

    /// Holds this camera at a manual exposure level, or releases it.
    pub fn set_manual(&mut self, exposure: Option<f64>) {
        self.manual = exposure.filter(|e| e.is_finite() && *e > 0.0);
    }

    /// The manual override, if any.
    pub fn manual(&self) -> Option<f64> {
        self.manual
    }

    /// The outcome of this camera's latest probe ([`super::probe`]): taken,
    /// rejected, abandoned or known without a probe; `None` once the camera
    /// is no longer under its own gradient law (balanced, manual, another
    /// mode).
    pub fn last_probe(&self) -> Option<ProbeEvent> {
        self.last_probe
    }

    /// Whether [`Self::last_probe`] was a brighter probe (where most of
    /// the frame was dark) rather than a darker one.
    pub fn last_probe_brighter(&self) -> bool {
        self.prober.last_brighter()
    }

    /// The exposure of the probe frame the estimator reads saturated pixels
    /// from (kept after a probe that measured no better, while the camera
    /// rests and the scene stays), if any.
    pub fn probe_frame(&self) -> Option<f64> {
        self.darker.as_ref().map(|d| d.exposure)
    }

    /// The exposure of the darker frame the estimator reads saturated
    /// pixels from while the scene stays: the probe frame, or else the
    /// frame after which the camera's own law last sent it brighter, if
    /// any.
    pub fn darker_frame(&self) -> Option<f64> {
        self.darker
            .as_ref()
            .or(self.passed.as_ref())
            .map(|d| d.exposure)
    }

    /// Tells the controller the camera's current setting (e.g. after the
    /// camera's built-in auto-exposure ran) and forgets the history.
    pub fn sync(&mut self, current: ExposureSetting) {
        self.splitter.sync(current);
        self.pid.reset();
        self.in_flight.clear();
        self.must_show = false;
        self.probe_next = None;
        self.probe_frame = false;
        self.probe_home = None;
        self.prober.reset();
        self.reacquiring = false;
        self.probe_alone = false;
        self.darker = None;
        self.passed = None;
        self.bracket.reset();
        self.repeller.reset();
        self.light.reset();
        self.kept_light_ev = 0.0;
        if let Some(w) = &mut self.walker {
            w.reset();
        }
        self.level_request = None;
    }

    /// The setting the camera will have once the commands in flight have
    /// shown: the newest command's, or `taken` when none is in flight.
    pub fn base(&self, taken: ExposureSetting) -> ExposureSetting {
        self.in_flight.back().map_or(taken, |c| c.setting)
    }

    /// Where the camera rests, its probes left out: the exposure of
    /// [`Self::base`], or the probe's home while the newest command in
    /// flight is a probe (a ladder's rung too), or while the latest frame
    /// shows one and nothing is in flight. A probe is a glance the camera
    /// returns from (or goes on from, when its prober takes it), not where
    /// its neighbours should balance to.
    pub fn rest_exposure(&self, taken: ExposureSetting) -> f64 {
        match self.in_flight.back() {
            Some(c) => c.home.unwrap_or_else(|| c.setting.exposure()),
            None => self
                .probe_home
                .filter(|_| self.probe_frame)
                .unwrap_or_else(|| taken.exposure()),
        }
    }

    /// Whether balancing leaves this frame's command as the camera's own:
    /// a balanced camera's probe or the return from one (scale-and-clip).
    pub fn probe_alone(&self) -> bool {
        self.probe_alone
    }

    /// Whether the camera takes only fixed levels.
    pub fn has_levels(&self) -> bool {
        self.walker.is_some()
    }

    /// Commands in flight (sent, not yet shown by a frame).
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Takes a new frame taken with `taken` into account: the newest
    /// command it shows and every older one are no longer in flight; when
    /// the oldest left has waited more than `timeout` frames, the camera
    /// has not applied it, and none of them is expected any more.
    fn track(&mut self, taken: &ExposureSetting, timeout: u32) {
        self.frames += 1;
        // A probe's exposure lasts until the next command shows.
        if let Some(k) = shown(&self.in_flight, taken.exposure()) {
            self.probe_frame = self.in_flight[k].home.is_some();
            self.probe_home = self.in_flight[k].home;
            self.in_flight.drain(..=k);
        }
        if self
            .in_flight
            .front()
            .is_some_and(|c| self.frames - c.sent > u64::from(timeout))
        {
            self.in_flight.clear();
        }
    }

    /// The camera's own desired exposure for this frame.
    pub fn unary(
        &mut self,
        config: &ControllerConfig,
        info: &FrameInfo,
        metered: &Metered,
    ) -> Result<UnaryStep> {
        let taken = info.taken.exposure();
        if !(taken.is_finite() && taken > 0.0) {
            return Err(Error::InvalidParameter {
                name: "frame exposure",
                value: taken,
                expected: "a positive exposure level (shutter_us · 10^(gain_dB/20))",
            });
        }
        let mut hold = None;
        if self.last_frame == Some(info.frame_id) {
            hold = Some(Hold::RepeatedFrame);
        } else {
            self.last_frame = Some(info.frame_id);
            self.track(&info.taken, config.latency_timeout_frames);
            if self.in_flight.iter().any(|c| c.must_show) {
                hold = Some(Hold::AwaitingCommand);
            }
        }
        let base = self.base(info.taken).exposure();
        let needs_estimate = matches!(config.mode, ControlMode::Gradient | ControlMode::Pid);
        let wants_slope = config.mode == ControlMode::Gradient && config.law.kind == LawKind::Fast;
        // Every gradient law under scale-and-clip searches beyond the
        // brightest anchor (span after span, where brightening is exact):
        // γ̂ at the anchors' end (0.53) asks a law for 0.44–0.56 EV a step
        // wherever the best lies; the distance searched asks for more.
        let extends_up = config.mode == ControlMode::Gradient
            && self.estimator.config().simulation == Simulation::ScaleClip;
        // Mostly saturated frames under scale-and-clip start a
        // reacquisition: the camera probes with a ladder where it rests
        // again.
        let stats = metered.stats();
        let saturated = f64::from(stats.saturated_fraction);
        let gradient = config.mode == ControlMode::Gradient && self.manual.is_none();
        let scale_clip = config.estimator.simulation == Simulation::ScaleClip;
        // Scale-and-clip's probing beyond a camera alone: reacquisitions,
        // and balanced cameras' probes (not on fixed levels).
        let clip_probes = gradient && scale_clip && self.walker.is_none();
        self.probe_alone = false;
        // So does a start with half the pixels saturated or more
        // (`reacquire_start_saturated`): a camera that starts far above its
        // best comes down onto the first hump of `M(E)` it meets, as from
        // saturation.
        let starting = clip_probes && !self.was_clip_probing;
        if hold.is_none() {
            self.was_clip_probing = clip_probes;
        }
        match config.probe.filter(|_| clip_probes) {
            Some(p)
                if hold.is_none()
                    && (saturated >= p.reacquire_saturated
                        || (starting && saturated >= p.reacquire_start_saturated)) =>
            {
                self.reacquiring = true;
            }
            Some(_) => {}
            None => self.reacquiring = false,
        }
        let own_law = gradient && config.balancing.is_none();
        // PID alone probes too, but only brighter (`ProbeInput::brighter_only`).
        let pid_alone = config.mode == ControlMode::Pid
            && self.manual.is_none()
            && config.balancing.is_none()
            && self.walker.is_none();
        // Under scale-and-clip a balanced camera probes too, from where
        // balancing holds it at rest: the estimator cannot see under
        // saturated pixels, and coming down from saturation (a brighter
        // light, a tunnel's exit) a balanced rig rests on a hump of `M(E)`
        // well below its best (docs/exposure-results.md).
        let balanced_probe = clip_probes && config.balancing.is_some();
        // A camera under its own law keeps the frames of its probes for the
        // estimator to read under its saturated pixels; a balanced camera
        // only while it reacquires. Coming down from far above, the first
        // rung that measures better is otherwise undone at once: balancing
        // goes on from it with an estimate that, blind under the clipping,
        // asks for brighter. (At rest, frames kept by balanced cameras
        // moved the rest's compromise: four strip cameras 0.20 EV apart
        // against 0.15, `tests/tests/balancing.rs`.)
        let keeps_frames = (own_law || (balanced_probe && self.reacquiring)) && scale_clip;
        if (own_law || pid_alone) != self.was_own_law {
            self.prober.reset();
            self.last_probe = None;
            self.was_own_law = own_law || pid_alone;
        }
        if !keeps_frames {
            self.darker = None;
        }
        if !(needs_estimate && config.estimator.simulation == Simulation::ScaleClip) {
            self.passed = None;
        }
        // A uniform change of light measured against the reference frame
        // (every gradient law): the best exposure is the reference's over
        // the change, until a frame shows the camera there.
        let light = config.light.filter(|_| {
            config.mode == ControlMode::Gradient
                && self.manual.is_none()
                && hold != Some(Hold::RepeatedFrame)
        });
        let measured = light.and_then(|p| self.light.change(&p, metered, taken));
        let follow = light.zip(measured).and_then(|(p, c)| {
            (c.follow(&p) && (c.best / taken).log2().abs() >= p.min_change_ev / 2.0).then_some(c)
        });
        if light.is_none() && hold.is_none() {
            self.light.reset();
        }
        if follow.is_some() {
            // A probe, or its return, was measuring the old light: give it
            // up and follow the new one now.
            if hold == Some(Hold::AwaitingCommand) {
                hold = None;
            }
            for c in &mut self.in_flight {
                c.must_show = false;
            }
        }
        if let Some(c) = follow {
            // A kept frame shows the scene as the frame would at its
            // exposure times the change of light, and so do the frames the
            // prober remembers; what the bracket learnt was in the old
            // light.
            let scale = (self.kept_light_ev - c.ev).exp2();
            self.kept_light_ev = c.ev;
            for kept in [&mut self.darker, &mut self.passed].into_iter().flatten() {
                kept.exposure *= scale;
            }
            self.prober.rescale(scale);
            self.bracket.reset();
            self.repeller.reset();
        }
        let from_probe = usable_darker(self.darker.as_ref(), taken);
        let darker = from_probe.or_else(|| usable_darker(self.passed.as_ref(), taken));
        let estimate = if needs_estimate {
            let e = self.estimator.estimate_with(
                metered,
                EstimateOptions {
                    slope: wants_slope,
                    darker,
                    extend: wants_slope || extends_up,
                    ..Default::default()
                },
            )?;
            Some(e)
        } else {
            None
        };
        let (read_darker, read_probe) = (darker.is_some(), from_probe.is_some());
        // (Unless the light changed and the kept frames were scaled to it.)
        if read_darker && follow.is_none() && estimate.as_ref().is_some_and(|e| !e.declipped) {
            // The scene is no longer the kept frame's.
            if read_probe {
                self.darker = None;
            } else {
                self.passed = None;
            }
        }
        let mean = f64::from(stats.mean);
        let mut fallback = false;
        let step = match (config.mode, &estimate) {
            (ControlMode::Fixed, _) => LawStep::Relative(config.fixed_exposure / taken),
            (ControlMode::MeanIntensity, _) => {
                LawStep::Relative(config.law.bound(config.mean.ratio(f64::from(stats.mean))))
            }
            (_, Some(e))
                if follow.is_none()
                    && (e.flat || stats.saturated_fraction > SATURATED_FALLBACK) =>
            {
                fallback = true;
                let ratio = config.law.bound(config.mean.ratio(f64::from(stats.mean)));
                // A mostly saturated frame under scale-and-clip: the best
                // lies below what the commands in flight will show too, so
                // they are followed by the same step.
                if config.mode == ControlMode::Gradient
                    && e.simulation == Simulation::ScaleClip
                    && stats.saturated_fraction > SATURATED_FALLBACK
                    && ratio < 1.0
                {
                    LawStep::Ahead {
                        ratio,
                        best: ratio,
                        beyond: true,
                    }
                } else {
                    LawStep::Relative(ratio)
                }
            }
            (ControlMode::Gradient, Some(e)) => config.law.step(e, stats),
            // (A probe frame is the prober's, not the integral's.)
            (ControlMode::Pid, Some(e)) if hold.is_none() && !self.prober.probing() => {
                LawStep::Relative(
                    config
                        .law
                        .bound(self.pid.update(&config.pid, 1.0 - e.gamma_hat)),
                )
            }
            _ => LawStep::Relative(1.0),
        };
        // On fixed levels the walker adds up what each frame asks: a step
        // from the commands in flight would count them twice. A balanced
        // camera's commands in flight carry balancing's moves, which its own
        // step near rest does not stand by (that left balanced cameras up to
        // 0.25 EV off their best on the real-light brackets).
        let step = if self.walker.is_some() {
            step.anchored()
        } else if let (LawStep::Standing(r), false) = (step, own_law) {
            LawStep::Relative(r)
        } else {
            step
        };
        // Under the camera's own law, between frames that do not ask
        // towards each other.
        let step = match &estimate {
            // (On fixed levels the walker does this: the frames of two
            // levels ask apart by a level's spacing.)
            Some(e) if own_law && hold.is_none() && follow.is_none() && self.walker.is_none() => {
                let at = taken.log2();
                let asked = at + step.frame_ev();
                let followed = self.repeller.follow(
                    at,
                    asked,
                    e.m_current,
                    mean,
                    config.bracket.light_tolerance,
                );
                step.with_frame_ev(followed - at)
            }
            _ => {
                if hold.is_none() {
                    self.repeller.reset();
                }
                step
            }
        };
        let mut desired = match (self.manual, follow) {
            (Some(m), _) => m,
            // A bound that the commands in flight already go beyond
            // stands as they are.
            (None, Some(c)) if c.bound && (base / c.best).ln() * (c.best / taken).ln() > 0.0 => {
                base
            }
            (None, Some(c)) => base * config.law.bound(c.best / base),
            (None, None) => config.law.next_exposure(step, taken, base, own_law),
        };
        // The bracket is the estimator's: under the fast law, whose jumps
        // can straddle a discontinuity of the estimate, it holds whether or
        // not balancing moves the camera afterwards.
        let bracketed = own_law
            || (config.mode == ControlMode::Gradient
                && config.law.kind == LawKind::Fast
                && self.manual.is_none());
        // On fixed levels the walker brackets the fixed point between two
        // levels instead.
        let bracketed = bracketed && self.walker.is_none();
        if bracketed && follow.is_none() {
            if hold.is_none() {
                self.bracket
                    .observe(&config.bracket, taken.log2(), mean, step.frame_ev());
            }
            desired = self.bracket.clamp(desired.log2()).exp2();
        } else {
            self.bracket.reset();
        }
        // Frames the camera does not react to leave the prober as it is.
        let probe_params = config
            .probe
            .filter(|_| (own_law || pid_alone || balanced_probe) && !fallback);
        let mut probe = None;
        match (probe_params, &estimate) {
            (Some(params), Some(e)) => {
                if hold.is_none() && follow.is_none() {
                    // A balanced camera probes from where balancing has
                    // brought it to rest. That rest is rarely the camera's
                    // own maximum, so only a probe that measures clearly
                    // more is taken (`ProbeParams::ladder_gain`).
                    let asked = if own_law || pid_alone { desired } else { base };
                    let (d, event) = self.prober.step(
                        &params,
                        ProbeInput {
                            taken,
                            m: e.m_current,
                            saturated,
                            dark: f64::from(stats.dark_fraction),
                            desired: asked,
                            wants_frame: keeps_frames,
                            read_probe_frame: e.declipped && read_probe,
                            rungs: if self.reacquiring { params.ladder } else { 1 },
                            balanced: balanced_probe,
                            relight: scale_clip,
                            brighter_only: pid_alone,
                        },
                    );
                    let alone = matches!(
                        event,
                        Some(
                            ProbeEvent::Sent { .. }
                                | ProbeEvent::Rejected { .. }
                                | ProbeEvent::Abandoned
                        )
                    );
                    if own_law || pid_alone || alone {
                        desired = d;
                    }
                    if pid_alone && matches!(event, Some(ProbeEvent::Taken { .. })) {
                        // PID goes on from the rung taken, its history (of
                        // the rest left behind) forgotten.
                        self.pid.reset();
                    }
                    self.probe_alone = alone && balanced_probe;
                    probe = event;
                    // A reacquisition ends where the camera rests: after
                    // its ladder, or settled with too little saturated to
                    // probe.
                    let settled = (asked / taken).log2().abs() <= params.settle_ev
                        && saturated < params.min_saturated;
                    if self.prober.resting() || (settled && event.is_none()) {
                        self.reacquiring = false;
                    }
                    if let Some(e) = event.filter(|e| !matches!(e, ProbeEvent::Sent { .. })) {
                        self.last_probe = Some(e);
                    }
                    // (A brighter probe's frame shows nothing darkening
                    // would: the camera goes back down to `d`.)
                    if keeps_frames
                        && matches!(event, Some(ProbeEvent::Rejected { .. }))
                        && taken < d
                    {
                        self.darker = Some(ProbeFrame {
                            exposure: taken,
                            image: metered.clone(),
                        });
                    } else if keeps_frames && matches!(event, Some(ProbeEvent::Taken { .. })) {
                        // The law goes on from the probe: should it go
                        // brighter, the probe's frame shows what the
                        // saturated pixels hide.
                        self.passed = Some(ProbeFrame {
                            exposure: taken,
                            image: metered.clone(),
                        });
                        self.darker = None;
                    } else if !self.prober.resting() {
                        self.darker = None;
                    }
                }
            }
            _ => {
                self.prober.reset();
                self.last_probe = None;
                self.darker = None;
            }
        }
        // A probe frame, and the return from it, must show before the
        // camera reacts again; so must every PID step (its integral counts
        // frames, not commands).
        self.must_show = config.mode == ControlMode::Pid
            || matches!(
                probe,
                Some(ProbeEvent::Sent { .. } | ProbeEvent::Rejected { .. } | ProbeEvent::Abandoned)
            );
        self.probe_next = match probe {
            Some(ProbeEvent::Sent { from, .. }) => Some(from),
            _ => None,
        };
        let probe_frame = self.probe_frame;
        if matches!(probe, Some(ProbeEvent::Taken { .. })) {
            // The law goes on from the probe's exposure: it is the
            // camera's own from now on.
            self.probe_frame = false;
        }
        // A frame that shows the camera at rest, in the light the law
        // worked in, is the next change's reference.
        if let Some(p) = light.filter(|_| {
            follow.is_none()
                && (!self.light.has_reference() || measured.is_some())
                && (base / taken).log2().abs() < REST_EV
                && probe.is_none()
                && !probe_frame
        }) {
            self.light.set_reference(&p, metered, taken, desired);
            self.kept_light_ev = 0.0;
            self.fresh_reference = true;
        }
        if estimate.is_some()
            && follow.is_none()
            && config.estimator.simulation == Simulation::ScaleClip
            && hold.is_none()
            && (desired / taken).log2() >= DARKER_MIN_EV
        {
            self.passed = Some(ProbeFrame {
                exposure: taken,
                image: metered.clone(),
            });
        }
        // On fixed levels, what the walker reads from this frame: a
        // prediction (the fast law's, undamped; a fixed or manual exposure;
        // a change of light followed) is the distance itself, any other
        // request a step to add up (mean-intensity AE too: clipping makes
        // the mean grow more slowly than the exposure, so its one-frame
        // prediction falls short, and only its repetition reaches the
        // exposure where the mean is on target). A probe's command,
        // and a frame that shows no level yet, leave it out.
        self.level_request = None;
        if self.walker.is_some() && hold.is_none() && probe.is_none() {
            let predicted = self.manual.is_some()
                || follow.is_some()
                || config.mode == ControlMode::Fixed
                || matches!(step, LawStep::Predicted { .. });
            let step_ev = match step {
                // Undamped (on fixed levels no bracket clamps it).
                LawStep::Predicted { .. } if self.manual.is_none() && follow.is_none() => {
                    step.frame_ev()
                }
                _ => (desired / taken).log2(),
            };
            let kind = if predicted {
                Request::Predicted
            } else {
                Request::Incremental
            };
            let frame = LevelFrame {
                log2_e: taken.log2(),
                mean,
                saturated,
            };
            let signal = match (kind, &estimate) {
                (Request::Incremental, Some(e)) if e.gamma_hat > 0.0 => Some(-e.gamma_hat.ln()),
                _ => None,
            };
            // Scale-and-clip's ŝ is the exposure ratio to the estimator's
            // fixed point (a linear sensor), where the laws come to rest:
            // within the anchors' span it places the fixed point itself.
            let distance_ev = estimate
                .as_ref()
                .filter(|e| {
                    kind == Request::Incremental
                        && e.simulation == Simulation::ScaleClip
                        && e.at_bound.is_none()
                        && !e.flat
                        && e.x_hat > 0.0
                })
                .map(|e| e.x_hat.log2());
            self.level_request = Some(LevelRequest {
                frame,
                step_ev,
                signal,
                distance_ev,
                kind,
                desired,
            });
        }
        Ok(UnaryStep {
            light: follow,
            probe_frame,
            estimate,
            taken,
            desired,
            hold,
            fallback,
            probe,
        })
    }

    /// Splits `target` and records the command as in flight; returns the
    /// setting to send, or `None` when the camera has it already or will
    /// have it once the commands in flight show (`taken`: the setting of
    /// the frame the target was computed on).
    pub fn command(
        &mut self,
        target: f64,
        taken: ExposureSetting,
    ) -> (Option<ExposureSetting>, Option<Clamped>) {
        if std::mem::take(&mut self.fresh_reference) {
            self.light.set_best(target);
        }
        let (mut setting, clamped) = self.splitter.split(target);
        let base = self.base(taken);
        if let Some(walker) = &mut self.walker {
            // The camera is sent a level: the walker's, after a frame at
            // rest; the one it will have, while a command is in flight; the
            // nearest otherwise (a probe).
            let level = match self.level_request.take() {
                Some(r) => {
                    let moved = (setting.exposure() / r.desired).log2();
                    let moved = if moved.is_finite() { moved } else { 0.0 };
                    let step = r.step_ev + moved;
                    // Balancing moves the fixed point: its step places it.
                    let alone = moved.abs() < 1e-6;
                    let signal = r.signal.filter(|_| alone).unwrap_or(step);
                    let request = match r.distance_ev.filter(|_| alone) {
                        Some(d) => Request::Placed(d),
                        None => r.kind,
                    };
                    walker.step(r.frame, base.exposure(), step, signal, request)
                }
                None => walker.round(setting.exposure()),
            };
            setting = self.splitter.split(level).0;
        }
        let must_show = std::mem::take(&mut self.must_show);
        let home = self.probe_next.take();
        let same = (setting.shutter_us / base.shutter_us - 1.0).abs() <= SETTLED_TOLERANCE / 4.0
            && (setting.gain_db - base.gain_db).abs() <= 0.01;
        if same {
            return (None, clamped);
        }
        if self.in_flight.len() == MAX_IN_FLIGHT {
            self.in_flight.pop_front();
        }
        self.in_flight.push_back(InFlight {
            from: base,
            setting,
            sent: self.frames,
            must_show,
            home,
        });
        (Some(setting), clamped)
    }
}
