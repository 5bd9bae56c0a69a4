//! Checks of a scene description: every value in its range, the error
//! naming the field.

use super::{Asphalt, Scene};
use crate::sim::{check_field as check, FieldError};

fn check_point(field: String, p: &[f64]) -> Result<(), FieldError> {
    match p.iter().find(|v| !(v.is_finite() && v.abs() <= 1e4)) {
        None => Ok(()),
        Some(v) => Err(FieldError::new(
            field,
            "coordinates in metres within ±10 km",
            format!("{v}"),
        )),
    }
}

const REFLECTANCE: &str = "a reflectance in [0, 1]";

/// Checks an asphalt-like surface whose fields are `{prefix}.reflectance`…
fn check_surface(prefix: &str, a: &Asphalt) -> Result<(), FieldError> {
    let at = |f: &str| format!("{prefix}.{f}");
    check(at("reflectance"), a.reflectance, 0.0, 1.0, REFLECTANCE)?;
    check(
        at("variation"),
        a.variation,
        0.0,
        1.0,
        "a relative variation in [0, 1]",
    )?;
    check(
        at("grain"),
        a.grain,
        0.0,
        1.0,
        "a relative contrast in [0, 1]",
    )?;
    check(
        at("grain_m"),
        a.grain_m,
        1e-4,
        10.0,
        "a grain size in metres in [0.0001, 10]",
    )
}

