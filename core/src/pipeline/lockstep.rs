//! The processor driven synchronously in lock step with its source: each
//! set is processed and its commands applied before the next set is asked
//! for. Offline runs, the demo and the closed-loop tests use it; the app's
//! threads ([`super::Pipeline`]) run the same [`Processor`].

use std::time::{Duration, Instant};

use super::{Output, ProcessingSettings, Processor, StageTimes, Strategy};
use crate::error::Error;
use crate::source::{FrameSet, FrameSource, SourceError};

/// One set through the loop.
#[derive(Clone, Debug)]
pub struct LoopStep {
    /// The frame set as the source gave it.
    pub set: FrameSet,
    /// What processing made of it (`None`: the set was incomplete and was
    /// kept from the controller).
    pub output: Option<Output>,
}

/// A source and a [`Processor`] in lock step.
#[derive(Debug)]
pub struct LockStep<S: FrameSource> {
    source: S,
    processor: Processor,
    timeout: Duration,
    processed: u64,
    incomplete: u64,
}

impl<S: FrameSource> LockStep<S> {
    /// A loop of `processor` on `source`; their cameras must agree in count
    /// and image size. Under [`Strategy::CameraAuto`] the cameras' own
    /// auto-exposure is switched on.
    pub fn new(mut source: S, processor: Processor) -> Result<Self, SourceError> {
        let (a, b) = (source.cameras(), processor.cameras());
        if a.len() != b.len() {
            return Err(Error::invalid(
                "lock step",
                "the source's cameras",
                format!("the processor's {}", b.len()),
                a.len(),
            )
            .into());
        }
        if let Some((s, p)) = a
            .iter()
            .zip(b)
            .find(|(s, p)| (s.width, s.height) != (p.width, p.height))
        {
            return Err(Error::invalid(
                "lock step",
                format!("camera \"{}\"'s image size", s.name),
                format!("the processor's {}×{}", p.width, p.height),
                format_args!("{}×{}", s.width, s.height),
            )
            .into());
        }
        if processor.settings().strategy == Strategy::CameraAuto {
            source.set_camera_auto(true)?;
        }
        Ok(Self {
            source,
            processor,
            timeout: Duration::from_secs(5),
            processed: 0,
            incomplete: 0,
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

    /// The processor.
    pub fn processor(&self) -> &Processor {
        &self.processor
    }

    /// The processor, to change (settings, manual overrides, a new
    /// calibration, composition on or off).
    pub fn processor_mut(&mut self) -> &mut Processor {
        &mut self.processor
    }

    /// Applies new processing settings from the next set on, switching the
    /// cameras' own auto-exposure where the strategy asks.
    pub fn set_settings(&mut self, settings: ProcessingSettings) -> Result<(), SourceError> {
        if let Some(on) = self.processor.set_settings(settings)? {
            self.source.set_camera_auto(on)?;
        }
        Ok(())
    }

    /// How long [`LockStep::step`] waits for a set (default 5 s).
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// Complete sets processed so far.
    pub fn processed(&self) -> u64 {
        self.processed
    }

    /// Incomplete sets so far (kept from the controller).
    pub fn incomplete(&self) -> u64 {
        self.incomplete
    }

    /// One set through the loop: processed, and its commands applied to the
    /// source. `None` when the source gave no set within its timeout or has
    /// ended.
    pub fn step(&mut self) -> Result<Option<LoopStep>, SourceError> {
        let t = Instant::now();
        let Some(set) = self.source.next_set(self.timeout)? else {
            return Ok(None);
        };
        let ready = Instant::now();
        if !set.is_complete() {
            self.incomplete += 1;
            return Ok(Some(LoopStep { set, output: None }));
        }
        let times = StageTimes {
            capture_ms: super::processor::ms(ready - t),
            ..Default::default()
        };
        let (output, commands) = self.processor.process(&set, ready, times)?;
        self.processed += 1;
        if !commands.is_empty() {
            self.source.apply(&commands)?;
        }
        Ok(Some(LoopStep {
            set,
            output: Some(output),
        }))
    }
}
