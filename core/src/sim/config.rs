//! Simulation files and the built-in presets.
//!
//! A simulation file says which rig, which scene, which illumination script
//! and which camera; every part has a default, and the scene and the script
//! may name a built-in preset instead of spelling it out:
//!
//! ```yaml
//! format: rigview-sim
//! version: 1
//! rig: reference            # the built-in reference rig, or a rig file (relative to this file)
//! scene: car-park           # a scene preset (car-park, low-sun, overcast, sky, tunnel-exit, snow, lawn) or a scene
//! script: tunnel            # a script preset (constant, steps, ramp, tunnel) or a list of events
//! sensor: {bits: 12}        # the camera model; every field has the reference camera's default
//! trigger_hz: 20
//! latency_frames: 1         # 0 to 2
//! duration_s: 8             # the scenario's length (the demo's default run)
//! seed: 1                   # noise
//! start: {shutter_us: 2000, gain_db: 0}
//! scale: 1.0                # render at this fraction of the rig's resolution
//! supersample: 2            # rays per pixel along each axis
//! lens_fov_deg: 185         # the lens's image circle
//! ```
//!
//! A scene spelled out (every field optional; see [`Scene`]):
//!
//! ```yaml
//! scene:
//!   seed: 7
//!   ground:
//!     asphalt: {reflectance: 0.12, variation: 0.35, grain: 0.5, grain_m: 0.03}
//!     lanes:
//!     - {from_m: [-40, -5.5], to_m: [40, -5.5], width_m: 0.15, dash_m: 3, gap_m: 3}
//!     mat: {centre_m: [0, 0], size_m: [10, 6], hole_m: [5, 2], square_m: 0.4, circle_square_m: 0.8}
//!     patches:              # ground with its own surface and light (here: tree shade)
//!     - {centre_m: [3, 2], size_m: [4, 3], yaw_deg: 20, surface: {reflectance: 0.1, grain: 0.9, grain_m: 0.01}, sun: 0, sky: 0.8}
//!   obstacles:
//!   - {kind: building, centre_m: [-10.5, -11], size_m: [19, 6, 15]}
//!   - {kind: wall, centre_m: [0, 11.5], size_m: [40, 0.3, 2.4]}
//!   - {kind: car, centre_m: [9, -4], size_m: [4.5, 1.8, 1.45], yaw_deg: 0}
//!   ego: {size_m: [4.6, 1.8, 1.5]}
//!   sun: {azimuth_deg: -100, elevation_deg: 50, level: 1.0}
//!   sky: {level: 0.1}
//! ```
//!
//! Every error names the file and the field (`tunnel.sim.yaml: field
//! "scene.sun.elevation_deg": expected an elevation in degrees in [-90, 90],
//! found 95`); unknown fields are errors, so a typo never turns into a
//! silent default. `assets/sim/` holds every preset written out in full, as
//! a starting point.

use std::fmt;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};

use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::scene::{Asphalt, Ground, Lane, Obstacle, ObstacleKind, Patch, Scene, Sky, Sun};
use super::script::{Event, LightPart, Script};
use super::sensor::Sensor;
use super::{check_field, field_error, FieldError};
use crate::error::{Error, Result};
use crate::exposure::ExposureSetting;

mod presets;

use presets::car_park;
pub use presets::{scene_preset, script_preset};

/// The value of the `format` field.
pub const FORMAT_NAME: &str = "rigview-sim";
/// The simulation file version this build reads and writes.
pub const VERSION: u32 = 1;

/// The built-in simulations: `(name, scene preset, script preset, what it
/// shows)`.
pub const PRESETS: [(&str, &str, &str, &str); 10] = [
    (
        "reference",
        "car-park",
        "constant",
        "a sunny car park with a building's shadow over the back half, constant light",
    ),
    (
        "steps",
        "car-park",
        "steps",
        "the car park with steps of +2, −2, −4 and +4 stops",
    ),
    (
        "ramp",
        "car-park",
        "ramp",
        "the car park slowly dimming by 4 stops and back",
    ),
    (
        "tunnel",
        "car-park",
        "tunnel",
        "the car park, then a tunnel 100× darker, then out again",
    ),
    (
        "backlight",
        "low-sun",
        "constant",
        "a low sun straight ahead: the front camera faces it",
    ),
    (
        "overcast",
        "overcast",
        "constant",
        "the car park under an overcast sky: soft light, no cast shadows",
    ),
    (
        "sky",
        "sky",
        "constant",
        "a bright hazy sky over dark, textured ground and façades (metered whole frames)",
    ),
    (
        "tunnel-exit",
        "tunnel-exit",
        "constant",
        "inside a dark tunnel, about 5 EV below the sunlit road ahead of its exit",
    ),
    (
        "snow",
        "snow",
        "constant",
        "bright, almost textureless snow with dark cars, a wall and tyre tracks",
    ),
    (
        "lawn",
        "lawn",
        "constant",
        "a finely textured lawn in sun and tree shade, 12-bit, starting 4 EV dark",
    ),
];

