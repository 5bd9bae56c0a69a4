//! The rig's controller: one [`CameraController`] per camera, the
//! balancing of neighbours (Eq. 5/6) and the split into shutter and gain.

use super::*;

/// One camera's input to a rig step.
#[derive(Clone, Copy, Debug)]
pub struct CameraInput<'a> {
    /// What the frame was taken with.
    pub info: FrameInfo,
    /// The metered frame.
    pub metered: &'a Metered,
}

/// The overlap patches of one neighbour pair, as seen in this frame set.
#[derive(Clone, Debug, PartialEq)]
pub struct PairObservation {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// The patch means in both cameras.
    pub patches: Vec<PatchPair>,
}

/// The measured brightness ratios of one pair.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairRatio {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// `r_ij`: how much brighter `j` sees the overlap than `i`.
    pub r_ij: Option<f64>,
}

/// One camera's outcome of a rig step (also its telemetry).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraStep {
    /// The camera's index.
    pub camera: usize,
    /// The frame's id.
    pub frame_id: u64,
    /// What the frame was taken with.
    pub taken: ExposureSetting,
    /// The estimate, when the mode uses one.
    pub estimate: Option<Estimate>,
    /// Mean intensity of the metered pixels.
    pub mean: f32,
    /// The camera's own desired exposure.
    pub unary: f64,
    /// α of Eq. 6, when balancing applied.
    pub alpha: Option<f64>,
    /// The fraction `κ` of the balanced step taken, when balancing applied
    /// (1 unless the camera has been circling: [`balance::Damping`]).
    pub damping: Option<f64>,
    /// The exposure after balancing.
    pub target: f64,
    /// The setting sent, if any.
    pub command: Option<ExposureSetting>,
    /// Why no command was sent.
    pub hold: Option<Hold>,
    /// Where the target was outside the camera's ranges.
    pub clamped: Option<Clamped>,
    /// Whether the mean-intensity fallback replaced an empty metric.
    pub fallback: bool,
    /// What a probe (darker or brighter) did on this frame
    /// ([`crate::exposure::probe`]).
    pub probe: Option<ProbeEvent>,
    /// Whether the frame was taken at a probe's exposure.
    pub probe_frame: bool,
}

/// The outcome of one rig step.
#[derive(Clone, Debug, PartialEq)]
pub struct RigStep {
    /// Per camera.
    pub cameras: Vec<CameraStep>,
    /// Per neighbour pair, both directions.
    pub ratios: Vec<PairRatio>,
}

/// The controllers of a whole rig.
#[derive(Clone, Debug)]
pub struct RigController {
    config: ControllerConfig,
    cameras: Vec<CameraController>,
    graph: NeighbourGraph,
    held: balance::HeldRatios,
}

