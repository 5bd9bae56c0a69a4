//! Every format: exact round trips, what the fields mean, and the errors
//! for bad files (each naming the file, the field and what was expected).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::{Path, PathBuf};

use common::fixture;

use nalgebra::Vector3;
use proptest::prelude::*;
use rigview_calib::formats::{
    self, basalt, camodocal, kalibr, ocamcalib, opencv, rig_yaml, ros, woodscape, Format,
};
use rigview_calib::report;
use rigview_calib::{
    CalibError, Camera, DeviceId, Distortion, Frame, Intrinsics, ModelKind, Pose, Rig,
};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "rigview-calib-formats-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn example_rig() -> Rig {
    let fisheye = Intrinsics {
        width: 960,
        height: 640,
        fx: 302.453_059_832_293,
        fy: 320.746_185_943_923,
        cx: 496.640_014_631_635,
        cy: 331.199_809_843_617,
        distortion: Distortion::Fisheye([-0.043_735_6, 0.021_692_5, -0.026_388_8, 0.008_412_3]),
    };
    let pinhole = Intrinsics {
        width: 640,
        height: 480,
        fx: 533.3,
        fy: 533.4,
        cx: 342.1,
        cy: 234.0,
        distortion: Distortion::RadTan([-0.281, 0.0294, 0.00112, -5.5e-5, 0.151]),
    };
    let mut front = Camera::new("front", fisheye);
    front.device = Some(DeviceId::GenICam("Basler-21234567".into()));
    front.pose = Some(Pose::from_ypr_deg([1.5, 20.0, -0.5], Vector3::new(2.4, 0.1, 0.8)).unwrap());
    let mut left = Camera::new("left", fisheye);
    left.device = Some(DeviceId::Ip("192.168.10.12".parse().unwrap()));
    left.pose = Some(Pose::from_ypr_deg([91.0, 45.0, 0.3], Vector3::new(0.9, 1.05, 1.0)).unwrap());
    let mut aux = Camera::new("aux", pinhole);
    aux.pose = Some(Pose::from_ypr_deg([-30.0, 5.0, 0.0], Vector3::new(1.0, -0.5, 1.5)).unwrap());
    Rig::new(Frame::Vehicle, vec![front, left, aux], vec![(0, 1), (2, 0)]).unwrap()
}

/// Every number of a rig, as bits.
fn bits(rig: &Rig) -> Vec<u64> {
    let mut v = Vec::new();
    for c in &rig.cameras {
        let k = &c.intrinsics;
        v.extend([k.fx, k.fy, k.cx, k.cy].map(f64::to_bits));
        v.extend(k.distortion.coefficients().iter().map(|x| x.to_bits()));
        if let Some(p) = &c.pose {
            v.extend(p.rotation_matrix().iter().map(|x| x.to_bits()));
            v.extend(p.translation().iter().map(|x| x.to_bits()));
        }
    }
    v
}

#[test]
fn rig_yaml_round_trips_exactly() {
    let rig = example_rig();
    let text = rig_yaml::to_string(&rig).unwrap();
    let back = rig_yaml::parse(&text, "rig.yaml").unwrap();
    assert_eq!(back, rig);
    assert_eq!(bits(&back), bits(&rig));
    // Through a file and the format detection too.
    let d = tmp("rig");
    let p = d.join("rig.yaml");
    formats::save(&rig, &p, None).unwrap();
    let loaded = formats::load(&p, None, None).unwrap();
    assert_eq!(loaded.format, Format::Rig);
    assert_eq!(bits(&loaded.rig), bits(&rig));
}

fn finite() -> impl Strategy<Value = f64> {
    any::<f64>().prop_filter("finite", |v| v.is_finite())
}

fn positive() -> impl Strategy<Value = f64> {
    any::<f64>().prop_filter("positive", |v| v.is_finite() && *v > 0.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Any finite numbers, including subnormals, −0.0 and extremes, come
    /// back with the same bits.
    #[test]
    fn rig_yaml_keeps_every_bit(
        f in (positive(), positive(), finite(), finite()),
        k in prop::array::uniform8(finite()),
        model in 0usize..3,
        ypr in prop::array::uniform3(-180.0..180.0f64),
        t in prop::array::uniform3(finite()),
        w in 1u32..100_000, h in 1u32..100_000,
    ) {
        let distortion = match model {
            0 => Distortion::Fisheye([k[0], k[1], k[2], k[3]]),
            1 => Distortion::RadTan([k[0], k[1], k[2], k[3], k[4]]),
            _ => Distortion::Rational(k),
        };
        let intr = Intrinsics { width: w, height: h, fx: f.0, fy: f.1, cx: f.2, cy: f.3, distortion };
        let mut cam = Camera::new("c", intr);
        cam.pose = Some(Pose::from_ypr_deg(ypr, Vector3::from(t)).unwrap());
        let rig = Rig::new(Frame::Vehicle, vec![cam], vec![]).unwrap();
        let back = rig_yaml::parse(&rig_yaml::to_string(&rig).unwrap(), "p.yaml").unwrap();
        prop_assert_eq!(bits(&back), bits(&rig));
        // OpenCV's FileStorage writes −0 as 0; every other bit survives.
        let unsigned_zero = |v: Vec<u64>| -> Vec<u64> {
            v.into_iter().map(|b| if b == (-0.0f64).to_bits() { 0 } else { b }).collect()
        };
        for xml in [false, true] {
            let text = opencv::write(&rig.cameras[0], xml).unwrap();
            let c = opencv::parse(&text, xml, "p", None).unwrap();
            let back = Rig::new(Frame::Vehicle, vec![Camera { name: "c".into(), device: None, intrinsics: c.intrinsics, pose: c.pose }], vec![]).unwrap();
            prop_assert_eq!(unsigned_zero(bits(&back)), unsigned_zero(bits(&rig)));
        }
    }
}

#[test]
fn opencv_files_round_trip_exactly_yaml_and_xml() {
    let rig = example_rig();
    for (format, ext) in [(Format::OpenCvYaml, "yaml"), (Format::OpenCvXml, "xml")] {
        let d = tmp(ext);
        let written =
            formats::save(&rig, &d.join(format!("{{camera}}.{ext}")), Some(format)).unwrap();
        assert_eq!(written.len(), 3);
        let loaded = formats::load(&d, None, None).unwrap();
        assert_eq!(loaded.format, format);
        // The folder lists files by name; compare camera by camera.
        for c in &rig.cameras {
            let b = loaded.rig.camera(&c.name).unwrap();
            assert_eq!(b.intrinsics, c.intrinsics);
            assert_eq!(b.pose, c.pose);
        }
    }
}

#[test]
fn opencv_reads_the_files_opencv_writes_and_says_what_it_misses() {
    // As OpenCV's calibration sample writes it: 5 coefficients, a pinhole.
    let text = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 5.36e+02, 0., 3.42e+02, 0., 5.36e+02, 2.35e+02, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ -2.6e-01, -4.6e-02, 1.8e-03, -3.2e-04, 2.5e-01 ]\n";
    let c = opencv::parse(text, false, "sample.yaml", None).unwrap();
    assert_eq!(c.intrinsics.distortion.kind(), ModelKind::Pinhole);
    assert_eq!((c.intrinsics.width, c.intrinsics.fx), (640, 536.0));
    // Without the %YAML line OpenCV's memory mode refuses the text; it gets
    // the line put in front.
    let headless = text.replace("%YAML:1.0\n---\n", "");
    assert_eq!(opencv::parse(&headless, false, "h.yaml", None).unwrap(), c);
    // Four coefficients fit both models: the file must say, or the caller.
    let four = "%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [300, 0, 320, 0, 300, 240, 0, 0, 1]\ndist_coeffs: [0.1, 0.01, 0.0, 0.0]\nresolution: [640, 480]\n";
    let e = opencv::parse(four, false, "four.yaml", None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("four.yaml") && e.contains("camera_model"), "{e}");
    let c = opencv::parse(four, false, "four.yaml", Some(ModelKind::Fisheye)).unwrap();
    assert_eq!(
        c.intrinsics.distortion,
        Distortion::Fisheye([0.1, 0.01, 0.0, 0.0])
    );
}

