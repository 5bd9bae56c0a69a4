//! The bowl's surface: a height field over the ground, flat near the
//! vehicle and rising beyond, and where a ray meets it.

use nalgebra::Vector3;

use super::{BowlSpec, Footprint};

/// Samples along a ray before the crossing is bisected. A ray from inside
/// the bowl crosses the surface once, so the first sample below it
/// brackets the crossing; only a ray grazing the wall could dip below and
/// out again between two samples.
const MARCH_STEPS: usize = 32;
/// The search in the bracket stops when it is this long, relative to the
/// distance along the ray.
const TOLERANCE: f64 = 1e-10;

impl BowlSpec {
    /// The horizontal distance of ground point `(x, y)` from where the
    /// footprint is measured: from the vehicle's rectangle (0 on it) for
    /// the rounded rectangle, from its centre for the round footprint.
    pub fn footprint_distance(&self, x: f64, y: f64) -> f64 {
        let [x0, x1, y0, y1] = self.vehicle_m;
        match self.footprint {
            Footprint::RoundedRectangle => {
                let dx = (x0 - x).max(x - x1).max(0.0);
                let dy = (y0 - y).max(y - y1).max(0.0);
                dx.hypot(dy)
            }
            Footprint::Round => (x - 0.5 * (x0 + x1)).hypot(y - 0.5 * (y0 + y1)),
        }
    }

    /// The surface's height at `(x, y)`: 0 on the flat part, then
    /// `wall_height_m · ((d − flat_m)/(radius_m − flat_m))^steepness` up to
    /// `radius_m`; `None` beyond the rim.
    pub fn height(&self, x: f64, y: f64) -> Option<f64> {
        let d = self.footprint_distance(x, y);
        if d <= self.flat_m {
            Some(0.0)
        } else if d <= self.radius_m {
            let u = (d - self.flat_m) / (self.radius_m - self.flat_m);
            // Whole exponents (the default 2) without `powf`.
            let curve = if self.steepness.fract() == 0.0 {
                u.powi(self.steepness as i32)
            } else {
                u.powf(self.steepness)
            };
            Some(self.wall_height_m * curve)
        } else {
            None
        }
    }

    /// The first point where the ray `origin + t·dir` (t > 0) meets the
    /// surface from above, or `None` if it leaves over the rim. From an
    /// origin beyond the rim, the wall's outside lets the ray through (as
    /// a renderer culls the faces turned away), so the inside shows.
    pub fn intersect(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<Vector3<f64>> {
        // How far the ray's point at t lies above the surface; once the
        // ray has been inside the rim, beyond it counts as the wall's
        // height (the ray cannot pass the rim below its height without
        // crossing the wall first), so that no crossing near the rim falls
        // between two samples unseen.
        let above = |t: f64, entered: bool| {
            let p = origin + dir * t;
            match self.height(p.x, p.y) {
                Some(h) => Some(p.z - h),
                None if entered => Some(p.z - self.wall_height_m),
                None => None,
            }
        };
        // The ray meets z = 0 at t_ground if it descends, and the surface
        // (never below the ground) no later; otherwise it may meet the wall
        // before it passes the rim, which lies within `reach` of the origin
        // horizontally.
        let horizontal = dir.x.hypot(dir.y);
        let t_end = if dir.z < 0.0 {
            // A hair past the ground, so that the last sample is below it
            // whatever the rounding.
            -origin.z / dir.z * (1.0 + 1e-9) + 1e-9
        } else if horizontal > 0.0 {
            let [x0, x1, y0, y1] = self.vehicle_m;
            let half_diagonal = 0.5 * (x1 - x0).hypot(y1 - y0);
            let from_centre = (origin.x - 0.5 * (x0 + x1)).hypot(origin.y - 0.5 * (y0 + y1));
            (from_centre + self.radius_m + half_diagonal) / horizontal
        } else {
            return None;
        };
        if !(t_end.is_finite() && t_end > 0.0) {
            return None;
        }
        // From over the flat part, a descending ray meets the ground where
        // it reaches z = 0 if that is on the flat part too: the distance
        // from a convex footprint is convex along the ray, so it stays
        // within the flat part between the two, where the surface is the
        // ground.
        let flat = |x: f64, y: f64| self.footprint_distance(x, y) <= self.flat_m;
        if dir.z < 0.0 && origin.z > 0.0 && flat(origin.x, origin.y) {
            let p = origin + dir * (-origin.z / dir.z);
            if flat(p.x, p.y) {
                return Some(Vector3::new(p.x, p.y, 0.0));
            }
        }
        let mut entered = self.height(origin.x, origin.y).is_some();
        let mut t_prev = 0.0;
        for i in 1..=MARCH_STEPS {
            let t = t_end * i as f64 / MARCH_STEPS as f64;
            if above(t, entered).is_some_and(|v| v <= 0.0) {
                // Regula falsi (the Illinois variant) between the last
                // sample above (or beyond the rim) and this one: the
                // distance above the surface is smooth there.
                let (mut lo, mut hi) = (t_prev, t);
                let (mut f_lo, mut f_hi) = (
                    above(lo, entered).unwrap_or(f64::INFINITY),
                    above(hi, entered).unwrap_or(0.0),
                );
                let mut side = 0;
                for _ in 0..100 {
                    if hi - lo <= TOLERANCE * hi {
                        break;
                    }
                    let mid = if f_lo.is_finite() && f_lo > f_hi {
                        (lo + (hi - lo) * f_lo / (f_lo - f_hi)).clamp(lo, hi)
                    } else {
                        0.5 * (lo + hi)
                    };
                    match above(mid, entered) {
                        Some(v) if v <= 0.0 => {
                            (hi, f_hi) = (mid, v);
                            if side == -1 {
                                f_lo *= 0.5;
                            }
                            side = -1;
                        }
                        v => {
                            (lo, f_lo) = (mid, v.unwrap_or(f64::INFINITY));
                            if side == 1 {
                                f_hi *= 0.5;
                            }
                            side = 1;
                        }
                    }
                }
                let p = origin + dir * hi;
                // On the flat part, exactly on the ground.
                let z = self.height(p.x, p.y)?;
                return Some(Vector3::new(p.x, p.y, z));
            }
            let p = origin + dir * t;
            entered |= self.height(p.x, p.y).is_some();
            t_prev = t;
        }
        None
    }
}
