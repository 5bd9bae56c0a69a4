//! The projection's Jacobian: how a pixel moves with the point it shows,
//! `∂(u, v)/∂(x, y, z)` in the camera frame, in closed form for every
//! model. A solver that moves points or cameras (a pose, a bundle
//! adjustment) chains it with the point's own derivative. The panorama's
//! refinement needs none: it compares rays, which unprojection gives.
//!
//! Every model maps the point to normalised coordinates `(xd, yd)` and
//! then `u = fx·xd + cx`, `v = fy·yd + cy`, so each part below is the
//! Jacobian of `(xd, yd)`:
//! - **radial models** (Kannala–Brandt, WoodScape, Scaramuzza):
//!   `(xd, yd) = ρ(θ)·(x, y)/r` with `r = √(x² + y²)` and `θ = atan2(r, z)`;
//! - **pinhole models** (radial-tangential, rational, field of view):
//!   the distortion of `(x/z, y/z)`;
//! - **sphere models**: `(x, y)/n(p)` with the model's own denominator,
//!   and for the unified model the pinhole distortion and skew after it.

use nalgebra::{Matrix2, Matrix2x3, Point2, RowVector3, Vector3};

use super::{ocam, pinhole, project_within, Distortion, Intrinsics};

/// The pixel of `p` and its Jacobian, with the model's validity limit
/// given; `None` where [`project_within`] has no pixel.
pub(super) fn project_jacobian_within(
    m: &Intrinsics,
    limit: f64,
    p: &Vector3<f64>,
) -> Option<(Point2<f64>, Matrix2x3<f64>)> {
    let px = project_within(m, limit, p)?;
    let j = match m.distortion {
        Distortion::Fisheye(k) => radial(p, |t| {
            (
                super::fisheye_theta_d(&k, t),
                super::fisheye_dtheta_d(&k, t),
            )
        }),
        Distortion::RadialPoly(k) => {
            radial(p, |t| (super::poly_rho(&k, t), super::poly_drho(&k, t)))
        }
        Distortion::Scaramuzza(o) => scaramuzza(&o, limit, p),
        Distortion::RadTan(_) | Distortion::Rational(_) => {
            pinhole::distort_jacobian(&m.distortion.pinhole()?, p.x / p.z, p.y / p.z)
                * perspective(p)
        }
        Distortion::Fov([w]) => fov(w, p.x / p.z, p.y / p.z) * perspective(p),
        Distortion::DoubleSphere([xi, alpha]) => {
            let d1 = p.norm();
            let k = xi * d1 + p.z;
            let dk = p.transpose() * (xi / d1) + RowVector3::new(0.0, 0.0, 1.0);
            let d2 = (p.x * p.x + p.y * p.y + k * k).sqrt();
            let dd2 = (RowVector3::new(p.x, p.y, 0.0) + dk * k) / d2;
            quotient(
                p,
                alpha * d2 + (1.0 - alpha) * k,
                dd2 * alpha + dk * (1.0 - alpha),
            )
        }
        Distortion::Eucm([alpha, beta]) => {
            let rho = (beta * (p.x * p.x + p.y * p.y) + p.z * p.z).sqrt();
            let drho = RowVector3::new(beta * p.x, beta * p.y, p.z) / rho;
            quotient(
                p,
                alpha * rho + (1.0 - alpha) * p.z,
                drho * alpha + RowVector3::new(0.0, 0.0, 1.0) * (1.0 - alpha),
            )
        }
        Distortion::Omni([xi, .., skew]) => {
            let d = p.norm();
            let den = p.z + xi * d;
            let plane = quotient(
                p,
                den,
                RowVector3::new(0.0, 0.0, 1.0) + p.transpose() * (xi / d),
            );
            let skewed = Matrix2::new(1.0, skew / m.fx, 0.0, 1.0);
            skewed
                * pinhole::distort_jacobian(&m.distortion.pinhole()?, p.x / den, p.y / den)
                * plane
        }
    };
    let j = Matrix2::new(m.fx, 0.0, 0.0, m.fy) * j;
    j.iter().all(|v| v.is_finite()).then_some((px, j))
}

/// `∂(x/z, y/z)/∂p`.
fn perspective(p: &Vector3<f64>) -> Matrix2x3<f64> {
    let iz = 1.0 / p.z;
    Matrix2x3::new(iz, 0.0, -p.x * iz * iz, 0.0, iz, -p.y * iz * iz)
}

