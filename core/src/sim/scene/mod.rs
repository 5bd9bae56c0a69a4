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
//!
//! # Files
//!
//! - `description.rs`: what a scene holds, as simulation files give it.
//! - `validation.rs`: the checks of a description, naming the field.
//! - `geometry.rs`: the solids and the rays' first hits.
//! - `shading.rs`: textures, sun and sky, shadows and ambient occlusion.

mod description;
mod geometry;
mod shading;
mod validation;

pub use description::{
    Asphalt, Ego, Environment, Ground, Lane, Mat, Obstacle, ObstacleKind, Patch, Scene, Sky, Sun,
};
pub(crate) use geometry::{Built, Hit};
pub use shading::Class;
pub(crate) use shading::Shade;
