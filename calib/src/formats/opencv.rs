//! OpenCV FileStorage calibration files (YAML and XML), one camera a file.
//!
//! Keys read:
//! - `camera_matrix` (3×3, no skew but in OpenCV omnidir's files);
//! - `xi` (a number or 1×1 matrix): OpenCV omnidir's unified model, with
//!   `distortion_coefficients` k1, k2, p1, p2 and the camera matrix's skew
//!   (`camera_model: omnidir`, which rigview writes, or none);
//! - `dist_coeffs` (or `distortion_coefficients`, OpenCV's calibration
//!   sample's name): 4 fisheye coefficients, or 4, 5, 8, 12 or 14 pinhole
//!   coefficients in OpenCV's order (k1, k2, p1, p2, k3, k4, k5, k6, then
//!   the thin-prism and tilt terms, which must be 0). A pinhole file whose
//!   k4, k5 or k6 is non-zero is the rational model (`CALIB_RATIONAL_MODEL`),
//!   otherwise the radial-tangential one;
//! - `resolution` (2 ints: width, height; or `image_width` and
//!   `image_height`);
//! - `camera_model` (`fisheye`, `pinhole` or `rational`), which rigview
//!   writes; `rational` keeps 8 coefficients as the rational model even
//!   when k4..k6 are 0. Without it, the model comes from the caller's hint,
//!   else from the surround layout (a file with `project_matrix` is
//!   fisheye), else from the number of coefficients (5 or more: pinhole); 4
//!   coefficients without any of these are ambiguous and an error says so;
//! - `project_matrix` (3×3), `scale_xy`, `shift_xy` (2 each) of the surround
//!   layout (see [`super::surround`]);
//! - `rotation_camera_to_rig` (3×3) and `translation_camera_in_rig_m` (3),
//!   rigview's pose keys, which it writes when the camera has a pose.
//!
//! The file is parsed by OpenCV's own `FileStorage`, from memory, after a
//! strict well-formedness check (OpenCV 4.6's parsers crash on some
//! truncated input; see [`parse`]): the bytes
//! are read here (so a missing file is reported with its path) and handed to
//! `FileStorage` with the `MEMORY` flag. In that mode OpenCV tells YAML from
//! XML by the first bytes only, and refuses YAML that lacks the `%YAML`
//! directive ("Unsupported file storage format"), which files written by
//! other YAML tools or edited by hand often lack. Such text gets a
//! `%YAML:1.0` line put in front, in memory; the file is never changed.
//!
//! Matrix sizes are checked on the parsed nodes before OpenCV builds a
//! matrix, so a file claiming a 100000×100000 matrix is an error, not an
//! allocation.

use nalgebra::{Matrix3, Vector3};
use opencv::core::{
    FileNode, FileNodeTraitConst, FileStorage, FileStorageTrait, FileStorageTraitConst,
    FileStorage_FORMAT_XML, FileStorage_MEMORY, FileStorage_READ, FileStorage_WRITE,
};

use crate::cvutil::{mat_f64, mat_i32, mat_to_f64};
use crate::error::{cv, CalibError, FieldError, Result};
use crate::model::{Distortion, Intrinsics, ModelKind};
use crate::pose::Pose;
use crate::rig::Camera;

/// The surround-view keys of a camera file (see [`super::surround`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurroundKeys {
    /// Homography from the undistorted image to the camera's strip of the
    /// bird's-eye canvas.
    pub project_matrix: Matrix3<f64>,
    /// Scale of fx, fy for the undistorted image's camera matrix.
    pub scale_xy: [f64; 2],
    /// Shift of cx, cy for the undistorted image's camera matrix, pixels.
    pub shift_xy: [f64; 2],
}

/// What one OpenCV camera file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct OpenCvCamera {
    /// Intrinsics.
    pub intrinsics: Intrinsics,
    /// The pose, if the file has rigview's pose keys.
    pub pose: Option<Pose>,
    /// The surround-view keys, if present.
    pub surround: Option<SurroundKeys>,
}

/// Largest number of elements a matrix in a calibration file may claim.
const MAX_ELEMENTS: i64 = 256;

