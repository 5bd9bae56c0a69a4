use rand::{Rng, SeedableRng};

use super::plan::bilinear;
use super::*;
use crate::cpu::Isa;

#[test]
fn rounding_to_a_total_keeps_the_total_where_rounding_each_misses_it() {
    // Two halves: each rounded on its own gives 129 + 128 = 257.
    let halves = [128.5f64, 127.5];
    let each: u32 = halves.iter().map(|v| v.round() as u32).sum();
    assert_eq!(each, 257);
    let mut out = [0u32; 2];
    round_to_total(&halves, 256, &mut out);
    assert_eq!(out.iter().sum::<u32>(), 256);
    assert!(out
        .iter()
        .zip(halves)
        .all(|(&o, v)| (f64::from(o) - v).abs() < 1.0));
    // Three thirds: each rounded gives 255.
    let thirds = [256.0f64 / 3.0; 3];
    let each: u32 = thirds.iter().map(|v| v.round() as u32).sum();
    assert_eq!(each, 255);
    let mut out = [0u32; 3];
    round_to_total(&thirds, 256, &mut out);
    assert_eq!(out, [86, 85, 85]);
    // Random splits of 4096 into up to 12 parts: the total, and each
    // within 1 of its value.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    for _ in 0..2000 {
        let n = rng.gen_range(1..=12);
        let raw: Vec<f64> = (0..n).map(|_| rng.gen::<f64>()).collect();
        let sum: f64 = raw.iter().sum();
        let values: Vec<f64> = raw.iter().map(|v| v / sum * 4096.0).collect();
        let mut out = vec![0u32; n];
        round_to_total(&values, 4096, &mut out);
        assert_eq!(out.iter().sum::<u32>(), 4096, "{values:?} → {out:?}");
        for (&o, &v) in out.iter().zip(&values) {
            assert!((f64::from(o) - v).abs() < 1.0, "{v} → {o}");
        }
    }
}

#[test]
fn the_bilinear_neighbourhood_stays_inside_the_image() {
    let same = |a: [f64; 4], b: [f64; 4]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
    let (w, h) = (7, 5);
    // The last pixel: the neighbourhood to its upper left, all weight on
    // its bottom-right pixel.
    let (i, b) = bilinear(6.0, 4.0, w, h);
    assert_eq!(i as usize, 3 * w + 5);
    assert!(same(b, [0.0, 0.0, 0.0, 1.0]), "{b:?}");
    let (i, b) = bilinear(0.0, 0.0, w, h);
    assert_eq!(i, 0);
    assert!(same(b, [1.0, 0.0, 0.0, 0.0]), "{b:?}");
    let (i, b) = bilinear(2.25, 1.5, w, h);
    assert_eq!(i as usize, w + 2);
    assert!(same(b, [0.375, 0.125, 0.375, 0.125]), "{b:?}");
}

/// Random images and a random plan over them: per canvas pixel, 0 to 3
/// cameras at random positions (a share `edge` of the coordinates on the
/// last column or row) with random blend weights.
struct Case {
    sources: Vec<(usize, usize)>,
    /// Per camera, its mosaic's colour order, or `None` for pixels of
    /// the case's channels.
    cfa: Vec<Option<Cfa>>,
    frames: Vec<Vec<u8>>,
    pixels: Vec<Vec<Contribution>>,
}

impl Case {
    fn new(seed: u64, ch: usize) -> Self {
        Self::with(
            seed,
            ch,
            vec![(37, 23), (2, 2), (64, 9)],
            vec![None; 3],
            0.2,
        )
    }

