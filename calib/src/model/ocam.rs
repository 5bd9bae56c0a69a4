//! Scaramuzza's omnidirectional model, as OCamCalib calibrates it.
//!
//! OCamCalib works on the sensor plane in (row, column) order: a pixel's
//! offset from the centre `(xc, yc)` (row, column) goes through the inverse
//! of the affine matrix `[[c, d], [e, 1]]` to `(x', y')`, and the ray is
//! `(x', y', pol(ρ))` with `ρ = |(x', y')|` (`cam2world`); `pol(0)` is
//! negative, so OCamCalib's z points away from the scene. In rigview's
//! camera frame (x right, y down, z along the optical axis) that ray is
//! `(y', x', −pol(ρ))`, and the pixel's column is rigview's `u`.
//!
//! `invpol` is OCamCalib's fitted inverse (`world2cam`): ρ as a polynomial
//! of `atan(z/‖(x, y)‖)`. It is an approximation of `pol`'s inverse (to
//! about a hundredth of a pixel), so rigview projects by inverting `pol`
//! itself (a bracketed Newton on the ray's angle, which increases with ρ
//! up to where the model folds), and the two directions agree to the
//! last bits; `invpol` is kept to write the file back.

use nalgebra::Vector3;

use crate::error::FieldError;

/// The most coefficients `pol` may have.
pub const MAX_POL: usize = 8;
/// The most coefficients `invpol` may have.
pub const MAX_INVPOL: usize = 24;

/// OCamCalib's parameters: `pol`, `invpol` and the affine `c, d, e` (the
/// centre is the intrinsics' principal point, and the focal length 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ocam {
    /// `c, d, e`, then `pol`, then `invpol`.
    values: [f64; 3 + MAX_POL + MAX_INVPOL],
    pol_len: u8,
    invpol_len: u8,
}

impl Ocam {
    /// The model of `pol` (ρ to z, lowest order first), `invpol` (angle
    /// to ρ, lowest order first) and the affine `[c, d, e]`.
    pub fn new(pol: &[f64], invpol: &[f64], affine: [f64; 3]) -> Result<Self, FieldError> {
        if pol.is_empty() || pol.len() > MAX_POL {
            return Err(FieldError::new(
                "pol",
                format!("1 to {MAX_POL} coefficients"),
                format!("{}", pol.len()),
            ));
        }
        if invpol.len() > MAX_INVPOL {
            return Err(FieldError::new(
                "invpol",
                format!("at most {MAX_INVPOL} coefficients"),
                format!("{}", invpol.len()),
            ));
        }
        let mut values = [0.0; 3 + MAX_POL + MAX_INVPOL];
        values[..3].copy_from_slice(&affine);
        values[3..3 + pol.len()].copy_from_slice(pol);
        values[3 + pol.len()..3 + pol.len() + invpol.len()].copy_from_slice(invpol);
        Ok(Self {
            values,
            pol_len: pol.len() as u8,
            invpol_len: invpol.len() as u8,
        })
    }

    /// `pol`: z of the ray at ρ on the sensor plane, lowest order first.
    pub fn pol(&self) -> &[f64] {
        &self.values[3..3 + usize::from(self.pol_len)]
    }

    /// `invpol`: ρ at the ray's angle, lowest order first.
    pub fn invpol(&self) -> &[f64] {
        let start = 3 + usize::from(self.pol_len);
        &self.values[start..start + usize::from(self.invpol_len)]
    }

    /// The affine parameters `[c, d, e]`.
    pub fn affine(&self) -> [f64; 3] {
        [self.values[0], self.values[1], self.values[2]]
    }

    /// Every number: `c, d, e`, `pol`, `invpol`.
    pub fn values(&self) -> &[f64] {
        &self.values[..3 + usize::from(self.pol_len) + usize::from(self.invpol_len)]
    }

    /// Checks what the model needs: `pol(0)` < 0 (the axis looks forward)
    /// and an invertible affine matrix (`c − d·e` ≠ 0).
    pub(super) fn validate(&self) -> Result<(), FieldError> {
        let [c, d, e] = self.affine();
        if (c - d * e).abs() < 1e-9 {
            return Err(FieldError::new(
                "affine",
                "an invertible affine matrix [[c, d], [e, 1]] (c − d·e ≠ 0)",
                format!("c = {c}, d = {d}, e = {e}"),
            ));
        }
        if self.pol()[0] >= 0.0 {
            return Err(FieldError::new(
                "pol",
                "a negative first coefficient (OCamCalib's z of the optical axis)",
                format!("{}", self.pol()[0]),
            ));
        }
        Ok(())
    }
}

