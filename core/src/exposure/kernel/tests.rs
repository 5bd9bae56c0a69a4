use super::*;
use crate::exposure::metric::SOBEL_NORM;
use rand::{Rng, SeedableRng};

fn textured(w: usize, h: usize, seed: u64) -> Vec<f32> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let base = 0.5 + 0.4 * (x * 0.3).sin() * (y * 0.17).cos();
            (base + rng.gen_range(-0.05..0.05)).clamp(0.0, 1.0)
        })
        .collect()
}

/// `ln q` of interior pixel `(x, y)` of a `w`-wide image, in double
/// precision (δ = 0.06).
fn reference_ln_q(img: &[f32], w: usize, x: usize, y: usize, lambda: f64) -> f64 {
    let at = |x: usize, y: usize| f64::from(img[y * w + x]);
    let gx = at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1)
        - at(x - 1, y - 1)
        - 2.0 * at(x - 1, y)
        - at(x - 1, y + 1);
    let gy = at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1)
        - at(x - 1, y - 1)
        - 2.0 * at(x, y - 1)
        - at(x + 1, y - 1);
    let m = (gx * gx + gy * gy).sqrt() / f64::from(SOBEL_NORM);
    (1.0 + lambda * (m - 0.06).max(0.0)).ln()
}

/// Straightforward double-precision Eq. 1 sum of `w·ln q`.
fn reference(img: &[f32], w: usize, h: usize, weight: Option<&[f32]>, lambda: f64) -> f64 {
    let mut total = 0.0;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            total += weight.map_or(1.0, |wt| f64::from(wt[y * w + x]))
                * reference_ln_q(img, w, x, y, lambda);
        }
    }
    total
}

#[test]
fn every_isa_matches_the_reference() {
    // Widths with and without a partial last chunk of 16 lanes.
    for (w, h) in [(37, 11), (64, 9), (3, 3), (130, 40)] {
        let img = textured(w, h, w as u64);
        let weight: Vec<f32> = (0..w * h).map(|i| (i % 7) as f32 / 6.0).collect();
        let binary: Vec<f32> = (0..w * h).map(|i| f32::from(i % 5 != 0)).collect();
        for lambda in [1000.0f64, 10.0, 1e9] {
            let p = Params::new(lambda as f32, 0.06, SOBEL_NORM);
            for wt in [None, Some(weight.as_slice()), Some(binary.as_slice())] {
                let want = reference(&img, w, h, wt, lambda);
                for isa in Isa::available() {
                    let got = sum_ln_q(isa, Source::Plain(&img), w, h, wt, p, &mut Rows::default());
                    let tol = 1e-5 * want.abs().max(1.0);
                    assert!(
                        (got - want).abs() <= tol,
                        "{isa:?} {w}×{h} λ={lambda} weighted={}: {got} vs {want}",
                        wt.is_some()
                    );
                    let mut map = Vec::new();
                    let (sum, _) = information(
                        isa,
                        &img,
                        None,
                        w,
                        h,
                        wt,
                        p,
                        &mut Rows::default(),
                        Some(&mut map),
                    );
                    assert!((sum - want).abs() <= tol, "{isa:?} map sum {sum} vs {want}");
                    let map_sum: f64 = map.iter().map(|&v| f64::from(v)).sum();
                    assert!(
                        (map_sum - want).abs() <= tol,
                        "{isa:?} map {map_sum} vs {want}"
                    );
                }
            }
        }
    }
}

