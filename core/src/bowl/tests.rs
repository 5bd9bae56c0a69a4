use nalgebra::Vector3;

use super::*;
use crate::sim::reference_rig;
use crate::surround::CameraLayer;

/// A small picture, for speed.
fn small() -> BowlSpec {
    BowlSpec {
        size_px: [320, 200],
        ..BowlSpec::default()
    }
}

/// Camera `layer`'s source position at picture pixel (col, row), if it
/// shows it.
fn mapped(layer: &CameraLayer, col: usize, row: usize) -> Option<[f32; 2]> {
    let [c0, r0, rw, rh] = layer.roi;
    if col < c0 || row < r0 || col >= c0 + rw || row >= r0 + rh {
        return None;
    }
    let m = layer.map[(row - r0) * rw + (col - c0)];
    (m[0] >= 0.0).then_some(m)
}

#[test]
fn the_surface_is_flat_then_rises_as_specified() {
    let s = BowlSpec::default();
    let [_, x1, _, y1] = s.vehicle_m;
    assert_eq!(s.height(x1 + s.flat_m - 1e-9, 0.0), Some(0.0));
    assert_eq!(s.height(0.0, 0.0), Some(0.0));
    // Half way up the wall's run: H/2^steepness.
    let mid = x1 + 0.5 * (s.flat_m + s.radius_m);
    let h = s.height(mid, 0.0).unwrap();
    assert!((h - s.wall_height_m / 4.0).abs() < 1e-12, "{h}");
    // The rounded rectangle: measured from the corner diagonally.
    let d = 0.5 * (s.flat_m + s.radius_m) / 2f64.sqrt();
    let h = s.height(x1 + d, y1 + d).unwrap();
    assert!((h - s.wall_height_m / 4.0).abs() < 1e-9, "{h}");
    assert_eq!(s.height(x1 + s.radius_m + 0.01, 0.0), None);
    // Round: from the centre.
    let round = BowlSpec {
        footprint: Footprint::Round,
        ..s.clone()
    };
    assert!((round.footprint_distance(3.0, 4.0) - 5.0).abs() < 1e-12);
}

#[test]
fn rays_meet_the_ground_and_the_wall_where_the_formula_says() {
    let s = BowlSpec::default();
    let [_, x1, _, _] = s.vehicle_m;
    // Straight down onto the flat part.
    let eye = Vector3::new(3.0, 1.0, 5.0);
    let p = s.intersect(&eye, &-Vector3::z()).unwrap();
    assert!((p - Vector3::new(3.0, 1.0, 0.0)).norm() < 1e-12, "{p}");
    // Level at height z0 from the vehicle: meets the wall where
    // H·u^s = z0, u = (d − flat)/(radius − flat).
    let z0 = 1.0;
    let p = s
        .intersect(&Vector3::new(0.0, 0.0, z0), &Vector3::x())
        .unwrap();
    let u = (z0 / s.wall_height_m).powf(1.0 / s.steepness);
    let want = x1 + s.flat_m + u * (s.radius_m - s.flat_m);
    assert!(
        (p.x - want).abs() < 1e-9 && (p.z - z0).abs() < 1e-9,
        "{p} against x {want}"
    );
    // Upwards over the rim: nothing.
    let up = Vector3::new(1.0, 0.0, 1.0).normalize();
    assert!(s.intersect(&Vector3::new(0.0, 0.0, 1.0), &up).is_none());
}

