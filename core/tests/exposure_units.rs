//! Each part of the exposure core against values derived by hand, plus bad
//! input. The closed-loop behaviour is in the workspace's `tests/` crate.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::float_cmp
)]

use rigview_core::exposure::balance::{self, NeighbourGraph, PatchPair};
use rigview_core::exposure::baselines::{MeanIntensityParams, PidParams, PidState};
use rigview_core::exposure::estimator::{fit, fit_in, AnchorScore, Bound, FitVariable, Polynomial};
use rigview_core::exposure::laws::{linear_ratio, nonlinear_r, nonlinear_ratio};
use rigview_core::exposure::metering::SATURATED_LEVEL;
use rigview_core::exposure::split::{Clamped, ExposureRange, SplitParams, Splitter};
use rigview_core::exposure::*;
use rigview_core::synth::{HdrScene, Illumination, LinearCamera};
use rigview_core::Error;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

// ---------- Eq. 1 ----------

#[test]
fn metric_of_a_step_edge_matches_eq1_by_hand() {
    // 3×3: columns 0 and 1 black, column 2 at c. The centre pixel has
    // gx = 4c, gy = 0, so m = 4c / (4√2) = c/√2.
    let metric = GradientMetric::new(MetricParams::default()).unwrap();
    let mut scratch = Default::default();
    for c in [1.0f32, 0.5, 0.2] {
        let img = [0.0, 0.0, c, 0.0, 0.0, c, 0.0, 0.0, c];
        let m = f64::from(c) / 2f64.sqrt();
        let expected = (1000.0 * (m - 0.06) + 1.0).ln() / (1000.0 * 0.94 + 1.0f64).ln();
        let got = metric.score(&img, 3, 3, None, &mut scratch);
        assert!(close(got, expected, 1e-5), "c={c}: {got} vs {expected}");
        assert!(close(metric.information(m), expected, 1e-12));
    }
    // Below δ: m = 0.05/√2 ≈ 0.035 < 0.06 gives nothing.
    let img = [0.0, 0.0, 0.05, 0.0, 0.0, 0.05, 0.0, 0.0, 0.05];
    assert_eq!(metric.score(&img, 3, 3, None, &mut scratch), 0.0);
    assert!(close(metric.information(1.0), 1.0, 1e-12));
    assert_eq!(metric.information(0.059), 0.0);
}

#[test]
fn metric_weights_and_lambda_behave() {
    let mut scratch = Default::default();
    // A 5×5 ramp: every interior pixel has the same gradient.
    let img: Vec<f32> = (0..25).map(|i| (i % 5) as f32 * 0.1).collect();
    let metric = GradientMetric::new(MetricParams::default()).unwrap();
    let full = metric.score(&img, 5, 5, None, &mut scratch);
    let mut w = vec![0.0f32; 25];
    w[12] = 1.0; // only the centre pixel
    let one = metric.score(&img, 5, 5, Some(&w), &mut scratch);
    assert!(close(full, 9.0 * one, 1e-5), "{full} vs 9×{one}");
    // Small λ favours strong edges: weak gradients count relatively less.
    let small = GradientMetric::new(MetricParams {
        delta: 0.06,
        lambda: 10.0,
    })
    .unwrap();
    let weak = 0.1 / (4.0 * 2f64.sqrt()) * 4.0;
    assert!(small.information(weak) < metric.information(weak));
}

// ---------- Eq. 2 ----------

#[test]
fn polynomial_fit_recovers_a_known_maximum_and_checks_the_ends() {
    let anchors = |f: &dyn Fn(f64) -> f64| -> Vec<AnchorScore> {
        DEFAULT_ANCHORS
            .iter()
            .map(|&x| AnchorScore { x, m: f(x) })
            .collect()
    };
    // An interior maximum at 1.3.
    let p = fit(&anchors(&|x| 5.0 - (x - 1.3).powi(2)), 5).unwrap();
    assert!((p.argmax() - 1.3).abs() < 1e-9, "{}", p.argmax());
    // Increasing everywhere: the upper end.
    let p = fit(&anchors(&|x| x), 5).unwrap();
    assert!((p.argmax() - 1.9).abs() < 1e-12);
    // Decreasing: the lower end.
    let p = fit(&anchors(&|x| -x), 5).unwrap();
    assert!((p.argmax() - 1.0 / 1.9).abs() < 1e-12);
    // Two interior maxima; the higher one (near 1.6) wins.
    let f = |x: f64| -(x - 0.7).powi(2) * (x - 1.6).powi(2) + 0.05 * x;
    let p = fit(&anchors(&f), 5).unwrap();
    let x = p.argmax();
    assert!((x - 1.6).abs() < 0.05, "{x}");
    assert!(p.eval(x) >= p.eval(0.7));
    // The curve for plots spans the anchors.
    let c = p.sample(64);
    assert_eq!(c.len(), 64);
    assert!((c[0][0] - 1.0 / 1.9).abs() < 1e-12 && (c[63][0] - 1.9).abs() < 1e-12);
}

/// Two humps of nearly equal height: the plain maximiser jumps from one to
/// the other as their heights cross; `argmax_within` moves between them
/// continuously, near or far apart, and is the plain maximiser with one
/// clearly higher.
#[test]
fn maxima_of_nearly_equal_height_are_blended_continuously() {
    // Humps at ln x = ±c, the right one higher by about `h`.
    let curve = |c: f64, h: f64| -> Polynomial {
        let anchors: Vec<AnchorScore> = (0..15)
            .map(|k| {
                let u = -1.6 * c + 0.2286 * c * f64::from(k);
                let m = 10.0 - (u * u - c * c).powi(2) * 100.0 / (c * c * 6.25) + h * u / (2.0 * c);
                AnchorScore { x: u.exp(), m }
            })
            .collect();
        fit_in(&anchors, 4, FitVariable::Log).unwrap()
    };
    let spread = 10.0;
    let tol = 0.02 * spread;
    // A plateau the fit wiggles over (0.8 apart in ln x) and two distinct
    // optima with a valley between them (1.2 apart: more than four of the
    // default anchors' spacings).
    for c in [0.4, 0.6] {
        let mut last: Option<f64> = None;
        let mut largest_jump: f64 = 0.0;
        for k in -40..=40 {
            let h = 0.01 * f64::from(k);
            let x = curve(c, h).argmax_within(tol).ln();
            if let Some(l) = last {
                largest_jump = largest_jump.max((x - l).abs());
            }
            last = Some(x);
        }
        assert!(
            largest_jump < 0.1 * c / 0.4,
            "humps ±{c}: blended maximiser jumped {largest_jump}"
        );
        // The plain one jumps from one hump to the other.
        let (a, b) = (curve(c, -0.05).argmax().ln(), curve(c, 0.05).argmax().ln());
        assert!(a < -0.7 * c && b > 0.7 * c, "humps ±{c}: {a} {b}");
        // Equal humps: midway.
        let mid = curve(c, 0.0).argmax_within(tol).ln();
        assert!(mid.abs() < 0.05, "humps ±{c}: {mid}");
        // One hump clearly higher: the plain maximiser.
        for h in [-0.4, 0.4] {
            let p = curve(c, h);
            assert!(
                (p.argmax_within(tol) - p.argmax()).abs() < 1e-12,
                "humps ±{c}, h = {h}"
            );
        }
    }
    let p = curve(0.4, 0.05);
    assert_eq!(p.argmax_within(0.0), p.argmax());
}

/// The anchors of a real frame (the surround-nz front camera's ground,
/// emulated at 3350 µs from its 2 ms frame, 26 % saturated, under
/// scale-and-clip): two humps, the sampled one at s = 1.2 the highest. The
/// 5th-order fit puts a hump between the two darkest anchors, 300 above
/// both, and its plain maximiser (and the blended one) goes there; the
/// supported maximiser stays at the hump the anchors show, and is the
/// blended one where a maximum is as high as its anchors. Only the end
/// intervals are capped: a true peak between two interior anchors stays
/// the fit's.
#[test]
fn a_hump_the_anchors_do_not_show_does_not_win() {
    let m = [13747.4, 13170.3, 12527.2, 13293.7, 14056.0, 12364.3, 8733.5];
    let anchors: Vec<AnchorScore> = DEFAULT_ANCHORS
        .iter()
        .zip(m)
        .map(|(&x, m)| AnchorScore { x, m })
        .collect();
    let p = fit_in(&anchors, 5, FitVariable::Log).unwrap();
    let tol = 0.02 * (14056.0 - 8733.5);
    // The fit's hump between the two darkest anchors: above both by more
    // than the band, and above the bright hump's fit.
    assert!(p.eval(0.56) > 13747.4 + tol, "the fit's overshoot");
    assert!(p.eval(0.56) > p.eval(1.2));
    let plain = p.argmax_within(tol);
    assert!(plain < 0.7, "the fit alone goes darker: {plain}");
    let supported = p.argmax_supported(&anchors, tol);
    assert!(
        (1.1..1.3).contains(&supported),
        "the anchors' hump: {supported}"
    );
    // With the darkest anchor clearly the highest, darker wins again.
    let mut darker = anchors.clone();
    darker[0].m = 14600.0;
    let p = fit_in(&darker, 5, FitVariable::Log).unwrap();
    assert!(p.argmax_supported(&darker, tol) < 0.7);
    // A hump between two interior anchors higher than both (and than the
    // darkest anchor, which is higher than both of them) is the fit's to
    // find: only the end intervals are capped. (A quartic in the
    // normalised ln x, which the 5th-order fit reproduces.)
    let half = 0.5 * (DEFAULT_ANCHORS[6].ln() - DEFAULT_ANCHORS[0].ln());
    let centre = 0.5 * (DEFAULT_ANCHORS[6].ln() + DEFAULT_ANCHORS[0].ln());
    let g =
        |t: f64| 10.0 - 6.0 * (t - 0.14).powi(2) * (t + 1.0).powi(2) - 0.05 * (t - 0.14).powi(2);
    let interior: Vec<AnchorScore> = DEFAULT_ANCHORS
        .iter()
        .map(|&x| AnchorScore {
            x,
            m: g((x.ln() - centre) / half),
        })
        .collect();
    assert!(interior[0].m > interior[3].m.max(interior[4].m));
    let p = fit_in(&interior, 5, FitVariable::Log).unwrap();
    let peak = (centre + 0.14 * half).exp();
    let x = p.argmax_supported(&interior, 0.0);
    assert!((x - peak).abs() < 1e-3, "{x} against the peak at {peak}");
    assert_eq!(x, p.argmax_within(0.0));
    // A single hump: the same as the plain maximiser.
    let one: Vec<AnchorScore> = DEFAULT_ANCHORS
        .iter()
        .map(|&x| AnchorScore {
            x,
            m: 5.0 - (x.ln() - 0.2).powi(2),
        })
        .collect();
    let p = fit_in(&one, 5, FitVariable::Log).unwrap();
    assert_eq!(p.argmax_supported(&one, 0.02), p.argmax_within(0.02));
}