    fn with(
        seed: u64,
        ch: usize,
        sources: Vec<(usize, usize)>,
        cfa: Vec<Option<Cfa>>,
        edge: f64,
    ) -> Self {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let frames = sources
            .iter()
            .zip(&cfa)
            .map(|(&(w, h), c)| {
                let bpp = if c.is_some() { 1 } else { ch };
                (0..w * h * bpp).map(|_| rng.gen::<u8>()).collect()
            })
            .collect();
        // The same cameras for stretches of 1 to 40 pixels, so that
        // the vector kernels see whole steps and ends of runs.
        let mut cams: Vec<u32> = Vec::new();
        let mut left = 0;
        let pixels = (0..61 * 17)
            .map(|_| {
                if left == 0 {
                    left = rng.gen_range(1..=40);
                    let n = rng.gen_range(0..=3usize);
                    let mut all: Vec<u32> = (0..3).collect();
                    all.sort_by_key(|_| rng.gen::<u32>());
                    cams = all.into_iter().take(n).collect();
                    cams.sort_unstable();
                }
                left -= 1;
                cams.iter()
                    .copied()
                    .map(|camera| {
                        let (w, h) = sources[camera as usize];
                        let mut pos = |len: usize| {
                            if rng.gen_bool(edge) {
                                (len - 1) as f32
                            } else {
                                rng.gen_range(0.0..(len - 1) as f32)
                            }
                        };
                        Contribution {
                            camera,
                            at: [pos(w), pos(h)],
                            weight: f64::from(rng.gen_range(1..=256u16)),
                        }
                    })
                    .collect()
            })
            .collect();
        Self {
            sources,
            cfa,
            frames,
            pixels,
        }
    }

    fn plan(&self) -> Plan {
        Plan::build(61, self.pixels.len(), self.sources.clone(), |i, list| {
            list.extend_from_slice(&self.pixels[i]);
        })
    }

    fn images(&self) -> Vec<Image<'_>> {
        self.frames
            .iter()
            .zip(&self.sources)
            .zip(&self.cfa)
            .map(|((bytes, &(width, height)), &cfa)| Image {
                bytes,
                width,
                height,
                cfa,
            })
            .collect()
    }

    /// The exact value of channel `c` of canvas pixel `i`.
    fn exact(&self, i: usize, c: usize, ch: usize) -> f64 {
        let list = &self.pixels[i];
        let total: f64 = list.iter().map(|p| p.weight).sum();
        list.iter()
            .map(|p| {
                let (w, h) = self.sources[p.camera as usize];
                let f = &self.frames[p.camera as usize];
                let (x, y) = (f64::from(p.at[0]), f64::from(p.at[1]));
                let (x0, y0) = (x.floor() as usize, y.floor() as usize);
                let (fx, fy) = (x - x0 as f64, y - y0 as f64);
                let px = |xx: usize, yy: usize| {
                    f64::from(f[(yy.min(h - 1) * w + xx.min(w - 1)) * ch + c])
                };
                let v = (1.0 - fy) * ((1.0 - fx) * px(x0, y0) + fx * px(x0 + 1, y0))
                    + fy * ((1.0 - fx) * px(x0, y0 + 1) + fx * px(x0 + 1, y0 + 1));
                v * p.weight / total
            })
            .sum()
    }
}

#[test]
fn the_remap_is_within_a_level_of_the_exact_bilinear_blend_with_every_kernel() {
    for ch in [1, 3] {
        let case = Case::new(7 + ch as u64, ch);
        let plan = case.plan();
        assert!(plan.gather_ok, "the plan's invariant");
        let (one, several, taps) = plan.counts();
        assert!(one > 100 && several > 300, "{one} {several}");
        // Runs of 1, 2 and 3 cameras long enough for whole vector
        // steps and their ends.
        for n in 1..=3 {
            assert!(
                plan.runs.iter().any(|r| r.n == n && r.len >= 19),
                "no long run of {n} cameras"
            );
        }
        assert_eq!(taps, case.pixels.iter().map(Vec::len).sum::<usize>());
        let images = case.images();
        let mut first: Option<Vec<u8>> = None;
        for isa in Isa::available() {
            // A canvas full of garbage: every byte must be written.
            let mut out = vec![0xa5; plan.pixels * ch];
            plan.execute_with(isa, &images, ch, None, &mut out).unwrap();
            let mut worst = 0.0f64;
            for i in 0..case.pixels.len() {
                for c in 0..ch {
                    let n = case.pixels[i].len() as f64;
                    let err = (f64::from(out[i * ch + c]) - case.exact(i, c, ch)).abs();
                    // Each weight is off by less than 1/4096, which
                    // moves the value by less than 127.5/4096 per
                    // weight, and the last rounding adds ½.
                    let bound = 0.5 + 127.5 * 4.0 * n / 4096.0;
                    assert!(
                        err < bound,
                        "{isa:?}, {ch} channels, pixel {i} ({:?}), channel {c}: off by {err}",
                        case.pixels[i]
                    );
                    worst = worst.max(err);
                }
            }
            eprintln!("{isa:?}, {ch} channels: worst error {worst:.3}");
            match &first {
                None => first = Some(out),
                Some(f) => assert!(f == &out, "{isa:?} differs from the portable kernel"),
            }
        }
    }
}

