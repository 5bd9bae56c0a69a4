//! Every camera model through the simulated rig, the surround view and the
//! panorama: a
//! rig whose cameras use the double-sphere, the extended unified or the
//! unified (Mei) model renders, and the surround view built from the same
//! rig lines neighbouring cameras up in their overlaps; a view built with
//! one model parameter wrong does not.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use rigview_calib::formats::{self, Format};
use rigview_calib::model::ocam::Ocam;
use rigview_calib::{Distortion, Rig};
use rigview_core::image::{FrameView, PixelFormat};
use rigview_core::panorama::{CylinderSpec, Panorama, PanoramaOptions};
use rigview_core::sim::{reference_rig, SimConfig, SimRender};
use rigview_core::source::Frame;
use rigview_core::surround::{CanvasSpec, Composer, SurroundOptions, SurroundView};

/// The reference rig's poses with every camera's lens replaced by
/// `distortion` at focal length `f` (pixels of the full-size image).
fn rig_with(distortion: Distortion, f: f64) -> Rig {
    let mut rig = reference_rig().unwrap();
    for c in &mut rig.cameras {
        c.intrinsics.distortion = distortion;
        c.intrinsics.fx = f;
        c.intrinsics.fy = f;
    }
    rig
}

/// The relative mean absolute difference between neighbours' warps where
/// both show the ground, over every neighbour pair, of the frames rendered
/// through `rendered` and warped through `viewed` (the same rig but for
/// the lens, scaled as the render's).
fn overlap_difference(render: &SimRender, viewed: &Rig) -> f64 {
    let spec = CanvasSpec {
        px_per_m: 25.0,
        ..CanvasSpec::default()
    };
    let view = SurroundView::build(viewed, &spec, &SurroundOptions::default()).unwrap();
    let setting = render.config().start;
    let frames: Vec<Frame> = render
        .cameras()
        .iter()
        .enumerate()
        .map(|(i, info)| {
            let req = rigview_core::sim::FillRequest::new(
                i,
                0,
                setting,
                info.format,
                info.width,
                info.height,
            );
            let mut buf = vec![0u8; req.buffer_len()];
            let meta = render.fill(&req, &mut buf).unwrap();
            Frame::new(meta, buf.into()).unwrap()
        })
        .collect();
    let views: Vec<FrameView<'_>> = frames.iter().map(|f| f.view().unwrap()).collect();
    let mut composer = Composer::new();
    let warps: Vec<_> = (0..views.len())
        .map(|k| composer.warp_camera(view.mosaic(), k, &views[k]).unwrap())
        .collect();
    let (mut diff, mut sum, mut n) = (0.0, 0.0, 0usize);
    for &(i, j) in &viewed.neighbours {
        for (a, b) in warps[i].data.iter().zip(&warps[j].data) {
            if *a > 0 && *b > 0 {
                diff += f64::from(a.abs_diff(*b));
                sum += 0.5 * (f64::from(*a) + f64::from(*b));
                n += 1;
            }
        }
    }
    assert!(n > 2000, "only {n} overlap pixels");
    diff / sum
}