#[test]
fn mapped_sources_match_mapping_first() {
    let (w, h) = (101, 23);
    let img = textured(w, h, 3);
    let mut log2 = Aligned::default();
    log2_map(Isa::detect(), &img, -126.0 / 1.9, &mut log2);
    let p = Params::new(1000.0, 0.06, SOBEL_NORM);
    for isa in Isa::available() {
        for gamma in [1.0f32 / 1.9, 1.5] {
            let mapped: Vec<f32> = img.iter().map(|v| v.powf(gamma)).collect();
            let want = reference(&mapped, w, h, None, 1000.0);
            let got = sum_ln_q(
                isa,
                Source::Gamma { log2: &log2, gamma },
                w,
                h,
                None,
                p,
                &mut Rows::default(),
            );
            assert!(
                (got - want).abs() <= 2e-5 * want,
                "{isa:?} γ={gamma}: {got} vs {want}"
            );
        }
        for s in [0.6f32, 1.9] {
            let mapped: Vec<f32> = img.iter().map(|v| (v * s).min(1.0)).collect();
            let want = reference(&mapped, w, h, None, 1000.0);
            let got = sum_ln_q(
                isa,
                Source::Scale { luma: &img, s },
                w,
                h,
                None,
                p,
                &mut Rows::default(),
            );
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "{isa:?} s={s}: {got} vs {want}"
            );
        }
        // Through a lookup (a tone curve's exposure change): a steep,
        // uneven table, interpolated between its entries.
        let table: Vec<f32> = (0..65)
            .map(|i| ((i as f32) / 64.0).powf(0.45).min(0.97))
            .collect();
        let through = |v: f32| {
            let x = v.clamp(0.0, 1.0) * 64.0;
            let i = (x as usize).min(63);
            table[i] + (x - i as f32) * (table[i + 1] - table[i])
        };
        let mapped: Vec<f32> = img.iter().map(|&v| through(v)).collect();
        for weight in [None, Some(&vec![1.0f32; w * h][..])] {
            let want = reference(&mapped, w, h, weight, 1000.0);
            let got = sum_ln_q(
                isa,
                Source::Table {
                    luma: &img,
                    table: &table,
                },
                w,
                h,
                weight,
                p,
                &mut Rows::default(),
            );
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "{isa:?} table: {got} vs {want}"
            );
        }
        // Scale-and-hold, on an image with saturated patches, weighted.
        let level = 0.9f32;
        let held: Vec<f32> = img.iter().map(|&v| (v * 1.3).min(1.0)).collect();
        let weight: Vec<f32> = (0..w * h).map(|i| (i % 5) as f32 / 4.0).collect();
        for s in [0.6f32, 0.9] {
            let mapped: Vec<f32> = held
                .iter()
                .map(|&v| if v >= level { v } else { v * s })
                .collect();
            let want = reference(&mapped, w, h, Some(&weight), 1000.0);
            let got = sum_ln_q(
                isa,
                Source::Hold {
                    luma: &held,
                    s,
                    level,
                },
                w,
                h,
                Some(&weight),
                p,
                &mut Rows::default(),
            );
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "{isa:?} hold s={s}: {got} vs {want}"
            );
        }
        // Declipped: a part below saturation and a saturated part whose
        // true level is known, some of it far above saturation.
        let unsaturated: Vec<f32> = img.iter().map(|&v| 0.5 * v).collect();
        let saturated: Vec<f32> = (0..w * h).map(|i| (i % 3) as f32 / 4.0).collect();
        let hidden: Vec<f32> = saturated
            .iter()
            .zip(&img)
            .map(|(&f, &v)| f * (1.0 + 3.0 * v))
            .collect();
        for s in [0.4f32, 0.8] {
            let mapped: Vec<f32> = (0..w * h)
                .map(|i| (s * unsaturated[i] + saturated[i].min(s * hidden[i])).min(1.0))
                .collect();
            let want = reference(&mapped, w, h, Some(&weight), 1000.0);
            let got = sum_ln_q(
                isa,
                Source::Declipped {
                    unsaturated: &unsaturated,
                    saturated: &saturated,
                    hidden: &hidden,
                    s,
                },
                w,
                h,
                Some(&weight),
                p,
                &mut Rows::default(),
            );
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "{isa:?} declipped s={s}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn the_information_dot_and_the_logarithms_match_double_precision() {
    let (w, h) = (83, 29);
    let img = textured(w, h, 5);
    let p = Params::new(1000.0, 0.06, SOBEL_NORM);
    // Σ ln q·log₂ I in double precision.
    let (mut exact_sum, mut exact_dot) = (0.0, 0.0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let ln_q = reference_ln_q(&img, w, x, y, 1000.0);
            exact_sum += ln_q;
            exact_dot += ln_q * f64::from(img[y * w + x]).log2();
        }
    }
    let exact_mean = exact_dot / exact_sum;
    assert!(
        exact_mean < -0.1,
        "the test image should be mid-grey: {exact_mean}"
    );
    let floor = -126.0 / 1.9;
    for isa in Isa::available() {
        let mut logs = Aligned::default();
        log2_map(isa, &img, floor, &mut logs);
        for (&l, &v) in logs.iter().zip(&img) {
            let want = f64::from(v).log2().clamp(f64::from(floor), 0.0);
            assert!(
                (f64::from(l) - want).abs() <= 3e-7 * (1.0 + want.abs()),
                "{isa:?}: log₂ {v} = {l}, not {want}"
            );
        }
        let (sum, dot) = sum_ln_q_and_dot(isa, &img, &logs, w, h, p, &mut Rows::default());
        assert!(
            (sum - exact_sum).abs() <= 1e-5 * exact_sum,
            "{isa:?}: {sum} vs {exact_sum}"
        );
        // ln q to 1.5e-4 of ~5: the weighted mean of log₂ I moves by less
        // than 1e-4.
        let mean = dot / sum;
        assert!(
            (mean - exact_mean).abs() < 1e-4,
            "{isa:?}: {mean} vs {exact_mean}"
        );
    }
}

