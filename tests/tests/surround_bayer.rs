#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Colour views straight from Bayer mosaics, against OpenCV: the frames of
//! the real rig in `tests/data/surround-nz` and of the simulated rig,
//! mosaicked here in each of the four orders, composed by rigview (which
//! demosaics inside the remap) and, as the reference, demosaiced whole by
//! OpenCV's `cvtColor` (`COLOR_Bayer*2RGB`, bilinear) and then composed
//! from RGB8 by the same composer. Run with `--nocapture` for the figures.

mod surround_common;

use opencv::core::{Mat, MatTraitConst, MatTraitConstManual};
use opencv::imgproc;
use rigview_calib::formats;
use rigview_core::exposure::{FrameView, PixelFormat};
use rigview_core::sim::{SimConfig, SimRender};
use rigview_core::surround::{BlendMode, Canvas, Composer, SurroundOptions, SurroundView};

/// Each GenICam Bayer order, OpenCV's code for it, and the channel
/// (0 R, 1 G, 2 B) of the pixels of its first two rows' first two
/// columns.
const ORDERS: [(PixelFormat, i32, [[usize; 2]; 2]); 4] = [
    (
        PixelFormat::BayerRg8,
        imgproc::COLOR_BayerRGGB2RGB,
        [[0, 1], [1, 2]],
    ),
    (
        PixelFormat::BayerGr8,
        imgproc::COLOR_BayerGRBG2RGB,
        [[1, 0], [2, 1]],
    ),
    (
        PixelFormat::BayerGb8,
        imgproc::COLOR_BayerGBRG2RGB,
        [[1, 2], [0, 1]],
    ),
    (
        PixelFormat::BayerBg8,
        imgproc::COLOR_BayerBGGR2RGB,
        [[2, 1], [1, 0]],
    ),
];

/// A packed RGB frame: width, height, pixels.
type Rgb = (usize, usize, Vec<u8>);

/// The mosaic of `rgb` whose 2×2 pattern has the channels `sites`.
fn mosaic((w, _, rgb): &Rgb, sites: [[usize; 2]; 2]) -> Vec<u8> {
    rgb.chunks_exact(3)
        .enumerate()
        .map(|(i, p)| p[sites[i / w % 2][i % w % 2]])
        .collect()
}

/// OpenCV's bilinear demosaic of a `w×h` mosaic, packed RGB.
fn opencv_demosaic(m: &[u8], w: usize, h: usize, code: i32) -> Vec<u8> {
    let src = Mat::new_rows_cols_with_data(h as i32, w as i32, m).unwrap();
    let mut dst = Mat::default();
    imgproc::cvt_color(&src, &mut dst, code, 0).unwrap();
    assert_eq!(
        (dst.cols(), dst.rows(), dst.channels()),
        (w as i32, h as i32, 3)
    );
    dst.data_bytes().unwrap().to_vec()
}

/// Per canvas pixel of blend mode `m` (index into [`BlendMode::ALL`]):
/// `None` where no camera shows it, else whether every camera it is
/// composed from takes its 2×2 neighbourhood from pixels off the image's
/// outermost ring, which OpenCV copies from the next ring instead of
/// demosaicing it (rigview reflects the mosaic there).
fn inside(view: &SurroundView, m: usize) -> Vec<Option<bool>> {
    let (w, h) = view.size();
    let mut out = vec![None; w * h];
    for layer in view.layers() {
        let [c0, r0, rw, rh] = layer.roi;
        let (sw, sh) = layer.source;
        for r in 0..rh {
            for c in 0..rw {
                let j = r * rw + c;
                if layer.weights[m][j] == 0 {
                    continue;
                }
                let [x, y] = layer.map[j];
                let x0 = (x.clamp(0.0, (sw - 1) as f32).floor() as usize).min(sw - 2);
                let y0 = (y.clamp(0.0, (sh - 1) as f32).floor() as usize).min(sh - 2);
                let ok = x0 >= 1 && x0 + 3 <= sw && y0 >= 1 && y0 + 3 <= sh;
                let o = &mut out[(r0 + r) * w + c0 + c];
                *o = Some(o.unwrap_or(true) && ok);
            }
        }
    }
    out
}

/// How far two canvases are apart: over the pixels [`inside`] the
/// image's ring, the largest difference, the mean and the share of values
/// that differ at all; and the largest difference at the ring.
#[derive(Debug, Default)]
struct Apart {
    worst: u8,
    mean: f64,
    differ: f64,
    values: usize,
    worst_ring: u8,
}

