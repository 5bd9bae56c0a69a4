//! The simulated rig's cameras: the built-in reference rig and rigs scaled
//! to another resolution.

use nalgebra::Vector3;
use rigview_calib::{Camera, Distortion, Frame, Intrinsics, Pose, Rig};

use crate::error::{Error, Result};

/// Focal length of the reference cameras, pixels (a 1.4 mm lens on
/// 3.75 µm pixels).
pub const REFERENCE_FOCAL_PX: f64 = 380.0;
/// Kannala–Brandt coefficients k1..k4 of the reference cameras.
pub const REFERENCE_DISTORTION: [f64; 4] = [0.02, -0.005, 0.0, 0.0];
/// Field of view of the reference lens, degrees.
pub const REFERENCE_FOV_DEG: f64 = 185.0;

/// The intrinsics of a reference camera: 1288×964, 185° Kannala–Brandt
/// fisheye (its 185° image circle is a little narrower than the sensor; it
/// spans about 144° vertically).
pub fn reference_intrinsics() -> Intrinsics {
    Intrinsics {
        width: 1288,
        height: 964,
        fx: REFERENCE_FOCAL_PX,
        fy: REFERENCE_FOCAL_PX,
        cx: 643.5,
        cy: 481.5,
        distortion: Distortion::Fisheye(REFERENCE_DISTORTION),
    }
}

/// The reference rig: four 185° fisheye cameras on a 4.6 m × 1.8 m car
/// (front bumper 0.9 m high and tilted down 20°, back 1.0 m and 30°,
/// the two mirrors 1.05 m and 45°), in the vehicle frame, with neighbours
/// front–left, front–right, left–back, back–right. Its calibration is the
/// simulation's truth. `assets/reference.rig.yaml` holds the same rig.
pub fn reference_rig() -> Result<Rig> {
    let k = reference_intrinsics();
    let cams = [
        ("front", [0.0, 20.0, 0.0], [2.35, 0.0, 0.9]),
        ("left", [90.0, 45.0, 0.0], [1.0, 1.0, 1.05]),
        ("back", [180.0, 30.0, 0.0], [-2.35, 0.0, 1.0]),
        ("right", [-90.0, 45.0, 0.0], [1.0, -1.0, 1.05]),
    ];
    let mut cameras = Vec::with_capacity(cams.len());
    for (name, ypr, t) in cams {
        let pose = Pose::from_ypr_deg(ypr, Vector3::from(t)).map_err(|e| {
            Error::invalid(
                format!("reference rig, camera {name}"),
                e.field,
                e.expected,
                e.found,
            )
        })?;
        cameras.push(Camera {
            name: name.into(),
            device: None,
            intrinsics: k,
            pose: Some(pose),
        });
    }
    Rig::new(
        Frame::Vehicle,
        cameras,
        vec![(0, 1), (0, 3), (1, 2), (2, 3)],
    )
    .map_err(|e| Error::invalid("reference rig", e.field, e.expected, e.found))
}

/// Intrinsics for the same lens on an image `scale` times as large (pixel
/// centres stay where they were: `c' = (c + ½)·s − ½`).
pub fn scale_intrinsics(k: &Intrinsics, scale: f64) -> Result<Intrinsics> {
    if !(scale.is_finite() && scale > 0.0 && scale <= 4.0) {
        return Err(Error::InvalidParameter {
            name: "scale",
            value: scale,
            expected: "a resolution factor in (0, 4]",
        });
    }
    let w = (f64::from(k.width) * scale).round().max(8.0);
    let h = (f64::from(k.height) * scale).round().max(8.0);
    let (sx, sy) = (w / f64::from(k.width), h / f64::from(k.height));
    Ok(Intrinsics {
        width: w as u32,
        height: h as u32,
        fx: k.fx * sx,
        fy: k.fy * sy,
        cx: (k.cx + 0.5) * sx - 0.5,
        cy: (k.cy + 0.5) * sy - 0.5,
        distortion: k.distortion,
    })
}

/// The rig with every camera's image scaled by `scale` (1: unchanged).
pub fn scale_rig(rig: &Rig, scale: f64) -> Result<Rig> {
    let mut out = rig.clone();
    if (scale - 1.0).abs() < 1e-12 {
        return Ok(out);
    }
    for c in &mut out.cameras {
        c.intrinsics = scale_intrinsics(&c.intrinsics, scale)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    #[test]
    fn the_reference_cameras_are_185_degree_fisheyes_about_a_metre_up_looking_down() {
        let rig = reference_rig().unwrap();
        assert_eq!(rig.cameras.len(), 4);
        for c in &rig.cameras {
            let fov = c.intrinsics.field_of_view();
            // The 185° lens fits the sensor's width (the image reaches
            // a little beyond); vertically it spans about 144°.
            assert!(fov.horizontal_deg.unwrap() > 185.0, "{fov:?}");
            let v = fov.vertical_deg.unwrap();
            assert!((v - 144.0).abs() < 2.0, "{v}");
            let pose = c.pose.unwrap();
            let z = pose.translation().z;
            assert!((0.85..=1.1).contains(&z), "{z}");
            assert!(pose.optical_axis().z < -0.3, "{} looks down", c.name);
        }
    }

    #[test]
    fn scaling_keeps_the_rays() {
        let k = reference_intrinsics();
        let s = scale_intrinsics(&k, 0.25).unwrap();
        assert_eq!((s.width, s.height), (322, 241));
        // The centre of full-resolution pixel (4·x + 1.5) is the centre of
        // the scaled pixel x.
        let a = k
            .unproject(&Point2::new(4.0 * 100.0 + 1.5, 4.0 * 50.0 + 1.5))
            .unwrap();
        let b = s.unproject(&Point2::new(100.0, 50.0)).unwrap();
        assert!((a.into_inner() - b.into_inner()).norm() < 1e-9);
        assert!(scale_intrinsics(&k, 0.0).is_err());
    }
}
