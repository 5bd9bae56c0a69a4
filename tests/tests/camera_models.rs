//! Every camera model through the simulated rig, the surround view and the
//! panorama: a
//! rig whose cameras use the double-sphere, the extended unified or the
//! unified (Mei) model renders, and the surround view built from the same
//! rig lines neighbouring cameras up in their overlaps; a view built with
//! one model parameter wrong does not.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod surround_common;

use nalgebra::{Point2, Vector3};
use rigview_calib::formats::{self, Format};
use rigview_calib::model::ocam::Ocam;
use rigview_calib::{report, Distortion, Rig};
use rigview_core::image::{FrameView, PixelFormat};
use rigview_core::panorama::{CylinderSpec, MatchOptions, Panorama, PanoramaOptions};
use rigview_core::sim::{reference_rig, SimConfig, SimRender};
use rigview_core::source::Frame;
use rigview_core::surround::{CanvasSpec, Composer, SurroundOptions, SurroundView};
use rigview_tests::rigs::{off, refine_by_default, turn_camera};

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

/// Lenses of about the reference camera's field of view, one of each new
/// model: the lens, its focal length (pixels of the full-size image), and
/// a coefficient (its index) and an error that make it wrong.
fn lenses() -> [(Distortion, f64, usize, f64); 5] {
    [
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
    ]
}