#[test]
fn kalibr_chain_means_what_kalibr_means() {
    // cam1 sits 0.11 m to the right of cam0 (its +x), same orientation:
    // T_c1_c0 takes cam0 points to cam1, so its translation is −0.11.
    let text = "cam0:\n  camera_model: pinhole\n  intrinsics: [461.6, 460.3, 363.0, 248.1]\n  distortion_model: radtan\n  distortion_coeffs: [-0.2917, 0.08228, 5.333e-05, -1.578e-04]\n  resolution: [752, 480]\n  cam_overlaps: [1]\n  rostopic: /cam0/image_raw\ncam1:\n  T_cn_cnm1:\n  - [1.0, 0.0, 0.0, -0.11]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  intrinsics: [380.8, 380.4, 510.3, 514.3]\n  distortion_model: equidistant\n  distortion_coeffs: [-0.0184, 0.0217, -0.0175, 0.0048]\n  resolution: [1024, 1024]\n  cam_overlaps: [0]\n";
    let rig = kalibr::parse(text, "camchain.yaml").unwrap();
    assert_eq!(rig.frame, Frame::Camera("cam0".into()));
    assert_eq!(rig.neighbours, [(0, 1)]);
    let c1 = rig.camera("cam1").unwrap();
    assert_eq!(c1.intrinsics.distortion.kind(), ModelKind::Fisheye);
    assert!((c1.pose.unwrap().translation() - Vector3::new(0.11, 0.0, 0.0)).norm() < 1e-15);
    assert_eq!(
        rig.camera("cam0").unwrap().intrinsics.distortion,
        Distortion::RadTan([-0.2917, 0.08228, 5.333e-05, -1.578e-04, 0.0])
    );
    // Round trip through Kalibr (the chain is recomposed: 1e-12).
    let mut r = example_rig();
    for c in &mut r.cameras {
        if let Distortion::RadTan(k) = &mut c.intrinsics.distortion {
            k[4] = 0.0;
        }
    }
    let back = kalibr::parse(&kalibr::write(&r).unwrap(), "k.yaml").unwrap();
    let back2 = kalibr::parse(&kalibr::write(&back).unwrap(), "k2.yaml").unwrap();
    assert_eq!(back.neighbours, r.neighbours);
    for (a, b) in r.cameras.iter().zip(&back.cameras) {
        assert_eq!(a.intrinsics, b.intrinsics);
        // Relative to the first camera.
        let rel_a = r.cameras[0]
            .pose
            .unwrap()
            .inverse()
            .compose(&a.pose.unwrap());
        let rel_b = b.pose.unwrap();
        assert!((rel_a.translation() - rel_b.translation()).norm() < 1e-12);
        assert!(rel_a.rotation_angle_to(&rel_b) < 1e-12);
    }
    for (a, b) in back.cameras.iter().zip(&back2.cameras) {
        assert_eq!(a.intrinsics, b.intrinsics);
        assert!((a.pose.unwrap().translation() - b.pose.unwrap().translation()).norm() < 1e-12);
    }
}

#[test]
fn ros_camera_info_round_trips_exactly() {
    let text = "image_width: 640\nimage_height: 480\ncamera_name: narrow_stereo\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [430.2, 0, 306.7, 0, 430.5, 235.0, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.337, 0.114, 0.0007, -0.0002, 0]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: [430.2, 0, 306.7, 0, 0, 430.5, 235.0, 0, 0, 0, 1, 0]\n";
    let c = ros::parse(text, "info.yaml", "x").unwrap();
    assert_eq!(c.name, "narrow_stereo");
    assert_eq!(
        c.intrinsics.distortion,
        Distortion::RadTan([-0.337, 0.114, 0.0007, -0.0002, 0.0])
    );
    for model in ["equidistant", "fisheye"] {
        let t = text
            .replace("plumb_bob", model)
            .replace("cols: 5", "cols: 4")
            .replace(", 0]\nrect", "]\nrect");
        let f = ros::parse(&t, "f.yaml", "x").unwrap();
        assert_eq!(
            f.intrinsics.distortion,
            Distortion::Fisheye([-0.337, 0.114, 0.0007, -0.0002])
        );
        assert_eq!(
            ros::parse(&ros::write(&f).unwrap(), "g.yaml", "x").unwrap(),
            f
        );
    }
    for cam in example_rig().cameras {
        let back = ros::parse(&ros::write(&cam).unwrap(), "r.yaml", "x").unwrap();
        assert_eq!(back.intrinsics, cam.intrinsics);
        assert_eq!(back.name, cam.name);
    }
}

#[test]
fn conversions_chain_through_every_format() {
    let mut rig = example_rig();
    // Kalibr's radtan has no k3.
    rig.cameras[2].intrinsics.distortion =
        Distortion::RadTan([-0.281, 0.0294, 0.00112, -5.5e-5, 0.0]);
    let d = tmp("chain");
    // rig → Kalibr → rig YAML → ROS files → OpenCV XML files → rig.
    let k = d.join("camchain.yaml");
    formats::save(&rig, &k, Some(Format::Kalibr)).unwrap();
    let from_k = formats::load(&k, None, None).unwrap();
    assert_eq!(from_k.format, Format::Kalibr);
    let ros_dir = d.join("ros/");
    formats::save(&from_k.rig, &ros_dir, Some(Format::Ros)).unwrap();
    let from_ros = formats::load(&ros_dir, None, None).unwrap();
    assert_eq!(from_ros.format, Format::Ros);
    let xml_dir = d.join("xml/");
    formats::save(&from_ros.rig, &xml_dir, Some(Format::OpenCvXml)).unwrap();
    let from_xml = formats::load(&xml_dir, None, None).unwrap();
    // Kalibr names the cameras cam0, cam1, … in rig order.
    for (i, c) in rig.cameras.iter().enumerate() {
        let b = from_xml.rig.camera(&format!("cam{i}")).unwrap();
        assert_eq!(b.intrinsics, c.intrinsics, "{}", c.name);
    }
}

fn err(r: Result<impl std::fmt::Debug, CalibError>) -> String {
    r.unwrap_err().to_string()
}

fn assert_mentions(e: &str, parts: &[&str]) {
    for p in parts {
        assert!(e.contains(p), "error \"{e}\" does not mention \"{p}\"");
    }
}

#[test]
fn bad_rig_files_get_errors_that_name_file_and_field() {
    let good = rig_yaml::to_string(&example_rig()).unwrap();
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            good.replace("version: 1", "version: 2"),
            vec!["bad.yaml", "version", "1", "2"],
        ),
        (
            good.replace("version: 1\n", ""),
            vec!["bad.yaml", "version"],
        ),
        (
            good.replacen("focal_px:\n  - 302.", "focal_px:\n  - -302.", 1),
            vec!["bad.yaml", "cameras[0]", "focal_px", "positive"],
        ),
        (
            good.replacen("model: fisheye", "model: omni", 1),
            vec!["bad.yaml", "cameras[0].model", "omni"],
        ),
        (
            good.replacen("distortion:\n  - -0.0437356", "distortion:\n  - .nan", 1),
            vec!["bad.yaml", "distortion", "finite"],
        ),
        (
            good.replacen("translation_m:", "translation:", 1),
            vec!["bad.yaml", "translation"],
        ),
        (
            good.replacen("- front\n  - left", "- front\n  - rear", 1),
            vec!["bad.yaml", "neighbours", "rear"],
        ),
        (good[..good.len() / 2].to_owned(), vec!["bad.yaml"]),
        (
            good.replacen("ip: 192.168.10.12", "ip: 192.168.10.300", 1),
            vec!["bad.yaml", "device.ip", "192.168.10.300"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(rig_yaml::parse(&text, "bad.yaml")), &parts);
    }
    // A rotation that is not orthonormal.
    let mut doc: serde_norway::Value = serde_norway::from_str(&good).unwrap();
    doc["cameras"][0]["pose"]["rotation_matrix"][0][0] = serde_norway::Value::from(0.5);
    let e = err(rig_yaml::parse(
        &serde_norway::to_string(&doc).unwrap(),
        "bad.yaml",
    ));
    assert_mentions(
        &e,
        &["bad.yaml", "cameras[0].pose.rotation_matrix", "orthonormal"],
    );
    // Wrong shape.
    doc["cameras"][0]["pose"]["rotation_matrix"] =
        serde_norway::from_str("[[1, 0], [0, 1]]").unwrap();
    let e = err(rig_yaml::parse(
        &serde_norway::to_string(&doc).unwrap(),
        "bad.yaml",
    ));
    assert_mentions(&e, &["bad.yaml", "rotation_matrix"]);
}