#[test]
fn short_inputs_score_zero() {
    let p = Params::new(1000.0, 0.06, SOBEL_NORM);
    let img = vec![0.5f32; 8];
    assert_eq!(
        sum_ln_q(
            Isa::Baseline,
            Source::Plain(&img),
            4,
            4,
            None,
            p,
            &mut Rows::default()
        ),
        0.0
    );
    let short_weight = vec![1.0f32; 3];
    let img = textured(5, 5, 1);
    assert_eq!(
        sum_ln_q(
            Isa::detect(),
            Source::Plain(&img),
            5,
            5,
            Some(&short_weight),
            p,
            &mut Rows::default()
        ),
        0.0
    );
}

/// [`saturation_sums`] in double precision, pixel by pixel.
fn reference_saturation(
    luma: &[f32],
    weight: Option<&[f32]>,
    info: &[f32],
    (w, h): (usize, usize),
    levels: &[f32],
    (widest, level): (f32, f32),
) -> SaturationSumsRef {
    let mut out = SaturationSumsRef {
        bands: vec![0.0; levels.len()],
        ..Default::default()
    };
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let k = y * w + x;
            let (v, wt) = (luma[k], weight.map_or(1.0, |wt| f64::from(wt[k])));
            let around =
                (y - 1..=y + 1).flat_map(|r| (x - 1..=x + 1).map(move |c| luma[r * w + c]));
            let (lo, hi) = around.fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
            if v >= level {
                out.saturated += wt;
            }
            if lo >= widest && hi < level {
                out.texture_weight += wt;
                out.texture_info += f64::from(info[k]);
            }
            for (b, &s) in out.bands.iter_mut().zip(levels) {
                if s < 1.0 && v >= s && v < level {
                    *b += wt;
                }
            }
        }
    }
    out
}

#[derive(Debug, Default)]
struct SaturationSumsRef {
    saturated: f64,
    bands: Vec<f64>,
    texture_weight: f64,
    texture_info: f64,
}

#[test]
fn saturation_sums_match_double_precision_on_every_isa() {
    // Widths with and without a partial last chunk of 16 lanes; a bright
    // image so that every sum has pixels (saturated areas, bands, texture).
    for (w, h) in [(37, 11), (64, 9), (3, 3), (130, 40)] {
        let luma: Vec<f32> = textured(w, h, 3 + w as u64)
            .iter()
            .map(|&v| (v * 1.6).min(1.0))
            .collect();
        let info: Vec<f32> = (0..w * h).map(|i| (i % 11) as f32 * 0.25).collect();
        let weight: Vec<f32> = (0..w * h).map(|i| (i % 7) as f32 / 6.0).collect();
        let levels = [0.35f32, 0.5, 0.71, 1.0, 1.41];
        for wt in [None, Some(weight.as_slice())] {
            let want = reference_saturation(&luma, wt, &info, (w, h), &levels, (0.3, 0.98));
            if w * h > 100 {
                let nonzero = want.saturated > 0.0 && want.texture_weight > 0.0;
                assert!(
                    nonzero && want.bands.iter().take(3).all(|&b| b > 0.0),
                    "{want:?}"
                );
            }
            for isa in Isa::available() {
                let got = saturation_sums(isa, &luma, wt, &info, w, h, &levels, 0.3, 0.98);
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-5 * b.abs().max(1.0);
                let what = format!("{isa:?} {w}×{h} weighted={}", wt.is_some());
                assert!(
                    close(got.saturated, want.saturated),
                    "{what}: {got:?} vs {want:?}"
                );
                assert!(
                    close(got.texture_weight, want.texture_weight),
                    "{what}: {got:?}"
                );
                assert!(
                    close(got.texture_info, want.texture_info),
                    "{what}: {got:?}"
                );
                assert_eq!(got.bands.len(), levels.len(), "{what}");
                for (g, r) in got.bands.iter().zip(&want.bands) {
                    assert!(
                        close(*g, *r),
                        "{what}: bands {:?} vs {:?}",
                        got.bands,
                        want.bands
                    );
                }
            }
        }
    }
}

