//! rigview's own rig file: versioned YAML.
//!
//! ```yaml
//! format: rigview-rig
//! version: 1
//! frame: vehicle            # or "camera:NAME" (poses relative to that camera)
//! cameras:
//! - name: front
//!   device:                 # optional; exactly one of the two
//!     genicam: Basler-21234567
//!     # ip: 192.168.10.11
//!   model: fisheye          # or pinhole-radtan, pinhole-rational, double-sphere, eucm, omni-radtan,
//!                           # radial-poly, scaramuzza
//!   resolution_px: [960, 640]
//!   focal_px: [302.45, 320.75]
//!   principal_point_px: [496.64, 331.20]
//!   distortion: [-0.0437, 0.0217, -0.0264, 0.0084]   # fisheye: k1..k4; pinhole-radtan: k1, k2, p1, p2, k3;
//!                                                    # pinhole-rational: k1, k2, p1, p2, k3, k4, k5, k6;
//!                                                    # omni-radtan: k1, k2, p1, p2[, skew (px)]; none for the others
//!   # xi: -0.2               # double-sphere and omni-radtan: ξ (unitless)
//!   # alpha: 0.6             # double-sphere and eucm: α (unitless)
//!   # beta: 1.1              # eucm: β (unitless)
//!   # pol: [...]             # scaramuzza: OCamCalib's pol, invpol and affine [c, d, e]
//!   # invpol: [...]          #   (pixels: focal_px [1, 1])
//!   # affine: [1, 0, 0]
//!   pose:                   # optional; camera (OpenCV axes) to rig frame
//!     translation_m: [1.9, 0.0, 0.9]                 # camera centre, metres
//!     rotation_matrix: [[...], [...], [...]]         # row-major, p_rig = R·p_cam + t
//!     # or, instead of rotation_matrix: rotation_ypr_deg: [yaw, pitch, roll]
//! neighbours:
//! - [front, left]
//! ```
//!
//! Numbers are written in their shortest exact form, so saving and loading
//! gives back the same bits. Unknown fields are errors (a typo must not turn
//! into a silent default). A file of another version is refused with a clear
//! error.

use std::net::IpAddr;

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{CalibError, FieldError, Result};
use crate::model::ocam::Ocam;
use crate::model::{Distortion, Intrinsics};
use crate::pose::Pose;
use crate::rig::{Camera, DeviceId, Frame, Rig};

/// The value of the `format` field.
pub const FORMAT_NAME: &str = "rigview-rig";
/// The rig file version this build reads and writes.
pub const VERSION: u32 = 1;