#[test]
fn a_source_too_small_for_a_neighbourhood_contributes_nothing() {
    let one = Contribution {
        camera: 0,
        at: [0.0, 1.0],
        weight: 1.0,
    };
    let other = Contribution { camera: 1, ..one };
    let plan = Plan::build(2, 2, vec![(1, 5), (2, 2)], |i, list| {
        list.push(one);
        if i == 1 {
            list.push(other);
        }
    });
    // Such a plan runs the scalar kernels only.
    assert!(!plan.gather_ok);
    let (a, b) = (vec![200u8; 5], vec![10u8, 20, 30, 40]);
    let images = [
        Image {
            bytes: &a,
            width: 1,
            height: 5,
            cfa: None,
        },
        Image {
            bytes: &b,
            width: 2,
            height: 2,
            cfa: None,
        },
    ];
    let mut out = vec![0xff; 2];
    plan.execute(&images, 1, None, &mut out).unwrap();
    // Pixel 0: only the 1-pixel-wide camera, so black; pixel 1: the
    // other camera alone, at (0, 1).
    assert_eq!(out, [0, 30]);
}

#[test]
fn images_that_do_not_fit_the_plan_are_refused() {
    let case = Case::new(3, 3);
    let plan = case.plan();
    let mut images = case.images();
    let mut out = vec![0; plan.pixels * 3];
    assert!(plan.execute(&images[..2], 3, None, &mut out).is_err());
    assert!(plan.execute(&images, 2, None, &mut out).is_err());
    assert!(plan.execute(&images, 3, None, &mut out[1..]).is_err());
    images[0].bytes = &images[0].bytes[1..];
    let e = plan.execute(&images, 3, None, &mut out).unwrap_err();
    assert!(e.to_string().contains("37×23"), "{e}");
    images[0].width = 36;
    assert!(plan.execute(&images, 3, None, &mut out).is_err());
    // A mosaic: one byte a pixel, and only into an RGB canvas.
    let (_, case) = mosaic_cases().remove(0);
    let plan = case.plan();
    let mut images = case.images();
    let mut out = vec![0; plan.pixels * 3];
    assert!(plan.execute(&images, 3, None, &mut out).is_ok());
    let mut mono = vec![0; plan.pixels];
    let e = plan.execute(&images, 1, None, &mut mono).unwrap_err();
    assert!(e.to_string().contains("RGB canvas"), "{e}");
    // Gains: one per camera, from 1/16 to 16.
    for gains in [
        &[UNIT_GAIN; 2][..],
        &[UNIT_GAIN, MIN_GAIN - 1, UNIT_GAIN],
        &[MAX_GAIN + 1; 3],
    ] {
        assert!(
            plan.execute(&images, 3, Some(gains), &mut out).is_err(),
            "{gains:?}"
        );
    }
    images[2].bytes = &images[2].bytes[1..];
    let e = plan.execute(&images, 3, None, &mut out).unwrap_err();
    assert!(e.to_string().contains("64×33"), "{e}");
}

