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
                Error::invalid(
                    "region",
                    "rectangle",
                    format!("inside the canvas of {:?}", view.size()),
                    format_args!("{rect:?}"),
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
            return Err(Error::invalid(
                view.what(),
                "display gains",
                format!("one for each of {n} cameras"),
                gains.len(),
            ));
        }
        self.gains.clear();
        for (k, &g) in gains.iter().enumerate() {
            let fixed = (f64::from(g) * f64::from(UNIT_GAIN)).round();
            if !(f64::from(MIN_GAIN)..=f64::from(MAX_GAIN)).contains(&fixed) {
                return Err(view.camera_error(
                    k,
                    Error::invalid("display", "gain", "a finite gain from 1/16 to 16", g),
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
mod tests;
