//! `rigview surround`: compose still images of a calibrated rig into a
//! bird's-eye view, to check a calibration.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use rigview_core::bowl::{BowlSpec, Viewpoint};
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
    /// What to compose: the bird's-eye view, or the 3-D bowl around the
    /// vehicle (flat as far as the ground shown reaches, the vehicle model
    /// in the middle) from `--viewpoint`.
    #[arg(long, value_enum, default_value = "surround")]
    pub view: StillView,
    /// Where the bowl is seen from: top, rear, front, behind-left,
    /// behind-right, left or right.
    #[arg(long, value_name = "NAME", default_value = "behind-left")]
    pub viewpoint: String,
    /// A vehicle model for the bowl instead of the built-in one: glTF 2.0
    /// (`.gltf` with its `.bin`, or `.glb`; front along +z) or Wavefront
    /// OBJ (front along −z); y up, scaled onto the vehicle's box.
    #[arg(long, value_name = "FILE")]
    pub vehicle_model: Option<PathBuf>,
    /// The bowl picture's width and height, pixels.
    #[arg(long, num_args = 2, value_names = ["W", "H"], default_values_t = [1280, 800])]
    pub size_px: Vec<usize>,
}

/// What `rigview surround` composes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StillView {
    /// The bird's-eye view of the ground.
    Surround,
    /// The bowl around the vehicle from a viewpoint.
    Bowl,
}

impl SurroundArgs {
    /// What to compose: the options given, the canvas's defaults for the
    /// rest; an unknown viewpoint is an error naming the presets.
    pub fn stills(&self) -> Result<Stills> {
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
        let canvas = CanvasSpec {
            x_min_m,
            x_max_m,
            y_min_m,
            y_max_m,
            px_per_m: self.px_per_m,
            vehicle_m: four(&self.vehicle_m, defaults.vehicle_m),
        };
        let bowl = match self.view {
            StillView::Surround => None,
            StillView::Bowl => {
                let viewpoint = Viewpoint::preset(&self.viewpoint)
                    .map_err(|e| anyhow::anyhow!("--viewpoint: {e}"))?;
                let size_px = match self.size_px.as_slice() {
                    [w, h] => [*w, *h],
                    _ => anyhow::bail!("--size-px: expected a width and a height"),
                };
                Some((
                    BowlSpec {
                        size_px,
                        vehicle_model: self.vehicle_model.clone(),
                        ..BowlSpec::around(&canvas)
                    },
                    viewpoint,
                ))
            }
        };
        Ok(Stills {
            rig: self.input.rig.clone(),
            images: self.input.images.clone(),
            out: self.out.clone(),
            blend: self.input.blend,
            canvas,
            vehicle_image: self.vehicle_image.clone(),
            bowl,
        })
    }
}

/// Runs `rigview surround`, reporting to `out`.
pub fn run(args: &SurroundArgs, out: &mut dyn Write) -> Result<()> {
    surround::run(&args.stills()?, out)
}
