//! Rigid poses of cameras.
//!
//! A [`Pose`] takes points from the camera frame (OpenCV's: x right, y down,
//! z along the optical axis) to the rig frame: `p_rig = R · p_cam + t`. In a
//! vehicle-frame rig, the rig frame is x forward, y left, z up, with the
//! ground at z = 0, and `t` is the camera's centre in metres.
//!
//! For people, an orientation is also given as yaw, pitch and roll in
//! degrees relative to a camera that looks straight ahead along +x, level:
//! `R = Rz(yaw) · Ry(pitch) · Rx(roll) · B`, where `B` maps the camera axes
//! to the vehicle axes (optical axis → +x, image right → −y, image down →
//! −z). Yaw turns left (front 0°, left 90°, back 180°, right −90°), pitch
//! tilts the optical axis down, roll turns about the optical axis.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::error::FieldError;

/// How far `RᵀR` may be from the identity (largest entry) for a rotation
/// read from a file.
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-6;

/// The camera-to-vehicle rotation of a camera that looks straight ahead.
pub fn forward_camera_axes() -> Matrix3<f64> {
    Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0)
}

/// A rigid camera-to-rig transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    rotation: Matrix3<f64>,
    translation: Vector3<f64>,
}

impl Pose {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// A pose from a rotation matrix (camera to rig) and a translation (the
    /// camera centre in the rig frame, metres). The matrix must be finite and
    /// orthonormal with determinant +1 (to [`ORTHONORMAL_TOLERANCE`]); it is
    /// kept exactly as given.
    pub fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Result<Self, FieldError> {
        if let Some(v) = translation.iter().find(|v| !v.is_finite()) {
            return Err(FieldError::new(
                "translation_m",
                "three finite numbers",
                format!("{v}"),
            ));
        }
        check_rotation(&rotation)?;
        Ok(Self {
            rotation,
            translation,
        })
    }

