//! The four real fisheye cameras of `tests/data/surround-nz` become one rig:
//! poses recovered from each camera's bird's-eye homography, checked for
//! plausibility and against the homographies themselves.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod calib_common;

use nalgebra::Vector3;
use rigview_calib::formats::{self, rig_yaml, surround};
use rigview_calib::Frame;

fn wrap_deg(a: f64) -> f64 {
    (a + 180.0).rem_euclid(360.0) - 180.0
}

#[test]
fn the_four_cameras_become_one_plausible_rig() {
    let loaded = formats::load(&calib_common::data_dir().join("surround-nz"), None, None).unwrap();
    let imp = loaded
        .surround
        .as_ref()
        .expect("read as the surround layout");
    let rig = &loaded.rig;
    assert_eq!(rig.frame, Frame::Vehicle);
    let names: Vec<&str> = rig.cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["front", "left", "back", "right"]);
    assert_eq!(rig.neighbours, [(0, 1), (0, 3), (1, 2), (2, 3)]);

    // The four fitted ground points, through pose and fisheye model and back
    // through K' and H, land within a few centimetres.
    let mut worst = 0.0_f64;
    for f in &imp.fits {
        let r = f.residual_cm.map(|v| (v * 100.0).round() / 100.0);
        println!(
            "{}: fitted points land {:?} cm from where the README puts them",
            f.camera, r
        );
        for v in f.residual_cm {
            assert!(v < 5.0, "{}: {v} cm", f.camera);
            worst = worst.max(v);
        }
    }
    println!("worst fitted-point residual: {worst:.2} cm");

    // Expected yaw and where each camera sits on the car's outline
    // (car: x ∈ [−2.5, 2.5] m, y ∈ [−1, 1] m).
    let expect = [
        ("front", 0.0),
        ("left", 90.0),
        ("back", 180.0),
        ("right", -90.0),
    ];
    for (c, (name, yaw_expected)) in rig.cameras.iter().zip(expect) {
        let p = c.pose.unwrap();
        let t = p.translation();
        let [yaw, pitch, roll] = p.ypr_deg();
        println!(
            "{name}: at ({:.3}, {:.3}, {:.3}) m, yaw {yaw:.1}°, pitch {pitch:.1}° down, roll {roll:.1}°",
            t.x, t.y, t.z
        );
        assert!((0.4..1.6).contains(&t.z), "{name}: height {}", t.z);
        assert!(
            wrap_deg(yaw - yaw_expected).abs() < 15.0,
            "{name}: yaw {yaw}"
        );
        assert!((5.0..70.0).contains(&pitch), "{name}: pitch {pitch}");
        assert!(roll.abs() < 10.0, "{name}: roll {roll}");
        assert!(
            t.x.abs() < 3.0 && t.y.abs() < 1.5,
            "{name}: off the car at {t}"
        );
        match name {
            "front" => assert!(t.x > 2.0, "{t}"),
            "back" => assert!(t.x < -1.5, "{t}"),
            "left" => assert!(t.y > 0.8, "{t}"),
            _ => assert!(t.y < -0.8, "{t}"),
        }
    }

    // Over each camera's whole strip of the mat (canvas x ∈ [300, 900],
    // y ∈ [300, 1300], less the car), the pose and the homography agree:
    // ground point → pose → fisheye pixel → K', H → canvas.
    for (i, c) in rig.cameras.iter().enumerate() {
        let keys = &imp.keys[i];
        let mut d = Vec::new();
        for v in (300..=1300).step_by(20) {
            for u in (300..=900).step_by(20) {
                let (u, v) = (f64::from(u), f64::from(v));
                let (cx, cy) = surround::CAR_RECT;
                if (cx[0]..=cx[1]).contains(&u) && (cy[0]..=cy[1]).contains(&v) {
                    continue;
                }
                let [sx, sy] = surround::canvas_to_strip(&c.name, u, v).unwrap();
                let in_strip = match c.name.as_str() {
                    "front" | "back" => (0.0..1200.0).contains(&sx) && (0.0..550.0).contains(&sy),
                    _ => (0.0..1600.0).contains(&sx) && (0.0..500.0).contains(&sy),
                };
                if !in_strip {
                    continue;
                }
                let [x, y] = surround::canvas_to_vehicle(u, v);
                let Some(px) = c.project_rig(&Vector3::new(x, y, 0.0)) else {
                    continue;
                };
                if !c.intrinsics.contains(&px) {
                    continue;
                }
                // Rays beyond 90° have no place in the undistorted image.
                let Some([lu, lv]) = surround::pixel_to_canvas(&c.name, &c.intrinsics, keys, &px)
                else {
                    continue;
                };
                d.push((lu - u).hypot(lv - v));
            }
        }
        d.sort_by(f64::total_cmp);
        let median = d[d.len() / 2];
        let p90 = d[d.len() * 9 / 10];
        let max = d[d.len() - 1];
        println!(
            "{}: over {} mat points of its strip, pose vs homography: median {median:.1} cm, 90th percentile {p90:.1} cm, max {max:.1} cm",
            c.name,
            d.len()
        );
        assert!(
            d.len() > 100,
            "{}: only {} mat points in view",
            c.name,
            d.len()
        );
        assert!(
            median < 5.0 && p90 < 15.0,
            "{}: median {median}, p90 {p90}",
            c.name
        );
    }

    // Neighbours see the same ground in the corner squares: a point of the
    // front-left square projects into both cameras' images.
    let fl = Vector3::new(
        surround::canvas_to_vehicle(400.0, 450.0)[0],
        surround::canvas_to_vehicle(400.0, 450.0)[1],
        0.0,
    );
    for name in ["front", "left"] {
        let c = rig.camera(name).unwrap();
        let px = c.project_rig(&fl).unwrap();
        assert!(
            c.intrinsics.contains(&px),
            "{name} does not see the front-left square: {px}"
        );
    }

    // The rig file round-trips exactly.
    let text = rig_yaml::to_string(rig).unwrap();
    let back = rig_yaml::parse(&text, "surround-nz.yaml").unwrap();
    assert_eq!(&back, rig);
}