/// The file with its first distortion coefficient replaced by NaN (which
/// OpenCV writes as `.Nan`).
fn nan_coefficient(text: &str) -> String {
    let start = text.find("dist_coeffs").unwrap();
    let data = start + text[start..].find("data: [ ").unwrap() + "data: [ ".len();
    let end = data + text[data..].find(',').unwrap();
    format!("{}.Nan{}", &text[..data], &text[end..])
}

#[test]
fn bad_opencv_files_get_errors_that_name_file_and_field() {
    let good = opencv::write(&example_rig().cameras[0], false).unwrap();
    let two_by_three = good.replacen(
        "rows: 3\n   cols: 3\n   dt: d\n   data: [ 3.0245",
        "rows: 2\n   cols: 3\n   dt: d\n   data: [ 3.0245",
        1,
    );
    let cut = good.find("   data: [ 3.0245").unwrap();
    let two_by_three = format!(
        "{}   data: [ 1, 2, 3, 4, 5, 6 ]{}",
        &two_by_three[..cut],
        &good[good[cut..].find(']').unwrap() + cut + 1..]
    );
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            two_by_three,
            vec!["front.yaml", "camera_matrix", "3×3", "2×3"],
        ),
        (
            good.replace("dist_coeffs", "distortion"),
            vec!["front.yaml", "dist_coeffs"],
        ),
        (
            good.replace("camera_model: fisheye", "camera_model: omni"),
            vec!["front.yaml", "camera_model", "omni"],
        ),
        (
            nan_coefficient(&good),
            vec!["front.yaml", "dist_coeffs", "finite"],
        ),
        (
            good.replace("rows: 4", "rows: 100000"),
            vec!["front.yaml", "dist_coeffs", "100000"],
        ),
        (
            good.replace("resolution", "size"),
            vec!["front.yaml", "resolution"],
        ),
        (good[..good.len() / 2].to_owned(), vec!["front.yaml"]),
        (
            good.replacen("3.0245", "-3.0245", 1),
            vec!["front.yaml", "camera_matrix", "positive"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(
            &err(opencv::parse(&text, false, "front.yaml", None)),
            &parts,
        );
    }
    let xml = opencv::write(&example_rig().cameras[0], true).unwrap();
    assert_mentions(
        &err(opencv::parse(
            &xml[..xml.len() / 2],
            true,
            "front.xml",
            None,
        )),
        &["front.xml"],
    );
    assert_mentions(
        &err(opencv::parse(
            &xml.replace("camera_matrix", "k"),
            true,
            "front.xml",
            None,
        )),
        &["front.xml", "camera_matrix"],
    );
}

#[test]
fn bad_kalibr_and_ros_files_get_errors_that_name_file_and_field() {
    let rig = example_rig();
    let mut r = rig.clone();
    r.cameras.truncate(2);
    r.neighbours.retain(|&(a, b)| a < 2 && b < 2);
    let good = kalibr::write(&r).unwrap();
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            good.replacen("camera_model: pinhole", "camera_model: scaramuzza", 1),
            vec!["chain.yaml", "cam0.camera_model", "scaramuzza-equidistant"],
        ),
        (
            // The unified model has no equidistant distortion, and its
            // intrinsics start with ξ.
            good.replacen("camera_model: pinhole", "camera_model: omni", 1),
            vec![
                "chain.yaml",
                "cam0.intrinsics",
                "5 numbers [xi, fu, fv, pu, pv]",
            ],
        ),
        (
            good.replacen("distortion_model: equidistant", "distortion_model: kb8", 1),
            vec!["chain.yaml", "cam0.distortion_model", "pinhole-kb8"],
        ),
        (
            // Kalibr's fov distortion has one coefficient.
            good.replacen("distortion_model: equidistant", "distortion_model: fov", 1),
            vec!["chain.yaml", "cam0.distortion_coeffs", "1 field-of-view"],
        ),
        (
            good.replacen("intrinsics:", "intrinsic:", 1),
            vec!["chain.yaml", "cam0.intrinsics"],
        ),
        (
            good.replacen("T_cn_cnm1", "T_cam_imu", 1),
            vec!["chain.yaml", "cam1.T_cn_cnm1"],
        ),
        (
            good.replacen("- 1.0\n", "- 1.5\n", 1),
            vec!["chain.yaml", "cam1.T_cn_cnm1"],
        ),
        (String::from("cam1: {}\n"), vec!["chain.yaml", "cam0"]),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(kalibr::parse(&text, "chain.yaml")), &parts);
    }
    let info = ros::write(&rig.cameras[2]).unwrap();
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            info.replace("plumb_bob", "fov"),
            vec![
                "info.yaml",
                "distortion_model",
                "fov",
                "rational_polynomial",
            ],
        ),
        (
            info.replace("plumb_bob", "rational_polynomial"),
            vec![
                "info.yaml",
                "distortion_coefficients",
                "8 rational_polynomial coefficients",
                "found 5",
            ],
        ),
        (
            info.replacen("rows: 3", "rows: 2", 1),
            vec!["info.yaml", "camera_matrix", "3×3"],
        ),
        (
            info.replace("image_width: 640\n", ""),
            vec!["info.yaml", "image_width"],
        ),
        (
            info.replacen("- 533.3", "- -533.3", 1),
            vec!["info.yaml", "camera_matrix", "positive"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(ros::parse(&text, "info.yaml", "x")), &parts);
    }
}

#[test]
fn missing_and_unreadable_files_are_named() {
    let e = err(formats::load(
        Path::new("/nonexistent/front.yaml"),
        None,
        None,
    ));
    assert_mentions(&e, &["/nonexistent/front.yaml"]);
    let d = tmp("binary");
    let p = d.join("cam.yaml");
    std::fs::write(&p, [0xff, 0xfe, 0x00, 0x41]).unwrap();
    assert_mentions(&err(formats::load(&p, None, None)), &["cam.yaml", "UTF-8"]);
    std::fs::write(&p, "just: a map\n").unwrap();
    assert_mentions(
        &err(formats::load(&p, None, None)),
        &["cam.yaml", "cannot tell"],
    );
    std::fs::write(&p, "").unwrap();
    assert!(formats::load(&p, Some(Format::OpenCvYaml), None).is_err());
    // Several cameras to a one-camera format need a folder or {camera}.
    assert!(formats::save(&example_rig(), &d.join("one.yaml"), Some(Format::Ros)).is_err());
}

/// Loads a file both ways: told from its contents, and named.
fn load_both(p: &Path, format: Format) -> Rig {
    let auto = formats::load(p, None, None).unwrap();
    assert_eq!(auto.format, format, "{}", p.display());
    let named = formats::load(p, Some(format), None).unwrap();
    assert_eq!(auto.rig, named.rig);
    auto.rig
}

