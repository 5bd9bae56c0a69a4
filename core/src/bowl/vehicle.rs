//! The vehicle in the middle of the bowl: a clean low-poly model made from
//! the rig's vehicle rectangle (body, glasshouse with windows, roof, four
//! wheels, and a shadow that covers the ground under it, which no camera
//! sees), ray cast and lit by one light from above.

use nalgebra::Vector3;

/// An axis-aligned box of the model, with its colour (linear RGB, 0–1).
#[derive(Clone, Copy, Debug)]
pub(super) struct Part {
    pub(super) min: Vector3<f64>,
    pub(super) max: Vector3<f64>,
    pub(super) colour: [f64; 3],
    /// Shadows are drawn unlit and half transparent.
    pub(super) shadow: bool,
}

/// The vehicle model: boxes and wheels within the vehicle's rectangle.
#[derive(Clone, Debug)]
pub struct VehicleModel {
    parts: Vec<Part>,
    /// Wheels: centre, radius and half width (axis along y).
    wheels: Vec<(Vector3<f64>, f64, f64)>,
}

/// The body's colour (linear RGB, 0–1), also a user's model's where its
/// file gives none.
pub(super) const BODY: [f64; 3] = [0.70, 0.74, 0.80];
const GLASS: [f64; 3] = [0.13, 0.16, 0.20];
pub(super) const TYRE: [f64; 3] = [0.08, 0.08, 0.09];
const SHADOW: [f64; 3] = [0.0, 0.0, 0.0];

/// What a ray sees of the vehicle: the distance along it, and the shaded
/// colour (RGB 0–255) with its opacity (0–255).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VehicleHit {
    /// Distance along the (unit) ray, metres.
    pub t: f64,
    /// Shaded colour.
    pub rgb: [u8; 3],
    /// Opacity.
    pub alpha: u8,
}

impl VehicleModel {
    /// The model of a vehicle on the rectangle `[x_min, x_max, y_min,
    /// y_max]` (metres, x forward), `height_m` tall.
    pub fn new(rect: [f64; 4], height_m: f64) -> Self {
        let [x0, x1, y0, y1] = rect;
        let (len, wid) = (x1 - x0, y1 - y0);
        let h = height_m;
        let v = Vector3::new;
        let wheel_r = (0.2 * h).clamp(0.1, 0.45);
        let sill = 0.55 * wheel_r;
        let belt = 0.62 * h;
        let part = |min: Vector3<f64>, max: Vector3<f64>, colour| Part {
            min,
            max,
            colour,
            shadow: false,
        };
        let parts = vec![
            // The shadow: a little larger than the body, just above the
            // ground, so that the blind area under the vehicle is covered.
            Part {
                min: v(x0 - 0.1, y0 - 0.1, 0.0),
                max: v(x1 + 0.1, y1 + 0.1, 0.005),
                colour: SHADOW,
                shadow: true,
            },
            part(v(x0, y0, sill), v(x1, y1, belt), BODY),
            // Glasshouse: windows all round, set back from the bonnet.
            part(
                v(x0 + 0.12 * len, y0 + 0.07 * wid, belt),
                v(x1 - 0.30 * len, y1 - 0.07 * wid, 0.95 * h),
                GLASS,
            ),
            // Roof.
            part(
                v(x0 + 0.15 * len, y0 + 0.09 * wid, 0.95 * h),
                v(x1 - 0.33 * len, y1 - 0.09 * wid, h),
                BODY,
            ),
        ];
        let half = 0.09 * wid;
        let wheels = [x0 + 0.18 * len, x1 - 0.2 * len]
            .into_iter()
            .flat_map(|x| {
                [y0 + half, y1 - half]
                    .into_iter()
                    .map(move |y| (v(x, y, wheel_r), wheel_r, half))
            })
            .collect();
        Self { parts, wheels }
    }

