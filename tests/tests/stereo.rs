#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The stereo measure of `rigview eval` on the simulated forward stereo
//! pair (`assets/sim/lawn-stereo.sim.yaml`: the lawn seen by two of the
//! reference fisheyes 0.5 m apart): the pair is found and rectified
//! through its lens model, `StereoSGBM`'s disparities agree with the
//! scene's geometry (and few fall in the textureless sky), and their
//! density is highest where the exposure keeps the lawn's texture, falling
//! off as the frames sink into the noise or clip.

use std::path::PathBuf;

use rigview_calib::tools::stereo::{stereo_pairs, StereoRectifier};
use rigview_core::exposure::ExposureSetting;
use rigview_core::image::{FrameView, PixelFormat};
use rigview_core::sim::{FillRequest, SimConfig, SimRender};

fn render() -> SimRender {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/sim/lawn-stereo.sim.yaml");
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::load(&path).unwrap()
    };
    SimRender::new(&config).unwrap()
}

/// Camera `cam`'s noisy Mono8 frame at `shutter_us`, as grey bytes.
fn frame(render: &SimRender, cam: usize, shutter_us: f64) -> Vec<u8> {
    let info = &render.cameras()[cam];
    let req = FillRequest::new(
        cam,
        3,
        ExposureSetting {
            shutter_us,
            gain_db: 0.0,
        },
        PixelFormat::Mono8,
        info.width,
        info.height,
    );
    let mut buf = vec![0u8; req.buffer_len()];
    render.fill(&req, &mut buf).unwrap();
    // (Mono8 bytes are the grey image the measure reads.)
    FrameView::new(PixelFormat::Mono8, info.width, info.height, &buf).unwrap();
    buf
}

#[test]
fn the_forward_pair_matches_the_scene_and_its_density_peaks_at_a_good_exposure() {
    let render = render();
    let rig = render.rig();
    assert_eq!(stereo_pairs(rig), vec![(0, 1)], "left, right");
    let s = StereoRectifier::new(rig, 0, 1).unwrap();
    assert!((s.baseline_m - 0.5).abs() < 1e-9);

    // Density against exposure, 1 EV apart.
    let shutters: Vec<f64> = (6..=16).map(|k| f64::from(1u32 << k)).collect();
    let densities: Vec<f64> = shutters
        .iter()
        .map(|&e| {
            s.disparities(&frame(&render, 0, e), &frame(&render, 1, e))
                .unwrap()
                .density()
        })
        .collect();
    for (e, d) in shutters.iter().zip(&densities) {
        println!("{e:>6} µs: density {d:.3}");
    }
    let (best, &peak) = densities
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    assert!(peak > 0.15, "peak density {peak}");
    assert!(
        best > 0 && best + 1 < densities.len(),
        "the peak at {} µs is at an end of the range",
        shutters[best]
    );
    // At the ends of the range the lawn is buried in noise or clipped.
    // (Four stops above the peak the sunlit lawn clips but the tree shade
    // is well exposed: the density holds up there.)
    for (e, d) in [(shutters[0], densities[0]), (shutters[10], densities[10])] {
        assert!(d < 0.25 * peak, "{e} µs: density {d} of {peak}");
    }

    // At the peak, the disparities are the scene's: each valid pixel's
    // ray meets the scene at a point whose true disparity is f·b/depth.
    let got = s
        .disparities(
            &frame(&render, 0, shutters[best]),
            &frame(&render, 1, shutters[best]),
        )
        .unwrap();
    // (Errors where the truth is beyond the search range, or within a
    // pixel of zero, the far lawn on the horizon, are not the matcher's to
    // get right: the near ground is where the texture is.)
    let mut errors = Vec::new();
    let mut in_the_sky = 0;
    for (k, d) in got.values.iter().enumerate() {
        if !d.is_finite() {
            continue;
        }
        let (o, ray) = s.ray((k % s.width) as f64, (k / s.width) as f64);
        let Some(p) = render.scene_point(&o, &ray) else {
            in_the_sky += 1;
            continue;
        };
        let (.., truth) = s.rectified(&p).unwrap();
        if (8.0..s.max_disparity as f64).contains(&truth) {
            errors.push((f64::from(*d) - truth).abs());
        }
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let p75 = errors[errors.len() * 3 / 4];
    println!(
        "at {} µs: {} of {} disparities on the near ground, median |error| {median:.3} px, 75th percentile {p75:.3} px",
        shutters[best],
        errors.len(),
        got.valid
    );
    // The sky has no texture but the sensor's noise: a disparity there is
    // a false match (the texture check keeps them few).
    println!("{in_the_sky} disparities in the sky");
    assert!(
        in_the_sky * 20 < got.valid,
        "{in_the_sky} of {} disparities in the sky",
        got.valid
    );
    assert!(errors.len() > got.valid / 2);
    assert!(median < 1.0, "median |error| {median} px");
    assert!(p75 < 2.0, "75th percentile |error| {p75} px");
}