#[test]
fn kalibr_camchain_with_opencvs_header_line() {
    let (p, text) = fixture("kalibr-opencv-header.yaml");
    assert!(text.starts_with("%YAML:1.0\n"));
    let rig = load_both(&p, Format::Kalibr);
    assert_eq!(rig.frame, Frame::Camera("cam0".into()));
    assert_eq!(rig.neighbours, [(0, 1)]);
    let c0 = &rig.cameras[0].intrinsics;
    assert_eq!(
        (c0.width, c0.height, c0.fx, c0.cy),
        (752, 480, 461.2, 246.8)
    );
    assert_eq!(
        c0.distortion,
        Distortion::RadTan([-0.2831, 0.0738, 0.00021, 1.9e-05, 0.0])
    );
    // cam1 sits 0.11 m to the right of cam0.
    let t = *rig.cameras[1].pose.unwrap().translation();
    assert!(
        (t - Vector3::new(0.110_052_318, -0.000_171_210, 0.000_900_939)).norm() < 1e-8,
        "{t:?}"
    );
    // The same chain without the header line reads the same.
    let plain = kalibr::parse(&text.replacen("%YAML:1.0\n", "", 1), "plain.yaml").unwrap();
    assert_eq!(plain, rig);
    // A YAML error after the header gives the line as the file has it.
    let broken = text.replacen(
        "  camera_model: pinhole\n",
        "  camera_model: pinhole: x\n",
        1,
    );
    let at = broken
        .lines()
        .position(|l| l.contains("pinhole: x"))
        .unwrap()
        + 1;
    assert_mentions(
        &err(kalibr::parse(&broken, "chain.yaml")),
        &["chain.yaml", &format!("line {at} ")],
    );
    // Bad variants name the file and the field, header or not.
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            text.replacen(
                "distortion_coeffs: [-0.2831, 0.0738, 0.00021, 1.9e-05]",
                "distortion_coeffs: [-0.2831, 0.0738, 0.00021]",
                1,
            ),
            vec![
                "chain.yaml",
                "cam0.distortion_coeffs",
                "4 radtan",
                "3 numbers",
            ],
        ),
        (
            text.replacen("  intrinsics: [461.2, 460.1, 362.4, 246.8]\n", "", 1),
            vec!["chain.yaml", "cam0.intrinsics", "[fu, fv, pu, pv]"],
        ),
    ];
    for (t, parts) in cases {
        assert_mentions(&err(kalibr::parse(&t, "chain.yaml")), &parts);
        let d = tmp("kalibr-bad");
        let f = d.join("chain.yaml");
        std::fs::write(&f, &t).unwrap();
        assert_mentions(&err(formats::load(&f, None, None)), &parts[1..]);
    }
}

#[test]
fn ros_plumb_bob_with_eight_coefficients() {
    let (p, text) = fixture("ros-plumb-bob-8.yaml");
    let rig = load_both(&p, Format::Ros);
    let c = &rig.cameras[0];
    assert_eq!(c.name, "stereo_left");
    assert_eq!(
        c.intrinsics.distortion,
        Distortion::RadTan([-0.0512, 0.0583, 0.00021, -0.00113, -0.0189])
    );
    assert_eq!((c.intrinsics.fx, c.intrinsics.cy), (383.91, 238.24));
    // Non-zero extra coefficients are the rational model, not plumb_bob.
    let extra = text.replace("-0.0189, 0, 0, 0]", "-0.0189, 0.25, 0, 0]");
    assert_ne!(extra, text);
    assert_mentions(
        &err(ros::parse(&extra, "left.yaml", "x")),
        &[
            "left.yaml",
            "distortion_coefficients",
            "5 plumb_bob coefficients",
            "rational_polynomial",
            "[0.25, 0.0, 0.0]",
        ],
    );
    // Other counts.
    let six = text
        .replace("cols: 8", "cols: 6")
        .replace("-0.0189, 0, 0, 0]", "-0.0189, 0]");
    assert_mentions(
        &err(ros::parse(&six, "left.yaml", "x")),
        &[
            "left.yaml",
            "distortion_coefficients",
            "5 plumb_bob coefficients",
            "found 6 coefficients",
        ],
    );
}

/// A rig of one rational camera.
fn rational_rig() -> Rig {
    let k = Intrinsics {
        width: 1280,
        height: 720,
        fx: 610.2,
        fy: 609.8,
        cx: 638.4,
        cy: 366.9,
        distortion: Distortion::Rational([0.52, -2.6, 0.00062, -0.00021, 1.5, 0.4, -2.45, 1.42]),
    };
    let mut cam = Camera::new("rgb_camera", k);
    cam.pose = Some(Pose::from_ypr_deg([5.0, 10.0, 0.0], Vector3::new(1.2, 0.0, 1.4)).unwrap());
    Rig::new(Frame::Vehicle, vec![cam], vec![]).unwrap()
}

#[test]
fn rational_model_reads_and_writes_in_every_format_that_has_it() {
    let want = rational_rig();
    let want_k = want.cameras[0].intrinsics;
    // ROS 1 camera_info and OpenCV's calibration sample with
    // CALIB_RATIONAL_MODEL.
    let (p, ros_text) = fixture("ros-rational.yaml");
    let from_ros = load_both(&p, Format::Ros);
    assert_eq!(from_ros.cameras[0].intrinsics, want_k);
    assert_eq!(from_ros.cameras[0].name, "rgb_camera");
    let (p, cv_text) = fixture("opencv-rational.yaml");
    let from_cv = load_both(&p, Format::OpenCvYaml);
    assert_eq!(from_cv.cameras[0].intrinsics, want_k);
    // Written and read back, bit for bit: rig YAML, ROS, OpenCV YAML and
    // XML.
    let back = rig_yaml::parse(&rig_yaml::to_string(&want).unwrap(), "r.yaml").unwrap();
    assert_eq!(back, want);
    assert!(rig_yaml::to_string(&want)
        .unwrap()
        .contains("model: pinhole-rational"));
    let text = ros::write(&want.cameras[0]).unwrap();
    assert!(
        text.contains("distortion_model: rational_polynomial"),
        "{text}"
    );
    assert_eq!(ros::parse(&text, "r.yaml", "x").unwrap().intrinsics, want_k);
    for xml in [false, true] {
        let text = opencv::write(&want.cameras[0], xml).unwrap();
        let c = opencv::parse(&text, xml, "r", None).unwrap();
        assert_eq!((c.intrinsics, c.pose), (want_k, want.cameras[0].pose));
    }
    // rigview's camera_model: rational keeps 8 coefficients rational even
    // when k4..k6 are 0; a pinhole file with them 0 is radial-tangential.
    let mut flat = want.cameras[0].clone();
    flat.intrinsics.distortion = Distortion::Rational([0.1, 0.01, 0.0, 0.0, 0.001, 0.0, 0.0, 0.0]);
    let text = opencv::write(&flat, false).unwrap();
    assert_eq!(
        opencv::parse(&text, false, "f", None).unwrap().intrinsics,
        flat.intrinsics
    );
    assert_eq!(
        opencv::parse(
            &text.replace("camera_model: rational", "camera_model: pinhole"),
            false,
            "f",
            None
        )
        .unwrap()
        .intrinsics
        .distortion,
        Distortion::RadTan([0.1, 0.01, 0.0, 0.0, 0.001])
    );
    // Kalibr has no rational model: writing says so and names the camera.
    assert_mentions(
        &err(kalibr::write(&want)),
        &["rgb_camera", "Kalibr has no rational"],
    );
    // `calib show`'s summary names the model and every coefficient.
    let shown = report::summary(&formats::Loaded {
        rig: from_ros,
        format: Format::Ros,
        surround: None,
    });
    assert_mentions(
        &shown,
        &[
            "pinhole-rational 1280×720",
            "k1 0.520000, k2 -2.600000, p1 0.000620, p2 -0.000210, k3 1.500000, k4 0.400000, k5 -2.450000, k6 1.420000",
        ],
    );
    // Bad variants.
    let ros_cases: Vec<(String, Vec<&str>)> = vec![
        (
            ros_text
                .replace("cols: 8", "cols: 5")
                .replace(", 0.4, -2.45, 1.42]", "]"),
            vec![
                "rgb.yaml",
                "distortion_coefficients",
                "8 rational_polynomial coefficients k1, k2, p1, p2, k3, k4, k5, k6",
                "found 5 coefficients",
            ],
        ),
        (
            ros_text.replace("-2.45", ".nan"),
            vec![
                "rgb.yaml",
                "distortion_coefficients",
                "numbers",
                "item 6",
                ".nan",
            ],
        ),
    ];
    for (t, parts) in ros_cases {
        assert_mentions(&err(ros::parse(&t, "rgb.yaml", "x")), &parts);
    }
    let with_model = cv_text.replace("flags: 16384", "camera_model: rational");
    assert!(opencv::parse(&with_model, false, "rgb.yaml", None).is_ok());
    let cv_cases: Vec<(String, Vec<&str>)> = vec![
        (
            with_model
                .replace("rows: 8", "rows: 5")
                .replace(
                    ",\n       1.5000000000000000e+00, 4.0000000000000002e-01,\n       -2.4500000000000002e+00, 1.4199999999999999e+00 ]",
                    ",\n       1.5 ]",
                ),
            vec!["rgb.yaml", "distortion_coefficients", "8 rational coefficients", "found 5"],
        ),
        (
            cv_text.replace("rows: 8", "rows: 12").replace(
                "1.4199999999999999e+00 ]",
                "1.4199999999999999e+00, 0., 0.01, 0., 0. ]",
            ),
            vec!["rgb.yaml", "distortion_coefficients", "thin-prism", "coefficient 9 = 0.01"],
        ),
    ];
    for (t, parts) in cv_cases {
        assert_mentions(&err(opencv::parse(&t, false, "rgb.yaml", None)), &parts);
    }
}