/// Parses the text of an OpenCV FileStorage file; `xml` says which syntax,
/// `file` names it in errors, `hint` gives the model where the file does
/// not.
pub fn parse(text: &str, xml: bool, file: &str, hint: Option<ModelKind>) -> Result<OpenCvCamera> {
    if text.contains('\0') {
        return Err(CalibError::Parse {
            file: file.into(),
            detail: "the file contains NUL bytes; expected OpenCV FileStorage text".into(),
        });
    }
    let trimmed = text.trim_start_matches('\u{feff}');
    let fixed;
    let source = if xml || trimmed.starts_with("%YAML") {
        trimmed
    } else {
        fixed = format!("%YAML:1.0\n{trimmed}");
        fixed.as_str()
    };
    if source.trim().is_empty() {
        return Err(CalibError::Parse {
            file: file.into(),
            detail: "the file is empty".into(),
        });
    }
    well_formed(source, xml, file)?;
    let fs = FileStorage::new(source, FileStorage_READ | FileStorage_MEMORY, "").map_err(|e| {
        CalibError::Parse {
            file: file.into(),
            detail: format!("not a valid OpenCV FileStorage file: {}", e.message.trim()),
        }
    })?;
    let reader = Reader { fs: &fs, file };
    reader.camera(hint)
}

/// Checks that the text is well-formed XML or YAML before OpenCV sees it.
/// OpenCV 4.6's parsers read past the end of some malformed input (the
/// fuzz test found that `<?xml version=` crashes its XML parser), so only
/// text that a strict parser accepts is handed to it. For YAML, OpenCV's
/// `%YAML:1.0` line (not valid YAML itself) is left out of the check.
fn well_formed(source: &str, xml: bool, file: &str) -> Result<()> {
    let detail = if xml {
        roxmltree::Document::parse(source)
            .err()
            .map(|e| format!("not well-formed XML: {e}"))
    } else {
        let body = match source.split_once('\n') {
            Some((first, rest)) if first.starts_with("%YAML") => rest,
            _ => source,
        };
        serde_norway::from_str::<serde_norway::Value>(body)
            .err()
            .map(|e| format!("not well-formed YAML: {e}"))
    };
    match detail {
        Some(detail) => Err(CalibError::Parse {
            file: file.into(),
            detail,
        }),
        None => Ok(()),
    }
}

struct Reader<'a> {
    fs: &'a FileStorage,
    file: &'a str,
}

/// A matrix read from a file: rows, cols, row-major data.
struct Matrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

impl Matrix {
    fn shape(&self) -> String {
        format!("{}×{}", self.rows, self.cols)
    }
    fn is_vector(&self, n: usize) -> bool {
        self.data.len() == n && (self.rows == 1 || self.cols == 1)
    }
}

