//! The simulated world: a textured ground plane with lane markings and a
//! calibration mat, textured obstacles (buildings, walls, parked cars, the
//! rig's own vehicle), a sky with a sun, and the light they receive.
//!
//! Coordinates are the rig's vehicle frame: x forward, y left, z up, ground
//! at z = 0, metres. Angles are degrees; the sun's azimuth counts from +x
//! towards +y (counter-clockwise seen from above).
//!
//! # Units of light
//!
//! Radiance is in relative units: **1 is the radiance of a white Lambertian
//! surface facing the sun at `sun.level = 1`.** Every surface point's
//! radiance is split into two parts that scale with the two light sources:
//!
//! ```text
//! L = sun_factor(t) · L_sun + sky_factor(t) · L_sky
//! L_sun = ρ · sun.level · max(0, n·s) · lit      (+ light bounced off the ground onto walls)
//! L_sky = ρ · sky.level · ao                     (ao: how much of the sky the point sees)
//! ```
//!
//! `ρ` is the reflectance, `s` the direction to the sun, `lit` 0 in a cast
//! shadow (one shadow ray per sample) and 1 in sunlight. The sky's own
//! radiance is `sky.level · (zenith + (horizon − zenith)·(1 − sin e)³)` at
//! elevation `e` (in the `L_sky` part), plus the sun's disc and the glow
//! around it (in the `L_sun` part). The scripted illumination
//! ([`super::script`]) scales the two parts over time, so a change of light
//! needs no new ray tracing.
//!
//! Ambient occlusion is analytic: a vertical face sees half the sky, a
//! ground point under a vehicle little of it, and a ground point beside an
//! obstacle loses the part of the sky the obstacle covers (its angular
//! width times `sin²` of its elevation, the cosine-weighted share).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::texture::{band, detail, fbm, hash2, mix};
use super::{check_field as check, FieldError};

/// The scene: ground, obstacles, the rig's own vehicle, sun and sky.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Seed of every texture.
    #[serde(default)]
    pub seed: u64,
    /// The ground plane.
    #[serde(default)]
    pub ground: Ground,
    /// Buildings, walls and parked cars.
    #[serde(default)]
    pub obstacles: Vec<Obstacle>,
    /// The vehicle that carries the rig (`null`: none). The cameras must be
    /// outside it.
    #[serde(default = "default_ego")]
    pub ego: Option<Ego>,
    /// The sun.
    #[serde(default)]
    pub sun: Sun,
    /// The sky.
    #[serde(default)]
    pub sky: Sky,
}

fn default_ego() -> Option<Ego> {
    Some(Ego::default())
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            seed: 0,
            ground: Ground::default(),
            obstacles: Vec::new(),
            ego: default_ego(),
            sun: Sun::default(),
            sky: Sky::default(),
        }
    }
}

/// The ground plane.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ground {
    /// The asphalt everywhere else.
    #[serde(default)]
    pub asphalt: Asphalt,
    /// Painted lines.
    #[serde(default)]
    pub lanes: Vec<Lane>,
    /// The calibration mat (`null`: none).
    #[serde(default = "default_mat")]
    pub mat: Option<Mat>,
}

fn default_mat() -> Option<Mat> {
    Some(Mat::default())
}

impl Default for Ground {
    fn default() -> Self {
        Self {
            asphalt: Asphalt::default(),
            lanes: Vec::new(),
            mat: default_mat(),
        }
    }
}

/// Asphalt: a mean reflectance, large-scale patches and fine grain.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Asphalt {
    /// Mean reflectance.
    pub reflectance: f64,
    /// Relative variation of the patches (0: uniform).
    pub variation: f64,
    /// Relative contrast of the aggregate (0: smooth).
    pub grain: f64,
    /// Size of the finest grain, metres.
    pub grain_m: f64,
}

impl Default for Asphalt {
    fn default() -> Self {
        Self {
            reflectance: 0.12,
            variation: 0.35,
            grain: 0.5,
            grain_m: 0.03,
        }
    }
}

/// A painted line on the ground, solid or dashed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Lane {
    /// Start (x, y), metres.
    pub from_m: [f64; 2],
    /// End (x, y), metres.
    pub to_m: [f64; 2],
    /// Width, metres.
    #[serde(default = "default_lane_width")]
    pub width_m: f64,
    /// Length of a dash, metres (0: a solid line).
    #[serde(default)]
    pub dash_m: f64,
    /// Gap between dashes, metres.
    #[serde(default)]
    pub gap_m: f64,
    /// Reflectance of the paint.
    #[serde(default = "default_paint")]
    pub reflectance: f64,
}

fn default_lane_width() -> f64 {
    0.15
}
fn default_paint() -> f64 {
    0.65
}

