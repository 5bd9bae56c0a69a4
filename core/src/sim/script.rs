//! Scripted illumination: how the sun and the sky change over time.
//!
//! A script is a list of events; each scales the sun's part, the sky's part
//! or both parts of the scene's radiance (see [`super::scene`]) by a number
//! of stops. Events add up in stops. In a file:
//!
//! ```yaml
//! script:
//! - step: {at_s: 2.0, stops: 2}                # +2 stops at once at t = 2 s
//! - ramp: {from_s: 4, to_s: 14, stops: -3}     # −3 stops spread over 10 s
//! - step: {at_s: 20, stops: -1, light: sun}    # only the sun (a cloud)
//! - tunnel: {enter_s: 22, exit_s: 26, darkening: 100, transition_s: 0.5}
//! ```
//!
//! A tunnel darkens everything by `darkening` (both parts), over
//! `transition_s` at the entry and again, backwards, at the exit.

use serde::{Deserialize, Serialize};

use super::{check_field, FieldError};

/// Which part of the light an event scales.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightPart {
    /// Sun and sky alike.
    #[default]
    All,
    /// The sun (direct light, the sun's disc and glow).
    Sun,
    /// The sky (ambient light, the sky's own radiance).
    Sky,
}

impl LightPart {
    fn is_all(&self) -> bool {
        *self == Self::All
    }
}

/// One change of light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Event {
    /// A sudden change by `stops` at `at_s`.
    Step {
        /// When, seconds.
        at_s: f64,
        /// By how much, stops (+1 doubles the light).
        stops: f64,
        /// Which part of the light.
        #[serde(default, skip_serializing_if = "LightPart::is_all")]
        light: LightPart,
    },
    /// A change by `stops`, linear in stops from `from_s` to `to_s`.
    Ramp {
        /// Start, seconds.
        from_s: f64,
        /// End, seconds.
        to_s: f64,
        /// By how much in all, stops.
        stops: f64,
        /// Which part of the light.
        #[serde(default, skip_serializing_if = "LightPart::is_all")]
        light: LightPart,
    },
    /// A tunnel: everything `darkening` times darker from `enter_s` to
    /// `exit_s`, with smooth transitions of `transition_s`.
    Tunnel {
        /// Entry, seconds.
        enter_s: f64,
        /// Exit, seconds.
        exit_s: f64,
        /// How much darker inside (> 1).
        #[serde(default = "default_darkening")]
        darkening: f64,
        /// Length of each transition, seconds.
        #[serde(default = "default_transition")]
        transition_s: f64,
    },
}

fn default_darkening() -> f64 {
    100.0
}
fn default_transition() -> f64 {
    0.5
}

/// Multipliers of the sun's and the sky's part at one moment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Levels {
    /// Multiplier of the sun's part.
    pub sun: f64,
    /// Multiplier of the sky's part.
    pub sky: f64,
}