#[test]
fn ros2_camera_info_message_as_echoed() {
    let (p, text) = fixture("ros2-camera-info.yaml");
    let rig = load_both(&p, Format::Ros);
    let c = &rig.cameras[0];
    // A message has no camera name: its frame_id names the camera.
    assert_eq!(c.name, "camera_optical");
    assert_eq!(
        c.intrinsics,
        Intrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
            distortion: Distortion::RadTan([-0.28, 0.07, 0.0, 0.0, 0.0]),
        }
    );
    // Without frame_id, the file names the camera.
    let no_frame = text.replace("  frame_id: camera_optical\n", "");
    assert_eq!(
        ros::parse(&no_frame, "f.yaml", "front").unwrap().name,
        "front"
    );
    let empty_frame = text.replace("frame_id: camera_optical", "frame_id: ''");
    assert_eq!(
        ros::parse(&empty_frame, "f.yaml", "front").unwrap().name,
        "front"
    );
    // Flow-style lists, as older ROS 2 releases print them, and the
    // rational model.
    let rational = text.replace("plumb_bob", "rational_polynomial").replace(
        "d:\n- -0.28\n- 0.07\n- 0.0\n- 0.0\n- 0.0\n",
        "d: [-0.28, 0.07, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0]\n",
    );
    assert_eq!(
        ros::parse(&rational, "f.yaml", "x")
            .unwrap()
            .intrinsics
            .distortion,
        Distortion::Rational([-0.28, 0.07, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0])
    );
    // Bad variants name the file, the message's field and what was
    // expected.
    let d_list = "d:\n- -0.28\n- 0.07\n- 0.0\n- 0.0\n- 0.0\n";
    let k_start = text.find("\nk:\n").unwrap() + 1;
    let k_end = text.find("\nr:\n").unwrap() + 1;
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!("{}{}", &text[..k_start], &text[k_end..]),
            vec![
                "cam.yaml",
                "missing field \"k\"",
                "9 numbers",
                "3×3 camera matrix",
            ],
        ),
        (
            text.replacen("- 1.0\nr:", "r:", 1),
            vec!["cam.yaml", "field \"k\"", "9 numbers", "found 8 numbers"],
        ),
        (
            text.replace(d_list, "d:\n- -0.28\n- 0.07\n- 0.0\n- 0.0\n- 0.0\n- 0.0\n"),
            vec![
                "cam.yaml",
                "field \"d\"",
                "5 plumb_bob coefficients",
                "found 6 coefficients",
            ],
        ),
        (
            text.replace(d_list, "d: [-0.28, 0.07, 0.0, 0.0, 0.0, 0.0, 0.03, 0.0]\n"),
            vec![
                "cam.yaml",
                "field \"d\"",
                "rational_polynomial",
                "[0.0, 0.03, 0.0]",
            ],
        ),
        (
            text.replace("- 500.0\n- 0.0\n- 320.0", "- 500.0\n- 0.5\n- 320.0"),
            vec!["cam.yaml", "field \"k\"", "[fx 0 cx; 0 fy cy; 0 0 1]"],
        ),
        (
            text.replace("width: 640", "width: -640"),
            vec!["cam.yaml", "field \"width\"", "positive whole number"],
        ),
        (
            text.replace("binning_x: 0", "binning_x: 2"),
            vec!["cam.yaml", "binning_x", "0 or 1", "2"],
        ),
        (
            text.replace("  height: 0\n  width: 0", "  height: 240\n  width: 320"),
            vec!["cam.yaml", "roi", "the whole image", "320×240 at (0, 0)"],
        ),
        (
            format!("{text}{text}"),
            vec!["cam.yaml", "2 YAML documents", "expected one"],
        ),
    ];
    for (t, parts) in cases {
        assert_mentions(&err(ros::parse(&t, "cam.yaml", "x")), &parts);
    }
    // A ROS 2 message missing k is still told for camera_info.
    let d = tmp("ros2");
    let f = d.join("cam.yaml");
    std::fs::write(&f, format!("{}{}", &text[..k_start], &text[k_end..])).unwrap();
    assert_mentions(&err(formats::load(&f, None, None)), &["cam.yaml", "\"k\""]);
}

