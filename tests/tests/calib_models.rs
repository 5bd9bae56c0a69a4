//! The camera models against OpenCV, in the same test: projection against
//! `fisheye::projectPoints` / `projectPoints`, unprojection against
//! `fisheye::undistortPoints` / `undistortPoints`, on random points across
//! the field of view, for the four real surround-view calibrations and for
//! pinhole (radial-tangential and rational, OpenCV's 8 coefficients) and
//! fisheye model sets of realistic and random coefficients.
//!
//! OpenCV's fisheye functions work with x/z and clip θd to π/2, so they only
//! describe the forward hemisphere; there the models must agree to 1e-6 px.
//! Beyond it (the real lenses reach 93° and more), project ∘ unproject must
//! give the pixel back.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod calib_common;

use nalgebra::{Point2, Vector3};
use opencv::core::{
    Mat, Point2d, Point3d, TermCriteria, TermCriteria_COUNT, TermCriteria_EPS, Vector,
};
use opencv::prelude::MatTraitConst;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rigview_calib::{formats, Distortion, Intrinsics};

fn k_mat(k: &Intrinsics) -> Mat {
    Mat::from_slice_2d(&k.camera_matrix()).unwrap()
}

fn d_mat(k: &Intrinsics) -> Mat {
    let d = k.distortion.coefficients();
    Mat::from_slice(d).unwrap().try_clone().unwrap()
}

/// OpenCV's projection of camera-frame points.
fn opencv_project(k: &Intrinsics, pts: &[Vector3<f64>]) -> Vec<[f64; 2]> {
    let obj: Vector<Point3d> = pts.iter().map(|p| Point3d::new(p.x, p.y, p.z)).collect();
    let zero = Mat::from_slice(&[0.0f64, 0.0, 0.0])
        .unwrap()
        .try_clone()
        .unwrap();
    let mut out = Vector::<Point2d>::new();
    match k.distortion {
        Distortion::Fisheye(_) => opencv::calib3d::fisheye_project_points_vec(
            &obj,
            &mut out,
            &zero,
            &zero,
            &k_mat(k),
            &d_mat(k),
            0.0,
            &mut Mat::default(),
        )
        .unwrap(),
        Distortion::RadTan(_) | Distortion::Rational(_) => opencv::calib3d::project_points(
            &obj,
            &zero,
            &zero,
            &k_mat(k),
            &d_mat(k),
            &mut out,
            &mut Mat::default(),
            0.0,
        )
        .unwrap(),
        other => panic!("OpenCV has no {} model", other.model_name()),
    }
    out.iter().map(|p| [p.x, p.y]).collect()
}

/// OpenCV's unprojection of pixels to normalised points (x/z, y/z).
fn opencv_unproject(k: &Intrinsics, px: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let src: Vector<Point2d> = px.iter().map(|p| Point2d::new(p[0], p[1])).collect();
    let mut out = Vector::<Point2d>::new();
    let none = Mat::default();
    match k.distortion {
        Distortion::Fisheye(_) => {
            let c = TermCriteria::new(TermCriteria_COUNT + TermCriteria_EPS, 100, 1e-14).unwrap();
            opencv::calib3d::fisheye_undistort_points(
                &src,
                &mut out,
                &k_mat(k),
                &d_mat(k),
                &none,
                &none,
                c,
            )
            .unwrap();
        }
        Distortion::RadTan(_) | Distortion::Rational(_) => {
            let c = TermCriteria::new(TermCriteria_COUNT + TermCriteria_EPS, 2000, 1e-13).unwrap();
            opencv::calib3d::undistort_points_iter(
                &src,
                &mut out,
                &k_mat(k),
                &d_mat(k),
                &none,
                &none,
                c,
            )
            .unwrap();
        }
        other => panic!("OpenCV has no {} model", other.model_name()),
    }
    out.iter().map(|p| [p.x, p.y]).collect()
}