/// A calibration mat lying on the ground, laid out like the surround-view
/// mats: a `size_m` rectangle around a `hole_m` rectangle left free for the
/// vehicle; the four corner fields hold a checkerboard of `square_m`
/// squares, the bands beside the hole `circle_square_m` squares, each white
/// with a black circle, except the row next to the hole, which alternates
/// plain black and white squares.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Mat {
    /// Centre (x, y), metres.
    pub centre_m: [f64; 2],
    /// Outer size along the mat's own x and y, metres.
    pub size_m: [f64; 2],
    /// The free rectangle in the middle, metres (`[0, 0]`: none).
    pub hole_m: [f64; 2],
    /// Side of the checkerboard squares, metres.
    pub square_m: f64,
    /// Side of the circle squares, metres.
    pub circle_square_m: f64,
    /// Direction of the mat's x axis (0 = forward), degrees.
    pub yaw_deg: f64,
    /// Reflectance of black.
    pub black: f64,
    /// Reflectance of white.
    pub white: f64,
}

impl Default for Mat {
    /// The surround-view mat: 10 m × 6 m around a 5 m × 2 m car, 40 cm
    /// squares, 80 cm circle squares.
    fn default() -> Self {
        Self {
            centre_m: [0.0, 0.0],
            size_m: [10.0, 6.0],
            hole_m: [5.0, 2.0],
            square_m: 0.4,
            circle_square_m: 0.8,
            yaw_deg: 0.0,
            black: 0.05,
            white: 0.8,
        }
    }
}

/// What an obstacle is; it decides its shape and texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ObstacleKind {
    /// A block with storeys of windows and a flat roof.
    Building,
    /// A brick wall.
    Wall,
    /// A parked car: body, wheels and a glazed cabin.
    Car,
}

/// A textured obstacle standing on the ground.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Obstacle {
    /// What it is.
    pub kind: ObstacleKind,
    /// Centre of its footprint (x, y), metres.
    pub centre_m: [f64; 2],
    /// Length (along its yaw), width and height, metres.
    pub size_m: [f64; 3],
    /// Direction of its length (0 = along x), degrees.
    #[serde(default)]
    pub yaw_deg: f64,
    /// Reflectance of its walls or paint (default: by kind; a car's paint
    /// is picked from the scene's seed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reflectance: Option<f64>,
}

/// The vehicle that carries the rig: a car shape around the vehicle
/// frame's origin.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ego {
    /// Centre of its footprint (x, y), metres.
    pub centre_m: [f64; 2],
    /// Length, width and height, metres.
    pub size_m: [f64; 3],
    /// Reflectance of its paint.
    pub reflectance: f64,
}

impl Default for Ego {
    fn default() -> Self {
        Self {
            centre_m: [0.0, 0.0],
            size_m: [4.6, 1.8, 1.5],
            reflectance: 0.1,
        }
    }
}

/// The sun.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sun {
    /// Azimuth, degrees from +x towards +y.
    pub azimuth_deg: f64,
    /// Elevation above the horizon, degrees (≤ 0: no direct light).
    pub elevation_deg: f64,
    /// Radiance of a white surface facing the sun.
    pub level: f64,
    /// Radiance of the sun's disc, in units of `level`.
    pub disc: f64,
    /// Angular radius of the disc, degrees.
    pub disc_radius_deg: f64,
    /// Radiance of the sky right next to the sun, in units of `level`.
    pub glow: f64,
    /// Angle over which the glow falls by e, degrees.
    pub glow_width_deg: f64,
}

impl Default for Sun {
    fn default() -> Self {
        Self {
            azimuth_deg: -100.0,
            elevation_deg: 50.0,
            level: 1.0,
            disc: 50_000.0,
            disc_radius_deg: 0.27,
            glow: 4.0,
            glow_width_deg: 6.0,
        }
    }
}

/// The sky.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sky {
    /// Radiance of a white horizontal surface lit by the sky alone.
    pub level: f64,
    /// The sky's radiance at the horizon, in units of `level`.
    pub horizon: f64,
    /// The sky's radiance at the zenith, in units of `level`.
    pub zenith: f64,
}

impl Default for Sky {
    fn default() -> Self {
        Self {
            level: 0.1,
            horizon: 2.0,
            zenith: 0.85,
        }
    }
}

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

impl Scene {
    /// Checks every value; the error names the field (`scene.sun.level`).
    pub fn validate(&self) -> Result<(), FieldError> {
        let a = &self.ground.asphalt;
        check(
            "scene.ground.asphalt.reflectance",
            a.reflectance,
            0.0,
            1.0,
            REFLECTANCE,
        )?;
        check(
            "scene.ground.asphalt.variation",
            a.variation,
            0.0,
            1.0,
            "a relative variation in [0, 1]",
        )?;
        check(
            "scene.ground.asphalt.grain",
            a.grain,
            0.0,
            1.0,
            "a relative contrast in [0, 1]",
        )?;
        check(
            "scene.ground.asphalt.grain_m",
            a.grain_m,
            1e-4,
            10.0,
            "a grain size in metres in [0.0001, 10]",
        )?;
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
        Ok(())
    }
}

