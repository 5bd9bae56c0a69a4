//! WoodScape's calibration JSON: one camera a file, a folder of them a rig.
//!
//! ```json
//! {
//!   "extrinsic": {
//!     "quaternion": [0.5947, -0.5838, 0.3906, -0.3923],
//!     "translation": [3.7484, 0.0, 0.6577]
//!   },
//!   "intrinsic": {
//!     "aspect_ratio": 1.0, "cx_offset": 3.942, "cy_offset": -3.093,
//!     "height": 966, "width": 1280,
//!     "k1": 339.749, "k2": -31.988, "k3": 48.275, "k4": -7.201,
//!     "model": "radial_poly", "poly_order": 4
//!   },
//!   "name": "FV"
//! }
//! ```
//!
//! - **Intrinsics.** ρ(θ) = k1 θ + k2 θ² + k3 θ³ + k4 θ⁴ pixels from the
//!   principal point, θ the angle from the optical axis; the image row is
//!   stretched by `aspect_ratio`. The principal point is the image centre
//!   plus the offsets, in WoodScape's pixel convention: the centre of the
//!   top-left pixel is (0, 0), as rigview's, so it lies at
//!   `(width/2 + cx_offset − ½, height/2 + cy_offset − ½)`. rigview keeps ρ
//!   in pixels: `fx` = 1, `fy` = `aspect_ratio` ([`Distortion::RadialPoly`]).
//! - **Extrinsics.** The camera's pose in the vehicle frame (ISO 8855: x
//!   forward, y left, z up, the ground at z = 0): a unit quaternion in
//!   (x, y, z, w) order and a translation in metres, taking camera points
//!   (x right, y down, z along the optical axis) to the vehicle frame.
//!
//! JSON is read with the YAML parser (JSON is YAML), so a syntax error
//! names its line; the writer lays the file out as WoodScape's are.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::yaml::{self, Map};
use crate::error::{CalibError, FieldError, Result};
use crate::model::{Distortion, Intrinsics};
use crate::pose::Pose;
use crate::rig::Camera;

/// How far from unit length a quaternion may be (files round to 4–16
/// digits).
const UNIT_TOLERANCE: f64 = 1e-3;

/// Whether a parsed document looks like a WoodScape calibration.
pub(crate) fn is_woodscape(doc: &serde_norway::Value) -> bool {
    doc.get("intrinsic").is_some() && doc.get("extrinsic").is_some()
}

/// Parses one camera; its name is the file's `name`, or `fallback_name`.
pub fn parse(text: &str, file: &str, fallback_name: &str) -> Result<Camera> {
    let doc = yaml::parse(text, file)?;
    let root = Map::root(&doc, file, "a WoodScape calibration (intrinsic, extrinsic)")?;
    let intr = root.map("intrinsic", "a map of the lens: k1..k4, cx_offset, …")?;
    let model = intr.string("model", "\"radial_poly\"")?;
    if model != "radial_poly" {
        return Err(CalibError::UnknownModel {
            file: file.into(),
            field: intr.field_name("model"),
            model: model.into(),
            supported: "radial_poly".into(),
        });
    }
    if let Some(order) = intr.get("poly_order") {
        if order.as_f64() != Some(4.0) {
            return Err(intr.error("poly_order", "4 (k1..k4)", yaml::describe(order)));
        }
    }
    let number = |key: &str, expected: &str| intr.number(key, expected);
    let size = |key: &str| -> Result<u32> {
        let expected = "a positive whole number of pixels";
        let x = number(key, expected)?;
        if (1.0..=1e6).contains(&x) && x.fract() == 0.0 {
            Ok(x as u32)
        } else {
            Err(intr.error(key, expected, format!("{x}")))
        }
    };
    let (width, height) = (size("width")?, size("height")?);
    let k = [
        number("k1", "ρ's coefficient of θ, pixels")?,
        number("k2", "ρ's coefficient of θ², pixels")?,
        number("k3", "ρ's coefficient of θ³, pixels")?,
        number("k4", "ρ's coefficient of θ⁴, pixels")?,
    ];
    let aspect = number("aspect_ratio", "a positive number")?;
    if aspect <= 0.0 {
        return Err(intr.error("aspect_ratio", "a positive number", format!("{aspect}")));
    }
    let (w, h) = (f64::from(width), f64::from(height));
    let offset = |key: &str, side: f64| -> Result<f64> {
        let expected =
            "an offset from the image centre that keeps the principal point on the image, pixels";
        let o = number(key, expected)?;
        let c = side / 2.0 + o - 0.5;
        if (-0.5..=side - 0.5).contains(&c) {
            Ok(c)
        } else {
            Err(intr.error(key, expected, format!("{o} (principal point at {c})")))
        }
    };
    let intrinsics = Intrinsics {
        width,
        height,
        fx: 1.0,
        fy: aspect,
        cx: offset("cx_offset", w)?,
        cy: offset("cy_offset", h)?,
        distortion: Distortion::RadialPoly(k),
    };
    intrinsics.validate().map_err(|e| {
        let field = intr.field_name(match e.field.as_str() {
            "distortion[0]" => "k1",
            "fy" => "aspect_ratio",
            other => other,
        });
        FieldError { field, ..e }.in_file(file)
    })?;
    let ext = root.map("extrinsic", "a map of the pose: quaternion, translation")?;
    let q = ext.numbers(
        "quaternion",
        Some(4),
        "4 numbers [x, y, z, w], a unit quaternion",
    )?;
    let t = ext.numbers("translation", Some(3), "3 numbers [x, y, z], metres")?;
    let quat = Quaternion::new(q[3], q[0], q[1], q[2]);
    if (quat.norm() - 1.0).abs() > UNIT_TOLERANCE {
        return Err(ext.error(
            "quaternion",
            "a unit quaternion [x, y, z, w]",
            format!("{q:?} of length {:.6}", quat.norm()),
        ));
    }
    let rotation = UnitQuaternion::from_quaternion(quat);
    let pose = Pose::new(
        *rotation.to_rotation_matrix().matrix(),
        Vector3::new(t[0], t[1], t[2]),
    )
    .map_err(|e| e.renamed(ext.field_name("quaternion")).in_file(file))?;
    let name = match root.get("name") {
        Some(serde_norway::Value::String(s)) if !s.trim().is_empty() => s.clone(),
        Some(other) => return Err(root.error("name", "the camera's name", yaml::describe(other))),
        None => fallback_name.to_owned(),
    };
    Ok(Camera {
        name,
        device: None,
        intrinsics,
        pose: Some(pose),
    })
}

