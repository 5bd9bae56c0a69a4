//! The rig: named cameras with their device ids, intrinsics and poses, and
//! the neighbour graph of which cameras overlap.

use std::fmt;
use std::net::IpAddr;

use nalgebra::{Point2, Vector3};

use crate::error::FieldError;
use crate::model::{Intrinsics, Projector};
use crate::pose::Pose;

/// How to reach a camera.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DeviceId {
    /// A GenICam device id (as Aravis lists it, e.g. `Basler-21234567`).
    GenICam(String),
    /// An IP address (GigE Vision).
    Ip(IpAddr),
}

impl fmt::Display for DeviceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DeviceId::GenICam(s) => write!(f, "GenICam {s}"),
            DeviceId::Ip(ip) => write!(f, "IP {ip}"),
        }
    }
}

/// What the poses of a rig are relative to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Frame {
    /// The vehicle frame: x forward, y left, z up, ground plane z = 0,
    /// metres.
    Vehicle,
    /// The frame of one of the rig's cameras (OpenCV axes, metres), for
    /// rigs whose relation to the ground is not known (a Kalibr camchain).
    Camera(String),
}

/// One camera of a rig.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Its name, unique in the rig (`front`, `cam0`).
    pub name: String,
    /// How to reach it, if known.
    pub device: Option<DeviceId>,
    /// Its intrinsics.
    pub intrinsics: Intrinsics,
    /// Its pose in the rig's frame, if known.
    pub pose: Option<Pose>,
}

impl Camera {
    /// A camera without device id or pose.
    pub fn new(name: impl Into<String>, intrinsics: Intrinsics) -> Self {
        Self {
            name: name.into(),
            device: None,
            intrinsics,
            pose: None,
        }
    }

    /// Projects a rig-frame point to a pixel (`None` without a pose or
    /// outside the model's valid region; the pixel may lie off the image).
    pub fn project_rig(&self, p: &Vector3<f64>) -> Option<Point2<f64>> {
        self.projector()?.project_rig(p)
    }

    /// The ray a pixel sees, in the rig frame: origin and unit direction.
    pub fn ray_rig(&self, px: &Point2<f64>) -> Option<(Vector3<f64>, Vector3<f64>)> {
        self.projector()?.ray_rig(px)
    }

    /// Where a pixel's ray meets the ground plane z = 0 (only meaningful in a
    /// vehicle-frame rig); `None` if it looks at or above the horizon.
    pub fn ground_point(&self, px: &Point2<f64>) -> Option<Vector3<f64>> {
        self.projector()?.ground_point(px)
    }

    /// The camera's pose and its model's [`Projector`] (the valid region
    /// found once), for projecting many points; `None` without a pose.
    pub fn projector(&self) -> Option<CameraProjector> {
        Some(CameraProjector {
            pose: self.pose?,
            model: self.intrinsics.projector(),
        })
    }
}

/// A posed camera ready to project many points: [`Camera::project_rig`],
/// [`Camera::ray_rig`] and [`Camera::ground_point`] with the model's valid
/// region found once (the same answers, to the bit). Built by
/// [`Camera::projector`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraProjector {
    pose: Pose,
    model: Projector,
}

impl CameraProjector {
    /// The camera's pose in the rig frame.
    pub fn pose(&self) -> &Pose {
        &self.pose
    }

    /// As [`Camera::project_rig`].
    pub fn project_rig(&self, p: &Vector3<f64>) -> Option<Point2<f64>> {
        self.model.project(&self.pose.to_camera(p))
    }

    /// As [`Camera::ray_rig`].
    pub fn ray_rig(&self, px: &Point2<f64>) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let d = self.model.unproject(px)?;
        Some((
            *self.pose.translation(),
            self.pose.rotation_matrix() * d.into_inner(),
        ))
    }

    /// As [`Camera::ground_point`].
    pub fn ground_point(&self, px: &Point2<f64>) -> Option<Vector3<f64>> {
        let (o, d) = self.ray_rig(px)?;
        if d.z >= -1e-9 || o.z <= 0.0 {
            return None;
        }
        let s = -o.z / d.z;
        Some(o + d * s)
    }
}

/// A rig of cameras.
#[derive(Clone, Debug, PartialEq)]
pub struct Rig {
    /// What the poses are relative to.
    pub frame: Frame,
    /// The cameras, in order.
    pub cameras: Vec<Camera>,
    /// Pairs of camera indices whose views overlap, each pair once with the
    /// smaller index first.
    pub neighbours: Vec<(usize, usize)>,
}

impl Rig {
    /// A rig; see [`Rig::validate`] for what is checked.
    pub fn new(
        frame: Frame,
        cameras: Vec<Camera>,
        neighbours: Vec<(usize, usize)>,
    ) -> Result<Self, FieldError> {
        let mut neighbours: Vec<(usize, usize)> = neighbours
            .into_iter()
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        neighbours.sort_unstable();
        let rig = Self {
            frame,
            cameras,
            neighbours,
        };
        rig.validate()?;
        Ok(rig)
    }

    /// Checks the rig: at least one camera, unique non-empty names, valid
    /// intrinsics, neighbour pairs of two different existing cameras with no
    /// pair twice, and a reference camera (for [`Frame::Camera`]) that
    /// exists.
    pub fn validate(&self) -> Result<(), FieldError> {
        if self.cameras.is_empty() {
            return Err(FieldError::new("cameras", "at least one camera", "none"));
        }
        for (i, c) in self.cameras.iter().enumerate() {
            let at = format!("cameras[{i}]");
            if c.name.trim().is_empty() {
                return Err(FieldError::new("name", "a non-empty name", "\"\"").within(&at));
            }
            if self.cameras[..i].iter().any(|o| o.name == c.name) {
                return Err(FieldError::new(
                    "name",
                    "a name no other camera has",
                    format!("\"{}\" a second time", c.name),
                )
                .within(&at));
            }
            c.intrinsics.validate().map_err(|e| e.within(&at))?;
        }
        let n = self.cameras.len();
        for (k, &(a, b)) in self.neighbours.iter().enumerate() {
            if a >= n || b >= n || a == b {
                return Err(FieldError::new(
                    format!("neighbours[{k}]"),
                    "two different cameras of the rig",
                    format!("({a}, {b})"),
                ));
            }
            if self.neighbours[..k]
                .iter()
                .any(|&(c, d)| (c.min(d), c.max(d)) == (a.min(b), a.max(b)))
            {
                return Err(FieldError::new(
                    format!("neighbours[{k}]"),
                    "each pair once",
                    format!("{} – {} again", self.cameras[a].name, self.cameras[b].name),
                ));
            }
        }
        if let Frame::Camera(name) = &self.frame {
            if self.index_of(name).is_none() {
                return Err(FieldError::new(
                    "frame.camera",
                    "the name of one of the rig's cameras",
                    format!("\"{name}\""),
                ));
            }
        }
        Ok(())
    }

    /// The index of the camera with this name.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.cameras.iter().position(|c| c.name == name)
    }

    /// The camera with this name.
    pub fn camera(&self, name: &str) -> Option<&Camera> {
        self.cameras.iter().find(|c| c.name == name)
    }

    /// The neighbours of camera `i`.
    pub fn neighbours_of(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.neighbours
            .iter()
            .filter(move |&&(a, b)| a == i || b == i)
            .map(move |&(a, b)| a + b - i)
    }
}
