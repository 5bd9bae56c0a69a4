//! Per-frame composition of a view (the surround view, the panorama): each
//! frame as the 8-bit pixels the plan reads (Mono12 and Mono16 scaled to 8
//! bits, mono and RGB converted to the canvas's channels, a Bayer mosaic as
//! it is: the remap demosaics it), then one pass of the plan.

use super::remap::{Cfa, Image, Plan, MAX_GAIN, MIN_GAIN, UNIT_GAIN};
use super::{BlendMode, Mosaic};
use crate::error::{Error, Result};
use crate::image::{mono8_to_rgb8, rgb8_to_mono8, FrameView, PixelFormat};

/// A composed canvas: 8-bit, 1 (mono) or 3 (RGB) channels, row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Canvas {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// 1 for mono, 3 for RGB.
    pub channels: usize,
    /// The pixels.
    pub data: Vec<u8>,
}

impl Canvas {
    /// A black canvas.
    pub fn new(width: usize, height: usize, channels: usize) -> Self {
        Self {
            width,
            height,
            channels,
            data: vec![0; width * height * channels],
        }
    }
}

/// Composes frame sets into canvases; holds the buffers reused from frame
/// to frame.
///
/// Every pixel format composes into either canvas: Mono8, Mono12 and
/// Mono16 (the top 8 bits), RGB8, and the Bayer mosaics BayerRG8,
/// BayerGR8, BayerGB8 and BayerBG8, which the remap demosaics as it
/// samples them (bilinear demosaicing, within one level of OpenCV's
/// `cvtColor` `COLOR_Bayer*2RGB` followed by the same remap: see
/// `remap/`). A mono canvas from Bayer frames is the grey (BT.601, as
/// [`rgb8_to_mono8`]) of the colour one.
#[derive(Debug, Default)]
pub struct Composer {
    buffers: Buffers,
    /// Per camera, the display gain in 1/256.
    gains: Vec<u16>,
}

/// The per-camera buffers of a composition.
#[derive(Debug, Default)]
struct Buffers {
    /// Per camera, frames converted to packed 8 bits.
    scratch: Vec<Vec<u8>>,
    /// Per camera, frames converted between mono and RGB.
    converted: Vec<Vec<u8>>,
    /// The colour canvas of a mono composition with Bayer frames.
    colour: Vec<u8>,
}

/// Where a camera's 8-bit pixels are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Prepared {
    /// The frame's own buffer.
    Frame,
    /// The composer's scratch buffer.
    Scratch,
    /// The composer's converted buffer.
    Converted,
}

