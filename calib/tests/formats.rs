//! Every format: exact round trips, what the fields mean, and the errors
//! for bad files (each naming the file, the field and what was expected).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use proptest::prelude::*;
use rigview_calib::formats::{self, kalibr, opencv, rig_yaml, ros, Format};
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
        k in prop::array::uniform5(finite()),
        fisheye in any::<bool>(),
        ypr in prop::array::uniform3(-180.0..180.0f64),
        t in prop::array::uniform3(finite()),
        w in 1u32..100_000, h in 1u32..100_000,
    ) {
        let distortion = if fisheye {
            Distortion::Fisheye([k[0], k[1], k[2], k[3]])
        } else {
            Distortion::RadTan(k)
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
            good.replacen("camera_model: pinhole", "camera_model: omni", 1),
            vec!["chain.yaml", "cam0.camera_model", "omni-equidistant"],
        ),
        (
            good.replacen("distortion_model: equidistant", "distortion_model: fov", 1),
            vec!["chain.yaml", "cam0.distortion_model", "pinhole-fov"],
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
            info.replace("plumb_bob", "rational_polynomial"),
            vec!["info.yaml", "distortion_model", "rational_polynomial"],
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