/// What a pixel sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[repr(u8)]
pub enum Class {
    /// Outside the lens's image circle or the model's valid region.
    Outside = 0,
    /// The sky.
    Sky = 1,
    /// The ground.
    Ground = 2,
    /// An obstacle.
    Obstacle = 3,
    /// The rig's own vehicle.
    Ego = 4,
}

impl Class {
    pub(crate) fn from_u8(v: u8) -> Self {
        match v {
            1 => Self::Sky,
            2 => Self::Ground,
            3 => Self::Obstacle,
            4 => Self::Ego,
            _ => Self::Outside,
        }
    }
}

/// The light a ray brings back, split by source.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Shade {
    /// The part that scales with the sun.
    pub sun: f64,
    /// The part that scales with the sky.
    pub sky: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Skin {
    Facade {
        wall: f64,
    },
    Brick {
        brick: f64,
    },
    Body {
        paint: f64,
        half_len: f64,
        bottom: f64,
    },
    Cabin {
        paint: f64,
        half_len: f64,
        half_wid: f64,
    },
}

/// An oriented box standing on (or above) the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Solid {
    c: [f64; 2],
    cos: f64,
    sin: f64,
    half: [f64; 2],
    z0: f64,
    z1: f64,
    skin: Skin,
    seed: u64,
    ego: bool,
    centre: Vector3<f64>,
    radius2: f64,
}

impl Solid {
    #[allow(clippy::too_many_arguments)]
    fn new(
        c: [f64; 2],
        yaw_deg: f64,
        half: [f64; 2],
        z0: f64,
        z1: f64,
        skin: Skin,
        seed: u64,
        ego: bool,
    ) -> Self {
        let (sin, cos) = yaw_deg.to_radians().sin_cos();
        let hz = 0.5 * (z1 - z0);
        Self {
            c,
            cos,
            sin,
            half,
            z0,
            z1,
            skin,
            seed,
            ego,
            centre: Vector3::new(c[0], c[1], 0.5 * (z0 + z1)),
            radius2: half[0] * half[0] + half[1] * half[1] + hz * hz,
        }
    }

