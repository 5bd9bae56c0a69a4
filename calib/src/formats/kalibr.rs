//! Kalibr camchain YAML (`camchain.yaml`, `camchain-imucam.yaml`).
//!
//! ```yaml
//! cam0:
//!   camera_model: pinhole
//!   intrinsics: [fu, fv, pu, pv]
//!   distortion_model: equidistant      # or radtan (or none)
//!   distortion_coeffs: [k1, k2, k3, k4] # radtan: [k1, k2, r1, r2]
//!   resolution: [width, height]
//!   cam_overlaps: [1]
//! cam1:
//!   T_cn_cnm1: [[...4], [...4], [...4], [0, 0, 0, 1]]   # cam0 frame → cam1 frame
//!   ...
//! ```
//!
//! Supported: `pinhole` with `equidistant` (the OpenCV fisheye model) or
//! `radtan` (k3 = 0), and `none`. Any other camera or distortion model is an
//! error that names it. Kalibr has no rational distortion model, so a rig
//! with a `pinhole-rational` camera cannot be written as a camchain (an
//! error names the camera). A file that begins with OpenCV's `%YAML:1.0`
//! line, as some tools write camchains, reads like one without it. The rig's frame is `cam0`'s (Kalibr knows nothing of
//! the ground): cam0 sits at the origin, camera n at the inverse of the
//! chained `T_cn_cnm1 · … · T_c1_c0`. Other keys (`rostopic`, `T_cam_imu`,
//! `timeshift_cam_imu`) are ignored on reading.

use nalgebra::{Matrix3, Matrix4, Vector3};
use serde_norway::{Mapping, Value};

use crate::error::{CalibError, FieldError, Result};
use crate::formats::yaml::{self, Map};
use crate::model::{Distortion, Intrinsics};
use crate::pose::Pose;
use crate::rig::{Camera, Frame, Rig};