#[test]
fn every_sphere_model_renders_and_its_surround_view_lines_neighbours_up() {
    let cases = lenses();
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
        // The metering masks (each camera's ground pixels): every masked
        // pixel's ray meets the ground in the canvas, through this model.
        let spec = CanvasSpec::default();
        let view = SurroundView::build(render.rig(), &spec, &SurroundOptions::default()).unwrap();
        for (mask, camera) in view.ground_masks().iter().zip(&render.rig().cameras) {
            let projector = camera.projector().unwrap();
            let (mut on, mut off_ground) = (0usize, 0usize);
            let step = f64::from(camera.intrinsics.width) / mask.width() as f64;
            for y in (0..mask.height()).step_by(5) {
                for (x, _) in mask
                    .row(y)
                    .iter()
                    .enumerate()
                    .filter(|m| *m.1 > 0)
                    .step_by(5)
                {
                    let px = nalgebra::Point2::new(x as f64 * step, y as f64 * step);
                    match projector.ground_point(&px) {
                        Some(g)
                            if (spec.x_min_m - 1.0..=spec.x_max_m + 1.0).contains(&g.x)
                                && (spec.y_min_m - 1.0..=spec.y_max_m + 1.0).contains(&g.y) =>
                        {
                            on += 1;
                        }
                        _ => off_ground += 1,
                    }
                }
            }
            let coverage = mask.coverage();
            assert!(
                coverage > 0.1 && off_ground * 200 <= on,
                "{name} {}: mask covers {coverage:.2}, {on} pixels on the ground, {off_ground} not",
                camera.name
            );
        }
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

/// The panorama's matching and refinement on every model, as on the
/// reference rig's fisheye lens: on the frames of a rig of each new model,
/// Harris corners and BRIEF descriptors on the matching cylinder (with its
/// floor) find inliers in every overlap of the true rig, and the product's
/// refinement in rounds brings the cameras back from turns of 1.5° about
/// three different axes.
#[test]
fn every_models_panorama_matches_and_refines() {
    use rigview_core::panorama::matching_spec;
    let config = SimConfig {
        scale: 1.0,
        ..SimConfig::preset("overcast").unwrap()
    };
    let spec = matching_spec(&CylinderSpec::default());
    let turns = [
        Vector3::new(0.3, -0.5, 1.0),
        Vector3::new(1.0, 0.2, -0.3),
        Vector3::new(-0.4, 1.0, 0.5),
    ];
    let fisheye = reference_rig().unwrap().cameras[0].intrinsics;
    let lenses =
        std::iter::once((fisheye.distortion, fisheye.fx)).chain(lenses().map(|l| (l.0, l.1)));
    for (distortion, f) in lenses {
        let name = distortion.model_name();
        let render = SimRender::with_rig(&config, rig_with(distortion, f)).unwrap();
        let truth = render.rig().clone();
        let buffers: Vec<Vec<u8>> = (0..4)
            .map(|k| surround_common::still(&render, k, 4000.0))
            .collect();
        let frames = surround_common::still_views(&render, &buffers);
        let pano = Panorama::build(&truth, &spec, &PanoramaOptions::default()).unwrap();
        let (pairs, _) = pano
            .match_pairs(
                &frames,
                &rigview_tests::harris_subpixel,
                &MatchOptions::default(),
            )
            .unwrap();
        for p in &pairs {
            println!(
                "{name} {}–{}: corners {:?}, {} matches, {} inliers, rotation {:.3}°{}",
                p.i,
                p.j,
                p.corners,
                p.matches.len(),
                p.inliers,
                p.rotation.map_or(f64::NAN, |q| q.angle().to_degrees()),
                p.problem
                    .as_deref()
                    .map(|s| format!(" ({s})"))
                    .unwrap_or_default()
            );
            assert!(
                p.inliers >= 10,
                "{name} {}–{}: {} inliers",
                p.i,
                p.j,
                p.inliers
            );
            let angle = p.rotation.unwrap().angle().to_degrees();
            assert!(angle < 0.15, "{name} {}–{}: {angle}°", p.i, p.j);
        }
        let mut turned = truth.clone();
        for (k, axis) in (1..4).zip(turns) {
            turn_camera(&mut turned, k, &axis, 1.5);
        }
        let rounds = refine_by_default(&turned, &frames).unwrap();
        for k in 1..4 {
            let left = off(&rounds.rig, &truth, k);
            println!("{name} camera {k}: turned 1.5°, {left:.3}° after the refinement");
            assert!(left < 0.2, "{name} camera {k}: {left}° from the truth");
        }
    }
}

/// `rig` with every camera's focal length times `s` (for Scaramuzza's
/// model, whose focal length is in `pol`, there: pol_i · s^(1−i)).
fn focal_times(rig: &Rig, s: f64) -> Rig {
    let mut out = rig.clone();
    for c in &mut out.cameras {
        let k = &mut c.intrinsics;
        if let Distortion::Scaramuzza(o) = k.distortion {
            let pol: Vec<f64> = (0..o.pol().len())
                .map(|i| o.pol()[i] * s.powi(1 - i as i32))
                .collect();
            k.distortion = Distortion::Scaramuzza(Ocam::new(&pol, &[], o.affine()).unwrap());
        } else {
            k.fx *= s;
            k.fy *= s;
        }
    }
    out
}

/// `rigview calib show` on every model: the model and its coefficients by
/// name, the field of view across the image as the model projects it, the
/// ground each camera sees, and no warnings for a lens whose image corners
/// lie within the model; the same lens with a third of the focal length is
/// warned of.
#[test]
fn calib_show_checks_every_model() {
    for (distortion, f, _, _) in lenses() {
        let name = distortion.model_name();
        // The focal length at which the image corners are at 0.9 of the
        // model's largest angle (by bisection on the scale of `f`).
        let corner_angle = |s: f64| {
            let k = focal_times(&rig_with(distortion, f), s).cameras[0].intrinsics;
            k.unproject(&Point2::new(0.0, 0.0))
                .map_or(f64::INFINITY, |r| r.z.acos() / k.max_incidence())
        };
        let (mut lo, mut hi) = (0.05, 20.0);
        for _ in 0..60 {
            let mid = f64::sqrt(lo * hi);
            if corner_angle(mid) > 0.9 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let rig = focal_times(&rig_with(distortion, f), hi);
        let shown = report::summary(&formats::Loaded {
            rig: rig.clone(),
            format: Format::Rig,
            surround: None,
        });
        let k = rig.cameras[0].intrinsics;
        // The horizontal field of view found independently: the angles
        // whose projections reach the image's left and right edges
        // (bisection on `project`; the summary unprojects the edges).
        let reach = |edge: f64| {
            let dir = if edge < k.cx { -1.0 } else { 1.0 };
            let (mut lo, mut hi) = (0.0f64, k.max_incidence() * (1.0 - 1e-9));
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                let (s, c) = mid.sin_cos();
                let reached = k
                    .project(&Vector3::new(dir * s, 0.0, c))
                    .is_some_and(|q| (q.x - k.cx).abs() < (edge - k.cx).abs());
                if reached {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo.to_degrees()
        };
        let horizontal = reach(0.0) + reach(f64::from(k.width) - 1.0);
        println!("{name}: focal length × {hi:.3}, horizontal {horizontal:.1}°");
        assert!(
            shown.contains(&format!("model: {name} ")),
            "{name}: {shown}"
        );
        for coefficient in k.distortion.coefficient_names() {
            assert!(
                shown.contains(&format!("{coefficient} ")),
                "{name}: {coefficient}"
            );
        }
        assert!(
            shown.contains(&format!("field of view: horizontal {horizontal:.1}°")),
            "{name}: {horizontal:.1}° expected in {shown}"
        );
        assert_eq!(
            shown.matches("sees ground from").count(),
            4,
            "{name}: {shown}"
        );
        assert!(shown.ends_with("\n0 warning(s)\n"), "{name}: {shown}");
        // A third of the focal length: the corners lie beyond the model,
        // and every camera says so; except where the model maps the whole
        // image into its field: a unified camera whose distortion never
        // folds (k1 −0.05, k2 0.004: its rays near the cone's edge lie
        // arbitrarily far out), and Scaramuzza's, whose angle atan2(ρ,
        // −pol(ρ)) rises to 180° as ρ grows (pol[2] > 0), taken up to the
        // image's diagonal.
        let covers_any_image =
            matches!(distortion, Distortion::Omni(_) | Distortion::Scaramuzza(_));
        let shown = report::summary(&formats::Loaded {
            rig: focal_times(&rig, 1.0 / 3.0),
            format: Format::Rig,
            surround: None,
        });
        assert_eq!(
            shown
                .matches("the image corners lie beyond where the lens model is valid")
                .count(),
            if covers_any_image { 0 } else { 4 },
            "{name}: {shown}"
        );
    }
}
