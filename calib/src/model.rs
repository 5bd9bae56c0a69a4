//! Camera models: the OpenCV fisheye model (Kannala–Brandt with k1..k4, as
//! `cv::fisheye`) and the pinhole model with OpenCV's radial-tangential
//! distortion (k1, k2, p1, p2, k3, as `cv::projectPoints`).
//!
//! Camera frame: OpenCV's, x right, y down, z along the optical axis. Pixel
//! coordinates: OpenCV's, the centre of the top-left pixel is (0, 0).
//!
//! Each model knows where it is valid. The fisheye polynomial
//! θd(θ) = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸) is used up to the first θ
//! where it stops increasing (or π); the radial factor of the pinhole model
//! up to the first radius where r·(1 + k1 r² + k2 r⁴ + k3 r⁶) stops
//! increasing (and only in front of the camera). Outside, `project` and
//! `unproject` return `None` rather than a folded-over answer.
//!
//! Unlike `cv::fisheye`, which works with x/z and so only sees the forward
//! hemisphere, the fisheye model here takes θ = atan2(√(x²+y²), z), so a
//! 185° lens projects points slightly behind the camera plane. For z > 0
//! both agree exactly.

use nalgebra::{Point2, Unit, Vector3};

use crate::error::FieldError;

/// A camera model without its coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModelKind {
    /// OpenCV fisheye (Kannala–Brandt, k1..k4).
    Fisheye,
    /// Pinhole with radial-tangential distortion.
    Pinhole,
}

/// The lens model and its distortion coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distortion {
    /// OpenCV fisheye (Kannala–Brandt): `[k1, k2, k3, k4]`.
    Fisheye([f64; 4]),
    /// Pinhole with radial-tangential distortion: `[k1, k2, p1, p2, k3]`
    /// (OpenCV's order).
    RadTan([f64; 5]),
}

impl Distortion {
    /// The model's name in rig files: `fisheye` or `pinhole-radtan`.
    pub fn model_name(&self) -> &'static str {
        match self {
            Distortion::Fisheye(_) => "fisheye",
            Distortion::RadTan(_) => "pinhole-radtan",
        }
    }

    /// The model without its coefficients.
    pub fn kind(&self) -> ModelKind {
        match self {
            Distortion::Fisheye(_) => ModelKind::Fisheye,
            Distortion::RadTan(_) => ModelKind::Pinhole,
        }
    }

    /// The coefficients in OpenCV's order.
    pub fn coefficients(&self) -> &[f64] {
        match self {
            Distortion::Fisheye(k) => k,
            Distortion::RadTan(k) => k,
        }
    }

    /// Builds a model from its rig-file name and coefficients. For
    /// `pinhole-radtan`, 4 coefficients mean k3 = 0.
    pub fn from_name(name: &str, coefficients: &[f64]) -> Result<Self, FieldError> {
        match (name, coefficients.len()) {
            ("fisheye", 4) => Ok(Distortion::Fisheye([
                coefficients[0],
                coefficients[1],
                coefficients[2],
                coefficients[3],
            ])),
            ("pinhole-radtan", 4 | 5) => {
                let mut k = [0.0; 5];
                k[..coefficients.len()].copy_from_slice(coefficients);
                Ok(Distortion::RadTan(k))
            }
            ("fisheye", n) => Err(FieldError::new(
                "distortion",
                "4 fisheye coefficients k1..k4",
                format!("{n}"),
            )),
            (_, n) => Err(FieldError::new(
                "distortion",
                "4 or 5 radial-tangential coefficients k1, k2, p1, p2[, k3]",
                format!("{n}"),
            )),
        }
    }
}

/// The intrinsics of one camera: image size, focal lengths and principal
/// point in pixels, and the lens model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Lens model and coefficients.
    pub distortion: Distortion,
}

/// The angular field of view of a camera, measured by unprojecting its image
/// border. Each span is the sum of the two angles from the optical axis, so
/// a 185° lens shows 185, not 175.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldOfView {
    /// Across the image through the principal point's row, degrees (`None`
    /// where the border lies outside the model's valid region).
    pub horizontal_deg: Option<f64>,
    /// Down the image through the principal point's column, degrees.
    pub vertical_deg: Option<f64>,
    /// Between opposite image corners (the larger diagonal), degrees.
    pub diagonal_deg: Option<f64>,
    /// The largest angle from the optical axis where the model is valid,
    /// degrees.
    pub model_limit_deg: f64,
}

fn check_finite(field: &str, v: f64) -> Result<(), FieldError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(FieldError::new(field, "a finite number", format!("{v}")))
    }
}

