//! 8-bit colour conversions between RGB and grey, as OpenCV's `cvtColor`
//! makes them: `RGB2GRAY` is
//!
//! ```text
//! Y = (9798·R + 19235·G + 3735·B + 2¹⁴) >> 15
//! ```
//!
//! (the luminance weights in 15-bit fixed point, rounded to nearest), and
//! `GRAY2RGB` copies the grey value to the three channels.
//!
//! The RGB loop is compiled twice, for baseline x86-64 and for AVX2, where
//! LLVM splits the interleaved channels with byte shuffles; the CPU picks
//! ([`Isa::detect`]).

use super::luma::{FIXED, FIXED_SHIFT};
use crate::cpu::Isa;
use crate::error::{Error, Result};

/// Converts packed 8-bit RGB pixels (`rgb`, 3 bytes a pixel) to 8-bit grey
/// (`mono`, one byte a pixel, as many pixels).
pub fn rgb8_to_mono8(rgb: &[u8], mono: &mut [u8]) -> Result<()> {
    check(rgb, mono, 3)?;
    match Isa::detect() {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 => {
            // SAFETY: `detect` returns these only when the CPU has AVX2.
            #[allow(unsafe_code)]
            unsafe {
                rgb_to_mono_avx2(rgb, mono);
            }
        }
        _ => rgb_to_mono(rgb, mono),
    }
    Ok(())
}

/// Converts 8-bit grey pixels (`mono`) to packed 8-bit RGB (`rgb`, 3 bytes
/// a pixel, as many pixels), each channel the grey value.
pub fn mono8_to_rgb8(mono: &[u8], rgb: &mut [u8]) -> Result<()> {
    check(rgb, mono, 3)?;
    let (pixels, _) = rgb.as_chunks_mut::<3>();
    for (p, &v) in pixels.iter_mut().zip(mono) {
        *p = [v; 3];
    }
    Ok(())
}

/// Checks that `wide` holds `channels` bytes for each byte of `mono`.
fn check(wide: &[u8], mono: &[u8], channels: usize) -> Result<()> {
    if wide.len() != channels * mono.len() {
        return Err(Error::BufferSize {
            what: "RGB image of a colour conversion",
            expected: channels * mono.len(),
            actual: wide.len(),
            detail: format!("{} pixels of 3 bytes", mono.len()),
        });
    }
    Ok(())
}

#[inline(always)]
fn rgb_to_mono(rgb: &[u8], mono: &mut [u8]) {
    let [r, g, b] = FIXED;
    let half = 1 << (FIXED_SHIFT - 1);
    let (pixels, _) = rgb.as_chunks::<3>();
    for (m, p) in mono.iter_mut().zip(pixels) {
        let y = r * u32::from(p[0]) + g * u32::from(p[1]) + b * u32::from(p[2]) + half;
        *m = (y >> FIXED_SHIFT) as u8;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn rgb_to_mono_avx2(rgb: &[u8], mono: &mut [u8]) {
    rgb_to_mono(rgb, mono);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_and_colour_convert_as_the_fixed_point_formula_says() {
        // Every value of each channel against the other two at a few
        // levels, on every instruction set's loop.
        let mut rgb = Vec::new();
        for v in 0..=255u8 {
            for o in [0u8, 1, 127, 128, 254, 255] {
                rgb.extend_from_slice(&[v, o, o, o, v, o, o, o, v]);
            }
        }
        let n = rgb.len() / 3;
        let want: Vec<u8> = rgb
            .chunks_exact(3)
            .map(|p| {
                let y = 9798 * u32::from(p[0]) + 19235 * u32::from(p[1]) + 3735 * u32::from(p[2]);
                ((y + (1 << 14)) >> 15) as u8
            })
            .collect();
        let mut mono = vec![0u8; n];
        rgb8_to_mono8(&rgb, &mut mono).unwrap();
        assert_eq!(mono, want);
        let mut portable = vec![0u8; n];
        rgb_to_mono(&rgb, &mut portable);
        assert_eq!(portable, want);
        // Grey stays grey, white white.
        let grey: Vec<u8> = (0..=255).flat_map(|v| [v, v, v]).collect();
        let mut back = vec![0u8; 256];
        rgb8_to_mono8(&grey, &mut back).unwrap();
        assert!(back.iter().enumerate().all(|(i, &v)| usize::from(v) == i));
        let mut colour = vec![0u8; 3 * 256];
        mono8_to_rgb8(&back, &mut colour).unwrap();
        assert_eq!(colour, grey);
    }

    #[test]
    fn buffers_that_do_not_match_are_refused() {
        let mut mono = [0u8; 4];
        assert!(rgb8_to_mono8(&[0u8; 11], &mut mono).is_err());
        let mut rgb = [0u8; 13];
        assert!(mono8_to_rgb8(&[0u8; 4], &mut rgb).is_err());
    }
}
