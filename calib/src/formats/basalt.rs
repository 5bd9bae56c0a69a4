//! Basalt's calibration JSON: a rig of cameras posed on an IMU.
//!
//! ```json
//! {
//!   "value0": {
//!     "T_imu_cam": [
//!       {"px": 0.04, "py": -0.02, "pz": -0.01,
//!        "qx": 0.01, "qy": 0.0, "qz": 0.70, "qw": 0.71}
//!     ],
//!     "intrinsics": [
//!       {"camera_type": "ds",
//!        "intrinsics": {"fx": 349.7, "fy": 349.6, "cx": 254.9, "cy": 257.5,
//!                       "xi": -0.23, "alpha": 0.56}}
//!     ],
//!     "resolution": [[512, 512]]
//!   }
//! }
//! ```
//!
//! `camera_type` is `ds` (ξ, α), `eucm` (α, β), `kb4` (Kannala–Brandt's
//! k1..k4: OpenCV's fisheye) or `pinhole`. `T_imu_cam[i]` takes camera `i`'s
//! points (x right, y down, z along the optical axis) to the IMU frame, a
//! translation in metres and a unit quaternion. The IMU has no ground, so
//! the rig is posed in its first camera's frame (as a Kalibr camchain);
//! the cameras are named cam0, cam1, ….

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde_norway::Value;

use super::yaml::{self, Map};
use crate::error::{CalibError, Result};
use crate::model::{Distortion, Intrinsics};
use crate::pose::Pose;
use crate::rig::{Camera, Frame, Rig};

const SUPPORTED: &str = "ds, eucm, kb4, pinhole";

/// How far from unit length a quaternion may be.
const UNIT_TOLERANCE: f64 = 1e-3;

fn list<'a>(m: &Map<'a>, key: &str, expected: &str) -> Result<&'a Vec<Value>> {
    match m.require(key, expected)? {
        Value::Sequence(v) => Ok(v),
        other => Err(m.error(key, expected, yaml::describe(other))),
    }
}

/// The `i`-th map of a list, with its path.
fn item<'a>(m: &Map<'a>, key: &str, i: usize, v: &'a Value, expected: &str) -> Result<Map<'a>> {
    let path = format!("{}[{i}]", m.field_name(key));
    match v {
        Value::Mapping(map) => Ok(Map {
            map,
            path,
            file: m.file,
        }),
        other => Err(
            crate::error::FieldError::new(path, expected, yaml::describe(other)).in_file(m.file),
        ),
    }
}

/// Parses a Basalt calibration into a rig posed in cam0's frame.
pub fn parse(text: &str, file: &str) -> Result<Rig> {
    let doc = yaml::parse(text, file)?;
    let root = Map::root(&doc, file, "a Basalt calibration (value0: …)")?;
    let v0 = root.map(
        "value0",
        "Basalt's calibration: T_imu_cam, intrinsics, resolution",
    )?;
    let poses = list(&v0, "T_imu_cam", "a list of camera poses on the IMU")?;
    let intr = list(&v0, "intrinsics", "a list of camera intrinsics")?;
    let res = list(&v0, "resolution", "a list of [width, height]")?;
    if intr.is_empty() || poses.len() != intr.len() || res.len() != intr.len() {
        return Err(CalibError::Format {
            file: file.into(),
            detail: format!(
                "value0: {} poses (T_imu_cam), {} intrinsics and {} resolutions: expected one \
                 of each per camera, at least one camera",
                poses.len(),
                intr.len(),
                res.len()
            ),
        });
    }
    let mut imu_poses = Vec::with_capacity(intr.len());
    let mut cameras = Vec::with_capacity(intr.len());
    for i in 0..intr.len() {
        let cam = item(
            &v0,
            "intrinsics",
            i,
            &intr[i],
            "a map with camera_type, intrinsics",
        )?;
        let kind = cam.string("camera_type", SUPPORTED)?;
        let p = cam.map("intrinsics", "a map of the camera's parameters")?;
        let distortion = match kind {
            "ds" => Distortion::DoubleSphere([p.number("xi", "ξ")?, p.number("alpha", "α")?]),
            "eucm" => Distortion::Eucm([p.number("alpha", "α")?, p.number("beta", "β")?]),
            "kb4" => Distortion::Fisheye([
                p.number("k1", "k1")?,
                p.number("k2", "k2")?,
                p.number("k3", "k3")?,
                p.number("k4", "k4")?,
            ]),
            "pinhole" => Distortion::RadTan([0.0; 5]),
            other => {
                return Err(CalibError::UnknownModel {
                    file: file.into(),
                    field: cam.field_name("camera_type"),
                    model: other.into(),
                    supported: SUPPORTED.into(),
                })
            }
        };
        let size = yaml::numbers_of(&res[i], Some(2))
            .ok()
            .filter(|s| {
                s.iter()
                    .all(|&x| (1.0..=1e6).contains(&x) && x.fract() == 0.0)
            })
            .ok_or_else(|| {
                crate::error::FieldError::new(
                    format!("value0.resolution[{i}]"),
                    "2 whole numbers [width, height]",
                    yaml::describe(&res[i]),
                )
                .in_file(file)
            })?;
        let intrinsics = Intrinsics {
            width: size[0] as u32,
            height: size[1] as u32,
            fx: p.number("fx", "the focal length along x, pixels")?,
            fy: p.number("fy", "the focal length along y, pixels")?,
            cx: p.number("cx", "the principal point's x, pixels")?,
            cy: p.number("cy", "the principal point's y, pixels")?,
            distortion,
        };
        intrinsics
            .validate()
            .map_err(|e| e.renamed(p.field_name("intrinsics")).in_file(file))?;
        let t = item(
            &v0,
            "T_imu_cam",
            i,
            &poses[i],
            "a map of px, py, pz, qx, qy, qz, qw",
        )?;
        let q = Quaternion::new(
            t.number("qw", "a unit quaternion's w")?,
            t.number("qx", "a unit quaternion's x")?,
            t.number("qy", "a unit quaternion's y")?,
            t.number("qz", "a unit quaternion's z")?,
        );
        if (q.norm() - 1.0).abs() > UNIT_TOLERANCE {
            return Err(t.error(
                "qw",
                "a unit quaternion (qx, qy, qz, qw)",
                format!("length {:.6}", q.norm()),
            ));
        }
        let r = UnitQuaternion::from_quaternion(q).to_rotation_matrix();
        let tr = Vector3::new(
            t.number("px", "metres")?,
            t.number("py", "metres")?,
            t.number("pz", "metres")?,
        );
        imu_poses.push((r, tr));
        cameras.push(Camera {
            name: format!("cam{i}"),
            device: None,
            intrinsics,
            pose: None,
        });
    }
    // Each camera in cam0's frame: T_cam0_cami = T_imu_cam0⁻¹ · T_imu_cami.
    let (r0, t0) = imu_poses[0];
    for (cam, (r, t)) in cameras.iter_mut().zip(&imu_poses) {
        let rotation = r0.inverse() * r;
        let translation = r0.inverse() * (t - t0);
        cam.pose = Some(
            Pose::new(*rotation.matrix(), translation)
                .map_err(|e| e.renamed("value0.T_imu_cam").in_file(file))?,
        );
    }
    Rig::new(Frame::Camera("cam0".into()), cameras, vec![]).map_err(|e| e.in_file(file))
}

