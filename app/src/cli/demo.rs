//! `rigview demo`: closed-loop exposure control on the simulated rig,
//! printed frame set by frame set.

use std::io::Write;

use anyhow::{Context, Result};
use clap::Args;
use rigview_core::pipeline::ProcessingSettings;
use rigview_core::sim::SimConfig;

use super::options::ControlArgs;
use crate::commands::demo::{self, Demo};

/// Options of `rigview demo`.
#[derive(Clone, Debug, Args)]
pub struct DemoArgs {
    /// The simulation: a preset (reference, steps, ramp, tunnel, backlight,
    /// overcast, sky, tunnel-exit, snow, lawn) or a simulation file (see
    /// assets/sim/).
    #[arg(long, default_value = "reference")]
    pub scenario: String,
    /// Frame sets to run [default: the scenario's length at its trigger
    /// rate].
    #[arg(long)]
    pub frames: Option<u64>,
    /// Print every K-th frame set.
    #[arg(long, default_value_t = 1)]
    pub every: u64,
    /// The control loop's options [defaults: multi, nonlinear, gamma,
    /// ground, probes on].
    #[command(flatten)]
    pub control: ControlArgs,
    /// Frames between a command and the first frame that shows it, 0 to 2
    /// [default: the scenario's].
    #[arg(long)]
    pub latency: Option<u32>,
    /// Starting shutter time of every camera, µs [default: the scenario's].
    #[arg(long)]
    pub start_us: Option<f64>,
    /// Render at this fraction of the rig's resolution (0.25: 322×241).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Output bits of the cameras, 8 or 12 [default: the scenario's].
    #[arg(long)]
    pub bits: Option<u32>,
    /// Seed of the sensor noise [default: the scenario's].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Produce frame sets at the trigger rate instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
}

impl DemoArgs {
    /// The processing settings: the defaults, with the options given.
    pub fn settings(&self) -> ProcessingSettings {
        let mut s = ProcessingSettings::default();
        self.control.apply(&mut s);
        s
    }

    /// The demo these options ask for.
    pub fn demo(&self) -> Result<Demo> {
        let mut c = SimConfig::named(&self.scenario)
            .with_context(|| format!("loading the simulation \"{}\"", self.scenario))?;
        c.scale = self.scale;
        if let Some(l) = self.latency {
            c.latency_frames = l;
        }
        if let Some(s) = self.start_us {
            c.start.shutter_us = s;
        }
        if let Some(b) = self.bits {
            c.sensor.bits = b;
        }
        if let Some(s) = self.seed {
            c.seed = s;
        }
        c.validate().context("the demo's options")?;
        Ok(Demo {
            scenario: self.scenario.clone(),
            sim: c,
            frames: self.frames,
            every: self.every,
            realtime: self.realtime,
        })
    }
}

/// Runs `rigview demo`, printing to `out`.
pub fn run(args: &DemoArgs, out: &mut dyn Write) -> Result<()> {
    demo::run(&args.demo()?, &args.settings(), out)
}