#[test]
fn every_sphere_model_renders_and_its_surround_view_lines_neighbours_up() {
    // Lenses of about the reference camera's field of view.
    let cases = [
        (Distortion::DoubleSphere([-0.2, 0.6]), 250.0, 1, 0.05),
        (Distortion::Eucm([0.6, 1.1]), 260.0, 0, 0.05),
        (
            Distortion::Omni([0.9, -0.05, 0.004, 0.0005, -0.0005, 0.0]),
            420.0,
            0,
            0.1,
        ),
        // WoodScape's polynomial (in units of the focal length here).
        (
            Distortion::RadialPoly([1.0, -0.05, 0.06, -0.015]),
            300.0,
            1,
            0.05,
        ),
        // Scaramuzza's (OCamCalib's pol in pixels: focal length 1), its
        // pol[0] (the focal length, about) the parameter made wrong.
        (
            Distortion::Scaramuzza(
                Ocam::new(&[-320.0, 0.0, 1.2e-3], &[], [1.0, 0.0, 0.0]).unwrap(),
            ),
            1.0,
            3,
            30.0,
        ),
    ];
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::preset("overcast").unwrap()
    };
    // What neighbours differ by through the reference rig's own lens (the
    // Kannala–Brandt fisheye): the ground seen from two angles, noise and
    // each camera's vignetting.
    let reference = SimRender::with_rig(&config, reference_rig().unwrap()).unwrap();
    let baseline = overlap_difference(&reference, reference.rig());
    println!("fisheye: overlap difference {baseline:.4}");
    for (distortion, f, wrong_at, delta) in cases {
        let name = distortion.model_name();
        let render = SimRender::with_rig(&config, rig_with(distortion, f)).unwrap();
        let same = overlap_difference(&render, render.rig());
        // The same rig with one parameter of the lens off by `delta`.
        let mut wrong = render.rig().clone();
        for c in &mut wrong.cameras {
            let mut k = c.intrinsics.distortion.coefficients().to_vec();
            k[wrong_at] += delta;
            c.intrinsics.distortion = match c.intrinsics.distortion {
                Distortion::Scaramuzza(o) => {
                    let pol = &k[3..3 + o.pol().len()];
                    Distortion::Scaramuzza(Ocam::new(pol, o.invpol(), [k[0], k[1], k[2]]).unwrap())
                }
                _ => Distortion::from_name(name, &k).unwrap(),
            };
        }
        let off = overlap_difference(&render, &wrong);
        // The panorama of the same rig: its maps, masks and overlaps (an
        // error if neighbours shared no pixel of the cylinder).
        let cylinder = CylinderSpec {
            width: 1024,
            height: 256,
            ..CylinderSpec::default()
        };
        let pano = Panorama::build(render.rig(), &cylinder, &PanoramaOptions::default()).unwrap();
        assert_eq!(pano.bands().len(), render.rig().neighbours.len(), "{name}");
        println!("{name}: overlap difference {same:.4} with the rig rendered, {off:.4} with a wrong lens");
        // The lenses here spread the overlaps over fewer pixels than the
        // reference lens (0.16–0.17 against 0.13); one parameter off by a
        // few hundredths gives 0.5 and more.
        assert!(same < 1.4 * baseline, "{name}: {same} against {baseline}");
        assert!(
            off > 2.5 * same,
            "{name}: {same} against {off} with a wrong lens"
        );
    }
}

/// A rig of four WoodScape files (one JSON a camera, ρ in pixels) gives the
/// surround view that the same rig gives from rigview's rig file, pixel for
/// pixel.
#[test]
fn a_rig_of_woodscape_files_gives_the_surround_view_of_the_same_rig_file() {
    let mut rig = reference_rig().unwrap();
    for c in &mut rig.cameras {
        c.intrinsics.fx = 1.0;
        c.intrinsics.fy = 1.0;
        c.intrinsics.distortion = Distortion::RadialPoly([330.0, -20.0, 30.0, -6.0]);
    }
    let dir = std::env::temp_dir().join(format!("rigview-woodscape-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let json = dir.join("json/");
    let written = formats::save(&rig, &json, Some(Format::WoodScape)).unwrap();
    assert_eq!(written.len(), 4);
    let yaml = dir.join("rig.yaml");
    formats::save(&rig, &yaml, Some(Format::Rig)).unwrap();
    let from_yaml = formats::load(&yaml, None, None).unwrap().rig;
    let loaded = formats::load(&json, None, None).unwrap();
    assert_eq!(loaded.format, Format::WoodScape);
    // A folder names no neighbours: the rig's, and its order.
    let cameras = rig
        .cameras
        .iter()
        .map(|c| loaded.rig.camera(&c.name).unwrap().clone())
        .collect();
    let from_json = Rig::new(rig.frame.clone(), cameras, rig.neighbours.clone()).unwrap();
    let spec = CanvasSpec {
        px_per_m: 25.0,
        ..CanvasSpec::default()
    };
    let a = SurroundView::build(&from_json, &spec, &SurroundOptions::default()).unwrap();
    let b = SurroundView::build(&from_yaml, &spec, &SurroundOptions::default()).unwrap();
    let mut composer = Composer::new();
    for (k, c) in rig.cameras.iter().enumerate() {
        let (w, h) = (c.intrinsics.width as usize, c.intrinsics.height as usize);
        // A frame whose every pixel differs from its neighbours.
        let data: Vec<u8> = (0..w * h).map(|i| (i * 7919 % 251) as u8).collect();
        let frame = FrameView::new(PixelFormat::Mono8, w, h, &data).unwrap();
        let wa = composer.warp_camera(a.mosaic(), k, &frame).unwrap();
        let wb = composer.warp_camera(b.mosaic(), k, &frame).unwrap();
        assert!(
            wa.data.iter().filter(|&&v| v > 0).count() > 10_000,
            "{}",
            c.name
        );
        let differ = wa.data.iter().zip(&wb.data).filter(|(x, y)| x != y).count();
        let most = wa
            .data
            .iter()
            .zip(&wb.data)
            .map(|(x, y)| x.abs_diff(*y))
            .max();
        println!("{}: {differ} pixels differ, by at most {most:?}", c.name);
        assert!(wa.data == wb.data, "camera {}: the views differ", c.name);
    }
    let _ = std::fs::remove_dir_all(&dir);
}
