//! Sub-pixel alignment of a matched pair of corners.
//!
//! A corner detector places the same corner a fraction of a pixel apart in
//! two images that see it at different scales, blur and brightness: each
//! detection errs on its own. (On the simulated rig, whose scene is known,
//! a match's two subpixel Harris corners lie a median 0.3 to 0.55 canvas
//! pixels from being the same scene point.) A match's two positions are
//! therefore made to agree by aligning image patches instead: the patch of
//! image `a` centred on the pixel nearest its corner is the template, and
//! the position in image `b` where the same patch lies is found to a
//! fraction of a pixel (0.12 to 0.27 pixels from the truth on that rig).
//!
//! The alignment is Lucas–Kanade (Gauss–Newton) over a shift and a linear
//! change of brightness: it minimises
//! `Σ w(x) · (B(p + x) − α·A(q + x) − β)²` over the shift `p` and the
//! gain and offset `α`, `β` (the two cameras of an overlap expose
//! differently; without `α` a step edge's alignment would lean towards its
//! brighter side). `w` is a Gaussian of σ = radius / 2 over a square of
//! side `2·radius + 1`, `A` is read at whole pixels and `B` bilinearly
//! (one fraction for the whole patch). `B`'s gradient is taken as `α`
//! times `A`'s (central differences), equal where the patches align, so
//! the Gauss–Newton matrix comes from the template's moments, computed
//! once; each step reads `B` once a pixel. OpenCV's
//! `calcOpticalFlowPyrLK` assumes equal brightness, and `core` calls no
//! OpenCV.

use nalgebra::{Matrix4, Vector4};

/// A Mono8 image: packed rows of `width` bytes ([`Gray::new`] checks
/// that they are all there).
#[derive(Clone, Copy, Debug)]
pub struct Gray<'a> {
    data: &'a [u8],
    width: usize,
    height: usize,
}

impl<'a> Gray<'a> {
    /// A view of `data` as a `width × height` image; `None` unless `data`
    /// holds exactly that many pixels.
    pub fn new(data: &'a [u8], width: usize, height: usize) -> Option<Self> {
        (width.checked_mul(height) == Some(data.len())).then_some(Self {
            data,
            width,
            height,
        })
    }

    fn at(&self, x: usize, y: usize) -> f32 {
        f32::from(self.data[y * self.width + x])
    }

    /// Calls `f` with each texel of `template` and the bilinear value of
    /// this image at `p` plus its offset (one fraction for all: the
    /// offsets are whole pixels). The caller keeps the reads inside.
    fn patch(&self, p: [f32; 2], template: &[Texel], mut f: impl FnMut(&Texel, f32)) {
        let (x0, y0) = (p[0].floor(), p[1].floor());
        let (fx, fy) = (p[0] - x0, p[1] - y0);
        let (x0, y0) = (x0 as isize, y0 as isize);
        let w = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        for q in template {
            let i = (y0 + q.dy) as usize * self.width + (x0 + q.dx) as usize;
            let d = self.data;
            let v = w[0] * f32::from(d[i])
                + w[1] * f32::from(d[i + 1])
                + w[2] * f32::from(d[i + self.width])
                + w[3] * f32::from(d[i + self.width + 1]);
            f(q, v);
        }
    }
}

/// The limits of an [`Aligner`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlignOptions {
    /// Half the side of the patch, pixels.
    pub radius: usize,
    /// How far the aligned position may lie from the guess, pixels.
    pub max_shift: f32,
    /// Gauss–Newton steps at most.
    pub iterations: usize,
    /// The step (pixels) below which the alignment has converged.
    pub converged: f32,
    /// The least normalised correlation of the aligned patches.
    pub min_correlation: f32,
}

impl Default for AlignOptions {
    fn default() -> Self {
        Self {
            radius: 7,
            max_shift: 2.0,
            iterations: 20,
            converged: 1e-2,
            min_correlation: 0.8,
        }
    }
}

/// [`AlignOptions`] with the patch's weights computed once: aligns many
/// matches ([`Aligner::align`]).
#[derive(Clone, Debug)]
pub struct Aligner {
    options: AlignOptions,
    /// Per patch pixel: its offset from the centre and its weight.
    weights: Vec<(isize, isize, f32)>,
}