#[derive(Deserialize)]
struct Header {
    format: Option<serde_norway::Value>,
    version: Option<serde_norway::Value>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RigDoc {
    format: String,
    version: u32,
    frame: String,
    cameras: Vec<CameraDoc>,
    #[serde(default)]
    neighbours: Vec<[String; 2]>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDoc {
    name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    device: Option<DeviceDoc>,
    model: String,
    resolution_px: [u32; 2],
    focal_px: [f64; 2],
    principal_point_px: [f64; 2],
    /// The sphere models' own parameters (unitless): the double sphere's
    /// and the unified model's ξ, the double sphere's and the extended
    /// unified model's α, the extended unified model's β.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    xi: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    alpha: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    beta: Option<f64>,
    /// Scaramuzza's model (OCamCalib): `pol` (ρ to z, pixels, lowest order
    /// first), `invpol` (angle to ρ) and the affine `[c, d, e]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pol: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    invpol: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    affine: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    distortion: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pose: Option<PoseDoc>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct DeviceDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    genicam: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    ip: Option<String>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseDoc {
    translation_m: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rotation_matrix: Option<[[f64; 3]; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rotation_ypr_deg: Option<[f64; 3]>,
}

/// Parses a rig file's text; `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<Rig> {
    let parse_err = |e: serde_norway::Error| CalibError::Parse {
        file: file.to_owned(),
        detail: e.to_string(),
    };
    let header: Header = serde_norway::from_str(text).map_err(parse_err)?;
    match header.format.as_ref().and_then(|f| f.as_str()) {
        Some(FORMAT_NAME) => {}
        Some(other) => {
            return Err(FieldError::new(
                "format",
                format!("\"{FORMAT_NAME}\""),
                format!("\"{other}\""),
            )
            .in_file(file))
        }
        None => {
            return Err(CalibError::Missing {
                file: file.to_owned(),
                field: "format".into(),
                expected: format!("\"{FORMAT_NAME}\""),
            })
        }
    }
    match header.version {
        None => {
            return Err(CalibError::Missing {
                file: file.to_owned(),
                field: "version".into(),
                expected: format!("the rig format version ({VERSION})"),
            })
        }
        Some(v) if v.as_u64() == Some(u64::from(VERSION)) => {}
        Some(v) => {
            let found = serde_norway::to_string(&v)
                .map(|s| s.trim().to_owned())
                .unwrap_or_else(|_| "?".into());
            return Err(CalibError::UnsupportedVersion {
                file: file.to_owned(),
                found,
                supported: VERSION.to_string(),
            });
        }
    }
    let doc: RigDoc = serde_norway::from_str(text).map_err(parse_err)?;
    from_doc(doc).map_err(|e| e.in_file(file))
}

fn from_doc(doc: RigDoc) -> Result<Rig, FieldError> {
    let frame = match doc.frame.as_str() {
        "vehicle" => Frame::Vehicle,
        s => match s.strip_prefix("camera:") {
            Some(name) => Frame::Camera(name.trim().to_owned()),
            None => {
                return Err(FieldError::new(
                    "frame",
                    "\"vehicle\" or \"camera:NAME\"",
                    format!("\"{s}\""),
                ))
            }
        },
    };
    let mut cameras = Vec::with_capacity(doc.cameras.len());
    for (i, c) in doc.cameras.into_iter().enumerate() {
        cameras.push(camera_from_doc(c).map_err(|e| e.within(&format!("cameras[{i}]")))?);
    }
    let mut neighbours = Vec::with_capacity(doc.neighbours.len());
    for (k, [a, b]) in doc.neighbours.iter().enumerate() {
        let find = |n: &str| {
            cameras.iter().position(|c| c.name == n).ok_or_else(|| {
                FieldError::new(
                    format!("neighbours[{k}]"),
                    "names of cameras of the rig",
                    format!("\"{n}\""),
                )
            })
        };
        neighbours.push((find(a)?, find(b)?));
    }
    // Rig::new sorts the pairs; check duplicates on the order as written.
    let rig = Rig {
        frame,
        cameras,
        neighbours,
    };
    rig.validate()?;
    Rig::new(rig.frame, rig.cameras, rig.neighbours)
}

/// The parameters the model `c.model` names as fields (`xi`, `alpha`,
/// `beta`), in [`Distortion::coefficients`]' order, before `distortion`'s.
fn named_parameters(c: &CameraDoc) -> Result<Vec<f64>, FieldError> {
    let names: &[&str] = match c.model.as_str() {
        "double-sphere" => &["xi", "alpha"],
        "eucm" => &["alpha", "beta"],
        "omni-radtan" => &["xi"],
        _ => &[],
    };
    for (name, value) in [("xi", c.xi), ("alpha", c.alpha), ("beta", c.beta)] {
        if value.is_some() && !names.contains(&name) {
            return Err(FieldError::new(
                name,
                format!("no `{name}` for the {} model", c.model),
                "a value",
            ));
        }
    }
    names
        .iter()
        .map(|&name| {
            let value = match name {
                "xi" => c.xi,
                "alpha" => c.alpha,
                _ => c.beta,
            };
            value.ok_or_else(|| {
                FieldError::new(name, format!("the {} model's {name}", c.model), "nothing")
            })
        })
        .collect()
}

/// Scaramuzza's model from its named fields; `None` for another model
/// (which must not have them).
fn scaramuzza(c: &CameraDoc) -> Result<Option<Distortion>, FieldError> {
    if c.model != "scaramuzza" {
        for (name, given) in [
            ("pol", c.pol.is_some()),
            ("invpol", c.invpol.is_some()),
            ("affine", c.affine.is_some()),
        ] {
            if given {
                return Err(FieldError::new(
                    name,
                    format!("no `{name}` for the {} model", c.model),
                    "a value",
                ));
            }
        }
        return Ok(None);
    }
    if !c.distortion.is_empty() {
        return Err(FieldError::new(
            "distortion",
            "none for the scaramuzza model (its polynomials are pol and invpol)",
            format!("{} coefficients", c.distortion.len()),
        ));
    }
    let pol = c.pol.as_deref().ok_or_else(|| {
        FieldError::new(
            "pol",
            "the scaramuzza model's pol, lowest order first",
            "nothing",
        )
    })?;
    let ocam = Ocam::new(
        pol,
        c.invpol.as_deref().unwrap_or(&[]),
        c.affine.unwrap_or([1.0, 0.0, 0.0]),
    )?;
    Ok(Some(Distortion::Scaramuzza(ocam)))
}

fn camera_from_doc(c: CameraDoc) -> Result<Camera, FieldError> {
    let distortion = match scaramuzza(&c)? {
        Some(d) => d,
        None => {
            let mut coefficients = named_parameters(&c)?;
            coefficients.extend_from_slice(&c.distortion);
            Distortion::from_name(&c.model, &coefficients)?
        }
    };
    let intrinsics = Intrinsics {
        width: c.resolution_px[0],
        height: c.resolution_px[1],
        fx: c.focal_px[0],
        fy: c.focal_px[1],
        cx: c.principal_point_px[0],
        cy: c.principal_point_px[1],
        distortion,
    };
    intrinsics.validate().map_err(|e| {
        let field = match e.field.as_str() {
            "fx" | "fy" => "focal_px".to_owned(),
            "cx" | "cy" => "principal_point_px".to_owned(),
            "resolution" => "resolution_px".to_owned(),
            other => other.to_owned(),
        };
        FieldError { field, ..e }
    })?;
    let device = match c.device {
        None => None,
        Some(DeviceDoc {
            genicam: Some(id),
            ip: None,
        }) if !id.trim().is_empty() => Some(DeviceId::GenICam(id)),
        Some(DeviceDoc {
            genicam: None,
            ip: Some(ip),
        }) => Some(DeviceId::Ip(ip.trim().parse::<IpAddr>().map_err(|_| {
            FieldError::new("device.ip", "an IPv4 or IPv6 address", format!("\"{ip}\""))
        })?)),
        Some(_) => {
            return Err(FieldError::new(
                "device",
                "exactly one of \"genicam\" (a non-empty id) or \"ip\"",
                "something else",
            ))
        }
    };
    let pose = c
        .pose
        .map(|p| {
            let t = Vector3::from(p.translation_m);
            match (p.rotation_matrix, p.rotation_ypr_deg) {
                (Some(m), None) => Pose::new(Matrix3::from_fn(|r, col| m[r][col]), t),
                (None, Some(ypr)) => Pose::from_ypr_deg(ypr, t),
                (None, None) => Err(FieldError::new(
                    "rotation_matrix",
                    "rotation_matrix or rotation_ypr_deg",
                    "neither",
                )),
                (Some(_), Some(_)) => Err(FieldError::new(
                    "rotation_ypr_deg",
                    "only one of rotation_matrix and rotation_ypr_deg",
                    "both",
                )),
            }
            .map_err(|e| e.within("pose"))
        })
        .transpose()?;
    Ok(Camera {
        name: c.name,
        device,
        intrinsics,
        pose,
    })
}

/// Writes a rig as a rig file's text.
pub fn to_string(rig: &Rig) -> Result<String> {
    let doc = RigDoc {
        format: FORMAT_NAME.into(),
        version: VERSION,
        frame: match &rig.frame {
            Frame::Vehicle => "vehicle".into(),
            Frame::Camera(name) => format!("camera:{name}"),
        },
        cameras: rig
            .cameras
            .iter()
            .map(|c| {
                let k = &c.intrinsics;
                CameraDoc {
                    name: c.name.clone(),
                    device: c.device.as_ref().map(|d| match d {
                        DeviceId::GenICam(id) => DeviceDoc {
                            genicam: Some(id.clone()),
                            ip: None,
                        },
                        DeviceId::Ip(ip) => DeviceDoc {
                            genicam: None,
                            ip: Some(ip.to_string()),
                        },
                    }),
                    model: k.distortion.model_name().into(),
                    resolution_px: [k.width, k.height],
                    focal_px: [k.fx, k.fy],
                    principal_point_px: [k.cx, k.cy],
                    xi: match k.distortion {
                        Distortion::DoubleSphere([xi, _]) | Distortion::Omni([xi, ..]) => Some(xi),
                        _ => None,
                    },
                    alpha: match k.distortion {
                        Distortion::DoubleSphere([_, a]) | Distortion::Eucm([a, _]) => Some(a),
                        _ => None,
                    },
                    beta: match k.distortion {
                        Distortion::Eucm([_, b]) => Some(b),
                        _ => None,
                    },
                    pol: match k.distortion {
                        Distortion::Scaramuzza(o) => Some(o.pol().to_vec()),
                        _ => None,
                    },
                    invpol: match k.distortion {
                        Distortion::Scaramuzza(o) => Some(o.invpol().to_vec()),
                        _ => None,
                    },
                    affine: match k.distortion {
                        Distortion::Scaramuzza(o) => Some(o.affine()),
                        _ => None,
                    },
                    distortion: match k.distortion {
                        Distortion::DoubleSphere(_)
                        | Distortion::Eucm(_)
                        | Distortion::Scaramuzza(_) => Vec::new(),
                        Distortion::Omni([_, k1, k2, p1, p2, skew]) if skew != 0.0 => {
                            vec![k1, k2, p1, p2, skew]
                        }
                        Distortion::Omni([_, k1, k2, p1, p2, _]) => vec![k1, k2, p1, p2],
                        d => d.coefficients().to_vec(),
                    },
                    pose: c.pose.as_ref().map(|p| {
                        let m = p.rotation_matrix();
                        PoseDoc {
                            translation_m: [
                                p.translation().x,
                                p.translation().y,
                                p.translation().z,
                            ],
                            rotation_matrix: Some(std::array::from_fn(|r| {
                                std::array::from_fn(|col| m[(r, col)])
                            })),
                            rotation_ypr_deg: None,
                        }
                    }),
                }
            })
            .collect(),
        neighbours: rig
            .neighbours
            .iter()
            .map(|&(a, b)| [rig.cameras[a].name.clone(), rig.cameras[b].name.clone()])
            .collect(),
    };
    let body = serde_norway::to_string(&doc).map_err(|e| CalibError::Parse {
        file: "(rig)".into(),
        detail: e.to_string(),
    })?;
    Ok(format!(
        "# rigview rig file. Poses: camera (OpenCV axes: x right, y down, z optical axis)\n\
         # to rig frame, p_rig = rotation_matrix · p_cam + translation_m (metres).\n{body}"
    ))
}
