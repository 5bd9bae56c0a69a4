//! Per-frame composition of the surround view.

use opencv::core::{
    Mat, MatTraitConst, MatTraitConstManual, Scalar, ToInputArray, BORDER_CONSTANT,
};
use opencv::imgproc;

use super::{BlendMode, SurroundView};
use crate::error::{Error, Result};
use crate::exposure::{FrameView, PixelFormat};

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
    acc: Vec<u16>,
    scratch: Vec<Vec<u8>>,
    converted: Vec<Mat>,
    warped: Vec<Mat>,
}

fn cv(context: &str, e: opencv::Error) -> Error {
    Error::InvalidConfig(format!("surround view: {context}: {e}"))
}

impl Composer {
    /// A composer with empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Composes `frames` (one per camera, rig order; Mono8/12/16 or RGB8)
    /// into `out`, whose `channels` (1 or 3) say mono or RGB; `out` is
    /// resized to the view's canvas.
    pub fn compose(
        &mut self,
        view: &SurroundView,
        frames: &[FrameView<'_>],
        mode: BlendMode,
        out: &mut Canvas,
    ) -> Result<()> {
        let (w, h) = view.size();
        let ch = out.channels;
        if ch != 1 && ch != 3 {
            return Err(Error::InvalidParameter {
                name: "canvas.channels",
                value: ch as f64,
                expected: "1 (mono) or 3 (RGB)",
            });
        }
        view.check_frames(frames)?;
        let layers = view.layers();
        self.scratch.resize_with(layers.len(), Vec::new);
        self.converted.resize_with(layers.len(), Mat::default);
        self.warped.resize_with(layers.len(), Mat::default);
        // Pixels no camera covers stay black; blended pixels are summed in
        // `acc`, which only they use (zeroed where they lie).
        out.width = w;
        out.height = h;
        out.data.clear();
        out.data.resize(w * h * ch, 0);
        self.acc.resize(w * h * ch, 0);
        for &(start, len) in view.blended(mode) {
            self.acc[start * ch..(start + len) * ch].fill(0);
        }
        for (k, (layer, frame)) in layers.iter().zip(frames).enumerate() {
            let (bytes, src_ch) =
                bytes_8bit(frame, &mut self.scratch[k]).map_err(Error::InvalidConfig)?;
            let flat = flat_mat(frame, bytes, src_ch)?;
            let shaped = flat
                .reshape(src_ch as i32, frame.height() as i32)
                .map_err(|e| cv("frame", e))?;
            let layer_maps = (&layer.map1, &layer.map2);
            match (src_ch, ch) {
                (3, 1) | (1, 3) => {
                    let code = if src_ch == 3 {
                        imgproc::COLOR_RGB2GRAY
                    } else {
                        imgproc::COLOR_GRAY2RGB
                    };
                    imgproc::cvt_color(&shaped, &mut self.converted[k], code, 0)
                        .map_err(|e| cv("colour conversion", e))?;
                    remap(&self.converted[k], layer_maps, &mut self.warped[k])?;
                }
                _ => remap(&shaped, layer_maps, &mut self.warped[k])?,
            }
            let [c0, r0, rw, _] = layer.roi;
            let warped = self.warped[k]
                .data_bytes()
                .map_err(|e| cv("remap output", e))?;
            let weights = &layer.weights[mode.index()];
            for span in &layer.spans[mode.index()] {
                let (rr, cc, len) = (span.row as usize, span.col as usize, span.len as usize);
                let src = &warped[(rr * rw + cc) * ch..(rr * rw + cc + len) * ch];
                let start = ((r0 + rr) * w + c0 + cc) * ch;
                if !span.blend {
                    out.data[start..start + len * ch].copy_from_slice(src);
                    continue;
                }
                let wrow = &weights[rr * rw + cc..rr * rw + cc + len];
                let dst = &mut self.acc[start..start + len * ch];
                if ch == 1 {
                    for ((d, &s), &wt) in dst.iter_mut().zip(src).zip(wrow) {
                        *d += wt * u16::from(s);
                    }
                } else {
                    let (dst, _) = dst.as_chunks_mut::<3>();
                    let (src, _) = src.as_chunks::<3>();
                    for ((d, s), &wt) in dst.iter_mut().zip(src).zip(wrow) {
                        for c in 0..3 {
                            d[c] += wt * u16::from(s[c]);
                        }
                    }
                }
            }
        }
        // The blended pixels, from their sums.
        for &(start, len) in view.blended(mode) {
            let span = start * ch..(start + len) * ch;
            for (o, &v) in out.data[span.clone()].iter_mut().zip(&self.acc[span]) {
                *o = ((u32::from(v) + 128) >> 8).min(255) as u8;
            }
        }
        Ok(())
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
        let layer = view.layers().get(k).ok_or(Error::CameraIndex {
            index: k,
            count: view.layers().len(),
        })?;
        let mut scratch = Vec::new();
        let (bytes, src_ch) = bytes_8bit(frame, &mut scratch).map_err(Error::InvalidConfig)?;
        let flat = flat_mat(frame, bytes, src_ch)?;
        let shaped = flat
            .reshape(src_ch as i32, frame.height() as i32)
            .map_err(|e| cv("frame", e))?;
        let mut mono = Mat::default();
        let mut warped = Mat::default();
        if src_ch == 3 {
            imgproc::cvt_color(&shaped, &mut mono, imgproc::COLOR_RGB2GRAY, 0)
                .map_err(|e| cv("colour conversion", e))?;
            remap(&mono, (&layer.map1, &layer.map2), &mut warped)?;
        } else {
            remap(&shaped, (&layer.map1, &layer.map2), &mut warped)?;
        }
        let bytes = warped.data_bytes().map_err(|e| cv("remap output", e))?;
        let (w, h) = view.size();
        let mut out = Canvas::new(w, h, 1);
        let [c0, r0, rw, rh] = layer.roi;
        for rr in 0..rh {
            for cc in 0..rw {
                if layer.map[rr * rw + cc][0] >= 0.0 {
                    out.data[(r0 + rr) * w + c0 + cc] = bytes[rr * rw + cc];
                }
            }
        }
        Ok(out)
    }
}

/// `bytes` (a frame's 8-bit pixels, `ch` channels) as a one-channel Mat of
/// `width·ch` columns, borrowed.
fn flat_mat<'a>(
    frame: &FrameView<'_>,
    bytes: &'a [u8],
    ch: usize,
) -> Result<opencv::boxed_ref::BoxedRef<'a, Mat>> {
    Mat::new_rows_cols_with_data(frame.height() as i32, (frame.width() * ch) as i32, bytes)
        .map_err(|e| cv("frame", e))
}

