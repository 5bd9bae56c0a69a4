//! camodocal's camera YAML (as VINS-Fusion and KITTI-360 ship it): one
//! camera a file, without a pose.
//!
//! ```yaml
//! %YAML:1.0
//! ---
//! model_type: MEI            # or KANNALA_BRANDT, PINHOLE
//! camera_name: left
//! image_width: 1280
//! image_height: 960
//! mirror_parameters:
//!    xi: 1.5000000000000000e+00
//! distortion_parameters:
//!    k1: -5.0000000000000003e-02
//!    k2: 2.0000000000000000e-01
//!    p1: 1.0000000000000000e-03
//!    p2: -2.0000000000000000e-03
//! projection_parameters:
//!    gamma1: 8.0000000000000000e+02
//!    gamma2: 8.1000000000000000e+02
//!    u0: 6.4000000000000000e+02
//!    v0: 4.8000000000000000e+02
//! ```
//!
//! - `MEI`: the unified model, `xi`, radial-tangential `k1, k2, p1, p2` on
//!   its projection plane (OpenCV's order and formula), `gamma1, gamma2`
//!   the focal lengths and `u0, v0` the principal point.
//! - `KANNALA_BRANDT`: θd = θ + k2 θ³ + k3 θ⁵ + k4 θ⁷ + k5 θ⁹ with the
//!   projection parameters `k2..k5, mu, mv, u0, v0`: OpenCV's fisheye
//!   k1..k4 are camodocal's k2..k5, and `mu, mv` the focal lengths.
//! - `PINHOLE`: `k1, k2, p1, p2` and `fx, fy, cx, cy`.

use super::yaml::{self, Map};
use crate::error::{CalibError, Result};
use crate::model::{Distortion, Intrinsics};
use crate::rig::Camera;

const SUPPORTED: &str = "MEI, KANNALA_BRANDT, PINHOLE";

/// Parses one camera; its name is `camera_name`, or `fallback_name`.
pub fn parse(text: &str, file: &str, fallback_name: &str) -> Result<Camera> {
    let doc = yaml::parse(text, file)?;
    let root = Map::root(&doc, file, "a camodocal camera (model_type, …)")?;
    let model = root.string("model_type", SUPPORTED)?;
    let width = root.pixels("image_width")?;
    let height = root.pixels("image_height")?;
    let number = |m: &Map<'_>, key: &str| m.number(key, "a finite number");
    let proj = root.map(
        "projection_parameters",
        "a map of the projection's parameters",
    )?;
    let radtan = || -> Result<[f64; 4]> {
        let d = root.map("distortion_parameters", "a map of k1, k2, p1, p2")?;
        Ok([
            number(&d, "k1")?,
            number(&d, "k2")?,
            number(&d, "p1")?,
            number(&d, "p2")?,
        ])
    };
    let (f, c, distortion) = match model {
        "MEI" => {
            let mirror = root.map("mirror_parameters", "a map of xi")?;
            let [k1, k2, p1, p2] = radtan()?;
            (
                [number(&proj, "gamma1")?, number(&proj, "gamma2")?],
                [number(&proj, "u0")?, number(&proj, "v0")?],
                Distortion::Omni([number(&mirror, "xi")?, k1, k2, p1, p2, 0.0]),
            )
        }
        "KANNALA_BRANDT" => (
            [number(&proj, "mu")?, number(&proj, "mv")?],
            [number(&proj, "u0")?, number(&proj, "v0")?],
            Distortion::Fisheye([
                number(&proj, "k2")?,
                number(&proj, "k3")?,
                number(&proj, "k4")?,
                number(&proj, "k5")?,
            ]),
        ),
        "PINHOLE" => {
            let [k1, k2, p1, p2] = radtan()?;
            (
                [number(&proj, "fx")?, number(&proj, "fy")?],
                [number(&proj, "cx")?, number(&proj, "cy")?],
                Distortion::RadTan([k1, k2, p1, p2, 0.0]),
            )
        }
        other => {
            return Err(CalibError::UnknownModel {
                file: file.into(),
                field: "model_type".into(),
                model: other.into(),
                supported: SUPPORTED.into(),
            })
        }
    };
    let intrinsics = Intrinsics {
        width,
        height,
        fx: f[0],
        fy: f[1],
        cx: c[0],
        cy: c[1],
        distortion,
    };
    intrinsics
        .validate()
        .map_err(|e| e.renamed(format!("model_type {model}")).in_file(file))?;
    let name = match root.get("camera_name") {
        Some(serde_norway::Value::String(s)) if !s.trim().is_empty() => s.clone(),
        _ => fallback_name.to_owned(),
    };
    Ok(Camera {
        name,
        device: None,
        intrinsics,
        pose: None,
    })
}

/// Writes one camera as camodocal does (OpenCV's FileStorage YAML).
pub fn write(camera: &Camera) -> Result<String> {
    let k = &camera.intrinsics;
    let n = |x: f64| format!("{x:e}");
    // The name as a YAML scalar (quoted where it needs to be).
    let name = serde_norway::to_string(&camera.name)
        .map(|s| s.trim_end().to_owned())
        .map_err(|e| CalibError::Argument(format!("camera \"{}\": {e}", camera.name)))?;
    let head = |model: &str| {
        format!(
            "%YAML:1.0\n---\nmodel_type: {model}\ncamera_name: {name}\nimage_width: {}\nimage_height: {}\n",
            k.width, k.height
        )
    };
    let radtan = |d: &[f64]| {
        format!(
            "distortion_parameters:\n   k1: {}\n   k2: {}\n   p1: {}\n   p2: {}\n",
            n(d[0]),
            n(d[1]),
            n(d[2]),
            n(d[3])
        )
    };
    Ok(match k.distortion {
        Distortion::Omni([xi, k1, k2, p1, p2, 0.0]) => format!(
            "{}mirror_parameters:\n   xi: {}\n{}projection_parameters:\n   gamma1: {}\n   gamma2: {}\n   u0: {}\n   v0: {}\n",
            head("MEI"),
            n(xi),
            radtan(&[k1, k2, p1, p2]),
            n(k.fx),
            n(k.fy),
            n(k.cx),
            n(k.cy)
        ),
        Distortion::Fisheye([k1, k2, k3, k4]) => format!(
            "{}projection_parameters:\n   k2: {}\n   k3: {}\n   k4: {}\n   k5: {}\n   mu: {}\n   mv: {}\n   u0: {}\n   v0: {}\n",
            head("KANNALA_BRANDT"),
            n(k1),
            n(k2),
            n(k3),
            n(k4),
            n(k.fx),
            n(k.fy),
            n(k.cx),
            n(k.cy)
        ),
        Distortion::RadTan(d) if d[4] == 0.0 => format!(
            "{}{}projection_parameters:\n   fx: {}\n   fy: {}\n   cx: {}\n   cy: {}\n",
            head("PINHOLE"),
            radtan(&d),
            n(k.fx),
            n(k.fy),
            n(k.cx),
            n(k.cy)
        ),
        other => {
            return Err(CalibError::Argument(format!(
                "camera \"{}\": camodocal's files hold MEI (omni-radtan without skew), \
                 KANNALA_BRANDT (fisheye) and PINHOLE (radial-tangential without k3), not this {}; \
                 write it as rig",
                camera.name,
                other.model_name()
            )))
        }
    })
}
