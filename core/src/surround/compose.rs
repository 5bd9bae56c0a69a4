//! Per-frame composition of the surround view: each frame as the 8-bit
//! pixels the plan reads (Mono12 and Mono16 scaled to 8 bits, mono and RGB
//! converted to the canvas's channels, a Bayer mosaic as it is: the remap
//! demosaics it), then one pass of the plan.

use super::remap::{Cfa, Image, Plan};
use super::{BlendMode, SurroundView};
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
        view: &SurroundView,
        frames: &[FrameView<'_>],
        mode: BlendMode,
        out: &mut Canvas,
    ) -> Result<()> {
        let (w, h) = view.size();
        let ch = out.channels;
        check_channels(ch)?;
        view.check_frames(frames)?;
        out.width = w;
        out.height = h;
        out.data.resize(w * h * ch, 0);
        let cameras: Vec<usize> = (0..frames.len()).collect();
        self.buffers
            .execute(view, view.plan(mode), &cameras, frames, ch, &mut out.data)
    }

    /// Camera `k`'s warped image alone on a canvas (mono, 1 channel),
    /// wherever the camera sees its side of the ground (overlaps included);
    /// elsewhere 0. For checking a calibration camera by camera.
    pub fn warp_camera(
        &mut self,
        view: &SurroundView,
        k: usize,
        frame: &FrameView<'_>,
    ) -> Result<Canvas> {
        let count = view.layers().len();
        let plan = view
            .camera_plan(k)
            .ok_or(Error::CameraIndex { index: k, count })?;
        view.layers()[k]
            .check_frame(frame)
            .map_err(|e| view.camera_error(k, e))?;
        let (w, h) = view.size();
        let mut out = Canvas::new(w, h, 1);
        self.buffers.execute(
            view,
            &plan,
            &[k],
            std::slice::from_ref(frame),
            1,
            &mut out.data,
        )?;
        Ok(out)
    }
}

impl Buffers {
    /// Composes `frames` (the sources of `plan`, rig cameras `cameras`)
    /// into `out` (`ch` channels).
    fn execute(
        &mut self,
        view: &SurroundView,
        plan: &Plan,
        cameras: &[usize],
        frames: &[FrameView<'_>],
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
            let (how, src) = prepare(
                frame,
                kernel_ch,
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
        if kernel_ch == ch {
            return plan.execute(&images, ch, out);
        }
        self.colour.resize(3 * out.len(), 0);
        plan.execute(&images, 3, &mut self.colour)?;
        rgb8_to_mono8(&self.colour, out)
    }
}

/// Makes `frame` what the plan reads on a canvas of `ch` channels: where
/// its 8-bit pixels are (its own packed buffer, or converted into
/// `scratch` or `converted`) and, for a mosaic, its colour order.
fn prepare(
    frame: &FrameView<'_>,
    ch: usize,
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
        PixelFormat::Mono12 | PixelFormat::Mono16 => {
            // The top 8 bits.
            let shift = if format == PixelFormat::Mono12 { 4 } else { 8 };
            scratch.clear();
            for y in 0..frame.height() {
                scratch.extend(
                    frame
                        .row(y)
                        .chunks_exact(2)
                        .map(|b| (u16::from_le_bytes([b[0], b[1]]) >> shift).min(255) as u8),
                );
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
    use PixelFormat::{BayerBg8, BayerGb8, BayerGr8, BayerRg8, Mono12, Mono8, Rgb8};

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
        ch: usize,
    ) -> Vec<u8> {
        let mut canvas = Canvas::new(0, 0, ch);
        composer.compose(view, frames, mode, &mut canvas).unwrap();
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
            let colour = compose(&mut composer, &view, &frames, BlendMode::Seams, 3);
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
                let colour = compose(&mut composer, &view, &frames, mode, 3);
                assert!(colour == compose(&mut composer, &view, &strided, mode, 3));
                let grey = compose(&mut composer, &view, &frames, mode, 1);
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
        let colour = compose(&mut composer, &view, &frames, BlendMode::Seams, 3);
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
        let grey = compose(&mut composer, &view, &frames, BlendMode::Linear, 1);
        let mut want = vec![0; grey.len()];
        let linear = compose(&mut composer, &view, &frames, BlendMode::Linear, 3);
        rgb8_to_mono8(&linear, &mut want).unwrap();
        assert!(grey == want);
    }

    #[test]
    fn errors_name_the_camera_and_the_cause() {
        let view = small_view(SIZE.0 as u32, SIZE.1 as u32);
        let data = random(SIZE.0 * SIZE.1 * 3, 5);
        let mut frames = views(&data, Rgb8);
        let mut composer = Composer::new();
        let mut canvas = Canvas::new(0, 0, 3);
        let e = |r: Result<()>| r.unwrap_err().to_string();
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