    fn local(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.c[0], y - self.c[1]);
        (
            self.cos * dx + self.sin * dy,
            -self.sin * dx + self.cos * dy,
        )
    }

    fn contains(&self, p: &Vector3<f64>) -> bool {
        let (lx, ly) = self.local(p.x, p.y);
        lx.abs() < self.half[0] && ly.abs() < self.half[1] && p.z > self.z0 && p.z < self.z1
    }

    /// The entry distance and face (0 +x, 1 −x, 2 +y, 3 −y, 4 top,
    /// 5 bottom) of a ray, if it enters within `(eps, t_max)`.
    fn hit(&self, o: &Vector3<f64>, d: &Vector3<f64>, t_max: f64) -> Option<(f64, u8)> {
        // Bounding sphere first.
        let v = self.centre - o;
        let tc = v.dot(d);
        let dist2 = v.norm_squared() - tc * tc;
        if dist2 > self.radius2 {
            return None;
        }
        let r = self.radius2.sqrt();
        if tc + r < 0.0 || tc - r > t_max {
            return None;
        }
        let (ox, oy) = self.local(o.x, o.y);
        let dx = self.cos * d.x + self.sin * d.y;
        let dy = -self.sin * d.x + self.cos * d.y;
        let mut t0 = f64::NEG_INFINITY;
        let mut t1 = f64::INFINITY;
        let mut face = 0u8;
        for (axis, (o, d, lo, hi)) in [
            (ox, dx, -self.half[0], self.half[0]),
            (oy, dy, -self.half[1], self.half[1]),
            (o.z, d.z, self.z0, self.z1),
        ]
        .into_iter()
        .enumerate()
        {
            if d.abs() < 1e-15 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            // Entering through the low side means the face whose normal
            // points to −axis.
            let (near, far, f) = if a < b {
                (a, b, 2 * axis as u8 + 1)
            } else {
                (b, a, 2 * axis as u8)
            };
            if near > t0 {
                t0 = near;
                face = f;
            }
            t1 = t1.min(far);
        }
        (t0 <= t1 && t0 > 1e-9 && t0 < t_max).then_some((t0, face))
    }

    fn normal(&self, face: u8) -> Vector3<f64> {
        let (c, s) = (self.cos, self.sin);
        match face {
            0 => Vector3::new(c, s, 0.0),
            1 => Vector3::new(-c, -s, 0.0),
            2 => Vector3::new(-s, c, 0.0),
            3 => Vector3::new(s, -c, 0.0),
            4 => Vector3::z(),
            _ => -Vector3::z(),
        }
    }

    /// Reflectance at a point of a face, from the face's own coordinates,
    /// and the share of the light that reaches it (below 1 in recesses such
    /// as open doorways).
    fn reflectance(&self, face: u8, p: &Vector3<f64>, fp: f64) -> (f64, f64) {
        let rho = self.texture(face, p, fp);
        match self.skin {
            // Open doorways in every second bay of the ground floor: the dark
            // inside of the building (reflectance 0.03), which 1 % of the
            // light outside reaches.
            Skin::Facade { .. } if face < 4 => {
                let (lx, ly) = self.local(p.x, p.y);
                let u = if face < 2 { ly } else { lx };
                let open = band(u, 5.6, 0.2, 2.4, fp) * band(p.z, 1e3, 0.0, 2.6, fp);
                (rho + (0.03 - rho) * open, 1.0 - 0.99 * open)
            }
            _ => (rho, 1.0),
        }
    }

    fn texture(&self, face: u8, p: &Vector3<f64>, fp: f64) -> f64 {
        let (lx, ly) = self.local(p.x, p.y);
        // u runs along the face, v up it (metres).
        let (u, v) = match face {
            0 | 1 => (ly, p.z),
            2 | 3 => (lx, p.z),
            _ => (lx, ly),
        };
        let side = face < 4;
        let s = self.seed;
        match self.skin {
            Skin::Facade { wall } => {
                if !side {
                    return 0.15 * (1.0 + 0.2 * fbm(s, u, v, 2.0, 3, fp));
                }
                let w = wall * (1.0 + 0.15 * fbm(s, u, v, 1.0, 4, fp));
                // Storeys of 3.2 m with 1.6 m × 1.7 m windows in 2.8 m bays,
                // the ground floor without.
                let glazing = if v > 3.2 {
                    band(u, 2.8, 0.6, 1.6, fp) * band(v, 3.2, 0.9, 1.7, fp)
                } else {
                    0.0
                };
                let pane =
                    0.04 + 0.05 * hash2(s, (u / 2.8).floor() as i64, (v / 3.2).floor() as i64);
                w + (pane - w) * glazing
            }
            Skin::Brick { brick } => {
                if !side {
                    return brick * 1.3;
                }
                // Running bond: 23.5 cm × 7.5 cm courses with 1 cm mortar.
                let course = (v / 0.075).floor();
                let shift = if course as i64 % 2 == 0 { 0.0 } else { 0.1175 };
                let uu = u + shift;
                let id = (uu / 0.235).floor();
                let var = 0.6 * (hash2(s, id as i64, course as i64) - 0.5) * detail(fp, 0.075);
                let b = brick * (1.0 + var) * (1.0 + 0.1 * fbm(s, u, v, 0.5, 3, fp));
                let mortar = band(v, 0.075, 0.0, 0.01, fp).max(band(uu, 0.235, 0.0, 0.01, fp));
                b + (0.45 - b) * mortar
            }
            Skin::Body {
                paint,
                half_len,
                bottom,
            } => {
                let p = paint * (1.0 + 0.05 * fbm(s, u, v, 0.5, 2, fp));
                match face {
                    2 | 3 => {
                        // Wheels of 0.33 m radius at ±0.3 of the length.
                        let wx = 0.6 * half_len;
                        let (du, dv) = ((u.abs() - wx).abs(), v - 0.33);
                        if du * du + dv * dv < 0.33 * 0.33 {
                            0.03
                        } else {
                            p
                        }
                    }
                    0 | 1 => {
                        // A dark grille just above the bumper.
                        let g = band(v, 1e3, bottom + 0.15, 0.2, fp);
                        p + (0.05 - p) * g
                    }
                    _ => p,
                }
            }
            Skin::Cabin {
                paint,
                half_len,
                half_wid,
            } => {
                if !side {
                    return paint;
                }
                let half = if face < 2 { half_wid } else { half_len };
                // Glass, with pillars at the ends (and in the middle of the
                // sides).
                let pillar = u.abs() > half - 0.12 || (face >= 2 && u.abs() < 0.06);
                if pillar {
                    paint
                } else {
                    0.04
                }
            }
        }
    }
}

/// A scene ready to trace.
#[derive(Clone, Debug)]
pub(crate) struct Built {
    scene: Scene,
    solids: Vec<Solid>,
    ao: AoGrid,
    sun_dir: Vector3<f64>,
    sun_up: bool,
    cos_disc: f64,
}

/// What a ray hit first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Hit {
    Sky,
    Ground(f64),
    Solid(f64, usize, u8),
}

