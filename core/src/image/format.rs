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
    /// 12-bit Bayer mosaic (`R G` first), unpacked as Mono12.
    BayerRg12,
    /// 12-bit Bayer mosaic (`G R` first), unpacked as Mono12.
    BayerGr12,
    /// 12-bit Bayer mosaic (`G B` first), unpacked as Mono12.
    BayerGb12,
    /// 12-bit Bayer mosaic (`B G` first), unpacked as Mono12.
    BayerBg12,
    /// 16-bit Bayer mosaic (`R G` first), little-endian.
    BayerRg16,
    /// 16-bit Bayer mosaic (`G R` first), little-endian.
    BayerGr16,
    /// 16-bit Bayer mosaic (`G B` first), little-endian.
    BayerGb16,
    /// 16-bit Bayer mosaic (`B G` first), little-endian.
    BayerBg16,
}

/// The Bayer formats by colour order (RGGB, GRBG, GBRG, BGGR) and depth
/// (8, 12, 16 bits).
const BAYER: [[PixelFormat; 3]; 4] = [
    [
        PixelFormat::BayerRg8,
        PixelFormat::BayerRg12,
        PixelFormat::BayerRg16,
    ],
    [
        PixelFormat::BayerGr8,
        PixelFormat::BayerGr12,
        PixelFormat::BayerGr16,
    ],
    [
        PixelFormat::BayerGb8,
        PixelFormat::BayerGb12,
        PixelFormat::BayerGb16,
    ],
    [
        PixelFormat::BayerBg8,
        PixelFormat::BayerBg12,
        PixelFormat::BayerBg16,
    ],
];

/// The colour orders' names, as `BAYER`'s rows.
pub const BAYER_PATTERNS: [&str; 4] = ["RGGB", "GRBG", "GBRG", "BGGR"];

impl PixelFormat {
    /// Every format.
    pub const ALL: [PixelFormat; 16] = [
        Self::Mono8,
        Self::Mono12,
        Self::Mono16,
        Self::Rgb8,
        Self::BayerRg8,
        Self::BayerGr8,
        Self::BayerGb8,
        Self::BayerBg8,
        Self::BayerRg12,
        Self::BayerGr12,
        Self::BayerGb12,
        Self::BayerBg12,
        Self::BayerRg16,
        Self::BayerGr16,
        Self::BayerGb16,
        Self::BayerBg16,
    ];

    /// Bytes per pixel in the buffer.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Rgb8 => 3,
            _ if self.bits() > 8 => 2,
            _ => 1,
        }
    }

    /// Bits of each sample's value: 8, 12 or 16.
    pub fn bits(self) -> u32 {
        match self {
            Self::Mono12
            | Self::BayerRg12
            | Self::BayerGr12
            | Self::BayerGb12
            | Self::BayerBg12 => 12,
            Self::Mono16
            | Self::BayerRg16
            | Self::BayerGr16
            | Self::BayerGb16
            | Self::BayerBg16 => 16,
            _ => 8,
        }
    }

    /// Whether this is a Bayer mosaic.
    pub fn is_bayer(self) -> bool {
        self.bayer_pattern().is_some()
    }

    /// A Bayer mosaic's colour order (`RGGB`, `GRBG`, `GBRG` or `BGGR`: the
    /// first row's two colours, then the second row's).
    pub fn bayer_pattern(self) -> Option<&'static str> {
        BAYER
            .iter()
            .position(|row| row.contains(&self))
            .map(|k| BAYER_PATTERNS[k])
    }

    /// The Bayer format of colour order `pattern` (as
    /// [`Self::bayer_pattern`], any case) at `bits` (8, 12 or 16).
    pub fn bayer(pattern: &str, bits: u32) -> Option<Self> {
        let row = BAYER_PATTERNS
            .iter()
            .position(|p| p.eq_ignore_ascii_case(pattern))?;
        let depth = [8, 12, 16].iter().position(|&b| b == bits)?;
        Some(BAYER[row][depth])
    }

    /// The 8-bit format of the same layout (a Bayer mosaic keeps its
    /// colour order; grey formats are Mono8, RGB8 stays).
    pub fn to_8bit(self) -> Self {
        match self.bayer_pattern() {
            Some(p) => Self::bayer(p, 8).unwrap_or(self),
            None if self == Self::Rgb8 => self,
            None => Self::Mono8,
        }
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
            Self::BayerRg12 => "BayerRG12",
            Self::BayerGr12 => "BayerGR12",
            Self::BayerGb12 => "BayerGB12",
            Self::BayerBg12 => "BayerBG12",
            Self::BayerRg16 => "BayerRG16",
            Self::BayerGr16 => "BayerGR16",
            Self::BayerGb16 => "BayerGB16",
            Self::BayerBg16 => "BayerBG16",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bayer_formats_agree_in_order_and_depth() {
        for f in PixelFormat::ALL {
            assert!(f.bytes_per_pixel() * 8 >= f.bits() as usize, "{f:?}");
            if let Some(p) = f.bayer_pattern() {
                assert_eq!(PixelFormat::bayer(p, f.bits()), Some(f));
                assert_eq!(f.to_8bit().bayer_pattern(), Some(p));
                assert_eq!(f.to_8bit().bits(), 8);
                // The GenICam name: "Bayer" + the first row + the depth.
                assert_eq!(f.genicam_name(), format!("Bayer{}{}", &p[..2], f.bits()));
            }
        }
        assert_eq!(PixelFormat::bayer("bggr", 12), Some(PixelFormat::BayerBg12));
        assert_eq!(PixelFormat::bayer("RGBG", 8), None);
        assert_eq!(PixelFormat::bayer("RGGB", 10), None);
        assert_eq!(PixelFormat::Mono16.to_8bit(), PixelFormat::Mono8);
    }
}
