//! A renderer of a checkerboard mat lying on the ground as a camera of the
//! rig sees it, through the camera model. It makes the test images of the
//! ground calibration (and of anything else that needs a known picture of
//! a known pose).

use nalgebra::Point2;

use crate::rig::Camera;
use crate::tools::ground::GroundMat;
use crate::tools::GrayImage;

/// Grey levels of the rendered scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Palette {
    /// Dark squares.
    pub black: f64,
    /// Light squares and the mat's border.
    pub white: f64,
    /// The ground around the mat.
    pub floor: f64,
    /// Everything that is not ground (sky, the camera's own body).
    pub sky: f64,
}

impl Default for Palette {
    fn default() -> Self {
        Self {
            black: 25.0,
            white: 225.0,
            floor: 95.0,
            sky: 170.0,
        }
    }
}

/// Renders what `camera` (which needs a pose in the vehicle frame) sees of
/// `mat` on the ground, antialiased with `supersample × supersample` rays a
/// pixel. Pixels outside the model's valid region get the sky's level.
pub fn render_mat(
    camera: &Camera,
    mat: &GroundMat,
    palette: &Palette,
    supersample: u32,
) -> GrayImage {
    let k = &camera.intrinsics;
    let s = supersample.max(1);
    let (w, h) = (k.width, k.height);
    let mut data = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for sy in 0..s {
                for sx in 0..s {
                    let px = Point2::new(
                        f64::from(x) - 0.5 + (f64::from(sx) + 0.5) / f64::from(s),
                        f64::from(y) - 0.5 + (f64::from(sy) + 0.5) / f64::from(s),
                    );
                    acc += match camera.ground_point(&px) {
                        None => palette.sky,
                        Some(g) => match mat.shade_at(g.x, g.y) {
                            Some(true) => palette.black,
                            Some(false) => palette.white,
                            None => palette.floor,
                        },
                    };
                }
            }
            let v = acc / f64::from(s * s);
            data.push(v.round().clamp(0.0, 255.0) as u8);
        }
    }
    GrayImage {
        width: w,
        height: h,
        data,
    }
}