/// The four Bayer orders.
fn orders() -> [Cfa; 4] {
    use crate::image::PixelFormat::{BayerBg8, BayerGb8, BayerGr8, BayerRg8};
    [BayerRg8, BayerGr8, BayerGb8, BayerBg8].map(|f| Cfa::of(f).unwrap())
}

/// `v` (at most one pixel outside `[0, n)`) reflected into it without
/// repeating the edge.
fn reflect(v: isize, n: usize) -> usize {
    let n = n as isize;
    (if v < 0 {
        -v
    } else if v >= n {
        2 * (n - 1) - v
    } else {
        v
    }) as usize
}

/// 4× the bilinear demosaic (R, G, B) of pixel (`x`, `y`) of a `w×h`
/// mosaic of order `cfa`, written out per site: the pixel's own colour is
/// its sample, a colour it lacks the mean of its 2 or 4 nearest samples of
/// that colour; the edge reflected.
fn demosaic4(m: &[u8], (w, h): (usize, usize), cfa: Cfa, x: usize, y: usize) -> [u64; 3] {
    let at = |dx: isize, dy: isize| {
        u64::from(m[reflect(y as isize + dy, h) * w + reflect(x as isize + dx, w)])
    };
    let own = 4 * at(0, 0);
    let cross = at(-1, 0) + at(1, 0) + at(0, -1) + at(0, 1);
    let diagonal = at(-1, -1) + at(1, -1) + at(-1, 1) + at(1, 1);
    let across = 2 * (at(-1, 0) + at(1, 0));
    let down = 2 * (at(0, -1) + at(0, 1));
    match cfa.code() ^ (x & 1) as u8 ^ ((y & 1) as u8) << 1 {
        // Red: green around it, blue on the diagonals.
        0 => [own, cross, diagonal],
        // Green on a red row: red left and right, blue above and below.
        1 => [across, own, down],
        // Green on a blue row.
        2 => [down, own, across],
        _ => [diagonal, cross, own],
    }
}

impl Case {
    /// Per canvas pixel, each contributing camera and its sums per
    /// channel from the plan's taps, `4·Σ w·p` (`p` a pixel's value, or
    /// 4× its demosaic for a mosaic: scale 4·4096), computed here
    /// without the kernels.
    fn sums(&self, plan: &Plan, ch: usize) -> Vec<Vec<(u32, [u64; 3])>> {
        let mut out = vec![Vec::new(); plan.pixels];
        for run in &plan.runs {
            let (len, first) = (run.len as usize, run.taps as usize);
            let cams = &plan.cameras[run.cameras as usize..][..run.n as usize];
            for (j, &c) in cams.iter().enumerate() {
                let (w, h) = self.sources[c as usize];
                let f = &self.frames[c as usize];
                for p in 0..len {
                    let t = first + j * len + p;
                    let i = plan.index[t] as usize;
                    let wt = plan.weights[t];
                    let (x0, y0) = (i % w, i / w);
                    let mut s = [0u64; 3];
                    for (k, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
                        let weight = wt >> (16 * k) & 0xffff;
                        let v = match self.cfa[c as usize] {
                            Some(cfa) => demosaic4(f, (w, h), cfa, x0 + dx, y0 + dy),
                            None => std::array::from_fn(|ch_i| {
                                4 * u64::from(f[((y0 + dy) * w + x0 + dx) * ch + ch_i.min(ch - 1)])
                            }),
                        };
                        for (s, v) in s.iter_mut().zip(v) {
                            *s += weight * v;
                        }
                    }
                    out[run.start as usize + p].push((c, s));
                }
            }
        }
        out
    }
}

