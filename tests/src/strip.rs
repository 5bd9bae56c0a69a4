//! A strip of linear cameras in a closed loop: [`StripHarness`] renders a
//! [`StripRig`]'s frame sets at the cameras' settings, meters them and
//! measures the overlap patches, and applies commands with the simulated
//! cameras' actuation latency ([`Actuation`]).

use rigview_core::sim::Actuation;
use rigview_core::source::ExposureCommand;
use rigview_core::synth::{LinearCamera, Rect, StripRig};
use rigview_core::Result;

/// One frame set from a [`StripHarness`].
#[derive(Clone, Debug)]
pub struct CapturedSet {
    /// The rendered Mono8 frames.
    pub frames: Vec<Vec<u8>>,
    /// The metered frames.
    pub metered: Vec<rigview_core::exposure::Metered>,
    /// What each frame was taken with.
    pub infos: Vec<rigview_core::exposure::FrameInfo>,
    /// The overlap patches of each neighbour pair.
    pub pairs: Vec<rigview_core::exposure::PairObservation>,
}

/// A [`StripRig`] seen by linear cameras with actuation latency: it renders
/// frame sets at the cameras' current settings and applies exposure
/// commands `latency` frames late, as real cameras do.
#[derive(Clone, Debug)]
pub struct StripHarness {
    rig: StripRig,
    camera: LinearCamera,
    meter: rigview_core::exposure::Meter,
    settings: Vec<rigview_core::exposure::ExposureSetting>,
    actuation: Actuation,
    next_frame: u64,
    patches: Vec<(Rect, Rect)>,
}

impl StripHarness {
    /// A harness on `rig`; every camera starts at `initial`.
    pub fn new(
        rig: StripRig,
        camera: LinearCamera,
        metering: rigview_core::exposure::MeteringConfig,
        latency: u64,
        initial: rigview_core::exposure::ExposureSetting,
    ) -> Result<Self> {
        let patches = rig.overlap_patches(2, 4);
        Ok(Self {
            settings: vec![initial; rig.cameras()],
            rig,
            camera,
            meter: rigview_core::exposure::Meter::new(metering)?,
            actuation: Actuation::new(latency),
            next_frame: 0,
            patches,
        })
    }

    /// The rig.
    pub fn rig(&self) -> &StripRig {
        &self.rig
    }

    /// The setting camera `i` has now.
    pub fn setting(&self, i: usize) -> rigview_core::exposure::ExposureSetting {
        self.settings[i]
    }

    /// Sets camera `i` at once (as at start-up).
    pub fn force(&mut self, i: usize, setting: rigview_core::exposure::ExposureSetting) {
        self.settings[i] = setting;
    }

    /// Sends a command to camera `i`; frames `latency` sets after the next
    /// one show it.
    pub fn command(&mut self, i: usize, setting: rigview_core::exposure::ExposureSetting) {
        self.actuation
            .send(self.next_frame, ExposureCommand { camera: i, setting });
    }

    /// Renders, meters and measures the next frame set.
    pub fn capture(&mut self) -> Result<CapturedSet> {
        use rigview_core::exposure::{FrameInfo, PairObservation, PatchPair};
        use rigview_core::image::{FrameView, PixelFormat};
        let id = self.next_frame;
        self.actuation.apply_due(id, &mut self.settings);
        let (w, h) = (self.rig.width(), self.rig.height());
        let mut frames = Vec::with_capacity(self.rig.cameras());
        let mut metered = Vec::with_capacity(self.rig.cameras());
        let mut infos = Vec::with_capacity(self.rig.cameras());
        for (i, setting) in self.settings.iter().enumerate() {
            let seed = id.wrapping_mul(31).wrapping_add(i as u64);
            let frame =
                self.camera
                    .render_mono8(self.rig.view(i).radiance(), setting.exposure(), seed);
            let view = FrameView::new(PixelFormat::Mono8, w, h, &frame)?;
            metered.push(self.meter.meter(&view, None)?);
            infos.push(FrameInfo {
                frame_id: id,
                taken: *setting,
            });
            frames.push(frame);
        }
        let pairs = self
            .rig
            .pairs()
            .into_iter()
            .map(|(i, j)| PairObservation {
                i,
                j,
                patches: self
                    .patches
                    .iter()
                    .filter_map(|(ri, rj)| {
                        let (mi, si) = metered[i].region_mean(ri.x, ri.y, ri.w, ri.h)?;
                        let (mj, sj) = metered[j].region_mean(rj.x, rj.y, rj.w, rj.h)?;
                        Some(PatchPair {
                            mean_i: mi,
                            saturated_i: si,
                            mean_j: mj,
                            saturated_j: sj,
                        })
                    })
                    .collect(),
            })
            .collect();
        self.next_frame += 1;
        Ok(CapturedSet {
            frames,
            metered,
            infos,
            pairs,
        })
    }

    /// Captures one set, steps `controller` on it and sends its commands.
    pub fn step(
        &mut self,
        controller: &mut rigview_core::exposure::RigController,
    ) -> Result<(CapturedSet, rigview_core::exposure::RigStep)> {
        use rigview_core::exposure::CameraInput;
        let set = self.capture()?;
        let inputs: Vec<CameraInput<'_>> = set
            .metered
            .iter()
            .zip(&set.infos)
            .map(|(m, info)| CameraInput {
                info: *info,
                metered: m,
            })
            .collect();
        let step = controller.step(&inputs, &set.pairs)?;
        for cam in &step.cameras {
            if let Some(cmd) = cam.command {
                self.command(cam.camera, cmd);
            }
        }
        Ok((set, step))
    }
}
