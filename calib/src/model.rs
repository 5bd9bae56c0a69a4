//! Camera models: the OpenCV fisheye model (Kannala–Brandt with k1..k4, as
//! `cv::fisheye`), the pinhole model with OpenCV's radial-tangential
//! distortion (k1, k2, p1, p2, k3, as `cv::projectPoints`) and the pinhole
//! model with OpenCV's rational distortion (k1, k2, p1, p2, k3, k4, k5, k6:
//! `cv::projectPoints` with 8 coefficients, `CALIB_RATIONAL_MODEL`, ROS's
//! `rational_polynomial`); WoodScape's radial polynomial; and, in
//! submodules, the models that project through a sphere (double sphere,
//! extended unified, unified/Mei: `sphere.rs`) and Scaramuzza's ([`ocam`]).
//!
//! Camera frame: OpenCV's, x right, y down, z along the optical axis. Pixel
//! coordinates: OpenCV's, the centre of the top-left pixel is (0, 0).
//!
//! Each model knows where it is valid. The fisheye polynomial
//! θd(θ) = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸) is used up to the first θ
//! where it stops increasing (or π); the pinhole models up to the first
//! radius where the distorted radius r·(1 + k1 r² + k2 r⁴ + k3 r⁶) /
//! (1 + k4 r² + k5 r⁴ + k6 r⁶) stops increasing, its denominator reaches 0
//! (radial-tangential: k4 = k5 = k6 = 0), or the tangential terms fold the
//! image over (they grow with r², so they overtake a radial factor that
//! tends to k3/k6, as the rational model's does), and only in front of the
//! camera. Outside, `project` and `unproject` return `None` rather than a
//! folded-over answer. The radial-tangential model is computed as the
//! rational one with k4 = k5 = k6 = 0, which gives the same bits (the
//! denominator is exactly 1).
//!
//! Unlike `cv::fisheye`, which works with x/z and so only sees the forward
//! hemisphere, the fisheye model here takes θ = atan2(√(x²+y²), z), so a
//! 185° lens projects points slightly behind the camera plane. For z > 0
//! both agree exactly.

use nalgebra::{Matrix2x3, Point2, Unit, Vector3};

use crate::error::FieldError;

mod jacobian;
pub mod ocam;
mod pinhole;
mod solve;

use solve::{cached, first_stationary, invert_increasing, Family};

use pinhole::{pinhole_distort, pinhole_r2_max, pinhole_undistort};
mod sphere;

/// A camera model without its coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ModelKind {
    /// OpenCV fisheye (Kannala–Brandt, k1..k4).
    Fisheye,
    /// Pinhole with radial-tangential distortion (k1, k2, p1, p2, k3).
    Pinhole,
    /// Pinhole with OpenCV's rational distortion (k1, k2, p1, p2, k3, k4,
    /// k5, k6; ROS's rational_polynomial).
    Rational,
    /// Double sphere (ξ, α).
    DoubleSphere,
    /// Extended unified (α, β).
    Eucm,
    /// Unified / Mei with radial-tangential distortion (ξ, k1, k2, p1, p2).
    Omni,
    /// WoodScape's radial polynomial ρ(θ) = k1 θ + k2 θ² + k3 θ³ + k4 θ⁴.
    RadialPoly,
    /// Scaramuzza's omnidirectional model (OCamCalib: pol, invpol, c, d, e).
    Scaramuzza,
    /// Pinhole with the field-of-view distortion (Devernay and Faugeras; ω).
    Fov,
}

