//! Probing darker where saturation hides what darkening would show, and
//! brighter where the noise floor hides what brightening would.
//!
//! Neither exposure simulation can look under saturated pixels: a frame
//! does not say how far above full well a saturated region lies, so what
//! darkening would bring back is unknown. Scale-and-clip holds saturated
//! pixels saturated and credits darkening with nothing there; the
//! γ-mapping maps them to a flat plateau too. Where `M(E)` has several
//! local maxima, one before each saturation event, a camera coming down
//! from bright settles on the first fixed point it meets, and the
//! estimator cannot see the better one further down.
//!
//! A [`Prober`] finds out by measuring instead of simulating. When a
//! camera's own law has settled (for `settle_frames` frames, its steps and
//! its exposure's drift from the first of them within `settle_ev`: a law
//! still creeping towards its fixed point has not, unless it is the
//! camera's own law creeping darker, by steps of at most twice
//! `settle_ev`, with saturation in view: that goes where the probe would
//! look, a step at a time) and at least
//! `min_saturated` of its metered
//! pixels are saturated, it takes one frame `step_ev` darker and compares
//! `M` measured there with `M` measured at the settled exposure:
//!
//! - better by more than `accept_gain` (relative): the probe is taken and
//!   the law goes on from the probe frame, towards the estimator's fixed
//!   point nearest it;
//! - otherwise: the camera goes back to the settled exposure and rests
//!   there: it probes again only after the scene has changed (`M` moved
//!   by more than `rearm_change`, or the law moved the camera more than
//!   half a probe step away).
//!
//! A frame the camera took recently in the probe's range (a camera that
//! climbed from dark passed through it) answers without a probe; so does
//! the probe frame itself when the law brings the camera back after a
//! probe that measured better (the estimator then disagrees with the
//! measurement, as the γ-mapping's biased fixed points do, and a second
//! round trip would end the same way). After a probe that found nothing,
//! `cooldown_frames` must pass before the next.
//!
//! A law that circles (a jump of its estimate across 1, where a finite
//! step cannot settle) never settles; the prober recognises the circle
//! (up and down at least twice each within 1 EV, ending where it began,
//! over nine frames) and probes from where the camera is.
//!
//! For scale-and-clip the probe's frame is worth keeping: the estimator
//! reads from it what the saturated pixels hide
//! ([`super::estimator::Darker`]), which moves the camera's fixed point to
//! where the measurement says. The controller keeps the frame of a probe
//! that measured no better while the camera rests after it and the frame
//! still matches the scene; such a camera therefore does not let a recent
//! frame that measured no better answer for a probe (it probes for the
//! frame), and its rest does not end while the estimate reads the frame,
//! however far the law moves it: the frame says the scene is the same.
//!
//! A probe may be a *ladder* ([`ProbeInput::rungs`]): a rung that measured
//! no better (by `ladder_gain`) is followed by one `step_ev` darker again,
//! up to the last, before the camera goes back. The controller asks for one
//! under scale-and-clip when the camera comes to rest after a frame that
//! was mostly saturated (`reacquire_saturated`; the exit of a tunnel): coming
//! down from there, a camera meets the highest hump of `M(E)` first, and
//! the best can lie two or three probe steps below it, past a dip
//! (docs/exposure-results.md).
//!
//! A camera so ends at a fixed point of its estimator where a probe
//! `step_ev` darker measures no better. The cost is one darker frame each
//! time a camera settles (or circles) with saturation in view, and after a
//! probe that found nothing, at most one in `cooldown_frames` frames unless
//! `M` at the rest changes by `relight_change` (a new light; scale-and-clip,
//! [`ProbeInput::relight`]). A manual or fixed exposure is the operator's
//! and never probes.
//!
//! The same holds upwards where most of a frame is black. A camera under
//! its own law that rests with at least `min_dark` of its metered
//! pixels dark probes *brighter*, by a ladder of `bright_ladder` frames
//! `bright_step_ev` apart (up to 4.5 EV by default), the first rung that
//! measures `ladder_gain` more taken; the dark test comes before the
//! saturated one. Texture in the noise floor is invisible to both
//! simulations: at the rig's resolution a tunnel exit's front camera rests
//! with the exit resolved and two thirds of its ground black, on a hump of
//! `M(E)` a quarter as high as the walls' texture 5.4 EV up
//! (docs/exposure-results.md). Balanced cameras probe brighter too: the
//! guard of balancing ([`super::balance::guard_m`]) keeps their
//! neighbours from pulling them over such humps, as it keeps them from
//! pulling a camera into saturation. PID probes only brighter
//! ([`ProbeInput::brighter_only`]): a darker probe at each rest with
//! saturation in view would disturb its integral for little. A recent
//! frame answers for a brighter ladder only if one lay as far as its last
//! rung, or one in its reach measured better.
//!
//! Under scale-and-clip a balanced camera probes too
//! ([`ProbeInput::balanced`]), from where balancing holds it at rest:
//! coming down from a brighter light, every camera of a balanced rig meets
//! a hump of `M(E)` it cannot see past, and without probes the rig rested
//! there 1 EV too bright (at a quarter of the resolution;
//! docs/exposure-results.md). Balancing's rest is
//! not a maximum of the camera's own `M`, so such a probe, like a ladder's
//! rung, must measure `ladder_gain` more to be taken; the balancing then
//! goes on from the probe's exposure.

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Result};

