use rand::{Rng, SeedableRng};

use super::*;
use crate::surround::tests::small_view;
use crate::surround::SurroundView;
use PixelFormat::{BayerBg8, BayerGb8, BayerGr8, BayerRg8, Mono12, Mono16, Mono8, Rgb8};

const BAYER: [PixelFormat; 4] = [BayerRg8, BayerGr8, BayerGb8, BayerBg8];
/// The small view's source size.
const SIZE: (usize, usize) = (160, 120);

/// The Bayer mosaic (`format`) of a packed RGB image `w` pixels wide.
fn mosaic(rgb: &[u8], w: usize, format: PixelFormat) -> Vec<u8> {
    let order = Cfa::of(format).map_or(0, Cfa::code);
    rgb.chunks_exact(3)
        .enumerate()
        .map(|(i, p)| {
            let site = order ^ ((i % w) & 1) as u8 ^ (((i / w) & 1) as u8) << 1;
            p[[0, 1, 1, 2][usize::from(site)]]
        })
        .collect()
}

/// Four random frames of `bytes` bytes.
fn random(bytes: usize, seed: u64) -> Vec<Vec<u8>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..4)
        .map(|_| (0..bytes).map(|_| rng.gen::<u8>()).collect())
        .collect()
}

fn views(data: &[Vec<u8>], format: PixelFormat) -> Vec<FrameView<'_>> {
    data.iter()
        .map(|d| FrameView::new(format, SIZE.0, SIZE.1, d).unwrap())
        .collect()
}