fn car_solids(
    centre: [f64; 2],
    size: [f64; 3],
    yaw_deg: f64,
    paint: f64,
    seed: u64,
    ego: bool,
) -> [Solid; 2] {
    let [l, w, h] = size;
    let bottom = 0.18 * h;
    let belt = 0.65 * h;
    let (s, c) = yaw_deg.to_radians().sin_cos();
    // The cabin sits a little behind the middle.
    let back = -0.05 * l;
    let cabin_c = [centre[0] + c * back, centre[1] + s * back];
    [
        Solid::new(
            centre,
            yaw_deg,
            [0.5 * l, 0.5 * w],
            bottom,
            belt,
            Skin::Body {
                paint,
                half_len: 0.5 * l,
                bottom,
            },
            seed,
            ego,
        ),
        Solid::new(
            cabin_c,
            yaw_deg,
            [0.275 * l, 0.46 * w],
            belt,
            h,
            Skin::Cabin {
                paint,
                half_len: 0.275 * l,
                half_wid: 0.46 * w,
            },
            seed,
            ego,
        ),
    ]
}

impl Built {
    /// Builds the solids of a (validated) scene.
    pub fn new(scene: &Scene) -> Self {
        let mut solids = Vec::new();
        for (k, o) in scene.obstacles.iter().enumerate() {
            let seed = mix(scene.seed ^ mix(k as u64 + 1));
            let [l, w, h] = o.size_m;
            match o.kind {
                ObstacleKind::Building => solids.push(Solid::new(
                    o.centre_m,
                    o.yaw_deg,
                    [0.5 * l, 0.5 * w],
                    0.0,
                    h,
                    Skin::Facade {
                        wall: o.reflectance.unwrap_or(0.35),
                    },
                    seed,
                    false,
                )),
                ObstacleKind::Wall => solids.push(Solid::new(
                    o.centre_m,
                    o.yaw_deg,
                    [0.5 * l, 0.5 * w],
                    0.0,
                    h,
                    Skin::Brick {
                        brick: o.reflectance.unwrap_or(0.22),
                    },
                    seed,
                    false,
                )),
                ObstacleKind::Car => {
                    let paint = o
                        .reflectance
                        .unwrap_or_else(|| 0.04 + 0.66 * hash2(seed, 7, 11).powf(1.5));
                    solids.extend(car_solids(
                        o.centre_m, o.size_m, o.yaw_deg, paint, seed, false,
                    ));
                }
            }
        }
        if let Some(e) = &scene.ego {
            solids.extend(car_solids(
                e.centre_m,
                e.size_m,
                0.0,
                e.reflectance,
                mix(scene.seed ^ 0xe90),
                true,
            ));
        }
        let (se, ce) = scene.sun.elevation_deg.to_radians().sin_cos();
        let (sa, ca) = scene.sun.azimuth_deg.to_radians().sin_cos();
        Self {
            scene: scene.clone(),
            ao: AoGrid::new(&solids),
            solids,
            sun_dir: Vector3::new(ce * ca, ce * sa, se),
            sun_up: scene.sun.elevation_deg > 0.0,
            cos_disc: scene.sun.disc_radius_deg.to_radians().cos(),
        }
    }

    /// The unit vector towards the sun.
    pub fn sun_dir(&self) -> Vector3<f64> {
        self.sun_dir
    }

    /// Whether a point lies inside an obstacle or the vehicle.
    pub fn inside(&self, p: &Vector3<f64>) -> bool {
        self.solids.iter().any(|s| s.contains(p))
    }

