//! Borrowed camera frames and region-of-interest masks.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The pixel formats the metering understands (GenICam PFNC names).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PixelFormat {
    /// 8-bit monochrome.
    Mono8,
    /// 12-bit monochrome, unpacked: one little-endian `u16` per pixel, the
    /// value in the low 12 bits.
    Mono12,
    /// 16-bit monochrome, little-endian.
    Mono16,
    /// 8-bit RGB, interleaved.
    Rgb8,
    /// 8-bit Bayer mosaic, first row `R G R G …`.
    BayerRg8,
    /// 8-bit Bayer mosaic, first row `G R G R …`.
    BayerGr8,
    /// 8-bit Bayer mosaic, first row `G B G B …`.
    BayerGb8,
    /// 8-bit Bayer mosaic, first row `B G B G …`.
    BayerBg8,
}

impl PixelFormat {
    /// Bytes per pixel in the buffer.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Mono8 | Self::BayerRg8 | Self::BayerGr8 | Self::BayerGb8 | Self::BayerBg8 => 1,
            Self::Mono12 | Self::Mono16 => 2,
            Self::Rgb8 => 3,
        }
    }

    /// Whether this is a Bayer mosaic.
    pub fn is_bayer(self) -> bool {
        matches!(
            self,
            Self::BayerRg8 | Self::BayerGr8 | Self::BayerGb8 | Self::BayerBg8
        )
    }

    /// The GenICam PFNC name.
    pub fn genicam_name(self) -> &'static str {
        match self {
            Self::Mono8 => "Mono8",
            Self::Mono12 => "Mono12",
            Self::Mono16 => "Mono16",
            Self::Rgb8 => "RGB8",
            Self::BayerRg8 => "BayerRG8",
            Self::BayerGr8 => "BayerGR8",
            Self::BayerGb8 => "BayerGB8",
            Self::BayerBg8 => "BayerBG8",
        }
    }
}

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
    /// frame: BT.601 weights for RGB; for Bayer, the 2×2 quad holding the
    /// pixel (as the metering bins it).
    pub fn luma_at(&self, x: usize, y: usize) -> f32 {
        use crate::exposure::metering::{W_B, W_G, W_R};
        let row = self.row(y);
        match self.format {
            PixelFormat::Mono8 => f32::from(row[x]) / 255.0,
            PixelFormat::Mono12 => {
                f32::from(u16::from_le_bytes([row[2 * x], row[2 * x + 1]]) & 0x0fff) / 4095.0
            }
            PixelFormat::Mono16 => {
                f32::from(u16::from_le_bytes([row[2 * x], row[2 * x + 1]])) / 65535.0
            }
            PixelFormat::Rgb8 => {
                let p = &row[3 * x..3 * x + 3];
                (W_R * f32::from(p[0]) + W_G * f32::from(p[1]) + W_B * f32::from(p[2])) / 255.0
            }
            PixelFormat::BayerRg8
            | PixelFormat::BayerGr8
            | PixelFormat::BayerGb8
            | PixelFormat::BayerBg8 => {
                let (qx, qy) = (x & !1, y & !1);
                if qx + 1 >= self.width || qy + 1 >= self.height {
                    return f32::from(row[x]) / 255.0;
                }
                let (top, bottom) = (self.row(qy), self.row(qy + 1));
                let quad = [top[qx], top[qx + 1], bottom[qx], bottom[qx + 1]];
                let g = W_G * 0.5;
                let w = match self.format {
                    PixelFormat::BayerRg8 => [W_R, g, g, W_B],
                    PixelFormat::BayerGr8 => [g, W_R, W_B, g],
                    PixelFormat::BayerGb8 => [g, W_B, W_R, g],
                    _ => [W_B, g, g, W_R],
                };
                quad.iter()
                    .zip(w)
                    .map(|(&v, w)| w * f32::from(v))
                    .sum::<f32>()
                    / 255.0
            }
        }
    }
}

/// A region of interest at full frame resolution: non-zero marks a pixel that
/// counts (in surround mode, the ground pixels that reach the canvas).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RoiMask {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

impl RoiMask {
    /// A mask from one byte per pixel, row-major.
    pub fn new(width: usize, height: usize, data: Vec<u8>) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::EmptyImage {
                what: "ROI mask",
                width,
                height,
            });
        }
        if data.len() != width * height {
            return Err(Error::BufferSize {
                what: "ROI mask",
                expected: width * height,
                actual: data.len(),
                detail: format!("one byte per pixel, {width}×{height}"),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A mask that keeps the rows from `first_row` down (e.g. the bottom half
    /// of a forward-looking image).
    pub fn rows_from(width: usize, height: usize, first_row: usize) -> Result<Self> {
        let mut data = vec![0u8; width * height];
        let start = first_row.min(height) * width;
        data[start..].fill(1);
        Self::new(width, height, data)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Row `y` of the mask.
    pub fn row(&self, y: usize) -> &[u8] {
        &self.data[y * self.width..(y + 1) * self.width]
    }
    /// The fraction of pixels that count.
    pub fn coverage(&self) -> f64 {
        let on = self.data.iter().filter(|&&v| v != 0).count();
        on as f64 / self.data.len() as f64
    }
}