/// The lens model and its distortion coefficients.
// Scaramuzza's polynomials make its variant some 280 bytes, the others
// 64 at most: a camera's intrinsics are copied per camera (a handful), not
// per pixel, and staying `Copy` keeps every consumer simple.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distortion {
    /// OpenCV fisheye (Kannala–Brandt): `[k1, k2, k3, k4]`.
    Fisheye([f64; 4]),
    /// Pinhole with radial-tangential distortion: `[k1, k2, p1, p2, k3]`
    /// (OpenCV's order).
    RadTan([f64; 5]),
    /// Pinhole with OpenCV's rational distortion:
    /// `[k1, k2, p1, p2, k3, k4, k5, k6]` (OpenCV's order, as ROS's
    /// `rational_polynomial`). The radial factor is
    /// (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶).
    Rational([f64; 8]),
    /// Double sphere (Usenko et al. 2018): `[ξ, α]`.
    DoubleSphere([f64; 2]),
    /// Extended unified (Khomutenko et al. 2016): `[α, β]`.
    Eucm([f64; 2]),
    /// Unified / Mei (OpenCV's omnidir, Kalibr's omni-radtan): `[ξ, k1, k2,
    /// p1, p2, s]`, the radial-tangential distortion on the unit sphere's
    /// projection plane and OpenCV omnidir's skew `s` in pixels (the camera
    /// matrix's (0, 1): u = fx·x + s·y + cx; 0 for Kalibr and camodocal).
    Omni([f64; 6]),
    /// WoodScape's radial polynomial: `[k1, k2, k3, k4]`, the distance from
    /// the principal point ρ(θ) = k1 θ + k2 θ² + k3 θ³ + k4 θ⁴ in units of
    /// the focal length (WoodScape's files give ρ in pixels: focal length
    /// 1, and `fy` the aspect ratio).
    RadialPoly([f64; 4]),
    /// Pinhole with the field-of-view distortion of Devernay and Faugeras
    /// (Kalibr's `pinhole-fov`): `[ω]`, the distorted radius
    /// `r_d = atan(2 r tan(ω/2)) / ω` of the radius `r` on the plane z = 1.
    Fov([f64; 1]),
    /// Scaramuzza's omnidirectional model as OCamCalib calibrates it
    /// ([`ocam`]); its focal length is 1 and its centre the principal
    /// point.
    Scaramuzza(ocam::Ocam),
}

/// The model names of rig files, for error messages.
const MODEL_NAMES: &str = "\"fisheye\", \"pinhole-radtan\", \"pinhole-rational\", \"double-sphere\", \"eucm\", \"omni-radtan\", \"radial-poly\" or \"scaramuzza\"";

