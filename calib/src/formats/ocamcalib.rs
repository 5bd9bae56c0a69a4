//! OCamCalib's `calib_results.txt`: one camera, without a pose.
//!
//! ```text
//! #polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by cam2world
//!
//! 5 -1.800000e+02 0.000000e+00 2.300000e-03 -4.000000e-06 1.300000e-08
//!
//! #polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). These are used by world2cam
//!
//! 13 285.007714 185.052865 4.161359 …
//!
//! #center: "row" and "column", starting from 0 (C convention)
//!
//! 249.336977 360.589015
//!
//! #affine parameters "c", "d", "e"
//!
//! 1.000012 0.000067 0.000154
//!
//! #image size: "height" and "width"
//!
//! 480 720
//! ```
//!
//! Each polynomial's line starts with its number of coefficients, lowest
//! order first. The centre is (row, column) and the size (height, width):
//! rigview's principal point is (column, row), and its image width ×
//! height. Lines starting with `#` are comments; the five lines of numbers
//! come in this order.

use crate::error::{CalibError, FieldError, Result};
use crate::model::ocam::Ocam;
use crate::model::{Distortion, Intrinsics};
use crate::rig::Camera;

/// The first comment OCamCalib writes.
const HEADER: &str = "#polynomial coefficients for the DIRECT mapping function";

/// Whether `text` is an OCamCalib result file.
pub(crate) fn looks_like(text: &str) -> bool {
    text.trim_start_matches('\u{feff}')
        .trim_start()
        .starts_with(HEADER)
}

/// The five lines of numbers, each with its line number and name.
const FIELDS: [(&str, &str); 5] = [
    ("pol", "the count of pol's coefficients, then each"),
    ("invpol", "the count of invpol's coefficients, then each"),
    ("center", "2 numbers: row, column"),
    ("affine", "3 numbers: c, d, e"),
    ("image size", "2 whole numbers: height, width"),
];

fn field_error(file: &str, line: usize, field: &str, expected: &str, found: String) -> CalibError {
    FieldError::new(format!("{field} (line {line})"), expected, found).in_file(file)
}

/// Parses one camera named `name`.
pub fn parse(text: &str, file: &str, name: &str) -> Result<Camera> {
    let mut rows: Vec<(usize, Vec<f64>)> = Vec::with_capacity(5);
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let k = rows.len();
        let Some(&(field, expected)) = FIELDS.get(k) else {
            return Err(CalibError::Format {
                file: file.into(),
                detail: format!(
                    "line {}: a sixth line of numbers; OCamCalib's file has five (pol, invpol, \
                     center, affine, image size)",
                    i + 1
                ),
            });
        };
        let numbers = line
            .split_whitespace()
            .map(|w| w.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| field_error(file, i + 1, field, expected, format!("\"{line}\"")))?;
        rows.push((i + 1, numbers));
    }
    if rows.len() < FIELDS.len() {
        let (field, expected) = FIELDS[rows.len()];
        return Err(CalibError::Missing {
            file: file.into(),
            field: field.into(),
            expected: expected.into(),
        });
    }
    let counted = |k: usize| -> Result<&[f64]> {
        let (line, v) = &rows[k];
        let (field, expected) = FIELDS[k];
        let n = v.first().copied().unwrap_or(-1.0);
        if n < 0.0 || n.fract() != 0.0 || v.len() != n as usize + 1 {
            return Err(field_error(
                file,
                *line,
                field,
                expected,
                format!(
                    "a count of {n} and {} coefficients",
                    v.len().saturating_sub(1)
                ),
            ));
        }
        Ok(&v[1..])
    };
    let sized = |k: usize, len: usize| -> Result<&[f64]> {
        let (line, v) = &rows[k];
        let (field, expected) = FIELDS[k];
        if v.len() == len {
            Ok(v)
        } else {
            Err(field_error(
                file,
                *line,
                field,
                expected,
                format!("{} numbers", v.len()),
            ))
        }
    };
    let pol = counted(0)?;
    let invpol = counted(1)?;
    let center = sized(2, 2)?;
    let affine = sized(3, 3)?;
    let size = sized(4, 2)?;
    let pixels = |v: f64| -> Result<u32> {
        if (1.0..=1e6).contains(&v) && v.fract() == 0.0 {
            Ok(v as u32)
        } else {
            Err(field_error(
                file,
                rows[4].0,
                "image size",
                FIELDS[4].1,
                format!("{v}"),
            ))
        }
    };
    let (height, width) = (pixels(size[0])?, pixels(size[1])?);
    let (row, col) = (center[0], center[1]);
    if !(-0.5..=f64::from(height) - 0.5).contains(&row)
        || !(-0.5..=f64::from(width) - 0.5).contains(&col)
    {
        return Err(field_error(
            file,
            rows[2].0,
            "center",
            "a centre (row, column) on the image",
            format!("({row}, {col}) on a {height}×{width} (height × width) image"),
        ));
    }
    let ocam = Ocam::new(pol, invpol, [affine[0], affine[1], affine[2]]).map_err(|e| {
        let line = if e.field == "invpol" {
            rows[1].0
        } else {
            rows[0].0
        };
        FieldError {
            field: format!("{} (line {line})", e.field),
            ..e
        }
        .in_file(file)
    })?;
    let intrinsics = Intrinsics {
        width,
        height,
        fx: 1.0,
        fy: 1.0,
        cx: col,
        cy: row,
        distortion: Distortion::Scaramuzza(ocam),
    };
    intrinsics.validate().map_err(|e| e.in_file(file))?;
    Ok(Camera {
        name: name.into(),
        device: None,
        intrinsics,
        pose: None,
    })
}

/// Writes one camera of Scaramuzza's model as OCamCalib does (its pose,
/// if any, has no place in the file).
pub fn write(camera: &Camera) -> Result<String> {
    let k = &camera.intrinsics;
    let Distortion::Scaramuzza(o) = k.distortion else {
        return Err(CalibError::Argument(format!(
            "camera \"{}\": OCamCalib's file holds Scaramuzza's model, not {}; write it as rig",
            camera.name,
            k.distortion.model_name()
        )));
    };
    if (k.fx - 1.0).abs() > 0.0 || (k.fy - 1.0).abs() > 0.0 {
        return Err(CalibError::Argument(format!(
            "camera \"{}\": OCamCalib's polynomials are in pixels (focal length 1), these \
             intrinsics have ({}, {})",
            camera.name, k.fx, k.fy
        )));
    }
    let list = |v: &[f64]| {
        std::iter::once(format!("{}", v.len()))
            .chain(v.iter().map(|x| format!("{x:e}")))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let [c, d, e] = o.affine();
    Ok(format!(
        "{HEADER} (ocam_model.ss in MATLAB). These are used by cam2world\n\n{}\n\n\
         #polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). \
         These are used by world2cam\n\n{}\n\n\
         #center: \"row\" and \"column\", starting from 0 (C convention)\n\n{:e} {:e}\n\n\
         #affine parameters \"c\", \"d\", \"e\"\n\n{c:e} {d:e} {e:e}\n\n\
         #image size: \"height\" and \"width\"\n\n{} {}\n",
        list(o.pol()),
        list(o.invpol()),
        k.cy,
        k.cx,
        k.height,
        k.width,
    ))
}
