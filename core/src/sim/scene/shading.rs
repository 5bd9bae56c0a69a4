//! What the rays bring back: the textures of the ground, the mat and the
//! solids, the sun and the sky, shadows and ambient occlusion (see the
//! module documentation of [`super`]).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::geometry::{Built, Hit, Solid};
use super::{Lane, Mat};
use crate::sim::texture::{band, detail, fbm, hash2};

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

/// How a solid's faces look.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Skin {
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

impl Solid {
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

impl Built {
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

    /// The reflectance of the ground at (x, y) for a pixel footprint `fp`,
    /// and the shares of the sun's and the sky's light that reach it (below
    /// 1 on a patch in shade).
    fn ground_reflectance(&self, x: f64, y: f64, fp: f64) -> (f64, f64, f64) {
        let g = &self.scene.ground;
        let patch = g.patches.iter().rev().find(|p| p.contains(x, y));
        let (sun, sky) = patch.map_or((1.0, 1.0), |p| (p.sun, p.sky));
        if let Some(m) = &g.mat {
            if let Some(r) = mat_reflectance(m, x, y) {
                // Creases and dirt on the cloth.
                let r = r * (1.0 + 0.06 * fbm(self.scene.seed ^ 0x3a, x, y, 0.5, 3, fp));
                return (r, sun, sky);
            }
        }
        let a = patch.map_or(&g.asphalt, |p| &p.surface);
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
        (r.clamp(0.005, 0.98), sun, sky)
    }

    /// Traces one ray: what it sees and the light it brings back. `pixel`
    /// is the angle one sample spans, radians (for texture filtering).
    pub fn shade(&self, o: &Vector3<f64>, d: &Vector3<f64>, pixel: f64) -> (Shade, Class) {
        let level = self.scene.sun.level;
        let sky_level = self.scene.sky.level;
        let hit = self.first_hit(o, d);
        if let (Some(map), Some(e)) = (&self.environment, &self.scene.environment) {
            // A real scene: the map's radiance in the ray's direction, or
            // in the direction the panorama saw the ground point from.
            let yaw = e.yaw_deg.to_radians();
            let seen = match hit {
                Hit::Sky => Some((*d, Class::Sky)),
                Hit::Ground(t) => Some((o + d * t - Vector3::z() * e.height_m, Class::Ground)),
                Hit::Solid(..) => None,
            };
            if let Some((dir, class)) = seen {
                let sky = e.level * map.radiance(&dir, yaw);
                return (Shade { sun: 0.0, sky }, class);
            }
        }
        match hit {
            Hit::Sky => (self.sky_radiance(d), Class::Sky),
            Hit::Ground(t) => {
                let p = o + d * t;
                let fp = t * pixel / d.z.abs().max(0.05);
                let (rho, sun_share, sky_share) = self.ground_reflectance(p.x, p.y, fp);
                let lift = p + Vector3::z() * 1e-6;
                let lit = self.sun_up && sun_share > 0.0 && !self.shadowed(&lift);
                let sun = if lit {
                    rho * sun_share * level * self.sun_dir.z
                } else {
                    0.0
                };
                let sky = rho * sky_share * sky_level * self.ground_ao(p.x, p.y);
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
pub(super) struct AoGrid {
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

    pub(super) fn new(solids: &[Solid]) -> Self {
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
    use super::super::{Asphalt, Ground, Obstacle, ObstacleKind, Patch, Scene, Sun};
    use super::*;

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
    fn a_patch_has_its_own_surface_and_light() {
        let shade = |patches: Vec<Patch>| {
            let scene = Scene {
                ego: None,
                ground: Ground {
                    mat: None,
                    patches,
                    ..Default::default()
                },
                ..Default::default()
            };
            let b = Built::new(&scene).expect("a scene without a map");
            let eye = Vector3::new(0.0, 0.0, 1.0);
            let d = (Vector3::new(2.0, 0.0, 0.0) - eye).normalize();
            let (s, class) = b.shade(&eye, &d, 1e-3);
            assert_eq!(class, Class::Ground);
            s
        };
        let bare = shade(Vec::new());
        let snow = Asphalt {
            reflectance: 0.9,
            variation: 0.0,
            grain: 0.0,
            grain_m: 0.03,
        };
        let patch = |centre_m: [f64; 2], sun: f64, sky: f64| Patch {
            centre_m,
            size_m: [2.0, 1.0],
            yaw_deg: 0.0,
            surface: snow,
            sun,
            sky,
        };
        // (2, 0) on a snow patch in full light: the reflectance is the
        // snow's, 0.9, against about 0.12 for the asphalt.
        let lit = shade(vec![patch([2.0, 0.0], 1.0, 1.0)]);
        assert!(
            lit.sun > 4.0 * bare.sun && lit.sky > 4.0 * bare.sky,
            "{lit:?} {bare:?}"
        );
        let ratio = lit.sky / lit.sun;
        assert!((ratio - bare.sky / bare.sun).abs() < 1e-9);
        // In shade: no sun, a tenth of the sky.
        let dark = shade(vec![patch([2.0, 0.0], 0.0, 0.1)]);
        assert!(dark.sun.abs() < 1e-15);
        assert!((dark.sky - 0.1 * lit.sky).abs() < 1e-12);
        // A patch elsewhere changes nothing; a later patch covers an
        // earlier one.
        assert_eq!(shade(vec![patch([6.0, 0.0], 1.0, 1.0)]), bare);
        let later = shade(vec![
            patch([2.0, 0.0], 0.0, 0.1),
            patch([2.0, 0.0], 1.0, 1.0),
        ]);
        assert_eq!(later, lit);
        let turned = Patch {
            yaw_deg: 90.0,
            ..patch([2.0, 0.0], 1.0, 1.0)
        };
        assert!(turned.contains(2.0, 0.9) && !turned.contains(2.9, 0.0));
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
        let b = Built::new(&scene).expect("a scene without a map");
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