#[test]
fn the_log_fit_recovers_a_maximum_in_ln_x_and_reports_anchor_values() {
    let anchors: Vec<AnchorScore> = DEFAULT_ANCHORS
        .iter()
        .map(|&x| AnchorScore {
            x,
            m: 5.0 - (x.ln() - 0.2).powi(2),
        })
        .collect();
    let p = fit_in(&anchors, 5, FitVariable::Log).unwrap();
    assert_eq!(p.variable, FitVariable::Log);
    assert!((p.argmax() - 0.2f64.exp()).abs() < 1e-9, "{}", p.argmax());
    let (lo, hi) = p.range();
    assert!((lo - 1.0 / 1.9).abs() < 1e-12 && (hi - 1.9).abs() < 1e-12);
    for a in &anchors {
        assert!(close(p.eval(a.x), a.m, 1e-9), "{} vs {}", p.eval(a.x), a.m);
    }
    // In x, the same scores are no polynomial: the linear fit misses.
    let q = fit(&anchors, 5).unwrap();
    assert!(anchors.iter().any(|a| !close(q.eval(a.x), a.m, 1e-6)));
    // A fit in ln x needs positive anchors.
    let bad = [AnchorScore { x: 0.0, m: 1.0 }; 7];
    assert!(fit_in(&bad, 5, FitVariable::Log).is_err());
    assert_eq!(Simulation::ScaleClip.fit_variable(), FitVariable::Log);
    assert_eq!(Simulation::Gamma.fit_variable(), FitVariable::Linear);
}

/// The paper's γ-mapping, named: these tests are about its numbers, whatever
/// the default simulation.
fn gamma_estimator() -> Estimator {
    Estimator::new(EstimatorConfig {
        simulation: Simulation::Gamma,
        ..Default::default()
    })
    .unwrap()
}

fn scale_clip_estimator() -> Estimator {
    Estimator::new(EstimatorConfig {
        simulation: Simulation::ScaleClip,
        ..Default::default()
    })
    .unwrap()
}

/// `M_sim(s)` of scale-and-clip below 1 (estimator.rs), straight from its
/// definition in double precision: the held image scored on the pixels that
/// carry information now, plus the assumed texture recovery.
/// Returns the held part and the assumed part.
fn scale_clip_reference(image: &Metered, s: f64) -> (f64, f64) {
    let (w, h) = (image.width(), image.height());
    let weight = |i: usize| image.weight().map_or(1.0, |wt| f64::from(wt[i]));
    let luma = image.luma();
    let metric = GradientMetric::new(MetricParams::default()).unwrap();
    let at = |img: &[f64], x: usize, y: usize| img[y * w + x];
    let m_of = |img: &[f64], x: usize, y: usize| {
        let gx = at(img, x + 1, y - 1) + 2.0 * at(img, x + 1, y) + at(img, x + 1, y + 1)
            - at(img, x - 1, y - 1)
            - 2.0 * at(img, x - 1, y)
            - at(img, x - 1, y + 1);
        let gy = at(img, x - 1, y + 1) + 2.0 * at(img, x, y + 1) + at(img, x + 1, y + 1)
            - at(img, x - 1, y - 1)
            - 2.0 * at(img, x, y - 1)
            - at(img, x + 1, y - 1);
        (gx * gx + gy * gy).sqrt() / (4.0 * 2f64.sqrt())
    };
    let sat = f64::from(SATURATED_LEVEL);
    let now: Vec<f64> = luma.iter().map(|&v| f64::from(v)).collect();
    let held: Vec<f64> = now
        .iter()
        .map(|&v| if v >= sat { v } else { s * v })
        .collect();
    let widest = 1.0 / 1.9;
    let (mut known, mut saturated, mut band, mut tw, mut ti) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let wt = weight(y * w + x);
            let info_now = metric.information(m_of(&now, x, y));
            if info_now > 0.0 {
                known += wt * metric.information(m_of(&held, x, y));
            }
            let v = now[y * w + x];
            if v >= sat {
                saturated += wt;
                continue;
            }
            if v >= s {
                band += wt;
            }
            let mut hood = (0..9).map(|k| now[(y + k / 3 - 1) * w + x + k % 3 - 1]);
            if hood.all(|n| n >= widest && n < sat) {
                tw += wt;
                ti += wt * info_now;
            }
        }
    }
    let texture = if tw > 0.0 { ti / tw } else { 0.0 };
    (known, f64::min(saturated, band) * texture)
}

#[test]
fn scale_clip_darkening_matches_its_definition() {
    let mut est = scale_clip_estimator();
    // A bright exposure of the synthetic scene: textured patches saturate.
    // Its luminance as single samples (the definition above; blocks with
    // saturated samples have their own rule, tested below).
    let blocks = metered_scene(30_000.0);
    let (w, h) = (blocks.width(), blocks.height());
    let image = Metered::from_luma(w, h, blocks.luma().to_vec(), None).unwrap();
    let saturated = image.stats().saturated_fraction;
    assert!(
        saturated > 0.05 && saturated < 0.6,
        "precondition: partly saturated ({saturated})"
    );
    // And with a metering mask (the lower two thirds).
    let mask: Vec<f32> = (0..w * h).map(|i| f32::from(i / w >= h / 3)).collect();
    let masked = Metered::from_luma(w, h, image.luma().to_vec(), Some(mask)).unwrap();
    for image in [&image, &masked] {
        for s in [1.0 / 1.9, 1.0 / 1.5, 1.0 / 1.2] {
            let (known, assumed) = scale_clip_reference(image, s);
            assert!(
                assumed > 0.02 * known,
                "precondition: texture is assumed to come back ({assumed} of {known})"
            );
            let got = est.score_at(image, s);
            let want = known + assumed;
            assert!(close(got, want, 2e-4), "s={s}: {got} vs {want}");
        }
    }
    // Brightening stays the plain min(1, s·I).
    let bright: Vec<f32> = image.luma().iter().map(|&v| (v * 1.5).min(1.0)).collect();
    let bright = Metered::from_luma(image.width(), image.height(), bright, None).unwrap();
    let plain = Estimator::new(EstimatorConfig::default())
        .unwrap()
        .score(&bright);
    assert!(close(est.score_at(&image, 1.5), plain, 1e-5));
}

#[test]
fn scale_clip_holds_saturated_edges_and_invents_none_at_smooth_contours() {
    let mut est = scale_clip_estimator();
    let (w, h) = (40, 30);
    // A saturated square (far above saturation, say) on a flat grey 0.3:
    // its edges carry information now, and darkening keeps its bright side
    // while the grey darkens, so the edges keep (more than) their
    // information. The plain min(1, s·I) would darken the square too.
    let square: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (10..30).contains(&x) && (8..22).contains(&y) {
                1.0
            } else {
                0.3
            }
        })
        .collect();
    let image = Metered::from_luma(w, h, square.clone(), None).unwrap();
    let now = est.score(&image);
    assert!(now > 0.0);
    let held = est.score_at(&image, 0.6);
    assert!(held >= now, "held {held} vs now {now}");
    let darkened: Vec<f32> = square.iter().map(|&v| v * 0.6).collect();
    let plain = est.score(&Metered::from_luma(w, h, darkened, None).unwrap());
    assert!(
        plain < now,
        "the plain darkening loses contrast: {plain} vs {now}"
    );
    // No texture anywhere below saturation: nothing is assumed to come back.
    let estimate = est.estimate(&image).unwrap();
    assert!(estimate.anchors.iter().all(|a| a.m > 0.0));
    // A smooth ramp that crosses saturation (gradient far below δ): no
    // information now, and none after darkening, although holding the
    // saturated side alone would put a step at the contour.
    let ramp: Vec<f32> = (0..w * h)
        .map(|i| (0.9 + 0.004 * (i % w) as f32).min(1.0))
        .collect();
    let image = Metered::from_luma(w, h, ramp.clone(), None).unwrap();
    assert_eq!(est.score(&image), 0.0);
    assert_eq!(est.score_at(&image, 0.6), 0.0);
    let stepped: Vec<f32> = ramp
        .iter()
        .map(|&v| if v >= SATURATED_LEVEL { v } else { 0.6 * v })
        .collect();
    assert!(est.score(&Metered::from_luma(w, h, stepped, None).unwrap()) > 0.0);
}

/// Frame `id`, taken at `us` microseconds and 0 dB.
fn at(id: u64, us: f64) -> FrameInfo {
    FrameInfo {
        frame_id: id,
        taken: ExposureSetting {
            shutter_us: us,
            gain_db: 0.0,
        },
    }
}

fn metered_scene(exposure: f64) -> Metered {
    let scene = HdrScene::generate(640, 480, 3, &Illumination::Uniform(1.0)).unwrap();
    let frame = LinearCamera::default().render_mono8(scene.radiance(), exposure, 0);
    let view = FrameView::new(PixelFormat::Mono8, 640, 480, &frame).unwrap();
    Meter::new(MeteringConfig::default())
        .unwrap()
        .meter(&view, None)
        .unwrap()
}