impl Intrinsics {
    /// Checks that every number is finite, the image is not empty and the
    /// focal lengths are positive.
    pub fn validate(&self) -> Result<(), FieldError> {
        if self.width == 0 || self.height == 0 {
            return Err(FieldError::new(
                "resolution",
                "a width and height of at least 1 pixel",
                format!("{}×{}", self.width, self.height),
            ));
        }
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            check_finite(name, v)?;
            if v <= 0.0 {
                return Err(FieldError::new(
                    name,
                    "a positive focal length in pixels",
                    format!("{v}"),
                ));
            }
        }
        check_finite("cx", self.cx)?;
        check_finite("cy", self.cy)?;
        for (i, &k) in self.distortion.coefficients().iter().enumerate() {
            check_finite(&format!("distortion[{i}]"), k)?;
        }
        Ok(())
    }

    /// Projects a point in the camera frame to a pixel; `None` behind a
    /// pinhole camera, at the centre of projection, or outside the model's
    /// valid region.
    pub fn project(&self, p: &Vector3<f64>) -> Option<Point2<f64>> {
        let (xd, yd) = match self.distortion {
            Distortion::Fisheye(k) => {
                let r = p.x.hypot(p.y);
                if r == 0.0 && p.z <= 0.0 {
                    return None;
                }
                let theta = r.atan2(p.z);
                if theta > fisheye_theta_max(&k) {
                    return None;
                }
                let td = fisheye_theta_d(&k, theta);
                if r > 0.0 {
                    (td * p.x / r, td * p.y / r)
                } else {
                    (0.0, 0.0)
                }
            }
            Distortion::RadTan(k) => {
                if p.z <= 0.0 || !p.z.is_finite() {
                    return None;
                }
                let (a, b) = (p.x / p.z, p.y / p.z);
                if a * a + b * b > radtan_r2_max(&k) {
                    return None;
                }
                radtan_distort(&k, a, b)
            }
        };
        let u = self.fx * xd + self.cx;
        let v = self.fy * yd + self.cy;
        (u.is_finite() && v.is_finite()).then(|| Point2::new(u, v))
    }

    /// Unprojects a pixel to the unit ray it sees (camera frame); `None`
    /// outside the model's valid region.
    pub fn unproject(&self, px: &Point2<f64>) -> Option<Unit<Vector3<f64>>> {
        let xd = (px.x - self.cx) / self.fx;
        let yd = (px.y - self.cy) / self.fy;
        if !(xd.is_finite() && yd.is_finite()) {
            return None;
        }
        match self.distortion {
            Distortion::Fisheye(k) => {
                let td = xd.hypot(yd);
                if td == 0.0 {
                    return Some(Vector3::z_axis());
                }
                let theta = fisheye_theta_from_theta_d(&k, td)?;
                let s = theta.sin() / td;
                Some(Unit::new_normalize(Vector3::new(
                    s * xd,
                    s * yd,
                    theta.cos(),
                )))
            }
            Distortion::RadTan(k) => {
                let (a, b) = radtan_undistort(&k, xd, yd)?;
                Some(Unit::new_normalize(Vector3::new(a, b, 1.0)))
            }
        }
    }

    /// The largest angle from the optical axis where the model is valid,
    /// radians.
    pub fn max_incidence(&self) -> f64 {
        match self.distortion {
            Distortion::Fisheye(k) => fisheye_theta_max(&k),
            Distortion::RadTan(k) => radtan_r2_max(&k).sqrt().atan(),
        }
    }

    /// Whether a point in the camera frame projects into the image.
    pub fn sees(&self, p: &Vector3<f64>) -> bool {
        self.project(p).is_some_and(|q| self.contains(&q))
    }

    /// Whether a pixel position lies on the image (pixel centres 0..w−1,
    /// with half a pixel of border).
    pub fn contains(&self, px: &Point2<f64>) -> bool {
        px.x >= -0.5
            && px.y >= -0.5
            && px.x <= f64::from(self.width) - 0.5
            && px.y <= f64::from(self.height) - 0.5
    }

    /// The field of view, by unprojecting the image border.
    pub fn field_of_view(&self) -> FieldOfView {
        let (w, h) = (f64::from(self.width) - 1.0, f64::from(self.height) - 1.0);
        let angle = |x: f64, y: f64| {
            self.unproject(&Point2::new(x, y))
                .map(|r| r.z.clamp(-1.0, 1.0).acos().to_degrees())
        };
        let span = |a: Option<f64>, b: Option<f64>| a.zip(b).map(|(a, b)| a + b);
        let cx = self.cx.clamp(0.0, w);
        let cy = self.cy.clamp(0.0, h);
        let d1 = span(angle(0.0, 0.0), angle(w, h));
        let d2 = span(angle(w, 0.0), angle(0.0, h));
        FieldOfView {
            horizontal_deg: span(angle(0.0, cy), angle(w, cy)),
            vertical_deg: span(angle(cx, 0.0), angle(cx, h)),
            diagonal_deg: match (d1, d2) {
                (Some(a), Some(b)) => Some(a.max(b)),
                _ => None,
            },
            model_limit_deg: self.max_incidence().to_degrees(),
        }
    }

    /// The 3×3 camera matrix K, row-major.
    pub fn camera_matrix(&self) -> [[f64; 3]; 3] {
        [
            [self.fx, 0.0, self.cx],
            [0.0, self.fy, self.cy],
            [0.0, 0.0, 1.0],
        ]
    }
}

