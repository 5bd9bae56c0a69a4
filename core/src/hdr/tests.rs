use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;
use crate::exposure::ExposureSetting;
use crate::sim::Sensor;
use crate::stats::median;

fn at(shutter_us: f64) -> ExposureSetting {
    ExposureSetting {
        shutter_us,
        gain_db: 0.0,
    }
}

fn noise(bits: u32) -> SensorNoise {
    SensorNoise::of(&Sensor::default(), bits).unwrap()
}

/// A standard normal draw (Box–Muller), independent of the emulator's
/// table.
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let (u1, u2): (f64, f64) = (1.0 - rng.gen::<f64>(), rng.gen());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The image a linear sensor with `n`'s noise takes of radiances `x` (DN
/// per unit exposure) at `s`, with or without noise, as bytes.
fn shoot(x: &[f64], s: ExposureSetting, n: &SensorNoise, rng: Option<&mut ChaCha8Rng>) -> Vec<u8> {
    let (kg, read_var, full, top) = n.at_gain(s.gain_db);
    let mut rng = rng;
    let values: Vec<f64> = x
        .iter()
        .map(|&x| {
            let mu = x * s.exposure();
            let v = match rng.as_deref_mut() {
                Some(r) => mu + (kg * mu.min(full) + read_var).sqrt() * normal(r),
                None => mu,
            };
            v.clamp(0.0, top).round()
        })
        .collect();
    if n.bits > 8 {
        values
            .iter()
            .flat_map(|&v| (v as u16).to_le_bytes())
            .collect()
    } else {
        values.iter().map(|&v| v as u8).collect()
    }
}

/// The shots of `images` taken at `levels` (µs at 0 dB).
fn shots<'a>(levels: &[f64], images: &'a [Vec<u8>]) -> Vec<Shot<'a>> {
    levels
        .iter()
        .zip(images)
        .map(|(&t, d)| Shot {
            setting: at(t),
            data: d,
        })
        .collect()
}

fn values(data: &[u8], bits: u32) -> Vec<f64> {
    if bits > 8 {
        data.chunks_exact(2)
            .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
            .collect()
    } else {
        data.iter().map(|&v| f64::from(v)).collect()
    }
}

/// Radiances spread evenly in log over `decades` decades from `lo`.
fn scene(n: usize, lo: f64, decades: f64) -> Vec<f64> {
    (0..n)
        .map(|i| lo * 10f64.powf(decades * i as f64 / (n - 1) as f64))
        .collect()
}

#[test]
fn the_merge_of_noise_free_brackets_recovers_the_radiance() {
    let n = noise(12);
    // From 0.03 DN at 64 µs to 8000 DN (clipped) at the same exposure.
    let x = scene(2000, 4e-4, 5.5);
    let levels = [64.0, 128.0, 256.0, 512.0, 1024.0, 2048.0];
    let images: Vec<Vec<u8>> = levels.iter().map(|&t| shoot(&x, at(t), &n, None)).collect();
    let shots = shots(&levels, &images);
    let r = merge(&shots, &MergeConfig::new(x.len(), n)).unwrap();
    assert_eq!(r.span(), (64.0, 2048.0));
    // Where some image holds at least 200 DN unclipped, rounding is below
    // 0.25 %; the merged value is within 0.5 %.
    for (i, (&truth, &got)) in x.iter().zip(r.values()).enumerate() {
        let best = levels
            .iter()
            .map(|&t| truth * t)
            .filter(|&v| v < 0.97 * 4095.0)
            .fold(0.0, f64::max);
        if best >= 200.0 {
            let err = (f64::from(got) / truth - 1.0).abs();
            assert!(err < 0.005, "sample {i}: {got} for {truth} ({err})");
        }
    }
    // The brightest samples are clipped in every image: a lower bound.
    let last = *r.values().last().unwrap();
    assert!(f64::from(last) <= *x.last().unwrap() && r.variances().last() == Some(&0.0));
}

