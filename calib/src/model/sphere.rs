//! The models that project through a unit sphere: double sphere (Usenko,
//! Demmel and Cremers 2018), the extended unified model (EUCM, Khomutenko,
//! Garcia and Martinet 2016) and the unified model of Mei and Rives (2007)
//! with radial-tangential distortion on its projection plane (OpenCV's
//! `omnidir`, Kalibr's `omni-radtan`).
//!
//! Each maps a point to normalised coordinates `m` (the pixel is
//! `(fx·mx + cx, fy·my + cy)`) and back in closed form, except the unified
//! model's distortion, which is inverted iteratively as the pinhole
//! model's is. Each is valid on a cone about the optical axis, given in
//! closed form by the paper that defines it: outside, `project` and
//! `unproject` return `None`.
//!
//! - **Double sphere** `[ξ, α]`: `d₁ = |p|`, `k = ξ·d₁ + z`,
//!   `d₂ = √(x² + y² + k²)`, `m = (x, y) / (α·d₂ + (1 − α)·k)`; valid where
//!   `z > −w₂·d₁`, with `w₁ = α/(1 − α)` for `α ≤ ½` and `(1 − α)/α`
//!   above, and `w₂ = (w₁ + ξ)/√(2·w₁·ξ + ξ² + 1)`.
//! - **EUCM** `[α, β]`: `ρ = √(β·(x² + y²) + z²)`,
//!   `m = (x, y) / (α·ρ + (1 − α)·z)`; valid where `z > −w·ρ`, with `w` as
//!   `w₁` above.
//! - **Unified** `[ξ, k1, k2, p1, p2]`: `m = (x, y) / (z + ξ·|p|)`, then
//!   OpenCV's radial-tangential distortion of `m`; valid where
//!   `z > −ξ'·|p|`, `ξ' = ξ` for `ξ ≤ 1` and `1/ξ` above (Kalibr's rule),
//!   and where the distortion is one to one.

use nalgebra::Vector3;

/// `w₁` of the double-sphere and extended unified models.
fn w1(alpha: f64) -> f64 {
    if alpha <= 0.5 {
        alpha / (1.0 - alpha)
    } else {
        (1.0 - alpha) / alpha
    }
}

/// The cosine of the largest angle from the optical axis a double-sphere
/// camera projects: `−w₂`.
pub(super) fn double_sphere_cos_max(xi: f64, alpha: f64) -> f64 {
    let w1 = w1(alpha);
    -((w1 + xi) / (2.0 * w1 * xi + xi * xi + 1.0).sqrt())
}

/// Double sphere: `p` to normalised coordinates.
pub(super) fn double_sphere_project(xi: f64, alpha: f64, p: &Vector3<f64>) -> Option<(f64, f64)> {
    let r2 = p.x * p.x + p.y * p.y;
    let d1 = (r2 + p.z * p.z).sqrt();
    if !(d1 > 0.0 && d1.is_finite()) || p.z <= double_sphere_cos_max(xi, alpha) * d1 {
        return None;
    }
    let k = xi * d1 + p.z;
    let d2 = (r2 + k * k).sqrt();
    let norm = alpha * d2 + (1.0 - alpha) * k;
    (norm > 0.0).then(|| (p.x / norm, p.y / norm))
}

/// Double sphere: normalised coordinates to the ray (not unit).
pub(super) fn double_sphere_unproject(
    xi: f64,
    alpha: f64,
    mx: f64,
    my: f64,
) -> Option<Vector3<f64>> {
    let r2 = mx * mx + my * my;
    let q = 1.0 - (2.0 * alpha - 1.0) * r2;
    if q < 0.0 {
        return None;
    }
    let mz = (1.0 - alpha * alpha * r2) / (alpha * q.sqrt() + 1.0 - alpha);
    let disc = mz * mz + (1.0 - xi * xi) * r2;
    if disc < 0.0 {
        return None;
    }
    let k = (mz * xi + disc.sqrt()) / (mz * mz + r2);
    let p = Vector3::new(k * mx, k * my, k * mz - xi);
    // Beyond the valid cone the formula answers with a point that projects
    // elsewhere (the model folds over there).
    (p.z > double_sphere_cos_max(xi, alpha) * p.norm()).then_some(p)
}