    /// The first thing a ray from `o` along unit `d` hits.
    pub fn first_hit(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Hit {
        let mut best = if d.z < -1e-12 && o.z > 0.0 {
            Hit::Ground(-o.z / d.z)
        } else {
            Hit::Sky
        };
        let mut t_best = match best {
            Hit::Ground(t) => t,
            _ => f64::INFINITY,
        };
        for (k, s) in self.solids.iter().enumerate() {
            if let Some((t, face)) = s.hit(o, d, t_best) {
                t_best = t;
                best = Hit::Solid(t, k, face);
            }
        }
        best
    }

    /// Whether a point's path to the sun is blocked.
    fn shadowed(&self, p: &Vector3<f64>) -> bool {
        self.solids
            .iter()
            .any(|s| s.hit(p, &self.sun_dir, f64::INFINITY).is_some())
    }

    fn sky_radiance(&self, d: &Vector3<f64>) -> Shade {
        let sky = &self.scene.sky;
        let e = d.z.clamp(0.0, 1.0);
        let shape = sky.zenith + (sky.horizon - sky.zenith) * (1.0 - e).powi(3);
        let mut sun = 0.0;
        if self.sun_up {
            let c = d.dot(&self.sun_dir).clamp(-1.0, 1.0);
            let sn = &self.scene.sun;
            let angle = c.acos().to_degrees();
            sun = sn.level * sn.glow * (-angle / sn.glow_width_deg).exp();
            if c >= self.cos_disc {
                sun += sn.level * sn.disc;
            }
        }
        Shade {
            sun,
            sky: sky.level * shape,
        }
    }

    /// The share of the sky a ground point sees: from the grid near the
    /// rig, computed further out.
    fn ground_ao(&self, x: f64, y: f64) -> f64 {
        self.ao
            .at(x, y)
            .unwrap_or_else(|| ao_at(&self.solids, x, y))
    }

    /// The reflectance of the ground at (x, y) for a pixel footprint `fp`.
    fn ground_reflectance(&self, x: f64, y: f64, fp: f64) -> f64 {
        let g = &self.scene.ground;
        if let Some(m) = &g.mat {
            if let Some(r) = mat_reflectance(m, x, y) {
                // Creases and dirt on the cloth.
                return r * (1.0 + 0.06 * fbm(self.scene.seed ^ 0x3a, x, y, 0.5, 3, fp));
            }
        }
        let a = &g.asphalt;
        let seed = self.scene.seed;
        // Patches from 2 m down to 12 cm, and the aggregate from 4 grains
        // down to one.
        let patches = fbm(seed, x, y, 2.0, 5, fp);
        let grain = fbm(seed ^ 0xa5, x, y, 4.0 * a.grain_m, 3, fp);
        let mut r = a.reflectance * (1.0 + a.variation * patches) * (1.0 + a.grain * grain);
        for l in &g.lanes {
            let cover = lane_cover(l, x, y, fp);
            if cover > 0.0 {
                let paint = l.reflectance * (1.0 + 0.1 * fbm(seed ^ 0x1a, x, y, 0.3, 2, fp));
                r += (paint - r) * cover;
            }
        }
        r.clamp(0.005, 0.98)
    }

    /// Traces one ray: what it sees and the light it brings back. `pixel`
    /// is the angle one sample spans, radians (for texture filtering).
    pub fn shade(&self, o: &Vector3<f64>, d: &Vector3<f64>, pixel: f64) -> (Shade, Class) {
        let level = self.scene.sun.level;
        let sky_level = self.scene.sky.level;
        match self.first_hit(o, d) {
            Hit::Sky => (self.sky_radiance(d), Class::Sky),
            Hit::Ground(t) => {
                let p = o + d * t;
                let fp = t * pixel / d.z.abs().max(0.05);
                let rho = self.ground_reflectance(p.x, p.y, fp);
                let lift = p + Vector3::z() * 1e-6;
                let lit = self.sun_up && !self.shadowed(&lift);
                let sun = if lit {
                    rho * level * self.sun_dir.z
                } else {
                    0.0
                };
                let sky = rho * sky_level * self.ground_ao(p.x, p.y);
                (Shade { sun, sky }, Class::Ground)
            }
            Hit::Solid(t, k, face) => {
                let s = &self.solids[k];
                let p = o + d * t;
                let n = s.normal(face);
                let fp = t * pixel / n.dot(d).abs().max(0.05);
                let (rho, light) = s.reflectance(face, &p, fp);
                let rho = rho * light;
                let cos = n.dot(&self.sun_dir);
                let lift = p + n * 1e-6;
                let lit = self.sun_up && cos > 0.0 && light > 0.5 && !self.shadowed(&lift);
                let ground_albedo = self.scene.ground.asphalt.reflectance;
                let (ao, bounce) = match face {
                    4 => (1.0, 0.0),
                    5 => (0.1, 0.5),
                    _ => (0.5, 0.5),
                };
                let sun_on_ground = if self.sun_up { self.sun_dir.z } else { 0.0 };
                let mut sun = rho * level * bounce * ground_albedo * sun_on_ground;
                if lit {
                    sun += rho * level * cos;
                }
                let sky = rho * sky_level * (ao + bounce * ground_albedo);
                let class = if s.ego { Class::Ego } else { Class::Obstacle };
                (Shade { sun, sky }, class)
            }
        }
    }
}

/// The share of the sky a ground point sees, with the obstacles and
/// vehicles around it (see the module documentation).
fn ao_at(solids: &[Solid], x: f64, y: f64) -> f64 {
    let mut ao = 1.0;
    for s in solids {
        let (lx, ly) = s.local(x, y);
        let (ex, ey) = (lx.abs() - s.half[0], ly.abs() - s.half[1]);
        if ex < 0.0 && ey < 0.0 {
            if s.z0 > 0.0 {
                // Under a vehicle: dark, lighter towards its edges.
                let edge = -ex.max(ey);
                ao *= 0.03 + 0.47 * (-edge / (1.5 * s.z0)).exp();
            } else {
                ao = 0.0;
            }
            continue;
        }
        let (ex, ey) = (ex.max(0.0), ey.max(0.0));
        let d2 = ex * ex + ey * ey;
        let h2 = s.z1 * s.z1;
        // The cosine-weighted share of the sky below the obstacle's top
        // edge, sin² of its elevation.
        let below = h2 / (h2 + d2);
        if below < 1e-4 {
            continue;
        }
        let r2 = s.half[0] * s.half[0] + s.half[1] * s.half[1];
        let dc2 = (lx * lx + ly * ly).max(1e-18);
        let width = 2.0 * (r2 / dc2).min(1.0).sqrt().asin();
        let blocked = width / std::f64::consts::TAU * below;
        ao *= 1.0 - blocked.min(0.95);
    }
    ao
}

/// [`ao_at`] on a grid around the rig, interpolated bilinearly.
#[derive(Clone, Debug)]
struct AoGrid {
    values: Vec<f32>,
}

impl AoGrid {
    /// Half the side of the grid, metres.
    const HALF: f64 = 25.0;
    /// Grid step, metres.
    const STEP: f64 = 0.2;