/// The angle between two vectors, accurate for tiny angles too.
fn angle(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

fn model_sets() -> Vec<(String, Intrinsics)> {
    let mut sets = Vec::new();
    let nz = formats::load(&calib_common::data_dir().join("surround-nz"), None, None).unwrap();
    for c in nz.rig.cameras {
        sets.push((format!("surround-nz {}", c.name), c.intrinsics));
    }
    let pinhole = |fx: f64, d: [f64; 5]| Intrinsics {
        width: 640,
        height: 480,
        fx,
        fy: fx * 1.001,
        cx: 331.5,
        cy: 242.25,
        distortion: Distortion::RadTan(d),
    };
    // As OpenCV calibrates the left*.jpg sample camera.
    sets.push((
        "pinhole left*.jpg-like".into(),
        pinhole(533.3, [-0.281, 0.0294, 0.00112, -5.5e-5, 0.151]),
    ));
    sets.push((
        "pinhole strong barrel".into(),
        pinhole(400.0, [-0.35, 0.12, -0.002, 0.003, -0.02]),
    ));
    sets.push((
        "pinhole pincushion".into(),
        pinhole(700.0, [0.12, 0.05, 0.001, 0.001, 0.0]),
    ));
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for i in 0..4 {
        let k = [
            rng.gen_range(-0.08..0.08),
            rng.gen_range(-0.03..0.03),
            rng.gen_range(-0.01..0.01),
            rng.gen_range(-0.003..0.003),
        ];
        sets.push((
            format!("fisheye random {i}"),
            Intrinsics {
                width: 1280,
                height: 1024,
                fx: rng.gen_range(300.0..400.0),
                fy: rng.gen_range(300.0..400.0),
                cx: rng.gen_range(600.0..680.0),
                cy: rng.gen_range(480.0..540.0),
                distortion: Distortion::Fisheye(k),
            },
        ));
        let d = [
            rng.gen_range(-0.3..0.1),
            rng.gen_range(-0.05..0.1),
            rng.gen_range(-0.003..0.003),
            rng.gen_range(-0.003..0.003),
            rng.gen_range(-0.02..0.02),
        ];
        sets.push((
            format!("pinhole random {i}"),
            pinhole(rng.gen_range(450.0..800.0), d),
        ));
    }
    let rational = |w: u32, h: u32, fx: f64, d: [f64; 8]| Intrinsics {
        width: w,
        height: h,
        fx,
        fy: fx * 0.9993,
        cx: f64::from(w) / 2.0 - 1.6,
        cy: f64::from(h) / 2.0 + 3.1,
        distortion: Distortion::Rational(d),
    };
    // As depth cameras' colour streams calibrate: numerator and denominator
    // nearly cancel.
    sets.push((
        "rational depth-camera-like".into(),
        rational(
            1280,
            720,
            610.2,
            [0.52, -2.6, 6.2e-4, -2.1e-4, 1.5, 0.4, -2.45, 1.42],
        ),
    ));
    // A wide lens as CALIB_RATIONAL_MODEL fits it: large k1 and k4.
    sets.push((
        "rational wide".into(),
        rational(
            640,
            480,
            300.0,
            [2.3, 0.9, 2e-4, -3e-4, 0.02, 2.7, 1.6, 0.15],
        ),
    ));
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for i in 0..4 {
        let r = [
            rng.gen_range(-0.3..0.3),
            rng.gen_range(-0.1..0.1),
            rng.gen_range(-0.003..0.003),
            rng.gen_range(-0.003..0.003),
            rng.gen_range(-0.02..0.02),
            rng.gen_range(-0.3..0.3),
            rng.gen_range(-0.1..0.1),
            rng.gen_range(-0.02..0.02),
        ];
        sets.push((
            format!("rational random {i}"),
            rational(640, 480, rng.gen_range(450.0..800.0), r),
        ));
    }
    sets
}

/// Random camera-frame points across the field of view: through random
/// pixels of the image, and at random angles up to the model's limit.
fn sample_points(k: &Intrinsics, rng: &mut ChaCha8Rng, n: usize) -> Vec<Vector3<f64>> {
    let mut pts = Vec::with_capacity(n);
    let limit = k.max_incidence();
    while pts.len() < n {
        let ray = if pts.len() % 2 == 0 {
            let px = Point2::new(
                rng.gen_range(-0.5..f64::from(k.width) - 0.5),
                rng.gen_range(-0.5..f64::from(k.height) - 0.5),
            );
            match k.unproject(&px) {
                Some(r) => r.into_inner(),
                None => continue,
            }
        } else {
            let theta = rng.gen_range(0.0..limit);
            let phi = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
            Vector3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )
        };
        pts.push(ray * rng.gen_range(0.05..50.0));
    }
    pts
}