/// Bilinear remap of `src` through fixed-point maps into `dst`.
fn remap(src: &impl ToInputArray, maps: (&Mat, &Mat), dst: &mut Mat) -> Result<()> {
    imgproc::remap(
        src,
        dst,
        maps.0,
        maps.1,
        imgproc::INTER_LINEAR,
        BORDER_CONSTANT,
        Scalar::all(0.0),
    )
    .map_err(|e| cv("remap", e))
}

/// The 8-bit bytes of `frame` and their channel count: the frame's own
/// buffer where it is packed Mono8 or RGB8, else a conversion in `scratch`.
fn bytes_8bit<'a>(
    frame: &FrameView<'a>,
    scratch: &'a mut Vec<u8>,
) -> std::result::Result<(&'a [u8], usize), String> {
    let rows = |scratch: &mut Vec<u8>| {
        scratch.clear();
        for y in 0..frame.height() {
            scratch.extend_from_slice(frame.row(y));
        }
    };
    match frame.format() {
        PixelFormat::Mono8 | PixelFormat::Rgb8 => {
            let ch = if frame.format() == PixelFormat::Rgb8 { 3 } else { 1 };
            match frame.packed() {
                Some(bytes) => Ok((bytes, ch)),
                None => {
                    rows(scratch);
                    Ok((scratch.as_slice(), ch))
                }
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
            Ok((scratch.as_slice(), 1))
        }
        other => Err(format!(
            "pixel format {} is not supported by the surround view: expected Mono8, Mono12, Mono16 or RGB8",
            other.genicam_name()
        )),
    }
}