    fn nodes() -> usize {
        (2.0 * Self::HALF / Self::STEP).round() as usize + 1
    }

    fn new(solids: &[Solid]) -> Self {
        let n = Self::nodes();
        let values = (0..n * n)
            .map(|k| {
                let (i, j) = (k % n, k / n);
                let x = -Self::HALF + i as f64 * Self::STEP;
                let y = -Self::HALF + j as f64 * Self::STEP;
                ao_at(solids, x, y) as f32
            })
            .collect();
        Self { values }
    }

    fn at(&self, x: f64, y: f64) -> Option<f64> {
        let n = Self::nodes();
        let (fx, fy) = ((x + Self::HALF) / Self::STEP, (y + Self::HALF) / Self::STEP);
        if !(fx >= 0.0 && fy >= 0.0 && fx < (n - 1) as f64 && fy < (n - 1) as f64) {
            return None;
        }
        let (i, j) = (fx as usize, fy as usize);
        let (tx, ty) = (fx - i as f64, fy - j as f64);
        let v = |i: usize, j: usize| f64::from(self.values[j * n + i]);
        let top = v(i, j) + (v(i + 1, j) - v(i, j)) * tx;
        let bottom = v(i, j + 1) + (v(i + 1, j + 1) - v(i, j + 1)) * tx;
        Some(top + (bottom - top) * ty)
    }
}

/// The share of a footprint `fp` wide, centred `d` from the axis of a
/// stripe `half` wide on each side, that falls on the stripe.
fn box_cover(d: f64, half: f64, fp: f64) -> f64 {
    if fp < 1e-9 {
        return f64::from(u8::from(d.abs() <= half));
    }
    let lo = (d - 0.5 * fp).max(-half);
    let hi = (d + 0.5 * fp).min(half);
    ((hi - lo) / fp).clamp(0.0, 1.0)
}

fn lane_cover(l: &Lane, x: f64, y: f64, fp: f64) -> f64 {
    let (ax, ay) = (l.to_m[0] - l.from_m[0], l.to_m[1] - l.from_m[1]);
    let len = (ax * ax + ay * ay).sqrt();
    if len < 1e-9 {
        return 0.0;
    }
    let (ux, uy) = (ax / len, ay / len);
    let (px, py) = (x - l.from_m[0], y - l.from_m[1]);
    let along = px * ux + py * uy;
    let across = -px * uy + py * ux;
    let half = 0.5 * l.width_m;
    if across.abs() > half + fp || along < -fp || along > len + fp {
        return 0.0;
    }
    let mut c = box_cover(across, half, fp) * box_cover(along - 0.5 * len, 0.5 * len, fp);
    if l.dash_m > 0.0 {
        c *= band(along, l.dash_m + l.gap_m, 0.0, l.dash_m, fp);
    }
    c
}

/// The mat's reflectance at (x, y), `None` off the mat.
pub(crate) fn mat_reflectance(m: &Mat, x: f64, y: f64) -> Option<f64> {
    let (s, c) = m.yaw_deg.to_radians().sin_cos();
    let (dx, dy) = (x - m.centre_m[0], y - m.centre_m[1]);
    let (mx, my) = (c * dx + s * dy, -s * dx + c * dy);
    let (lx, ly) = (0.5 * m.size_m[0], 0.5 * m.size_m[1]);
    let (hx, hy) = (0.5 * m.hole_m[0], 0.5 * m.hole_m[1]);
    if mx.abs() >= lx || my.abs() >= ly || (mx.abs() < hx && my.abs() < hy) {
        return None;
    }
    let black = if mx.abs() >= hx && my.abs() >= hy {
        // The corner fields: a checkerboard from the mat's outer corner.
        let i = ((mx + lx) / m.square_m).floor() as i64;
        let j = ((my + ly) / m.square_m).floor() as i64;
        (i + j).rem_euclid(2) == 0
    } else {
        // The bands beside the hole: cells counted outwards from the hole.
        let (along, out) = if my.abs() >= hy {
            (mx + hx, my.abs() - hy)
        } else {
            (my + hy, mx.abs() - hx)
        };
        let cell = m.circle_square_m;
        let (i, j) = ((along / cell).floor(), (out / cell).floor());
        let (fu, fv) = (along / cell - i - 0.5, out / cell - j - 0.5);
        if (j + 1.0) * cell > (if my.abs() >= hy { ly - hy } else { lx - hx }) + 1e-9 {
            // A partial cell at the outer edge stays white.
            false
        } else if j < 0.5 {
            (i as i64).rem_euclid(2) == 0
        } else {
            fu * fu + fv * fv < 0.35 * 0.35
        }
    };
    Some(if black { m.black } else { m.white })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_entered_through_the_right_face() {
        let s = Solid::new(
            [5.0, 0.0],
            0.0,
            [1.0, 2.0],
            0.0,
            3.0,
            Skin::Brick { brick: 0.2 },
            1,
            false,
        );
        let o = Vector3::new(0.0, 0.0, 1.0);
        let (t, face) = s.hit(&o, &Vector3::x(), f64::INFINITY).unwrap();
        assert!((t - 4.0).abs() < 1e-12);
        assert_eq!(face, 1);
        assert_eq!(s.normal(face), Vector3::new(-1.0, -0.0, 0.0));
        assert!(s.hit(&o, &-Vector3::x(), f64::INFINITY).is_none());
        assert!(s.hit(&o, &Vector3::x(), 3.0).is_none());
        let down = Vector3::new(0.0, 0.0, -1.0);
        let (t, face) = s.hit(&Vector3::new(5.0, 0.0, 10.0), &down, 100.0).unwrap();
        assert!((t - 7.0).abs() < 1e-12);
        assert_eq!(face, 4);
        // Turned by 90°, the box is 4 m long in x.
        let r = Solid::new(
            [5.0, 0.0],
            90.0,
            [1.0, 2.0],
            0.0,
            3.0,
            Skin::Brick { brick: 0.2 },
            1,
            false,
        );
        let (t, _) = r.hit(&o, &Vector3::x(), f64::INFINITY).unwrap();
        assert!((t - 3.0).abs() < 1e-9);
    }

    #[test]
    fn the_default_mat_has_the_surround_view_layout() {
        let m = Mat::default();
        // Off the mat, in the hole.
        assert_eq!(mat_reflectance(&m, 5.1, 0.0), None);
        assert_eq!(mat_reflectance(&m, 0.0, 0.0), None);
        // The front-left corner field: square (0, 0) counted from the
        // mat's corner (−5, −3) is black, its neighbours white, 40 cm on.
        assert_eq!(mat_reflectance(&m, -4.8, -2.8), Some(m.black));
        assert_eq!(mat_reflectance(&m, -4.4, -2.8), Some(m.white));
        assert_eq!(mat_reflectance(&m, 4.8, 2.8), Some(m.black));
        // The band beside the hole: a circle in the middle of a cell of the
        // second row, white at its corner.
        let centre = (0.4 - 2.5 + 1e-3, 1.0 + 0.8 + 0.4);
        assert_eq!(mat_reflectance(&m, centre.0, centre.1), Some(m.black));
        assert_eq!(
            mat_reflectance(&m, centre.0 - 0.35, centre.1 - 0.35),
            Some(m.white)
        );
    }

    #[test]
    fn a_wall_casts_a_shadow_and_the_sky_is_brighter_near_the_sun() {
        let scene = Scene {
            ego: None,
            ground: Ground {
                mat: None,
                ..Default::default()
            },
            obstacles: vec![Obstacle {
                kind: ObstacleKind::Wall,
                centre_m: [0.0, -3.0],
                size_m: [20.0, 0.3, 3.0],
                yaw_deg: 0.0,
                reflectance: None,
            }],
            sun: Sun {
                azimuth_deg: -90.0,
                elevation_deg: 45.0,
                ..Default::default()
            },
            ..Default::default()
        };
        let b = Built::new(&scene);
        let eye = Vector3::new(0.0, 0.0, 1.0);
        let at = |y: f64| {
            let d = (Vector3::new(0.0, y, 0.0) - eye).normalize();
            b.shade(&eye, &d, 1e-3)
        };
        // The sun comes from −y over the wall: the ground just behind it
        // (y = −1) is in shadow, further on (y = 3) it is lit.
        let (shadow, c1) = at(-1.0);
        let (lit, c2) = at(3.0);
        assert_eq!((c1, c2), (Class::Ground, Class::Ground));
        assert!(shadow.sun.abs() < 1e-12 && shadow.sky > 0.0);
        assert!(lit.sun > 0.0);
        let toward_sun = b.sun_dir();
        let away = Vector3::new(0.0, 1.0, 0.3).normalize();
        let (near, _) = b.shade(&eye, &toward_sun, 1e-3);
        let (far, _) = b.shade(&eye, &away, 1e-3);
        assert!(near.sun > 1000.0 * far.sun.max(1e-9));
    }
}