#[test]
fn viewpoints_orbit_animate_and_project() {
    for name in PRESETS {
        let v = Viewpoint::preset(name).unwrap();
        v.validate().unwrap();
        // Every preset's eye is inside the bowl, above its surface.
        let eye = v.eye();
        let s = BowlSpec::default();
        let h = s
            .height(eye.x, eye.y)
            .unwrap_or_else(|| panic!("{name}: beyond the rim"));
        assert!(eye.z > h + 0.3, "{name}: eye {eye} on a surface at {h}");
        // Ray and projection are inverse.
        let cam = v.camera(640, 400);
        let p = cam.eye + cam.ray(100.5, 300.5) * 7.0;
        let (c, r) = cam.project(&p).unwrap();
        assert!(
            (c - 100.5).abs() < 1e-9 && (r - 300.5).abs() < 1e-9,
            "{name}"
        );
    }
    let e = Viewpoint::preset("sideways").unwrap_err().to_string();
    assert!(e.contains("viewpoint") && e.contains("behind-left"), "{e}");
    // The top view shows the front up and the left on the left.
    let top = Viewpoint::preset("top").unwrap().camera(640, 400);
    let (_, r_front) = top.project(&Vector3::new(3.0, 0.0, 0.0)).unwrap();
    let (c_left, _) = top.project(&Vector3::new(0.0, 3.0, 0.0)).unwrap();
    assert!(r_front < 200.0 && c_left < 320.0, "{r_front} {c_left}");
    // Animation: the ends, the shorter way round in azimuth.
    let a = Viewpoint {
        yaw_deg: 170.0,
        ..Viewpoint::default()
    };
    let b = Viewpoint {
        yaw_deg: -170.0,
        pitch_deg: 60.0,
        ..Viewpoint::default()
    };
    assert_eq!(a.towards(&b, 0.0), a);
    let end = a.towards(&b, 1.0);
    assert!(
        (end.yaw_deg - 190.0).abs() < 1e-9 && (end.pitch_deg - 60.0).abs() < 1e-12,
        "{end:?}"
    );
    assert!((a.towards(&b, 0.5).yaw_deg - 180.0).abs() < 1e-9);
    // Orbit: elevation and distance stay in range.
    let o = a.orbited(30.0, 500.0, 1e-6);
    assert_eq!((o.pitch_deg, o.distance_m), (90.0, 100.0));
    assert!((o.yaw_deg - -160.0).abs() < 1e-9, "{}", o.yaw_deg);
}

#[test]
fn bad_specs_are_refused_with_the_field() {
    let ok = BowlSpec::default();
    ok.validate().unwrap();
    let cases = [
        (
            BowlSpec {
                radius_m: ok.flat_m,
                ..ok.clone()
            },
            "bowl.radius_m",
        ),
        (
            BowlSpec {
                steepness: f64::NAN,
                ..ok.clone()
            },
            "bowl.steepness",
        ),
        (
            BowlSpec {
                vehicle_m: [1.0, -1.0, -1.0, 1.0],
                ..ok.clone()
            },
            "bowl.vehicle_m",
        ),
        (
            BowlSpec {
                size_px: [0, 800],
                ..ok.clone()
            },
            "bowl.size_px",
        ),
    ];
    for (spec, field) in cases {
        let e = spec.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e} should name {field}");
    }
    let far = Viewpoint {
        distance_m: 1e4,
        ..Viewpoint::default()
    };
    let e = far.validate().unwrap_err().to_string();
    assert!(e.contains("viewpoint.distance_m"), "{e}");
}

/// A ground point of the simulated rig renders where its projection
/// says: the pixel whose ray meets the ground at P samples each camera
/// that shows P at that camera's projection of P.
#[test]
fn a_ground_point_renders_where_its_projection_says() {
    let rig = reference_rig().unwrap();
    let spec = small();
    let view = BowlView::build(&rig, &spec, &Viewpoint::preset("top").unwrap()).unwrap();
    let cam = view.camera();
    // Ahead of the vehicle, and beside its front-left corner.
    for ground in [Vector3::new(4.0, 0.4, 0.0), Vector3::new(3.2, 2.0, 0.0)] {
        let (c, r) = cam.project(&ground).unwrap();
        let (col, row) = (c.floor() as usize, r.floor() as usize);
        let p = spec
            .intersect(&cam.eye, &cam.ray(col as f64 + 0.5, row as f64 + 0.5))
            .unwrap();
        assert!(
            p.z == 0.0 && (p - ground).norm() < 0.1,
            "{p} against {ground}"
        );
        let mut shown = 0;
        for layer in view.mosaic().layers() {
            let projector = rig.cameras[layer.camera].projector().unwrap();
            if let Some(m) = mapped(layer, col, row) {
                let want = projector.project_rig(&p).unwrap();
                let e = (f64::from(m[0]) - want.x).hypot(f64::from(m[1]) - want.y);
                assert!(e < 0.05, "{}: {e} px", layer.name);
                shown += 1;
            }
        }
        assert!(shown >= 1, "{ground}: no camera shows it");
    }
}