#[test]
fn counted_spans_bound_the_weights_above_zero() {
    let mut wt = vec![0.0f32; 70];
    assert_eq!(sobel::counted_span(&wt), (0, 0));
    wt[69] = 0.5;
    // Only in the tail past the whole vectors: from the tail's start.
    assert_eq!(sobel::counted_span(&wt), (64, 70));
    wt[20] = 1.0;
    assert_eq!(sobel::counted_span(&wt), (16, 70));
    wt[69] = 0.0;
    wt[37] = 1.0;
    assert_eq!(sobel::counted_span(&wt), (16, 38));
    wt[0] = 1.0;
    assert_eq!(sobel::counted_span(&wt), (0, 38));
    assert_eq!(sobel::counted_span(&[]), (0, 0));
}

#[test]
fn rows_and_columns_a_mask_leaves_out_are_not_scored() {
    // A mask like a ground region: rows without a counted pixel above, a
    // span in the middle of each row below it, one row counting a lone
    // pixel past the last whole vector.
    for (w, h) in [(150usize, 40usize), (37, 12)] {
        let img = textured(w, h, 5);
        let binary: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let inside = y > h / 3 && x > 2 + y % 5 && x < w - 3 - y % 7;
                f32::from(inside || (y == 2 && x == w - 2))
            })
            .collect();
        let fraction: Vec<f32> = binary
            .iter()
            .enumerate()
            .map(|(i, &b)| b * (0.25 + (i % 4) as f32 / 4.0))
            .collect();
        let p = Params::new(1000.0, 0.06, SOBEL_NORM);
        for wt in [binary.as_slice(), fraction.as_slice()] {
            let want = reference(&img, w, h, Some(wt), 1000.0);
            for isa in Isa::available() {
                let src = Source::Scale { luma: &img, s: 1.3 };
                let scaled: Vec<f32> = img.iter().map(|v| (v * 1.3).min(1.0)).collect();
                let want_scaled = reference(&scaled, w, h, Some(wt), 1000.0);
                let mut rows = Rows::default();
                let got = sum_ln_q(isa, src, w, h, Some(wt), p, &mut rows);
                assert!(
                    (got - want_scaled).abs() <= 1e-5 * want_scaled,
                    "{isa:?} {w}×{h}: {got} vs {want_scaled}"
                );
                let got = sum_ln_q(isa, Source::Plain(&img), w, h, Some(wt), p, &mut rows);
                assert!(
                    (got - want).abs() <= 1e-5 * want,
                    "{isa:?}: {got} vs {want}"
                );
                let mut map = Vec::new();
                let (sum, _) = information(
                    isa,
                    &img,
                    None,
                    w,
                    h,
                    Some(wt),
                    p,
                    &mut rows,
                    Some(&mut map),
                );
                assert!(
                    (sum - want).abs() <= 1e-5 * want,
                    "{isa:?} map sum {sum} vs {want}"
                );
                // Each pixel's value where it counts, 0 elsewhere.
                for y in 1..h - 1 {
                    for x in 1..w - 1 {
                        let i = y * w + x;
                        let v = f64::from(wt[i]) * reference_ln_q(&img, w, x, y, 1000.0);
                        assert!(
                            (f64::from(map[i]) - v).abs() <= 1e-4 * v.max(1.0),
                            "{isa:?} ({x}, {y}): {} vs {v}",
                            map[i]
                        );
                    }
                }
            }
        }
    }
}