/// When and how far a settled camera probes (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProbeParams {
    /// How much darker the probe frame is, in EV. The default,
    /// `log2 1.9 ≈ 0.93`, is as far as the estimator's darkest anchor
    /// looks.
    pub step_ev: f64,
    /// The saturated fraction of the metered pixels from which darkening
    /// is uncertain enough to probe.
    pub min_saturated: f64,
    /// The law's steps (|log2 E_{t+1}/E_t|, EV) at most this small count
    /// as settled.
    pub settle_ev: f64,
    /// Settled frames (frames the camera reacts to) before a probe.
    pub settle_frames: u32,
    /// The relative gain in measured `M` a probe must show to be taken.
    pub accept_gain: f64,
    /// The relative change of `M` at the exposure a camera rests at that
    /// counts as a new scene and allows probing again.
    pub rearm_change: f64,
    /// Frames the camera reacts to after a probe that found nothing before
    /// it may probe again, however the scene changes (but for a new light,
    /// `relight_change`): on a moving vehicle this bounds the darker frames
    /// to one in so many.
    pub cooldown_frames: u32,
    /// The relative change of `M` at the exposure a camera rests at that
    /// counts as a new light and allows probing again before
    /// `cooldown_frames`: a brighter light saturates what the estimator
    /// cannot see under, and the camera would otherwise rest on the hump
    /// it meets coming down for the whole cooldown.
    pub relight_change: f64,
    /// Under scale-and-clip, a frame with at least this fraction of its
    /// metered pixels saturated starts a *reacquisition*: where the camera
    /// (balanced or not) rests again, it probes with a ladder of `ladder`
    /// rungs ([`ProbeInput::rungs`]). Coming down from saturation (a
    /// tunnel's exit), a camera meets the highest hump of `M(E)` first,
    /// which need not be the best.
    pub reacquire_saturated: f64,
    /// Under scale-and-clip, a camera's first frame under its gradient law
    /// with at least this fraction of its metered pixels saturated starts
    /// a reacquisition too. A camera that starts far above its best (a
    /// GenICam camera's default exposure of 10 ms in daylight) comes down
    /// onto the first hump of `M(E)` it meets, where the estimator, blind
    /// under the saturated pixels, sees a fixed point
    /// (docs/exposure-results.md, *The default simulation*). Below it the
    /// ladder would cost three darker frames at every start for nothing,
    /// and a ladder that straddles a change of light measures the wrong
    /// thing. At 1 only the frames [`Self::reacquire_saturated`] names do.
    pub reacquire_start_saturated: f64,
    /// The rungs of a reacquisition's probe: after a rung that measured no
    /// better, the next is `step_ev` darker again.
    pub ladder: u32,
    /// The relative gain in measured `M` a rung of a ladder, or a balanced
    /// camera's probe, must show to be taken. A balanced camera's rest is
    /// rarely its own maximum: where `M` is flat (a broad hump), a darker
    /// frame measures a little more, and the camera would leave its
    /// neighbours for nothing. The hump a camera meets coming down from
    /// saturation lies 20–40 % below the best (docs/exposure-results.md).
    pub ladder_gain: f64,
    /// The dark fraction of the metered pixels (at or below
    /// [`crate::exposure::metering::DARK_LEVEL`]) from which a camera
    /// under its own law probes *brighter* where it rests: a ladder of up
    /// to `bright_ladder` frames, each `bright_step_ev` brighter than the
    /// last, the first that measures `ladder_gain` more taken. Neither
    /// simulation sees texture that lies in the noise floor, so where
    /// most of a frame is black (a tunnel's walls behind its bright exit)
    /// a camera can rest on a hump of `M(E)` several EV below its best
    /// (docs/exposure-results.md). At 1 only wholly dark frames do.
    pub min_dark: f64,
    /// How much brighter each rung of a brighter probe is, in EV.
    pub bright_step_ev: f64,
    /// The rungs of a brighter probe.
    pub bright_ladder: u32,
}