/// θd(θ) of the fisheye model.
pub(crate) fn fisheye_theta_d(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
}

/// dθd/dθ of the fisheye model.
fn fisheye_dtheta_d(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])))
}

/// The first root in (0, limit] of an increasing-at-zero function's
/// derivative `d`, or `limit` if it has none there: scanned in `steps`
/// steps, then bisected to full precision.
fn first_stationary(d: impl Fn(f64) -> f64, limit: f64, steps: usize) -> f64 {
    let mut prev = 0.0;
    for i in 1..=steps {
        let x = limit * i as f64 / steps as f64;
        if d(x) <= 0.0 {
            let (mut lo, mut hi) = (prev, x);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if d(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return lo;
        }
        prev = x;
    }
    limit
}

thread_local! {
    /// The last validity limit computed on this thread, by coefficient bits:
    /// projecting many points through one camera scans only once.
    static LIMIT_CACHE: std::cell::Cell<([u64; 5], bool, f64)> =
        const { std::cell::Cell::new(([0; 5], false, f64::NAN)) };
}

fn cached(key: [u64; 5], fisheye: bool, compute: impl FnOnce() -> f64) -> f64 {
    LIMIT_CACHE.with(|c| {
        let (k, f, v) = c.get();
        if k == key && f == fisheye && !v.is_nan() {
            return v;
        }
        let v = compute();
        c.set((key, fisheye, v));
        v
    })
}

/// The largest θ where the fisheye polynomial still increases (≤ π).
pub(crate) fn fisheye_theta_max(k: &[f64; 4]) -> f64 {
    let key = [
        k[0].to_bits(),
        k[1].to_bits(),
        k[2].to_bits(),
        k[3].to_bits(),
        0,
    ];
    cached(key, true, || {
        first_stationary(|t| fisheye_dtheta_d(k, t), std::f64::consts::PI, 4096)
    })
}

/// θ for a given θd (safeguarded Newton on [0, θmax]); `None` if θd is
/// beyond the valid region.
fn fisheye_theta_from_theta_d(k: &[f64; 4], td: f64) -> Option<f64> {
    let t_max = fisheye_theta_max(k);
    if td > fisheye_theta_d(k, t_max) {
        return None;
    }
    let (mut lo, mut hi) = (0.0, t_max);
    let mut t = td.min(t_max);
    for _ in 0..100 {
        let f = fisheye_theta_d(k, t) - td;
        if f > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let d = fisheye_dtheta_d(k, t);
        let mut next = t - f / d;
        if !(next > lo && next < hi) || d <= 0.0 {
            next = 0.5 * (lo + hi);
        }
        if (next - t).abs() <= 1e-16 * t.max(1.0) {
            return Some(next);
        }
        t = next;
    }
    Some(t)
}

/// Radial-tangential distortion of a normalised point.
fn radtan_distort(k: &[f64; 5], a: f64, b: f64) -> (f64, f64) {
    let [k1, k2, p1, p2, k3] = *k;
    let r2 = a * a + b * b;
    let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    (
        a * radial + 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a),
        b * radial + p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b,
    )
}

/// The largest r² = (x/z)² + (y/z)² where the radial factor still
/// increases, capped at tan²(89.9°).
pub(crate) fn radtan_r2_max(k: &[f64; 5]) -> f64 {
    cached(k.map(f64::to_bits), false, || radtan_r2_max_uncached(k))
}

