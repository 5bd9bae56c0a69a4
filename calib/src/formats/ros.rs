//! ROS `camera_info` YAML (as `camera_calibration_parsers` reads and writes
//! it), one camera a file.
//!
//! ```yaml
//! image_width: 640
//! image_height: 480
//! camera_name: front
//! camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
//! distortion_model: plumb_bob            # or equidistant / fisheye
//! distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
//! rectification_matrix: {rows: 3, cols: 3, data: [...]}
//! projection_matrix: {rows: 3, cols: 4, data: [...]}
//! ```
//!
//! `plumb_bob` is the radial-tangential model (5 coefficients; 4 mean
//! k3 = 0); `equidistant` and `fisheye` are the OpenCV fisheye model (4
//! coefficients). The rectification and projection matrices describe a
//! rectified image, not the camera, and are ignored on reading; on writing,
//! R is the identity and P = [K | 0].

use serde_norway::{Mapping, Value};

use crate::error::{CalibError, Result};
use crate::formats::yaml::{self, Map};
use crate::model::{Distortion, Intrinsics};
use crate::rig::Camera;

fn matrix(root: &Map<'_>, key: &str, rows: usize, cols: Option<usize>) -> Result<Vec<f64>> {
    let expected = match cols {
        Some(c) => format!("a {rows}×{c} matrix {{rows, cols, data}}"),
        None => "a list of coefficients {rows, cols, data}".to_owned(),
    };
    let m = root.map(key, &expected)?;
    let r = m.pixels("rows")? as usize;
    let c = m.pixels("cols")? as usize;
    let data = m.numbers("data", None, "a list of numbers")?;
    let shape_ok = match cols {
        Some(cc) => r == rows && c == cc,
        None => r == 1 || c == 1,
    };
    if !shape_ok || r * c != data.len() {
        return Err(root.error(
            key,
            &expected,
            format!("{r}×{c} with {} values", data.len()),
        ));
    }
    Ok(data)
}

/// Parses a camera_info file (the structural zeros and one of the camera
/// matrix must be exact); `file` names it in errors, `fallback_name`
/// names the camera if the file does not.
#[allow(clippy::float_cmp)]
pub fn parse(text: &str, file: &str, fallback_name: &str) -> Result<Camera> {
    let doc = yaml::parse(text, file)?;
    let root = Map::root(&doc, file, "a camera_info map")?;
    let width = root.pixels("image_width")?;
    let height = root.pixels("image_height")?;
    let name = match root.get("camera_name") {
        Some(Value::String(s)) if !s.trim().is_empty() => s.clone(),
        Some(Value::String(_)) | None => fallback_name.to_owned(),
        Some(other) => return Err(root.error("camera_name", "a string", yaml::describe(other))),
    };
    let k = matrix(&root, "camera_matrix", 3, Some(3))?;
    if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
        return Err(root.error(
            "camera_matrix",
            "[fx 0 cx; 0 fy cy; 0 0 1]",
            format!("{k:?}"),
        ));
    }
    let model = root.string("distortion_model", "plumb_bob, equidistant or fisheye")?;
    let d = matrix(&root, "distortion_coefficients", 1, None)?;
    let distortion = match model {
        "plumb_bob" => match d.len() {
            4 | 5 => {
                let mut c = [0.0; 5];
                c[..d.len()].copy_from_slice(&d);
                Distortion::RadTan(c)
            }
            n => {
                return Err(root.error(
                    "distortion_coefficients",
                    "5 plumb_bob coefficients k1, k2, p1, p2, k3",
                    format!("{n}"),
                ))
            }
        },
        "equidistant" | "fisheye" => match d.len() {
            4 => Distortion::Fisheye([d[0], d[1], d[2], d[3]]),
            n => {
                return Err(root.error(
                    "distortion_coefficients",
                    &format!("4 {model} coefficients k1..k4"),
                    format!("{n}"),
                ))
            }
        },
        other => {
            return Err(CalibError::UnknownModel {
                file: file.into(),
                field: "distortion_model".into(),
                model: other.into(),
                supported: "plumb_bob, equidistant, fisheye".into(),
            })
        }
    };
    let intrinsics = Intrinsics {
        width,
        height,
        fx: k[0],
        fy: k[4],
        cx: k[2],
        cy: k[5],
        distortion,
    };
    intrinsics.validate().map_err(|e| {
        let f = if e.field.starts_with("distortion") {
            "distortion_coefficients"
        } else {
            "camera_matrix"
        };
        e.renamed(f).in_file(file)
    })?;
    Ok(Camera::new(name, intrinsics))
}

fn mat(rows: u64, cols: u64, data: &[f64]) -> Value {
    let mut m = Mapping::new();
    m.insert("rows".into(), rows.into());
    m.insert("cols".into(), cols.into());
    m.insert(
        "data".into(),
        Value::Sequence(data.iter().map(|&v| Value::from(v)).collect()),
    );
    Value::Mapping(m)
}

/// Writes one camera as a camera_info file.
pub fn write(camera: &Camera) -> Result<String> {
    let k = &camera.intrinsics;
    let mut m = Mapping::new();
    m.insert("image_width".into(), k.width.into());
    m.insert("image_height".into(), k.height.into());
    m.insert("camera_name".into(), camera.name.clone().into());
    let km: Vec<f64> = k.camera_matrix().iter().flatten().copied().collect();
    m.insert("camera_matrix".into(), mat(3, 3, &km));
    let (model, d) = match k.distortion {
        Distortion::Fisheye(d) => ("equidistant", d.to_vec()),
        Distortion::RadTan(d) => ("plumb_bob", d.to_vec()),
    };
    m.insert("distortion_model".into(), model.into());
    m.insert("distortion_coefficients".into(), mat(1, d.len() as u64, &d));
    m.insert(
        "rectification_matrix".into(),
        mat(3, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
    );
    let p = [
        k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
    ];
    m.insert("projection_matrix".into(), mat(3, 4, &p));
    yaml::to_string(&Value::Mapping(m))
}
