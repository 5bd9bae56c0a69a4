//! An 8-bit frame scaled by a gain, sample by sample, and clipped: the
//! frame as the sensor would have recorded it at a proportionally longer
//! exposure, up to what it clipped.
//!
//! The view shows a frame taken darker on purpose (a probe) at its
//! camera's previous exposure. Scaling the samples *before* the remap
//! interpolates them keeps the clipping where the sensor has it: a
//! saturated sample next to a dark one blends to the same byte as in the
//! frames before and after, where scaling the interpolated value would
//! brighten such edges (the saturated sample of the darker frame was not
//! clipped, and its scaled value exceeds 255 before the blend).

use super::FrameView;
#[cfg(test)]
use super::PixelFormat;
use crate::error::Result;

/// Writes `frame`'s samples times `gain` (rounded to nearest, clipped at
/// 255) into `out`, packed, and returns that frame. `None` for the formats
/// wider than 8 bits: their conversion to 8 bits takes a gain at full
/// precision.
pub fn scale_8bit<'b>(
    frame: &FrameView<'_>,
    gain: f32,
    out: &'b mut Vec<u8>,
) -> Result<Option<FrameView<'b>>> {
    if frame.format().bits() > 8 {
        return Ok(None);
    }
    let gain = if gain.is_finite() { gain.max(0.0) } else { 1.0 };
    let mut table = [0u8; 256];
    for (v, t) in table.iter_mut().enumerate() {
        *t = (v as f32 * gain).round().min(255.0) as u8;
    }
    let row = frame.width() * frame.format().bytes_per_pixel();
    out.clear();
    out.reserve(row * frame.height());
    for y in 0..frame.height() {
        out.extend(frame.row(y).iter().map(|&v| table[usize::from(v)]));
    }
    FrameView::new(frame.format(), frame.width(), frame.height(), out).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_scaled_rounded_and_clipped_and_wide_formats_are_left_alone() {
        // Two rows of three RGB pixels with a stride of 10 bytes.
        let mut data = vec![0u8; 20];
        data[..9].copy_from_slice(&[0, 1, 2, 100, 127, 128, 200, 254, 255]);
        data[10..19].copy_from_slice(&[3, 4, 5, 60, 61, 62, 90, 91, 92]);
        let f = FrameView::with_stride(PixelFormat::Rgb8, 3, 2, 10, &data).unwrap();
        let mut out = Vec::new();
        let s = scale_8bit(&f, 2.0, &mut out).unwrap().unwrap();
        assert_eq!(s.stride(), 9);
        assert_eq!(s.row(0), &[0, 2, 4, 200, 254, 255, 255, 255, 255]);
        assert_eq!(s.row(1), &[6, 8, 10, 120, 122, 124, 180, 182, 184]);
        // 1.5 rounds half away from zero: 1 → 2 (1.5), 3 → 5 (4.5).
        let s = scale_8bit(&f, 1.5, &mut out).unwrap().unwrap();
        assert_eq!(&s.row(1)[..2], &[5, 6]);
        assert_eq!(&s.row(0)[..3], &[0, 2, 3]);
        let wide = vec![0u8; 8];
        let f = FrameView::new(PixelFormat::Mono16, 2, 2, &wide).unwrap();
        assert!(scale_8bit(&f, 2.0, &mut out).unwrap().is_none());
    }
}