/// The canvas the kernels must give from `sums`: per channel
/// `(Σ s + 2¹³) >> 14`, or with gains (1/256)
/// `min(255, (Σ G·⌊s/4⌋ + 2¹⁹) >> 20)`.
fn expected(sums: &[Vec<(u32, [u64; 3])>], ch: usize, gains: Option<&[u16]>) -> Vec<u8> {
    let mut out = Vec::with_capacity(sums.len() * ch);
    for pixel in sums {
        for c in 0..ch {
            out.push(match gains {
                None => ((pixel.iter().map(|(_, s)| s[c]).sum::<u64>() + (1 << 13)) >> 14) as u8,
                Some(g) => {
                    let acc: u64 = pixel
                        .iter()
                        .map(|&(k, s)| (s[c] >> 2) * u64::from(g[k as usize]))
                        .sum();
                    ((acc + (1 << 19)) >> 20).min(255) as u8
                }
            });
        }
    }
    out
}

/// Mosaics of every order, alone and with an RGB camera in the same runs,
/// over images with few taps at their edge (so that the vector kernel
/// sees whole steps).
fn mosaic_cases() -> Vec<(String, Case)> {
    let [rg, gr, gb, bg] = orders().map(Some);
    let sources = vec![(37, 23), (2, 2), (64, 33)];
    [
        ("RG, GR, BG", vec![rg, gr, bg]),
        ("GB, BG, RG", vec![gb, bg, rg]),
        ("GR, RGB, GB", vec![gr, None, gb]),
    ]
    .into_iter()
    .enumerate()
    .map(|(n, (name, cfa))| {
        (
            name.to_string(),
            Case::with(20 + n as u64, 3, sources.clone(), cfa, 0.01),
        )
    })
    .collect()
}

#[test]
fn mosaics_are_demosaiced_in_the_remap_alike_by_every_kernel() {
    for (name, case) in mosaic_cases() {
        let plan = case.plan();
        assert!(plan.gather_ok);
        let images = case.images();
        let want = expected(&case.sums(&plan, 3), 3, None);
        for isa in Isa::available() {
            let mut out = vec![0xa5; plan.pixels * 3];
            plan.execute_with(isa, &images, 3, None, &mut out).unwrap();
            let differ = out.iter().zip(&want).filter(|(a, b)| a != b).count();
            let first = out.iter().zip(&want).position(|(a, b)| a != b);
            assert_eq!(
                differ,
                0,
                "{name}, {isa:?}: {differ} bytes differ, the first {first:?} ({:?})",
                first.map(|b| &case.pixels[b / 3])
            );
        }
        // Steps of 8 taps of one camera, all inside their mosaic: those
        // the vector kernel takes.
        let sites = plan.sites();
        let inside = plan
            .runs
            .iter()
            .flat_map(|r| {
                let len = r.len as usize;
                (0..r.n as usize)
                    .flat_map(move |j| (0..len / 8).map(move |s| r.taps as usize + j * len + 8 * s))
            })
            .filter(|&t| sites[t..t + 8].iter().all(|&s| s & bayer::BORDER == 0))
            .count();
        assert!(inside > 15, "{name}: {inside} steps inside the mosaics");
        // Against the exact demosaic and blend: the weights' rounding
        // and the last one.
        let mut out = vec![0; plan.pixels * 3];
        plan.execute(&images, 3, None, &mut out).unwrap();
        let mut worst = 0.0f64;
        for (i, list) in case.pixels.iter().enumerate() {
            let total: f64 = list.iter().map(|p| p.weight).sum();
            for c in 0..3 {
                let exact: f64 = list
                    .iter()
                    .map(|p| {
                        let k = p.camera as usize;
                        let (w, h) = case.sources[k];
                        let (x0, y0, b) = {
                            let (i, b) = bilinear(p.at[0], p.at[1], w, h);
                            (i as usize % w, i as usize / w, b)
                        };
                        let v: f64 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                            .iter()
                            .zip(b)
                            .map(|(&(dx, dy), b)| {
                                let px = match case.cfa[k] {
                                    Some(cfa) => {
                                        demosaic4(&case.frames[k], (w, h), cfa, x0 + dx, y0 + dy)[c]
                                            as f64
                                            / 4.0
                                    }
                                    None => {
                                        f64::from(case.frames[k][3 * ((y0 + dy) * w + x0 + dx) + c])
                                    }
                                };
                                b * px
                            })
                            .sum();
                        v * p.weight / total
                    })
                    .sum();
                let err = (f64::from(out[3 * i + c]) - exact).abs();
                let bound = 0.5 + 127.5 * 4.0 * list.len() as f64 / 4096.0;
                assert!(err < bound, "{name}: pixel {i}, channel {c}: off by {err}");
                worst = worst.max(err);
            }
        }
        eprintln!("{name}: worst error against the exact demosaic and blend {worst:.3}");
    }
}