/// Writes one camera as WoodScape's JSON. It needs the radial polynomial
/// and a pose; ρ is written in pixels (the coefficients times `fx`) and
/// the aspect ratio is `fy/fx`, which gives back the same bits for a
/// camera read from WoodScape's files (`fx` = 1).
pub fn write(camera: &Camera) -> Result<String> {
    let k = &camera.intrinsics;
    let Distortion::RadialPoly(c) = k.distortion else {
        return Err(CalibError::Argument(format!(
            "camera \"{}\": WoodScape's files hold the radial polynomial (radial-poly), not {}; \
             write it as rig or kalibr",
            camera.name,
            k.distortion.model_name()
        )));
    };
    let pose = camera.pose.ok_or_else(|| {
        CalibError::Argument(format!(
            "camera \"{}\" has no pose; a WoodScape file needs it",
            camera.name
        ))
    })?;
    let q = pose.quaternion();
    let t = pose.translation();
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    // A JSON string: the name with quotes and backslashes escaped.
    let name_json = format!(
        "\"{}\"",
        camera.name.replace('\\', "\\\\").replace('"', "\\\"")
    );
    Ok(format!(
        "{{\n    \"extrinsic\": {{\n        \"quaternion\": [\n            {},\n            {},\n            {},\n            {}\n        ],\n        \"translation\": [\n            {},\n            {},\n            {}\n        ]\n    }},\n    \"intrinsic\": {{\n        \"aspect_ratio\": {},\n        \"cx_offset\": {},\n        \"cy_offset\": {},\n        \"height\": {},\n        \"k1\": {},\n        \"k2\": {},\n        \"k3\": {},\n        \"k4\": {},\n        \"model\": \"radial_poly\",\n        \"poly_order\": 4,\n        \"width\": {}\n    }},\n    \"name\": {name_json}\n}}\n",
        json_number(q.i),
        json_number(q.j),
        json_number(q.k),
        json_number(q.w),
        json_number(t.x),
        json_number(t.y),
        json_number(t.z),
        json_number(k.fy / k.fx),
        json_number(k.cx + 0.5 - w / 2.0),
        json_number(k.cy + 0.5 - h / 2.0),
        k.height,
        json_number(c[0] * k.fx),
        json_number(c[1] * k.fx),
        json_number(c[2] * k.fx),
        json_number(c[3] * k.fx),
        k.width,
    ))
}

/// A number as JSON writes it: the shortest text that reads back to the
/// same bits, with a decimal point.
pub(crate) fn json_number(x: f64) -> String {
    let s = format!("{x:?}");
    if s.contains(['.', 'e', 'E']) {
        s
    } else {
        format!("{s}.0")
    }
}