impl RigController {
    /// A controller for cameras with `ranges` and overlaps `graph`.
    pub fn new(
        config: ControllerConfig,
        ranges: &[ExposureRange],
        graph: NeighbourGraph,
    ) -> Result<Self> {
        config.validate()?;
        if graph.cameras() != ranges.len() {
            return Err(Error::invalid(
                "rig controller",
                "exposure ranges",
                format!(
                    "one for each of the neighbour graph's {} cameras",
                    graph.cameras()
                ),
                ranges.len(),
            ));
        }
        let cameras = ranges
            .iter()
            .map(|r| CameraController::new(&config, *r))
            .collect::<Result<_>>()?;
        Ok(Self {
            config,
            cameras,
            graph,
            held: balance::HeldRatios::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Replaces the configuration live; each camera keeps its state, and its
    /// estimator is rebuilt if the estimator settings changed.
    pub fn set_config(&mut self, config: ControllerConfig) -> Result<()> {
        config.validate()?;
        if config.estimator != self.config.estimator || config.split != self.config.split {
            for cam in &mut self.cameras {
                let mut fresh = CameraController::new(&config, *cam.splitter.range())?;
                fresh.manual = cam.manual;
                fresh.last_frame = cam.last_frame;
                fresh.in_flight = cam.in_flight.clone();
                fresh.frames = cam.frames;
                fresh.walker = cam.walker.take();
                fresh.set_tone_curve(cam.tone.take())?;
                *cam = fresh;
            }
        }
        if config.pid != self.config.pid || config.mode != self.config.mode {
            for cam in &mut self.cameras {
                cam.pid.reset();
            }
        }
        self.config = config;
        Ok(())
    }

    /// The neighbour graph.
    pub fn graph(&self) -> &NeighbourGraph {
        &self.graph
    }

    /// Camera `i`'s controller.
    pub fn camera_mut(&mut self, i: usize) -> Result<&mut CameraController> {
        let count = self.cameras.len();
        self.cameras
            .get_mut(i)
            .ok_or(Error::CameraIndex { index: i, count })
    }

    /// Number of cameras.
    pub fn len(&self) -> usize {
        self.cameras.len()
    }

    /// Whether the rig has no cameras.
    pub fn is_empty(&self) -> bool {
        self.cameras.is_empty()
    }

    /// One step on a complete frame set: `inputs[i]` is camera `i`'s frame,
    /// `pairs` the overlap patches of neighbour pairs (their ratios are
    /// reported in every mode and acted on when balancing is on).
    pub fn step(
        &mut self,
        inputs: &[CameraInput<'_>],
        pairs: &[PairObservation],
    ) -> Result<RigStep> {
        if inputs.len() != self.cameras.len() {
            return Err(Error::invalid(
                "rig step",
                "frames",
                format!(
                    "a complete set, one for each of {} cameras",
                    self.cameras.len()
                ),
                inputs.len(),
            ));
        }
        let config = &self.config;
        let unary = self
            .cameras
            .iter_mut()
            .zip(inputs)
            .map(|(c, input)| c.unary(config, &input.info, input.metered))
            .collect::<Result<Vec<_>>>()?;
        // The ratios are measured in every mode (telemetry); only balancing
        // acts on them.
        let mut ratios = Vec::with_capacity(pairs.len() * 2);
        // The same as ratios of light, which balancing moves exposures by:
        // through the cameras' tone curves (as `ratios` where none has one).
        let mut light = Vec::with_capacity(pairs.len() * 2);
        // Per ratio, whether its patches are clipped.
        let mut clipped = Vec::with_capacity(pairs.len() * 2);
        let measure = config.balancing.unwrap_or_default();
        {
            let params = &measure;
            for p in pairs {
                for k in [p.i, p.j] {
                    if k >= self.cameras.len() {
                        return Err(Error::CameraIndex {
                            index: k,
                            count: self.cameras.len(),
                        });
                    }
                }
                let swapped: Vec<PatchPair> = p
                    .patches
                    .iter()
                    .map(|q| PatchPair {
                        mean_i: q.mean_j,
                        saturated_i: q.saturated_j,
                        mean_j: q.mean_i,
                        saturated_j: q.saturated_i,
                    })
                    .collect();
                for (i, j, patches) in [(p.i, p.j, &p.patches), (p.j, p.i, &swapped)] {
                    let r_ij = balance::pair_ratio(patches, params);
                    let curves = [self.cameras[i].tone_curve(), self.cameras[j].tone_curve()];
                    light.push(PairRatio {
                        i,
                        j,
                        r_ij: if curves.iter().any(Option::is_some) {
                            balance::pair_ratio_through(patches, params, curves)
                        } else {
                            r_ij
                        },
                    });
                    ratios.push(PairRatio { i, j, r_ij });
                }
                let clips = balance::clipped(&p.patches, params);
                clipped.extend([clips, clips]);
            }
        }
        // Where each camera will be once its commands in flight show: the
        // balancing works there, so that a frame taken before the last
        // command showed does not ask for the same step again.
        let bases: Vec<f64> = self
            .cameras
            .iter()
            .zip(inputs)
            .map(|(c, input)| c.base(input.info.taken).exposure())
            .collect();
        // Where each camera rests, for its neighbours: a probe (a ladder's
        // rung too), in flight or shown, counts at its home, the exposure
        // the camera returns to. Balanced to the probe in flight, the car
        // park's front and back cameras stepped 0.16 and 0.18 EV down with
        // the left camera's probe and climbed back over four sets.
        let rests: Vec<f64> = self
            .cameras
            .iter()
            .zip(inputs)
            .map(|(c, input)| c.rest_exposure(input.info.taken))
            .collect();
        // What balancing acts on: the measured ratios, or a pair's held
        // scene ratio while its patches are unusable. A probe frame's
        // patches are clipped less than the frames at rest, so its ratio
        // is not the one the rest balances: the pair holds its scene ratio
        // over it, and the neighbours stay where they are.
        let probing = |k: usize| unary.get(k).is_some_and(|u| u.probe_frame);
        let acted: Vec<PairRatio> = light
            .iter()
            .zip(&clipped)
            .map(|(r, &clipped)| {
                let probe = probing(r.i) || probing(r.j);
                PairRatio {
                    r_ij: self.held.update(
                        (r.i, r.j),
                        r.r_ij.filter(|_| !probe),
                        inputs[r.i].info.taken.exposure(),
                        inputs[r.j].info.taken.exposure(),
                        measure.hold_sets,
                        clipped || probe,
                    ),
                    ..*r
                }
            })
            .collect();
        let mut steps = Vec::with_capacity(inputs.len());
        for (i, (u, input)) in unary.into_iter().zip(inputs).enumerate() {
            let cam = &mut self.cameras[i];
            let balancing = config.balancing.filter(|_| {
                cam.manual.is_none() && config.mode != ControlMode::Fixed && !cam.probe_alone()
            });
            let neighbour: Vec<f64> = match balancing {
                Some(_) => self
                    .graph
                    .neighbours(i)
                    .filter_map(|j| {
                        // r_ij as the two cameras will see the overlap,
                        // camera i at its base and j where it rests (a
                        // linear sensor's brightness follows its exposure).
                        let moved =
                            (rests[j] / inputs[j].info.taken.exposure()) / (bases[i] / u.taken);
                        acted
                            .iter()
                            .find(|r| r.i == i && r.j == j)
                            .and_then(|r| r.r_ij)
                            .map(|r| r * moved)
                    })
                    .collect(),
                None => Vec::new(),
            };
            // A camera following a change of light goes where its
            // balanced command would have gone in the reference's light.
            let (target, alpha, damping) = match balancing
                .filter(|_| !neighbour.is_empty() && u.light.is_none())
            {
                Some(params) => {
                    // A uniform change of light is measured under
                    // every gradient law (the camera follows it, and
                    // the damping starts again). The frames' means
                    // also guess at changes the measurement leaves to
                    // the law (not uniform over the image), except
                    // under the fast law, whose jumps leave frames at
                    // several exposures in flight that would read as
                    // changes. (A probe frame's mean is no change of
                    // light.)
                    if config.law.kind != LawKind::Fast && !u.probe_frame {
                        cam.damping.observe(
                            input.info.taken.exposure().log2(),
                            f64::from(input.metered.stats().mean),
                            config.bracket.light_tolerance,
                        );
                    }
                    // A probe frame's own law asks from a darker frame:
                    // its `α` is not the rest's, and stays out of the
                    // mean.
                    let b = balance::balance_with(u.desired, bases[i], &neighbour, |a| {
                        if cam.has_levels() {
                            a
                        } else if u.probe_frame {
                            cam.damping.alpha_mean().unwrap_or(a)
                        } else {
                            cam.damping.smooth_alpha(
                                a,
                                params
                                    .damping
                                    .alpha_weight_under(config.estimator.simulation),
                            )
                        }
                    });
                    // Balancing may not cost the camera more than
                    // its share of `M` (a probe frame's estimate is
                    // of a darker frame and says nothing of the rest).
                    let balanced = match (&u.estimate, u.probe_frame) {
                        (Some(est), false) => {
                            balance::guard_m(b.exposure, u.desired, u.taken, est, params.max_m_loss)
                        }
                        _ => b.exposure,
                    };
                    // On fixed levels the walker keeps a camera from
                    // circling, and a damped step would only add up
                    // more slowly.
                    let (e, kappa) = if cam.has_levels() {
                        (balanced, 1.0)
                    } else if u.hold.is_some() {
                        (balanced, cam.damping.kappa())
                    } else {
                        cam.damping.apply(bases[i], balanced, &params.damping)
                    };
                    (e, Some(b.alpha), Some(kappa))
                }
                None => {
                    cam.damping.reset();
                    (u.desired, None, None)
                }
            };
            let (command, clamped, hold) = if u.hold.is_some() {
                (None, None, u.hold)
            } else {
                let (cmd, clamped) = cam.command(target, input.info.taken);
                let hold = if cmd.is_none() {
                    Some(Hold::Settled)
                } else {
                    None
                };
                (cmd, clamped, hold)
            };
            steps.push(CameraStep {
                camera: i,
                frame_id: input.info.frame_id,
                taken: input.info.taken,
                estimate: u.estimate,
                mean: input.metered.stats().mean,
                unary: u.desired,
                alpha,
                damping,
                target,
                command,
                hold,
                clamped,
                fallback: u.fallback,
                probe: u.probe,
                probe_frame: u.probe_frame,
            });
        }
        Ok(RigStep {
            cameras: steps,
            ratios,
        })
    }
}
