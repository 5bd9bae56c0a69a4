//! `rigview live` end to end on Aravis's in-process fake cameras showing the
//! simulated rig (`--fake`), through the app's own processing pipeline with
//! the settings the window would use, and its errors for a rig file whose
//! cameras have no device and for an unknown simulation.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

use clap::Parser;
use rigview::cli::live::LiveArgs;
use rigview::cli::{Cli, Command};
use rigview::logging::LogBuffer;
use rigview_core::pipeline::ProcessingSettings;

/// `rigview live ARGS` as the command line parses it.
fn parse(args: &[&str]) -> Result<LiveArgs, clap::Error> {
    let cli = Cli::try_parse_from(["rigview", "live"].iter().chain(args))?;
    match cli.command {
        Some(Command::Live(live)) => Ok(live),
        other => panic!("not `rigview live`: {other:?}"),
    }
}

/// `rigview live --headless` as the command line runs it: the default
/// settings with the options' overrides, the events of this thread (the
/// cameras' start-up among them) printed with the status.
fn run(args: &LiveArgs, out: &mut Vec<u8>) -> anyhow::Result<()> {
    let mut settings = ProcessingSettings::default();
    args.processing.apply(&mut settings);
    let log = LogBuffer::new();
    let _events = rigview::logging::capture(&log);
    rigview::cli::live::headless(args, &settings, &log, out)
}

fn rig() -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/surround-nz.rig.yaml");
    p.display().to_string()
}

#[test]
fn live_runs_the_loop_on_fake_cameras_and_prints_status() {
    let cli = parse(&[
        "--fake", "--scale", "0.25", "--frames", "30", "--settle", "0.2",
    ])
    .unwrap();
    let mut out = Vec::new();
    run(&cli, &mut out).unwrap();
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

/// Balanced control (the default strategy, asked for explicitly) on the
/// fake cameras: the fake rig comes with its calibration, so the overlaps
/// are measured and every camera's command is balanced.
#[test]
fn live_headless_balances_the_cameras_through_their_overlaps() {
    let cli = parse(&[
        "--fake",
        "--scale",
        "0.25",
        "--frames",
        "80",
        "--settle",
        "0.2",
        "--strategy",
        "multi",
        "--law",
        "fast",
    ])
    .unwrap();
    let mut out = Vec::new();
    run(&cli, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    println!("{text}");
    assert!(text.contains("gradient AE (multi), fast law"), "{text}");
    assert!(text.contains("done: 80 frame sets"), "{text}");
    // Every overlap is listed, and overlaps are measured. (An overlap
    // where either camera has too few usable patches, saturated or near
    // black, says n/a rather than give a noisy ratio.)
    let blocks: Vec<&str> = text
        .lines()
        .filter_map(|l| l.split("overlaps, log2 r_ij: ").nth(1))
        .collect();
    assert!(!blocks.is_empty(), "no overlap line:\n{text}");
    let mut measured = std::collections::BTreeSet::new();
    for b in &blocks {
        let entries: Vec<&str> = b.split(", ").collect();
        assert_eq!(entries.len(), 4, "{b}");
        for e in entries {
            let (pair, value) = e.rsplit_once(' ').unwrap();
            if let Ok(v) = value.parse::<f64>() {
                assert!(v.is_finite() && v.abs() < 8.0, "{e}");
                measured.insert(pair.to_owned());
            } else {
                assert_eq!(value, "n/a", "{e}");
            }
        }
    }
    assert!(measured.len() >= 2, "only {measured:?} measured:\n{text}");
    // Every camera of a measured overlap is balanced: it sent commands with
    // α of Eq. 6. (A camera waits for a frame that shows its last command
    // before the next, so not every block has a command for every camera.)
    for name in measured.iter().flat_map(|p| p.split('-')) {
        assert!(
            text.lines().any(|l| l.trim_start().starts_with(name)
                && l.contains("→")
                && l.contains("balanced α")),
            "{name} never sent a balanced command:\n{text}"
        );
    }
}

#[test]
fn a_rig_without_device_ids_is_refused_with_the_camera_named() {
    let rig = rig();
    let cli = parse(&["--rig", &rig, "--seconds", "1"]).unwrap();
    let err = run(&cli, &mut Vec::new()).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("camera \"front\" has no device"), "{msg}");
}

#[test]
fn an_unknown_simulation_is_refused_with_the_presets_named() {
    let cli = parse(&["--fake", "--scenario", "moonlight"]).unwrap();
    let err = run(&cli, &mut Vec::new()).unwrap_err();
    let msg = format!("{err:#}");
    assert!(msg.contains("moonlight"), "{msg}");
    assert!(msg.contains("reference, steps, ramp, tunnel"), "{msg}");
}

#[test]
fn fake_and_rig_exclude_each_other_and_a_scenario_needs_fake() {
    let rig = rig();
    let both = parse(&["--rig", &rig, "--fake"]).unwrap_err();
    assert!(both.to_string().contains("cannot be used with"), "{both}");
    let neither = parse(&[]).unwrap_err();
    assert!(neither.to_string().contains("--rig"), "{neither}");
    let stray = parse(&["--rig", &rig, "--scenario", "tunnel"]).unwrap();
    let err = run(&stray, &mut Vec::new()).unwrap_err();
    assert!(format!("{err:#}").contains("need --fake"), "{err:#}");
}