impl Composer {
    /// A composer with empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Composes `frames` (one per camera, rig order; any [`PixelFormat`])
    /// into `out`, whose `channels` (1 or 3) say mono or RGB; `out` is
    /// resized to the view's canvas and every pixel is written.
    pub fn compose(
        &mut self,
        view: &Mosaic,
        frames: &[FrameView<'_>],
        mode: BlendMode,
        out: &mut Canvas,
    ) -> Result<()> {
        self.compose_with_gains(view, frames, mode, None, out)
    }

    /// [`Composer::compose`] with a display gain per camera (`gains`, rig
    /// order): each camera's pixels are scaled by its gain before the
    /// cameras are blended, and saturate at white.
    ///
    /// A gain is 1/16 to 16, taken in steps of 1/256 (rounded to the
    /// nearest). For 8-bit frames (Mono8, RGB8, Bayer) the remap scales
    /// each camera's bilinear sample before it is rounded: a pixel shown
    /// by one camera with gain `g` is `min(255, round(g·v))` of its
    /// unrounded ungained value `v` (so within `1 + g/2` of `g` times the
    /// ungained byte, whose rounding the gain multiplies). Mono12 and
    /// Mono16 frames, which are scaled to 8 bits in a pass of their own,
    /// take their gain in that pass, at their full precision:
    /// `min(255, ⌊g·v / 16⌋)` (Mono12) or `min(255, ⌊g·v / 256⌋)` (Mono16)
    /// of each source pixel `v`. A mono canvas from Bayer frames is the
    /// grey of the gained colour canvas.
    ///
    /// `None`, or a gain of 1 for every camera, composes as
    /// [`Composer::compose`]: the same bytes, with the same kernels.
    pub fn compose_with_gains(
        &mut self,
        view: &Mosaic,
        frames: &[FrameView<'_>],
        mode: BlendMode,
        gains: Option<&[f32]>,
        out: &mut Canvas,
    ) -> Result<()> {
        let (w, h) = view.size();
        let ch = out.channels;
        check_channels(ch)?;
        view.check_frames(frames)?;
        let gained = self.set_gains(view, gains)?;
        out.width = w;
        out.height = h;
        out.data.resize(w * h * ch, 0);
        let cameras: Vec<usize> = (0..frames.len()).collect();
        let gains = gained.then_some(self.gains.as_mut_slice());
        self.buffers.execute(
            view,
            view.plan(mode),
            &cameras,
            frames,
            gains,
            ch,
            &mut out.data,
        )
    }

    /// Camera `k`'s warped image alone on a canvas (mono, 1 channel),
    /// wherever the camera sees its part of the view (overlaps included);
    /// elsewhere 0. For checking a calibration camera by camera.
    pub fn warp_camera(
        &mut self,
        view: &Mosaic,
        k: usize,
        frame: &FrameView<'_>,
    ) -> Result<Canvas> {
        let (w, h) = view.size();
        self.warp_region(view, k, [0, 0, w, h], frame)
    }

    /// [`Composer::warp_camera`] over the canvas rectangle `rect` (column,
    /// row, width, height) only.
    pub fn warp_region(
        &mut self,
        view: &Mosaic,
        k: usize,
        rect: [usize; 4],
        frame: &FrameView<'_>,
    ) -> Result<Canvas> {
        let count = view.layers().len();
        if k >= count {
            return Err(Error::CameraIndex { index: k, count });
        }
        let plan = view.region_plan(k, rect).ok_or_else(|| {
            view.camera_error(
                k,
                format_args!(
                    "the rectangle {rect:?} leaves the canvas of {:?}",
                    view.size()
                ),
            )
        })?;
        self.warp_with_plan(view, &plan, k, frame, (rect[2], rect[3]))
    }

    /// Camera `k`'s `frame` through `plan` (one of [`Mosaic::region_plan`])
    /// onto a mono canvas of `size`.
    pub(crate) fn warp_with_plan(
        &mut self,
        view: &Mosaic,
        plan: &Plan,
        k: usize,
        frame: &FrameView<'_>,
        (w, h): (usize, usize),
    ) -> Result<Canvas> {
        let count = view.layers().len();
        view.layers()
            .get(k)
            .ok_or(Error::CameraIndex { index: k, count })?
            .check_frame(frame)
            .map_err(|e| view.camera_error(k, e))?;
        let mut out = Canvas::new(w, h, 1);
        self.buffers.execute(
            view,
            plan,
            &[k],
            std::slice::from_ref(frame),
            None,
            1,
            &mut out.data,
        )?;
        Ok(out)
    }

    /// Checks `gains` (one per camera of `view`) and keeps them in 1/256;
    /// whether any is other than 1.
    fn set_gains(&mut self, view: &Mosaic, gains: Option<&[f32]>) -> Result<bool> {
        let Some(gains) = gains else {
            return Ok(false);
        };
        let n = view.layers().len();
        if gains.len() != n {
            return Err(Error::InvalidConfig(format!(
                "{}: {} display gains for a rig of {n} cameras",
                view.what(),
                gains.len()
            )));
        }
        self.gains.clear();
        for (k, &g) in gains.iter().enumerate() {
            let fixed = (f64::from(g) * f64::from(UNIT_GAIN)).round();
            if !(f64::from(MIN_GAIN)..=f64::from(MAX_GAIN)).contains(&fixed) {
                return Err(view.camera_error(
                    k,
                    format_args!("display gain {g}: expected a finite gain from 1/16 to 16"),
                ));
            }
            self.gains.push(fixed as u16);
        }
        Ok(self.gains.iter().any(|&g| g != UNIT_GAIN))
    }
}

impl Buffers {
    /// Composes `frames` (the sources of `plan`, rig cameras `cameras`)
    /// into `out` (`ch` channels) with `gains` (per source, 1/256) when
    /// given. A Mono12 or Mono16 frame takes its gain in its conversion
    /// to 8 bits (its entry of `gains` is then set to 1).
    #[allow(clippy::too_many_arguments)]
    fn execute(
        &mut self,
        view: &Mosaic,
        plan: &Plan,
        cameras: &[usize],
        frames: &[FrameView<'_>],
        mut gains: Option<&mut [u16]>,
        ch: usize,
        out: &mut [u8],
    ) -> Result<()> {
        // A mosaic composes in colour; a mono canvas is then the grey of
        // the colour one.
        let colour = frames.iter().any(|f| f.format().is_bayer());
        let kernel_ch = if colour { 3 } else { ch };
        let n = frames.len();
        self.scratch.resize_with(n, Vec::new);
        self.converted.resize_with(n, Vec::new);
        let mut prepared = Vec::with_capacity(n);
        for (k, frame) in frames.iter().enumerate() {
            let camera = cameras.get(k).copied().unwrap_or(k);
            let gain = gains.as_deref_mut().and_then(|g| g.get_mut(k));
            let (how, src) = prepare(
                frame,
                kernel_ch,
                gain,
                &mut self.scratch[k],
                &mut self.converted[k],
            )
            .map_err(|e| view.camera_error(camera, e))?;
            prepared.push((how, src));
        }
        let mut images = Vec::with_capacity(n);
        for (k, (frame, (how, cfa))) in frames.iter().zip(prepared).enumerate() {
            let bytes = match how {
                Prepared::Frame => frame.packed().unwrap_or_default(),
                Prepared::Scratch => self.scratch[k].as_slice(),
                Prepared::Converted => self.converted[k].as_slice(),
            };
            images.push(Image {
                bytes,
                width: frame.width(),
                height: frame.height(),
                cfa,
            });
        }
        let gains = gains
            .map(|g| &*g)
            .filter(|g| g.iter().any(|&v| v != UNIT_GAIN));
        if kernel_ch == ch {
            return plan.execute(&images, ch, gains, out);
        }
        self.colour.resize(3 * out.len(), 0);
        plan.execute(&images, 3, gains, &mut self.colour)?;
        rgb8_to_mono8(&self.colour, out)
    }
}

/// Makes `frame` what the plan reads on a canvas of `ch` channels: where
/// its 8-bit pixels are (its own packed buffer, or converted into
/// `scratch` or `converted`) and, for a mosaic, its colour order. A Mono12
/// or Mono16 frame takes its `gain` in its conversion to 8 bits, which
/// sets `gain` to 1.
fn prepare(
    frame: &FrameView<'_>,
    ch: usize,
    gain: Option<&mut u16>,
    scratch: &mut Vec<u8>,
    converted: &mut Vec<u8>,
) -> Result<(Prepared, Option<Cfa>)> {
    let format = frame.format();
    let (how, src_ch) = match format {
        PixelFormat::Mono8
        | PixelFormat::Rgb8
        | PixelFormat::BayerRg8
        | PixelFormat::BayerGr8
        | PixelFormat::BayerGb8
        | PixelFormat::BayerBg8 => {
            let how = if frame.packed().is_some() {
                Prepared::Frame
            } else {
                scratch.clear();
                for y in 0..frame.height() {
                    scratch.extend_from_slice(frame.row(y));
                }
                Prepared::Scratch
            };
            (how, format.bytes_per_pixel())
        }
        _ => {
            // Mono12, Mono16 and the 12- and 16-bit mosaics: the top 8 bits
            // (rounded down), the gain applied at the frame's precision and
            // saturated at white (a mosaic stays a mosaic, demosaiced by the
            // remap as an 8-bit one).
            let shift = if format.bits() == 12 { 4 } else { 8 };
            let g = gain.map_or(UNIT_GAIN, |g| std::mem::replace(g, UNIT_GAIN));
            let g = u32::from(g);
            scratch.clear();
            for y in 0..frame.height() {
                scratch.extend(frame.row(y).chunks_exact(2).map(|b| {
                    ((u32::from(u16::from_le_bytes([b[0], b[1]])) * g) >> (shift + 8)).min(255)
                        as u8
                }));
            }
            (Prepared::Scratch, 1)
        }
    };
    if let Some(cfa) = Cfa::of(format) {
        return Ok((how, Some(cfa)));
    }
    if src_ch == ch {
        return Ok((how, None));
    }
    let bytes = match how {
        Prepared::Scratch => scratch.as_slice(),
        _ => frame.packed().unwrap_or_default(),
    };
    converted.resize(frame.width() * frame.height() * ch, 0);
    if src_ch == 3 {
        rgb8_to_mono8(bytes, converted)?;
    } else {
        mono8_to_rgb8(bytes, converted)?;
    }
    Ok((Prepared::Converted, None))
}

fn check_channels(ch: usize) -> Result<()> {
    if ch != 1 && ch != 3 {
        return Err(Error::InvalidParameter {
            name: "canvas.channels",
            value: ch as f64,
            expected: "1 (mono) or 3 (RGB)",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
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
                        .flat_map(|b| {
                            (u16::from_le_bytes([b[0], b[1]]) >> (16 - bits)).to_le_bytes()
                        })
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
                                        (f64::from(g) * v / f64::from(1 << s)).floor().min(255.0)
                                            as u8
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
                "camera 1 (\"left\"): display gain NaN",
            ),
            (
                vec![1.0, 1.0, 17.0, 1.0],
                "camera 2 (\"back\"): display gain 17",
            ),
            (
                vec![1.0, 1.0, 1.0, 0.01],
                "camera 3 (\"right\"): display gain 0.01",
            ),
            (vec![1.0; 3], "3 display gains for a rig of 4 cameras"),
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
}