/// A point on the wall near `radius_m`, off the vehicle's front-left
/// corner, where the front and left cameras overlap: both cameras' maps
/// at its pixel sample that same point.
#[test]
fn a_wall_point_lines_up_across_the_two_cameras_that_see_it() {
    let rig = reference_rig().unwrap();
    let spec = small();
    let view = BowlView::build(&rig, &spec, &Viewpoint::preset("behind-right").unwrap()).unwrap();
    let cam = view.camera();
    let [_, x1, _, y1] = spec.vehicle_m;
    // Just below the rim (a pixel's ray through the rim itself may pass
    // over it).
    let d = (spec.radius_m - 0.2) / 2f64.sqrt();
    let wall = Vector3::new(x1 + d, y1 + d, spec.height(x1 + d, y1 + d).unwrap());
    assert!(wall.z > 0.9 * spec.wall_height_m, "{wall}");
    let (c, r) = cam.project(&wall).unwrap();
    let (col, row) = (c.floor() as usize, r.floor() as usize);
    let p = spec
        .intersect(&cam.eye, &cam.ray(col as f64 + 0.5, row as f64 + 0.5))
        .unwrap();
    assert!((p - wall).norm() < 0.2, "{p} against {wall}");
    let seen: Vec<&str> = view
        .mosaic()
        .layers()
        .iter()
        .filter_map(|layer| {
            let m = mapped(layer, col, row)?;
            let want = rig.cameras[layer.camera]
                .projector()
                .unwrap()
                .project_rig(&p)
                .unwrap();
            let e = (f64::from(m[0]) - want.x).hypot(f64::from(m[1]) - want.y);
            assert!(e < 0.05, "{}: {e} px", layer.name);
            Some(layer.name.as_str())
        })
        .collect();
    assert_eq!(seen, ["front", "left"]);
}

/// From every preset, each pixel whose ray meets the bowl shows a camera
/// or the vehicle: the vehicle (with its shadow) covers the blind area
/// under it, and nothing within the bowl is left black.
#[test]
fn the_vehicle_covers_the_blind_area_from_every_viewpoint() {
    let rig = reference_rig().unwrap();
    let spec = small();
    for name in PRESETS {
        let view = BowlView::build(&rig, &spec, &Viewpoint::preset(name).unwrap()).unwrap();
        let cam = view.camera();
        let [w, h] = spec.size_px;
        let (mut holes, mut bowl) = (0, 0);
        for row in 0..h {
            for col in 0..w {
                let ray = cam.ray(col as f64 + 0.5, row as f64 + 0.5);
                if spec.intersect(&cam.eye, &ray).is_none() {
                    continue;
                }
                bowl += 1;
                let camera = view
                    .mosaic()
                    .layers()
                    .iter()
                    .any(|l| mapped(l, col, row).is_some());
                let vehicle = view.vehicle_at(col, row).is_some_and(|c| c[3] >= 128);
                if !camera && !vehicle {
                    holes += 1;
                }
            }
        }
        println!("{name}: {holes} of {bowl} pixels of the bowl show nothing");
        assert!(bowl > w * h / 3, "{name}: {bowl}");
        assert!(
            holes * 10_000 <= bowl,
            "{name}: {holes} of {bowl} pixels show nothing"
        );
        // From above, every ray descends onto the bowl (none slips past
        // the ground by rounding).
        if name == "top" {
            assert_eq!(bowl, w * h, "{name}");
        }
        assert!(view.vehicle_coverage() > 0.005, "{name}");
    }
    // From above, the vehicle's rectangle is covered opaquely.
    let view = BowlView::build(&rig, &spec, &Viewpoint::preset("top").unwrap()).unwrap();
    let cam = view.camera();
    let [x0, x1, y0, y1] = spec.vehicle_m;
    for (x, y) in [(x0 + 0.05, y0 + 0.05), (0.0, 0.0), (x1 - 0.05, y1 - 0.05)] {
        let (c, r) = cam.project(&Vector3::new(x, y, 0.0)).unwrap();
        let at = view.vehicle_at(c as usize, r as usize);
        assert!(at.is_some_and(|c| c[3] == 255), "({x}, {y}): {at:?}");
    }
}