impl Default for ProbeParams {
    fn default() -> Self {
        Self {
            step_ev: 1.9f64.log2(),
            min_saturated: 0.01,
            settle_ev: 0.03,
            settle_frames: 3,
            accept_gain: 0.005,
            rearm_change: 0.02,
            cooldown_frames: 80,
            relight_change: 0.2,
            reacquire_saturated: 0.75,
            reacquire_start_saturated: 0.5,
            ladder: 3,
            ladder_gain: 0.1,
            min_dark: 0.5,
            bright_step_ev: 1.5,
            bright_ladder: 3,
        }
    }
}

impl ProbeParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "controller.probe.step_ev",
            self.step_ev,
            0.1,
            4.0,
            "an exposure step in EV in [0.1, 4]",
        )?;
        check_range(
            "controller.probe.min_saturated",
            self.min_saturated,
            0.0,
            1.0,
            "a fraction of pixels in [0, 1]",
        )?;
        check_range(
            "controller.probe.settle_ev",
            self.settle_ev,
            0.0,
            0.5,
            "an exposure step in EV in [0, 0.5]",
        )?;
        check_range(
            "controller.probe.settle_frames",
            f64::from(self.settle_frames),
            1.0,
            1000.0,
            "a number of frames in [1, 1000]",
        )?;
        check_range(
            "controller.probe.accept_gain",
            self.accept_gain,
            0.0,
            1.0,
            "a relative gain of M in [0, 1]",
        )?;
        check_range(
            "controller.probe.rearm_change",
            self.rearm_change,
            1e-4,
            1.0,
            "a relative change of M in [0.0001, 1]",
        )?;
        check_range(
            "controller.probe.cooldown_frames",
            f64::from(self.cooldown_frames),
            0.0,
            1e6,
            "a number of frames in [0, 1000000]",
        )?;
        check_range(
            "controller.probe.relight_change",
            self.relight_change,
            1e-4,
            1.0,
            "a relative change of M in [0.0001, 1]",
        )?;
        check_range(
            "controller.probe.reacquire_saturated",
            self.reacquire_saturated,
            0.0,
            1.0,
            "a fraction of pixels in [0, 1]",
        )?;
        check_range(
            "controller.probe.reacquire_start_saturated",
            self.reacquire_start_saturated,
            0.0,
            1.0,
            "a fraction of pixels in [0, 1]",
        )?;
        check_range(
            "controller.probe.ladder",
            f64::from(self.ladder),
            1.0,
            8.0,
            "a number of probe frames in [1, 8]",
        )?;
        check_range(
            "controller.probe.ladder_gain",
            self.ladder_gain,
            0.0,
            1.0,
            "a relative gain of M in [0, 1]",
        )?;
        check_range(
            "controller.probe.min_dark",
            self.min_dark,
            0.0,
            1.0,
            "a fraction of pixels in [0, 1]",
        )?;
        check_range(
            "controller.probe.bright_step_ev",
            self.bright_step_ev,
            0.1,
            4.0,
            "an exposure step in EV in [0.1, 4]",
        )?;
        check_range(
            "controller.probe.bright_ladder",
            f64::from(self.bright_ladder),
            1.0,
            8.0,
            "a number of probe frames in [1, 8]",
        )?;
        Ok(())
    }
}

