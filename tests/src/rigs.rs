//! Comparing rigs' orientations (the panorama's refinement tests).

use nalgebra::Rotation3;
use rigview_calib::Rig;

/// Camera `k`'s rotation relative to camera 0's (posed cameras only: an
/// unposed one fails the test that asks).
#[allow(clippy::expect_used)]
pub fn relative(rig: &Rig, k: usize) -> Rotation3<f64> {
    let r = |c: usize| {
        let pose = rig.cameras[c].pose.expect("a posed camera");
        Rotation3::from_matrix_unchecked(*pose.rotation_matrix())
    };
    r(0).inverse() * r(k)
}

/// How far camera `k` of `rig` is turned from `truth`'s, relative to
/// camera 0, degrees.
pub fn off(rig: &Rig, truth: &Rig, k: usize) -> f64 {
    (relative(rig, k) * relative(truth, k).inverse())
        .angle()
        .to_degrees()
}
