//! Small synthetic high-dynamic-range scenes seen by ideal linear cameras.
//!
//! They give the exposure core something real to control without hardware:
//! a radiance map with textures and edges of every contrast, lit by one or
//! several illumination levels, and a linear camera that saturates at full
//! scale and quantises to 8 bits. [`StripRig`] places several cameras side by
//! side on one cyclic scene so that neighbours see the same surfaces in their
//! overlaps. The full rig simulator (fisheye cameras, noise, latency,
//! scenarios) is [`crate::sim`].

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::{Error, Result};

/// How a scene is lit.
#[derive(Clone, Debug, PartialEq)]
pub enum Illumination {
    /// One level everywhere.
    Uniform(f32),
    /// The left part (up to `boundary`, a fraction of the width) at `left`,
    /// the rest at `right`: e.g. sunlit ground beside a building's shadow.
    Split {
        /// Level left of the boundary.
        left: f32,
        /// Level right of the boundary.
        right: f32,
        /// Where the boundary is, as a fraction of the width.
        boundary: f32,
    },
    /// A level per column (length = width).
    Columns(Vec<f32>),
}

/// A radiance map in relative units.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrScene {
    width: usize,
    height: usize,
    radiance: Vec<f32>,
}

impl HdrScene {
    /// A textured scene: random rectangles of reflectance 0.03–0.9, fine
    /// value-noise texture, thin bright lines, times the illumination.
    pub fn generate(
        width: usize,
        height: usize,
        seed: u64,
        illumination: &Illumination,
    ) -> Result<Self> {
        if width < 8 || height < 8 {
            return Err(Error::EmptyImage {
                what: "synthetic scene (needs at least 8×8)",
                width,
                height,
            });
        }
        if let Illumination::Columns(c) = illumination {
            if c.len() != width {
                return Err(Error::BufferSize {
                    what: "column illumination",
                    expected: width,
                    actual: c.len(),
                    detail: format!("one level per column of a {width}-wide scene"),
                });
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut refl = vec![0.25f32; width * height];
        // Layered rectangles: edges of many contrasts and sizes.
        let rects = (width * height / 900).clamp(20, 400);
        for _ in 0..rects {
            let w = rng.gen_range(4..(width / 4).max(5));
            let h = rng.gen_range(4..(height / 4).max(5));
            let x0 = rng.gen_range(0..width);
            let y0 = rng.gen_range(0..height.saturating_sub(h).max(1));
            let v: f32 = 0.03 + 0.87 * rng.gen::<f32>().powf(1.5);
            for y in y0..(y0 + h).min(height) {
                for x in x0..x0 + w {
                    // Wrap horizontally so cyclic strips have no seam.
                    refl[y * width + x % width] = v;
                }
            }
        }
        // Fine texture: value noise on an 6-pixel lattice, ±25 %.
        let cell = 6usize;
        let gw = width.div_ceil(cell) + 1;
        let gh = height / cell + 2;
        let lattice: Vec<f32> = (0..gw * gh).map(|_| rng.gen_range(-1.0f32..1.0)).collect();
        for y in 0..height {
            let fy = y as f32 / cell as f32;
            let (iy, ty) = (fy as usize, fy.fract());
            for x in 0..width {
                let fx = x as f32 / cell as f32;
                let (ix, tx) = (fx as usize, fx.fract());
                // Wrap the lattice horizontally too.
                let at = |gx: usize, gy: usize| lattice[gy * gw + gx % (gw - 1)];
                let top = at(ix, iy) * (1.0 - tx) + at(ix + 1, iy) * tx;
                let bottom = at(ix, iy + 1) * (1.0 - tx) + at(ix + 1, iy + 1) * tx;
                let n = top * (1.0 - ty) + bottom * ty;
                let r = &mut refl[y * width + x];
                *r = (*r * (1.0 + 0.25 * n)).clamp(0.01, 0.95);
            }
        }
        // Thin bright lines, like lane markings.
        for _ in 0..4 {
            let y = rng.gen_range(0..height);
            for x in 0..width {
                refl[y * width + x] = 0.9;
            }
        }
        let radiance = refl
            .iter()
            .enumerate()
            .map(|(i, &r)| {
                let x = i % width;
                let level = match illumination {
                    Illumination::Uniform(l) => *l,
                    Illumination::Split {
                        left,
                        right,
                        boundary,
                    } => {
                        if (x as f32) < boundary * width as f32 {
                            *left
                        } else {
                            *right
                        }
                    }
                    Illumination::Columns(c) => c[x],
                };
                r * level
            })
            .collect();
        Ok(Self {
            width,
            height,
            radiance,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// The radiance, row-major.
    pub fn radiance(&self) -> &[f32] {
        &self.radiance
    }

    /// The columns `x0 .. x0 + width`, wrapping around horizontally.
    pub fn window(&self, x0: usize, width: usize) -> Self {
        let mut radiance = Vec::with_capacity(width * self.height);
        for y in 0..self.height {
            let row = &self.radiance[y * self.width..(y + 1) * self.width];
            radiance.extend((0..width).map(|x| row[(x0 + x) % self.width]));
        }
        Self {
            width,
            height: self.height,
            radiance,
        }
    }
}

/// An ideal linear camera: `value = min(1, radiance · E / saturation)`,
/// quantised to 8 bits, optionally with Gaussian read noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearCamera {
    /// `radiance · E` at which the sensor reaches full scale.
    pub saturation: f64,
    /// Standard deviation of additive noise in 8-bit digital numbers (0: none).
    pub noise_dn: f32,
}

impl Default for LinearCamera {
    fn default() -> Self {
        Self {
            saturation: 10_000.0,
            noise_dn: 0.0,
        }
    }
}

impl LinearCamera {
    /// A Mono8 frame of `radiance` at exposure level `exposure`; `seed` picks
    /// the noise.
    pub fn render_mono8(&self, radiance: &[f32], exposure: f64, seed: u64) -> Vec<u8> {
        let k = (exposure / self.saturation * 255.0) as f32;
        if self.noise_dn <= 0.0 {
            return radiance
                .iter()
                .map(|&r| (r * k).clamp(0.0, 255.0).round() as u8)
                .collect();
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        radiance
            .iter()
            .map(|&r| {
                // Sum of uniforms: cheap, bounded, near-Gaussian noise.
                let n: f32 = (0..4).map(|_| rng.gen_range(-0.5f32..0.5)).sum::<f32>() * 1.732;
                (r * k + n * self.noise_dn).clamp(0.0, 255.0).round() as u8
            })
            .collect()
    }
}

/// A rectangle in pixels (`x, y, width, height`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// Left.
    pub x: usize,
    /// Top.
    pub y: usize,
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
}

/// Several cameras side by side on one cyclic scene: camera `i` sees columns
/// `i·(width − overlap) …` and shares `overlap` columns with each neighbour.
#[derive(Clone, Debug)]
pub struct StripRig {
    views: Vec<HdrScene>,
    width: usize,
    height: usize,
    overlap: usize,
}

impl StripRig {
    /// `cameras` cameras of `width×height`; `levels[i]` is the illumination
    /// around camera `i`'s centre (it blends linearly between camera centres,
    /// so every overlap is lit alike in both cameras).
    pub fn new(
        width: usize,
        height: usize,
        overlap: usize,
        levels: &[f32],
        seed: u64,
    ) -> Result<Self> {
        let cameras = levels.len();
        if cameras < 2 || overlap == 0 || overlap * 2 > width {
            return Err(Error::invalid(
                "strip rig",
                "cameras and overlap",
                "at least 2 cameras and 0 < overlap ≤ width/2",
                format_args!("{cameras} cameras of width {width} with overlap {overlap}"),
            ));
        }
        let step = width - overlap;
        let total = cameras * step;
        let columns: Vec<f32> = (0..total)
            .map(|x| {
                // Camera i's centre is at i·step + width/2.
                let pos = (x as f32 - width as f32 / 2.0).rem_euclid(total as f32) / step as f32;
                let i = pos.floor() as usize % cameras;
                let t = pos.fract();
                // Log-linear blend between neighbouring centres.
                let (a, b) = (levels[i].ln(), levels[(i + 1) % cameras].ln());
                (a * (1.0 - t) + b * t).exp()
            })
            .collect();
        let scene = HdrScene::generate(total, height, seed, &Illumination::Columns(columns))?;
        let views = (0..cameras)
            .map(|i| scene.window(i * step, width))
            .collect();
        Ok(Self {
            views,
            width,
            height,
            overlap,
        })
    }

    /// Number of cameras.
    pub fn cameras(&self) -> usize {
        self.views.len()
    }
    /// Camera image width.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Camera image height.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Camera `i`'s radiance.
    pub fn view(&self, i: usize) -> &HdrScene {
        &self.views[i % self.views.len()]
    }

    /// The neighbour pairs `(i, i+1 mod n)`.
    pub fn pairs(&self) -> Vec<(usize, usize)> {
        let n = self.cameras();
        if n == 2 {
            vec![(0, 1)]
        } else {
            (0..n).map(|i| (i, (i + 1) % n)).collect()
        }
    }

    /// A grid of `cols × rows` patches in the overlap of `i` and its right
    /// neighbour, as rectangles in camera `i` and in camera `i+1`.
    pub fn overlap_patches(&self, cols: usize, rows: usize) -> Vec<(Rect, Rect)> {
        let (cols, rows) = (cols.max(1), rows.max(1));
        let pw = self.overlap / cols;
        let ph = self.height / rows;
        let mut out = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            for c in 0..cols {
                let xj = c * pw;
                let y = r * ph;
                out.push((
                    Rect {
                        x: self.width - self.overlap + xj,
                        y,
                        w: pw,
                        h: ph,
                    },
                    Rect {
                        x: xj,
                        y,
                        w: pw,
                        h: ph,
                    },
                ));
            }
        }
        out
    }
}