/// What a probe did on one frame (telemetry).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum ProbeEvent {
    /// A probe frame was commanded: from the settled exposure to a darker
    /// one (or a brighter one, where most of the frame is dark).
    Sent {
        /// The settled exposure.
        from: f64,
        /// The probe's exposure.
        to: f64,
    },
    /// The probe frame measured better: the law goes on from it.
    Taken {
        /// `M_probe / M_settled − 1`.
        gain: f64,
    },
    /// The probe frame measured no better: back to the settled exposure.
    Rejected {
        /// `M_probe / M_settled − 1`.
        gain: f64,
    },
    /// The probe frame did not come (the exposure range ends, or the
    /// command did not show in time): back to the settled exposure.
    Abandoned,
    /// No probe was sent: a recent frame lies in the probe's range. A
    /// camera that climbed from dark passed through it; a camera whose law
    /// brought it back from a probe that measured better has an estimator
    /// that disagrees with the measurement, and probing again would only
    /// repeat the round trip.
    Known {
        /// The best `M` measured there over `M_settled`, minus 1.
        gain: f64,
    },
}

/// One frame the camera reacts to, as the prober sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeInput {
    /// The exposure the frame was taken with.
    pub taken: f64,
    /// `M` measured on the frame.
    pub m: f64,
    /// The saturated fraction of its metered pixels.
    pub saturated: f64,
    /// The dark fraction of its metered pixels (at or below
    /// [`crate::exposure::metering::DARK_LEVEL`]).
    pub dark: f64,
    /// The exposure the camera's own law wants next.
    pub desired: f64,
    /// Whether the estimator reads saturated pixels from a probe frame
    /// (scale-and-clip): then a recent frame does not answer for a probe
    /// unless it measured better, and the probe is sent for its frame.
    pub wants_frame: bool,
    /// Whether this frame's estimate read the frame of the probe the camera
    /// rests after (it matched this frame where neither is saturated): the
    /// scene is still the probe's, however far the law has moved the camera
    /// or `M` with it, so the rest goes on.
    pub read_probe_frame: bool,
    /// How many probe frames, each `step_ev` darker than the last, a probe
    /// sent now may take before the camera goes back (1: one).
    pub rungs: u32,
    /// Whether the camera is balanced with its neighbours: its rest is
    /// balancing's, not a maximum of its own `M`, so a probe must measure
    /// `ladder_gain` more to be taken, as a ladder's rungs must.
    pub balanced: bool,
    /// Whether a change of `M` by `relight_change` at the rest allows
    /// probing again before the cooldown (scale-and-clip, whose estimate
    /// cannot see under what a brighter light saturates).
    pub relight: bool,
    /// Whether the camera probes only brighter (PID, whose integral a
    /// darker probe at every rest with saturation in view disturbs; a
    /// mostly black rest is rarer, and far from its best).
    pub brighter_only: bool,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
enum State {
    /// The law is moving the camera.
    #[default]
    Watching,
    /// `frames` settled frames at `home`, with their `M` summed.
    Settling { home: f64, m_sum: f64, frames: u32 },
    /// A probe frame at `probe` was commanded, the `rung`th of `rungs`,
    /// each `step` EV from the last (negative: darker).
    Probing {
        home: f64,
        home_m: f64,
        probe: f64,
        rung: u32,
        rungs: u32,
        step: f64,
    },
    /// A probe from `home` measured no better `frames` frames ago; no
    /// probing until the scene changes.
    Resting { home: f64, home_m: f64, frames: u32 },
}

/// How many of the latest frames a camera reacted to a [`Prober`]
/// remembers.
const MEMORY: usize = 16;

