//! Where the bowl is seen from: an orbit about a point of the vehicle
//! (azimuth, elevation, distance and field of view), its presets, and the
//! virtual pinhole camera it gives.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::error::{check_range, Error, Result};

/// A viewpoint: the virtual camera at `distance_m` from `target_m`, in the
/// direction of azimuth `yaw_deg` (0: ahead of the vehicle, 90: to its
/// left, 180: behind) and elevation `pitch_deg` (90: straight above),
/// looking at `target_m`, with a vertical field of view `fov_deg`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Viewpoint {
    /// The point looked at, vehicle frame, metres.
    pub target_m: [f64; 3],
    /// Azimuth of the eye about the target, degrees from the vehicle's
    /// forward axis towards its left.
    pub yaw_deg: f64,
    /// Elevation of the eye above the target, degrees (−10 to 90).
    pub pitch_deg: f64,
    /// Distance of the eye from the target, metres.
    pub distance_m: f64,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
}

/// The named viewpoints, in the order the window offers them.
pub const PRESETS: [&str; 7] = [
    "top",
    "rear",
    "front",
    "behind-left",
    "behind-right",
    "left",
    "right",
];

impl Default for Viewpoint {
    /// Behind and to the left, as a driver looks back over the shoulder.
    fn default() -> Self {
        Self::preset("behind-left").unwrap_or(Self::TOP)
    }
}

impl Viewpoint {
    const TOP: Self = Self {
        target_m: [0.0, 0.0, 0.0],
        yaw_deg: 180.0,
        pitch_deg: 90.0,
        distance_m: 11.0,
        fov_deg: 60.0,
    };

    /// The preset `name` (one of [`PRESETS`]).
    pub fn preset(name: &str) -> Result<Self> {
        let around = |yaw_deg: f64, pitch_deg: f64, distance_m: f64| Self {
            target_m: [0.0, 0.0, 0.5],
            yaw_deg,
            pitch_deg,
            distance_m,
            fov_deg: 65.0,
        };
        // Beside a door, at door height, looking across the vehicle.
        let door = |yaw_deg: f64| Self {
            target_m: [0.0, 0.0, 0.8],
            yaw_deg,
            pitch_deg: 8.0,
            distance_m: 4.5,
            fov_deg: 75.0,
        };
        Ok(match name {
            "top" => Self::TOP,
            "rear" => around(180.0, 32.0, 8.0),
            "front" => around(0.0, 32.0, 8.0),
            "behind-left" => around(145.0, 30.0, 8.0),
            "behind-right" => around(-145.0, 30.0, 8.0),
            "left" => door(90.0),
            "right" => door(-90.0),
            _ => {
                return Err(Error::invalid(
                    "bowl view",
                    "viewpoint",
                    format!("one of {}", PRESETS.join(", ")),
                    name,
                ))
            }
        })
    }

    /// Checks the numbers: finite, an elevation of −10° to 90°, a distance
    /// of 0.5 to 100 m, a field of view of 10° to 150°.
    pub fn validate(&self) -> Result<()> {
        for v in self.target_m {
            check_range("viewpoint.target_m", v, -1e3, 1e3, "within 1 km")?;
        }
        check_range(
            "viewpoint.yaw_deg",
            self.yaw_deg,
            -1e6,
            1e6,
            "a finite angle",
        )?;
        check_range(
            "viewpoint.pitch_deg",
            self.pitch_deg,
            -10.0,
            90.0,
            "−10° to 90°",
        )?;
        check_range(
            "viewpoint.distance_m",
            self.distance_m,
            0.5,
            100.0,
            "0.5 to 100 m",
        )?;
        check_range(
            "viewpoint.fov_deg",
            self.fov_deg,
            10.0,
            150.0,
            "10° to 150°",
        )?;
        Ok(())
    }

    /// The eye's position, vehicle frame.
    pub fn eye(&self) -> Vector3<f64> {
        let (yaw, pitch) = (self.yaw_deg.to_radians(), self.pitch_deg.to_radians());
        Vector3::from(self.target_m)
            + Vector3::new(
                pitch.cos() * yaw.cos(),
                pitch.cos() * yaw.sin(),
                pitch.sin(),
            ) * self.distance_m
    }