impl Aligner {
    /// The aligner of `options`.
    pub fn new(options: AlignOptions) -> Self {
        let ri = options.radius as isize;
        let sigma = (options.radius.max(1) as f32) / 2.0;
        let weights = (-ri..=ri)
            .flat_map(|dy| (-ri..=ri).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| {
                let d2 = (dx * dx + dy * dy) as f32;
                (dx, dy, (-d2 / (2.0 * sigma * sigma)).exp())
            })
            .collect();
        Self { options, weights }
    }

    /// Where in `b` the patch of `a` centred on pixel `at_a` lies,
    /// starting from `guess` (pixel coordinates, the centre of the top-left
    /// pixel at (0, 0)): see the module documentation. `None` when a patch
    /// leaves its image, the patch has no texture to align on, the
    /// alignment does not converge within `max_shift` of the guess, or the
    /// aligned patches correlate less than `min_correlation`.
    pub fn align(
        &self,
        a: &Gray<'_>,
        at_a: [usize; 2],
        b: &Gray<'_>,
        guess: [f32; 2],
    ) -> Option<[f32; 2]> {
        let o = &self.options;
        let r = o.radius;
        let [qx, qy] = at_a;
        // The template and its central differences stay inside.
        if qx < r + 1 || qy < r + 1 || qx + r + 1 >= a.width || qy + r + 1 >= a.height {
            return None;
        }
        // Per template pixel: its offset, weight, value and gradient; and
        // the weighted moments of value and gradient, which make the
        // Gauss–Newton matrix (B's gradient taken as the gain times the
        // template's, equal where the patches align).
        let mut m = [0.0f64; 10];
        let template: Vec<Texel> = self
            .weights
            .iter()
            .map(|&(dx, dy, w)| {
                let (x, y) = ((qx as isize + dx) as usize, (qy as isize + dy) as usize);
                let q = Texel {
                    dx,
                    dy,
                    w,
                    t: a.at(x, y),
                    gx: 0.5 * (a.at(x + 1, y) - a.at(x - 1, y)),
                    gy: 0.5 * (a.at(x, y + 1) - a.at(x, y - 1)),
                };
                let (w, t, gx, gy) = (
                    f64::from(w),
                    f64::from(q.t),
                    f64::from(q.gx),
                    f64::from(q.gy),
                );
                for (k, v) in [
                    gx * gx,
                    gx * gy,
                    gy * gy,
                    gx * t,
                    gy * t,
                    gx,
                    gy,
                    t * t,
                    t,
                    1.0,
                ]
                .into_iter()
                .enumerate()
                {
                    m[k] += w * v;
                }
                q
            })
            .collect();
        let [xx, xy, yy, xt, yt, x1, y1, tt, t1, w1] = m;
        // B's bilinear reads stay inside.
        let margin = r as f32 + 1.0;
        let inside = |p: [f32; 2]| {
            p[0] >= margin
                && p[1] >= margin
                && p[0] + margin < b.width as f32
                && p[1] + margin < b.height as f32
        };
        let (mut p, mut gain, mut offset) = (guess, 1.0f64, 0.0f64);
        let mut converged = false;
        for _ in 0..o.iterations {
            if !inside(p) {
                return None;
            }
            // Σ w·e·(gx, gy, t, 1) with e = B(p + x) − gain·T(x) − offset.
            let mut sums = [0.0f64; 4];
            b.patch(p, &template, |q, v| {
                let e = f64::from(q.w) * (f64::from(v) - gain * f64::from(q.t) - offset);
                sums[0] += e * f64::from(q.gx);
                sums[1] += e * f64::from(q.gy);
                sums[2] += e * f64::from(q.t);
                sums[3] += e;
            });
            let g2 = gain * gain;
            #[rustfmt::skip]
            let h = Matrix4::new(
                g2 * xx,     g2 * xy,     -gain * xt, -gain * x1,
                g2 * xy,     g2 * yy,     -gain * yt, -gain * y1,
                -gain * xt,  -gain * yt,  tt,         t1,
                -gain * x1,  -gain * y1,  t1,         w1,
            );
            let grad = Vector4::new(gain * sums[0], gain * sums[1], -sums[2], -sums[3]);
            let step = h.cholesky()?.solve(&(-grad));
            if !step.iter().all(|v| v.is_finite()) {
                return None;
            }
            p = [p[0] + step[0] as f32, p[1] + step[1] as f32];
            gain += step[2];
            offset += step[3];
            // (A step may overshoot on the way: only a divergence stops it.)
            if (p[0] - guess[0]).hypot(p[1] - guess[1]) > 2.0 * o.max_shift {
                return None;
            }
            if (step[0].hypot(step[1]) as f32) < o.converged {
                converged = true;
                break;
            }
        }
        let moved = (p[0] - guess[0]).hypot(p[1] - guess[1]);
        if !converged || moved > o.max_shift || !inside(p) || gain <= 0.0 {
            return None;
        }
        (correlation(&template, (w1, t1, tt), b, p)? >= o.min_correlation).then_some(p)
    }
}

