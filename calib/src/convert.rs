//! One camera model fitted to another: rays sampled over the image of the
//! camera as it is, and the other model's parameters (focal lengths,
//! principal point and its own) fitted by least squares to put each ray on
//! the pixel it comes from, with the workspace's Levenberg–Marquardt
//! ([`crate::lm`]). For tools that read one model only (OCamCalib or
//! double sphere to OpenCV's fisheye, say).

use nalgebra::{Point2, Vector3};

use crate::error::{CalibError, Result};
use crate::model::{Distortion, Intrinsics, ModelKind};

/// A camera fitted to another model, and how well it fits.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelFit {
    /// The camera in the target model.
    pub intrinsics: Intrinsics,
    /// Root-mean-square reprojection error over the rays fitted, pixels.
    pub rms_px: f64,
    /// Largest reprojection error over the rays fitted, pixels.
    pub max_px: f64,
    /// Rays sampled on the image (a grid), and how many the target model
    /// reaches and was fitted to.
    pub rays: usize,
    /// Of [`ModelFit::rays`], those the target model reaches.
    pub fitted: usize,
    /// The largest angle from the optical axis the camera sees on its
    /// image, degrees.
    pub source_fov_deg: f64,
    /// The largest such angle the fitted model reaches, degrees (less
    /// than [`ModelFit::source_fov_deg`] where the target model cannot see
    /// that far, as a pinhole model cannot reach 90°).
    pub reach_deg: f64,
}

/// The residual of a ray the model does not reach, pixels.
const UNREACHED_PX: f64 = 100.0;

/// Grid of pixels sampled on the image: `GRID × GRID`.
const GRID: u32 = 41;