#[test]
fn kalibr_sphere_models_are_read_as_kalibr_writes_them_and_written_back() {
    // As Kalibr's camchain writer lays them out: the projection's own
    // parameters first in `intrinsics` ([xi, fu, fv, pu, pv] for omni,
    // [xi, alpha, fu, fv, pu, pv] for ds, [alpha, beta, fu, fv, pu, pv]
    // for eucm), distortion none or radtan.
    let text = "cam0:\n  camera_model: omni\n  intrinsics: [0.9, 300.0, 310.0, 640.0, 480.0]\n  distortion_model: radtan\n  distortion_coeffs: [-0.1, 0.02, 0.001, -0.002]\n  resolution: [1280, 960]\n  cam_overlaps: [1]\n  rostopic: /cam0/image_raw\ncam1:\n  T_cn_cnm1:\n  - [1.0, 0.0, 0.0, -0.11]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: ds\n  intrinsics: [-0.2, 0.6, 350.0, 351.0, 512.0, 511.0]\n  distortion_model: none\n  distortion_coeffs: []\n  resolution: [1024, 1024]\n  cam_overlaps: [0, 2]\ncam2:\n  T_cn_cnm1:\n  - [1.0, 0.0, 0.0, -0.11]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: eucm\n  intrinsics: [0.6, 1.1, 350.0, 351.0, 512.0, 511.0]\n  distortion_model: none\n  distortion_coeffs: []\n  resolution: [1024, 1024]\n  cam_overlaps: [1]\n";
    let rig = kalibr::parse(text, "camchain.yaml").unwrap();
    let k: Vec<_> = rig.cameras.iter().map(|c| c.intrinsics).collect();
    assert_eq!(
        k[0].distortion,
        Distortion::Omni([0.9, -0.1, 0.02, 0.001, -0.002, 0.0])
    );
    assert_eq!(
        (k[0].fx, k[0].fy, k[0].cx, k[0].cy),
        (300.0, 310.0, 640.0, 480.0)
    );
    assert_eq!(k[1].distortion, Distortion::DoubleSphere([-0.2, 0.6]));
    assert_eq!((k[1].fx, k[1].cy), (350.0, 511.0));
    assert_eq!(k[2].distortion, Distortion::Eucm([0.6, 1.1]));
    let back = kalibr::parse(&kalibr::write(&rig).unwrap(), "k.yaml").unwrap();
    for (a, b) in rig.cameras.iter().zip(&back.cameras) {
        assert_eq!(a.intrinsics, b.intrinsics, "{}", a.name);
    }
    // The rig file names the sphere models' parameters and reads them back.
    let yaml = rig_yaml::to_string(&rig).unwrap();
    assert!(yaml.contains("model: double-sphere"), "{yaml}");
    assert!(
        yaml.contains("xi: -0.2") && yaml.contains("beta: 1.1"),
        "{yaml}"
    );
    let again = rig_yaml::parse(&yaml, "rig.yaml").unwrap();
    for (a, b) in rig.cameras.iter().zip(&again.cameras) {
        assert_eq!(a.intrinsics, b.intrinsics, "{}", a.name);
    }
    // A model's parameter left out, or one it does not have, is an error
    // naming the file and the field.
    let missing = yaml.replacen("  beta: 1.1\n", "", 1);
    assert_mentions(
        &err(rig_yaml::parse(&missing, "rig.yaml")),
        &["rig.yaml", "beta"],
    );
    let extra = yaml.replacen("  beta: 1.1\n", "  beta: 1.1\n  xi: 0.5\n", 1);
    assert_mentions(
        &err(rig_yaml::parse(&extra, "rig.yaml")),
        &["rig.yaml", "xi"],
    );
    // ROS camera_info and OpenCV's files cannot hold these models: a clear
    // error, not a file that means something else.
    let e = ros::write(&rig.cameras[1]).unwrap_err().to_string();
    assert!(e.contains("double-sphere") && e.contains("kalibr"), "{e}");
    let e = opencv::write(&rig.cameras[2], false)
        .unwrap_err()
        .to_string();
    assert!(e.contains("eucm"), "{e}");
}

/// A WoodScape calibration as the dataset ships it (its front camera's
/// layout; 2-space indentation and the keys in WoodScape's order).
const WOODSCAPE_FV: &str = r#"{
    "extrinsic": {
        "quaternion": [
            0.5946970238045494,
            -0.5837953694518585,
            0.39063952590941925,
            -0.39234550555338396
        ],
        "translation": [
            3.7484,
            0.0,
            0.6577
        ]
    },
    "intrinsic": {
        "aspect_ratio": 1.02,
        "cx_offset": 3.942,
        "cy_offset": -3.093,
        "height": 966.0,
        "k1": 339.749,
        "k2": -31.988,
        "k3": 48.275,
        "k4": -7.201,
        "model": "radial_poly",
        "poly_order": 4,
        "width": 1280.0
    },
    "name": "FV"
}
"#;

#[test]
fn woodscape_json_means_what_woodscapes_projection_means() {
    let path = tmp("woodscape").join("00000_FV.json");
    std::fs::write(&path, WOODSCAPE_FV).unwrap();
    let loaded = formats::load(&path, None, None).unwrap();
    assert_eq!(loaded.format, Format::WoodScape);
    let cam = &loaded.rig.cameras[0];
    assert_eq!(cam.name, "FV");
    let k = cam.intrinsics;
    // The principal point: the image centre plus the offsets, less half a
    // pixel (WoodScape's pixel centres are rigview's).
    assert_eq!((k.cx, k.cy), (643.442, 479.407));
    assert_eq!(
        k.distortion,
        Distortion::RadialPoly([339.749, -31.988, 48.275, -7.201])
    );
    // WoodScape's own formula, worked by hand: θ = π/2 − atan2(z, χ),
    // ρ = Σ kᵢ θⁱ, u = ρ·x/χ + cx, v = ρ·y/χ·aspect + cy.
    let q = k.project(&Vector3::new(0.5, -0.3, 0.8)).unwrap();
    assert!((q.x - 825.4246053073341).abs() < 1e-9, "{q}");
    assert!((q.y - 368.03364555191155).abs() < 1e-9, "{q}");
    // The pose: camera to vehicle, the quaternion (x, y, z, w). The front
    // camera looks forward and down: its optical axis has x > 0, z < 0.
    let pose = cam.pose.unwrap();
    let axis = pose.rotation_matrix() * Vector3::z();
    assert!(axis.x > 0.5 && axis.z < 0.0, "{axis}");
    assert_eq!(pose.translation().z.to_bits(), 0.6577f64.to_bits());
    // Written back and read again: the same bits.
    let text = formats::to_text(&loaded.rig, Format::WoodScape, 0).unwrap();
    let back = woodscape::parse(&text, "back.json", "x").unwrap();
    assert_eq!(back.intrinsics, k);
    assert_eq!(back.name, "FV");
    let (p, b) = (pose, back.pose.unwrap());
    assert!((p.rotation_matrix() - b.rotation_matrix()).abs().max() < 1e-15);
    assert_eq!(p.translation(), b.translation());
}

#[test]
fn bad_woodscape_files_get_errors_that_name_file_and_field() {
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            WOODSCAPE_FV.replacen("        \"k3\": 48.275,\n", "", 1),
            vec!["fv.json", "intrinsic.k3"],
        ),
        (
            WOODSCAPE_FV.replacen("-0.39234550555338396", "-0.49234550555338396", 1),
            vec!["fv.json", "extrinsic.quaternion", "unit"],
        ),
        (
            WOODSCAPE_FV.replacen("\"cx_offset\": 3.942", "\"cx_offset\": 700.0", 1),
            vec!["fv.json", "intrinsic.cx_offset", "principal point"],
        ),
        (
            WOODSCAPE_FV.replacen("\"radial_poly\"", "\"fov\"", 1),
            vec!["fv.json", "intrinsic.model", "radial_poly"],
        ),
        (
            WOODSCAPE_FV.replacen("\"k1\": 339.749", "\"k1\": -339.749", 1),
            vec!["fv.json", "intrinsic.k1"],
        ),
        (
            WOODSCAPE_FV.replacen("\"translation\": [", "\"translation\": [[", 1),
            vec!["fv.json", "line"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(woodscape::parse(&text, "fv.json", "fv")), &parts);
    }
}

/// An OCamCalib result as its toolbox writes it: pol, invpol (fitted to
/// pol), the centre (row, column), the affine parameters and the size
/// (height, width).
const OCAMCALIB: &str = "#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by cam2world\n\n5 -1.800000e+02 0.000000e+00 2.300000e-03 -4.000000e-06 1.300000e-08 \n\n#polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). These are used by world2cam\n\n13 285.007714 185.052865 4.161359 14.660081 18.490413 2.515648 -1.679842 5.210756 3.398764 -0.845990 -0.760291 0.068709 0.071227 \n\n#center: \"row\" and \"column\", starting from 0 (C convention)\n\n249.336977 360.589015\n\n#affine parameters \"c\", \"d\", \"e\"\n\n1.000012 0.000067 0.000154\n\n#image size: \"height\" and \"width\"\n\n480 720\n\n";

