//! Luminance in [0, 1] from each pixel format's samples: the one place that
//! holds the luminance weights and reads a format's rows (see the module
//! documentation of [`crate::image`]).

use super::PixelFormat;

/// BT.601 weight of red (OpenCV's `RGB2GRAY`).
pub(crate) const W_R: f32 = 0.299;
/// BT.601 weight of green.
pub(crate) const W_G: f32 = 0.587;
/// BT.601 weight of blue.
pub(crate) const W_B: f32 = 0.114;

/// Bits of the fixed-point weights of 8-bit conversions ([`FIXED`]).
pub(crate) const FIXED_SHIFT: u32 = 15;

/// The weights of red, green and blue in 1/2¹⁵: red's and green's rounded,
/// blue's the rest of 2¹⁵, so that they sum to exactly one: 9798, 19235 and
/// 3735 (OpenCV's for 8-bit `RGB2GRAY`).
pub(crate) const FIXED: [u32; 3] = {
    let (r, g) = (fixed(W_R), fixed(W_G));
    [r, g, (1 << FIXED_SHIFT) - r - g]
};

const fn fixed(w: f32) -> u32 {
    (w * (1u32 << FIXED_SHIFT) as f32 + 0.5) as u32
}

/// The luminance of red, green and blue values (or of sums of them, in
/// their own units): `W_R·r + W_G·g + W_B·b`.
#[inline(always)]
pub(crate) fn rgb(r: f32, g: f32, b: f32) -> f32 {
    W_R * r + W_G * g + W_B * b
}

/// The luminance weights of a Bayer quad's positions (top-left, top-right,
/// bottom-left, bottom-right); the two greens share `W_G`. Formats other
/// than Bayer read as `BayerBG8`; 12- and 16-bit mosaics as their 8-bit
/// order.
#[inline]
pub(crate) fn bayer_weights(format: PixelFormat) -> [f32; 4] {
    let g = W_G * 0.5;
    match format.to_8bit() {
        PixelFormat::BayerRg8 => [W_R, g, g, W_B],
        PixelFormat::BayerGr8 => [g, W_R, W_B, g],
        PixelFormat::BayerGb8 => [g, W_B, W_R, g],
        _ => [W_B, g, g, W_R],
    }
}

/// `Σ w_i·value(sample_i)` over each 2×2 Bayer quad of the two rows `top`
/// and `bottom`, into `dst` (one value per quad).
#[inline(always)]
pub(crate) fn bayer_row(
    w: [f32; 4],
    top: &[u8],
    bottom: &[u8],
    dst: &mut [f32],
    value: impl Fn(u8) -> f32,
) {
    // Pairs as arrays (not `chunks_exact` slices), so that the loop
    // vectorises.
    let (top, _) = top.as_chunks::<2>();
    let (bottom, _) = bottom.as_chunks::<2>();
    for ((d, t), b) in dst.iter_mut().zip(top).zip(bottom) {
        *d = w[0] * value(t[0]) + w[1] * value(t[1]) + w[2] * value(b[0]) + w[3] * value(b[1]);
    }
}

/// Luminance of a row of 2×2 Bayer quads, from the quad's two source rows.
#[inline(always)]
pub(crate) fn bayer_luma_row(format: PixelFormat, top: &[u8], bottom: &[u8], dst: &mut [f32]) {
    if format.bytes_per_pixel() == 2 {
        bayer_wide_row(format, top, bottom, dst, |v| v);
        return;
    }
    let w = bayer_weights(format).map(|v| v * (1.0 / 255.0));
    bayer_row(w, top, bottom, dst, f32::from);
}

/// A 12- or 16-bit sample (little-endian; 12 bits in the low bits, as
/// Mono12) in [0, 1] of the format's full scale.
#[inline(always)]
fn wide_sample(format: PixelFormat, s: [u8; 2]) -> f32 {
    let v = u16::from_le_bytes(s);
    if format.bits() == 12 {
        f32::from(v & 0x0fff) * (1.0 / 4095.0)
    } else {
        f32::from(v) * (1.0 / 65535.0)
    }
}

/// `Σ w_i·value(s_i)` over each 2×2 quad of a 12- or 16-bit Bayer mosaic's
/// rows `top` and `bottom`, each sample `s_i` in [0, 1] of full scale.
#[inline]
pub(crate) fn bayer_wide_row(
    format: PixelFormat,
    top: &[u8],
    bottom: &[u8],
    dst: &mut [f32],
    value: impl Fn(f32) -> f32,
) {
    let w = bayer_weights(format);
    let v = |s: &[u8]| value(wide_sample(format, [s[0], s[1]]));
    for ((d, t), b) in dst
        .iter_mut()
        .zip(top.chunks_exact(4))
        .zip(bottom.chunks_exact(4))
    {
        *d = w[0] * v(&t[..2]) + w[1] * v(&t[2..]) + w[2] * v(&b[..2]) + w[3] * v(&b[2..]);
    }
}

/// The luminance of a Mono8 sample.
#[inline(always)]
pub(crate) fn mono8(v: u8) -> f32 {
    f32::from(v) * (1.0 / 255.0)
}

/// The luminance of an RGB8 pixel (its first three bytes).
#[inline(always)]
pub(crate) fn rgb8(p: &[u8]) -> f32 {
    rgb(f32::from(p[0]), f32::from(p[1]), f32::from(p[2])) * (1.0 / 255.0)
}

/// Luminance of one row of a frame, one value per pixel; a Bayer row is
/// read sample by sample (its quads go through [`bayer_luma_row`]).
#[inline]
pub(crate) fn luma_row(format: PixelFormat, src: &[u8], dst: &mut [f32]) {
    match format {
        PixelFormat::Mono8 => {
            for (d, &s) in dst.iter_mut().zip(src) {
                *d = mono8(s);
            }
        }
        PixelFormat::Mono12 => {
            for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                let v = u16::from_le_bytes([s[0], s[1]]) & 0x0fff;
                *d = f32::from(v) * (1.0 / 4095.0);
            }
        }
        PixelFormat::Mono16 => {
            for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                *d = f32::from(u16::from_le_bytes([s[0], s[1]])) * (1.0 / 65535.0);
            }
        }
        PixelFormat::Rgb8 => {
            let (pixels, _) = src.as_chunks::<3>();
            for (d, s) in dst.iter_mut().zip(pixels) {
                *d = rgb8(s);
            }
        }
        PixelFormat::BayerRg8
        | PixelFormat::BayerGr8
        | PixelFormat::BayerGb8
        | PixelFormat::BayerBg8 => {
            for (d, &s) in dst.iter_mut().zip(src) {
                *d = f32::from(s) * (1.0 / 255.0);
            }
        }
        // The 12- and 16-bit mosaics, sample by sample.
        _ => {
            for (d, s) in dst.iter_mut().zip(src.chunks_exact(2)) {
                *d = wide_sample(format, [s[0], s[1]]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fixed_point_weights_are_opencvs_and_sum_to_one() {
        assert_eq!(FIXED, [9798, 19235, 3735]);
        assert_eq!(FIXED.iter().sum::<u32>(), 1 << FIXED_SHIFT);
    }
}