/// The `lawn` preset's starting shutter: 4 EV below the shutter of its
/// best M (`tests/tests/hard_scenes.rs` checks it).
pub const LAWN_START_US: f64 = 90.0;

/// The built-in scenes.
pub const SCENE_PRESETS: [&str; 7] = [
    "car-park",
    "low-sun",
    "overcast",
    "sky",
    "tunnel-exit",
    "snow",
    "lawn",
];
/// The built-in scripts.
pub const SCRIPT_PRESETS: [&str; 4] = ["constant", "steps", "ramp", "tunnel"];

/// Which rig the simulation uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RigChoice {
    /// The built-in reference rig ([`super::rig::reference_rig`]).
    Reference,
    /// A rig file (any format `rigview-calib` reads; poses in the vehicle
    /// frame).
    File(PathBuf),
}

/// Everything a simulation needs.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    /// Where it came from (a preset's name or a file), for messages.
    pub name: String,
    /// The rig.
    pub rig: RigChoice,
    /// Render at this fraction of the rig's resolution (0.25: 322×241 for
    /// the reference rig).
    pub scale: f64,
    /// Rays per pixel along each axis when precomputing the radiance.
    pub supersample: u32,
    /// The lens's field of view, degrees: rays further than half of it from
    /// the optical axis bring no light.
    pub lens_fov_deg: f64,
    /// The scene.
    pub scene: Scene,
    /// The illumination over time.
    pub script: Script,
    /// The camera model.
    pub sensor: Sensor,
    /// Triggers per second (simulation time; also the pace of a real-time
    /// source).
    pub trigger_hz: f64,
    /// Frames between a command and the first frame that shows it.
    pub latency_frames: u32,
    /// The scenario's length, seconds.
    pub duration_s: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Every camera's setting at the start.
    pub start: ExposureSetting,
}

impl Default for SimConfig {
    /// The `reference` preset.
    fn default() -> Self {
        Self {
            name: "reference".into(),
            rig: RigChoice::Reference,
            scale: 1.0,
            supersample: 2,
            lens_fov_deg: super::rig::REFERENCE_FOV_DEG,
            scene: car_park(),
            script: Script::default(),
            sensor: Sensor::default(),
            trigger_hz: 20.0,
            latency_frames: 1,
            duration_s: 2.0,
            seed: 1,
            start: ExposureSetting {
                shutter_us: 2000.0,
                gain_db: 0.0,
            },
        }
    }
}

/// A preset name or a description spelled out.
#[derive(Clone, Debug, PartialEq)]
enum PresetOr<T> {
    Preset(String),
    Inline(T),
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for PresetOr<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V<T>(PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = PresetOr<T>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a preset name or a description")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Self::Value, E> {
                Ok(PresetOr::Preset(v.to_owned()))
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                m: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                T::deserialize(MapAccessDeserializer::new(m)).map(PresetOr::Inline)
            }
            fn visit_seq<A: SeqAccess<'de>>(
                self,
                s: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                T::deserialize(SeqAccessDeserializer::new(s)).map(PresetOr::Inline)
            }
        }
        d.deserialize_any(V(PhantomData))
    }
}

impl<T: Serialize> Serialize for PresetOr<T> {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            PresetOr::Preset(name) => s.serialize_str(name),
            PresetOr::Inline(t) => t.serialize(s),
        }
    }
}

#[derive(Deserialize)]
struct Header {
    format: Option<serde_norway::Value>,
    version: Option<serde_norway::Value>,
}

fn default_rig() -> String {
    "reference".into()
}
fn default_scene() -> PresetOr<Scene> {
    PresetOr::Preset("car-park".into())
}
fn default_script() -> PresetOr<Script> {
    PresetOr::Preset("constant".into())
}