/// Writes a rig as Basalt's calibration: the poses relative to the rig's
/// frame stand for the IMU's (Basalt reads them as T_imu_cam).
pub fn write(rig: &Rig) -> Result<String> {
    let n = super::woodscape::json_number;
    let mut poses = Vec::new();
    let mut intrinsics = Vec::new();
    let mut resolution = Vec::new();
    for c in &rig.cameras {
        let k = &c.intrinsics;
        let pose = c.pose.ok_or_else(|| {
            CalibError::Argument(format!(
                "camera \"{}\" has no pose; Basalt's calibration needs every pose",
                c.name
            ))
        })?;
        let q = pose.quaternion();
        let t = pose.translation();
        poses.push(format!(
            "            {{\n                \"px\": {},\n                \"py\": {},\n                \"pz\": {},\n                \"qx\": {},\n                \"qy\": {},\n                \"qz\": {},\n                \"qw\": {}\n            }}",
            n(t.x), n(t.y), n(t.z), n(q.i), n(q.j), n(q.k), n(q.w)
        ));
        let (kind, own): (&str, Vec<(&str, f64)>) = match k.distortion {
            Distortion::DoubleSphere([xi, alpha]) => ("ds", vec![("xi", xi), ("alpha", alpha)]),
            Distortion::Eucm([alpha, beta]) => ("eucm", vec![("alpha", alpha), ("beta", beta)]),
            Distortion::Fisheye([k1, k2, k3, k4]) => {
                ("kb4", vec![("k1", k1), ("k2", k2), ("k3", k3), ("k4", k4)])
            }
            Distortion::RadTan(d) if d.iter().all(|&v| v == 0.0) => ("pinhole", vec![]),
            other => {
                return Err(CalibError::Argument(format!(
                    "camera \"{}\": Basalt's cameras are ds, eucm, kb4 and pinhole without \
                     distortion, not {}; write it as rig or kalibr",
                    c.name,
                    other.model_name()
                )))
            }
        };
        let fields: Vec<String> = [("fx", k.fx), ("fy", k.fy), ("cx", k.cx), ("cy", k.cy)]
            .into_iter()
            .chain(own)
            .map(|(name, v)| format!("                    \"{name}\": {}", n(v)))
            .collect();
        intrinsics.push(format!(
            "            {{\n                \"camera_type\": \"{kind}\",\n                \"intrinsics\": {{\n{}\n                }}\n            }}",
            fields.join(",\n")
        ));
        resolution.push(format!(
            "            [\n                {},\n                {}\n            ]",
            k.width, k.height
        ));
    }
    Ok(format!(
        "{{\n    \"value0\": {{\n        \"T_imu_cam\": [\n{}\n        ],\n        \"intrinsics\": [\n{}\n        ],\n        \"resolution\": [\n{}\n        ]\n    }}\n}}\n",
        poses.join(",\n"),
        intrinsics.join(",\n"),
        resolution.join(",\n")
    ))
}