/// `∂((x, y)/n)/∂p` for a denominator `n(p)` with gradient `dn`.
fn quotient(p: &Vector3<f64>, n: f64, dn: RowVector3<f64>) -> Matrix2x3<f64> {
    let mut j = Matrix2x3::new(1.0 / n, 0.0, 0.0, 0.0, 1.0 / n, 0.0);
    let s = 1.0 / (n * n);
    j.set_row(0, &(j.row(0) - dn * (p.x * s)));
    j.set_row(1, &(j.row(1) - dn * (p.y * s)));
    j
}

/// `∂(ρ(θ)·(x, y)/r)/∂p` for a radius `rho` giving `(ρ(θ), ρ'(θ))`.
fn radial(p: &Vector3<f64>, rho: impl Fn(f64) -> (f64, f64)) -> Matrix2x3<f64> {
    let r = p.x.hypot(p.y);
    let (value, slope) = rho(r.atan2(p.z));
    if r == 0.0 {
        // On the axis (in front: `project` refuses the point behind), ρ/r
        // tends to ρ'(0)/z in every direction.
        let s = slope / p.z;
        return Matrix2x3::new(s, 0.0, 0.0, 0.0, s, 0.0);
    }
    let (ux, uy) = (p.x / r, p.y / r);
    let n2 = r * r + p.z * p.z;
    // ∂θ/∂p, then ρ'·u·∂θ/∂p + (ρ/r)·(I − u uᵀ) on the first two columns.
    let dtheta = RowVector3::new(p.z * ux / n2, p.z * uy / n2, -r / n2);
    let g = value / r;
    let mut j = Matrix2x3::new(
        g * uy * uy,
        -g * ux * uy,
        0.0,
        -g * ux * uy,
        g * ux * ux,
        0.0,
    );
    j.set_row(0, &(j.row(0) + dtheta * (slope * ux)));
    j.set_row(1, &(j.row(1) + dtheta * (slope * uy)));
    j
}

/// Scaramuzza's model: radial in OCamCalib's axes (x along the rows),
/// with `ρ(θ)` the inverse of the ray's angle (so `ρ' = 1/θ'(ρ)`), then
/// the affine matrix.
fn scaramuzza(o: &ocam::Ocam, limit: f64, p: &Vector3<f64>) -> Matrix2x3<f64> {
    let radial_j = radial(p, |theta| ocam::radius(o, limit, theta));
    // (x, y) in OCamCalib's axes are rigview's rows 1 and 0; column =
    // e·x + y, row = c·x + d·y.
    let [c, d, e] = o.affine();
    Matrix2::new(1.0, e, d, c) * radial_j
}

/// `∂(xd, yd)/∂(a, b)` of the field-of-view distortion
/// `(a, b)·s(r)`, `s(r) = atan(2 r tan(ω/2))/(ω r)`.
fn fov(w: f64, a: f64, b: f64) -> Matrix2<f64> {
    let r = a.hypot(b);
    if w.abs() < 1e-8 {
        return Matrix2::identity();
    }
    let t = (w / 2.0).tan();
    // s(r) and s'(r)/r, by their series near the centre (s is even in r).
    let (s, ds_over_r) = if r < 1e-6 {
        let s0 = 2.0 * t / w;
        (s0, -s0 * 8.0 * t * t / 3.0)
    } else {
        let u = 2.0 * r * t;
        let s = u.atan() / (w * r);
        let ds = (2.0 * t / (1.0 + u * u)) / (w * r) - s / r;
        (s, ds / r)
    };
    Matrix2::new(
        s + ds_over_r * a * a,
        ds_over_r * a * b,
        ds_over_r * a * b,
        s + ds_over_r * b * b,
    )
}

#[cfg(test)]
mod tests {
    use super::super::ocam::Ocam;
    use super::super::tests::sphere_camera;
    use super::*;

    /// The central difference of `project` at `p`, step `h` relative to
    /// |p|.
    fn numeric(k: &Intrinsics, p: &Vector3<f64>) -> Matrix2x3<f64> {
        let h = 1e-6 * p.norm();
        let mut j = Matrix2x3::zeros();
        for c in 0..3 {
            let mut e = Vector3::zeros();
            e[c] = h;
            let (Some(a), Some(b)) = (k.project(&(p + e)), k.project(&(p - e))) else {
                panic!("{p} is too close to the edge of the model");
            };
            j.set_column(c, &((a - b) / (2.0 * h)));
        }
        j
    }

