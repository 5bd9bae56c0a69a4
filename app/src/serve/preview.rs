//! Frames made small for the remote view: `n × n` pixel boxes averaged
//! into one (a Bayer mosaic's 2 × 2 cells into RGB pixels, so a mosaic is
//! shown in colour at half size or smaller), then JPEG.

use rigview_core::image::PixelFormat;
use rigview_core::source::Frame;

/// A small 8-bit picture: width, height, channels (1 or 3) and rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Small {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<u8>,
}

/// Where a Bayer mosaic's red and blue sit in its 2 × 2 cell (column,
/// row); `None` for the other formats.
fn bayer_sites(format: PixelFormat) -> Option<((usize, usize), (usize, usize))> {
    use PixelFormat::*;
    match format {
        BayerRg8 | BayerRg12 | BayerRg16 => Some(((0, 0), (1, 1))),
        BayerGr8 | BayerGr12 | BayerGr16 => Some(((1, 0), (0, 1))),
        BayerGb8 | BayerGb12 | BayerGb16 => Some(((0, 1), (1, 0))),
        BayerBg8 | BayerBg12 | BayerBg16 => Some(((1, 1), (0, 0))),
        _ => None,
    }
}

/// `frame` averaged over boxes of `n × n` pixels (`n` ≥ 1; even for a
/// Bayer mosaic), as 8-bit grey or RGB.
pub fn shrink(frame: &Frame, n: usize) -> Result<Small, String> {
    let (w, h, format) = (frame.meta.width, frame.meta.height, frame.meta.format);
    let n = n.max(1);
    let bayer = bayer_sites(format);
    if bayer.is_some() && n % 2 == 1 {
        return Err(format!(
            "{format:?} frames are shown at half size or smaller (a scale of 1/{n} asked)"
        ));
    }
    let (sw, sh) = (w / n, h / n);
    if sw == 0 || sh == 0 {
        return Err(format!("a {w}×{h} frame at 1/{n}: nothing left"));
    }
    let bytes = format.bytes_per_pixel();
    let deep = matches!(bytes, 2 | 6);
    // The 8-bit value of a sample (12-bit frames hold 12 bits in 16).
    let shift = match format {
        PixelFormat::Mono12
        | PixelFormat::BayerRg12
        | PixelFormat::BayerGr12
        | PixelFormat::BayerGb12
        | PixelFormat::BayerBg12 => 4,
        _ if deep => 8,
        _ => 0,
    };
    let data = &frame.data;
    let sample = |x: usize, y: usize, c: usize| -> u32 {
        // Only RGB8 has more than one channel (a byte each).
        let i = (y * w + x) * bytes + c;
        if deep {
            u32::from(u16::from_le_bytes([data[i], data[i + 1]])) >> shift
        } else {
            u32::from(data[i])
        }
    };
    let expected = w * h * bytes;
    if data.len() < expected {
        return Err(format!(
            "a {w}×{h} {format:?} frame of {} bytes, not {expected}",
            data.len()
        ));
    }
    let channels = if format == PixelFormat::Rgb8 || bayer.is_some() {
        3
    } else {
        1
    };
    if !deep && bayer.is_none() {
        return Ok(boxes_8bit(&data[..expected], w, h, channels, n));
    }
    let mut out = Vec::with_capacity(sw * sh * channels);
    for by in 0..sh {
        for bx in 0..sw {
            let (x0, y0) = (bx * n, by * n);
            match bayer {
                Some(((rx, ry), (bxs, bys))) => {
                    let (mut r, mut g, mut b) = (0u32, 0u32, 0u32);
                    for cy in (0..n).step_by(2) {
                        for cx in (0..n).step_by(2) {
                            let (x, y) = (x0 + cx, y0 + cy);
                            r += sample(x + rx, y + ry, 0);
                            b += sample(x + bxs, y + bys, 0);
                            g += sample(x + (1 - rx), y + ry, 0) + sample(x + rx, y + (1 - ry), 0);
                        }
                    }
                    let cells = (n / 2) * (n / 2);
                    out.push(((r + cells as u32 / 2) / cells as u32) as u8);
                    out.push(((g + cells as u32) / (2 * cells as u32)) as u8);
                    out.push(((b + cells as u32 / 2) / cells as u32) as u8);
                }
                None => {
                    for c in 0..channels {
                        let mut s = 0u32;
                        for y in y0..y0 + n {
                            for x in x0..x0 + n {
                                s += sample(x, y, c);
                            }
                        }
                        let k = (n * n) as u32;
                        out.push(((s + k / 2) / k) as u8);
                    }
                }
            }
        }
    }
    Ok(Small {
        width: sw,
        height: sh,
        channels,
        data: out,
    })
}

