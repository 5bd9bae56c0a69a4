#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The simulated scene and its illumination, seen through the rig and the
//! surround view: the dynamic range of one scene, the sun in one camera
//! only, overlaps that line up (and do not once a camera is turned),
//! scripted light in the frames, and the exposure loop through a tunnel.
//! Run with `--nocapture` for the figures.

use std::sync::Arc;

use nalgebra::{Rotation3, Vector3};
use rigview_calib::Pose;
use rigview_core::exposure::{ControllerConfig, ExposureSetting, LawKind, LawParams, PixelFormat};
use rigview_core::pipeline::ProcessingSettings;
use rigview_core::sim::{truth, FillRequest, SimConfig, SimRender};
use rigview_core::surround::{CanvasSpec, SurroundOptions, SurroundView};

fn render(preset: &str, scale: f64) -> SimRender {
    let config = SimConfig {
        scale,
        ..SimConfig::preset(preset).unwrap()
    };
    SimRender::new(&config).unwrap()
}

fn view(rig: &rigview_calib::Rig) -> SurroundView {
    let spec = CanvasSpec {
        px_per_m: 25.0,
        ..CanvasSpec::default()
    };
    SurroundView::build(rig, &spec, &SurroundOptions::default()).unwrap()
}

#[test]
fn one_scene_spans_more_than_four_decades_and_only_the_front_camera_faces_the_low_sun() {
    let r = render("reference", 0.5);
    let dr = truth::dynamic_range(&r, 0.0).unwrap();
    println!(
        "reference: irradiance 0.01–99.99 % quantiles {:.2e} … {:.2e}: {:.0}:1 ({:.1} decades; the sensor: {:.1} dB = {:.0}:1)",
        dr.low,
        dr.high,
        dr.ratio(),
        dr.ratio().log10(),
        r.sensor().dynamic_range_db(),
        10f64.powf(r.sensor().dynamic_range_db() / 20.0)
    );
    assert!(dr.ratio() >= 1e4, "{dr:?}");
    let b = render("backlight", 0.25);
    let brightest: Vec<f32> = (0..4)
        .map(|c| {
            b.irradiance(c, 0.0)
                .unwrap()
                .into_iter()
                .fold(0.0, f32::max)
        })
        .collect();
    println!("backlight: brightest irradiance per camera {brightest:?}");
    // The sun's disc (50 000 × the sunlit white) in the front camera; the
    // others see nothing brighter than the glow of the sky.
    assert!(brightest[0] > 1e4);
    assert!(brightest[1..].iter().all(|&v| v < 10.0));
    assert!(truth::dynamic_range(&b, 0.0).unwrap().ratio() > 5e4);
}

#[test]
fn the_overlaps_line_up_and_a_turned_camera_does_not() {
    let r = render("reference", 0.5);
    let truths = truth::overlap_ratios(&r, &view(r.rig()), 0.0).unwrap();
    for t in &truths {
        let (ratio, spread) = (t.ratio.unwrap(), t.spread.unwrap());
        println!(
            "{}–{}: {} patches, true ratio {ratio:.3}, patch spread {spread:.3} EV",
            t.i, t.j, t.patches
        );
        // Lambertian ground, no vignetting: both cameras see the same
        // radiance in every patch.
        assert!(t.patches >= 20);
        assert!(ratio.log2().abs() < 0.02, "{t:?}");
        assert!(spread < 0.05, "{t:?}");
    }
    // The same frames through a calibration with the left camera turned by
    // 5°: its patches see other ground.
    let mut turned = r.rig().clone();
    let pose = turned.cameras[1].pose.unwrap();
    let yaw = Rotation3::from_axis_angle(&Vector3::z_axis(), 5f64.to_radians());
    turned.cameras[1].pose =
        Some(Pose::new(yaw.matrix() * pose.rotation_matrix(), *pose.translation()).unwrap());
    let broken = truth::overlap_ratios(&r, &view(&turned), 0.0).unwrap();
    for t in broken.iter().filter(|t| t.i == 1 || t.j == 1) {
        println!(
            "turned left camera, {}–{}: patch spread {:.3} EV",
            t.i,
            t.j,
            t.spread.unwrap()
        );
        assert!(t.spread.unwrap() > 0.1, "{t:?}");
    }
}