#[test]
fn gains_scale_each_camera_before_the_blend_alike_by_every_kernel() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let mut cases = vec![
        ("mono".to_string(), 1, Case::new(7, 1)),
        ("RGB".into(), 3, Case::new(8, 3)),
    ];
    cases.extend(mosaic_cases().into_iter().map(|(n, c)| (n, 3, c)));
    for (name, ch, case) in cases {
        let plan = case.plan();
        let images = case.images();
        let sums = case.sums(&plan, ch);
        let mut plain = vec![0; plan.pixels * ch];
        plan.execute(&images, ch, None, &mut plain).unwrap();
        assert_eq!(plain, expected(&sums, ch, None), "{name}");
        // Gains of 1: the same bytes through the gained kernels.
        for isa in Isa::available() {
            let mut out = vec![0xa5; plan.pixels * ch];
            plan.execute_with(isa, &images, ch, Some(&[UNIT_GAIN; 3]), &mut out)
                .unwrap();
            assert!(
                out == plain,
                "{name}, {isa:?}: gains of 1 changed the canvas"
            );
        }
        for round in 0..4 {
            let gains: Vec<u16> = match round {
                0 => vec![MIN_GAIN, MAX_GAIN, UNIT_GAIN],
                1 => vec![MAX_GAIN; 3],
                2 => (0..3).map(|_| rng.gen_range(128..=512)).collect(),
                _ => (0..3).map(|_| rng.gen_range(MIN_GAIN..=MAX_GAIN)).collect(),
            };
            let want = expected(&sums, ch, Some(&gains));
            for isa in Isa::available() {
                let mut out = vec![0xa5; plan.pixels * ch];
                plan.execute_with(isa, &images, ch, Some(&gains), &mut out)
                    .unwrap();
                let differ = out.iter().zip(&want).filter(|(a, b)| a != b).count();
                assert_eq!(
                    differ, 0,
                    "{name}, gains {gains:?}, {isa:?}: {differ} bytes differ"
                );
            }
            // A pixel of one camera with gain g: min(255, round(g·v)) of
            // its unrounded ungained value v (the fixed-point sum); against
            // g times the ungained byte, whose rounding the gain
            // multiplies, within 1 + g/2.
            let mut worst = vec![0u8; 3];
            for (i, pixel) in sums.iter().enumerate() {
                let &[(k, s)] = pixel.as_slice() else {
                    continue;
                };
                let g = f64::from(gains[k as usize]) / 256.0;
                for c in 0..ch {
                    let v = s[c] as f64 / 16384.0;
                    let got = want[i * ch + c];
                    let exact = (g * v).min(255.0);
                    assert!(
                        (f64::from(got) - exact).abs() <= 0.5 + 1e-9,
                        "{name}: {got} for {g}·{v}"
                    );
                    let byte = f64::from(plain[i * ch + c]);
                    let d = got.abs_diff((g * byte).round().min(255.0) as u8);
                    assert!(
                        f64::from(d) <= 1.0 + g / 2.0,
                        "{name}: {got} for {g}·{byte}"
                    );
                    worst[k as usize] = worst[k as usize].max(d);
                }
            }
            eprintln!(
                "{name}, gains {:?}: largest difference from min(255, round(g·v)) of the ungained byte v, per camera: {worst:?}",
                gains.iter().map(|&g| f64::from(g) / 256.0).collect::<Vec<_>>()
            );
        }
    }
}
