//! Region-of-interest masks at full frame resolution.

use crate::error::{Error, Result};

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
