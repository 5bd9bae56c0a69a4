//! `rigview live` end to end on Aravis's in-process fake cameras (`--fake`),
//! and its error for a rig file whose cameras have no device.

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
    let rig = rig();
    let cli = Cli::try_parse_from([
        "live", "--rig", &rig, "--fake", "--frames", "30", "--settle", "0.2",
    ])
    .unwrap();
    let mut out = Vec::new();
    run(&cli.live, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    println!("{text}");
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