fn apart(a: &Canvas, b: &Canvas, inside: &[Option<bool>]) -> Apart {
    let mut d = Apart::default();
    let (mut sum, mut differ) = (0u64, 0usize);
    for ((pa, pb), place) in a
        .data
        .chunks_exact(3)
        .zip(b.data.chunks_exact(3))
        .zip(inside)
    {
        for (&x, &y) in pa.iter().zip(pb) {
            let diff = x.abs_diff(y);
            match place {
                Some(true) => {
                    d.worst = d.worst.max(diff);
                    sum += u64::from(diff);
                    differ += usize::from(diff > 0);
                    d.values += 1;
                }
                Some(false) => d.worst_ring = d.worst_ring.max(diff),
                None => assert_eq!((x, y), (0, 0), "a pixel no camera shows"),
            }
        }
    }
    d.mean = sum as f64 / d.values.max(1) as f64;
    d.differ = differ as f64 / d.values.max(1) as f64;
    d
}

/// Composes `frames` (RGB) of `view` mosaicked in every order, straight
/// and through OpenCV's demosaic, in linear blending and in seams mode,
/// and checks them within one level of each other off the ring.
fn against_opencv(what: &str, view: &SurroundView, frames: &[Rgb]) {
    let mut composer = Composer::new();
    for (format, code, sites) in ORDERS {
        let mosaics: Vec<Vec<u8>> = frames.iter().map(|f| mosaic(f, sites)).collect();
        let demosaiced: Vec<Vec<u8>> = mosaics
            .iter()
            .zip(frames)
            .map(|(m, (w, h, _))| opencv_demosaic(m, *w, *h, code))
            .collect();
        let bayer: Vec<FrameView<'_>> = mosaics
            .iter()
            .zip(frames)
            .map(|(m, (w, h, _))| FrameView::new(format, *w, *h, m).unwrap())
            .collect();
        let rgb: Vec<FrameView<'_>> = demosaiced
            .iter()
            .zip(frames)
            .map(|(d, (w, h, _))| FrameView::new(PixelFormat::Rgb8, *w, *h, d).unwrap())
            .collect();
        for (m, mode) in BlendMode::ALL.into_iter().enumerate() {
            if mode == BlendMode::Alpha {
                continue;
            }
            let (mut ours, mut theirs) = (Canvas::new(0, 0, 3), Canvas::new(0, 0, 3));
            composer.compose(view, &bayer, mode, &mut ours).unwrap();
            composer.compose(view, &rgb, mode, &mut theirs).unwrap();
            let d = apart(&ours, &theirs, &inside(view, m));
            println!(
                "{what}, {}, {}: against OpenCV's demosaic and the RGB remap over {} values: largest difference {}, mean {:.4}, {:.3} % differ; at the image's ring up to {}",
                format.genicam_name(),
                mode.name(),
                d.values,
                d.worst,
                d.mean,
                100.0 * d.differ,
                d.worst_ring
            );
            assert!(d.values > 100_000, "{what}: too few values compared");
            assert!(d.worst <= 1, "{what}, {format:?}, {}: {d:?}", mode.name());
            assert!(d.mean < 0.2, "{what}, {format:?}, {}: {d:?}", mode.name());
        }
    }
}

#[test]
fn mosaics_of_the_real_rig_compose_within_a_level_of_opencvs_demosaic() {
    let rig = formats::load(&surround_common::data(), None, None)
        .unwrap()
        .rig;
    let frames = surround_common::images(&rig);
    let view =
        SurroundView::build(&rig, &surround_common::spec(), &SurroundOptions::default()).unwrap();
    against_opencv("real rig", &view, &frames);
}

#[test]
fn mosaics_of_the_simulated_rig_compose_within_a_level_of_opencvs_demosaic() {
    let config = SimConfig {
        scale: 0.5,
        ..SimConfig::preset("overcast").unwrap()
    };
    let render = SimRender::new(&config).unwrap();
    // A colour scene from the grey one: red, green and blue exposed 8, 4
    // and 2 ms, without noise.
    let frames: Vec<Rgb> = render
        .cameras()
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let planes: Vec<Vec<u8>> = [8000.0, 4000.0, 2000.0]
                .iter()
                .map(|&shutter_us| surround_common::still(&render, k, shutter_us))
                .collect();
            let rgb = (0..c.width * c.height)
                .flat_map(|i| [planes[0][i], planes[1][i], planes[2][i]])
                .collect();
            (c.width, c.height, rgb)
        })
        .collect();
    let spec = surround_common::sim_spec();
    let view = SurroundView::build(render.rig(), &spec, &SurroundOptions::default()).unwrap();
    against_opencv("simulated rig", &view, &frames);
}