impl Reader<'_> {
    fn node(&self, key: &str) -> Result<Option<FileNode>> {
        let n = cv("reading a FileStorage node", self.fs.get(key))?;
        if n.empty().unwrap_or(true) || n.is_none().unwrap_or(true) {
            Ok(None)
        } else {
            Ok(Some(n))
        }
    }

    fn field(&self, key: &str, expected: &str, found: impl Into<String>) -> CalibError {
        FieldError::new(key, expected, found).in_file(self.file)
    }

    fn missing(&self, key: &str, expected: &str) -> CalibError {
        CalibError::Missing {
            file: self.file.into(),
            field: key.into(),
            expected: expected.into(),
        }
    }

    fn describe(n: &FileNode) -> String {
        if n.is_string().unwrap_or(false) {
            format!("the string \"{}\"", n.to_string().unwrap_or_default())
        } else if n.is_int().unwrap_or(false) || n.is_real().unwrap_or(false) {
            format!("the number {}", n.to_f64().unwrap_or(f64::NAN))
        } else if n.is_seq().unwrap_or(false) {
            format!("a list of {} items", n.size().unwrap_or(0))
        } else if n.is_map().unwrap_or(false) {
            "a map that is not an OpenCV matrix".into()
        } else {
            "something else".into()
        }
    }

    fn number(n: &FileNode) -> Option<f64> {
        if n.is_int().unwrap_or(false) || n.is_real().unwrap_or(false) {
            n.to_f64().ok()
        } else {
            None
        }
    }

    /// A matrix node (`!!opencv-matrix` / `type_id="opencv-matrix"`) or a
    /// plain list of numbers (read as a column).
    fn matrix(&self, key: &str, expected: &str) -> Result<Option<Matrix>> {
        let Some(n) = self.node(key)? else {
            return Ok(None);
        };
        if n.is_seq().unwrap_or(false) {
            let len = n.size().unwrap_or(0);
            if len as i64 > MAX_ELEMENTS {
                return Err(self.field(key, expected, format!("a list of {len} items")));
            }
            let mut data = Vec::with_capacity(len);
            for i in 0..len {
                let item = cv("reading a list item", n.at(i as i32))?;
                match Self::number(&item) {
                    Some(v) => data.push(v),
                    None => {
                        return Err(self.field(
                            key,
                            expected,
                            format!("item {i}: {}", Self::describe(&item)),
                        ))
                    }
                }
            }
            return Ok(Some(Matrix {
                rows: len,
                cols: 1,
                data,
            }));
        }
        if !n.is_map().unwrap_or(false) {
            return Err(self.field(key, expected, Self::describe(&n)));
        }
        let int = |name: &str| -> Option<i64> {
            let c = n.get(name).ok()?;
            if c.is_int().unwrap_or(false) {
                c.to_i32().ok().map(i64::from)
            } else {
                None
            }
        };
        let (Some(rows), Some(cols)) = (int("rows"), int("cols")) else {
            return Err(self.field(key, expected, "a map without integer \"rows\" and \"cols\""));
        };
        if rows < 1 || cols < 1 || rows * cols > MAX_ELEMENTS {
            return Err(self.field(key, expected, format!("{rows}×{cols}")));
        }
        let data_node = cv("reading matrix data", n.get("data"))?;
        // OpenCV's XML reader gives the data of a 1×1 matrix (omnidir's
        // xi) as a number, not a list of one.
        let count = if data_node.is_seq().unwrap_or(false) {
            data_node.size().unwrap_or(0) as i64
        } else if Self::number(&data_node).is_some() {
            1
        } else {
            -1
        };
        let dt = n
            .get("dt")
            .ok()
            .and_then(|d| d.to_string().ok())
            .unwrap_or_default();
        if count != rows * cols || !matches!(dt.as_str(), "u" | "c" | "w" | "s" | "i" | "f" | "d") {
            return Err(self.field(
                key,
                &format!(
                    "a {rows}×{cols} single-channel matrix with {} values",
                    rows * cols
                ),
                if count < 0 {
                    "no data list".to_owned()
                } else {
                    format!("{count} values of type \"{dt}\"")
                },
            ));
        }
        let m = n.mat().map_err(|e| {
            self.field(
                key,
                expected,
                format!("a matrix OpenCV cannot read ({})", e.message.trim()),
            )
        })?;
        let data = mat_to_f64(&m)?;
        Ok(Some(Matrix {
            rows: rows as usize,
            cols: cols as usize,
            data,
        }))
    }

    fn finite(&self, key: &str, m: &Matrix) -> Result<()> {
        match m.data.iter().find(|v| !v.is_finite()) {
            Some(v) => Err(self.field(key, "finite numbers", format!("{v}"))),
            None => Ok(()),
        }
    }

    fn matrix3(&self, key: &str) -> Result<Option<Matrix3<f64>>> {
        let expected = "a 3×3 matrix";
        match self.matrix(key, expected)? {
            None => Ok(None),
            Some(m) if m.rows == 3 && m.cols == 3 => {
                self.finite(key, &m)?;
                Ok(Some(Matrix3::from_row_slice(&m.data)))
            }
            Some(m) => Err(self.field(key, expected, m.shape())),
        }
    }

    fn vector(&self, key: &str, n: usize) -> Result<Option<Vec<f64>>> {
        let expected = format!("{n} numbers ({n}×1 or 1×{n})");
        match self.matrix(key, &expected)? {
            None => Ok(None),
            Some(m) if m.is_vector(n) => {
                self.finite(key, &m)?;
                Ok(Some(m.data))
            }
            Some(m) => Err(self.field(key, &expected, m.shape())),
        }
    }

    fn resolution(&self) -> Result<(u32, u32)> {
        let to_u32 = |key: &str, v: f64| -> Result<u32> {
            if (1.0..=1e6).contains(&v) && v.fract() == 0.0 {
                Ok(v as u32)
            } else {
                Err(self.field(key, "a positive whole number of pixels", format!("{v}")))
            }
        };
        if let Some(r) = self.vector("resolution", 2)? {
            return Ok((to_u32("resolution", r[0])?, to_u32("resolution", r[1])?));
        }
        let scalar = |key: &str| -> Result<Option<f64>> {
            match self.node(key)? {
                None => Ok(None),
                Some(n) => match Self::number(&n) {
                    Some(v) => Ok(Some(v)),
                    None => Err(self.field(key, "a number of pixels", Self::describe(&n))),
                },
            }
        };
        match (scalar("image_width")?, scalar("image_height")?) {
            (Some(w), Some(h)) => Ok((to_u32("image_width", w)?, to_u32("image_height", h)?)),
            _ => Err(self.missing(
                "resolution",
                "the image size: width and height (2×1), or image_width and image_height",
            )),
        }
    }

    // The structural zeros and one of a camera matrix are exact in any file
    // OpenCV writes; anything else is not a camera matrix.
    #[allow(clippy::float_cmp)]
    fn camera(&self, hint: Option<ModelKind>) -> Result<OpenCvCamera> {
        let k = self
            .matrix3("camera_matrix")?
            .ok_or_else(|| self.missing("camera_matrix", "a 3×3 camera matrix"))?;
        let structural = [(1, 0), (2, 0), (2, 1)];
        if structural.iter().any(|&(r, c)| k[(r, c)] != 0.0) || k[(2, 2)] != 1.0 {
            return Err(self.field(
                "camera_matrix",
                "[fx 0 cx; 0 fy cy; 0 0 1]",
                format!(
                    "a last row of [{} {} {}] or a non-zero below the diagonal",
                    k[(2, 0)],
                    k[(2, 1)],
                    k[(2, 2)]
                ),
            ));
        }
        // OpenCV omnidir's files (the unified model) carry ξ as `xi`, a
        // number or a 1×1 matrix, and may have a skew.
        let xi = match self.node("xi")? {
            None => None,
            Some(n) => match Self::number(&n) {
                Some(v) if v.is_finite() => Some(v),
                _ => self.vector("xi", 1)?.map(|v| v[0]),
            },
        };
        if k[(0, 1)] != 0.0 && xi.is_none() {
            return Err(self.field(
                "camera_matrix",
                "no skew (element (0,1) = 0) outside OpenCV omnidir's files (which have xi)",
                format!("{}", k[(0, 1)]),
            ));
        }
        let (dist_key, dist) = match self.matrix("dist_coeffs", "distortion coefficients")? {
            Some(d) => ("dist_coeffs", d),
            None => match self.matrix("distortion_coefficients", "distortion coefficients")? {
                Some(d) => ("distortion_coefficients", d),
                None => return Err(self.missing(
                    "dist_coeffs",
                    "the distortion coefficients (4 for fisheye, 4, 5, 8, 12 or 14 for pinhole)",
                )),
            },
        };
        self.finite(dist_key, &dist)?;
        if dist.rows != 1 && dist.cols != 1 {
            return Err(self.field(dist_key, "a row or column of coefficients", dist.shape()));
        }
        let (width, height) = self.resolution()?;

        let surround = match self.matrix3("project_matrix")? {
            None => None,
            Some(project_matrix) => {
                let pair = |key: &str| -> Result<[f64; 2]> {
                    let v = self.vector(key, 2)?.ok_or_else(|| {
                        self.missing(key, "2 numbers (x, y), since the file has project_matrix")
                    })?;
                    Ok([v[0], v[1]])
                };
                Some(SurroundKeys {
                    project_matrix,
                    scale_xy: pair("scale_xy")?,
                    shift_xy: pair("shift_xy")?,
                })
            }
        };

        let declared = match self.node("camera_model")? {
            None => None,
            Some(n) => {
                let s = n.to_string().unwrap_or_default();
                match s.as_str() {
                    "fisheye" => Some(ModelKind::Fisheye),
                    "pinhole" => Some(ModelKind::Pinhole),
                    "rational" => Some(ModelKind::Rational),
                    "omnidir" => Some(ModelKind::Omni),
                    _ if n.is_string().unwrap_or(false) => {
                        return Err(CalibError::UnknownModel {
                            file: self.file.into(),
                            field: "camera_model".into(),
                            model: s,
                            supported: "fisheye, pinhole, rational, omnidir".into(),
                        })
                    }
                    _ => {
                        return Err(self.field(
                            "camera_model",
                            "\"fisheye\", \"pinhole\" or \"rational\"",
                            Self::describe(&n),
                        ))
                    }
                }
            }
        };
        let n = dist.data.len();
        let kind = declared
            .or(hint)
            .or(surround.map(|_| ModelKind::Fisheye))
            .or((n >= 5).then_some(ModelKind::Pinhole));
        let distortion = if let Some(xi) = xi {
            if declared.is_some_and(|d| d != ModelKind::Omni) {
                return Err(self.field(
                    "camera_model",
                    "\"omnidir\" or none in a file with xi (OpenCV omnidir's unified model)",
                    format!("{declared:?}"),
                ));
            }
            if n != 4 {
                return Err(self.field(
                    dist_key,
                    "4 coefficients k1, k2, p1, p2 (OpenCV omnidir)",
                    format!("{n}"),
                ));
            }
            let d = &dist.data;
            Distortion::Omni([xi, d[0], d[1], d[2], d[3], k[(0, 1)]])
        } else {
            match kind {
            Some(ModelKind::Fisheye) if n == 4 => {
                Distortion::Fisheye([dist.data[0], dist.data[1], dist.data[2], dist.data[3]])
            }
            Some(ModelKind::Fisheye) => {
                return Err(self.field(dist_key, "4 fisheye coefficients k1..k4", format!("{n}")))
            }
            Some(kind @ (ModelKind::Pinhole | ModelKind::Rational))
                if matches!(n, 4 | 5 | 8 | 12 | 14)
                    && (kind == ModelKind::Pinhole || n >= 8) =>
            {
                let d = &dist.data;
                if let Some(i) = (8..n).find(|&i| d[i] != 0.0) {
                    return Err(self.field(
                        dist_key,
                        "pinhole coefficients k1, k2, p1, p2, k3[, k4, k5, k6] (the thin-prism and tilt terms must be 0)",
                        format!("coefficient {i} = {}", d[i]),
                    ));
                }
                let rational_terms = n >= 8 && d[5..8].iter().any(|&v| v != 0.0);
                if n >= 8 && (kind == ModelKind::Rational || rational_terms) {
                    let mut k = [0.0; 8];
                    k.copy_from_slice(&d[..8]);
                    Distortion::Rational(k)
                } else {
                    let mut k = [0.0; 5];
                    k[..n.min(5)].copy_from_slice(&d[..n.min(5)]);
                    Distortion::RadTan(k)
                }
            }
            Some(ModelKind::Pinhole) => {
                return Err(self.field(
                    dist_key,
                    "4, 5, 8, 12 or 14 pinhole coefficients",
                    format!("{n}"),
                ))
            }
            Some(ModelKind::Rational) => {
                return Err(self.field(
                    dist_key,
                    "8 rational coefficients k1, k2, p1, p2, k3, k4, k5, k6 (or 12 or 14 whose terms after k6 are 0)",
                    format!("{n}"),
                ))
            }
            Some(
                other @ (ModelKind::DoubleSphere
                | ModelKind::Eucm
                | ModelKind::Omni
                | ModelKind::RadialPoly
                | ModelKind::Scaramuzza
                | ModelKind::Fov),
            ) => {
                return Err(self.field(
                    "camera_model",
                    "\"fisheye\", \"pinhole\" or \"rational\" (OpenCV's files hold no other model)",
                    format!("{other:?} asked for"),
                ))
            }
            None => {
                return Err(self.field(
                    "camera_model",
                    "\"fisheye\" or \"pinhole\" (4 coefficients fit both models: add camera_model to the file or name the model)",
                    "no camera_model",
                ))
            }
        }
        };
        let intrinsics = Intrinsics {
            width,
            height,
            fx: k[(0, 0)],
            fy: k[(1, 1)],
            cx: k[(0, 2)],
            cy: k[(1, 2)],
            distortion,
        };
        intrinsics.validate().map_err(|e| {
            let field = match e.field.as_str() {
                "fx" | "fy" | "cx" | "cy" => "camera_matrix".to_owned(),
                "resolution" => "resolution".to_owned(),
                _ => dist_key.to_owned(),
            };
            e.renamed(field).in_file(self.file)
        })?;

        let pose = match (
            self.matrix3("rotation_camera_to_rig")?,
            self.vector("translation_camera_in_rig_m", 3)?,
        ) {
            (None, None) => None,
            (Some(r), Some(t)) => {
                Some(Pose::new(r, Vector3::new(t[0], t[1], t[2])).map_err(|e| {
                    FieldError {
                        field: "rotation_camera_to_rig".into(),
                        ..e
                    }
                    .in_file(self.file)
                })?)
            }
            (Some(_), None) => {
                return Err(self.missing(
                    "translation_camera_in_rig_m",
                    "3 numbers, since the file has rotation_camera_to_rig",
                ))
            }
            (None, Some(_)) => {
                return Err(self.missing(
                    "rotation_camera_to_rig",
                    "a 3×3 rotation, since the file has translation_camera_in_rig_m",
                ))
            }
        };
        Ok(OpenCvCamera {
            intrinsics,
            pose,
            surround,
        })
    }
}