impl Scene {
    /// Checks every value; the error names the field (`scene.sun.level`).
    pub fn validate(&self) -> Result<(), FieldError> {
        check_surface("scene.ground.asphalt", &self.ground.asphalt)?;
        for (k, p) in self.ground.patches.iter().enumerate() {
            let at = |f: &str| format!("scene.ground.patches[{k}].{f}");
            check_point(at("centre_m"), &p.centre_m)?;
            for (i, &s) in p.size_m.iter().enumerate() {
                check(
                    format!("scene.ground.patches[{k}].size_m[{i}]"),
                    s,
                    0.01,
                    1e4,
                    "a size in metres in [0.01, 10000]",
                )?;
            }
            check(
                at("yaw_deg"),
                p.yaw_deg,
                -360.0,
                360.0,
                "an angle in degrees",
            )?;
            check_surface(&format!("scene.ground.patches[{k}].surface"), &p.surface)?;
            check(
                at("sun"),
                p.sun,
                0.0,
                1.0,
                "a share of the sunlight in [0, 1]",
            )?;
            check(
                at("sky"),
                p.sky,
                0.0,
                1.0,
                "a share of the skylight in [0, 1]",
            )?;
        }
        for (k, l) in self.ground.lanes.iter().enumerate() {
            let at = |f: &str| format!("scene.ground.lanes[{k}].{f}");
            check_point(at("from_m"), &l.from_m)?;
            check_point(at("to_m"), &l.to_m)?;
            check(
                at("width_m"),
                l.width_m,
                1e-3,
                10.0,
                "a width in metres in (0, 10]",
            )?;
            check(
                at("dash_m"),
                l.dash_m,
                0.0,
                1e3,
                "a dash length ≥ 0 (0: solid)",
            )?;
            check(at("gap_m"), l.gap_m, 0.0, 1e3, "a gap length ≥ 0")?;
            check(at("reflectance"), l.reflectance, 0.0, 1.0, REFLECTANCE)?;
            if l.dash_m > 0.0 && l.gap_m <= 0.0 {
                return Err(FieldError::new(
                    at("gap_m"),
                    "a positive gap for a dashed line",
                    format!("{}", l.gap_m),
                ));
            }
        }
        if let Some(m) = &self.ground.mat {
            let at = |f: &str| format!("scene.ground.mat.{f}");
            check_point(at("centre_m"), &m.centre_m)?;
            for (i, (&s, &h)) in m.size_m.iter().zip(&m.hole_m).enumerate() {
                check(
                    format!("scene.ground.mat.size_m[{i}]"),
                    s,
                    0.1,
                    1e3,
                    "a size in metres in [0.1, 1000]",
                )?;
                check(
                    format!("scene.ground.mat.hole_m[{i}]"),
                    h,
                    0.0,
                    s,
                    "a hole no larger than the mat",
                )?;
            }
            check(
                at("square_m"),
                m.square_m,
                0.01,
                10.0,
                "a square side in metres in [0.01, 10]",
            )?;
            check(
                at("circle_square_m"),
                m.circle_square_m,
                0.01,
                10.0,
                "a square side in metres in [0.01, 10]",
            )?;
            check(
                at("yaw_deg"),
                m.yaw_deg,
                -360.0,
                360.0,
                "an angle in degrees",
            )?;
            check(at("black"), m.black, 0.0, 1.0, REFLECTANCE)?;
            check(at("white"), m.white, 0.0, 1.0, REFLECTANCE)?;
        }
        for (k, o) in self.obstacles.iter().enumerate() {
            let at = |f: &str| format!("scene.obstacles[{k}].{f}");
            check_point(at("centre_m"), &o.centre_m)?;
            for (i, &s) in o.size_m.iter().enumerate() {
                check(
                    format!("scene.obstacles[{k}].size_m[{i}]"),
                    s,
                    0.01,
                    1e3,
                    "a size in metres in [0.01, 1000]",
                )?;
            }
            check(
                at("yaw_deg"),
                o.yaw_deg,
                -360.0,
                360.0,
                "an angle in degrees",
            )?;
            if let Some(r) = o.reflectance {
                check(at("reflectance"), r, 0.0, 1.0, REFLECTANCE)?;
            }
        }
        if let Some(e) = &self.ego {
            check_point("scene.ego.centre_m".into(), &e.centre_m)?;
            for (i, &s) in e.size_m.iter().enumerate() {
                check(
                    format!("scene.ego.size_m[{i}]"),
                    s,
                    0.1,
                    100.0,
                    "a size in metres in [0.1, 100]",
                )?;
            }
            check(
                "scene.ego.reflectance",
                e.reflectance,
                0.0,
                1.0,
                REFLECTANCE,
            )?;
        }
        let s = &self.sun;
        check(
            "scene.sun.azimuth_deg",
            s.azimuth_deg,
            -360.0,
            360.0,
            "an angle in degrees",
        )?;
        check(
            "scene.sun.elevation_deg",
            s.elevation_deg,
            -90.0,
            90.0,
            "an elevation in degrees in [-90, 90]",
        )?;
        check("scene.sun.level", s.level, 0.0, 1e6, "a radiance level ≥ 0")?;
        check(
            "scene.sun.disc",
            s.disc,
            0.0,
            1e9,
            "a relative radiance ≥ 0",
        )?;
        check(
            "scene.sun.disc_radius_deg",
            s.disc_radius_deg,
            0.0,
            10.0,
            "an angle in degrees in [0, 10]",
        )?;
        check(
            "scene.sun.glow",
            s.glow,
            0.0,
            1e6,
            "a relative radiance ≥ 0",
        )?;
        check(
            "scene.sun.glow_width_deg",
            s.glow_width_deg,
            0.01,
            180.0,
            "an angle in degrees in (0, 180]",
        )?;
        let k = &self.sky;
        check("scene.sky.level", k.level, 0.0, 1e6, "a radiance level ≥ 0")?;
        check(
            "scene.sky.horizon",
            k.horizon,
            0.0,
            1e3,
            "a relative radiance ≥ 0",
        )?;
        check(
            "scene.sky.zenith",
            k.zenith,
            0.0,
            1e3,
            "a relative radiance ≥ 0",
        )?;
        if let Some(e) = &self.environment {
            check(
                "scene.environment.level",
                e.level,
                1e-9,
                1e9,
                "a positive factor on the map's radiance",
            )?;
            check(
                "scene.environment.yaw_deg",
                e.yaw_deg,
                -360.0,
                360.0,
                "an angle in degrees in [-360, 360]",
            )?;
            check(
                "scene.environment.height_m",
                e.height_m,
                0.05,
                100.0,
                "a height in metres in [0.05, 100]",
            )?;
            if !self.obstacles.is_empty() {
                return Err(FieldError::new(
                    "scene.obstacles",
                    "none with an environment map (the map holds the scene's solids)",
                    format!("{} obstacles", self.obstacles.len()),
                ));
            }
        }
        Ok(())
    }
}