#[test]
fn both_simulations_point_the_right_way() {
    let dark = metered_scene(2000.0);
    let bright = metered_scene(40000.0);
    let mut g = gamma_estimator();
    let mut s = Estimator::new(EstimatorConfig {
        simulation: Simulation::ScaleClip,
        ..Default::default()
    })
    .unwrap();
    // Dark: γ̂ < 1 (brighter is better), ŝ > 1 (brighter is better).
    let (gd, sd) = (g.estimate(&dark).unwrap(), s.estimate(&dark).unwrap());
    assert!(gd.x_hat < 1.0 && gd.gamma_hat < 1.0);
    assert!(sd.x_hat > 1.0 && sd.gamma_hat < 1.0, "{}", sd.x_hat);
    // Bright: γ̂ > 1, ŝ < 1; the γ-equivalents agree in sign.
    let (gb, sb) = (g.estimate(&bright).unwrap(), s.estimate(&bright).unwrap());
    assert!(gb.gamma_hat > 1.0);
    assert!(sb.x_hat < 1.0 && sb.gamma_hat > 1.0, "{}", sb.x_hat);
    // Telemetry: seven anchors, current M equals the anchor at 1.
    assert_eq!(gd.anchors.len(), 7);
    assert_eq!(gd.anchors[3].m, gd.m_current);
    assert!(!gd.flat);
}

/// The information-weighted intensity (only the fast law uses it) comes
/// when asked for, and asking changes nothing else of the estimate.
#[test]
fn the_information_weighted_intensity_comes_when_asked() {
    let image = metered_scene(9000.0);
    let mut g = gamma_estimator();
    let plain = g.estimate(&image).unwrap();
    let full = g.estimate_with_info(&image).unwrap();
    assert_eq!(plain.info_intensity, None);
    let mu = full.info_intensity.expect("asked for");
    assert!(
        close(plain.m_current, full.m_current, 1e-5 * full.m_current),
        "M {} vs {}",
        plain.m_current,
        full.m_current
    );
    assert!(close(plain.gamma_hat, full.gamma_hat, 1e-6));
    // exp2(Σ m̄·log₂ I / Σ m̄) from the information map, in double precision.
    let mut map = Vec::new();
    let mut scratch = rigview_core::exposure::metric::Scratch::default();
    g.metric().information_map(
        image.luma(),
        image.width(),
        image.height(),
        None,
        &mut scratch,
        &mut map,
    );
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (&m, &v) in map.iter().zip(image.luma()) {
        if m > 0.0 {
            num += f64::from(m) * f64::from(v).log2();
            den += f64::from(m);
        }
    }
    let want = (num / den).exp2();
    assert!(close(mu, want, 1e-3 * want), "μ {mu} vs {want}");
    // Scale-and-clip gives it when asked too, the same from its
    // information map (which a plain estimate fills without it).
    let mut s = Estimator::new(EstimatorConfig {
        simulation: Simulation::ScaleClip,
        ..Default::default()
    })
    .unwrap();
    assert_eq!(s.estimate(&image).unwrap().info_intensity, None);
    let mu_s = s.estimate_with_info(&image).unwrap().info_intensity;
    let mu_s = mu_s.expect("asked for");
    assert!(close(mu_s, want, 1e-3 * want), "μ {mu_s} vs {want}");
    // The fast law's controller asks for it.
    assert!(g
        .estimate_with_slope(&image)
        .unwrap()
        .info_intensity
        .is_some());
}

#[test]
fn a_black_image_is_flat_and_the_controller_falls_back_to_mean_steps() {
    let black = Metered::from_luma(16, 16, vec![0.0; 256], None).unwrap();
    let mut g = Estimator::new(EstimatorConfig::default()).unwrap();
    let e = g.estimate(&black).unwrap();
    assert!(e.flat);
    assert_eq!(e.gamma_hat, 1.0);
    let config = ControllerConfig {
        balancing: None,
        ..Default::default()
    };
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    let info = FrameInfo {
        frame_id: 0,
        taken: ExposureSetting {
            shutter_us: 1000.0,
            gain_db: 0.0,
        },
    };
    let u = cam.unary(&config, &info, &black).unwrap();
    assert!(u.fallback);
    assert_eq!(
        u.desired, 4000.0,
        "a black image opens up by the largest step"
    );
}

// ---------- Eq. 3 and 4 ----------

#[test]
fn update_laws_match_hand_values() {
    assert!(close(linear_ratio(1.0, 0.8), 1.2, 1e-12));
    assert!(close(linear_ratio(1.0, 1.5), 0.75, 1e-12)); // α = 1/2
    assert!(close(linear_ratio(2.0, 1.0), 1.0, 1e-12));
    // d = 1: atan(1) = π/4; γ̂ = 0.5 gives tan(π/8) = √2 − 1.
    assert!(close(nonlinear_r(1.0, 0.5), 2f64.sqrt(), 1e-12));
    assert!(close(nonlinear_r(1.0, 1.5), 2.0 - 2f64.sqrt(), 1e-12));
    assert!(close(nonlinear_r(0.3, 1.0), 1.0, 1e-12));
    assert!(close(nonlinear_ratio(1.0, 1.0, 0.5), 2f64.sqrt(), 1e-12));
    assert!(close(
        nonlinear_ratio(1.0, 1.0, 1.5),
        1.0 - 0.5 * (2f64.sqrt() - 1.0),
        1e-12
    ));
    // Smaller d is flatter around γ̂ = 1.
    assert!(nonlinear_r(0.2, 0.9) - 1.0 < nonlinear_r(5.0, 0.9) - 1.0);
    // Every law is bounded per frame.
    let law = LawParams {
        kind: LawKind::Linear,
        kp: 20.0,
        ..Default::default()
    };
    assert_eq!(law.bound(linear_ratio(20.0, 1.9)), 0.25);
    assert_eq!(law.bound(f64::NAN), 1.0);
    assert_eq!(law.bound(100.0), 4.0);
}

#[test]
fn baselines_match_hand_values() {
    let mean = MeanIntensityParams {
        target: 0.45,
        gain: 1.0,
    };
    assert!(close(mean.ratio(0.225), 2.0, 1e-12));
    let pid = PidParams {
        kp: 1.0,
        ki: 0.5,
        kd: 0.2,
        integral_limit: 10.0,
    };
    let mut s = PidState::default();
    assert!(close(s.update(&pid, 0.1), 1.15, 1e-12));
    assert!(close(s.update(&pid, 0.2), 1.37, 1e-12));
}

// ---------- Eq. 5 and 6 ----------

#[test]
fn pair_ratio_is_the_median_of_usable_patches() {
    let p = |mi: f32, si: f32, mj: f32, sj: f32| PatchPair {
        mean_i: mi,
        saturated_i: si,
        mean_j: mj,
        saturated_j: sj,
    };
    let params = BalanceParams::default();
    let patches = [
        p(0.2, 0.0, 0.4, 0.0),
        p(0.2, 0.0, 0.41, 0.0),
        p(0.3, 0.5, 0.3, 0.0), // saturated in i: left out
        p(0.1, 0.0, 0.9, 0.0),
        p(0.001, 0.0, 0.2, 0.0), // too dark in i: left out
    ];
    let r = balance::pair_ratio(&patches, &params).unwrap();
    assert!(close(r, 0.41 / 0.201, 1e-6), "{r}");
    assert_eq!(balance::pair_ratio(&patches[2..3], &params), None);
}

#[test]
fn alpha_follows_eq6() {
    for (r, a) in [
        (0.5, 1.0),
        (0.75, 0.75),
        (1.0, 0.5),
        (1.5, 0.75),
        (2.0, 1.0),
        (0.1, 1.0),
        (3.0, 1.0),
    ] {
        assert!(close(balance::alpha(r), a, 1e-12), "α({r})");
    }
}

#[test]
fn balance_is_the_minimiser_of_eq5() {
    let (u, e, ratios) = (1200.0, 1000.0, [2.0, 1.0]);
    let b = balance::balance(u, e, &ratios);
    assert!(close(b.alpha, 0.6, 1e-12));
    assert!(close(b.exposure, 0.6 * 1200.0 + 0.4 * 1.5 * 1000.0, 1e-12));
    let cost = |x: f64| {
        b.alpha * (x - u).powi(2)
            + (1.0 - b.alpha) / 2.0 * ratios.iter().map(|r| (x - r * e).powi(2)).sum::<f64>()
    };
    assert!(cost(b.exposure) < cost(b.exposure + 1.0));
    assert!(cost(b.exposure) < cost(b.exposure - 1.0));
    // No neighbours: the unary stands.
    assert_eq!(balance::balance(u, e, &[]).exposure, u);
}

/// Cameras seeing the same surfaces, each content with its exposure
/// (R = 1, so α = 1/2): balancing alone drives every ratio to 1, on any graph.
#[test]
fn balancing_alone_equalises_brightness_on_any_graph() {
    let graphs = [
        NeighbourGraph::ring(2).unwrap(),
        NeighbourGraph::ring(4).unwrap(),
        NeighbourGraph::new(5, &[(0, 1), (1, 2), (2, 3), (3, 4)]).unwrap(),
        NeighbourGraph::new(4, &[(0, 1), (0, 2), (0, 3)]).unwrap(),
    ];
    for g in graphs {
        let n = g.cameras();
        let mut e: Vec<f64> = (0..n).map(|i| 500.0 * 3f64.powi(i as i32)).collect();
        for _ in 0..60 {
            e = (0..n)
                .map(|i| {
                    let r: Vec<f64> = g.neighbours(i).map(|j| e[j] / e[i]).collect();
                    balance::balance(e[i], e[i], &r).exposure
                })
                .collect();
        }
        let spread =
            e.iter().cloned().fold(f64::MIN, f64::max) / e.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread.log2() < 0.01, "{n} cameras: {e:?}");
    }
}