/// 8-bit rows (`channels` interleaved) averaged over `n × n` boxes.
fn boxes_8bit(data: &[u8], w: usize, h: usize, channels: usize, n: usize) -> Small {
    let (sw, sh) = (w / n, h / n);
    let stride = w * channels;
    let k = (n * n) as u32;
    let mut out = Vec::with_capacity(sw * sh * channels);
    for by in 0..sh {
        let rows: Vec<&[u8]> = (0..n)
            .map(|dy| &data[(by * n + dy) * stride..(by * n + dy + 1) * stride])
            .collect();
        for bx in 0..sw {
            let at = bx * n * channels;
            for c in 0..channels {
                let mut s = 0u32;
                for row in &rows {
                    for v in row[at + c..at + n * channels].iter().step_by(channels) {
                        s += u32::from(*v);
                    }
                }
                out.push(((s + k / 2) / k) as u8);
            }
        }
    }
    Small {
        width: sw,
        height: sh,
        channels,
        data: out,
    }
}

/// A composed view (`w × h` 8-bit rows of `channels` interleaved: grey
/// or RGB) averaged over `n × n` boxes.
pub fn shrink_picture(data: &[u8], (w, h): (usize, usize), channels: usize, n: usize) -> Small {
    let n = n.max(1);
    if n == 1 || w < n || h < n {
        return Small {
            width: w,
            height: h,
            channels,
            data: data.to_vec(),
        };
    }
    boxes_8bit(data, w, h, channels, n)
}

/// `small` as a JPEG of `quality` (1–100), with the `jpeg-encoder` crate
/// (its AVX2 paths where the CPU has them: three times the `image` crate's
/// encoder here, `BENCHMARKS.md`).
pub fn jpeg(small: &Small, quality: u8) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(small.data.len() / 8);
    let colour = if small.channels == 3 {
        jpeg_encoder::ColorType::Rgb
    } else {
        jpeg_encoder::ColorType::Luma
    };
    let (w, h) = (
        u16::try_from(small.width).map_err(|_| format!("a JPEG {} wide", small.width))?,
        u16::try_from(small.height).map_err(|_| format!("a JPEG {} high", small.height))?,
    );
    jpeg_encoder::Encoder::new(&mut out, quality.clamp(1, 100))
        .encode(&small.data, w, h, colour)
        .map_err(|e| format!("JPEG encoding: {e}"))?;
    Ok(out)
}

/// `small` as a JPEG of `quality` with the `image` crate's encoder (the
/// peer in the benchmark).
pub fn jpeg_with_image(small: &Small, quality: u8) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let colour = if small.channels == 3 {
        image::ExtendedColorType::Rgb8
    } else {
        image::ExtendedColorType::L8
    };
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100))
        .encode(&small.data, small.width as u32, small.height as u32, colour)
        .map_err(|e| format!("JPEG encoding: {e}"))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rigview_core::source::FrameMeta;
    use std::sync::Arc;

    fn frame(format: PixelFormat, w: usize, h: usize, data: Vec<u8>) -> Frame {
        Frame::new(FrameMeta::still(0, format, w, h), Arc::from(data)).unwrap()
    }

    /// Boxes average exactly: grey, RGB, 16-bit and a Bayer mosaic's cells
    /// (red, the mean of the greens, blue), and a mosaic at full size is
    /// refused.
    #[test]
    fn boxes_average_each_format() {
        let grey = frame(PixelFormat::Mono8, 4, 2, vec![0, 2, 10, 20, 4, 6, 30, 40]);
        assert_eq!(shrink(&grey, 2).unwrap().data, vec![3, 25]);
        let rgb = frame(
            PixelFormat::Rgb8,
            2,
            2,
            vec![10, 0, 100, 20, 0, 100, 30, 0, 100, 40, 255, 100],
        );
        let s = shrink(&rgb, 2).unwrap();
        assert_eq!((s.width, s.height, s.channels), (1, 1, 3));
        assert_eq!(s.data, vec![25, 64, 100]);
        let deep: Vec<u8> = [0x1000u16, 0x2000, 0x3000, 0x4000]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let m16 = frame(PixelFormat::Mono16, 2, 2, deep);
        assert_eq!(shrink(&m16, 2).unwrap().data, vec![0x28]);
        // RGGB: R 200, G 100 and 50, B 10.
        let bayer = frame(PixelFormat::BayerRg8, 2, 2, vec![200, 100, 50, 10]);
        let s = shrink(&bayer, 2).unwrap();
        assert_eq!(s.data, vec![200, 75, 10]);
        let e = shrink(&bayer, 1).unwrap_err();
        assert!(e.contains("half size"), "{e}");
        // A JPEG of it decodes to its size.
        let small = shrink(&frame(PixelFormat::Mono8, 64, 32, vec![128; 64 * 32]), 2).unwrap();
        let j = jpeg(&small, 80).unwrap();
        let d = image::load_from_memory(&j).unwrap();
        assert_eq!((d.width(), d.height()), (32, 16));
    }
}