/// A template pixel: its offset from the centre, weight, value and
/// gradient.
#[derive(Clone, Copy, Debug)]
struct Texel {
    dx: isize,
    dy: isize,
    w: f32,
    t: f32,
    gx: f32,
    gy: f32,
}

/// The weighted normalised correlation of the template and `b`'s patch at
/// `p`; `None` for a flat patch. `(sw, st, tt)` are the template's
/// weighted moments `Σw`, `Σw·t` and `Σw·t²`.
fn correlation(
    template: &[Texel],
    (sw, st, tt): (f64, f64, f64),
    b: &Gray<'_>,
    p: [f32; 2],
) -> Option<f32> {
    let (mut sv, mut vv, mut tv) = (0.0f64, 0.0, 0.0);
    b.patch(p, template, |q, v| {
        let (w, t, v) = (f64::from(q.w), f64::from(q.t), f64::from(v));
        sv += w * v;
        vv += w * v * v;
        tv += w * t * v;
    });
    let (mt, mv) = (st / sw, sv / sw);
    let (tt, vv, tv) = (tt - sw * mt * mt, vv - sw * mv * mv, tv - sw * mt * mv);
    (tt > 1e-9 && vv > 1e-9).then(|| (tv / (tt * vv).sqrt()) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth texture of blobs, `value(x, y)` at any real position.
    fn texture(x: f64, y: f64) -> f64 {
        let s = (0.31 * x + 0.07 * y).sin() * (0.23 * y - 0.11 * x).cos()
            + 0.5 * (0.53 * x + 0.41 * y).sin();
        100.0 + 50.0 * s
    }

    fn image(w: usize, h: usize, f: impl Fn(f64, f64) -> f64) -> Vec<u8> {
        (0..w * h)
            .map(|q| f((q % w) as f64, (q / w) as f64).round().clamp(0.0, 255.0) as u8)
            .collect()
    }

    #[test]
    fn a_shifted_and_brightened_patch_is_found_to_a_twentieth_of_a_pixel() {
        let (w, h) = (64, 64);
        let a = image(w, h, texture);
        for &(sx, sy) in &[(0.3, -0.45), (-1.2, 0.7), (0.0, 0.0), (1.6, 1.1)] {
            // B is A shifted by (sx, sy), 40 % brighter and offset.
            let b = image(w, h, |x, y| 1.4 * texture(x - sx, y - sy) - 20.0);
            let (ga, gb) = (Gray::new(&a, w, h).unwrap(), Gray::new(&b, w, h).unwrap());
            let found = Aligner::new(AlignOptions::default())
                .align(&ga, [30, 32], &gb, [30.0, 32.0])
                .expect("aligned");
            let (ex, ey) = (found[0] - 30.0 - sx as f32, found[1] - 32.0 - sy as f32);
            assert!(
                ex.hypot(ey) < 0.05,
                "shift ({sx}, {sy}): found {found:?}, off by ({ex}, {ey})"
            );
        }
    }

    #[test]
    fn a_flat_patch_a_patch_at_the_edge_and_an_unrelated_patch_are_refused() {
        let (w, h) = (64, 64);
        let a = image(w, h, texture);
        let flat = vec![90u8; w * h];
        let other = image(w, h, |x, y| texture(y * 1.7 + 5.0, x * 0.6));
        let gray = |d| Gray::new(d, w, h).unwrap();
        let aligner = Aligner::new(AlignOptions::default());
        let align = |a: &Gray<'_>, at, b: &Gray<'_>, guess| aligner.align(a, at, b, guess);
        assert_eq!(align(&gray(&flat), [30, 30], &gray(&a), [30.0, 30.0]), None);
        assert_eq!(align(&gray(&a), [30, 30], &gray(&flat), [30.0, 30.0]), None);
        assert_eq!(align(&gray(&a), [3, 30], &gray(&a), [3.0, 30.0]), None);
        assert_eq!(align(&gray(&a), [30, 30], &gray(&a), [60.0, 30.0]), None);
        assert_eq!(
            align(&gray(&a), [30, 30], &gray(&other), [30.0, 30.0]),
            None
        );
    }
}
