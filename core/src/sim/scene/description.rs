//! What a scene holds, as simulation files describe it.

use serde::{Deserialize, Serialize};

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
    /// A real scene: an HDR panorama's radiance in place of the ground and
    /// the sky (`null`: none; see [`crate::sim::environment`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<Environment>,
}

/// A real scene's radiance map and how it lies around the rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Environment {
    /// The equirectangular radiance map (Radiance `.hdr`); a relative path
    /// is taken from the simulation file's folder.
    pub file: std::path::PathBuf,
    /// Multiplies the map's values into the scene's unit of radiance.
    #[serde(default = "default_env_level")]
    pub level: f64,
    /// The azimuth the map's centre column looks along, degrees from +x
    /// towards +y.
    #[serde(default)]
    pub yaw_deg: f64,
    /// How high above the ground the panorama was taken, metres.
    #[serde(default = "default_env_height")]
    pub height_m: f64,
}

fn default_env_level() -> f64 {
    1.0
}

fn default_env_height() -> f64 {
    1.7
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
            environment: None,
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
    /// Regions of the ground with a surface and a light of their own (snow,
    /// grass, the shade of trees, the inside of a tunnel), over the asphalt
    /// and under the lanes and the mat; a later patch covers an earlier one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub patches: Vec<Patch>,
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
            patches: Vec::new(),
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

/// A rectangle of the ground with its own surface (textured as asphalt
/// is, from its own reflectance, patches and grain) and its own share of
/// the sun's and the sky's light: 0 sun for the shade of trees or a roof,
/// a small sky share for the inside of a tunnel. It needs no geometry, so
/// nothing else (walls, cars) is darkened by it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Patch {
    /// Centre (x, y), metres.
    pub centre_m: [f64; 2],
    /// Size along the patch's own x and y, metres.
    pub size_m: [f64; 2],
    /// Direction of the patch's x axis (0 = forward), degrees.
    #[serde(default)]
    pub yaw_deg: f64,
    /// The surface.
    #[serde(default)]
    pub surface: Asphalt,
    /// The share of direct sunlight that reaches it, in [0, 1].
    #[serde(default = "one")]
    pub sun: f64,
    /// The share of skylight that reaches it, in [0, 1].
    #[serde(default = "one")]
    pub sky: f64,
}

fn one() -> f64 {
    1.0
}

impl Patch {
    /// Whether (x, y) lies on the patch.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let (s, c) = self.yaw_deg.to_radians().sin_cos();
        let (dx, dy) = (x - self.centre_m[0], y - self.centre_m[1]);
        let (px, py) = (c * dx + s * dy, -s * dx + c * dy);
        px.abs() <= 0.5 * self.size_m[0] && py.abs() <= 0.5 * self.size_m[1]
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
