//! The pixel formats of camera frames (GenICam PFNC names).

use serde::{Deserialize, Serialize};

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
    /// Every format.
    pub const ALL: [PixelFormat; 8] = [
        Self::Mono8,
        Self::Mono12,
        Self::Mono16,
        Self::Rgb8,
        Self::BayerRg8,
        Self::BayerGr8,
        Self::BayerGb8,
        Self::BayerBg8,
    ];

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