    /// The viewpoint a fraction `s` (0 to 1) of the way from `self` to
    /// `to`, along the shorter way round in azimuth, eased at both ends:
    /// what the window shows while a change of viewpoint animates.
    pub fn towards(&self, to: &Self, s: f64) -> Self {
        let s = s.clamp(0.0, 1.0);
        let e = s * s * (3.0 - 2.0 * s);
        let lerp = |a: f64, b: f64| a + (b - a) * e;
        let turn = (to.yaw_deg - self.yaw_deg + 180.0).rem_euclid(360.0) - 180.0;
        Self {
            target_m: std::array::from_fn(|i| lerp(self.target_m[i], to.target_m[i])),
            yaw_deg: self.yaw_deg + turn * e,
            pitch_deg: lerp(self.pitch_deg, to.pitch_deg),
            distance_m: lerp(self.distance_m, to.distance_m),
            fov_deg: lerp(self.fov_deg, to.fov_deg),
        }
    }

    /// The viewpoint after a drag of `(dx, dy)` degrees (orbit: azimuth and
    /// elevation, the elevation kept within its range) and a zoom by
    /// `factor` (distance divided by it, within its range).
    pub fn orbited(&self, dx: f64, dy: f64, factor: f64) -> Self {
        Self {
            yaw_deg: (self.yaw_deg + dx + 180.0).rem_euclid(360.0) - 180.0,
            pitch_deg: (self.pitch_deg + dy).clamp(-10.0, 90.0),
            distance_m: (self.distance_m / factor.max(1e-3)).clamp(0.5, 100.0),
            ..*self
        }
    }

    /// The virtual camera of this viewpoint for an image of `width` ×
    /// `height` pixels.
    pub fn camera(&self, width: usize, height: usize) -> VirtualCamera {
        let eye = self.eye();
        let forward = (Vector3::from(self.target_m) - eye).normalize();
        // Straight down, the image's up is the vehicle's forward axis
        // turned by the azimuth (so that the top view from behind shows the
        // front up); otherwise the world's up.
        let yaw = self.yaw_deg.to_radians();
        let world_up = if forward.z.abs() > 1.0 - 1e-9 {
            -Vector3::new(yaw.cos(), yaw.sin(), 0.0)
        } else {
            Vector3::z()
        };
        let right = forward.cross(&world_up).normalize();
        let up = right.cross(&forward);
        let focal = 0.5 * height as f64 / (0.5 * self.fov_deg.to_radians()).tan();
        VirtualCamera {
            eye,
            forward,
            right,
            up,
            focal,
            centre: (0.5 * width as f64, 0.5 * height as f64),
        }
    }
}

/// A pinhole camera at the viewpoint: image x along `right`, y down.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualCamera {
    /// The centre of projection, vehicle frame.
    pub eye: Vector3<f64>,
    /// The optical axis.
    pub forward: Vector3<f64>,
    /// The image's x axis.
    pub right: Vector3<f64>,
    /// The image's up (its y axis points the other way).
    pub up: Vector3<f64>,
    /// The focal length, pixels.
    pub focal: f64,
    /// The principal point (column, row), pixels.
    pub centre: (f64, f64),
}

impl VirtualCamera {
    /// The ray (unit direction) through image position (column, row).
    pub fn ray(&self, col: f64, row: f64) -> Vector3<f64> {
        (self.forward * self.focal + self.right * (col - self.centre.0)
            - self.up * (row - self.centre.1))
            .normalize()
    }

    /// The image position (column, row) of a point in front of the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        let d = p - self.eye;
        let z = d.dot(&self.forward);
        (z > 1e-9).then(|| {
            (
                self.centre.0 + self.focal * d.dot(&self.right) / z,
                self.centre.1 - self.focal * d.dot(&self.up) / z,
            )
        })
    }
}