/// Parses a camchain's text; `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<Rig> {
    let doc = yaml::parse(text, file)?;
    let root = Map::root(&doc, file, "a map of cameras cam0, cam1, …")?;
    let mut n = 0;
    while root.get(&format!("cam{n}")).is_some() {
        n += 1;
    }
    if n == 0 {
        return Err(CalibError::Missing {
            file: file.into(),
            field: "cam0".into(),
            expected: "the first camera of the chain".into(),
        });
    }
    let mut cameras = Vec::with_capacity(n);
    let mut chain = Pose::identity(); // cam_{i} ← cam0 (rig), as a pose of cam0 in cam_i
    let mut neighbours = Vec::new();
    for i in 0..n {
        let key = format!("cam{i}");
        let cam = root.map(&key, "a camera")?;
        let model = cam.string("camera_model", "pinhole")?;
        let dmodel = cam.string("distortion_model", "equidistant or radtan")?;
        const SUPPORTED: &str = "pinhole-equi (distortion_model equidistant), pinhole-radtan, \
             pinhole-fov, pinhole-none, omni-radtan, omni-none, ds-none, eucm-none";
        // The projection's own parameters come before [fu, fv, pu, pv].
        let (own, own_names) = match model {
            "pinhole" => (0, ""),
            "omni" => (1, "xi, "),
            "ds" => (2, "xi, alpha, "),
            "eucm" => (2, "alpha, beta, "),
            _ => {
                return Err(CalibError::UnknownModel {
                    file: file.into(),
                    field: cam.field_name("camera_model"),
                    model: format!("{model}-{dmodel}"),
                    supported: SUPPORTED.into(),
                })
            }
        };
        let all = cam.numbers(
            "intrinsics",
            Some(own + 4),
            &format!("{} numbers [{own_names}fu, fv, pu, pv]", own + 4),
        )?;
        let (params, intr) = all.split_at(own);
        let res = cam.numbers("resolution", Some(2), "2 numbers [width, height]")?;
        let (width, height) = (
            pixels(&cam, "resolution", res[0])?,
            pixels(&cam, "resolution", res[1])?,
        );
        let distortion = match (model, dmodel) {
            ("ds", "none") => Distortion::DoubleSphere([params[0], params[1]]),
            ("eucm", "none") => Distortion::Eucm([params[0], params[1]]),
            ("omni", "none") => Distortion::Omni([params[0], 0.0, 0.0, 0.0, 0.0, 0.0]),
            ("omni", "radtan") => {
                let k = cam.numbers(
                    "distortion_coeffs",
                    Some(4),
                    "4 radtan coefficients [k1, k2, r1, r2]",
                )?;
                Distortion::Omni([params[0], k[0], k[1], k[2], k[3], 0.0])
            }
            ("pinhole", "equidistant") => {
                let k = cam.numbers(
                    "distortion_coeffs",
                    Some(4),
                    "4 equidistant coefficients [k1, k2, k3, k4]",
                )?;
                Distortion::Fisheye([k[0], k[1], k[2], k[3]])
            }
            ("pinhole", "radtan") => {
                let k = cam.numbers(
                    "distortion_coeffs",
                    Some(4),
                    "4 radtan coefficients [k1, k2, r1, r2]",
                )?;
                Distortion::RadTan([k[0], k[1], k[2], k[3], 0.0])
            }
            ("pinhole", "none") => Distortion::RadTan([0.0; 5]),
            ("pinhole", "fov") => {
                let k = cam.numbers(
                    "distortion_coeffs",
                    Some(1),
                    "1 field-of-view coefficient [w]",
                )?;
                Distortion::Fov([k[0]])
            }
            (_, other) => {
                return Err(CalibError::UnknownModel {
                    file: file.into(),
                    field: cam.field_name("distortion_model"),
                    model: format!("{model}-{other}"),
                    supported: SUPPORTED.into(),
                })
            }
        };
        let intrinsics = Intrinsics {
            width,
            height,
            fx: intr[0],
            fy: intr[1],
            cx: intr[2],
            cy: intr[3],
            distortion,
        };
        intrinsics.validate().map_err(|e| {
            let f = if e.field.starts_with("distortion") {
                "distortion_coeffs"
            } else {
                "intrinsics"
            };
            e.renamed(cam.field_name(f)).in_file(file)
        })?;
        if i > 0 {
            let t = transform(&cam, "T_cn_cnm1")?;
            chain = t.compose(&chain);
        }
        if let Some(v) = cam.get("cam_overlaps") {
            let list = yaml::numbers_of(v, None)
                .map_err(|found| cam.error("cam_overlaps", "a list of camera indices", found))?;
            for o in list {
                if o.fract() != 0.0 || o < 0.0 || o as usize >= n || o as usize == i {
                    return Err(cam.error(
                        "cam_overlaps",
                        &format!("indices of other cameras (0..{n})"),
                        format!("{o}"),
                    ));
                }
                let pair = (i.min(o as usize), i.max(o as usize));
                if !neighbours.contains(&pair) {
                    neighbours.push(pair);
                }
            }
        }
        cameras.push(Camera {
            name: key,
            device: None,
            intrinsics,
            pose: Some(chain.inverse()),
        });
    }
    Rig::new(Frame::Camera("cam0".into()), cameras, neighbours).map_err(|e| e.in_file(file))
}

fn pixels(cam: &Map<'_>, key: &str, v: f64) -> Result<u32> {
    if v.fract() == 0.0 && (1.0..=1e6).contains(&v) {
        Ok(v as u32)
    } else {
        Err(cam.error(key, "positive whole numbers of pixels", format!("{v}")))
    }
}

/// A 4×4 rigid transform field; returned as the pose it applies (points of
/// the source frame to the target frame).
fn transform(cam: &Map<'_>, key: &str) -> Result<Pose> {
    let expected = "a 4×4 rigid transform (4 rows of 4 numbers, last row [0, 0, 0, 1])";
    let v = cam.require(key, expected)?;
    let Value::Sequence(rows) = v else {
        return Err(cam.error(key, expected, yaml::describe(v)));
    };
    if rows.len() != 4 {
        return Err(cam.error(key, expected, format!("{} rows", rows.len())));
    }
    let mut m = Matrix4::zeros();
    for (r, row) in rows.iter().enumerate() {
        let vals = yaml::numbers_of(row, Some(4))
            .map_err(|f| cam.error(key, expected, format!("row {r}: {f}")))?;
        for (c, x) in vals.into_iter().enumerate() {
            m[(r, c)] = x;
        }
    }
    let last = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
    if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > 1e-9 {
        return Err(cam.error(key, expected, format!("last row {last:?}")));
    }
    let rot: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Pose::new(rot, t).map_err(|e| {
        FieldError {
            field: cam.field_name(key),
            ..e
        }
        .in_file(cam.file)
    })
}