#[test]
fn ocamcalib_results_mean_what_ocamcalibs_functions_mean() {
    let path = tmp("ocam").join("calib_results.txt");
    std::fs::write(&path, OCAMCALIB).unwrap();
    let loaded = formats::load(&path, None, None).unwrap();
    assert_eq!(loaded.format, Format::OcamCalib);
    let cam = &loaded.rig.cameras[0];
    assert_eq!(cam.name, "calib_results");
    assert!(cam.pose.is_none());
    let k = cam.intrinsics;
    // The centre is (row, column) and the size (height, width).
    assert_eq!((k.width, k.height), (720, 480));
    assert_eq!((k.cx, k.cy), (360.589015, 249.336977));
    let Distortion::Scaramuzza(o) = k.distortion else {
        panic!("{:?}", k.distortion)
    };
    assert_eq!(o.pol().len(), 5);
    assert_eq!(o.invpol().len(), 13);
    assert_eq!(
        o.affine().map(f64::to_bits),
        [1.000012f64, 0.000067, 0.000154].map(f64::to_bits)
    );
    // cam2world worked by hand for pixel (column 500, row 300), in
    // rigview's axes (OCamCalib's (y, x, −z)).
    let r = k.unproject(&nalgebra::Point2::new(500.0, 300.0)).unwrap();
    let want = Vector3::new(0.692364868998783, 0.25157538462792833, 0.6762697050922863);
    assert!((r.into_inner() - want).norm() < 1e-12, "{r:?}");
    // Projection inverts pol exactly; OCamCalib's world2cam (invpol)
    // agrees to its fit, and both directions round trip.
    let (mut fit, mut trip): (f64, f64) = (0.0, 0.0);
    for row in (0..480).step_by(20) {
        for col in (0..720).step_by(20) {
            let px = nalgebra::Point2::new(f64::from(col), f64::from(row));
            let Some(ray) = k.unproject(&px) else {
                continue;
            };
            let q = k.project(&ray).unwrap();
            trip = trip.max((q - px).norm());
            let (du, dv) = rigview_calib::model::ocam::world2cam(&o, &ray);
            fit = fit.max((du + k.cx - q.x).hypot(dv + k.cy - q.y));
        }
    }
    assert!(trip < 1e-6, "round trip {trip} px");
    assert!(fit < 0.02, "invpol against pol: {fit} px");
    // Written back: the same bits.
    let text = formats::to_text(&loaded.rig, Format::OcamCalib, 0).unwrap();
    let back = ocamcalib::parse(&text, "back.txt", "back").unwrap();
    assert_eq!(back.intrinsics, k);
    // And through the rig file, with the polynomials named.
    let yaml = rig_yaml::to_string(&loaded.rig).unwrap();
    assert!(
        yaml.contains("model: scaramuzza") && yaml.contains("invpol:"),
        "{yaml}"
    );
    let again = rig_yaml::parse(&yaml, "rig.yaml").unwrap();
    assert_eq!(again.cameras[0].intrinsics, k);
}

#[test]
fn bad_ocamcalib_files_get_errors_that_name_file_line_and_field() {
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            OCAMCALIB.replacen("5 -1.8", "6 -1.8", 1),
            vec!["cam.txt", "pol (line 3)", "count of 6"],
        ),
        (
            OCAMCALIB.replacen("249.336977 360.589015", "249.336977 760.589015", 1),
            vec!["cam.txt", "center (line 11)", "on the image"],
        ),
        (
            OCAMCALIB.replacen("1.000012 0.000067", "1.000012 0.0000x67", 1),
            vec!["cam.txt", "affine (line 15)"],
        ),
        (
            OCAMCALIB.replacen("480 720", "", 1),
            vec!["cam.txt", "image size"],
        ),
        (
            OCAMCALIB.replacen("5 -1.800000e+02", "5 1.800000e+02", 1),
            vec!["cam.txt", "pol", "negative"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(ocamcalib::parse(&text, "cam.txt", "cam")), &parts);
    }
}

/// A camodocal MEI camera as its calibration tool writes it (through
/// OpenCV's FileStorage).
const CAMODOCAL_MEI: &str = "%YAML:1.0\n---\nmodel_type: MEI\ncamera_name: left\nimage_width: 1280\nimage_height: 960\nmirror_parameters:\n   xi: 1.5000000000000000e+00\ndistortion_parameters:\n   k1: -5.0000000000000003e-02\n   k2: 2.0000000000000000e-01\n   p1: 1.0000000000000000e-03\n   p2: -2.0000000000000000e-03\nprojection_parameters:\n   gamma1: 8.0000000000000000e+02\n   gamma2: 8.1000000000000000e+02\n   u0: 6.4000000000000000e+02\n   v0: 4.8000000000000000e+02\n";

#[test]
fn camodocal_cameras_mean_what_camodocal_means() {
    let path = tmp("camodocal").join("left.yaml");
    std::fs::write(&path, CAMODOCAL_MEI).unwrap();
    let loaded = formats::load(&path, None, None).unwrap();
    assert_eq!(loaded.format, Format::Camodocal);
    let cam = &loaded.rig.cameras[0];
    assert_eq!(cam.name, "left");
    let k = cam.intrinsics;
    assert_eq!(
        k.distortion,
        Distortion::Omni([1.5, -0.05, 0.2, 0.001, -0.002, 0.0])
    );
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (800.0, 810.0, 640.0, 480.0));
    // Mei's projection worked by hand: the unit sphere, the plane at ξ,
    // camodocal's distortion (OpenCV's), γ and (u0, v0).
    let q = k.project(&Vector3::new(0.5, -0.3, 0.8)).unwrap();
    assert!((q.x - 814.3355742094254).abs() < 1e-9, "{q}");
    assert!((q.y - 374.08058871971537).abs() < 1e-9, "{q}");
    // KANNALA_BRANDT's k2..k5 are OpenCV's fisheye k1..k4, mu and mv the
    // focal lengths; PINHOLE is radial-tangential without k3.
    let kb = CAMODOCAL_MEI
        .replace("model_type: MEI", "model_type: KANNALA_BRANDT")
        .replace(
            "projection_parameters:\n",
            "projection_parameters:\n   k2: 0.01\n   k3: -0.002\n   k4: 0.0003\n   k5: -0.00004\n   mu: 300.0\n   mv: 301.0\n",
        );
    let kb = camodocal::parse(&kb, "kb.yaml", "kb").unwrap();
    assert_eq!(
        kb.intrinsics.distortion,
        Distortion::Fisheye([0.01, -0.002, 0.0003, -0.00004])
    );
    assert_eq!((kb.intrinsics.fx, kb.intrinsics.fy), (300.0, 301.0));
    let pinhole = CAMODOCAL_MEI
        .replace("model_type: MEI", "model_type: PINHOLE")
        .replace("gamma1:", "fx:")
        .replace("gamma2:", "fy:")
        .replace("u0:", "cx:")
        .replace("v0:", "cy:");
    let pinhole = camodocal::parse(&pinhole, "p.yaml", "p").unwrap();
    assert_eq!(
        pinhole.intrinsics.distortion,
        Distortion::RadTan([-0.05, 0.2, 0.001, -0.002, 0.0])
    );
    // Each written back: the same bits.
    for c in [cam, &kb, &pinhole] {
        let text = camodocal::write(c).unwrap();
        let back = camodocal::parse(&text, "back.yaml", "x").unwrap();
        assert_eq!(back.intrinsics, c.intrinsics, "{text}");
        assert_eq!(back.name, c.name);
    }
    // Bad files: errors name the file and the field.
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            CAMODOCAL_MEI.replace("   xi: 1.5000000000000000e+00\n", ""),
            vec!["left.yaml", "mirror_parameters"],
        ),
        (
            CAMODOCAL_MEI.replace("model_type: MEI", "model_type: SCARAMUZZA"),
            vec!["left.yaml", "model_type", "SCARAMUZZA", "KANNALA_BRANDT"],
        ),
        (
            CAMODOCAL_MEI.replace("gamma1: 8.0000000000000000e+02", "gamma1: wide"),
            vec!["left.yaml", "projection_parameters.gamma1"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(camodocal::parse(&text, "left.yaml", "left")), &parts);
    }
}