    /// What the ray `origin + t·dir` (unit `dir`) meets first of the
    /// model, if anything.
    pub fn hit(&self, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<VehicleHit> {
        let mut best: Option<(f64, Vector3<f64>, [f64; 3], bool)> = None;
        let mut consider = |t: f64, n: Vector3<f64>, colour: [f64; 3], shadow: bool| {
            if t > 0.0 && best.is_none_or(|b| t < b.0) {
                best = Some((t, n, colour, shadow));
            }
        };
        for p in &self.parts {
            if let Some((t, n)) = slab(origin, dir, &p.min, &p.max) {
                consider(t, n, p.colour, p.shadow);
            }
        }
        for &(c, r, half) in &self.wheels {
            if let Some((t, n)) = wheel(origin, dir, &c, r, half) {
                consider(t, n, TYRE, false);
            }
        }
        let (t, n, colour, shadow) = best?;
        if shadow {
            return Some(VehicleHit {
                t,
                rgb: [0, 0, 0],
                alpha: 200,
            });
        }
        let rgb = shade(colour, &n, dir).map(|v| v.round().clamp(0.0, 255.0) as u8);
        Some(VehicleHit { t, rgb, alpha: 255 })
    }

    /// Its boxes.
    pub(super) fn parts(&self) -> &[Part] {
        &self.parts
    }

    /// Its wheels: centre, radius and half width (axis along y).
    pub(super) fn wheels(&self) -> &[(Vector3<f64>, f64, f64)] {
        &self.wheels
    }

    /// The model's shadow alone: what a user's model is drawn over.
    pub fn shadow_only(&self) -> Self {
        Self {
            parts: self.parts.iter().filter(|p| p.shadow).copied().collect(),
            wheels: Vec::new(),
        }
    }
}

/// Where a ray enters an axis-aligned box, and the face's normal.
fn slab(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    min: &Vector3<f64>,
    max: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    let mut axis = 0;
    for i in 0..3 {
        if d[i].abs() < 1e-12 {
            if o[i] < min[i] || o[i] > max[i] {
                return None;
            }
            continue;
        }
        let (a, b) = ((min[i] - o[i]) / d[i], (max[i] - o[i]) / d[i]);
        let (near, far) = if a < b { (a, b) } else { (b, a) };
        if near > t0 {
            t0 = near;
            axis = i;
        }
        t1 = t1.min(far);
    }
    if t0 > t1 || t1 <= 0.0 || t0 <= 0.0 {
        return None;
    }
    let mut n = Vector3::zeros();
    n[axis] = -d[axis].signum();
    Some((t0, n))
}

/// Where a ray enters a wheel: a cylinder about the y axis through `c`,
/// radius `r`, `half` wide either side, and its normal.
fn wheel(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    c: &Vector3<f64>,
    r: f64,
    half: f64,
) -> Option<(f64, Vector3<f64>)> {
    let mut best: Option<(f64, Vector3<f64>)> = None;
    // The tread: (x − cx)² + (z − cz)² = r².
    let (ox, oz) = (o.x - c.x, o.z - c.z);
    let a = d.x * d.x + d.z * d.z;
    if a > 1e-12 {
        let b = ox * d.x + oz * d.z;
        let q = b * b - a * (ox * ox + oz * oz - r * r);
        if q >= 0.0 {
            let t = (-b - q.sqrt()) / a;
            let y = o.y + t * d.y;
            if t > 0.0 && (y - c.y).abs() <= half {
                best = Some((t, Vector3::new(ox + t * d.x, 0.0, oz + t * d.z) / r));
            }
        }
    }
    // The two sides.
    if d.y.abs() > 1e-12 {
        for side in [c.y - half, c.y + half] {
            let t = (side - o.y) / d.y;
            let (x, z) = (ox + t * d.x, oz + t * d.z);
            if t > 0.0 && x * x + z * z <= r * r && best.is_none_or(|b| t < b.0) {
                best = Some((t, Vector3::new(0.0, -d.y.signum(), 0.0)));
            }
        }
    }
    best
}

/// The colour (0–255, display gamma) of a surface of colour `base` (linear
/// RGB, 0–1) with normal `n`, seen along `view`: one light from above, a
/// little ahead and to the left, and some light from all round; either
/// side of a face is lit alike.
pub(super) fn shade(base: [f64; 3], n: &Vector3<f64>, view: &Vector3<f64>) -> [f64; 3] {
    let light = Vector3::new(0.35, 0.25, 1.0).normalize();
    let facing = if n.dot(view) > 0.0 { -n } else { *n };
    let lit = 0.4 + 0.6 * facing.dot(&light).max(0.0);
    base.map(|c| 255.0 * (c * lit).clamp(0.0, 1.0).powf(1.0 / 2.2))
}
