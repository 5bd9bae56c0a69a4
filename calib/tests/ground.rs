//! `calib ground` recovers known poses from rendered images of checkerboard
//! mats: each camera of a synthetic rig (three 190° fisheyes, a
//! radial-tangential pinhole and a rational pinhole) sees its own mat, rendered through the camera model at a known
//! pose; the tool detects the corners, solves the poses, and must find the
//! poses the images were rendered with.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::Vector3;
use rigview_calib::tools::ground::{self, GroundLayout, GroundMat, GroundView};
use rigview_calib::tools::render::{render_mat, Palette};
use rigview_calib::{Camera, Distortion, Frame, Intrinsics, Pose, Rig};

fn fisheye() -> Intrinsics {
    Intrinsics {
        width: 640,
        height: 480,
        fx: 205.0,
        fy: 204.0,
        cx: 322.5,
        cy: 238.0,
        distortion: Distortion::Fisheye([-0.02, 0.01, -0.004, 0.0005]),
    }
}

fn pinhole() -> Intrinsics {
    Intrinsics {
        width: 640,
        height: 480,
        fx: 420.0,
        fy: 421.0,
        cx: 318.0,
        cy: 243.0,
        distortion: Distortion::RadTan([-0.25, 0.07, 0.001, -0.0005, -0.01]),
    }
}

fn rational() -> Intrinsics {
    Intrinsics {
        distortion: Distortion::Rational([-0.2, 0.05, 0.001, -0.0005, 0.0, 0.15, 0.02, 0.0]),
        ..pinhole()
    }
}

/// The true rig, and each camera's mat: on the ground, centred where the
/// optical axis meets it, its x axis across the view.
fn truth() -> (Rig, Vec<GroundMat>) {
    let cams = [
        ("front", fisheye(), [2.0, 30.0, 1.0], [2.3, 0.1, 0.75], 0.3),
        ("left", fisheye(), [88.0, 45.0, -1.5], [0.8, 1.0, 1.05], 0.3),
        (
            "back",
            fisheye(),
            [178.0, 35.0, 0.5],
            [-2.1, 0.0, 0.95],
            0.3,
        ),
        (
            "right",
            pinhole(),
            [-93.0, 50.0, 2.0],
            [0.9, -1.0, 1.0],
            0.2,
        ),
        (
            "aux",
            rational(),
            [-40.0, 50.0, -1.0],
            [1.6, -0.8, 1.0],
            0.2,
        ),
    ];
    let mut cameras = Vec::new();
    let mut mats = Vec::new();
    for (name, k, ypr, t, square) in cams {
        let pose = Pose::from_ypr_deg(ypr, Vector3::from(t)).unwrap();
        let axis = pose.optical_axis();
        let hit = pose.translation() + axis * (-t[2] / axis.z);
        let yaw = ypr[0] - 90.0;
        let (s, c) = yaw.to_radians().sin_cos();
        let (w, h) = (8.0 * square, 5.0 * square);
        mats.push(GroundMat {
            squares: [8, 5],
            square_m: square,
            origin_m: [hit.x - 0.5 * (w * c - h * s), hit.y - 0.5 * (w * s + h * c)],
            yaw_deg: yaw,
            margin_m: square,
        });
        let mut cam = Camera::new(name, k);
        cam.pose = Some(pose);
        cameras.push(cam);
    }
    let rig = Rig::new(
        Frame::Vehicle,
        cameras,
        vec![(0, 1), (1, 2), (2, 3), (3, 0)],
    )
    .unwrap();
    (rig, mats)
}

#[test]
fn recovers_known_poses_from_rendered_mats() {
    let (truth, mats) = truth();
    let dir = std::env::temp_dir().join(format!("rigview-calib-ground-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut views = Vec::new();
    for (c, mat) in truth.cameras.iter().zip(&mats) {
        let img = render_mat(c, mat, &Palette::default(), 2);
        let file = format!("{}.png", c.name);
        img.save_png(&dir.join(&file)).unwrap();
        views.push(GroundView {
            camera: c.name.clone(),
            image: file.into(),
            mat: *mat,
        });
    }
    let layout = GroundLayout {
        format: "rigview-ground".into(),
        version: 1,
        views,
    };
    let layout_path = dir.join("layout.yaml");
    std::fs::write(&layout_path, layout.to_string().unwrap()).unwrap();

    // Start from the rig without poses, as a fresh intrinsic calibration
    // would give it.
    let mut start = truth.clone();
    for c in &mut start.cameras {
        c.pose = None;
    }
    let (solved, results) =
        ground::calibrate(&start, &GroundLayout::load(&layout_path).unwrap()).unwrap();
    for (g, t) in results.iter().zip(&truth.cameras) {
        let tp = t.pose.unwrap();
        let dt = (g.pose.translation() - tp.translation()).norm();
        let da = g.pose.rotation_angle_to(&tp).to_degrees();
        println!(
            "{}: {} corners, reprojection RMS {:.3} px (max {:.3}), position error {:.2} mm, rotation error {:.4}°, square contrast {:.0}",
            g.camera,
            g.corners,
            g.rms_px,
            g.max_px,
            dt * 1000.0,
            da,
            g.contrast
        );
        assert!(g.rms_px < 0.3, "{}: {} px", g.camera, g.rms_px);
        assert!(dt < 0.005, "{}: position off by {dt} m", g.camera);
        assert!(da < 0.1, "{}: rotation off by {da}°", g.camera);
        assert_eq!(solved.camera(&g.camera).unwrap().pose, Some(g.pose));
    }
    assert_eq!(results.len(), 5);

    // A mat of the wrong size is not found, and the error names the camera.
    let mut wrong = GroundLayout::load(&layout_path).unwrap();
    wrong.views.truncate(1);
    wrong.views[0].mat.squares = [9, 5];
    let e = ground::calibrate(&start, &wrong).unwrap_err().to_string();
    assert!(e.contains("front") && e.contains("8×4"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
