//! Human-readable summaries and sanity checks of a calibration (what
//! `rigview calib show` prints).

use std::fmt::Write as _;

use nalgebra::Point2;

use crate::formats::Loaded;
use crate::rig::{Camera, Frame, Rig};

/// Where a camera of a vehicle-frame rig sees the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundView {
    /// Where the image centre's ray meets the ground (x, y), metres, if it
    /// does.
    pub centre_hit_m: Option<[f64; 2]>,
    /// Nearest ground point seen, horizontal distance from the point below
    /// the camera, metres.
    pub nearest_m: f64,
    /// Farthest ground point seen within `horizon_limit_m`, metres.
    pub farthest_m: f64,
    /// The box of ground seen within the limit: x range and y range in the
    /// vehicle frame, metres.
    pub extent_m: [[f64; 2]; 2],
    /// Share of the image (sampled) that sees ground within the limit.
    pub ground_fraction: f64,
}

/// The distance up to which ground counts as seen.
pub const GROUND_LIMIT_M: f64 = 20.0;

/// Where a camera with a vehicle-frame pose sees the ground, from a 64 × 48
/// grid of its pixels; `None` if it sees none.
pub fn ground_view(camera: &Camera) -> Option<GroundView> {
    let pose = camera.pose.as_ref()?;
    let k = &camera.intrinsics;
    let foot = pose.translation();
    let (mut near, mut far) = (f64::INFINITY, 0.0_f64);
    let mut extent = [[f64::INFINITY, f64::NEG_INFINITY]; 2];
    let (nx, ny) = (64, 48);
    let mut hits = 0;
    for j in 0..ny {
        for i in 0..nx {
            let px = Point2::new(
                (f64::from(i) + 0.5) / f64::from(nx) * f64::from(k.width) - 0.5,
                (f64::from(j) + 0.5) / f64::from(ny) * f64::from(k.height) - 0.5,
            );
            let Some(g) = camera.ground_point(&px) else {
                continue;
            };
            let d = (g.x - foot.x).hypot(g.y - foot.y);
            if d > GROUND_LIMIT_M {
                continue;
            }
            hits += 1;
            near = near.min(d);
            far = far.max(d);
            for (e, v) in extent.iter_mut().zip([g.x, g.y]) {
                e[0] = e[0].min(v);
                e[1] = e[1].max(v);
            }
        }
    }
    if hits == 0 {
        return None;
    }
    let centre_hit_m = camera
        .ground_point(&Point2::new(k.cx, k.cy))
        .map(|g| [g.x, g.y]);
    Some(GroundView {
        centre_hit_m,
        nearest_m: near,
        farthest_m: far,
        extent_m: extent,
        ground_fraction: f64::from(hits) / f64::from(nx * ny),
    })
}

fn opt_deg(v: Option<f64>) -> String {
    v.map_or_else(|| "beyond the model".into(), |d| format!("{d:.1}°"))
}

/// The sanity warnings for one camera.
pub fn camera_warnings(camera: &Camera, frame: &Frame) -> Vec<String> {
    let k = &camera.intrinsics;
    let mut w = Vec::new();
    let (dx, dy) = (
        k.cx - (f64::from(k.width) - 1.0) / 2.0,
        k.cy - (f64::from(k.height) - 1.0) / 2.0,
    );
    if dx.abs() > 0.05 * f64::from(k.width) || dy.abs() > 0.05 * f64::from(k.height) {
        w.push(format!(
            "principal point is {dx:+.1}, {dy:+.1} px from the image centre (more than 5% of the image)"
        ));
    }
    if !(0.9..=1.1).contains(&(k.fx / k.fy)) {
        w.push(format!(
            "fx/fy = {:.3}: pixels far from square",
            k.fx / k.fy
        ));
    }
    let fov = k.field_of_view();
    if fov.diagonal_deg.is_none() {
        w.push(format!(
            "the image corners lie beyond where the lens model is valid ({:.1}° from the axis); pixels there have no ray",
            fov.model_limit_deg
        ));
    }
    if let (Some(p), Frame::Vehicle) = (&camera.pose, frame) {
        if p.translation().z <= 0.0 {
            w.push(format!(
                "the camera is {:.2} m below the ground",
                -p.translation().z
            ));
        } else if ground_view(camera).is_none() {
            w.push("the camera sees no ground within 20 m".into());
        }
    }
    w
}