/// The largest angle from the optical axis an extended unified camera
/// projects, radians.
pub(super) fn eucm_theta_max(alpha: f64, beta: f64) -> f64 {
    let w = w1(alpha);
    if w >= 1.0 {
        return std::f64::consts::PI;
    }
    // cos θ = −w·√(β sin²θ + cos²θ) on the boundary: tan²θ = (1 − w²)/(w² β).
    std::f64::consts::PI - ((1.0 - w * w) / (w * w * beta)).sqrt().atan()
}

/// Extended unified: `p` to normalised coordinates.
pub(super) fn eucm_project(alpha: f64, beta: f64, p: &Vector3<f64>) -> Option<(f64, f64)> {
    let r2 = p.x * p.x + p.y * p.y;
    let rho = (beta * r2 + p.z * p.z).sqrt();
    if !(rho > 0.0 && rho.is_finite()) || p.z <= -w1(alpha) * rho {
        return None;
    }
    let norm = alpha * rho + (1.0 - alpha) * p.z;
    (norm > 0.0).then(|| (p.x / norm, p.y / norm))
}

/// Extended unified: normalised coordinates to the ray (not unit).
pub(super) fn eucm_unproject(alpha: f64, beta: f64, mx: f64, my: f64) -> Option<Vector3<f64>> {
    let r2 = mx * mx + my * my;
    let gamma = 1.0 - alpha;
    let q = 1.0 - (alpha - gamma) * beta * r2;
    if q < 0.0 {
        return None;
    }
    let mz = (1.0 - alpha * alpha * beta * r2) / (alpha * q.sqrt() + gamma);
    let p = Vector3::new(mx, my, mz);
    let rho = (beta * r2 + mz * mz).sqrt();
    (mz > -w1(alpha) * rho).then_some(p)
}

/// `ξ'` of the unified model: the cosine bound of its valid cone is `−ξ'`.
pub(super) fn unified_cos_max(xi: f64) -> f64 {
    -(if xi <= 1.0 { xi } else { 1.0 / xi })
}

/// Unified: `p` to undistorted normalised coordinates (before the
/// radial-tangential distortion).
pub(super) fn unified_project(xi: f64, p: &Vector3<f64>) -> Option<(f64, f64)> {
    let d = p.norm();
    if !(d > 0.0 && d.is_finite()) || p.z <= unified_cos_max(xi) * d {
        return None;
    }
    let den = p.z + xi * d;
    (den > 0.0).then(|| (p.x / den, p.y / den))
}

/// Unified: undistorted normalised coordinates to the ray (not unit).
pub(super) fn unified_unproject(xi: f64, mx: f64, my: f64) -> Option<Vector3<f64>> {
    let r2 = mx * mx + my * my;
    let disc = 1.0 + (1.0 - xi * xi) * r2;
    if disc < 0.0 {
        return None;
    }
    let f = (xi + disc.sqrt()) / (r2 + 1.0);
    let p = Vector3::new(f * mx, f * my, f - xi);
    (p.z > unified_cos_max(xi) * p.norm()).then_some(p)
}

/// The largest angle from the optical axis a unified camera projects with
/// its distortion one to one up to `r2_max` on the projection plane.
pub(super) fn unified_theta_max(xi: f64, r2_max: f64) -> f64 {
    let cone = unified_cos_max(xi).acos();
    // |m|(θ) = sin θ / (cos θ + ξ) increases on the cone: bisect for the
    // θ where it reaches √r2_max, if it does.
    let m = |t: f64| t.sin() / (t.cos() + xi);
    let target = r2_max.sqrt();
    let edge = cone * (1.0 - 1e-12);
    if m(edge).is_nan() || m(edge) <= target {
        return cone;
    }
    let (mut lo, mut hi) = (0.0, edge);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if m(mid) > target {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}