/// Writes one camera as OpenCV FileStorage text (YAML, or XML if `xml`),
/// with rigview's `camera_model` and, if the camera has a pose, its pose
/// keys. Numbers are written with 17 significant digits, so they read back
/// exactly.
pub fn write(camera: &Camera, xml: bool) -> Result<String> {
    let k = &camera.intrinsics;
    let name = if xml { ".xml" } else { ".yaml" };
    let mut fs = cv(
        "opening a FileStorage for writing",
        FileStorage::new(
            name,
            FileStorage_WRITE | FileStorage_MEMORY | if xml { FileStorage_FORMAT_XML } else { 0 },
            "",
        ),
    )?;
    let mut cm = k.camera_matrix();
    let ctx = "writing a FileStorage file";
    if let Distortion::Omni([xi, k1, k2, p1, p2, skew]) = k.distortion {
        // As OpenCV omnidir writes it: K with its skew, D (1×4), xi (1×1).
        cm[0][1] = skew;
        let flat: Vec<f64> = cm.iter().flatten().copied().collect();
        cv(ctx, fs.write_mat("camera_matrix", &mat_f64(3, 3, &flat)?))?;
        cv(
            ctx,
            fs.write_mat(
                "distortion_coefficients",
                &mat_f64(1, 4, &[k1, k2, p1, p2])?,
            ),
        )?;
        cv(ctx, fs.write_mat("xi", &mat_f64(1, 1, &[xi])?))?;
    } else {
        let flat: Vec<f64> = cm.iter().flatten().copied().collect();
        cv(ctx, fs.write_mat("camera_matrix", &mat_f64(3, 3, &flat)?))?;
        let d = k.distortion.coefficients();
        cv(
            ctx,
            fs.write_mat("dist_coeffs", &mat_f64(d.len() as i32, 1, d)?),
        )?;
    }
    let res = [
        i32::try_from(k.width).unwrap_or(i32::MAX),
        i32::try_from(k.height).unwrap_or(i32::MAX),
    ];
    cv(ctx, fs.write_mat("resolution", &mat_i32(2, 1, &res)?))?;
    let model = match k.distortion {
        Distortion::Fisheye(_) => "fisheye",
        Distortion::RadTan(_) => "pinhole",
        Distortion::Rational(_) => "rational",
        Distortion::Omni(_) => "omnidir",
        Distortion::DoubleSphere(_)
        | Distortion::Eucm(_)
        | Distortion::RadialPoly(_)
        | Distortion::Scaramuzza(_)
        | Distortion::Fov(_) => {
            return Err(CalibError::Argument(format!(
                "camera \"{}\": OpenCV's calibration files hold the fisheye, pinhole, \
                 rational and omnidir (omni-radtan) models, not {}; write it as rig or kalibr",
                camera.name,
                k.distortion.model_name()
            )))
        }
    };
    cv(ctx, fs.write_str("camera_model", model))?;
    if let Some(p) = &camera.pose {
        let r = p.rotation_matrix();
        let rows: Vec<f64> = (0..3)
            .flat_map(|i| (0..3).map(move |j| r[(i, j)]))
            .collect();
        cv(
            ctx,
            fs.write_mat("rotation_camera_to_rig", &mat_f64(3, 3, &rows)?),
        )?;
        let t = p.translation();
        cv(
            ctx,
            fs.write_mat(
                "translation_camera_in_rig_m",
                &mat_f64(3, 1, &[t.x, t.y, t.z])?,
            ),
        )?;
    }
    cv(ctx, fs.release_and_get_string())
}
