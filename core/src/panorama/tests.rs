use nalgebra::Vector3;
use rigview_calib::pose::Pose;
use rigview_calib::rig::{Camera, Frame};

use super::*;
use crate::surround::tests::fisheye_185;
use crate::surround::BlendMode;

/// Four 185° equidistant fisheyes with `w×h` images on a car, turned to
/// `yaws` (degrees) and tilted down by 15° to 30°.
fn rig(w: u32, h: u32, yaws: [f64; 4]) -> Rig {
    let intrinsics = fisheye_185(w, h);
    let names = ["front", "left", "back", "right"];
    let places = [
        [2.3, 0.0, 0.9],
        [1.0, 0.95, 1.0],
        [-2.3, 0.0, 1.0],
        [1.0, -0.95, 1.0],
    ];
    let pitches = [15.0, 30.0, 20.0, 30.0];
    let cameras = (0..4)
        .map(|k| {
            let mut c = Camera::new(names[k], intrinsics);
            c.pose = Some(
                Pose::from_ypr_deg([yaws[k], pitches[k], 0.0], Vector3::from(places[k])).unwrap(),
            );
            c
        })
        .collect();
    Rig::new(
        Frame::Vehicle,
        cameras,
        vec![(0, 1), (1, 2), (2, 3), (0, 3)],
    )
    .unwrap()
}

fn small_spec() -> CylinderSpec {
    CylinderSpec {
        width: 720,
        height: 140,
        ..CylinderSpec::default()
    }
}

#[test]
fn bad_specs_are_refused_with_the_field() {
    assert!(CylinderSpec::default().validate().is_ok());
    let ok = CylinderSpec::default();
    let cases = [
        (
            CylinderSpec {
                radius_m: f64::NAN,
                ..ok.clone()
            },
            "panorama.radius_m",
        ),
        (
            CylinderSpec {
                width: 3,
                ..ok.clone()
            },
            "panorama.width",
        ),
        (
            CylinderSpec {
                above_deg: -30.0,
                ..ok.clone()
            },
            "is empty",
        ),
        (
            CylinderSpec {
                below_deg: 95.0,
                ..ok.clone()
            },
            "panorama.below_deg",
        ),
    ];
    for (spec, field) in cases {
        let e = spec.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e} should name {field}");
    }
}

