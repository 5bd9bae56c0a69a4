//! The built-in scenes and illumination scripts that a simulation file
//! can name instead of spelling them out.

use super::*;

/// The car park: the calibration mat around the car, painted bays with
/// parked cars on the left, a brick wall behind them and another behind the
/// car, a block to the back right whose shadow covers the back half of the
/// scene, a tall block far ahead to the left, and the sun high to the right.
pub(super) fn car_park() -> Scene {
    let car = |x: f64, y: f64, yaw: f64| Obstacle {
        kind: ObstacleKind::Car,
        centre_m: [x, y],
        size_m: [4.5, 1.8, 1.45],
        yaw_deg: yaw,
        reflectance: None,
    };
    let mut lanes = vec![
        Lane {
            from_m: [-40.0, -5.5],
            to_m: [40.0, -5.5],
            width_m: 0.15,
            dash_m: 3.0,
            gap_m: 3.0,
            reflectance: 0.65,
        },
        Lane {
            from_m: [-40.0, 6.0],
            to_m: [40.0, 6.0],
            width_m: 0.12,
            dash_m: 0.0,
            gap_m: 0.0,
            reflectance: 0.6,
        },
    ];
    for k in 0..8 {
        let x = -8.75 + 2.5 * f64::from(k);
        lanes.push(Lane {
            from_m: [x, 6.0],
            to_m: [x, 11.2],
            width_m: 0.12,
            dash_m: 0.0,
            gap_m: 0.0,
            reflectance: 0.6,
        });
    }
    Scene {
        seed: 7,
        ground: crate::sim::scene::Ground {
            lanes,
            ..Default::default()
        },
        obstacles: vec![
            Obstacle {
                kind: ObstacleKind::Building,
                centre_m: [-10.5, -11.0],
                size_m: [19.0, 6.0, 15.0],
                yaw_deg: 0.0,
                reflectance: None,
            },
            Obstacle {
                kind: ObstacleKind::Building,
                centre_m: [24.0, 18.0],
                size_m: [14.0, 10.0, 24.0],
                yaw_deg: 20.0,
                reflectance: Some(0.45),
            },
            Obstacle {
                kind: ObstacleKind::Wall,
                centre_m: [0.0, 11.5],
                size_m: [40.0, 0.3, 2.4],
                yaw_deg: 0.0,
                reflectance: None,
            },
            Obstacle {
                kind: ObstacleKind::Wall,
                centre_m: [-22.0, 0.0],
                size_m: [30.0, 0.3, 3.0],
                yaw_deg: 90.0,
                reflectance: Some(0.3),
            },
            car(-7.5, 8.6, 90.0),
            car(-2.5, 8.6, 90.0),
            car(0.0, 8.6, 90.0),
            car(5.0, 8.6, 90.0),
            car(9.0, -3.8, 0.0),
            car(-9.5, -3.8, 180.0),
        ],
        ..Default::default()
    }
}

/// The car park under a low sun straight ahead (12° up): the front camera
/// looks into it, the others do not see it.
fn low_sun() -> Scene {
    Scene {
        sun: Sun {
            azimuth_deg: 0.0,
            elevation_deg: 12.0,
            ..Default::default()
        },
        ..car_park()
    }
}

/// The car park under an overcast sky: no sun, a sky three times brighter
/// at the zenith than at the horizon (after the CIE overcast sky), about a
/// third of the sunny scene's light.
fn overcast() -> Scene {
    Scene {
        sun: Sun {
            level: 0.0,
            ..Default::default()
        },
        sky: crate::sim::scene::Sky {
            level: 0.25,
            horizon: 0.45,
            zenith: 1.4,
        },
        ..car_park()
    }
}

/// A textured ground surface (see [`Asphalt`]).
fn surface(reflectance: f64, variation: f64, grain: f64, grain_m: f64) -> Asphalt {
    Asphalt {
        reflectance,
        variation,
        grain,
        grain_m,
    }
}

/// An obstacle with the default yaw.
fn obstacle(kind: ObstacleKind, centre_m: [f64; 2], size_m: [f64; 3], rho: f64) -> Obstacle {
    Obstacle {
        kind,
        centre_m,
        size_m,
        yaw_deg: 0.0,
        reflectance: Some(rho),
    }
}

/// A bright hazy sky over a dark foreground: no sun, a sky 3.5 times the
/// car park's, three times brighter at the horizon than at the zenith;
/// dark, coarse asphalt without a mat, dark façades and a brick wall
/// around. Seen by whole frames, the sky is 4–5 EV brighter than the
/// ground and takes a large part of each image, but has no texture.
fn sky() -> Scene {
    Scene {
        seed: 11,
        ground: Ground {
            asphalt: surface(0.08, 0.4, 0.6, 0.03),
            mat: None,
            ..Default::default()
        },
        obstacles: vec![
            obstacle(
                ObstacleKind::Building,
                [16.0, -10.0],
                [14.0, 8.0, 9.0],
                0.15,
            ),
            obstacle(
                ObstacleKind::Building,
                [-18.0, 9.0],
                [16.0, 8.0, 10.0],
                0.15,
            ),
            obstacle(ObstacleKind::Wall, [0.0, 7.5], [24.0, 0.3, 1.8], 0.12),
            obstacle(ObstacleKind::Car, [-1.0, -4.0], [4.5, 1.8, 1.45], 0.08),
        ],
        sun: Sun {
            level: 0.0,
            ..Default::default()
        },
        sky: Sky {
            level: 0.35,
            horizon: 3.0,
            zenith: 1.0,
        },
        ..Default::default()
    }
}