fn radtan_r2_max_uncached(k: &[f64; 5]) -> f64 {
    let [k1, k2, _, _, k3] = *k;
    let cap = 89.9_f64.to_radians().tan().powi(2);
    // d/dr [r (1 + k1 r² + k2 r⁴ + k3 r⁶)] in s = r²; scanned on a
    // geometric grid because the cap is large.
    let d = |s: f64| 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3));
    let mut prev = 0.0;
    let mut s = 1e-4;
    while s < cap {
        if d(s) <= 0.0 {
            return first_stationary(|x| d(prev + x), s - prev, 64) + prev;
        }
        prev = s;
        s *= 1.05;
    }
    if d(cap) <= 0.0 {
        return first_stationary(|x| d(prev + x), cap - prev, 64) + prev;
    }
    cap
}

/// Inverts the radial-tangential distortion by Newton's method; `None` if
/// it does not converge inside the valid region.
fn radtan_undistort(k: &[f64; 5], xd: f64, yd: f64) -> Option<(f64, f64)> {
    let [k1, k2, p1, p2, k3] = *k;
    let r2_max = radtan_r2_max(k);
    let (mut a, mut b) = (xd, yd);
    for _ in 0..100 {
        let r2 = a * a + b * b;
        if r2 > 4.0 * r2_max {
            // Far outside: pull back towards the valid region.
            let s = (r2_max / r2).sqrt();
            a *= s;
            b *= s;
            continue;
        }
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let dradial = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3);
        let (fx, fy) = radtan_distort(k, a, b);
        let (ex, ey) = (fx - xd, fy - yd);
        let j11 = radial + 2.0 * a * a * dradial + 2.0 * p1 * b + 6.0 * p2 * a;
        let j12 = 2.0 * a * b * dradial + 2.0 * p1 * a + 2.0 * p2 * b;
        let j21 = j12;
        let j22 = radial + 2.0 * b * b * dradial + 6.0 * p1 * b + 2.0 * p2 * a;
        let det = j11 * j22 - j12 * j21;
        if det.abs() < 1e-300 || !det.is_finite() {
            return None;
        }
        let da = (j22 * ex - j12 * ey) / det;
        let db = (j11 * ey - j21 * ex) / det;
        a -= da;
        b -= db;
        if da.abs().max(db.abs()) <= 1e-16 * (1.0 + a.abs().max(b.abs())) {
            break;
        }
    }
    let (fx, fy) = radtan_distort(k, a, b);
    let err = (fx - xd).hypot(fy - yd);
    let ok = err <= 1e-12 * (1.0 + xd.hypot(yd)) && a * a + b * b <= r2_max;
    ok.then_some((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fisheye() -> Intrinsics {
        Intrinsics {
            width: 960,
            height: 640,
            fx: 302.45,
            fy: 320.75,
            cx: 496.6,
            cy: 331.2,
            distortion: Distortion::Fisheye([-0.0437, 0.0217, -0.0264, 0.0084]),
        }
    }

    #[test]
    fn fisheye_round_trip_beyond_ninety_degrees() {
        let cam = fisheye();
        let t_max = cam.max_incidence();
        assert!(t_max > 95f64.to_radians(), "θmax = {}", t_max.to_degrees());
        for i in 0..200 {
            let theta = t_max * 0.999 * f64::from(i) / 199.0;
            let phi = f64::from(i) * 0.7;
            let ray = Vector3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let px = cam.project(&(ray * 3.0)).unwrap();
            let back = cam.unproject(&px).unwrap();
            assert!((back.into_inner() - ray).norm() < 1e-12, "θ = {theta}");
        }
    }

    #[test]
    fn radtan_folds_are_invalid() {
        // k1 < 0 folds at r² = −1/(3 k1).
        let k = [-0.3, 0.0, 0.0, 0.0, 0.0];
        let r2 = radtan_r2_max(&k);
        assert!((r2 - 1.0 / 0.9).abs() < 1e-9, "{r2}");
        let cam = Intrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
            distortion: Distortion::RadTan(k),
        };
        assert!(cam.project(&Vector3::new(2.0, 0.0, 1.0)).is_none());
        assert!(cam.project(&Vector3::new(0.5, 0.0, -1.0)).is_none());
        assert!(cam.project(&Vector3::new(0.5, 0.2, 1.0)).is_some());
    }

    #[test]
    fn validate_names_the_field() {
        let mut cam = fisheye();
        cam.fy = -3.0;
        let e = cam.validate().unwrap_err();
        assert_eq!(e.field, "fy");
        cam.fy = 300.0;
        cam.distortion = Distortion::Fisheye([0.0, f64::NAN, 0.0, 0.0]);
        assert_eq!(cam.validate().unwrap_err().field, "distortion[1]");
    }
}