/// A summary of a loaded calibration with its sanity checks.
pub fn summary(loaded: &Loaded) -> String {
    let rig = &loaded.rig;
    let mut s = String::new();
    let frame = match &rig.frame {
        Frame::Vehicle => "vehicle (x forward, y left, z up, ground z = 0, metres)".to_owned(),
        Frame::Camera(c) => format!("camera \"{c}\" (poses relative to it; ground unknown)"),
    };
    let _ = writeln!(s, "format: {}", loaded.format);
    let _ = writeln!(s, "cameras: {}; frame: {frame}", rig.cameras.len());
    let mut warnings = 0;
    for (i, c) in rig.cameras.iter().enumerate() {
        let k = &c.intrinsics;
        let _ = writeln!(s, "\n[{i}] {}", c.name);
        if let Some(d) = &c.device {
            let _ = writeln!(s, "  device: {d}");
        }
        let coeffs: Vec<String> = k
            .distortion
            .coefficient_names()
            .iter()
            .zip(k.distortion.coefficients())
            .map(|(n, v)| {
                // Polynomial coefficients of high order are tiny.
                if *v != 0.0 && v.abs() < 1e-5 {
                    format!("{n} {v:.6e}")
                } else {
                    format!("{n} {v:.6}")
                }
            })
            .collect();
        let _ = writeln!(
            s,
            "  model: {} {}×{}, f = ({:.2}, {:.2}) px, principal point ({:.2}, {:.2}) px, offset ({:+.2}, {:+.2}) px from centre",
            k.distortion.model_name(),
            k.width,
            k.height,
            k.fx,
            k.fy,
            k.cx,
            k.cy,
            k.cx - (f64::from(k.width) - 1.0) / 2.0,
            k.cy - (f64::from(k.height) - 1.0) / 2.0
        );
        let _ = writeln!(s, "  distortion: [{}]", coeffs.join(", "));
        let fov = k.field_of_view();
        let _ = writeln!(
            s,
            "  field of view: horizontal {}, vertical {}, diagonal {}; model valid to {:.1}° from the axis",
            opt_deg(fov.horizontal_deg),
            opt_deg(fov.vertical_deg),
            opt_deg(fov.diagonal_deg),
            fov.model_limit_deg
        );
        if let Some(p) = &c.pose {
            let t = p.translation();
            if rig.frame == Frame::Vehicle {
                let [yaw, pitch, roll] = p.ypr_deg();
                let _ = writeln!(
                    s,
                    "  pose: at ({:.3}, {:.3}, {:.3}) m, yaw {yaw:.1}°, pitch {pitch:.1}° (down), roll {roll:.1}°",
                    t.x, t.y, t.z
                );
            } else {
                let r = p.rotation().scaled_axis();
                let _ = writeln!(
                    s,
                    "  pose: at ({:.3}, {:.3}, {:.3}) m, turned {:.2}° about ({:.3}, {:.3}, {:.3})",
                    t.x,
                    t.y,
                    t.z,
                    r.norm().to_degrees(),
                    r.x / r.norm().max(1e-300),
                    r.y / r.norm().max(1e-300),
                    r.z / r.norm().max(1e-300)
                );
            }
            if rig.frame == Frame::Vehicle {
                match ground_view(c) {
                    Some(g) => {
                        let centre = g.centre_hit_m.map_or_else(
                            || "above the horizon".to_owned(),
                            |[x, y]| format!("the ground at ({x:.2}, {y:.2}) m"),
                        );
                        let _ = writeln!(
                            s,
                            "  ground: image centre looks at {centre}; sees ground from {:.2} m to {:.1} m away (limit {GROUND_LIMIT_M} m) over x {:.1}..{:.1} m, y {:.1}..{:.1} m, {:.0}% of the image",
                            g.nearest_m,
                            g.farthest_m,
                            g.extent_m[0][0],
                            g.extent_m[0][1],
                            g.extent_m[1][0],
                            g.extent_m[1][1],
                            100.0 * g.ground_fraction
                        );
                    }
                    None => {
                        let _ = writeln!(s, "  ground: none in view");
                    }
                }
            }
        } else {
            let _ = writeln!(s, "  pose: none");
        }
        let nb: Vec<&str> = rig
            .neighbours_of(i)
            .map(|j| rig.cameras[j].name.as_str())
            .collect();
        if !nb.is_empty() {
            let _ = writeln!(s, "  neighbours: {}", nb.join(", "));
        }
        for w in camera_warnings(c, &rig.frame) {
            warnings += 1;
            let _ = writeln!(s, "  warning: {w}");
        }
    }
    #[cfg(feature = "opencv")]
    if let Some(imp) = &loaded.surround {
        let _ = writeln!(
            s,
            "\nsurround layout: poses recovered from each homography's four ground points; residual on the ground (cm):"
        );
        for f in &imp.fits {
            let r: Vec<String> = f.residual_cm.iter().map(|v| format!("{v:.2}")).collect();
            let _ = writeln!(s, "  {}: {}", f.camera, r.join(", "));
        }
    }
    let _ = writeln!(s, "\n{warnings} warning(s)");
    s
}

/// Whether a rig has every pose in the vehicle frame.
pub fn has_vehicle_poses(rig: &Rig) -> bool {
    rig.frame == Frame::Vehicle && rig.cameras.iter().all(|c| c.pose.is_some())
}
