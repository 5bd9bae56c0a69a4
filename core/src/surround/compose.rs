//! Per-frame composition of the surround view.

use super::remap::Image;
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
#[derive(Debug, Default)]
pub struct Composer {
    /// Per camera, frames converted to packed 8 bits.
    scratch: Vec<Vec<u8>>,
    /// Per camera, frames converted between mono and RGB.
    converted: Vec<Vec<u8>>,
}

/// Where a camera's 8-bit pixels with the canvas's channel count are.
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

    /// Composes `frames` (one per camera, rig order; Mono8/12/16 or RGB8)
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
        let images = self.images(frames, ch)?;
        out.width = w;
        out.height = h;
        out.data.resize(w * h * ch, 0);
        view.plan(mode).execute(&images, ch, &mut out.data)
    }

    /// Each frame as packed 8-bit pixels of `ch` channels, converted into
    /// the composer's buffers where it is not that already.
    fn images<'s>(&'s mut self, frames: &[FrameView<'s>], ch: usize) -> Result<Vec<Image<'s>>> {
        let n = frames.len();
        self.scratch.resize_with(n, Vec::new);
        self.converted.resize_with(n, Vec::new);
        let mut prepared = Vec::with_capacity(n);
        for ((frame, scratch), converted) in frames
            .iter()
            .zip(&mut self.scratch)
            .zip(&mut self.converted)
        {
            let (in_scratch, src_ch) = bytes_8bit(frame, scratch).map_err(Error::InvalidConfig)?;
            if src_ch == ch {
                prepared.push(if in_scratch {
                    Prepared::Scratch
                } else {
                    Prepared::Frame
                });
                continue;
            }
            let bytes = if in_scratch {
                scratch.as_slice()
            } else {
                frame.packed().unwrap_or_default()
            };
            let pixels = frame.width() * frame.height();
            converted.resize(pixels * ch, 0);
            if src_ch == 3 {
                rgb8_to_mono8(bytes, converted)?;
            } else {
                mono8_to_rgb8(bytes, converted)?;
            }
            prepared.push(Prepared::Converted);
        }
        let mut images = Vec::with_capacity(n);
        for (k, (frame, how)) in frames.iter().zip(prepared).enumerate() {
            let bytes = match how {
                Prepared::Frame => frame.packed().unwrap_or_default(),
                Prepared::Scratch => self.scratch[k].as_slice(),
                Prepared::Converted => self.converted[k].as_slice(),
            };
            images.push(Image {
                bytes,
                width: frame.width(),
                height: frame.height(),
            });
        }
        Ok(images)
    }
}

impl Composer {
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
        view.layers()[k].check_frame(frame)?;
        let images = self.images(std::slice::from_ref(frame), 1)?;
        let (w, h) = view.size();
        let mut out = Canvas::new(w, h, 1);
        plan.execute(&images, 1, &mut out.data)?;
        Ok(out)
    }
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

/// Where the 8-bit bytes of `frame` are (`true`: converted into `scratch`,
/// `false`: the frame's own packed buffer) and their channel count.
fn bytes_8bit(
    frame: &FrameView<'_>,
    scratch: &mut Vec<u8>,
) -> std::result::Result<(bool, usize), String> {
    let rows = |scratch: &mut Vec<u8>| {
        scratch.clear();
        for y in 0..frame.height() {
            scratch.extend_from_slice(frame.row(y));
        }
    };
    match frame.format() {
        PixelFormat::Mono8 | PixelFormat::Rgb8 => {
            let ch = if frame.format() == PixelFormat::Rgb8 { 3 } else { 1 };
            if frame.packed().is_some() {
                Ok((false, ch))
            } else {
                rows(scratch);
                Ok((true, ch))
            }
        }
        PixelFormat::Mono12 | PixelFormat::Mono16 => {
            let shift = if frame.format() == PixelFormat::Mono12 { 4 } else { 8 };
            scratch.clear();
            for y in 0..frame.height() {
                scratch.extend(
                    frame
                        .row(y)
                        .chunks_exact(2)
                        .map(|b| (u16::from_le_bytes([b[0], b[1]]) >> shift).min(255) as u8),
                );
            }
            Ok((true, 1))
        }
        other => Err(format!(
            "pixel format {} is not supported by the surround view: expected Mono8, Mono12, Mono16 or RGB8",
            other.genicam_name()
        )),
    }
}