#[test]
fn damping_keeps_a_steady_direction_and_halves_on_reversals() {
    let p = balance::DampingParams::default();
    let mut d = balance::Damping::default();
    // The same direction: the whole step, every time.
    assert_eq!(d.apply(1000.0, 2000.0, &p), (2000.0, 1.0));
    assert_eq!(d.apply(2000.0, 8000.0, &p), (8000.0, 1.0));
    // A reversal halves κ, in log exposure: 8000·2^(−1/2).
    let (e, k) = d.apply(8000.0, 4000.0, &p);
    assert_eq!(k, 0.5);
    assert!(close(e, 8000.0 * 0.5f64.sqrt(), 1e-9));
    // Another: a quarter of a 1 EV step.
    let (e2, k) = d.apply(e, 2.0 * e, &p);
    assert_eq!(k, 0.25);
    assert!(close(e2, e * 2f64.powf(0.25), 1e-9));
    // Steps inside the dead band change nothing, whatever their direction.
    let tiny = 2f64.powf(0.5 * p.dead_band_ev);
    assert_eq!(d.apply(e2, e2 / tiny, &p).1, 0.25);
    assert_eq!(d.apply(e2, e2 * tiny, &p).1, 0.25);
    // Keeping the direction doubles κ back to 1, not beyond, once the
    // camera has moved `recover_ev` (0.5 EV) since the reversal: 0.25 EV
    // after the reversal, then 0.5.
    assert_eq!(p.recover_ev, 0.5);
    assert_eq!(d.apply(e2, 2.0 * e2, &p).1, 0.25);
    assert_eq!(d.apply(e2, 2.0 * e2, &p).1, 0.5);
    assert_eq!(d.apply(e2, 2.0 * e2, &p).1, 1.0);
    assert_eq!(d.apply(e2, 2.0 * e2, &p).1, 1.0);
    // Reversals stop at the floor.
    for k in 0..12 {
        let t = if k % 2 == 0 { 0.5 } else { 2.0 };
        d.apply(1000.0, 1000.0 * t, &p);
    }
    assert_eq!(d.kappa(), p.floor);
    d.reset();
    assert_eq!(d.kappa(), 1.0);
    // No exposure to step from: the target stands.
    assert_eq!(d.apply(0.0, 500.0, &p).0, 500.0);
    let bad = balance::DampingParams { floor: 0.0, ..p };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("balance.damping.floor"), "{err}");
    let bad = balance::DampingParams {
        recover_ev: -1.0,
        ..p
    };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("balance.damping.recover_ev"), "{err}");
}

/// A balanced target that jumps: 0.1 EV above the camera's exposure below
/// 2^10, 2^9.7 above it (as when γ̂ jumps to the end of the anchors). The
/// camera climbs and drops, a saw-tooth with one reversal every few steps.
/// Letting `κ` grow on every step that keeps the direction
/// (`recover_ev = 0`) gives it back before each drop; waiting for 0.5 EV of
/// travel settles it at the jump.
#[test]
fn damping_settles_a_saw_tooth() {
    let target = |e: f64| {
        if e.log2() < 10.0 {
            e * 0.1f64.exp2()
        } else {
            9.7f64.exp2()
        }
    };
    let run = |params: balance::DampingParams| {
        let mut d = balance::Damping::default();
        let mut e = 9.5f64.exp2();
        let mut path = Vec::new();
        for _ in 0..200 {
            e = d.apply(e, target(e), &params).0;
            path.push(e.log2());
        }
        let tail = &path[path.len() - 30..];
        tail.iter().cloned().fold(f64::MIN, f64::max)
            - tail.iter().cloned().fold(f64::MAX, f64::min)
    };
    let eager = run(balance::DampingParams {
        recover_ev: 0.0,
        ..Default::default()
    });
    assert!(eager > 0.1, "κ regained on every step: band {eager:.3} EV");
    let patient = run(balance::DampingParams::default());
    assert!(patient < 0.05, "band {patient:.3} EV");
}

/// A camera whose own law wants `E0` (`R = E0/E`) while its neighbours want
/// it at `4·E0`: Eq. 5 and 6 have a fixed point at `1.5·E0` (`R = 2/3`,
/// `α = 5/6`), but there `d ln E*/d ln E = 1 − (6R − ½)·R = −4/3`, so the
/// plain iteration circles it. The damped one settles on it.
#[test]
fn damping_settles_a_two_step_cycle_on_the_balanced_fixed_point() {
    let e0: f64 = 1000.0;
    let run = |params: balance::DampingParams| {
        let mut d = balance::Damping::default();
        let mut e: f64 = 1400.0;
        let mut path = Vec::new();
        for _ in 0..60 {
            let unary = e * (e0 / e).clamp(0.5, 2.0);
            let b = balance::balance(unary, e, &[4.0 * e0 / e]);
            e = d.apply(e, b.exposure, &params).0;
            path.push(e);
        }
        path
    };
    let band = |p: &[f64]| {
        let tail = &p[p.len() - 10..];
        (tail.iter().cloned().fold(f64::MIN, f64::max)
            / tail.iter().cloned().fold(f64::MAX, f64::min))
        .log2()
    };
    let plain = run(balance::DampingParams {
        floor: 1.0,
        ..Default::default()
    });
    assert!(band(&plain) > 0.3, "the plain iteration: {plain:?}");
    let damped = run(balance::DampingParams::default());
    assert!(band(&damped) < 0.01, "damped: {damped:?}");
    let last = damped[damped.len() - 1];
    assert!((last / (1.5 * e0)).log2().abs() < 0.01, "settled at {last}");
    // It is Eq. 5's own fixed point.
    let b = balance::balance(e0, last, &[4.0 * e0 / last]);
    assert!((b.exposure / last).log2().abs() < 0.01);
}

/// A camera whose own law's ratio `R` falls steeply near its balanced rest
/// (from 0.9 to 0.5 within 0.02 EV, as where the estimate moves from one
/// hump of `M` to the other) while its neighbours want it about 1.5 EV
/// brighter. With each frame's own `α`, Eq. 6 amplifies every swing of `R`
/// and the damped camera circles 1.5 EV wide; with `α` averaged over frames
/// it settles, on Eq. 5's fixed point.
#[test]
fn averaging_alpha_settles_a_camera_whose_own_law_turns_steeply() {
    let ratio = |e: f64| 0.7 - 0.2 * ((e.log2() - 10.0) / 0.01).clamp(-1.0, 1.0);
    let neighbours = |e: f64| 3000.0 / e;
    let run = |params: balance::DampingParams| {
        let mut d = balance::Damping::default();
        let mut e = 9.5f64.exp2();
        let mut path = Vec::new();
        for _ in 0..400 {
            let b = balance::balance_with(e * ratio(e), e, &[neighbours(e)], |a| {
                d.smooth_alpha(a, params.alpha_weight_under(Simulation::Gamma))
            });
            e = d.apply(e, b.exposure, &params).0;
            path.push(e.log2());
        }
        let tail = &path[path.len() - 50..];
        let band = tail.iter().cloned().fold(f64::MIN, f64::max)
            - tail.iter().cloned().fold(f64::MAX, f64::min);
        (band, path[path.len() - 1])
    };
    let (plain, _) = run(balance::DampingParams::default());
    let averaged_params = balance::DampingParams {
        alpha_weight: Some(0.125),
        ..Default::default()
    };
    let (averaged, at) = run(averaged_params);
    println!("each frame's α: band {plain:.4} EV; averaged: {averaged:.4} EV at 2^{at:.3}");
    assert!(plain > 0.3, "each frame's α: band {plain:.4} EV");
    assert!(averaged < 0.01, "averaged α: band {averaged:.4} EV");
    // Eq. 5's own fixed point: the balanced target is the exposure.
    let e = at.exp2();
    let b = balance::balance(e * ratio(e), e, &[neighbours(e)]);
    assert!(
        (b.exposure / e).log2().abs() < 0.02,
        "{} at {e}",
        b.exposure
    );
    // Each frame's own α by default (Eq. 6 as written). Averaged: the
    // first frame starts the mean; the next ones fold in with the weight; a
    // change of light starts it again.
    let mut d = balance::Damping::default();
    let default = balance::DampingParams::default();
    // Unset, the weight follows the simulation: 1 under the γ-mapping,
    // 1/8 under scale-and-clip; a weight that is set holds under both.
    assert_eq!(default.alpha_weight, None);
    let under_gamma = default.alpha_weight_under(Simulation::Gamma);
    assert_eq!(under_gamma, 1.0);
    assert_eq!(
        default.alpha_weight_under(Simulation::ScaleClip),
        balance::SCALE_CLIP_ALPHA_WEIGHT
    );
    assert_eq!(d.smooth_alpha(0.6, under_gamma), 0.6);
    assert_eq!(d.smooth_alpha(1.0, under_gamma), 1.0);
    let p = averaged_params;
    let w = p.alpha_weight_under(Simulation::Gamma);
    assert_eq!(w, 0.125);
    let mut d = balance::Damping::default();
    assert_eq!(d.smooth_alpha(0.6, w), 0.6);
    assert!(close(d.smooth_alpha(1.0, w), 0.6 + 0.4 * w, 1e-12));
    d.observe(10.0, 0.5, 0.1);
    d.observe(10.0, 0.05, 0.1);
    assert_eq!(d.smooth_alpha(0.9, w), 0.9);
    let bad = balance::DampingParams {
        alpha_weight: Some(0.0),
        ..p
    };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("balance.damping.alpha_weight"), "{err}");
}

// ---------- split ----------

#[test]
fn split_is_shutter_first_then_gain_and_does_not_chatter() {
    let mut s = Splitter::new(ExposureRange::default(), SplitParams::default()).unwrap();
    let (a, c) = s.split(10_000.0);
    assert_eq!((a.shutter_us, a.gain_db, c), (10_000.0, 0.0, None));
    let (b, _) = s.split(98_000.0);
    assert!(close(b.shutter_us, 49_000.0, 1e-12));
    assert!(close(b.gain_db, 20.0 * 2f64.log10(), 1e-9));
    assert!(close(b.exposure(), 98_000.0, 1e-12));
    // Back well below the knee: gain released, shutter only.
    let (d, _) = s.split(20_000.0);
    assert_eq!(d.gain_db, 0.0);
    // Oscillating around the knee changes the gain at most once.
    let mut gains = Vec::new();
    for k in 0..40 {
        let e = if k % 2 == 0 { 48_000.0 } else { 50_500.0 };
        let (set, _) = s.split(e);
        assert!(close(set.exposure(), e, 1e-9));
        gains.push(set.gain_db);
    }
    let switches = gains
        .windows(2)
        .filter(|w| (w[0] - w[1]).abs() > 1e-9)
        .count();
    assert!(switches <= 1, "gain changed {switches} times: {gains:?}");
    // Outside the camera's ranges: clamped and said so.
    let (hi, c) = s.split(1e12);
    assert_eq!(c, Some(Clamped::High));
    assert_eq!(hi.gain_db, 24.0);
    let (lo, c) = s.split(1.0);
    assert_eq!(c, Some(Clamped::Low));
    assert_eq!(lo.shutter_us, 10.0);
}

