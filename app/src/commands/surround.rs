//! Still images of a calibrated rig composed into a bird's-eye view or
//! the bowl around the vehicle (`rigview surround`), to check a
//! calibration.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use rigview_calib::formats;
use rigview_calib::rig::Rig;
use rigview_core::bowl::{BowlSpec, BowlView, Viewpoint};
use rigview_core::exposure::balance::pair_ratio;
use rigview_core::exposure::{BalanceParams, FrameView, PixelFormat};
use rigview_core::surround::{
    BlendMode, Canvas, CanvasSpec, Composer, SurroundOptions, SurroundView,
};

/// What to compose.
#[derive(Clone, Debug)]
pub struct Stills {
    /// The rig: a rig file or calibration in any supported format (or a
    /// folder of per-camera files), its poses in the vehicle frame.
    pub rig: PathBuf,
    /// One image per camera, in rig order, or as `NAME=PATH`.
    pub images: Vec<String>,
    /// Where to write the bird's-eye view (PNG).
    pub out: PathBuf,
    /// How overlapping cameras are mixed.
    pub blend: BlendMode,
    /// The ground shown, its resolution and the vehicle's rectangle.
    pub canvas: CanvasSpec,
    /// A top-down picture of the vehicle to paste over its rectangle.
    pub vehicle_image: Option<PathBuf>,
    /// The bowl and its viewpoint, to compose the bowl instead of the
    /// bird's-eye view.
    pub bowl: Option<(BowlSpec, Viewpoint)>,
}

/// Composes `stills`, reporting to `out`: the file written, each camera's
/// ground mask, and each overlap's brightness ratio.
pub fn run(stills: &Stills, out: &mut dyn Write) -> Result<()> {
    let (rig, images) = load(&stills.rig, &stills.images)?;
    let spec = &stills.canvas;
    let view = SurroundView::build(&rig, spec, &SurroundOptions::default())
        .context("building the surround view")?;
    let frames = frames(&images)?;
    let mut canvas = Canvas::new(0, 0, 3);
    match &stills.bowl {
        None => {
            Composer::new().compose(&view, &frames, stills.blend, &mut canvas)?;
            if let Some(path) = &stills.vehicle_image {
                paste_vehicle(&mut canvas, spec, path)?;
            }
            save(&canvas, &stills.out)?;
            writeln!(
                out,
                "wrote {} ({}×{} px, {} px/m, {} blending)",
                stills.out.display(),
                canvas.width,
                canvas.height,
                spec.px_per_m,
                stills.blend.name()
            )?;
        }
        Some((bowl, viewpoint)) => {
            let view = BowlView::build(&rig, bowl, viewpoint).context("building the bowl view")?;
            Composer::new().compose(view.mosaic(), &frames, stills.blend, &mut canvas)?;
            view.paint_vehicle(&mut canvas)?;
            save(&canvas, &stills.out)?;
            writeln!(
                out,
                "wrote {} ({}×{} px, the bowl from yaw {:.0}°, pitch {:.0}°, {:.1} m; flat {:.1} m, wall {:.1} m high at {:.1} m; {} blending)",
                stills.out.display(),
                canvas.width,
                canvas.height,
                viewpoint.yaw_deg,
                viewpoint.pitch_deg,
                viewpoint.distance_m,
                bowl.flat_m,
                bowl.wall_height_m,
                bowl.radius_m,
                stills.blend.name()
            )?;
        }
    }
    for (cam, mask) in rig.cameras.iter().zip(view.ground_masks()) {
        writeln!(
            out,
            "{}: ground mask {:.1} % of the image",
            cam.name,
            100.0 * mask.coverage()
        )?;
    }
    let params = BalanceParams::default();
    for (obs, overlap) in view.pair_observations(&frames)?.iter().zip(view.overlaps()) {
        let (a, b) = (&rig.cameras[obs.i].name, &rig.cameras[obs.j].name);
        match pair_ratio(&obs.patches, &params) {
            Some(r) => writeln!(
                out,
                "overlap {a}–{b}: {} px, {} patches, brightness {b}/{a} = {r:.3} ({:+.2} EV)",
                overlap.pixels,
                obs.patches.len(),
                r.log2()
            )?,
            None => writeln!(
                out,
                "overlap {a}–{b}: {} px, no usable patch for a brightness ratio",
                overlap.pixels
            )?,
        }
    }
    Ok(())
}