/// The last metres of a tunnel: the road around the car and behind it is a
/// patch that no sunlight and 15 % of the skylight reach (concrete, textured),
/// the road from 4 m ahead of the rig on is the sunlit asphalt outside,
/// about 5 EV brighter; lane lines run through both.
fn tunnel_exit() -> Scene {
    let lane = |y: f64, dash_m: f64| Lane {
        from_m: [-40.0, y],
        to_m: [40.0, y],
        width_m: 0.15,
        dash_m,
        gap_m: dash_m,
        reflectance: 0.65,
    };
    Scene {
        seed: 13,
        ground: Ground {
            lanes: vec![lane(-1.8, 3.0), lane(1.8, 3.0), lane(-5.0, 0.0)],
            mat: None,
            patches: vec![Patch {
                centre_m: [-18.0, 0.0],
                size_m: [44.0, 16.0],
                yaw_deg: 0.0,
                surface: surface(0.2, 0.3, 0.6, 0.02),
                sun: 0.0,
                sky: 0.15,
            }],
            ..Default::default()
        },
        obstacles: vec![
            obstacle(ObstacleKind::Car, [10.0, -2.0], [4.5, 1.8, 1.45], 0.3),
            obstacle(
                ObstacleKind::Building,
                [30.0, 14.0],
                [14.0, 10.0, 18.0],
                0.4,
            ),
        ],
        sun: Sun {
            azimuth_deg: 180.0,
            elevation_deg: 45.0,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Snow in sunshine: a ground of reflectance 0.85 with hardly any texture,
/// two dark tyre tracks of wet asphalt behind the car, dark parked cars on
/// both sides and a dark brick wall ahead.
fn snow() -> Scene {
    let track = |y: f64| Patch {
        centre_m: [-8.0, y],
        size_m: [12.0, 0.5],
        yaw_deg: 0.0,
        surface: surface(0.08, 0.3, 0.6, 0.02),
        sun: 1.0,
        sky: 1.0,
    };
    let car = |x: f64, y: f64, rho: f64| obstacle(ObstacleKind::Car, [x, y], [4.5, 1.8, 1.45], rho);
    Scene {
        seed: 17,
        ground: Ground {
            asphalt: surface(0.85, 0.05, 0.04, 0.05),
            mat: None,
            patches: vec![track(-0.8), track(0.8)],
            ..Default::default()
        },
        obstacles: vec![
            car(0.5, 3.6, 0.06),
            car(-5.0, -3.6, 0.1),
            car(5.5, -3.8, 0.05),
            obstacle(ObstacleKind::Wall, [5.5, 2.0], [0.3, 4.0, 2.0], 0.15),
        ],
        sun: Sun {
            elevation_deg: 30.0,
            ..Default::default()
        },
        sky: Sky {
            level: 0.15,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// A lawn in sun and the shade of trees: fine grass (1 cm grain, strong
/// contrast) everywhere, and shade patches (no sun, 80 % of the sky) over
/// about half the ground around the car, at angles. No mat, no obstacles
/// besides the car, and a high sun (65°) so that the car's own shadow is
/// short: no large bright or dark areas, so M rises until the sunlit grass
/// begins to clip.
fn lawn() -> Scene {
    let shade = |centre_m: [f64; 2], size_m: [f64; 2], yaw_deg: f64| Patch {
        centre_m,
        size_m,
        yaw_deg,
        surface: surface(0.1, 0.35, 0.9, 0.01),
        sun: 0.0,
        sky: 0.8,
    };
    Scene {
        seed: 19,
        ground: Ground {
            asphalt: surface(0.1, 0.35, 0.9, 0.01),
            mat: None,
            patches: vec![
                shade([3.8, 1.5], [2.5, 2.5], 20.0),
                shade([4.0, -2.5], [2.0, 2.0], 45.0),
                shade([0.5, 3.6], [2.0, 1.5], -15.0),
                shade([-4.0, 3.5], [2.0, 2.0], 0.0),
                shade([-3.8, -1.0], [2.5, 3.0], 10.0),
                shade([0.0, -3.5], [3.0, 2.0], 30.0),
            ],
            ..Default::default()
        },
        sun: Sun {
            elevation_deg: 65.0,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// A scene preset by name.
pub fn scene_preset(name: &str) -> Option<Scene> {
    match name {
        "car-park" => Some(car_park()),
        "low-sun" => Some(low_sun()),
        "overcast" => Some(overcast()),
        "sky" => Some(sky()),
        "tunnel-exit" => Some(tunnel_exit()),
        "snow" => Some(snow()),
        "lawn" => Some(lawn()),
        _ => None,
    }
}

/// A script preset by name, with its natural length in seconds.
pub fn script_preset(name: &str) -> Option<(Script, f64)> {
    let step = |at_s: f64, stops: f64| Event::Step {
        at_s,
        stops,
        light: LightPart::All,
    };
    let ramp = |from_s: f64, to_s: f64, stops: f64| Event::Ramp {
        from_s,
        to_s,
        stops,
        light: LightPart::All,
    };
    match name {
        "constant" => Some((Script::default(), 2.0)),
        "steps" => Some((
            Script::new(vec![
                step(1.0, 2.0),
                step(3.0, -2.0),
                step(5.0, -4.0),
                step(7.0, 4.0),
            ]),
            9.0,
        )),
        "ramp" => Some((
            Script::new(vec![ramp(1.0, 11.0, -4.0), ramp(13.0, 23.0, 4.0)]),
            24.0,
        )),
        "tunnel" => Some((
            Script::new(vec![Event::Tunnel {
                enter_s: 1.5,
                exit_s: 5.5,
                darkening: 100.0,
                transition_s: 0.4,
            }]),
            8.0,
        )),
        _ => None,
    }
}
