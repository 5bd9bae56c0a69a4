//! ROS `camera_info`, one camera a file, in either of two shapes.
//!
//! The YAML of ROS 1's `camera_calibration_parsers` (which rigview writes):
//!
//! ```yaml
//! image_width: 640
//! image_height: 480
//! camera_name: front
//! camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
//! distortion_model: plumb_bob            # or rational_polynomial, equidistant, fisheye
//! distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
//! rectification_matrix: {rows: 3, cols: 3, data: [...]}
//! projection_matrix: {rows: 3, cols: 4, data: [...]}
//! ```
//!
//! and a ROS 2 `sensor_msgs/msg/CameraInfo` message as
//! `ros2 topic echo --once /camera_info` prints it (a trailing `---` is
//! fine), told apart by its keys:
//!
//! ```yaml
//! header: {stamp: {sec: 1700000000, nanosec: 123}, frame_id: camera_optical}
//! height: 480
//! width: 640
//! distortion_model: plumb_bob
//! d: [k1, k2, p1, p2, k3]
//! k: [fx, 0, cx, 0, fy, cy, 0, 0, 1]
//! r: [...]
//! p: [...]
//! binning_x: 0
//! binning_y: 0
//! roi: {x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false}
//! ```
//!
//! A message has no camera name: the camera is named after
//! `header.frame_id`, or after the file if that is empty. Its binning and
//! region of interest say how the images it came with were taken from the
//! calibrated `width` × `height`; rigview reads calibrations of the whole
//! image, so binning above 1 or a region smaller than the image is an
//! error rather than a calibration applied to images of another size.
//!
//! Models: `plumb_bob` is the radial-tangential model (5 coefficients; 4
//! mean k3 = 0; 8 are read when the last three are 0, as some drivers
//! write them); `rational_polynomial` is OpenCV's rational model (8
//! coefficients k1, k2, p1, p2, k3, k4, k5, k6); `equidistant` and
//! `fisheye` are the OpenCV fisheye model (4 coefficients). The
//! rectification and projection matrices describe a rectified image, not
//! the camera, and are ignored on reading; on writing (ROS 1's shape), R is
//! the identity and P = [K | 0].

use serde_norway::{Mapping, Value};

use crate::error::{CalibError, Result};
use crate::formats::yaml::{self, Map};
use crate::model::{Distortion, Intrinsics};
use crate::rig::Camera;

/// The distortion models read, for error messages.
const MODELS: &str = "plumb_bob, rational_polynomial, equidistant or fisheye";

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

/// The names of a file's fields: ROS 1's YAML or a ROS 2 message.
struct Keys {
    width: &'static str,
    height: &'static str,
    k: &'static str,
    d: &'static str,
}

const ROS1: Keys = Keys {
    width: "image_width",
    height: "image_height",
    k: "camera_matrix",
    d: "distortion_coefficients",
};

const ROS2: Keys = Keys {
    width: "width",
    height: "height",
    k: "k",
    d: "d",
};

/// Whether a document is a ROS 2 message (lower-case `k`, `d`, `width`,
/// `height`, `header`) rather than ROS 1's YAML.
pub(crate) fn is_message(root: &Mapping) -> bool {
    let has = |k: &str| root.contains_key(k);
    ["k", "d", "width", "height", "header"]
        .iter()
        .any(|k| has(k))
        && ![
            "image_width",
            "image_height",
            "camera_matrix",
            "distortion_coefficients",
        ]
        .iter()
        .any(|k| has(k))
}

/// Parses a camera_info file of either shape (the structural zeros and one
/// of the camera matrix must be exact); `file` names it in errors,
/// `fallback_name` names the camera if the file does not.
pub fn parse(text: &str, file: &str, fallback_name: &str) -> Result<Camera> {
    let doc = yaml::parse(text, file)?;
    let root = Map::root(&doc, file, "a camera_info map")?;
    let message = is_message(root.map);
    let keys = if message { ROS2 } else { ROS1 };
    let width = root.pixels(keys.width)?;
    let height = root.pixels(keys.height)?;
    let (name, k, d) = if message {
        check_capture(&root, width, height)?;
        let name = match root.get("header") {
            None => None,
            Some(Value::Mapping(_)) => {
                let header = root.map("header", "a map with frame_id")?;
                match header.get("frame_id") {
                    None => None,
                    Some(Value::String(s)) => Some(s.clone()),
                    Some(other) => {
                        return Err(header.error("frame_id", "a string", yaml::describe(other)))
                    }
                }
            }
            Some(other) => {
                return Err(root.error(
                    "header",
                    "a map with stamp and frame_id",
                    yaml::describe(other),
                ))
            }
        };
        let k = root.numbers(
            "k",
            Some(9),
            "9 numbers: the 3×3 camera matrix K, row by row",
        )?;
        let d = root.numbers("d", None, "a list of distortion coefficients")?;
        (name, k, d)
    } else {
        let name = match root.get("camera_name") {
            Some(Value::String(s)) => Some(s.clone()),
            None => None,
            Some(other) => {
                return Err(root.error("camera_name", "a string", yaml::describe(other)))
            }
        };
        let k = matrix(&root, "camera_matrix", 3, Some(3))?;
        let d = matrix(&root, "distortion_coefficients", 1, None)?;
        (name, k, d)
    };
    let name = name
        .filter(|n| !n.trim().is_empty())
        .unwrap_or_else(|| fallback_name.to_owned());
    check_camera_matrix(&root, keys.k, &k)?;
    let model = root.string("distortion_model", MODELS)?;
    let distortion = distortion(&root, keys.d, model, &d)?;
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
            keys.d
        } else {
            keys.k
        };
        e.renamed(f).in_file(file)
    })?;
    Ok(Camera::new(name, intrinsics))
}

