//! Borrowed camera frames.

use super::luma;
use super::PixelFormat;
use crate::error::{Error, Result};

/// One camera frame, borrowed: the pixels and their layout.
#[derive(Clone, Copy, Debug)]
pub struct FrameView<'a> {
    format: PixelFormat,
    width: usize,
    height: usize,
    stride: usize,
    data: &'a [u8],
}

impl<'a> FrameView<'a> {
    /// A tightly packed frame (`stride = width · bytes_per_pixel`).
    pub fn new(format: PixelFormat, width: usize, height: usize, data: &'a [u8]) -> Result<Self> {
        Self::with_stride(
            format,
            width,
            height,
            width * format.bytes_per_pixel(),
            data,
        )
    }

    /// A frame whose rows are `stride` bytes apart.
    pub fn with_stride(
        format: PixelFormat,
        width: usize,
        height: usize,
        stride: usize,
        data: &'a [u8],
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::EmptyImage {
                what: "frame",
                width,
                height,
            });
        }
        let row = width * format.bytes_per_pixel();
        let detail = || {
            format!(
                "{} {width}×{height}, stride {stride}",
                format.genicam_name()
            )
        };
        if stride < row {
            return Err(Error::BufferSize {
                what: "frame row stride",
                expected: row,
                actual: stride,
                detail: detail(),
            });
        }
        let needed = stride * (height - 1) + row;
        if data.len() < needed {
            return Err(Error::BufferSize {
                what: "frame",
                expected: needed,
                actual: data.len(),
                detail: detail(),
            });
        }
        if format.is_bayer() && (width < 2 || height < 2) {
            return Err(Error::EmptyImage {
                what: "Bayer frame (needs at least one 2×2 quad)",
                width,
                height,
            });
        }
        Ok(Self {
            format,
            width,
            height,
            stride,
            data,
        })
    }

    /// The pixel format.
    pub fn format(&self) -> PixelFormat {
        self.format
    }
    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Bytes from one row to the next.
    pub fn stride(&self) -> usize {
        self.stride
    }
    /// The bytes of row `y` (exactly `width · bytes_per_pixel` long).
    pub fn row(&self, y: usize) -> &'a [u8] {
        let start = y * self.stride;
        &self.data[start..start + self.width * self.format.bytes_per_pixel()]
    }

    /// All pixels as one slice, when the rows are packed (stride = row
    /// length).
    pub fn packed(&self) -> Option<&'a [u8]> {
        let row = self.width * self.format.bytes_per_pixel();
        (self.stride == row).then(|| &self.data[..row * self.height])
    }

    /// The luminance in [0, 1] at pixel (`x`, `y`), which must lie in the
    /// frame, as the metering reads it ([`Meter`](crate::exposure::Meter)):
    /// for Bayer, that of the 2×2 quad holding the pixel (a pixel of an odd last
    /// row or column, outside every quad, is read as it is).
    pub fn luma_at(&self, x: usize, y: usize) -> f32 {
        let mut out = [0.0f32];
        if self.format.is_bayer() {
            let (qx, qy) = (x & !1, y & !1);
            if qx + 1 < self.width && qy + 1 < self.height {
                let (top, bottom) = (self.row(qy), self.row(qy + 1));
                let quad =
                    qx * self.format.bytes_per_pixel()..(qx + 2) * self.format.bytes_per_pixel();
                luma::bayer_luma_row(self.format, &top[quad.clone()], &bottom[quad], &mut out);
                return out[0];
            }
        }
        let bpp = self.format.bytes_per_pixel();
        luma::luma_row(self.format, &self.row(y)[x * bpp..(x + 1) * bpp], &mut out);
        out[0]
    }

    /// Asks the CPU to bring the first byte of each pixel of `pixels`
    /// (row-major indices) into its caches, without waiting: for reads
    /// that follow soon. Reads nothing into the program.
    pub(crate) fn prefetch(&self, pixels: &[u32]) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let (w, stride) = (self.width, self.stride);
            let bpp = self.format.bytes_per_pixel();
            for &p in pixels {
                let p = p as usize;
                let at = self
                    .data
                    .as_ptr()
                    .wrapping_add(p / w * stride + p % w * bpp);
                // SAFETY: a prefetch reads nothing into the program and
                // never faults, whatever the address.
                #[allow(unsafe_code)]
                unsafe {
                    _mm_prefetch::<_MM_HINT_T0>(at.cast::<i8>());
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = pixels;
    }

    /// Calls `f` with the luminance of each pixel `p` of `pixels` (row-major
    /// indices, `y · width + x`, in the frame), in order: the values of
    /// [`FrameView::luma_at`], with the format looked at once rather than
    /// per pixel for Mono8 and RGB8.
    pub fn for_each_luma<'p>(
        &self,
        pixels: impl IntoIterator<Item = &'p u32>,
        mut f: impl FnMut(f32),
    ) {
        let (w, stride, data) = (self.width, self.stride, self.data);
        let bpp = self.format.bytes_per_pixel();
        // The pixel's first byte: in packed rows at its index, with no
        // division into row and column.
        let packed = stride == w * bpp;
        let at = move |p: u32| {
            let p = p as usize;
            if packed {
                p * bpp
            } else {
                p / w * stride + p % w * bpp
            }
        };
        match self.format {
            PixelFormat::Mono8 => {
                for &p in pixels {
                    f(luma::mono8(data[at(p)]));
                }
            }
            PixelFormat::Rgb8 => {
                for &p in pixels {
                    let i = at(p);
                    f(luma::rgb8(&data[i..i + 3]));
                }
            }
            _ => {
                for &p in pixels {
                    f(self.luma_at(p as usize % w, p as usize / w));
                }
            }
        }
    }
}
