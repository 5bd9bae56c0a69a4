//! Turning rigs' cameras, refining them and comparing their orientations
//! (the panorama's refinement tests).

use nalgebra::{Rotation3, Unit, Vector3};
use rigview_calib::{Pose, Rig};
use rigview_core::image::FrameView;
use rigview_core::panorama::{
    refine_in_rounds, CylinderSpec, PanoramaOptions, Rounds, RoundsOptions,
};
use rigview_core::Result;

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

/// Turns camera `k` of `rig` by `angle_deg` about `axis` (rig frame), its
/// centre kept (posed cameras only).
#[allow(clippy::expect_used)]
pub fn turn_camera(rig: &mut Rig, k: usize, axis: &Vector3<f64>, angle_deg: f64) {
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(*axis), angle_deg.to_radians());
    let pose = rig.cameras[k].pose.expect("a posed camera");
    rig.cameras[k].pose = Some(
        Pose::new(turn * pose.rotation_matrix(), *pose.translation())
            .expect("a rotation turned stays a rotation"),
    );
}

/// The product's refinement in rounds of `rig` on `frames`, at its
/// defaults (cylinder, panorama, rounds) with the subpixel Harris corners.
pub fn refine_by_default(rig: &Rig, frames: &[FrameView<'_>]) -> Result<Rounds> {
    refine_in_rounds(
        rig,
        &CylinderSpec::default(),
        &PanoramaOptions::default(),
        frames,
        &crate::harris_subpixel,
        &RoundsOptions::default(),
    )
}
