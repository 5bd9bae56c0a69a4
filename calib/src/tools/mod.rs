//! Calibration tools: intrinsics from chessboard images, extrinsics from a
//! checkerboard mat on the ground, Harris corners for the panorama's
//! feature matches, and the shared pieces (grey images, chessboard
//! detection, a renderer of a mat seen through a camera model).

pub mod corners;
pub mod ground;
mod harris;
pub mod intrinsics;
pub mod render;
pub mod stereo;

use std::path::Path;

use opencv::core::{
    Mat, MatTraitConst, Point2f, Size, TermCriteria, TermCriteria_COUNT, TermCriteria_EPS, Vector,
};

use crate::error::{cv, CalibError, Result};

/// An 8-bit grey image, row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GrayImage {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `width × height` values, row by row.
    pub data: Vec<u8>,
}

impl GrayImage {
    /// Loads an image file (PNG or JPEG) as grey.
    pub fn load(path: &Path) -> Result<Self> {
        let img = image::open(path).map_err(|source| CalibError::Image {
            file: path.display().to_string(),
            source,
        })?;
        let g = img.to_luma8();
        Ok(Self {
            width: g.width(),
            height: g.height(),
            data: g.into_raw(),
        })
    }

    /// Saves the image as PNG.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        let img = image::GrayImage::from_raw(self.width, self.height, self.data.clone())
            .ok_or_else(|| CalibError::Argument("image buffer of the wrong size".into()))?;
        img.save(path).map_err(|source| CalibError::Image {
            file: path.display().to_string(),
            source,
        })
    }

    /// The value at a pixel position, bilinearly interpolated; `None` off
    /// the image.
    pub fn sample(&self, x: f64, y: f64) -> Option<f64> {
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        if !(x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = (
            (x0 + 1).min(self.width as usize - 1),
            (y0 + 1).min(self.height as usize - 1),
        );
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |xx: usize, yy: usize| f64::from(self.data[yy * self.width as usize + xx]);
        let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
        let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    }

    fn to_mat(&self) -> Result<Mat> {
        let rows = i32::try_from(self.height)
            .map_err(|_| CalibError::Argument("image too tall".into()))?;
        let cols =
            i32::try_from(self.width).map_err(|_| CalibError::Argument("image too wide".into()))?;
        let m = cv(
            "wrapping an image",
            Mat::new_rows_cols_with_data(rows, cols, &self.data),
        )?;
        cv("copying an image", m.try_clone())
    }
}

/// Finds the inner corners of a chessboard with `cols × rows` inner
/// corners, refined to sub-pixel accuracy; `None` if it is not seen whole.
/// OpenCV's classic detector is tried first, then the sector-based one
/// (more robust under strong distortion).
pub fn find_chessboard(img: &GrayImage, cols: u32, rows: u32) -> Result<Option<Vec<[f64; 2]>>> {
    use opencv::calib3d::{
        find_chessboard_corners, find_chessboard_corners_sb, CALIB_CB_ACCURACY,
        CALIB_CB_ADAPTIVE_THRESH, CALIB_CB_EXHAUSTIVE, CALIB_CB_NORMALIZE_IMAGE,
    };
    let mat = img.to_mat()?;
    let size = Size::new(cols as i32, rows as i32);
    let mut corners = Vector::<Point2f>::new();
    let found = cv(
        "finding chessboard corners",
        find_chessboard_corners(
            &mat,
            size,
            &mut corners,
            CALIB_CB_ADAPTIVE_THRESH | CALIB_CB_NORMALIZE_IMAGE,
        ),
    )?;
    if found {
        // Search window: as OpenCV's calibration sample (11, a 23×23 window)
        // where the squares are large enough, smaller where they are not.
        let c = cols as usize;
        let mut spacing = f32::INFINITY;
        for i in 0..corners.len() {
            let p = corners.get(i).unwrap_or_default();
            for j in [i + 1, i + c] {
                let same_row = j != i + 1 || (i + 1) % c != 0;
                if let (true, Ok(q)) = (same_row, corners.get(j)) {
                    spacing = spacing.min((p.x - q.x).hypot(p.y - q.y));
                }
            }
        }
        let win = ((spacing * 0.4).floor() as i32).clamp(2, 11);
        let criteria = cv(
            "sub-pixel criteria",
            TermCriteria::new(TermCriteria_EPS + TermCriteria_COUNT, 100, 1e-4),
        )?;
        cv(
            "refining chessboard corners",
            opencv::imgproc::corner_sub_pix(
                &mat,
                &mut corners,
                Size::new(win, win),
                Size::new(-1, -1),
                criteria,
            ),
        )?;
    } else {
        let found_sb = cv(
            "finding chessboard corners (sector-based)",
            find_chessboard_corners_sb(
                &mat,
                size,
                &mut corners,
                CALIB_CB_NORMALIZE_IMAGE | CALIB_CB_EXHAUSTIVE | CALIB_CB_ACCURACY,
            ),
        )?;
        if !found_sb {
            return Ok(None);
        }
    }
    if corners.len() != (cols * rows) as usize {
        return Ok(None);
    }
    Ok(Some(
        corners
            .iter()
            .map(|p| [f64::from(p.x), f64::from(p.y)])
            .collect(),
    ))
}