/// Loads the rig at `rig` and one RGB image per camera (`images`: in rig
/// order, or `NAME=PATH`); an image of another size than its camera's
/// calibration is an error naming the file and the camera.
pub fn load(rig: &Path, images: &[String]) -> Result<(Rig, Vec<image::RgbImage>)> {
    let loaded = formats::load(rig, None, None)
        .with_context(|| format!("loading the rig {}", rig.display()))?;
    let rig = loaded.rig;
    let paths = image_paths(images, &rig)?;
    let images = paths
        .iter()
        .map(|p| {
            image::open(p)
                .map(|i| i.to_rgb8())
                .with_context(|| format!("reading the image {}", p.display()))
        })
        .collect::<Result<Vec<_>>>()?;
    for ((cam, img), path) in rig.cameras.iter().zip(&images).zip(&paths) {
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        if (img.width(), img.height()) != (w, h) {
            bail!(
                "{}: the image is {}×{}, but camera `{}` is calibrated for {w}×{h}",
                path.display(),
                img.width(),
                img.height(),
                cam.name
            );
        }
    }
    Ok((rig, images))
}

/// The images as RGB8 frames.
pub fn frames(images: &[image::RgbImage]) -> Result<Vec<FrameView<'_>>> {
    Ok(images
        .iter()
        .map(|i| {
            FrameView::new(
                PixelFormat::Rgb8,
                i.width() as usize,
                i.height() as usize,
                i.as_raw(),
            )
        })
        .collect::<rigview_core::Result<Vec<_>>>()?)
}

/// Writes an RGB canvas as PNG.
pub fn save(canvas: &Canvas, path: &Path) -> Result<()> {
    image::save_buffer(
        path,
        &canvas.data,
        canvas.width as u32,
        canvas.height as u32,
        image::ColorType::Rgb8,
    )
    .with_context(|| format!("writing {}", path.display()))
}

/// The image of each camera, in rig order.
fn image_paths(images: &[String], rig: &Rig) -> Result<Vec<PathBuf>> {
    let n = rig.cameras.len();
    let named: Vec<Option<(&str, &str)>> = images.iter().map(|a| a.split_once('=')).collect();
    if named.iter().all(Option::is_some) {
        let mut paths = vec![None; n];
        for (name, path) in named.into_iter().flatten() {
            let Some(k) = rig.index_of(name) else {
                bail!(
                    "--images {name}={path}: the rig has no camera `{name}` (it has {})",
                    names(rig)
                );
            };
            paths[k] = Some(PathBuf::from(path));
        }
        return paths
            .into_iter()
            .enumerate()
            .map(|(k, p)| {
                p.with_context(|| {
                    format!("--images: no image for camera `{}`", rig.cameras[k].name)
                })
            })
            .collect();
    }
    if images.len() != n {
        bail!(
            "--images: {} images for a rig of {n} cameras ({}): give one per camera in rig order, or NAME=PATH",
            images.len(),
            names(rig)
        );
    }
    Ok(images.iter().map(PathBuf::from).collect())
}

