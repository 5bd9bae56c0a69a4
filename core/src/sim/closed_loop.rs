//! Exposure control in closed loop on a frame source: each set is metered
//! (optionally on the surround view's ground masks), its overlap patches are
//! measured, the rig controller steps, and its commands go back to the
//! source.

use std::time::Duration;

use crate::error::{Error, Result};
use crate::exposure::{
    CameraMasks, Meter, Metered, PairObservation, RigController, RigStep, RoiMask,
};
use crate::source::{FrameSet, FrameSource, SourceError};
use crate::surround::SurroundView;

/// What one step did.
#[derive(Clone, Debug)]
pub struct LoopStep {
    /// The frame set.
    pub set: FrameSet,
    /// The metered frames (empty when the set was incomplete).
    pub metered: Vec<Metered>,
    /// The overlap patches measured in the set.
    pub pairs: Vec<PairObservation>,
    /// The controller's step (`None`: the set was incomplete and skipped).
    pub step: Option<RigStep>,
}

/// A source, a meter and a rig controller in a loop.
#[derive(Debug)]
pub struct ClosedLoop<S: FrameSource> {
    source: S,
    meter: Meter,
    view: Option<SurroundView>,
    masks: CameraMasks,
    controller: RigController,
    timeout: Duration,
}

impl<S: FrameSource> ClosedLoop<S> {
    /// A loop on `source`. With a surround view, only its ground masks are
    /// metered and its overlap patches give the pairs; without, whole
    /// frames are metered and no pairs are measured.
    pub fn new(
        source: S,
        controller: RigController,
        meter: Meter,
        view: Option<SurroundView>,
    ) -> Result<Self> {
        let n = source.cameras().len();
        if controller.len() != n {
            return Err(Error::InvalidConfig(format!(
                "closed loop: the controller has {} cameras, the source {n}",
                controller.len()
            )));
        }
        let masks = match &view {
            Some(v) => {
                if v.layers().len() != n {
                    return Err(Error::InvalidConfig(format!(
                        "closed loop: the surround view has {} cameras, the source {n}",
                        v.layers().len()
                    )));
                }
                let formats: Vec<_> = source.cameras().iter().map(|c| c.format).collect();
                CameraMasks::new(&meter, v.ground_masks(), &formats)
            }
            None => CameraMasks::none(n),
        };
        Ok(Self {
            source,
            meter,
            view,
            masks,
            controller,
            timeout: Duration::from_secs(5),
        })
    }

    /// The source.
    pub fn source(&self) -> &S {
        &self.source
    }

    /// The source, to change.
    pub fn source_mut(&mut self) -> &mut S {
        &mut self.source
    }

    /// The controller.
    pub fn controller(&self) -> &RigController {
        &self.controller
    }

    /// The controller, to change.
    pub fn controller_mut(&mut self) -> &mut RigController {
        &mut self.controller
    }

    /// The surround view, if any.
    pub fn view(&self) -> Option<&SurroundView> {
        self.view.as_ref()
    }

    /// The metering masks, one per camera.
    pub fn masks(&self) -> &[Option<RoiMask>] {
        self.masks.raw()
    }

    /// One set through the loop; `None` when the source gave no set.
    pub fn step(&mut self) -> Result<Option<LoopStep>, SourceError> {
        let Some(set) = self.source.next_set(self.timeout)? else {
            return Ok(None);
        };
        if !set.is_complete() {
            return Ok(Some(LoopStep {
                set,
                metered: Vec::new(),
                pairs: Vec::new(),
                step: None,
            }));
        }
        let frames: Vec<_> = set.frames.iter().flatten().collect();
        let views = frames
            .iter()
            .map(|f| f.view())
            .collect::<Result<Vec<_>>>()?;
        let metered = self.masks.meter(&self.meter, &views)?;
        let pairs = match &self.view {
            Some(v) => v.pair_observations(&views)?,
            None => Vec::new(),
        };
        let step = self.controller.step_frames(&frames, &metered, &pairs)?;
        let commands = step.commands();
        self.source.apply(&commands)?;
        Ok(Some(LoopStep {
            set,
            metered,
            pairs,
            step: Some(step),
        }))
    }
}