#[test]
fn leaving_one_bracket_out_emulates_it_within_a_twentieth_of_a_stop() {
    let n = noise(12);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let x = scene(20_000, 2e-3, 3.0);
    let levels = [128.0, 256.0, 512.0, 1024.0, 2048.0];
    let images: Vec<Vec<u8>> = levels
        .iter()
        .map(|&t| shoot(&x, at(t), &n, Some(&mut rng)))
        .collect();
    for j in 1..levels.len() - 1 {
        let shots: Vec<Shot<'_>> = (0..levels.len())
            .filter(|&k| k != j)
            .map(|k| Shot {
                setting: at(levels[k]),
                data: &images[k],
            })
            .collect();
        let r = merge(&shots, &MergeConfig::new(x.len(), n)).unwrap();
        let mut out = vec![0u8; x.len() * 2];
        let options = EmulateOptions {
            noise: false,
            seed: 1,
            camera: 0,
            frame: 0,
        };
        r.emulate(&at(levels[j]), &options, &mut out).unwrap();
        let (emulated, truth) = (values(&out, 12), shoot(&x, at(levels[j]), &n, None));
        // Against the noise-free truth: the merge's own error, the noise of
        // the brackets it averages (about 1 % at the median).
        let mut errors: Vec<f64> = emulated
            .iter()
            .zip(values(&truth, 12))
            .filter(|(_, t)| (100.0..3900.0).contains(t))
            .map(|(e, t)| (e / t).log2().abs())
            .collect();
        assert!(errors.len() > 3000, "{}", errors.len());
        let m = median(&mut errors).unwrap();
        assert!(m < 0.02, "bracket {j}: median |error| {m:.4} EV");
        // Against the real (noisy) bracket: its own noise dominates.
        let mut errors: Vec<f64> = emulated
            .iter()
            .zip(values(&images[j], 12))
            .filter(|(_, t)| (100.0..3900.0).contains(t))
            .map(|(e, t)| (e / t).log2().abs())
            .collect();
        let m = median(&mut errors).unwrap();
        assert!(m < 0.05, "bracket {j}: median |error| {m:.4} EV");
    }
}

#[test]
fn an_emulated_frame_has_the_sensors_noise_and_is_a_function_of_its_seed() {
    let n = noise(12);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // A flat field: 1000 DN at 1000 µs.
    let x = vec![1.0; 50_000];
    let levels = [250.0, 500.0, 1000.0, 2000.0];
    let images: Vec<Vec<u8>> = levels
        .iter()
        .map(|&t| shoot(&x, at(t), &n, Some(&mut rng)))
        .collect();
    let shots = shots(&levels, &images);
    let r = merge(&shots, &MergeConfig::new(x.len(), n)).unwrap();
    let options = EmulateOptions {
        noise: true,
        seed: 11,
        camera: 2,
        frame: 5,
    };
    let (kg, read_var, _, _) = n.at_gain(0.0);
    // At a bracket's exposure, between two, at a gain: the sensor's
    // variance at that mean (not twice it), within 5 %.
    for s in [
        at(1000.0),
        at(700.0),
        ExposureSetting {
            shutter_us: 350.0,
            gain_db: 6.0,
        },
    ] {
        let mut out = vec![0u8; x.len() * 2];
        r.emulate(&s, &options, &mut out).unwrap();
        let v = values(&out, 12);
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / v.len() as f64;
        let g = crate::exposure::split::gain_factor(s.gain_db);
        let want_mean = s.exposure();
        let want_var = g * g * (kg * want_mean / g + read_var) + 1.0 / 12.0;
        assert!(
            (mean / want_mean - 1.0).abs() < 0.002,
            "{s:?}: mean {mean} for {want_mean}"
        );
        assert!(
            (var / want_var - 1.0).abs() < 0.05,
            "{s:?}: variance {var:.1} for {want_var:.1}"
        );
        let mut again = vec![0u8; out.len()];
        r.emulate(&s, &options, &mut again).unwrap();
        assert_eq!(out, again);
        r.emulate(
            &s,
            &EmulateOptions {
                seed: 12,
                ..options
            },
            &mut again,
        )
        .unwrap();
        assert_ne!(out, again);
    }
}

#[test]
fn an_emulated_frame_clips_at_full_well_and_at_the_top() {
    let n = noise(12);
    let x = vec![1.0; 4096];
    let images: Vec<Vec<u8>> = [500.0, 1000.0]
        .iter()
        .map(|&t| shoot(&x, at(t), &n, None))
        .collect();
    let shots = [
        Shot {
            setting: at(500.0),
            data: &images[0],
        },
        Shot {
            setting: at(1000.0),
            data: &images[1],
        },
    ];
    let r = merge(&shots, &MergeConfig::new(x.len(), n)).unwrap();
    let options = EmulateOptions {
        noise: true,
        seed: 1,
        camera: 0,
        frame: 0,
    };
    let mut out = vec![0u8; x.len() * 2];
    r.emulate(&at(100_000.0), &options, &mut out).unwrap();
    assert!(values(&out, 12).iter().all(|&v| v >= 4094.5));
    // At 12 dB (×3.98) full well is at 4095 · 3.98 DN: the converter clips
    // first. At −12 dB the full well (1029 DN) clips first.
    let low = ExposureSetting {
        shutter_us: 100_000.0,
        gain_db: -12.0,
    };
    r.emulate(&low, &options, &mut out).unwrap();
    let top = (4095.0 * crate::exposure::split::gain_factor(-12.0)).round();
    assert!(values(&out, 12).iter().all(|&v| (v - top).abs() <= 1.0));
    // A buffer of the wrong size is refused.
    let e = r
        .emulate(&at(1000.0), &options, &mut out[..10])
        .unwrap_err();
    assert!(e.to_string().contains("emulated frame"), "{e}");
}