fn names(rig: &Rig) -> String {
    rig.cameras
        .iter()
        .map(|c| c.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Pastes a picture of the vehicle over its rectangle.
fn paste_vehicle(canvas: &mut Canvas, spec: &CanvasSpec, path: &Path) -> Result<()> {
    let [c0, r0, w, h] = spec.vehicle_rect_px();
    if w == 0 || h == 0 {
        return Ok(());
    }
    let img = image::open(path)
        .with_context(|| format!("reading the vehicle image {}", path.display()))?
        .to_rgb8();
    let img = image::imageops::resize(
        &img,
        w as u32,
        h as u32,
        image::imageops::FilterType::Triangle,
    );
    for (y, row) in img.rows().enumerate() {
        for (x, p) in row.enumerate() {
            let i = 3 * ((r0 + y) * canvas.width + c0 + x);
            if let Some(dst) = canvas.data.get_mut(i..i + 3) {
                dst.copy_from_slice(&p.0);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz")
    }

    fn args(images: Vec<String>, out: PathBuf) -> Stills {
        Stills {
            rig: data(),
            images,
            out,
            blend: BlendMode::Seams,
            canvas: CanvasSpec {
                x_min_m: -8.0,
                x_max_m: 8.0,
                y_min_m: -6.0,
                y_max_m: 6.0,
                px_per_m: 25.0,
                vehicle_m: [-2.5, 2.5, -1.0, 1.0],
            },
            vehicle_image: Some(data().join("car.png")),
            bowl: None,
        }
    }

    #[test]
    fn composes_the_real_rig_into_the_bowl() {
        let dir = std::env::temp_dir().join(format!("rigview-bowl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out_png = dir.join("bowl.png");
        let images = ["front", "left", "back", "right"]
            .iter()
            .map(|n| data().join(format!("{n}.png")).display().to_string())
            .collect();
        let mut stills = args(images, out_png.clone());
        let viewpoint = Viewpoint::preset("behind-left").unwrap();
        stills.bowl = Some((
            BowlSpec {
                size_px: [400, 250],
                ..BowlSpec::around(&stills.canvas)
            },
            viewpoint,
        ));
        let mut report = Vec::new();
        run(&stills, &mut report).unwrap();
        let report = String::from_utf8(report).unwrap();
        assert!(report.contains("the bowl from yaw 145°"), "{report}");
        let written = image::open(&out_png).unwrap().to_rgb8();
        assert_eq!((written.width(), written.height()), (400, 250));
        // The bowl fills the picture below the rim: most pixels show a
        // camera or the vehicle.
        let lit = written
            .pixels()
            .filter(|p| p.0.iter().any(|&v| v > 8))
            .count();
        assert!(lit * 10 > 7 * 400 * 250, "{lit} lit pixels");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn composes_the_real_rig_from_named_images() {
        let dir = std::env::temp_dir().join(format!("rigview-surround-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out_png = dir.join("bev.png");
        let images = ["back", "front", "left", "right"]
            .iter()
            .map(|n| format!("{n}={}", data().join(format!("{n}.png")).display()))
            .collect();
        let mut report = Vec::new();
        run(&args(images, out_png.clone()), &mut report).unwrap();
        let report = String::from_utf8(report).unwrap();
        assert!(report.contains("overlap front–left"), "{report}");
        assert!(report.contains("brightness"), "{report}");
        let written = image::open(&out_png).unwrap();
        assert_eq!((written.width(), written.height()), (300, 400));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn wrong_image_lists_are_errors_naming_the_problem() {
        let out = std::env::temp_dir().join("never-written.png");
        let e = run(&args(vec!["a.png".into()], out.clone()), &mut Vec::new()).unwrap_err();
        assert!(
            format!("{e:#}").contains("1 images for a rig of 4 cameras"),
            "{e:#}"
        );
        let e = run(
            &args(vec!["top=a.png".into(); 4], out.clone()),
            &mut Vec::new(),
        )
        .unwrap_err();
        assert!(format!("{e:#}").contains("no camera `top`"), "{e:#}");
        let small = data().join("car.png");
        let images = vec![small.display().to_string(); 4];
        let e = run(&args(images, out), &mut Vec::new()).unwrap_err();
        assert!(format!("{e:#}").contains("calibrated for 960×640"), "{e:#}");
    }
}