fn poly(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &k| acc * x + k)
}

fn dpoly(c: &[f64], x: f64) -> f64 {
    c.iter()
        .enumerate()
        .skip(1)
        .rev()
        .fold(0.0, |acc, (i, &k)| acc * x + i as f64 * k)
}

/// The ray's angle from the optical axis at ρ, and its derivative in ρ.
fn angle(o: &Ocam, rho: f64) -> (f64, f64) {
    let z = -poly(o.pol(), rho);
    let dz = -dpoly(o.pol(), rho);
    (rho.atan2(z), (z - rho * dz) / (rho * rho + z * z))
}

/// The largest ρ up to which the ray's angle increases (≤ `cap`), kept
/// per thread as the other models' limits are (keyed by a hash of `pol`
/// and `cap`: it has up to 8 coefficients).
pub(super) fn rho_max(o: &Ocam, cap: f64) -> f64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for v in o.pol().iter().chain(std::iter::once(&cap)) {
        for b in v.to_bits().to_le_bytes() {
            hash = (hash ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    super::cached(super::Family::Ocam, &[f64::from_bits(hash)], || {
        super::first_stationary(|r| angle(o, r).1, cap, 4096)
    })
}

/// The largest angle from the optical axis the model reaches.
pub(super) fn theta_max(o: &Ocam, rho_max: f64) -> f64 {
    angle(o, rho_max).0
}

/// A point of the camera frame to the pixel offset `(column, row)` from
/// the centre; `None` beyond the model.
pub(super) fn project(o: &Ocam, rho_max: f64, p: &Vector3<f64>) -> Option<(f64, f64)> {
    // OCamCalib's axes: x along the rows, y along the columns.
    let (xo, yo) = (p.y, p.x);
    let norm = xo.hypot(yo);
    if norm == 0.0 {
        return (p.z > 0.0).then_some((0.0, 0.0));
    }
    let theta = norm.atan2(p.z);
    if theta.is_nan() || theta > theta_max(o, rho_max) {
        return None;
    }
    let rho = super::invert_increasing(|r| angle(o, r), theta, rho_max);
    let (x, y) = (xo / norm * rho, yo / norm * rho);
    let [c, d, e] = o.affine();
    Some((x * e + y, x * c + y * d))
}

/// ρ at the ray's angle θ from the optical axis and dρ/dθ (the inverse
/// of [`angle`]'s slope); θ within the model.
pub(super) fn radius(o: &Ocam, rho_max: f64, theta: f64) -> (f64, f64) {
    let rho = super::invert_increasing(|r| angle(o, r), theta, rho_max);
    (rho, 1.0 / angle(o, rho).1)
}

/// The pixel offset `(column, row)` from the centre to the ray (not unit);
/// `None` beyond the model.
pub(super) fn unproject(o: &Ocam, rho_max: f64, du: f64, dv: f64) -> Option<Vector3<f64>> {
    let [c, d, e] = o.affine();
    let det = c - d * e;
    let (row, col) = (dv, du);
    let x = (row - d * col) / det;
    let y = (-e * row + c * col) / det;
    let rho = x.hypot(y);
    if rho.is_nan() || rho > rho_max {
        return None;
    }
    Some(Vector3::new(y, x, -poly(o.pol(), rho)))
}

/// OCamCalib's own `world2cam` through `invpol`: the pixel offset
/// `(column, row)` from the centre. For checking a file's `invpol`
/// against its `pol`.
pub fn world2cam(o: &Ocam, p: &Vector3<f64>) -> (f64, f64) {
    let (xo, yo, zo) = (p.y, p.x, -p.z);
    let norm = xo.hypot(yo);
    if norm == 0.0 {
        return (0.0, 0.0);
    }
    let theta = (zo / norm).atan();
    let rho = poly(o.invpol(), theta);
    let (x, y) = (xo / norm * rho, yo / norm * rho);
    let [c, d, e] = o.affine();
    (x * e + y, x * c + y * d)
}
