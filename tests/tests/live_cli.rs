//! `rigview live` end to end on Aravis's in-process fake cameras showing the
//! simulated rig (`--fake`), and its errors for a rig file whose cameras
//! have no device and for an unknown simulation.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

use clap::Parser;
use rigview::live::cmd::{run, LiveArgs};

#[derive(Debug, Parser)]
struct Cli {
    #[command(flatten)]
    live: LiveArgs,
}

fn rig() -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/surround-nz.rig.yaml");
    p.display().to_string()
}

#[test]
fn live_runs_the_loop_on_fake_cameras_and_prints_status() {
    let cli = Cli::try_parse_from([
        "live", "--fake", "--scale", "0.25", "--frames", "30", "--settle", "0.2",
    ])
    .unwrap();
    let mut out = Vec::new();
    run(&cli.live, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    println!("{text}");
    assert!(
        text.contains("simulation \"reference\": 4 cameras of 322×241 Mono8"),
        "{text}"
    );
    assert!(text.contains("front: open"), "{text}");
    assert!(text.contains("done: 30 frame sets"), "{text}");
    for name in ["front", "left", "back", "right"] {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(name) && l.contains("streaming")),
            "no status line for {name}:\n{text}"
        );
    }
}

#[test]
fn a_rig_without_device_ids_is_refused_with_the_camera_named() {
    let rig = rig();
    let cli = Cli::try_parse_from(["live", "--rig", &rig, "--seconds", "1"]).unwrap();
    let err = run(&cli.live, &mut Vec::new()).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("camera \"front\" has no device"), "{msg}");
}

#[test]
fn an_unknown_simulation_is_refused_with_the_presets_named() {
    let cli = Cli::try_parse_from(["live", "--fake", "--scenario", "moonlight"]).unwrap();
    let err = run(&cli.live, &mut Vec::new()).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("moonlight"), "{msg}");
    assert!(msg.contains("reference, steps, ramp, tunnel"), "{msg}");
}

#[test]
fn fake_and_rig_exclude_each_other_and_a_scenario_needs_fake() {
    let rig = rig();
    let both = Cli::try_parse_from(["live", "--rig", &rig, "--fake"]).unwrap_err();
    assert!(both.to_string().contains("cannot be used with"), "{both}");
    let neither = Cli::try_parse_from(["live"]).unwrap_err();
    assert!(neither.to_string().contains("--rig"), "{neither}");
    let stray = Cli::try_parse_from(["live", "--rig", &rig, "--scenario", "tunnel"]).unwrap();
    let err = run(&stray.live, &mut Vec::new()).unwrap_err();
    assert!(format!("{err:#}").contains("need --fake"), "{err:#}");
}