/// The frames over which a circling law is recognised (three turns of the
/// shortest circle, up-up-down).
const CIRCLE_FRAMES: usize = 9;
/// The widest band a circling law is recognised in, EV.
const CIRCLE_BAND_EV: f64 = 1.0;
/// How far the circle may drift over [`CIRCLE_FRAMES`], EV.
const CIRCLE_DRIFT_EV: f64 = 0.1;

/// The probing state of one camera (module documentation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Prober {
    state: State,
    /// Whether the latest probe (sent, or known without one) was brighter.
    brighter: bool,
    /// `(exposure, M)` of the latest frames the camera reacted to, in this
    /// scene.
    recent: VecDeque<(f64, f64)>,
}

/// How many settled steps (`settle_ev`) a frame a law creeping darker
/// with saturation in view may move and still count as settling.
const CREEP_STEPS: f64 = 2.0;

/// |log2 a/b|.
fn ev(a: f64, b: f64) -> f64 {
    (a / b).log2().abs()
}

impl Prober {
    /// Whether the camera rests after a probe that measured no better (or
    /// one that did not come), until the scene changes.
    pub fn resting(&self) -> bool {
        matches!(self.state, State::Resting { .. })
    }

    /// Whether the latest probe (sent, or answered by a recent frame) was
    /// brighter: its outcome ([`ProbeEvent`]) is then of a brighter frame.
    pub fn last_brighter(&self) -> bool {
        self.brighter
    }

    /// Whether a probe frame was commanded and not yet measured: the next
    /// frame the camera reacts to is the probe's (or shows it did not come).
    pub fn probing(&self) -> bool {
        matches!(self.state, State::Probing { .. })
    }

    /// Moves what the prober knows by a uniform change of light: the
    /// exposures it remembers are multiplied by `scale` (the reciprocal of
    /// the change), and their `M` stand. A probe in flight measured the old
    /// light against the new one, so it is given up.
    pub fn rescale(&mut self, scale: f64) {
        self.state = match self.state {
            State::Probing { .. } => State::Watching,
            State::Settling {
                home,
                m_sum,
                frames,
            } => State::Settling {
                home: home * scale,
                m_sum,
                frames,
            },
            State::Resting {
                home,
                home_m,
                frames,
            } => State::Resting {
                home: home * scale,
                home_m,
                frames,
            },
            State::Watching => State::Watching,
        };
        for (e, _) in &mut self.recent {
            *e *= scale;
        }
    }

    /// Forgets everything (the camera left its own law's control).
    pub fn reset(&mut self) {
        self.state = State::Watching;
        self.recent.clear();
    }

    /// The exposure to command for a frame the camera reacts to, and what
    /// the probe did. Frames with a non-finite or non-positive `m` or
    /// exposure reset the prober and pass `desired` through.
    pub fn step(&mut self, params: &ProbeParams, input: ProbeInput) -> (f64, Option<ProbeEvent>) {
        let ProbeInput {
            taken, m, desired, ..
        } = input;
        let valid =
            [taken, desired].iter().all(|v| v.is_finite() && *v > 0.0) && m.is_finite() && m >= 0.0;
        if !valid {
            self.reset();
            return (desired, None);
        }
        let out = self.react(params, input);
        if self.recent.len() == MEMORY {
            self.recent.pop_front();
        }
        self.recent.push_back((taken, m));
        out
    }