#[test]
fn an_8_bit_gamma_response_is_recovered_and_emulated() {
    // Codes of a display gamma: z = 255 (v/255)^(1/2.2).
    let n = noise(8);
    let gamma = |v: f64| 255.0 * (v.clamp(0.0, 255.0) / 255.0).powf(1.0 / 2.2);
    let x = scene(30_000, 1e-3, 3.0);
    let levels = [100.0, 200.0, 400.0, 800.0, 1600.0, 3200.0];
    let image = |t: f64| -> Vec<u8> { x.iter().map(|&x| gamma(x * t).round() as u8).collect() };
    let images: Vec<Vec<u8>> = levels.iter().map(|&t| image(t)).collect();
    let shots = shots(&levels, &images);
    let curve = Response::recover(&shots, x.len(), 300, 10.0).unwrap();
    let Response::Curve { inverse, .. } = &curve else {
        panic!("a linear response")
    };
    // The recovered linear value of code z against (z/255)^2.2 · 255: within
    // 6 % over the codes the images use well.
    for z in [40usize, 80, 128, 180, 230] {
        let want = 255.0 * (z as f64 / 255.0).powf(2.2);
        let got = f64::from(inverse[z]);
        assert!(
            (got / want - 1.0).abs() < 0.06,
            "code {z}: {got:.2} for {want:.2}"
        );
    }
    // Leave the 400 µs image out and emulate it: codes within 2 of the
    // image's, on the whole, where it is neither black nor clipped.
    let config = MergeConfig {
        response: curve,
        ..MergeConfig::new(x.len(), n)
    };
    let rest: Vec<Shot<'_>> = shots
        .iter()
        .filter(|s| (s.setting.shutter_us - 400.0).abs() > 1.0)
        .copied()
        .collect();
    let r = merge(&rest, &config).unwrap();
    let mut out = vec![0u8; x.len()];
    let options = EmulateOptions {
        noise: false,
        seed: 0,
        camera: 0,
        frame: 0,
    };
    r.emulate(&at(400.0), &options, &mut out).unwrap();
    let mut diffs: Vec<f64> = out
        .iter()
        .zip(&images[2])
        .filter(|(_, &t)| (10..245).contains(&t))
        .map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs())
        .collect();
    assert!(diffs.len() > 10_000);
    let m = median(&mut diffs).unwrap();
    let worst = diffs.iter().fold(0.0f64, |a, &b| a.max(b));
    assert!(m <= 1.0 && worst <= 6.0, "median {m}, largest {worst}");
    // A linear merge of the same images is off: the curve matters.
    let r = merge(&rest, &MergeConfig::new(x.len(), n)).unwrap();
    r.emulate(&at(400.0), &options, &mut out).unwrap();
    let linear_worst = out
        .iter()
        .zip(&images[2])
        .filter(|(_, &t)| (10..245).contains(&t))
        .map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs())
        .fold(0.0f64, f64::max);
    assert!(linear_worst > 10.0, "{linear_worst}");
}

#[test]
fn bad_inputs_are_refused_with_what_was_expected() {
    let n = noise(12);
    let data = vec![0u8; 10];
    let e = merge(
        &[Shot {
            setting: at(100.0),
            data: &data,
        }],
        &MergeConfig::new(100, n),
    )
    .unwrap_err();
    assert!(e.to_string().contains("expected 200 bytes"), "{e}");
    let e = merge(&[], &MergeConfig::new(100, n)).unwrap_err();
    assert!(e.to_string().contains("no images"), "{e}");
    let e = merge(
        &[Shot {
            setting: at(0.0),
            data: &data,
        }],
        &MergeConfig::new(5, n),
    )
    .unwrap_err();
    assert!(e.to_string().contains("positive exposure"), "{e}");
    assert!(SensorNoise::of(&Sensor::default(), 17).is_err());
    let e = Response::recover(
        &[Shot {
            setting: at(1.0),
            data: &data,
        }],
        10,
        10,
        10.0,
    )
    .unwrap_err();
    assert!(e.to_string().contains("two exposures"), "{e}");
}