    fn cameras() -> Vec<(&'static str, Intrinsics)> {
        let base = sphere_camera(Distortion::Fisheye([-0.0437, 0.0217, -0.0264, 0.0084]));
        let with = |d| Intrinsics {
            distortion: d,
            ..base
        };
        let ocam = Ocam::new(
            &[-280.0, 0.0, 1.1e-3, -2.0e-7, 3.0e-10],
            &[],
            [1.002, 0.003, -0.004],
        )
        .unwrap();
        vec![
            ("fisheye", base),
            (
                "radtan",
                with(Distortion::RadTan([-0.28, 0.07, 0.001, -0.002, -0.01])),
            ),
            (
                "rational",
                with(Distortion::Rational([
                    0.4, -0.05, 0.001, 0.002, 0.01, 0.7, -0.02, 0.005,
                ])),
            ),
            ("double sphere", with(Distortion::DoubleSphere([-0.2, 0.6]))),
            ("eucm", with(Distortion::Eucm([0.6, 1.1]))),
            (
                "omni",
                with(Distortion::Omni([0.9, -0.1, 0.02, 0.001, -0.002, 0.7])),
            ),
            (
                "radial poly",
                Intrinsics {
                    fx: 1.0,
                    fy: 1.02,
                    distortion: Distortion::RadialPoly([339.749, -31.988, 48.275, -7.201]),
                    ..base
                },
            ),
            (
                "scaramuzza",
                Intrinsics {
                    fx: 1.0,
                    fy: 1.0,
                    distortion: Distortion::Scaramuzza(ocam),
                    ..base
                },
            ),
            ("fov", with(Distortion::Fov([0.9]))),
        ]
    }

    #[test]
    fn every_models_jacobian_agrees_with_finite_differences() {
        for (name, k) in cameras() {
            let t_max = k.max_incidence().min(1.55);
            let projector = k.projector();
            let mut checked = 0;
            for i in 0..=24 {
                // From the axis (and a hair off it) to 0.97 of the field.
                let theta = match i {
                    0 => 0.0,
                    1 => 1e-7,
                    _ => 0.97 * t_max * f64::from(i) / 24.0,
                };
                for j in 0..7 {
                    let phi = 0.3 + std::f64::consts::TAU * f64::from(j) / 7.0;
                    let (s, c) = theta.sin_cos();
                    let p = Vector3::new(s * phi.cos(), s * phi.sin(), c) * 2.5;
                    let (px, jac) = k
                        .project_jacobian(&p)
                        .unwrap_or_else(|| panic!("{name}: no Jacobian at θ {theta}"));
                    assert_eq!(px, k.project(&p).unwrap(), "{name}");
                    assert_eq!(projector.project_jacobian(&p), Some((px, jac)), "{name}");
                    let want = numeric(&k, &p);
                    let scale = want.norm().max(1.0);
                    let err = (jac - want).norm() / scale;
                    assert!(
                        err < 2e-6,
                        "{name} θ {theta:.4} φ {phi:.2}: {jac} against {want} ({err:e})"
                    );
                    checked += 1;
                }
            }
            assert_eq!(checked, 25 * 7, "{name}");
            // Nothing where the model has no pixel.
            assert!(
                k.project_jacobian(&Vector3::new(0.0, 0.0, -1.0)).is_none(),
                "{name}"
            );
        }
    }

    #[test]
    fn the_jacobian_moves_the_pixel_as_a_small_step_does() {
        // A first-order prediction of a 1e-4 step is good to second order
        // (~1e-8 of the step's pixel motion), on every model.
        for (name, k) in cameras() {
            let p = Vector3::new(0.4, -0.25, 0.9);
            let step = Vector3::new(1e-4, 2e-4, -1e-4);
            let (q, jac) = k.project_jacobian(&p).unwrap();
            let moved = k.project(&(p + step)).unwrap();
            let predicted = q + jac * step;
            let motion = (moved - q).norm();
            assert!(motion > 1e-3, "{name}: {motion}");
            assert!(
                (moved - predicted).norm() < 1e-3 * motion,
                "{name}: {moved} against {predicted}"
            );
        }
    }
}
