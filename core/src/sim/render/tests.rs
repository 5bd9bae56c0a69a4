use super::super::test_render;
use super::*;
use crate::sim::Class;

fn setting(shutter_us: f64, gain_db: f64) -> ExposureSetting {
    ExposureSetting {
        shutter_us,
        gain_db,
    }
}

fn frame(
    r: &SimRender,
    cam: usize,
    frame: u64,
    s: ExposureSetting,
    f: PixelFormat,
    noise: bool,
) -> Vec<u8> {
    let info = &r.cameras()[cam];
    let req = FillRequest {
        noise,
        ..FillRequest::new(cam, frame, s, f, info.width, info.height)
    };
    let mut buf = vec![0u8; req.buffer_len()];
    r.fill(&req, &mut buf).unwrap();
    buf
}

fn values(buf: &[u8], f: PixelFormat) -> Vec<f64> {
    match f {
        PixelFormat::Mono12 | PixelFormat::Mono16 => buf
            .chunks_exact(2)
            .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
            .collect(),
        _ => buf.iter().map(|&v| f64::from(v)).collect(),
    }
}

#[test]
fn renders_are_deterministic_for_a_seed() {
    let r = test_render();
    let s = setting(400.0, 0.0);
    let a = frame(&r, 1, 5, s, PixelFormat::Mono8, true);
    assert_eq!(a, frame(&r, 1, 5, s, PixelFormat::Mono8, true));
    assert_ne!(
        a,
        frame(&r, 1, 6, s, PixelFormat::Mono8, true),
        "the noise changes from frame to frame"
    );
    let other = SimRender::new(&SimConfig {
        scale: 0.25,
        supersample: 1,
        seed: 2,
        ..SimConfig::default()
    })
    .unwrap();
    let one = SimRender::new(&SimConfig {
        scale: 0.25,
        supersample: 1,
        ..SimConfig::default()
    })
    .unwrap();
    assert_ne!(
        frame(&one, 1, 5, s, PixelFormat::Mono8, true),
        frame(&other, 1, 5, s, PixelFormat::Mono8, true)
    );
    assert_eq!(
        frame(&one, 1, 5, s, PixelFormat::Mono8, false),
        frame(&other, 1, 5, s, PixelFormat::Mono8, false),
        "the seed picks the noise only"
    );
}

#[test]
fn the_mean_is_proportional_to_the_exposure_below_saturation() {
    let r = test_render();
    for cam in 0..4 {
        // 12 bits, and low enough that nothing saturates.
        let f = PixelFormat::Mono12;
        // The pixels well above the read noise at the lowest exposure
        // (below it, clipping at 0 lifts the mean of the noisy values).
        let lowest = values(&frame(&r, cam, 3, setting(50.0, 0.0), f, false), f);
        let lit: Vec<bool> = lowest.iter().map(|&v| v > 40.0).collect();
        assert!(lit.iter().filter(|&&l| l).count() > lit.len() / 4);
        let mean = |s: ExposureSetting| {
            let v = values(&frame(&r, cam, 3, s, f, true), f);
            assert!(
                v.iter().all(|&x| x < 4000.0),
                "camera {cam} saturates at {s:?}"
            );
            let kept: Vec<f64> = v
                .iter()
                .zip(&lit)
                .filter(|(_, &l)| l)
                .map(|(&x, _)| x)
                .collect();
            kept.iter().sum::<f64>() / kept.len() as f64
        };
        let base = mean(setting(50.0, 0.0));
        for (s, k) in [
            (setting(100.0, 0.0), 2.0),
            (setting(200.0, 0.0), 4.0),
            (setting(50.0, 20.0 * 4f64.log10()), 4.0),
            (setting(25.0, 20.0 * 8f64.log10()), 4.0),
        ] {
            let ratio = mean(s) / base;
            assert!(
                (ratio / k - 1.0).abs() < 0.01,
                "camera {cam}: {s:?} gives {ratio:.4}, expected {k}"
            );
        }
    }
}

#[test]
fn noise_follows_the_emva_model_and_gain_amplifies_it() {
    let r = test_render();
    let f = PixelFormat::Mono12;
    let sensor = *r.sensor();
    for s in [setting(400.0, 0.0), setting(100.0, 12.0)] {
        let clean = values(&frame(&r, 0, 0, s, f, false), f);
        let a = values(&frame(&r, 0, 1, s, f, true), f);
        let b = values(&frame(&r, 0, 2, s, f, true), f);
        let kg = 4095.0 / sensor.full_well_e * 10f64.powf(s.gain_db / 20.0);
        let (mut measured, mut expected, mut n) = (0.0, 0.0, 0.0);
        for ((&c, &x), &y) in clean.iter().zip(&a).zip(&b) {
            if c > 100.0 && c < 3000.0 {
                // Half the variance of the difference of two frames.
                measured += 0.5 * (x - y).powi(2);
                expected += kg * c + (kg * sensor.read_noise_e).powi(2) + 1.0 / 12.0;
                n += 1.0;
            }
        }
        assert!(n > 1000.0);
        let ratio = measured / expected;
        assert!(
            (ratio - 1.0).abs() < 0.05,
            "{s:?}: measured/expected variance {ratio:.3}"
        );
    }
}