/// K must be [fx 0 cx; 0 fy cy; 0 0 1], exactly: the structural zeros and
/// one are exact in any file ROS writes.
#[allow(clippy::float_cmp)]
fn check_camera_matrix(root: &Map<'_>, key: &str, k: &[f64]) -> Result<()> {
    if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
        return Err(root.error(key, "[fx 0 cx; 0 fy cy; 0 0 1]", format!("{k:?}")));
    }
    Ok(())
}

/// The lens model named by `distortion_model`, from the coefficients of
/// the field `key`.
fn distortion(root: &Map<'_>, key: &str, model: &str, d: &[f64]) -> Result<Distortion> {
    let count = |expected: &str| root.error(key, expected, format!("{} coefficients", d.len()));
    match model {
        "plumb_bob" => match d.len() {
            4 | 5 => {
                let mut c = [0.0; 5];
                c[..d.len()].copy_from_slice(d);
                Ok(Distortion::RadTan(c))
            }
            8 => match (5..8).find(|&i| d[i] != 0.0) {
                None => Ok(Distortion::RadTan([d[0], d[1], d[2], d[3], d[4]])),
                Some(_) => Err(root.error(
                    key,
                    "5 plumb_bob coefficients k1, k2, p1, p2, k3 (8 only if the last three \
                     are 0; non-zero k4, k5, k6 are the rational model: \
                     distortion_model: rational_polynomial)",
                    format!("8 coefficients with k4, k5, k6 = {:?}", &d[5..]),
                )),
            },
            _ => Err(count(
                "5 plumb_bob coefficients k1, k2, p1, p2, k3 (or 4 without k3, or 8 whose \
                 last three are 0)",
            )),
        },
        "rational_polynomial" => match d.len() {
            8 => {
                let mut c = [0.0; 8];
                c.copy_from_slice(d);
                Ok(Distortion::Rational(c))
            }
            _ => Err(count(
                "8 rational_polynomial coefficients k1, k2, p1, p2, k3, k4, k5, k6",
            )),
        },
        "equidistant" | "fisheye" => match d.len() {
            4 => Ok(Distortion::Fisheye([d[0], d[1], d[2], d[3]])),
            _ => Err(count(&format!("4 {model} coefficients k1..k4"))),
        },
        other => Err(CalibError::UnknownModel {
            file: root.file.into(),
            field: "distortion_model".into(),
            model: other.into(),
            supported: MODELS.into(),
        }),
    }
}

/// A message's binning and region of interest must describe the whole
/// calibrated image (0 and all zeros are ROS's "not used").
fn check_capture(root: &Map<'_>, width: u32, height: u32) -> Result<()> {
    let whole = |v: &Value| v.as_u64().filter(|&n| n <= 1);
    for key in ["binning_x", "binning_y"] {
        if let Some(v) = root.get(key) {
            if whole(v).is_none() {
                return Err(root.error(
                    key,
                    "0 or 1 (rigview reads calibrations of the whole image, not of binned images)",
                    yaml::describe(v),
                ));
            }
        }
    }
    let Some(v) = root.get("roi") else {
        return Ok(());
    };
    let expected = "the whole image: all zeros, or offsets 0 and the image's width and height";
    let roi = match v {
        Value::Mapping(_) => root.map("roi", expected)?,
        other => return Err(root.error("roi", expected, yaml::describe(other))),
    };
    let field = |k: &str| match roi.get(k) {
        None => Ok(0),
        Some(v) => v
            .as_u64()
            .ok_or_else(|| roi.error(k, "a whole number of pixels", yaml::describe(v))),
    };
    let (x, y, w, h) = (
        field("x_offset")?,
        field("y_offset")?,
        field("width")?,
        field("height")?,
    );
    let full = (w, h) == (0, 0) || (w, h) == (u64::from(width), u64::from(height));
    if x != 0 || y != 0 || !full {
        return Err(root.error(
            "roi",
            expected,
            format!("{w}×{h} at ({x}, {y}) in a {width}×{height} image"),
        ));
    }
    Ok(())
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

/// Writes one camera as a camera_info file (ROS 1's YAML).
pub fn write(camera: &Camera) -> Result<String> {
    let k = &camera.intrinsics;
    let mut m = Mapping::new();
    m.insert("image_width".into(), k.width.into());
    m.insert("image_height".into(), k.height.into());
    m.insert("camera_name".into(), camera.name.clone().into());
    let km: Vec<f64> = k.camera_matrix().iter().flatten().copied().collect();
    m.insert("camera_matrix".into(), mat(3, 3, &km));
    let model = match k.distortion {
        Distortion::Fisheye(_) => "equidistant",
        Distortion::RadTan(_) => "plumb_bob",
        Distortion::Rational(_) => "rational_polynomial",
        Distortion::DoubleSphere(_)
        | Distortion::Eucm(_)
        | Distortion::Omni(_)
        | Distortion::RadialPoly(_)
        | Distortion::Scaramuzza(_)
        | Distortion::Fov(_) => {
            return Err(CalibError::Argument(format!(
                "camera \"{}\": camera_info has no {} model (its models are plumb_bob, \
                 rational_polynomial and equidistant); write it as rig or kalibr",
                camera.name,
                k.distortion.model_name()
            )))
        }
    };
    let d = k.distortion.coefficients();
    m.insert("distortion_model".into(), model.into());
    m.insert("distortion_coefficients".into(), mat(1, d.len() as u64, d));
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