fn seq(v: impl IntoIterator<Item = f64>) -> Value {
    Value::Sequence(v.into_iter().map(Value::from).collect())
}

/// Writes a rig as a Kalibr camchain. Cameras become cam0, cam1, … in rig
/// order; every camera needs a pose; radial-tangential cameras must have
/// k3 = 0 (Kalibr's radtan has no k3).
pub fn write(rig: &Rig) -> Result<String> {
    let mut root = Mapping::new();
    let mut prev: Option<Pose> = None;
    for (i, c) in rig.cameras.iter().enumerate() {
        let k = &c.intrinsics;
        let mut m = Mapping::new();
        let (cm, own): (&str, Vec<f64>) = match k.distortion {
            Distortion::DoubleSphere(d) => ("ds", d.to_vec()),
            Distortion::Eucm(d) => ("eucm", d.to_vec()),
            Distortion::Omni(d) => ("omni", vec![d[0]]),
            _ => ("pinhole", Vec::new()),
        };
        m.insert("camera_model".into(), cm.into());
        m.insert(
            "intrinsics".into(),
            seq(own.into_iter().chain([k.fx, k.fy, k.cx, k.cy])),
        );
        let (dm, coeffs) = match k.distortion {
            Distortion::Fisheye(d) => ("equidistant", d.to_vec()),
            Distortion::Fov(d) => ("fov", d.to_vec()),
            Distortion::DoubleSphere(_) | Distortion::Eucm(_) => ("none", Vec::new()),
            Distortion::Omni(d) if d[5] == 0.0 => ("radtan", d[1..5].to_vec()),
            Distortion::Omni(d) => {
                return Err(CalibError::Argument(format!(
                    "camera \"{}\": Kalibr's omni model has no skew, and its skew is {} px; \
                     write it as rig or opencv-yaml (omnidir)",
                    c.name, d[5]
                )))
            }
            Distortion::RadTan(d) if d[4] == 0.0 => ("radtan", d[..4].to_vec()),
            Distortion::RadTan(d) => {
                return Err(CalibError::Argument(format!(
                    "camera \"{}\": Kalibr's radtan model has no k3, and k3 = {}",
                    c.name, d[4]
                )))
            }
            Distortion::RadialPoly(_) | Distortion::Scaramuzza(_) => {
                return Err(CalibError::Argument(format!(
                    "camera \"{}\": Kalibr has no {} model; write it as rig, woodscape \
                     (radial-poly) or ocamcalib (scaramuzza)",
                    c.name,
                    k.distortion.model_name()
                )))
            }
            Distortion::Rational(_) => {
                return Err(CalibError::Argument(format!(
                    "camera \"{}\": Kalibr has no rational distortion model (its pinhole \
                     distortions are radtan, equidistant, fov and none); write it as rig, \
                     opencv-yaml, opencv-xml or ros",
                    c.name
                )))
            }
        };
        m.insert("distortion_model".into(), dm.into());
        m.insert("distortion_coeffs".into(), seq(coeffs));
        m.insert(
            "resolution".into(),
            Value::Sequence(vec![k.width.into(), k.height.into()]),
        );
        let overlaps: Vec<Value> = rig
            .neighbours_of(i)
            .map(|j| Value::from(j as u64))
            .collect();
        m.insert("cam_overlaps".into(), Value::Sequence(overlaps));
        let pose = c.pose.ok_or_else(|| {
            CalibError::Argument(format!(
                "camera \"{}\" has no pose; a Kalibr camchain needs every pose",
                c.name
            ))
        })?;
        if let Some(p) = prev {
            // Points of cam_{n-1} → rig → cam_n.
            let t = pose.inverse().compose(&p);
            let r = t.rotation_matrix();
            let tr = t.translation();
            let rows: Vec<Value> = (0..3)
                .map(|a| seq([r[(a, 0)], r[(a, 1)], r[(a, 2)], tr[a]]))
                .chain(std::iter::once(seq([0.0, 0.0, 0.0, 1.0])))
                .collect();
            m.insert("T_cn_cnm1".into(), Value::Sequence(rows));
        }
        m.insert("rostopic".into(), format!("/{}/image_raw", c.name).into());
        root.insert(format!("cam{i}").into(), Value::Mapping(m));
        prev = Some(pose);
    }
    yaml::to_string(&Value::Mapping(root))
}