fn mean_at(r: &SimRender, camera: usize, frame: u64, setting: ExposureSetting) -> f64 {
    let info = &r.cameras()[camera];
    let req = FillRequest {
        noise: false,
        ..FillRequest::new(
            camera,
            frame,
            setting,
            PixelFormat::Mono12,
            info.width,
            info.height,
        )
    };
    let mut buf = vec![0u8; req.buffer_len()];
    r.fill(&req, &mut buf).unwrap();
    let v: Vec<f64> = buf
        .chunks_exact(2)
        .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
        .collect();
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn the_frames_follow_the_scripted_light() {
    // Dim enough that nothing saturates at the brightest step, bright
    // enough that rounding does not bias the darkest.
    let s = ExposureSetting {
        shutter_us: 40.0,
        gain_db: 0.0,
    };
    let steps = render("steps", 0.125);
    let at = |t: f64| mean_at(&steps, 2, (t * 20.0).round() as u64, s);
    let base = at(0.5);
    // +2 stops at 1 s, back at 3 s, −4 at 5 s, back at 7 s.
    for (t, k) in [(2.0, 4.0), (4.0, 1.0), (6.0, 1.0 / 16.0), (8.0, 1.0)] {
        let ratio = at(t) / base;
        assert!(
            (ratio / k - 1.0).abs() < 0.02,
            "t = {t} s: ×{ratio:.4}, expected ×{k}"
        );
    }
    let tunnel = render("tunnel", 0.125);
    let bright = ExposureSetting {
        shutter_us: 1000.0,
        gain_db: 0.0,
    };
    let at = |t: f64, s| mean_at(&tunnel, 2, (t * 20.0).round() as u64, s);
    // 25× the exposure inside: a quarter of the light of outside.
    let inside = at(3.5, bright) / at(0.5, s) / 25.0;
    assert!(
        (inside - 0.01).abs() < 0.0005,
        "inside the tunnel: ×{inside:.4}"
    );
    assert!((at(7.5, s) / at(0.5, s) - 1.0).abs() < 0.01);
}

#[test]
fn the_loop_follows_the_light_through_the_tunnel() {
    let render = Arc::new(render("tunnel", 0.25));
    let n = render.cameras().len();
    let settings = ProcessingSettings {
        controller: ControllerConfig {
            law: LawParams {
                kind: LawKind::Fast,
                ..Default::default()
            },
            ..Default::default()
        },
        ..Default::default()
    };
    let surround = view(render.rig());
    let mut lp =
        rigview_tests::sim_loop(&render, surround, settings, &render.rig().neighbours).unwrap();
    // Enter at 1.5 s, exit at 5.5 s (0.4 s transitions), 100× darker.
    let (mut before, mut inside, mut after) = (Vec::new(), Vec::new(), Vec::new());
    let mut gain_used = false;
    for f in 0..160u64 {
        let step = lp.step().unwrap().unwrap();
        let t = f as f64 / 20.0;
        let cams = step
            .output
            .expect("the simulated rig gives complete sets")
            .cameras;
        let e: f64 = cams.iter().map(|c| c.taken.exposure().log2()).sum::<f64>() / n as f64;
        let mean: f64 = cams.iter().map(|c| f64::from(c.mean)).sum::<f64>() / n as f64;
        gain_used |= cams.iter().any(|c| c.taken.gain_db > 1.0);
        if (1.0..1.5).contains(&t) {
            before.push((e, mean));
        } else if (5.0..5.5).contains(&t) {
            inside.push((e, mean));
        } else if t >= 7.5 {
            after.push((e, mean));
        }
    }
    let avg = |v: &[(f64, f64)]| {
        let k = v.len() as f64;
        (
            v.iter().map(|x| x.0).sum::<f64>() / k,
            v.iter().map(|x| x.1).sum::<f64>() / k,
        )
    };
    let ((e0, m0), (e1, m1), (e2, m2)) = (avg(&before), avg(&inside), avg(&after));
    println!(
        "tunnel: mean log2 E {e0:.2} before, {e1:.2} inside (+{:.2} EV for a 6.64 EV darkening), {e2:.2} after; mean intensity {m0:.3}, {m1:.3}, {m2:.3}",
        e1 - e0
    );
    assert!(gain_used, "100× darker needs gain beyond the 49 ms shutter");
    assert!(
        (e1 - e0 - 100f64.log2()).abs() < 0.7,
        "inside: +{:.2} EV",
        e1 - e0
    );
    assert!((m1 / m0 - 1.0).abs() < 0.25 && (m2 / m0 - 1.0).abs() < 0.25);
    assert!((e2 - e0).abs() < 0.5);
}