#[test]
fn the_vehicle_is_painted_over_grey_and_colour_pictures() {
    let rig = reference_rig().unwrap();
    let spec = small();
    let view = BowlView::build(&rig, &spec, &Viewpoint::preset("top").unwrap()).unwrap();
    let [w, h] = spec.size_px;
    for ch in [1, 3] {
        let mut canvas = Canvas::new(w, h, ch);
        canvas.data.fill(255);
        view.paint_vehicle(&mut canvas).unwrap();
        let (c, r) = view.camera().project(&Vector3::new(0.0, 0.0, 1.5)).unwrap();
        let at = (r as usize * w + c as usize) * ch;
        // The roof: the body's colour, lit from above.
        assert!(
            canvas.data[at] < 250 && canvas.data[at] > 120,
            "{}",
            canvas.data[at]
        );
        // Far from the vehicle: untouched.
        assert_eq!(canvas.data[ch * 5], 255);
    }
    let mut wrong = Canvas::new(w + 1, h, 1);
    let e = view.paint_vehicle(&mut wrong).unwrap_err().to_string();
    assert!(e.contains("321×200"), "{e}");
}

/// A unit cube as a Wavefront OBJ file (y up, front along −z), its faces
/// in a red material.
fn cube_obj(dir: &std::path::Path) -> std::path::PathBuf {
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\n";
    std::fs::write(dir.join("cube.mtl"), mtl).unwrap();
    let mut obj = String::from("mtllib cube.mtl\no cube\n");
    for z in [0.0, 1.0] {
        for y in [0.0, 1.0] {
            for x in [0.0, 1.0] {
                obj += &format!("v {x} {y} {z}\n");
            }
        }
    }
    // Corners 1..8: x fastest, then y, then z; six quads.
    obj += "usemtl red\n";
    for f in [
        "1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6",
    ] {
        obj += &format!("f {f}\n");
    }
    let path = dir.join("cube.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

#[test]
fn a_users_obj_model_is_scaled_onto_the_vehicle_and_drawn() {
    let dir = std::env::temp_dir().join(format!("rigview-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = cube_obj(&dir);
    let spec = BowlSpec {
        vehicle_model: Some(path.clone()),
        ..small()
    };
    let mesh = Mesh::load_obj(&path, spec.vehicle_m, spec.vehicle_height_m).unwrap();
    assert_eq!(mesh.len(), 12);
    let rig = reference_rig().unwrap();
    let top = Viewpoint::preset("top").unwrap();
    let view = BowlView::build(&rig, &spec, &top).unwrap();
    let cam = view.camera();
    // From above the box covers the vehicle's rectangle opaquely, in its
    // material's red (lit from above).
    let [x0, x1, y0, y1] = spec.vehicle_m;
    for (x, y) in [(x0 + 0.1, y0 + 0.1), (0.0, 0.0), (x1 - 0.1, y1 - 0.1)] {
        let (c, r) = cam
            .project(&Vector3::new(x, y, spec.vehicle_height_m))
            .unwrap();
        let at = view.vehicle_at(c as usize, r as usize).unwrap();
        assert_eq!(at[3], 255, "({x}, {y}): {at:?}");
        assert!(
            at[0] > 150 && at[1] < 100 && at[2] < 100,
            "({x}, {y}): {at:?}"
        );
    }
    // Beyond the rectangle and its shadow: nothing.
    let (c, r) = cam.project(&Vector3::new(x1 + 1.0, 0.0, 0.0)).unwrap();
    assert!(view.vehicle_at(c as usize, r as usize).is_none());
    // The next viewpoint uses the model as loaded: not read again (the
    // file is gone), the same triangles; another box reads it again.
    let kept = dir.join("kept.obj");
    std::fs::rename(&path, &kept).unwrap();
    let spec_kept = BowlSpec {
        vehicle_model: Some(kept.clone()),
        ..spec.clone()
    };
    let first = BowlView::build(&rig, &spec_kept, &top).unwrap();
    std::fs::remove_file(&kept).unwrap();
    let rear = Viewpoint::preset("rear").unwrap();
    let next = BowlView::build_after(&rig, &spec_kept, &rear, true, Some(&first)).unwrap();
    let (a, b) = (first.mesh.as_ref().unwrap(), next.mesh.as_ref().unwrap());
    assert!(std::sync::Arc::ptr_eq(a, b));
    let taller = BowlSpec {
        vehicle_height_m: 2.0,
        ..spec_kept.clone()
    };
    let e = BowlView::build_after(&rig, &taller, &rear, true, Some(&first))
        .unwrap_err()
        .to_string();
    assert!(e.contains("kept.obj"), "{e}");
    // Bad files name themselves.
    let missing = dir.join("none.obj");
    let e = Mesh::load_obj(&missing, spec.vehicle_m, 1.5)
        .unwrap_err()
        .to_string();
    assert!(e.contains("none.obj"), "{e}");
    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "o nothing\nv 0 0 0\n").unwrap();
    let e = Mesh::load_obj(&empty, spec.vehicle_m, 1.5)
        .unwrap_err()
        .to_string();
    assert!(e.contains("empty.obj") && e.contains("triangles"), "{e}");
    let flat = dir.join("flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n").unwrap();
    let e = Mesh::load_obj(&flat, spec.vehicle_m, 1.5)
        .unwrap_err()
        .to_string();
    assert!(e.contains("flat.obj") && e.contains("extent"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The largest distance (source pixels) between two bowls' maps where
/// both show a pixel, and the share of the pixels only one shows.
fn map_difference(a: &BowlView, b: &BowlView) -> (f64, f64) {
    let [w, h] = a.spec().size_px;
    let (mut worst, mut differ, mut shown) = (0.0f64, 0usize, 0usize);
    for (la, lb) in a.mosaic().layers().iter().zip(b.mosaic().layers()) {
        for row in 0..h {
            for col in 0..w {
                match (mapped(la, col, row), mapped(lb, col, row)) {
                    (Some(p), Some(q)) => {
                        shown += 1;
                        worst = worst.max(f64::from(p[0] - q[0]).hypot(f64::from(p[1] - q[1])));
                    }
                    (None, None) => {}
                    _ => differ += 1,
                }
            }
        }
    }
    (worst, differ as f64 / shown.max(1) as f64)
}

/// On the real surround-nz rig, the interpolated maps stay near the exact
/// ones (every pixel cast): within their tolerance (0.1 source pixel, and
/// half a pixel for a preview) but for where the probes of a cell miss
/// its curvature.
#[test]
fn the_bowls_interpolated_maps_stay_near_the_exact_ones() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz");
    let rig = rigview_calib::formats::load(&data, None, None).unwrap().rig;
    let spec = BowlSpec {
        size_px: [480, 300],
        ..BowlSpec::around(&CanvasSpec::around_car_16x12(25.0))
    };
    let v = Viewpoint::preset("behind-left").unwrap();
    let plan = std::sync::Arc::new(GroundPlan::build(&rig, &spec).unwrap());
    let exact = BowlView::build_on_grid(&rig, &spec, &v, (1, 0.0), None, plan).unwrap();
    for (what, view, limit) in [
        ("whole", BowlView::build(&rig, &spec, &v).unwrap(), 0.1),
        (
            "preview",
            BowlView::build_preview(&rig, &spec, &v).unwrap(),
            0.8,
        ),
    ] {
        let (worst, differ) = map_difference(&view, &exact);
        eprintln!(
            "{what}: worst {worst:.3} px, {:.4} % of the pixels differ in coverage",
            100.0 * differ
        );
        assert!(worst <= limit, "{what}: {worst} px");
        assert!(differ < 1e-3, "{what}: {differ}");
    }
}

/// The bowl's seams lie where the bird's-eye view's do: in the overlaps
/// on the flat ground, each camera's blend weight in the bowl's picture is
/// the bird's-eye view's at the same ground point, from above and from an
/// oblique viewpoint alike (the distances are measured on the ground plan,
/// not on the picture, which foreshortens them).
#[test]
fn the_bowls_seams_lie_where_the_birds_eye_views_do() {
    use crate::surround::{BlendMode, SurroundOptions, SurroundView};
    let rig = reference_rig().unwrap();
    let canvas = CanvasSpec::around_car_16x12(25.0);
    let surround = SurroundView::build(&rig, &canvas, &SurroundOptions::default()).unwrap();
    let (cw, ch) = canvas.size();
    let spec = BowlSpec {
        size_px: [480, 300],
        ..BowlSpec::around(&canvas)
    };
    for name in ["top", "behind-left", "front"] {
        let v = Viewpoint::preset(name).unwrap();
        let view = BowlView::build(&rig, &spec, &v).unwrap();
        let camera = *view.camera();
        let (mut sum, mut n, mut worst) = (0.0f64, 0usize, 0.0f64);
        for r in 0..300 {
            for c in 0..480 {
                let ray = camera.ray(c as f64 + 0.5, r as f64 + 0.5);
                let Some(p) = spec.intersect(&camera.eye, &ray) else {
                    continue;
                };
                let (cc, rr) = canvas.canvas(p.x, p.y);
                if p.z > 0.0 || cc < 2.0 || rr < 2.0 || cc > cw as f64 - 3.0 || rr > ch as f64 - 3.0
                {
                    continue;
                }
                let weights = |k| view.mosaic().weight(k, BlendMode::Linear, c, r);
                if (0..4).filter(|&k| weights(k) > 0).count() < 2 {
                    continue;
                }
                // The bird's-eye view's weight at the point, bilinear over
                // its canvas's pixel centres.
                let (x, y) = (cc - 0.5, rr - 0.5);
                let (ix, iy) = (x.floor() as usize, y.floor() as usize);
                let (fx, fy) = (x - ix as f64, y - iy as f64);
                for k in 0..4 {
                    let s = |c, r| f64::from(surround.mosaic().weight(k, BlendMode::Linear, c, r));
                    let expected = (s(ix, iy) * (1.0 - fx) + s(ix + 1, iy) * fx) * (1.0 - fy)
                        + (s(ix, iy + 1) * (1.0 - fx) + s(ix + 1, iy + 1) * fx) * fy;
                    let d = (f64::from(weights(k)) - expected).abs();
                    sum += d;
                    worst = worst.max(d);
                    n += 1;
                }
            }
        }
        let mean = sum / n as f64;
        eprintln!("{name}: {n} weights in the overlaps, mean difference {mean:.2}/256, worst {worst:.0}/256");
        assert!(n > 2000, "{name}: {n}");
        assert!(mean < 3.0, "{name}: {mean}");
    }
}

/// The GPU's mesh: every vertex on the surface, with each camera's
/// projection of it through the calibration, its distance on the ground
/// plan and how far it lies beyond the camera's side; its triangles face
/// up and into the bowl, and its rings reach from the vehicle to the rim.
#[test]
fn the_gpus_mesh_carries_each_cameras_projection_and_faces_into_the_bowl() {
    let rig = reference_rig().unwrap();
    for footprint in [Footprint::RoundedRectangle, Footprint::Round] {
        let spec = BowlSpec {
            footprint,
            ..small()
        };
        let plan = GroundPlan::build(&rig, &spec).unwrap();
        let mesh = plan.mesh().unwrap();
        let cameras = mosaic::vehicle_cameras(&rig, "test").unwrap();
        let sides = Side::of_cameras(&cameras.projectors);
        let (mut nearest, mut farthest, mut outside) = (f64::MAX, 0.0f64, 0usize);
        for v in &mesh.vertices {
            let [x, y, z] = v.position.map(f64::from);
            let d = spec.footprint_distance(x, y);
            if v.beyond.iter().all(|&b| b < 0.0) && d == 0.0 {
                // Under the vehicle.
                continue;
            }
            nearest = nearest.min(d);
            farthest = farthest.max(d);
            let h = spec.height(x, y).unwrap_or(spec.wall_height_m);
            assert!((z - h).abs() < 1e-4, "({x}, {y}): z {z} against {h}");
            for (k, projector) in cameras.projectors.iter().enumerate() {
                let p = Vector3::new(x, y, z);
                let [u, w] = v.source[k].map(f64::from);
                let Some(px) = projector.project_rig(&p) else {
                    // Beyond the model's field: shown by no fragment.
                    assert!(v.beyond[k] < 0.0 && u < -1e3);
                    outside += 1;
                    continue;
                };
                assert!((u - px.x).abs() < 1e-2 && (w - px.y).abs() < 1e-2);
                let margin = sides[k].margin(&spec.vehicle_m, x, y);
                assert!((f64::from(v.beyond[k]) - margin).abs() < 1e-4);
                let d = plan.distance(k, x, y).unwrap();
                assert!((v.distance[k] - d).abs() < 1e-3 * d.max(1.0));
            }
        }
        // Most of the bowl lies within every camera's model (the rest
        // behind a fisheye).
        assert!(
            outside * 4 < mesh.vertices.len() * cameras.projectors.len(),
            "{outside}"
        );
        assert!(nearest < 1e-9 || footprint == Footprint::Round, "{nearest}");
        assert!((farthest - spec.radius_m).abs() < 1e-6, "{farthest}");
        let (mut faces, mut up, mut inward, mut wall) = (0, 0, 0, 0);
        for t in mesh.indices.chunks_exact(3) {
            let p = |i: u32| Vector3::from(mesh.vertices[i as usize].position.map(f64::from));
            let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
            let n = (b - a).cross(&(c - a));
            if n.norm() < 1e-12 {
                continue;
            }
            faces += 1;
            up += usize::from(n.z > 0.0);
            if (a.z - b.z).abs() + (a.z - c.z).abs() > 1e-6 {
                wall += 1;
                let [x0, x1, y0, y1] = spec.vehicle_m;
                let centre = Vector3::new(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0);
                let towards = centre - (a + b + c) / 3.0;
                inward += usize::from(n.x * towards.x + n.y * towards.y > 0.0);
            }
        }
        assert!(faces > 10_000 && up == faces, "{up} of {faces} face up");
        assert!(
            wall > 1000 && inward == wall,
            "{inward} of {wall} wall faces inward"
        );
    }
}

/// The next viewpoint's build takes the ground plan (and the GPU's mesh)
/// of the bowl before it; another bowl gets a plan of its own.
#[test]
fn the_ground_plan_is_built_once_per_bowl() {
    let rig = reference_rig().unwrap();
    let (top, left) = (
        Viewpoint::preset("top").unwrap(),
        Viewpoint::preset("left").unwrap(),
    );
    let a = BowlView::build(&rig, &small(), &top).unwrap();
    let b = BowlView::build_after(&rig, &small(), &left, true, Some(&a)).unwrap();
    assert!(Arc::ptr_eq(a.plan(), b.plan()));
    let wider = BowlSpec {
        flat_m: small().flat_m + 0.5,
        ..small()
    };
    let c = BowlView::build_after(&rig, &wider, &left, false, Some(&b)).unwrap();
    assert!(!Arc::ptr_eq(b.plan(), c.plan()));
    assert!(c.plan().serves(&wider) && !c.plan().serves(&small()));
}

/// A glTF wedge: a box whose top rises towards the asset's front (+z) and
/// its left (+x), under a parent node turned half round (about y) and a
/// child node moved sideways; as `.gltf` with `.bin` and as `.glb`.
fn gltf_wedge(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let mut positions = Vec::new();
    for (x, z) in [(-1.0f32, -1.0f32), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let top = 1.0 + if z > 0.0 { 1.0 } else { 0.0 } + if x > 0.0 { 0.5 } else { 0.0 };
        positions.push([x, 0.0, z]);
        positions.push([x, top, z]);
    }
    // Corners: 2k bottom, 2k + 1 top, for (x, z) in the order above.
    let quads: [[u16; 4]; 6] = [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
    ];
    let indices: Vec<u16> = quads
        .iter()
        .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
        .collect();
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let json = |buffer: &str| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"rotation":[0,1,0,0],"children":[1]}},{{"mesh":0,"translation":[5,0,0]}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.9,0.1,0.1,1.0]}}}}],
"buffers":[{{{buffer}"byteLength":{}}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":96}},{{"buffer":0,"byteOffset":96,"byteLength":72}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":8,"type":"VEC3","min":[-1,0,-1],"max":[1,2.5,1]}},
{{"bufferView":1,"componentType":5123,"count":36,"type":"SCALAR"}}]}}"#,
            bin.len()
        )
    };
    let gltf = dir.join("wedge.gltf");
    std::fs::write(&gltf, json(r#""uri":"wedge.bin","#)).unwrap();
    std::fs::write(dir.join("wedge.bin"), &bin).unwrap();
    let mut text = json("").into_bytes();
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    let mut glb = Vec::new();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&((12 + 8 + text.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend_from_slice(&(text.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&text);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);
    let glb_path = dir.join("wedge.glb");
    std::fs::write(&glb_path, glb).unwrap();
    (gltf, glb_path)
}

/// A user's glTF model: its nodes' transforms apply, its axes (y up, the
/// front along +z, the left along +x) turn into the vehicle's, it is
/// scaled onto the vehicle's box in its material's colour; a `.glb` gives
/// the same; bad files name the file and what was expected.
#[test]
fn a_users_gltf_model_is_placed_by_its_nodes_and_axes() {
    let dir = std::env::temp_dir().join(format!("rigview-gltf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (gltf, glb) = gltf_wedge(&dir);
    let spec = small();
    let [x0, x1, y0, y1] = spec.vehicle_m;
    let h = spec.vehicle_height_m;
    let a = Mesh::load(&gltf, spec.vehicle_m, h).unwrap();
    let b = Mesh::load(&glb, spec.vehicle_m, h).unwrap();
    assert_eq!(a.len(), 12);
    assert_eq!(a.triangles(), b.triangles());
    assert!(a
        .triangles()
        .iter()
        .all(|(_, c)| (c[0] - 0.9).abs() < 1e-6 && c[1] < 0.2));
    // The wedge's top rises to the asset's front left; the parent node
    // turned it half round, so it rises to the vehicle's back right.
    let top_at = |x: f64, y: f64| {
        a.triangles()
            .iter()
            .flat_map(|(t, _)| t.iter())
            .filter(|p| (p.x - x).abs() < 1e-9 && (p.y - y).abs() < 1e-9)
            .map(|p| p.z)
            .fold(f64::MIN, f64::max)
    };
    assert!(
        (top_at(x0, y0) - h).abs() < 1e-9,
        "back right {}",
        top_at(x0, y0)
    );
    assert!(
        (top_at(x1, y1) - h / 2.5).abs() < 1e-9,
        "front left {}",
        top_at(x1, y1)
    );
    assert!(
        (top_at(x1, y0) - 1.5 * h / 2.5).abs() < 1e-9,
        "front right {}",
        top_at(x1, y0)
    );
    // The bowl draws it, as it draws an OBJ model.
    let rig = reference_rig().unwrap();
    let with = BowlSpec {
        vehicle_model: Some(glb.clone()),
        ..spec.clone()
    };
    let view = BowlView::build(&rig, &with, &Viewpoint::preset("top").unwrap()).unwrap();
    let (c, r) = view.camera().project(&Vector3::new(0.0, 0.0, h)).unwrap();
    let at = view.vehicle_at(c as usize, r as usize).unwrap();
    assert!(at[3] == 255 && at[0] > 150 && at[1] < 100, "{at:?}");
    // Bad files.
    let e = |p: &std::path::Path| Mesh::load(p, spec.vehicle_m, h).unwrap_err().to_string();
    std::fs::remove_file(dir.join("wedge.bin")).unwrap();
    let msg = e(&gltf);
    assert!(
        msg.contains("wedge.gltf") && msg.contains("buffer 0") && msg.contains("wedge.bin"),
        "{msg}"
    );
    let text = std::fs::read_to_string(&gltf).unwrap();
    std::fs::write(
        &gltf,
        text.replace("wedge.bin", "data:application/octet-stream;base64,AAAA"),
    )
    .unwrap();
    let msg = e(&gltf);
    assert!(
        msg.contains("buffer 0") && msg.contains("data: URI"),
        "{msg}"
    );
    let junk = dir.join("junk.glb");
    std::fs::write(&junk, "not a model").unwrap();
    let msg = e(&junk);
    assert!(
        msg.contains("junk.glb") && msg.contains("glTF 2.0"),
        "{msg}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