#[test]
fn projection_and_unprojection_agree_with_opencv() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let mut worst_project = 0.0_f64;
    let mut worst_unproject = 0.0_f64;
    for (name, k) in model_sets() {
        let fisheye = matches!(k.distortion, Distortion::Fisheye(_));
        // OpenCV's domain: the forward hemisphere, θd below its π/2 clip.
        let in_opencv_domain = |p: &Vector3<f64>| {
            let theta = p.x.hypot(p.y).atan2(p.z);
            let q = k.project(p);
            let (w, h) = (f64::from(k.width), f64::from(k.height));
            theta < 89.5f64.to_radians()
                && q.is_some_and(|q| {
                    // Within the image and a margin of its own size (a
                    // pinhole sends rays near 90° to millions of pixels).
                    q.x.abs() < 2.0 * w
                        && q.y.abs() < 2.0 * h
                        && (!fisheye || ((q.x - k.cx) / k.fx).hypot((q.y - k.cy) / k.fy) < 1.5)
                })
        };
        let pts: Vec<Vector3<f64>> = sample_points(&k, &mut rng, 4000);
        let ours: Vec<Option<Point2<f64>>> = pts.iter().map(|p| k.project(p)).collect();
        let compared: Vec<usize> = (0..pts.len())
            .filter(|&i| in_opencv_domain(&pts[i]))
            .collect();
        assert!(
            compared.len() > 500,
            "{name}: only {} points in OpenCV's domain",
            compared.len()
        );
        let sub: Vec<Vector3<f64>> = compared.iter().map(|&i| pts[i]).collect();
        let theirs = opencv_project(&k, &sub);
        let mut max_p = 0.0_f64;
        let mut max_theta = 0.0_f64;
        for (&i, t) in compared.iter().zip(&theirs) {
            let o = ours[i].unwrap();
            let e = (o.x - t[0]).hypot(o.y - t[1]);
            assert!(
                e < 1e-6,
                "{name}: projection of {:?} differs by {e} px",
                pts[i]
            );
            max_p = max_p.max(e);
            max_theta = max_theta.max(pts[i].x.hypot(pts[i].y).atan2(pts[i].z));
        }
        // Unprojection: the pixels of those points that lie on the image back
        // to rays, compared as angles × focal length. (Off the image,
        // OpenCV's fixed-point iteration for the pinhole model can diverge.)
        let pixels: Vec<[f64; 2]> = compared
            .iter()
            .map(|&i| ours[i].unwrap())
            .filter(|p| k.contains(p))
            .map(|p| [p.x, p.y])
            .collect();
        assert!(
            pixels.len() > 500,
            "{name}: only {} pixels on the image",
            pixels.len()
        );
        let theirs = opencv_unproject(&k, &pixels);
        let f = 0.5 * (k.fx + k.fy);
        let mut max_u = 0.0_f64;
        let mut unconverged = 0;
        for (px, t) in pixels.iter().zip(&theirs) {
            let ray = k.unproject(&Point2::new(px[0], px[1])).unwrap();
            let cv_ray = Vector3::new(t[0], t[1], 1.0).normalize();
            let e = angle(&ray, &cv_ray) * f;
            if e >= 1e-6 {
                // Judge both inverses by OpenCV's own forward projection:
                // ours must land on the pixel, and OpenCV's must be the one
                // that does not (its fixed-point iteration for the pinhole
                // model converges slowly near strongly distorted edges).
                let back = opencv_project(&k, &[ray.into_inner(), cv_ray]);
                let ours_err = (back[0][0] - px[0]).hypot(back[0][1] - px[1]);
                let cv_err = (back[1][0] - px[0]).hypot(back[1][1] - px[1]);
                assert!(
                    ours_err < 1e-9 && cv_err > 1e3 * ours_err,
                    "{name}: unprojection of {px:?} differs by {e} px \
                     (reprojection through OpenCV: ours {ours_err:e} px, OpenCV's {cv_err:e} px)"
                );
                unconverged += 1;
                continue;
            }
            max_u = max_u.max(e);
        }
        // Beyond OpenCV's domain (fisheye only): a round trip.
        let mut beyond = 0;
        for (p, o) in pts.iter().zip(&ours) {
            if in_opencv_domain(p) {
                continue;
            }
            let Some(o) = o else { continue };
            beyond += 1;
            let ray = k.unproject(o).unwrap();
            let e = angle(&ray, &p.normalize()) * f;
            assert!(
                e < 1e-6,
                "{name}: round trip beyond 90° off by {e} px at {p:?}"
            );
        }
        println!(
            "{name}: {} points vs OpenCV up to θ = {:.1}°: max projection difference {max_p:.2e} px; \
             {} pixels: max unprojection difference {max_u:.2e} px ({unconverged} where OpenCV's iteration had not converged \
             and ours reprojects through OpenCV exactly); {beyond} points beyond OpenCV's domain round-trip (model valid to {:.1}°)",
            compared.len(),
            max_theta.to_degrees(),
            pixels.len(),
            k.max_incidence().to_degrees()
        );
        worst_project = worst_project.max(max_p);
        worst_unproject = worst_unproject.max(max_u);
    }
    println!("worst: projection {worst_project:.2e} px, unprojection {worst_unproject:.2e} px");
}

#[test]
fn outside_the_valid_region_there_is_no_answer() {
    // A pinhole model folds where r·(1 + k1 r²) stops growing: r² = −1/(3 k1).
    let k = Intrinsics {
        width: 640,
        height: 480,
        fx: 300.0,
        fy: 300.0,
        cx: 320.0,
        cy: 240.0,
        distortion: Distortion::RadTan([-0.4, 0.0, 0.0, 0.0, 0.0]),
    };
    let r_max = (1.0_f64 / 1.2).sqrt();
    assert!(k.project(&Vector3::new(r_max * 0.99, 0.0, 1.0)).is_some());
    assert!(k.project(&Vector3::new(r_max * 1.01, 0.0, 1.0)).is_none());
    // The folded image radius is the largest one reachable; beyond it,
    // unprojection has no ray.
    let edge = k
        .project(&Vector3::new(r_max * 0.999_999, 0.0, 1.0))
        .unwrap();
    assert!(k.unproject(&Point2::new(edge.x + 1.0, edge.y)).is_none());
    assert!(k.unproject(&Point2::new(edge.x - 1.0, edge.y)).is_some());
}