#[test]
fn canvas_positions_and_directions_are_inverse() {
    let s = CylinderSpec::default();
    for (col, row) in [
        (0.5, 0.5),
        (1000.25, 300.0),
        (4095.5, 759.5),
        (2048.0, 380.0),
    ] {
        let (c, r) = s.canvas(s.azimuth(col), s.slope(row));
        assert!(
            (c - col).abs() < 1e-9 && (r - row).abs() < 1e-9,
            "{col},{row} -> {c},{r}"
        );
    }
    // The front in the middle, the left side left of it; the band's edges.
    assert!(s.azimuth(2048.0).abs() < 1e-12);
    assert!((s.azimuth(1024.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    assert!((s.slope(0.0) - 35f64.to_radians().tan()).abs() < 1e-12);
    assert!((s.slope(760.0) + 25f64.to_radians().tan()).abs() < 1e-12);
}

#[test]
fn every_map_position_sees_its_canvas_pixel() {
    // A canvas pixel's source position in a camera, unprojected and met
    // with the cylinder, is the canvas pixel again: the maps project the
    // cylinder's points with the full pose. Every pixel projected exactly
    // (grid 1): the interpolation of the default build is bounded against
    // these maps in `surround::grid`'s tests.
    // With a floor too: the ground inside the radius.
    let rig = rig(160, 120, [0.0, 90.0, 180.0, -90.0]);
    for floor in [false, true] {
        let spec = CylinderSpec {
            floor,
            ..small_spec()
        };
        let pano = Panorama::build_on_grid(&rig, &spec, &PanoramaOptions::default(), 1).unwrap();
        let (w, _) = pano.size();
        let mut checked = 0;
        for (k, layer) in pano.layers().iter().enumerate() {
            let projector = rig.cameras[k].projector().unwrap();
            let [c0, r0, rw, _] = layer.roi;
            for (j, &[x, y]) in layer.map.iter().enumerate().step_by(7) {
                if x < 0.0 {
                    continue;
                }
                let (col, row) = ((c0 + j % rw) as f64 + 0.5, (r0 + j / rw) as f64 + 0.5);
                let px = Point2::new(f64::from(x), f64::from(y));
                let (c, r) = pano.canvas_of_pixel(&projector, &px).unwrap();
                // f32 positions: within a few thousandths of a pixel, the
                // column modulo the width.
                let dc = (c - col).rem_euclid(w as f64);
                let dc = dc.min(w as f64 - dc);
                assert!(
                    dc < 0.01 && (r - row).abs() < 0.01,
                    "{k}: {col},{row} -> {c},{r}"
                );
                checked += 1;
            }
        }
        assert!(checked > 1000, "{checked}");
    }
}

#[test]
fn the_cylinder_is_covered_with_weights_summing_to_256() {
    let rig = rig(160, 120, [0.0, 90.0, 180.0, -90.0]);
    let pano = Panorama::build(&rig, &small_spec(), &PanoramaOptions::default()).unwrap();
    let (w, h) = pano.size();
    for mode in BlendMode::ALL {
        let mut covered = 0;
        for r in 0..h {
            for c in 0..w {
                let sum: u32 = (0..4).map(|k| u32::from(pano.weight(k, mode, c, r))).sum();
                assert!(sum == 0 || sum == 256, "{} at {c},{r}: {sum}", mode.name());
                covered += usize::from(sum == 256);
            }
        }
        // The horizon row is seen all round.
        assert!(
            (0..w).all(|c| (0..4).any(|k| pano.weight(k, mode, c, h / 2) > 0)),
            "{}",
            mode.name()
        );
        assert!(covered > w * h * 3 / 4, "{} {covered}", mode.name());
    }
    // Each overlap is about 30° wide, on the horizon.
    for o in pano.overlaps() {
        let row = h / 2;
        let both = (0..w)
            .filter(|&c| pano.weight(o.i, BlendMode::Alpha, c, row) > 0)
            .filter(|&c| pano.weight(o.j, BlendMode::Alpha, c, row) > 0)
            .count() as f64;
        let deg = both * 360.0 / w as f64;
        assert!((deg - 30.0).abs() < 1.5, "{}–{}: {deg}°", o.i, o.j);
        assert!(!o.patches.is_empty());
    }
    // The metered pixels are the ones that reach the cylinder: none where
    // the band does not reach (the bottom of a camera looking down).
    for (k, mask) in pano.source_masks().iter().enumerate() {
        let coverage = mask.coverage();
        assert!(coverage > 0.1 && coverage < 0.99, "{k}: {coverage}");
    }
}

#[test]
fn neighbours_that_share_no_pixel_are_an_error_naming_them() {
    // The left camera turned to look forward right, between the front and
    // right cameras: those two, neighbours in the rig, no longer meet.
    let rig = rig(160, 120, [0.0, -45.0, 180.0, -90.0]);
    let e = Panorama::build(
        &rig,
        &small_spec(),
        &PanoramaOptions {
            overlap_deg: 5.0,
            ..PanoramaOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("`front` and `right`") && e.contains("share no pixel"),
        "{e}"
    );
}

#[test]
fn cylinder_hits_are_on_the_cylinder_ahead_of_the_ray() {
    let o = Vector3::new(1.0, -0.5, 0.3);
    for d in [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(-0.3, 0.8, -0.2),
        Vector3::new(0.0, -1.0, 0.5),
    ] {
        let q = cylinder_hit(&o, &d, 10.0).unwrap();
        assert!((q.x.hypot(q.y) - 10.0).abs() < 1e-9);
        assert!((q - o).dot(&d) > 0.0);
    }
    assert!(cylinder_hit(&o, &Vector3::new(0.0, 0.0, -1.0), 10.0).is_none());
}

#[test]
fn the_floor_is_the_ground_inside_the_radius_and_rays_find_it_again() {
    let surface = |floor| Surface {
        centre: Vector3::new(0.2, 0.0, 1.0),
        radius: 10.0,
        floor,
    };
    let (co, si) = (0.6f64, 0.8f64);
    // 20° below the horizon: the ground 2.75 m out with a floor, the
    // cylinder under the ground without.
    let t = -20f64.to_radians().tan();
    let p = surface(true).point(co, si, t);
    assert!(p.z.abs() < 1e-12, "{p}");
    assert!(((p - surface(true).centre).xy().norm() - 1.0 / 20f64.to_radians().tan()).abs() < 1e-9);
    assert!(surface(false).point(co, si, t).z < -2.0);
    // 3° below: the centre's ray meets the ground beyond the radius, so the
    // wall shows it, above the ground.
    let wall = surface(true).point(co, si, -3f64.to_radians().tan());
    assert!(wall.z > 0.0 && ((wall - surface(true).centre).xy().norm() - 10.0).abs() < 1e-9);
    // A ray from a camera through a point of the surface finds it again.
    let camera = Vector3::new(2.3, 0.4, 0.9);
    for q in [p, wall, surface(true).point(co, si, 0.2)] {
        let hit = surface(true)
            .hit(&camera, &(q - camera).normalize())
            .unwrap();
        assert!(
            (hit + surface(true).centre - q).norm() < 1e-9,
            "{q} -> {hit}"
        );
    }
}