/// The events of a script, in any order.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Script {
    /// The events.
    #[serde(with = "serde_norway::with::singleton_map_recursive")]
    pub events: Vec<Event>,
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl Script {
    /// A script of these events.
    pub fn new(events: Vec<Event>) -> Self {
        Self { events }
    }

    /// The light at `t` seconds.
    pub fn levels(&self, t: f64) -> Levels {
        let (mut sun, mut sky) = (0.0, 0.0);
        let mut add = |part: LightPart, stops: f64| match part {
            LightPart::All => {
                sun += stops;
                sky += stops;
            }
            LightPart::Sun => sun += stops,
            LightPart::Sky => sky += stops,
        };
        for e in &self.events {
            match *e {
                Event::Step { at_s, stops, light } => {
                    if t >= at_s {
                        add(light, stops);
                    }
                }
                Event::Ramp {
                    from_s,
                    to_s,
                    stops,
                    light,
                } => {
                    let x = if to_s > from_s {
                        ((t - from_s) / (to_s - from_s)).clamp(0.0, 1.0)
                    } else {
                        f64::from(u8::from(t >= from_s))
                    };
                    add(light, stops * x);
                }
                Event::Tunnel {
                    enter_s,
                    exit_s,
                    darkening,
                    transition_s,
                } => {
                    let w = transition_s.max(1e-9);
                    let inside =
                        smoothstep((t - enter_s) / w).min(1.0 - smoothstep((t - exit_s) / w));
                    add(LightPart::All, -darkening.log2() * inside.max(0.0));
                }
            }
        }
        Levels {
            sun: sun.exp2(),
            sky: sky.exp2(),
        }
    }

    /// Checks every event; the error names it (`script[2].stops`).
    pub fn validate(&self) -> Result<(), FieldError> {
        let time = |f: String, v: f64| check_field(f, v, 0.0, 1e7, "a time in seconds ≥ 0");
        let stops =
            |f: String, v: f64| check_field(f, v, -40.0, 40.0, "a number of stops within ±40");
        // A later time must not come before an earlier one.
        let after = |f: String, v: f64, earlier: &str, e: f64| {
            check_field(f, v, e, 1e7, &format!("a time not before {earlier} ({e})"))
        };
        for (k, e) in self.events.iter().enumerate() {
            match *e {
                Event::Step { at_s, stops: s, .. } => {
                    time(format!("script[{k}].step.at_s"), at_s)?;
                    stops(format!("script[{k}].step.stops"), s)?;
                }
                Event::Ramp {
                    from_s,
                    to_s,
                    stops: s,
                    ..
                } => {
                    time(format!("script[{k}].ramp.from_s"), from_s)?;
                    time(format!("script[{k}].ramp.to_s"), to_s)?;
                    stops(format!("script[{k}].ramp.stops"), s)?;
                    after(format!("script[{k}].ramp.to_s"), to_s, "from_s", from_s)?;
                }
                Event::Tunnel {
                    enter_s,
                    exit_s,
                    darkening,
                    transition_s,
                } => {
                    time(format!("script[{k}].tunnel.enter_s"), enter_s)?;
                    time(format!("script[{k}].tunnel.exit_s"), exit_s)?;
                    after(
                        format!("script[{k}].tunnel.exit_s"),
                        exit_s,
                        "enter_s",
                        enter_s,
                    )?;
                    check_field(
                        format!("script[{k}].tunnel.darkening"),
                        darkening,
                        1.0,
                        1e9,
                        "a factor from 1 to 10⁹",
                    )?;
                    time(format!("script[{k}].tunnel.transition_s"), transition_s)?;
                }
            }
        }
        Ok(())
    }

    /// Whether the light never changes.
    pub fn is_constant(&self) -> bool {
        self.events.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * b.abs().max(1.0)
    }

    #[test]
    fn steps_ramps_and_tunnels_scale_the_light() {
        let s = Script::new(vec![
            Event::Step {
                at_s: 1.0,
                stops: 2.0,
                light: LightPart::All,
            },
            Event::Ramp {
                from_s: 2.0,
                to_s: 4.0,
                stops: -4.0,
                light: LightPart::Sun,
            },
        ]);
        assert!(close(s.levels(0.5).sun, 1.0));
        assert!(close(s.levels(1.0).sun, 4.0));
        assert!(close(s.levels(3.0).sun, 1.0));
        assert!(close(s.levels(3.0).sky, 4.0));
        assert!(close(s.levels(9.0).sun, 0.25));
        let t = Script::new(vec![Event::Tunnel {
            enter_s: 1.0,
            exit_s: 5.0,
            darkening: 100.0,
            transition_s: 0.5,
        }]);
        assert!(close(t.levels(0.9).sun, 1.0));
        assert!(close(t.levels(3.0).sun, 0.01));
        assert!(close(t.levels(3.0).sky, 0.01));
        let mid = t.levels(1.25).sun;
        assert!(mid < 0.5 && mid > 0.02, "{mid}");
        assert!(close(t.levels(6.0).sky, 1.0));
        assert!(t.validate().is_ok());
    }

    #[test]
    fn bad_events_name_their_field() {
        let s = Script::new(vec![
            Event::Step {
                at_s: 0.0,
                stops: 1.0,
                light: LightPart::All,
            },
            Event::Ramp {
                from_s: 5.0,
                to_s: 4.0,
                stops: 1.0,
                light: LightPart::All,
            },
        ]);
        let e = s.validate().unwrap_err();
        assert_eq!(e.field, "script[1].ramp.to_s");
    }
}
