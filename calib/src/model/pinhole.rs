//! OpenCV's pinhole distortion (radial-tangential and rational): the
//! distortion, where it is one to one, and its inversion. The unified
//! model applies it on its projection plane too.

use nalgebra::Matrix2;

use super::{cached, first_stationary, invert_increasing, Family};

/// The radial factor of OpenCV's pinhole distortion at r² = `s`,
/// (1 + k1 s + k2 s² + k3 s³) / (1 + k4 s + k5 s² + k6 s³), with its
/// numerator, denominator and their derivatives in s.
struct Radial {
    n: f64,
    d: f64,
    dn: f64,
    dd: f64,
}

impl Radial {
    fn at(k: &[f64; 8], s: f64) -> Self {
        let [k1, k2, _, _, k3, k4, k5, k6] = *k;
        Self {
            n: 1.0 + s * (k1 + s * (k2 + s * k3)),
            d: 1.0 + s * (k4 + s * (k5 + s * k6)),
            dn: k1 + s * (2.0 * k2 + s * 3.0 * k3),
            dd: k4 + s * (2.0 * k5 + s * 3.0 * k6),
        }
    }

    /// The factor.
    fn value(&self) -> f64 {
        self.n / self.d
    }

    /// Its derivative in s.
    fn slope(&self) -> f64 {
        (self.dn * self.d - self.n * self.dd) / (self.d * self.d)
    }
}

/// OpenCV's pinhole distortion (k1, k2, p1, p2, k3, k4, k5, k6) of a
/// normalised point.
pub(super) fn pinhole_distort(k: &[f64; 8], a: f64, b: f64) -> (f64, f64) {
    let [_, _, p1, p2, ..] = *k;
    let r2 = a * a + b * b;
    let radial = Radial::at(k, r2).value();
    (
        a * radial + 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a),
        b * radial + p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b,
    )
}

/// `∂(xd, yd)/∂(a, b)` of [`pinhole_distort`].
pub(super) fn distort_jacobian(k: &[f64; 8], a: f64, b: f64) -> Matrix2<f64> {
    let [_, _, p1, p2, ..] = *k;
    let radial = Radial::at(k, a * a + b * b);
    let (f, df) = (radial.value(), radial.slope());
    // r² = a² + b², so ∂f/∂a = 2a·f' and ∂f/∂b = 2b·f'.
    let cross = 2.0 * a * b * df + 2.0 * p1 * a + 2.0 * p2 * b;
    Matrix2::new(
        f + 2.0 * a * a * df + 2.0 * p1 * b + 6.0 * p2 * a,
        cross,
        cross,
        f + 2.0 * b * b * df + 6.0 * p1 * b + 2.0 * p2 * a,
    )
}

/// The largest r² = (x/z)² + (y/z)² up to which the model is one to one:
/// the distorted radius r·factor(r²) still increases, the factor's
/// denominator is positive, and the tangential terms do not fold the image
/// (the Jacobian's determinant is positive at every angle). Capped at
/// tan²(89.9°).
pub(super) fn pinhole_r2_max(k: &[f64; 8]) -> f64 {
    cached(Family::Pinhole, k, || pinhole_r2_max_uncached(k))
}

/// Positive where the pinhole model is locally one to one at r² = `s` (the
/// distorted radius increases and the Jacobian's determinant is positive
/// at every angle; see [`pinhole_r2_max`]). With the radial factor R, A = d(r R)/dr and
/// q = (p2, p1) at an angle φ from the point's direction, the Jacobian's
/// determinant is (A + 6 r|q| cos φ)(R + 2 r|q| cos φ) − 4 r²|q|² sin² φ,
/// a quadratic in cos φ whose least value over φ is taken here.
fn pinhole_one_to_one(k: &[f64; 8], s: f64) -> f64 {
    let q = Radial::at(k, s);
    if q.d <= 0.0 {
        // Past the denominator's pole.
        return -1.0;
    }
    let b = q.value();
    let a = b + 2.0 * s * q.slope();
    let c = s.sqrt() * k[2].hypot(k[3]);
    if c == 0.0 {
        return a;
    }
    let t = (-(a + 3.0 * b) / (16.0 * c)).clamp(-1.0, 1.0);
    let det = a * b - 4.0 * c * c + 2.0 * c * (a + 3.0 * b) * t + 16.0 * c * c * t * t;
    a.min(det)
}

fn pinhole_r2_max_uncached(k: &[f64; 8]) -> f64 {
    let cap = 89.9_f64.to_radians().tan().powi(2);
    // Scanned on a geometric grid because the cap is large.
    let d = |s: f64| pinhole_one_to_one(k, s);
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

/// Inverts OpenCV's pinhole distortion: the radial part alone first (a
/// bracketed Newton on the valid radii), then Newton's method on both
/// coordinates with the tangential terms. `None` if that does not converge
/// to the distorted point inside the valid region.
pub(super) fn pinhole_undistort(k: &[f64; 8], r2_max: f64, xd: f64, yd: f64) -> Option<(f64, f64)> {
    let [_, _, p1, p2, ..] = *k;
    let rd = xd.hypot(yd);
    let (mut a, mut b) = if rd > 0.0 {
        let r = invert_increasing(
            |r| {
                let q = Radial::at(k, r * r);
                (r * q.value(), q.value() + 2.0 * r * r * q.slope())
            },
            rd,
            r2_max.sqrt(),
        );
        (xd * r / rd, yd * r / rd)
    } else {
        (0.0, 0.0)
    };
    for _ in 0..100 {
        let r2 = a * a + b * b;
        if r2 > r2_max {
            // Outside: pull back into the valid region.
            let s = (r2_max / r2).sqrt() * (1.0 - 1e-9);
            a *= s;
            b *= s;
            continue;
        }
        let q = Radial::at(k, r2);
        let (radial, dradial) = (q.value(), q.slope());
        let (fx, fy) = pinhole_distort(k, a, b);
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
    let (fx, fy) = pinhole_distort(k, a, b);
    let err = (fx - xd).hypot(fy - yd);
    let ok = err <= 1e-12 * (1.0 + xd.hypot(yd)) && a * a + b * b <= r2_max;
    ok.then_some((a, b))
}