/// A simulation file as written.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SimDoc {
    format: String,
    version: u32,
    #[serde(default = "default_rig")]
    rig: String,
    #[serde(default = "default_scene")]
    scene: PresetOr<Scene>,
    #[serde(default = "default_script")]
    script: PresetOr<Script>,
    #[serde(default)]
    sensor: Sensor,
    #[serde(default = "defaults::trigger_hz")]
    trigger_hz: f64,
    #[serde(default = "defaults::latency_frames")]
    latency_frames: u32,
    #[serde(default = "defaults::duration_s")]
    duration_s: f64,
    #[serde(default = "defaults::seed")]
    seed: u64,
    #[serde(default = "defaults::start")]
    start: Start,
    #[serde(default = "defaults::scale")]
    scale: f64,
    #[serde(default = "defaults::supersample")]
    supersample: u32,
    #[serde(default = "defaults::lens_fov_deg")]
    lens_fov_deg: f64,
}

#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Start {
    shutter_us: f64,
    #[serde(default)]
    gain_db: f64,
}

mod defaults {
    use super::*;
    pub fn trigger_hz() -> f64 {
        SimConfig::default().trigger_hz
    }
    pub fn latency_frames() -> u32 {
        SimConfig::default().latency_frames
    }
    pub fn duration_s() -> f64 {
        SimConfig::default().duration_s
    }
    pub fn seed() -> u64 {
        SimConfig::default().seed
    }
    pub fn start() -> Start {
        let s = SimConfig::default().start;
        Start {
            shutter_us: s.shutter_us,
            gain_db: s.gain_db,
        }
    }
    pub fn scale() -> f64 {
        1.0
    }
    pub fn supersample() -> u32 {
        SimConfig::default().supersample
    }
    pub fn lens_fov_deg() -> f64 {
        SimConfig::default().lens_fov_deg
    }
}

fn names(list: &[&str]) -> String {
    list.join(", ")
}

impl SimConfig {
    /// A built-in simulation by name (see [`PRESETS`]).
    pub fn preset(name: &str) -> Result<Self> {
        let Some(&(_, scene, script, _)) = PRESETS.iter().find(|p| p.0 == name) else {
            return Err(Error::invalid(
                "simulation",
                "preset",
                format!("one of {}", names(&PRESETS.map(|p| p.0))),
                format_args!("\"{name}\""),
            ));
        };
        let (script, duration_s) = script_preset(script).ok_or_else(|| {
            Error::invalid(
                format!("preset {name}"),
                "script",
                "a built-in script",
                script,
            )
        })?;
        let mut config = Self {
            name: name.into(),
            scene: scene_preset(scene).ok_or_else(|| {
                Error::invalid(format!("preset {name}"), "scene", "a built-in scene", scene)
            })?,
            script,
            duration_s,
            ..Self::default()
        };
        if name == "lawn" {
            // As the real lawn sequence: a 12-bit camera starting 4 EV below
            // the best M.
            config.sensor.bits = 12;
            config.start.shutter_us = LAWN_START_US;
        }
        Ok(config)
    }

    /// A preset if `name` is one, otherwise the simulation file at that
    /// path.
    pub fn named(name: &str) -> Result<Self> {
        if PRESETS.iter().any(|p| p.0 == name) {
            Self::preset(name)
        } else {
            Self::load(Path::new(name))
        }
    }

    /// Reads a simulation file.
    pub fn load(path: &Path) -> Result<Self> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| Error::File {
            file: file.clone(),
            detail: format!("cannot read the simulation file: {e}"),
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::parse(&text, &file, base)
    }

