//! `rigview surround`: compose still images of a calibrated rig into a
//! bird's-eye view, to check a calibration.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use rigview_core::surround::{BlendMode, CanvasSpec};

use crate::commands::surround::{self, Stills};

/// A calibrated rig, one still image per camera, and how to blend them:
/// what `rigview surround` and `rigview panorama` compose.
#[derive(Debug, Args)]
pub struct RigImages {
    /// The rig: a rig file or calibration in any supported format (a folder
    /// of per-camera files works too). Its poses must be in the vehicle
    /// frame.
    #[arg(long)]
    pub rig: PathBuf,
    /// One image per camera, in rig order, or as NAME=PATH (e.g.
    /// front=front.png). Any format the `image` crate reads.
    #[arg(long, num_args = 1.., required = true)]
    pub images: Vec<String>,
    /// How overlapping cameras are mixed.
    #[arg(long, value_enum, default_value = "linear")]
    pub blend: BlendMode,
}

/// Options of `rigview surround`.
#[derive(Debug, Args)]
pub struct SurroundArgs {
    /// The rig, its images and the blending.
    #[command(flatten)]
    pub input: RigImages,
    /// Where to write the bird's-eye view (PNG).
    #[arg(long)]
    pub out: PathBuf,
    /// The ground shown: X_MIN X_MAX Y_MIN Y_MAX in metres (vehicle frame: x
    /// forward, y left).
    #[arg(long, num_args = 4, value_names = ["X_MIN", "X_MAX", "Y_MIN", "Y_MAX"], allow_negative_numbers = true)]
    pub extent_m: Option<Vec<f64>>,
    /// The vehicle's rectangle: X_MIN X_MAX Y_MIN Y_MAX in metres.
    #[arg(long, num_args = 4, value_names = ["X_MIN", "X_MAX", "Y_MIN", "Y_MAX"], allow_negative_numbers = true)]
    pub vehicle_m: Option<Vec<f64>>,
    /// Canvas pixels per metre.
    #[arg(long, default_value_t = 100.0)]
    pub px_per_m: f64,
    /// A top-down picture of the vehicle to paste over its rectangle.
    #[arg(long)]
    pub vehicle_image: Option<PathBuf>,
}

impl SurroundArgs {
    /// What to compose: the options given, the canvas's defaults for the
    /// rest.
    pub fn stills(&self) -> Stills {
        let defaults = CanvasSpec::default();
        let four = |v: &Option<Vec<f64>>, d: [f64; 4]| match v.as_deref() {
            Some([a, b, c, e]) => [*a, *b, *c, *e],
            _ => d,
        };
        let [x_min_m, x_max_m, y_min_m, y_max_m] = four(
            &self.extent_m,
            [
                defaults.x_min_m,
                defaults.x_max_m,
                defaults.y_min_m,
                defaults.y_max_m,
            ],
        );
        Stills {
            rig: self.input.rig.clone(),
            images: self.input.images.clone(),
            out: self.out.clone(),
            blend: self.input.blend,
            canvas: CanvasSpec {
                x_min_m,
                x_max_m,
                y_min_m,
                y_max_m,
                px_per_m: self.px_per_m,
                vehicle_m: four(&self.vehicle_m, defaults.vehicle_m),
            },
            vehicle_image: self.vehicle_image.clone(),
        }
    }
}

/// Runs `rigview surround`, reporting to `out`.
pub fn run(args: &SurroundArgs, out: &mut dyn Write) -> Result<()> {
    surround::run(&args.stills(), out)
}