impl Distortion {
    /// The model's name in rig files: `fisheye`, `pinhole-radtan` or
    /// `pinhole-rational`.
    pub fn model_name(&self) -> &'static str {
        match self {
            Distortion::Fisheye(_) => "fisheye",
            Distortion::RadTan(_) => "pinhole-radtan",
            Distortion::Rational(_) => "pinhole-rational",
            Distortion::DoubleSphere(_) => "double-sphere",
            Distortion::Eucm(_) => "eucm",
            Distortion::Omni(_) => "omni-radtan",
            Distortion::RadialPoly(_) => "radial-poly",
            Distortion::Fov(_) => "pinhole-fov",
            Distortion::Scaramuzza(_) => "scaramuzza",
        }
    }

    /// The model without its coefficients.
    pub fn kind(&self) -> ModelKind {
        match self {
            Distortion::Fisheye(_) => ModelKind::Fisheye,
            Distortion::RadTan(_) => ModelKind::Pinhole,
            Distortion::Rational(_) => ModelKind::Rational,
            Distortion::DoubleSphere(_) => ModelKind::DoubleSphere,
            Distortion::Eucm(_) => ModelKind::Eucm,
            Distortion::Omni(_) => ModelKind::Omni,
            Distortion::RadialPoly(_) => ModelKind::RadialPoly,
            Distortion::Fov(_) => ModelKind::Fov,
            Distortion::Scaramuzza(_) => ModelKind::Scaramuzza,
        }
    }

    /// The coefficients in OpenCV's order.
    pub fn coefficients(&self) -> &[f64] {
        match self {
            Distortion::Fisheye(k) | Distortion::RadialPoly(k) => k,
            Distortion::Fov(k) => k,
            Distortion::RadTan(k) => k,
            Distortion::Rational(k) => k,
            Distortion::DoubleSphere(k) | Distortion::Eucm(k) => k,
            Distortion::Omni(k) => k,
            Distortion::Scaramuzza(o) => o.values(),
        }
    }

    /// The names of the coefficients, in the order of
    /// [`coefficients`](Self::coefficients).
    pub fn coefficient_names(&self) -> Vec<String> {
        let names: &[&str] = match self {
            Distortion::Fisheye(_) | Distortion::RadialPoly(_) => &["k1", "k2", "k3", "k4"],
            Distortion::Fov(_) => &["omega"],
            Distortion::RadTan(_) => &["k1", "k2", "p1", "p2", "k3"],
            Distortion::Rational(_) => &["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"],
            Distortion::DoubleSphere(_) => &["xi", "alpha"],
            Distortion::Eucm(_) => &["alpha", "beta"],
            Distortion::Omni(_) => &["xi", "k1", "k2", "p1", "p2", "skew"],
            Distortion::Scaramuzza(o) => {
                return ["c", "d", "e"]
                    .map(String::from)
                    .into_iter()
                    .chain((0..o.pol().len()).map(|i| format!("pol[{i}]")))
                    .chain((0..o.invpol().len()).map(|i| format!("invpol[{i}]")))
                    .collect();
            }
        };
        names.iter().map(|n| (*n).to_owned()).collect()
    }

    /// Builds a model from its rig-file name and coefficients. For
    /// `pinhole-radtan`, 4 coefficients mean k3 = 0.
    pub fn from_name(name: &str, coefficients: &[f64]) -> Result<Self, FieldError> {
        let c = coefficients;
        match (name, c.len()) {
            ("fisheye", 4) => Ok(Distortion::Fisheye([c[0], c[1], c[2], c[3]])),
            ("pinhole-radtan", 4 | 5) => {
                let mut k = [0.0; 5];
                k[..c.len()].copy_from_slice(c);
                Ok(Distortion::RadTan(k))
            }
            ("pinhole-rational", 8) => {
                let mut k = [0.0; 8];
                k.copy_from_slice(c);
                Ok(Distortion::Rational(k))
            }
            ("radial-poly", 4) => Ok(Distortion::RadialPoly([c[0], c[1], c[2], c[3]])),
            ("pinhole-fov", 1) => Ok(Distortion::Fov([c[0]])),
            ("pinhole-fov", n) => Err(FieldError::new(
                "distortion",
                "1 field-of-view parameter omega (radians)",
                format!("{n}"),
            )),
            ("radial-poly", n) => Err(FieldError::new(
                "distortion",
                "4 radial-polynomial coefficients k1..k4",
                format!("{n}"),
            )),
            ("double-sphere", 2) => Ok(Distortion::DoubleSphere([c[0], c[1]])),
            ("eucm", 2) => Ok(Distortion::Eucm([c[0], c[1]])),
            ("omni-radtan", 5) => Ok(Distortion::Omni([c[0], c[1], c[2], c[3], c[4], 0.0])),
            ("omni-radtan", 6) => Ok(Distortion::Omni([c[0], c[1], c[2], c[3], c[4], c[5]])),
            ("double-sphere", n) => Err(FieldError::new(
                "distortion",
                "2 double-sphere parameters xi, alpha",
                format!("{n}"),
            )),
            ("eucm", n) => Err(FieldError::new(
                "distortion",
                "2 extended-unified parameters alpha, beta",
                format!("{n}"),
            )),
            ("omni-radtan", n) => Err(FieldError::new(
                "distortion",
                "5 or 6 unified-model parameters xi, k1, k2, p1, p2[, skew]",
                format!("{n}"),
            )),
            ("fisheye", n) => Err(FieldError::new(
                "distortion",
                "4 fisheye coefficients k1..k4",
                format!("{n}"),
            )),
            ("pinhole-radtan", n) => Err(FieldError::new(
                "distortion",
                "4 or 5 radial-tangential coefficients k1, k2, p1, p2[, k3]",
                format!("{n}"),
            )),
            ("pinhole-rational", n) => Err(FieldError::new(
                "distortion",
                "8 rational coefficients k1, k2, p1, p2, k3, k4, k5, k6",
                format!("{n}"),
            )),
            (other, _) => Err(FieldError::new(
                "model",
                MODEL_NAMES,
                format!("\"{other}\""),
            )),
        }
    }

    /// The eight coefficients of OpenCV's pinhole distortion
    /// (radial-tangential: k4 = k5 = k6 = 0), and the unified model's on
    /// its projection plane; `None` for the other models.
    fn pinhole(&self) -> Option<[f64; 8]> {
        match *self {
            Distortion::Fisheye(_)
            | Distortion::RadialPoly(_)
            | Distortion::Scaramuzza(_)
            | Distortion::Fov(_)
            | Distortion::DoubleSphere(_)
            | Distortion::Eucm(_) => None,
            Distortion::RadTan([k1, k2, p1, p2, k3]) => Some([k1, k2, p1, p2, k3, 0.0, 0.0, 0.0]),
            Distortion::Omni([_, k1, k2, p1, p2, _]) => Some([k1, k2, p1, p2, 0.0, 0.0, 0.0, 0.0]),
            Distortion::Rational(k) => Some(k),
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
        // The sphere models' own parameters are checked by name below; the
        // rest is the distortion list as files write it.
        let own = match self.distortion {
            Distortion::DoubleSphere(_) | Distortion::Eucm(_) => 2,
            Distortion::Omni(_) => 1,
            Distortion::Scaramuzza(o) => o.values().len(),
            _ => 0,
        };
        if let Distortion::Scaramuzza(o) = self.distortion {
            for (name, &v) in self.distortion.coefficient_names().iter().zip(o.values()) {
                check_finite(name, v)?;
            }
            o.validate()?;
        }
        for (i, &k) in self.distortion.coefficients()[own..].iter().enumerate() {
            check_finite(&format!("distortion[{i}]"), k)?;
        }
        let range = |name: &str, v: f64, ok: bool, expected: &str| {
            if ok {
                Ok(())
            } else {
                Err(FieldError::new(name, expected, format!("{v}")))
            }
        };
        match self.distortion {
            Distortion::DoubleSphere([xi, alpha]) => {
                range("xi", xi, (-1.0..=1.0).contains(&xi), "ξ in [−1, 1]")?;
                range("alpha", alpha, (0.0..1.0).contains(&alpha), "α in [0, 1)")?;
            }
            Distortion::Eucm([alpha, beta]) => {
                range("alpha", alpha, (0.0..1.0).contains(&alpha), "α in [0, 1)")?;
                range("beta", beta, beta > 0.0, "β > 0")?;
            }
            Distortion::Omni([xi, ..]) => range("xi", xi, xi >= 0.0, "ξ ≥ 0")?,
            Distortion::Fov([w]) => range(
                "distortion[0]",
                w,
                (0.0..std::f64::consts::PI).contains(&w),
                "ω in [0, π) radians",
            )?,
            Distortion::RadialPoly([k1, ..]) => range(
                "distortion[0]",
                k1,
                k1 > 0.0,
                "k1 > 0 (ρ increasing from the principal point)",
            )?,
            _ => {}
        }
        Ok(())
    }

    /// Projects a point in the camera frame to a pixel; `None` behind a
    /// pinhole camera, at the centre of projection, or outside the model's
    /// valid region. To project many points, [`Intrinsics::projector`]
    /// finds the valid region once.
    pub fn project(&self, p: &Vector3<f64>) -> Option<Point2<f64>> {
        project_within(self, self.validity_limit(), p)
    }

    /// Unprojects a pixel to the unit ray it sees (camera frame); `None`
    /// outside the model's valid region.
    pub fn unproject(&self, px: &Point2<f64>) -> Option<Unit<Vector3<f64>>> {
        unproject_within(self, self.validity_limit(), px)
    }

    /// The pixel of a point in the camera frame (as [`Intrinsics::project`])
    /// and the projection's Jacobian there, `∂(u, v)/∂(x, y, z)`, in closed
    /// form for every model; `None` where `project` has no pixel.
    pub fn project_jacobian(&self, p: &Vector3<f64>) -> Option<(Point2<f64>, Matrix2x3<f64>)> {
        jacobian::project_jacobian_within(self, self.validity_limit(), p)
    }

    /// These intrinsics with their valid region found once, for projecting
    /// and unprojecting many points (a view's every pixel): the same
    /// answers as [`Intrinsics::project`] and [`Intrinsics::unproject`], to
    /// the bit.
    pub fn projector(&self) -> Projector {
        Projector {
            intrinsics: *self,
            limit: self.validity_limit(),
        }
    }

    /// The fisheye model's largest θ, or the largest r² of the pinhole
    /// models and of the unified model's distortion (0 if a pinhole model
    /// has no coefficients, which cannot happen); the double-sphere and
    /// extended unified models' limits are closed forms (0).
    fn validity_limit(&self) -> f64 {
        match self.distortion {
            Distortion::Fisheye(k) => fisheye_theta_max(&k),
            Distortion::RadialPoly(k) => poly_theta_max(&k),
            Distortion::Scaramuzza(o) => {
                ocam::rho_max(&o, f64::from(self.width).hypot(f64::from(self.height)))
            }
            Distortion::RadTan(_) | Distortion::Rational(_) | Distortion::Omni(_) => self
                .distortion
                .pinhole()
                .map_or(0.0, |k| pinhole_r2_max(&k)),
            Distortion::DoubleSphere(_) | Distortion::Eucm(_) | Distortion::Fov(_) => 0.0,
        }
    }

    /// The largest angle from the optical axis where the model is valid,
    /// radians.
    pub fn max_incidence(&self) -> f64 {
        match self.distortion {
            Distortion::Fisheye(k) => fisheye_theta_max(&k),
            Distortion::RadialPoly(k) => poly_theta_max(&k),
            Distortion::Scaramuzza(o) => ocam::theta_max(&o, self.validity_limit()),
            Distortion::RadTan(_) | Distortion::Rational(_) => self
                .distortion
                .pinhole()
                .map_or(0.0, |k| pinhole_r2_max(&k).sqrt().atan()),
            Distortion::DoubleSphere([xi, alpha]) => sphere::double_sphere_cos_max(xi, alpha)
                .clamp(-1.0, 1.0)
                .acos(),
            Distortion::Eucm([alpha, beta]) => sphere::eucm_theta_max(alpha, beta),
            // In front of the camera: r_d stays below π/(2ω) as r grows.
            Distortion::Fov(_) => std::f64::consts::FRAC_PI_2,
            Distortion::Omni([xi, ..]) => sphere::unified_theta_max(xi, self.validity_limit()),
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

/// An [`Intrinsics`] with its valid region found once (the fisheye model's
/// largest θ, the pinhole models' largest r²), so that projecting a point
/// costs no search. Built by [`Intrinsics::projector`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projector {
    intrinsics: Intrinsics,
    limit: f64,
}

impl Projector {
    /// The intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// As [`Intrinsics::project`].
    pub fn project(&self, p: &Vector3<f64>) -> Option<Point2<f64>> {
        project_within(&self.intrinsics, self.limit, p)
    }

    /// As [`Intrinsics::project_jacobian`].
    pub fn project_jacobian(&self, p: &Vector3<f64>) -> Option<(Point2<f64>, Matrix2x3<f64>)> {
        jacobian::project_jacobian_within(&self.intrinsics, self.limit, p)
    }

    /// As [`Intrinsics::unproject`].
    pub fn unproject(&self, px: &Point2<f64>) -> Option<Unit<Vector3<f64>>> {
        unproject_within(&self.intrinsics, self.limit, px)
    }
}

/// [`Intrinsics::project`] with the model's validity limit given.
fn project_within(m: &Intrinsics, limit: f64, p: &Vector3<f64>) -> Option<Point2<f64>> {
    let (xd, yd) = match m.distortion {
        Distortion::Fisheye(k) => radial_project(p, limit, |t| fisheye_theta_d(&k, t))?,
        Distortion::RadTan(_) | Distortion::Rational(_) => {
            let k = m.distortion.pinhole()?;
            if p.z <= 0.0 || !p.z.is_finite() {
                return None;
            }
            let (a, b) = (p.x / p.z, p.y / p.z);
            if a * a + b * b > limit {
                return None;
            }
            pinhole_distort(&k, a, b)
        }
        Distortion::RadialPoly(k) => radial_project(p, limit, |t| poly_rho(&k, t))?,
        Distortion::Fov([w]) => {
            if p.z <= 0.0 || !p.z.is_finite() {
                return None;
            }
            let (a, b) = (p.x / p.z, p.y / p.z);
            let s = fov_scale(w, a.hypot(b));
            (a * s, b * s)
        }
        Distortion::Scaramuzza(o) => ocam::project(&o, limit, p)?,
        Distortion::DoubleSphere([xi, alpha]) => sphere::double_sphere_project(xi, alpha, p)?,
        Distortion::Eucm([alpha, beta]) => sphere::eucm_project(alpha, beta, p)?,
        Distortion::Omni([xi, .., skew]) => {
            let (a, b) = sphere::unified_project(xi, p)?;
            if a * a + b * b > limit {
                return None;
            }
            let (x, y) = pinhole_distort(&m.distortion.pinhole()?, a, b);
            // u = fx·x + s·y + cx, as fx·(x + s/fx·y) + cx.
            (x + skew / m.fx * y, y)
        }
    };
    let u = m.fx * xd + m.cx;
    let v = m.fy * yd + m.cy;
    (u.is_finite() && v.is_finite()).then(|| Point2::new(u, v))
}

/// The models that map the angle θ from the optical axis to a distance
/// from the principal point (`radius`, increasing up to `limit`):
/// normalised coordinates along the point's azimuth. θ = atan2(r, z), so
/// a point slightly behind the camera plane projects too.
fn radial_project(p: &Vector3<f64>, limit: f64, radius: impl Fn(f64) -> f64) -> Option<(f64, f64)> {
    let r = p.x.hypot(p.y);
    if r == 0.0 && p.z <= 0.0 {
        return None;
    }
    let theta = r.atan2(p.z);
    if theta > limit {
        return None;
    }
    let rho = radius(theta);
    Some(if r > 0.0 {
        (rho * p.x / r, rho * p.y / r)
    } else {
        (0.0, 0.0)
    })
}

/// The unit ray of normalised coordinates `(xd, yd)` at the angle
/// `theta(ρ)` from the optical axis (`None`: beyond the model).
fn radial_unproject(
    xd: f64,
    yd: f64,
    theta: impl Fn(f64) -> Option<f64>,
) -> Option<Unit<Vector3<f64>>> {
    let rho = xd.hypot(yd);
    if rho == 0.0 {
        return Some(Vector3::z_axis());
    }
    let theta = theta(rho)?;
    let s = theta.sin() / rho;
    Some(Unit::new_normalize(Vector3::new(
        s * xd,
        s * yd,
        theta.cos(),
    )))
}

/// [`Intrinsics::unproject`] with the model's validity limit given.
fn unproject_within(m: &Intrinsics, limit: f64, px: &Point2<f64>) -> Option<Unit<Vector3<f64>>> {
    let xd = (px.x - m.cx) / m.fx;
    let yd = (px.y - m.cy) / m.fy;
    if !(xd.is_finite() && yd.is_finite()) {
        return None;
    }
    match m.distortion {
        Distortion::Fisheye(k) => {
            radial_unproject(xd, yd, |td| fisheye_theta_from_theta_d(&k, limit, td))
        }
        Distortion::RadTan(_) | Distortion::Rational(_) => {
            let (a, b) = pinhole_undistort(&m.distortion.pinhole()?, limit, xd, yd)?;
            Some(Unit::new_normalize(Vector3::new(a, b, 1.0)))
        }
        Distortion::RadialPoly(k) => radial_unproject(xd, yd, |rho| {
            (rho <= poly_rho(&k, limit))
                .then(|| invert_increasing(|t| (poly_rho(&k, t), poly_drho(&k, t)), rho, limit))
        }),
        Distortion::Scaramuzza(o) => ocam::unproject(&o, limit, xd, yd).map(Unit::new_normalize),
        Distortion::Fov([w]) => {
            let rd = xd.hypot(yd);
            if rd == 0.0 {
                return Some(Vector3::z_axis());
            }
            // r_d ω reaches π/2 at r = ∞: beyond, no point of the plane.
            let r = if w.abs() < 1e-8 {
                rd
            } else if rd * w < std::f64::consts::FRAC_PI_2 {
                (rd * w).tan() / (2.0 * (w / 2.0).tan())
            } else {
                return None;
            };
            Some(Unit::new_normalize(Vector3::new(
                xd * r / rd,
                yd * r / rd,
                1.0,
            )))
        }
        Distortion::DoubleSphere([xi, alpha]) => {
            sphere::double_sphere_unproject(xi, alpha, xd, yd).map(Unit::new_normalize)
        }
        Distortion::Eucm([alpha, beta]) => {
            sphere::eucm_unproject(alpha, beta, xd, yd).map(Unit::new_normalize)
        }
        Distortion::Omni([xi, .., skew]) => {
            let (a, b) =
                pinhole_undistort(&m.distortion.pinhole()?, limit, xd - skew / m.fx * yd, yd)?;
            sphere::unified_unproject(xi, a, b).map(Unit::new_normalize)
        }
    }
}

/// `r_d / r` of the field-of-view distortion at the radius `r` (1 at the
/// centre; the undistorted model for ω → 0).
fn fov_scale(w: f64, r: f64) -> f64 {
    if r == 0.0 || w.abs() < 1e-8 {
        1.0
    } else {
        (2.0 * r * (w / 2.0).tan()).atan() / (w * r)
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

/// The largest θ where the fisheye polynomial still increases (≤ π).
pub(crate) fn fisheye_theta_max(k: &[f64; 4]) -> f64 {
    cached(Family::Fisheye, k, || {
        first_stationary(|t| fisheye_dtheta_d(k, t), std::f64::consts::PI, 4096)
    })
}

/// ρ(θ) of the radial polynomial.
fn poly_rho(k: &[f64; 4], theta: f64) -> f64 {
    theta * (k[0] + theta * (k[1] + theta * (k[2] + theta * k[3])))
}

/// dρ/dθ of the radial polynomial.
fn poly_drho(k: &[f64; 4], theta: f64) -> f64 {
    k[0] + theta * (2.0 * k[1] + theta * (3.0 * k[2] + theta * 4.0 * k[3]))
}

/// The largest θ where the radial polynomial still increases (≤ π).
fn poly_theta_max(k: &[f64; 4]) -> f64 {
    cached(Family::Poly, k, || {
        first_stationary(|t| poly_drho(k, t), std::f64::consts::PI, 4096)
    })
}

/// θ for a given θd on [0, θmax]; `None` if θd is beyond the valid region.
fn fisheye_theta_from_theta_d(k: &[f64; 4], t_max: f64, td: f64) -> Option<f64> {
    if td > fisheye_theta_d(k, t_max) {
        return None;
    }
    Some(invert_increasing(
        |t| (fisheye_theta_d(k, t), fisheye_dtheta_d(k, t)),
        td,
        t_max,
    ))
}

#[cfg(test)]
mod tests;