    /// Parses a simulation file's text; `file` names it in errors and
    /// relative rig paths are taken from `base`.
    pub fn parse(text: &str, file: &str, base: &Path) -> Result<Self> {
        let parse_error = |e: serde_norway::Error| Error::File {
            file: file.to_owned(),
            detail: e.to_string(),
        };
        let header: Header = serde_norway::from_str(text).map_err(parse_error)?;
        let field = |field: &str, expected: String, found: String| Error::Field {
            file: file.to_owned(),
            field: field.to_owned(),
            expected,
            found,
        };
        let show = |v: Option<serde_norway::Value>| {
            v.map_or("nothing".to_owned(), |v| {
                serde_norway::to_string(&v).map_or("?".into(), |s| s.trim().to_owned())
            })
        };
        match &header.format {
            Some(serde_norway::Value::String(s)) if s == FORMAT_NAME => {}
            other => {
                return Err(field(
                    "format",
                    format!("\"{FORMAT_NAME}\" (a rigview simulation file)"),
                    show(other.clone()),
                ))
            }
        }
        match &header.version {
            Some(serde_norway::Value::Number(n)) if n.as_u64() == Some(u64::from(VERSION)) => {}
            other => {
                return Err(field(
                    "version",
                    format!("simulation file version {VERSION}"),
                    show(other.clone()),
                ))
            }
        }
        let doc: SimDoc = serde_norway::from_str(text).map_err(parse_error)?;
        let rig = if doc.rig == "reference" {
            RigChoice::Reference
        } else {
            let p = Path::new(&doc.rig);
            RigChoice::File(if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            })
        };
        let scene = match doc.scene {
            PresetOr::Inline(mut s) => {
                if let Some(e) = &mut s.environment {
                    if e.file.is_relative() {
                        e.file = base.join(&e.file);
                    }
                }
                s
            }
            PresetOr::Preset(name) => scene_preset(&name).ok_or_else(|| {
                field(
                    "scene",
                    format!("a scene preset ({}) or a scene", names(&SCENE_PRESETS)),
                    format!("\"{name}\""),
                )
            })?,
        };
        let script = match doc.script {
            PresetOr::Inline(s) => s,
            PresetOr::Preset(name) => {
                script_preset(&name)
                    .ok_or_else(|| {
                        field(
                            "script",
                            format!(
                                "a script preset ({}) or a list of events",
                                names(&SCRIPT_PRESETS)
                            ),
                            format!("\"{name}\""),
                        )
                    })?
                    .0
            }
        };
        let config = Self {
            name: file.to_owned(),
            rig,
            scale: doc.scale,
            supersample: doc.supersample,
            lens_fov_deg: doc.lens_fov_deg,
            scene,
            script,
            sensor: doc.sensor,
            trigger_hz: doc.trigger_hz,
            latency_frames: doc.latency_frames,
            duration_s: doc.duration_s,
            seed: doc.seed,
            start: ExposureSetting {
                shutter_us: doc.start.shutter_us,
                gain_db: doc.start.gain_db,
            },
        };
        config.validate()?;
        Ok(config)
    }

    /// Checks every value; errors name [`SimConfig::name`] and the field.
    pub fn validate(&self) -> Result<()> {
        self.issues().map_err(|e| field_error(e, &self.name))
    }

    fn issues(&self) -> std::result::Result<(), FieldError> {
        let num = |f: &str, v: f64, lo: f64, hi: f64, e: &str| check_field(f, v, lo, hi, e);
        num(
            "scale",
            self.scale,
            0.01,
            4.0,
            "a resolution factor in [0.01, 4]",
        )?;
        if !(1..=8).contains(&self.supersample) {
            return Err(FieldError::new(
                "supersample",
                "1 to 8 rays per pixel along each axis",
                format!("{}", self.supersample),
            ));
        }
        num(
            "lens_fov_deg",
            self.lens_fov_deg,
            1.0,
            360.0,
            "an angle in degrees in [1, 360]",
        )?;
        num(
            "trigger_hz",
            self.trigger_hz,
            0.01,
            10_000.0,
            "a rate in Hz in [0.01, 10000]",
        )?;
        if self.latency_frames > 2 {
            return Err(FieldError::new(
                "latency_frames",
                "0, 1 or 2 frames",
                format!("{}", self.latency_frames),
            ));
        }
        num(
            "duration_s",
            self.duration_s,
            0.0,
            1e6,
            "a duration in seconds ≥ 0",
        )?;
        let r = self.sensor.range();
        num(
            "start.shutter_us",
            self.start.shutter_us,
            r.shutter_min_us,
            r.shutter_max_us,
            "an exposure time within the sensor's shutter range",
        )?;
        num(
            "start.gain_db",
            self.start.gain_db,
            r.gain_min_db,
            r.gain_max_db,
            "a gain within the sensor's gain range",
        )?;
        self.sensor.validate()?;
        self.scene.validate()?;
        self.script.validate()
    }

    /// The simulation as a file, with the scene and the script spelled out.
    pub fn to_yaml(&self) -> Result<String> {
        let doc = SimDoc {
            format: FORMAT_NAME.into(),
            version: VERSION,
            rig: match &self.rig {
                RigChoice::Reference => "reference".into(),
                RigChoice::File(p) => p.display().to_string(),
            },
            scene: PresetOr::Inline(self.scene.clone()),
            script: PresetOr::Inline(self.script.clone()),
            sensor: self.sensor,
            trigger_hz: self.trigger_hz,
            latency_frames: self.latency_frames,
            duration_s: self.duration_s,
            seed: self.seed,
            start: Start {
                shutter_us: self.start.shutter_us,
                gain_db: self.start.gain_db,
            },
            scale: self.scale,
            supersample: self.supersample,
            lens_fov_deg: self.lens_fov_deg,
        };
        let body = serde_norway::to_string(&doc).map_err(|source| Error::Yaml {
            what: "cannot write the simulation as YAML".into(),
            source,
        })?;
        Ok(format!(
            "# rigview simulation file: the rig, the scene, the illumination script and the camera.\n\
             # Radiance unit: a white surface facing the sun at sun.level = 1. Lengths in metres,\n\
             # angles in degrees, times in seconds; see core/src/sim/config.rs for every field.\n{body}"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<SimConfig> {
        SimConfig::parse(text, "test.sim.yaml", Path::new("/base"))
    }

    #[test]
    fn every_preset_is_valid_and_round_trips_through_its_file() {
        for (name, ..) in PRESETS {
            let c = SimConfig::preset(name).unwrap();
            c.validate().unwrap();
            let text = c.to_yaml().unwrap();
            let back = SimConfig::parse(&text, name, Path::new(".")).unwrap();
            assert_eq!(back, c, "{name}\n{text}");
        }
        assert!(SimConfig::preset("nope").is_err());
    }

    #[test]
    fn a_short_file_takes_presets_and_defaults() {
        let c = parse("format: rigview-sim\nversion: 1\nscript: tunnel\nrig: rigs/my.rig.yaml\n")
            .unwrap();
        assert_eq!(c.scene, scene_preset("car-park").unwrap());
        assert_eq!(c.script, script_preset("tunnel").unwrap().0);
        assert_eq!(
            c.rig,
            RigChoice::File(PathBuf::from("/base/rigs/my.rig.yaml"))
        );
        assert_eq!(c.sensor, Sensor::default());
    }

    #[test]
    fn errors_name_the_file_and_the_field() {
        let msg = |t: &str| parse(t).unwrap_err().to_string();
        let m = msg("format: rigview-rig\nversion: 1\n");
        assert!(
            m.contains("test.sim.yaml") && m.contains("\"format\""),
            "{m}"
        );
        let m = msg("format: rigview-sim\nversion: 2\n");
        assert!(m.contains("\"version\"") && m.contains("found 2"), "{m}");
        let m = msg("format: rigview-sim\nversion: 1\nscene: {sun: {elevation_deg: 95}}\n");
        assert!(
            m.contains("scene.sun.elevation_deg") && m.contains("95"),
            "{m}"
        );
        let m = msg("format: rigview-sim\nversion: 1\nscene: {obstacles: [{kind: car, centre_m: [1, 2], size_m: [1, 2]}]}\n");
        assert!(
            m.contains("scene.obstacles[0].size_m") && m.contains("line"),
            "{m}"
        );
        let m = msg("format: rigview-sim\nversion: 1\nscript:\n- step: {at_s: 1, stop: 2}\n");
        assert!(m.contains("script[0].step") && m.contains("stop"), "{m}");
        let m = msg("format: rigview-sim\nversion: 1\nscript: sunset\n");
        assert!(
            m.contains("\"script\"") && m.contains("sunset") && m.contains("tunnel"),
            "{m}"
        );
        let m = msg("format: rigview-sim\nversion: 1\nsensor: {bits: 10}\n");
        assert!(m.contains("sensor.bits"), "{m}");
        let m = msg("format: rigview-sim\nversion: 1\nlatency_frames: 3\n");
        assert!(m.contains("latency_frames"), "{m}");
        let m = msg("format: rigview-sim\nversion: 1\nsceen: car-park\n");
        assert!(m.contains("sceen"), "{m}");
        let m = msg("format: rigview-sim\nversion: 1\nscene: {ground: {mat: {hole_m: [11, 1]}}}\n");
        assert!(m.contains("scene.ground.mat.hole_m[0]"), "{m}");
        let m = msg("format: rigview-sim\nversion: 1\nscene: {ground: {patches: [{centre_m: [0, 0], size_m: [2, 2], sun: 1.5}]}}\n");
        assert!(
            m.contains("scene.ground.patches[0].sun") && m.contains("1.5") && m.contains("[0, 1]"),
            "{m}"
        );
        let m = msg("format: rigview-sim\nversion: 1\nscene: {ground: {patches: [{centre_m: [0, 0], size_m: [2, 2], surface: {grain: 2}}]}}\n");
        assert!(m.contains("scene.ground.patches[0].surface.grain"), "{m}");
    }
}