    /// A pose from yaw, pitch and roll in degrees (see the module docs) and
    /// the camera centre.
    pub fn from_ypr_deg(ypr: [f64; 3], translation: Vector3<f64>) -> Result<Self, FieldError> {
        if let Some(v) = ypr.iter().find(|v| !v.is_finite()) {
            return Err(FieldError::new(
                "rotation_ypr_deg",
                "three finite angles",
                format!("{v}"),
            ));
        }
        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), ypr[0].to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), ypr[1].to_radians())
            * Rotation3::from_axis_angle(&Vector3::x_axis(), ypr[2].to_radians());
        Self::new(r.matrix() * forward_camera_axes(), translation)
    }

    /// A pose from OpenCV's `rvec`/`tvec` (rig to camera, as `solvePnP`
    /// returns them).
    pub fn from_opencv_rvec_tvec(rvec: &Vector3<f64>, tvec: &Vector3<f64>) -> Self {
        let r_cw = Rotation3::new(*rvec);
        let r = r_cw.inverse();
        Self {
            rotation: *r.matrix(),
            translation: -(r * tvec),
        }
    }

    /// OpenCV's `rvec`/`tvec` (rig to camera).
    pub fn to_opencv_rvec_tvec(&self) -> (Vector3<f64>, Vector3<f64>) {
        let r_cw = self.rotation().inverse();
        (r_cw.scaled_axis(), -(r_cw * self.translation))
    }

    /// The rotation matrix, camera to rig, exactly as stored.
    pub fn rotation_matrix(&self) -> &Matrix3<f64> {
        &self.rotation
    }

    /// The rotation, re-orthonormalised: through its unit quaternion
    /// (Shepperd's closed form, exact for every orientation; nalgebra's
    /// `Rotation3::from_matrix` iterates from the identity and can end at
    /// another rotation near a half turn from it).
    pub fn rotation(&self) -> Rotation3<f64> {
        UnitQuaternion::new_normalize(self.quaternion().into_inner()).to_rotation_matrix()
    }

    /// The rotation as a quaternion, by Shepperd's closed form from the
    /// stored matrix (exact for every orientation), as the formats that
    /// write quaternions give it.
    pub fn quaternion(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(self.rotation))
    }

    /// The camera centre in the rig frame, metres.
    pub fn translation(&self) -> &Vector3<f64> {
        &self.translation
    }

    /// Yaw, pitch and roll in degrees (see the module docs).
    pub fn ypr_deg(&self) -> [f64; 3] {
        let m = self.rotation * forward_camera_axes().transpose();
        let yaw = m[(1, 0)].atan2(m[(0, 0)]);
        let pitch = (-m[(2, 0)]).clamp(-1.0, 1.0).asin();
        let roll = m[(2, 1)].atan2(m[(2, 2)]);
        [yaw.to_degrees(), pitch.to_degrees(), roll.to_degrees()]
    }

    /// The optical axis in the rig frame (unit vector).
    pub fn optical_axis(&self) -> Vector3<f64> {
        self.rotation.column(2).normalize()
    }

    /// A camera-frame point in the rig frame.
    pub fn to_rig(&self, p_cam: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p_cam + self.translation
    }

    /// A rig-frame point in the camera frame.
    pub fn to_camera(&self, p_rig: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.transpose() * (p_rig - self.translation)
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Pose) -> Self {
        Self {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The angle of the rotation between two poses, radians (accurate for
    /// tiny angles too: 2·atan2(|v|, w) of the quaternion).
    pub fn rotation_angle_to(&self, other: &Pose) -> f64 {
        let q =
            UnitQuaternion::from_rotation_matrix(&(self.rotation().inverse() * other.rotation()));
        2.0 * q.imag().norm().atan2(q.w.abs())
    }
}

/// Checks that a matrix is a rotation: finite, orthonormal to
/// [`ORTHONORMAL_TOLERANCE`], determinant +1.
pub fn check_rotation(m: &Matrix3<f64>) -> Result<(), FieldError> {
    if let Some(v) = m.iter().find(|v| !v.is_finite()) {
        return Err(FieldError::new(
            "rotation_matrix",
            "nine finite numbers",
            format!("{v}"),
        ));
    }
    let dev = (m.transpose() * m - Matrix3::identity()).amax();
    if dev > ORTHONORMAL_TOLERANCE {
        return Err(FieldError::new(
            "rotation_matrix",
            format!("an orthonormal rotation (|RᵀR − I| ≤ {ORTHONORMAL_TOLERANCE:e})"),
            format!("|RᵀR − I| = {dev:.3e}"),
        ));
    }
    let det = m.determinant();
    if det < 0.0 {
        return Err(FieldError::new(
            "rotation_matrix",
            "a proper rotation (determinant +1)",
            format!("determinant {det:.6}"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ypr_round_trip_and_meaning() {
        let p = Pose::from_ypr_deg([90.0, 30.0, 5.0], Vector3::new(0.0, 1.0, 1.2)).unwrap();
        let ypr = p.ypr_deg();
        for (a, b) in ypr.iter().zip([90.0, 30.0, 5.0]) {
            assert!((a - b).abs() < 1e-9, "{ypr:?}");
        }
        // Yaw 90° looks left (+y), pitch 30° looks down.
        let axis = p.optical_axis();
        assert!(axis.y > 0.8 && axis.z < -0.4, "{axis}");
        let front = Pose::from_ypr_deg([0.0, 0.0, 0.0], Vector3::zeros()).unwrap();
        assert!((front.optical_axis() - Vector3::x()).norm() < 1e-15);
    }

    #[test]
    fn opencv_rvec_tvec_round_trip() {
        let p = Pose::from_ypr_deg([-120.0, 40.0, -3.0], Vector3::new(-2.0, -0.9, 0.8)).unwrap();
        let (r, t) = p.to_opencv_rvec_tvec();
        let q = Pose::from_opencv_rvec_tvec(&r, &t);
        assert!((p.translation() - q.translation()).norm() < 1e-12);
        assert!(p.rotation_angle_to(&q) < 1e-12);
        let x = Vector3::new(1.0, 2.0, 3.0);
        assert!((p.to_camera(&p.to_rig(&x)) - x).norm() < 1e-12);
        assert!((p.inverse().compose(&p).translation()).norm() < 1e-12);
    }

    #[test]
    fn rejects_non_rotations() {
        let mut m = forward_camera_axes();
        m[(0, 0)] = 0.01;
        assert!(check_rotation(&m).is_err());
        let mirror = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        assert!(check_rotation(&mirror)
            .unwrap_err()
            .expected
            .contains("determinant"));
    }
}

#[cfg(test)]
mod rotation_tests {
    use super::*;

    #[test]
    fn the_reorthonormalised_rotation_is_the_stored_one_for_every_orientation() {
        let mut worst: f64 = 0.0;
        for yaw in (-180..180).step_by(15) {
            for pitch in (-90..=90).step_by(15) {
                for roll in (-180..180).step_by(30) {
                    let ypr = [f64::from(yaw), f64::from(pitch), f64::from(roll)];
                    let p = Pose::from_ypr_deg(ypr, Vector3::zeros()).unwrap();
                    let d = (p.rotation().matrix() - p.rotation_matrix()).abs().max();
                    worst = worst.max(d);
                }
            }
        }
        assert!(worst < 1e-12, "{worst}");
    }
}