// ---------- metering ----------

#[test]
fn every_pixel_format_meters_to_the_same_luminance() {
    let (w, h) = (64usize, 48usize);
    let grey: Vec<u8> = (0..w * h).map(|i| ((i * 37) % 251) as u8).collect();
    let meter = Meter::new(MeteringConfig {
        target_width: 16,
        target_height: 12,
    })
    .unwrap();
    let reference = meter
        .meter(
            &FrameView::new(PixelFormat::Mono8, w, h, &grey).unwrap(),
            None,
        )
        .unwrap();
    assert_eq!((reference.width(), reference.height()), (16, 12));
    let mono16: Vec<u8> = grey
        .iter()
        .flat_map(|&v| (u16::from(v) * 257).to_le_bytes())
        .collect();
    let mono12: Vec<u8> = grey
        .iter()
        .flat_map(|&v| ((u32::from(v) * 4095 / 255) as u16).to_le_bytes())
        .collect();
    let rgb: Vec<u8> = grey.iter().flat_map(|&v| [v, v, v]).collect();
    let cases = [
        (PixelFormat::Mono16, mono16),
        (PixelFormat::Mono12, mono12),
        (PixelFormat::Rgb8, rgb),
    ];
    for (fmt, data) in cases {
        let m = meter
            .meter(&FrameView::new(fmt, w, h, &data).unwrap(), None)
            .unwrap();
        for (a, b) in m.luma().iter().zip(reference.luma()) {
            assert!((a - b).abs() < 1.0 / 255.0, "{fmt:?}: {a} vs {b}");
        }
    }
    // Bayer of a grey scene: 2×2 quads of equal values meter as grey.
    let quad: Vec<u8> = (0..w * h)
        .map(|i| grey[(i / w / 2 * 2) * w + (i % w) / 2 * 2])
        .collect();
    let quad_ref = meter
        .meter(
            &FrameView::new(PixelFormat::Mono8, w, h, &quad).unwrap(),
            None,
        )
        .unwrap();
    let bayer = meter
        .meter(
            &FrameView::new(PixelFormat::BayerRg8, w, h, &quad).unwrap(),
            None,
        )
        .unwrap();
    // Quads are binned first, then 2×2 blocks of quads: the same 16×12.
    assert_eq!((bayer.width(), bayer.height()), (16, 12));
    assert_eq!(bayer.scale(), 4);
    for (a, b) in bayer.luma().iter().zip(quad_ref.luma()) {
        assert!((a - b).abs() < 1.0 / 255.0, "Bayer: {a} vs {b}");
    }
}

#[test]
fn colour_weights_are_bt601_for_rgb_and_every_bayer_order() {
    let meter = Meter::new(MeteringConfig {
        target_width: 3,
        target_height: 3,
    })
    .unwrap();
    let red_rgb: Vec<u8> = (0..36).flat_map(|_| [255u8, 0, 0]).collect();
    let m = meter
        .meter(
            &FrameView::new(PixelFormat::Rgb8, 6, 6, &red_rgb).unwrap(),
            None,
        )
        .unwrap();
    assert!((m.stats().mean - 0.299).abs() < 1e-4);
    // Red sits at (0,0) for RG, (1,0) for GR, (0,1) for GB, (1,1) for BG.
    for (fmt, rx, ry) in [
        (PixelFormat::BayerRg8, 0, 0),
        (PixelFormat::BayerGr8, 1, 0),
        (PixelFormat::BayerGb8, 0, 1),
        (PixelFormat::BayerBg8, 1, 1),
    ] {
        let data: Vec<u8> = (0..36)
            .map(|i| {
                if (i % 6) % 2 == rx && (i / 6) % 2 == ry {
                    255
                } else {
                    0
                }
            })
            .collect();
        let m = meter
            .meter(&FrameView::new(fmt, 6, 6, &data).unwrap(), None)
            .unwrap();
        assert!(
            (m.stats().mean - 0.299).abs() < 1e-4,
            "{fmt:?}: {}",
            m.stats().mean
        );
    }
}

#[test]
fn reference_frame_size_and_roi_mask() {
    let (w, h) = (1288usize, 964usize);
    // Bright sky on top, dark ground below.
    let frame: Vec<u8> = (0..w * h)
        .map(|i| {
            if i / w < h / 2 {
                250
            } else {
                40 + (i % 7) as u8
            }
        })
        .collect();
    let view = FrameView::new(PixelFormat::Mono8, w, h, &frame).unwrap();
    let meter = Meter::new(MeteringConfig::default()).unwrap();
    let all = meter.meter(&view, None).unwrap();
    assert_eq!((all.width(), all.height()), (322, 241));
    let mask = RoiMask::rows_from(w, h, h / 2).unwrap();
    let ground = meter.meter(&view, Some(&mask)).unwrap();
    assert!(ground.stats().mean < 0.2, "{}", ground.stats().mean);
    assert!(all.stats().mean > 0.5);
    let weight = ground.weight().unwrap();
    assert!(weight[10 * 322 + 10] == 0.0 && weight[200 * 322 + 10] == 1.0);
}

// ---------- controller and latency ----------

#[test]
fn the_controller_commands_every_frame_and_never_reacts_twice() {
    // Eq. 4 under the γ-mapping: a step anchored to the frame it was
    // computed from.
    let config = ControllerConfig {
        balancing: None,
        law: LawParams {
            kind: LawKind::Nonlinear,
            ..Default::default()
        },
        estimator: EstimatorConfig {
            simulation: Simulation::Gamma,
            ..Default::default()
        },
        ..Default::default()
    };
    let dark = metered_scene(2000.0);
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    let u = cam.unary(&config, &at(0, 2000.0), &dark).unwrap();
    assert_eq!(u.hold, None);
    let (cmd, _) = cam.command(u.desired, at(0, 2000.0).taken);
    let cmd = cmd.expect("a dark image asks for more exposure");
    assert!(cmd.exposure() > 2000.0);
    assert_eq!(cam.in_flight(), 1);
    // Latency: the next frame still shows the old exposure. The controller
    // reacts to it, but a step anchored to the frame asks for what is in
    // flight already: no second command on top of the first.
    let u = cam.unary(&config, &at(1, 2000.0), &dark).unwrap();
    assert_eq!(u.hold, None);
    let (again, _) = cam.command(u.desired, at(1, 2000.0).taken);
    assert_eq!(again, None, "the same step must not be sent twice");
    assert_eq!(cam.in_flight(), 1);
    // The same frame again.
    let u = cam.unary(&config, &at(1, 2000.0), &dark).unwrap();
    assert_eq!(u.hold, Some(Hold::RepeatedFrame));
    // The command shows: nothing in flight any more.
    let shown = metered_scene(cmd.exposure());
    let u = cam.unary(&config, &at(2, cmd.shutter_us), &shown).unwrap();
    assert_eq!(u.hold, None);
    assert_eq!(cam.in_flight(), 0);
}

