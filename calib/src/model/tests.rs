use super::*;

fn fisheye() -> Intrinsics {
    Intrinsics {
        width: 960,
        height: 640,
        fx: 302.45,
        fy: 320.75,
        cx: 496.6,
        cy: 331.2,
        distortion: Distortion::Fisheye([-0.0437, 0.0217, -0.0264, 0.0084]),
    }
}

#[test]
fn fisheye_round_trip_beyond_ninety_degrees() {
    let cam = fisheye();
    let t_max = cam.max_incidence();
    assert!(t_max > 95f64.to_radians(), "θmax = {}", t_max.to_degrees());
    for i in 0..200 {
        let theta = t_max * 0.999 * f64::from(i) / 199.0;
        let phi = f64::from(i) * 0.7;
        let ray = Vector3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        );
        let px = cam.project(&(ray * 3.0)).unwrap();
        let back = cam.unproject(&px).unwrap();
        assert!((back.into_inner() - ray).norm() < 1e-12, "θ = {theta}");
    }
}

#[test]
fn radtan_folds_are_invalid() {
    // k1 < 0 folds at r² = −1/(3 k1).
    let k = [-0.3, 0.0, 0.0, 0.0, 0.0];
    let r2 = pinhole_r2_max(&[-0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert!((r2 - 1.0 / 0.9).abs() < 1e-9, "{r2}");
    let cam = Intrinsics {
        width: 640,
        height: 480,
        fx: 500.0,
        fy: 500.0,
        cx: 320.0,
        cy: 240.0,
        distortion: Distortion::RadTan(k),
    };
    assert!(cam.project(&Vector3::new(2.0, 0.0, 1.0)).is_none());
    assert!(cam.project(&Vector3::new(0.5, 0.0, -1.0)).is_none());
    assert!(cam.project(&Vector3::new(0.5, 0.2, 1.0)).is_some());
}

fn rational(k: [f64; 8]) -> Intrinsics {
    Intrinsics {
        width: 1280,
        height: 720,
        fx: 610.2,
        fy: 609.8,
        cx: 638.4,
        cy: 366.9,
        distortion: Distortion::Rational(k),
    }
}

/// As a depth camera's colour stream calibrates: numerator and
/// denominator nearly cancel.
const DEPTH_CAMERA: [f64; 8] = [0.52, -2.6, 6.2e-4, -2.1e-4, 1.5, 0.4, -2.45, 1.42];

#[test]
fn rational_round_trip_across_the_image() {
    let cam = rational(DEPTH_CAMERA);
    let mut worst = 0.0_f64;
    for j in 0..=36 {
        for i in 0..=64 {
            let px = Point2::new(f64::from(i) / 64.0 * 1279.0, f64::from(j) / 36.0 * 719.0);
            let ray = cam.unproject(&px).unwrap();
            let back = cam.project(&(ray.into_inner() * 2.5)).unwrap();
            worst = worst.max((back - px).norm());
        }
    }
    assert!(worst < 1e-9, "round trip off by {worst} px");
}

#[test]
fn rational_validity_ends_at_a_fold_or_a_pole() {
    // A denominator 1 − r² has its pole at r² = 1, and the numerator
    // 1 + r² keeps r·n/d increasing up to it.
    let pole = rational([1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0]);
    let r2 = pinhole_r2_max(&[1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0]);
    assert!((r2 - 1.0).abs() < 1e-9, "{r2}");
    assert!(pole.project(&Vector3::new(0.999, 0.0, 1.0)).is_some());
    assert!(pole.project(&Vector3::new(1.001, 0.0, 1.0)).is_none());
    // Numerator 1, denominator 1 + r²: r/(1 + r²) peaks at r = 1.
    let fold = rational([0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
    assert!((fold.max_incidence() - std::f64::consts::FRAC_PI_4).abs() < 1e-9);
    let edge = fold.project(&Vector3::new(0.999_999, 0.0, 1.0)).unwrap();
    assert!(fold.unproject(&Point2::new(edge.x + 1.0, edge.y)).is_none());
    let inside = fold.unproject(&Point2::new(edge.x - 1.0, edge.y)).unwrap();
    assert!(inside.x / inside.z < 1.0);
    // Tangential terms fold the image where they outgrow the radial
    // part: with p1 = 0.1 alone, y ↦ y + 0.3 y² along x = 0 turns back
    // at y = −1/0.6.
    let tangential = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0];
    let r2 = pinhole_r2_max(&tangential);
    assert!((r2 - 1.0 / 0.36).abs() < 1e-9, "{r2}");
    let cam = rational(tangential);
    assert!(cam.project(&Vector3::new(0.0, -1.66, 1.0)).is_some());
    assert!(cam.project(&Vector3::new(0.0, -1.67, 1.0)).is_none());
    // The depth camera is valid beyond its image corners.
    let cam = rational(DEPTH_CAMERA);
    let fov = cam.field_of_view();
    assert!(fov.diagonal_deg.is_some(), "{fov:?}");
    assert!(fov.model_limit_deg > 0.5 * fov.diagonal_deg.unwrap_or(180.0));
}

/// The inversion of the fisheye polynomial agrees with a bisection to
/// the last bit within 1e-12 rad wherever the polynomial is not flat
/// (dθd/dθ ≥ 0.05; the real surround-nz lens, θmax about 101°).
#[test]
fn fisheye_inversion_agrees_with_a_bisection() {
    let Distortion::Fisheye(k) = fisheye().distortion else {
        unreachable!()
    };
    let t_max = fisheye_theta_max(&k);
    for i in 1..20_000 {
        let td = fisheye_theta_d(&k, t_max) * f64::from(i) / 20_000.0;
        let t = fisheye_theta_from_theta_d(&k, t_max, td).unwrap();
        if fisheye_dtheta_d(&k, t) < 0.05 {
            continue;
        }
        let (mut lo, mut hi) = (0.0, t_max);
        while hi - lo > 0.0 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if fisheye_theta_d(&k, mid) < td {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        assert!((t - lo).abs() < 1e-12, "θd = {td}: {t} against {lo}");
    }
}

/// A projector gives the same bits as the intrinsics it was built from,
/// inside and outside the valid region, for every model.
#[test]
fn projector_gives_the_same_bits() {
    let models = [
        fisheye(),
        // Folds at θ = 1.29 rad.
        Intrinsics {
            distortion: Distortion::Fisheye([-0.2, 0.0, 0.0, 0.0]),
            ..fisheye()
        },
        rational(DEPTH_CAMERA),
        rational([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]),
        Intrinsics {
            distortion: Distortion::RadTan([-0.3, 0.08, 1e-3, -2e-3, 0.0]),
            ..rational(DEPTH_CAMERA)
        },
    ];
    let bits = |p: Option<Point2<f64>>| p.map(|p| (p.x.to_bits(), p.y.to_bits()));
    let ray_bits =
        |r: Option<Unit<Vector3<f64>>>| r.map(|r| (r.x.to_bits(), r.y.to_bits(), r.z.to_bits()));
    let mut outside = 0;
    for cam in models {
        let proj = cam.projector();
        assert_eq!(proj.intrinsics(), &cam);
        let mut inside = 0;
        for i in 0..60 {
            for j in 0..40 {
                // Directions all round the sphere, and pixels beyond
                // the image.
                let theta = std::f64::consts::PI * f64::from(i) / 59.0;
                let phi = 0.37 + std::f64::consts::TAU * f64::from(j) / 40.0;
                let p = Vector3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ) * 2.5;
                let a = cam.project(&p);
                assert_eq!(bits(a), bits(proj.project(&p)), "{p:?}");
                if a.is_some() {
                    inside += 1;
                } else {
                    outside += 1;
                }
                let px = Point2::new(f64::from(i) * 40.0 - 400.0, f64::from(j) * 30.0 - 200.0);
                assert_eq!(ray_bits(cam.unproject(&px)), ray_bits(proj.unproject(&px)));
            }
        }
        assert!(inside > 0, "{cam:?}");
    }
    // Every model but the first fisheye's leaves directions outside.
    assert!(outside > 4 * 600, "{outside} outside");
}

#[test]
fn rig_file_model_names() {
    let d = Distortion::from_name("pinhole-rational", &DEPTH_CAMERA).unwrap();
    assert_eq!(d, Distortion::Rational(DEPTH_CAMERA));
    assert_eq!(d.model_name(), "pinhole-rational");
    assert_eq!(d.coefficient_names().len(), d.coefficients().len());
    let e = Distortion::from_name("pinhole-rational", &[0.0; 5]).unwrap_err();
    assert_eq!((e.field.as_str(), e.found.as_str()), ("distortion", "5"));
    assert!(e.expected.contains("8 rational"), "{e}");
    let e = Distortion::from_name("omni", &[0.0; 5]).unwrap_err();
    assert_eq!(e.field, "model");
    assert!(e.expected.contains("pinhole-rational"), "{e}");
}

#[test]
fn validate_names_the_field() {
    let mut cam = fisheye();
    cam.fy = -3.0;
    let e = cam.validate().unwrap_err();
    assert_eq!(e.field, "fy");
    cam.fy = 300.0;
    cam.distortion = Distortion::Fisheye([0.0, f64::NAN, 0.0, 0.0]);
    assert_eq!(cam.validate().unwrap_err().field, "distortion[1]");
}

pub(super) fn sphere_camera(distortion: Distortion) -> Intrinsics {
    Intrinsics {
        width: 1280,
        height: 960,
        fx: 300.0,
        fy: 310.0,
        cx: 640.0,
        cy: 480.0,
        distortion,
    }
}

/// The sphere models' cameras of the tests: a double sphere, an extended
/// unified and a unified (Mei) camera with distortion, each over 180°.
fn sphere_cameras() -> [Intrinsics; 5] {
    [
        sphere_camera(Distortion::DoubleSphere([-0.2, 0.6])),
        sphere_camera(Distortion::DoubleSphere([0.3, 0.45])),
        sphere_camera(Distortion::Eucm([0.6, 1.1])),
        sphere_camera(Distortion::Eucm([0.4, 0.9])),
        sphere_camera(Distortion::Omni([0.9, -0.1, 0.02, 0.001, -0.002, 0.0])),
    ]
}

#[test]
fn sphere_models_project_as_their_papers_formulas_worked_by_hand() {
    // x = (0.5, −0.3, 0.8), worked from each model's published formula.
    let p = Vector3::new(0.5, -0.3, 0.8);
    for (k, want) in [
        (
            sphere_camera(Distortion::DoubleSphere([-0.2, 0.6])),
            [841.7035424228345, 354.9438036978426],
        ),
        (
            sphere_camera(Distortion::Eucm([0.6, 1.1])),
            [802.3050955728509, 379.3708407448325],
        ),
        (
            sphere_camera(Distortion::Omni([0.9, -0.1, 0.02, 0.001, -0.002, 0.0])),
            [727.4698266746568, 425.761335098215],
        ),
    ] {
        let q = k.project(&p).unwrap();
        let name = k.distortion.model_name();
        assert!((q.x - want[0]).abs() < 1e-9, "{name}: {q}");
        assert!((q.y - want[1]).abs() < 1e-9, "{name}: {q}");
    }
}

#[test]
fn sphere_models_round_trip_over_their_field_of_view() {
    for k in sphere_cameras() {
        let name = k.distortion.model_name();
        let limit = k.max_incidence();
        assert!(limit > 90f64.to_radians(), "{name}: θmax {limit}");
        let mut worst: f64 = 0.0;
        let mut seen = 0;
        for i in 0..=60 {
            let theta = limit * (1.0 - 1e-3) * f64::from(i) / 60.0;
            for j in 0..24 {
                let phi = std::f64::consts::TAU * f64::from(j) / 24.0;
                let (s, c) = theta.sin_cos();
                let p = Vector3::new(s * phi.cos(), s * phi.sin(), c);
                let q = k
                    .project(&p)
                    .unwrap_or_else(|| panic!("{name}: θ {theta} does not project"));
                // The field of view is the image's: far outside it (the
                // unified model's plane reaches 10⁵ px before its
                // distortion folds) only the relative error is small.
                if !k.contains(&q) {
                    continue;
                }
                seen += 1;
                let r = k
                    .unproject(&q)
                    .unwrap_or_else(|| panic!("{name}: {q} does not unproject"));
                let back = k.project(&r).unwrap();
                worst = worst.max((back - q).norm());
                assert!(
                    (r.into_inner() - p).norm() < 1e-8,
                    "{name}: θ {theta} φ {phi}"
                );
            }
        }
        assert!(seen > 500, "{name}: {seen} samples on the image");
        assert!(worst < 1e-6, "{name}: {worst} px");
    }
}

#[test]
fn sphere_models_refuse_what_lies_beyond_their_valid_cone() {
    for k in sphere_cameras() {
        let name = k.distortion.model_name();
        let limit = k.max_incidence();
        if limit >= std::f64::consts::PI {
            continue;
        }
        let theta = limit + 1e-3;
        let p = Vector3::new(theta.sin(), 0.0, theta.cos());
        assert!(k.project(&p).is_none(), "{name}: θ {theta} projects");
    }
    // The double sphere with α > ½ unprojects nothing beyond
    // r² = 1/(2α − 1) on its plane.
    let k = sphere_camera(Distortion::DoubleSphere([-0.2, 0.6]));
    let r = (1.0 / (2.0 * 0.6 - 1.0_f64)).sqrt() * 1.01;
    assert!(k.unproject(&Point2::new(k.cx + k.fx * r, k.cy)).is_none());
    // Bad parameters are refused naming the field.
    for (d, field) in [
        (Distortion::DoubleSphere([0.1, 1.0]), "alpha"),
        (Distortion::DoubleSphere([1.5, 0.5]), "xi"),
        (Distortion::Eucm([0.5, 0.0]), "beta"),
        (Distortion::Omni([-0.1, 0.0, 0.0, 0.0, 0.0, 0.0]), "xi"),
    ] {
        let e = sphere_camera(d).validate().unwrap_err();
        assert_eq!(e.field, field, "{e}");
    }
}

#[test]
fn sphere_models_are_named_in_rig_files_and_read_back() {
    for k in sphere_cameras() {
        let d = k.distortion;
        let back = Distortion::from_name(d.model_name(), d.coefficients()).unwrap();
        assert_eq!(back, d);
        assert_eq!(d.coefficients().len(), d.coefficient_names().len());
    }
    let e = Distortion::from_name("eucm", &[0.5]).unwrap_err();
    assert!(e.expected.contains("alpha, beta"), "{e}");
}

#[test]
fn the_radial_polynomial_round_trips_and_stops_where_it_folds() {
    // WoodScape's front camera (ρ in pixels: focal length 1).
    let k = Intrinsics {
        width: 1280,
        height: 966,
        fx: 1.0,
        fy: 1.02,
        cx: 643.442,
        cy: 479.407,
        distortion: Distortion::RadialPoly([339.749, -31.988, 48.275, -7.201]),
    };
    k.validate().unwrap();
    // dρ/dθ = k1 + 2k2 θ + 3k3 θ² + 4k4 θ³ stays positive up to π.
    let limit = k.max_incidence();
    assert_eq!(limit.to_bits(), std::f64::consts::PI.to_bits());
    let worst = worst_round_trip(&k, limit * 0.999);
    assert!(worst < 1e-6, "{worst} px");
    // ρ = 300 θ − 20 θ⁴ stops increasing at θ = ∛3.75 (89.0°): beyond,
    // neither way has an answer.
    let folding = Intrinsics {
        distortion: Distortion::RadialPoly([300.0, 0.0, 0.0, -20.0]),
        ..k
    };
    let limit = folding.max_incidence();
    assert!((limit - 3.75f64.cbrt()).abs() < 1e-9, "{limit}");
    let beyond = limit + 1e-3;
    assert!(folding
        .project(&Vector3::new(beyond.sin(), 0.0, beyond.cos()))
        .is_none());
    let edge = folding
        .project(&Vector3::new(limit.sin(), 0.0, limit.cos()))
        .unwrap();
    assert!(folding
        .unproject(&Point2::new(edge.x + 1.0, edge.y))
        .is_none());
    let e = Intrinsics {
        distortion: Distortion::RadialPoly([-1.0, 0.0, 0.0, 0.0]),
        ..k
    }
    .validate()
    .unwrap_err();
    assert_eq!(e.field, "distortion[0]", "{e}");
}

#[test]
fn the_field_of_view_model_projects_as_devernay_and_faugeras_wrote_it() {
    let k = sphere_camera(Distortion::Fov([0.9]));
    // r_d = atan(2 r tan(ω/2)) / ω, worked by hand for (0.5, −0.3, 0.8).
    let q = k.project(&Vector3::new(0.5, -0.3, 0.8)).unwrap();
    assert!((q.x - 815.3623378279683).abs() < 1e-9, "{q}");
    assert!((q.y - 371.2753505466597).abs() < 1e-9, "{q}");
    // Round trips over the forward hemisphere.
    let worst = worst_round_trip(&k, 1.5);
    assert!(worst < 1e-6, "{worst} px");
    // Nothing behind the camera, and nothing beyond r_d = π/(2ω).
    assert!(k.project(&Vector3::new(1.0, 0.0, -0.1)).is_none());
    let edge = std::f64::consts::FRAC_PI_2 / 0.9;
    assert!(k
        .unproject(&Point2::new(k.cx + k.fx * edge * 1.001, k.cy))
        .is_none());
    // ω = 0 is the undistorted pinhole.
    let plain = sphere_camera(Distortion::Fov([0.0]));
    let q = plain.project(&Vector3::new(0.5, -0.3, 0.8)).unwrap();
    assert!((q.x - (640.0 + 300.0 * 0.625)).abs() < 1e-9, "{q}");
}

/// The largest pixel distance between a projection and the projection of
/// its unprojection, over rays from the axis to `theta_max` on 16 azimuths
/// (every ray also unprojects to itself within 1e-9).
fn worst_round_trip(k: &Intrinsics, theta_max: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..=50 {
        let theta = theta_max * f64::from(i) / 50.0;
        for j in 0..16 {
            let phi = std::f64::consts::TAU * f64::from(j) / 16.0;
            let (s, c) = theta.sin_cos();
            let p = Vector3::new(s * phi.cos(), s * phi.sin(), c);
            let q = k.project(&p).unwrap();
            let r = k.unproject(&q).unwrap();
            assert!((r.into_inner() - p).norm() < 1e-9, "θ {theta}");
            worst = worst.max((k.project(&r).unwrap() - q).norm());
        }
    }
    worst
}