    fn react(&mut self, params: &ProbeParams, input: ProbeInput) -> (f64, Option<ProbeEvent>) {
        let ProbeInput {
            taken, m, desired, ..
        } = input;
        match self.state {
            State::Probing {
                home,
                home_m,
                probe,
                rung,
                rungs,
                step,
            } => {
                // The pending-command logic lets this frame through once it
                // shows the probe, or once the wait timed out; where the
                // exposure range ends, the probe may be shallower. Half the
                // step is still a probe.
                let away = (taken / home).log2() * step.signum();
                if !(away >= 0.5 * step.abs()
                    && away <= (probe / home).log2().abs() + params.settle_ev)
                {
                    self.state = State::Resting {
                        home,
                        home_m,
                        frames: 0,
                    };
                    return (home, Some(ProbeEvent::Abandoned));
                }
                let gain = if home_m > 0.0 {
                    m / home_m - 1.0
                } else if m > 0.0 {
                    f64::INFINITY
                } else {
                    0.0
                };
                let needed = if rungs > 1 || input.balanced || step > 0.0 {
                    params.accept_gain.max(params.ladder_gain)
                } else {
                    params.accept_gain
                };
                if gain > needed {
                    self.state = State::Watching;
                    (desired, Some(ProbeEvent::Taken { gain }))
                } else if rung < rungs {
                    // The next rung of the ladder, from the same home.
                    self.send(home, home_m, rung + 1, rungs, step)
                } else {
                    self.state = State::Resting {
                        home,
                        home_m,
                        frames: 0,
                    };
                    (home, Some(ProbeEvent::Rejected { gain }))
                }
            }
            State::Resting {
                home,
                home_m,
                frames,
            } => {
                // A law still creeping towards its fixed point does not
                // re-arm; a camera that has moved half a probe step has
                // found another scene.
                let moved = ev(taken, home) > 0.5 * params.step_ev;
                let change = (m - home_m).abs();
                let changed = change > params.rearm_change * home_m.max(f64::MIN_POSITIVE);
                let relit =
                    input.relight && change > params.relight_change * home_m.max(f64::MIN_POSITIVE);
                if (relit || frames >= params.cooldown_frames && (moved || changed))
                    && !input.read_probe_frame
                {
                    self.state = State::Watching;
                    if changed {
                        self.recent.clear();
                    }
                    self.watch(params, input)
                } else {
                    self.state = State::Resting {
                        home,
                        home_m,
                        frames: frames.saturating_add(1),
                    };
                    (desired, None)
                }
            }
            State::Watching | State::Settling { .. } => self.watch(params, input),
        }
    }

    /// Commands the `rung`th probe frame of `rungs` from `home` (measured
    /// `home_m` there): `rung` steps of `step` EV (negative: darker).
    fn send(
        &mut self,
        home: f64,
        home_m: f64,
        rung: u32,
        rungs: u32,
        step: f64,
    ) -> (f64, Option<ProbeEvent>) {
        let probe = home * (f64::from(rung) * step).exp2();
        self.state = State::Probing {
            home,
            home_m,
            probe,
            rung,
            rungs,
            step,
        };
        (
            probe,
            Some(ProbeEvent::Sent {
                from: home,
                to: probe,
            }),
        )
    }

    /// Whether the law circles: over the latest [`CIRCLE_FRAMES`] frames
    /// (this one, taken at `taken`, included) the exposure went up and down
    /// by more than `settle_ev` at least twice each, within a band of at
    /// most [`CIRCLE_BAND_EV`], and ended where it began (the first and the
    /// last third within `CIRCLE_DRIFT_EV` of each other on average).
    fn circling(&self, params: &ProbeParams, taken: f64) -> bool {
        if self.recent.len() + 1 < CIRCLE_FRAMES {
            return false;
        }
        let l: Vec<f64> = self
            .recent
            .iter()
            .skip(self.recent.len() + 1 - CIRCLE_FRAMES)
            .map(|(e, _)| e.log2())
            .chain([taken.log2()])
            .collect();
        let (lo, hi) = l
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let steps = l.windows(2).map(|w| w[1] - w[0]);
        let up = steps.clone().filter(|d| *d > params.settle_ev).count();
        let down = steps.filter(|d| *d < -params.settle_ev).count();
        let third = CIRCLE_FRAMES / 3;
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let drift = (mean(&l[l.len() - third..]) - mean(&l[..third])).abs();
        hi - lo <= CIRCLE_BAND_EV && up >= 2 && down >= 2 && drift <= CIRCLE_DRIFT_EV
    }

