//! Arbitrary bytes, and valid files cut short or with bytes changed, fed to
//! every parser: an error is fine, a panic or a crash is not.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::Path;

use common::fixture;
use nalgebra::Vector3;
use proptest::prelude::*;
use rigview_calib::formats::{self, kalibr, opencv, rig_yaml, ros};
use rigview_calib::tools::ground::GroundLayout;
use rigview_calib::{Camera, Distortion, Frame, Intrinsics, Pose, Rig};

fn rig() -> Rig {
    let k = Intrinsics {
        width: 960,
        height: 640,
        fx: 302.4,
        fy: 320.7,
        cx: 496.6,
        cy: 331.2,
        distortion: Distortion::Fisheye([-0.04, 0.02, -0.03, 0.008]),
    };
    let mut a = Camera::new("a", k);
    a.pose = Some(Pose::from_ypr_deg([10.0, 20.0, 0.0], Vector3::new(1.0, 0.0, 1.0)).unwrap());
    let mut b = Camera::new("b", k);
    b.pose = Some(Pose::from_ypr_deg([100.0, 40.0, 1.0], Vector3::new(0.0, 1.0, 1.0)).unwrap());
    Rig::new(Frame::Vehicle, vec![a, b], vec![(0, 1)]).unwrap()
}

/// The valid documents the mutations start from.
fn seeds() -> Vec<String> {
    let r = rig();
    vec![
        rig_yaml::to_string(&r).unwrap(),
        opencv::write(&r.cameras[0], false).unwrap(),
        opencv::write(&r.cameras[0], true).unwrap(),
        kalibr::write(&r).unwrap(),
        ros::write(&r.cameras[0]).unwrap(),
        fixture("kalibr-opencv-header.yaml").1,
        fixture("ros2-camera-info.yaml").1,
        fixture("ros-rational.yaml").1,
    ]
}

/// Every parser on one text; none may panic.
fn parse_all(text: &str) {
    let _ = rig_yaml::parse(text, "f");
    let _ = opencv::parse(text, false, "f", None);
    let _ = opencv::parse(text, true, "f", None);
    let _ = kalibr::parse(text, "f");
    let _ = ros::parse(text, "f", "c");
    let _ = formats::detect(Path::new("f.yaml"), text);
    let _ = serde_norway::from_str::<GroundLayout>(text);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let text = String::from_utf8_lossy(&bytes);
        parse_all(&text);
        // With an OpenCV header in front, the bytes reach OpenCV's parsers.
        parse_all(&format!("%YAML:1.0\n{text}"));
        parse_all(&format!("<?xml version=\"1.0\"?>\n<opencv_storage>\n{text}"));
    }

    #[test]
    fn cut_or_changed_files_never_panic(
        which in 0usize..8,
        cut in any::<prop::sample::Index>(),
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<char>()), 0..4),
    ) {
        let seed = &seeds()[which];
        let mut chars: Vec<char> = seed.chars().collect();
        for (at, c) in edits {
            let i = at.index(chars.len());
            chars[i] = c;
        }
        let end = cut.index(chars.len() + 1);
        let text: String = chars[..end].iter().collect();
        parse_all(&text);
    }
}

/// Inputs that once crashed OpenCV's own parsers (found by the tests above).
#[test]
fn inputs_that_crash_opencv_are_refused_first() {
    for text in [
        "<?xml version=",
        "<?xml version=\"1.0\"?>\n<opencv_storage>\n<camera_matrix type_id=",
    ] {
        assert!(opencv::parse(text, true, "f.xml", None).is_err());
        parse_all(text);
    }
}

#[test]
fn the_seeds_parse() {
    let s = seeds();
    assert!(rig_yaml::parse(&s[0], "f").is_ok());
    assert!(opencv::parse(&s[1], false, "f", None).is_ok());
    assert!(opencv::parse(&s[2], true, "f", None).is_ok());
    assert!(kalibr::parse(&s[3], "f").is_ok());
    assert!(ros::parse(&s[4], "f", "c").is_ok());
    assert!(kalibr::parse(&s[5], "f").is_ok());
    assert!(ros::parse(&s[6], "f", "c").is_ok());
    assert!(ros::parse(&s[7], "f", "c").is_ok());
}