/// A camera alone under Eq. 4, without probes.
fn nonlinear_alone(simulation: Simulation) -> ControllerConfig {
    ControllerConfig {
        balancing: None,
        probe: None,
        law: LawParams {
            kind: LawKind::Nonlinear,
            ..Default::default()
        },
        estimator: EstimatorConfig {
            simulation,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn under_scale_and_clip_the_law_goes_on_from_the_command_in_flight() {
    // Eq. 4 under scale-and-clip: ŝ places the fixed point, so a frame
    // taken before the first command showed applies the law again from
    // where that command leaves the camera, as the estimate sees it from
    // there, and never past the fixed point the frame shows.
    let config = nonlinear_alone(Simulation::ScaleClip);
    let dark = metered_scene(1500.0);
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    let u = cam.unary(&config, &at(0, 1500.0), &dark).unwrap();
    let e = u.estimate.clone().unwrap();
    // The estimate is ahead of the law's step: more than one step away.
    let first = u.desired;
    let law = config.law.ratio(&e, dark.stats());
    assert!(
        close(first, 1500.0 * law, 1e-9),
        "{first} against {}",
        1500.0 * law
    );
    assert!(
        e.x_hat > law * law,
        "ŝ {} and the law's ratio {law}",
        e.x_hat
    );
    let (cmd, _) = cam.command(first, at(0, 1500.0).taken);
    assert!(cmd.is_some());
    let u = cam.unary(&config, &at(1, 1500.0), &dark).unwrap();
    let e1 = u.estimate.clone().unwrap();
    let best = 1500.0 * e1.x_hat;
    let expected = first * nonlinear_ratio(1.0, 0.8, first / best);
    assert!(
        close(u.desired, expected, 1e-9),
        "{} against {expected}",
        u.desired
    );
    assert!(u.desired > first && u.desired < best);
    let (again, _) = cam.command(u.desired, at(1, 1500.0).taken);
    assert!(
        again.is_some(),
        "the law goes on from the command in flight"
    );
    assert_eq!(cam.in_flight(), 2);
}

#[test]
fn a_frame_still_at_the_old_setting_shows_no_command_that_leads_back_towards_it() {
    // Two frames of latency: a command down, then one back up towards
    // where the camera was. A frame still taken at the old setting lies
    // nearer the second command than the first command does, and must not
    // be taken for it.
    let config = ControllerConfig {
        balancing: None,
        probe: None,
        ..Default::default()
    };
    let scene = metered_scene(2000.0);
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    cam.unary(&config, &at(0, 2000.0), &scene).unwrap();
    assert!(cam.command(1000.0, at(0, 2000.0).taken).0.is_some());
    cam.unary(&config, &at(1, 2000.0), &scene).unwrap();
    assert!(cam.command(1800.0, at(1, 2000.0).taken).0.is_some());
    assert_eq!(cam.in_flight(), 2);
    cam.unary(&config, &at(2, 2000.0), &scene).unwrap();
    assert_eq!(
        cam.in_flight(),
        2,
        "a frame at the old setting shows nothing"
    );
    assert_eq!(cam.base(at(2, 2000.0).taken).exposure(), 1800.0);
    cam.unary(&config, &at(3, 1000.0), &scene).unwrap();
    assert_eq!(cam.in_flight(), 1);
    cam.unary(&config, &at(4, 1800.0), &scene).unwrap();
    assert_eq!(cam.in_flight(), 0);
}

#[test]
fn a_frame_that_shows_a_change_of_light_is_answered_before_the_last_command_shows() {
    // Under the γ-mapping, whose fixed point on this scene lies below
    // 8000 µs.
    let config = ControllerConfig {
        balancing: None,
        probe: None,
        estimator: EstimatorConfig {
            simulation: Simulation::Gamma,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    // A bright frame: the controller asks for less.
    let u = cam
        .unary(&config, &at(0, 8000.0), &metered_scene(8000.0))
        .unwrap();
    let (first, _) = cam.command(u.desired, at(0, 8000.0).taken);
    let first = first.expect("a bright image asks for less exposure");
    assert!(first.exposure() < 8000.0);
    // The light falls by eight: the next frame, still at the old exposure,
    // is much darker, and the controller answers it at once.
    let u = cam
        .unary(&config, &at(1, 8000.0), &metered_scene(1000.0))
        .unwrap();
    assert_eq!(u.hold, None);
    let (second, _) = cam.command(u.desired, at(1, 8000.0).taken);
    let second = second.expect("a darker scene asks for a new command at once");
    assert!(
        second.exposure() > first.exposure(),
        "{} after {}",
        second.exposure(),
        first.exposure()
    );
    assert_eq!(cam.in_flight(), 2);
}

#[test]
fn a_command_the_camera_quantises_counts_as_shown() {
    let config = ControllerConfig {
        balancing: None,
        ..Default::default()
    };
    let dark = metered_scene(40.0);
    // Cameras apply exposure on their own grid: whole microseconds, or
    // sensor rows (here 14.6 µs); either can be well over 0.2 % off at short
    // exposures.
    for grid in [1.0, 14.6] {
        let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
        let u = cam.unary(&config, &at(0, 40.0), &dark).unwrap();
        let (cmd, _) = cam.command(u.desired, at(0, 40.0).taken);
        let cmd = cmd.expect("a dark image asks for more exposure");
        let applied = (cmd.shutter_us / grid).floor() * grid + 0.6 * grid;
        assert!(
            (applied / cmd.shutter_us - 1.0).abs() > 2e-3,
            "the quantisation must exceed the 0.2 % tolerance for this test to mean anything"
        );
        let u = cam
            .unary(&config, &at(1, applied), &metered_scene(applied))
            .unwrap();
        assert_eq!(u.hold, None);
        assert_eq!(
            cam.in_flight(),
            0,
            "grid {grid} µs: the applied command must count as shown"
        );
    }
    // A frame still at the old exposure leaves the command in flight.
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    let u = cam.unary(&config, &at(0, 40.0), &dark).unwrap();
    let _ = cam.command(u.desired, at(0, 40.0).taken);
    let _ = cam.unary(&config, &at(1, 40.0), &dark).unwrap();
    assert_eq!(cam.in_flight(), 1);
}

// ---------- bad input ----------

#[test]
fn bad_input_gives_errors_not_panics() {
    assert!(matches!(
        FrameView::new(PixelFormat::Mono8, 0, 10, &[]),
        Err(Error::EmptyImage { .. })
    ));
    assert!(matches!(
        FrameView::new(PixelFormat::Rgb8, 10, 10, &[0; 299]),
        Err(Error::BufferSize {
            expected: 300,
            actual: 299,
            ..
        })
    ));
    let frame = vec![0u8; 100];
    let view = FrameView::new(PixelFormat::Mono8, 10, 10, &frame).unwrap();
    let mask = RoiMask::new(5, 5, vec![1; 25]).unwrap();
    let meter = Meter::new(MeteringConfig::default()).unwrap();
    assert!(matches!(
        meter.meter(&view, Some(&mask)),
        Err(Error::SizeMismatch { .. })
    ));
    let tiny = FrameView::new(PixelFormat::Mono8, 2, 2, &frame[..4]).unwrap();
    assert!(meter.meter(&tiny, None).is_err());
    assert!(RoiMask::new(4, 4, vec![0; 15]).is_err());
    assert!(Metered::from_luma(4, 4, vec![0.0; 15], None).is_err());
    assert!(Metered::from_luma(4, 4, vec![f32::NAN; 16], None).is_err());
    for (delta, lambda) in [
        (f64::NAN, 1000.0),
        (0.06, f64::NAN),
        (0.06, -1.0),
        (1.5, 10.0),
    ] {
        let e = GradientMetric::new(MetricParams { delta, lambda }).unwrap_err();
        assert!(matches!(e, Error::InvalidParameter { .. }), "{e}");
    }
    let law = LawParams {
        kp: f64::NAN,
        ..Default::default()
    };
    assert!(law.validate().unwrap_err().to_string().contains("kp"));
    let few = EstimatorConfig {
        anchors: vec![0.8, 1.0, 1.2],
        ..Default::default()
    };
    assert!(few
        .validate()
        .unwrap_err()
        .to_string()
        .contains("at least 6"));
    let zero = ExposureRange {
        shutter_min_us: 100.0,
        shutter_max_us: 100.0,
        gain_min_db: 0.0,
        gain_max_db: 0.0,
    };
    assert!(Splitter::new(zero, SplitParams::default()).is_err());
    let inverted = ExposureRange {
        shutter_min_us: 100.0,
        shutter_max_us: 10.0,
        ..Default::default()
    };
    assert!(inverted.validate().is_err());
    let negative = ExposureRange {
        shutter_min_us: -1.0,
        ..Default::default()
    };
    assert!(negative.validate().is_err());
    assert!(NeighbourGraph::new(2, &[(0, 2)]).is_err());
    assert!(NeighbourGraph::new(2, &[(1, 1)]).is_err());
    let config = ControllerConfig::default();
    let mut rig = RigController::new(
        config.clone(),
        &[ExposureRange::default(); 2],
        NeighbourGraph::ring(2).unwrap(),
    )
    .unwrap();
    assert!(rig.step(&[], &[]).is_err());
    assert!(RigController::new(
        config.clone(),
        &[ExposureRange::default()],
        NeighbourGraph::ring(2).unwrap()
    )
    .is_err());
    let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
    let bad = FrameInfo {
        frame_id: 0,
        taken: ExposureSetting {
            shutter_us: f64::NAN,
            gain_db: 0.0,
        },
    };
    let m = Metered::from_luma(4, 4, vec![0.5; 16], None).unwrap();
    assert!(cam.unary(&config, &bad, &m).is_err());
}

/// A 16-bit frame of `w×h` sensor pixels of a piecewise-constant scene
/// (squares of 13 pixels, which straddle the 4×4 metering blocks): five
/// radiance levels, the brightest 4× above full well at exposure 1.
fn block_scene_frame(exposure: f64, w: usize, h: usize) -> Vec<u8> {
    const LEVELS: [f64; 5] = [0.05, 0.12, 0.3, 0.5, 4.0];
    let mut out = Vec::with_capacity(w * h * 2);
    for y in 0..h {
        for x in 0..w {
            let level = LEVELS[(x / 13 + 7 * (y / 13)) % LEVELS.len()];
            let v = (level * exposure).min(1.0);
            out.extend_from_slice(&((v * 65535.0).round() as u16).to_le_bytes());
        }
    }
    out
}

#[test]
fn scale_clip_on_metered_blocks_scales_only_their_unsaturated_samples() {
    let (w, h) = (320, 240);
    let meter = Meter::new(MeteringConfig {
        target_width: 80,
        target_height: 60,
    })
    .unwrap();
    let metered = |e: f64| {
        let data = block_scene_frame(e, w, h);
        meter
            .meter(
                &FrameView::new(PixelFormat::Mono16, w, h, &data).unwrap(),
                None,
            )
            .unwrap()
    };
    let now = metered(1.0);
    assert_eq!((now.width(), now.height(), now.scale()), (80, 60, 4));
    let plane = now.saturated_samples().expect("saturated samples");
    // A block is saturated in whole, in part or not at all.
    assert!(plane.contains(&1.0));
    assert!(plane.iter().any(|&f| f > 0.0 && f < 1.0));
    assert!(plane.contains(&0.0));
    // The same luminance without the plane: every block scaled whole.
    let whole = Metered::from_luma(now.width(), now.height(), now.luma().to_vec(), None).unwrap();
    let mut est = scale_clip_estimator();
    let truth_est = |m: &Metered| Estimator::new(EstimatorConfig::default()).unwrap().score(m);
    for s in [1.0 / 1.9, 1.0 / 1.5, 1.0 / 1.2, 1.2, 1.5, 1.9] {
        let truth = truth_est(&metered(s));
        let blocks = est.score_at(&now, s);
        let scaled_whole = est.score_at(&whole, s);
        let (e_blocks, e_whole) = ((blocks - truth) / truth, (scaled_whole - truth) / truth);
        println!("s {s:.3}: truth {truth:.0}, blocks {blocks:.0} ({e_blocks:+.4}), whole {scaled_whole:.0} ({e_whole:+.4})");
        // The brightest squares stay saturated at every anchor and the
        // others are flat, so brightening is exact up to rounding; a
        // darkening counts only the pixels that carry information now.
        let tolerance = if s > 1.0 { 1e-3 } else { 1e-2 };
        assert!(e_blocks.abs() < tolerance, "s={s}: {blocks} vs {truth}");
        if (s.ln().abs() - 1.9f64.ln()).abs() < 1e-9 {
            assert!(
                e_whole.abs() > 5.0 * e_blocks.abs() && e_whole.abs() > 0.02,
                "s={s}: scaling whole blocks is off by only {e_whole:+.4}"
            );
        }
    }
}

/// A 16-bit frame of `w×h` sensor pixels at `exposure`, the scene shifted
/// `dx` pixels: squares of 13 pixels at six radiance levels, two of them
/// above full well at exposure 1 (1.3× and 4×), each with a texture of
/// ±25 % that carries gradient information wherever it is not clipped.
fn textured_square_frame(exposure: f64, w: usize, h: usize, dx: usize) -> Vec<u8> {
    const LEVELS: [f64; 6] = [0.05, 0.12, 0.3, 1.3, 0.5, 4.0];
    let mut out = Vec::with_capacity(w * h * 2);
    for y in 0..h {
        for x in (0..w).map(|x| x + dx) {
            let level = LEVELS[(x / 13 + 7 * (y / 13)) % LEVELS.len()];
            let texture = 1.0 + 0.25 * (0.9 * x as f64).sin() * (0.7 * y as f64).cos();
            let v = (level * texture * exposure).min(1.0);
            out.extend_from_slice(&((v * 65535.0).round() as u16).to_le_bytes());
        }
    }
    out
}

/// Given a darker frame of the same scene, scale-and-clip reads what the
/// saturated pixels hide and predicts every darkening anchor to within
/// 1 % (the textured squares 1.3× above full well come back at
/// `s < 1/1.3`), where holding them misses by more: metered 1:1 and in
/// 4×4 blocks, with the darker frame at the smallest anchor and beyond it.
/// Brightening is unchanged. A darker frame that is not the same scene
/// (shifted, other light, too near, another size) is not read, and the
/// γ-mapping ignores one.
#[test]
fn a_darker_frame_tells_scale_clip_what_saturation_hides() {
    for (w, h, scale) in [(80, 60, 1), (320, 240, 4)] {
        let meter = Meter::new(MeteringConfig {
            target_width: 80,
            target_height: 60,
        })
        .unwrap();
        let metered_shifted = |e: f64, dx: usize| {
            let data = textured_square_frame(e, w, h, dx);
            meter
                .meter(
                    &FrameView::new(PixelFormat::Mono16, w, h, &data).unwrap(),
                    None,
                )
                .unwrap()
        };
        let metered = |e: f64| metered_shifted(e, 0);
        let now = metered(1.0);
        assert_eq!(now.scale(), scale);
        let truth = |s: f64| {
            Estimator::new(EstimatorConfig::default())
                .unwrap()
                .score(&metered(s))
        };
        let mut est = scale_clip_estimator();
        let plain = est.estimate(&now).unwrap();
        assert!(!plain.declipped);
        for ratio in [1.0 / 1.9, 0.4] {
            let darker = metered(ratio);
            let declipped = est
                .estimate_with(
                    &now,
                    EstimateOptions {
                        darker: Some(Darker {
                            image: &darker,
                            ratio,
                        }),
                        ..Default::default()
                    },
                )
                .unwrap();
            assert!(declipped.declipped, "{w}×{h}: the same scene was not read");
            for (p, d) in plain.anchors.iter().zip(&declipped.anchors) {
                let t = truth(p.x);
                let (ep, ed) = ((p.m - t) / t, (d.m - t) / t);
                println!(
                    "{w}×{h}, darker frame at {ratio:.3}: s {:.3}: truth {t:.1}, held {:.1} ({ep:+.4}), declipped {:.1} ({ed:+.4})",
                    p.x, p.m, d.m
                );
                if p.x < 1.0 {
                    assert!(ed.abs() <= 0.01, "{w}×{h} s={}: {ed:+.4}", p.x);
                } else {
                    assert!((d.m - p.m).abs() <= 1e-5 * p.m, "{w}×{h} s={}", p.x);
                }
                if (p.x - 1.0 / 1.9).abs() < 1e-9 {
                    assert!(
                        ep.abs() > 0.02 && ep.abs() > 3.0 * ed.abs(),
                        "{w}×{h}: holding is off by only {ep:+.4} at s={}",
                        p.x
                    );
                }
            }
        }
        // Not the same scene: the estimate is the plain one.
        let shifted = metered_shifted(1.0 / 1.9, 13);
        let brighter_light = metered(1.2 / 1.9);
        let other_size = Meter::new(MeteringConfig {
            target_width: 40,
            target_height: 30,
        })
        .unwrap()
        .meter(
            &FrameView::new(
                PixelFormat::Mono16,
                w,
                h,
                &textured_square_frame(1.0 / 1.9, w, h, 0),
            )
            .unwrap(),
            None,
        )
        .unwrap();
        let near = metered(0.97);
        for (what, image, ratio) in [
            ("shifted", &shifted, 1.0 / 1.9),
            ("other light", &brighter_light, 1.0 / 1.9),
            ("other size", &other_size, 1.0 / 1.9),
            ("too near", &near, 0.97),
            ("not darker", &now, 1.0),
        ] {
            let e = est
                .estimate_with(
                    &now,
                    EstimateOptions {
                        darker: Some(Darker { image, ratio }),
                        ..Default::default()
                    },
                )
                .unwrap();
            assert!(!e.declipped, "{w}×{h}: a darker frame {what} was read");
            assert_eq!(e.anchors, plain.anchors, "{w}×{h}: {what}");
        }
        let mut gamma = gamma_estimator();
        let darker = metered(1.0 / 1.9);
        let g = gamma
            .estimate_with(
                &now,
                EstimateOptions {
                    darker: Some(Darker {
                        image: &darker,
                        ratio: 1.0 / 1.9,
                    }),
                    ..Default::default()
                },
            )
            .unwrap();
        assert!(!g.declipped);
        assert_eq!(g, gamma.estimate(&now).unwrap());
    }
}

#[test]
fn a_pair_without_usable_patches_keeps_its_scene_ratio() {
    use rigview_core::exposure::balance::HeldRatios;
    let mut held = HeldRatios::default();
    // Measured at E_i = 100, E_j = 200: r = 1.5, so the scene ratio is 0.75.
    assert_eq!(
        held.update((0, 1), Some(1.5), 100.0, 200.0, 3, false),
        Some(1.5)
    );
    // Unusable patches: at E_i = 50, E_j = 200 the held scene ratio gives
    // r = 0.75 · 200 / 50 = 3.
    let r = held.update((0, 1), None, 50.0, 200.0, 3, false).unwrap();
    assert!((r - 3.0).abs() < 1e-12, "{r}");
    // Another pair has nothing held.
    assert_eq!(held.update((1, 0), None, 200.0, 50.0, 3, false), None);
    // Held for at most `hold_sets` sets.
    assert!(held.update((0, 1), None, 50.0, 200.0, 3, false).is_some());
    assert!(held.update((0, 1), None, 50.0, 200.0, 3, false).is_some());
    assert_eq!(held.update((0, 1), None, 50.0, 200.0, 3, false), None);
    // A new measurement starts again.
    assert_eq!(
        held.update((0, 1), Some(2.0), 50.0, 200.0, 3, false),
        Some(2.0)
    );
    // Sets whose patches are clipped do not age the held ratio.
    for _ in 0..10 {
        assert!(held.update((0, 1), None, 50.0, 200.0, 3, true).is_some());
    }
    for _ in 0..3 {
        assert!(held.update((0, 1), None, 50.0, 200.0, 3, false).is_some());
    }
    assert_eq!(held.update((0, 1), None, 50.0, 200.0, 3, false), None);
    held.clear();
    assert_eq!(held.update((0, 1), None, 50.0, 200.0, 3, true), None);
}

// ---------- Scale-and-clip through a tone curve ----------

/// `radiance` at exposure `2^ev`, through the tone curve `I = L^(1/p)`,
/// quantised to 8 bits.
fn toned_frame(scene: &HdrScene, ev: f64, p: f64) -> Metered {
    let e = ev.exp2();
    let luma = scene
        .radiance()
        .iter()
        .map(|&r| {
            let l = (f64::from(r) * e).clamp(0.0, 1.0);
            ((l.powf(1.0 / p) * 255.0).round() / 255.0) as f32
        })
        .collect();
    Metered::from_luma(scene.width(), scene.height(), luma, None).unwrap()
}

/// Where `est`'s estimate on the frames of `scene` says "stay" (ŝ = 1),
/// EV, searched within `[lo, hi]`.
fn fixed_point(est: &mut Estimator, scene: &HdrScene, p: f64, lo: f64, hi: f64) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    for _ in 0..16 {
        let mid = 0.5 * (lo + hi);
        if est.estimate(&toned_frame(scene, mid, p)).unwrap().x_hat > 1.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn scale_and_clip_through_the_tone_curve_predicts_the_frames_and_rests_near_the_best_m() {
    // Frames through a display gamma: scaling the recorded values is not
    // what a longer exposure does; scaling the light under the curve is.
    for p in [1.0, 2.2, 4.4] {
        for seed in [1u64, 2, 3, 7] {
            let scene = HdrScene::generate(160, 120, seed, &Illumination::Uniform(1.0)).unwrap();
            let mut plain = scale_clip_estimator();
            let mut toned = Estimator::new(EstimatorConfig {
                simulation: Simulation::ScaleClip,
                tone_curve: Some(ToneCurve::Power(p)),
                ..Default::default()
            })
            .unwrap();
            // M of the frames themselves, every 0.05 EV.
            let (best, m_best) = (0..=120)
                .map(|k| -2.0 + 0.05 * f64::from(k))
                .map(|ev| (ev, plain.score(&toned_frame(&scene, ev, p))))
                .fold((0.0, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
            // Half a stop under the best (few pixels saturated): each
            // anchor's simulated M against M of the frame at that exposure.
            let ev0 = best - 0.5;
            let frame = toned_frame(&scene, ev0, p);
            let (a, b) = (
                plain.estimate(&frame).unwrap(),
                toned.estimate(&frame).unwrap(),
            );
            let (mut err_plain, mut err_toned) = (0.0f64, 0.0f64);
            for (x, y) in a.anchors.iter().zip(&b.anchors) {
                let truth = plain.score(&toned_frame(&scene, ev0 + x.x.log2(), p));
                err_plain = err_plain.max((x.m / truth - 1.0).abs());
                err_toned = err_toned.max((y.m / truth - 1.0).abs());
                if p == 1.0 {
                    // A linear curve is plain scale-and-clip.
                    assert!(
                        close(y.m, x.m, 1e-4),
                        "seed {seed} s {}: {} {}",
                        x.x,
                        y.m,
                        x.m
                    );
                }
            }
            // (At p = 1 both are plain scale-and-clip, whose assumptions
            // about the few saturated pixels leave up to 3 % here.)
            if p > 1.0 {
                assert!(
                    err_toned < 0.01,
                    "p {p} seed {seed}: anchors off by {err_toned}"
                );
                assert!(
                    err_plain > 0.2,
                    "p {p} seed {seed}: plain off by {err_plain}"
                );
            }
            // Where the estimate says "stay", M is near its best.
            let ft = fixed_point(&mut toned, &scene, p, best - 2.0, best + 2.0);
            let m = plain.score(&toned_frame(&scene, ft, p));
            assert!(
                m >= 0.98 * m_best,
                "p {p} seed {seed}: {m} of {m_best} at {ft}, best {best}"
            );
        }
    }
}

#[test]
fn a_tone_curve_in_the_settings_is_checked() {
    let bad = EstimatorConfig {
        tone_curve: Some(ToneCurve::Table(vec![0.0, 0.7, 0.5, 1.0])),
        ..Default::default()
    };
    let e = Estimator::new(bad).unwrap_err().to_string();
    assert!(
        e.contains("tone_curve") && e.contains("non-decreasing"),
        "{e}"
    );
    let mut est = scale_clip_estimator();
    assert!(est.set_tone_curve(Some(ToneCurve::Power(-1.0))).is_err());
    assert!(est.tone_curve().is_none());
    est.set_tone_curve(Some(ToneCurve::Power(2.2))).unwrap();
    assert_eq!(est.tone_curve(), Some(&ToneCurve::Power(2.2)));
}

#[test]
fn a_camera_keeps_its_levels_and_tone_curve_when_the_settings_change() {
    let ranges = [ExposureRange::default(); 2];
    let mut rig = RigController::new(
        ControllerConfig::default(),
        &ranges,
        NeighbourGraph::ring(2).unwrap(),
    )
    .unwrap();
    let cam = rig.camera_mut(0).unwrap();
    cam.set_levels(Some(vec![500.0, 1000.0, 2000.0]));
    cam.set_tone_curve(Some(ToneCurve::Power(2.2))).unwrap();
    // New estimator settings rebuild each camera's estimator.
    let mut config = ControllerConfig::default();
    config.estimator.plateau = 0.05;
    rig.set_config(config.clone()).unwrap();
    let cam = rig.camera_mut(0).unwrap();
    assert!(cam.has_levels(), "the levels were lost");
    assert_eq!(
        cam.estimator_mut().tone_curve(),
        Some(&ToneCurve::Power(2.2))
    );
    let other = rig.camera_mut(1).unwrap();
    assert!(!other.has_levels());
    assert_eq!(other.estimator_mut().tone_curve(), None);
    // The settings' curve is every camera's but the one with its own.
    config.estimator.tone_curve = Some(ToneCurve::Power(1.8));
    rig.set_config(config).unwrap();
    assert_eq!(
        rig.camera_mut(0).unwrap().estimator_mut().tone_curve(),
        Some(&ToneCurve::Power(2.2))
    );
    assert_eq!(
        rig.camera_mut(1).unwrap().estimator_mut().tone_curve(),
        Some(&ToneCurve::Power(1.8))
    );
    // The power the display reads each curve as follows the curve in force.
    assert_eq!(rig.camera_mut(0).unwrap().tone_power(), 2.2);
    assert_eq!(rig.camera_mut(1).unwrap().tone_power(), 1.8);
    rig.camera_mut(0).unwrap().set_tone_curve(None).unwrap();
    assert_eq!(rig.camera_mut(0).unwrap().tone_power(), 1.8);
    rig.set_config(ControllerConfig::default()).unwrap();
    assert_eq!(rig.camera_mut(1).unwrap().tone_power(), 1.0);
}

/// Balancing moves exposures by ratios of light: through a camera's tone
/// curve a patch ratio is read as light. Two cameras see the same textured
/// frame (the same own steps) and an overlap whose light in camera 1 is
/// twice camera 0's. Recorded through a power curve of 2.2 the patches
/// differ by 2^(1/2.2) = 1.37; with the curve set, balancing moves the
/// cameras as a linear rig recording the ratio 2 does, not as one
/// recording 1.37.
#[test]
fn balancing_reads_overlap_ratios_as_light_through_tone_curves() {
    let p = 2.2;
    let (w, h) = (64, 48);
    let luma: Vec<f32> = (0..w * h)
        .map(|k| 0.2 + 0.15 * (((k % w) / 4 + (k / w) / 4) % 3) as f32)
        .collect();
    let metered = Metered::from_luma(w, h, luma, None).unwrap();
    let moved = |curve: Option<ToneCurve>, recorded_ratio: f64| {
        let config = ControllerConfig {
            estimator: EstimatorConfig {
                simulation: Simulation::Gamma,
                ..Default::default()
            },
            probe: None,
            light: None,
            ..Default::default()
        };
        let mut rig = RigController::new(
            config,
            &[ExposureRange::default(); 2],
            NeighbourGraph::ring(2).unwrap(),
        )
        .unwrap();
        for k in 0..2 {
            rig.camera_mut(k)
                .unwrap()
                .set_tone_curve(curve.clone())
                .unwrap();
        }
        let info = FrameInfo {
            frame_id: 1,
            taken: ExposureSetting {
                shutter_us: 2000.0,
                gain_db: 0.0,
            },
        };
        let inputs = [
            CameraInput {
                info,
                metered: &metered,
            },
            CameraInput {
                info,
                metered: &metered,
            },
        ];
        let patches: Vec<PatchPair> = (0..8)
            .map(|k| {
                let m = 0.25 + 0.02 * k as f32;
                PatchPair {
                    mean_i: m,
                    saturated_i: 0.0,
                    mean_j: (f64::from(m) * recorded_ratio).min(0.95) as f32,
                    saturated_j: 0.0,
                }
            })
            .collect();
        let pairs = [PairObservation {
            i: 0,
            j: 1,
            patches,
        }];
        let step = rig.step(&inputs, &pairs).unwrap();
        let c = &step.cameras;
        // Balancing's move of each camera from its own desired exposure.
        [
            (c[0].target / c[0].unary).log2(),
            (c[1].target / c[1].unary).log2(),
        ]
    };
    let linear_2 = moved(None, 2.0);
    let toned = moved(Some(ToneCurve::Power(p)), 2f64.powf(1.0 / p));
    let linear_137 = moved(None, 2f64.powf(1.0 / p));
    println!("balancing's moves (EV): linear, ratio 2 {linear_2:?}; through 2.2 {toned:?}; linear, ratio 1.37 {linear_137:?}");
    // Camera 0 sees the overlap darker: balancing brightens it and darkens
    // camera 1.
    assert!(linear_2[0] > 0.05 && linear_2[1] < -0.05, "{linear_2:?}");
    for k in 0..2 {
        assert!(
            (toned[k] - linear_2[k]).abs() < 0.02,
            "camera {k}: {toned:?} against {linear_2:?}"
        );
        assert!(
            (linear_137[k] - linear_2[k]).abs() > 0.05,
            "camera {k}: the recorded ratio alone moves it the same: {linear_137:?}"
        );
    }
}

/// Scale-and-clip brightens exactly, so where its maximiser sits at the
/// brightest anchor it searches span after span beyond it: a frame 3 EV
/// under the fixed point is placed there, not at the first span's end
/// (1.9² ≈ 3.6), and the laws take the step that distance asks for.
#[test]
fn scale_and_clip_searches_span_after_span_beyond_its_brightest_anchor() {
    let mut s = Estimator::new(EstimatorConfig {
        simulation: Simulation::ScaleClip,
        ..Default::default()
    })
    .unwrap();
    // The fixed point, found from near it.
    let mut e = 20000.0;
    for _ in 0..6 {
        let est = s.estimate(&metered_scene(e)).unwrap();
        e *= est.x_hat;
    }
    let near = s.estimate(&metered_scene(e)).unwrap();
    assert!(near.x_hat.log2().abs() < 0.05, "{}", near.x_hat);
    let dark = metered_scene(e / 8.0);
    let plain = s.estimate(&dark).unwrap();
    assert_eq!(plain.at_bound, Some(Bound::Upper));
    let options = EstimateOptions {
        extend: true,
        ..Default::default()
    };
    let far = s.estimate_with(&dark, options).unwrap();
    println!("fixed point {e:.0} µs; from 3 EV under: ŝ {:.2}", far.x_hat);
    assert!(far.extended && far.at_bound.is_none(), "{far:?}");
    assert!((far.x_hat.log2() - 3.0).abs() < 0.3, "ŝ {}", far.x_hat);
    assert!(far.x_hat > 1.9f64.powi(2));
    assert!((far.gamma_hat - 1.0 / far.x_hat).abs() < 1e-12);
}

/// A mostly saturated frame under scale-and-clip says the best lies below
/// where the commands in flight will leave the camera too: the next frame
/// taken before the first command showed steps on from it (the
/// mean-intensity fallback's step, again), where the γ-mapping's waits.
#[test]
fn a_saturated_frame_steps_on_from_the_command_in_flight_under_scale_and_clip() {
    for (simulation, compounds) in [(Simulation::ScaleClip, true), (Simulation::Gamma, false)] {
        let config = nonlinear_alone(simulation);
        let e = 400_000.0;
        let bright = metered_scene(e);
        assert!(bright.stats().saturated_fraction > 0.8);
        let mut cam = CameraController::new(&config, ExposureRange::default()).unwrap();
        let u = cam.unary(&config, &at(0, e), &bright).unwrap();
        assert!(u.fallback);
        let first = u.desired;
        assert!(first < e);
        cam.command(first, at(0, e).taken);
        let u = cam.unary(&config, &at(1, e), &bright).unwrap();
        let expected = if compounds { first * first / e } else { first };
        assert!(
            close(u.desired, expected, 1e-9),
            "{simulation:?}: {} against {expected}",
            u.desired
        );
    }
}