/// The starting point of a target model (its own parameters).
fn start(kind: ModelKind) -> Result<Distortion> {
    Ok(match kind {
        ModelKind::Fisheye => Distortion::Fisheye([0.0; 4]),
        ModelKind::Pinhole => Distortion::RadTan([0.0; 5]),
        ModelKind::Rational => Distortion::Rational([0.0; 8]),
        ModelKind::DoubleSphere => Distortion::DoubleSphere([0.0, 0.5]),
        ModelKind::Eucm => Distortion::Eucm([0.5, 1.0]),
        ModelKind::Omni => Distortion::Omni([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        ModelKind::RadialPoly => Distortion::RadialPoly([1.0, 0.0, 0.0, 0.0]),
        ModelKind::Fov => Distortion::Fov([0.5]),
        ModelKind::Scaramuzza => {
            return Err(CalibError::Argument(
                "converting to Scaramuzza's model is not offered: its polynomials come from \
                 OCamCalib's own calibration"
                    .into(),
            ))
        }
    })
}

/// The model's own parameters that the fit moves (the unified model's
/// skew stays 0).
fn free(d: &Distortion) -> usize {
    match d {
        Distortion::Omni(_) => 5,
        other => other.coefficients().len(),
    }
}

fn with_params(base: &Intrinsics, x: &[f64]) -> Option<Intrinsics> {
    let mut coefficients = base.distortion.coefficients().to_vec();
    let own = free(&base.distortion);
    coefficients[..own].copy_from_slice(&x[4..4 + own]);
    let distortion = Distortion::from_name(base.distortion.model_name(), &coefficients).ok()?;
    let k = Intrinsics {
        fx: x[0],
        fy: x[1],
        cx: x[2],
        cy: x[3],
        distortion,
        ..*base
    };
    k.validate().ok().map(|()| k)
}

/// Fits `source` to the model `target`.
pub fn fit_model(source: &Intrinsics, target: ModelKind) -> Result<ModelFit> {
    let distortion = start(target)?;
    // Rays of a grid of pixels over the image.
    let (w, h) = (f64::from(source.width), f64::from(source.height));
    let samples: Vec<(Point2<f64>, Vector3<f64>)> = (0..GRID)
        .flat_map(|i| (0..GRID).map(move |j| (i, j)))
        .filter_map(|(i, j)| {
            let px = Point2::new(
                (w - 1.0) * f64::from(i) / f64::from(GRID - 1),
                (h - 1.0) * f64::from(j) / f64::from(GRID - 1),
            );
            source.unproject(&px).map(|r| (px, r.into_inner()))
        })
        .collect();
    let angle = |r: &Vector3<f64>| r.z.clamp(-1.0, 1.0).acos();
    let source_fov = samples.iter().map(|(_, r)| angle(r)).fold(0.0, f64::max);
    if source.distortion.kind() == target {
        return Ok(ModelFit {
            intrinsics: *source,
            rms_px: 0.0,
            max_px: 0.0,
            rays: samples.len(),
            fitted: samples.len(),
            source_fov_deg: source_fov.to_degrees(),
            reach_deg: source_fov.to_degrees(),
        });
    }
    // The focal length near the axis, from a ray 0.05 rad off it.
    let axis = source
        .project(&Vector3::z())
        .ok_or_else(|| CalibError::Argument("the camera does not see its own axis".into()))?;
    let off = source
        .project(&Vector3::new(0.05f64.sin(), 0.0, 0.05f64.cos()))
        .ok_or_else(|| CalibError::Argument("the camera does not see near its axis".into()))?;
    let f0 = (off - axis).norm() / 0.05;
    let mut base = Intrinsics {
        fx: f0,
        fy: f0 * source.fy / source.fx,
        cx: axis.x,
        cy: axis.y,
        distortion,
        ..*source
    };
    let own = free(&distortion);
    let mut x: Vec<f64> = vec![base.fx, base.fy, base.cx, base.cy];
    x.extend_from_slice(&distortion.coefficients()[..own]);
    // The rays the target model can hold: a pinhole model stops short of
    // 90°. Fit first the central ones, then all that the model reaches.
    let reach = |k: &Intrinsics| k.max_incidence().min(std::f64::consts::PI);
    let mut fit_set: Vec<&(Point2<f64>, Vector3<f64>)> = Vec::new();
    for limit in [0.3, 0.5, 0.7, 0.85, 1.0] {
        let bound = reach(&with_params(&base, &x).unwrap_or(base)) * 0.999;
        let cap = source_fov * limit;
        fit_set = samples
            .iter()
            .filter(|(_, r)| angle(r) <= cap.min(bound))
            .collect();
        let residuals = |p: &[f64]| -> Option<Vec<f64>> {
            let k = with_params(&base, p)?;
            let mut out = Vec::with_capacity(2 * fit_set.len());
            for (px, ray) in &fit_set {
                // A ray the model does not reach at these parameters
                // costs a fixed amount, so the fit can move through them.
                let (ex, ey) = k
                    .project(ray)
                    .map_or((UNREACHED_PX, UNREACHED_PX), |q| (q.x - px.x, q.y - px.y));
                out.push(ex);
                out.push(ey);
            }
            Some(out)
        };
        let (next, _) = crate::lm::minimise(&x, residuals, 2000);
        x = next;
        if let Some(k) = with_params(&base, &x) {
            base = Intrinsics {
                distortion: k.distortion,
                ..base
            };
        }
    }
    let fitted = with_params(&base, &x)
        .ok_or_else(|| CalibError::Argument(format!("no valid {target:?} model fits")))?;
    let mut errors: Vec<f64> = Vec::with_capacity(fit_set.len());
    for (px, ray) in &fit_set {
        if let Some(q) = fitted.project(ray) {
            errors.push((q - px).norm());
        }
    }
    if errors.is_empty() {
        return Err(CalibError::Argument(format!(
            "the {target:?} model reaches none of the camera's rays"
        )));
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let max = errors.iter().copied().fold(0.0, f64::max);
    let reach_deg = fit_set
        .iter()
        .map(|(_, r)| angle(r))
        .fold(0.0, f64::max)
        .to_degrees();
    Ok(ModelFit {
        intrinsics: fitted,
        rms_px: rms,
        max_px: max,
        rays: samples.len(),
        fitted: errors.len(),
        source_fov_deg: source_fov.to_degrees(),
        reach_deg,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn double_sphere() -> Intrinsics {
        Intrinsics {
            width: 1280,
            height: 960,
            fx: 250.0,
            fy: 252.0,
            cx: 641.0,
            cy: 478.0,
            distortion: Distortion::DoubleSphere([-0.2, 0.6]),
        }
    }

    /// The largest pixel distance between two cameras' projections of the
    /// rays of `k`'s image that both reach.
    fn distance(a: &Intrinsics, b: &Intrinsics) -> f64 {
        let mut worst: f64 = 0.0;
        for i in 0..=40 {
            for j in 0..=30 {
                let px = Point2::new(
                    f64::from(a.width - 1) * f64::from(i) / 40.0,
                    f64::from(a.height - 1) * f64::from(j) / 30.0,
                );
                let Some(r) = a.unproject(&px) else { continue };
                if let Some(q) = b.project(&r) {
                    worst = worst.max((q - px).norm());
                }
            }
        }
        worst
    }

    #[test]
    fn a_double_sphere_camera_to_kannala_brandt_and_back_stays_within_the_reported_error() {
        let ds = double_sphere();
        let kb = fit_model(&ds, ModelKind::Fisheye).unwrap();
        assert_eq!(kb.intrinsics.distortion.kind(), ModelKind::Fisheye);
        // Kannala–Brandt with four terms follows a double sphere closely.
        assert!(kb.max_px < 1.0, "{kb:?}");
        assert!(kb.rms_px <= kb.max_px);
        assert!(kb.fitted == kb.rays, "{kb:?}");
        let back = fit_model(&kb.intrinsics, ModelKind::DoubleSphere).unwrap();
        let d = distance(&ds, &back.intrinsics);
        assert!(
            d <= kb.max_px + back.max_px + 0.05,
            "{d} px against {} + {}",
            kb.max_px,
            back.max_px
        );
        // A camera already in the model is kept as it is.
        let same = fit_model(&ds, ModelKind::DoubleSphere).unwrap();
        assert_eq!(same.intrinsics, ds);
        assert_eq!(same.max_px.to_bits(), 0f64.to_bits());
    }

    #[test]
    fn a_pinhole_model_reports_the_field_of_view_it_cannot_reach() {
        let fit = fit_model(&double_sphere(), ModelKind::Pinhole).unwrap();
        assert!(fit.source_fov_deg > 100.0, "{fit:?}");
        assert!(fit.reach_deg < 90.0, "{fit:?}");
        assert!(fit.fitted < fit.rays, "{fit:?}");
        assert!(fit_model(&double_sphere(), ModelKind::Scaramuzza).is_err());
    }
}