    /// Counts settled frames and sends a probe when there are enough.
    fn watch(&mut self, params: &ProbeParams, input: ProbeInput) -> (f64, Option<ProbeEvent>) {
        let ProbeInput {
            taken,
            m,
            saturated,
            desired,
            wants_frame,
            ..
        } = input;
        // (A camera that probes only brighter has no darker probe to make.)
        let saturated = if input.brighter_only { 0.0 } else { saturated };
        // A camera's own law creeping darker by small steps (up to
        // `CREEP_STEPS` settled steps a frame) with saturation in view goes
        // where a probe would look, a step at a time: under scale-and-clip
        // the held pixels put its fixed point too high, and it creeps on
        // until a probe shows the better exposure below. The creep counts as settling, and the
        // probe goes from where the camera has come.
        let creep = !input.balanced
            && saturated >= params.min_saturated
            && input.dark < params.min_dark
            && desired <= taken
            && ev(desired, taken) <= CREEP_STEPS * params.settle_ev;
        let creeping = |home: f64, frames: u32| {
            creep
                && taken < home
                && ev(taken, home) <= f64::from(frames + 1) * CREEP_STEPS * params.settle_ev
        };
        let (home, m_sum, frames) =
            if saturated >= params.min_saturated && self.circling(params, taken) {
                // A law that circles a jump of its estimate never settles:
                // it counts as settled where it is, and probes from there.
                (
                    taken,
                    m * f64::from(params.settle_frames),
                    params.settle_frames,
                )
            } else {
                match self.state {
                    State::Settling {
                        home,
                        m_sum,
                        frames,
                    } if ev(desired, taken) <= params.settle_ev
                        && ev(taken, home) <= params.settle_ev =>
                    {
                        (home, m_sum + m, frames + 1)
                    }
                    State::Settling { home, frames, .. } if creeping(home, frames) => {
                        (taken, m * f64::from(frames + 1), frames + 1)
                    }
                    _ if ev(desired, taken) > params.settle_ev && !creep => {
                        self.state = State::Watching;
                        return (desired, None);
                    }
                    _ => (taken, m, 1),
                }
            };
        // Mostly dark (the texture in the noise floor): brighter, by a
        // ladder. Otherwise, with saturation in view: darker.
        let brighter = input.dark >= params.min_dark;
        if frames >= params.settle_frames && (brighter || saturated >= params.min_saturated) {
            let home_m = m_sum / f64::from(frames);
            let (step, rungs) = if brighter {
                (params.bright_step_ev, params.bright_ladder.max(1))
            } else {
                (-params.step_ev, input.rungs.max(1))
            };
            // What a probe would show, if a recent frame shows it already
            // (within a darker probe's one step, or a brighter ladder's
            // reach). A brighter ladder reaches far: a recent frame answers
            // for it only if one lay as far as its last rung, or one in its
            // range measured better (the estimator then disagrees with the
            // measurement, and the round trip would repeat).
            self.brighter = brighter;
            let reach = if brighter { f64::from(rungs) } else { 1.0 };
            let away = |e: f64| (e / home).log2() * step.signum();
            let reached = !brighter
                || self
                    .recent
                    .iter()
                    .any(|&(e, _)| away(e) >= (reach - 0.5) * step.abs());
            let known = self
                .recent
                .iter()
                .filter(|&&(e, _)| {
                    away(e) >= 0.5 * step.abs() && away(e) <= reach * step.abs() + params.settle_ev
                })
                .map(|(_, m)| *m)
                .fold(None, |best: Option<f64>, m| {
                    Some(best.map_or(m, |b| b.max(m)))
                });
            let known = known.map(|best| {
                if home_m > 0.0 {
                    best / home_m - 1.0
                } else {
                    0.0
                }
            });
            let answers = |g: f64| {
                if brighter {
                    reached || g > params.ladder_gain
                } else {
                    !wants_frame || g > params.accept_gain
                }
            };
            if let Some(gain) = known.filter(|&g| answers(g)) {
                self.state = State::Resting {
                    home,
                    home_m,
                    frames: 0,
                };
                return (desired, Some(ProbeEvent::Known { gain }));
            }
            return self.send(home, home_m, 1, rungs, step);
        }
        self.state = State::Settling {
            home,
            m_sum,
            frames,
        };
        (desired, None)
    }
}