fn compose(
    composer: &mut Composer,
    view: &SurroundView,
    frames: &[FrameView<'_>],
    mode: BlendMode,
    gains: Option<&[f32]>,
    ch: usize,
) -> Vec<u8> {
    let mut canvas = Canvas::new(0, 0, ch);
    composer
        .compose_with_gains(view, frames, mode, gains, &mut canvas)
        .unwrap();
    canvas.data
}

#[test]
fn every_bayer_order_shows_its_colours() {
    // Each camera sees one colour; seams mode takes each canvas pixel
    // from one camera, whose colour a bilinear demosaic of a uniform
    // mosaic reproduces exactly.
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let colours = [
        [200u8, 100, 30],
        [20, 220, 90],
        [60, 40, 250],
        [255, 0, 128],
    ];
    let (w, h) = view.size();
    let owner = |i: usize| {
        view.layers().iter().position(|l| {
            let [c0, r0, rw, rh] = l.roi;
            let (c, r) = (i % w, i / w);
            c >= c0
                && r >= r0
                && c < c0 + rw
                && r < r0 + rh
                && l.weights[2][(r - r0) * rw + c - c0] == 256
        })
    };
    let mut composer = Composer::new();
    for format in BAYER {
        let data: Vec<Vec<u8>> = colours
            .iter()
            .map(|c| mosaic(&c.repeat(SIZE.0 * SIZE.1), SIZE.0, format))
            .collect();
        let frames = views(&data, format);
        let colour = compose(&mut composer, &view, &frames, BlendMode::Seams, None, 3);
        let mut shown = 0;
        for (i, px) in colour.chunks_exact(3).enumerate() {
            let want = owner(i).map_or([0; 3], |k| colours[k]);
            assert_eq!(px, want, "{format:?}, canvas pixel {i}");
            shown += usize::from(owner(i).is_some());
        }
        assert!(shown > w * h / 2, "{shown}");
        // Camera by camera: the grey of its colour.
        for (k, c) in colours.iter().enumerate() {
            let warped = composer.warp_camera(&view, k, &frames[k]).unwrap();
            let mut grey = [0u8];
            rgb8_to_mono8(c, &mut grey).unwrap();
            assert!(warped.data.iter().all(|&v| v == 0 || v == grey[0]));
            assert!(warped.data.contains(&grey[0]));
        }
    }
}

#[test]
fn mosaics_compose_alike_from_a_strided_buffer_and_in_grey() {
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let rgb = random(SIZE.0 * SIZE.1 * 3, 11);
    let mut composer = Composer::new();
    for format in BAYER {
        let data: Vec<Vec<u8>> = rgb.iter().map(|f| mosaic(f, SIZE.0, format)).collect();
        let frames = views(&data, format);
        // The same rows 7 bytes apart more.
        let stride = SIZE.0 + 7;
        let padded: Vec<Vec<u8>> = data
            .iter()
            .map(|d| {
                d.chunks_exact(SIZE.0)
                    .flat_map(|row| row.iter().copied().chain([0x33; 7]))
                    .collect()
            })
            .collect();
        let strided: Vec<FrameView<'_>> = padded
            .iter()
            .map(|d| FrameView::with_stride(format, SIZE.0, SIZE.1, stride, d).unwrap())
            .collect();
        for mode in BlendMode::ALL {
            let colour = compose(&mut composer, &view, &frames, mode, None, 3);
            assert!(colour == compose(&mut composer, &view, &strided, mode, None, 3));
            let grey = compose(&mut composer, &view, &frames, mode, None, 1);
            let mut want = vec![0; grey.len()];
            rgb8_to_mono8(&colour, &mut want).unwrap();
            assert!(grey == want, "{format:?}, {}", mode.name());
        }
    }
}

#[test]
fn cameras_of_different_formats_compose_together() {
    // Uniform frames, one format per camera: in seams mode each pixel
    // is its camera's value, on a colour canvas and a mono one.
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let n = SIZE.0 * SIZE.1;
    let data = [
        mosaic(&[200, 100, 30].repeat(n), SIZE.0, BayerGb8),
        [20u8, 220, 90].repeat(n),
        vec![50; n],
        2000u16.to_le_bytes().repeat(n),
    ];
    let formats = [BayerGb8, Rgb8, Mono8, Mono12];
    let frames: Vec<FrameView<'_>> = data
        .iter()
        .zip(formats)
        .map(|(d, f)| FrameView::new(f, SIZE.0, SIZE.1, d).unwrap())
        .collect();
    let colours = [
        [200u8, 100, 30],
        [20, 220, 90],
        [50; 3],
        [(2000 >> 4) as u8; 3],
    ];
    let mut composer = Composer::new();
    let colour = compose(&mut composer, &view, &frames, BlendMode::Seams, None, 3);
    let mut found = [false; 4];
    for px in colour.chunks_exact(3) {
        if px == [0; 3] {
            continue;
        }
        let k = colours.iter().position(|c| c == px);
        assert!(k.is_some(), "{px:?}");
        found[k.unwrap_or(0)] = true;
    }
    assert_eq!(found, [true; 4]);
    let grey = compose(&mut composer, &view, &frames, BlendMode::Linear, None, 1);
    let mut want = vec![0; grey.len()];
    let linear = compose(&mut composer, &view, &frames, BlendMode::Linear, None, 3);
    rgb8_to_mono8(&linear, &mut want).unwrap();
    assert!(grey == want);
}

#[test]
fn a_wide_mosaic_composes_as_the_8_bit_mosaic_of_its_top_bits() {
    // The 12- and 16-bit mosaics are demosaiced by the remap as the
    // 8-bit mosaic of their top 8 bits, with or without gains.
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let mut composer = Composer::new();
    let n = SIZE.0 * SIZE.1;
    for (bits, format) in [(16, PixelFormat::BayerGb16), (12, PixelFormat::BayerRg12)] {
        let wide: Vec<Vec<u8>> = random(2 * n, 9)
            .into_iter()
            .map(|d| {
                d.chunks_exact(2)
                    .flat_map(|b| (u16::from_le_bytes([b[0], b[1]]) >> (16 - bits)).to_le_bytes())
                    .collect()
            })
            .collect();
        let narrow: Vec<Vec<u8>> = wide
            .iter()
            .map(|d| {
                d.chunks_exact(2)
                    .map(|b| (u16::from_le_bytes([b[0], b[1]]) >> (bits - 8)) as u8)
                    .collect()
            })
            .collect();
        let (wf, nf) = (views(&wide, format), views(&narrow, format.to_8bit()));
        for ch in [1, 3] {
            let a = compose(&mut composer, &view, &wf, BlendMode::Linear, None, ch);
            let b = compose(&mut composer, &view, &nf, BlendMode::Linear, None, ch);
            assert!(a == b, "{format:?}, {ch} channels");
            // A gain of 2 on the wide frames: the top bits of twice the
            // value, saturated, as the 8-bit mosaic of those.
            let gains = [2.0f32; 4];
            let a = compose(
                &mut composer,
                &view,
                &wf,
                BlendMode::Linear,
                Some(&gains),
                ch,
            );
            let doubled: Vec<Vec<u8>> = wide
                .iter()
                .map(|d| {
                    d.chunks_exact(2)
                        .map(|b| {
                            ((u32::from(u16::from_le_bytes([b[0], b[1]])) * 2) >> (bits - 8))
                                .min(255) as u8
                        })
                        .collect()
                })
                .collect();
            let b = compose(
                &mut composer,
                &view,
                &views(&doubled, format.to_8bit()),
                BlendMode::Linear,
                None,
                ch,
            );
            assert!(a == b, "{format:?}, {ch} channels, gain 2");
            assert!(a.iter().any(|&v| v > 0));
        }
    }
}

/// Frames of every format the composer takes, random, one set each.
fn every_format() -> Vec<(PixelFormat, Vec<Vec<u8>>)> {
    let n = SIZE.0 * SIZE.1;
    let rgb = random(3 * n, 4);
    vec![
        (Mono8, random(n, 1)),
        (
            Mono12,
            random(2 * n, 2)
                .into_iter()
                .map(|d| {
                    d.chunks_exact(2)
                        .flat_map(|b| (u16::from_le_bytes([b[0], b[1]]) & 0x0fff).to_le_bytes())
                        .collect()
                })
                .collect(),
        ),
        (Mono16, random(2 * n, 3)),
        (Rgb8, rgb.clone()),
        (
            BayerRg8,
            rgb.iter().map(|f| mosaic(f, SIZE.0, BayerRg8)).collect(),
        ),
        (
            BayerBg8,
            rgb.iter().map(|f| mosaic(f, SIZE.0, BayerBg8)).collect(),
        ),
    ]
}

#[test]
fn gains_of_one_compose_the_same_bytes_in_every_format() {
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let mut composer = Composer::new();
    for (format, data) in every_format() {
        let frames = views(&data, format);
        for ch in [1, 3] {
            for mode in [BlendMode::Linear, BlendMode::Seams] {
                let plain = compose(&mut composer, &view, &frames, mode, None, ch);
                for gains in [[1.0f32; 4], [1.0, 1.001, 0.999, 1.0]] {
                    let gained = compose(&mut composer, &view, &frames, mode, Some(&gains), ch);
                    assert!(plain == gained, "{format:?}, {ch} channels, {gains:?}");
                }
            }
        }
    }
}

#[test]
fn a_gain_scales_each_format_before_the_blend_and_saturates() {
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let mut composer = Composer::new();
    for (format, data) in every_format() {
        let frames = views(&data, format);
        for ch in [1, 3] {
            let plain = compose(&mut composer, &view, &frames, BlendMode::Linear, None, ch);
            for g in [0.5f32, 1.5, 16.0] {
                let gained = compose(
                    &mut composer,
                    &view,
                    &frames,
                    BlendMode::Linear,
                    Some(&[g; 4]),
                    ch,
                );
                if matches!(format, Mono12 | Mono16) {
                    // At the frame's precision: the composition of
                    // min(255, ⌊g·v / 2^s⌋).
                    let s = if format == Mono12 { 4 } else { 8 };
                    let scaled: Vec<Vec<u8>> = data
                        .iter()
                        .map(|d| {
                            d.chunks_exact(2)
                                .map(|b| {
                                    let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
                                    (f64::from(g) * v / f64::from(1 << s)).floor().min(255.0) as u8
                                })
                                .collect()
                        })
                        .collect();
                    let want = compose(
                        &mut composer,
                        &view,
                        &views(&scaled, Mono8),
                        BlendMode::Linear,
                        None,
                        ch,
                    );
                    assert!(gained == want, "{format:?}, gain {g}");
                    continue;
                }
                if format.is_bayer() && ch == 1 {
                    // The grey of the gained colour canvas (whose
                    // channels saturate each on its own).
                    let colour = compose(
                        &mut composer,
                        &view,
                        &frames,
                        BlendMode::Linear,
                        Some(&[g; 4]),
                        3,
                    );
                    let mut want = vec![0; gained.len()];
                    rgb8_to_mono8(&colour, &mut want).unwrap();
                    assert!(gained == want, "{format:?}, gain {g}");
                    continue;
                }
                // One gain everywhere scales the unrounded blend: within
                // one level of g times the ungained bytes while the
                // gain does not magnify their rounding beyond ½.
                let worst = gained
                    .iter()
                    .zip(&plain)
                    .map(|(&a, &v)| {
                        let want = (f64::from(g) * f64::from(v)).round().min(255.0);
                        (f64::from(a) - want).abs()
                    })
                    .fold(0.0, f64::max);
                let bound = if g <= 1.5 {
                    1.0
                } else {
                    0.5 + f64::from(g) / 2.0
                };
                assert!(
                    worst <= bound,
                    "{format:?}, {ch} channels, gain {g}: {worst}"
                );
                if g >= 16.0 {
                    // Saturated at white wherever the ungained value
                    // is at least 16.5.
                    assert!(gained.iter().zip(&plain).all(|(&a, &v)| v < 17 || a == 255));
                }
            }
        }
    }
}

#[test]
fn errors_name_the_camera_and_the_cause() {
    let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
    let data = random(SIZE.0 * SIZE.1 * 3, 5);
    let mut frames = views(&data, Rgb8);
    let mut composer = Composer::new();
    let mut canvas = Canvas::new(0, 0, 3);
    let e = |r: Result<()>| r.unwrap_err().to_string();
    for (gains, cause) in [
        (
            vec![1.0, f32::NAN, 1.0, 1.0],
            "camera 1 (\"left\"): display: gain: expected a finite gain from 1/16 to 16, found NaN",
        ),
        (
            vec![1.0, 1.0, 17.0, 1.0],
            "camera 2 (\"back\"): display: gain: expected a finite gain from 1/16 to 16, found 17",
        ),
        (
            vec![1.0, 1.0, 1.0, 0.01],
            "camera 3 (\"right\"): display: gain: expected a finite gain from 1/16 to 16, found 0.01",
        ),
        (vec![1.0; 3], "display gains: expected one for each of 4 cameras, found 3"),
    ] {
        let msg = e(composer.compose_with_gains(
            &view,
            &frames,
            BlendMode::Linear,
            Some(&gains),
            &mut canvas,
        ));
        assert!(msg.contains(cause), "{msg}");
    }
    // A frame of another size than its camera's calibration.
    let small = vec![0u8; 158 * 120 * 3];
    frames[2] = FrameView::new(Rgb8, 158, 120, &small).unwrap();
    let msg = e(composer.compose(&view, &frames, BlendMode::Linear, &mut canvas));
    assert!(
        msg.contains("camera 2 (\"back\")") && msg.contains("expected 160×120, got 158×120"),
        "{msg}"
    );
    let msg = composer
        .warp_camera(&view, 2, &frames[2])
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("camera 2 (\"back\")") && msg.contains("158×120"),
        "{msg}"
    );
}
