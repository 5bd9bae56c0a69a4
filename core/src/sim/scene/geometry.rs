//! The scene's solids: oriented boxes (buildings, walls, the bodies and
//! cabins of cars), and the rays' first hits.

use nalgebra::Vector3;

use super::shading::{AoGrid, Skin};
use super::{ObstacleKind, Scene};
use crate::error::Result;
use crate::sim::environment::EnvironmentMap;
use crate::sim::texture::{hash2, mix};

/// An oriented box standing on (or above) the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Solid {
    c: [f64; 2],
    cos: f64,
    sin: f64,
    pub(super) half: [f64; 2],
    pub(super) z0: f64,
    pub(super) z1: f64,
    pub(super) skin: Skin,
    pub(super) seed: u64,
    pub(super) ego: bool,
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

    pub(super) fn local(&self, x: f64, y: f64) -> (f64, f64) {
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

    pub(super) fn normal(&self, face: u8) -> Vector3<f64> {
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
}

/// A scene ready to trace.
#[derive(Clone, Debug)]
pub(crate) struct Built {
    pub(super) scene: Scene,
    pub(super) solids: Vec<Solid>,
    pub(super) ao: AoGrid,
    pub(super) sun_dir: Vector3<f64>,
    pub(super) sun_up: bool,
    pub(super) cos_disc: f64,
    /// A real scene's radiance map, loaded ([`crate::sim::environment`]).
    pub(super) environment: Option<std::sync::Arc<EnvironmentMap>>,
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
    /// Builds the solids of a (validated) scene and loads its environment
    /// map, if it has one (the error names the map's file).
    pub fn new(scene: &Scene) -> Result<Self> {
        let environment = match &scene.environment {
            Some(e) => Some(std::sync::Arc::new(EnvironmentMap::load(&e.file)?)),
            None => None,
        };
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
        Ok(Self {
            scene: scene.clone(),
            ao: AoGrid::new(&solids),
            solids,
            sun_dir: Vector3::new(ce * ca, ce * sa, se),
            sun_up: scene.sun.elevation_deg > 0.0,
            cos_disc: scene.sun.disc_radius_deg.to_radians().cos(),
            environment,
        })
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
    pub(super) fn shadowed(&self, p: &Vector3<f64>) -> bool {
        self.solids
            .iter()
            .any(|s| s.hit(p, &self.sun_dir, f64::INFINITY).is_some())
    }
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
}