#[test]
fn pixels_saturate_at_the_top_of_8_and_12_bits() {
    let r = test_render();
    for (f, top) in [
        (PixelFormat::Mono8, 255.0),
        (PixelFormat::Mono12, 4095.0),
        (PixelFormat::Mono16, 65535.0),
    ] {
        let v = values(&frame(&r, 0, 0, setting(1e6, 0.0), f, true), f);
        let (w, h) = (r.cameras()[0].width, r.cameras()[0].height);
        let seen = (0..w * h)
            .filter(|&i| r.class(0, i % w, i / w) != Some(Class::Outside))
            .count();
        let full = v.iter().filter(|&&x| x >= top).count();
        assert!(
            full as f64 > 0.97 * seen as f64,
            "{f:?}: {full} of {seen} pixels saturated"
        );
        assert!(v.iter().all(|&x| x <= top));
    }
}

#[test]
fn fill_takes_any_size_and_refuses_what_it_cannot_fill() {
    let r = test_render();
    let s = setting(300.0, 0.0);
    // The Aravis fake camera's default 512×512, RGB8 and Bayer.
    for f in [
        PixelFormat::Mono8,
        PixelFormat::Rgb8,
        PixelFormat::BayerRg8,
        PixelFormat::Mono16,
    ] {
        let req = FillRequest::new(2, 9, s, f, 512, 512);
        let mut buf = vec![0u8; req.buffer_len()];
        let meta = r.fill(&req, &mut buf).unwrap();
        assert_eq!(
            (meta.width, meta.height, meta.format, meta.frame_id),
            (512, 512, f, 9)
        );
        assert!(buf.iter().any(|&b| b > 0));
    }
    let native = values(
        &frame(&r, 2, 9, s, PixelFormat::Mono8, false),
        PixelFormat::Mono8,
    );
    let req = FillRequest {
        noise: false,
        ..FillRequest::new(2, 9, s, PixelFormat::Mono8, 512, 512)
    };
    let mut buf = vec![0u8; req.buffer_len()];
    r.fill(&req, &mut buf).unwrap();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let resampled = values(&buf, PixelFormat::Mono8);
    assert!((mean(&resampled) / mean(&native) - 1.0).abs() < 0.05);
    let mut short = vec![0u8; req.buffer_len() - 1];
    assert!(matches!(
        r.fill(&req, &mut short),
        Err(Error::BufferSize { .. })
    ));
    let bad = FillRequest { camera: 4, ..req };
    assert!(matches!(
        r.fill(&bad, &mut buf),
        Err(Error::CameraIndex { index: 4, count: 4 })
    ));
    let nan = FillRequest {
        setting: setting(f64::NAN, 0.0),
        ..req
    };
    assert!(r.fill(&nan, &mut buf).is_err());
    let empty = FillRequest { width: 0, ..req };
    assert!(r.fill(&empty, &mut buf).is_err());
}

#[test]
fn a_shared_render_fills_the_same_bytes_from_any_thread() {
    fn shareable<T: Send + Sync>(_: &T) {}
    let r = test_render();
    shareable(&r);
    let s = setting(300.0, 3.0);
    let here = frame(&r, 3, 11, s, PixelFormat::Mono8, true);
    let there = std::thread::spawn({
        let r = std::sync::Arc::clone(&r);
        move || frame(&r, 3, 11, s, PixelFormat::Mono8, true)
    })
    .join()
    .unwrap();
    assert_eq!(here, there);
}

#[test]
fn vignetting_darkens_the_edges_only() {
    let plain = SimRender::new(&SimConfig {
        scale: 0.125,
        supersample: 1,
        ..SimConfig::default()
    })
    .unwrap();
    let mut config = SimConfig {
        scale: 0.125,
        supersample: 1,
        ..SimConfig::default()
    };
    config.sensor.vignetting = 0.4;
    let vign = SimRender::new(&config).unwrap();
    let (a, b) = (
        plain.irradiance(0, 0.0).unwrap(),
        vign.irradiance(0, 0.0).unwrap(),
    );
    let w = plain.cameras()[0].width;
    let (cx, cy) = (w / 2, plain.cameras()[0].height / 2);
    let centre = cy * w + cx;
    assert!((b[centre] / a[centre] - 1.0).abs() < 0.01);
    let edge = cy * w + 2;
    assert!(
        a[edge] > 0.0 && b[edge] / a[edge] < 0.7,
        "{} → {}",
        a[edge],
        b[edge]
    );
}

#[test]
fn a_camera_inside_the_vehicle_is_refused() {
    let mut rig = reference_rig().unwrap();
    let k = rig.cameras[0].intrinsics;
    rig.cameras[0].pose = Some(
        rigview_calib::Pose::from_ypr_deg([0.0, 20.0, 0.0], Vector3::new(0.0, 0.0, 1.0)).unwrap(),
    );
    rig.cameras[0].intrinsics = k;
    let err = SimRender::with_rig(
        &SimConfig {
            scale: 0.125,
            ..SimConfig::default()
        },
        rig,
    )
    .unwrap_err();
    assert!(err.to_string().contains("\"front\""), "{err}");
}

#[test]
fn the_ray_table_agrees_with_the_camera_model() {
    let k = super::super::rig::reference_intrinsics();
    let t = RayTable::new(&k, 95f64.to_radians()).unwrap();
    let mut worst = 0f64;
    for j in 0..97 {
        for i in 0..129 {
            let (u, v) = (f64::from(i) * 10.03, f64::from(j) * 10.01);
            let exact = k.unproject(&Point2::new(u, v));
            match (exact, t.ray(u, v)) {
                (Some(e), Some(r)) => worst = worst.max((e.into_inner() - r).norm()),
                (Some(e), None) => assert!(e.z.acos() > 94.9f64.to_radians()),
                (None, Some(_)) => panic!("({u}, {v}): a ray where the model has none"),
                (None, None) => {}
            }
        }
    }
    assert!(worst < 1e-8, "largest difference {worst}");
}