/// A Basalt calibration of two cameras as Basalt writes it (cereal's JSON).
const BASALT: &str = r#"{
    "value0": {
        "T_imu_cam": [
            {
                "px": 0.04,
                "py": -0.02,
                "pz": -0.01,
                "qx": 0.0,
                "qy": 0.0,
                "qz": 0.7071067811865476,
                "qw": 0.7071067811865476
            },
            {
                "px": -0.06,
                "py": -0.02,
                "pz": -0.01,
                "qx": 0.0,
                "qy": 0.0,
                "qz": 0.7071067811865476,
                "qw": 0.7071067811865476
            }
        ],
        "intrinsics": [
            {
                "camera_type": "ds",
                "intrinsics": {
                    "fx": 349.7,
                    "fy": 349.6,
                    "cx": 254.9,
                    "cy": 257.5,
                    "xi": -0.23,
                    "alpha": 0.56
                }
            },
            {
                "camera_type": "eucm",
                "intrinsics": {
                    "fx": 380.1,
                    "fy": 380.2,
                    "cx": 255.0,
                    "cy": 256.0,
                    "alpha": 0.61,
                    "beta": 1.02
                }
            }
        ],
        "resolution": [
            [
                512,
                512
            ],
            [
                512,
                512
            ]
        ],
        "vignette": [],
        "calib_accel_bias": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        "calib_gyro_bias": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        "imu_update_rate": 200.0
    }
}
"#;

#[test]
fn basalt_calibrations_mean_what_basalt_means() {
    let path = tmp("basalt").join("calibration.json");
    std::fs::write(&path, BASALT).unwrap();
    let loaded = formats::load(&path, None, None).unwrap();
    assert_eq!(loaded.format, Format::Basalt);
    let rig = loaded.rig;
    assert_eq!(rig.frame, Frame::Camera("cam0".into()));
    let k0 = rig.cameras[0].intrinsics;
    assert_eq!(k0.distortion, Distortion::DoubleSphere([-0.23, 0.56]));
    assert_eq!((k0.fx, k0.cy, k0.width), (349.7, 257.5, 512));
    assert_eq!(
        rig.cameras[1].intrinsics.distortion,
        Distortion::Eucm([0.61, 1.02])
    );
    // Both cameras turned a quarter turn about the IMU's z: cam1 lies
    // 0.1 m along the IMU's −x, which is cam0's +y.
    let p1 = rig.cameras[1].pose.unwrap();
    assert!(
        (p1.translation() - Vector3::new(0.0, 0.1, 0.0)).norm() < 1e-12,
        "{:?}",
        p1.translation()
    );
    assert!(p1.rotation_angle_to(&rig.cameras[0].pose.unwrap()) < 1e-12);
    // Written back and read again.
    let back = basalt::parse(&basalt::write(&rig).unwrap(), "back.json").unwrap();
    for (a, b) in rig.cameras.iter().zip(&back.cameras) {
        assert_eq!(a.intrinsics, b.intrinsics);
        let (pa, pb) = (a.pose.unwrap(), b.pose.unwrap());
        assert!((pa.translation() - pb.translation()).norm() < 1e-12);
        assert!(pa.rotation_angle_to(&pb) < 1e-12);
    }
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            BASALT.replacen("\"camera_type\": \"ds\"", "\"camera_type\": \"fov\"", 1),
            vec![
                "calibration.json",
                "value0.intrinsics[0].camera_type",
                "fov",
            ],
        ),
        (
            BASALT.replacen("\"qw\": 0.7071067811865476", "\"qw\": 0.9", 1),
            vec!["calibration.json", "value0.T_imu_cam[0].qw", "unit"],
        ),
        (
            BASALT.replacen("\"alpha\": 0.56", "\"alpha\": 1.56", 1),
            vec!["calibration.json", "alpha"],
        ),
        (
            BASALT.replacen("\"fy\": 349.6,\n", "", 1),
            vec!["calibration.json", "value0.intrinsics[0].intrinsics.fy"],
        ),
    ];
    for (text, parts) in cases {
        assert_mentions(&err(basalt::parse(&text, "calibration.json")), &parts);
    }
}

/// An OpenCV omnidir calibration as its calibration sample saves it
/// (FileStorage YAML: K with its skew, D as 1×4, xi as 1×1).
const OMNIDIR: &str = "%YAML:1.0\n---\ncalibration_time: \"Fri 27 Nov 2026 07:50:00 UTC\"\nnFrames: 20\nimage_width: 1280\nimage_height: 960\nflags: 0\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 8.0000000000000000e+02, 1.5000000000000000e+00,\n       6.4000000000000000e+02, 0., 8.1000000000000000e+02,\n       4.8000000000000000e+02, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n   data: [ -5.0000000000000003e-02, 2.0000000000000001e-01,\n       1.0000000000000000e-03, -2.0000000000000000e-03 ]\nxi: !!opencv-matrix\n   rows: 1\n   cols: 1\n   dt: d\n   data: [ 1.5000000000000000e+00 ]\nrms: 3.0000000000000000e-01\n";

#[test]
fn opencv_omnidir_files_mean_what_omnidir_means() {
    let c = opencv::parse(OMNIDIR, false, "omni.yaml", None).unwrap();
    let k = c.intrinsics;
    assert_eq!(
        k.distortion,
        Distortion::Omni([1.5, -0.05, 0.2, 0.001, -0.002, 1.5])
    );
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (800.0, 810.0, 640.0, 480.0));
    // Mei's projection with omnidir's skew, worked by hand:
    // u = fx·x + s·y + cx.
    let q = k.project(&Vector3::new(0.5, -0.3, 0.8)).unwrap();
    assert!(
        (q.x - 814.3355742094254 - 1.5 * (374.08058871971537 - 480.0) / 810.0).abs() < 1e-9,
        "{q}"
    );
    assert!((q.y - 374.08058871971537).abs() < 1e-9, "{q}");
    let r = k.unproject(&q).unwrap();
    assert!((r.into_inner() - Vector3::new(0.5, -0.3, 0.8).normalize()).norm() < 1e-12);
    // Written back as omnidir's keys (YAML and XML) and read again.
    let cam = rigview_calib::Camera {
        name: "omni".into(),
        device: None,
        intrinsics: k,
        pose: None,
    };
    for xml in [false, true] {
        let text = opencv::write(&cam, xml).unwrap();
        assert!(text.contains("xi") && text.contains("omnidir"), "{text}");
        let back =
            opencv::parse(&text, xml, "back", None).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back.intrinsics, k, "{text}");
    }
    // Skew without xi is not omnidir, and omnidir has 4 coefficients.
    let no_xi = OMNIDIR.split("xi:").next().unwrap().to_owned();
    assert_mentions(
        &err(opencv::parse(&no_xi, false, "omni.yaml", None)),
        &["omni.yaml", "camera_matrix", "skew"],
    );
    let five = OMNIDIR
        .replace("cols: 4", "cols: 5")
        .replace("-2.0000000000000000e-03 ]", "-2.0000000000000000e-03, 0. ]");
    assert_mentions(
        &err(opencv::parse(&five, false, "omni.yaml", None)),
        &["omni.yaml", "distortion_coefficients", "k1, k2, p1, p2"],
    );
}

#[test]
fn kalibr_pinhole_fov_is_read_and_written() {
    let text = "cam0:\n  camera_model: pinhole\n  intrinsics: [300.0, 310.0, 640.0, 480.0]\n  distortion_model: fov\n  distortion_coeffs: [0.9]\n  resolution: [1280, 960]\n  rostopic: /cam0/image_raw\n";
    let rig = kalibr::parse(text, "fov.yaml").unwrap();
    assert_eq!(rig.cameras[0].intrinsics.distortion, Distortion::Fov([0.9]));
    let back = kalibr::parse(&kalibr::write(&rig).unwrap(), "back.yaml").unwrap();
    assert_eq!(back.cameras[0].intrinsics, rig.cameras[0].intrinsics);
}
